"""The regressor of a term set: the kinematics shifted by the delay, and the columns of each term."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import interpolate

from commission.identify.ls import ripple_name
from commission.identify.signals import Preprocessed
from commission.identify.richer.settings import STRIBECK_XI, TERM_COEFFICIENTS, TERM_NONLINEAR


def _shifted(pp: Preprocessed, tau_samples: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Filtered ``q, qd, qdd`` evaluated ``tau_samples`` later (cubic interpolation, per segment, clamped)."""
    if tau_samples == 0.0:
        return pp.q, pp.qd, pp.qdd
    outs = [np.empty_like(pp.q) for _ in range(3)]
    for s in pp.segments():
        n = s.stop - s.start
        k = np.arange(n, dtype=np.float64)
        x = np.clip(k + tau_samples, 0.0, n - 1.0)
        for src, dst in zip((pp.q, pp.qd, pp.qdd), outs):
            dst[s] = interpolate.CubicSpline(k, src[s])(x)
    return outs[0], outs[1], outs[2]


class _Design:
    """Decimated columns of every term at one shift (cached per delay and Stribeck velocity)."""

    def __init__(self, pp: Preprocessed, pitches: tuple[float, ...], q_center: float, q_scale: float,
                 keep: np.ndarray | None = None):
        self.pp, self.pitches, self.qc, self.qs = pp, pitches, q_center, q_scale
        self.y = pp.decimate(pp.u)
        self.keep = np.ones(self.y.size, bool) if keep is None else keep
        self._cache: dict[float, dict[str, np.ndarray]] = {}
        self._stribeck: dict[tuple[float, float], np.ndarray] = {}

    def columns(self, d: float) -> dict[str, np.ndarray]:
        key = round(float(d), 9)
        if key not in self._cache:
            q, qd, qdd = _shifted(self.pp, 0.5 + d if d is not None else 0.0)
            z = (q - self.qc) / self.qs
            cols = [qdd, qd, np.sign(qd), np.ones_like(qd), np.abs(qd), z, z * z, qd * np.abs(qd)]
            for p in self.pitches:
                ph = 2.0 * np.pi * q / p
                cols += [np.sin(ph), np.cos(ph)]
            D = self.pp.decimate(np.column_stack(cols))
            out = {"base": D[:, :4], "viscous_asym": D[:, 4:5], "position": D[:, 5:7], "drag": D[:, 7:8],
                   "ripple": D[:, 8:], "_qd": qd}
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = out
        return self._cache[key]

    def stribeck(self, d: float, vs: float) -> np.ndarray:
        key = (round(float(d), 9), float(vs))
        if key not in self._stribeck:
            qd = self.columns(d)["_qd"]
            if len(self._stribeck) > 256:
                self._stribeck.clear()
            self._stribeck[key] = self.pp.decimate(np.exp(-(np.abs(qd) / vs) ** STRIBECK_XI) * np.sign(qd))[:, None]
        return self._stribeck[key]

    def matrix(self, terms: Sequence[str], d: float, vs: float | None) -> np.ndarray:
        """The regressor on all decimated rows."""
        c = self.columns(d)
        blocks = [c["base"]]
        for t in ("viscous_asym", "stribeck", "position", "drag"):
            if t in terms:
                blocks.append(self.stribeck(d, vs) if t == "stribeck" else c[t])  # type: ignore[arg-type]
        blocks.append(c["ripple"])
        return np.hstack(blocks)


def _names_units(terms: Sequence[str], pitches: tuple[float, ...]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    pairs = list(TERM_COEFFICIENTS["base"])
    for t in ("viscous_asym", "stribeck", "position", "drag"):
        if t in terms:
            pairs += list(TERM_COEFFICIENTS[t])
    for k in range(len(pitches)):
        pairs += [(ripple_name("ripple_sin", k), "u"), (ripple_name("ripple_cos", k), "u")]
    return tuple(n for n, _ in pairs), tuple(u for _, u in pairs)


def _rss(A: np.ndarray, y: np.ndarray) -> float:
    theta, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ theta
    return float(r @ r)


def n_parameters(terms: Sequence[str]) -> int:
    """Parameters a term set adds to the base model (linear coefficients and profiled nonlinear ones)."""
    return sum(len(TERM_COEFFICIENTS.get(t, ())) + (1 if t in TERM_NONLINEAR else 0) for t in terms)
