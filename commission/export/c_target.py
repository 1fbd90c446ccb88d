"""C99 sources of a validated controller: header, step, parameters, replay program, README.

The step functions are translated from the compiled Python step
(:mod:`commission.export.translate`); this module wraps them in the public
API below and writes the packed parameters of one controller::

    typedef struct { double v[<PREFIX>_NP]; } <prefix>_params;   fixed at export (const)
    typedef struct { double v[<PREFIX>_NS]; } <prefix>_state;    everything that changes
    void   <prefix>_init(<prefix>_state *s, const <prefix>_params *p, double y0);
    double <prefix>_step(<prefix>_state *s, const <prefix>_params *p,
                         double y, double qd, double dqd, double ddqd);
    int32_t <prefix>_fault(const <prefix>_state *s);        0, or the FAULT_* reason code
    const char *<prefix>_fault_reason(int32_t code);

No heap, no global state (the parameters are a ``const`` object the caller
passes), re-entrant; the header includes only ``<stdint.h>``, the step
``<math.h>``.  ``<prefix>`` is ``commission_arc`` or ``commission_pid``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from commission.controllers import arc as _arc
from commission.controllers import pid as _pid
from commission.export.text import check_comment_line
from commission.export.translate import c_float, translate


@dataclass(frozen=True)
class Target:
    """One exportable controller kind.

    Attributes
    ----------
    name : str
        ``arc`` or ``pid``.
    module : module
        Where its compiled step lives.
    functions : tuple of str
        Translated functions, callees first.
    reset, step : str
        The Python names of the reset and step functions.
    np_name, ns_name : str
        Module constants of the parameter and state lengths.
    layout_prefixes : tuple of str
        Module constants exported to the header (layout and fault codes).
    fault_slot : str or None
        State slot holding the fault reason code (None: the law has no fault state).
    fault_reasons : mapping
        Code -> text.
    """

    name: str
    module: Any
    functions: tuple[str, ...]
    reset: str
    step: str
    np_name: str
    ns_name: str
    layout_prefixes: tuple[str, ...]
    fault_slot: str | None
    fault_reasons: Mapping[int, str]

    @property
    def prefix(self) -> str:
        return f"commission_{self.name}_"

    @property
    def base(self) -> str:
        return f"commission_{self.name}"


ARC = Target("arc", _arc, ("arc_reset", "_alpha1", "_fault", "arc_step"), "arc_reset", "arc_step",
             "NP", "NS", ("P_", "S_", "FAULT_"), "S_FAULT", _arc.FAULT_REASONS)
PID = Target("pid", _pid, ("pid_reset", "pid_step"), "pid_reset", "pid_step",
             "NG", "NS", ("G_", "S_"), "S_FAULT", {0: "none", 1: "non-finite input"})
TARGETS = {"arc": ARC, "pid": PID}

#: Compiler flags that keep the C arithmetic identical to the Python step's.
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off")


def _layout(t: Target) -> dict[str, int]:
    out = {}
    for k, v in vars(t.module).items():
        if isinstance(v, int) and not isinstance(v, bool) and (k.startswith(t.layout_prefixes)
                                                                or k in (t.np_name, t.ns_name)):
            out[k] = v
    return dict(sorted(out.items(), key=lambda kv: (not kv[0] in (t.np_name, t.ns_name), kv[0][:2], kv[1], kv[0])))


def header(t: Target, banner: str) -> str:
    up = t.base.upper()
    lay = _layout(t)
    defs = "\n".join(f"#define {up}_{k} {v}" for k, v in lay.items())
    reasons = "\n".join(f" *   {c}: {r}" for c, r in sorted(t.fault_reasons.items()))
    return f"""{banner}
#ifndef {up}_H
#define {up}_H

#include <stdint.h>

/* Packed layout: the constants of {t.module.__name__} ({t.np_name} parameters, {t.ns_name} state entries). */
{defs}

/* Everything fixed at export: a const object (see {t.base}_params.c). */
typedef struct {{ double v[{up}_{t.np_name}]; }} {t.base}_params;
/* Everything that changes from sample to sample; one per axis, owned by the caller. */
typedef struct {{ double v[{up}_{t.ns_name}]; }} {t.base}_state;

/* The validated parameters ({t.base}_params.c). */
extern const {t.base}_params {t.base}_params_validated;

/* Start at rest at the measured position y0 (m), the axis at rest with q_d(0) = y0. */
void {t.base}_init({t.base}_state *s, const {t.base}_params *p, double y0);

/* One sample: measured position y (m), desired position qd (m), velocity dqd (m/s) and
 * acceleration ddqd (m/s^2); returns the command to hold until the next sample (u-unit). */
double {t.base}_step({t.base}_state *s, const {t.base}_params *p, double y, double qd, double dqd, double ddqd);

/* The latched fault's reason code, 0 while none.  Once a fault latches the step returns
 * the safe command 0 until {t.base}_init.  Codes:
{reasons}
 */
int32_t {t.base}_fault(const {t.base}_state *s);
const char *{t.base}_fault_reason(int32_t code);

