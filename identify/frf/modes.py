"""More modes, fewer modes, and the two-mode plant the simulator holds (step 5 of the method).

Data-driven starts (:func:`_starts`), one more mode tried while the response departs from the
fit (:func:`_one_more_mode`), the modes that change the response most kept under
``max_modes`` (:func:`_keep_modes`), and two modes refitted as the simulator's plant
(:func:`plant_fit`).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import signal
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from commission.controllers.linear import continuous_model
from commission.controllers.plant import plant_vector
from commission.identify.frf.settings import (BAND_COHERENCE, BAND_GAIN_TOL, FIT_COHERENCE, MAX_DAMPING,
                                              MAX_DELAY_SAMPLES, MIN_DAMPING)
from commission.identify.frf.model import ExtraMode, StructureFit, _sampled_response
from commission.identify.frf.structfit import (_parameter_std, _weights, departures, fit_structure, mirrors_in_reach,
                                               mode_hz_max)


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
    """The mode's frequency or damping sits on the fit's bounds, or on Nyquist (the data do not place it).

    At Nyquist a mode and its alias are one: the sampled response cannot say on which side it is.
    """
    return (damping >= 0.99 * MAX_DAMPING or damping <= 1.01 * MIN_DAMPING or hz <= 1.01 * fmin
            or abs(hz - 0.5 * fs) <= 0.01 * 0.5 * fs or hz >= 0.99 * mode_hz_max(fs))


def _one_more_mode(current: StructureFit, peaks: list[float], ff: np.ndarray, Hf: np.ndarray, cf: np.ndarray,
                   n_avg: int, M: float, B: float, Ts: float) -> StructureFit | None:
    """The fit with one mode more than ``current``; None when the data do not support it.

    Starts come from the data: ``current`` plus a mode where the measured response
    departs from it (:func:`departures`) or at that departure's mirror above Nyquist, and
    afresh every choice of ``k + 1`` frequencies among the peaks of ``|H / H_rigid|`` (``peaks``), the departures and ``current``'s modes,
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
    dep_mirrors = mirrors_in_reach(dep_f, 1.0 / Ts)  # a departure high below Nyquist may be a mode above it
    k = current.n_modes + 1
    x0 = _pack(current)
    kinds = tuple(m.kind for m in current.extra)
    cands = []
    for kind in ("load", "motor") if current.structure != "rigid" else ():  # from rigid: the fresh starts below
        starts = [np.concatenate([x0, [math.log(fd), math.log(z)] + ([0.3] if kind == "motor" else [])])
                  for fd in dep_f + dep_mirrors for z in (0.03, 0.15)]
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

    What :func:`plant_fit` returns: the physical reading of a two-mode :class:`StructureFit`
    (masses and springs the simulator can run), kept beside the modal fit it came from
    because the two answer different questions (what the response shows, what plant
    produces it).

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
        Total mass of the fitted plant over the rigid fit's M, - (as :attr:`StructureFit.mass_scale`).
    cost : float
        Sum of squared normalised residuals, - (as :attr:`StructureFit.cost`).
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
    lo = [-1.0, 0.0, math.log(fmin), math.log(MIN_DAMPING), 0.02, math.log(fmin), math.log(MIN_DAMPING), 0.02]
    top = math.log(mode_hz_max(1.0 / Ts))
    hi = [1.0, MAX_DELAY_SAMPLES, top, math.log(MAX_DAMPING), 0.9, top,
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
