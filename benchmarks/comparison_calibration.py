"""Does validate's ARC-vs-PID comparison on the model predict the one on the machine? (issue 30)

The gate compares the ARC with the tool's PID yardstick on the identified plant
(``arc_vs_pid_nominal``: per case, the summed e_rms over ``<case>/nominal``, ``<case>/delay+1``
and, for a Coulomb-only fit, ``<case>/stribeck``); `benchmarks/sweep_random_axes.py` calls an
emitted ARC working when each of its four runs on the TRUE axis (Case 1 and Case 2, as logged and
with one more sample of delay) tracks below the true-plant PID's.  For each axis of a sweep's
``--workdir`` whose gains were written (``controller.json``, or ``controller_not_better.json``:
safe but not better) this prints the two side by side, run by run: the model's ARC/yardstick
e_rms ratio (validation.json), and the true axis's ARC/true-plant-PID ratio
(:func:`commission.true_axis.true_runs`, noise seed 0, the PID as the sweep chooses it), with the
case's summed value the gate judged.  The summary counts the runs where the model's per-run
ratio and the true one fall on different sides of 1, and the axes a per-run rule on the model
(each of ``nominal`` and ``delay+1`` below the yardstick) would have refused at the first try.
Nothing in the tool or the sweep changes.

Run: ``python benchmarks/comparison_calibration.py DIR [DIR ...]``.  Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib

import numpy as np

from commission.controllers.arc import arc_pack
from commission.controllers.design import KIND_ARC
from commission.controllers.metrics import SCORE_NAMES, Indexes
from commission.gate.comparison import nominal_comparisons
from commission.runtime import load_controller
from commission.synth import random_axis
from commission.true_axis import Feedforward, true_pid, true_runs
from commission.tuning import Tuning

#: The sweep's four true-axis runs and the validate scenario each mirrors.
RUNS = {("case1", 0.0): "case1/nominal", ("case1", 1.0): "case1/delay+1",
        ("case2", 0.0): "case2/nominal", ("case2", 1.0): "case2/delay+1"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdirs", type=pathlib.Path, nargs="+")
    args = ap.parse_args()
    disagree = total = per_run_refusals = 0
    for workdir in args.workdirs:
        for axis in sorted(workdir.glob("axis*"), key=lambda p: int(p.name[4:])):
            seed = int(axis.name[4:])
            out = axis / "out"
            written = next((out / n for n in ("controller.json", "controller_not_better.json") if (out / n).exists()),
                           None)
            if written is None or not (out / "validation.json").exists():
                print(f"axis {seed}: no gains written")
                continue
            v = json.loads((out / "validation.json").read_text())
            model = {r["name"]: (r["arc"]["e_rms"], r["pid"]["e_rms"]) for r in v["runs"]}
            summed = _summed(v["runs"])
            t = Tuning.from_dict(json.loads((out / "tuning.json").read_text()), source=str(out / "tuning.json"))
            truth = random_axis(np.random.default_rng(seed))
            ref = true_pid(truth, t.spec, feedforward=Feedforward.identified(t.identification))
            if ref.gains is None:
                print(f"axis {seed}: no true-plant PID keeps the floors")
                continue
            gains = load_controller(written).config.gains
            arc = true_runs(truth, KIND_ARC, arc_pack(gains), t.spec)
            cells, refuse = [], False
            for a, p in zip(arc, ref.runs):
                name = RUNS[(a.case, a.extra_delay)]
                ma, mp = model.get(name, (None, None))
                m = ma / mp if ma is not None and mp else float("nan")
                tr = float("inf") if a.diverged else a.e_rms / p.e_rms
                refuse |= m >= 1.0
                if np.isfinite(m):
                    total += 1
                    disagree += (m < 1.0) != (tr < 1.0)
                cells.append(f"{name} {m:.3f}/{tr:.3f}")
            per_run_refusals += refuse and written.name == "controller.json"
            print(f"axis {seed} ({written.name}): model/true per run: {'; '.join(cells)} | gate's summed value per "
                  f"case {', '.join(f'{k} {x:.3f}' for k, x in sorted(summed.items()))}"
                  f"{' | a per-run rule refuses it' if refuse else ''}", flush=True)
    print(f"{total} runs: the model's ARC/yardstick and the true ARC/true-plant-PID fall on different sides of 1 in "
          f"{disagree}; a per-run rule on the model would refuse {per_run_refusals} of the emitted axes at the first try")


def _summed(runs: list[dict]) -> dict[str, float]:
    """Per case, the gate's ``arc_vs_pid_nominal`` value (:func:`commission.gate.comparison.nominal_comparisons`)
    from validation.json's ``runs``."""
    def ix(d: dict) -> Indexes:
        return Indexes(**{k: math.nan if d.get(k) is None else float(d[k]) for k in SCORE_NAMES},
                       diverged=bool(d.get("diverged")))

    return {case: v for case, (v, _rows) in
            nominal_comparisons([(r["name"], ix(r["arc"]), ix(r["pid"])) for r in runs]).items()}


if __name__ == "__main__":
    main()
