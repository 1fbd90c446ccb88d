"""Issue 30, build 2: certify only within the evidence (commission/evidence.py).

The weight against its closed forms; the robust-stability bound against the small-gain
theorem on plants inside and outside the uncertainty set (closed-loop eigenvalues, computed
independently of the frequency grid); the margins on a measured response against the
model's; the band and the measured bins ident.json carries; the limits.toml sketch parsed
back with tomllib.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from commission.controllers.arc import arc_pack
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import (closed_loop_radius, frequency_grid, linearize_arc, linearize_pid,
                                            loop_margins)
from commission.controllers.pid import pid_pack, pid_place_poles
from commission.evidence import (EVIDENCE_FACTOR, W_INF, ZETA_W, Evidence, EvidenceBound, MeasuredResponse,
                                 evidence_checks, evidence_lines, evidence_of, excite_command, limits_toml,
                                 measured_margins, raise_evidence_line)
from commission.paper import TS, paper_pid_gains, reference_identification, reference_plant
from commission.spec import spec_from_mapping
from commission.tuning import Tuning

DATA = Path(__file__).resolve().parent / "data"

#: The sample's whole-log band (ident.json of sample_data/axis_excitation.h5): 8 to 22 Hz.
WHOLE_LOG = {"source": "whole_log", "band_hz": [8.0, 22.0]}
SPEC = spec_from_mapping({})
#: The pole (rad/s) of the PID of the paper's family that holds the default bound on the sample's band.
POLE = 60.0


def _ident(fr):
    return reference_identification(frequency_response=fr)


def test_the_weight_is_the_envelope_of_every_unseen_mode_above_the_first():
    ev = Evidence("whole_log", (8.0, 22.0))
    fm = EVIDENCE_FACTOR * 22.0
    z = ZETA_W
    assert ev.mode_hz == pytest.approx(fm) and ev.w_inf == pytest.approx(W_INF)
    assert ev.weight(np.array([ev.unity_hz]))[0] == pytest.approx(1.0, rel=1e-9)
    # Well below f_m: (f / f_m)^2; at and above it, the peak 1 / (2 zeta sqrt(1 - zeta^2)).
    assert ev.weight(np.array([fm / 30.0]))[0] == pytest.approx(1.0 / 900.0, rel=1e-2)
    assert ev.weight(np.array([fm, 3.0 * fm]))[1] == pytest.approx(1.0 / (2 * z * math.sqrt(1 - z * z)))
    # The envelope: the relative error -s^2 / (s^2 + 2 zeta' w' s + w'^2) of any mode at f' >= f_m,
    # damped zeta' >= zeta, never exceeds |W| (continuous time, closed form).
    f = np.geomspace(1.0, 20.0 * fm, 3000)
    w = ev.weight(f)
    for f_mode in (fm, 1.3 * fm, 2.0 * fm, 7.0 * fm):
        for zeta in (z, 0.1, 0.4):
            s_ = 2j * np.pi * f
            wm = 2 * np.pi * f_mode
            rel = np.abs(-s_ ** 2 / (s_ ** 2 + 2 * zeta * wm * s_ + wm ** 2))
            assert np.all(rel <= w * (1 + 1e-9)), (f_mode, zeta)
    assert np.all(np.diff(ev.weight(np.geomspace(1.0, 1e5, 200))) >= 0)
    assert not Evidence("none", None).applies and np.all(Evidence("none", None).weight(np.ones(3)) == 0)


def test_the_evidence_comes_from_ident_json_and_falls_back_to_the_older_band_key():
    assert evidence_of(reference_identification()).source == "none"
    assert evidence_of(_ident(WHOLE_LOG)).band_hz == (8.0, 22.0)  # an ident.json before evidence_band_hz
    ev = evidence_of(_ident({**WHOLE_LOG, "source": "broadband", "evidence_band_hz": [8.0, 600.0],
                             "measured": {"frequency_hz": [10.0, 20.0], "magnitude": [1e-3, 2e-4],
                                          "phase_deg": [-180.0, -175.0], "coherence": [0.9, 0.5]}}))
    assert ev.band_hz == (8.0, 600.0) and ev.source == "broadband"
    assert ev.measured.H[0] == pytest.approx(-1e-3) and ev.measured.coherence[1] == 0.5


def _mode_plant(hz: float, zeta: float) -> np.ndarray:
    return reference_plant(mode_hz=hz, mode_damping=zeta, mode_ratio=0.3, mode_load_side=True)


def test_a_loop_within_the_bound_is_stable_on_every_unseen_mode_inside_the_uncertainty_set():
    """Small-gain theorem: ||W T|| < 1 and |P_true / P - 1| <= |W| everywhere give a stable loop.

    A PID of the paper's family (57), its poles lowered to -POLE rad/s, holds the bound on the
    reference plant backed to 22 Hz; load-side modes at or above f_m whose sampled relative error
    stays below |W| (up to 0.9 x Nyquist) are in the set, and the closed loop's eigenvalues (not
    the frequency grid) say it is stable on each.
    """
    ident = _ident(WHOLE_LOG)
    b = EvidenceBound(ident, SPEC)
    Kp, Ki, Kd = pid_place_poles(0.02, -POLE)
    K = linearize_pid(pid_pack(dataclasses.replace(paper_pid_gains(), Kp=Kp, Ki=Ki, Kd=Kd)))
    row = b.row(K, "pid", "")
    assert row.holds and row.peak > 0.3  # the bound is active, not vacuous
    f = frequency_grid(TS)
    nominal = sampled_plant(reference_plant(), TS).frequency_response(f)
    inside = 0
    for hz in (b.evidence.mode_hz, 300.0, 479.0, 800.0, 1100.0):
        for zeta in (ZETA_W, 0.1, 0.3):
            true = sampled_plant(_mode_plant(hz, zeta), TS)
            rel = np.abs(true.frequency_response(f) / nominal - 1.0)
            # Up to 0.9 x Nyquist: the hold's zero at z = -1 sends the rigid body's response to 0 at
            # Nyquist, where every relative error is unbounded (and |T| is too small to matter).
            below = f <= 0.9 * 0.5 / TS
            if np.all(rel[below] <= b.W[below]):
                inside += 1
                assert closed_loop_radius(K, true) < 1.0, (hz, zeta)
    assert inside >= 5  # the set is not empty of real modes


def test_the_arc_the_old_gate_certified_breaks_the_bound_and_fails_on_the_mode_its_log_never_showed():
    """The reference ARC (crossover 230 Hz) on a log backed to 22 Hz: peak |W T| > 1, refused.

    On the stage with the paper's 479-Hz load-side mode it is indeed unstable, and the paper's
    PID, which holds the bound, is not (an independent check through the closed-loop eigenvalues).
    """
    tuning = Tuning.load(str(DATA / "tuning_paper_budget8.json"))
    ident = _ident(WHOLE_LOG)
    b = EvidenceBound(ident, SPEC)
    rows = b.arc_rows(tuning.arc)
    assert max(r.peak for r in rows) > 1.0
    checks = evidence_checks(rows, b.evidence, 0.5)
    assert checks and not all(c.passed for c in checks)
    assert all("peak |W T|" in c.detail and "Hz" in c.detail for c in checks)
    true = sampled_plant(_mode_plant(479.0, 0.07), TS)
    K_arc = linearize_arc(arc_pack(tuning.arc), tuning.arc.theta0)
    assert closed_loop_radius(K_arc, true) > 1.0
    assert closed_loop_radius(linearize_pid(pid_pack(paper_pid_gains())), true) < 1.0
    # Without a recorded frequency response no bound (and no check) is applied.
    none = EvidenceBound(reference_identification(), SPEC)
    assert none.violation(tuning.arc) == 0.0 and evidence_checks(none.arc_rows(tuning.arc), none.evidence, 0.5) == []


def test_margins_on_a_measured_response_equal_the_models_where_the_measurement_is_the_model():
    plant = sampled_plant(_mode_plant(479.0, 0.07), TS)
    K = linearize_pid(pid_pack(paper_pid_gains()))
    f = np.geomspace(5.0, 1200.0, 4000)
    exact = loop_margins(K, plant, f)
    m = MeasuredResponse(f, plant.frequency_response(f), np.ones_like(f))
    mod, pm, up, high = measured_margins(K, m)
    assert high == pytest.approx(mod)  # coherence 1: no estimation error
    assert mod == pytest.approx(exact.modulus_margin, rel=1e-3)
    assert pm == pytest.approx(exact.phase_margin_deg, abs=0.1)
    assert up == pytest.approx(1200.0)
    # Incoherent bins do not count: hide the resonance and the modulus margin is the rigid part's.
    low = np.where(f < 300.0, 1.0, 0.3)
    mod_low, _, up_low, _ = measured_margins(K, MeasuredResponse(f, m.H, low))
    assert up_low < 300.0 and mod_low > mod
    # The H1 estimate's standard error, sqrt((1 - g2) / (2 n g2)) of |L|, widens the margin the gate tests.
    g2 = np.full_like(f, 0.9)
    _, _, _, high = measured_margins(K, MeasuredResponse(f, m.H, g2, 10))
    L = -K.frequency_response(f) * m.H
    assert high == pytest.approx(float((np.abs(1 + L) + 2 * np.abs(L) * math.sqrt(0.1 / 18.0)).min()))


def test_the_limits_toml_sketch_parses_and_carries_the_spec_and_the_log():
    spec = spec_from_mapping({"trajectory": {"travel": 0.3, "v_max": 0.5, "a_max": 6.0},
                              "controller": {"sample_rate": 4000.0, "u_max": 5.0}})
    ident = _ident(WHOLE_LOG)
    d = tomllib.loads(limits_toml(spec, ident))
    assert d == {"limits": {"travel": 0.3, "v_max": 0.5, "a_max": 6.0, "u_max": 5.0},
                 "drive": {"sample_rate": 4000.0, "bandwidth_hz": 10.0},
                 "axis": {"mass": 0.027, "friction": 0.1, "viscous": 0.273, "q_unit": "m", "u_unit": "V"}}
    line = raise_evidence_line(evidence_of(ident), spec, ident)
    assert excite_command() == "commission excite --spec limits.toml --out-dir excite"
    assert f"`{excite_command()}`" in line and "22 Hz" in line and "travel = 0.3" in line


def test_the_spec_states_the_machines_lowest_mode_and_its_damping():
    ident = _ident(WHOLE_LOG)
    ev = evidence_of(ident, spec_from_mapping({"evidence": {"first_mode_hz": 900.0, "damping": 0.02}}))
    assert ev.mode_hz == pytest.approx(900.0) and ev.w_inf == pytest.approx(1 / (0.04 * math.sqrt(1 - 4e-4)))
    assert ev.unity_hz == pytest.approx(900.0 / math.sqrt(2 - 4 * 0.02 ** 2))
    assert evidence_of(ident, SPEC).mode_hz == pytest.approx(EVIDENCE_FACTOR * 22.0)
    # The paper's PID (crossover 114 Hz) exceeds the default bound on a log backed to 22 Hz, and holds
    # it when the user states that the machine has no mode below 5 kHz (beyond its Nyquist frequency).
    K = linearize_pid(pid_pack(paper_pid_gains()))
    assert not EvidenceBound(ident, SPEC).row(K, "pid", "").holds
    stated = spec_from_mapping({"evidence": {"first_mode_hz": 5000.0}})
    assert EvidenceBound(ident, stated).row(K, "pid", "").holds


def _verdict_with(*checks):
    from types import SimpleNamespace
    return SimpleNamespace(failures=tuple(c for c in checks if not c.passed))


def test_a_refusal_on_error_limits_within_a_rigid_logs_band_is_for_want_of_evidence():
    from types import SimpleNamespace

    from commission.evidence import evidence_limited_line
    from commission.gate import Check

    e_rms = Check("e_rms", "case1/nominal", 32.1e-6, 20e-6, False, "32.1 um (limit 20 um)")
    c_u = Check("c_u", "case1/nominal", 1.2, 1.0, False, "1.2 (limit 1)")
    rigid = Evidence(source="whole_log", band_hz=(8.0, 22.0))
    line = evidence_limited_line(SimpleNamespace(evidence=rigid, verdict=_verdict_with(e_rms)))
    assert line is not None and line.startswith("Missing evidence:")
    assert "up to 22 Hz" in line and "case1/nominal e_rms 32.1 um (limit 20 um)" in line
    assert "commission excite --spec limits.toml" in line
    # not for want of evidence: a broadband log, no band at all, or a failure that is not an error limit
    broadband = Evidence(source="broadband", band_hz=(5.0, 600.0))
    for ev, verdict in ((broadband, _verdict_with(e_rms)), (Evidence(source="none", band_hz=None), _verdict_with(e_rms)),
                        (rigid, _verdict_with(c_u))):
        assert evidence_limited_line(SimpleNamespace(evidence=ev, verdict=verdict)) is None


def test_where_the_logs_coherent_data_depart_from_the_model_the_unknown_starts_at_the_bands_top():
    # Axis 26 of the issue-30 sweep (20 kHz, encoder noise ~1 count: no broadband segment found): the
    # whole-log response is coherent up to 710 Hz, but backs the rigid model only to 380 Hz.
    departing = {"source": "whole_log", "band_hz": [14.0, 380.0], "evidence_band_hz": [14.0, 380.0],
                 "coherent_up_to_hz": 710.0, "resolution_hz": 2.0}
    ev = evidence_of(_ident(departing), SPEC)
    assert ev.factor_basis == "departure"
    assert ev.factor == pytest.approx(math.sqrt(2.0 - 4.0 * ZETA_W ** 2))
    # |W| reaches 1 where the data first contradict the model, W_inf just above
    assert ev.unity_hz == pytest.approx(380.0)
    assert ev.weight(np.array([380.0]))[0] == pytest.approx(1.0, rel=1e-9)
    d = ev.to_dict()
    assert d["factor_basis"] == "departure" and d["coherent_up_to_hz"] == 710.0
    # coherence that ends with the band (nothing measured above it) keeps the default decade
    ending = {**departing, "coherent_up_to_hz": 381.0}
    ev = evidence_of(_ident(ending), SPEC)
    assert ev.factor_basis == "default" and ev.mode_hz == pytest.approx(EVIDENCE_FACTOR * 380.0)
    # the user's statement of the machine wins
    stated = spec_from_mapping({"evidence": {"first_mode_hz": 5000.0}})
    ev = evidence_of(_ident(departing), stated)
    assert ev.factor_basis == "spec" and ev.mode_hz == pytest.approx(5000.0)
    # an older ident.json without coherent_up_to_hz: the default
    assert evidence_of(_ident(WHOLE_LOG), SPEC).factor_basis == "default"


def test_a_departure_bound_refuses_the_loop_a_decade_would_have_let_through():
    # the sample's rigid band, departing: the PID of the paper's family that holds the default
    # decade (POLE) breaks the bound once the unknown starts at the band's top, 22 Hz
    Kp, Ki, Kd = pid_place_poles(0.02, -POLE)
    K = linearize_pid(pid_pack(dataclasses.replace(paper_pid_gains(), Kp=Kp, Ki=Ki, Kd=Kd)))
    assert EvidenceBound(_ident(WHOLE_LOG), SPEC).row(K, "pid", "").holds
    departing = EvidenceBound(_ident({**WHOLE_LOG, "coherent_up_to_hz": 400.0, "resolution_hz": 2.0}), SPEC)
    assert departing.evidence.factor_basis == "departure"
    assert not departing.row(K, "pid", "").holds


def test_a_loop_unstable_on_the_model_holds_no_bound_in_the_gate_and_the_report():
    """||W T|| < 1 proves robust stability only of a loop that is stable on the model.  The paper's PID
    with its gains' signs flipped and scaled down (Kp x 1e-3, Ki x 1e-6, Kd x 0.03) is unstable on the
    reference plant (closed-loop eigenvalues), yet its |W T| on the grid is below 1 (its |T| is large
    only at low frequency, where |W| is small): the gate's rows (evidence_table)
    give it no bound, an emitted loop's check fails and says why, and the report's evidence line says
    UNSTABLE; the stable PID's row is the grid's peak either way.  The PID's row is reported, not gated."""
    from commission.controllers.margins import closed_loop_radius
    from commission.evidence import evidence_lines, evidence_table

    ident = _ident(WHOLE_LOG)
    pid = paper_pid_gains()
    flipped = dataclasses.replace(pid, Kp=-pid.Kp * 1e-3, Ki=-pid.Ki * 1e-6, Kd=-pid.Kd * 1e-3 ** 0.5)
    b = EvidenceBound(ident, SPEC)
    assert closed_loop_radius(linearize_pid(pid_pack(flipped)), b.plant) > 1.0
    grid_only = b.pid_row(flipped)
    assert grid_only.holds  # the grid alone would call it robust
    tuning = Tuning.load(str(DATA / "tuning_paper_budget8.json"))
    evidence, rows = evidence_table(tuning.arc, flipped, ident, SPEC)
    row = rows[-1]
    assert row.controller == "pid" and math.isinf(row.peak) and not row.holds
    assert row.to_dict()["peak_wt"] is None and row.to_dict()["holds"] is False
    # The yardstick's row is reported, not gated: the checks are the ARC's alone, and the same with
    # either PID (held out axis 1821 was refused on its default-pole PID's row alone).
    checks = evidence_checks(rows, evidence, 0.5)
    assert checks and all(c.scenario.startswith(("evidence/nominal/arc", "measured/nominal/arc")) for c in checks)
    assert checks == evidence_checks(evidence_table(tuning.arc, pid, ident, SPEC)[1], evidence, 0.5)
    # An emitted loop unstable on the model is gated: the check fails and says why.
    unstable = b.row(linearize_pid(pid_pack(flipped)), "arc", "initial", stability=True)
    check = evidence_checks([unstable], evidence, 0.5)[0]
    assert check.scenario == "evidence/nominal/arc(theta_hat initial)" and not check.passed
    assert "UNSTABLE" in check.detail
    pid_line = next(line for line in evidence_lines(evidence, rows) if line.startswith("PID: "))
    assert pid_line.startswith("PID: closed loop UNSTABLE") and pid_line.endswith("reported, not gated (only the emitted ARC's is)")
    stable = evidence_table(tuning.arc, pid, ident, SPEC)[1][-1]
    assert stable.peak == b.pid_row(pid).peak
    # The ARC's adaptation leaves neutral modes on the unit circle (spectral radius 1 + ~1e-10 here):
    # stable as the margin table counts it, so its rows keep the grid's peaks.
    K = linearize_arc(arc_pack(tuning.arc), tuple(tuning.arc.theta0))
    assert 1.0 <= closed_loop_radius(K, b.plant) < 1.0 + 1e-7
    assert [r.peak for r in rows[:2]] == [r.peak for r in b.arc_rows(tuning.arc)]


