"""Signal preprocessing of the EMPS reference method (IDIM-LS), generalised by sample rate.

The EMPS benchmark (Janot, Gautier & Brunot 2019, ``Script_IDIM_LS.m``) builds the
inverse-dynamics regression from a 1 kHz log as follows:

1. low-pass the encoder position with a 4th-order Butterworth filter at
   ``5 * 20 Hz = 100 Hz``, zero phase (MATLAB ``filtfilt``);
2. velocity and acceleration by central differences (``diffcent`` = ``numpy.gradient``);
3. drop the first 49 samples (edge effects);
4. decimate every regressor column and the force with MATLAB ``decimate``
   (8th-order Chebyshev-I, 0.05 dB ripple, cut-off ``0.8/r`` of Nyquist, zero phase)
   by ``r = round(0.8 * (fs/2) / (2 * 20 Hz)) = 10``.

The 20 Hz in the script is the dynamic bandwidth of the data; it is a physical
frequency, so this module keeps it (``bandwidth_hz``) and lets the sample rate
enter only where the script has ``fnyq``: the Butterworth cut-off is
``5 * bandwidth_hz`` (clamped below 0.8 Nyquist), the decimation factor is
``round(0.8 * (fs/2) / (2 * bandwidth_hz))`` and the trimmed edge is
``round(4.9 * fs / cutoff_hz)`` samples (49 at the EMPS settings).  Keeping the
bandwidth fixed, rather than scaling the cut-off with the sample rate, keeps the
noise that double differentiation draws from encoder quantisation independent
of the sample rate.

Bit-faithfulness to MATLAB: ``filtfilt`` pads ``3 * order`` samples by odd
reflection and starts each pass from the step-response steady state scaled by
the first sample; :func:`scipy.signal.sosfiltfilt` with ``padlen = 3 * order``
does the same (scipy's default pad is longer).  MATLAB ``decimate`` keeps the
samples ``nbeg:r:nd`` with ``nbeg = r - (r*ceil(nd/r) - nd)`` (1-based), i.e. it
is aligned so that the *last* sample is kept; scipy keeps the first.  With both
details matched the pipeline reproduces the published EMPS numbers to every
printed digit (tests/test_identify_emps.py).  Second-order sections are used
instead of transfer-function coefficients because the Chebyshev filter becomes
ill-conditioned in ``(b, a)`` form for decimation factors above ~13.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from commission.identify.errors import SignalError

#: Dynamic bandwidth of the EMPS script (``freq_dyn = 20 Hz``), Hz.
DEFAULT_BANDWIDTH_HZ = 20.0
#: Butterworth order of the position pre-filter (EMPS ``nfilt``).
BUTTER_ORDER = 4
#: Chebyshev-I order and pass-band ripple (dB) of MATLAB ``decimate``.
CHEBY_ORDER = 8
CHEBY_RIPPLE_DB = 0.05
#: Maximum relative deviation of a sample interval from the median interval.
TIME_JITTER_RTOL = 0.01


def check_signals(t: np.ndarray, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Validate a log's arrays and return them as float64 with the sample rate.

    Parameters
    ----------
    t : array_like, shape (N,)
        Sample times, s; strictly increasing and uniform to within 1 %.
    q : array_like, shape (N,)
        Measured position, m.
    u : array_like, shape (N,)
        Command, u-unit.

    Returns
    -------
    t, q, u : ndarray
        Contiguous float64 copies.
    sample_rate : float
        ``(N - 1) / (t[-1] - t[0])``, Hz.

    Raises
    ------
    SignalError
        Naming the array, its shape or the first bad sample.
    """
    arrays = {}
    for name, x in (("t", t), ("q", q), ("u", u)):
        a = np.asarray(x, dtype=np.float64)
        if a.ndim != 1:
            raise SignalError(f"{name}: expected a 1-D array, got shape {a.shape}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise SignalError(f"{name}: sample {bad[0]} is {float(a[bad[0]])} (non-finite)")
        arrays[name] = np.ascontiguousarray(a)
    t, q, u = arrays["t"], arrays["q"], arrays["u"]
    if not (t.shape == q.shape == u.shape):
        raise SignalError(f"t, q, u: lengths differ (t {t.shape}, q {q.shape}, u {u.shape})")
    if t.size < 3:
        raise SignalError(f"t: need at least 3 samples, got {t.size}")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = bad[0] + 1
        raise SignalError(
            f"t: not strictly increasing at index {i} (t[{i}]={float(t[i])!r} <= t[{i - 1}]={float(t[i - 1])!r})")
    # Irregular intervals are located against the median (robust to the outlier itself);
    # the sample rate uses the mean, which cancels time stamps stored rounded (EMPS's t
    # has steps of 0.99998 ms and 1.00002 ms that average to exactly 1 ms).
    med = float(np.median(dt))
    bad = np.flatnonzero(np.abs(dt - med) > TIME_JITTER_RTOL * med)
    if bad.size:
        i = bad[0] + 1
        raise SignalError(
            f"t: not uniformly sampled at index {i} (t[{i}]-t[{i - 1}]={float(dt[i - 1])!r} s, median interval "
            f"{med!r} s); resample the log first")
    h = float((t[-1] - t[0]) / (t.size - 1))
    return t, q, u, 1.0 / h


def default_settings(sample_rate: float, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ) -> tuple[float, int, int]:
    """Pre-filter cut-off, decimation factor and trimmed edge for a sample rate.

    Parameters
    ----------
    sample_rate : float
        Hz.
    bandwidth_hz : float
        Dynamic bandwidth of the excitation, Hz (EMPS: 20 Hz).

    Returns
    -------
    cutoff_hz : float
        Butterworth cut-off, ``min(5 * bandwidth_hz, 0.8 * sample_rate / 2)``, Hz.
    decimation : int
        ``max(1, round(0.8 * (sample_rate / 2) / (2 * bandwidth_hz)))``.
    trim_start : int
        Samples dropped at the start, ``round(4.9 * sample_rate / cutoff_hz)``.
    """
    if not (sample_rate > 0 and bandwidth_hz > 0):
        raise ValueError(f"need sample_rate > 0 and bandwidth_hz > 0, got {sample_rate}, {bandwidth_hz}")
    nyq = sample_rate / 2.0
    cutoff = min(5.0 * bandwidth_hz, 0.8 * nyq)
    # Python's round() is half-to-even, MATLAB's half-away; they differ only on exact .5.
    decimation = max(1, int(math.floor(0.8 * nyq / (2.0 * bandwidth_hz) + 0.5)))
    trim = int(math.floor(4.9 * sample_rate / cutoff + 0.5))
    return cutoff, decimation, trim


def zero_phase_lowpass(x: np.ndarray, cutoff_hz: float, sample_rate: float) -> np.ndarray:
    """4th-order Butterworth low-pass applied forward and backward (MATLAB ``filtfilt``).

    Parameters
    ----------
    x : ndarray, shape (N,) or (N, k)
        Signal(s) along axis 0.
    cutoff_hz, sample_rate : float
        Hz.
    """
    wn = cutoff_hz / (sample_rate / 2.0)
    if not 0.0 < wn < 1.0:
        raise ValueError(f"cutoff_hz={cutoff_hz} must lie in (0, {sample_rate / 2}) Hz")
    sos = signal.butter(BUTTER_ORDER, wn, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0, padlen=3 * BUTTER_ORDER)


def decimate(x: np.ndarray, r: int) -> np.ndarray:
    """MATLAB ``decimate(x, r)``: zero-phase 8th-order Chebyshev-I, then every r-th sample.

    The kept samples are aligned on the last sample, as MATLAB does.

    Parameters
    ----------
    x : ndarray, shape (N,) or (N, k)
        Signal(s) along axis 0.
    r : int
        Decimation factor; 1 returns ``x`` unchanged.
    """
    if r == 1:
        return np.array(x, dtype=np.float64, copy=True)
    sos = signal.cheby1(CHEBY_ORDER, CHEBY_RIPPLE_DB, 0.8 / r, output="sos")
    y = signal.sosfiltfilt(sos, x, axis=0, padlen=3 * CHEBY_ORDER)
    return y[decimation_start(x.shape[0], r)::r]


def decimation_start(n: int, r: int) -> int:
    """0-based index of the first sample MATLAB ``decimate`` keeps from ``n`` samples."""
    nout = -(-n // r)
    return r - (r * nout - n) - 1


@dataclass(frozen=True)
class Preprocessed:
    """A log after filtering, differentiation and edge trimming (full rate).

    The one input every fit takes: the filter, the differences and the trim are done
    once here, so the fits of one log see the same signals and rows.

    Attributes
    ----------
    sample_rate : float
        Sample rate of the log, Hz.
    cutoff_hz : float
        Butterworth cut-off used on ``q``, Hz.
    decimation : int
        Decimation factor for the regression rows, samples per row.
    trim_start : int
        Samples dropped at the start of the raw log, samples.
    t : ndarray
        Time of the kept samples, s.
    q : ndarray
        Filtered position, m.
    qd : ndarray
        Velocity (central differences of ``q``), m/s.
    qdd : ndarray
        Acceleration (central differences of ``qd``), m/s^2.
    u : ndarray
        Command of the kept samples, u-unit.
    t_dec : ndarray
        Time of the decimated rows, s.
    bounds : tuple of int
        Segment boundaries in the full-rate arrays: segment ``k`` is
        ``[bounds[k], bounds[k + 1])``.  One log is one segment ``(0, N)``; several
        logs of one axis (:func:`preprocess_segments`) are one segment each, laid end
        to end, and no filter ever runs across a boundary.
    """

    sample_rate: float
    cutoff_hz: float
    decimation: int
    trim_start: int
    t: np.ndarray = field(repr=False)
    q: np.ndarray = field(repr=False)
    qd: np.ndarray = field(repr=False)
    qdd: np.ndarray = field(repr=False)
    u: np.ndarray = field(repr=False)
    t_dec: np.ndarray = field(repr=False)
    bounds: tuple[int, ...] = ()

    def segments(self) -> list[slice]:
        """The full-rate slice of every segment (one for a single log)."""
        b = self.bounds or (0, self.t.shape[0])
        return [slice(a, c) for a, c in zip(b[:-1], b[1:])]

    def decimate(self, x: np.ndarray) -> np.ndarray:
        """Decimate full-rate column(s) aligned with ``self.t`` to the regression rows, segment by segment."""
        x = np.asarray(x)
        parts = [decimate(x[s], self.decimation) for s in self.segments()]
        return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=0)

    def decimate_mask(self, mask: np.ndarray) -> np.ndarray:
        """Pick, without filtering, the full-rate boolean ``mask`` at the decimated rows."""
        mask = np.asarray(mask)
        parts = [mask[s][decimation_start(s.stop - s.start, self.decimation)::self.decimation]
                 for s in self.segments()]
        return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=0)


