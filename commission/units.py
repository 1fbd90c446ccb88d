"""How every quantity's unit is worded: the one place labels, warnings and reports take it from.

An axis is linear (``q`` in m) or rotary (``q`` in rad); ident.json's ``units``
(``{"u": u-unit, "q": "m" or "rad"}``) says which.  Every other unit follows from
those two (a velocity is ``q``/s, the coefficient of the acceleration ``u``·s²/``q``),
so no label spells out "m": it asks :func:`unit` (or :func:`parameter_units`) with
the axis's units.

The numerics (:mod:`commission.identify`) do not know the axis: they work on
numbers.  Their messages ask :func:`unit` without ``units``, which answers in the
position unit set by :func:`axis_units_context` around the call (the identify stage
sets it from the log; default m).  A context variable, not a parameter threaded
through every numerical function, because only the wording of messages depends on it.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
from typing import Iterator, Mapping

#: Position unit of the axis whose numbers are being processed (messages of the numerics).
_Q_UNIT: contextvars.ContextVar[str] = contextvars.ContextVar("commission_q_unit", default="m")

#: Tracking errors and encoder steps are small: printed in micro-units of q, with this scale.
SMALL_SCALE = 1e6


@contextlib.contextmanager
def axis_units_context(q: str) -> Iterator[None]:
    """Within the block, :func:`unit` without ``units`` words positions in ``q`` (``"m"`` or ``"rad"``)."""
    token = _Q_UNIT.set(q)
    try:
        yield
    finally:
        _Q_UNIT.reset(token)


def unit(kind: str, units: Mapping[str, str] | None = None) -> str:
    """The unit of a quantity on this axis.

    Parameters
    ----------
    kind : str
        ``"q"`` position, ``"v"`` velocity, ``"a"`` acceleration, ``"small"`` a position in
        micro-units (tracking errors, encoder steps; scale :data:`SMALL_SCALE`), ``"u"`` the
        command, ``"q/u"`` the compliance of a frequency response, or a parameter name of
        :func:`parameter_units` (``"M"``, ``"B"``, ``"theta1"`` ...).
    units : mapping, optional
        ``{"u": u-unit, "q": "m" or "rad"}``; default: the position unit of
        :func:`axis_units_context` and ``"u-unit"``.

    Returns
    -------
    str
        E.g. ``"m/s"`` or ``"rad/s"``, ``"um"`` or ``"urad"``.
    """
    u = (units or {}).get("u", "u-unit")
    q = (units or {}).get("q") or _Q_UNIT.get()
    table = {"q": q, "v": f"{q}/s", "a": f"{q}/s²", "small": f"u{q}", "u": u, "q/u": f"{q}/{u}"}
    if kind in table:
        return table[kind]
    return parameter_units({"u": u, "q": q})[kind]


def parameter_units(units: Mapping[str, str]) -> dict[str, str]:
    """Unit of every identified parameter and theta component, for ident.json's ``units``.

    ``theta = [1/M, B/M, d_n/M]`` is in [q/(u·s²), 1/s, q/s²].
    """
    u, q = units.get("u", "u-unit"), units.get("q", "m")
    return {"M": f"{u}·s²/{q}", "B": f"{u}·s/{q}", "fc": u, "fs": u, "vs": f"{q}/s", "xi": "-", "offset": u,
            "theta1": f"{q}/({u}·s²)", "theta2": "1/s", "theta3": f"{q}/s²", "delta_d": f"{q}/s²"}


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

    A sample period computed as ``1 / rate`` (``0.0003999999999990677``) or a rate estimated
    from time stamps carries rounding digits that say nothing; printed, it reads as its
    nominal value (``0.0004``).  A value that differs from its 6-digit rounding by more
    (a real estimate, e.g. 1000.016 Hz) is printed with ``fallback``.  Printing only:
    stored numbers keep every digit.
    """
    if not math.isfinite(x):
        return fallback.format(x)
    short = f"{x:.6g}"
    if abs(float(short) - x) <= 1e-6 * abs(x):
        return short
    return fallback.format(x)
