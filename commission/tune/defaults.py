"""Spec defaulting against the identified axis, before any simulation.

The tuning spec's defaults are the paper's; here they are fitted to this axis: the
envelope to the sample rate (:func:`rate_scaled_envelope`) and to what the drive can
move on the heaviest plant of the box (:class:`DriveNeed`, :func:`default_envelope`),
a defaulted load-force bound that leaves the drive no room is narrowed
(:func:`fit_disturbance_to_drive`), and a given spec is checked against the axis
(:func:`check_spec_against_ident`).  Every change is returned as a note for the user.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Mapping

from commission.artifacts import Identification
from commission.controllers.plant import P_B, P_FC, P_FS, P_M, P_OFFSET, P_RIPPLE_AMP
from commission.errors import SpecError
from commission.gate import GateLimits, GateSpec, resolve_gate
from commission.scenarios import (
    CASE1_SPEED_FRACTION,
    FRICTION_SCALE,
    force_range,
    identified_plant,
    resolve_quantization,
    theta3_range_for_forces,
    viscous_range,
)
from commission.spec import Spec
from commission.units import unit
from commission.tune.settings import DEFAULT_SETTINGS, PAPER_RATE, TuneSettings


def _axis_units(units: Mapping[str, str] | None) -> tuple[str, str, str]:
    """Position, velocity and acceleration units of the refusals and notes here: ``("m", "m/s", "m/s^2")``.

    From the identification's ``units`` (:func:`commission.units.unit`; without them, the
    axis of :func:`commission.units.axis_units_context`, default m), so a rotary axis reads
    rad, rad/s and rad/s^2.  The square is written ``^2``, as these messages always have:
    they are one plain-text line that users and scripts search for the values to set.
    """
    q, v, a = (unit(k, units) for k in ("q", "v", "a"))
    return q, v, a.replace("²", "^2")


@dataclass(frozen=True)
class DriveNeed:
    """Feedforward input the most demanding plant of the validation matrix needs, u-unit.

    ``need(v, a, beta1) = mass max(a, a1) + viscous v + const`` bounds the |u| needed
    along the envelope (v_max ``v`` m/s, a_max ``a`` m/s^2) by any plant of
    :mod:`commission.scenarios`: the heaviest mass of the box, the largest viscous
    coefficient (:func:`~commission.scenarios.viscous_range` or the +20 % friction
    scenario), the +20 % friction level plus the ripple, and the largest constant
    force (:func:`~commission.scenarios.force_range`, or the identified offset plus
    the delta_d-sized disturbance step).  ``a1 = beta1 CASE1_SPEED_FRACTION v`` is Case 1's
    start-up acceleration: filter (58) starts at rest under a moving reference.

    Attributes
    ----------
    mass : float
        1/theta1_min, u-unit s^2/m.
    viscous : float
        u-unit s/m.
    const : float
        Friction level, ripple and constant force, u-unit.
    """

    mass: float
    viscous: float
    const: float

    def need(self, v: float, a: float, beta1: float) -> float:
        """|u| needed for v_max ``v`` (m/s), a_max ``a`` (m/s^2), filter (58) ``beta1`` (1/s), u-unit."""
        return self.mass * max(a, beta1 * CASE1_SPEED_FRACTION * v) + self.viscous * v + self.const

    def a_max(self, u: float, v: float) -> float:
        """Largest a_max (m/s^2) with ``mass a + viscous v + const <= u``; <= 0 when none."""
        return (u - self.viscous * v - self.const) / self.mass

    def v_max(self, u: float, beta1: float) -> float:
        """Largest v_max (m/s) whose Case-1 start-up and viscous terms fit in ``u``; <= 0 when none."""
        return (u - self.const) / (self.mass * beta1 * CASE1_SPEED_FRACTION + self.viscous)


def forces_at_rest(ident: Identification) -> tuple[float, float, float]:
    """``(friction, ripple, load step)`` the drive holds at rest on the identified plant, u-unit.

    Friction is the larger of fc and fs with the scenarios' +20 % (``friction_high``); the load
    step is the ``disturbance`` scenario's, ``|offset| + delta_d M``.  :func:`drive_need` adds the
    box's constant load force where it exceeds that step; the refusals name each term.
    """
    p = identified_plant(ident)
    return ((1.0 + FRICTION_SCALE) * max(p[P_FC], p[P_FS]), float(p[P_RIPPLE_AMP]),
            abs(p[P_OFFSET]) + ident.delta_d * p[P_M])


def drive_need(ident: Identification) -> DriveNeed:
    """The :class:`DriveNeed` of an identification's scenario matrix."""
    p = identified_plant(ident)
    friction, ripple, step = forces_at_rest(ident)
    d_lo, d_hi = force_range(ident)
    force = max(abs(d_lo), abs(d_hi), step)
    return DriveNeed(mass=1.0 / ident.theta.min[0],
                     viscous=max(viscous_range(ident)[1], (1.0 + FRICTION_SCALE) * p[P_B]),
                     const=friction + ripple + force)


