"""The PID yardstick's design mass, judged on the TRUE axes of a random-axis sweep (issue 30).

The tool's yardstick (:func:`commission.tune.baseline.pid_yardstick`) is the fastest PID of the
paper's (57) that keeps the margin floors on the identified plant, is stable with one more sample
of delay, holds the evidence bound and stays within c_u on the tuning scenarios; the family places
its triple pole for the box's lightest mass ``M_min = 1/theta1_max`` (the paper's design,
:func:`commission.tune.baseline.pid_baseline`).  The sweep's yardstick
(:func:`commission.true_axis.true_pid`) places the pole for the TRUE mass.  Where ``M_min`` sits
well below the axis's mass (a mass range of the box), the tool's PID at a given pole has the loop
of a slower one, and an ARC that beats it may lose to the PID a drive's auto-tuner would set
from the identified inertia: a false certification (held-out 1004, docs/robustness.md).

For each axis of a sweep's ``--workdir`` (``axisN/log.h5`` and ``axisN/out/tuning.json``), this
prints the true-plant PID's pole, then the tool's yardstick as tuned (pole, floors and runs on the
true plant, worst e_rms over the true-plant PID's, :func:`commission.true_axis.tool_yardstick`)
and the same search with the family's pole placed for the **identified** mass instead (the
evaluator of the tuning scenarios rebuilt as ``tune`` builds it, seed ``--tune-seed``): what a
yardstick "at the identified mass" would have been, judged the same way.  Nothing in the tool
changes; the second yardstick is computed here by swapping the family's design mass for the
duration of the call.  Axes refused before tuning are listed as such.

Run: ``python benchmarks/yardstick_mass.py DIR [--tune-seed 0]``.  Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import pathlib
import statistics

import numpy as np

from commission.controllers.pid import pid_place_poles
from commission.scenarios import tuning_scenarios
from commission.synth import random_axis
from commission.true_axis import Feedforward, tool_yardstick, true_pid
from commission.tune import baseline as _baseline
from commission.tune.objective import Evaluator
from commission.tune.defaults import default_gate_limits
from commission.tuning import Tuning


@contextlib.contextmanager
def identified_mass_family():
    """The yardstick family of (57) with its pole placed for the identified mass, not ``M_min``."""
    original = _baseline.pid_baseline

    def at_identified_mass(ident, spec):
        g, _ = original(ident, spec)
        m = ident.value("M")
        kp, ki, kd = pid_place_poles(m, -spec.pid_pole)
        return dataclasses.replace(g, Kp=kp, Ki=ki, Kd=kd), m

    _baseline.pid_baseline = at_identified_mass
    try:
        yield
    finally:
        _baseline.pid_baseline = original


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=pathlib.Path)
    ap.add_argument("--tune-seed", type=int, default=0)
    args = ap.parse_args()
    rows = []
    for axis in sorted(args.workdir.glob("axis*"), key=lambda p: int(p.name[4:])):
        seed = int(axis.name[4:])
        tpath = axis / "out" / "tuning.json"
        if not tpath.exists():
            print(f"axis {seed}: no tuning.json (refused before tuning)")
            continue
        truth = random_axis(np.random.default_rng(seed))
        t = Tuning.from_dict(json.loads(tpath.read_text()), source=str(tpath))
        ident, spec = t.identification, t.spec
        ref = true_pid(truth, spec, feedforward=Feedforward.identified(ident), noise_seed=args.tune_seed)
        if not ref.runs:
            print(f"axis {seed}: no true-plant PID keeps the floors")
            continue
        now = tool_yardstick(truth, t.pid, t.pid_pole, spec, noise_seed=args.tune_seed)
        ev = Evaluator(tuning_scenarios(ident, spec, rng=np.random.default_rng(args.tune_seed)), spec, workers=1)
        with identified_mass_family():
            base, choice = _baseline.pid_yardstick(ident, spec, ev, default_gate_limits(ident, spec).c_u, True)
        alt = tool_yardstick(truth, base.gains, base.pole, spec, noise_seed=args.tune_seed)
        m_min = 1.0 / ident.theta.max[0]
        r_now, r_alt = now.ratio_to(ref), alt.ratio_to(ref)
        rows.append((r_now, r_alt))
        print(f"axis {seed}: M true {truth.M:.4g}, identified {ident.value('M'):.4g}, M_min {m_min:.4g} "
              f"(u-unit s^2/m); true-plant PID {ref.pole:.0f} rad/s | yardstick at M_min {t.pid_pole:.0f} rad/s: "
              f"{'ok' if now.ok else 'NOT ok'} on the true plant, e_rms x{r_now:.3f} of the true-plant PID's | "
              f"at the identified mass {base.pole:.0f} rad/s ({choice.method}): {'ok' if alt.ok else 'NOT ok'}, "
              f"x{r_alt:.3f}")
    if rows:
        fin = [(a, b) for a, b in rows if math.isfinite(a) and math.isfinite(b)]
        print(f"{len(rows)} axes; median e_rms over the true-plant PID's: at M_min "
              f"{statistics.median(a for a, _ in fin):.3f}, at the identified mass {statistics.median(b for _, b in fin):.3f}; "
              f"weaker than the true-plant PID by more than 10 %: {sum(a > 1.1 for a, _ in fin)} and "
              f"{sum(b > 1.1 for _, b in fin)} of {len(fin)}")


if __name__ == "__main__":
    main()
