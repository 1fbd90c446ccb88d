"""The machine's own moves: S-curve point-to-point moves and sampled profiles.

:func:`scurve_segments` is the time-optimal rest-to-rest move under speed, acceleration
and jerk limits; :func:`scurve_schedule` chains :class:`Move` s into one schedule
(:mod:`commission.controllers.trajectory.schedules`), and :func:`scheduled` samples it
as the desired trajectory itself (the drive follows its own generator, unfiltered).
:func:`resampled` puts a recorded profile (time, q, v, a) on the controller grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from commission.controllers.trajectory.core import Trajectory, TrajectoryError, require_positive_finite, sample_grid
from commission.controllers.trajectory.schedules import AccelSchedule, JerkSchedule


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
    require_positive_finite(v_max=v_max, a_max=a_max)
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
