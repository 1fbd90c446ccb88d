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
   the peak.  The structure with the least information criterion wins
   (:attr:`StructureFit.score`: BIC with the residuals' scale unknown,
   ``n ln(cost / n) + k ln n`` for n residuals and k free parameters: a fair
   comparison whether or not the model explains the data to their coherence,
   with no threshold of its own), and a mode only counts when it changes the
   fitted response by more than ``BAND_GAIN_TOL`` somewhere in the fitted
   range and its frequency and damping are not on their bounds.  The load ratio of a load-side mode does not show in u -> q (the
   response is ``(2 zeta w s + w^2) / (M s^2 (s^2 + 2 zeta w s + w^2))`` for
   any ratio): it is reported at 0.5 with ``mode_ratio_identified`` false.
5. **More modes.**  While the measured response departs from the fit beyond
   the estimate's uncertainty (:func:`departures`), one more mode is tried
   (:class:`ExtraMode`: a unit-DC-gain factor, with or without its
   anti-resonance), from the departures and afresh from the peaks of ``|R|``,
   and kept when it lowers the criterion and passes the same checks; up to
   ``MAX_MODES``.  Each parameter gets a standard deviation from the
   Jacobian at the solution (``(J^T J)^-1``, scaled by the reduced chi-square
   when above 1): statistical only, it does not hold the bias of a model
   that is not the plant's.  Two modes are then refitted as the simulator's
   plant, two appendages on the motor (:func:`plant_fit`); what is still
   left is reported as departures, each named by its frequency.
6. **Encoder noise** (:func:`encoder_noise`): the floor of ``q - P u``'s
   spectrum high in the band, less quantization's ``step^2 / 12``.

scipy.linalg on the 5x5 matrices of the sampled plant spends milliseconds in
BLAS thread hand-offs on a busy machine (a thousand times its single-thread
cost), so the fit runs under ``threadpoolctl.threadpool_limits(1)``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import signal
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from commission.controllers.linear import (SampledPlant, _hold, continuous_model, rigid_frequency_response,
                                          sampled_plant)
from commission.controllers.plant import plant_vector

#: A block is broadband when its high-passed command RMS is this many times the moving blocks' median.
#: The median is the holding loop's answer to the encoder's noise and quantization: on a noisy or coarse
#: encoder an injection within a_max stands only 4-6 times above it (a 1 um-noise 2.5 kHz axis, a 5 um
#: 1 kHz one: tests/test_excite.py), which a factor of 10 missed; the real logs without injection
#: (EMPS, ODrive, the screw drive) show no block at 3 times.
BROADBAND_FACTOR = 3.0
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
#: Largest delay fitted, samples.
MAX_DELAY_SAMPLES = 6.0
#: Largest damping ratio fitted (a mode damped more than this is no resonance to report).
MAX_DAMPING = 0.7
#: Coherent bins the fit needs.
MIN_FIT_BINS = 12
#: Probability that a right model shows a departure somewhere in the measured response (:func:`departures`).
DEPARTURE_ALPHA = 0.01
#: Multi-start fits: iterations of the screening stage from every start, and the starts kept to the end.
SCREEN_NFEV = 30
SCREEN_KEEP = 2
#: Most modes fitted (each further one must lower the information criterion and pass the guards).
MAX_MODES = 4
#: Most measured bins carried into ident.json (``frequency_response.measured``).
MEASURED_POINTS = 200

STRUCTURES = ("rigid", "load_side_mode", "motor_side_mode")


@dataclass(frozen=True)
class ExtraMode:
    """A structural mode beyond the first, as an input-side factor of the fitted response.

    ``kind`` ``"load"``: ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)`` (a resonance only, as a
    mode seen across the structure); ``"motor"``: ``(w / w_a)^2 (s^2 + 2 zeta_a w_a s + w_a^2) /
    (s^2 + 2 zeta w s + w^2)`` with ``w_a = w sqrt(1 - r)``, ``zeta_a = zeta sqrt(1 - r)`` (an
    anti-resonance below the resonance, as a mode seen next to the force).  Both have unit gain at
    DC, so the rigid body and the first mode keep their meaning.

    Attributes
    ----------
    kind : {"load", "motor"}
    hz : float
        Resonance, Hz.
    damping : float
        Damping ratio, -.
    ratio : float
        Load fraction r of the anti-resonance (0.5, not identified, for ``"load"``), -.
    hz_std, damping_std, ratio_std : float or None
        One standard deviation from the fit's covariance, Hz, -, -.
    """

    kind: str
    hz: float
    damping: float
    ratio: float = 0.5
    hz_std: float | None = None
    damping_std: float | None = None
    ratio_std: float | None = None


