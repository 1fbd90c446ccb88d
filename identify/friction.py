"""Stribeck friction: the curve, its separable least-squares fit, and the atan compensation.

Separable (variable-projection) fit
-----------------------------------
For fixed ``(vs, xi)`` the inverse-dynamics model is linear in its coefficients
(``M, B, fc, fs - fc, offset, ...``).  :func:`fit_separable` therefore searches
only ``(log vs, xi)`` over a box: a coarse grid gives the start, then
:func:`scipy.optimize.least_squares` (bounded trust region) minimises the
projected residual ``y - Phi(vs, xi) theta_hat(vs, xi)``.  Standard deviations
of every parameter, ``fs``, ``vs`` and ``xi`` included, come from the Jacobian of
the full nonlinear model at the optimum, ``cov = sigma^2 (J^T J)^-1`` with
``sigma^2 = ||r||^2 / (N - p)``.

Friction compensation
---------------------
The paper compensates friction with ``F_hat(v) = level (2/pi) atan(slope v)``
(eq. 57: ``(0.2/pi) atan(900 v)``).  A least-squares fit of that smooth curve to
the discontinuous ``Ff`` has no finite optimum (the steeper, the better), so the
target is ``Ff`` as the controller sees it: averaged over the error of a
backward-difference velocity estimate from a quantised encoder, which is
triangular on ``[-v_res, v_res]`` with ``v_res = LSB * sample_rate``, sampled
on a log-spaced velocity grid (equal weight per decade).  For the paper's
friction (fc 0.1 V, fs 0.12 V, vs 0.01 m/s, 1 um at 2.5 kHz, |v| <= 1 m/s) this
gives level 0.107 V and slope 2.1e3 s/m, against the paper's hand-picked 0.1 V
and 900 s/m; the slope scales as ``1 / v_res``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from commission.identify.errors import NotIdentifiableError, StribeckNotIdentifiableError
from commission.identify.units import unit

#: Bounds of the Stribeck exponent searched.
XI_BOUNDS = (0.3, 5.0)


def stribeck_friction(v: np.ndarray, fc: float, fs: float | None = None, vs: float | None = None,
                      xi: float | None = None) -> np.ndarray:
    """Nonlinear friction ``Ff(v) = [fc + (fs - fc) exp(-|v/vs|^xi)] sign(v)``, u-unit.

    With ``fs`` None the curve is Coulomb, ``fc sign(v)``.

    Parameters
    ----------
    v : ndarray
        Velocity, m/s.
    fc, fs : float
        Coulomb and static levels, u-unit.
    vs : float
        Stribeck velocity, m/s.
    xi : float
        Stribeck exponent.
    """
    v = np.asarray(v, dtype=np.float64)
    if fs is None:
        return fc * np.sign(v)
    return (fc + (fs - fc) * np.exp(-np.abs(v / vs) ** xi)) * np.sign(v)


def stribeck_shape_derivatives(v: np.ndarray, vs: float, xi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``s = exp(-|v/vs|^xi) sign(v)`` and its derivatives with respect to ``vs`` (1/(m/s)) and ``xi``."""
    a = np.abs(v / vs)
    w = a**xi
    s = np.exp(-w) * np.sign(v)
    with np.errstate(divide="ignore", invalid="ignore"):
        lna = np.where(a > 0, np.log(np.where(a > 0, a, 1.0)), 0.0)
    return s, s * xi * w / vs, -s * w * lna


@dataclass(frozen=True)
class SeparableFit:
    """Result of :func:`fit_separable`.

    Attributes
    ----------
    names : tuple of str
        Parameter names, in the order of ``value``: the linear names with ``fs``
        in place of ``dfs``, then ``vs`` and ``xi``.
    value, std : ndarray
        Estimates and standard deviations.
    cov : ndarray
        Covariance from the nonlinear Jacobian.
    sigma2 : float
        ``||r||^2 / (N - p)``.
    residuals : ndarray
        ``y - y_hat``.
    condition_number : float
        2-norm condition number of the linear observation matrix at the optimum.
    at_bound : tuple of str
        Nonlinear parameters whose optimum lies on the search box.
    """

    names: tuple[str, ...]
    value: np.ndarray
    std: np.ndarray
    cov: np.ndarray
    sigma2: float
    residuals: np.ndarray
    condition_number: float
    at_bound: tuple[str, ...]