def check_spec_against_ident(spec: Spec, ident: Identification, source: str = "spec.toml", *,
                             settings: TuneSettings = DEFAULT_SETTINGS) -> None:
    """Reject a spec whose input limit cannot drive the envelope on the most demanding plant of the box.

    Needed |u| (u-unit): :meth:`DriveNeed.need` at (v_max, a_max) (:func:`drive_need`).
    Raises :class:`SpecError` naming ``controller.u_max`` and ``trajectory.a_max`` (with the
    largest a_max the limit allows), or ``controller.theta1_0`` outside the box.
    """
    if spec.theta1_0 is not None and not ident.theta.min[0] <= spec.theta1_0 <= ident.theta.max[0]:
        raise SpecError(
            f"{source}: controller.theta1_0 = {spec.theta1_0:g} lies outside the identified theta1 box "
            f"[{ident.theta.min[0]:.4g}, {ident.theta.max[0]:.4g}]")
    d = drive_need(ident)
    u = ident.units.get("u", "u-unit")
    _, v_unit, a_unit = _axis_units(ident.units)
    check_moves_against_drive(spec, ident, source, settings=settings)
    vc, ac = spec.case_v_max, spec.case_a_max
    ref = spec.reference_v_max is not None or spec.reference_a_max is not None
    kv, ka = ("trajectory.reference_v_max", "trajectory.reference_a_max") if ref else ("trajectory.v_max",
                                                                                      "trajectory.a_max")
    need = d.need(vc, ac, spec.beta1)
    if need > spec.u_max:
        # Remedies in order: a smaller envelope (values that pass when followed: Case 1's start-up
        # acceleration counts), a narrower box, and only then a larger drive.
        a_ok = d.a_max(spec.u_max, vc)
        a1 = spec.beta1 * CASE1_SPEED_FRACTION * vc
        v_ok = d.v_max(spec.u_max, spec.beta1)
        if a_ok > 0 and a_ok >= a1:
            hint = f"set {ka} <= {_floor3(a_ok):.3g} {a_unit} at this v_max"
        elif v_ok > 0:
            v_fix = _floor3(v_ok)
            hint = (f"Case 1's start-up alone needs {a1:.3g} {a_unit} at this v_max, so no a_max fits; set "
                    f"{kv} <= {v_fix:.3g} {v_unit} with {ka} <= "
                    f"{_floor3(d.a_max(spec.u_max, v_fix)):.3g} {a_unit}")
        else:
            hint = f"no envelope fits: even at rest the plant needs {d.const:.3g} {u}"
        raise SpecError(
            f"{source}: controller.u_max = {spec.u_max:g} {u} is below the {need:.3g} {u} needed for "
            f"{ka} = {ac:g} {a_unit} and {kv.split('.')[1]} = {vc:g} {v_unit} on the most demanding "
            f"plant of the theta box (M = {d.mass:.3g}, B = {d.viscous:.3g}); {hint}; else narrow the box "
            f"(commission identify --payload-max, --disturbance-bound); raise controller.u_max only if the "
            f"drive really has it")


