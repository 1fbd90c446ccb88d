"""The dynamic (EMPS, IDIM-LS) method: the whole log's decimated regression (module docstring)."""

from __future__ import annotations

import numpy as np

from commission.identify.friction import fit_separable, stribeck_shape_derivatives
from commission.identify.ls import FrictionModel, regressor, ripple_name, ripple_pitches, solve, stribeck_shape
from commission.identify.signals import Preprocessed
from commission.identify.fit.checks import MIN_STRIBECK_ROWS, _check_mass, _check_reversals, _check_stribeck
from commission.identify.fit.friction_map import viscous_note
from commission.identify.fit.result import _ordered, _ripple_params


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
    i_b = names.index("B")
    if friction == "coulomb":
        res = solve(Phi, y)
        b_free = (float(res.theta[i_b]), float(res.std[i_b]))
        if b_free[0] < 0.0:  # B >= 0 (VISCOUS_BOUND_NOTE): the bounded optimum has B = 0
            names = names[:i_b] + names[i_b + 1:]
            Phi = np.delete(Phi, i_b, axis=1)
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

        def separable(cols: np.ndarray, nms: tuple[str, ...]):
            return fit_separable(cols, nms, column, jacobian, y, vs_bounds=(vs_lo, vs_hi),
                                 grid_column=lambda vs, xi: stribeck_shape(v_dec, vs, xi))

        sep = separable(Phi, tuple(names))
        b_free = (float(sep.value[i_b]), float(sep.std[i_b]))
        if b_free[0] < 0.0:  # B >= 0 (VISCOUS_BOUND_NOTE): the bounded optimum has B = 0
            names = names[:i_b] + names[i_b + 1:]
            Phi = np.delete(Phi, i_b, axis=1)
            sep = separable(Phi, tuple(names))
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
    if b_free[0] < 0.0:
        params = _ordered({**params, "B": (0.0, b_free[1])})
        warnings.append(viscous_note("whole-log", b_free[0], float(np.max(np.abs(v_dec)))))
    if mass is None:
        _check_mass(params["M"][0], params["M"][1], cond)
    return params, cond
