"""Identification of one axis from an excitation log: :func:`fit_axis` and :func:`evaluate`.

Model (contract §2), in command units (u-unit), ``u`` already multiplied by any input gain::

    u = M qdd + B qd + Ff(qd) + offset [+ A sin(2 pi q / P + phase)]
    Ff(v) = [fc + (fs - fc) exp(-|v/vs|^xi)] sign(v)      (Coulomb model: fc sign(v))

Two methods, chosen from the data:

``"dynamic"`` — the EMPS reference method (IDIM-LS), used when the log has no
usable constant-velocity legs (or ``use_steady=False``).  Filter and
differentiate the position, build the regressor ``[qdd, qd, sign(qd), 1]``
(plus the Stribeck column and ripple columns), decimate every column and the
command with the anti-alias filter, solve by least squares; for the Stribeck
model by separable nonlinear least squares over ``(vs, xi)``.  It reproduces the
published EMPS numbers exactly.  Its weakness: ``sign(qd)`` is discontinuous, the
filtered velocity crosses zero at slightly different times than the true one and
the axis sticks at reversals, so on logs with many slow reversals the filtered
friction columns do not match the filtered force.  On simulated closed-loop logs
with known truth the whole-log fit is off by up to ~9 % in ``B``, ~6 % in ``fc``
and ~60 % in ``fs``, or finds a negative Stribeck hump and is refused, where the
method below is within 0.5 %.

``"steady+dynamic"`` — used when the log contains a friction ladder:
constant-velocity legs at 3 (Coulomb) or 4 (Stribeck) distinct speeds in each
direction.  Fewer levels (EMPS's trapezoids cruise at two speeds) give a map
without redundancy, and the dynamic method is used.  Friction is taken from the
legs, mass from the dynamics:

1. **Friction map.**  :func:`commission.identify.steady.find_steady_segments`
   finds the legs; each gives one point ``(v_k, F_k)`` with ``v_k`` the position
   change over the leg divided by its duration and ``F_k`` the mean command minus
   ``M`` times the mean acceleration and minus the mean ripple force over the leg.
   No filter touches ``F_k``, so these points are unbiased.  ``B, fc, offset``
   (Coulomb) or ``B, fc, fs, vs, xi, offset`` (Stribeck, separable least squares)
   are fitted to them, with standard deviations from the map residuals.
2. **Mass.**  With the friction curve fixed, ``M`` (and the ripple ``sin``/``cos``
   coefficients) are fitted to the decimated dynamic rows
   ``D[u - B qd - Ff(qd) - offset] = M D[qdd] (+ ripple)``, leaving out every row
   whose anti-alias window saw a speed below ``reversal_speed`` (default ``3 vs``
   of the map's Stribeck curve, or 5 % of the fastest leg when the map shows no
   Stribeck hump), i.e. the reversals and stiction phases where the filtered
   friction column is wrong.  (Coulomb model: when the map shows a clear Stribeck
   hump, the legs slower than ``3 vs`` are left out of the Coulomb line, which
   would otherwise trade ~20 % of ``B`` for ~10 % of ``fc``.)
3. Steps 1-2 alternate: a first pass with a Coulomb map gives provisional ``M``
   and ripple, then three passes with the requested model (``M`` and the ripple
   enter the map points; the ripple matters on the slow legs, which cover a short
   stretch of travel where it does not average out).

Standard deviations: friction parameters from the map fit (its residuals), ``M``
and the ripple from the mass regression with the friction curve held fixed (the
cross-covariance between the two steps is neglected).

The figures of merit (relative error, condition number, residuals) are always
those of the full model on all decimated rows, as in the EMPS benchmark; the
condition number is that of the full decimated regressor at the fitted
``(vs, xi)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy import ndimage, stats

from commission.identify.errors import MassNotIdentifiableError, NotIdentifiableError, StribeckNotIdentifiableError
from commission.identify.friction import (XI_BOUNDS, SeparableFit, fit_separable, stribeck_friction,
                                          stribeck_shape_derivatives)
from commission.identify.ls import (FrictionModel, readonly_copy, regressor, ripple_name, ripple_pitches, solve,
                                    stribeck_shape)
from commission.identify.signals import (DEFAULT_BANDWIDTH_HZ, Preprocessed, default_settings, preprocess_segments,
                                         quantization_step, segment_rates)
from commission.identify.steady import SteadySegments, find_steady_segments
from commission.identify.units import unit

Method = Literal["dynamic", "steady+dynamic"]

#: Order of the parameters in :attr:`AxisFit.parameters`.
PARAMETER_ORDER = ("M", "B", "fc", "fs", "vs", "xi", "offset", "ripple_amp", "ripple_phase")


def _ordered(params: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """``params`` in :data:`PARAMETER_ORDER`, then the further ripple pitches' ``ripple_amp_k``, ``ripple_phase_k``."""
    out = {k: params[k] for k in PARAMETER_ORDER if k in params}
    out.update({k: params[k] for k in sorted(params, key=lambda n: (len(n), n))
                if k.startswith(("ripple_amp_", "ripple_phase_"))})
    return out

