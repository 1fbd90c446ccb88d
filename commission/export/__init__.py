"""``commission export``: the validated controller as C99 for a real-time target.

:func:`export_c` writes into one folder::

    commission_<kind>.h, commission_<kind>.c   the step, translated from the compiled
                                               Python step (commission.export.translate)
    commission_<kind>_params.c                 the packed parameters, a const object
    test_vectors.csv                           inputs and commands of the Python runtime
    test_main.c                                replays the vectors, prints the largest difference
    README.md                                  how to call it from a timer interrupt

``<kind>`` is ``arc`` (controller.json) or ``pid`` (the PID baseline validate
simulated beside it, read from the tuning.json whose sha256 controller.json
records).  The controller is loaded exactly as :func:`commission.runtime.load_controller`
loads it, the site's signing key included, so ``export`` refuses what the
runtime refuses; every input and the output folder are checked before anything
is written, and the files are written as every command writes them
(:class:`commission.infra.files.Outputs`: locked, staged, moved into place together).

The generated files are code a compiler or PLC IDE reads, so no string of
controller.json is copied into them unchecked (:mod:`commission.export.text`):
provenance fields must have their fixed form or the export is refused, the
unit is escaped for the language it lands in, numbers are formatted here.
A checksum or a signature does not make a string safe to compile: the one is
recomputed by anyone, the other only says who emitted the file.

Test vectors: three closed-loop scenarios of up to :data:`VECTOR_STEPS`
samples each, simulated with the compiled step and replayed through the
Python runtime: Case 1 and Case 2 of the validation, and a fault case (Case 1
with a one-sample glitch of 0.001, then a jump of 1, in the axis's position unit
(m, or rad on a rotary axis), then a non-finite measurement).  With ``tuning``
(checked against the controller's provenance) they are the validated scenarios:
the identified plant, the envelope's trajectories, the encoder and the actuator
limit validate used.  Without it,
controller.json alone does not carry the plant: the vectors then run on the
nominal plant its initial estimates describe (M = 1/theta0_1, B = theta0_2 M,
offset = -theta0_3 M) with the default envelope; the vectors test the C
against the Python step either way.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from commission.controller_config import SIGN_KEY_ENV, ControllerConfig
from commission.controllers.arc import arc_pack
from commission.controllers.pid import pid_pack
from commission.controllers.plant import plant_vector
from commission.controllers.simulate import KIND_ARC, KIND_PID, simulate
from commission.errors import CommissionError, UsageError
from commission.export import c_target
from commission.export.c_target import CFLAGS, TARGETS, Target
from commission.export.text import c_comment, check_comment_line, checked_provenance, markdown_code, st_comment
from commission.infra.files import Outputs
from commission.jsonio import read_json, sha256_file, write_text_atomic
from commission.scenarios import case1_trajectory, case2_trajectory, identified_plant, plant_substeps
from commission.spec import default_spec
from commission.tuning import Tuning

#: Samples per scenario in test_vectors.csv (at most; a shorter trajectory gives all of its).
VECTOR_STEPS = 25_000
VECTORS_NAME = "test_vectors.csv"


def output_names(kind: str, target: str = "c") -> tuple[str, ...]:
    """Every file ``export --target target --controller kind`` writes."""
    if target == "st":
        return (f"FB_Commission{kind.capitalize()}.st",)
    b = f"commission_{kind}"
    return (f"{b}.h", f"{b}.c", f"{b}_params.c", VECTORS_NAME, "test_main.c", "README.md")


@dataclass(frozen=True)
class Vectors:
    """Replay data: per row scenario, k, y, qd, dqd, ddqd, u (Python runtime), fault code after the step."""

    scenario: tuple[str, ...]
    k: np.ndarray
    y: np.ndarray
    qd: np.ndarray
    dqd: np.ndarray
    ddqd: np.ndarray
    u: np.ndarray
    fault: np.ndarray

    def csv(self) -> str:
        lines = ["scenario,k,y,qd,dqd,ddqd,u,fault"]
        for i in range(len(self.scenario)):
            lines.append(f"{self.scenario[i]},{int(self.k[i])},{float(self.y[i])!r},{float(self.qd[i])!r},"
                         f"{float(self.dqd[i])!r},{float(self.ddqd[i])!r},{float(self.u[i])!r},{int(self.fault[i])}")
        return "\n".join(lines) + "\n"


def python_step(kind: str):
    """(reset, step, new_state, fault slot) of the compiled Python step for ``kind``."""
    t = TARGETS[kind]
    mod = t.module
    return getattr(mod, t.reset), getattr(mod, t.step), getattr(mod, t.ns_name), getattr(mod, t.fault_slot)


def _setting(config: ControllerConfig, tuning: Tuning | None) -> tuple[np.ndarray, Any, float, float, int]:
    """(plant, spec, quantization, u_sat, substeps) of the vector scenarios (module docstring)."""
    Ts = config.gains.Ts
    if tuning is not None:
        spec = tuning.spec
        return (identified_plant(tuning.identification), spec, tuning.quantization, spec.u_max,
                plant_substeps(1.0 / Ts))
    g = config.gains
    M = 1.0 / g.theta0[0]
    plant = plant_vector(M, g.theta0[1] * M, g.fric_level, offset=-g.theta0[2] * M)
    sim = config.validated.get("simulation", {}) if isinstance(config.validated, dict) else {}
    quant = sim.get("quantization", 1e-6)
    quant = float(quant) if isinstance(quant, (int, float)) and quant >= 0 else 1e-6
    u_sat = g.u_max if math.isfinite(g.u_max) else math.inf
    return plant, default_spec(), quant, u_sat, plant_substeps(1.0 / Ts)


def make_vectors(kind: str, p: np.ndarray, config: ControllerConfig, tuning: Tuning | None) -> Vectors:
    """Simulate the three scenarios with the compiled step and replay them through it (module docstring)."""
    plant, spec, quant, u_sat, substeps = _setting(config, tuning)
    Ts = config.gains.Ts
    reset, step, ns, fslot = python_step(kind)
    rows: dict[str, list] = {k: [] for k in ("scenario", "k", "y", "qd", "dqd", "ddqd", "u", "fault")}
    for name, tspec, glitch in (("case1", case1_trajectory(spec), False), ("case2", case2_trajectory(spec), False),
                                ("fault", case1_trajectory(spec), True)):
        traj = tspec.render(Ts, 0.0)
        n = min(traj.n, VECTOR_STEPS)
        noise = None
        if glitch:
            noise = np.zeros(traj.n)
            noise[n // 5] = 1e-3  # a one-sample glitch the plausibility guard rejects
            noise[n // 3] = 1.0  # a jump beyond the stroke: a fault when the guards are on
        r = simulate(plant, KIND_ARC if kind == "arc" else KIND_PID, p, traj, substeps=substeps, quant=quant,
                     noise=noise, u_sat=u_sat, e_abort=spec.travel)
        y = np.array(r.y[:n])
        n = y.shape[0]
        if glitch and n > 2:
            y[(2 * n) // 3] = math.nan  # a non-finite measurement latches a fault in any case
        s = np.zeros(ns)
        for k in range(n):
            if k == 0:
                reset(p, s, y[0])
            u = step(p, s, y[k], traj.qd[k], traj.dqd[k], traj.ddqd[k])
            rows["scenario"].append(name)
            rows["k"].append(k)
            rows["y"].append(y[k])
            rows["qd"].append(traj.qd[k])
            rows["dqd"].append(traj.dqd[k])
            rows["ddqd"].append(traj.ddqd[k])
            rows["u"].append(u)
            rows["fault"].append(int(s[fslot]))
    return Vectors(tuple(rows["scenario"]), *(np.asarray(rows[k]) for k in ("k", "y", "qd", "dqd", "ddqd", "u",
                                                                            "fault")))


def _banner(kind: str) -> str:
    return (f"/* Generated by `commission export --target c --controller {kind}` from the compiled Python step;\n"
            f" * do not edit: regenerate.  Build with {' '.join(CFLAGS)} (no -ffast-math) to keep the\n"
            f" * arithmetic identical to what commission validate simulated. */")


def _params_comment(config: ControllerConfig, kind: str, p: np.ndarray, tuning_sha: str | None, *,
                    lang: str = "c", source: str = "controller.json") -> list[str]:
    """The comment lines of the parameters (C ``_params.c``, ST header) for the language ``lang``.

    No string of controller.json is copied unchecked (:mod:`commission.export.text`): the
    provenance fields are checked against their fixed forms (a SchemaError otherwise), the unit
    is escaped for ``lang``, numbers are formatted here, and every line is checked last.
    """
    pr = checked_provenance(config.provenance, source)
    ck = config.to_dict()["checksum"]["value"]  # recomputed here: a sha256 hex digest
    if tuning_sha is not None and not _is_sha256(tuning_sha):
        raise RuntimeError(f"export bug: tuning sha256 {tuning_sha[:80]!r} is not a hex digest")
    esc = c_comment if lang == "c" else st_comment
    lines = [
        f"Packed parameters of the {kind.upper()} controller validated by commission validate.",
        f"Sample rate {float(config.sample_rate)!r} Hz (period {float(config.gains.Ts)!r} s): "
        f"call the step exactly then.",
        f"Units: y, qd in m, dqd in m/s, ddqd in m/s^2; command in {esc(config.units.get('u', 'u-unit'))}.",
        f"controller.json sha256 checksum: {ck}",
        f"provenance: tuning_sha256 {pr['tuning_sha256']}, ident_sha256 {pr['ident_sha256']},",
        f"  log_sha256 {pr['log_sha256']}, tool {pr['tool_version']}, validated {pr['created_utc']}",
        *([f"PID gains read from tuning.json (sha256 {tuning_sha}, as recorded in controller.json)"]
          if kind == "pid" else []),
        f"{p.shape[0]} doubles; each written so that it reads back exactly.",
    ]
    return [check_comment_line(line, lang) for line in lines]


def _is_sha256(text: str) -> bool:
    return len(text) == 64 and all(c in "0123456789abcdef" for c in text)


def readme(kind: str, config: ControllerConfig, target: Target, with_tuning: bool) -> str:
    """README.md of a C export; every unit it carries, as an escaped code span.

    The position unit is worded by the axis (m, or rad on a rotary one) wherever a length
    or an encoder read-out appears, and only ever as :func:`markdown_code` of the file's
    ``units.q``: the code block of the interrupt example names a unit-neutral
    ``read_position()``, since no text of the file may enter it, and the sentence after it
    says the unit.
    """
    from commission.units import nominal, unit  # printed rates at their nominal value, the axis's units

    q = markdown_code(unit("q", config.units))  # from the file: escaped like every free text
    b = target.base
    up = b.upper()
    return f"""# {b}: the validated {kind.upper()} step in C99

