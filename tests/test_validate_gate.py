"""The validation gate: TOML parsing, documented defaults, and the checks it makes."""

import dataclasses
import math

import numpy as np
import pytest

from commission.errors import InputFileError, SpecError
from commission.gate import (
    required_factor,
    CRITERIA,
    DEFAULT_C_U,
    GateSpec,
    evaluate_gate,
    gate_from_mapping,
    load_gate,
    resolve_gate,
)
from commission.controllers.metrics import Indexes

NAN = math.nan


def score(e_M=50e-6, e_F=5e-6, e_rms=2e-6, c_u=0.3, u_peak=1.0, diverged=False, u_rms=0.2, du_rms=0.06):
    return Indexes(e_M, e_F, e_rms, u_rms, du_rms, c_u, u_peak, diverged)


def test_defaults_on_the_paper_axis_are_the_documented_formulas():
    # 1 um encoder, 0.4 m travel (the paper's envelope): the travel terms dominate.
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0)
    assert lim.e_F == pytest.approx(max(30 * 1e-6, 1e-4 * 0.4))  # 40 um
    assert lim.e_M == pytest.approx(max(200 * 1e-6, 2e-3 * 0.4))  # 800 um
    assert lim.e_rms == pytest.approx(max(15 * 1e-6, 5e-5 * 0.4))  # 20 um
    assert lim.c_u == DEFAULT_C_U == 1.0
    assert lim.u_max == 10.0 and lim.no_divergence and lim.arc_vs_pid_e_rms == 1.0
    assert "default" in lim.basis["e_F"] and "LSB" in lim.basis["e_F"]


def test_defaults_follow_the_encoder_on_a_short_coarse_axis():
    # 10 um encoder on a 20 mm stroke: the LSB terms dominate.
    lim = resolve_gate(GateSpec(), lsb=10e-6, travel=0.02, u_max=5.0)
    assert lim.e_F == pytest.approx(300e-6)
    assert lim.e_M == pytest.approx(2000e-6)
    assert lim.e_rms == pytest.approx(150e-6)
    assert lim.u_max == 5.0


@pytest.mark.parametrize(
    "text, expected",
    [
        ("20 um", 20e-6),
        ("20um", 20e-6),
        ("0.02 mm", 20e-6),
        ("20000 nm", 20e-6),
        ("2e-5 m", 2e-5),
        ("20 lsb", 20 * 0.5e-6),
        ("0.005 %travel", 0.005e-2 * 0.4),
        (3e-5, 3e-5),
    ],
)
def test_error_limit_units(text, expected):
    g = gate_from_mapping({"gate": {"e_rms": text}}, "g.toml")
    lim = resolve_gate(g, lsb=0.5e-6, travel=0.4, u_max=10.0)
    assert lim.e_rms == pytest.approx(expected, rel=1e-12)
    assert lim.basis["e_rms"].startswith("g.toml")


def test_every_key_overrides_its_default():
    g = gate_from_mapping({"gate": {"e_F": "5 um", "e_M": "50 um", "e_rms": "2 um", "c_u": 0.4, "u_max": 3.0,
                                    "no_divergence": False, "arc_vs_pid_e_rms": 1.5}})
    lim = resolve_gate(g, lsb=1e-6, travel=0.4, u_max=10.0)
    assert (lim.e_F, lim.e_M, lim.e_rms) == pytest.approx((5e-6, 50e-6, 2e-6))
    assert (lim.c_u, lim.u_max, lim.no_divergence, lim.arc_vs_pid_e_rms) == (0.4, 3.0, False, 1.5)


@pytest.mark.parametrize(
    "doc, match",
    [
        ({"gate": {"e_F": -1.0}}, r"gate\.e_F = -1\.0: must be a positive"),
        ({"gate": {"e_M": "12 furlongs"}}, r"gate\.e_M = '12 furlongs': expected \"<number> <unit>\""),
        ({"gate": {"e_rms": True}}, r"gate\.e_rms = True"),
        ({"gate": {"c_u": "low"}}, r"gate\.c_u = 'low': expected a positive finite number"),
        ({"gate": {"u_max": 0}}, r"gate\.u_max = 0: expected a positive finite number in u-unit"),
        ({"gate": {"no_divergence": "yes"}}, r"gate\.no_divergence = 'yes': expected true or false"),
        ({"gate": {"arc_vs_pid_e_rms": -2}}, r"gate\.arc_vs_pid_e_rms = -2"),
        ({"gate": {"e_max": 1e-5}}, r"gate\.e_max: unknown key \(known: e_F, e_M"),
        ({"gates": {}}, r"gates: unknown section"),
        ({"gate": 3}, r"gate: expected a table"),
    ],
)
def test_bad_gate_names_the_key(doc, match):
    with pytest.raises(SpecError, match=match):
        gate_from_mapping(doc, "gate.toml")


