"""Inverse-dynamics regressor and ordinary least squares with statistics.

Model (contract §2, EMPS sign convention), in command units (u-unit)::

    u = M qdd + B qd + Ff(qd) + offset [+ a sin(2 pi q / P) + b cos(2 pi q / P)]
    Ff(v) = [fc + (fs - fc) exp(-|v / vs|^xi)] sign(v)

For fixed ``(vs, xi)`` the model is linear in its coefficients; :func:`regressor`
builds the columns and :func:`solve` estimates them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from commission.identify.errors import NotIdentifiableError
from commission.identify.units import unit

FrictionModel = Literal["coulomb", "stribeck"]

#: Column-equilibrated condition number above which a regression is refused.
MAX_SCALED_CONDITION = 1e8


def readonly_copy(a: np.ndarray) -> np.ndarray:
    """A float64 copy of ``a`` that cannot be written (result arrays of frozen dataclasses)."""
    a = np.array(a, dtype=np.float64, copy=True)
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class Regressor:
    """Observation matrix of the linear-in-parameters model.

    Attributes
    ----------
    Phi : ndarray, shape (N, p)
        Columns in the order of ``names``.
    names : tuple of str
        Coefficient names: ``M`` (u-unit s^2/m), ``B`` (u-unit s/m), ``fc``
        (u-unit), ``dfs`` (``fs - fc``, u-unit), ``offset`` (u-unit),
        ``ripple_sin``/``ripple_cos`` (u-unit).
    """

    Phi: np.ndarray = field(repr=False)
    names: tuple[str, ...]


def ripple_pitches(ripple_pitch: float | Sequence[float] | None) -> tuple[float, ...]:
    """The ripple pitches as a tuple (``()`` for none), each checked positive and finite, m."""
    if ripple_pitch is None:
        return ()
    out = (float(ripple_pitch),) if np.ndim(ripple_pitch) == 0 else tuple(float(p) for p in ripple_pitch)  # type: ignore[union-attr]
    for p in out:
        if not (np.isfinite(p) and p > 0):
            raise ValueError(f"ripple_pitch must be > 0 {unit('q')}, got {p}")
    return out


def ripple_name(base: str, k: int) -> str:
    """Name of the ``k``-th (0-based) ripple pitch's coefficient: ``base`` for the first, ``base_2``, ... after."""
    return base if k == 0 else f"{base}_{k + 1}"


def stribeck_shape(v: np.ndarray, vs: float, xi: float) -> np.ndarray:
    """Stribeck column ``exp(-|v/vs|^xi) sign(v)`` (dimensionless)."""
    return np.exp(-np.abs(v / vs) ** xi) * np.sign(v)


def regressor(qd: np.ndarray, qdd: np.ndarray, *, q: np.ndarray | None = None, model: FrictionModel = "coulomb",
              vs: float | None = None, xi: float | None = None, ripple_pitch: float | None = None) -> Regressor:
    """Build the inverse-dynamics observation matrix.

    Parameters
    ----------
    qd : ndarray, shape (N,)
        Velocity, m/s.
    qdd : ndarray, shape (N,)
        Acceleration, m/s^2.
    q : ndarray, shape (N,), optional
        Position, m; required with ``ripple_pitch``.
    model : {"coulomb", "stribeck"}
        Coulomb: columns ``[qdd, qd, sign(qd), 1]`` -> ``M, B, fc, offset``.
        Stribeck: adds ``exp(-|qd/vs|^xi) sign(qd)`` -> ``dfs = fs - fc`` after ``fc``.
    vs : float, optional
        Stribeck velocity, m/s (Stribeck model only).
    xi : float, optional
        Stribeck exponent (Stribeck model only).
    ripple_pitch : float or sequence of float, optional
        Force-ripple pitch P, m: adds ``sin(2 pi q/P)``, ``cos(2 pi q/P)``
        (``ripple_sin``, ``ripple_cos``); each further pitch P_k adds its own pair
        (``ripple_sin_k``, ``ripple_cos_k``, k = 2, 3, ...).

    Returns
    -------
    Regressor
    """
    qd = np.asarray(qd, dtype=np.float64)
    qdd = np.asarray(qdd, dtype=np.float64)
    if qd.shape != qdd.shape or qd.ndim != 1:
        raise ValueError(f"qd, qdd: need equal 1-D shapes, got {qd.shape} and {qdd.shape}")
    cols = [qdd, qd, np.sign(qd)]
    names = ["M", "B", "fc"]
    if model == "stribeck":
        if vs is None or xi is None or not (vs > 0 and xi > 0):
            raise ValueError(f"stribeck regressor needs vs > 0 and xi > 0, got vs={vs}, xi={xi}")
        cols.append(stribeck_shape(qd, vs, xi))
        names.append("dfs")
    elif model != "coulomb":
        raise ValueError(f"model must be 'coulomb' or 'stribeck', got {model!r}")
    cols.append(np.ones_like(qd))
    names.append("offset")
    pitches = ripple_pitches(ripple_pitch)
    if pitches:
        if q is None:
            raise ValueError("ripple_pitch needs the position q")
        q = np.asarray(q, dtype=np.float64)
        if q.shape != qd.shape:
            raise ValueError(f"q: shape {q.shape} differs from qd {qd.shape}")
        for k, pitch in enumerate(pitches):
            ph = 2.0 * np.pi * q / pitch
            cols += [np.sin(ph), np.cos(ph)]
            names += [ripple_name("ripple_sin", k), ripple_name("ripple_cos", k)]
    return Regressor(Phi=np.column_stack(cols), names=tuple(names))


