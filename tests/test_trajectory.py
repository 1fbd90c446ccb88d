"""Trajectories against closed forms and an independent ODE solver."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from commission.controllers.trajectory import (
    Trajectory,
    TrajectoryError,
    back_and_forth,
    expm_small,
    filter58,
    sample_grid,
    sinusoid,
    smooth,
    trapezoid_moves,
)

TS = 1 / 2500


def test_filter58_critically_damped_closed_form():
    # beta1 = 100, beta2 = 2500: double root at -50.  eps = q_d - q_r solves the
    # homogeneous equation: eps(t) = (c1 + c2 t) exp(-50 t), c1 = eps(0),
    # c2 = deps(0) + 50 eps(0), with q_d(0) = y0 and dq_d(0) = 0.
    A, w, y0 = 0.05, 4.0, 2e-3
    tr = sinusoid(10.0, TS, amplitude=A, omega=w, y0=y0)
    t = tr.t
    qr, dqr, ddqr = A * np.sin(w * t), A * w * np.cos(w * t), -A * w * w * np.sin(w * t)
    c1, c2 = y0, -A * w + 50 * y0
    ex = np.exp(-50 * t)
    eps = (c1 + c2 * t) * ex
    deps = (c2 - 50 * (c1 + c2 * t)) * ex
    ddeps = (-100 * c2 + 2500 * (c1 + c2 * t)) * ex
    np.testing.assert_allclose(tr.qd, qr + eps, rtol=0, atol=1e-14)
    np.testing.assert_allclose(tr.dqd, dqr + deps, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.ddqd, ddqr + ddeps, rtol=0, atol=1e-9)
    # Remark 4 initialisation; ddq_d(0) follows from (58): ddq_r + b1 dq_r + b2 (q_r - q_d).
    assert tr.qd[0] == y0 and tr.dqd[0] == 0.0
    assert tr.ddqd[0] == pytest.approx(100 * A * w - 2500 * y0, rel=1e-12)


def test_filter58_steady_state_is_unit_gain_zero_phase():
    # (58) has transfer function 1: after the transient, q_d = q_r in amplitude and phase.
    tr = sinusoid(10.0, TS)
    late = tr.t > 2.0
    t = tr.t[late]
    X = np.column_stack([np.sin(4 * t), np.cos(4 * t)])
    a, b = np.linalg.lstsq(X, tr.qd[late], rcond=None)[0]
    assert math.hypot(a, b) == pytest.approx(0.05, rel=1e-10)
    assert math.atan2(b, a) == pytest.approx(0.0, abs=1e-10)


def test_filter58_underdamped_matches_ode_solver():
    t = sample_grid(1.0, TS)
    w = 7.0
    qr, dqr, ddqr = np.sin(w * t) ** 2, w * np.sin(2 * w * t), 2 * w * w * np.cos(2 * w * t)
    b1, b2, y0 = 30.0, 2500.0, 0.1
    tr = filter58(t, qr, dqr, ddqr, beta1=b1, beta2=b2, y0=y0)

    def f(tt, z):
        r = math.sin(w * tt) ** 2
        dr = w * math.sin(2 * w * tt)
        ddr = 2 * w * w * math.cos(2 * w * tt)
        return [z[1], ddr + b1 * dr + b2 * r - b1 * z[1] - b2 * z[0]]

    sol = solve_ivp(f, (0, t[-1]), [y0, 0.0], t_eval=t, rtol=1e-11, atol=1e-13, method="DOP853")
    np.testing.assert_allclose(tr.qd, sol.y[0], atol=1e-9)
    np.testing.assert_allclose(tr.dqd, sol.y[1], atol=1e-7)


def test_trapezoid_reference_peaks_travel_and_timing():
    travel, vmax, amax, dwell = 0.4, 1.0, 12.0, 0.5
    sched = trapezoid_moves(travel, vmax, amax, dwell, 6)
    t = np.linspace(0, sched.t_switch[-1] + 0.5, 400_001)
    q, v, a = sched.sample(t)
    assert v.max() == pytest.approx(vmax, rel=1e-12)
    assert v.min() == pytest.approx(-vmax, rel=1e-12)
    assert np.abs(a).max() == amax
    assert q.max() == pytest.approx(travel, abs=1e-12)
    assert q[-1] == pytest.approx(0.0, abs=1e-12)
    # Move time travel/v + v/a, six moves and six dwells.
    t_move = travel / vmax + vmax / amax
    assert sched.t_switch[-1] == pytest.approx(6 * (t_move + dwell), rel=1e-12)
    # Rest during the first dwell and at the far end after the first move.
    assert np.all(q[t < dwell] == 0.0)
    mid = (t > dwell + t_move + 1e-9) & (t < 2 * dwell + t_move - 1e-9)
    assert np.allclose(q[mid], travel, atol=1e-12) and np.all(np.abs(v[mid]) < 1e-12)


def test_short_move_is_triangular():
    sched = trapezoid_moves(0.01, 1.0, 12.0, 0.1, 2)
    v_peak = math.sqrt(0.01 * 12.0)
    # Accelerate for v_peak/a, then decelerate at once (no cruise).
    assert sched.t_switch[1] - sched.t_switch[0] == pytest.approx(v_peak / 12.0, rel=1e-12)
    _, v, _ = sched.sample(sched.t_switch[1:2])
    assert v[0] == pytest.approx(v_peak, rel=1e-12)
    q, _, _ = sched.sample(sched.t_switch[3:4])
    assert q[0] == pytest.approx(0.01, abs=1e-15)


def test_smoothing_matches_ode_solver_piecewise():
    # Integrate b2/(s^2+b1 s+b2) segment by segment (no discontinuity inside a
    # segment) with a tight ODE solver, driven by the exact reference.
    sched = trapezoid_moves(0.4, 1.0, 12.0, 0.5, 2)
    t = sample_grid(2.5, TS)
    tr = smooth(sched, t)
    b1, b2 = 100.0, 2500.0
    bounds = np.concatenate(([0.0], sched.t_switch, [t[-1]]))
    z = np.array([0.0, 0.0])
    ref = np.empty((t.size, 2))
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        sel = (t >= lo) & (t < hi) if hi < t[-1] else (t >= lo)
        if hi <= lo:
            continue

        def f(tt, zz):
            r = sched.sample(np.array([tt]))[0][0]
            return [zz[1], b2 * (r - zz[0]) - b1 * zz[1]]

        sol = solve_ivp(f, (lo, hi), z, t_eval=t[sel], rtol=1e-11, atol=1e-14, method="DOP853",
                        dense_output=True)
        ref[sel] = sol.y.T if sel.any() else ref[sel]
        z = sol.sol(hi)
    np.testing.assert_allclose(tr.qd, ref[:, 0], atol=2e-10)
    np.testing.assert_allclose(tr.dqd, ref[:, 1], atol=2e-8)


def test_case2_paper_defaults():
    tr = back_and_forth()
    assert tr.n == 20000 and tr.Ts == pytest.approx(TS)
    assert tr.qd.max() == pytest.approx(0.4, abs=1e-9)
    assert abs(tr.qd[-1]) < 1e-12
    # Smoothing keeps the limits (unit DC gain, no overshoot for a critically damped filter).
    assert np.abs(tr.dqd).max() <= 1.0 + 1e-9
    assert np.abs(tr.ddqd).max() <= 12.0 + 1e-9
    assert np.abs(tr.ddqd).max() > 10.0


def test_expm_small_matches_scipy():
    rng = np.random.default_rng(0)
    for scale in (1e-4, 1.0, 50.0):
        X = rng.normal(size=(5, 5)) * scale
        np.testing.assert_allclose(expm_small(X), expm(X), rtol=1e-11, atol=1e-13 * np.abs(expm(X)).max())


def test_errors_name_the_field():
    t = np.array([0.0, 1e-3, 2e-3, 2e-3])
    with pytest.raises(TrajectoryError, match=r"Trajectory.t: not uniformly sampled at index 3"):
        Trajectory(t, t, t, t)
    with pytest.raises(TrajectoryError, match=r"duration: 5.0 s is shorter than the 6 moves"):
        back_and_forth(5.0)
    with pytest.raises(TrajectoryError, match="v_max"):
        trapezoid_moves(0.4, -1.0, 12.0, 0.5, 6)
    q = np.zeros(10)
    q[4] = np.inf
    with pytest.raises(TrajectoryError, match="Trajectory.qd: sample 4 is inf"):
        Trajectory(np.arange(10) * 1e-3, q, np.zeros(10), np.zeros(10))


def test_trajectory_arrays_are_read_only():
    tr = sinusoid(1.0)
    with pytest.raises(ValueError):
        tr.qd[0] = 1.0