#: Least number of decimated rows on each side of zero velocity for the Coulomb level.
MIN_ROWS_PER_DIRECTION = 5
#: Least number of map points (Stribeck) / decimated rows below 3 vs for the Stribeck curve.
MIN_STRIBECK_POINTS = 4
MIN_STRIBECK_ROWS = 20
#: A friction test's Stribeck dip is kept when a Coulomb line explains the map's odd part this
#: unlikely well (F-test p-value of the Coulomb line against the Stribeck curve).
STRIBECK_DIP_P_VALUE = 1e-3
#: Two legs of opposite directions are a pair when their speeds differ by at most this fraction.
PAIR_SPEED_TOLERANCE = 0.1
#: Refuse M when its relative standard deviation exceeds this.
MAX_REL_STD_M = 0.25
#: Alternations of the friction-map / mass steps.
N_ALTERNATIONS = 3


@dataclass(frozen=True)
class AxisFit:
    """Identified model of one axis.

    Attributes
    ----------
    friction : {"coulomb", "stribeck"}
        Friction model fitted.
    method : {"dynamic", "steady+dynamic"}
        How it was fitted (see the module docstring).
    parameters : dict of str to (float, float)
        ``name -> (value, std)``: ``M`` (u-unit s^2/m), ``B`` (u-unit s/m),
        ``fc`` (u-unit), Stribeck only ``fs`` (u-unit), ``vs`` (m/s), ``xi`` (-),
        ``offset`` (u-unit), with a ripple pitch ``ripple_amp`` (u-unit) and
        ``ripple_phase`` (rad, ripple = ``ripple_amp sin(2 pi q / P + ripple_phase)``);
        each further pitch P_k its ``ripple_amp_k``, ``ripple_phase_k`` (k = 2, 3, ...).
    relative_error : float
        ``||y - y_hat|| / ||y||`` on all decimated rows, fraction.
    condition_number : float
        2-norm condition number of the decimated full-model regressor.
    residual_std : float
        Sample standard deviation of the residuals, u-unit.
    residuals : ndarray
        ``y - y_hat`` at the decimated rows, u-unit.
    t_decimated : ndarray
        Times of the decimated rows, s.
    force_measured : ndarray
        Decimated command ``y``, u-unit.
    force_fitted : ndarray
        Decimated model force ``y_hat``, u-unit.
    steady_velocity, steady_force : ndarray
        Friction-map points (mean velocity m/s, mean command corrected for
        inertia and ripple, u-unit); empty when no constant-velocity legs were used.
    quantization : float or None
        Encoder step the position data show, m (None: not on a grid).
    velocity_resolution : float
        Half-width of the velocity error of a backward-difference estimate, m/s:
        ``quantization * sample_rate``, else ``sqrt(6)`` times the RMS of the
        backward-difference velocity about the filtered velocity.
    v_max : float
        Largest filtered speed in the log, m/s.
    sample_rate : float
        Hz.
    bandwidth_hz, cutoff_hz : float
        Preprocessing bandwidth and Butterworth cut-off, Hz.
    decimation, trim_start : int
        Preprocessing decimation factor and samples trimmed at the start.
    ripple_pitch : float, tuple of float or None
        Force-ripple pitch(es) used, m.
    reversal_speed : float
        Speed below which rows were left out of the mass fit, m/s (0 for ``"dynamic"``).
    warnings : tuple of str
        Human-readable caveats.
    not_identified : dict of str to str
        Parameters the log carries no information on, with the reason (``M`` of a log
        without usable acceleration, when allowed); they are absent from ``parameters``.
    """

    friction: FrictionModel
    method: Method
    parameters: dict[str, tuple[float, float]]
    relative_error: float
    condition_number: float
    residual_std: float
    residuals: np.ndarray = field(repr=False)
    t_decimated: np.ndarray = field(repr=False)
    force_measured: np.ndarray = field(repr=False)
    force_fitted: np.ndarray = field(repr=False)
    steady_velocity: np.ndarray = field(repr=False)
    steady_force: np.ndarray = field(repr=False)
    quantization: float | None
    velocity_resolution: float
    v_max: float
    sample_rate: float
    bandwidth_hz: float
    cutoff_hz: float
    decimation: int
    trim_start: int
    ripple_pitch: float | tuple[float, ...] | None
    reversal_speed: float
    warnings: tuple[str, ...]
    not_identified: dict[str, str] = field(default_factory=dict)

    def value(self, name: str) -> float:
        """Value of a parameter."""
        return self.parameters[name][0]


