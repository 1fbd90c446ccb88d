"""MUST SHOW 1: on the CONTRACT §5 reference plant, the tuned ARC against the paper's hand-set
gains (made implementable) on e_rms, and against the PID on e_M, e_F and e_rms.

Since issue 20 the search keeps the stability margins (delay margin one sample beyond the
identified delay, ...); since issue 30 it compares with the PID yardstick (the comment above
``test_tuned_arc_beats_the_pids``).  Before the margin constraints (the history below) it won them all:
the search chose theta_hat1(0) below the nominal (as the paper did,
30 for 37) together with a higher K2 cap and a faster theta3 adaptation, so the
start-up against the unlearnt payload no longer decides e_M and e_rms.
Measured with seed 0, session 12 (eta filter with y interpolated between samples):
e_rms of Sets 1-3 and Case 2 0.47 / 2.57 / 0.60 / 0.35 um against the paper's
implementable ARC 1.05 / 3.08 / 2.27 / 1.40 um; e_M 5.0 / 107 / 16.5 / 2.6 um against
the tuned PID's 15.4 / 165 / 70.9 / 17.3 and the paper's PID 65.6 / 120 / 77.9 / 17.4 um.
The closest comparison is Set 2's e_M against the paper's PID (0.89x).  The search's objective
compares e_M with the PID's on every tuning scenario
(:func:`commission.tune.cost`): without that term, once the filter fix let it meet
the c_u target with a K2 cap of 1640 instead of 3400, the search chose theta_hat1(0) = 22.7
and lost Set 1's start-up to the tuned PID (e_M 34.6 against 15.4 um, measured in session 11
before the term was added).

The identification is not constructed by hand: the plan ``commission excite`` makes from
sample_data/limits.toml is played on the reference plant (:func:`commission.excite.simulate_plan`,
known truth) and the log identified by the product (:func:`commission.identification.identify_log`,
with the plan's injection windows); the tuning
then runs on that ident.json exactly as ``commission tune`` would.  Scores are
measured on the paper's Table-1 scenarios (:mod:`commission.paper`: Sets 1-3
and Case 2, 2.5 kHz, 1 um encoder), which are independent of the tuning's own
scenario matrix (none of them is a tuning scenario: Set 2's M = 0.1 is not the
box's heaviest 1/theta1_min, and Set 3's step is 0.5 V from 2.2 s).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from commission import paper
from commission.controllers.arc import arc_pack, paper_gains_implementable
from commission.controllers.pid import pid_pack
from commission.controllers.simulate import KIND_ARC, KIND_PID, simulate
from commission.identification import BoundsOptions, identify_log
from commission.jsonio import write_json_atomic
from commission.tune.settings import DEFAULT_SETTINGS
from commission.excite import load_excite_spec, plan_run, simulate_plan
from commission.synth import AxisTruth, write_log_h5
from commission.tune.api import run_tune

#: Issue 30 (open).  The log is recorded as the tool tells users to record it: the plan `commission
#: excite` makes from sample_data/limits.toml (friction ladder, moves, broadband injection), played on
#: the rigid reference plant, so that the evidence backs the model to about 520 Hz and does not cap
#: the loop (a rigid log without broadband content backs only tens of hertz; the evidence tests cover
#: that case).  Measured (seed 0, docs/robustness.md "Table 1"): the tuned ARC beats the paper's
#: PID(-300) on every index of Sets 1 and 3 and Case 2 and on Set 2's e_F, but not on Set 2's e_M
#: (198 against 120 um: the start-up with the 3.7x payload theta_hat has not learnt) nor its e_rms
#: (6.7 against 5.8 um); it loses e_M and e_rms to the yardstick in all four.  Not strict: the design
#: checks and the robustness test pass.
pytestmark = [pytest.mark.slow,
              pytest.mark.xfail(strict=False, reason="issue 30 open: Table 1 on the reference plant: Set 2's payload "
                                                "start-up (e_M 198 vs the paper's PID 120 um) and the PID yardstick "
                                                "(e_M, e_rms) beat the tuned ARC")]

#: The payload of Table 1's Set 2 (M = 0.1 V s^2/m on the 0.027 axis), stated to identify, V s^2/m.
SET2_PAYLOAD = 0.1 - 0.027 + 0.005

#: The reference axis's limits, as the sample's plan is made from them (CONTRACT §5).
LIMITS = Path(__file__).resolve().parents[1] / "sample_data" / "limits.toml"

REFERENCE = AxisTruth(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.0, ripple_amp=0.01,
                      ripple_pitch=0.03, lsb=1e-6, sample_rate=2500.0, u_unit="V", noise_std=0.0, u_max=10.0)


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    d = tmp_path_factory.mktemp("reference")
    plan = plan_run(load_excite_spec(LIMITS))
    write_log_h5(d / "log.h5", simulate_plan(plan, REFERENCE, np.random.default_rng(2001)))
    # Table 1's Set 2 carries M = 0.1 (3.7 x the axis): the payload is stated, as a user who knows the
    # loads does, so that the box covers it (a defaulted payload range is narrowed to what the gains certify).
    ident = identify_log(str(d / "log.h5"), bounds=BoundsOptions(payload_max=SET2_PAYLOAD), plan=plan.to_dict(),
                         plan_path="plan.json").ident
    write_json_atomic(d / "ident.json", ident.to_dict())
    return run_tune(d / "ident.json", d / "tuning.json", seed=0)


def _run(name: str, kind: int, p: np.ndarray):
    sc = paper.scenario(name)
    r = simulate(sc.plant_p, kind, p, sc.traj, substeps=paper.SUBSTEPS, quant=paper.QUANT,
                 disturbance=sc.disturbance, y0=sc.y0, u_sat=10.0)
    assert not r.diverged, (name, kind)
    return r.indexes


@pytest.fixture(scope="module")
def table(tuned):
    ctrls = {"tuned": (KIND_ARC, arc_pack(tuned.arc)),
             "paper_arc": (KIND_ARC, arc_pack(paper_gains_implementable())),
             "paper_pid": paper.paper_controller("PID"),
             "tuned_pid": (KIND_PID, pid_pack(tuned.pid))}
    return {s: {c: _run(s, *kp) for c, kp in ctrls.items()} for s in paper.SCENARIOS}


def test_identified_reference_is_close_to_the_truth(tuned):
    ident = tuned.identification
    assert ident.value("M") == pytest.approx(0.027, rel=0.05)
    assert ident.theta.min[0] <= 10.0 <= ident.theta.max[0]  # Set 2's payload is inside the box
    assert tuned.spec.sample_rate == pytest.approx(2500.0)


def test_design_checks_hold(tuned):
    # the defaulted observer pole (200 rad/s) is a coordinate of the search, within its bounds
    lo, hi = DEFAULT_SETTINGS.observer_factor_bounds
    assert 200.0 * lo <= tuned.observer.pole <= 200.0 * hi
    assert tuned.observer.k1 == pytest.approx(2 * tuned.observer.pole)
    assert tuned.observer.k2 == pytest.approx(tuned.observer.pole ** 2)
    assert tuned.theorem1.holds
    assert tuned.feasibility["arc"].holds
    assert tuned.guarantees["sampled_data_stability"].holds


#: The tuned PID is the yardstick (issue 30): the fastest PID of (57) that keeps the margin floors on
#: the identified plant and +1 sample, and robust stability above the band the log backs.  The
#: reference log holds no broadband content, so that bound holds both loops to a few tens of hertz:
#: the tuned ARC beats the yardstick on every index, but not the paper's PID(-300), which no bound
#: holds (the module's expected failure).
@pytest.mark.parametrize("scenario", paper.SCENARIOS)
def test_tuned_arc_beats_the_papers_gains_on_e_rms(table, scenario):
    row = table[scenario]
    assert row["tuned"].e_rms < row["paper_arc"].e_rms


@pytest.mark.parametrize("scenario,pid,index", [
    (s, p, i)
    for s in paper.SCENARIOS for p in ("tuned_pid", "paper_pid") for i in ("e_M", "e_F", "e_rms")])
def test_tuned_arc_beats_the_pids(table, scenario, pid, index):
    row = table[scenario]
    assert getattr(row["tuned"], index) < getattr(row[pid], index)


def test_theta_hat1_0_is_chosen_inside_the_box_at_or_below_the_nominal(tuned):
    ident = tuned.identification
    th10 = tuned.arc.theta0[0]
    assert ident.theta.min[0] <= th10 <= ident.theta.nominal[0]
    assert tuned.arc.theta0[1:] == tuple(ident.theta.nominal[1:])


def test_tuned_arc_is_robust_where_the_hand_set_gains_are_not(tuned):
    """The tuning must hold over the whole theta box, which the hand-set gains do not.

    On the 16 box corners of the tuning set (heaviest/lightest mass x viscous x
    disturbance force, both trajectories) the paper's gains made implementable
    are worse in the worst case than the tuned ones (measured: they lose the
    heavy-mass Case-2 corners, e_rms ~1.8 mm, while the tuned ARC stays within 25 um).
    """
    import dataclasses

    from commission.scenarios import corner_scenarios

    ident, spec = tuned.identification, tuned.spec
    impl = dataclasses.replace(paper_gains_implementable(spec.period), theta_min=ident.theta.min,
                               theta_max=ident.theta.max)
    worst = {}
    for name, g in (("tuned", tuned.arc), ("paper", impl)):
        e = []
        for s in corner_scenarios(ident, spec):
            r = simulate(s.plant, KIND_ARC, arc_pack(g), s.reference(spec.period), quant=s.quantization,
                         u_sat=spec.u_max, e_abort=spec.travel)
            e.append(float("inf") if r.diverged else r.indexes.e_rms)
        worst[name] = max(e)
    assert worst["tuned"] < 25e-6
    assert worst["tuned"] < worst["paper"]


def test_chattering_stays_within_the_gate(table):
    # commission.gate's default c_u limit is 1.0; the paper's ARC measured 0.19-0.32.
    assert all(row["tuned"].c_u < 1.0 for row in table.values())
