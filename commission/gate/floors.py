"""The floors (:data:`FLOORS`) and the margin checks of the gate.

The gate decides what is *good enough*; the floors decide what may be *deployed at all*, and no
``gate.toml`` can lower them: no scenario diverges (the robustness scenarios included: one more
sample of delay, the mode's variants), the peak |u| stays below a finite ``u_max`` (the command
never clipped), ``u_max``, ``k1s_max``, ``k2s_max`` are finite, and the ARC on the identified plant
keeps the tuning spec's ``[margins]`` floors.  A gate that switches a criterion off
(``no_divergence = false``) or loosens it (``u_max = 1e9``) still gives a report, but
``controller.json`` is written only when every floor holds.

The margin checks (:func:`margin_checks`, :func:`box_checks`) hold the loops of
:mod:`commission.robustness` to the floors, one check per loop and floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

from commission.gate.check import Check, divergence_check
from commission.gate.limits import SATURATION_TOL
from commission.robustness import margin_rows
from commission.controllers.metrics import Indexes


@dataclass(frozen=True)
class Floor:
    """A condition every emitted ``controller.json`` meets, whatever ``gate.toml`` says.

    Attributes
    ----------
    name : str
        Its checks are reported as criterion ``floor:<name>``.
    rule : str
        One line for the report and the documentation.
    check : callable(FloorContext) -> list of Check
        Every check of the floor (one per scenario, or one for the controller).
    """

    name: str
    rule: str
    check: Callable[[FloorContext], list[Check]]


@dataclass(frozen=True)
class FloorContext:
    """What the floors look at.

    Attributes
    ----------
    runs : sequence of (scenario, arc, t_abort)
        The ARC's score on every scenario of the validation and the time (s) its run aborted
        (NaN if it did not).
    limits : mapping of str to float
        The deployed controller's output and gain limits: ``u_max`` (u-unit), ``k1s_max``,
        ``k2s_max`` (1/s); ``math.inf`` where absent.
    drive_u_max : float
        The drive's input limit the validation simulated (the tuning spec's ``controller.u_max``), u-unit.

    margins : sequence of commission.robustness.LoopMargins
        The stability margins of the validated loops.
    margin_floors : commission.robustness.MarginFloors or None
        The tuning spec's ``[margins]``: what tune designed for (None: no margin floor checked).

    A floor that needs more adds an optional field here and an entry in :data:`FLOORS`.
    """

    runs: Sequence[tuple[str, Indexes, float]]
    limits: Mapping[str, float]
    drive_u_max: float
    margins: Sequence[Any] = ()
    margin_floors: Any = None


def _floor_no_divergence(ctx: FloorContext) -> list[Check]:
    return [divergence_check("floor:no_divergence", name, arc, t_abort) for name, arc, t_abort in ctx.runs]


def _floor_u_peak(ctx: FloorContext) -> list[Check]:
    u_max = min(ctx.limits.get("u_max", math.inf), ctx.drive_u_max)
    out = []
    for name, arc, _t in ctx.runs:
        # As the gate's u_peak: reaching the limit means the command relied on clipping.
        ok = math.isfinite(u_max) and math.isfinite(arc.u_peak) and arc.u_peak < u_max * (1.0 - SATURATION_TOL)
        out.append(Check("floor:u_peak", name, arc.u_peak, u_max, ok,
                         f"peak |u| {arc.u_peak:.4g} (floor: below the finite u_max {u_max:.4g})"))
    return out


def _floor_finite_limits(ctx: FloorContext) -> list[Check]:
    out = []
    for key in ("u_max", "k1s_max", "k2s_max"):
        v = ctx.limits.get(key, math.inf)
        ok = math.isfinite(v) and v > 0
        detail = f"{key} = {v:.4g}" if ok else f"{key} = {v}: the controller would have no {key} limit"
        if key == "u_max" and ok and v > ctx.drive_u_max * (1.0 + SATURATION_TOL):
            ok = False
            detail = f"u_max = {v:.4g} exceeds the drive's limit {ctx.drive_u_max:.4g} that was validated"
        out.append(Check("floor:finite_limits", key, v, math.nan, ok, detail))
    return out


#: The floors, in report order.  ``commission validate`` appends their checks to the gate's
#: verdict, so a controller.json is written only when every floor holds, however loose
#: ``gate.toml`` is.  Add a floor by appending a :class:`Floor` (and, if it needs new
#: inputs, an optional field to :class:`FloorContext`).
FLOORS: tuple[Floor, ...] = (
    Floor("no_divergence", "no scenario may diverge (non-finite, |q - q_d| > travel, |u| > 1e6)",
          _floor_no_divergence),
    Floor("u_peak", "peak |u| below the controller's finite u_max (never clipped) on every scenario",
          _floor_u_peak),
    Floor("finite_limits", "u_max, k1s_max and k2s_max are finite and positive, u_max within the drive's",
          _floor_finite_limits),
    Floor("margins", "the ARC on the identified plant is stable and keeps the tuning spec's [margins] floors",
          lambda ctx: [] if ctx.margin_floors is None else margin_checks(ctx.margins, ctx.margin_floors,
                                                                          "floor:margins")),
)


def check_floors(ctx: FloorContext) -> list[Check]:
    """Every check of every floor of :data:`FLOORS`."""
    return [c for f in FLOORS for c in f.check(ctx)]


#: The loops whose margins the gate holds to the floors: the ARC on the identified plant
#: (with its mode and delay), at both linearisation points.  The box corners are reported, not
#: gated: a payload range is a design choice, and at its heaviest corner even the paper's own PID
#: keeps little phase (README, "What the rigid model lacks").
GATED_PLANT = "nominal"


def _loop_checks(m: Any, floors: Any, criterion: str, where: str) -> list[Check]:
    """Stability (value 0, or inf when unstable) and each floor of one loop's margins ``m``
    (value floor / margin, limit 1): the checks :func:`margin_checks` and :func:`box_checks` share."""
    out = [Check(criterion, where, 0.0 if m.stable else math.inf, 1.0, m.stable,
                 f"closed loop {'stable' if m.stable else 'UNSTABLE'} (spectral radius {m.spectral_radius:.4f})")]
    for name, val, floor, unit in margin_rows(m, floors):
        ratio = floor / val if val > 0 else math.inf
        out.append(Check(criterion, where, ratio, 1.0, bool(val >= floor),
                         f"{name} {val:.3g} {unit} (floor {floor:g} {unit})".replace("  ", " ")))
    return out


def margin_checks(rows: Sequence[Any], floors: Any, criterion: str = "margins") -> list[Check]:
    """Gate checks (criterion ``criterion``) of the ARC loops on the identified plant.

    ``rows`` are :class:`commission.robustness.LoopMargins`, ``floors`` a
    :class:`commission.robustness.MarginFloors`.
    One check per loop and floor; ``value`` is floor / margin (at most 1 passes;
    inf for a margin at or below zero), ``limit`` 1.
    """
    out = []
    for r in rows:
        if r.controller != "arc" or r.plant != GATED_PLANT:
            continue
        m = r.margins
        where = f"margins/{r.plant}/arc(theta_hat {r.theta_hat_at})"
        out += _loop_checks(m, floors, criterion, where)
    return out


def box_checks(box: Any, floors: Any, criterion: str = "margins_box") -> list[Check]:
    """Gate checks of the ARC over the whole theta box (:class:`commission.robustness.BoxRobustness`).

    (a) per box plant, the ARC with theta_hat at that plant's theta: stable (value 0, or inf when
    unstable) and each floor of ``floors`` (value floor / margin, limit 1, as :func:`margin_checks`);
    (b) one check, the least stable loop with theta_hat anywhere the projection allows (value its
    spectral radius, limit 1).  The scenario names the corner (``box/<corner>[/<variant>]/...``), so
    a refusal names it.
    """
    out = []
    for r in box.at_plant:
        m = r.margins
        where = f"box/{r.plant}/arc(theta_hat plant)"
        out += _loop_checks(m, floors, criterion, where)
    a = box.any_estimate
    out.append(Check(criterion, f"box/{a.plant}/arc(theta_hat {a.theta_hat_at})", a.spectral_radius, 1.0, a.stable,
                     f"largest spectral radius {a.spectral_radius:.4f} of {a.loops} loops with theta_hat anywhere "
                     f"the projection allows ({'stable' if a.stable else 'UNSTABLE'})"))
    return out

