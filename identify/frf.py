"""Frequency response u -> q from an excitation log, and what the rigid model lacks.

Method
------
1. **Broadband segments.**  A drive's frequency-response tool injects a PRBS,
   noise or chirp into the command while the axis moves slowly; the closed
   loop's own command is narrow-band (the reference) plus the feedback's answer
   to encoder noise, a background that is there whenever the axis moves.  The
   command is high-passed at ``fs / 10`` (zero-phase Butterworth) and its RMS
   taken over 0.1-s blocks; a block is broadband when that RMS is at least
   ``BROADBAND_FACTOR`` times the median of the moving blocks and holds at
   least a quarter of the block's command variance.  Runs of such blocks at
   least ``MIN_SEGMENT_S`` long are the segments.
2. **Estimate.**  H1 = P_uq / P_uu with coherence (Welch averaging of
   ``scipy.signal.csd`` / ``welch``, Hann windows, half overlap, linear detrend
   per window so the constant-velocity ramp drops out), averaged over the
   segments with their window counts.  Without segments the whole log is used
   (its content is then the reference's: it backs the rigid model at low
   frequency only); with segments, the whole log's estimate extends the band
   below the segments' first bins.  In a closed loop H1 is unbiased where the injection
   dominates the command; where the feedback of encoder noise dominates it
   tends to minus the controller's inverse, which is why the segments are
   chosen by the command's broadband level and not by coherence alone.
3. **Compare.**  ``R = H / H_rigid`` with ``H_rigid`` the identified rigid
   body ``1 / (M s^2 + B s)`` sampled behind the zero-order hold
   (:func:`commission.controllers.linear.rigid_frequency_response`).  The band
   the data back is the run of coherent bins (``gamma^2 >= BAND_COHERENCE``),
   from the lowest, in which ``|R|`` is within ``BAND_GAIN_TOL`` and its phase
   within ``BAND_PHASE_TOL_DEG``; it ends at the first two consecutive
   coherent bins outside.
4. **Fit.**  Candidate plants (rigid; a mode seen on the load side; a mode
   seen on the motor side, with its anti-resonance at ``f_r sqrt(1 - r)``),
   each with an input delay and a scale on the mass, are evaluated with the
   exact sampled response :meth:`commission.controllers.linear.SampledPlant.frequency_response`
   and fitted by ``scipy.optimize.least_squares`` to the log-magnitude and the
   phase of H, each bin weighted by its inverse variance
   ``2 n_avg gamma^2 / (1 - gamma^2)`` (gamma^2 capped at ``COHERENCE_CAP``).
   Starts come from the data: the delay from the phase slope of R, the
   resonance from the peak of ``|R|``, the anti-resonance from its dip below
   the peak.  The structure with the least ``cost (1 + STRUCTURE_PENALTY k)``
   (k free parameters) wins, and a mode only counts when it changes the
   fitted response by more than ``BAND_GAIN_TOL`` somewhere in the fitted
   range and its frequency and damping are not on their bounds.  The load ratio of a load-side mode does not show in u -> q (the
   response is ``(2 zeta w s + w^2) / (M s^2 (s^2 + 2 zeta w s + w^2))`` for
   any ratio): it is reported at 0.5 with ``mode_ratio_identified`` false.

scipy.linalg on the 5x5 matrices of the sampled plant spends milliseconds in
BLAS thread hand-offs on a busy machine (a thousand times its single-thread
cost), so the fit runs under ``threadpoolctl.threadpool_limits(1)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import signal
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from commission.controllers.linear import rigid_frequency_response, sampled_plant
from commission.controllers.plant import plant_vector

#: A block is broadband when its high-passed command RMS is this many times the moving blocks' median.
BROADBAND_FACTOR = 10.0
#: ... and holds at least this fraction of the block's (detrended) command variance.
BROADBAND_FRACTION = 0.25
#: Block length of the detection, s.
BLOCK_S = 0.1
#: Shortest broadband segment used, s.
MIN_SEGMENT_S = 0.5
#: Target frequency resolution on broadband segments, Hz.
RESOLUTION_HZ = 5.0
#: Frequency resolution on a log without broadband segments, Hz.
WHOLE_LOG_RESOLUTION_HZ = 2.0
#: Coherence a bin needs to count for the band.
BAND_COHERENCE = 0.8
#: |H / H_rigid| within [1 / tol, tol] counts as agreement.
BAND_GAIN_TOL = 1.25
#: ... and its phase within this many degrees.
BAND_PHASE_TOL_DEG = 30.0
#: Coherence a bin needs to enter the fit.
FIT_COHERENCE = 0.5
#: Cap of gamma^2 in the weights (a perfect bin would weigh infinitely).
COHERENCE_CAP = 0.995
#: Relative cost per free parameter when choosing the structure.
STRUCTURE_PENALTY = 0.1
#: Largest delay fitted, samples.
MAX_DELAY_SAMPLES = 6.0
#: Largest damping ratio fitted (a mode damped more than this is no resonance to report).
MAX_DAMPING = 0.7
#: Coherent bins the fit needs.
MIN_FIT_BINS = 12
#: Most measured bins carried into ident.json (``frequency_response.measured``).
MEASURED_POINTS = 200

STRUCTURES = ("rigid", "load_side_mode", "motor_side_mode")


@dataclass(frozen=True)
class StructureFit:
    """One candidate structure fitted to the measured response.

    Attributes
    ----------
    structure : str
        ``"rigid"``, ``"load_side_mode"`` or ``"motor_side_mode"``.
    mass_scale : float
        Mass of the fitted plant over the rigid fit's M.
    delay_samples : float
        Input delay beyond the zero-order hold, samples.
    mode_hz, mode_damping, mode_ratio : float or None
        Mode of the fitted plant (Hz, -, -); None for rigid.
    cost : float
        Sum of squared normalised residuals (about the number of residuals for a right model).
    n_residuals : int
    n_params : int
    """

    structure: str
    mass_scale: float
    delay_samples: float
    mode_hz: float | None
    mode_damping: float | None
    mode_ratio: float | None
    cost: float
    n_residuals: int
    n_params: int

    @property
    def score(self) -> float:
        return self.cost * (1.0 + STRUCTURE_PENALTY * self.n_params)

    def plant(self, M: float, B: float, Ts: float) -> np.ndarray:
        """The fitted plant vector (linear part only: no friction)."""
        return _plant(self.structure, M * self.mass_scale, B, Ts, self.delay_samples,
                      self.mode_hz or 0.0, self.mode_damping or 0.0, self.mode_ratio or 0.5)


@dataclass(frozen=True)
class FrequencyResponse:
    """Measured frequency response of an axis and its comparison with the rigid model.

    Attributes
    ----------
    f : ndarray
        Frequencies, Hz (DC and Nyquist left out).
    H : ndarray, complex
        H1 estimate of u -> q, m per u-unit.
    coherence : ndarray
        Magnitude-squared coherence, 0-1.
    n_averages : int
        Welch windows averaged.
    source : {"broadband", "whole_log"}
        Where the estimate comes from.
    segments : tuple of (float, float)
        Broadband segments used, ``(start, stop)`` in s (empty for ``whole_log``).
    H_rigid : ndarray, complex
        The identified rigid model at ``f``.
    M, B : float
        That rigid model, u-unit s^2/m and u-unit s/m.
    band_hz : (float, float) or None
        Band in which the data back the rigid model, Hz.
    fit : StructureFit or None
        The chosen structure (None when the data do not support a fit).
    fits : dict of str to StructureFit
        Every structure tried.
    H_model : ndarray, complex, or None
        The chosen fit at ``f``.
    sample_rate : float
        Hz.
    note : str or None
        What the data could not show.
    """

    f: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    n_averages: int
    source: str
    segments: tuple[tuple[float, float], ...]
    H_rigid: np.ndarray
    M: float
    B: float
    band_hz: tuple[float, float] | None
    fit: StructureFit | None
    fits: dict[str, StructureFit] = field(default_factory=dict)
    H_model: np.ndarray | None = None
    sample_rate: float = 0.0
    note: str | None = None

    @property
    def modes(self) -> list[dict[str, Any]]:
        """Resonances and anti-resonances of the fitted structure, lowest first.

        ``frequency_hz`` (Hz), ``damping`` (-), ``kind`` and ``gain``: ``|H / H_rigid|``
        of the fitted model there (-).
        """
        fit = self.fit
        if fit is None or fit.mode_hz is None:
            return []
        out = []
        if fit.structure == "motor_side_mode":
            r = fit.mode_ratio
            out.append({"frequency_hz": fit.mode_hz * math.sqrt(1.0 - r),
                        "damping": fit.mode_damping * math.sqrt(1.0 - r), "kind": "anti-resonance"})
        out.append({"frequency_hz": fit.mode_hz, "damping": fit.mode_damping, "kind": "resonance"})
        for m in out:
            m["gain"] = self._model_gain(m["frequency_hz"])
        return out

    def _model_gain(self, f_hz: float) -> float:
        Ts = 1.0 / self.sample_rate
        Hm = sampled_plant(self.fit.plant(self.M, self.B, Ts), Ts).frequency_response(np.array([f_hz]))[0]  # type: ignore[union-attr]
        Hr = rigid_frequency_response(self.M, self.B, Ts, np.array([f_hz]))[0]
        return float(abs(Hm / Hr))

    def to_dict(self) -> dict[str, Any]:
        """The ``frequency_response`` section of ident.json (units in the key names or below)."""
        fit = self.fit
        model: dict[str, Any] | None = None
        if fit is not None:
            has_mode = fit.mode_hz is not None
            model = {
                "mode_hz": fit.mode_hz,
                "mode_damping": fit.mode_damping,
                "mode_ratio": None if fit.mode_ratio is None else float(fit.mode_ratio),
                "mode_ratio_identified": (fit.structure == "motor_side_mode") if has_mode else None,
                "mode_load_side": (fit.structure == "load_side_mode") if has_mode else None,
                "delay_s": fit.delay_samples / self.sample_rate,
                "mass_scale": fit.mass_scale,
            }
        quality = None
        if fit is not None:
            quality = {
                "structure": fit.structure,
                "model_rms_error": _weighted_rms(self.H, self.H_model, self.coherence),
                "rigid_rms_error": _weighted_rms(self.H, self.H_rigid, self.coherence),
                "scores": {k: v.score for k, v in self.fits.items()},
                "n_residuals": fit.n_residuals,
            }
        coherent = self.coherence >= BAND_COHERENCE
        evidence = self.evidence_band_hz
        return {
            "evidence_band_hz": list(evidence) if evidence is not None else None,
            "measured": self.measured_points() if self.source == "broadband" else None,
            "source": self.source,
            "segments_s": [list(s) for s in self.segments],
            "n_averages": int(self.n_averages),
            "resolution_hz": float(self.f[1] - self.f[0]) if self.f.size > 1 else None,
            "coherent_up_to_hz": float(self.f[coherent].max()) if np.any(coherent) else None,
            "band_hz": list(self.band_hz) if self.band_hz is not None else None,
            "modes": self.modes,
            "delay_samples": fit.delay_samples if fit is not None else None,
            "model": model,
            "fit_quality": quality,
            "note": self.note,
            "units": {"frequency": "Hz", "delay_s": "s", "delay_samples": "samples",
                      "rms_error": "coherence-weighted RMS of |ln(H_measured / H_model)|",
                      "measured.magnitude": "q-unit per u-unit",
                      "measured.phase_deg": "deg", "measured.coherence": "1"},
        }

    @property
    def evidence_band_hz(self) -> tuple[float, float] | None:
        """The band the log backs for the model that tune and validate use, Hz (None: none).

        One definition for every log: the rule of :func:`backed_band` (the run of coherent
        bins, from the lowest that agrees, until two consecutive coherent bins disagree),
        applied to the measured response over the **model handed downstream**: the fitted
        structure (mode and delay included) where a broadband segment gave one, else the
        rigid body, so that without broadband content it is ``band_hz``.  Above its top
        the plant is unknown (:mod:`commission.evidence`).
        """
        if self.fit is None or self.H_model is None:
            return self.band_hz
        with np.errstate(divide="ignore", invalid="ignore"):
            R = np.where(np.abs(self.H) > 0, self.H / self.H_model, 1e-300)
        band = backed_band(self.f, R, self.coherence)
        if band is None:
            return self.band_hz
        if self.band_hz is not None and self.band_hz[0] < band[0] <= self.band_hz[1]:
            band = (self.band_hz[0], band[1])  # the whole log's extension below the segments' bins
        return band

    def measured_points(self, n_max: int = MEASURED_POINTS) -> dict[str, Any]:
        """The measured response, thinned to at most ``n_max`` log-spaced bins (ident.json's ``measured``).

        ``frequency_hz`` (Hz), ``magnitude`` (q-unit per u-unit), ``phase_deg`` (deg),
        ``coherence`` (0-1): the bins nearest to ``n_max`` log-spaced frequencies over the
        estimate's range, each kept once, every value rounded to 6 significant digits.
        """
        f = self.f
        keep = np.flatnonzero(f > 0)
        if keep.size > n_max:
            targets = np.geomspace(f[keep[0]], f[keep[-1]], n_max)
            idx = np.unique(np.clip(np.searchsorted(f, targets), keep[0], keep[-1]))
        else:
            idx = keep

        def r6(a: np.ndarray) -> list[float]:
            return [float(f"{x:.6g}") for x in a]

        H = self.H[idx]
        return {"frequency_hz": r6(f[idx]), "magnitude": r6(np.abs(H)),
                "phase_deg": r6(np.degrees(np.angle(H))), "coherence": r6(self.coherence[idx])}


def _weighted_rms(H: np.ndarray, Hm: np.ndarray | None, coh: np.ndarray) -> float | None:
    if Hm is None:
        return None
    w = np.where(coh >= FIT_COHERENCE, coh, 0.0)
    if not np.any(w > 0):
        return None
    e = np.abs(np.log(H / Hm))
    return float(np.sqrt(np.sum(w * e**2) / np.sum(w)))


# --------------------------------------------------------------------------- segments


def broadband_segments(u: np.ndarray, fs: float) -> list[tuple[int, int]]:
    """Sample ranges ``[i0, i1)`` of the log where the command carries a broadband injection.

    Parameters
    ----------
    u : ndarray
        Command, u-unit.
    fs : float
        Sample rate, Hz.
    """
    nb = max(int(round(BLOCK_S * fs)), 8)
    n_blocks = u.size // nb
    if n_blocks < 3 or u.size < 64:
        return []
    sos = signal.butter(4, fs / 10.0, "highpass", fs=fs, output="sos")
    u_hp = signal.sosfiltfilt(sos, u)
    blocks_hp = u_hp[: n_blocks * nb].reshape(n_blocks, nb)
    blocks = u[: n_blocks * nb].reshape(n_blocks, nb)
    rms = np.sqrt(np.mean(blocks_hp**2, axis=1))
    var = np.var(signal.detrend(blocks, axis=1), axis=1)
    moving = rms > 0
    if not np.any(moving):
        return []
    background = float(np.median(rms[moving]))
    flag = (rms >= BROADBAND_FACTOR * background) & (rms**2 >= BROADBAND_FRACTION * np.maximum(var, 1e-300))
    segs = []
    i = 0
    min_blocks = int(math.ceil(MIN_SEGMENT_S / BLOCK_S))
    while i < n_blocks:
        if not flag[i]:
            i += 1
            continue
        j = i
        while j < n_blocks and flag[j]:
            j += 1
        if j - i >= min_blocks:
            # Leave out the edge blocks: the injection may start or stop inside them.
            a, b = i + 1, j - 1
            if b - a >= max(min_blocks - 2, 1):
                segs.append((a * nb, b * nb))
        i = j
    return segs


# --------------------------------------------------------------------------- estimate


def estimate(q: np.ndarray, u: np.ndarray, fs: float, ranges: list[tuple[int, int]],
             nperseg: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Welch H1 estimate of u -> q averaged over the sample ranges.

    Returns
    -------
    f : ndarray
        Hz, without DC and Nyquist.
    H : ndarray, complex
        m per u-unit.
    coherence : ndarray
    n_averages : int
    """
    step = nperseg - nperseg // 2
    Puu = Pqq = 0.0
    Puq: Any = 0.0
    n_avg = 0
    f = None
    for i0, i1 in ranges:
        L = i1 - i0
        if L < nperseg:
            continue
        k = 1 + (L - nperseg) // step
        kw = dict(fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2, detrend="linear")
        f, puu = signal.welch(u[i0:i1], **kw)
        _, pqq = signal.welch(q[i0:i1], **kw)
        _, puq = signal.csd(u[i0:i1], q[i0:i1], **kw)
        Puu = Puu + k * puu
        Pqq = Pqq + k * pqq
        Puq = Puq + k * puq
        n_avg += k
    if f is None:
        raise ValueError("estimate: no range holds one window")
    keep = (f > 0) & (f < fs / 2.0)
    Puu, Pqq, Puq = np.asarray(Puu)[keep], np.asarray(Pqq)[keep], np.asarray(Puq)[keep]
    with np.errstate(divide="ignore", invalid="ignore"):
        H = Puq / Puu
        coh = np.abs(Puq) ** 2 / (Puu * Pqq)
    coh = np.nan_to_num(np.clip(coh, 0.0, 1.0))
    H = np.where(np.isfinite(H), H, 0.0)
    return f[keep], H, coh, n_avg


# --------------------------------------------------------------------------- band


def backed_band(f: np.ndarray, R: np.ndarray, coh: np.ndarray) -> tuple[float, float] | None:
    """Band in which the coherent data agree with the rigid model (module docstring, step 3), Hz."""
    coherent = np.flatnonzero(coh >= BAND_COHERENCE)
    if coherent.size == 0:
        return None
    ok = ((np.abs(np.log(np.abs(R) + 1e-300)) <= math.log(BAND_GAIN_TOL))
          & (np.abs(np.degrees(np.angle(R))) <= BAND_PHASE_TOL_DEG))
    agree = [i for i in coherent if ok[i]]
    if not agree:
        return None
    low = agree[0]
    high = low
    misses = 0
    for i in coherent[coherent >= low]:
        if ok[i]:
            high = i
            misses = 0
        else:
            misses += 1
            if misses >= 2:
                break
    return round(float(f[low]), 6), round(float(f[high]), 6)  # Hz; drops the round-off of 1 / median(dt)


# --------------------------------------------------------------------------- fit


def _plant(structure: str, M: float, B: float, Ts: float, delay_samples: float, mode_hz: float,
           damping: float, ratio: float) -> np.ndarray:
    if structure == "rigid":
        return plant_vector(M, B, delay=delay_samples * Ts)
    return plant_vector(M, B, mode_hz=mode_hz, mode_damping=damping, mode_ratio=ratio,
                        mode_load_side=structure == "load_side_mode", delay=delay_samples * Ts)


def _unpack(structure: str, x: np.ndarray) -> tuple[float, float, float, float, float]:
    """x -> (mass_scale, delay_samples, mode_hz, damping, ratio)."""
    scale, delay = math.exp(x[0]), x[1]
    if structure == "rigid":
        return scale, delay, 0.0, 0.0, 0.5
    ratio = x[4] if structure == "motor_side_mode" else 0.5
    return scale, delay, math.exp(x[2]), math.exp(x[3]), ratio


def fit_structure(structure: str, f: np.ndarray, H: np.ndarray, coh: np.ndarray, n_avg: int,
                  M: float, B: float, Ts: float, starts: list[np.ndarray]) -> StructureFit:
    """Fit one structure from several starts; the best by cost (module docstring, step 4)."""
    g2 = np.minimum(coh, COHERENCE_CAP)
    sw = np.sqrt(2.0 * n_avg * g2 / (1.0 - g2))
    logH = np.log(H)
    fmin = float(f[0])

    def resid(x: np.ndarray) -> np.ndarray:
        s, d, fr, z, r = _unpack(structure, x)
        Hm = sampled_plant(_plant(structure, M * s, B, Ts, d, fr, z, r), Ts).frequency_response(f)
        e = logH - np.log(Hm)
        ph = np.angle(np.exp(1j * e.imag))  # phase error wrapped to (-pi, pi]
        return np.concatenate([sw * e.real, sw * ph])

    lo = [-1.0, 0.0]
    hi = [1.0, MAX_DELAY_SAMPLES]
    if structure != "rigid":
        lo += [math.log(fmin), math.log(0.002)]
        hi += [math.log(0.5 / Ts), math.log(MAX_DAMPING)]
    if structure == "motor_side_mode":
        lo.append(0.02)
        hi.append(0.95)
    best = None
    for x0 in starts:
        x0 = np.clip(np.asarray(x0, float), np.array(lo) + 1e-9, np.array(hi) - 1e-9)
        sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=200)
        if best is None or sol.cost < best.cost:
            best = sol
    s, d, fr, z, r = _unpack(structure, best.x)
    has_mode = structure != "rigid"
    return StructureFit(structure=structure, mass_scale=s, delay_samples=float(d),
                        mode_hz=fr if has_mode else None, mode_damping=z if has_mode else None,
                        mode_ratio=r if has_mode else None, cost=float(2.0 * best.cost),
                        n_residuals=int(2 * f.size), n_params=len(lo))