@dataclass(frozen=True)
class StructureFit:
    """One candidate structure fitted to the measured response.

    Attributes
    ----------
    structure : str
        ``"rigid"``, ``"load_side_mode"`` or ``"motor_side_mode"``: the first mode, as the
        simulator's two-mass plant.
    mass_scale : float
        Mass of the fitted plant over the rigid fit's M.
    delay_samples : float
        Input delay beyond the zero-order hold, samples.
    mode_hz, mode_damping, mode_ratio : float or None
        First mode of the fitted plant (Hz, -, -); None for rigid.
    cost : float
        Sum of squared normalised residuals (about the number of residuals for a right model).
    n_residuals : int
    n_params : int
    mode_hz_std, mode_damping_std, mode_ratio_std : float or None
        One standard deviation of the first mode's parameters (Hz, -, -) from the fit's
        covariance ``(J^T J)^-1``, scaled by the reduced chi-square when that exceeds 1.
    delay_std : float or None
        Of the delay, samples.
    extra : tuple of ExtraMode
        Further modes, as input-side factors.
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
    mode_hz_std: float | None = None
    mode_damping_std: float | None = None
    mode_ratio_std: float | None = None
    delay_std: float | None = None
    extra: tuple[ExtraMode, ...] = ()

    @property
    def n_modes(self) -> int:
        return (0 if self.structure == "rigid" else 1) + len(self.extra)

    @property
    def all_modes(self) -> list[ExtraMode]:
        """Every fitted mode, the first (the two-mass plant's) as an :class:`ExtraMode` too."""
        if self.structure == "rigid" or self.mode_hz is None or self.mode_damping is None:
            return list(self.extra)
        first = ExtraMode("motor" if self.structure == "motor_side_mode" else "load", self.mode_hz,
                          self.mode_damping, self.mode_ratio if self.mode_ratio is not None else 0.5,
                          self.mode_hz_std, self.mode_damping_std, self.mode_ratio_std)
        return [first, *self.extra]

    @property
    def score(self) -> float:
        """Bayesian information criterion with the residuals' scale unknown: ``n ln(cost / n) + k ln n``.

        The residuals are normalised by the coherence's variance, so for a right model
        ``cost ~ n``; a model the data reject (closed-loop bias, a missed mode) has a larger
        cost, and the unknown-scale form stays fair between structures then.  Lower is better.
        """
        n = max(self.n_residuals, 1)
        return n * math.log(max(self.cost, 1e-300) / n) + self.n_params * math.log(n)

    def plant(self, M: float, B: float, Ts: float) -> np.ndarray:
        """The fitted plant vector (linear part only: no friction; the first mode only)."""
        return _plant(self.structure, M * self.mass_scale, B, Ts, self.delay_samples,
                      self.mode_hz or 0.0, self.mode_damping or 0.0, self.mode_ratio or 0.5)

    def response(self, M: float, B: float, Ts: float, f: np.ndarray) -> np.ndarray:
        """Sampled response of the fitted model at ``f`` (Hz), every mode included, m per u-unit."""
        return _model_response(self.structure, M * self.mass_scale, B, Ts, self.delay_samples,
                               self.mode_hz or 0.0, self.mode_damping or 0.0, self.mode_ratio or 0.5,
                               self.extra, f)


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
    departures : tuple of Departure
        Where the measured response departs from the chosen fit beyond its uncertainty
        (:func:`departures`).
    plant : PlantFit or None
        Two modes as the simulator's plant (:func:`plant_fit`); None with fewer.
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
    departures: tuple["Departure", ...] = ()
    plant: "PlantFit | None" = None

    @property
    def modes(self) -> list[dict[str, Any]]:
        """Resonances and anti-resonances of the fitted model, lowest first.

        ``frequency_hz`` (Hz), ``damping`` (-), ``kind``, ``gain``: ``|H / H_rigid|`` of the
        fitted model there (-), ``frequency_std_hz`` (Hz) and ``damping_std`` (-): one standard
        deviation from the fit's covariance (None where the fit gives none), and ``mode``: which
        fitted mode (1, 2, ...) the entry belongs to.
        """
        fit = self.fit
        if fit is None or fit.mode_hz is None:
            return []
        out = []
        for k, m in enumerate(fit.all_modes, start=1):
            if m.kind == "motor":
                c = math.sqrt(1.0 - m.ratio)
                out.append({"frequency_hz": m.hz * c, "damping": m.damping * c, "kind": "anti-resonance",
                            "frequency_std_hz": None if m.hz_std is None else m.hz_std * c,
                            "damping_std": None if m.damping_std is None else m.damping_std * c, "mode": k})
            out.append({"frequency_hz": m.hz, "damping": m.damping, "kind": "resonance",
                        "frequency_std_hz": m.hz_std, "damping_std": m.damping_std, "mode": k})
        for m in out:
            m["gain"] = self._model_gain(m["frequency_hz"])
        out.sort(key=lambda m: m["frequency_hz"])
        return out

    def _model_gain(self, f_hz: float) -> float:
        Ts = 1.0 / self.sample_rate
        Hm = self.fit.response(self.M, self.B, Ts, np.array([f_hz]))[0]  # type: ignore[union-attr]
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
                "mode_hz_std": fit.mode_hz_std,
                "mode_damping_std": fit.mode_damping_std,
                "delay_s": fit.delay_samples / self.sample_rate,
                "delay_std_s": None if fit.delay_std is None else fit.delay_std / self.sample_rate,
                "mass_scale": fit.mass_scale,
                "n_modes": fit.n_modes,
            }
            m2: ExtraMode | None = None  # the simulator's second mode comes from the plant fit only (below)
            model.update({
                "mode2_hz": None if m2 is None else m2.hz,
                "mode2_damping": None if m2 is None else m2.damping,
                "mode2_ratio": None if m2 is None else float(m2.ratio),
                "mode2_ratio_identified": None if m2 is None else m2.kind == "motor",
                "mode2_load_side": None if m2 is None else m2.kind == "load",
                "mode2_hz_std": None if m2 is None else m2.hz_std,
                "mode2_damping_std": None if m2 is None else m2.damping_std,
            })
            if self.plant is not None:
                # The simulator's plant: each appendage's own frequency (coupled: the measured modes).
                kw, sd = self.plant.kwargs, self.plant.std
                model.update({
                    "mode_hz": kw["mode_hz"], "mode_damping": kw["mode_damping"], "mode_ratio": kw["mode_ratio"],
                    "mode_load_side": kw["mode_load_side"], "mode_ratio_identified": not kw["mode_load_side"],
                    "mode_hz_std": sd["mode_hz"], "mode_damping_std": sd["mode_damping"],
                    "mode2_hz": kw["mode2_hz"], "mode2_damping": kw["mode2_damping"],
                    "mode2_ratio": kw["mode2_ratio"], "mode2_load_side": kw["mode2_load_side"],
                    "mode2_ratio_identified": True, "mode2_hz_std": sd["mode2_hz"],
                    "mode2_damping_std": sd["mode2_damping"], "delay_s": kw["delay"],
                    "mass_scale": self.plant.mass_scale,
                    "appendages": True,
                })
        quality = None
        if fit is not None:
            quality = {
                "structure": fit.structure,
                "n_modes": fit.n_modes,
                "model_rms_error": _weighted_rms(self.H, self.H_model, self.coherence),
                "rigid_rms_error": _weighted_rms(self.H, self.H_rigid, self.coherence),
                "scores": {k: v.score for k, v in self.fits.items()},
                "criterion": "BIC, unknown scale: n ln(cost/n) + k ln n (lower is better)",
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
            "departures": [d.to_dict() for d in self.departures],
            "note": self.note,
            "units": {"frequency": "Hz", "delay_s": "s", "delay_samples": "samples",
                      "frequency_std_hz": "Hz", "departures.ratio_db": "dB",
                      "rms_error": "coherence-weighted RMS of |ln(H_measured / H_model)|",
                      "measured.magnitude": "q-unit per u-unit",
                      "measured.phase_deg": "deg", "measured.coherence": "1"},
        }

    @property
    def warnings(self) -> list[str]:
        """One sentence per departure of the measured response from the fitted model (a missed mode?)."""
        return [d.sentence() for d in self.departures]

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


