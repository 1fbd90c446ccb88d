"""Desired trajectories ``q_d, dq_d, ddq_d`` sampled at the controller rate.

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
from dataclasses import dataclass

import numpy as np
from numba import njit


class TrajectoryError(ValueError):
    """A trajectory parameter or sample grid is invalid."""


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Trajectory:
    """Desired motion on a uniform sample grid.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Sample times ``k Ts``, s, starting at 0.
    qd : ndarray, shape (N,)
        Desired position, m.
    dqd : ndarray, shape (N,)
        Desired velocity, m/s.
    ddqd : ndarray, shape (N,)
        Desired acceleration, m/s^2.
    """

    t: np.ndarray
    qd: np.ndarray
    dqd: np.ndarray
    ddqd: np.ndarray

    def __post_init__(self) -> None:
        n = None
        for name in ("t", "qd", "dqd", "ddqd"):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.ndim != 1:
                raise TrajectoryError(f"Trajectory.{name}: expected a 1-D array, got shape {a.shape}")
            if n is None:
                n = a.shape[0]
            elif a.shape[0] != n:
                raise TrajectoryError(f"Trajectory.{name}: has {a.shape[0]} samples, t has {n}")
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise TrajectoryError(f"Trajectory.{name}: sample {bad[0]} is {a[bad[0]]}")
            object.__setattr__(self, name, _frozen(a))
        if n < 2:
            raise TrajectoryError(f"Trajectory.t: need at least 2 samples, got {n}")
        dt = np.diff(self.t)
        Ts = dt[0]
        if not Ts > 0:
            raise TrajectoryError(f"Trajectory.t: not strictly increasing at index 1 (t[1]={self.t[1]} <= t[0]={self.t[0]})")
        off = np.flatnonzero(np.abs(dt - Ts) > 1e-9 * max(Ts, 1.0))
        if off.size:
            i = off[0] + 1
            raise TrajectoryError(f"Trajectory.t: not uniformly sampled at index {i} (t[{i}]-t[{i-1}]={dt[i-1]}, Ts={Ts})")

    @property
    def Ts(self) -> float:
        """Sample period, s."""
        return float(self.t[1] - self.t[0])

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])


@njit(cache=True)
def expm_small(X):
    """Matrix exponential of a small dense matrix: scaling and squaring with Taylor(18).

    Plain loops on purpose: LAPACK-based ``scipy.linalg.expm`` can take tens of
    ms per call on a busy multi-threaded BLAS, and the smoother needs one
    per switch instant.  After scaling, ``||X||_1 <= 1/2`` and the truncation
    error is below 1e-21 (relative).
    """
    n = X.shape[0]
    norm = 0.0
    for j in range(n):
        c = 0.0
        for i in range(n):
            c += abs(X[i, j])
        norm = max(norm, c)
    sq = 0
    while norm > 0.5:
        norm *= 0.5
        sq += 1
    Y = X / (2.0 ** sq)
    E = np.eye(n)
    term = np.eye(n)
    for k in range(1, 19):
        term = (term @ Y) / k
        E += term
    for _ in range(sq):
        E = E @ E
    return E


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


def sample_grid(duration: float, Ts: float) -> np.ndarray:
    """Times ``0, Ts, ..., `` covering ``[0, duration)``: ``round(duration/Ts)`` samples, s."""
    if not (Ts > 0 and math.isfinite(Ts)):
        raise TrajectoryError(f"Ts: must be a positive number of seconds, got {Ts}")
    if not (duration > 0 and math.isfinite(duration)):
        raise TrajectoryError(f"duration: must be a positive number of seconds, got {duration}")
    n = int(round(duration / Ts))
    if n < 2:
        raise TrajectoryError(f"duration: {duration} s holds fewer than 2 samples of Ts={Ts} s")
    return np.arange(n) * Ts


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
    Trajectory(t, qr, dqr, ddqr)  # validates shapes and the grid
    if t[0] != 0.0:
        raise TrajectoryError(f"t: must start at 0 s, got t[0]={t[0]}")
    Ts = t[1] - t[0]
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


@dataclass(frozen=True)
class AccelSchedule:
    """A reference with piecewise-constant acceleration.

    Attributes
    ----------
    t_switch : ndarray, shape (K+1,)
        Segment boundaries, s, increasing; acceleration is zero before the
        first and after the last.
    accel : ndarray, shape (K,)
        Acceleration on each segment, m/s^2.
    q0 : float
        Position at ``t = 0``, m (the reference starts at rest).
    """

    t_switch: np.ndarray
    accel: np.ndarray
    q0: float = 0.0

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact reference position (m), velocity (m/s), acceleration (m/s^2) at ``t``."""
        t = np.asarray(t, dtype=np.float64)
        ts, a = self.t_switch, self.accel
        # Velocity and position at each boundary, integrating segment by segment.
        dur = np.diff(ts)
        v_b = np.concatenate(([0.0], np.cumsum(a * dur)))
        q_b = self.q0 + np.concatenate(([0.0], np.cumsum(v_b[:-1] * dur + 0.5 * a * dur ** 2)))
        # Boundary at or before each t, clipped into the schedule; before the
        # first boundary tau = 0 (at rest at q0), after the last acc = 0.
        i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(a))
        tau = np.maximum(t - ts[i], 0.0)
        acc = np.where(t >= ts[0], np.append(a, 0.0)[i], 0.0)
        q = q_b[i] + v_b[i] * tau + 0.5 * acc * tau ** 2
        v = v_b[i] + acc * tau
        return q, v, acc


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
    for name, val in (("travel", travel), ("v_max", v_max), ("a_max", a_max)):
        if not (val > 0 and math.isfinite(val)):
            raise TrajectoryError(f"{name}: must be a positive finite number, got {val}")
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
    Trajectory(t, t, t, t)  # validates the grid
    if t[0] != 0.0:
        raise TrajectoryError(f"t: must start at 0 s, got t[0]={t[0]}")
    Ts = t[1] - t[0]
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


