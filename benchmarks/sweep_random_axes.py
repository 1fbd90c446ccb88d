"""Must-show 2 of issue #4 as a measurement: random axes -> identify -> tune -> validate.

For each seed, :func:`commission.synth.write_random_axis_log` draws an axis the repository
does not contain and simulates its commissioning log; the product then identifies it
(defaults), tunes it (default spec, ``--tune-seed``) and validates the tuning against the
default gate on the full matrix (12 fixed scenarios + 64 Monte-Carlo plants, seed 0).
One line per axis: passed or not, failures by criterion, the first failures, the tune
time, the robustness part of the verdict (one more sample of delay, the mode's variants,
the ARC's stability margins: required since issue 20) and the ARC's smallest delay margin on
the identified plant; then "N of M pass" for the gate and for its robustness part.
Seeds 0-29 are the development set, 100-129 the held-out set (never tuned for).  Refused axes (exit-2 errors) are counted as not passing.

About 20-80 s per axis on 2 cores; a set of 30 seeds takes 17-20 minutes.  Nothing is asserted: the tests run a fixed subset
(``tests/test_tune_random_axes.py``).

Run: ``python benchmarks/sweep_random_axes.py [--seeds 0-29] [--tune-seed 0] [--workdir DIR]``
(``--seeds`` takes ``A-B`` and/or comma lists; ``--workdir`` keeps log.h5, ident.json and
tuning.json of each axis under ``DIR/axisN``).
"""

from __future__ import annotations

import argparse
import collections
import pathlib
import tempfile
import time

from commission.errors import CommissionError
from commission.gate import GateSpec
from commission.identification import identify_log
from commission.jsonio import write_json_atomic
from commission.synth import write_random_axis_log
from commission.tune import run_tune
from commission.validate import validate


def parse_seeds(text: str) -> list[int]:
    """``"0-3,16"`` -> ``[0, 1, 2, 3, 16]``."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def sweep_axis(seed: int, workdir: pathlib.Path, tune_seed: int) -> tuple[bool, str]:
    """Identify, tune and validate random axis ``seed``; ``(passed, one-line summary)``."""
    d = workdir / f"axis{seed}"
    d.mkdir(parents=True, exist_ok=True)
    truth = write_random_axis_log(seed, d / "log.h5")
    head = (f"axis {seed:2d}: {truth.sample_rate / 1e3:g} kHz, M {truth.M:.3g} V s^2/m, "
            f"encoder {truth.lsb * 1e6:.2g} um")
    t0 = time.perf_counter()
    try:
        ident = identify_log(str(d / "log.h5")).ident
        write_json_atomic(d / "ident.json", ident.to_dict())
        tuning = run_tune(d / "ident.json", d / "tuning.json", seed=tune_seed)
    except CommissionError as exc:
        return False, f"{head}: REFUSED ({exc})"
    t_tune = time.perf_counter() - t0
    res = validate(tuning, GateSpec(), seed=0)
    fails = res.verdict.failures
    rob = res.robustness
    if rob is None:
        robust = None
        rob_text = "robustness: not checked"
    elif rob.passed:
        robust = True
        rob_text = "robustness: pass"
    else:
        robust = False
        rb = collections.Counter(f.criterion for f in rob.failures)
        rob_text = f"robustness: FAIL {dict(rb)} ({rob.failures[0].scenario} {rob.failures[0].detail})"
    ROBUST.append(robust)
    dms = [r.margins.delay_margin_samples for r in res.margins if r.controller == "arc" and r.plant == "nominal"]
    rob_text += f"; ARC delay margin {min(dms):.2f} samples" if dms else ""
    if not fails:
        return True, f"{head}: pass (tune {t_tune:.0f} s); {rob_text}"
    by = collections.Counter(f.criterion for f in fails)
    first = "; ".join(f"{f.scenario} {f.criterion} {f.detail}" for f in fails[:2])
    return False, f"{head}: FAIL {len(fails)} {dict(by)} (tune {t_tune:.0f} s); {first}; {rob_text}"


#: Robustness verdict per swept axis (True, False, or None when not checked), in sweep order.
ROBUST: list[bool | None] = []


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-29")
    ap.add_argument("--tune-seed", type=int, default=0)
    ap.add_argument("--workdir", type=pathlib.Path, default=None)
    args = ap.parse_args()
    seeds = parse_seeds(args.seeds)
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.workdir or pathlib.Path(tmp)
        passed = 0
        for seed in seeds:
            ok, line = sweep_axis(seed, workdir, args.tune_seed)
            passed += ok
            print(line, flush=True)
    print(f"{passed} of {len(seeds)} pass validate's default gate")
    checked = [r for r in ROBUST if r is not None]
    print(f"{sum(checked)} of {len(checked)} pass its robustness part (one more sample of delay, the mode's "
          "variants, margin floors)")


if __name__ == "__main__":
    main()