# ----------------------------------------------------------------------------- model evaluation

def _param_values(params: dict[str, tuple[float, float]]) -> dict[str, float]:
    return {k: v[0] for k, v in params.items()}


def model_force(p: dict[str, float], q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                ripple_pitch: float | tuple[float, ...] | None) -> np.ndarray:
    """Full-rate model force ``M qdd + B qd + Ff(qd) + offset + ripple(q)``, u-unit."""
    y = p.get("M", 0.0) * qdd + p["B"] * qd + stribeck_friction(qd, p["fc"], p.get("fs"), p.get("vs"), p.get("xi"))
    y = y + p["offset"]
    for k, pitch in enumerate(ripple_pitches(ripple_pitch)):
        amp = ripple_name("ripple_amp", k)
        if amp in p:
            y = y + p[amp] * np.sin(2.0 * np.pi * q / pitch + p[ripple_name("ripple_phase", k)])
    return y


def _friction_force(p: dict[str, float], qd: np.ndarray) -> np.ndarray:
    return p["B"] * qd + stribeck_friction(qd, p["fc"], p.get("fs"), p.get("vs"), p.get("xi")) + p["offset"]


def _ripple_params(a: float, b: float, cov: np.ndarray, k: int = 0) -> dict[str, tuple[float, float]]:
    """Amplitude and phase of ``a sin x + b cos x = A sin(x + phase)`` with delta-method std (``k``-th pitch)."""
    amp, phase = ripple_name("ripple_amp", k), ripple_name("ripple_phase", k)
    A = math.hypot(a, b)
    if A == 0:
        return {amp: (0.0, float(math.sqrt(max(cov[0, 0], 0.0)))), phase: (0.0, float("inf"))}
    g_amp = np.array([a / A, b / A])
    g_ph = np.array([-b / A**2, a / A**2])
    return {amp: (A, float(math.sqrt(max(g_amp @ cov @ g_amp, 0.0)))),
            phase: (math.atan2(b, a), float(math.sqrt(max(g_ph @ cov @ g_ph, 0.0))))}


# ----------------------------------------------------------------------------- checks

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


# ----------------------------------------------------------------------------- dynamic (EMPS) method

