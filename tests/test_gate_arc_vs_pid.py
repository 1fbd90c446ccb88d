"""The ARC must beat the PID yardstick on the identified plant (gate criterion ``arc_vs_pid_nominal``, issue 30).

Dev axis 25 of the issue-30 sweep: emitted, safe, but 1.21 x a true-plant PID's e_rms on its true
plant.  On its identified plant the ARC already lost to the yardstick in Case 2 (0.74 vs 0.61 LSB
nominal, 0.76 vs 0.71 LSB with one more sample of delay), within the quantiles' slack.  Its figures
below are the ones its validation.json recorded; axis 14's are a working axis's (0.80 of a true-plant
PID), which loses by 0.04 LSB in one run and wins each case as a whole.
"""

import math

import pytest

from commission.errors import SpecError
from commission.gate import (GateSpec, arc_vs_pid_nominal_checks, evaluate_gate, gate_from_mapping, resolve_gate,
                             safe_not_better)
from commission.controllers.metrics import Indexes

NAN = math.nan


def score(e_rms, diverged=False):
    return Indexes(e_M=10 * e_rms, e_F=2 * e_rms, e_rms=e_rms, u_rms=0.5, du_rms=0.2, c_u=0.4, u_peak=2.0,
                 diverged=diverged)


def runs_of(lsb, table):
    """``table``: scenario -> (ARC e_rms, PID e_rms) in LSB."""
    return [(name, score(a * lsb), score(p * lsb), NAN) for name, (a, p) in table.items()]


AXIS25 = {"case1/nominal": (0.66, 0.63), "case1/delay+1": (0.70, 0.79),
          "case2/nominal": (0.74, 0.61), "case2/delay+1": (0.76, 0.71)}
AXIS14 = {"case1/nominal": (1.31, 1.26), "case1/delay+1": (1.35, 1.55),
          "case2/nominal": (1.06, 1.12), "case2/delay+1": (1.05, 1.26)}


def limits(lsb, **kw):
    return resolve_gate(GateSpec(**kw), lsb=lsb, travel=0.3, u_max=10.0)


def test_axis25_is_safe_but_not_better_and_says_where():
    lsb = 0.78e-6
    v = evaluate_gate(limits(lsb), runs_of(lsb, AXIS25), compare_nominal=True)
    checks = {c.scenario: c for c in v.checks if c.criterion == "arc_vs_pid_nominal"}
    assert set(checks) == {"case1", "case2"}
    assert checks["case1"].passed and checks["case1"].value == pytest.approx((0.66 + 0.70) / (0.63 + 0.79))
    c2 = checks["case2"]
    assert not c2.passed and c2.value == pytest.approx((0.74 + 0.76) / (0.61 + 0.71)) and c2.limit == 1.0
    assert "a tie there is not a win" in c2.detail and "case2/nominal" in c2.detail
    # the quantiles (with their slack) let it through; the verdict is "safe, but not better", not a silent refusal
    assert [c.criterion for c in v.failures] == ["arc_vs_pid_nominal"]
    assert safe_not_better(v)


def test_a_loss_within_one_run_is_not_a_refusal_when_the_case_is_won():
    lsb = 0.06e-6
    cs = arc_vs_pid_nominal_checks(limits(lsb), runs_of(lsb, AXIS14))
    assert [c.passed for c in cs] == [True, True]
    assert cs[0].value == pytest.approx((1.31 + 1.35) / (1.26 + 1.55))


def test_a_tie_is_not_a_win_and_the_limit_is_the_gate_tomls():
    lsb = 1e-6
    tie = {"case1/nominal": (0.3, 0.3), "case2/nominal": (0.29, 0.3)}
    cs = arc_vs_pid_nominal_checks(limits(lsb), runs_of(lsb, tie))
    assert [c.passed for c in cs] == [False, True]
    loose = gate_from_mapping({"gate": {"arc_vs_pid_nominal": 1.05}}, "g.toml")
    assert all(c.passed for c in arc_vs_pid_nominal_checks(resolve_gate(loose, lsb=lsb, travel=0.3, u_max=10.0),
                                                         runs_of(lsb, tie)))
    with pytest.raises(SpecError, match="arc_vs_pid_nominal"):
        gate_from_mapping({"gate": {"arc_vs_pid_nominal": -1}}, "g.toml")


def test_divergence_and_scenarios_outside_the_identified_plant():
    lsb = 1e-6
    lim = limits(lsb)
    runs = [("case1/nominal", score(1e-6, diverged=True), score(1e-6), NAN),
            ("case2/nominal", score(2e-6), score(NAN, diverged=True), NAN),
            ("case2/delay+1", score(2e-6), score(3e-6), NAN),
            ("case2/payload_heavy", score(9e-6), score(1e-6), NAN),
            ("mc/000", score(9e-6), score(1e-6), NAN)]
    cs = {c.scenario: c for c in arc_vs_pid_nominal_checks(lim, runs)}
    assert cs["case1"].value == math.inf and not cs["case1"].passed
    # the PID's divergence leaves its run out; the payload corner and the Monte-Carlo plant are not the identified plant
    assert cs["case2"].value == pytest.approx(2.0 / 3.0) and cs["case2"].passed
    # tune's objective does not ask for it
    assert not [c for c in evaluate_gate(lim, runs).checks if c.criterion == "arc_vs_pid_nominal"]


def test_the_rise_the_log_could_not_show_is_part_of_the_identified_plant():
    """``<case>/stribeck`` (a Coulomb-only fit's robustness variant) joins nominal and delay+1 in the sum:
    held-out axis 905's ARC beat its yardstick as identified and lost on the true axis through the
    Stribeck rise its fit had dropped; an ARC that wins only without the rise is not certified better."""
    lsb = 1e-6
    table = {"case1/nominal": (1.0, 1.5), "case1/delay+1": (1.1, 1.6), "case1/stribeck": (6.0, 3.0),
             "case2/nominal": (1.0, 1.5), "case2/delay+1": (1.1, 1.6), "case2/stribeck": (2.0, 3.0)}
    cs = {c.scenario: c for c in arc_vs_pid_nominal_checks(limits(lsb), runs_of(lsb, table))}
    assert cs["case1"].value == pytest.approx((1.0 + 1.1 + 6.0) / (1.5 + 1.6 + 3.0)) and not cs["case1"].passed
    assert cs["case2"].value == pytest.approx((1.0 + 1.1 + 2.0) / (1.5 + 1.6 + 3.0)) and cs["case2"].passed
    # without the variant the same case would have been won
    no_rise = {k: v for k, v in table.items() if not k.endswith("/stribeck")}
    assert all(c.passed for c in arc_vs_pid_nominal_checks(limits(lsb), runs_of(lsb, no_rise)))