# ---------------------------------------------------------------------------
# The machine's own moves: S-curve point-to-point moves and sampled profiles.
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class JerkSchedule:
    """A reference with piecewise-constant jerk, starting at rest.

    Attributes
    ----------
    t_switch : ndarray, shape (K+1,)
        Segment boundaries, s, non-decreasing; jerk, acceleration and velocity
        are zero before the first and after the last (a schedule ends at rest).
    jerk : ndarray, shape (K,)
        Jerk on each segment, m/s^3 (``inf`` is not allowed: an unlimited jerk
        is a segment of zero length and is left out).
    q0 : float
        Position at ``t = 0``, m.
    """

    t_switch: np.ndarray
    jerk: np.ndarray
    q0: float = 0.0

    def boundaries(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (m), velocity (m/s), acceleration (m/s^2) at each boundary, exact polynomials."""
        ts, j = np.asarray(self.t_switch, float), np.asarray(self.jerk, float)
        K = j.shape[0]
        q, v, a = np.empty(K + 1), np.empty(K + 1), np.empty(K + 1)
        q[0], v[0], a[0] = self.q0, 0.0, 0.0
        for k in range(K):
            d = ts[k + 1] - ts[k]
            q[k + 1] = q[k] + v[k] * d + a[k] * d * d / 2.0 + j[k] * d ** 3 / 6.0
            v[k + 1] = v[k] + a[k] * d + j[k] * d * d / 2.0
            a[k + 1] = a[k] + j[k] * d
        return q, v, a

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact position (m), velocity (m/s), acceleration (m/s^2) at ``t`` (s).

        After the last boundary the reference holds its final position at rest
        (velocity and acceleration are exactly zero there, whatever the rounding
        of the boundary values).
        """
        t = np.asarray(t, dtype=np.float64)
        ts, j = np.asarray(self.t_switch, float), np.asarray(self.jerk, float)
        qb, vb, ab = self.boundaries()
        i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(j))
        inside = (t >= ts[0]) & (i < len(j))
        jj = np.where(inside, np.append(j, 0.0)[i], 0.0)
        tau = np.maximum(t - ts[i], 0.0)
        a0 = np.where(inside, ab[i], 0.0)
        v0 = np.where(inside, vb[i], 0.0)
        q = qb[i] + v0 * tau + a0 * tau ** 2 / 2.0 + jj * tau ** 3 / 6.0
        v = v0 + a0 * tau + jj * tau ** 2 / 2.0
        a = a0 + jj * tau
        return q, v, a

    @property
    def end(self) -> float:
        """Time of the last boundary, s (the reference is at rest from then on)."""
        return float(self.t_switch[-1])