@dataclass(frozen=True)
class Departure:
    """A run of coherent bins where the measured response departs from the fitted model beyond its uncertainty.

    Attributes
    ----------
    frequency_hz : float
        Bin of the largest departure, Hz.
    low_hz, high_hz : float
        The run, Hz.
    ratio_db : float
        ``20 log10 |H_measured / H_model|`` there, dB.
    phase_deg : float
        Phase of that ratio, degrees.
    sigma : float
        The departure in standard deviations of the estimate there (from its coherence), -.
    coherence : float
        There, -.
    """

    frequency_hz: float
    low_hz: float
    high_hz: float
    ratio_db: float
    phase_deg: float
    sigma: float
    coherence: float

    def to_dict(self) -> dict[str, float]:
        return {"frequency_hz": self.frequency_hz, "low_hz": self.low_hz, "high_hz": self.high_hz,
                "ratio_db": self.ratio_db, "phase_deg": self.phase_deg, "sigma": self.sigma,
                "coherence": self.coherence}

    def sentence(self) -> str:
        return (f"frequency response: the measured response departs from the fitted model at "
                f"{self.frequency_hz:.4g} Hz by {self.ratio_db:+.1f} dB and {self.phase_deg:+.0f} deg "
                f"({self.sigma:.0f} standard deviations at coherence {self.coherence:.2f}; "
                f"{self.low_hz:.4g}-{self.high_hz:.4g} Hz): a mode the model lacks? The simulator does "
                f"not hold it")


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


def _factor(m: ExtraMode) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """State space ``(A, B, C, D)`` of an extra mode's factor (:class:`ExtraMode`), scaled states.

    States ``x1``, ``x2 = x1' / w`` with ``x1'' + 2 zeta w x1' + w^2 x1 = w^2 u``: then
    ``load = x1 + 2 zeta x2`` and ``motor = (w/wa)^2 (s^2 + 2 zeta_a wa s + wa^2) / den =
    (1 - 1/c) (x1 + 2 zeta x2) + u / c`` with ``c = 1 - r`` (the two-mass plant's motor-side
    numerator ``(m2 s^2 + c s + k) / k``).  Both have unit gain at DC.
    """
    w = 2.0 * math.pi * m.hz
    A = np.array([[0.0, w], [-w, -2.0 * m.damping * w]])
    B = np.array([[0.0], [w]])
    C = np.array([[1.0, 2.0 * m.damping]])
    if m.kind == "load":
        return A, B, C, 0.0
    c = 1.0 - m.ratio
    return A, B, C * (1.0 - 1.0 / c), 1.0 / c


def _sampled_response(A: np.ndarray, Bm: np.ndarray, C: np.ndarray, Ts: float, tau: float,
                      f: np.ndarray) -> np.ndarray:
    """Response at ``f`` (Hz) of ``(A, Bm, C)`` behind a zero-order hold and ``tau`` samples of input delay.

    The discretisation of :func:`commission.controllers.linear.sampled_plant` (modified
    z-transform), for any continuous model.
    """
    n = int(math.floor(tau + 1e-9))
    fr = tau - n
    if fr < 1e-9:
        fr = 0.0
    Phi_a, G_a = _hold(A, Bm, (1.0 - fr) * Ts)
    if fr > 0:
        Phi_b, G_b = _hold(A, Bm, fr * Ts)
        G1 = Phi_a @ G_b
        Phi = Phi_a @ Phi_b
    else:
        G1 = np.zeros_like(G_a)
        Phi = Phi_a
    return SampledPlant(Phi=Phi, G0=G_a, G1=G1, C=C, n=n, Ts=float(Ts)).frequency_response(f)


def _model_response(structure: str, M: float, B: float, Ts: float, delay_samples: float, mode_hz: float,
                    damping: float, ratio: float, extra: tuple[ExtraMode, ...], f: np.ndarray) -> np.ndarray:
    """Sampled response of the two-mass plant (first mode) behind the extra modes' factors, m per u-unit."""
    A, Bm, C = continuous_model(_plant(structure, M, B, Ts, 0.0, mode_hz, damping, ratio))
    for m in extra:
        Af, Bf, Cf, Df = _factor(m)
        nf, nx = Af.shape[0], A.shape[0]
        A2 = np.zeros((nf + nx, nf + nx))
        A2[:nf, :nf] = Af
        A2[nf:, :nf] = Bm @ Cf
        A2[nf:, nf:] = A
        B2 = np.vstack([Bf, Bm * Df])
        C2 = np.hstack([np.zeros((1, nf)), C])
        A, Bm, C = A2, B2, C2
    return _sampled_response(A, Bm, C, Ts, delay_samples, f)


def _layout(structure: str, extra_kinds: tuple[str, ...]) -> list[int]:
    """Parameters per mode: 0 (rigid), 2 (load side: f, zeta) or 3 (motor side: f, zeta, r)."""
    first = {"rigid": 0, "load_side_mode": 2, "motor_side_mode": 3}[structure]
    return [first] + [3 if k == "motor" else 2 for k in extra_kinds]


