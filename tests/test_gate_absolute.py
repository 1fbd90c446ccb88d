"""Absolute error limits of an axis (issue 30, Build 3): a defaulted limit the best admissible PID cannot
meet on this axis follows that PID (the yardstick) on the same scenario; without any admissible PID the
limits are reported, not gated; safety never moves; a limit the user set in gate.toml never moves.

Driven through :func:`commission.gate.resolve_gate` and :func:`commission.gate.evaluate_gate` with
scores built by hand: the known truth of each case is the score itself (defaults for a 1 um encoder on
the 0.4 m envelope: e_rms 20 um, e_F 40 um, e_M 800 um).
"""

import math

from commission.gate import (ABSOLUTE_FIXED, ABSOLUTE_REPORTED, ABSOLUTE_YARDSTICK, GateSpec, absolute_mode,
                             evaluate_gate, gate_from_mapping, resolve_gate)
from commission.controllers.metrics import Indexes

NAN = math.nan
NOMINAL = frozenset({"case2/nominal"})
#: tuning.json ``pid_yardstick`` records: the fastest PID the floors admit (the first simulated, kept); one
#: whose faster candidates chattered (eight simulated); none admissible.
AT_FLOORS = {"method": "margin_search", "is_yardstick": True, "simulated": 1, "admissible": 11, "pole": 102.0}
SLOWED = {"method": "margin_search", "is_yardstick": True, "simulated": 8, "admissible": 18, "pole": 102.0}
NONE = {"method": "none_admissible", "is_yardstick": False, "simulated": 1, "admissible": 0, "pole": 441.0}


def score(e_rms, e_F=None, e_M=1e-4, c_u=0.1, u_peak=1.0, diverged=False) -> Indexes:
    return Indexes(e_M=e_M, e_F=e_rms if e_F is None else e_F, e_rms=e_rms, u_rms=1.0, du_rms=c_u, c_u=c_u,
                 u_peak=u_peak, diverged=diverged)


def failed(limits, arc, pid, t_abort=NAN):
    v = evaluate_gate(limits, [("case2/nominal", arc, pid, t_abort)], performance=NOMINAL)
    return {c.criterion for c in v.failures}


def test_without_a_yardstick_record_the_defaults_are_fixed_as_before():
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0)
    assert lim.absolute == ABSOLUTE_FIXED and math.isclose(lim.e_rms, 20e-6)
    assert failed(lim, score(58e-6), score(800e-6)) == {"e_rms", "e_F"}


def test_a_default_the_yardstick_cannot_meet_follows_the_yardstick_on_the_same_scenario():
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, yardstick=AT_FLOORS)
    assert lim.absolute == ABSOLUTE_YARDSTICK and set(lim.defaulted) == {"e_F", "e_M", "e_rms"}
    # The ARC at 22 um rms, 65 um final; the yardstick at 33 um and 197 um: the axis's defaults (20, 40 um)
    # ask more than any PID keeping the floors gives, so the yardstick's values are the limits there.
    assert failed(lim, score(22e-6, e_F=65e-6), score(33e-6, e_F=197e-6)) == set()
    # Above the yardstick it still fails, naming the criterion and the yardstick's value.
    v = evaluate_gate(lim, [("case2/nominal", score(40e-6), score(33e-6), NAN)], performance=NOMINAL)
    bad = [c for c in v.failures if c.criterion == "e_rms"]
    assert len(bad) == 1 and math.isclose(bad[0].limit, 33e-6) and "yardstick" in bad[0].detail
    # A yardstick that meets the default does not loosen it: 25 um fails the 20 um default.
    assert "e_rms" in failed(lim, score(25e-6), score(5e-6))
    # A diverged yardstick sets no level: the default holds.
    assert "e_rms" in failed(lim, score(25e-6), score(NAN, diverged=True))


def test_a_limit_the_user_set_never_follows_the_yardstick():
    lim = resolve_gate(gate_from_mapping({"gate": {"e_rms": "20 um"}}), lsb=1e-6, travel=0.4, u_max=10.0,
                       yardstick=AT_FLOORS)
    assert lim.defaulted == ("e_F", "e_M")
    assert failed(lim, score(22e-6, e_F=30e-6), score(33e-6, e_F=197e-6)) == {"e_rms"}


def test_without_an_admissible_yardstick_errors_are_reported_and_safety_stays():
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, yardstick=NONE)
    assert lim.absolute == ABSOLUTE_REPORTED and "reported" in lim.basis["e_rms"]
    assert failed(lim, score(58e-6), score(800e-6)) == set()
    v = evaluate_gate(lim, [("case2/nominal", score(58e-6), score(800e-6), NAN)], performance=NOMINAL)
    row = [c for c in v.checks if c.criterion == "e_rms"][0]
    assert math.isclose(row.value, 58e-6) and "reported" in row.detail
    two = evaluate_gate(lim, [("case1/nominal", score(13e-6), score(800e-6), NAN),
                              ("case2/nominal", score(58e-6), score(800e-6), NAN)],
                        performance={"case1/nominal", "case2/nominal"})
    assert two.worst()["e_rms"].scenario == "case2/nominal"  # the report's worst row: the largest error
    # Safety is never reported only: chattering, a clipped command and divergence still refuse.
    assert failed(lim, score(58e-6, c_u=1.5), score(800e-6)) == {"c_u"}
    assert "u_peak" in failed(lim, score(58e-6, u_peak=10.0), score(800e-6))
    assert "divergence" in failed(lim, score(NAN, diverged=True), score(800e-6), t_abort=0.5)