Generated by `commission export --target c --controller {kind}` from the compiled Python
step that `commission validate` simulated (translated statement by statement, same order of
operations, same packed layout, same fault logic). Do not edit; regenerate.

Sample rate: {nominal(config.sample_rate, '{:.9g}')} Hz (period {nominal(config.gains.Ts, '{:.9g}')} s; the
exact values are in `{b}_params.c`). Units: positions in {q}, velocity {q}/s, acceleration {q}/s²,
command in {markdown_code(config.units.get('u', 'u-unit'))}.

## Files

- `{b}.h`, `{b}.c`: the step. C99, only `<math.h>` and `<stdint.h>`, no heap, no global
  state, re-entrant (one `{b}_state` per axis).
- `{b}_params.c`: `{b}_params_validated`, the parameters as a `const` object (sample rate,
  units, the controller.json checksum and provenance in its comment).
- `test_vectors.csv`: y, qd, dqd, ddqd and the command u of the Python runtime, three scenarios
  (`case1`, `case2`, and `fault`: a one-sample glitch of 0.001 {q}, a jump of 1 {q}, a non-finite sample).
  {'The validated scenarios (identified plant, envelope, encoder).' if with_tuning else
   'Run on the nominal plant of the controller initial estimates (no tuning.json was given).'}
