"""Which random axes ``commission run`` refuses before tuning, and why: the cheap part of a sweep.

A refusal before tuning (an exit-2 error from identification or from the spec resolved against the
identified axis) leaves no candidate to judge, and on an axis where a PID works it costs the user as
much as a false refusal (issue 30).  The full sweep (``sweep_random_axes.py``) spends a minute or more
per axis to find them; the refusal itself takes seconds.  For each seed this records the axis as the
sweep does (:func:`commission.synth.record_random_axis_log`, ``--log excite``), identifies the log
(:func:`commission.identification.identify_log`, ``run``'s defaults) and resolves the spec as ``run``
does (:func:`commission.tune.resolve_spec`, the axis's rail written to spec.toml as
:func:`commission.true_axis.judge_axis` writes it), and prints one line per axis: ``ok`` (tuning would
start), or the refusal's first 400 characters.  For a refused axis, whether the true-plant PID of the
sweep exists (:func:`commission.true_axis.true_pid`: a working controller the refusal forgoes).

Run: ``python benchmarks/refusals_before_tuning.py --seeds 30-99 [--workers 2] [--workdir DIR]``
(``--workdir`` keeps each axis's log.h5, ident.json and spec.toml under ``DIR/axisN``).  Prints
figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from sweep_random_axes import describe, parse_seeds  # noqa: E402


def prescreen_axis(seed: int, workdir: str) -> tuple[int, str, str]:
    """``(seed, line, outcome)``; outcome ``"ok"``, ``"refused"`` or ``"refused (a true-plant PID works)"``."""
    from commission.artifacts import Identification
    from commission.errors import CommissionError
    from commission.identification import identify_log
    from commission.jsonio import canonical_json
    from commission.spec import Spec, read_spec_toml, spec_from_mapping
    from commission.synth import record_random_axis_log
    from commission.true_axis import true_pid
    from commission.tune import resolve_spec

    d = pathlib.Path(workdir) / f"axis{seed}"
    d.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rec = record_random_axis_log(seed, d / "log.h5", log="excite")
    truth = rec.truth
    spec_path = None
    if truth.u_max != next(f.default for f in dataclasses.fields(Spec) if f.name == "u_max"):
        spec_path = d / "spec.toml"
        spec_path.write_text(f"[controller]\nu_max = {truth.u_max!r}\n")
    try:
        out = identify_log(str(d / "log.h5"))
        doc = out.ident.to_dict()
        (d / "ident.json").write_text(canonical_json(doc))
        ident = Identification.from_dict(json.loads(canonical_json(doc)), source=str(d / "ident.json"))
        spec_data, spec_src = read_spec_toml(spec_path)
        resolve_spec(spec_data, spec_src, ident)
        outcome, text = "ok", "ok"
    except CommissionError as exc:
        data = {"controller": {"u_max": truth.u_max}} if spec_path is not None else {}
        pid = true_pid(truth, spec_from_mapping(data, "spec.toml", sample_rate_default=truth.sample_rate))
        works = pid.gains is not None
        outcome = "refused (a true-plant PID works)" if works else "refused"
        text = (f"REFUSED {type(exc).__name__}: {str(exc)[:400]} | "
                + (f"true-plant PID {pid.pole:.0f} rad/s works" if works else "no true-plant PID keeps the floors"))
    return seed, f"axis {seed:3d}: {describe(truth)} | {text} | {time.perf_counter() - t0:.0f} s", outcome


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-29")
    ap.add_argument("--workers", type=int, default=1, help="axes in parallel processes (default 1)")
    ap.add_argument("--workdir", type=pathlib.Path, default=None)
    args = ap.parse_args()
    seeds = parse_seeds(args.seeds)
    t0 = time.perf_counter()
    outcomes = []
    with tempfile.TemporaryDirectory() as tmp:
        workdir = str(args.workdir or tmp)
        with ProcessPoolExecutor(max_workers=max(1, args.workers)) as ex:
            for _, line, outcome in ex.map(prescreen_axis, seeds, [workdir] * len(seeds)):
                outcomes.append(outcome)
                print(line, flush=True)
    refused = [o for o in outcomes if o != "ok"]
    print(f"{len(refused)} of {len(outcomes)} axes refused before tuning; on "
          f"{sum(o.endswith('works)') for o in refused)} of them a true-plant PID works; "
          f"{time.perf_counter() - t0:.0f} s wall ({args.workers} worker(s))")


if __name__ == "__main__":
    main()