def preprocess(t: np.ndarray, q: np.ndarray, u: np.ndarray, *, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
               cutoff_hz: float | None = None, decimation: int | None = None,
               trim_start: int | None = None) -> Preprocessed:
    """Filter, differentiate and trim a log (steps 1-3 of the EMPS method).

    Parameters
    ----------
    t : array_like, shape (N,)
        Sample times, s (uniform).
    q : array_like, shape (N,)
        Encoder position, m.
    u : array_like, shape (N,)
        Command, u-unit (any input gain already applied).
    bandwidth_hz : float
        Dynamic bandwidth of the excitation, Hz; sets the defaults below.
    cutoff_hz : float, optional
        Butterworth cut-off, Hz (default ``5 * bandwidth_hz``).
    decimation : int, optional
        Decimation factor (default ``round(0.8 * (fs/2) / (2 * bandwidth_hz))``).
    trim_start : int, optional
        Samples dropped at the start (default ``round(4.9 * fs / cutoff_hz)``).

    Returns
    -------
    Preprocessed
    """
    t, q, u, fs = check_signals(t, q, u)
    c0, r0, _ = default_settings(fs, bandwidth_hz)
    cutoff = c0 if cutoff_hz is None else float(cutoff_hz)
    r = r0 if decimation is None else int(decimation)
    if r < 1:
        raise ValueError(f"decimation must be >= 1, got {decimation}")
    trim = int(math.floor(4.9 * fs / cutoff + 0.5)) if trim_start is None else int(trim_start)
    n_keep = t.size - trim
    if trim < 0 or n_keep < max(4 * r, 3 * CHEBY_ORDER + 2, 3 * BUTTER_ORDER + 2):
        raise SignalError(f"t: {t.size} samples are too few for trim_start={trim} and decimation={r}")
    h = 1.0 / fs
    qf = zero_phase_lowpass(q, cutoff, fs)
    qd = np.gradient(qf, h)
    qdd = np.gradient(qd, h)
    s = slice(trim, None)
    tt = t[s].copy()
    return Preprocessed(sample_rate=fs, cutoff_hz=cutoff, decimation=r, trim_start=trim, t=tt, q=qf[s].copy(),
                        qd=qd[s].copy(), qdd=qdd[s].copy(), u=u[s].copy(),
                        t_dec=tt[decimation_start(tt.size, r)::r].copy(), bounds=(0, tt.size))