- `test_main.c`: replays the vectors; prints the largest |u_C - u_Python| and exits 0 only when
  every command and fault code is identical.

## Build and check

    cc {' '.join(CFLAGS)} -o replay test_main.c {b}.c {b}_params.c -lm
    ./replay test_vectors.csv

Keep `-ffp-contract=off` (no fused multiply-add: it changes the rounding of `a*b + c`) and
never use `-ffast-math` (or `-Ofast`): both let the compiler reorder the arithmetic, and the
command is then no longer the one that was validated. The same holds for other compilers
(e.g. `/fp:precise` on MSVC). `atan` comes from the target's libm.

## Calling it from a timer interrupt

    static {b}_state axis;                        /* state: changes every sample */
    /* at enable, axis at rest: */
    {b}_init(&axis, &{b}_params_validated, read_position());
    /* every {nominal(config.gains.Ts, '{:.9g}')} s, in the servo interrupt: */
    double u = {b}_step(&axis, &{b}_params_validated, read_position(), qd, dqd, ddqd);
    if ({b}_fault(&axis)) {{ disable_drive(); /* reason: {b}_fault_reason({b}_fault(&axis)) */ }}
    else write_dac(u);                            /* hold until the next sample */

`read_position()` stands for the encoder's reading in {q}, and `qd`, `dqd`, `ddqd` for the
reference in {q}, {q}/s and {q}/s²: the units the controller was validated in.

