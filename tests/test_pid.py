"""PID law (57) and pole placement (56)."""

import math

import numpy as np
import pytest

from commission.controllers.pid import (
    PidGains,
    pid_new_state,
    pid_pack,
    pid_place_poles,
    pid_reset,
    pid_step,
)


def test_pole_placement_reproduces_the_papers_gains():
    # Paper, Sec. 4.3: all poles at -300 for M_min = 0.02 -> Kp 5.4e3, Ki 5.4e5, Kd 18;
    # at -320 -> Kp 6144, Ki 655360, Kd 19.2.
    assert pid_place_poles(0.02, -300.0) == pytest.approx((5400.0, 5.4e5, 18.0), rel=1e-12)
    assert pid_place_poles(0.02, -320.0) == pytest.approx((6144.0, 655360.0, 19.2), rel=1e-12)


def test_pole_placement_roots_of_56():
    M, pole = 0.037, -212.0
    Kp, Ki, Kd = pid_place_poles(M, pole)
    roots = np.roots([1.0, Kd / M, Kp / M, Ki / M])
    # A triple root is ill-conditioned numerically: |perturbation| ~ eps^(1/3) |pole|.
    np.testing.assert_allclose(roots, pole, atol=1e-3 * abs(pole))
    with pytest.raises(ValueError, match="pole must be < 0"):
        pid_place_poles(0.02, 300.0)


def test_step_sequence_by_hand():
    g = PidGains(Ts=1e-3, M_hat=0.05, B_hat=0.24, Kp=100.0, Ki=1000.0, Kd=2.0,
                 fric_level=0.1, fric_slope=900.0)
    p = pid_pack(g)
    s = pid_new_state(p)
    pid_reset(p, s, 0.001)
    # Sample 1: y = 0.001 (no motion yet), qd = 0, dqd = 0.1, ddqd = 2.
    u1 = pid_step(p, s, 0.001, 0.0, 0.1, 2.0)
    e1, I1 = 0.001, 1e-3 * 0.001
    assert u1 == pytest.approx(0.05 * 2 - 100 * e1 - 1000 * I1 - 2 * (0.0 - 0.1), rel=1e-14)
    # Sample 2: y moves 2 um in one period -> v = 0.002 m/s.
    y2 = 0.001002
    u2 = pid_step(p, s, y2, 0.0005, 0.1, 2.0)
    v2 = (y2 - 0.001) / 1e-3
    e2 = y2 - 0.0005
    I2 = I1 + 1e-3 * e2
    expect = (0.05 * 2 + 0.24 * v2 + 0.1 * (2 / math.pi) * math.atan(900 * v2)
              - 100 * e2 - 1000 * I2 - 2 * (v2 - 0.1))
    assert u2 == pytest.approx(expect, rel=1e-13)


def test_output_limit_and_reset():
    g = PidGains(Ts=1e-3, M_hat=0.0, B_hat=0.0, Kp=1e6, Ki=0.0, Kd=0.0, u_max=2.5)
    p = pid_pack(g)
    s = pid_new_state(p)
    pid_reset(p, s, 0.0)
    assert pid_step(p, s, 1.0, 0.0, 0.0, 0.0) == -2.5
    assert pid_step(p, s, -1.0, 0.0, 0.0, 0.0) == 2.5
    pid_reset(p, s, 0.3)
    assert s.tolist() == [0.3, 0.0, 0.0]  # y_prev, integral, no fault


def test_non_finite_input_latches_the_safe_command():
    g = PidGains(Ts=1e-3, M_hat=0.01, B_hat=0.1, Kp=100.0, Ki=10.0, Kd=1.0, u_max=2.5)
    p = pid_pack(g)
    s = pid_new_state(p)
    pid_reset(p, s, 0.0)
    assert pid_step(p, s, 1e-3, 0.0, 0.0, 0.0) != 0.0
    kept = s.copy()
    assert pid_step(p, s, math.nan, 0.0, 0.0, 0.0) == 0.0
    assert s[2] == 1.0 and s[:2].tolist() == kept[:2].tolist()  # latched, state kept
    assert pid_step(p, s, 1e-3, 0.0, 0.0, 0.0) == 0.0  # until pid_reset
    pid_reset(p, s, 0.0)
    assert pid_step(p, s, 1e-3, 0.0, 0.0, 0.0) != 0.0


def test_gains_are_validated():
    with pytest.raises(ValueError, match="PidGains.Ts"):
        PidGains(Ts=0.0, M_hat=0.05, B_hat=0.24, Kp=1.0, Ki=1.0, Kd=1.0)
    with pytest.raises(ValueError, match="PidGains.Kd: must be finite"):
        PidGains(Ts=1e-3, M_hat=0.05, B_hat=0.24, Kp=1.0, Ki=1.0, Kd=math.nan)
