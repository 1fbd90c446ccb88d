"""The paper's desired trajectories (sec. 4): reference filter (58), Case 1 and Case 2.

Two generators, both discretised exactly (no integration error):

* :func:`filter58` -- the paper's reference filter (58),
  ``ddq_d + b1 dq_d + b2 q_d = ddq_r + b1 dq_r + b2 q_r``, with the Remark-4
  initialisation ``q_d(0) = y(0)``, ``dq_d(0) = 0``.  Its transfer function is
  one, so ``eps = q_d - q_r`` obeys the homogeneous equation
  ``ddeps + b1 deps + b2 eps = 0`` and is propagated exactly by the matrix
  exponential; ``q_d = q_r + eps`` then uses the analytic ``q_r``
  derivatives.  (The paper also lists ``ddq_d(0) = 0``; for a second-order
  filter that value is not free: it follows from the equation, e.g.
  ``ddq_d(0) = b1 dq_r(0) = 20 m/s^2`` for Case 1 with ``y(0) = 0``.)
* :func:`back_and_forth` -- Case 2: trapezoidal-velocity moves smoothed by
  ``b2 / (s^2 + b1 s + b2)``.  The reference has piecewise-constant
  acceleration, so the filter plus reference form a linear system with a
  constant input between switch instants, advanced exactly by matrix
  exponentials (splitting the sample interval at each switch).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from commission.controllers.trajectory.core import (Trajectory, TrajectoryError, expm_small, grid_period,
    require_positive_finite, sample_grid)
from commission.controllers.trajectory.schedules import AccelSchedule


@njit(cache=True)
def _homogeneous(Phi, e0, de0, n):
    """Samples of the 2-state homogeneous solution ``[eps, deps]_{k+1} = Phi [eps, deps]_k``."""
    eps = np.empty(n)
    deps = np.empty(n)
    e, de = e0, de0
    for k in range(n):
        eps[k] = e
        deps[k] = de
        e, de = Phi[0, 0] * e + Phi[0, 1] * de, Phi[1, 0] * e + Phi[1, 1] * de
    return eps, deps


def filter58(t: np.ndarray, qr: np.ndarray, dqr: np.ndarray, ddqr: np.ndarray, *,
             beta1: float = 100.0, beta2: float = 2500.0, y0: float = 0.0) -> Trajectory:
    """Reference filter (58) with the Remark-4 initialisation, exact at the samples.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times starting at 0, s.
    qr, dqr, ddqr : ndarray, shape (N,)
        Reference position (m), velocity (m/s), acceleration (m/s^2) at ``t``.
    beta1 : float
        Filter coefficient, 1/s (paper: 100).
    beta2 : float
        Filter coefficient, 1/s^2 (paper: 2500).
    y0 : float
        Initial measured position, m; ``q_d(0) = y0`` and ``dq_d(0) = 0``.

    Returns
    -------
    Trajectory
    """
    if not (beta1 > 0 and beta2 > 0):
        raise TrajectoryError(f"beta1, beta2: must be > 0 for a stable filter, got {beta1}, {beta2}")
    t = np.asarray(t, dtype=np.float64)
    qr, dqr, ddqr = (np.asarray(a, dtype=np.float64) for a in (qr, dqr, ddqr))
    Ts = grid_period(t, qr, dqr, ddqr)
    A = np.array([[0.0, 1.0], [-beta2, -beta1]])
    Phi = expm_small(A * Ts)
    # q_d(0) = y0, dq_d(0) = 0
    eps, deps = _homogeneous(Phi, float(y0 - qr[0]), float(-dqr[0]), t.shape[0])
    ddeps = -beta1 * deps - beta2 * eps
    return Trajectory(t, qr + eps, dqr + deps, ddqr + ddeps)


def sinusoid(duration: float = 10.0, Ts: float = 1.0 / 2500.0, *, amplitude: float = 0.05,
             omega: float = 4.0, beta1: float = 100.0, beta2: float = 2500.0,
             y0: float = 0.0) -> Trajectory:
    """Case 1: ``q_r = amplitude sin(omega t)`` through filter (58).

    Parameters
    ----------
    duration : float
        Length, s (``round(duration/Ts)`` samples).
    Ts : float
        Sample period, s.
    amplitude : float
        Reference amplitude, m (paper: 0.05).
    omega : float
        Reference frequency, rad/s (paper: 4).
    beta1, beta2 : float
        Filter (58) coefficients, 1/s and 1/s^2.
    y0 : float
        Initial measured position, m.
    """
    t = sample_grid(duration, Ts)
    s, c = np.sin(omega * t), np.cos(omega * t)
    return filter58(t, amplitude * s, amplitude * omega * c, -amplitude * omega ** 2 * s,
                    beta1=beta1, beta2=beta2, y0=y0)


def trapezoid_moves(travel: float, v_max: float, a_max: float, dwell: float, n_moves: int,
                    *, start: float = 0.0) -> AccelSchedule:
    """Back-and-forth point-to-point moves with a trapezoidal velocity profile.

    The axis rests ``dwell`` seconds, moves ``+travel``, rests ``dwell``, moves
    ``-travel``, ... for ``n_moves`` moves.  A move too short to reach
    ``v_max`` becomes triangular with peak speed ``sqrt(travel a_max)``.

    Parameters
    ----------
    travel : float
        Length of each move, m (> 0).
    v_max : float
        Speed limit, m/s.
    a_max : float
        Acceleration limit, m/s^2.
    dwell : float
        Rest before each move, s.
    n_moves : int
        Number of moves (alternating direction).
    start : float
        Start position, m.
    """
    require_positive_finite(travel=travel, v_max=v_max, a_max=a_max)
    if not (dwell >= 0 and math.isfinite(dwell)):
        raise TrajectoryError(f"dwell: must be >= 0 s, got {dwell}")
    if int(n_moves) != n_moves or n_moves < 1:
        raise TrajectoryError(f"n_moves: must be a positive integer, got {n_moves}")
    v_peak = min(v_max, math.sqrt(travel * a_max))
    t_acc = v_peak / a_max
    t_cruise = travel / v_peak - t_acc  # 0 for a triangular move
    ts: list[float] = []
    acc: list[float] = []
    t = 0.0
    for m in range(int(n_moves)):
        sgn = 1.0 if m % 2 == 0 else -1.0
        t += dwell
        ts += [t, t + t_acc, t + t_acc + t_cruise, t + 2 * t_acc + t_cruise]
        acc += [sgn * a_max, 0.0, -sgn * a_max, 0.0]  # the last 0 holds through the next dwell
        t += 2 * t_acc + t_cruise
    return AccelSchedule(np.array(ts), np.array(acc[:-1]), float(start))


def smooth(schedule: AccelSchedule, t: np.ndarray, *, b1: float = 100.0,
           b2: float = 2500.0) -> Trajectory:
    """Filter a piecewise-constant-acceleration reference by ``b2/(s^2 + b1 s + b2)``, exactly.

    The filter starts at rest at the reference's start position.

    Parameters
    ----------
    schedule : AccelSchedule
        Reference.
    t : ndarray, shape (N,)
        Uniform sample times starting at 0, s.
    b1, b2 : float
        Filter coefficients, 1/s and 1/s^2.
    """
    if not (b1 > 0 and b2 > 0):
        raise TrajectoryError(f"b1, b2: must be > 0 for a stable filter, got {b1}, {b2}")
    t = np.asarray(t, dtype=np.float64)
    n = t.shape[0]
    Ts = grid_period(t, t, t, t)
    # State z = [q_d, dq_d, q_r, dq_r, a]; a is the held reference acceleration.
    A = np.zeros((5, 5))
    A[0, 1] = 1.0
    A[1, 0], A[1, 1], A[1, 2] = -b2, -b1, b2
    A[2, 3] = 1.0
    A[3, 4] = 1.0
    out = _smooth_kernel(A, float(Ts), n, schedule.t_switch, np.append(schedule.accel, 0.0),
                         float(schedule.q0))
    qd, dqd, qr = out[:, 0], out[:, 1], out[:, 2]
    ddqd = b2 * (qr - qd) - b1 * dqd
    return Trajectory(t, qd, dqd, ddqd)


@njit(cache=True)
def _smooth_kernel(A, Ts, n, ts, acc_after, q0):
    """Exact samples of z = [q_d, dq_d, q_r, dq_r, a]; ``acc_after[j]`` holds from ``ts[j]`` on."""
    Phi = expm_small(A * Ts)
    z = np.array([q0, 0.0, q0, 0.0, 0.0])
    out = np.empty((n, 5))
    nb = ts.shape[0]
    j = 0  # next boundary not yet applied
    while j < nb and ts[j] <= 0.0:
        z[4] = acc_after[j]
        j += 1
    for k in range(n):
        out[k] = z
        tk = k * Ts
        t_end = tk + Ts
        if j < nb and ts[j] < t_end:
            # Split the sample interval at each boundary inside it.
            while j < nb and ts[j] < t_end:
                z = expm_small(A * (ts[j] - tk)) @ z
                tk = ts[j]
                z[4] = acc_after[j]
                j += 1
            z = expm_small(A * (t_end - tk)) @ z
        else:
            z = Phi @ z
    return out


def back_and_forth(duration: float = 8.0, Ts: float = 1.0 / 2500.0, *, travel: float = 0.4,
                   v_max: float = 1.0, a_max: float = 12.0, dwell: float = 0.5, n_moves: int = 6,
                   b1: float = 100.0, b2: float = 2500.0, start: float = 0.0) -> Trajectory:
    """Case 2: ``n_moves`` trapezoidal moves ``start -> start+travel -> start ...``, smoothed.

    Defaults are the paper's (0 -> 0.4 m -> 0, 6 moves, 1 m/s, 12 m/s^2,
    0.5 s dwell, 8 s).  The moves must end within ``duration``.

    Parameters
    ----------
    duration : float
        Length, s.
    Ts : float
        Sample period, s.
    travel, v_max, a_max, dwell, n_moves, start
        See :func:`trapezoid_moves` (m, m/s, m/s^2, s, -, m).
    b1, b2 : float
        Smoothing-filter coefficients, 1/s and 1/s^2.
    """
    sched = trapezoid_moves(travel, v_max, a_max, dwell, n_moves, start=start)
    t = sample_grid(duration, Ts)
    if sched.t_switch[-1] > t[-1]:
        raise TrajectoryError(
            f"duration: {duration} s is shorter than the {n_moves} moves ({sched.t_switch[-1]:.4g} s)")
    return smooth(sched, t, b1=b1, b2=b2)