def check_moves_against_drive(spec: Spec, ident: Identification, source: str = "spec.toml", *,
                              settings: TuneSettings = DEFAULT_SETTINGS) -> None:
    """Refuse the machine's moves (``spec.profile``) when the drive cannot make them on the worst plant.

    The need is ``max_k (mass |a_k| + viscous |v_k|) + const`` along the profile sampled at the
    controller's period (mass, viscous and const of :class:`DriveNeed`: the heaviest mass of the
    box, the largest viscous coefficient, friction +20 %, ripple and the largest constant force),
    the forces of the ``user/payload_heavy``, ``user/friction_high`` and ``user/disturbance``
    scenarios at once.  No Case-1 start-up counts here: the profile starts at rest on its own
    limits.  The refusal names each term with its figures, then values that would pass: the
    acceleration of the moves, and the load-force bound of ``commission identify`` when the
    box's constant force is what does not fit, both sized so that the worst plant's feedforward
    takes at most ``settings.drive_headroom`` x u_max (the rest is the feedback's: a command that
    reaches u_max fails validate's gate).
    """
    p = spec.profile
    if p is None:
        return
    d = drive_need(ident)
    u = ident.units.get("u", "u-unit")
    _, v_unit, a_unit = _axis_units(ident.units)
    dyn, v, a = p.drive_demand(d.mass, d.viscous, spec.period)
    need = dyn + d.const
    if need <= spec.u_max:
        return
    friction, ripple, step = forces_at_rest(ident)
    force = d.const - friction - ripple
    hints = []
    budget = settings.drive_headroom * spec.u_max
    a_ok = (budget - d.viscous * p.v_peak - d.const) / d.mass
    if a_ok > 0:
        hints.append(f"moves with a_max <= {_floor3(a_ok):.3g} {a_unit} at their peak speed {p.v_peak:.3g} {v_unit}")
    bounds = ident.extra.get("bounds")
    bound = bounds.get("disturbance_bound") if isinstance(bounds, dict) else None
    d_lo, d_hi = force_range(ident)
    if isinstance(bound, (int, float)) and max(abs(d_lo), abs(d_hi)) > step:
        excess = need - budget
        d_ok = bound - excess
        if d_ok > 0 and max(abs(d_lo), abs(d_hi)) - excess >= step:
            dflt = ", the default 10 max(fc, fs)" if bounds.get("disturbance_bound_defaulted") else ""
            hints.append(f"a load-force bound commission identify --disturbance-bound {_floor3(d_ok):.3g} ({u}; now "
                         f"{bound:.4g} {u}{dflt}) if the real load is that small")
    hint = (" or ".join(hints) + f" would leave the feedback {1 - settings.drive_headroom:.0%} of u_max"
            if hints else f"no move fits: even at rest the plant needs {d.const:.4g} {u}")
    raise SpecError(
        f"{source}: controller.u_max = {spec.u_max:g} {u} is below the {need:.4g} {u} that {p.label} need on the "
        f"most demanding plant of the theta box (scenarios user/payload_heavy, user/friction_high, user/disturbance): "
        f"M a = {d.mass:.4g} x {a:.4g} {a_unit} = {d.mass * a:.4g} {u}, B v = {d.viscous:.4g} x {v:.4g} {v_unit} = "
        f"{d.viscous * v:.4g} {u}, friction +20 % {friction:.4g} {u}, ripple {ripple:.4g} {u} and the box's largest "
        f"constant load force {force:.4g} {u}; {hint}; else narrow the box (commission identify --payload-max, "
        f"--disturbance-bound); raise controller.u_max only if the drive really has it")


def _floor3(x: float) -> float:
    """``x`` > 0 rounded down to 3 significant digits, so that the printed value still fits."""
    step = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.floor(x * (1 - 1e-12) / step) * step


def _ceil3(x: float) -> float:
    """``x`` > 0 rounded up to 3 significant digits, so that the printed value is enough."""
    step = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.ceil(x * (1 - 1e-12) / step) * step