def scurve_segments(distance: float, v_max: float, a_max: float,
                    j_max: float = math.inf) -> tuple[list[float], list[float], float, float]:
    """Time-optimal rest-to-rest move under speed, acceleration and jerk limits (the S-curve).

    Seven phases of constant jerk ``+j, 0, -j, 0, -j, 0, +j`` (times the move's
    sign): the acceleration rises to its peak at ``j_max``, holds, falls to zero;
    the speed cruises; the deceleration mirrors the acceleration.  A move too short
    to reach ``v_max`` has no cruise, and one too short (or a jerk too low) to reach
    ``a_max`` has no constant-acceleration phase; the peak speed is then the
    largest one whose two ramps fit in ``distance``.  ``j_max = inf`` gives the
    trapezoid (its jerk phases have zero length and are dropped).

    Parameters
    ----------
    distance : float
        Signed length of the move, m.
    v_max, a_max : float
        Speed (m/s) and acceleration (m/s^2) limits, positive.
    j_max : float
        Jerk limit, m/s^3, positive (``inf``: unlimited).

    Returns
    -------
    durations : list of float
        Phase durations, s (phases of zero length dropped).
    jerks : list of float
        Jerk of each phase, m/s^3 (0 on the constant-acceleration and cruise phases;
        all 0 with ``j_max = inf``: :func:`scurve_schedule` then builds the trapezoid's
        acceleration steps from the durations).
    v_peak, a_peak : float
        Peak speed (m/s) and acceleration (m/s^2) reached.
    """
    for name, val in (("v_max", v_max), ("a_max", a_max)):
        if not (val > 0 and math.isfinite(val)):
            raise TrajectoryError(f"{name}: must be a positive finite number, got {val}")
    if not j_max > 0:
        raise TrajectoryError(f"j_max: must be positive (inf: unlimited), got {j_max}")
    D = abs(float(distance))
    if D == 0.0:
        return [], [], 0.0, 0.0
    a, j = float(a_max), float(j_max)

    def ramp(vp: float) -> tuple[float, float, float]:
        """(jerk time, constant-acceleration time, peak acceleration) of a ramp 0 -> vp."""
        if vp * j >= a * a:  # the acceleration reaches a_max
            return a / j, vp / a - a / j, a
        tj = math.sqrt(vp / j)
        return tj, 0.0, j * tj

    def ramp_time(vp: float) -> float:
        tj, ta, _ = ramp(vp)
        return 2.0 * tj + ta

    vp = float(v_max)
    if vp * ramp_time(vp) > D:  # no cruise: the largest peak speed whose ramps cover D
        vp = a * (-a / j + math.sqrt((a / j) ** 2 + 4.0 * D / a)) / 2.0
        if not vp * j >= a * a:
            vp = (D * math.sqrt(j) / 2.0) ** (2.0 / 3.0)
        vp = min(vp, float(v_max))
    tj, ta, ap = ramp(vp)
    tc = max(D / vp - (2.0 * tj + ta), 0.0)
    s = 1.0 if distance > 0 else -1.0
    dur = [tj, ta, tj, tc, tj, ta, tj]
    jerk = [s * j, 0.0, -s * j, 0.0, -s * j, 0.0, s * j]
    keep = [k for k, d in enumerate(dur) if d > 0.0]
    return [dur[k] for k in keep], [jerk[k] if math.isfinite(jerk[k]) else 0.0 for k in keep], vp, ap


@dataclass(frozen=True)
class Move:
    """One point-to-point move of the machine (see :func:`scurve_schedule`).

    Attributes
    ----------
    to : float
        Target position, m (absolute; a move to the current position is a pause).
    v_max, a_max : float
        Speed (m/s) and acceleration (m/s^2) limits of the move.
    j_max : float
        Jerk limit, m/s^3 (``inf``: unlimited, a trapezoidal velocity).
    dwell : float
        Rest at the target after the move, s.
    """

    to: float
    v_max: float
    a_max: float
    j_max: float = math.inf
    dwell: float = 0.0


