"""Fitting one structure to the measured response, and where a fit departs from it.

:func:`fit_structure` fits a candidate plant by weighted least squares on the log-magnitude
and phase (multi-start: a screening stage from every start, the best kept to the end);
:func:`departures` names the runs of bins where the measured response leaves the fit beyond
the estimate's uncertainty.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from commission.identify.frf.settings import (BAND_COHERENCE, BAND_GAIN_TOL, BAND_PHASE_TOL_DEG, COHERENCE_CAP,
                                              DEPARTURE_ALPHA, MAX_DAMPING, MAX_DELAY_SAMPLES, MIN_DAMPING,
                                              MODE_MAX_NYQUIST, SCREEN_KEEP, SCREEN_NFEV)
from commission.identify.frf.model import StructureFit, _layout, _model_response, _unpack


def _weights(coh: np.ndarray, n_avg: int) -> np.ndarray:
    """Inverse standard deviation of ln H (each of its real and imaginary parts) per bin, from the coherence."""
    g2 = np.minimum(coh, COHERENCE_CAP)
    return np.sqrt(2.0 * n_avg * g2 / (1.0 - g2))


def mode_hz_max(fs: float) -> float:
    """Highest mode frequency the fits may place, Hz, at the sample rate ``fs`` (Hz): ``MODE_MAX_NYQUIST`` Nyquists."""
    return MODE_MAX_NYQUIST * 0.5 * fs


def mirrors_in_reach(freqs: list[float], fs: float) -> list[float]:
    """The mirrors ``fs - f`` (Hz) of ``freqs`` (Hz) that lie above Nyquist and within :func:`mode_hz_max`, in order.

    A resonance seen below Nyquist may be the alias of a mode at its mirror (settings.MODE_MAX_NYQUIST).
    """
    return [fs - f for f in freqs if 0.5 * fs < fs - f < mode_hz_max(fs)]


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
            lo += [math.log(fmin), math.log(MIN_DAMPING)]
            hi += [math.log(mode_hz_max(1.0 / Ts)), math.log(MAX_DAMPING)]
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
