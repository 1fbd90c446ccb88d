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

With ``--choice`` it asks instead whether the *rule* that picks the pole is the lever: for each
axis with a margin-search yardstick, every admissible pole of both placements (M_min and the
identified mass; the grid, and below it only where the model admits none of the grid) within the
gate's c_u is simulated on the tuning scenarios, and the pole with the least summed e_rms over
``<case>/nominal`` and ``<case>/delay+1`` (the scenarios of ``arc_vs_pid_nominal``) is taken per
placement: the best PID of the family on the identified plant, not the fastest.  Printed: the
e_rms profile of the M_min family down the grid (relative to its best; ``!`` outside c_u), and
each placement's best judged on the true plant as above.

Run: ``python benchmarks/yardstick_mass.py DIR [--tune-seed 0] [--choice]``.  Prints figures;
asserts nothing.
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

from commission.controllers.design import KIND_PID
from commission.controllers.pid import pid_pack, pid_place_poles
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


def _best_of_family(ident, spec, ev: Evaluator, at_identified: bool, tune_seed: int):
    """``(best pole, its gains, its summed e_rms, profile)`` of one placement (module docstring), or None.

    ``profile``: ``(pole, summed e_rms, within c_u)`` of every admissible pole, fastest first.
    """
    settings = _baseline.DEFAULT_SETTINGS
    c_u = default_gate_limits(ident, spec).c_u
    ctx = identified_mass_family() if at_identified else contextlib.nullcontext()
    with ctx:
        pids = []
        for fractions in (settings.yardstick_pole_fractions, settings.yardstick_low_fractions):
            poles = [fr * spec.sample_rate for fr in fractions]
            ok = [c for c in _baseline._within_evidence(_baseline.pid_candidates(ident, spec, poles), ident, spec)
                  if c.admissible]
            if ok:
                pids = [(c.pole, _baseline._pid_at(ident, spec, c.pole)) for c in ok]
                break
    if not pids:
        return None
    key = [i for i, n in enumerate(ev.names) if n.endswith("/nominal") or n.endswith("/delay+1")]
    scores = ev.scores(KIND_PID, [pid_pack(g) for _, g in pids])
    prof = sorted(((w, sum(s[i].e_rms for i in key), _baseline._within_c_u(s, c_u), g)
                   for (w, g), s in zip(pids, scores)), key=lambda r: -r[0])
    within = [r for r in prof if r[2]]
    if not within:
        return None
    best = min(within, key=lambda r: r[1])
    return best[0], best[3], best[1], [(w, tot, ok) for w, tot, ok, _ in prof]


def _axes(workdir: pathlib.Path, tune_seed: int, margin_search_only: bool = False):
    """Each axis of a sweep's workdir that has a tuning and a true-plant PID, with what both modes need.

    Yields ``(seed, truth, tuning, true-plant PID, the tool's yardstick on the true plant, the
    evaluator of the tuning scenarios)``; prints a line for each axis it skips.
    """
    for axis in sorted(workdir.glob("axis*"), key=lambda p: int(p.name[4:])):
        seed = int(axis.name[4:])
        tpath = axis / "out" / "tuning.json"
        if not tpath.exists():
            print(f"axis {seed}: no tuning.json (refused before tuning)")
            continue
        t = Tuning.from_dict(json.loads(tpath.read_text()), source=str(tpath))
        method = (t.pid_yardstick or {}).get("method")
        if margin_search_only and method != "margin_search":
            print(f"axis {seed}: yardstick {method}, not a margin search")
            continue
        truth = random_axis(np.random.default_rng(seed))
        ident, spec = t.identification, t.spec
        ref = true_pid(truth, spec, feedforward=Feedforward.identified(ident), noise_seed=tune_seed)
        if not ref.runs:
            print(f"axis {seed}: no true-plant PID keeps the floors")
            continue
        now = tool_yardstick(truth, t.pid, t.pid_pole, spec, noise_seed=tune_seed)
        ev = Evaluator(tuning_scenarios(ident, spec, rng=np.random.default_rng(tune_seed)), spec, workers=1)
        yield seed, truth, t, ref, now, ev


def best_choice(args) -> None:
    """``--choice``: the best pole of each placement on the model, judged on the true plant."""
    for seed, truth, t, ref, now, ev in _axes(args.workdir, args.tune_seed, margin_search_only=True):
        ident, spec = t.identification, t.spec
        line = (f"axis {seed}: true-plant PID {ref.pole:.0f} rad/s | tool {t.pid_pole:.0f} rad/s "
                f"x{now.ratio_to(ref):.3f}{'' if now.ok else ' (NOT ok)'}")
        profile = None
        for at_id, name in ((False, "M_min"), (True, "identified M")):
            got = _best_of_family(ident, spec, ev, at_id, args.tune_seed)
            if got is None:
                line += f" | {name}: none within c_u"
                continue
            w, g, tot, prof = got
            profile = profile or (prof, tot)
            y = tool_yardstick(truth, g, w, spec, noise_seed=args.tune_seed)
            line += (f" | best at {name}: {w:.0f} rad/s, summed e_rms {tot * 1e6:.4g} um on the model, "
                     f"x{y.ratio_to(ref):.3f} on the true plant{'' if y.ok else ' (NOT ok)'}")
        print(line)
        if profile is not None:
            prof, tot = profile
            print("    M_min family on the model, e_rms over its best: " +
                  " ".join(f"{w:.0f}:{x / tot:.2f}{'' if ok else '!'}" for w, x, ok in prof[:12]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=pathlib.Path)
    ap.add_argument("--tune-seed", type=int, default=0)
    ap.add_argument("--choice", action="store_true", help="the best pole of each placement on the model (docstring)")
    args = ap.parse_args()
    if args.choice:
        best_choice(args)
        return
    rows = []
    for seed, truth, t, ref, now, ev in _axes(args.workdir, args.tune_seed):
        ident, spec = t.identification, t.spec
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
