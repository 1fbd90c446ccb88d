"""How far one encoder-noise realisation decides a random-axis sweep's verdict (issue 30).

`benchmarks/sweep_random_axes.py` judges each emitted controller on the TRUE axis with one
encoder-noise realisation (:func:`commission.true_axis.true_runs`, ``noise_seed`` 0): four runs
(Case 1 and Case 2, as logged and with one more sample of delay), and the axis *works* when each
run's e_rms is below the true-plant PID's in the same run.  On an axis whose error sits a few
encoder counts above its noise, that comparison moves with the realisation.  For each emitted
axis of a sweep's ``--workdir`` (``axisN/out/controller.json`` and ``tuning.json``) this re-judges
the same gains against the same true-plant PID (its pole chosen as the sweep chooses it, seed 0)
over ``--noise-seeds`` realisations and prints, per axis: the worst-run ARC/PID ratio of each
realisation, how many realisations call it working, and the ratio of the per-run medians (the
judgement of the median realisation, :func:`commission.true_axis.median_ratio`, as the sweep
prints it over its ``--noise-draws``).  Nothing in the tool or the sweep changes.

Run: ``python benchmarks/judge_noise.py DIR [--noise-seeds 6]``.  Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import statistics

import numpy as np

from commission.controllers.arc import arc_pack
from commission.controllers.design import KIND_ARC, KIND_PID
from commission.controllers.pid import pid_pack
from commission.runtime import load_controller
from commission.synth import random_axis
from commission.true_axis import Feedforward, median_ratio, runs_beat, true_pid, true_runs, worst_ratio
from commission.tuning import Tuning


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=pathlib.Path)
    ap.add_argument("--noise-seeds", type=int, default=6)
    args = ap.parse_args()
    flips = judged = 0
    for axis in sorted(args.workdir.glob("axis*"), key=lambda p: int(p.name[4:])):
        seed = int(axis.name[4:])
        ctrl_path, tpath = axis / "out" / "controller.json", axis / "out" / "tuning.json"
        if not ctrl_path.exists() or not tpath.exists():
            print(f"axis {seed}: not emitted")
            continue
        truth = random_axis(np.random.default_rng(seed))
        t = Tuning.from_dict(json.loads(tpath.read_text()), source=str(tpath))
        spec = t.spec
        gains = load_controller(ctrl_path).config.gains
        ref = true_pid(truth, spec, feedforward=Feedforward.identified(t.identification), noise_seed=0)
        if ref.gains is None:
            print(f"axis {seed}: no true-plant PID keeps the floors")
            continue
        ratios, works, arcs, pids = [], 0, [], []
        for ns in range(args.noise_seeds):
            a = true_runs(truth, KIND_ARC, arc_pack(gains), spec, noise_seed=ns)
            p = true_runs(truth, KIND_PID, pid_pack(ref.gains), spec, noise_seed=ns)
            ratios.append(worst_ratio(a, p))
            works += runs_beat(a, p)
            arcs.append(a)
            pids.append(p)
        med = median_ratio(arcs, pids)
        judged += 1
        flips += 0 < works < args.noise_seeds
        print(f"axis {seed}: worst-run ARC/PID per realisation "
              f"{' '.join(f'{r:.3f}' for r in ratios)} | works in {works} of {args.noise_seeds} | "
              f"median realisation {med:.3f} (spread {min(ratios):.3f}-{max(ratios):.3f}, "
              f"median {statistics.median(ratios):.3f})", flush=True)
    print(f"{judged} emitted axes judged; the verdict depends on the realisation on {flips}")


if __name__ == "__main__":
    main()