def test_where_the_bound_stays_below_one_up_to_nyquist_the_report_says_that_band_is_assumed_mode_free():
    # Held-out axis 1009 of the issue-30 sweep: 4 kHz, a log backed to 1290 Hz by its broadband segment,
    # and a motor-side mode at 2000 Hz that the default decade (12.9 kHz) put outside the bound.
    backed = {"source": "broadband", "band_hz": [12.0, 1290.0], "evidence_band_hz": [12.0, 1290.0],
              "coherent_up_to_hz": 1290.0, "resolution_hz": 5.0}
    spec = spec_from_mapping({"controller": {"sample_rate": 4000.0}})
    ev = evidence_of(_ident(backed), spec)
    assert ev.nyquist_hz == 2000.0 and ev.mode_hz == pytest.approx(12900.0)
    assert ev.assumed_mode_free_hz == (1290.0, 2000.0)
    w_nyq = float(ev.weight(np.array([2000.0]))[0])
    # the weight over the whole unbacked part of the loop's band is (f / f_m)^2-small: it bounds nothing there
    assert w_nyq == pytest.approx((2000.0 / 12900.0) ** 2, rel=0.05) and w_nyq < 0.03
    line = evidence_lines(ev, ())[0]
    assert "Assumed, not measured" in line and "no structural mode from 1290 to 2000 Hz" in line
    assert f"Hz; {w_nyq:.2g} there" in line and "[evidence] first_mode_hz" in line
    d = ev.to_dict()
    assert d["nyquist_hz"] == 2000.0 and d["assumed_mode_free_hz"] == [1290.0, 2000.0]
    # the user's statement of the machine's first mode is not an assumption of the tool's
    stated = evidence_of(_ident(backed), spec_from_mapping({"controller": {"sample_rate": 4000.0},
                                                            "evidence": {"first_mode_hz": 1800.0}}))
    assert stated.assumed_mode_free_hz is None and "Assumed" not in evidence_lines(stated, ())[0]
    # a rigid log's band a decade below Nyquist: the bound itself rises through 1 below Nyquist
    low = evidence_of(_ident(WHOLE_LOG), SPEC)
    assert low.mode_hz < low.nyquist_hz and low.assumed_mode_free_hz is None
    # held-out 1024 (20 kHz, backed to 1150 Hz): the mode (11.5 kHz) is above Nyquist but |W| passes 1
    # below it (at 8.1 kHz): the bound does weigh part of the gap, nothing is claimed
    near = evidence_of(_ident({**backed, "evidence_band_hz": [12.0, 1150.0], "coherent_up_to_hz": 1150.0}),
                       spec_from_mapping({"controller": {"sample_rate": 20000.0}}))
    assert near.mode_hz > near.nyquist_hz > near.unity_hz and near.assumed_mode_free_hz is None
    assert "Assumed" not in evidence_lines(low, ())[0] and low.to_dict()["assumed_mode_free_hz"] is None
    # without a spec (no rate known) nothing is claimed
    assert evidence_of(_ident(backed)).assumed_mode_free_hz is None
