"""Delay-aware inverse dynamics with switchable interpretable terms, chosen by blocked cross-validation.

Model, in command units (u-unit, the contract's sign convention)::

    u(t) = F(t + tau),   tau = (0.5 + d) Ts
    F = M qdd + B qd + fc sign(qd) + offset                         (base: the IDIM-LS model)
        + dB |qd|                                                   (viscous_asym)
        + dfs exp(-(|qd| / vs)^2) sign(qd)                          (stribeck, xi = 2)
        + kq1 (q - q_c) + kq2 (q - q_c)^2                           (position)
        + cd qd |qd|                                                (drag)
        [+ ripple sin/cos(2 pi q / P) for every given pitch]        (always in when given)

Delay
-----
The command reaches the force ``d`` samples after the zero-order hold (the plant
vector's ``P_DELAY``, :mod:`commission.controllers.plant`): a held command acts on
average half a sample after it is logged, so the kinematics the command explains
are those ``tau = (0.5 + d) Ts`` later.  The regression keeps ``u`` as measured
and evaluates the regressor at ``t + tau`` (cubic interpolation of the filtered
position, velocity and acceleration, segment by segment), so the relative error
of every delay is measured against the same ``u``.  ``d`` is profiled: for a
term set, the residual sum of squares is minimised over ``d`` (grid, then a
bounded scalar search) on the rows away from reversals (whose anti-alias window
saw no speed below :data:`REVERSAL_FRACTION` of the fastest): at a reversal a
sticking axis and ``sign(qd)`` of the filtered velocity disagree, and on all rows
the delay absorbs part of that misfit (docs/inverse-dynamics.md).  ``vs`` and the
linear coefficients are then fitted on all rows.  The delay's standard deviation
comes from the curvature of the profile, ``var(d) = 2 sigma^2 / RSS''(d)`` (the
Gauss-Newton variance of the one nonlinear parameter).  ``d`` may be negative down to -0.5 sample (a log whose
command is stamped after it acts).

Asymmetry
---------
Coulomb asymmetry while moving, ``fc+ [v > 0] - fc- [v < 0]``, equals
``fc sign(v) + offset`` with ``fc = (fc+ + fc-)/2`` and ``offset = (fc+ - fc-)/2``:
the base model already holds it, and a constant force and a direction-dependent
Coulomb level cannot be told apart from a log that is never at rest (the two
columns differ only where ``v = 0``).  :func:`RichFit.derived` reports both
readings' levels ``fc_pos = fc + offset`` and ``fc_neg = fc - offset``.  Viscous
asymmetry needs its own column, ``|qd|``: ``B_pos = B + dB``, ``B_neg = B - dB``.

Selection (without the test set)
--------------------------------
Blocked K-fold cross-validation on the decimated rows of the identification
log(s): K contiguous blocks; each block in turn is predicted by the model fitted
on the other rows, leaving out ``gap`` rows on each side of the block (the
decimation filter and the position filter correlate neighbouring rows, so a
random split would let the training rows see the test rows).  The nonlinear
parameters (``d``, ``vs``) are chosen inside each fold on its training rows
only.  Among all term sets the simplest (fewest parameters; ties: lowest CV
error) whose CV mean squared error is within one standard error of the minimum
is chosen (the one-standard-error rule of Hastie, Tibshirani & Friedman,
section 7.10), with the standard error of each candidate's excess over the best
taken fold by fold (paired): the folds' own errors differ far more between
stretches of the log than two models' errors on one stretch, so the unpaired
standard error would hide every term.  A candidate also counts as equivalent to
the best when its excess is below :data:`MIN_RELATIVE_GAIN` of the best's error:
on long logs the paired rule alone keeps terms worth a few tenths of a percent
(docs/inverse-dynamics.md).  Why not BIC: the residuals of decimated inverse-dynamics rows are
correlated (unmodelled dynamics, filtered quantisation noise), so the row count
overstates the information and BIC's penalty is too weak; blocked CV measures
prediction on unseen stretches of the log directly.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import interpolate, ndimage, optimize

from commission.identify.errors import NotIdentifiableError
from commission.identify.ls import readonly_copy, ripple_name, ripple_pitches
from commission.identify.signals import DEFAULT_BANDWIDTH_HZ, Preprocessed, preprocess_segments, segment_rates

#: Switchable terms, in the order they are listed.
TERMS = ("delay", "viscous_asym", "stribeck", "position", "drag")
#: Coefficient names of every term's columns, with their units ("u" is the command unit).
TERM_COEFFICIENTS: dict[str, tuple[tuple[str, str], ...]] = {
    "base": (("M", "u s^2/m"), ("B", "u s/m"), ("fc", "u"), ("offset", "u")),
    "viscous_asym": (("dB", "u s/m"),),
    "stribeck": (("dfs", "u"),),
    "position": (("kq1", "u/m"), ("kq2", "u/m^2")),
    "drag": (("cd", "u s^2/m^2"),),
}
#: Nonlinear parameters of the terms (profiled), with their units.
TERM_NONLINEAR = {"delay": ("delay_samples", "samples"), "stribeck": ("vs", "m/s")}
#: Stribeck exponent of the ``stribeck`` term (Gaussian shape), fixed.
STRIBECK_XI = 2.0
#: Delay grid beyond the zero-order hold, samples.
DELAY_GRID = tuple(np.round(np.arange(-0.5, 3.0001, 0.25), 4))
#: The delay is profiled on the rows away from reversals: those whose anti-alias window saw no speed
#: below this fraction of the fastest (where sign(qd) of the filtered velocity and a sticking axis disagree).
REVERSAL_FRACTION = 0.01
#: Cross-validation folds and rows left out on each side of a test block.
N_FOLDS = 5
GAP_ROWS = 3
#: A term must lower the CV mean squared error by more than this fraction (of the best) to be
#: worth its parameter, however consistent its gain: on long logs a systematic misfit of a few
#: tenths of a percent (the whole-log regression's own bias) is "significant" fold by fold.
MIN_RELATIVE_GAIN = 0.01
#: Initialisation window of the position simulation, samples (first samples of the log:
#: the simulation starts from the filtered state at its end and is scored after it).
SIM_INIT_SAMPLES = 20


@dataclass(frozen=True)
class RichFit:
    """A fitted term set.

    Attributes
    ----------
    terms : tuple of str
        Switchable terms in the model (a subset of :data:`TERMS`).
    names, units : tuple of str
        Linear coefficients and their units (``u`` = command unit).
    theta, std : ndarray
        Linear coefficients and standard deviations.
    delay_samples, delay_std_samples : float
        Delay beyond the zero-order hold and its standard deviation, samples
        (0 and 0 without the ``delay`` term).
    vs, vs_std : float or None
        Stribeck velocity and its standard deviation, m/s (``stribeck`` term only).
    q_center : float
        Centre of the position polynomial, m.
    ripple_pitch : tuple of float
        Ripple pitches fitted (always in when given), m.
    relative_error : float
        ``||y - y_hat|| / ||y||`` on the decimated rows, fraction.
    condition_number : float
        2-norm condition number of the decimated regressor.
    residuals, force_measured, force_fitted : ndarray
        Decimated rows, u-unit.
    sample_rate : float
        Hz.
    """

    terms: tuple[str, ...]
    names: tuple[str, ...]
    units: tuple[str, ...]
    theta: np.ndarray = field(repr=False)
    std: np.ndarray = field(repr=False)
    cov: np.ndarray = field(repr=False)
    delay_samples: float
    delay_std_samples: float
    vs: float | None
    vs_std: float | None
    q_center: float
    ripple_pitch: tuple[float, ...]
    relative_error: float
    condition_number: float
    residuals: np.ndarray = field(repr=False)
    force_measured: np.ndarray = field(repr=False)
    force_fitted: np.ndarray = field(repr=False)
    sample_rate: float

    def value(self, name: str) -> float:
        """A linear coefficient (0 when its term is off)."""
        return float(self.theta[self.names.index(name)]) if name in self.names else 0.0

    def derived(self) -> dict[str, tuple[float, float, str]]:
        """Direction-wise levels ``fc_pos, fc_neg, B_pos, B_neg`` and ``fs``: (value, std, unit)."""
        i = {n: k for k, n in enumerate(self.names)}

        def lin(w: dict[str, float]) -> tuple[float, float]:
            a = np.zeros(len(self.names))
            for n, c in w.items():
                if n in i:
                    a[i[n]] = c
            return float(a @ self.theta), float(math.sqrt(max(a @ self.cov @ a, 0.0)))

        out = {"fc_pos": (*lin({"fc": 1, "offset": 1}), "u"), "fc_neg": (*lin({"fc": 1, "offset": -1}), "u")}
        if "dB" in i:
            out["B_pos"] = (*lin({"B": 1, "dB": 1}), "u s/m")
            out["B_neg"] = (*lin({"B": 1, "dB": -1}), "u s/m")
        if "dfs" in i:
            out["fs"] = (*lin({"fc": 1, "dfs": 1}), "u")
        return out

    def to_dict(self) -> dict[str, object]:
        """JSON-ready record (ident.json ``model.inverse_dynamics``); a non-finite std (flat profile) is null."""
        def fin(x: float | None) -> float | None:
            return float(x) if x is not None and math.isfinite(x) else None

        return {
            "terms": list(self.terms),
            "coefficients": {n: {"value": float(v), "std": fin(s), "unit": u}
                             for n, v, s, u in zip(self.names, self.theta, self.std, self.units)},
            "derived": {k: {"value": v, "std": fin(s), "unit": u} for k, (v, s, u) in self.derived().items()},
            "delay_samples": self.delay_samples,
            "delay_std_samples": fin(self.delay_std_samples),
            "delay_s": self.delay_samples / self.sample_rate,
            "delay_std_s": fin(self.delay_std_samples / self.sample_rate),
            "delay_reference": "beyond the zero-order hold (the plant's input delay)",
            "vs": self.vs, "vs_std": fin(self.vs_std), "stribeck_xi": STRIBECK_XI if self.vs is not None else None,
            "q_center": self.q_center,
            "relative_error": self.relative_error,
            "condition_number": self.condition_number,
        }


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


@dataclass(frozen=True)
class Selection:
    """Result of :func:`select_model`.

    Attributes
    ----------
    fit : RichFit
        The chosen term set, fitted on all rows.
    table : tuple of dict
        One row per candidate: ``terms``, ``n_parameters`` (beyond the 4 of the
        base), ``cv_rmse`` (u-unit), ``cv_mse`` (u-unit^2), ``cv_excess`` (mean over
        folds of the excess over the best candidate's fold MSE, u-unit^2) and
        ``cv_se`` (its standard error, u-unit^2); a candidate is within the rule when
        ``cv_excess <= cv_se``.
    threshold_mse : float
        Minimum CV mean squared error plus the chosen candidate's paired standard error, u-unit^2.
    """

    fit: RichFit
    table: tuple[dict[str, object], ...]
    threshold_mse: float
    folds: int
    gap_rows: int

    def to_dict(self) -> dict[str, object]:
        """JSON-ready record (ident.json ``model_selection``)."""
        return {"method": "blocked K-fold cross-validation, one-standard-error rule",
                "data": "identification log(s) only", "folds": self.folds, "gap_rows": self.gap_rows,
                "min_relative_gain": MIN_RELATIVE_GAIN,
                "chosen": list(self.fit.terms), "threshold_mse": self.threshold_mse,
                "units": {"cv_rmse": "u", "cv_mse": "u^2", "cv_se": "u^2", "cv_excess": "u^2", "delay_grid": "samples",
                          "vs_grid": "m/s"},
                "delay_grid": [float(d) for d in DELAY_GRID],
                "table": [dict(r) for r in self.table]}


class RichModel:
    """Preprocessed identification log(s) and the cached designs of :func:`select_model` / :meth:`fit`."""

    def __init__(self, segments: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], *,
                 ripple_pitch: float | Sequence[float] | None = None, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ,
                 reversal_fraction: float = REVERSAL_FRACTION):
        checked = segment_rates(list(segments))
        self.pp = preprocess_segments([c[:3] for c in checked], bandwidth_hz=bandwidth_hz)
        self.bandwidth_hz = float(bandwidth_hz)
        self.pitches = ripple_pitches(ripple_pitch)
        q = self.pp.q
        self.q_center = float(0.5 * (q.min() + q.max()))
        self.q_scale = max(float(0.5 * (q.max() - q.min())), 1e-12)
        speed = np.abs(self.pp.qd)
        vmax = float(speed.max())
        if not vmax > 0:
            raise NotIdentifiableError("q: the axis does not move; no inverse dynamics to fit")
        keep = None
        if reversal_fraction > 0:
            # Rows whose anti-alias window (and the delay's reach) saw a speed below the threshold.
            low = ndimage.maximum_filter1d((speed < reversal_fraction * vmax).astype(np.uint8),
                                           size=4 * self.pp.decimation + 1) > 0
            keep = ~self.pp.decimate_mask(low)
            if keep.sum() < 20 * (len(TERMS) + 8):
                keep = None
        self.design = _Design(self.pp, self.pitches, self.q_center, self.q_scale, keep)
        lo = max(float(np.percentile(speed, 5.0)), 1e-3 * vmax)
        self.vs_grid = tuple(float(v) for v in np.geomspace(lo, 0.3 * vmax, 6))

    # ------------------------------------------------------------------ profile over the nonlinear parameters
    def _grid(self, terms: Sequence[str]) -> list[tuple[float, float | None]]:
        ds = DELAY_GRID if "delay" in terms else (0.0,)
        vss: tuple[float | None, ...] = self.vs_grid if "stribeck" in terms else (None,)
        return [(d, v) for d in ds for v in vss]

    def _best_on(self, terms: Sequence[str], rows: np.ndarray) -> tuple[float, float | None]:
        """Grid choice of the delay (on ``rows`` away from reversals) and then of ``vs`` (on all ``rows``)."""
        y = self.design.y
        d_best = 0.0
        if "delay" in terms:
            kept = rows & self.design.keep
            best = math.inf
            for d, vs in self._grid(terms):
                c = _rss(self.design.matrix(terms, d, vs)[kept], y[kept])
                if c < best:
                    best, d_best = c, d
        if "stribeck" not in terms:
            return d_best, None
        costs = [(_rss(self.design.matrix(terms, d_best, vs)[rows], y[rows]), vs) for vs in self.vs_grid]
        return d_best, min(costs)[1]

    # ------------------------------------------------------------------ cross-validation through Gram matrices
    def _columns_of(self, terms: Sequence[str], with_stribeck: bool) -> np.ndarray:
        """Indices of ``terms``' columns in the full matrix (every term; Stribeck only ``with_stribeck``)."""
        full = [t for t in ("viscous_asym", "stribeck", "position", "drag") if t != "stribeck" or with_stribeck]
        idx, k = list(range(4)), 4
        for t in full:
            w = len(TERM_COEFFICIENTS[t])
            if t in terms:
                idx += list(range(k, k + w))
            k += w
        idx += list(range(k, k + 2 * len(self.pitches)))
        return np.asarray(idx)

    def _fold_stats(self, folds: int, gap: int, d: float, vs: float | None) -> dict[str, list]:
        """``(A^T A, A^T y, y^T y)`` of the full matrix at ``(d, vs)`` over each fold's row sets, cached."""
        key = (folds, gap, round(float(d), 9), vs)
        cache = self.__dict__.setdefault("_stats_cache", {})
        if key in cache:
            return cache[key]
        full = [t for t in TERMS if t != "stribeck" or vs is not None]
        A = self.design.matrix(full, d, vs)
        y, keep = self.design.y, self.design.keep
        n = y.size

        def st(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
            Am, ym = A[m], y[m]
            return Am.T @ Am, Am.T @ ym, float(ym @ ym)

        edges = np.linspace(0, n, folds + 1).astype(int)
        out: dict[str, list] = {"all": [st(np.ones(n, bool))], "keep": [st(keep)], "test": [], "excl": [],
                                "keep_excl": []}
        for a, b in zip(edges[:-1], edges[1:]):
            test = np.zeros(n, bool)
            test[a:b] = True
            excl = np.zeros(n, bool)
            excl[max(a - gap, 0):min(b + gap, n)] = True
            out["test"].append(st(test))
            out["excl"].append(st(excl))
            out["keep_excl"].append(st(excl & keep))
        cache[key] = out
        return out

    @staticmethod
    def _solve(G: np.ndarray, b: np.ndarray, yy: float, idx: np.ndarray) -> tuple[np.ndarray, float]:
        Gs, bs = G[np.ix_(idx, idx)], b[idx]
        theta = np.linalg.lstsq(Gs, bs, rcond=None)[0]
        return theta, yy - float(bs @ theta)

    def cross_validate(self, terms: Sequence[str], folds: int = N_FOLDS, gap: int = GAP_ROWS) -> tuple[float, np.ndarray]:
        """Blocked K-fold CV mean squared error of a term set (u-unit^2) and every fold's own.

        In each fold the delay is chosen on the training rows away from reversals and
        ``vs`` on all training rows (grids), then the linear coefficients on all training
        rows; the held-out block is predicted.  Sums of squares come from Gram matrices
        (training = all minus the held-out block and its gap), one per grid point.
        """
        n = self.design.y.size
        edges = np.linspace(0, n, folds + 1).astype(int)
        has_s = "stribeck" in terms
        sse, mses = 0.0, []
        for f, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            d_best = 0.0
            if "delay" in terms:
                best = math.inf
                for d, vs in self._grid(terms):
                    S = self._fold_stats(folds, gap, d, vs)
                    (G, bb, yy), (Ge, be, ye) = S["keep"][0], S["keep_excl"][f]
                    _, rss = self._solve(G - Ge, bb - be, yy - ye, self._columns_of(terms, has_s))
                    if rss < best:
                        best, d_best = rss, d
            choices = []
            for vs in (self.vs_grid if has_s else (None,)):
                S = self._fold_stats(folds, gap, d_best, vs)
                (G, bb, yy), (Ge, be, ye) = S["all"][0], S["excl"][f]
                idx = self._columns_of(terms, has_s)
                theta, rss = self._solve(G - Ge, bb - be, yy - ye, idx)
                choices.append((rss, vs, theta, idx))
            _, vs, theta, idx = min(choices, key=lambda c: c[0])
            Gt, bt, yt = self._fold_stats(folds, gap, d_best, vs)["test"][f]
            e = yt - 2.0 * float(theta @ bt[idx]) + float(theta @ Gt[np.ix_(idx, idx)] @ theta)
            sse += e
            mses.append(e / max(b - a, 1))
        return sse / n, np.asarray(mses)

    def _profile_delay(self, terms: Sequence[str], vs: float | None, d0: float) -> tuple[float, float]:
        """Delay minimising the RSS on the rows away from reversals (bounded search about the grid's
        ``d0``) and its standard deviation from the profile's curvature, samples."""
        kept = self.design.keep
        y = self.design.y[kept]

        def cost(d: float) -> float:
            return _rss(self.design.matrix(terms, d, vs)[kept], y)

        lo, hi = max(d0 - 0.25, DELAY_GRID[0]), min(d0 + 0.25, DELAY_GRID[-1])
        d = float(optimize.minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3}).x)
        h = 0.05
        f0, fp, fm = cost(d), cost(d + h), cost(d - h)
        curv = (fp - 2 * f0 + fm) / h**2
        p = self.design.matrix(terms, d, vs).shape[1] + 1
        sigma2 = f0 / (y.size - p)
        return d, (math.sqrt(2.0 * sigma2 / curv) if curv > 0 else math.inf)

    def fit(self, terms: Sequence[str]) -> RichFit:
        """Fit a term set: the delay profiled on the rows away from reversals, ``vs`` and the
        linear coefficients on all rows."""
        terms = tuple(t for t in TERMS if t in terms)
        unknown = set(terms) - set(TERMS)
        if unknown:
            raise ValueError(f"terms: unknown {sorted(unknown)}; known: {', '.join(TERMS)}")
        y = self.design.y
        rows = np.ones(y.size, bool)
        d, vs = self._best_on(terms, rows)
        d_std = 0.0
        if "delay" in terms:
            d, d_std = self._profile_delay(terms, vs, d)
        vs_std = None
        if vs is not None:
            # Refine vs on log scale at the delay, std from the profile's curvature.
            lv = math.log(vs)
            step = math.log(self.vs_grid[1] / self.vs_grid[0])
            res = optimize.minimize_scalar(lambda x: _rss(self.design.matrix(terms, d, math.exp(x)), y),
                                           bounds=(lv - step, lv + step), method="bounded", options={"xatol": 1e-4})
            vs = float(math.exp(res.x))
            lv, h = math.log(vs), 0.02
            f = [_rss(self.design.matrix(terms, d, math.exp(lv + k * h)), y) for k in (-1, 0, 1)]
            curv = (f[2] - 2 * f[1] + f[0]) / h**2
            sigma2 = f[1] / (y.size - self.design.matrix(terms, d, vs).shape[1] - 1)
            vs_std = vs * math.sqrt(2 * sigma2 / curv) if curv > 0 else math.inf
        A = self.design.matrix(terms, d, vs)
        names, units = _names_units(terms, self.pitches)
        n, p = A.shape
        theta, *_ = np.linalg.lstsq(A, y, rcond=None)
        r = y - A @ theta
        sigma2 = float(r @ r) / (n - p)
        _, s, vt = np.linalg.svd(A, full_matrices=False)
        cov = sigma2 * (vt.T / s**2) @ vt
        # Position polynomial back to physical units: z = (q - q_c) / q_scale.
        scale = np.ones(p)
        for nm, k in (("kq1", 1), ("kq2", 2)):
            if nm in names:
                scale[names.index(nm)] = self.q_scale ** -k
        theta_p, cov_p = theta * scale, cov * np.outer(scale, scale)
        y_all, fit_all, r_all = y, A @ theta, r
        return RichFit(terms=terms, names=names, units=units, theta=readonly_copy(theta_p),
                       std=readonly_copy(np.sqrt(np.diag(cov_p))), cov=readonly_copy(cov_p), delay_samples=float(d),
                       delay_std_samples=float(d_std), vs=vs, vs_std=vs_std, q_center=self.q_center,
                       ripple_pitch=self.pitches, relative_error=float(np.linalg.norm(r_all) / np.linalg.norm(y_all)),
                       condition_number=float(s[0] / s[-1]), residuals=readonly_copy(r_all),
                       force_measured=readonly_copy(y_all), force_fitted=readonly_copy(fit_all),
                       sample_rate=self.pp.sample_rate)