def _starts(f: np.ndarray, R: np.ndarray, coh: np.ndarray, fs: float) -> tuple[float, list[float], list[tuple[float, float]]]:
    """Data-driven starts: delay (samples), resonance candidates (Hz), (anti-resonance, resonance) pairs."""
    mag = np.abs(R)
    # Delay from the phase slope of R where |R| is near 1 (no mode there).
    near = (np.abs(np.log(mag)) < math.log(1.5)) & (coh >= BAND_COHERENCE)
    delay0 = 0.0
    if np.count_nonzero(near) >= 4:
        ph = np.unwrap(np.angle(R[near]))
        slope = np.sum(f[near] * ph) / np.sum(f[near] ** 2)
        delay0 = float(np.clip(-slope * fs / (2.0 * np.pi), 0.0, MAX_DELAY_SAMPLES))
    sm = signal.medfilt(np.log(mag), 3)
    peaks, _ = signal.find_peaks(sm)
    peaks = [int(p) for p in peaks if coh[p] >= FIT_COHERENCE]
    peaks.sort(key=lambda p: -sm[p])
    res = [float(f[p]) for p in peaks[:3]]
    if not res:
        res = [float(f[int(np.argmax(sm))])]
    pairs = []
    for fr in res:
        below = np.flatnonzero(f < fr)
        if below.size >= 2:
            ia = below[int(np.argmin(sm[below]))]
            pairs.append((float(f[ia]), fr))
    return delay0, res, pairs


