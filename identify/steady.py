"""Constant-velocity (friction-test) segments of a log and their friction map.

Commissioning logs contain legs at a ladder of constant speeds in both
directions.  On such a leg ``qdd ~ 0``, so the mean command over the leg is the
friction force at that speed (plus offset and the mean force ripple) with no
filtering bias: the mean velocity is the position change over the leg divided by
its duration, exact up to one encoder count, and the mean command needs no filter
at all.  This is why :func:`commission.identify.fit.fit_axis` takes the friction
curve from these points.

Detection (all on the filtered full-rate velocity ``v``):

1. ``vm`` = ``v`` averaged over ``smooth_s`` (20 ms);
2. a sample is steady if, over the centred window of ``window_s`` (0.1 s), the
   range of ``vm`` is at most ``rel_tol * |vm| + v_tol`` and ``|vm| > 3 v_tol``;
3. steady samples of one sign form runs; each run loses ``edge_s`` (0.05 s) at
   both ends (acceleration transients) and is kept if it still lasts
   ``min_duration_s`` (0.2 s) and its whole velocity range passes step 2's test
   at three times the tolerance.

Quantised velocity (``v_quantum``, the step of the position-difference velocity:
one encoder count per sample, or the recorder's resolution when ``q`` is the
integral of a velocity logged in whole rpm).  An encoder's quantisation error is
bounded in position, so averaging over ``smooth_s`` divides it (``v_tol``).  A
velocity logged in whole rpm errs by up to a quantum at every sample and the
error does not cancel: at a slow sample period (6.4 ms) the 20 ms average spans
three samples and a speed toggling between 1 and 2 rpm swings it by a whole rpm.
With ``v_quantum`` given, the average spans at least
:data:`MIN_SMOOTH_SAMPLES` samples (the steadiness window at least twice that,
the trimmed edge at least half of it), the allowed range of ``vm`` is at least
:data:`QUANTUM_SWING` quanta, and the least speed stays ``3 v_quantum`` over the
averaging window (not three times the widened range), so legs at one or two
quanta are kept.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage


#: Least smoothing window, samples, when the velocity is quantised (``v_quantum``).
MIN_SMOOTH_SAMPLES = 8
#: Least allowed velocity swing, in velocity quanta.
QUANTUM_SWING = 1.5


@dataclass(frozen=True)
class SteadySegments:
    """Constant-velocity segments found in a (preprocessed, full-rate) log.

    What :func:`find_steady_segments` returns, one entry per segment in every array:
    the points of the friction map (mean velocity, mean command) and what is needed to
    correct them for the inertia force left in each leg.

    Attributes
    ----------
    start, stop : ndarray of int
        Sample index ranges ``[start, stop)`` into the arrays given to :func:`find_steady_segments`.
    velocity : ndarray
        Mean velocity, ``(q[stop-1] - q[start]) / (t[stop-1] - t[start])``, m/s.
    command : ndarray
        Mean command over the segment, u-unit.
    acceleration : ndarray
        Mean acceleration, ``(v[stop-1] - v[start]) / duration``, m/s^2.
    duration : ndarray
        Duration of the segment, ``t[stop-1] - t[start]``, s.
    """

    start: np.ndarray = field(repr=False)
    stop: np.ndarray = field(repr=False)
    velocity: np.ndarray
    command: np.ndarray
    acceleration: np.ndarray = field(repr=False)
    duration: np.ndarray = field(repr=False)

    def __len__(self) -> int:
        return int(self.start.size)

    def mean_over(self, x: np.ndarray) -> np.ndarray:
        """Mean of a full-rate signal over every segment."""
        return _segment_means(x, self.start, self.stop)


def find_steady_segments(t: np.ndarray, q: np.ndarray, v: np.ndarray, u: np.ndarray, *,
                         min_duration_s: float = 0.2, rel_tol: float = 0.05, v_tol: float = 0.0,
                         v_quantum: float = 0.0, smooth_s: float = 0.02, window_s: float = 0.1,
                         edge_s: float = 0.05) -> SteadySegments:
    """Find constant-velocity segments and their mean velocity and command.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform time, s.
    q : ndarray, shape (N,)
        Filtered position, m.
    v : ndarray, shape (N,)
        Filtered velocity, m/s.
    u : ndarray, shape (N,)
        Command, u-unit.
    min_duration_s : float
        Shortest segment kept after edge removal, s.
    rel_tol : float
        Allowed velocity variation relative to the speed.
    v_tol : float
        Allowed absolute velocity variation, m/s (e.g. the velocity resolution of
        the encoder over ``smooth_s``); also ``3 v_tol`` is the least speed.
    v_quantum : float
        Step of the position-difference velocity, m/s (``quantization_step(q) *
        sample_rate``); 0: not quantised.  Widens the allowed range to
        :data:`QUANTUM_SWING` quanta and the averaging to :data:`MIN_SMOOTH_SAMPLES`
        samples (module docstring).
    smooth_s, window_s, edge_s : float
        Averaging window, steadiness window and trimmed edge, s.

    Returns
    -------
    SteadySegments
    """
    n = t.size
    h = (t[-1] - t[0]) / (n - 1)
    w = max(1, int(round(smooth_s / h)))
    floor, v_min = v_tol, 3.0 * v_tol
    if v_quantum > 0:
        w = max(w, MIN_SMOOTH_SAMPLES)
        floor = max(v_tol, QUANTUM_SWING * v_quantum)
        v_min = max(v_min, 3.0 * v_quantum / w)
    vm = ndimage.uniform_filter1d(v, w, mode="nearest")
    L = max(3, int(round(window_s / h)), 2 * w)
    rng = ndimage.maximum_filter1d(vm, L, mode="nearest") - ndimage.minimum_filter1d(vm, L, mode="nearest")
    speed = np.abs(vm)
    tol = rel_tol * speed + floor
    steady = (rng <= tol) & (speed > v_min) & (speed > 0)
    sgn = np.where(steady, np.sign(vm), 0).astype(np.int8)
    # Run boundaries: wherever the (sign-labelled) steady flag changes.
    change = np.flatnonzero(np.diff(sgn) != 0) + 1
    bounds = np.concatenate([[0], change, [n]])
    edge = max(int(round(edge_s / h)), (w + 1) // 2)
    nmin = int(np.ceil(min_duration_s / h))
    starts, stops = [], []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if sgn[a] == 0:
            continue
        a2, b2 = a + edge, b - edge
        if b2 - a2 < max(nmin, 2):
            continue
        seg = vm[a2:b2]
        mean = float(np.mean(seg))
        if np.ptp(seg) > 3.0 * (rel_tol * abs(mean) + floor):
            continue
        starts.append(a2)
        stops.append(b2)
    start = np.asarray(starts, dtype=np.int64)
    stop = np.asarray(stops, dtype=np.int64)
    if start.size == 0:
        empty = np.zeros(0)
        return SteadySegments(start=start, stop=stop, velocity=empty, command=empty, acceleration=empty,
                              duration=empty)
    dur = t[stop - 1] - t[start]
    return SteadySegments(start=start, stop=stop, velocity=(q[stop - 1] - q[start]) / dur,
                          command=_segment_means(u, start, stop), acceleration=(v[stop - 1] - v[start]) / dur,
                          duration=dur)


def _segment_means(x: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    c = np.concatenate([[0.0], np.cumsum(x)])
    return (c[stop] - c[start]) / (stop - start)


@dataclass(frozen=True)
class FrictionMap:
    """Friction map of constant-velocity legs: one entry per leg, in the log's units.

    Attributes
    ----------
    velocity : ndarray
        Mean velocity of the leg, ``(q[-1] - q[0]) / (t[-1] - t[0])``, m/s (rad/s on a rotary axis).
    force : ndarray
        Median command over the leg, u-unit (the median ignores the odd spike of a rough slow leg).
    std : ndarray
        Standard deviation of the command over the leg, u-unit.
    n : ndarray of int
        Samples in the leg.
    """

    velocity: np.ndarray
    force: np.ndarray
    std: np.ndarray
    n: np.ndarray

    def to_dict(self) -> dict[str, list[float] | list[int]]:
        """``{"velocity", "force", "std", "n"}`` as JSON lists (ident.json's ``friction_map``)."""
        return {"velocity": [float(x) for x in self.velocity], "force": [float(x) for x in self.force],
                "std": [float(x) for x in self.std], "n": [int(x) for x in self.n]}


def friction_map(legs: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> FrictionMap:
    """Friction map of whole constant-velocity legs, each given as ``(t, q, u)``.

    Each leg is a separate recording (e.g. one friction-test file per speed), so
    nothing is filtered across legs: the mean velocity is the position change over
    the leg's duration and the force is the median command.

    Parameters
    ----------
    legs : list of (t, q, u)
        Time [s], position [m or rad] and command [u-unit] of each leg, at least 2 samples each.

    Returns
    -------
    FrictionMap
        Entries in the order of ``legs``.
    """
    v, f, s, n = [], [], [], []
    for t, q, u in legs:
        t, q, u = (np.asarray(a, dtype=np.float64) for a in (t, q, u))
        if t.size < 2 or not (t.shape == q.shape == u.shape):
            raise ValueError(f"friction_map: a leg needs >= 2 samples of t, q, u of one length, got "
                             f"{t.shape}, {q.shape}, {u.shape}")
        v.append((q[-1] - q[0]) / (t[-1] - t[0]))
        f.append(float(np.median(u)))
        s.append(float(np.std(u)))
        n.append(int(t.size))
    return FrictionMap(np.array(v), np.array(f), np.array(s), np.array(n, dtype=np.int64))