def test_load_gate_file_errors(tmp_path):
    with pytest.raises(InputFileError, match="no such file"):
        load_gate(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[gate\ne_F = 1")
    with pytest.raises(SpecError, match="bad.toml: not valid TOML"):
        load_gate(bad)
    good = tmp_path / "good.toml"
    good.write_text('[gate]\ne_F = "12 um"\n')
    assert resolve_gate(load_gate(good), lsb=1e-6, travel=0.4, u_max=10).e_F == pytest.approx(12e-6)
    assert load_gate(None) == GateSpec()


def test_lsb_limit_needs_an_encoder_resolution():
    g = gate_from_mapping({"gate": {"e_F": "10 lsb"}}, "g.toml")
    with pytest.raises(SpecError, match=r"g\.toml: gate\.e_F = '10 lsb': the tuning has no encoder quantization"):
        resolve_gate(g, lsb=0.0, travel=0.4, u_max=10.0)


def test_a_good_run_passes_every_criterion():
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0)
    v = evaluate_gate(lim, [("case1/nominal", score(), score(e_rms=3e-6), NAN)], compare_nominal=True)
    assert v.passed and not v.failures
    # every criterion of a scenario run; the margins are checked per loop (margin_checks), not per run;
    # by default the ARC-vs-PID comparison is judged by quantiles per group, scenario by scenario on request
    assert [c.criterion for c in v.checks] == [c for c in CRITERIA if c not in ("margins", "margins_box", "arc_vs_pid_e_rms")]
    every = resolve_gate(GateSpec(arc_vs_pid_e_rms=1.0), lsb=1e-6, travel=0.4, u_max=10.0)
    v = evaluate_gate(every, [("case1/nominal", score(), score(e_rms=3e-6), NAN)], compare_nominal=True)
    assert [c.criterion for c in v.checks] == [c for c in CRITERIA if c not in ("margins", "margins_box")]


def test_every_failure_is_listed_with_scenario_and_value():
    lim = resolve_gate(GateSpec(arc_vs_pid_e_rms=1.0), lsb=1e-6, travel=0.4, u_max=10.0)
    runs = [
        ("case1/nominal", score(), score(e_rms=3e-6), NAN),  # passes
        ("case1/payload_heavy", score(e_F=41e-6, e_M=801e-6, e_rms=21e-6, c_u=1.2), score(e_rms=30e-6), NAN),
        ("case2/nominal", score(u_peak=10.0), score(e_rms=1e-6), NAN),  # saturated, and worse than PID
        ("mc/007", score(diverged=True, e_M=NAN, e_F=NAN, e_rms=NAN, c_u=NAN, u_peak=10.0), score(), 1.234),
    ]
    v = evaluate_gate(lim, runs)
    assert not v.passed
    got = {(c.criterion, c.scenario) for c in v.failures}
    assert got == {
        ("e_F", "case1/payload_heavy"), ("e_M", "case1/payload_heavy"), ("e_rms", "case1/payload_heavy"),
        ("c_u", "case1/payload_heavy"),
        ("u_peak", "case2/nominal"), ("arc_vs_pid_e_rms", "case2/nominal"),
        ("divergence", "mc/007"), ("e_F", "mc/007"), ("e_M", "mc/007"), ("e_rms", "mc/007"), ("c_u", "mc/007"),
        ("u_peak", "mc/007"), ("arc_vs_pid_e_rms", "mc/007"),
        ("arc_vs_pid_p90", "fixed"), ("arc_vs_pid_median", "monte_carlo"), ("arc_vs_pid_p90", "monte_carlo"),
    }
    by = {(c.criterion, c.scenario): c for c in v.failures}
    assert by[("e_F", "case1/payload_heavy")].value == 41e-6
    assert "41 um (limit 40 um)" in by[("e_F", "case1/payload_heavy")].detail
    assert by[("divergence", "mc/007")].value == 1.234
    assert "aborted at t = 1.234 s" in by[("divergence", "mc/007")].detail
    assert "clipped" in by[("u_peak", "case2/nominal")].detail
    assert by[("arc_vs_pid_e_rms", "case2/nominal")].value == pytest.approx(2.0)
    worst = v.worst()
    assert worst["e_M"].scenario == "mc/007"  # a diverged run is worse than any finite error
    assert worst["divergence"].scenario == "mc/007"
    assert evaluate_gate(lim, runs[:3]).worst()["e_M"].scenario == "case1/payload_heavy"
    assert evaluate_gate(lim, runs[:1]).worst()["e_M"].value == 50e-6


def test_limits_are_inclusive_and_pid_divergence_favours_arc():
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0)
    at = score(e_F=lim.e_F, e_M=lim.e_M, e_rms=lim.e_rms, c_u=lim.c_u, u_peak=9.999)
    pid_div = score(diverged=True, e_M=NAN, e_F=NAN, e_rms=NAN, c_u=NAN)
    v = evaluate_gate(lim, [("s", at, pid_div, NAN)])
    assert v.passed, [c.detail for c in v.failures]


