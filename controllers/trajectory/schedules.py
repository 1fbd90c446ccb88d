"""Piecewise-polynomial references, sampled exactly: constant acceleration or constant jerk per segment.

:class:`AccelSchedule` (acceleration steps: the trapezoid of the paper's Case 2 and of
moves without a jerk limit) and :class:`JerkSchedule` (jerk steps: the S-curve) both
start at rest and give the exact position, velocity and acceleration at any time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