def scurve_schedule(moves: "list[Move] | tuple[Move, ...]",
                    start: float = 0.0) -> tuple["JerkSchedule | AccelSchedule", list[tuple[float, float]]]:
    """The moves one after the other, each an S-curve (:func:`scurve_segments`), from rest at ``start``.

    Moves with a finite jerk limit become phases of constant jerk (a
    :class:`JerkSchedule`); with every jerk unlimited the result is the exact
    trapezoid (an :class:`AccelSchedule`, acceleration steps).  A mix of both is
    refused: an acceleration step cannot be a phase of finite jerk.

    Parameters
    ----------
    moves : sequence of Move
    start : float
        Position before the first move, m.

    Returns
    -------
    schedule : JerkSchedule or AccelSchedule
    peaks : list of (v_peak, a_peak)
        Per move, m/s and m/s^2.
    """
    finite = [math.isfinite(m.j_max) for m in moves]
    if any(finite) and not all(finite):
        raise TrajectoryError("moves: give every move a j_max, or none (a trapezoid)")
    t = 0.0
    pos = float(start)
    ts: list[float] = [0.0]
    vals: list[float] = []
    peaks: list[tuple[float, float]] = []
    for m in moves:
        if not (m.dwell >= 0 and math.isfinite(m.dwell)):
            raise TrajectoryError(f"dwell: must be >= 0 s, got {m.dwell}")
        dist = float(m.to) - pos
        if all(finite):
            dur, jerk, vp, ap = scurve_segments(dist, m.v_max, m.a_max, m.j_max)
            for d, jv in zip(dur, jerk):
                t += d
                ts.append(t)
                vals.append(jv)
        else:
            dur, _jerk, vp, ap = scurve_segments(dist, m.v_max, m.a_max, math.inf)
            # dur = [ta, tc, ta] or [ta, ta] (constant acceleration, cruise, deceleration)
            s = 1.0 if dist > 0 else -1.0
            accs = [s * ap, 0.0, -s * ap] if len(dur) == 3 else [s * ap, -s * ap]
            for d, av in zip(dur, accs):
                t += d
                ts.append(t)
                vals.append(av)
        pos = float(m.to)
        peaks.append((vp, ap))
        if m.dwell > 0:
            t += m.dwell
            ts.append(t)
            vals.append(0.0)
    if not vals:  # no motion at all: one resting segment
        ts.append(max(t, 0.0))
        vals.append(0.0)
    if all(finite):
        return JerkSchedule(np.array(ts), np.array(vals), float(start)), peaks
    return AccelSchedule(np.array(ts), np.array(vals), float(start)), peaks


def scheduled(schedule: "JerkSchedule | AccelSchedule", duration: float, Ts: float, *,
              start: float | None = None) -> Trajectory:
    """Sample a piecewise-polynomial reference as the desired trajectory itself (no filter), exactly.

    The machine's drive follows its own trajectory generator's ``q, v, a``; so
    does the simulated ARC: ``q_d, dq_d, ddq_d`` are the schedule's values at
    ``k Ts``.  ``start`` shifts the positions so that ``q_d(0) = start`` (m).
    """
    t = sample_grid(duration, Ts)
    if schedule.t_switch[-1] > t[-1] + Ts:
        raise TrajectoryError(
            f"duration: {duration} s is shorter than the moves ({schedule.t_switch[-1]:.4g} s)")
    q, v, a = schedule.sample(t)
    if start is not None:
        q = q + (float(start) - float(schedule.q0))
    return Trajectory(t, q, v, a)


def resampled(t_src: np.ndarray, q_src: np.ndarray, v_src: np.ndarray, a_src: np.ndarray,
              duration: float, Ts: float, *, start: float = 0.0) -> Trajectory:
    """A sampled profile (time, q, v, a) on the controller grid: linear interpolation, held at its end.

    ``t_src`` starts at 0 and increases strictly (s); positions are shifted so that
    ``q_d(0) = start`` (m).  After the profile's last sample the trajectory holds its
    last position at rest (the profile ends at rest: its caller checks it).  Linear
    interpolation of each of q, v, a keeps every value within the profile's own range,
    so the envelope the profile implies bounds the trajectory.
    """
    t = sample_grid(duration, Ts)
    inside = t <= t_src[-1]
    q = np.interp(t, t_src, q_src) - float(q_src[0]) + float(start)
    v = np.where(inside, np.interp(t, t_src, v_src), 0.0)
    a = np.where(inside, np.interp(t, t_src, a_src), 0.0)
    return Trajectory(t, q, v, a)