def candidate_sets(allowed: Sequence[str] = TERMS) -> list[tuple[str, ...]]:
    """Every subset of ``allowed`` (the empty set is the base model)."""
    allowed = tuple(t for t in TERMS if t in allowed)
    return [c for k in range(len(allowed) + 1) for c in itertools.combinations(allowed, k)]


def select_model(model: RichModel, allowed: Sequence[str] = TERMS, *, folds: int = N_FOLDS,
                 gap: int = GAP_ROWS) -> Selection:
    """Choose the term set by blocked cross-validation (one-standard-error rule) and fit it on all rows.

    Reads only ``model`` (the identification logs): the validation log plays no part.
    """
    rows, per_fold = [], []
    for terms in candidate_sets(allowed):
        mse, fold_mse = model.cross_validate(terms, folds, gap)
        per_fold.append(fold_mse)
        rows.append({"terms": list(terms), "n_parameters": n_parameters(terms), "cv_mse": mse,
                     "cv_rmse": math.sqrt(mse)})
    ib = min(range(len(rows)), key=lambda i: rows[i]["cv_mse"])  # type: ignore[arg-type, return-value]
    for r, fm in zip(rows, per_fold):
        # Paired across folds: the folds differ far more from each other than the models do on one fold.
        diff = fm - per_fold[ib]
        r["cv_excess"] = float(np.mean(diff))
        r["cv_se"] = float(np.std(diff, ddof=1) / math.sqrt(folds))
    floor = MIN_RELATIVE_GAIN * float(rows[ib]["cv_mse"])  # type: ignore[arg-type]
    ok = [r for r in rows if r["cv_excess"] <= max(r["cv_se"], floor)]  # type: ignore[operator, call-overload]
    chosen = min(ok, key=lambda r: (r["n_parameters"], r["cv_mse"]))  # type: ignore[arg-type, return-value]
    threshold = float(rows[ib]["cv_mse"]) + float(chosen["cv_se"])  # type: ignore[arg-type]
    for r in rows:
        r["chosen"] = r is chosen
    return Selection(fit=model.fit(chosen["terms"]), table=tuple(rows), threshold_mse=threshold,  # type: ignore[arg-type]
                     folds=folds, gap_rows=gap)


