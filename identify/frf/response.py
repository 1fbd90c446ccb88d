"""The frequency-response step: :func:`frequency_response`, as named steps.

:func:`_ranges_and_resolution` chooses the samples and the window length, :func:`_measured`
estimates H and the backed band, :func:`_rigid_only_note` says why no structure is fitted, and
:func:`_fit_structures`, :func:`_best_structure` and :func:`_more_modes` choose the plant.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np
from threadpoolctl import threadpool_limits

from commission.controllers.linear import rigid_frequency_response, sampled_plant
from commission.controllers.plant import plant_vector
from commission.identify.frf.settings import (BAND_GAIN_TOL, FIT_COHERENCE, MAX_MODES, MIN_FIT_BINS, RESOLUTION_HZ,
                                              WHOLE_LOG_RESOLUTION_HZ)
from commission.identify.frf.estimate import backed_band, broadband_segments, estimate
from commission.identify.frf.model import StructureFit
from commission.identify.frf.noise import encoder_noise
from commission.identify.frf.modes import _keep_modes, _on_edge, _one_more_mode, _starts, plant_fit
from commission.identify.frf.result import FrequencyResponse
from commission.identify.frf.structfit import departures, fit_structure, mirrors_in_reach


def _ranges_and_resolution(u: np.ndarray, fs: float, ranges: list[tuple[int, int]] | None,
                           ) -> tuple[list[tuple[int, int]], list[tuple[int, int]], int, int, str]:
    """The sample ranges estimated on, and the window lengths (step 1 of the method).

    Returns
    -------
    (segs, ranges, nperseg, whole_nperseg, source)
        The broadband segments (empty: none), the ranges the estimate uses (the segments,
        else the whole log), the window length on them and on the whole log (samples), and
        ``"broadband"`` or ``"whole_log"``.
    """
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
    return segs, ranges, nperseg, whole_nperseg, source


def _noise_floor(q: np.ndarray, u: np.ndarray, fs: float, M: float, B: float,
                 segments: list[tuple[int, int]]) -> float | None:
    """One-sided PSD of the encoder's white measurement error, m^2/Hz (None: the log is too short).

    :func:`~commission.identify.frf.noise.encoder_noise` with the rigid body taking out the
    command's effect (the modes are not known yet; near Nyquist, where the floor is read, the
    rigid body's motion is far below it anyway): ``total_rms^2 / (fs / 2)``.
    """
    Ts = 1.0 / fs
    noise = encoder_noise(q, u, fs, lambda f: rigid_frequency_response(M, B, Ts, f), None, segments)
    return None if noise is None else noise.total_rms ** 2 * 2.0 / fs


def _measured(q: np.ndarray, u: np.ndarray, fs: float, M: float, B: float, ranges: list[tuple[int, int]],
              nperseg: int, whole_nperseg: int, source: str) -> tuple[Any, ...]:
    """The estimate, the rigid model's response, their ratio and the backed band (steps 2-3).

    Returns ``(f, H, coh, n_avg, H_rigid, R, band)``.  On broadband segments the rest of the
    log (ladder, multisine) backs the model below the segments' first bins: the band is
    extended down where the whole log's band reaches into it.
    """
    Ts = 1.0 / fs
    floor = _noise_floor(q, u, fs, M, B, ranges if source == "broadband" else [])
    f, H, coh, n_avg = estimate(q, u, fs, ranges, nperseg, floor)
    H_rigid = rigid_frequency_response(M, B, Ts, f)
    with np.errstate(divide="ignore", invalid="ignore"):
        R = np.where(np.abs(H) > 0, H / H_rigid, 1e-300)
    band = backed_band(f, R, coh)
    if source == "broadband" and band is not None:
        fw, Hw, cw, _ = estimate(q, u, fs, [(0, u.size)], whole_nperseg, floor)
        with np.errstate(divide="ignore", invalid="ignore"):
            Rw = np.where(np.abs(Hw) > 0, Hw / rigid_frequency_response(M, B, Ts, fw), 1e-300)
        wb = backed_band(fw, Rw, cw)
        if wb is not None and wb[0] < band[0] <= wb[1]:
            band = (wb[0], band[1])
    return f, H, coh, n_avg, H_rigid, R, band


def _rigid_only_note(source: str, fit_bins: np.ndarray, band: tuple[float, float] | None) -> str | None:
    """Why modes and delay are not measured (a log without broadband content, or too few coherent
    bins), with the band the rigid model is backed in; None when the structures can be fitted."""
    if not (source == "whole_log" or np.count_nonzero(fit_bins) < MIN_FIT_BINS):
        return None
    band_text = (f"the rigid model is backed by the data from {band[0]:.3g} to {band[1]:.3g} Hz"
                 if band is not None else "no band of coherent data agrees with the rigid model")
    why = ("no broadband content in the log (no segment where the command carries a broadband "
           "injection)" if source == "whole_log" else
           f"the broadband segments give only {int(np.count_nonzero(fit_bins))} coherent bins")
    note = f"{why}: modes and input delay are not measured; {band_text}"
    if band is not None:
        note += f", and nothing is known about the plant above {band[1]:.3g} Hz"
    return note


def _fit_structures(ff: np.ndarray, Hf: np.ndarray, cf: np.ndarray, n_avg: int, M: float, B: float, Ts: float,
                    starts: tuple[float, list[float], list[tuple[float, float]]],
                    max_modes: int) -> dict[str, StructureFit]:
    """The rigid plant, and with ``max_modes >= 1`` a load-side and a motor-side mode, each from its starts.

    Then each mode structure is fitted again from the mirror ``fs - f`` of every resonance
    candidate and of both fitted modes, where that is within the fit's reach
    (:func:`~commission.identify.frf.structfit.mirrors_in_reach`), and that fit replaces the
    first where its cost is lower: a peak below Nyquist may be the alias of a mode above it,
    seen on the other side of the encoder (settings), and a local fit started on the alias
    cannot cross Nyquist to find it.  Where no candidate lies above half of
    Nyquist there is no mirror to try and the fits are the data starts' alone.
    """
    delay0, res, pairs = starts
    lM = 0.0
    fits: dict[str, StructureFit] = {}
    fits["rigid"] = fit_structure("rigid", ff, Hf, cf, n_avg, M, B, Ts,
                                  [np.array([lM, delay0]), np.array([lM, 0.0])])
    d0 = fits["rigid"].delay_samples
    if max_modes < 1:
        return fits
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
        fits["motor_side_mode"] = fit_structure("motor_side_mode", ff, Hf, cf, n_avg, M, B, Ts, motor_starts)
    seen = [*res, *(f.mode_hz for k, f in fits.items() if k != "rigid")]
    mirrors = sorted({round(fm, 6) for fm in mirrors_in_reach(seen, 1.0 / Ts)})
    if not mirrors:
        return fits
    for structure, tail in (("load_side_mode", ()), ("motor_side_mode", (0.3,))):
        again = [np.array([lM, d0, math.log(fr), math.log(z), *tail]) for fr in mirrors for z in (0.03, 0.15)]
        fit = fit_structure(structure, ff, Hf, cf, n_avg, M, B, Ts, again)
        if structure not in fits or fit.cost < fits[structure].cost:
            fits[structure] = fit
    return fits


def _best_structure(fits: Mapping[str, StructureFit], ff: np.ndarray, M: float, B: float, Ts: float,
                    fs: float) -> tuple[StructureFit, str | None]:
    """The best structure by the criterion whose mode passes the checks (rigid always does), and a note.

    A compromise of one mode over two (damping on its bound) gives way to the next.
    """
    best, note = fits["rigid"], None
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
    return best, note


def _more_modes(best: StructureFit, note: str | None, fits: dict[str, StructureFit], res: list[float],
                ff: np.ndarray, Hf: np.ndarray, cf: np.ndarray, n_avg: int, M: float, B: float, Ts: float,
                max_modes: int) -> tuple[StructureFit, str | None]:
    """One more mode while the response departs from the fit (up to ``MAX_MODES``; each added to ``fits``),
    then only the ``max_modes`` that change the response most."""
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
    return best, note


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
    segs, ranges, nperseg, whole_nperseg, source = _ranges_and_resolution(u, fs, ranges)
    f, H, coh, n_avg, H_rigid, R, band = _measured(q, u, fs, M, B, ranges, nperseg, whole_nperseg, source)
    seg_times = tuple((float(t[a]), float(t[b - 1])) for a, b in segs) if source == "broadband" else ()
    common = dict(f=f, H=H, coherence=coh, n_averages=n_avg, source=source, segments=seg_times,
                  H_rigid=H_rigid, M=float(M), B=B, band_hz=band, sample_rate=fs)
    fit_bins = (coh >= FIT_COHERENCE) & (np.abs(H) > 0)
    note = _rigid_only_note(source, fit_bins, band)
    if note is not None:
        return FrequencyResponse(fit=None, note=note, **common)
    ff, Hf, cf = f[fit_bins], H[fit_bins], coh[fit_bins]
    starts = _starts(ff, R[fit_bins], cf, fs)
    with threadpool_limits(1):
        fits = _fit_structures(ff, Hf, cf, n_avg, M, B, Ts, starts, max_modes)
        best, note = _best_structure(fits, ff, M, B, Ts, fs)
        best, note = _more_modes(best, note, fits, starts[1], ff, Hf, cf, n_avg, M, B, Ts, max_modes)
    H_model = best.response(M, B, Ts, f)
    deps = tuple(departures(ff, Hf, best.response(M, B, Ts, ff), cf, n_avg))
    pf = plant_fit(best, ff, Hf, cf, n_avg, M, B, Ts)
    if best.n_modes >= 2 and pf is None:
        note = ("the two modes are both seen without an anti-resonance: no plant of the simulator (one encoder, "
                "two appendages on the motor) shows that; the simulator holds the first only")
    elif best.n_modes > 2:
        note = f"{best.n_modes} modes found; the simulator holds the first two"
    return FrequencyResponse(fit=best, fits=fits, H_model=H_model, note=note, departures=deps, plant=pf, **common)