def _dynamic_fit(pp: Preprocessed, friction: FrictionModel, ripple_pitch: float | tuple[float, ...] | None, v_noise: float,
                 warnings: list[str], mass: float | None = None) -> tuple[dict[str, tuple[float, float]], float]:
    """The whole-log regression; ``mass`` given: M is known (its term moved to the left side), not fitted."""
    base = regressor(pp.qd, pp.qdd, q=pp.q, model="coulomb", ripple_pitch=ripple_pitch)
    Phi = pp.decimate(base.Phi)
    y = pp.decimate(pp.u)
    names = base.names
    if mass is not None:
        y = y - mass * Phi[:, 0]
        Phi, names = Phi[:, 1:], names[1:]
    v_dec = pp.decimate(pp.qd)
    cond = float(np.linalg.cond(Phi))
    _check_reversals(v_dec, v_noise, cond)
    if friction == "coulomb":
        res = solve(Phi, y)
        params = {nm: (float(th), float(sd)) for nm, th, sd in zip(names, res.theta, res.std)}
        cov, cond = res.cov, res.condition_number
        idx = {nm: i for i, nm in enumerate(names)}
    else:
        speed = np.abs(pp.qd)
        vmax = float(speed.max())
        vs_lo = max(float(np.percentile(speed, 1.0)), 1e-4 * vmax, v_noise)
        vs_hi = 0.5 * vmax

        def column(vs: float, xi: float) -> np.ndarray:
            return pp.decimate(stribeck_shape(pp.qd, vs, xi))

        def jacobian(vs: float, xi: float) -> tuple[np.ndarray, np.ndarray]:
            _, dvs, dxi = stribeck_shape_derivatives(pp.qd, vs, xi)
            d = pp.decimate(np.column_stack([dvs, dxi]))
            return d[:, 0], d[:, 1]

        sep = fit_separable(Phi, names, column, jacobian, y, vs_bounds=(vs_lo, vs_hi),
                            grid_column=lambda vs, xi: stribeck_shape(v_dec, vs, xi))
        params = {nm: (float(val), float(sd)) for nm, val, sd in zip(sep.names, sep.value, sep.std)}
        _check_stribeck(sep, np.abs(v_dec), MIN_STRIBECK_ROWS, "decimated rows",
                        "excite slow motion or use friction='coulomb'", warnings)
        cov, cond = sep.cov, sep.condition_number
        idx = {nm: i for i, nm in enumerate(sep.names)}
    for k in range(len(ripple_pitches(ripple_pitch))):
        ns, nc = ripple_name("ripple_sin", k), ripple_name("ripple_cos", k)
        i, j = idx[ns], idx[nc]
        params.update(_ripple_params(params[ns][0], params[nc][0], cov[np.ix_([i, j], [i, j])], k))
        del params[ns], params[nc]
    if mass is None:
        _check_mass(params["M"][0], params["M"][1], cond)
    return params, cond


# ----------------------------------------------------------------------------- steady + dynamic method

def _map_fit_stribeck(v: np.ndarray, F: np.ndarray, warnings: list[str]) -> dict[str, tuple[float, float]]:
    """Fit ``F = B v + Ff(v) + offset`` (Stribeck ``Ff``) to friction-map points."""
    Phi0 = np.column_stack([v, np.sign(v), np.ones_like(v)])
    speed = np.abs(v)

    def jacobian(vs: float, xi: float) -> tuple[np.ndarray, np.ndarray]:
        return stribeck_shape_derivatives(v, vs, xi)[1:]

    sep = fit_separable(Phi0, ("B", "fc", "offset"), lambda vs, xi: stribeck_shape(v, vs, xi), jacobian, F,
                        vs_bounds=(0.3 * speed.min(), 0.5 * speed.max()))
    params = {nm: (float(val), float(sd)) for nm, val, sd in zip(sep.names, sep.value, sep.std)}
    _check_stribeck(sep, speed, MIN_STRIBECK_POINTS,
                    f"constant-velocity legs; the slowest runs at {float(speed.min()):.3g} {unit('v')}",
                    "add slower legs to the friction ladder, give the ripple pitch if the axis has force ripple "
                    "(it does not average out on slow legs), or use friction='coulomb'", warnings)
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
    return {nm: (float(th), float(sd)) for nm, th, sd in zip(("B", "fc", "offset"), res.theta, res.std)}


def _map_fit(v: np.ndarray, F: np.ndarray, friction: FrictionModel,
             warnings: list[str]) -> dict[str, tuple[float, float]]:
    """Fit the friction curve of ``friction`` to the map points ``(v, F)``."""
    if friction == "coulomb":
        return _map_fit_coulomb(v, F, warnings)
    return _map_fit_stribeck(v, F, warnings)


def _distinct_speeds(speeds: np.ndarray, rel: float = 0.1) -> int:
    """Number of speed levels, levels closer than ``rel`` (relative) counting as one."""
    if speeds.size == 0:
        return 0
    s = np.sort(speeds)
    return 1 + int(np.sum(s[1:] > (1.0 + rel) * s[:-1]))


#: Least number of distinct leg speeds per direction for a friction ladder.
MIN_LADDER_SPEEDS = {"coulomb": 3, "stribeck": 4}


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