def relative_error_on(fit: RichFit, segments: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], *,
                      bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ) -> float:
    """Relative error ``||y - y_hat|| / ||y||`` of a fitted term set on other log(s) (the EMPS cross-test)."""
    other = RichModel(segments, ripple_pitch=fit.ripple_pitch or None, bandwidth_hz=bandwidth_hz,
                      reversal_fraction=0.0)
    other.design.qc, other.design.qs = fit.q_center, 1.0
    A = other.design.matrix(fit.terms, fit.delay_samples, fit.vs)
    y = other.design.y
    r = y - A @ np.asarray(fit.theta)
    return float(np.linalg.norm(r) / np.linalg.norm(y))


def force_model(fit: RichFit, q: float, v: float) -> float:
    """Force of every term but the mass, ``F - M qdd`` at position ``q`` (m) and velocity ``v`` (m/s), u-unit."""
    s = (v > 0) - (v < 0)
    f = fit.value("B") * v + fit.value("fc") * s + fit.value("offset") + fit.value("dB") * abs(v) \
        + fit.value("cd") * v * abs(v)
    if fit.vs is not None:
        f += fit.value("dfs") * math.exp(-(abs(v) / fit.vs) ** STRIBECK_XI) * s
    z = q - fit.q_center
    f += fit.value("kq1") * z + fit.value("kq2") * z * z
    for k, p in enumerate(fit.ripple_pitch):
        ph = 2.0 * math.pi * q / p
        f += fit.value(ripple_name("ripple_sin", k)) * math.sin(ph) + fit.value(ripple_name("ripple_cos", k)) * math.cos(ph)
    return f


