"""The ARC over the whole Assumption-1 box: certify it, or narrow a defaulted payload range first.

``tune`` holds its search to :class:`commission.robustness.BoxArcCheck` (the margin floors at every
box plant with theta_hat at that plant's theta; stability with theta_hat anywhere the projection
allows, with one more sample of delay too: :func:`commission.tune.constraints.box_violation`).  Before
the search (:func:`narrow_default_payload`, called by :func:`commission.tune.resolve_spec`):

* the payload range was **defaulted** (``bounds.payload_defaulted`` of ident.json: the user did
  not say what the axis carries) and the search's start points hold the box check on no box
  that wide: the box's heavy end is narrowed to the largest payload one of them holds
  (:func:`commission.robustness.certified_payload`, bisection), so that the search starts
  feasible.  The robust gains scale with the box's heaviest mass (alpha_1s = -(K1/theta1_min) z1),
  so the box is narrowed before the gains are designed, not after (narrowing the projection of
  tuned gains changes the controller that was tuned).  tuning.json and controller.json state the
  range under ``validity``, the report's first lines say so, and ``validate`` tests the narrowed box.
  A user who stated no payload gets a controller with its stated range of validity, not a refusal;
* the payload range was **given** (or ident.json predates the record): nothing is narrowed; gains
  that do not hold the box are refused by ``validate``'s gate, naming the corner
  (:func:`commission.gate.box_checks`).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Sequence

from commission.artifacts import Identification
from commission.controllers.arc import ArcGains
from commission.robustness import (BoxArcCheck, BoxRobustness, MarginFloors, certified_payload, floor_violations,
                                   narrowed_ident, payload_box)
from commission.spec import Spec
from commission.tuning import Guarantee
from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings


def start_gains(ident: Identification, spec: Spec, settings: TuneSettings = DEFAULT_SETTINGS) -> list[ArcGains]:
    """The search's start points on ``ident``'s box (:func:`commission.tune.optimiser.search`'s first generation)."""
    from commission.tune.gains import apply_free, base_arc_gains, paper_implementable_start
    base = base_arc_gains(ident, spec)
    return [apply_free(base, x) for x in (settings.free_start, paper_implementable_start(settings),
                                          *settings.extra_starts)]


def narrow_default_payload(ident: Identification, spec: Spec,
                           settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[Identification, tuple[str, ...]]:
    """Narrow a *defaulted* payload range to the largest the search's start points certify (module docstring).

    Returns
    -------
    ident : Identification
        With the narrowed box and ``bounds.payload_narrowed_by_tune`` (the same object when nothing changed).
    notes : tuple of str
        One line when the box was narrowed.
    """
    pb = payload_box(ident)
    if pb is None or not pb[3] or ident.theta is None:
        return ident, ()
    floors = MarginFloors.from_spec(spec)
    full = BoxArcCheck(ident, spec, delay_any_estimate=True)
    starts = start_gains(ident, spec, settings)
    checks = [full(g) for g in starts]
    if any(r.holds(floors) for r in checks):
        return ident, ()
    got = certified_payload(lambda idn: start_gains(idn, spec, settings), ident, spec, floors, delay_any_estimate=True)
    if got is None:
        return ident, ()  # not even the empty axis: the search and the gate decide, naming the corner
    payload, _ = got
    pmin, pmax, m0, _ = pb
    first = checks[0]
    w = first.worst_at_plant(floors)
    miss = floor_violations(w.margins, floors)
    a = first.any_estimate
    unit = mass_unit(ident)
    why = (f"over the payload range {pmin:.4g}..{pmax:.4g} {unit} the search's start gains "
           + (f"miss the floors at corner {w.plant} with theta_hat at the plant's theta ({'; '.join(miss)})"
              if miss else "keep the floors with theta_hat at each plant's theta")
           + (f" and are UNSTABLE with theta_hat at {a.theta_hat_at} on {a.plant} (spectral radius "
              f"{a.spectral_radius:.4g})" if not a.stable else ""))
    return _narrowed(ident, payload, why)


def as_identified_box(ident: Identification, why: str) -> tuple[Identification, tuple[str, ...]] | None:
    """``ident`` with its *defaulted* payload range cut to none: the axis as identified (``run``'s second try).

    ``commission run`` tunes and validates on the default box first (up to 3 M of payload, narrowed
    where the start gains or the drive cannot hold it).  An ARC robust over a 4:1 mass range pays
    for it at the identified mass, where the PID yardstick is tuned and judged: the payload's heavy
    end bounds the robust gains (alpha_1s = -(K1/theta1_min) z1) and the margin floors at the heavy
    corner bound the integral action.  When that box is not certified, ``run`` tries once more on
    the axis as identified -- the box of the identification's spread and model margin alone, where
    the yardstick is designed -- and states it as the range of validity
    (``bounds.payload_narrowed_by_tune``, :func:`validity_of`).  Zero payload is no guess: it is
    what the log measured.  A bisection between the two ends would cost a full tune and
    validation per step.

    Parameters
    ----------
    ident : Identification
        As ident.json holds it (before tune's own narrowings, which :func:`resolve_spec` redoes).
    why : str
        Why the default box was not certified (the first try's verdict), for the record and the note.

    Returns
    -------
    (ident, notes) or None
        None when the payload range was stated, or is already none.
    """
    pb = payload_box(ident)
    if pb is None or not pb[3] or ident.theta is None or not pb[1] > pb[0]:
        return None
    return _narrowed(ident, pb[0], why)


def _narrowed(ident: Identification, payload: float, why: str) -> tuple[Identification, tuple[str, ...]]:
    """``ident`` with its defaulted payload range cut to ``payload``, the narrowing recorded, and its note.

    The record (``bounds.payload_narrowed_by_tune``) keeps the *default* box, so that ``validate``
    can undo every narrowing at once: a second narrowing (the drive's, then the box check's) keeps
    the first record's default and joins the reasons.
    """
    pmin, pmax, m0, _ = payload_box(ident)  # type: ignore[misc]
    unit = mass_unit(ident)
    old = ident.extra["bounds"].get("payload_narrowed_by_tune")
    out = narrowed_ident(ident, payload)
    bounds = dict(out.extra["bounds"])
    if isinstance(old, dict):
        rec = {**old, "reason": f"{old['reason']}; then {why}"}
    else:
        rec = {"default_payload_range": [pmin, pmax], "default_mass_range": list(ident.extra["bounds"]["mass_range"]),
               "theta1_min": ident.theta.min[0], "theta2_min": ident.theta.min[1], "unit": unit, "reason": why}
    bounds["payload_narrowed_by_tune"] = rec
    extra = dict(out.extra)
    extra["bounds"] = bounds
    out = dataclasses.replace(out, extra=extra)
    d0, d1 = rec["default_payload_range"]
    moving = "inertia" if ident.units.get("q") == "rad" else "moving mass"
    note = (f"payload range narrowed to {pmin:.4g}..{payload:.4g} {unit} ({moving} up to {m0 + payload:.4g} {unit}) "
            f"from the default {d0:.4g}..{d1:.4g} {unit}: {why}; the controller is certified for that range "
            f"only (controller.json's validity); state the real payload with commission identify --payload-max")
    return out, (note,)


def fit_payload_to_drive(spec: Spec, ident: Identification, given: set[str], source: str = "spec (defaults)", *,
                         settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[Identification, tuple[str, ...]]:
    """Narrow a *defaulted* payload range to what the drive can move, instead of refusing the axis.

    :func:`commission.tune.defaults.default_envelope` refuses a box whose heaviest plant leaves the
    drive (``u_max``, with its headroom) less than the least envelope it will default to.  When the
    user stated no payload, the default range (up to 3 M) is the tool's guess, not the machine's
    requirement: the heavy end is cut, by bisection, to the largest payload the drive can move, and
    the narrowing is recorded and stated as :func:`narrow_default_payload`'s is.  A stated payload
    (or a box the drive cannot move even empty) is left for ``default_envelope`` to refuse, naming
    ``controller.u_max``.
    """
    from commission.errors import SpecError
    from commission.tune.defaults import default_envelope

    pb = payload_box(ident)
    if pb is None or not pb[3] or ident.theta is None:
        return ident, ()

    def moves(p: float) -> bool:
        try:
            default_envelope(spec, narrowed_ident(ident, p), given, source, settings=settings)
        except SpecError:
            return False
        return True

    pmin, pmax, _, _ = pb
    if moves(pmax) or not moves(pmin):
        return ident, ()
    lo, hi = pmin, pmax
    for _ in range(settings.drive_bisections):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if moves(mid) else (lo, mid)
    why = (f"the drive (controller.u_max = {spec.u_max:g} {ident.units.get('u', 'u-unit')}) cannot move the heavier "
           f"plants of the default box within its headroom")
    return _narrowed(ident, lo, why)


def fit_force_to_drive(spec: Spec, ident: Identification, given: set[str],
                       source: str = "spec (defaults)", *,
                       settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[Identification, tuple[str, ...]]:
    """Narrow a *defaulted* load-force range to what the drive can hold, instead of refusing the axis.

    :func:`commission.tune.defaults.fit_disturbance_to_drive` narrows a defaulted load-force bound
    (``10 max(fc, fs)``) to a fixed share of the drive's feedforward budget; when that share cannot
    even hold the Assumption-1 load step of the ``disturbance`` scenario (``|offset| + delta_d M``),
    it leaves the box, and :func:`commission.tune.defaults.default_envelope` used to refuse the axis
    ("controller.u_max ... too small for this theta box") although no one stated that load.  Here,
    when the bound was defaulted and the box (with :func:`fit_payload_to_drive`'s payload fit) still
    leaves the drive no default envelope, the force range is narrowed symmetrically about the
    identified constant force to the load step that validate applies (``delta_d M`` about it): the
    least a certificate may cover, and the most room left to the envelope (whose defaulted keys
    :func:`commission.tune.defaults.default_envelope` then fits to the drive).  The record and
    note are :func:`fit_disturbance_to_drive`'s (``bounds.narrowed_by_tune``: ``validate`` checks
    and undoes it for provenance), so the range of validity is stated in tuning.json and the report.

    A bound the user stated, an envelope set in full, a box already narrowed, or a drive that cannot
    hold even the load step is left alone: ``default_envelope`` then refuses, naming ``controller.u_max``
    and the term that does not fit.
    """
    from commission.controllers.plant import P_M, P_OFFSET
    from commission.errors import SpecError
    from commission.scenarios import force_range, identified_plant
    from commission.tune.defaults import _axis_units, default_envelope, narrowed_load_range

    bounds = ident.extra.get("bounds")
    if not (isinstance(bounds, dict) and bounds.get("disturbance_bound_defaulted") is True) \
            or "narrowed_by_tune" in bounds or {"v_max", "a_max"} <= given or ident.theta is None:
        return ident, ()

    def fits(idn: Identification) -> bool:
        idn2, _ = fit_payload_to_drive(spec, idn, given, source)
        try:
            default_envelope(spec, idn2, given, source, settings=settings)
        except SpecError:
            return False
        return True

    if fits(ident):
        return ident, ()
    p = identified_plant(ident)
    dn = -float(p[P_OFFSET])
    d_lo, d_hi = force_range(ident)
    r_min = max(float(ident.delta_d) * float(p[P_M]), 0.0)  # the load step of the disturbance scenario
    r_max = max(dn - d_lo, d_hi - dn)
    if not r_max > r_min:
        return ident, ()

    out = narrowed_load_range(ident, dn, r_min, spec.u_max)
    if not fits(out):
        return ident, ()
    u = ident.units.get("u", "u-unit")
    _, _, a_unit = _axis_units(ident.units)
    old_bound = bounds.get("disturbance_bound")
    was = f" ({old_bound:.3g} {u}, the default 10 max(fc, fs))" if isinstance(old_bound, (int, float)) else ""
    f_lo, f_hi = out.extra["bounds"]["narrowed_by_tune"]["narrowed_force_range"]
    note = (f"theta3 box narrowed from [{ident.theta.min[2]:.4g}, {ident.theta.max[2]:.4g}] to "
            f"[{out.theta.min[2]:.4g}, {out.theta.max[2]:.4g}] {a_unit} (constant load force {f_lo:.3g}..{f_hi:.3g} "
            f"{u}, from {d_lo:.3g}..{d_hi:.3g} {u}): the defaulted load-force bound{was} with friction leaves "
            f"controller.u_max = {spec.u_max:g} {u} no default envelope on the most demanding plant; the controller "
            f"is certified for that load range only.  State the real load with commission identify "
            f"--disturbance-bound")
    return out, (note,)


def mass_unit(ident: Identification) -> str:
    """The mass unit of the axis: u-unit·s²/m (or /rad)."""
    u = ident.units.get("u", "u-unit")
    return f"{u}·s²/{'rad' if ident.units.get('q', 'm') == 'rad' else 'm'}"


def validity_of(ident: Identification) -> dict[str, Any] | None:
    """tuning.json's and controller.json's ``validity`` when the payload was narrowed (else None)."""
    b = ident.extra.get("bounds")
    rec = b.get("payload_narrowed_by_tune") if isinstance(b, dict) else None
    if not isinstance(rec, dict):
        return None
    return {"payload_range": list(b["payload_range"]), "mass_range": list(b["mass_range"]), "unit": rec["unit"],
            "default_payload_range": list(rec["default_payload_range"]), "payload_defaulted": True,
            "reason": rec["reason"]}


def box_guarantees(box: BoxRobustness, spec: Spec, validity: dict[str, Any] | None) -> dict[str, Guarantee]:
    """tuning.json's guarantees over the box's plants (additive to :func:`commission.tune.guarantees.guarantees`)."""
    floors = MarginFloors.from_spec(spec)
    w = box.worst_at_plant(floors)
    miss = floor_violations(w.margins, floors)
    a = box.any_estimate
    where = "" if validity is None else (f" (the box narrowed to payloads up to {validity['payload_range'][1]:.4g} "
                                         f"{validity['unit']}, see validity)")
    return {
        "margins_over_box_at_plant_estimate": Guarantee(
            not miss, f"the ARC linearised with theta_hat at the plant's own theta (where adaptation goes) at each "
                      f"of the {len(box.at_plant)} plants of the box{where} (its 4 (theta1, theta2) corners x the "
                      f"identified mode and its variants x both ends of the load-force range, identified delay): "
                      f"worst {w.plant}, phase margin "
                      f"{w.margins.phase_margin_deg:.3g} deg, delay margin {w.margins.delay_margin_samples:.3g} samples, "
                      f"modulus margin {w.margins.modulus_margin:.3g}, spectral radius {w.margins.spectral_radius:.4g}"
                      + (f"; misses {'; '.join(miss)}" if miss else "; every [margins] floor met")),
        "stability_over_box_any_estimate": Guarantee(
            a.stable, f"the ARC with theta_hat frozen at each corner of the projection box, at theta_hat(0) and at "
                      f"the plant's theta, on every plant of the box{where} with the identified delay, and at "
                      f"theta_hat(0) and the plant's theta with one more sample ({a.loops} loops): largest spectral radius {a.spectral_radius:.4g} on {a.plant} with "
                      f"theta_hat at {a.theta_hat_at} ({'< 1: stable' if a.stable else '>= 1: UNSTABLE'})"),
    }


__all__ = ["as_identified_box", "box_guarantees", "fit_force_to_drive", "mass_unit", "narrow_default_payload", "start_gains", "validity_of"]
