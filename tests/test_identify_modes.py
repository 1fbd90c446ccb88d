"""All that the data show (issue 31, Build 3; must-show 3 and 4).

Known truth: two simulated axes with two structural modes each (commission.synth, the plant's
second appendage) record a commissioning log with a broadband injection segment; only the
log goes to `identify`.  The modes a measured response shows are the plant's coupled modes
(:func:`commission.controllers.linear.structural_modes` of the truth), the reference here.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from commission.artifacts import Identification
from commission.cli.main import app
from commission.controllers.linear import structural_modes
from commission.controllers.plant import P_MODE2_DAMPING, P_MODE2_HZ, P_MODE_DAMPING, P_MODE_HZ
from commission.identification import identify_log
from commission.identify.frf import BAND_GAIN_TOL, ExtraMode, departures
from commission.identify.frf.model import _factor
from commission.scenarios import identified_plant, robustness_scenarios, scenario_matrix
from commission.spec import default_spec, spec_from_mapping
from commission.synth import AxisTruth, ExcitationPlan, simulate_excitation, write_log_h5
from shared_paths import EMPS_DIR

#: The shortened commissioning run of tests/test_frf.py (about 23 s, 3 s of PRBS on two slow legs).
PLAN = ExcitationPlan(n_speeds=5, ms_duration=6.0, leg_max_time=0.8, injection_s=3.0)

TWO_MODE = {
    # The axis: modes near 450 Hz and 1 kHz, the encoder on a bracket (the second load),
    # 0.5 um rms encoder noise on a 0.1 um scale, 5 kHz, half a sample late.
    "bracket_5k": AxisTruth(M=0.12, B=1.5, fc=0.3, fs=0.4, vs=0.015, xi=2.0, offset=-0.03, ripple_amp=0.02,
                            ripple_pitch=0.025, lsb=0.1e-6, sample_rate=5000.0, noise_std=0.5e-6, mode_hz=450.0,
                            mode_damping=0.04, mode_ratio=0.3, mode2_hz=1000.0, mode2_damping=0.03,
                            mode2_ratio=0.1, mode2_load_side=True, delay=0.5 / 5000.0),
    # Motor-side encoder (each mode with its anti-resonance), 4 kHz, 0.5 um scale, 0.1 um noise.
    "motor_4k": AxisTruth(M=0.06, B=0.5, fc=0.2, fs=0.26, vs=0.008, xi=1.5, offset=0.02, ripple_amp=0.01,
                          ripple_pitch=0.04, lsb=0.5e-6, sample_rate=4000.0, noise_std=0.1e-6, mode_hz=380.0,
                          mode_damping=0.03, mode_ratio=0.3, mode2_hz=900.0, mode2_damping=0.04, mode2_ratio=0.15),
}


def _log(tmp_path_factory, name: str) -> str:
    path = tmp_path_factory.mktemp(name) / f"{name}.h5"
    write_log_h5(path, simulate_excitation(TWO_MODE[name], PLAN, np.random.default_rng(3)))
    return str(path)


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> dict[str, str]:
    return {name: _log(tmp_path_factory, name) for name in TWO_MODE}


@pytest.fixture(scope="module")
def identified(logs) -> dict[str, dict]:
    return {name: identify_log(path).ident.to_dict() for name, path in logs.items()}


def _resonances(fr: dict) -> list[dict]:
    return [m for m in fr["modes"] if m["kind"] == "resonance"]


@pytest.mark.parametrize("name", sorted(TWO_MODE))
def test_both_modes_are_recovered_with_their_uncertainty(identified, name):
    truth = TWO_MODE[name]
    fr = identified[name]["frequency_response"]
    true_modes = structural_modes(truth.plant())
    assert len(true_modes) == 2
    res = _resonances(fr)
    assert fr["fit_quality"]["n_modes"] == 2 and len(res) == 2
    for (f_true, z_true), m in zip(true_modes, res):
        assert m["frequency_hz"] == pytest.approx(f_true, rel=0.05)
        assert m["damping"] == pytest.approx(z_true, rel=0.30)
        assert 0 < m["frequency_std_hz"] < 0.05 * m["frequency_hz"] and 0 < m["damping_std"] < m["damping"]
    # The encoder's place shows: on the bracket one mode has no anti-resonance; on the motor both have one.
    kinds = [m["kind"] for m in fr["modes"]]
    assert kinds.count("anti-resonance") == (1 if truth.mode2_load_side else 2)
    assert fr["departures"] == []  # nothing left beyond the estimate's uncertainty
    assert fr["fit_quality"]["model_rms_error"] < 0.2 < fr["fit_quality"]["rigid_rms_error"]
    assert abs(fr["delay_samples"] - truth.delay * truth.sample_rate) <= 0.2


@pytest.mark.parametrize("name", sorted(TWO_MODE))
def test_the_simulator_gets_both_modes(identified, name, tmp_path):
    truth = TWO_MODE[name]
    path = tmp_path / "ident.json"
    path.write_text(json.dumps(identified[name], sort_keys=True))
    ident = Identification.load(str(path))
    p = identified_plant(ident)
    assert p[P_MODE_HZ] > 0 and p[P_MODE2_HZ] > 0
    # The simulated plant's coupled modes are the log's, whichever appendage carries which.
    for (f_true, z_true), (f_sim, z_sim) in zip(structural_modes(truth.plant()), structural_modes(p)):
        assert f_sim == pytest.approx(f_true, rel=0.05) and z_sim == pytest.approx(z_true, rel=0.30)
    # The robustness variants move both modes; a spec that states its own mode drops the log's second.
    variants = {s.name.split("/")[1]: s.plant for s in robustness_scenarios(ident, default_spec())}
    assert variants["mode_low"][P_MODE2_HZ] == pytest.approx(0.8 * p[P_MODE2_HZ])
    assert variants["mode_high"][P_MODE_HZ] == pytest.approx(1.2 * p[P_MODE_HZ])
    assert variants["mode_damping_half"][P_MODE2_DAMPING] == pytest.approx(0.5 * p[P_MODE2_DAMPING])
    assert variants["mode_damping_half"][P_MODE_DAMPING] == pytest.approx(0.5 * p[P_MODE_DAMPING])
    # Every scenario validate simulates (nominal, Monte Carlo, corners, payloads) carries the second mode.
    matrix = scenario_matrix(ident, default_spec(), rng=np.random.default_rng(0), n_monte_carlo=4)
    assert matrix and all(s.plant[P_MODE2_HZ] > 0 for s in matrix)
    assert all(s.plant[P_MODE2_HZ] == pytest.approx(p[P_MODE2_HZ]) for s in matrix if "/mode_" not in s.name)
    own = identified_plant(ident, spec_from_mapping({"plant": {"mode_hz": 600.0}}))
    assert own[P_MODE_HZ] == 600.0 and own[P_MODE2_HZ] == 0.0


@pytest.mark.parametrize("name", sorted(TWO_MODE))
def test_encoder_noise_and_quantization_are_told_apart(identified, name):
    truth = TWO_MODE[name]
    enc = identified[name]["encoder"]
    assert enc["quantization"] == pytest.approx(truth.lsb, rel=1e-6)
    assert enc["quantization_noise_rms"] == pytest.approx(truth.lsb / math.sqrt(12.0), rel=1e-6)
    assert enc["noise_std"] == pytest.approx(truth.noise_std, rel=0.20)
    assert enc["noise_rms_total"] == pytest.approx(math.hypot(truth.noise_std, truth.lsb / math.sqrt(12.0)), rel=0.20)


def test_a_fit_kept_to_one_mode_names_the_other_mode(logs):
    # Must show 3: the fit keeps one of the two modes; the warning names the other one's frequency.
    truth = TWO_MODE["bracket_5k"]
    out = identify_log(logs["bracket_5k"], max_modes=1)
    fr = out.ident.to_dict()["frequency_response"]
    kept = _resonances(fr)
    assert fr["fit_quality"]["n_modes"] == 1 and len(kept) == 1
    true_f = [f for f, _ in structural_modes(truth.plant())]
    other = min(true_f, key=lambda f: -abs(f - kept[0]["frequency_hz"]))  # the one not kept
    assert abs(other - kept[0]["frequency_hz"]) > 0.2 * other
    named = [d for d in fr["departures"] if abs(d["frequency_hz"] - other) <= 0.05 * other]
    assert named and named[0]["ratio_db"] > 20.0 * math.log10(BAND_GAIN_TOL)
    text = [w for w in out.ident.extra["warnings"] if "departs from the fitted model" in w]
    assert any(f"{named[0]['frequency_hz']:.4g} Hz" in w for w in text)


def test_the_cli_takes_max_modes_and_prints_the_warning(logs, tmp_path):
    r = CliRunner().invoke(app, ["identify", logs["motor_4k"], "--out", str(tmp_path / "ident.json"),
                                 "--max-modes", "1"], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    flat = " ".join(r.output.split())
    assert "departs from the fitted model at" in flat
    fr = json.loads((tmp_path / "ident.json").read_text())["frequency_response"]
    f2 = structural_modes(TWO_MODE["motor_4k"].plant())[1][0]
    assert any(abs(d["frequency_hz"] - f2) <= 0.05 * f2 for d in fr["departures"])


# --------------------------------------------------------------------------- the numerics alone


@pytest.mark.parametrize("kind", ["load", "motor"])
def test_mode_factor_is_its_transfer_function(kind):
    m = ExtraMode(kind, 800.0, 0.05, 0.3)
    A, B, C, D = _factor(m)
    w = 2 * math.pi * 800.0
    s = 1j * 2 * math.pi * np.array([0.0, 10.0, 500.0, 800.0, 1500.0])
    H = np.array([(C @ np.linalg.solve(si * np.eye(2) - A, B))[0, 0] + D for si in s])
    den = s**2 + 2 * 0.05 * w * s + w**2
    num = 2 * 0.05 * w * s + w**2 if kind == "load" else s**2 / 0.7 + 2 * 0.05 * w * s + w**2
    np.testing.assert_allclose(H, num / den, rtol=1e-12)
    assert abs(H[0]) == pytest.approx(1.0)  # unit gain at DC: the rigid body keeps its meaning


def test_departures_find_a_bump_and_nothing_in_pure_noise():
    rng = np.random.default_rng(0)
    f = np.arange(5.0, 2000.0, 5.0)
    Hm = 1.0 / (-(2 * np.pi * f) ** 2)
    coh = np.full(f.size, 0.95)
    n_avg = 20
    sd = 1.0 / np.sqrt(2 * n_avg * 0.95 / 0.05)  # of ln H's real and imaginary parts
    noisy = Hm * np.exp(rng.normal(0, sd, f.size) + 1j * rng.normal(0, sd, f.size))
    assert departures(f, noisy, Hm, coh, n_avg) == []
    w = 2 * np.pi * 700.0
    s = 1j * 2 * np.pi * f
    bump = (2 * 0.03 * w * s + w**2) / (s**2 + 2 * 0.03 * w * s + w**2)
    found = departures(f, noisy * bump, Hm, coh, n_avg)
    assert len(found) >= 1
    top = max(found, key=lambda d: d.ratio_db)
    assert top.frequency_hz == pytest.approx(700.0, abs=5.0) and top.ratio_db > 20.0


# --------------------------------------------------------------------------- must show 4: EMPS


@pytest.mark.skipif(not (EMPS_DIR / "DATA_EMPS.mat").exists(), reason="EMPS data not present")
def test_emps_names_the_missing_evidence_and_the_excite_command(tmp_path):
    import tomllib

    r = CliRunner().invoke(app, ["identify", str(EMPS_DIR / "DATA_EMPS.mat"), "--map", "q=qm", "--map", "u=vir",
                                 "--input-gain", "35.15065188248547", "--u-unit", "N",
                                 "--out", str(tmp_path / "ident.json")], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    assert "missing evidence:" in r.output
    assert "commission excite --spec limits.toml --out-dir" in r.output
    ev = json.loads((tmp_path / "ident.json").read_text())["evidence"]
    band_top = json.loads((tmp_path / "ident.json").read_text())["frequency_response"]["band_hz"][1]
    assert f"backed only to {band_top:.3g} Hz" in ev["missing"][0]
    lim = tomllib.loads(ev["limits_toml"])
    # +-10 V x 35.15 N/V = +-351.5 N; the log's travel (README: 0 ... 0.24638 m), its peak speed (+-0.128 m/s).
    assert lim["limits"]["u_max"] == pytest.approx(351.5, abs=0.1)
    assert lim["limits"]["travel"] == pytest.approx(0.2464, abs=2e-4)
    assert lim["limits"]["v_max"] == pytest.approx(0.128, rel=0.05)
    assert lim["drive"]["sample_rate"] == 1000.0
    assert lim["axis"]["u_unit"] == "N" and lim["axis"]["mass"] == pytest.approx(95.1, rel=0.02)
    # Given explicitly, --u-max is used as is.
    r = CliRunner().invoke(app, ["identify", str(EMPS_DIR / "DATA_EMPS.mat"), "--map", "q=qm", "--map", "u=vir",
                                 "--input-gain", "35.15065188248547", "--u-unit", "N", "--u-max", "300",
                                 "--out", str(tmp_path / "ident2.json")], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    lim = tomllib.loads(json.loads((tmp_path / "ident2.json").read_text())["evidence"]["limits_toml"])
    assert lim["limits"]["u_max"] == 300.0


def test_a_log_with_an_injection_needs_no_excite_run(identified):
    assert all("evidence" not in ident for ident in identified.values())


def test_an_excite_plan_on_the_two_mode_axis_backs_both_modes(tmp_path):
    # The loop closed on the axis: plan from the limits, record it, identify with --plan.
    from commission.excite import excite_spec_from_mapping, plan_run, simulate_plan

    truth = TWO_MODE["bracket_5k"]
    spec = excite_spec_from_mapping({"limits": {"travel": 0.3, "v_max": 0.5, "a_max": 20.0, "u_max": 10.0},
                                     "drive": {"sample_rate": 5000.0, "bandwidth_hz": 40.0}, "axis": {"mass": 0.1}})
    plan = plan_run(spec)
    path = tmp_path / "log.h5"
    write_log_h5(path, simulate_plan(plan, truth, np.random.default_rng(1)))
    ident = identify_log(str(path), plan=json.loads(json.dumps(plan.to_dict()))).ident.to_dict()
    fr = ident["frequency_response"]
    assert fr["source"] == "broadband" and fr["departures"] == []
    res = _resonances(fr)
    assert len(res) == 2
    for (f_true, z_true), m in zip(structural_modes(truth.plant()), res):
        assert m["frequency_hz"] == pytest.approx(f_true, rel=0.05)
        assert m["damping"] == pytest.approx(z_true, rel=0.30)
    assert abs(fr["delay_samples"] - truth.delay * truth.sample_rate) <= 0.2
    assert ident["encoder"]["noise_std"] == pytest.approx(truth.noise_std, rel=0.20)
