"""Cost of the exported C step (issue 22, must-show 3): time per call and memory.

Exports the controller of the paper's identified axis (the §4.3 gains carried
over, with the runtime guards validate sets), compiles it with the system
compiler and the export's flags (``-std=c99 -O2 -ffp-contract=off``) together
with a small timing harness, and runs 10^6 steps on a periodic reference
(y = q_d, 4 Hz sine of 5 cm): 1000 blocks of 1000 calls, each block timed
with ``clock_gettime(CLOCK_MONOTONIC)``.  Prints the median time per call
over the blocks (target <= 1 us), ``sizeof`` the state (target <= 1 KiB) and
the parameters, for the ARC and the PID.

Run: ``python benchmarks/bench_export.py``.  Prints figures; asserts nothing.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.controllers.arc import arc_pack
from commission.controllers.pid import pid_pack
from commission.export import render
from commission.export.build import find_cc
from commission.export.c_target import CFLAGS
from commission.gate import GateSpec, resolve_gate
from commission.paper import reference_identification
from commission.spec import default_spec
from commission.tune import base_arc_gains, pid_baseline
from commission.validate import deployable_gains, guard_values

HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "commission_{k}.h"

#define N 25000
#define BLOCKS 1000
#define CALLS 1000

static int cmp(const void *a, const void *b)
{{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}}

int main(void)
{{
    static double qd[N], dqd[N], ddqd[N], per[BLOCKS];
    const double Ts = {Ts!r}, w = 2.0 * 3.141592653589793 * 4.0, A = 0.05;
    commission_{k}_state s;
    volatile double sink = 0.0;
    long i = 0;
    int b, c;
    for (c = 0; c < N; c++) {{
        double t = c * Ts;
        qd[c] = A * sin(w * t);
        dqd[c] = A * w * cos(w * t);
        ddqd[c] = -A * w * w * sin(w * t);
    }}
    commission_{k}_init(&s, &commission_{k}_params_validated, 0.0);
    for (b = 0; b < BLOCKS; b++) {{
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (c = 0; c < CALLS; c++, i++) {{
            long j = i % N;
            sink += commission_{k}_step(&s, &commission_{k}_params_validated, qd[j], qd[j], dqd[j], ddqd[j]);
        }}
        clock_gettime(CLOCK_MONOTONIC, &t1);
        per[b] = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / CALLS;
    }}
    qsort(per, BLOCKS, sizeof per[0], cmp);
    printf("%s step: median %.1f ns/call over %d x %d calls (min %.1f, max %.1f); fault %d\n",
           "{k}", per[BLOCKS / 2], BLOCKS, CALLS, per[0], per[BLOCKS - 1], (int)commission_{k}_fault(&s));
    printf("%s sizeof(state) = %zu B, sizeof(params) = %zu B\n", "{k}", sizeof(commission_{k}_state),
           sizeof(commission_{k}_params));
    return sink == 12345.0;
}}
"""


def main() -> int:
    cc = find_cc()
    if cc is None:
        print("no C compiler (cc) on the PATH", file=sys.stderr)
        return 2
    spec = default_spec()
    ident = reference_identification(delta_d=0.5)
    raw = base_arc_gains(ident, spec)
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=spec.travel, u_max=spec.u_max)
    g = deployable_gains(raw, guard_values(raw.Ts, 1e-6, spec.v_max, spec.travel, lim.e_M))
    cfg = ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"}, validated={},
                           provenance=ControllerProvenance(None, "0" * 64, "0" * 64, "bench", "-"))
    print(f"compiler: {subprocess.run([cc, '--version'], capture_output=True, text=True).stdout.splitlines()[0]}")
    print(f"flags: {' '.join(CFLAGS)}")
    for kind, p in (("arc", arc_pack(g)), ("pid", pid_pack(pid_baseline(ident, spec)[0]))):
        with tempfile.TemporaryDirectory() as td:
            d = Path(td)
            for name, text in render(kind, p, cfg, None, None).items():
                if name.endswith((".h", ".c")) and name != "test_main.c":
                    (d / name).write_text(text)
            (d / "bench.c").write_text(HARNESS.format(k=kind, Ts=g.Ts))
            exe = d / "bench"
            subprocess.run([cc, *CFLAGS, "-o", str(exe), str(d / "bench.c"), str(d / f"commission_{kind}.c"),
                            str(d / f"commission_{kind}_params.c"), "-lm"], check=True)
            print(subprocess.run([str(exe)], capture_output=True, text=True).stdout, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