def test_divergence_check_can_be_switched_off_but_indexes_still_fail():
    lim = resolve_gate(GateSpec(no_divergence=False), lsb=1e-6, travel=0.4, u_max=10.0)
    v = evaluate_gate(lim, [("s", score(diverged=True, e_M=NAN, e_F=NAN, e_rms=NAN, c_u=NAN), score(), 0.5)])
    crit = {c.criterion for c in v.failures}
    assert "divergence" not in crit and {"e_F", "e_M", "e_rms"} <= crit


def test_arc_vs_pid_slack_is_the_quantization_noise_rms_by_default():
    # An error-free loop read through an encoder of LSB q shows e_rms = q / sqrt(12): the default slack.
    lim = resolve_gate(GateSpec(arc_vs_pid_e_rms=1.0, arc_vs_pid_median=1e9, arc_vs_pid_p90=1e9), lsb=0.8e-6,
                       travel=0.4, u_max=10.0)
    assert lim.arc_vs_pid_slack == pytest.approx(0.8e-6 / math.sqrt(12.0))
    assert "sqrt(12)" in lim.basis["arc_vs_pid_slack"]
    pid = score(e_rms=0.31e-6)
    edge = 0.31e-6 + lim.arc_vs_pid_slack
    ok = evaluate_gate(lim, [("s", score(e_rms=edge), pid, NAN)])
    assert ok.passed, [c.detail for c in ok.failures]
    bad = evaluate_gate(lim, [("s", score(e_rms=edge * 1.001), pid, NAN)])
    assert [(c.criterion, c.scenario) for c in bad.failures] == [("arc_vs_pid_e_rms", "s")]
    assert "+ 0.231 um slack" in bad.failures[0].detail
    # strict comparison on request; lengths as the error limits; negative refused
    strict = resolve_gate(gate_from_mapping({"gate": {"arc_vs_pid_slack": 0, "arc_vs_pid_e_rms": 1.0}}), lsb=0.8e-6,
                          travel=0.4, u_max=10.0)
    assert strict.arc_vs_pid_slack == 0.0
    assert not evaluate_gate(strict, [("s", score(e_rms=0.32e-6), pid, NAN)]).passed
    two = resolve_gate(gate_from_mapping({"gate": {"arc_vs_pid_slack": "2 lsb"}}), lsb=0.8e-6, travel=0.4,
                       u_max=10.0)
    assert two.arc_vs_pid_slack == pytest.approx(1.6e-6)
    with pytest.raises(SpecError, match=r"gate\.arc_vs_pid_slack = -1: must be a non-negative finite length"):
        gate_from_mapping({"gate": {"arc_vs_pid_slack": -1}}, "g.toml")


def test_margin_checks_hold_the_arc_on_the_identified_plant_to_the_floors():
    from commission.controllers.margins import Margins
    from commission.gate import margin_checks
    from commission.robustness import LoopMargins, MarginFloors

    good = Margins(gain_margin_db=12.0, phase_margin_deg=45.0, delay_margin_samples=1.6, modulus_margin=0.7,
                   crossover_hz=180.0, spectral_radius=0.93, stable=True)
    thin = dataclasses.replace(good, delay_margin_samples=0.8, modulus_margin=0.45)
    rows = [LoopMargins("nominal", "arc", (30.0, 10.0, 0.0), "initial", good),
            LoopMargins("nominal", "arc", (37.0, 10.0, 0.0), "plant", thin),
            LoopMargins("nominal", "pid", None, "", thin),  # the baseline is reported, not gated
            LoopMargins("theta1_min/theta2_min", "arc", (8.3, 2.4, 0.0), "plant", thin)]  # a box corner: reported
    checks = margin_checks(rows, MarginFloors())
    assert len(checks) == 2 * 5 and {c.criterion for c in checks} == {"margins"}
    failed = [c for c in checks if not c.passed]
    assert [c.detail.split(" (")[0] for c in failed] == ["delay margin 0.8 samples", "modulus margin 0.45"]
    assert all(c.scenario == "margins/nominal/arc(theta_hat plant)" for c in failed)
    assert failed[0].value == pytest.approx(1.0 / 0.8)  # floor / margin: above 1 fails
    unstable = dataclasses.replace(good, stable=False, spectral_radius=1.01, gain_margin_db=-1.0)
    bad = margin_checks([LoopMargins("nominal", "arc", None, "initial", unstable)], MarginFloors())
    assert not bad[0].passed and "UNSTABLE" in bad[0].detail and bad[1].value == math.inf