ColumnFn = Callable[[float, float], np.ndarray]
JacobianFn = Callable[[float, float], tuple[np.ndarray, np.ndarray]]


def _grid_start(cost: Callable[[np.ndarray], float], lo: np.ndarray, hi: np.ndarray, n_grid_vs: int,
                xi_grid: tuple[float, ...], xi_bounds: tuple[float, float]) -> np.ndarray:
    """The start of :func:`fit_separable`: the grid point ``(log vs, xi)`` of least ``cost``, in the box.

    ``n_grid_vs`` values of ``log vs`` evenly over ``[lo[0], hi[0]]`` times the values of
    ``xi_grid`` within ``xi_bounds``; the first of equal costs is kept.
    """
    best = (math.inf, None)
    for lv in np.linspace(lo[0], hi[0], n_grid_vs):
        for xi in xi_grid:
            if not xi_bounds[0] <= xi <= xi_bounds[1]:
                continue
            z = np.array([lv, xi])
            c = cost(z)
            if c < best[0]:
                best = (c, z)
    return np.clip(best[1], lo, hi)


def fit_separable(Phi0: np.ndarray, names0: tuple[str, ...], column: ColumnFn, jacobian: JacobianFn, y: np.ndarray, *,
                  vs_bounds: tuple[float, float], xi_bounds: tuple[float, float] = XI_BOUNDS,
                  grid_column: ColumnFn | None = None,
                  n_grid_vs: int = 12, xi_grid: tuple[float, ...] = (0.5, 1.0, 1.5, 2.0, 3.0, 4.0)) -> SeparableFit:
    """Separable nonlinear least squares of a Stribeck model.

    Parameters
    ----------
    Phi0 : ndarray, shape (N, p0)
        The linear columns, which must include ``fc``'s column ``sign(v)``
        (transformed like ``y``, e.g. decimated or segment-averaged).
    names0 : tuple of str
        Names of ``Phi0``'s columns; must contain ``"fc"``.
    column : callable
        ``column(vs, xi) -> s``: the Stribeck column ``exp(-|v/vs|^xi) sign(v)``,
        transformed like ``y``.
    jacobian : callable
        ``jacobian(vs, xi) -> (ds_dvs, ds_dxi)``: its derivatives, transformed like ``y``.
    y : ndarray, shape (N,)
        Measurements, u-unit.
    vs_bounds : (float, float)
        Search box of ``vs``, m/s.
    xi_bounds : (float, float)
        Search box of ``xi``.
    grid_column : callable, optional
        A cheap approximation of ``column`` (e.g. the Stribeck function of the
        decimated velocity instead of the decimated Stribeck function) used for the
        grid and a first optimisation; the final optimisation always uses ``column``.

    Returns
    -------
    SeparableFit
    """
    i_fc = names0.index("fc")
    y = np.asarray(y, dtype=np.float64)
    if not (math.isfinite(vs_bounds[0]) and math.isfinite(vs_bounds[1]) and vs_bounds[0] > 0):
        # A stalled leg (mean speed 0) makes the lower edge 0: no Stribeck speed can be told apart.
        raise StribeckNotIdentifiableError(
            f"stribeck: the slowest speed seen is {vs_bounds[0]:g} {unit('v')}, so there is no search box for vs "
            f"(a leg that does not move, or a stalled axis)")
    lo = np.array([math.log(vs_bounds[0]), xi_bounds[0]])
    hi = np.array([math.log(vs_bounds[1]), xi_bounds[1]])
    if not np.all(hi > lo):
        raise StribeckNotIdentifiableError(f"stribeck: empty search box vs in {vs_bounds} {unit('v')}, xi in {xi_bounds}")

    # The residual of y on [Phi0, s] is that of y on Phi0 minus its projection on the
    # part of s orthogonal to Phi0: one QR of Phi0 makes every evaluation O(N p0).
    Q0, _ = np.linalg.qr(Phi0)
    r0 = y - Q0 @ (Q0.T @ y)

    def projected_residual(z: np.ndarray, col: ColumnFn = column) -> np.ndarray:
        s = col(math.exp(z[0]), z[1])
        s_perp = s - Q0 @ (Q0.T @ s)
        den = float(s_perp @ s_perp)
        return r0 - s_perp * (float(s_perp @ r0) / den) if den > 0 else r0

    def inner(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s = column(math.exp(z[0]), z[1])
        Phi = np.column_stack([Phi0, s])
        theta, *_ = np.linalg.lstsq(Phi, y, rcond=None)
        return theta, y - Phi @ theta, s

    z0 = _grid_start(lambda z: float(np.sum(projected_residual(z, grid_column or column) ** 2)), lo, hi,
                     n_grid_vs, xi_grid, xi_bounds)
    # x is (log vs, xi): a relative step of 1e-7 is far below their standard deviations.
    opts = dict(bounds=(lo, hi), x_scale=np.array([1.0, 1.0]), xtol=1e-7, ftol=1e-10, gtol=1e-10)
    if grid_column is not None:
        # Converge on the cheap column first, so the costly exact refinement starts close.
        z0 = optimize.least_squares(lambda z: projected_residual(z, grid_column), z0, **opts).x
    z = optimize.least_squares(projected_residual, z0, **opts).x
    theta, r, s = inner(z)
    vs, xi = math.exp(z[0]), float(z[1])
    dvs, dxi = jacobian(vs, xi)
    fc = theta[i_fc]
    dfs = theta[-1]
    # Jacobian of y_hat in the reported parametrisation (..., fc, ..., fs, vs, xi):
    # Ff = fc (sign - s) + fs s, so d/dfc = sign - s, d/dfs = s.
    J = np.column_stack([Phi0, s, dfs * dvs, dfs * dxi])
    J[:, i_fc] = Phi0[:, i_fc] - s
    n, p = J.shape
    if n <= p:
        raise StribeckNotIdentifiableError(f"stribeck: {n} rows for {p} parameters")
    sigma2 = float(r @ r) / (n - p)
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    # A near-singular Jacobian (a curve the log does not show) gives an inf/nan covariance, the
    # unidentifiable case said by the spread checks downstream, not a console warning.
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        cov = sigma2 * (vt.T / sv**2) @ vt if sv[-1] > 0 else np.full((p, p), np.inf)
    value = np.concatenate([theta[:-1], [fc + dfs, vs, xi]])
    names = tuple(names0) + ("fs", "vs", "xi")
    tol = 1e-6
    at_bound = tuple(nm for nm, zi, l, h in zip(("vs", "xi"), z, lo, hi) if zi - l < tol or h - zi < tol)
    Phi = np.column_stack([Phi0, s])
    sv_lin = np.linalg.svd(Phi, compute_uv=False)
    return SeparableFit(names=names, value=value, std=np.sqrt(np.abs(np.diag(cov))), cov=cov, sigma2=sigma2,
                        residuals=r, condition_number=float(sv_lin[0] / sv_lin[-1]), at_bound=at_bound)


@dataclass(frozen=True)
class FrictionCompensation:
    """``F_hat(v) = level (2/pi) atan(slope v)``.

    Attributes
    ----------
    level : float
        u-unit.
    slope : float
        s/m.
    rms_error : float
        RMS of ``F_hat - Ff_seen`` over the fitted velocity range, u-unit.
    v_max : float
        Upper end of the fitted velocity range, m/s.
    v_resolution : float
        Half-width of the velocity-error distribution used, m/s.
    """

    level: float
    slope: float
    rms_error: float
    v_max: float
    v_resolution: float


def fit_atan(v: np.ndarray, f: np.ndarray) -> tuple[float, float, float]:
    """Least-squares fit of ``level (2/pi) atan(slope v)`` to samples of an odd curve.

    ``level`` is linear given ``slope``; ``log(slope)`` is searched on a grid over
    ``[0.01 / max|v|, 100 / min|v|]`` and refined by a bounded scalar search.

    Parameters
    ----------
    v : ndarray, shape (n,)
        Velocities, m/s (non-zero).
    f : ndarray, shape (n,)
        Curve values, u-unit.

    Returns
    -------
    level : float
        u-unit.
    slope : float
        s/m.
    rms_error : float
        RMS fit error, u-unit.
    """
    v = np.asarray(v, dtype=np.float64)
    f = np.asarray(f, dtype=np.float64)
    av = np.abs(v[v != 0])
    if av.size < 2 or v.shape != f.shape:
        raise ValueError(f"fit_atan: need >= 2 non-zero velocities and matching shapes, got {v.shape}, {f.shape}")

    def level_for(slope: float) -> tuple[float, float]:
        g = (2.0 / math.pi) * np.arctan(slope * v)
        lev = float(g @ f / (g @ g))
        return lev, float(np.sqrt(np.mean((lev * g - f) ** 2)))

    grid = np.linspace(math.log(0.01 / av.max()), math.log(100.0 / av.min()), 161)
    costs = [level_for(math.exp(x))[1] for x in grid]
    k = int(np.argmin(costs))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    res = optimize.minimize_scalar(lambda x: level_for(math.exp(x))[1], bounds=(a, b), method="bounded",
                                   options={"xatol": 1e-9})
    slope = math.exp(res.x)
    lev, rms = level_for(slope)
    return lev, slope, rms


def friction_compensation_curve(fc: float, fs: float | None, vs: float | None, xi: float | None, *, v_max: float,
                                v_resolution: float, n_grid: int = 2000) -> FrictionCompensation:
    """Fit ``level (2/pi) atan(slope v)`` to the friction the controller sees.

    The target is ``Ff`` averaged over a triangular velocity error on
    ``[-v_resolution, v_resolution]``, sampled on a log-spaced grid from
    ``v_resolution / 10`` to ``v_max`` (equal weight per decade: the features of
    the curve, the velocity resolution and the Stribeck knee, live on a log scale).

    Parameters
    ----------
    fc, fs, vs, xi : float
        Friction curve (``fs`` None: Coulomb), u-unit, u-unit, m/s, -.
    v_max : float
        Largest speed the axis runs at, m/s (the curves are odd).
    v_resolution : float
        Half-width ``v_res`` of the triangular velocity-error distribution, m/s
        (``LSB * sample_rate`` for a backward difference of a quantised encoder).
    n_grid : int
        Velocity grid points.

    Returns
    -------
    FrictionCompensation
    """
    if not (v_max > v_resolution > 0):
        raise ValueError(f"need v_max > v_resolution > 0 {unit('v')}, got v_max={v_max}, v_resolution={v_resolution}")
    v = np.geomspace(v_resolution / 10.0, v_max, n_grid)
    # Triangular kernel by the midpoint rule (no node at e = 0, where Ff jumps).
    m = 400
    e = (np.arange(m) + 0.5) / m * 2.0 - 1.0
    wgt = 1.0 - np.abs(e)
    wgt /= wgt.sum()
    seen = stribeck_friction(v[:, None] - v_resolution * e[None, :], fc, fs, vs, xi) @ wgt
    lev, slope, rms = fit_atan(v, seen)
    return FrictionCompensation(level=lev, slope=slope, rms_error=rms, v_max=float(v_max),
                                v_resolution=float(v_resolution))
