"""Finding the force-ripple pitch in a log (``identify --ripple-pitch auto``).

A linear motor's force ripple (cogging, the magnets' pitch) and a rotary motor's cogging
torque repeat with position: ``ripple(q) = A sin(2 pi q / P + phi)``.  The fit models it
when told the pitch ``P`` (:func:`commission.identify.ls.regressor`); without it, the
ripple stays in the residual, and on the friction ladder's slow legs, where the loop
holds the axis against it for a whole pitch or more, it is as large as the Stribeck rise
the slow legs are there to show.  The fit then cannot resolve the rise and keeps Coulomb
friction only (docs/robustness.md, "Friction the log did not resolve").

The pitch is found where it shows best: on the constant-velocity legs.  On leg ``j``
(speed constant) the command is a constant (friction at that speed, viscous force,
offset) plus the ripple plus the loop's noise, so the model

    u_i = c_j(i) + a sin(2 pi q_i / P) + b cos(2 pi q_i / P) + noise

is linear in the leg constants ``c_j`` and in ``(a, b)``.  For every candidate ``P`` the
leg constants are projected out exactly (the sine, the cosine and ``u`` are centred on
each leg: Frisch-Waugh), and the two-column least squares gives the share of the
command's variance that the ripple of that pitch explains, a periodogram over position
(Lomb-Scargle with a floating mean per leg; scipy's ``lombscargle`` has one mean for all,
which lets the friction levels of the legs leak into every pitch longer than a leg).

Candidates are evenly spaced in the spatial frequency ``1/P``, four per cycle of the
span the legs visit (a peak is never missed between two of them), from ``2 / span`` to
:data:`LEAST_PITCH_STEPS` encoder steps; the peak is refined on a grid ten times finer.
It is kept when it stands above the periodogram's median by :data:`PEAK_OVER_MEDIAN`:
under white noise a bin's power is ``sigma^2 chi2_2 / 2`` and exceeds that ratio with
probability ``exp(-ratio ln 2) < 1e-8``, so even over tens of thousands of candidates a
noise peak is not taken for a pitch; the loop's coloured noise only raises the median.
The caller confirms the pitch with the full fit (its ripple amplitude against its
standard deviation) before using it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

#: Least pitch searched, in encoder steps (finer ripple is below what the encoder resolves) ...
LEAST_PITCH_STEPS = 50.0
#: ... and as a fraction of the span the legs visit (the search's cost grows as its square).
LEAST_PITCH_SPAN = 500.0
#: Least share of the legs' command variation a pitch must explain to be worth modelling.
LEAST_EXPLAINED = 0.05
#: Least ratio of the peak's power to the periodogram's median for a pitch to be reported.
PEAK_OVER_MEDIAN = 30.0
#: Candidates per cycle of the legs' span (coarse grid) and the refinement factor.
CANDIDATES_PER_CYCLE = 4.0
REFINE = 10
#: Candidates between two exact evaluations of the sines on the coarse grid (the rest rotate).
RESYNC = 32


@dataclass(frozen=True)
class RipplePitch:
    """The result of :func:`ripple_periodogram`.

    Attributes
    ----------
    pitch : float or None
        The pitch found, q-unit (m or rad); None when no peak stands out.
    amplitude : float
        The ripple's amplitude at the peak, u-unit (least squares on the legs).
    peak_over_median : float
        The peak's power over the periodogram's median, -.
    explained : float
        Share of the legs' command variance (about each leg's mean) the peak explains, -.
    span : float
        Extent of position the legs visit, q-unit.
    searched : tuple of float
        The pitch range searched, q-unit (least, largest).
    n_legs, n_samples : int
        Legs and command samples used.
    """

    pitch: float | None
    amplitude: float
    peak_over_median: float
    explained: float
    span: float
    searched: tuple[float, float]
    n_legs: int
    n_samples: int

    def record(self) -> dict[str, object]:
        """ident.json's ``model.ripple_search`` (q-unit, u-unit; the search's range and what it found)."""
        return {"pitch": self.pitch, "amplitude": self.amplitude, "peak_over_median": self.peak_over_median,
                "explained": self.explained, "span": self.span,
                "searched": [x if math.isfinite(x) else None for x in self.searched],
                "legs": self.n_legs, "samples": self.n_samples, "peak_needed": PEAK_OVER_MEDIAN,
                "explained_needed": LEAST_EXPLAINED}

    def describe(self, q_unit: str = "m") -> str:
        """One sentence for the identification's notes."""
        rng = f"{self.searched[0]:.3g}-{self.searched[1]:.3g} {q_unit}"
        if self.pitch is None:
            if not self.n_legs:
                return "ripple pitch auto: the log holds no constant-velocity legs to find a ripple pitch on"
            return (f"ripple pitch auto: no pitch stands out on {self.n_legs} constant-velocity legs (searched "
                    f"{rng}; the best peak is {self.peak_over_median:.1f} x the periodogram's median and explains "
                    f"{100 * self.explained:.0f} % of the legs' command variation, {PEAK_OVER_MEDIAN:g} x and "
                    f"{100 * LEAST_EXPLAINED:g} % needed); no ripple fitted")
        return (f"ripple pitch auto: {self.pitch:.5g} {q_unit} found on {self.n_legs} constant-velocity legs "
                f"(amplitude {self.amplitude:.3g}, {100 * self.explained:.0f} % of the legs' command variation, "
                f"{self.peak_over_median:.0f} x the periodogram's median; searched {rng})")


