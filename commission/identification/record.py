"""Result assembly: the parts of ``ident.json`` that both ways of identifying write alike.

The estimates, the ``bounds`` record and the theta box (the fits keep B >= 0:
:data:`commission.identify.fit.friction_map.VISCOUS_BOUND_NOTE`), the ``tool``/``created_utc`` stamp,
and the friction curve an :class:`~commission.artifacts.Identification` describes.
"""

from __future__ import annotations

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