def segment_rates(segments: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> list[tuple[np.ndarray, ...]]:
    """Check every segment (:func:`check_signals`) and that they share one sample rate.

    Returns
    -------
    list of (t, q, u, sample_rate)
        The checked float64 arrays of each segment, with its rate in Hz.

    Raises
    ------
    SignalError
        With :attr:`SignalError.segment` set to the offending segment's index.
    """
    if len(segments) == 0:
        raise SignalError("segments: need at least one (t, q, u)")
    out = []
    for k, (t, q, u) in enumerate(segments):
        try:
            out.append(check_signals(t, q, u))
        except SignalError as exc:
            raise SignalError(str(exc), segment=k) from None
    fs0 = out[0][3]
    for k, (*_, fs) in enumerate(out):
        if abs(fs - fs0) > TIME_JITTER_RTOL * fs0:
            raise SignalError(f"t: sampled at {fs:.6g} Hz where the first log is at {fs0:.6g} Hz; logs fitted "
                              "together must share their sample rate (resample them first)", segment=k)
    return out


def preprocess_segments(segments: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], *,
                        bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ, cutoff_hz: float | None = None,
                        decimation: int | None = None, trim_start: int | None = None) -> Preprocessed:
    """Filter, differentiate and trim several logs of one axis, each as its own segment.

    Every segment goes through :func:`preprocess` on its own, with the settings of
    the first segment's sample rate, so no filter, difference or decimation runs
    across the join between two recordings (where the position may jump and the
    command step).  The results are stacked: the full-rate arrays one segment after
    the other (:attr:`Preprocessed.bounds` marks the joins) and
    :meth:`Preprocessed.decimate` works segment by segment, so a regression on the
    stacked rows is one least-squares fit over all the logs.  Each segment loses its
    own ``trim_start`` samples.  The time of a later segment is shifted to follow the
    previous one by one sample period (a monotone time axis for plots); positions
    are kept as recorded (the force ripple depends on them).

    Parameters
    ----------
    segments : sequence of (t, q, u)
        Times [s], positions [m or rad] and commands [u-unit] of each log; one
        sample rate to within 1 %.
    bandwidth_hz, cutoff_hz, decimation, trim_start
        As in :func:`preprocess`; defaults from the first segment's rate.

    Returns
    -------
    Preprocessed
        One segment per log; a single log gives exactly :func:`preprocess`'s result.

    Raises
    ------
    SignalError
        A malformed or too short segment, or rates that differ; :attr:`SignalError.segment` names it.
    """
    checked = segment_rates(segments)
    fs0 = checked[0][3]
    c0, r0, _ = default_settings(fs0, bandwidth_hz)
    cutoff = c0 if cutoff_hz is None else float(cutoff_hz)
    r = r0 if decimation is None else int(decimation)
    parts = []
    for k, (t, q, u, _) in enumerate(checked):
        try:
            parts.append(preprocess(t, q, u, bandwidth_hz=bandwidth_hz, cutoff_hz=cutoff, decimation=r,
                                    trim_start=trim_start))
        except SignalError as exc:
            raise SignalError(str(exc), segment=k) from None
    if len(parts) == 1:
        return parts[0]
    h = 1.0 / fs0
    shifted, t_dec, bounds, end = [], [], [0], None
    for pp in parts:
        shift = 0.0 if end is None else end + h - float(pp.t[0])
        shifted.append(pp.t + shift)
        t_dec.append(pp.t_dec + shift)
        end = float(shifted[-1][-1])
        bounds.append(bounds[-1] + pp.t.size)
    return Preprocessed(sample_rate=fs0, cutoff_hz=cutoff, decimation=r, trim_start=parts[0].trim_start,
                        t=np.concatenate(shifted), q=np.concatenate([pp.q for pp in parts]),
                        qd=np.concatenate([pp.qd for pp in parts]), qdd=np.concatenate([pp.qdd for pp in parts]),
                        u=np.concatenate([pp.u for pp in parts]), t_dec=np.concatenate(t_dec), bounds=tuple(bounds))


