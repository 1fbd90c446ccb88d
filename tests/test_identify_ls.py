"""Closed-form checks of the identification numerics and its refusals."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from commission.identify import (NotIdentifiableError, SignalError, fit_atan, fit_axis,
                                 friction_compensation, friction_compensation_curve, quantization_step,
                                 regressor, solve, stribeck_friction, theta_bounds)
from commission.identify.friction import fit_separable, stribeck_shape_derivatives
from commission.identify.ls import stribeck_shape
from commission.identify.signals import check_signals, decimate, default_settings, zero_phase_lowpass


# ----------------------------------------------------------------------------- least squares

def _design(n: int, rng: np.random.Generator) -> np.ndarray:
    return np.column_stack([rng.standard_normal(n), rng.uniform(-1, 1, n), np.ones(n)])


def test_solve_recovers_exact_linear_data():
    rng = np.random.default_rng(0)
    Phi = _design(200, rng)
    theta = np.array([2.5, -0.7, 0.3])
    res = solve(Phi, Phi @ theta)
    np.testing.assert_allclose(res.theta, theta, rtol=1e-12)
    assert res.relative_error < 1e-13
    assert res.condition_number == pytest.approx(np.linalg.cond(Phi))


def test_solve_statistics_follow_the_textbook_formula():
    rng = np.random.default_rng(1)
    Phi = _design(300, rng)
    y = Phi @ np.array([1.0, 2.0, 3.0]) + 0.1 * rng.standard_normal(300)
    res = solve(Phi, y)
    r = y - Phi @ res.theta
    sigma2 = r @ r / (300 - 3)
    assert res.sigma2 == pytest.approx(sigma2)
    np.testing.assert_allclose(res.cov, sigma2 * np.linalg.inv(Phi.T @ Phi), rtol=1e-10)
    np.testing.assert_allclose(res.std, np.sqrt(np.diag(res.cov)))
    np.testing.assert_allclose(res.residuals, r)
    assert res.relative_error == pytest.approx(np.linalg.norm(r) / np.linalg.norm(y))


def test_solve_std_matches_monte_carlo_spread():
    rng = np.random.default_rng(2)
    Phi = _design(100, rng)
    theta = np.array([1.0, -1.0, 0.5])
    draws, stds = [], []
    for _ in range(400):
        res = solve(Phi, Phi @ theta + 0.2 * rng.standard_normal(100))
        draws.append(res.theta)
        stds.append(res.std)
    np.testing.assert_allclose(np.std(draws, axis=0), np.mean(stds, axis=0), rtol=0.12)
    np.testing.assert_allclose(np.mean(draws, axis=0), theta, atol=0.02)


def test_solve_refuses_collinear_columns():
    qd = np.linspace(-1, 1, 100)
    Phi = regressor(qd, np.zeros(100)).Phi  # no acceleration at all
    with pytest.raises(NotIdentifiableError, match="collinear.*condition number inf"):
        solve(Phi, qd)
    with pytest.raises(NotIdentifiableError, match="4 rows for 4 parameters"):
        solve(np.eye(4), np.ones(4))


def test_regressor_columns():
    q = np.array([0.0, 0.01, 0.02, 0.03])
    qd = np.array([-0.2, 0.0, 0.1, 0.3])
    qdd = np.array([1.0, 2.0, 3.0, 4.0])
    reg = regressor(qd, qdd)
    assert reg.names == ("M", "B", "fc", "offset")
    np.testing.assert_array_equal(reg.Phi, np.column_stack([qdd, qd, np.sign(qd), np.ones(4)]))
    st = regressor(qd, qdd, q=q, model="stribeck", vs=0.1, xi=2.0, ripple_pitch=0.04)
    assert st.names == ("M", "B", "fc", "dfs", "offset", "ripple_sin", "ripple_cos")
    np.testing.assert_allclose(st.Phi[:, 3], np.exp(-(np.abs(qd) / 0.1) ** 2) * np.sign(qd))
    np.testing.assert_allclose(st.Phi[:, 5], np.sin(2 * np.pi * q / 0.04))
    with pytest.raises(ValueError, match="vs > 0 and xi > 0"):
        regressor(qd, qdd, model="stribeck")
    with pytest.raises(ValueError, match="needs the position q"):
        regressor(qd, qdd, ripple_pitch=0.04)


# ----------------------------------------------------------------------------- Stribeck separable fit

def _map_points(rng, sigma):
    v = np.concatenate([np.geomspace(1e-3, 0.3, 12), -np.geomspace(1.2e-3, 0.25, 12)])
    F = 0.27 * v + stribeck_friction(v, 0.1, 0.12, 0.01, 2.0) + 0.02 + sigma * rng.standard_normal(v.size)
    return v, F


def _fit_map(v, F):
    Phi0 = np.column_stack([v, np.sign(v), np.ones_like(v)])
    return fit_separable(Phi0, ("B", "fc", "offset"), lambda vs, xi: stribeck_shape(v, vs, xi),
                         lambda vs, xi: stribeck_shape_derivatives(v, vs, xi)[1:], F,
                         vs_bounds=(3e-4, 0.15))


def test_separable_fit_recovers_exact_stribeck_curve():
    v, F = _map_points(np.random.default_rng(0), 0.0)
    sep = _fit_map(v, F)
    assert sep.names == ("B", "fc", "offset", "fs", "vs", "xi")
    np.testing.assert_allclose(sep.value, [0.27, 0.1, 0.02, 0.12, 0.01, 2.0], rtol=1e-6)
    assert sep.at_bound == ()


def test_separable_fit_std_matches_monte_carlo_spread():
    rng = np.random.default_rng(3)
    draws, stds = [], []
    for _ in range(150):
        sep = _fit_map(*_map_points(rng, 5e-4))
        draws.append(sep.value)
        stds.append(sep.std)
    # the linearised (J^T J)^-1 sigma^2 covariance predicts the spread of every
    # parameter, the nonlinear fs, vs, xi included
    np.testing.assert_allclose(np.std(draws, axis=0), np.mean(stds, axis=0), rtol=0.25)


def test_stribeck_shape_derivatives_match_finite_differences():
    v = np.array([-0.03, -0.004, 0.0, 0.002, 0.01, 0.05])
    s, dvs, dxi = stribeck_shape_derivatives(v, 0.01, 1.7)
    h = 1e-7
    np.testing.assert_allclose(dvs, (stribeck_shape(v, 0.01 + h, 1.7) - stribeck_shape(v, 0.01 - h, 1.7)) / (2 * h),
                               rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(dxi, (stribeck_shape(v, 0.01, 1.7 + h) - stribeck_shape(v, 0.01, 1.7 - h)) / (2 * h),
                               rtol=1e-5, atol=1e-9)


# ----------------------------------------------------------------------------- friction compensation

def test_fit_atan_recovers_an_exact_atan_curve():
    v = np.linspace(-0.5, 0.5, 1001)
    f = 0.1 * (2 / np.pi) * np.arctan(900.0 * v)
    level, slope, rms = fit_atan(v, f)
    assert level == pytest.approx(0.1, rel=1e-6)
    assert slope == pytest.approx(900.0, rel=1e-5)
    assert rms < 1e-9


def test_friction_compensation_of_the_paper_friction():
    # paper: fc 0.1 V, fs 0.12 V, vs 0.01 m/s, xi 2; 1 um encoder at 2.5 kHz; |v| <= 1 m/s
    c = friction_compensation_curve(0.1, 0.12, 0.01, 2.0, v_max=1.0, v_resolution=2.5e-3)
    assert 0.1 <= c.level <= 0.12
    assert 500 <= c.slope <= 5000  # the paper chose 900
    assert c.rms_error < 0.02
    # a finer velocity resolution justifies a steeper compensation, about in proportion
    fine = friction_compensation_curve(0.1, 0.12, 0.01, 2.0, v_max=1.0, v_resolution=1.25e-3)
    assert 1.6 < fine.slope / c.slope < 2.4
    # Coulomb friction: the level is fc
    cc = friction_compensation_curve(0.1, None, None, None, v_max=1.0, v_resolution=2.5e-3)
    assert cc.level == pytest.approx(0.1, rel=0.05)


# ----------------------------------------------------------------------------- signals

def test_default_settings_generalise_emps_by_sample_rate():
    assert default_settings(1000.0) == (100.0, 10, 49)  # the EMPS script
    assert default_settings(2500.0) == (100.0, 25, 123)
    assert default_settings(10000.0) == (100.0, 100, 490)
    cutoff, r, _ = default_settings(100.0)
    assert cutoff == pytest.approx(40.0) and r == 1


def test_decimate_keeps_matlab_alignment():
    n, r = 20003, 10
    x = np.arange(n, dtype=float)
    y = decimate(x, r)
    assert y.size == math.ceil(n / r)
    # A zero-phase filter maps a ramp k to G*k (G = its DC gain; an even-order
    # Chebyshev-I has G = 1/(1 + eps^2) < 1), away from the ends.  So the kept
    # samples can be read off: MATLAB keeps nbeg = r - (r*ceil(n/r) - n) = 3 (1-based),
    # i.e. 0-based 2, 12, ..., n-1.
    sos = signal.cheby1(8, 0.05, 0.8 / r, output="sos")
    G = abs(signal.sosfreqz(sos, worN=[0.0])[1][0]) ** 2
    idx = np.arange(2, n, r)
    assert idx[-1] == n - 1
    mid = slice(y.size // 4, 3 * y.size // 4)
    np.testing.assert_allclose(y[mid], G * x[idx][mid], atol=1e-6)
    np.testing.assert_array_equal(decimate(x, 1), x)


def test_zero_phase_lowpass_has_no_delay():
    fs = 1000.0
    t = np.arange(5000) / fs
    x = np.sin(2 * np.pi * 2.0 * t)
    y = zero_phase_lowpass(x, 100.0, fs)
    np.testing.assert_allclose(y[500:-500], x[500:-500], atol=1e-6)


def test_quantization_step():
    rng = np.random.default_rng(4)
    lsb = 5e-8
    q = 0.1234 + lsb * np.cumsum(rng.integers(-3, 4, 5000))
    assert quantization_step(q) == pytest.approx(lsb, rel=1e-9)
    assert quantization_step(np.sin(np.linspace(0, 3, 1000))) is None
    assert quantization_step(np.full(10, 0.2)) is None


def test_check_signals_names_the_bad_sample():
    t = np.arange(10) * 1e-3
    q = np.zeros(10)
    u = np.ones(10)
    bad = q.copy()
    bad[7] = np.nan
    with pytest.raises(SignalError, match="q: sample 7 is nan"):
        check_signals(t, bad, u)
    t2 = t.copy()
    t2[4] = t2[3]
    with pytest.raises(SignalError, match=r"t: not strictly increasing at index 4 \(t\[4\]=0.003 <= t\[3\]=0.003\)"):
        check_signals(t2, q, u)
    t3 = t.copy()
    t3[5:] += 5e-4
    with pytest.raises(SignalError, match="t: not uniformly sampled at index 5"):
        check_signals(t3, q, u)
    with pytest.raises(SignalError, match=r"lengths differ \(t \(10,\), q \(9,\)"):
        check_signals(t, q[:9], u)
    with pytest.raises(SignalError, match=r"u: expected a 1-D array, got shape \(10, 1\)"):
        check_signals(t, q, u[:, None])


# ----------------------------------------------------------------------------- whole-log fits on exact data

FS = 1000.0
TRUTH = dict(M=2.0, B=15.0, fc=3.0, offset=-0.4)


def _exact_log(q_fn, n=20000, truth=TRUTH, rng=None, noise=0.0):
    """Open-loop log whose command is the exact inverse model of an analytic motion."""
    t = np.arange(n) / FS
    q, qd, qdd = q_fn(t)
    u = truth["M"] * qdd + truth["B"] * qd + truth["fc"] * np.sign(qd) + truth["offset"]
    if noise:
        u = u + noise * rng.standard_normal(n)
    return t, q, u


def _multisine(t):
    f = np.array([0.3, 0.7, 1.3, 2.9])
    a = np.array([0.05, 0.02, 0.01, 0.004])
    w = 2 * np.pi * f
    q = (a * np.sin(w * t[:, None])).sum(1)
    qd = (a * w * np.cos(w * t[:, None])).sum(1)
    qdd = -(a * w**2 * np.sin(w * t[:, None])).sum(1)
    return q, qd, qdd


def test_dynamic_fit_on_exact_inverse_model():
    fit = fit_axis(*_exact_log(_multisine), friction="coulomb")
    assert fit.method == "dynamic"
    for name, value in TRUTH.items():
        assert fit.value(name) == pytest.approx(value, rel=0.01, abs=0.01), name
    assert fit.relative_error < 0.02
    assert fit.quantization is None  # a smooth, unquantised position


def test_theta_bounds_closed_form():
    fit = fit_axis(*_exact_log(_multisine), friction="coulomb")
    exact = dataclasses.replace(fit, parameters={"M": (2.0, 0.01), "B": (15.0, 0.1), "fc": (3.0, 0.02),
                                                 "offset": (-0.4, 0.005)})
    b = theta_bounds(exact, k_sigma=0.0, model_margin=0.0, payload_min=0.0, payload_max=4.0,
                     disturbance_bound=1.0)
    assert b.nominal == pytest.approx((0.5, 7.5, 0.2))
    # M in [2, 6], B = 15, d in [0.4 - 1, 0.4 + 1]
    assert b.theta_min == pytest.approx((1 / 6, 15 / 6, -0.6 / 2))
    assert b.theta_max == pytest.approx((0.5, 7.5, 1.4 / 2))
    # delta_d: the residuals' 0.999 quantile over M, on the rows away from reversals
    r = np.asarray(exact.residuals)[exact.model_rows]
    assert 0 < r.size < np.asarray(exact.residuals).size
    assert b.delta_d == pytest.approx(np.quantile(np.abs(r - r.mean()), 0.999) / 2.0)
    # with the statistical and model margins: the k-sigma box around M, B, offset
    b3 = theta_bounds(exact, k_sigma=3.0, model_margin=0.1, payload_max=0.0, disturbance_bound=0.0)
    assert b3.mass_range == pytest.approx(((2 - 0.03) * 0.9, (2 + 0.03) * 1.1))
    assert b3.viscous_range == pytest.approx(((15 - 0.3) * 0.9, (15 + 0.3) * 1.1))
    assert b3.disturbance_range == pytest.approx((0.4 - 0.015, 0.4 + 0.015))
    # defaults: payload up to 3 M, +-20 %, disturbance 10 fc
    bd = theta_bounds(exact)
    assert bd.mass_range[1] == pytest.approx((2 + 0.03) * 1.2 + 6.0)
    assert bd.disturbance_range[1] == pytest.approx(0.4 + 0.015 + 30.0)
    # the bound used, and whether it was the default, travel with the box (tune narrows only a default)
    assert (bd.disturbance_bound, bd.disturbance_bound_defaulted) == (pytest.approx(30.0), True)
    assert (b.disturbance_bound, b.disturbance_bound_defaulted) == (1.0, False)
    with pytest.raises(ValueError, match="payload_min <= payload_max"):
        theta_bounds(exact, payload_min=1.0, payload_max=0.5)


def test_friction_compensation_from_a_fit_uses_its_velocity_range():
    fit = fit_axis(*_exact_log(_multisine), friction="coulomb")
    c = friction_compensation(fit, v_resolution=1e-3)
    assert c.v_max == pytest.approx(fit.v_max)
    assert c.level == pytest.approx(fit.value("fc"), rel=0.05)


def test_refuses_a_constant_command():
    t, q, _ = _exact_log(_multisine)
    with pytest.raises(NotIdentifiableError, match="u: the command is constant"):
        fit_axis(t, q, np.full(t.size, 0.3), friction="coulomb")


def test_refuses_motion_without_reversals():
    def forward(t):
        w = 2 * np.pi * 2.0
        return 0.05 * t + 0.001 * np.sin(w * t), 0.05 + 0.001 * w * np.cos(w * t), -0.001 * w**2 * np.sin(w * t)

    with pytest.raises(NotIdentifiableError, match="no velocity reversals: the Coulomb level is not identifiable"
                                                   ".*condition number"):
        fit_axis(*_exact_log(forward), friction="coulomb")


def test_refuses_a_log_without_acceleration_content():
    def creep(t):
        w = 2 * np.pi * 0.02
        return 0.1 * np.sin(w * t), 0.1 * w * np.cos(w * t), -0.1 * w**2 * np.sin(w * t)

    log = _exact_log(creep, n=60000, truth=dict(TRUTH, M=0.05), rng=np.random.default_rng(5), noise=0.05)
    with pytest.raises(NotIdentifiableError, match="M: no usable acceleration content.*condition number"):
        fit_axis(*log, friction="coulomb")


def test_refuses_a_stribeck_fit_without_slow_motion():
    # fast multisine whose reversals are brief: almost no time below 3 vs
    def fast(t):
        w = 2 * np.pi * 1.0
        return 0.2 * np.sin(w * t), 0.2 * w * np.cos(w * t), -0.2 * w**2 * np.sin(w * t)

    with pytest.raises(NotIdentifiableError, match="Stribeck curve"):
        fit_axis(*_exact_log(fast), friction="stribeck")


def test_a_wide_stribeck_dip_lowers_the_reversal_cut_before_refusing_the_mass(tmp_path):
    """Known truth: random axis 75 (5 kHz, 1.31 kg, force command; fs 10.3 N over fc 7.0 N with vs
    = 25 mm/s, against the excite plan's 0.14 m/s peak speed), recorded as a user of ``commission
    excite`` would.  Cut at 3 vs (76 mm/s), the mass fit keeps too few accelerating rows and M came
    out 0.49 +- 0.25 N s^2/m: refused.  The legs pin the Stribeck curve to 0.2 %, so the fit lowers
    the cut to 1 vs, identifies M within 5 % of the truth, and says so."""
    from commission.identification import identify_log
    from commission.synth import random_axis, record_random_axis_log

    truth = random_axis(np.random.default_rng(75))
    rec = record_random_axis_log(75, tmp_path / "log.h5")
    assert rec.log == "excite", rec.note
    doc = identify_log(str(tmp_path / "log.h5")).ident.to_dict()
    m = doc["parameters"]["M"]
    assert m["value"] == pytest.approx(truth.M, rel=0.05) and m["std"] < 0.05 * m["value"]
    assert doc["parameters"]["vs"]["value"] == pytest.approx(truth.vs, rel=0.01)
    assert any("M: fitted on the rows faster than 1 vs" in w and "did not identify it" in w for w in doc["warnings"])
    # the mass given (identify --fix M) and no ripple: nothing left to regress, the friction map alone
    fixed = identify_log(str(tmp_path / "log.h5"), fix={"M": 1.3}, ripple_pitch=None, find_ripple=False).ident.to_dict()
    assert fixed["parameters"]["M"] == {"value": 1.3, "std": 0.0}
    assert fixed["parameters"]["fs"]["value"] == pytest.approx(truth.fs, rel=0.01)
