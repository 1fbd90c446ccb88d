"""How every quantity's unit is worded: the one place labels, warnings and reports take it from.

An axis is linear (``q`` in m) or rotary (``q`` in rad); ident.json's ``units``
(``{"u": u-unit, "q": "m" or "rad"}``) says which.  Every other unit follows from
those two (a velocity is ``q``/s, the coefficient of the acceleration ``u``·s²/``q``),
so no label spells out "m": it asks :func:`unit` (or :func:`parameter_units`) with
the axis's units.

:func:`unit`, :func:`parameter_units` and :func:`axis_units_context` live in the
numerics layer (:mod:`commission.identify.units`), whose messages need them too
(numerics never import the pipeline), and are re-exported here.
"""

from __future__ import annotations

import math
from typing import Mapping

from commission.identify.units import SMALL_SCALE, axis_units_context, parameter_units, unit  # noqa: F401


def mass_wording(units: Mapping[str, str]) -> tuple[str, str]:
    """How people call ``M`` on this axis, with its unit: ``("mass M", "N·s²/m")`` or ``("inertia J", "Nm·s²/rad")``.

    The model keeps one symbol ``M`` for the coefficient of the acceleration in every
    file (``parameters.M``); on a rotary axis (``units.q = "rad"``) that coefficient is
    the inertia seen by the command, in u-unit·s²/rad, and every message and report
    says so.

    Parameters
    ----------
    units : mapping
        ``{"u": u-unit, "q": "m" or "rad"}`` (ident.json's ``units``).

    Returns
    -------
    name : str
        ``"inertia J"`` on a rotary axis, else ``"mass M"``.
    unit : str
        ``"{u}·s²/{q}"``.
    """
    u, q = units.get("u", "u-unit"), units.get("q", "m")
    return ("inertia J" if q == "rad" else "mass M"), f"{u}·s²/{q}"


def parameter_label(name: str, units: Mapping[str, str]) -> str:
    """A parameter's row label: ``"M (mass)"`` or ``"M (inertia J)"``; other names as they are."""
    if name == "M":
        return "M (inertia J)" if units.get("q", "m") == "rad" else "M (mass)"
    return name


def nominal(x: float, fallback: str = "{!r}") -> str:
    """``x`` for printing: at 6 significant digits when that changes it by less than 1e-6 relative.

    A sample period computed as ``1 / rate`` from a rate estimated from time stamps carries
    rounding digits in its last places that say nothing; printed, it reads as its nominal
    value (``0.0004`` s, not ``0.000399999999999...``).  A value that differs from its
    6-digit rounding by more is a real estimate (a clock off its nominal rate) and is
    printed with ``fallback``.  Printing only: stored numbers keep every digit.
    """
    if not math.isfinite(x):
        return fallback.format(x)
    short = f"{x:.6g}"
    if abs(float(short) - x) <= 1e-6 * abs(x):
        return short
    return fallback.format(x)
