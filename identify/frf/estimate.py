"""The measured response: broadband segments, the H1 estimate with coherence, the band the data back.

Steps 1-3 of the method (:mod:`commission.identify.frf`): where the command carries a broadband
injection (:func:`broadband_segments`), the Welch estimate ``H1 = P_uq / P_uu`` over those
ranges (:func:`estimate`), and the band in which the measured response agrees with the rigid
model (:func:`backed_band`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import signal

from commission.identify.frf.settings import (BAND_COHERENCE, BAND_GAIN_TOL, BAND_PHASE_TOL_DEG, BLOCK_S,
                                              BROADBAND_FACTOR, BROADBAND_FACTOR_LONG, BROADBAND_FRACTION,
                                              BROADBAND_LONG_BLOCK, FIT_COHERENCE, MEASURABLE_SNR,
                                              MIN_SEGMENT_S)


def _weighted_rms(H: np.ndarray, Hm: np.ndarray | None, coh: np.ndarray) -> float | None:
    if Hm is None:
        return None
    w = np.where(coh >= FIT_COHERENCE, coh, 0.0)
    if not np.any(w > 0):
        return None
    e = np.abs(np.log(H / Hm))
    return float(np.sqrt(np.sum(w * e**2) / np.sum(w)))


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
    factor = BROADBAND_FACTOR_LONG if nb >= BROADBAND_LONG_BLOCK else BROADBAND_FACTOR
    flag = (rms >= factor * background) & (rms**2 >= BROADBAND_FRACTION * np.maximum(var, 1e-300))
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


def estimate(q: np.ndarray, u: np.ndarray, fs: float, ranges: list[tuple[int, int]],
             nperseg: int, noise_floor: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Welch H1 estimate of u -> q averaged over the sample ranges.

    With ``noise_floor`` (one-sided PSD of the encoder's white measurement error, m^2/Hz), a bin
    whose position PSD stays below :data:`MEASURABLE_SNR` times it gets coherence 0: the
    reading there is the noise and the command the loop's answer to it, coherent with each
    other through the controller and not through the plant (settings), so the bin measures
    nothing of the plant and no step after this one (band, fit, measured margins) may use it.

    Returns
    -------
    f : ndarray
        Hz, without DC and Nyquist.
    H : ndarray, complex
        m per u-unit.
    coherence : ndarray
        Magnitude-squared coherence, 0 where the position is at the noise floor (above).
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
    if noise_floor is not None and noise_floor > 0:
        coh = np.where(Pqq / n_avg >= MEASURABLE_SNR * noise_floor, coh, 0.0)  # Pqq sums n_avg windows
    H = np.where(np.isfinite(H), H, 0.0)
    return f[keep], H, coh, n_avg


def backed_band(f: np.ndarray, R: np.ndarray, coh: np.ndarray) -> tuple[float, float] | None:
    """Band in which the coherent data agree with the rigid model (module docstring, step 3), Hz.

    The run of coherent bins from the lowest that agrees until two consecutive coherent bins
    disagree; a run that holds only one agreeing bin is not a band, and the next run is taken.
    (A departure at low frequency -- the response of friction to an injection on a slow
    cruise -- swings its phase through the tolerance, and one bin on its way agreed by chance:
    that bin started the run, the departure's next bins ended it, and the band of the whole
    log was that one bin.)  When every run holds one agreeing bin, the lowest.
    """
    coherent = np.flatnonzero(coh >= BAND_COHERENCE)
    if coherent.size == 0:
        return None
    ok = ((np.abs(np.log(np.abs(R) + 1e-300)) <= math.log(BAND_GAIN_TOL))
          & (np.abs(np.degrees(np.angle(R))) <= BAND_PHASE_TOL_DEG))
    runs: list[tuple[int, int, int]] = []  # (first, last, agreeing bins) of each run
    run: list[int] | None = None
    misses = 0
    for i in coherent:
        if run is None:
            if ok[i]:
                run, misses = [i, i, 1], 0
            continue
        if ok[i]:
            run[1], run[2], misses = i, run[2] + 1, 0
        else:
            misses += 1
            if misses >= 2:
                runs.append((run[0], run[1], run[2]))
                run = None
    if run is not None:
        runs.append((run[0], run[1], run[2]))
    if not runs:
        return None
    low, high, _ = next((r for r in runs if r[2] >= 2), runs[0])
    return round(float(f[low]), 6), round(float(f[high]), 6)  # Hz; drops the round-off of 1 / median(dt)