def fit_disturbance_to_drive(spec: Spec, ident: Identification, given: set[str], *,
                             settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[Identification, tuple[str, ...]]:
    """Narrow the theta3 box of a *defaulted* load-force bound to what the drive can reject.

    ``commission identify`` bounds the load force by ``10 max(fc, fs)`` when the user does not
    say (``--disturbance-bound``): the paper's box allows about eleven times its stiction.  On a
    heavy axis with high friction that default alone can exceed the drive (10 x 1.1 V of
    stiction on a 10 V rail): no controller rejects a load the motor cannot push, and the
    spec used to be refused.  When the bound was defaulted (``bounds.disturbance_bound_defaulted``
    in ident.json) and even the smallest default envelope (``settings.min_default_v_max``,
    ``settings.min_default_a_max``) does not fit in the feedforward budget
    ``settings.drive_headroom x u_max``
    on the most demanding plant, the force range is narrowed symmetrically about the identified
    offset force until friction, ripple and constant force take ``settings.disturbance_share`` of the
    budget; the rest is left to the envelope (:func:`default_envelope`).  theta3's bounds
    follow over the box's masses (:func:`commission.scenarios.theta3_range_for_forces`, the inverse
    of :func:`commission.scenarios.force_range`), so that they hold the identified force at every
    mass whatever its sign and size (a constant load larger than the narrowed reach included).

    A bound the user gave, an envelope the user set in full, or an ident.json written before
    the flag existed is never narrowed; :func:`default_envelope` and
    :func:`check_spec_against_ident` then decide as before.  The narrowed box is what ``tune``
    designs for and ``validate`` tests (it is stored in tuning.json's identification, with
    ``bounds.narrowed_by_tune``); a note says so.

    Returns
    -------
    ident : Identification
        With the narrowed theta3 box (the same object when nothing changed).
    notes : tuple of str
        One line when the box was narrowed.
    """
    bounds = ident.extra.get("bounds")
    if not (isinstance(bounds, dict) and bounds.get("disturbance_bound_defaulted") is True):
        return ident, ()
    if {"v_max", "a_max"} <= given:
        return ident, ()
    budget = settings.drive_headroom * spec.u_max
    d = drive_need(ident)
    v_min = min(spec.v_max, settings.min_default_v_max)
    a_min = min(spec.a_max, settings.min_default_a_max)
    if d.need(v_min, a_min, spec.beta1) <= budget:
        return ident, ()
    p = identified_plant(ident)
    d_lo, d_hi = force_range(ident)
    step = forces_at_rest(ident)[2]
    force = max(abs(d_lo), abs(d_hi), step)
    fixed = d.const - force  # friction (+20 %) and ripple
    allowed = settings.disturbance_share * budget - fixed  # largest |constant force| left for the box
    dn = -p[P_OFFSET]
    reach = allowed - abs(dn)  # half-width of the narrowed force range about d_n
    if not (reach > 0 and allowed >= step and max(abs(d_lo), abs(d_hi)) > allowed):
        return ident, ()  # friction alone is too much: default_envelope refuses, naming u_max
    out = narrowed_load_range(ident, dn, reach, spec.u_max)
    lo, hi = out.theta.min[2], out.theta.max[2]
    f_lo, f_hi = out.extra["bounds"]["narrowed_by_tune"]["narrowed_force_range"]
    u = ident.units.get("u", "u-unit")
    old_bound = bounds.get("disturbance_bound")
    was = f" ({old_bound:.3g} {u}, the default 10 max(fc, fs))" if isinstance(old_bound, (int, float)) else ""
    _, v_unit, a_unit = _axis_units(ident.units)  # theta3 is in q/s², as the acceleration
    note = (f"theta3 box narrowed from [{ident.theta.min[2]:.4g}, {ident.theta.max[2]:.4g}] to [{lo:.4g}, {hi:.4g}] "
            f"{a_unit} (constant load force {f_lo:.3g}..{f_hi:.3g} {u}): the defaulted load-force "
            f"bound{was} leaves controller.u_max = {spec.u_max:g} {u} no room for even v_max = {v_min:g} {v_unit}, "
            f"a_max = {a_min:g} {a_unit} on the most demanding plant; it now takes {settings.disturbance_share:g} "
            f"of the "
            f"{budget:.3g} {u} feedforward budget.  State the real load with commission identify "
            f"--disturbance-bound")
    return out, (note,)


def narrowed_load_range(ident: Identification, dn: float, reach: float, u_max: float) -> Identification:
    """``ident`` with its defaulted load-force range narrowed to ``dn +- reach`` (u-unit), recorded.

    theta3's bounds follow over the box's masses (:func:`commission.scenarios.theta3_range_for_forces`),
    so they hold the identified theta3 whatever the sign and size of the load; ``bounds.narrowed_by_tune``
    keeps the box it started from and the force range the narrowed box admits at every mass
    (:func:`commission.scenarios.force_range`), which validate's provenance check reads back.  Shared by
    :func:`fit_disturbance_to_drive` and :func:`commission.tune.box.fit_force_to_drive`.
    """
    lo, hi = theta3_range_for_forces(ident, dn - reach, dn + reach)
    out = dataclasses.replace(ident, theta=dataclasses.replace(
        ident.theta, min=(*ident.theta.min[:2], lo), max=(*ident.theta.max[:2], hi)))
    bounds = dict(ident.extra["bounds"])
    bounds["narrowed_by_tune"] = {"theta3_min": ident.theta.min[2], "theta3_max": ident.theta.max[2],
                                  "force_range": list(force_range(ident)), "narrowed_force_range": list(force_range(out)),
                                  "u_max": u_max}
    return dataclasses.replace(out, extra={**ident.extra, "bounds": bounds})


def rate_scaled_envelope(spec: Spec, given: set[str],
                         units: Mapping[str, str] | None = None) -> tuple[Spec, tuple[str, ...]]:
    """Scale a *defaulted* envelope to a sample rate below the paper's 2.5 kHz.

    The defaults (1 m/s, 12 m/s^2) are the paper's envelope at its 2.5 kHz.  Every loop
    gain that can be implemented scales with the rate r = f_s / 2.5 kHz (observer poles,
    caps, the PID's poles), so the tracking error of a given trajectory grows as 1/r^2
    for the acceleration-driven part and 1/r for the velocity-driven part.  Below 2.5 kHz a
    defaulted a_max is therefore scaled by r^2 and v_max by r, which keeps the demand
    relative to the loop's bandwidth at the paper's (1 kHz: 0.4 m/s, 1.92 m/s^2); without it,
    slow axes miss the default gate's e_rms limit on their heavy plants (docs/robustness.md,
    "Tune's defaults, measured").
    Keys the user set are kept; at or above 2.5 kHz nothing changes.  ``units`` (the
    identification's) only words the notes: rad/s on a rotary axis; default m.
    """
    r = spec.sample_rate / PAPER_RATE
    if r >= 1.0:
        return spec, ()
    v = spec.v_max if "v_max" in given else spec.v_max * r
    a = spec.a_max if "a_max" in given else spec.a_max * r * r
    return dataclasses.replace(spec, v_max=v, a_max=a), _envelope_notes(
        spec, v, a, f"the sample rate {spec.sample_rate:g} Hz is {r:.3g} x the paper's {PAPER_RATE:g} Hz "
                    f"(the envelope scales as r for v_max, r^2 for a_max)", units)


def _envelope_notes(spec: Spec, v: float, a: float, why: str,
                    units: Mapping[str, str] | None = None) -> tuple[str, ...]:
    """One note per envelope key that (v, a) changes from ``spec``'s, in the axis's ``units``."""
    _, v_unit, a_unit = _axis_units(units)
    return tuple(f"trajectory.{k} defaulted to {new:.3g} {un} instead of {old:g}: {why}"
                 for k, old, new, un in (("v_max", spec.v_max, v, v_unit), ("a_max", spec.a_max, a, a_unit))
                 if new != old)


def default_envelope(spec: Spec, ident: Identification, given: set[str], source: str = "spec (defaults)", *,
                     settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[Spec, tuple[str, ...]]:
    """Lower the *defaulted* envelope (v_max, a_max) to what the drive can move on the worst plant.

    The paper's 1 m/s and 12 m/s^2 ask a heavy axis (with its payload bound) for more
    than a +-10 V drive gives.  A key the user set (``given`` holds ``"v_max"``,
    ``"a_max"``) is never changed: :func:`check_spec_against_ident` then accepts or
    rejects it.  Defaulted keys are lowered so that the worst plant's feedforward
    (:func:`drive_need`) uses at most ``settings.drive_headroom`` x u_max: a_max first; v_max
    too when the viscous term alone would take more than half of that budget or v_max
    could not be reached within ``travel``.

    Returns
    -------
    spec : Spec
        With the lowered envelope (the same object when nothing changed).
    notes : tuple of str
        One line per lowered key, for the user.

    Raises
    ------
    SpecError
        Naming ``controller.u_max`` when the limit cannot even hold the worst plant's
        friction and forces with the headroom.
    """
    d = drive_need(ident)
    budget = settings.drive_headroom * spec.u_max
    if d.need(spec.v_max, spec.a_max, spec.beta1) <= budget or {"v_max", "a_max"} <= given:
        return spec, ()
    free = budget - d.const
    u = ident.units.get("u", "u-unit")
    q_unit, v_unit, a_unit = _axis_units(ident.units)
    if free <= 0:
        raise _drive_too_small(spec, ident, d, source, settings)
    v, a = spec.v_max, spec.a_max
    if "v_max" not in given:
        v = min(v, d.v_max(budget, spec.beta1))
        if d.viscous * v > 0.5 * free:
            v = 0.5 * free / d.viscous
    if "a_max" not in given:
        a = min(a, d.a_max(budget, v))
        if "v_max" not in given and a > 0:
            v = min(v, math.sqrt(a * spec.travel))  # v_max reachable within the travel
    if not (a > 0 and v > 0):
        return spec, ()  # the set key cannot be met: check_spec_against_ident names it
    if (("v_max" not in given and v < settings.min_default_v_max)
            or ("a_max" not in given and a < settings.min_default_a_max)):
        raise _drive_too_small(spec, ident, d, source, settings)
    if v * v / a > spec.travel:
        raise SpecError(
            f"{source}: trajectory.v_max = {v:g} {v_unit} cannot be reached within trajectory.travel = "
            f"{spec.travel:g} {q_unit} at the a_max = {a:.3g} {a_unit} this drive allows on the most demanding plant "
            f"of the theta box (need v_max^2/a_max <= travel)")
    return dataclasses.replace(spec, v_max=v, a_max=a), _envelope_notes(
        spec, v, a, f"the most demanding plant of the theta box (M = {d.mass:.3g}, B = {d.viscous:.3g}) needs "
                    f"<= {settings.drive_headroom:g} x controller.u_max = {budget:.3g} {u} of feedforward", ident.units)


def _drive_too_small(spec: Spec, ident: Identification, d: DriveNeed, source: str,
                     settings: TuneSettings) -> SpecError:
    """:func:`default_envelope`'s refusal: the terms the drive cannot cover, with units, and what would.

    The most demanding plant's need at rest (friction +20 %, ripple, the largest constant load
    force and where that force comes from) and with the least envelope the tool defaults to; then
    what the least box the tool would certify needs -- a defaulted payload cut to none and a
    defaulted load-force bound cut to the load step the log shows (``|offset| + delta_d M``), as
    :mod:`commission.tune.box` tries before refusing --, the ``controller.u_max`` that would hold
    it, and only the changes that would fit: a lower stated load-force bound, a smaller stated
    payload, a slower envelope when the box's forces at rest fit (with the real load and payload
    stated when only the least box's do: an envelope set in full turns the tool's narrowing off); and
    when friction and the load step alone leave no room, ``delta_d``, the acceleration the
    identified model leaves unexplained, which a better log lowers.
    """
    from commission.robustness.payload import narrowed_ident, payload_box
    from commission.tune.box import mass_unit

    u = ident.units.get("u", "u-unit")
    _, v_unit, a_unit = _axis_units(ident.units)
    per = "rad" if ident.units.get("q", "m") == "rad" else "m"
    m_unit = mass_unit(ident).replace("²", "^2")  # plain text, as _axis_units
    p = identified_plant(ident)
    budget = settings.drive_headroom * spec.u_max
    v0 = min(spec.v_max, settings.min_default_v_max)
    a0 = min(spec.a_max, settings.min_default_a_max)
    need0 = d.need(v0, a0, spec.beta1)
    friction, ripple, step = forces_at_rest(ident)
    force = d.const - friction - ripple
    bounds = ident.extra.get("bounds") if isinstance(ident.extra.get("bounds"), dict) else {}
    bound = bounds.get("disturbance_bound")
    load_defaulted = bounds.get("disturbance_bound_defaulted") is True
    step_text = (f"|offset| {abs(p[P_OFFSET]):.3g} {u} + delta_d M = {ident.delta_d:.3g} {a_unit} x "
                 f"{p[P_M]:.3g} {m_unit}")
    if force > step * (1.0 + 1e-9):
        src = ("the default bound 10 max(fc, fs)" if load_defaulted
               else "the bound ident.json states, commission identify --disturbance-bound")
        load = (f"the box's largest constant load force {force:.3g} {u} ({src}; the load step the log shows is "
                f"{step_text})")
    else:
        load = f"the load step the log shows {force:.3g} {u} ({step_text})"
    at_rest = ", ".join([f"friction +20 % {friction:.3g} {u}", *([f"ripple {ripple:.3g} {u}"] if ripple > 0 else []),
                         load])
    pb = payload_box(ident)
    payload_cut = pb is not None and pb[3] and pb[1] > pb[0]
    light = drive_need(narrowed_ident(ident, pb[0])) if pb is not None and pb[1] > pb[0] else d
    least = DriveNeed(mass=light.mass if payload_cut else d.mass, viscous=light.viscous if payload_cut else d.viscous,
                      const=friction + ripple + (step if load_defaulted else force))
    need_least = least.need(v0, a0, spec.beta1)
    cut = [w for w, on in (("no payload", payload_cut), ("the load force cut to that load step", load_defaulted)) if on]
    least_text = (f"; even with {' and '.join(cut)}, as the tool tries before refusing, it needs {need_least:.3g} {u}"
                  if cut else "")
    ways = []
    if not load_defaulted and force > step and isinstance(bound, (int, float)):
        x = budget - (need0 - force)  # the largest load force that leaves the least envelope its room
        if x >= step and bound - (force - x) > 0:
            ways.append(f"a lower load-force bound, commission identify --disturbance-bound "
                        f"{_floor3(bound - (force - x)):.3g} ({u}; now {bound:.4g}) if the real load is that small")
    if pb is not None and not pb[3] and pb[1] > pb[0] and light.need(v0, a0, spec.beta1) <= budget:
        ways.append(f"a smaller payload, commission identify --payload-max (the axis with {pb[0]:.4g} {m_unit} of "
                    f"payload fits)")
    if friction + ripple + step >= budget:
        ways.append(f"a log the identified model explains better: friction and the load step the log shows alone "
                    f"take {friction + ripple + step:.3g} {u} of the {budget:.3g} {u}, and delta_d = "
                    f"{ident.delta_d:.3g} {a_unit} is the acceleration the model leaves unexplained (commission "
                    f"excite plans a run that measures the axis)")
    elif d.const < budget:
        ways.append("a slower envelope, trajectory.v_max and a_max in spec.toml")
    elif least.const < budget:  # an envelope set in full turns the tool's own narrowing off: state the box too
        stated = [f for f, on in (("--disturbance-bound", load_defaulted), ("--payload-max", payload_cut)) if on]
        ways.append(f"a slower envelope, trajectory.v_max and a_max in spec.toml, with the real load stated "
                    f"(commission identify {', '.join(stated)})")
    ways.append(f"controller.u_max >= {_ceil3(need_least / settings.drive_headroom):.3g} {u}, only if the drive "
                "really has it")
    return SpecError(
        f"{source}: controller.u_max = {spec.u_max:g} {u} is too small for this theta box: its most demanding "
        f"plant (M = {d.mass:.3g} {m_unit}, B = {d.viscous:.3g} {u}·s/{per}) needs {d.const:.3g} {u} at rest "
        f"({at_rest}) and {need0:.3g} {u} with the least envelope the tool defaults to (v_max = {v0:g} {v_unit}, "
        f"a_max = {a0:g} {a_unit}){least_text}, more than {settings.drive_headroom:g} x u_max = {budget:.3g} {u}; "
        f"what would fit: " + "; or ".join(ways))


def reference_envelope(spec: Spec, ident: Identification, given: set[str], source: str = "spec (defaults)", *,
                       settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[Spec, tuple[str, ...]]:
    """The envelope of the paper's Case 1 and Case 2 when the spec gives the machine's moves.

    With the machine's moves, the spec's envelope (``v_max``, ``a_max``, ``travel``: the runtime
    guard's speed and stroke, the gate's travel) is the moves' own (:mod:`commission.spec`), not
    a derivation from u_max.  Case 1 and Case 2 stay as the paper's reference scenarios, but at
    the moves' envelope Case 1's start-up (filter (58) at rest under a moving reference:
    beta1 x 0.2 v_max, a step of acceleration no S-curve of the machine makes) can ask more of
    the drive than any of its moves does, and would refuse moves the drive can make.  So their envelope
    (``reference_v_max``, ``reference_a_max``) is, unless given, what ``tune`` derives for a
    defaulted envelope (the paper's scaled to the rate, :func:`rate_scaled_envelope`, lowered to
    the drive's feedforward budget, :func:`default_envelope`), capped at the moves' peaks and
    at ``sqrt(a travel)``.  When even that derivation refuses (friction and forces take more than
    ``settings.drive_headroom`` x u_max) the cap is the whole of u_max instead.

    Parameters
    ----------
    given : set of str
        ``[trajectory]`` keys the user set (``reference_v_max``, ``reference_a_max`` are kept).

    Returns
    -------
    spec : Spec
        With ``reference_v_max``/``reference_a_max`` set (the same object without moves).
    notes : tuple of str
    """
    if spec.profile is None:
        return spec, ()
    keys = {"reference_v_max", "reference_a_max"}
    g = {k[len("reference_"):] for k in given & keys}
    paper = Spec()
    base = dataclasses.replace(
        spec, profile=None, reference_v_max=None, reference_a_max=None,
        v_max=spec.reference_v_max if "v_max" in g else paper.v_max,
        a_max=spec.reference_a_max if "a_max" in g else paper.a_max)
    base, _ = rate_scaled_envelope(base, g)
    try:
        base, _ = default_envelope(base, ident, g, source, settings=settings)
        v, a = base.v_max, base.a_max
    except SpecError:
        d = drive_need(ident)
        v = base.v_max if "v_max" in g else min(base.v_max, d.v_max(spec.u_max, spec.beta1))
        a = base.a_max if "a_max" in g else min(base.a_max, d.a_max(spec.u_max, v))
        if not (v > 0 and a > 0):
            raise
    if "a_max" not in g:
        a = min(a, spec.a_max)
    if "v_max" not in g:
        # Reachable within the travel, with a rounding margin so that tuning.json reloads (v^2/a <= travel).
        v = min(v, spec.v_max, math.sqrt(a * spec.travel) * (1.0 - 1e-12))
    out = dataclasses.replace(spec, reference_v_max=v, reference_a_max=a)
    u = ident.units.get("u", "u-unit")
    q_unit, v_unit, a_unit = _axis_units(ident.units)
    note = (f"the machine's moves set the envelope: trajectory.v_max = {spec.v_max:.4g} {v_unit}, a_max = "
            f"{spec.a_max:.4g} {a_unit}, travel = {spec.travel:.4g} {q_unit} (runtime guard and gate; "
            f"{spec.profile.describe(ident.units)}); the paper's Case 1 and Case 2 stay as reference scenarios at "
            f"trajectory.reference_v_max = {v:.3g} {v_unit}, reference_a_max = {a:.3g} {a_unit}"
            + ("" if g == {"v_max", "a_max"} else
               f" (derived for controller.u_max = {spec.u_max:g} {u} as for a defaulted envelope, capped at the "
               f"moves'; set them to choose)"))
    notes: tuple[str, ...] = (note,)
    if spec.profile.kind == "moves" and not any(math.isfinite(m.j_max) for m in spec.profile.moves):
        notes += ("the machine's moves have no j_max: their acceleration steps are validated as they are, and the "
                  "ARC's command peaks at each step; give [[trajectory.move]] j_max when the drive's trajectory "
                  "generator limits the jerk",)
    return out, notes


def default_gate_limits(ident: Identification, spec: Spec) -> GateLimits:
    """validate's default gate (an empty ``gate.toml``) resolved for this axis and spec."""
    return resolve_gate(GateSpec(), lsb=resolve_quantization(ident, spec), travel=spec.travel, u_max=spec.u_max,
                        targets=spec.targets)


def log_sample_rate(ident: Identification) -> float | None:
    """The excitation log's sample rate (Hz) if ident.json records one (``extra.source.sample_rate``)."""
    src = ident.extra.get("source")
    if isinstance(src, dict):
        v = src.get("sample_rate")
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0:
            return float(v)
    return None