def _binned(legs: list[tuple[np.ndarray, np.ndarray]], width: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each leg's samples averaged over position bins of ``width``: (q, u, weight, leg index) per bin.

    A bin of an eighth of the least pitch averages a sinusoid of that pitch to
    ``sinc(1/8) = 0.97`` of its amplitude; the search's cost then scales with the
    legs' extent, not with their samples.
    """
    qs, us, ws, ids = [], [], [], []
    for j, (q, u) in enumerate(legs):
        b = np.floor(q / width).astype(np.int64)
        _, inv, n = np.unique(b, return_inverse=True, return_counts=True)
        qs.append(np.bincount(inv, q) / n)
        us.append(np.bincount(inv, u) / n)
        ws.append(n.astype(float))
        ids.append(np.full(n.size, j))
    return np.concatenate(qs), np.concatenate(us), np.concatenate(ws), np.concatenate(ids)


@njit(cache=True, nogil=True)
def _powers(k: np.ndarray, q: np.ndarray, y: np.ndarray, w: np.ndarray, leg: np.ndarray,
            wsum: np.ndarray, resync: int) -> tuple[np.ndarray, np.ndarray]:
    """Explained (weighted) sum of squares and amplitude of a sinusoid of spatial frequency ``k``
    (1/q-unit, evenly spaced), each leg's weighted mean projected out of the sinusoid (``y`` is
    centred already).

    One compiled pass per candidate instead of ``k.size x q.size`` arrays: the sine and cosine
    of each bin are carried from one candidate to the next by the rotation of the grid's step
    (four multiplications instead of two transcendental functions), and taken afresh from
    ``k`` every ``resync`` candidates (1: every one), which keeps the carried phase within a
    few rounding errors of the exact one.  The leg means are removed in a second pass over the
    bins (two passes, not the one-pass identity ``sum w (s - m)^2 = sum w s^2 - W m^2``,
    which cancels on legs shorter than a cycle).
    """
    nk, n, nl = k.size, q.size, wsum.size
    power = np.empty(nk)
    amp = np.empty(nk)
    s = np.empty(n)
    c = np.empty(n)
    rs = np.empty(n)
    rc = np.empty(n)
    ms = np.empty(nl)
    mc = np.empty(nl)
    dk = (k[-1] - k[0]) / (nk - 1) if nk > 1 else 0.0
    for i in range(n):
        rs[i] = math.sin(2.0 * math.pi * dk * q[i])
        rc[i] = math.cos(2.0 * math.pi * dk * q[i])
    for a in range(nk):
        if a % resync == 0:
            for i in range(n):
                arg = 2.0 * math.pi * k[a] * q[i]
                s[i] = math.sin(arg)
                c[i] = math.cos(arg)
        else:
            for i in range(n):
                si = s[i] * rc[i] + c[i] * rs[i]
                c[i] = c[i] * rc[i] - s[i] * rs[i]
                s[i] = si
        ms[:] = 0.0
        mc[:] = 0.0
        for i in range(n):
            ms[leg[i]] += s[i] * w[i]
            mc[leg[i]] += c[i] * w[i]
        for j in range(nl):
            ms[j] /= wsum[j]
            mc[j] /= wsum[j]
        ss = cc = sc = sy = cy = 0.0
        for i in range(n):
            si = s[i] - ms[leg[i]]
            ci = c[i] - mc[leg[i]]
            wi = w[i]
            ss += si * si * wi
            cc += ci * ci * wi
            sc += si * ci * wi
            sy += si * wi * y[i]
            cy += ci * wi * y[i]
        det = ss * cc - sc * sc
        if det > 1e-12 * max(ss * cc, 1e-300):
            ca = (cc * sy - sc * cy) / det
            cb = (ss * cy - sc * sy) / det
        else:
            ca = cb = 0.0
        power[a] = ca * sy + cb * cy
        amp[a] = math.hypot(ca, cb)
    return power, amp


def ripple_periodogram(legs: list[tuple[np.ndarray, np.ndarray]], *, step: float | None) -> RipplePitch:
    """Find the force-ripple pitch on constant-velocity legs (module docstring).

    Parameters
    ----------
    legs : list of (q, u)
        Each leg's positions (q-unit) and commands (u-unit), one constant speed each.
    step : float or None
        The encoder's step, q-unit (None: unknown).

    Returns
    -------
    RipplePitch
    """
    legs = [(np.asarray(q, float), np.asarray(u, float)) for q, u in legs if len(q) >= 8]
    n_all = sum(q.size for q, _ in legs)
    if not legs or n_all < 64:
        return RipplePitch(None, 0.0, 0.0, 0.0, 0.0, (math.nan, math.nan), len(legs), n_all)
    lo = min(float(q.min()) for q, _ in legs)
    span = max(float(q.max()) for q, _ in legs) - lo
    p_max = max(float(np.ptp(q)) for q, _ in legs)
    p_min = max(LEAST_PITCH_STEPS * step if step else 0.0, span / LEAST_PITCH_SPAN)
    if not (span > 0 and p_max > 2.0 * p_min):
        return RipplePitch(None, 0.0, 0.0, 0.0, span, (p_min, p_max), len(legs), n_all)
    q, u, w, leg = _binned([(q - lo, u) for q, u in legs], p_min / 8.0)
    wsum = np.bincount(leg, w)
    y = u - (np.bincount(leg, w * u) / wsum)[leg]
    # the share explained is of the samples' variation about their leg's mean (binning averages noise)
    total = float(sum(np.sum((uu - uu.mean()) ** 2) for _q, uu in legs))
    if not total > 0:
        return RipplePitch(None, 0.0, 0.0, 0.0, span, (p_min, p_max), len(legs), n_all)
    dk = 1.0 / (CANDIDATES_PER_CYCLE * span)
    k = np.arange(1.0 / p_max, 1.0 / p_min, dk)
    power, _amp = _powers(k, q, y, w, leg, wsum, RESYNC)
    median = float(np.median(power))
    i = int(np.argmax(power))
    fine = np.linspace(k[i] - dk, k[i] + dk, 2 * REFINE + 1)
    fine = fine[(fine >= 1.0 / p_max) & (fine <= 1.0 / p_min)]
    pf, af = _powers(fine, q, y, w, leg, wsum, 1)
    j = int(np.argmax(pf))
    ratio = float(pf[j] / median) if median > 0 else math.inf
    explained = float(pf[j] / total)
    found = ratio >= PEAK_OVER_MEDIAN and explained >= LEAST_EXPLAINED
    return RipplePitch(float(1.0 / fine[j]) if found else None, float(af[j]), ratio, explained, span,
                       (p_min, p_max), len(legs), n_all)


__all__ = ["RipplePitch", "ripple_periodogram", "PEAK_OVER_MEDIAN", "LEAST_PITCH_STEPS"]
