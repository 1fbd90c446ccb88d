"""The unit of every quantity on an axis, for the numerics' messages and (via :mod:`commission.units`) every label.

Lives in the numerics layer so that :mod:`commission.identify` can word its messages
in the axis's unit without importing the pipeline (``tests/test_packaging.py``);
:mod:`commission.units` re-exports it with the rest of the wording.  The numerics do
not know the axis: they work on numbers.  Their messages ask :func:`unit` without
``units``, which answers in the position unit set by :func:`axis_units_context`
around the call (the identify stage sets it from the log; default m).  A context
variable, not a parameter threaded through every numerical function, because only
the wording of messages depends on it.
"""

from __future__ import annotations

import contextlib
import contextvars
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
