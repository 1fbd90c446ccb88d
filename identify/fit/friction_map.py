"""Friction curves fitted to a friction map: the points ``(v_k, F_k)`` of constant-velocity legs.

Used by the steady+dynamic method (step 1 of the module docstring) and, alone, for a friction
test of one leg per file (:func:`fit_friction_map`, :class:`MapFit`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from commission.identify.errors import NotIdentifiableError
from commission.identify.friction import fit_separable, stribeck_friction, stribeck_shape_derivatives
from commission.identify.ls import FrictionModel, solve, stribeck_shape
from commission.identify.steady import SteadySegments
from commission.identify.units import unit
from commission.identify.fit.checks import MIN_STRIBECK_POINTS, _check_stribeck
from commission.identify.fit.result import _ordered


#: Two legs of opposite directions are a pair when their speeds differ by at most this fraction.
PAIR_SPEED_TOLERANCE = 0.1


#: Why a friction map's viscous coefficient is bounded below by 0.  Viscous friction dissipates
#: (B >= 0), but a map fitted where the friction still falls with speed -- a ladder whose fastest
#: leg lies inside the Stribeck dip, as on an axis whose whole speed range does -- gives the least
#: squares a negative slope; the theta box then has theta2 = B/M < 0 and identification refused
#: the axis.  The least squares under the bound: a convex quadratic whose free optimum has B < 0
#: has its bounded optimum on B = 0, so the other coefficients are refitted with B held there
#: (and ``B``'s std is the free fit's).  Over the speeds the legs cover the map is then the
#: level friction of those speeds; the robust terms carry the rest.
VISCOUS_BOUND_NOTE = "viscous friction B >= 0"


def viscous_note(model: str, b_free: float, v_top: float) -> str:
    """The warning of a fit whose B was held at 0 (:data:`VISCOUS_BOUND_NOTE`); ``v_top``: its fastest speed."""
    return (f"{model}: the friction falls with speed up to the fastest speed fitted ({v_top:.3g} {unit('v')}): "
            f"the free fit gives B = {b_free:.4g} {unit('B')}, and viscous friction cannot be negative, so B "
            "is held at 0 (the motion does not reach past the Stribeck dip; faster legs would measure B)")


#: Least number of distinct leg speeds per direction for a friction ladder.
MIN_LADDER_SPEEDS = {"coulomb": 3, "stribeck": 4}


def _distinct_speeds(speeds: np.ndarray, rel: float = 0.1) -> int:
    """Number of speed levels, levels closer than ``rel`` (relative) counting as one."""
    if speeds.size == 0:
        return 0
    s = np.sort(speeds)
    return 1 + int(np.sum(s[1:] > (1.0 + rel) * s[:-1]))


def _map_fit_stribeck(v: np.ndarray, F: np.ndarray, warnings: list[str]) -> dict[str, tuple[float, float]]:
    """Fit ``F = B v + Ff(v) + offset`` (Stribeck ``Ff``) to friction-map points."""
    Phi0 = np.column_stack([v, np.sign(v), np.ones_like(v)])
    speed = np.abs(v)

    def jacobian(vs: float, xi: float) -> tuple[np.ndarray, np.ndarray]:
        return stribeck_shape_derivatives(v, vs, xi)[1:]

    def fit(cols: slice, names: tuple[str, ...]):
        return fit_separable(Phi0[:, cols], names, lambda vs, xi: stribeck_shape(v, vs, xi), jacobian, F,
                             vs_bounds=(0.3 * speed.min(), 0.5 * speed.max()))

    sep = fit(slice(None), ("B", "fc", "offset"))
    b_free = (float(sep.value[0]), float(sep.std[0]))
    if b_free[0] < 0.0:  # B >= 0 (:data:`VISCOUS_BOUND_NOTE`): the bounded optimum has B = 0
        sep = fit(slice(1, None), ("fc", "offset"))
    params = {nm: (float(val), float(sd)) for nm, val, sd in zip(sep.names, sep.value, sep.std)}
    if b_free[0] < 0.0:
        params = {"B": (0.0, b_free[1]), **params}
        warnings.append(viscous_note("stribeck", b_free[0], float(speed.max())))
    _check_stribeck(sep, speed, MIN_STRIBECK_POINTS,
                    f"constant-velocity legs; the slowest runs at {float(speed.min()):.3g} {unit('v')}",
                    "add slower legs to the friction ladder, give the ripple pitch if the axis has force ripple "
                    "the legs did not show (it does not average out on slow legs), or use "
                    "friction='coulomb'", warnings)
    return params


def _direction_pairs(v: np.ndarray) -> list[tuple[int, int]] | None:
    """Each forward leg paired with the backward leg nearest its speed, or None if a leg is left alone.

    Legs are matched in order of speed, one to one, within :data:`PAIR_SPEED_TOLERANCE`.
    """
    fwd = [int(i) for i in np.argsort(v) if v[i] > 0]
    bwd = [int(i) for i in np.argsort(-v) if v[i] < 0]
    if len(fwd) != len(bwd) or len(fwd) + len(bwd) != v.size:
        return None
    pairs = list(zip(fwd, bwd))
    for i, j in pairs:
        if abs(v[i] + v[j]) > PAIR_SPEED_TOLERANCE * max(v[i], -v[j]):
            return None
    return pairs


def _map_fit_stribeck_legs(v: np.ndarray, F: np.ndarray, warnings: list[str], speed_unit: str,
                           force_unit: str) -> dict[str, tuple[float, float]]:
    """Stribeck curve of a friction test; on the map's odd part when every leg has a partner the other way.

    The model ``F = B v + Ff(v) + offset`` is odd in ``v`` but for the constant
    ``offset``.  A real map's direction-dependent (even) part is often not constant:
    it can rise at the slowest legs as much as the dip itself.  Fitted to all legs, that
    misfit lands in the residual the Stribeck terms are judged against, and the dip drowns.
    With legs in pairs of opposite directions at matching speeds, the odd part
    ``(F(v) - F(-v)) / 2`` of each pair is ``B |v| + Ff(|v|)`` exactly, and the offset is
    the mean of the even parts ``(F(v) + F(-v)) / 2`` (std: their spread over
    ``sqrt(pairs)``).  The same curve, with every parameter's std from the odd part's own
    scatter.

    The dip is judged by an F-test of the Coulomb line against the Stribeck curve
    (:func:`_check_stribeck`, ``dip``), not by the std of ``fs - fc``: ``fs`` is the
    level at standstill, extrapolated below the slowest leg, and its std is reported as it
    is (large when few legs lie in the dip), with a warning naming the slowest speed.
    Without pairs the legs are fitted as one map (:func:`_map_fit_stribeck`).
    """
    pairs = _direction_pairs(v)
    if pairs is None or len(pairs) < 6:  # the F-test needs a residual degree of freedom beyond 5 parameters
        return _map_fit_stribeck(v, F, warnings)
    i, j = (np.array(k) for k in zip(*pairs))
    vo, Fo, Fe = (v[i] - v[j]) / 2.0, (F[i] - F[j]) / 2.0, (F[i] + F[j]) / 2.0
    Phi0 = np.column_stack([vo, np.ones_like(vo)])

    def jacobian(vs: float, xi: float) -> tuple[np.ndarray, np.ndarray]:
        return stribeck_shape_derivatives(vo, vs, xi)[1:]

    sep = fit_separable(Phi0, ("B", "fc"), lambda vs, xi: stribeck_shape(vo, vs, xi), jacobian, Fo,
                        vs_bounds=(0.3 * vo.min(), 0.5 * vo.max()))
    n, p = vo.size, len(sep.names)
    r_c = Fo - Phi0 @ np.linalg.lstsq(Phi0, Fo, rcond=None)[0]
    rss_c, rss_s = float(r_c @ r_c), float(sep.residuals @ sep.residuals)
    n_extra = p - Phi0.shape[1]  # fs, vs, xi
    f_stat = ((rss_c - rss_s) / n_extra) / (rss_s / (n - p)) if rss_s > 0 else math.inf
    p_value = float(stats.f.sf(f_stat, n_extra, n - p)) if math.isfinite(f_stat) else 0.0
    v0 = float(vo.min())
    _check_stribeck(sep, np.abs(v), MIN_STRIBECK_POINTS,
                    f"{n} pairs of legs, one each way; the slowest at {v0:.3g} {speed_unit}",
                    "add slower legs to the friction test, or use friction='coulomb'", warnings,
                    dip=(f_stat, p_value), speed_unit=speed_unit)
    params = {nm: (float(val), float(sd)) for nm, val, sd in zip(sep.names, sep.value, sep.std)}
    params["offset"] = (float(np.mean(Fe)), float(np.std(Fe, ddof=1) / math.sqrt(n)))
    fc, fs, vs, xi = (params[k][0] for k in ("fc", "fs", "vs", "xi"))
    left = math.exp(-((v0 / vs) ** xi))  # share of fs - fc still in the curve at the slowest pair
    if left < 0.5:
        warnings.append(f"stribeck: the dip is measured down to {v0:.3g} {speed_unit}, where the curve is "
                        f"{(fs - fc) * left:.3g} {force_unit} above fc; fs = {fs:.4g} +- {params['fs'][1]:.2g} "
                        f"{force_unit} is its value at standstill, extrapolated below the slowest legs")
    return params


def _stribeck_knee(v: np.ndarray, F: np.ndarray) -> float | None:
    """``3 vs`` of the map if it shows a clear Stribeck hump (fs > 1.05 fc, vs inside the box), else None."""
    if min(_distinct_speeds(v[v > 0]), _distinct_speeds(-v[v < 0])) < MIN_LADDER_SPEEDS["stribeck"]:
        return None
    try:
        w: list[str] = []
        p = _map_fit_stribeck(v, F, w)
    except (NotIdentifiableError, np.linalg.LinAlgError):
        return None
    if w or not p["fs"][0] > 1.05 * p["fc"][0]:
        return None
    return 3.0 * p["vs"][0]


def _map_fit_coulomb(v: np.ndarray, F: np.ndarray, warnings: list[str]) -> dict[str, tuple[float, float]]:
    """Fit ``F = B v + fc sign(v) + offset`` to the friction-map points above the Stribeck knee.

    A Coulomb line through legs inside the Stribeck hump would trade a too-low
    ``B`` for a too-high ``fc`` (about -20 % / +10 % on the paper's friction), so when
    the map shows a clear hump the legs slower than ``3 vs`` are left out, provided
    two distinct speeds remain each way.
    """
    keep = np.ones(v.size, dtype=bool)
    knee = _stribeck_knee(v, F)
    if knee is not None:
        fast = np.abs(v) > knee
        if min(_distinct_speeds(v[fast & (v > 0)]), _distinct_speeds(-v[fast & (v < 0)])) >= 2:
            keep = fast
            warnings.append(f"coulomb: {int(np.sum(~fast))} constant-velocity legs below {knee:.3g} {unit('v')} "
                            "(3 vs of the map's Stribeck hump) left out of the Coulomb fit")
    res = solve(np.column_stack([v[keep], np.sign(v[keep]), np.ones(int(keep.sum()))]), F[keep])
    if res.theta[0] < 0.0:  # B >= 0 (:data:`VISCOUS_BOUND_NOTE`): the bounded optimum has B = 0
        held = solve(np.column_stack([np.sign(v[keep]), np.ones(int(keep.sum()))]), F[keep])
        warnings.append(viscous_note("coulomb", float(res.theta[0]), float(np.max(np.abs(v[keep])))))
        return {"B": (0.0, float(res.std[0])), "fc": (float(held.theta[0]), float(held.std[0])),
                "offset": (float(held.theta[1]), float(held.std[1]))}
    return {nm: (float(th), float(sd)) for nm, th, sd in zip(("B", "fc", "offset"), res.theta, res.std)}


def _map_fit(v: np.ndarray, F: np.ndarray, friction: FrictionModel,
             warnings: list[str]) -> dict[str, tuple[float, float]]:
    """Fit the friction curve of ``friction`` to the map points ``(v, F)``."""
    if friction == "coulomb":
        return _map_fit_coulomb(v, F, warnings)
    return _map_fit_stribeck(v, F, warnings)


def _usable_map(segs: SteadySegments, friction: FrictionModel) -> str | None:
    """None if the legs form a friction ladder that can carry the friction fit, else why not.

    A ladder needs legs at ``MIN_LADDER_SPEEDS`` distinct speeds in each direction:
    with fewer, the map has no redundancy (two levels always fit a line exactly), so
    the legs are a by-product of the trajectory (e.g. the EMPS trapezoids), not a
    friction test, and the whole-log regression is used.
    """
    v = segs.velocity
    need = MIN_LADDER_SPEEDS[friction]
    n_pos, n_neg = _distinct_speeds(v[v > 0]), _distinct_speeds(-v[v < 0])
    if min(n_pos, n_neg) < need:
        return (f"constant-velocity legs at {n_pos} distinct speeds forward and {n_neg} backward "
                f"(a friction ladder for the {friction} map needs {need} each way)")
    return None


@dataclass(frozen=True)
class MapFit:
    """Friction curve fitted to a friction map alone (legs of a friction test, no dynamics).

    What :func:`fit_friction_map` returns: the map fit of the ``"steady+dynamic"`` method
    on its own, so that a friction test recorded as separate legs can be fitted without
    a whole-log regression.

    Attributes
    ----------
    friction : {"coulomb", "stribeck"}
        Model fitted.
    parameters : dict of str to (float, float)
        ``B`` (u-unit s/m), ``fc`` (u-unit), Stribeck only ``fs`` (u-unit), ``vs``
        (m/s), ``xi`` (-), and ``offset`` (u-unit): ``(value, std)``.  No ``M``: constant
        velocity carries no information on the mass.
    residuals : ndarray
        Map force minus fitted curve, per leg, u-unit.
    relative_error : float
        ``||F - F_hat|| / ||F||`` over the legs, fraction.
    condition_number : float
        2-norm condition number of the column-scaled map regressor ``[v, sign v, 1]``.
    warnings : tuple of str
        Human-readable caveats (e.g. how far down the Stribeck dip the legs reach).
    """

    friction: FrictionModel
    parameters: dict[str, tuple[float, float]]
    residuals: np.ndarray = field(repr=False)
    relative_error: float
    condition_number: float
    warnings: tuple[str, ...]


def fit_friction_map(velocity: np.ndarray, force: np.ndarray, *, friction: FrictionModel,
                     speed_unit: str | None = None, force_unit: str = "u-unit") -> MapFit:
    """Fit ``F = B v + Ff(v) + offset`` to friction-map points (one per constant-velocity leg).

    The same map fit as step 1 of the ``"steady+dynamic"`` method, on legs that are
    separate recordings (a friction test), so no mass and no inertia correction.

    Parameters
    ----------
    velocity : ndarray
        Mean velocity of each leg, m/s (rad/s on a rotary axis).
    force : ndarray
        Command of each leg (its median), u-unit.
    friction : {"coulomb", "stribeck"}
        A Stribeck curve is fitted to the map's odd part when the legs come in pairs of
        opposite directions (:func:`_map_fit_stribeck_legs`).
    speed_unit, force_unit : str
        Units of ``velocity`` and ``force`` in messages (default speed unit: the axis's,
        :func:`commission.identify.units.unit`).

    Returns
    -------
    MapFit

    Raises
    ------
    NotIdentifiableError
        Fewer than :data:`MIN_LADDER_SPEEDS` distinct speeds in a direction.
    StribeckNotIdentifiableError
        The Stribeck curve is not supported by the map.
    """
    speed_unit = speed_unit or unit("v")
    v = np.asarray(velocity, dtype=np.float64)
    F = np.asarray(force, dtype=np.float64)
    n_pos, n_neg = _distinct_speeds(v[v > 0]), _distinct_speeds(-v[v < 0])
    need = MIN_LADDER_SPEEDS[friction]
    if min(n_pos, n_neg) < need:
        raise NotIdentifiableError(f"friction: legs at {n_pos} distinct speeds forward and {n_neg} backward; the "
                                   f"{friction} curve needs {need} each way")
    warnings: list[str] = []
    if friction == "stribeck":
        params = _ordered(_map_fit_stribeck_legs(v, F, warnings, speed_unit, force_unit))
    else:
        params = _map_fit(v, F, friction, warnings)
    ff = stribeck_friction(v, params["fc"][0], params["fs"][0] if "fs" in params else None,
                           params["vs"][0] if "vs" in params else None, params["xi"][0] if "xi" in params else None)
    fitted = params["B"][0] * v + ff + params["offset"][0]
    r = F - fitted
    X = np.column_stack([v, np.sign(v), np.ones_like(v)])
    X = X / np.linalg.norm(X, axis=0)
    return MapFit(friction=friction, parameters=params, residuals=r,
                  relative_error=float(np.linalg.norm(r) / max(np.linalg.norm(F), 1e-300)),
                  condition_number=float(np.linalg.cond(X)), warnings=tuple(warnings))
