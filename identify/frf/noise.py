"""Encoder noise read from the part of the measured position the command does not explain (step 6)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import signal

from commission.identify.frf.settings import WHOLE_LOG_RESOLUTION_HZ


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