def test_a_yardstick_slowed_by_its_own_chattering_sets_no_level():
    """Faster PIDs that keep the floors but chatter on the encoder: the PID family's noise, not the axis,
    set the yardstick's level, so the axis's defaults stay (and a record from [pid] pole, or none, too)."""
    assert absolute_mode(AT_FLOORS) == ABSOLUTE_YARDSTICK
    assert absolute_mode(SLOWED) == ABSOLUTE_FIXED
    assert absolute_mode({**AT_FLOORS, "method": "spec_pole"}) == ABSOLUTE_FIXED
    assert absolute_mode(None) == ABSOLUTE_FIXED and absolute_mode(NONE) == ABSOLUTE_REPORTED
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, yardstick=SLOWED)
    assert failed(lim, score(22e-6, e_F=65e-6), score(33e-6, e_F=197e-6)) == {"e_rms", "e_F"}


def _comparison_runs(arc_e, pid_e):
    names = ["case1/nominal", "case1/delay+1", "case2/nominal", "case2/delay+1"]
    return [(n, score(arc_e), score(pid_e), NAN) for n in names]


def test_without_a_yardstick_the_comparison_is_reported_not_gated():
    """No PID of (57) keeps the floors (``none_admissible``): losing to the PID that tune simulated says
    nothing about the machine; the ARC at 1.5 x that PID passes the comparison criteria, which say why."""
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, yardstick=NONE)
    assert set(lim.comparison_reported) == {"arc_vs_pid_median", "arc_vs_pid_p90", "arc_vs_pid_nominal"}
    v = evaluate_gate(lim, _comparison_runs(3e-6, 2e-6), compare_nominal=True)
    comp = [c for c in v.checks if c.criterion.startswith("arc_vs_pid")]
    assert {c.criterion for c in comp} == {"arc_vs_pid_median", "arc_vs_pid_p90", "arc_vs_pid_nominal"}
    assert all(c.passed and math.isinf(c.limit) and "reported, not gated" in c.detail for c in comp)
    assert math.isclose(next(c for c in comp if c.criterion == "arc_vs_pid_nominal").value, 1.5)
    assert "reported, not gated" in lim.basis["arc_vs_pid_median"]
    assert lim.to_dict()["comparison_reported"] == list(lim.comparison_reported)


def test_a_yardstick_or_a_given_limit_keeps_the_comparison_gated():
    """The same runs fail the comparison against a yardstick at the floors, against a ``[pid] pole`` the user
    set (even one that misses the floors), and on a limit gate.toml gives without a yardstick."""
    runs = _comparison_runs(3e-6, 2e-6)
    spec_pole = {"method": "spec_pole", "is_yardstick": False, "simulated": 1, "admissible": 0, "pole": 300.0}
    for ys in (AT_FLOORS, spec_pole):
        lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, yardstick=ys)
        assert lim.comparison_reported == ()
        failed_now = {c.criterion for c in evaluate_gate(lim, runs, compare_nominal=True).failures}
        assert {"arc_vs_pid_median", "arc_vs_pid_p90", "arc_vs_pid_nominal"} <= failed_now
    lim = resolve_gate(gate_from_mapping({"gate": {"arc_vs_pid_nominal": 1.0}}), lsb=1e-6, travel=0.4, u_max=10.0,
                       yardstick=NONE)
    assert lim.comparison_reported == ("arc_vs_pid_median", "arc_vs_pid_p90")
    assert {c.criterion for c in evaluate_gate(lim, runs, compare_nominal=True).failures} == {"arc_vs_pid_nominal"}


def test_the_report_table_says_the_comparison_is_reported():
    from commission.report.tables import gate_table_markdown

    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, yardstick=NONE)
    table = gate_table_markdown(evaluate_gate(lim, _comparison_runs(3e-6, 2e-6), compare_nominal=True))
    rows = [line for line in table.splitlines() if line.startswith("| ARC")]
    assert len(rows) == 3  # median, 90th percentile, identified plant
    assert "| reported (default 1) |" in rows[0] and "| reported (default 1.2) |" in rows[1]
    assert "| reported (default below 1 (no slack)) |" in rows[2]
    assert all("no yardstick" in r for r in rows)
    assert [r.rsplit("|", 2)[1].strip() for r in rows] == ["0 of 1", "0 of 1", "0 of 2"]  # nothing failed