def _steady_fit(pp: Preprocessed, segs: SteadySegments, friction: FrictionModel,
                ripple_pitch: float | tuple[float, ...] | None,
                reversal_speed: float | None, warnings: list[str],
                mass: float | None = None) -> tuple[dict[str, tuple[float, float]], np.ndarray, float]:
    """Friction from the legs, mass (and ripple) from the dynamics; ``mass`` given: M is known, not fitted."""
    M = 0.0 if mass is None else mass  # the legs' mean acceleration is ~0; the first map fit needs no mass
    pitches = ripple_pitches(ripple_pitch)
    n_r = 2 * len(pitches)  # ripple coefficients: (sin, cos) per pitch
    ripple_ab = np.zeros(max(n_r, 2))
    if pitches:
        sc = [f(2.0 * np.pi * pp.q / pitch) for pitch in pitches for f in (np.sin, np.cos)]
        seg_sc = np.column_stack([segs.mean_over(c) for c in sc])
        X_rip = pp.decimate(np.column_stack([pp.qdd, *sc]))
    else:
        seg_sc = np.zeros((len(segs), 2))
        X_rip = pp.decimate(pp.qdd[:, None])
    n_m = 1 if mass is None else 0  # columns of X_rip before the ripple's
    if mass is not None:
        X_rip = X_rip[:, 1:]
    y_u = pp.decimate(pp.u)
    speed = np.abs(pp.qd)
    reach = 4 * pp.decimation + 1

    def usable_rows(v_ex: float) -> np.ndarray:
        # A row is unusable if any sample within the anti-alias filter's reach was slow.
        low = ndimage.maximum_filter1d((speed < v_ex).astype(np.uint8), reach, mode="nearest").astype(bool)
        rows = ~pp.decimate_mask(low)
        n_rows = int(rows.sum())
        if n_rows < 10 * X_rip.shape[1]:
            raise MassNotIdentifiableError(
                f"M: only {n_rows} decimated rows move faster than {v_ex:.3g} {unit('v')} away from reversals "
                "(need dynamic motion at speed for the mass)")
        return rows

    # Pass 0 fits a Coulomb line (robust, never refused) to get provisional M and ripple:
    # a requested Stribeck fit needs the ripple removed from the slow legs first, which
    # sit on a short stretch of travel where the ripple does not average out.
    # Passes 1..N fit the requested model.
    for it in range(N_ALTERNATIONS + 1):
        F = segs.command - M * segs.acceleration - seg_sc @ ripple_ab
        model: FrictionModel = "coulomb" if it == 0 else friction
        # Keep the warnings of the last pass only: the earlier ones saw a provisional M.
        fr = _map_fit(segs.velocity, F, model, warnings if it == N_ALTERNATIONS else [])
        p = {k: v[0] for k, v in fr.items()}
        if it <= 1:
            v_ex = reversal_speed
            if v_ex is None:
                if "vs" in p:
                    v_ex = 3.0 * p["vs"]
                else:
                    knee = _stribeck_knee(segs.velocity, F)
                    v_ex = knee if knee is not None else 0.05 * float(np.max(np.abs(segs.velocity)))
            rows = usable_rows(v_ex)
            reversal = float(v_ex)
        y = y_u - pp.decimate(_friction_force(p, pp.qd)) - (0.0 if mass is None else mass * pp.decimate(pp.qdd))
        if X_rip.shape[1] == 0:  # known mass, no ripple: nothing to regress
            continue
        res = solve(X_rip[rows], y[rows])
        if mass is None:
            M = float(res.theta[0])
            _check_mass(M, float(res.std[0]), res.condition_number)
        if pitches:
            ripple_ab = np.asarray(res.theta[n_m:n_m + n_r])
    params: dict[str, tuple[float, float]] = {"M": (M, float(res.std[0])) if mass is None else (mass, 0.0)}
    params.update(fr)
    for k in range(len(pitches)):
        i = n_m + 2 * k
        params.update(_ripple_params(ripple_ab[2 * k], ripple_ab[2 * k + 1], np.asarray(res.cov)[i:i + 2, i:i + 2], k))
    # The map points as the final friction fit saw them.
    return params, np.column_stack([segs.velocity, F]), reversal