#endif
"""


def source(t: Target, banner: str) -> str:
    code, consts = translate(t.module, t.functions, {"p": (t.np_name, True), "s": (t.ns_name, False)}, t.prefix)
    up = t.base.upper()
    floats = "\n".join(f"#define {up}_{k} {c_float(v)}" for k, v in sorted(consts.items()) if isinstance(v, float))
    cases = "\n".join(f'    case {c}: return "{r}";' for c, r in sorted(t.fault_reasons.items()))
    fault = (f"return (int32_t)s->v[{up}_{t.fault_slot}];" if t.fault_slot else
             "(void)s;\n    return 0; /* this law has no fault state */")
    return f"""{banner}
#include <math.h>
#include <stdint.h>

#include "{t.base}.h"

{floats}

{code}
void {t.base}_init({t.base}_state *s, const {t.base}_params *p, double y0)
{{
    {t.prefix}k_{t.reset.lstrip('_')}(p->v, s->v, y0);
}}

double {t.base}_step({t.base}_state *s, const {t.base}_params *p, double y, double qd, double dqd, double ddqd)
{{
    return {t.prefix}k_{t.step.lstrip('_')}(p->v, s->v, y, qd, dqd, ddqd);
}}

int32_t {t.base}_fault(const {t.base}_state *s)
{{
    {fault}
}}

const char *{t.base}_fault_reason(int32_t code)
{{
    switch (code) {{
{cases}
    default: return "unknown";
    }}
}}
"""


def _slot_names(t: Target) -> list[str]:
    """Name of each parameter slot (``P_TMIN[1]`` for the second entry of a 3-vector)."""
    starts = sorted((v, k) for k, v in _layout(t).items() if k.startswith(t.layout_prefixes[0]))
    n = getattr(t.module, t.np_name)
    names = []
    for i in range(n):
        v, k = max((s for s in starts if s[0] <= i), default=(0, "?"))
        width = min([s[0] for s in starts if s[0] > v] + [n]) - v
        names.append(k if width == 1 else f"{k}[{i - v}]")
    return names


def params_source(t: Target, p: np.ndarray, comment: Sequence[str], banner: str) -> str:
    """``<prefix>_params.c``: the packed parameters as a const object, ``comment`` above it.

    Each comment line must already be escaped (:func:`commission.export.text.c_comment`);
    it is checked once more here (no ``*/``, trigraph, backslash or non-printable character).
    """
    names = _slot_names(t)
    rows = ",\n".join(f"    /* [{i:2d}] {names[i]:<14s} */ {c_float(float(x))}" for i, x in enumerate(p))
    com = "\n".join(f" * {check_comment_line(line, 'c')}" for line in comment)
    return f"""{banner}
/*
{com}
 */
#include <math.h>

#include "{t.base}.h"

const {t.base}_params {t.base}_params_validated = {{{{
{rows}
}}}};
"""


TEST_MAIN = r"""{banner}
/* Replay test_vectors.csv through {base}_step; print the largest |u_C - u_Python|.
 * Build: cc -std=c99 -O2 -ffp-contract=off test_main.c {base}.c {base}_params.c -lm
 * Exit 0 when every command and fault code is identical, 1 otherwise. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "{base}.h"

int main(int argc, char **argv)
{{
    const char *path = argc > 1 ? argv[1] : "test_vectors.csv";
    FILE *f = fopen(path, "r");
    char line[1024];
    char scen[64] = "", prev[64] = "";
    {base}_state s;
    double maxdiff = 0.0;
    long rows = 0, fault_mismatch = 0, unequal = 0;
    if (!f) {{
        fprintf(stderr, "%s: cannot open\n", path);
        return 2;
    }}
    if (!fgets(line, sizeof line, f)) {{
        fprintf(stderr, "%s: empty\n", path);
        return 2;
    }}
    while (fgets(line, sizeof line, f)) {{
        char *tok = strtok(line, ",");
        double y, qd, dqd, ddqd, u_py, u_c, d;
        long k;
        int fault_py;
        if (!tok) continue;
        strncpy(scen, tok, sizeof scen - 1);
        k = strtol(strtok(NULL, ","), NULL, 10);
        y = strtod(strtok(NULL, ","), NULL);
        qd = strtod(strtok(NULL, ","), NULL);
        dqd = strtod(strtok(NULL, ","), NULL);
        ddqd = strtod(strtok(NULL, ","), NULL);
        u_py = strtod(strtok(NULL, ","), NULL);
        fault_py = (int)strtol(strtok(NULL, ",\n"), NULL, 10);
        if (k == 0 || strcmp(scen, prev) != 0) {{
            {base}_init(&s, &{base}_params_validated, y);
            strcpy(prev, scen);
        }}
        u_c = {base}_step(&s, &{base}_params_validated, y, qd, dqd, ddqd);
        d = fabs(u_c - u_py);
        if (d > maxdiff) maxdiff = d;
        if (u_c != u_py) unequal++;
        if ({base}_fault(&s) != fault_py) fault_mismatch++;
        rows++;
    }}
    fclose(f);
    printf("rows %ld max_abs_diff %.17g unequal %ld fault_mismatch %ld\n", rows, maxdiff, unequal, fault_mismatch);
    return (unequal == 0 && fault_mismatch == 0 && rows > 0) ? 0 : 1;
}}
"""


def test_main(t: Target, banner: str) -> str:
    return TEST_MAIN.format(banner=banner, base=t.base)