def test_a_gate_toml_sets_the_margin_criteria_but_cannot_lower_the_spec_floors():
    """gate.toml's margin keys set the criteria; the tuning spec's [margins] stay a floor.

    A loop with a 0.8-sample delay margin passes a gate whose delay_margin_samples is 0.5, but
    the floor (the spec's 1 sample) still fails it; a stricter gate fails the criterion itself.
    """
    from commission.controllers.margins import Margins
    from commission.gate import FloorContext, check_floors, margin_checks
    from commission.robustness import LoopMargins, MarginFloors

    spec_floors = MarginFloors()
    thin = Margins(gain_margin_db=12.0, phase_margin_deg=45.0, delay_margin_samples=0.8, modulus_margin=0.7,
                   crossover_hz=180.0, spectral_radius=0.93, stable=True)
    rows = [LoopMargins("nominal", "arc", (30.0, 10.0, 0.0), "initial", thin)]
    loose = gate_from_mapping({"gate": {"delay_margin_samples": 0.5}}, "g.toml")
    assert loose.margins == {"delay_margin_samples": 0.5}
    gate_floors = dataclasses.replace(spec_floors, delay_samples=loose.margins["delay_margin_samples"])
    assert all(c.passed for c in margin_checks(rows, gate_floors))
    ctx = FloorContext(runs=[], limits={"u_max": 10.0, "k1s_max": 1e3, "k2s_max": 1e3}, drive_u_max=10.0,
                       margins=rows, margin_floors=spec_floors)
    floor_fail = [c for c in check_floors(ctx) if not c.passed]
    assert [c.criterion for c in floor_fail] == ["floor:margins"]
    assert floor_fail[0].detail.startswith("delay margin 0.8 samples")
    strict = gate_from_mapping({"gate": {"phase_margin_deg": 50.0}}, "g.toml")
    strict_floors = dataclasses.replace(spec_floors, phase_deg=strict.margins["phase_margin_deg"])
    assert [c.detail.split(" (")[0] for c in margin_checks(rows, strict_floors) if not c.passed] == [
        "phase margin 45 deg", "delay margin 0.8 samples"]
    with pytest.raises(SpecError, match=r"gate\.modulus_margin = -0\.1: expected a positive finite number"):
        gate_from_mapping({"gate": {"modulus_margin": -0.1}}, "g.toml")


def test_a_diverged_robustness_scenario_fails_the_floor_whatever_the_gate_says():
    """no_divergence = false switches the gate's criterion off, never the floor, on any scenario."""
    from commission.gate import FloorContext, check_floors

    diverged = Indexes(math.inf, math.inf, math.inf, math.inf, math.inf, math.inf, 12.0, True)
    ctx = FloorContext(runs=[("case1/delay+1", diverged, 1.2)],
                       limits={"u_max": 10.0, "k1s_max": 1e3, "k2s_max": 1e3}, drive_u_max=10.0)
    off = resolve_gate(gate_from_mapping({"gate": {"no_divergence": False}}), lsb=1e-6, travel=0.4, u_max=10.0)
    v = evaluate_gate(off, [("case1/delay+1", diverged, diverged, 1.2)], ctx)
    assert not v.passed
    assert "floor:no_divergence" in {c.criterion for c in v.failures}
    assert "divergence" not in {c.criterion for c in v.checks}