def _unpack(structure: str, x: np.ndarray, extra_kinds: tuple[str, ...] = ()
            ) -> tuple[float, float, float, float, float, tuple[ExtraMode, ...]]:
    """x -> (mass_scale, delay_samples, mode_hz, damping, ratio, extra modes)."""
    scale, delay = math.exp(x[0]), x[1]
    lay = _layout(structure, extra_kinds)
    i = 2
    fr = z = 0.0
    r = 0.5
    if lay[0]:
        fr, z = math.exp(x[2]), math.exp(x[3])
        r = x[4] if lay[0] == 3 else 0.5
    i += lay[0]
    extra = []
    for kind, k in zip(extra_kinds, lay[1:]):
        extra.append(ExtraMode(kind, math.exp(x[i]), math.exp(x[i + 1]), float(x[i + 2]) if k == 3 else 0.5))
        i += k
    return scale, delay, fr, z, r, tuple(extra)


def _weights(coh: np.ndarray, n_avg: int) -> np.ndarray:
    """Inverse standard deviation of ln H (each of its real and imaginary parts) per bin, from the coherence."""
    g2 = np.minimum(coh, COHERENCE_CAP)
    return np.sqrt(2.0 * n_avg * g2 / (1.0 - g2))


def fit_structure(structure: str, f: np.ndarray, H: np.ndarray, coh: np.ndarray, n_avg: int,
                  M: float, B: float, Ts: float, starts: list[np.ndarray],
                  extra_kinds: tuple[str, ...] = ()) -> StructureFit:
    """Fit one structure from several starts; the best by cost (module docstring, step 4).

    ``extra_kinds`` adds further modes (:class:`ExtraMode`) after the first.  The
    parameters' standard deviations come from the Jacobian at the solution,
    ``cov = (J^T J)^-1 max(1, cost / (n - k))``.
    """
    sw = _weights(coh, n_avg)
    logH = np.log(H)
    fmin = float(f[0])

    def resid(x: np.ndarray) -> np.ndarray:
        s, d, fr, z, r, extra = _unpack(structure, x, extra_kinds)
        Hm = _model_response(structure, M * s, B, Ts, d, fr, z, r, extra, f)
        e = logH - np.log(Hm)
        ph = np.angle(np.exp(1j * e.imag))  # phase error wrapped to (-pi, pi]
        return np.concatenate([sw * e.real, sw * ph])

    lo = [-1.0, 0.0]
    hi = [1.0, MAX_DELAY_SAMPLES]
    for k in _layout(structure, extra_kinds):
        if k >= 2:
            lo += [math.log(fmin), math.log(0.002)]
            hi += [math.log(0.5 / Ts), math.log(MAX_DAMPING)]
        if k == 3:
            lo.append(0.02)
            hi.append(0.95)
    x0s = [np.clip(np.asarray(x0, float), np.array(lo) + 1e-9, np.array(hi) - 1e-9) for x0 in starts]
    if len(x0s) > SCREEN_KEEP:
        # Multi-start in two stages: a few iterations from every start, then the best few to the end.
        screened = [least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=SCREEN_NFEV) for x0 in x0s]
        screened.sort(key=lambda s: s.cost)
        x0s = [s.x for s in screened[:SCREEN_KEEP]]
    best = None
    for x0 in x0s:
        sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=200)
        if best is None or sol.cost < best.cost:
            best = sol
    s, d, fr, z, r, extra = _unpack(structure, best.x, extra_kinds)
    n_res, n_par = int(2 * f.size), len(lo)
    cost = float(2.0 * best.cost)
    std = _parameter_std(best.jac, cost, n_res)
    lay = _layout(structure, extra_kinds)
    has_mode = structure != "rigid"
    i = 2 + lay[0]
    ex = []
    for m, k in zip(extra, lay[1:]):
        ex.append(dataclasses.replace(m, hz_std=float(m.hz * std[i]), damping_std=float(m.damping * std[i + 1]),
                                      ratio_std=float(std[i + 2]) if k == 3 else None))
        i += k
    return StructureFit(structure=structure, mass_scale=s, delay_samples=float(d),
                        mode_hz=fr if has_mode else None, mode_damping=z if has_mode else None,
                        mode_ratio=r if has_mode else None, cost=cost, n_residuals=n_res, n_params=n_par,
                        mode_hz_std=float(fr * std[2]) if has_mode else None,
                        mode_damping_std=float(z * std[3]) if has_mode else None,
                        mode_ratio_std=float(std[4]) if lay[0] == 3 else None,
                        delay_std=float(std[1]), extra=tuple(ex))


def _parameter_std(J: np.ndarray, cost: float, n: int) -> np.ndarray:
    """Standard deviations of the fitted parameters from the Jacobian of the normalised residuals."""
    k = J.shape[1]
    scale = max(1.0, cost / max(n - k, 1))
    cov = np.linalg.pinv(J.T @ J) * scale
    return np.sqrt(np.maximum(np.diag(cov), 0.0))