#: An increment is a multiple of the step when within this fraction of a step of one.
GRID_TOLERANCE = 0.01
#: Divisors of the smallest increment tried as the step: an axis that never moves by a single count
#: (it moves by 2 or 3) still shows its grid.
GRID_MAX_DIVISOR = 10
#: Share of the non-zero increments that must sit on the grid: a few glitches (a stitched segment
#: boundary, one corrupted sample) do not hide an encoder.
GRID_MIN_SHARE = 0.999


def encoder_grid(q: np.ndarray) -> tuple[float | None, float]:
    """The encoder's grid step in ``q`` and the smallest increment the data show: the one estimator.

    The candidate steps are the smallest non-zero increment divided by 1, 2, ...
    :data:`GRID_MAX_DIVISOR` (the count itself may never occur alone).  The first
    candidate of which at least :data:`GRID_MIN_SHARE` of the non-zero increments
    are integer multiples, within :data:`GRID_TOLERANCE` of a step, is refined by
    least squares over those increments.  Increments are used rather than the
    positions so that stitched segments with arbitrary offsets keep their grid.

    Parameters
    ----------
    q : array_like, shape (N,)
        Position samples, m (or rad).

    Returns
    -------
    step : float or None
        The grid step, in q's unit; None if ``q`` never moves, is on no grid
        (resampled or filtered data), or moves only at floating-point resolution.
    apparent_resolution : float
        Smallest non-zero ``|dq|``, in q's unit; NaN when ``q`` is constant.
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 1:
        raise SignalError(f"q: expected a 1-D array, got shape {q.shape}")
    d = np.abs(np.diff(q))
    nz = d[d > 0]
    if nz.size == 0:
        return None, math.nan
    resolution = float(nz.min())
    # Below ~1e3 ulp of the largest |q| an increment is rounding noise, and any data would fit a grid.
    if resolution < 1e3 * np.finfo(np.float64).eps * float(np.max(np.abs(q))):
        return None, resolution
    for divisor in range(1, GRID_MAX_DIVISOR + 1):
        step = resolution / divisor
        k = nz / step
        kr = np.rint(k)
        on = np.abs(k - kr) <= GRID_TOLERANCE
        if np.mean(on) >= GRID_MIN_SHARE:
            return float(nz[on].sum() / kr[on].sum()), resolution
    return None, resolution


def quantization_step(q: np.ndarray) -> float | None:
    """The encoder's grid step in ``q`` (m), or None: :func:`encoder_grid`'s step."""
    return encoder_grid(q)[0]

