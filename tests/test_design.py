"""Gain-design numerics: observer poles, Lyapunov P of (11), Theorem 1, discrete feasibility.

References are independent closed forms (Kronecker-product solution of the
Lyapunov equation, the analytic ZOH of a mass-damper, the hand-derived
closed-loop matrix of the PID law (57) on that plant) and the paper's numbers.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from commission.controllers.arc import arc_pack, paper_gains_as_printed
from commission.controllers.design import (
    KIND_ARC,
    KIND_PID,
    PID_DYNAMIC_STATES,
    DesignError,
    discrete_feasibility,
    loop_jacobian,
    lyapunov_P,
    observer_design,
    theorem1_check,
    theta2_for_theorem1,
    theta_corners,
    zoh_plant,
)
from commission.controllers.pid import PidGains, pid_new_state, pid_pack, pid_place_poles, pid_reset
from commission.controllers.trajectory import sinusoid

TS = 1.0 / 2500.0


def test_observer_pole_placement_matches_the_paper():
    d = observer_design(200.0, TS)
    assert (d.k1, d.k2) == (400.0, 4e4)  # paper §4.3: roots at -200 -> k1 = 400, k2 = 4e4
    A0 = np.array([[-d.k1, 1.0], [-d.k2, 0.0]])
    assert np.allclose(np.linalg.eigvals(A0), -200.0, atol=1e-3)  # double root
    assert d.discrete_pole == pytest.approx(math.exp(-0.08))


@pytest.mark.parametrize("k1, k2", [(400.0, 4e4), (10.0, 3.0), (1e3, 1e6)])
def test_lyapunov_P_solves_eq_11(k1, k2):
    A0 = np.array([[-k1, 1.0], [-k2, 0.0]])
    # independent solution: vec(P A0 + A0^T P) = (A0^T (x) I + I (x) A0^T) vec(P) = -vec(I)
    K = np.kron(A0.T, np.eye(2)) + np.kron(np.eye(2), A0.T)
    P_ref = np.linalg.solve(K, -np.eye(2).ravel()).reshape(2, 2)
    P = lyapunov_P(k1, k2)
    assert np.allclose(P, P_ref, rtol=1e-9, atol=0)
    assert np.allclose(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0)


def test_unstable_observer_is_rejected():
    with pytest.raises(DesignError, match="Hurwitz"):
        lyapunov_P(-1.0, 4e4)
    with pytest.raises(DesignError, match="positive"):
        observer_design(0.0)


def test_theorem1_on_the_papers_gains():
    g = paper_gains_as_printed()
    c = theorem1_check(g.w1, g.w2, g.C_phi1, g.C_phi2, g.C_theta2)
    # c_phi12^2 = (5e-6)^2 = 2.5e-11 against w1 w2 / (2 c_theta2^2) = 0.1 / 2e10 = 5e-12: ratio 5,
    # the tightest of the six inequalities.
    assert c.holds and c.min_ratio == pytest.approx(5.0)
    assert c.ratios[0][0] == pytest.approx(2.5e-9 / 5e-12)
    assert c.ratios[1][2] == pytest.approx(1e-8 / 5e-13)
    bad = theorem1_check(g.w1, g.w2, g.C_phi1, g.C_phi2, (1e5, 1e3, 1e5))
    assert not bad.holds and bad.min_ratio == pytest.approx(5.0 * 1e-4)
    ct = theta2_for_theorem1(g.w1, g.w2, g.C_phi1, g.C_phi2, factor=1.0)
    assert theorem1_check(g.w1, g.w2, g.C_phi1, g.C_phi2, ct).min_ratio == pytest.approx(1.0)


def test_zoh_plant_closed_form():
    M, B = 0.027, 0.273
    a = B / M
    e = math.exp(-a * TS)
    Phi, Gam = zoh_plant(M, B, TS)
    assert np.allclose(Phi, [[1.0, (1 - e) / a], [0.0, e]], rtol=1e-12)
    assert np.allclose(Gam, [(TS - (1 - e) / a) / (a * M), (1 - e) / (a * M)], rtol=1e-9)


def test_theta_corners():
    c = theta_corners((8.3, 2.4, -50.0), (50.0, 17.5, 50.0))
    assert c.shape == (8, 3) and len({tuple(r) for r in c}) == 8
    assert set(c[:, 0]) == {8.3, 50.0} and set(c[:, 2]) == {-50.0, 50.0}


def _pid_gains(M_design: float = 0.02, pole: float = -300.0) -> PidGains:
    Kp, Ki, Kd = pid_place_poles(M_design, pole)
    return PidGains(Ts=TS, M_hat=0.05, B_hat=0.24, Kp=Kp, Ki=Ki, Kd=Kd, fric_level=0.0, fric_slope=0.0)


def _pid_matrix(g: PidGains, M: float, B: float) -> np.ndarray:
    """Closed-loop matrix of (57) (no friction term) on the exact ZOH plant, state [x, v, y_prev, I]."""
    Phi, Gam = zoh_plant(M, B, TS)
    du = np.array([g.B_hat / TS - g.Kp - g.Ki * TS - g.Kd / TS, 0.0, -g.B_hat / TS + g.Kd / TS, -g.Ki])
    J = np.zeros((4, 4))
    J[0, :2] = Phi[0]
    J[1, :2] = Phi[1]
    J[0] += Gam[0] * du
    J[1] += Gam[1] * du
    J[2, 0] = 1.0
    J[3, 0] = TS
    J[3, 3] = 1.0
    return J


def test_numerical_jacobian_matches_the_hand_derived_pid_loop():
    g = _pid_gains()
    p = pid_pack(g)
    s = pid_new_state(p)
    pid_reset(p, s, 0.01)
    s[1] = 3e-6  # some integral
    M, B = 0.05, 0.5
    Phi, Gam = zoh_plant(M, B, TS)
    J = loop_jacobian(KIND_PID, p, s, 0.0101, 0.02, 0.01, 0.03, 0.5, Phi, Gam, 0.1, math.inf, PID_DYNAMIC_STATES)
    assert np.allclose(J, _pid_matrix(g, M, B), rtol=1e-6, atol=1e-9)


def test_pid_feasibility_equals_the_analytic_spectral_radius():
    g = _pid_gains()
    lo, hi = (8.3, 2.4, -50.0), (50.0, 17.5, 50.0)
    rep = discrete_feasibility(KIND_PID, pid_pack(g), lo, hi, [sinusoid(1.0, TS)], margin=0.001, n_points=3)
    # the linearised PID loop is time-invariant: every point of a corner has the analytic radius
    rho_ref = max(max(abs(np.linalg.eigvals(_pid_matrix(g, 1 / th[0], th[1] / th[0])))) for th in theta_corners(lo, hi))
    assert rep.rho_max == pytest.approx(rho_ref, rel=1e-6)
    assert rep.holds == (rho_ref < 0.999)
    assert len(rep.points) % 8 == 0 and len(rep.points) >= 16  # 8 corners x several points each


def test_feasibility_detects_a_sampled_loop_pushed_past_its_limit():
    # Poles at -2000 rad/s (omega T = 0.8) for the lightest mass: fine in continuous time,
    # unstable once sampled with a backward-difference velocity.
    g = _pid_gains(pole=-2000.0)
    rep = discrete_feasibility(KIND_PID, pid_pack(g), (8.3, 2.4, -50.0), (50.0, 17.5, 50.0), [sinusoid(1.0, TS)],
                               n_points=2)
    assert not rep.holds and rep.rho_max > 1.0


def test_arc_as_printed_is_infeasible_and_bounded_gains_are_feasible():
    g = paper_gains_as_printed(TS)
    trajs = [sinusoid(2.0, TS)]
    printed = discrete_feasibility(KIND_ARC, arc_pack(g), g.theta_min, g.theta_max, trajs, n_points=3)
    assert not printed.holds and printed.rho_max > 1.0
    capped = dataclasses.replace(g, k1s_max=g.g1, k2s_max=g.g2)
    rep = discrete_feasibility(KIND_ARC, arc_pack(capped), g.theta_min, g.theta_max, trajs, n_points=3)
    assert rep.holds and 0.9 < rep.rho_max < 0.99  # slowest: the sampled observer/filter modes near exp(-200 Ts)
    assert rep.rho_max >= math.exp(-200.0 * TS) - 1e-9