Fixed at export: everything in `{b}_params_validated` (gains, limits, runtime guards, the
exact sampled filter matrices). State: `{b}_state` ({up}_NS doubles: filters, estimates,
the last accepted measurement, the fault code). Once a fault latches the step returns the
safe command 0 until `{b}_init`; the estimates keep their last good values. 0 is no force:
disable the drive or engage the brake on the fault flag, since 0 does not hold a vertical axis.
"""


def export_c(controller_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], *, kind: str = "arc",
             tuning_path: str | os.PathLike[str] | None = None, force: bool = False,
             target: str = "c", key: bytes | None = None, require_signature: bool = False,
             inputs: Sequence[str | os.PathLike[str] | None] = ()) -> list[Path]:
    """Write the C export of a validated controller (module docstring).

    Everything that can be refused is checked before anything is written,
    in this order: the flags, the controller (loaded as
    :func:`commission.runtime.load_controller` loads it, ``key`` included),
    its provenance strings (:func:`commission.export.text.checked_provenance`),
    the tuning, and the output folder.  The files are then written the way
    every command writes (:class:`commission.infra.files.Outputs`): under a lock on
    the folder, into a staging folder beside it, and moved into place
    together, so that an interruption (Ctrl-C, SIGTERM) or a write error (a
    full disk) leaves the folder as it was, with no staging folder behind.

    Parameters
    ----------
    controller_path : path
        controller.json (loaded as the runtime loads it).
    out_dir : path
        Output folder (created).
    kind : {"arc", "pid"}
        The ARC of controller.json, or the PID baseline validated beside it
        (needs ``tuning_path``).
    tuning_path : path, optional
        The tuning.json controller.json was validated from (its sha256 must
        match ``provenance.tuning_sha256``).
    force : bool
        Overwrite existing files.
    target : {"c", "st"}
        C99 (module docstring), or the IEC 61131-3 Structured Text function
        block of :mod:`commission.export.st_target` (one ``.st`` file).
    key : bytes, optional
        The site's signing key (:func:`commission.controller_config.load_sign_key`):
        controller.json must carry a valid HMAC-SHA256 signature under it, as
        ``load_controller(path, key=key)`` requires.
    require_signature : bool
        The site exports only signed controllers: without ``key`` the export
        is refused (an unsigned file with a key is refused by the load).
    inputs : sequence of path
        Further files the command read (the key file), which no output may replace.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    InputFileError, SchemaError, UsageError
        A controller the runtime refuses (a bad or missing signature under
        ``key`` included), a provenance string not of its form, a tuning.json
        that is not the one validated, ``pid`` without it, an existing output
        without ``force``, an output folder in use by another process or that
        cannot be written (a full disk); nothing is written.
    """
    if target not in ("c", "st"):
        raise UsageError(f"--target: expected 'c' or 'st', got {target!r}")
    if kind not in TARGETS:
        raise UsageError(f"--controller: expected one of {sorted(TARGETS)}, got {kind!r}")
    if require_signature and key is None:
        raise UsageError(f"--require-signature: no signing key; give --sign-key KEYFILE or set {SIGN_KEY_ENV}")
    cpath = os.fspath(controller_path)
    from commission.runtime import load_controller  # refuse exactly what the runtime refuses

    config = load_controller(cpath, key=key).config
    checked_provenance(config.provenance, cpath)
    tuning, tuning_sha, tpath = _matched_tuning(tuning_path, config, cpath)
    p = _packed_gains(kind, config, tuning)
    names = output_names(kind, target)
    _refuse_dangling_link(out_dir)
    outputs = Outputs(force=force, inputs=(cpath, tpath, *inputs))
    out = outputs.add_dir(out_dir, names, "--out-dir")
    outputs.open()  # locked, and proved writable, before the vectors are simulated
    moving = False
    try:
        files = render(kind, p, config, tuning, tuning_sha, target=target, source=cpath)
        staging = outputs.staging(out)
        for name in names:
            write_text_atomic(staging / name, files[name])
        moving = True
        outputs.commit()
    except OSError as exc:
        outputs.abort()
        if isinstance(exc, CommissionError):
            raise
        what = (f"cannot move the files into place ({exc.strerror or exc}); check {out}" if moving else
                f"cannot write ({exc.strerror or exc}); nothing was written")
        raise UsageError(f"--out-dir {out}: {what}") from None
    except BaseException:
        outputs.abort()  # Ctrl-C, SIGTERM (SystemExit), a bug: the folder stays as it was
        raise
    return [out / name for name in names]


def _matched_tuning(tuning_path: str | os.PathLike[str] | None, config: ControllerConfig,
                    cpath: str) -> tuple[Tuning | None, str | None, str | None]:
    """(tuning, its sha256, its path) of ``--tuning``, refused unless it is the tuning.json ``cpath`` records."""
    tuning = None
    tuning_sha = None
    tpath = None
    if tuning_path is not None:
        tpath = os.fspath(tuning_path)
        tuning = Tuning.from_dict(read_json(tpath), source=tpath)
        tuning_sha = sha256_file(tpath)
        if tuning_sha != config.provenance.tuning_sha256:
            raise UsageError(f"--tuning {tpath}: sha256 {tuning_sha[:16]}... is not the tuning.json "
                             f"{cpath} was validated from ($.provenance.tuning_sha256 "
                             f"{config.provenance.tuning_sha256[:16]}...)")
    return tuning, tuning_sha, tpath


def _packed_gains(kind: str, config: ControllerConfig, tuning: Tuning | None) -> np.ndarray:
    """The packed parameters of ``kind``: the ARC of ``config``, or the PID of ``tuning`` at the same period."""
    if kind == "pid" and tuning is None:
        raise UsageError("--controller pid: needs --tuning (controller.json holds the ARC; the PID baseline "
                         "validate simulated is in the tuning.json it records)")
    if kind == "arc":
        p = arc_pack(config.gains)
    else:
        assert tuning is not None
        if abs(tuning.pid.Ts - config.gains.Ts) > 1e-12 * config.gains.Ts:
            raise UsageError(f"--tuning: PID sample period {tuning.pid.Ts} s differs from the controller's "
                             f"{config.gains.Ts} s")
        p = pid_pack(tuning.pid)
    return p


def _refuse_dangling_link(out_dir: str | os.PathLike[str]) -> None:
    """Refuse an ``--out-dir`` that is a symlink to nothing: whether to create its target or replace the
    link is not for the export to guess (and the final move onto it would fail)."""
    d = Path(out_dir)
    if d.is_symlink() and not d.exists():
        try:
            to = os.readlink(d)
        except OSError:
            to = "?"
        raise UsageError(f"--out-dir {d}: is a symlink to {to}, which does not exist; create that folder "
                         f"or give another --out-dir")


def render(kind: str, p: np.ndarray, config: ControllerConfig, tuning: Tuning | None,
           tuning_sha: str | None, *, target: str = "c", source: str = "controller.json") -> dict[str, str]:
    """File name -> text of the export of the packed controller ``p`` (:func:`export_c` checks the inputs).

    Also safe on its own: no string of ``config`` reaches the text unchecked
    (:mod:`commission.export.text`), whatever checks its loader made; a
    provenance string not of its form is refused (SchemaError naming its JSON
    path in ``source``).
    """
    t = TARGETS[kind]
    if target == "st":
        from commission.export.st_target import st_source

        return {output_names(kind, "st")[0]: st_source(
            t, p, _params_comment(config, kind, p, tuning_sha, lang="st", source=source))}
    banner = _banner(kind)
    return {
        f"{t.base}.h": c_target.header(t, banner),
        f"{t.base}.c": c_target.source(t, banner),
        f"{t.base}_params.c": c_target.params_source(
            t, p, _params_comment(config, kind, p, tuning_sha, lang="c", source=source), banner),
        "test_main.c": c_target.test_main(t, banner),
        VECTORS_NAME: make_vectors(kind, p, config, tuning).csv(),
        "README.md": readme(kind, config, t, tuning is not None),
    }


__all__ = ["export_c", "render", "output_names", "make_vectors", "python_step", "VECTOR_STEPS", "VECTORS_NAME"]