"""Result assembly: the parts of ``ident.json`` that both ways of identifying write alike.

The estimates, the ``bounds`` record and the theta box (with a negative viscous estimate
clipped to the physical box when its interval allows), the ``tool``/``created_utc`` stamp,
and the friction curve an :class:`~commission.artifacts.Identification` describes.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
from typing import Mapping

import numpy as np

from commission import __version__
from commission.artifacts import Estimate, Identification, ThetaBox
from commission.errors import DataError
from commission.identification.options import BoundsOptions
from commission.identify.bounds import ThetaBounds
from commission.identify.fit import AxisFit
from commission.identify.friction import stribeck_friction


#: The parameters ident.json's ``parameters`` lists, in this order (null when not fitted).
PARAMETER_NAMES = ("M", "B", "fc", "fs", "vs", "xi", "offset")


def _estimates(parameters: Mapping[str, tuple[float, float]]) -> dict[str, Estimate | None]:
    """ident.json's ``parameters``: each of :data:`PARAMETER_NAMES` as an Estimate, None when not fitted."""
    params: dict[str, Estimate | None] = {}
    for name in PARAMETER_NAMES:
        v = parameters.get(name)
        params[name] = Estimate(float(v[0]), float(v[1])) if v is not None else None
    return params


def _stamp() -> dict[str, object]:
    """ident.json's ``tool`` and ``created_utc`` (UTC, to the second)."""
    return {"tool": {"name": "commission", "version": __version__},
            "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}


def _bounds_record(bounds: BoundsOptions, tb: ThetaBounds) -> dict[str, object]:
    """ident.json's ``bounds``: the declared settings and the ranges the theta box covers."""
    return {"k_sigma": bounds.k_sigma, "model_margin": bounds.model_margin, "mass_range": list(tb.mass_range),
            "viscous_range": list(tb.viscous_range), "disturbance_range": list(tb.disturbance_range),
            "disturbance_bound": tb.disturbance_bound, "disturbance_bound_defaulted": tb.disturbance_bound_defaulted,
            # The payload range the box covers and whether it was defaulted (tune may then narrow it to what
            # the controller can certify, commission.robustness.certified_payload).
            "payload_range": [tb.payload_range[0], tb.payload_range[1]], "payload_defaulted": tb.payload_defaulted}


def _clip_negative_viscous(tb: ThetaBounds, params: dict[str, Estimate | None], extra: dict[str, object],
                           warnings: list[str]) -> ThetaBounds:
    """A negative viscous estimate whose confidence interval reaches B > 0: the physical box, not a refusal.

    A viscous coefficient below zero (friction that pushes the axis along) is not physical; a fit
    returns one when the rigid model explains the log poorly (structural modes, a high rate).  The
    box already holds only B >= 0 (:func:`identify.bounds.theta_bounds_from` cuts its lower end at 0),
    and when its upper end is above 0 the estimate's interval B + k_sigma std reaches physical values:
    the nominal B is then clipped to the box's lower end (>= 0), which lies inside that interval's
    physical part, and the box is kept.  ``bounds.viscous_clipped`` records the estimate and a warning
    says so.  An interval entirely below zero (upper end 0) is still refused by :func:`_theta_box`.

    No fit of identify's reaches here with B < 0 any more: the least squares of
    :mod:`commission.identify.fit` (the friction map and the whole-log regression) are solved under
    B >= 0, the other coefficients refitted with B held at 0
    (:data:`commission.identify.fit.friction_map.VISCOUS_BOUND_NOTE`), and a delay-aware model
    (:mod:`commission.identify.richer`) that needs B < 0 is not carried on.  The clip stays as the
    guard of the theta box's physical end.
    """
    est = params.get("B")
    if est is None or not tb.nominal[1] < tb.theta_min[1] or not tb.theta_max[1] > 0:
        return tb
    b_phys = float(tb.viscous_range[0])
    m = 1.0 / tb.nominal[0]
    params["B"] = Estimate(b_phys, est.std)
    bounds = extra.get("bounds")
    if isinstance(bounds, dict):
        bounds["viscous_clipped"] = {"estimate": est.value, "std": est.std, "clipped_to": b_phys}
    warnings.append(f"B: the fit's viscous coefficient {est.value:.4g} +- {est.std:.2g} is negative (not physical); "
                    f"its interval reaches B > 0, so B is taken as {b_phys:.4g}, the lower end of the physical box "
                    f"[{tb.viscous_range[0]:.4g}, {tb.viscous_range[1]:.4g}] (ident.json bounds.viscous_clipped); "
                    f"the rigid model explains this log poorly: record a log with a broadband segment "
                    f"(commission excite)")
    return dataclasses.replace(tb, nominal=(tb.nominal[0], b_phys / m, tb.nominal[2]))


def _theta_box(tb: ThetaBounds, path: str, fit: AxisFit) -> ThetaBox:
    try:
        return ThetaBox(tb.nominal, tb.theta_min, tb.theta_max)
    except ValueError as exc:
        # E.g. a negative B from a log the rigid model does not explain: no controller can use it.
        raise DataError(f"{path}: the identified parameters give no usable theta box ({exc}); "
                        f"M = {fit.parameters['M'][0]:.4g}, B = {fit.parameters['B'][0]:.4g}, relative error "
                        f"{fit.relative_error:.3g}: the model does not explain this log") from None


def _maybe(v: tuple[float, float] | None) -> dict[str, float] | None:
    return None if v is None else {"value": float(v[0]), "std": float(v[1])}


def friction_curve(ident: Identification, v: np.ndarray) -> np.ndarray:
    """Identified total friction ``B v + Ff(v) + offset`` at velocities ``v`` (m/s), u-unit."""
    p = ident.parameters

    def val(name: str) -> float | None:
        e = p.get(name)
        return None if e is None else e.value

    ff = stribeck_friction(np.asarray(v, float), val("fc"), val("fs"), val("vs"), val("xi"))  # type: ignore[arg-type]
    return ident.value("B") * np.asarray(v, float) + ff + ident.value("offset")
