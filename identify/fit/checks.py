"""The refusals of a fit: what a log must hold for each parameter, checked on the data or the result.

Constant command, no reversals either way, a mass with too large a standard deviation, a
Stribeck curve the data do not show: each is a :class:`NotIdentifiableError` naming the figure
that failed.
"""

from __future__ import annotations

import numpy as np

from commission.identify.errors import MassNotIdentifiableError, NotIdentifiableError, StribeckNotIdentifiableError
from commission.identify.friction import XI_BOUNDS, SeparableFit
from commission.identify.units import unit


#: Least number of decimated rows on each side of zero velocity for the Coulomb level.
MIN_ROWS_PER_DIRECTION = 5


#: Least number of map points (Stribeck) / decimated rows below 3 vs for the Stribeck curve.
MIN_STRIBECK_POINTS = 4


MIN_STRIBECK_ROWS = 20


#: A friction test's Stribeck dip is kept when a Coulomb line explains the map's odd part this
#: unlikely well (F-test p-value of the Coulomb line against the Stribeck curve).
STRIBECK_DIP_P_VALUE = 1e-3


#: Refuse M when its relative standard deviation exceeds this.
MAX_REL_STD_M = 0.25


def _check_excitation(q: np.ndarray, u: np.ndarray) -> None:
    scale_u = max(float(np.max(np.abs(u))), 1e-300)
    if np.ptp(u) <= 1e-12 * scale_u:
        raise NotIdentifiableError(f"u: the command is constant ({float(u[0])!r} in all {u.size} samples); "
                                   "no parameter is identifiable")
    if np.ptp(q) == 0:
        raise NotIdentifiableError(f"q: the axis never moves (q = {float(q[0])!r} in all {q.size} samples)")


def _check_reversals(v_dec: np.ndarray, v_noise: float, cond: float) -> None:
    n_pos = int(np.sum(v_dec > v_noise))
    n_neg = int(np.sum(v_dec < -v_noise))
    if min(n_pos, n_neg) < MIN_ROWS_PER_DIRECTION:
        raise NotIdentifiableError(
            f"no velocity reversals: the Coulomb level is not identifiable (it is collinear with the offset); "
            f"{n_pos} decimated rows move forward and {n_neg} backward (need {MIN_ROWS_PER_DIRECTION} each); "
            f"condition number {cond:.3g}")


def _check_mass(M: float, std: float, cond: float) -> None:
    if not (M > 0 and std <= MAX_REL_STD_M * M):
        raise MassNotIdentifiableError(
            f"M: no usable acceleration content (M = {M:.4g} +- {std:.2g}, need M > 0 and a relative std "
            f"below {MAX_REL_STD_M:.0%}); condition number {cond:.3g}")


def _check_stribeck(sep: SeparableFit, speeds: np.ndarray, n_need: int, what: str, hint: str,
                    warnings: list[str], *, dip: tuple[float, float] | None = None,
                    speed_unit: str | None = None) -> None:
    """Refuse a Stribeck fit the data cannot support; warn about softer issues.

    Refused: fewer than ``n_need`` of ``speeds`` below ``3 vs`` (with ``dip``: inside the
    dip, below ``vs 3^(1/xi)`` where the Stribeck term is still 5 % of ``fs - fc``, and
    never below ``3 vs``: a small ``xi`` makes a dip that reaches far); no
    significant dip; ``vs`` on the search box (the dip lies outside the speeds seen).

    Significance: by default ``|fs - fc|`` must exceed three of its standard deviations.
    ``fs - fc`` is the dip *at standstill*, an extrapolation below the slowest speed
    seen; when few speeds lie in the dip, ``vs``, ``xi`` and ``fs`` trade against each
    other and its standard deviation can be many times the dip itself although the dip
    over the speeds seen is plain.  A friction test therefore passes
    ``dip = (F statistic, p-value)`` of a Coulomb line against the Stribeck curve (the
    residual sums of squares of the two fits): the dip is kept when ``p`` is below
    :data:`STRIBECK_DIP_P_VALUE`, whatever the spread of ``fs`` alone.
    """
    speed_unit = speed_unit or unit("v")
    i = {nm: k for k, nm in enumerate(sep.names)}
    fc, fs, vs, xi = (sep.value[i[k]] for k in ("fc", "fs", "vs", "xi"))
    g = np.zeros(len(sep.names))
    g[i["fs"]], g[i["fc"]] = 1.0, -1.0
    with np.errstate(over="ignore", invalid="ignore"):  # an inf covariance (friction.py): the spread is inf/nan
        sd_hump = float(np.sqrt(max(g @ sep.cov @ g, 0.0)))
    reach = vs * max(3.0, 3.0 ** (1.0 / xi)) if dip is not None else 3.0 * vs
    below = "3*vs" if reach == 3.0 * vs else f"vs*3^(1/xi) (xi = {xi:.3g})"
    n_low = int(np.sum(speeds < reach))
    head = f"too few samples below 3*vs for the Stribeck curve ({what}): "
    if n_low < n_need:
        raise StribeckNotIdentifiableError(head + f"{n_low} below {below} = {reach:.3g} {speed_unit}, need {n_need}; "
                                           f"{hint}")
    if dip is None and not abs(fs - fc) > 3.0 * sd_hump:
        raise StribeckNotIdentifiableError(head + f"no Stribeck hump shows (fs - fc = {fs - fc:.3g} +- {sd_hump:.2g}); {hint}")
    if dip is not None and not dip[1] < STRIBECK_DIP_P_VALUE:
        raise StribeckNotIdentifiableError(
            f"no Stribeck dip shows ({what}): the Stribeck curve fits the map no better than a Coulomb line "
            f"(F = {dip[0]:.3g}, p = {dip[1]:.2g}, need p < {STRIBECK_DIP_P_VALUE:g}; fs - fc = {fs - fc:.3g} "
            f"+- {sd_hump:.2g}); {hint}")
    if "vs" in sep.at_bound:
        raise StribeckNotIdentifiableError(head + f"vs = {vs:.3g} {speed_unit} lies on the edge of the speeds seen; "
                                           f"{hint}")
    if "xi" in sep.at_bound:
        warnings.append(f"stribeck: xi = {xi:.3g} at the edge of its search box {XI_BOUNDS}; "
                        "the shape of the curve is poorly determined")
    if fs < fc:
        warnings.append("stribeck: fs < fc (friction rises at low speed), which the model does not expect")