def frequency_response(t: np.ndarray, q: np.ndarray, u: np.ndarray, M: float, B: float) -> FrequencyResponse:
    """Measure the response u -> q of a log and compare it with the rigid model (module docstring).

    Parameters
    ----------
    t : ndarray
        Sample times, s (uniform).
    q : ndarray
        Measured position, m.
    u : ndarray
        Command, u-unit.
    M, B : float
        Identified rigid model, u-unit s^2/m and u-unit s/m.

    Returns
    -------
    FrequencyResponse
    """
    fs = 1.0 / float(np.median(np.diff(t)))
    Ts = 1.0 / fs
    B = max(float(B), 0.0)
    segs = broadband_segments(u, fs)
    if segs:
        nperseg = int(round(fs / RESOLUTION_HZ))
        # At least 8 windows in all: coarser resolution on short segments.
        while nperseg > 32 and sum(max(0, 1 + ((b - a) - nperseg) // (nperseg - nperseg // 2))
                                   for a, b in segs) < 8:
            nperseg //= 2
        segs = [(a, b) for a, b in segs if b - a >= nperseg]
        source = "broadband"
    whole_nperseg = min(int(round(fs / WHOLE_LOG_RESOLUTION_HZ)), max(u.size // 8, 16))
    if not segs:
        # 2-Hz bins: the reference's lines sit a few bins apart, each averaged over many windows.
        nperseg = whole_nperseg
        source = "whole_log"
        ranges = [(0, u.size)]
    else:
        ranges = segs
    f, H, coh, n_avg = estimate(q, u, fs, ranges, nperseg)
    H_rigid = rigid_frequency_response(M, B, Ts, f)
    with np.errstate(divide="ignore", invalid="ignore"):
        R = np.where(np.abs(H) > 0, H / H_rigid, 1e-300)
    band = backed_band(f, R, coh)
    if source == "broadband" and band is not None:
        # The rest of the log (ladder, multisine) backs the model below the segments' first bins:
        # extend the band down where the whole log's band reaches into it.
        fw, Hw, cw, _ = estimate(q, u, fs, [(0, u.size)], whole_nperseg)
        with np.errstate(divide="ignore", invalid="ignore"):
            Rw = np.where(np.abs(Hw) > 0, Hw / rigid_frequency_response(M, B, Ts, fw), 1e-300)
        wb = backed_band(fw, Rw, cw)
        if wb is not None and wb[0] < band[0] <= wb[1]:
            band = (wb[0], band[1])
    seg_times = tuple((float(t[a]), float(t[b - 1])) for a, b in segs) if source == "broadband" else ()
    common = dict(f=f, H=H, coherence=coh, n_averages=n_avg, source=source, segments=seg_times,
                  H_rigid=H_rigid, M=float(M), B=B, band_hz=band, sample_rate=fs)
    band_text = (f"the rigid model is backed by the data from {band[0]:.3g} to {band[1]:.3g} Hz"
                 if band is not None else "no band of coherent data agrees with the rigid model")
    fit_bins = (coh >= FIT_COHERENCE) & (np.abs(H) > 0)
    if source == "whole_log" or np.count_nonzero(fit_bins) < MIN_FIT_BINS:
        why = ("no broadband content in the log (no segment where the command carries a broadband "
               "injection)" if source == "whole_log" else
               f"the broadband segments give only {int(np.count_nonzero(fit_bins))} coherent bins")
        note = f"{why}: modes and input delay are not measured; {band_text}"
        if band is not None:
            note += f", and nothing is known about the plant above {band[1]:.3g} Hz"
        return FrequencyResponse(fit=None, note=note, **common)
    ff, Hf, cf = f[fit_bins], H[fit_bins], coh[fit_bins]
    Rf = R[fit_bins]
    delay0, res, pairs = _starts(ff, Rf, cf, fs)
    lM = 0.0
    fits: dict[str, StructureFit] = {}
    with threadpool_limits(1):
        fits["rigid"] = fit_structure("rigid", ff, Hf, cf, n_avg, M, B, Ts,
                                      [np.array([lM, delay0]), np.array([lM, 0.0])])
        d0 = fits["rigid"].delay_samples
        load_starts = [np.array([lM, dd, math.log(fr), math.log(z)])
                       for fr in res for z in (0.03, 0.15) for dd in sorted({round(d0, 6), round(delay0, 6)})]
        fits["load_side_mode"] = fit_structure("load_side_mode", ff, Hf, cf, n_avg, M, B, Ts, load_starts)
        motor_starts = []
        for fa, fr in pairs:
            r0 = float(np.clip(1.0 - (fa / fr) ** 2, 0.05, 0.9))
            for z in (0.03, 0.15):
                motor_starts.append(np.array([lM, delay0, math.log(fr), math.log(z), r0]))
        if motor_starts:
            fits["motor_side_mode"] = fit_structure("motor_side_mode", ff, Hf, cf, n_avg, M, B, Ts,
                                                    motor_starts)
    best = min(fits.values(), key=lambda s: s.score)
    note = None
    if best.structure != "rigid":
        Hm = sampled_plant(best.plant(M, B, Ts), Ts).frequency_response(ff)
        rigid_like = sampled_plant(plant_vector(M * best.mass_scale, B, delay=best.delay_samples * Ts),
                                   Ts).frequency_response(ff)
        on_edge = (best.mode_damping >= 0.99 * MAX_DAMPING or best.mode_hz <= 1.01 * float(ff[0])  # type: ignore[operator]
                   or best.mode_hz >= 0.99 * 0.5 * fs)  # type: ignore[operator]
        if np.max(np.abs(np.log(np.abs(Hm / rigid_like)))) <= math.log(BAND_GAIN_TOL):
            best = fits["rigid"]
            note = "the best mode changes the response by less than the band tolerance: reported as rigid"
        elif on_edge:
            best = fits["rigid"]
            note = ("the best mode sits on the edge of what the data can show (damping or frequency at its "
                    "bound): reported as rigid; see the measured response")
    H_model = sampled_plant(best.plant(M, B, Ts), Ts).frequency_response(f)
    return FrequencyResponse(fit=best, fits=fits, H_model=H_model, note=note, **common)
