"""What a fit and a selection return: :class:`RichFit` (one fitted term set) and :class:`Selection`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from commission.identify.richer.settings import DELAY_GRID, MIN_RELATIVE_GAIN, STRIBECK_XI


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