@dataclass(frozen=True)
class LSResult:
    """Ordinary least-squares estimate of ``y = Phi theta + e``.

    Attributes
    ----------
    theta : ndarray, shape (p,)
        Estimate.
    std : ndarray, shape (p,)
        Standard deviations, ``sqrt(diag(cov))``.
    cov : ndarray, shape (p, p)
        ``sigma2 * inv(Phi^T Phi)``.
    sigma2 : float
        Residual variance ``||r||^2 / (N - p)``.
    condition_number : float
        2-norm condition number of ``Phi`` (unscaled, as the EMPS benchmark reports it).
    relative_error : float
        ``||y - Phi theta|| / ||y||`` as a fraction.
    residuals : ndarray, shape (N,)
        ``y - Phi theta``.
    """

    theta: np.ndarray = field(repr=False)
    std: np.ndarray = field(repr=False)
    cov: np.ndarray = field(repr=False)
    sigma2: float
    condition_number: float
    relative_error: float
    residuals: np.ndarray = field(repr=False)


def scaled_condition(Phi: np.ndarray) -> float:
    """Condition number of ``Phi`` after scaling every column to unit 2-norm.

    Independent of the units of the parameters, so it measures collinearity only;
    a zero column gives ``inf``.
    """
    norms = np.linalg.norm(Phi, axis=0)
    if np.any(norms == 0):
        return float("inf")
    return float(np.linalg.cond(Phi / norms))


def solve(Phi: np.ndarray, y: np.ndarray) -> LSResult:
    """Ordinary least squares with the textbook covariance.

    Parameters
    ----------
    Phi : ndarray, shape (N, p)
        Observation matrix, N > p.
    y : ndarray, shape (N,)
        Measurements.

    Returns
    -------
    LSResult

    Raises
    ------
    NotIdentifiableError
        If a column is zero or the columns are collinear (column-scaled condition
        number above 1e8); the message gives the condition number.
    """
    Phi = np.asarray(Phi, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if Phi.ndim != 2 or y.shape != (Phi.shape[0],):
        raise ValueError(f"Phi, y: need shapes (N, p) and (N,), got {Phi.shape} and {y.shape}")
    n, p = Phi.shape
    if n <= p:
        raise NotIdentifiableError(f"least squares: {n} rows for {p} parameters (need more rows than parameters)")
    if not (np.all(np.isfinite(Phi)) and np.all(np.isfinite(y))):
        raise ValueError("least squares: non-finite value in Phi or y")
    kappa = scaled_condition(Phi)
    if not kappa < MAX_SCALED_CONDITION:
        raise NotIdentifiableError(
            f"least squares: the regressor columns are collinear (column-scaled condition number {kappa:.3g})")
    theta, *_ = np.linalg.lstsq(Phi, y, rcond=None)
    r = y - Phi @ theta
    sigma2 = float(r @ r) / (n - p)
    # inv(Phi^T Phi) through the SVD of Phi: better conditioned than forming the normal matrix.
    _, s, vt = np.linalg.svd(Phi, full_matrices=False)
    ginv = (vt.T / s**2) @ vt
    cov = sigma2 * ginv
    ny = float(np.linalg.norm(y))
    return LSResult(theta=readonly_copy(theta), std=readonly_copy(np.sqrt(np.diag(cov))), cov=readonly_copy(cov), sigma2=sigma2,
                    condition_number=float(s[0] / s[-1]),
                    relative_error=float(np.linalg.norm(r)) / ny if ny > 0 else float("inf"),
                    residuals=readonly_copy(r))
