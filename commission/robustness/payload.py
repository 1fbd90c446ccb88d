"""The payload range of ident.json's box: which scenarios it makes PERFORMANCE scenarios
(:func:`identified_performance`), the box narrowed to a smaller payload (:func:`narrowed_ident`)
and the largest payload the box check holds over (:func:`certified_payload`).
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Sequence

from commission.artifacts import Identification
from commission.controllers.arc import ArcGains
from commission.robustness.box import BOX_DELAY_ANY_ESTIMATE, BoxArcCheck, BoxRobustness
from commission.robustness.margins import MarginFloors
from commission.spec import Spec


def identified_performance(names: Sequence[str], ident: Identification) -> frozenset[str]:
    """The PERFORMANCE scenarios among ``names`` for this identification (:func:`commission.gate.performance_scenarios`).

    The payload range counts as stated unless ident.json records it as defaulted
    (``bounds.payload_defaulted``, :func:`payload_box`), the load-force bound unless
    ``bounds.disturbance_bound_defaulted`` is true.  validate's gate asks it; tune's search does not:
    its gate constraint holds the absolute error limits on every tuning scenario, the strict reading
    (:func:`commission.tune.objective.gate_excess`; holding them only here was measured and not kept,
    docs/robustness.md, "Where the search starts" and "Tune's gate where validate's holds").
    """
    from commission.gate import performance_scenarios

    pb = payload_box(ident)
    bounds = ident.extra.get("bounds")
    dist_defaulted = isinstance(bounds, dict) and bounds.get("disturbance_bound_defaulted") is True
    return performance_scenarios(list(names), payload_stated=pb is None or not pb[3],
                                 disturbance_stated=not dist_defaulted)


def payload_box(ident: Identification) -> tuple[float, float, float, bool] | None:
    """``(payload_min, payload_max, heaviest mass without payload, defaulted)`` from ident.json's ``bounds``.

    None when ident.json does not record the payload range (written before ``bounds.payload_range``):
    such a box is treated as one the user stated (never narrowed).  Masses in u-unit s^2/m.
    """
    b = ident.extra.get("bounds")
    if not isinstance(b, dict) or not isinstance(b.get("payload_range"), list) or "mass_range" not in b:
        return None
    pmin, pmax = (float(x) for x in b["payload_range"])
    m_hi = 1.0 / ident.theta.min[0]
    return pmin, pmax, m_hi - pmax, bool(b.get("payload_defaulted", False))


def narrowed_theta_min(ident: Identification, m_hi: float) -> tuple[float, float, float]:
    """The box's lower end with the heaviest mass ``m_hi`` (u-unit s^2/m): theta1 = 1/M, theta2 = B_min/M."""
    b_lo = float(ident.extra["bounds"]["viscous_range"][0])
    return (1.0 / m_hi, max(b_lo / m_hi, 0.0), ident.theta.min[2])


def narrowed_ident(ident: Identification, payload_max: float) -> Identification:
    """``ident`` with its box's heavy end at ``payload_max`` (u-unit s^2/m) of payload (:func:`payload_box`).

    theta1_min = 1/M_hi and theta2_min = B_min/M_hi follow the heaviest mass; the other ends stay.
    ``bounds.mass_range`` and ``bounds.payload_range`` record the narrowed ranges.
    """
    pb = payload_box(ident)
    if pb is None:
        raise ValueError("narrowed_ident: ident.json records no payload range (bounds.payload_range)")
    pmin, _, m0, _ = pb
    th = narrowed_theta_min(ident, m0 + payload_max)
    bounds = dict(ident.extra["bounds"])
    bounds["mass_range"] = [float(bounds["mass_range"][0]), m0 + payload_max]
    bounds["payload_range"] = [pmin, float(payload_max)]
    extra = dict(ident.extra)
    extra["bounds"] = bounds
    return dataclasses.replace(ident, theta=dataclasses.replace(ident.theta, min=th), extra=extra)


#: Bisection steps of :func:`certified_payload` (the payload range to 2^-10 of the default's).
PAYLOAD_BISECTIONS = 10


def certified_payload(gains_for: Callable[[Identification], Sequence[ArcGains]], ident: Identification,
                      spec: Spec, floors: MarginFloors,
                      delay_any_estimate: bool = BOX_DELAY_ANY_ESTIMATE) -> tuple[float, BoxRobustness] | None:
    """The largest payload over which one of ``gains_for(box)`` holds the box check, by bisection.

    ``gains_for`` designs gain sets for a (narrowed) identification -- ``tune`` passes its search's
    start points, which are built on the box (the robust gains scale with its heaviest mass), so
    a box they hold is one the search starts feasible in.  The heavy end ``M_hi0 + payload``
    (:func:`payload_box`) shrinks until (a) and (b) of :class:`BoxArcCheck` hold for one of them; the
    other ends of the box stay.  The bisection assumes that a smaller payload range holds if a
    larger one does (the loops that fail are the heaviest plant's, and the light plant's with
    theta_hat at the heavy end: both ease as the range shrinks) and checks the range it returns.
    ``delay_any_estimate``: the check's (b) with one more sample of delay at every estimate.

    Returns
    -------
    (payload_max, box) or None
        u-unit s^2/m and the check on the narrowed box; None when the box fails even at the least
        payload (or ident.json does not record the payload range).
    """
    pb = payload_box(ident)
    if pb is None:
        return None
    pmin, pmax, _, _ = pb

    def check(p: float) -> BoxRobustness | None:
        idn = narrowed_ident(ident, p)
        chk = BoxArcCheck(idn, spec, delay_any_estimate=delay_any_estimate)
        for g in gains_for(idn):
            if chk.holds(g, floors):  # stops at the first failing loop; the whole check for the one that holds
                return chk(g)
        return None

    best = check(pmin)
    if best is None:
        return None
    lo, hi = pmin, pmax
    for _ in range(PAYLOAD_BISECTIONS):
        mid = 0.5 * (lo + hi)
        r = check(mid)
        if r is not None:
            lo, best = mid, r
        else:
            hi = mid
    return lo, best