def departures(f: np.ndarray, H: np.ndarray, Hm: np.ndarray, coh: np.ndarray, n_avg: int,
               alpha: float = DEPARTURE_ALPHA) -> list[Departure]:
    """Runs of bins where the measured response departs from a model beyond the estimate's uncertainty.

    A bin departs when both hold:

    * **beyond its uncertainty**: ``z^2 = w^2 |ln(H / H_model)|^2`` (``w`` from the
      coherence, :func:`_weights`; real and imaginary parts each of unit variance for a right
      model, so ``z^2`` is chi-square with 2 degrees of freedom) exceeds the level a right
      model passes with probability ``alpha`` over *all* the bins at once (Bonferroni:
      ``z^2 > -2 ln(alpha / n_bins)``);
    * **large enough to matter**: the gain ratio is outside ``BAND_GAIN_TOL`` or its phase
      outside ``BAND_PHASE_TOL_DEG`` (the tolerance that ends the band the data back).

    Runs of such bins (gaps of one bin bridged) of at least two bins are reported at their
    largest rise of the gain ratio beyond the tolerance (the resonance of a missed mode), else
    at their deepest dip.  Only bins with coherence ``>= BAND_COHERENCE`` are judged (the level
    that bounds the band the data back): in a closed loop, where the coherence is lower the
    encoder noise's feedback dominates the command and H1 leans towards minus the
    controller's inverse (module docstring, step 2), a bias no model of the plant explains.
    """
    ok = (coh >= BAND_COHERENCE) & (np.abs(H) > 0) & (np.abs(Hm) > 0)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return []
    e = np.log(H[idx] / Hm[idx])
    e = e.real + 1j * np.angle(np.exp(1j * e.imag))
    z2 = (_weights(coh[idx], n_avg) ** 2) * np.abs(e) ** 2
    level = -2.0 * math.log(alpha / idx.size)
    big = (np.abs(e.real) > math.log(BAND_GAIN_TOL)) | (np.abs(np.degrees(e.imag)) > BAND_PHASE_TOL_DEG)
    flag = (z2 > level) & big
    out: list[Departure] = []
    j = 0
    while j < idx.size:
        if not flag[j]:
            j += 1
            continue
        k = j
        last = j
        while k + 1 < idx.size and (flag[k + 1] or (k + 2 < idx.size and flag[k + 2])):
            k += 1
            if flag[k]:
                last = k
        run = np.arange(j, last + 1)
        run = run[flag[run]]
        if run.size >= 2:
            # At the largest rise (a resonance the model lacks), else at the deepest dip.
            rise = e.real[run]
            p = run[int(np.argmax(rise))] if rise.max() > math.log(BAND_GAIN_TOL) else run[int(np.argmax(np.abs(rise)))]
            out.append(Departure(frequency_hz=float(f[idx[p]]), low_hz=float(f[idx[run[0]]]),
                                 high_hz=float(f[idx[run[-1]]]), ratio_db=float(20.0 / math.log(10.0) * e.real[p]),
                                 phase_deg=float(np.degrees(e.imag[p])), sigma=float(math.sqrt(z2[p])),
                                 coherence=float(coh[idx[p]])))
        j = last + 1
    return out


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


def _pack(fit: StructureFit) -> np.ndarray:
    """The parameter vector of a fit (the inverse of :func:`_unpack`)."""
    x = [math.log(fit.mass_scale), fit.delay_samples]
    if fit.structure != "rigid":
        x += [math.log(fit.mode_hz), math.log(fit.mode_damping)]  # type: ignore[arg-type]
        if fit.structure == "motor_side_mode":
            x.append(fit.mode_ratio)
    for m in fit.extra:
        x += [math.log(m.hz), math.log(m.damping)] + ([m.ratio] if m.kind == "motor" else [])
    return np.array(x, dtype=float)


def _on_edge(hz: float, damping: float, fmin: float, fs: float) -> bool:
    return damping >= 0.99 * MAX_DAMPING or hz <= 1.01 * fmin or hz >= 0.99 * 0.5 * fs


def _one_more_mode(current: StructureFit, peaks: list[float], ff: np.ndarray, Hf: np.ndarray, cf: np.ndarray,
                   n_avg: int, M: float, B: float, Ts: float) -> StructureFit | None:
    """The fit with one mode more than ``current``; None when the data do not support it.

    Starts come from the data: ``current`` plus a mode where the measured response
    departs from it (:func:`departures`), and afresh every choice of ``k + 1`` frequencies
    among the peaks of ``|H / H_rigid|`` (``peaks``), the departures and ``current``'s modes,
    all seen on the motor side or all on the load side (a fit of one mode too few can be a
    compromise far from either, so it is not always the best place to start from).  The
    larger model is kept when it lowers the information criterion
    (:attr:`StructureFit.score`), each of its modes changes the response by more than
    ``BAND_GAIN_TOL`` somewhere in the fitted range, and none is on a bound.
    """
    deps = departures(ff, Hf, current.response(M, B, Ts, ff), cf, n_avg)
    if not deps:
        return None
    dep_f = [d.frequency_hz for d in sorted(deps, key=lambda d: -d.sigma)[:3]]
    k = current.n_modes + 1
    x0 = _pack(current)
    kinds = tuple(m.kind for m in current.extra)
    cands = []
    for kind in ("load", "motor") if current.structure != "rigid" else ():  # from rigid: the fresh starts below
        starts = [np.concatenate([x0, [math.log(fd), math.log(z)] + ([0.3] if kind == "motor" else [])])
                  for fd in dep_f for z in (0.03, 0.15)]
        cands.append(fit_structure(current.structure, ff, Hf, cf, n_avg, M, B, Ts, starts,
                                   extra_kinds=kinds + (kind,)))
    own = [m.hz for m in current.all_modes]
    pool: list[float] = []
    for fr in sorted(set(own) | set(peaks[:3]) | set(dep_f)):
        if all(abs(fr - p) > 0.05 * p for p in pool):
            pool.append(fr)
    for first, kind in (("load_side_mode", "load"), ("motor_side_mode", "motor")):
        per = 3 if kind == "motor" else 2
        starts = []
        for combo in itertools.combinations(pool, k):
            x = [0.0, current.delay_samples]
            for fr in combo:
                x += [math.log(fr), math.log(0.05)] + ([0.3] if per == 3 else [])
            starts.append(np.array(x))
        if starts:
            cands.append(fit_structure(first, ff, Hf, cf, n_avg, M, B, Ts, starts, extra_kinds=(kind,) * (k - 1)))
    for cand in sorted(cands, key=lambda s: s.score):
        if not cand.score < current.score:
            return None
        if _modes_hold(cand, ff, M, B, Ts):
            return cand
    return None