@dataclass(frozen=True)
class PositionSimulation:
    """Open-loop simulation of an identified model under a log's command (the benchmark's output-error metric).

    Attributes
    ----------
    rmse : float
        RMS of ``q_sim - q_measured`` after the initialisation window, m.
    q_sim : ndarray
        Simulated position at the log's samples, m (the measured one in the window).
    init_samples : int
        Initialisation window, samples.
    """

    rmse: float
    q_sim: np.ndarray = field(repr=False)
    init_samples: int


def simulate_position(fit: RichFit, t: np.ndarray, q: np.ndarray, u: np.ndarray, *,
                      init_samples: int = SIM_INIT_SAMPLES, substeps: int = 10,
                      cutoff_hz: float = 5 * DEFAULT_BANDWIDTH_HZ) -> PositionSimulation:
    """Simulate ``M qdd = u(t - tau) - (F - M qdd)(q, qd)`` under the log's command; position RMSE.

    The command is held (zero-order hold) and acts ``fit.delay_samples`` after the
    hold; the state starts from the zero-phase filtered position and its central
    difference at the end of the initialisation window (the first ``init_samples``
    samples), and the error is scored from there to the end.  Coulomb-type terms
    at rest follow a stick-slip switch: the axis stays at rest while the remaining
    force is at most the break-away level ``fc + dfs`` (the model's friction as the
    speed goes to zero), and a step that would carry the speed through zero stops
    the axis instead.  Semi-implicit Euler with ``substeps`` steps per sample.

    Parameters
    ----------
    fit : RichFit
    t, q, u : ndarray, shape (N,)
        s (uniform), m, u-unit.
    init_samples : int
        Initialisation window, samples.
    substeps : int
        Integration steps per sample.
    cutoff_hz : float
        Cut-off of the filter giving the initial state, Hz.

    Returns
    -------
    PositionSimulation
    """
    from commission.identify.signals import zero_phase_lowpass

    t = np.asarray(t, float)
    q = np.asarray(q, float)
    u = np.asarray(u, float)
    n = t.size
    Ts = float(np.median(np.diff(t)))
    k0 = int(init_samples)
    if not 2 <= k0 < n - 2:
        raise ValueError(f"init_samples={init_samples} must lie in [2, {n - 3}]")
    qf = zero_phase_lowpass(q, min(cutoff_hz, 0.4 / Ts), 1.0 / Ts)
    x, v = float(qf[k0]), float((qf[k0 + 1] - qf[k0 - 1]) / (2 * Ts))
    M = fit.value("M")
    B, fc, off, dB, cd = (fit.value(n_) for n_ in ("B", "fc", "offset", "dB", "cd"))
    dfs = fit.value("dfs")
    vs = fit.vs if fit.vs is not None else 1.0
    kq1, kq2, qc = fit.value("kq1"), fit.value("kq2"), fit.q_center
    rip = [(p, fit.value(ripple_name("ripple_sin", k)), fit.value(ripple_name("ripple_cos", k)))
           for k, p in enumerate(fit.ripple_pitch)]
    brk = fc + dfs
    h = Ts / substeps
    d = fit.delay_samples
    out = np.empty(n)
    out[:k0 + 1] = q[:k0 + 1]
    for k in range(k0, n - 1):
        for j in range(substeps):
            # Command acting at time (k + (j + 0.5)/substeps) Ts: u[i] acts over [i + d, i + 1 + d).
            i = int(math.floor(k + (j + 0.5) / substeps - d))
            ui = u[min(max(i, 0), n - 1)]
            f_pos = off + kq1 * (x - qc) + kq2 * (x - qc) ** 2
            for p, a, b in rip:
                ph = 2.0 * math.pi * x / p
                f_pos += a * math.sin(ph) + b * math.cos(ph)
            drive = ui - f_pos
            if v == 0.0:
                if abs(drive) <= brk:
                    continue
                s = 1.0 if drive > 0 else -1.0
                v_new = (drive - s * brk) / M * h
            else:
                s = 1.0 if v > 0 else -1.0
                fr = B * v + s * fc + dB * abs(v) + cd * v * abs(v) + s * dfs * math.exp(-(abs(v) / vs) ** STRIBECK_XI)
                v_new = v + (drive - fr) / M * h
                if v_new * v < 0:
                    v_new = 0.0
            v = v_new
            x += v * h
        out[k + 1] = x
    e = out[k0 + 1:] - q[k0 + 1:]
    return PositionSimulation(rmse=float(np.sqrt(np.mean(e * e))), q_sim=readonly_copy(out), init_samples=k0)


def published_form(M: float, B: float, fc: float, offset: float, cov: np.ndarray | None, sample_rate: float) -> RichFit:
    """The IDIM-LS model (no delay beyond the published alignment: ``tau = 0``) as a :class:`RichFit`, for simulation."""
    theta = np.array([M, B, fc, offset], float)
    cov = np.zeros((4, 4)) if cov is None else np.asarray(cov, float)
    z = np.zeros(0)
    return RichFit(terms=(), names=("M", "B", "fc", "offset"), units=("u s^2/m", "u s/m", "u", "u"),
                   theta=readonly_copy(theta), std=readonly_copy(np.sqrt(np.diag(cov))), cov=readonly_copy(cov),
                   delay_samples=-0.5, delay_std_samples=0.0, vs=None, vs_std=None, q_center=0.0, ripple_pitch=(),
                   relative_error=math.nan, condition_number=math.nan, residuals=z, force_measured=z, force_fitted=z,
                   sample_rate=float(sample_rate))
