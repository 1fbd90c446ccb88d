"""What the frequency-response step returns: :class:`FrequencyResponse`, and how it is written to ident.json."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from commission.controllers.linear import rigid_frequency_response
from commission.identify.frf.settings import BAND_COHERENCE, MEASURED_POINTS
from commission.identify.frf.estimate import _weighted_rms, backed_band
from commission.identify.frf.model import ExtraMode, StructureFit
from commission.identify.frf.modes import PlantFit
from commission.identify.frf.structfit import Departure


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
        bins, from the lowest that agrees, until two consecutive coherent bins disagree; a run
        of one agreeing bin is not a band),
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
