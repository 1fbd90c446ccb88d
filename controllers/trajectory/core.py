"""The sampled desired motion every generator returns, its grid, and the small matrix exponential.

:class:`Trajectory` is what the simulator and the controllers read: ``q_d, dq_d, ddq_d``
on a uniform grid starting at 0 (checked on construction, arrays read-only).
:func:`sample_grid` is the one rule for the grid of a given duration, and
:func:`expm_small` the compiled matrix exponential the exact generators of
:mod:`commission.controllers.trajectory.paper` advance their filters with.
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

    Plain loops on purpose: LAPACK-based ``scipy.linalg.expm`` wakes the BLAS
    threads on every call, which is slow on a busy multi-threaded BLAS
    (docs/scaling.md), and the smoother needs one per switch instant.  After scaling, ``||X||_1 <= 1/2`` and the truncation
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


def require_positive_finite(**values: float) -> None:
    """Refuse the first of ``values`` (name = value, in the order given) that is not a positive finite number."""
    for name, val in values.items():
        if not (val > 0 and math.isfinite(val)):
            raise TrajectoryError(f"{name}: must be a positive finite number, got {val}")


def grid_period(t: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> float:
    """The period Ts (s) of the sample times ``t`` (s), checked uniform and starting at 0 s.

    ``q, v, a`` are checked to be finite and as long as ``t`` (a generator's input columns).
    """
    Trajectory(t, q, v, a)  # validates shapes and the grid
    if t[0] != 0.0:
        raise TrajectoryError(f"t: must start at 0 s, got t[0]={t[0]}")
    return t[1] - t[0]