def test_arc_vs_pid_is_judged_by_quantiles_not_by_the_worst_plant():
    """A synthetic distribution: 64 Monte-Carlo plants where the ARC is at 0.5 of the PID on 56, loses
    by 3-18 % on 7 and by 73 % on one (the issue's sample), and 12 fixed scenarios at 0.6.  The median
    (0.5) and the 90th percentile (the 58th of 64 sorted factors: 1.03) pass the default limits 1.0 and
    1.2; the worst plant is named.  Moving 3 more plants above 1.2 fails the 90th percentile."""
    lim = resolve_gate(GateSpec(), lsb=0.0, travel=0.4, u_max=10.0)
    assert (lim.arc_vs_pid_median, lim.arc_vs_pid_p90, lim.arc_vs_pid_every) == (1.0, 1.2, False)
    pid = 2e-6
    losses = [1.03, 1.05, 1.08, 1.1, 1.12, 1.15, 1.18, 1.73]
    mc = [0.5] * 56 + losses
    runs = [(f"case1/s{i}", score(e_rms=0.6 * pid), score(e_rms=pid), NAN) for i in range(12)]
    runs += [(f"mc/{i:03d}", score(e_rms=f * pid), score(e_rms=pid), NAN) for i, f in enumerate(mc)]
    v = evaluate_gate(lim, runs)
    q = {(c.criterion, c.scenario): c for c in v.checks if c.criterion.startswith("arc_vs_pid")}
    assert set(q) == {("arc_vs_pid_median", "fixed"), ("arc_vs_pid_p90", "fixed"),
                      ("arc_vs_pid_median", "monte_carlo"), ("arc_vs_pid_p90", "monte_carlo")}
    assert v.passed, [c.detail for c in v.failures]
    srt = sorted(mc)
    assert q[("arc_vs_pid_median", "monte_carlo")].value == pytest.approx(0.5)
    assert q[("arc_vs_pid_p90", "monte_carlo")].value == pytest.approx(srt[int(np.ceil(0.9 * 63))])
    assert q[("arc_vs_pid_p90", "fixed")].value == pytest.approx(0.6)
    assert "worst mc/063: f = 1.73" in q[("arc_vs_pid_p90", "monte_carlo")].detail
    worse = [0.5] * 50 + [1.3] * 6 + losses
    runs2 = runs[:12] + [(f"mc/{i:03d}", score(e_rms=f * pid), score(e_rms=pid), NAN) for i, f in enumerate(worse)]
    v2 = evaluate_gate(lim, runs2)
    assert [(c.criterion, c.scenario) for c in v2.failures] == [("arc_vs_pid_p90", "monte_carlo")]
    # a gate.toml sets the limits; a diverged ARC counts as an infinite factor
    g = resolve_gate(gate_from_mapping({"gate": {"arc_vs_pid_median": 0.4, "arc_vs_pid_p90": 2.0}}), lsb=0.0,
                     travel=0.4, u_max=10.0)
    v3 = evaluate_gate(g, runs)
    assert {(c.criterion, c.scenario) for c in v3.failures} == {("arc_vs_pid_median", "fixed"),
                                                                 ("arc_vs_pid_median", "monte_carlo")}
    div = score(diverged=True, e_M=NAN, e_F=NAN, e_rms=NAN, c_u=NAN)
    assert required_factor(div, score(e_rms=pid), 0.0) == math.inf
    assert required_factor(score(e_rms=pid), div, 0.0) == 0.0
    assert required_factor(score(e_rms=3e-6), score(e_rms=2e-6), 1e-6) == pytest.approx(1.0)


def test_default_error_limits_follow_the_axis_and_the_targets():
    """max(k LSB, k' travel, 4 x target): the paper's targets (5 um, 10 um) leave its 20 um and 40 um;
    a looser stated target, a coarser encoder or a longer stroke raise the limit, a gate.toml value wins."""
    paper = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, targets={"e_rms": 5e-6, "e_f": 10e-6})
    assert paper.e_rms == pytest.approx(20e-6) and paper.e_F == pytest.approx(40e-6)
    loose = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=10.0, targets={"e_rms": 30e-6, "e_f": 10e-6})
    assert loose.e_rms == pytest.approx(120e-6) and "4 x targets.e_rms" in loose.basis["e_rms"]
    coarse = resolve_gate(GateSpec(), lsb=5e-6, travel=0.4, u_max=10.0, targets={"e_rms": 5e-6, "e_f": 10e-6})
    assert coarse.e_rms == pytest.approx(75e-6)  # 15 encoder steps
    long = resolve_gate(GateSpec(), lsb=1e-6, travel=2.0, u_max=10.0, targets={"e_rms": 5e-6, "e_f": 10e-6})
    assert long.e_rms == pytest.approx(100e-6)  # 0.005 % of 2 m
    given = resolve_gate(gate_from_mapping({"gate": {"e_rms": "7 um"}}), lsb=1e-6, travel=0.4, u_max=10.0,
                         targets={"e_rms": 30e-6, "e_f": 10e-6})
    assert given.e_rms == pytest.approx(7e-6)