def _keep_modes(fit: StructureFit, n: int, ff: np.ndarray, M: float, B: float, Ts: float) -> StructureFit:
    """``fit`` cut to the ``n`` modes that change its response most, as fitted (no refit).

    A refit with fewer modes than the data hold can land on a compromise that is none of
    them; kept as fitted, the dropped modes show as departures at their own frequencies.
    """
    modes = fit.all_modes
    full = fit.response(M, B, Ts, ff)

    def effect(i: int) -> float:
        without = _with_modes(fit, modes[:i] + modes[i + 1:]).response(M, B, Ts, ff)
        return float(np.max(np.abs(np.log(np.abs(full / without)))))

    order = sorted(range(len(modes)), key=lambda i: -effect(i))
    kept = [modes[i] for i in sorted(order[:n], key=lambda i: modes[i].hz)]
    return _with_modes(fit, kept)


def _with_modes(fit: StructureFit, modes: list[ExtraMode]) -> StructureFit:
    """``fit`` (mass, delay, cost) with its modes replaced: the first as the two-mass plant's, the rest as factors."""
    if not modes:
        return dataclasses.replace(fit, structure="rigid", mode_hz=None, mode_damping=None, mode_ratio=None,
                                   mode_hz_std=None, mode_damping_std=None, mode_ratio_std=None, extra=())
    m = modes[0]
    return dataclasses.replace(fit, structure="motor_side_mode" if m.kind == "motor" else "load_side_mode",
                               mode_hz=m.hz, mode_damping=m.damping, mode_ratio=m.ratio, mode_hz_std=m.hz_std,
                               mode_damping_std=m.damping_std, mode_ratio_std=m.ratio_std, extra=tuple(modes[1:]))


def _modes_hold(fit: StructureFit, ff: np.ndarray, M: float, B: float, Ts: float) -> bool:
    """Every extra mode of ``fit`` is off its bounds and changes the fitted response by more than ``BAND_GAIN_TOL``."""
    full = fit.response(M, B, Ts, ff)
    for i, m in enumerate(fit.extra):
        if _on_edge(m.hz, m.damping, float(ff[0]), 1.0 / Ts):
            return False
        without = dataclasses.replace(fit, extra=fit.extra[:i] + fit.extra[i + 1:])
        if not np.max(np.abs(np.log(np.abs(full / without.response(M, B, Ts, ff))))) > math.log(BAND_GAIN_TOL):
            return False
    if fit.structure != "rigid":
        if _on_edge(fit.mode_hz, fit.mode_damping, float(ff[0]), 1.0 / Ts):  # type: ignore[arg-type]
            return False
        rigid_first = dataclasses.replace(fit, structure="rigid", extra=fit.extra)
        if not np.max(np.abs(np.log(np.abs(full / rigid_first.response(M, B, Ts, ff))))) > math.log(BAND_GAIN_TOL):
            return False
    return True


@dataclass(frozen=True)
class PlantFit:
    """Two fitted modes as the simulator's plant: two appendages on the motor (:mod:`commission.controllers.plant`).

    Attributes
    ----------
    kwargs : dict
        :func:`commission.controllers.plant.plant_vector` keywords: ``mode_hz`` (Hz), ``mode_damping``,
        ``mode_ratio``, ``mode_load_side``, ``mode2_hz`` (Hz), ``mode2_damping``, ``mode2_ratio``,
        ``mode2_load_side`` and ``delay`` (s).  The frequencies are each appendage's own; coupled,
        they give the measured modes.
    std : dict
        One standard deviation of ``mode_hz``, ``mode_damping``, ``mode2_hz``, ``mode2_damping``.
    mass_scale : float
    cost : float
        As :attr:`StructureFit.cost`.
    """

    kwargs: dict[str, Any]
    std: dict[str, float]
    mass_scale: float
    cost: float


def plant_fit(fit: StructureFit, ff: np.ndarray, Hf: np.ndarray, cf: np.ndarray, n_avg: int, M: float, B: float,
              Ts: float) -> PlantFit | None:
    """Refit a two-mode :class:`StructureFit` as the simulator's two-appendage plant; None when it has no such form.

    The modal fit says what the response shows; the simulator needs masses, springs and
    an encoder position.  A mode seen without an anti-resonance (``load``) is the appendage
    the encoder reads (``mode_load_side``); one seen with it (``motor``) hangs on the motor
    beside it.  Two ``load`` modes have no such plant (the encoder reads one place): None.
    The appendages' own frequencies, damping ratios and load fractions (``r2 = t (1 - r1)``,
    so ``r1 + r2 < 1``) are fitted to the measured response with the residuals of
    :func:`fit_structure`, from the modal fit's values.
    """
    if fit.n_modes != 2:
        return None
    modes = fit.all_modes
    kinds = [m.kind for m in modes]
    if kinds == ["load", "load"]:
        return None
    load_side = "load" in kinds
    a, b = ((modes[kinds.index("load")], modes[1 - kinds.index("load")]) if load_side
            else sorted(modes, key=lambda m: m.hz))
    sw = _weights(cf, n_avg)
    logH = np.log(Hf)

    def build(x: np.ndarray) -> tuple[np.ndarray, float]:
        r1 = float(x[4])
        p = plant_vector(M * math.exp(x[0]), B, mode_hz=math.exp(x[2]), mode_damping=math.exp(x[3]),
                         mode_ratio=r1, mode_load_side=load_side, mode2_hz=math.exp(x[5]),
                         mode2_damping=math.exp(x[6]), mode2_ratio=float(x[7]) * (1.0 - r1))
        return p, float(x[1])

    def resid(x: np.ndarray) -> np.ndarray:
        p, d = build(x)
        Hm = _sampled_response(*continuous_model(p), Ts, d, ff)
        e = logH - np.log(Hm)
        return np.concatenate([sw * e.real, sw * np.angle(np.exp(1j * e.imag))])

    fmin = float(ff[0])
    lo = [-1.0, 0.0, math.log(fmin), math.log(0.002), 0.02, math.log(fmin), math.log(0.002), 0.02]
    hi = [1.0, MAX_DELAY_SAMPLES, math.log(0.5 / Ts), math.log(MAX_DAMPING), 0.9, math.log(0.5 / Ts),
          math.log(MAX_DAMPING), 0.95]
    starts = []
    for r1 in ({0.3, a.ratio} if a.kind == "motor" else {0.3, 0.1}):
        r1 = float(np.clip(r1, 0.05, 0.85))
        t2 = float(np.clip(b.ratio / (1.0 - r1), 0.05, 0.9))
        starts.append(np.array([math.log(fit.mass_scale), fit.delay_samples, math.log(a.hz), math.log(a.damping), r1,
                                math.log(b.hz), math.log(b.damping), t2]))
    best = None
    with threadpool_limits(1):
        for x0 in starts:
            x0 = np.clip(x0, np.array(lo) + 1e-9, np.array(hi) - 1e-9)
            sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=200)
            if best is None or sol.cost < best.cost:
                best = sol
    x = best.x
    cost = float(2.0 * best.cost)
    std = _parameter_std(best.jac, cost, int(2 * ff.size))
    r1 = float(x[4])
    kwargs = {"mode_hz": math.exp(x[2]), "mode_damping": math.exp(x[3]), "mode_ratio": r1, "mode_load_side": load_side,
              "mode2_hz": math.exp(x[5]), "mode2_damping": math.exp(x[6]), "mode2_ratio": float(x[7]) * (1.0 - r1),
              "mode2_load_side": False, "delay": float(x[1]) * Ts}
    sd = {"mode_hz": kwargs["mode_hz"] * std[2], "mode_damping": kwargs["mode_damping"] * std[3],
          "mode2_hz": kwargs["mode2_hz"] * std[5], "mode2_damping": kwargs["mode2_damping"] * std[6]}
    return PlantFit(kwargs=kwargs, std={k: float(v) for k, v in sd.items()}, mass_scale=math.exp(x[0]), cost=cost)


