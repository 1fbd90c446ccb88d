"""Fitting and choosing a term set: :class:`RichModel` (profiled delay and ``vs``, blocked cross-validation)
and :func:`select_model` (the one-standard-error rule)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
from scipy import ndimage, optimize

from commission.identify.errors import NotIdentifiableError
from commission.identify.ls import readonly_copy, ripple_pitches
from commission.identify.signals import DEFAULT_BANDWIDTH_HZ, preprocess_segments, segment_rates
from commission.identify.richer.settings import (DELAY_GRID, GAP_ROWS, MIN_RELATIVE_GAIN, N_FOLDS, REVERSAL_FRACTION,
                                                 TERM_COEFFICIENTS, TERMS)
from commission.identify.richer.design import _Design, _names_units, _rss, n_parameters
from commission.identify.richer.result import RichFit, Selection


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