@dataclass(frozen=True)
class MapFit:
    """Friction curve fitted to a friction map alone (legs of a friction test, no dynamics).

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


# ----------------------------------------------------------------------------- public API

def _velocity_resolution(q_raws: list[np.ndarray], pp: Preprocessed, quant: float | None) -> float:
    """Velocity resolution over every segment (``q_raws``: each segment's raw positions, untrimmed)."""
    if quant is not None:
        return quant * pp.sample_rate
    k0 = pp.trim_start
    sq = []
    for q_raw, seg in zip(q_raws, pp.segments()):
        vb = np.diff(q_raw[k0:]) * pp.sample_rate  # backward difference at samples k0+1 ...
        qd = pp.qd[seg]
        sq.append((vb - 0.5 * (qd[1:] + qd[:-1])) ** 2)
    return float(math.sqrt(6.0) * np.sqrt(np.mean(np.concatenate(sq))))


def _stitched(qs: list[np.ndarray]) -> np.ndarray:
    """The segments' positions laid end to end with no jump at the joins (for grid and motion checks only)."""
    out, last = [], None
    for q in qs:
        out.append(q if last is None else q - q[0] + last)
        last = out[-1][-1]
    return out[0] if len(out) == 1 else np.concatenate(out)


def _steady_segments(pp: Preprocessed, min_duration_s: float, v_tol: float, v_quantum: float) -> SteadySegments:
    """Constant-velocity legs of every segment (none spans a join), indices into the stacked arrays."""
    found = []
    for seg in pp.segments():
        sg = find_steady_segments(pp.t[seg], pp.q[seg], pp.qd[seg], pp.u[seg], min_duration_s=min_duration_s,
                                  v_tol=v_tol, v_quantum=v_quantum)
        found.append((seg.start, sg))
    if len(found) == 1:
        return found[0][1]
    return SteadySegments(start=np.concatenate([sg.start + a for a, sg in found]).astype(np.int64),
                          stop=np.concatenate([sg.stop + a for a, sg in found]).astype(np.int64),
                          **{k: np.concatenate([getattr(sg, k) for _, sg in found])
                             for k in ("velocity", "command", "acceleration", "duration")})


def fit_axis(t: np.ndarray, q: np.ndarray, u: np.ndarray, *, friction: FrictionModel,
             **kwargs: object) -> AxisFit:
    """Identify ``M, B``, friction, offset (and ripple) of one axis from one log.

    The one-segment case of :func:`fit_segments`, which documents the keywords.

    Parameters
    ----------
    t, q, u : array_like, shape (N,)
        Sample times (s, uniform), encoder position (m) and command (u-unit, input
        gain already applied).
    friction : {"coulomb", "stribeck"}
    **kwargs
        As in :func:`fit_segments`.
    """
    return fit_segments([(t, q, u)], friction=friction, **kwargs)  # type: ignore[arg-type]


def fit_segments(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | tuple, *, friction: FrictionModel,
                 ripple_pitch: float | tuple[float, ...] | None = None, use_steady: bool = True,
                 bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ, cutoff_hz: float | None = None,
                 decimation: int | None = None, trim_start: int | None = None, min_segment_s: float = 0.2,
                 reversal_speed: float | None = None, mass: float | None = None,
                 allow_unidentified_mass: bool = False, velocity_logged: bool = False) -> AxisFit:
    """Identify ``M, B``, friction, offset (and ripple) of one axis from one or several logs.

    Each log is a segment: it is filtered, differentiated, trimmed and decimated on
    its own (:func:`commission.identify.signals.preprocess_segments`), its
    constant-velocity legs are found on its own, and the regression rows of all
    segments are stacked into one least-squares problem (standard deviations from
    ``sigma^2 (Phi^T Phi)^-1`` over all rows).  Nothing is filtered across the join
    between two logs, where the position may jump and the command step: a filter
    across it would smear a jump into a spurious velocity and acceleration.  One log
    gives exactly the single-log method of the module docstring.

    Parameters
    ----------
    segments : sequence of (t, q, u)
        Each log's sample times (s, uniform; one sample rate for all), encoder
        position (m) and command (u-unit, input gain already applied).
    friction : {"coulomb", "stribeck"}
        Friction model.
    ripple_pitch : float or sequence of float, optional
        Force-ripple pitch(es), m; fits a sinusoidal ripple of each pitch (e.g. the
        harmonics of one cogging period: P, P/2, P/4).
    use_steady : bool
        Use constant-velocity legs for the friction curve when the log has them.
    bandwidth_hz : float
        Dynamic bandwidth of the excitation, Hz (EMPS: 20); sets the defaults of
        the three preprocessing settings below (:mod:`commission.identify.signals`).
    cutoff_hz : float, optional
        Butterworth cut-off of the position pre-filter, Hz (default ``5 * bandwidth_hz``).
    decimation : int, optional
        Decimation factor (default ``round(0.8 * (fs/2) / (2 * bandwidth_hz))``).
    trim_start : int, optional
        Samples dropped at the start (default ``round(4.9 * fs / cutoff_hz)``).
    min_segment_s : float
        Shortest constant-velocity leg used, s.
    reversal_speed : float, optional
        Rows that come near speeds below this are left out of the mass fit of the
        ``"steady+dynamic"`` method, m/s (default ``3 vs`` of the map's Stribeck
        curve, else 5 % of the fastest constant-velocity leg).
    mass : float, optional
        A known mass, u-unit s^2/m: its term is moved to the left side and the rest
        is fitted (reported with std 0).
    allow_unidentified_mass : bool
        When the log has no usable acceleration content, fit the rest without the
        mass term and report M in :attr:`AxisFit.not_identified` instead of refusing
        the log (slow constant-speed runs: friction and ripple tests).
    velocity_logged : bool
        The position was integrated from a recorded velocity (an EPOS recorder file): leg
        detection allows for the velocity's quantum (:func:`find_steady_segments`, ``v_quantum``).

    Returns
    -------
    AxisFit

    Raises
    ------
    SignalError
        Malformed arrays (:attr:`SignalError.segment` names the log).
    NotIdentifiableError
        The log cannot identify the requested model (constant command, no
        reversals, no acceleration content, too little slow motion for Stribeck).
    """
    if friction not in ("coulomb", "stribeck"):
        raise ValueError(f"friction must be 'coulomb' or 'stribeck', got {friction!r}")
    checked = segment_rates(list(segments))
    q_all = _stitched([c[1] for c in checked])
    _check_excitation(q_all, np.concatenate([c[2] for c in checked]))
    pp = preprocess_segments([c[:3] for c in checked], bandwidth_hz=bandwidth_hz, cutoff_hz=cutoff_hz,
                             decimation=decimation, trim_start=trim_start)
    warnings: list[str] = []
    quant = quantization_step(q_all)
    if quant is None:
        warnings.append("q: the positions are not on an encoder grid (resampled or processed data?)")
    v_res = _velocity_resolution([c[1] for c in checked], pp, quant)
    # Velocity noise floor of the decimated velocity: one encoder count per anti-alias window.
    v_noise = (quant if quant is not None else 0.0) * pp.sample_rate / max(pp.decimation, 1)

    segs = None
    if use_steady:
        v_tol = (quant / 0.02) if quant is not None else 0.0
        # A position integrated from a recorded velocity (velocity_logged): the step of its
        # position-difference velocity (1 rpm of a recorder) bounds how steady a leg can look.  A
        # measured position's quantization averages out over the smoothing window: no quantum.
        v_quantum = quant * pp.sample_rate if (velocity_logged and quant is not None) else 0.0
        segs = _steady_segments(pp, min_segment_s, v_tol, v_quantum)
        reason = _usable_map(segs, friction) if len(segs) else "the log has no constant-velocity legs"
        if reason is not None:
            warnings.append(f"friction from the whole-log regression: {reason}; filtering the friction "
                            "discontinuity can bias B, fc and fs (a friction ladder avoids it)")
            segs = None
    if mass is not None and not (math.isfinite(mass) and mass > 0):
        raise ValueError(f"mass must be a positive finite number, got {mass!r}")
    method: Method = "steady+dynamic" if segs is not None else "dynamic"

    def fit_with(m: float | None) -> tuple[dict[str, tuple[float, float]], np.ndarray, float]:
        if segs is not None:
            return _steady_fit(pp, segs, friction, ripple_pitch, reversal_speed, warnings, mass=m)
        return _dynamic_fit(pp, friction, ripple_pitch, v_noise, warnings, mass=m)[0], np.zeros((0, 2)), 0.0

    not_identified: dict[str, str] = {}
    try:
        params, fmap, rev = fit_with(mass)
    except MassNotIdentifiableError as exc:
        if not allow_unidentified_mass:
            raise
        not_identified["M"] = str(exc).removeprefix("M: ")
        params, fmap, rev = fit_with(0.0)  # the model without the mass term
        params.pop("M", None)
    if mass is not None:
        params["M"] = (float(mass), 0.0)
    params = _ordered(params)

    p = _param_values(params)
    y = pp.decimate(pp.u)
    y_hat = pp.decimate(model_force(p, pp.q, pp.qd, pp.qdd, ripple_pitch))
    r = y - y_hat
    full = regressor(pp.qd, pp.qdd, q=pp.q, model=friction, vs=p.get("vs"), xi=p.get("xi"),
                     ripple_pitch=ripple_pitch)
    fitted_cols = pp.decimate(full.Phi)[:, (1 if (mass is not None or not_identified) else 0):]  # M is column 0
    cond = float(np.linalg.cond(fitted_cols))
    return AxisFit(friction=friction, method=method, parameters=params,
                   relative_error=float(np.linalg.norm(r) / np.linalg.norm(y)), condition_number=cond,
                   residual_std=float(np.std(r, ddof=1)), residuals=readonly_copy(r), t_decimated=readonly_copy(pp.t_dec),
                   force_measured=readonly_copy(y), force_fitted=readonly_copy(y_hat), steady_velocity=readonly_copy(fmap[:, 0]),
                   steady_force=readonly_copy(fmap[:, 1]), quantization=quant, velocity_resolution=v_res,
                   v_max=float(np.max(np.abs(pp.qd))), sample_rate=pp.sample_rate, bandwidth_hz=float(bandwidth_hz),
                   cutoff_hz=pp.cutoff_hz, decimation=pp.decimation, trim_start=pp.trim_start,
                   ripple_pitch=ripple_pitch, reversal_speed=rev, warnings=tuple(warnings),
                   not_identified=not_identified)


def evaluate(fit: AxisFit, t: np.ndarray, q: np.ndarray, u: np.ndarray) -> float:
    """Relative error ``||y - y_hat|| / ||y||`` of a fitted model on another log.

    The one-segment case of :func:`evaluate_segments`.

    Parameters
    ----------
    fit : AxisFit
    t, q, u : array_like, shape (N,)
        s, m, u-unit.

    Returns
    -------
    float
        Fraction.
    """
    return evaluate_segments(fit, [(t, q, u)])


def evaluate_segments(fit: AxisFit, segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | tuple) -> float:
    """Relative error ``||y - y_hat|| / ||y||`` of a fitted model on other logs, each its own segment.

    The log goes through the same preprocessing as the identification log (same
    cut-off, decimation and trim when the sample rates agree; otherwise the
    defaults for its own sample rate and the fit's bandwidth) and the error is
    taken over all decimated rows of all segments: the EMPS cross-test.  Each log is
    preprocessed on its own (nothing filtered across the joins), as in :func:`fit_segments`.

    Parameters
    ----------
    fit : AxisFit
    segments : sequence of (t, q, u)
        s, m, u-unit; one sample rate for all.

    Returns
    -------
    float
        Fraction.

    Raises
    ------
    SignalError
        Malformed arrays (:attr:`SignalError.segment` names the log).
    """
    checked = segment_rates(list(segments))
    fs_ = checked[0][3]
    data = [c[:3] for c in checked]
    if math.isclose(fs_, fit.sample_rate, rel_tol=1e-6):
        pp = preprocess_segments(data, cutoff_hz=fit.cutoff_hz, decimation=fit.decimation, trim_start=fit.trim_start)
    else:
        cutoff, _, _ = default_settings(fs_, fit.bandwidth_hz)
        pp = preprocess_segments(data, bandwidth_hz=fit.bandwidth_hz, cutoff_hz=cutoff)
    y = pp.decimate(pp.u)
    y_hat = pp.decimate(model_force(_param_values(fit.parameters), pp.q, pp.qd, pp.qdd, fit.ripple_pitch))
    ny = float(np.linalg.norm(y))
    if ny == 0:
        raise NotIdentifiableError("u: the validation command is zero; the relative error is undefined")
    return float(np.linalg.norm(y - y_hat) / ny)