def frequency_response(t: np.ndarray, q: np.ndarray, u: np.ndarray, M: float, B: float,
                       max_modes: int = MAX_MODES, *,
                       ranges: list[tuple[int, int]] | None = None) -> FrequencyResponse:
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
    max_modes : int
        Most structural modes fitted (0: rigid body only).  Fewer than the data hold leaves
        the rest as :attr:`FrequencyResponse.departures`, each named by its frequency.
    ranges : list of (int, int), optional
        Sample ranges ``[i0, i1)`` known to carry the broadband injection (from the
        excitation plan, ``identify --plan``) instead of those step 1 finds: a plan
        knows where its injection is, whatever its spectrum's shape over time.

    Returns
    -------
    FrequencyResponse
    """
    fs = 1.0 / float(np.median(np.diff(t)))
    Ts = 1.0 / fs
    B = max(float(B), 0.0)
    segs = broadband_segments(u, fs) if ranges is None else [(int(a), int(b)) for a, b in ranges if b > a]
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
    note = None
    with threadpool_limits(1):
        fits["rigid"] = fit_structure("rigid", ff, Hf, cf, n_avg, M, B, Ts,
                                      [np.array([lM, delay0]), np.array([lM, 0.0])])
        d0 = fits["rigid"].delay_samples
        if max_modes >= 1:
            load_starts = [np.array([lM, dd, math.log(fr), math.log(z)])
                           for fr in res for z in (0.03, 0.15) for dd in sorted({round(d0, 6), round(delay0, 6), 0.0})]
            fits["load_side_mode"] = fit_structure("load_side_mode", ff, Hf, cf, n_avg, M, B, Ts, load_starts)
            motor_starts = []
            for fa, fr in pairs:
                r0 = float(np.clip(1.0 - (fa / fr) ** 2, 0.05, 0.9))
                for z in (0.03, 0.15):
                    for dd in sorted({round(delay0, 6), 0.0}):
                        motor_starts.append(np.array([lM, dd, math.log(fr), math.log(z), r0]))
            if motor_starts:
                fits["motor_side_mode"] = fit_structure("motor_side_mode", ff, Hf, cf, n_avg, M, B, Ts,
                                                        motor_starts)
        # The best structure by the criterion whose mode passes the checks (rigid always does): a
        # compromise of one mode over two (damping on its bound) gives way to the next.
        best = fits["rigid"]
        for cand in sorted(fits.values(), key=lambda s: s.score):
            if cand.structure == "rigid":
                break
            Hm = cand.response(M, B, Ts, ff)
            rigid_like = sampled_plant(plant_vector(M * cand.mass_scale, B, delay=cand.delay_samples * Ts),
                                       Ts).frequency_response(ff)
            if np.max(np.abs(np.log(np.abs(Hm / rigid_like)))) <= math.log(BAND_GAIN_TOL):
                note = "the best mode changes the response by less than the band tolerance: reported as rigid"
            elif _on_edge(cand.mode_hz, cand.mode_damping, float(ff[0]), fs):  # type: ignore[arg-type]
                note = ("the best mode sits on the edge of what the data can show (damping or frequency at its "
                        "bound): reported as rigid; see the measured response")
            else:
                best, note = cand, None
                break
        while best.n_modes < MAX_MODES:  # from rigid too: departures say a mode is missing
            more = _one_more_mode(best, res, ff, Hf, cf, n_avg, M, B, Ts)
            if more is None:
                break
            best, note = more, None
            fits[f"{best.n_modes}_modes"] = best
        if best.n_modes > max_modes:
            found = best.n_modes
            best = fits["rigid"] if max_modes <= 0 else _keep_modes(best, max_modes, ff, M, B, Ts)
            note = (f"the data hold {found} modes; the model keeps the {max_modes} that change the response "
                    f"most (max_modes = {max_modes}): see the departures")
    H_model = best.response(M, B, Ts, f)
    deps = tuple(departures(ff, Hf, best.response(M, B, Ts, ff), cf, n_avg))
    pf = plant_fit(best, ff, Hf, cf, n_avg, M, B, Ts)
    if best.n_modes >= 2 and pf is None:
        note = ("the two modes are both seen without an anti-resonance: no plant of the simulator (one encoder, "
                "two appendages on the motor) shows that; the simulator holds the first only")
    elif best.n_modes > 2:
        note = f"{best.n_modes} modes found; the simulator holds the first two"
    return FrequencyResponse(fit=best, fits=fits, H_model=H_model, note=note, departures=deps, plant=pf, **common)


# --------------------------------------------------------------------------- encoder noise


@dataclass(frozen=True)
class EncoderNoise:
    """Encoder noise read from the part of the response the command does not explain.

    Attributes
    ----------
    total_rms : float
        RMS of the measurement error (noise and quantization together), m.
    quantization_rms : float or None
        ``step / sqrt(12)``, the rounding's share, m (None: the log is not on a grid).
    noise_std : float
        The noise beyond quantization, ``sqrt(max(total^2 - quantization^2, 0))``, m.
    band_hz : (float, float)
        Band the floor was read in, Hz.
    """

    total_rms: float
    quantization_rms: float | None
    noise_std: float
    band_hz: tuple[float, float]

    def to_dict(self) -> dict[str, Any]:
        return {"noise_std": self.noise_std, "noise_rms_total": self.total_rms,
                "quantization_noise_rms": self.quantization_rms, "noise_band_hz": list(self.band_hz)}


#: Band of the noise floor, as fractions of the sample rate (near Nyquist: the motion's share is least there).
NOISE_BAND = (0.35, 0.48)


def encoder_noise(q: np.ndarray, u: np.ndarray, fs: float, response: Any, quantization: float | None,
                  exclude: list[tuple[int, int]] = ()) -> EncoderNoise | None:  # type: ignore[assignment]
    """Estimate the encoder's measurement error from the log.

    The reading is ``q = x + n`` with ``x = P u`` the motion the command causes (closed loop
    or not: ``u`` is measured) and ``n`` the measurement error.  Its spectrum is therefore
    ``S_nn = S_qq - 2 Re(conj(P) S_uq) + |P|^2 S_uu`` (Welch, Hann windows, linear detrend),
    with ``P`` the identified model (``response(f)``: the fitted modes and delay where the
    log has a broadband segment, else the rigid body).  Measurement error is white; the
    floor is the median of ``S_nn`` over ``NOISE_BAND`` of the sample rate, well above the
    loop's bandwidth and the reference's content, where a model error weighs least and the
    median ignores a residual peak.  ``total^2 = floor * fs / 2`` (one-sided density).
    Quantization with a step ``d`` is uniform rounding error of variance ``d^2 / 12`` when
    the motion or the noise moves the reading across steps, so the noise beyond it is
    ``sqrt(total^2 - d^2 / 12)`` (0 when the floor is the rounding's alone).  That
    difference is only as good as the rounding model: where the noise is well below the
    rounding's share (``noise_std < d / sqrt(12) / 2`` or so) the reading seldom crosses a step
    at random and ``noise_std`` is poorly determined (docs/interface.md); ``total_rms`` stays
    a fair figure of the whole measurement error.  The band sits close to Nyquist so that a
    slow drive (1 kHz) still has its floor there.

    Parameters
    ----------
    q, u : ndarray
        Position (m) and command (u-unit).
    fs : float
        Sample rate, Hz.
    response : callable
        ``f (Hz) -> P(f)``, m per u-unit.
    quantization : float or None
        Encoder step, m.
    exclude : list of (int, int)
        Sample ranges left out (broadband segments: there the injected motion is large and a
        model error weighs most), when enough of the log is left.

    Returns
    -------
    EncoderNoise or None
        None when the log is too short for the estimate.
    """
    n = q.size
    nperseg = int(min(max(64, round(fs / WHOLE_LOG_RESOLUTION_HZ)), max(n // 8, 16)))
    keep: list[tuple[int, int]] = []
    i = 0
    for a, b in sorted(exclude):
        if a - i >= nperseg:
            keep.append((i, a))
        i = max(i, b)
    if n - i >= nperseg:
        keep.append((i, n))
    if sum(b - a for a, b in keep) < 8 * nperseg:
        keep = [(0, n)]
    if n < 2 * nperseg:
        return None
    kw = dict(fs=fs, window="hann", nperseg=nperseg, noverlap=nperseg // 2, detrend="linear")
    Sqq = Suu = 0.0
    Suq: Any = 0.0
    f = None
    for a, b in keep:
        w = b - a
        f, squu = signal.welch(u[a:b], **kw)
        _, sqq = signal.welch(q[a:b], **kw)
        _, suq = signal.csd(u[a:b], q[a:b], **kw)
        Sqq, Suu, Suq = Sqq + w * sqq, Suu + w * squu, Suq + w * suq
    tot = sum(b - a for a, b in keep)
    Sqq, Suu, Suq = np.asarray(Sqq) / tot, np.asarray(Suu) / tot, np.asarray(Suq) / tot
    band = (f >= NOISE_BAND[0] * fs) & (f <= NOISE_BAND[1] * fs)  # type: ignore[operator]
    if np.count_nonzero(band) < 4:
        return None
    P = response(f[band])  # type: ignore[index]
    Snn = Sqq[band] - 2.0 * np.real(np.conj(P) * Suq[band]) + np.abs(P) ** 2 * Suu[band]
    total = float(math.sqrt(max(float(np.median(Snn)), 0.0) * fs / 2.0))
    qr = None if quantization is None else float(quantization) / math.sqrt(12.0)
    noise = total if qr is None else math.sqrt(max(total**2 - qr**2, 0.0))
    return EncoderNoise(total_rms=total, quantization_rms=qr, noise_std=noise,
                        band_hz=(float(f[band][0]), float(f[band][-1])))  # type: ignore[index]
