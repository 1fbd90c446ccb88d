"""The theta box as plants: the ranges of the viscous coefficient and of the load force the box
admits at every mass, clipping a plant into it, and the Monte-Carlo sample drawn from it."""

from __future__ import annotations

import numpy as np

from commission.artifacts import Identification
from commission.controllers.plant import P_B, P_M, P_OFFSET
from commission.scenarios.identified import identified_plant
from commission.spec import Spec


def force_range(ident: Identification) -> tuple[float, float]:
    """Range of the nominal disturbance force d_n = -offset that the box admits at every mass, u-unit.

    theta3 = d_n / M must stay in [theta3_min, theta3_max] for every M in
    [m_light, m_heavy] = [1/theta1_max, 1/theta1_min].  An end of theta3's range away from zero binds
    at the lightest mass, where d_n / M is largest in magnitude; an end on the far side of zero (a
    range that excludes zero: a constant load such as gravity) binds at the heaviest, where d_n / M is
    smallest.  With zero inside the range (identify's boxes) this is d_n in [theta3_min,
    theta3_max] x m_light.  (A payload adds mass, not force.)  The inverse is
    :func:`theta3_range_for_forces`.
    """
    return forces_of_theta3(ident.theta.min[2], ident.theta.max[2], 1.0 / ident.theta.max[0],
                            1.0 / ident.theta.min[0])


def forces_of_theta3(lo: float, hi: float, m_light: float, m_heavy: float) -> tuple[float, float]:
    """:func:`force_range` of a theta3 range ``[lo, hi]`` (q/s^2) over masses ``[m_light, m_heavy]``, u-unit."""
    return lo * (m_heavy if lo > 0 else m_light), hi * (m_heavy if hi < 0 else m_light)


def theta3_range_for_forces(ident: Identification, f_lo: float, f_hi: float) -> tuple[float, float]:
    """The theta3 range, within the box's, whose :func:`force_range` is ``[f_lo, f_hi]`` (u-unit), q/s^2.

    Interval arithmetic over the box's masses, as :func:`commission.identify.bounds.theta_bounds`
    builds theta3: ``[min(f_lo / m), max(f_hi / m)]`` over m in [m_light, m_heavy].  For a range that
    holds the identified force ``d_n = -offset`` the result holds the nominal ``d_n / M`` (M within
    the masses), whatever the sign of d_n; then clipped to the box's theta3 range, which holds it too.
    """
    m_light, m_heavy = 1.0 / ident.theta.max[0], 1.0 / ident.theta.min[0]
    lo = min(f_lo / m_light, f_lo / m_heavy)
    hi = max(f_hi / m_light, f_hi / m_heavy)
    return max(ident.theta.min[2], lo), min(ident.theta.max[2], hi)


def viscous_range(ident: Identification) -> tuple[float, float]:
    """Range of the viscous coefficient B that the box admits at every mass, u-unit s/m.

    theta2 = B / M must stay in [theta2_min, theta2_max] for every M in
    [1/theta1_max, 1/theta1_min]: B >= theta2_min / theta1_min (heaviest mass) and
    B <= theta2_max / theta1_max (lightest).  This is the inverse of the interval
    arithmetic that built the box (:mod:`commission.identify.bounds`), so for a box
    built by ``commission identify`` it returns the viscous range it was built from.
    A payload adds mass, not viscous friction: pairing the heaviest payload with the
    largest theta2 (B = theta2_max / theta1_min) would ask for up to
    theta1_max / theta1_min times the largest B the empty axis may have.  When the
    box admits no B at every mass (lower end above the upper), the identified B
    (clipped to zero) is returned as a point range.
    """
    lo = ident.theta.min[1] / ident.theta.min[0]
    hi = ident.theta.max[1] / ident.theta.max[0]
    if lo > hi:
        b = max(ident.value("B"), 0.0)
        return b, b
    return lo, hi


def clip_to_box(plants: np.ndarray, ident: Identification) -> np.ndarray:
    """Clip B and the offset of plant vectors (rows) so that theta2, theta3 lie in the box at each row's mass."""
    out = np.array(plants, dtype=np.float64, copy=True)
    m = out[:, P_M]
    out[:, P_B] = np.clip(out[:, P_B], ident.theta.min[1] * m, ident.theta.max[1] * m)
    # theta3 = d_n / M with d_n = -offset
    out[:, P_OFFSET] = -np.clip(-out[:, P_OFFSET], ident.theta.min[2] * m, ident.theta.max[2] * m)
    return out


def monte_carlo_support(ident: Identification) -> tuple[float, float, float, float]:
    """The part of the theta box the Monte-Carlo sample draws from: ``(theta1_lo, theta1_hi, d_lo, d_hi)``.

    The whole box (theta1 in [theta1_min, theta1_max], d_n in :func:`force_range`), except where
    ident.json records a range as the tool's default rather than the user's statement
    (``bounds.payload_defaulted``, ``bounds.disturbance_bound_defaulted``):

    * a defaulted payload: masses up to the unloaded heavy end only (theta1 >= 1 / (M_hi - payload_max),
      the mass the identification itself supports, with its spread and model margin);
    * a defaulted load-force bound: d_n within the Assumption-1 load step about the identified
      constant force, ``-offset +- delta_d M`` (the step the ``disturbance`` scenario applies), cut to
      :func:`force_range`.

    Why: the Monte-Carlo plants certify performance (the ARC-vs-yardstick quantiles,
    :mod:`commission.gate`, "What each scenario certifies"), which rests on what the log supports;
    a default payload of up to three times the mass and a load of ten times the stiction are guesses,
    whose corners the fixed scenarios (``payload_heavy``, ``disturbance``) and the whole-box margins
    still hold to safety.  A stated range is drawn in full.
    """
    t_lo, t_hi = ident.theta.min[0], ident.theta.max[0]
    d_lo, d_hi = force_range(ident)
    b = ident.extra.get("bounds") if isinstance(ident.extra, dict) else None
    if not isinstance(b, dict):
        return t_lo, t_hi, d_lo, d_hi
    pr = b.get("payload_range")
    if b.get("payload_defaulted") is True and isinstance(pr, list) and len(pr) == 2:
        m_unloaded = 1.0 / t_lo - float(pr[1])
        if m_unloaded > 0:
            t_lo = min(max(t_lo, 1.0 / m_unloaded), t_hi)
    if b.get("disturbance_bound_defaulted") is True and ident.delta_d is not None:
        p = identified_plant(ident)
        dn, r = -float(p[P_OFFSET]), abs(float(ident.delta_d) * float(p[P_M]))
        lo, hi = max(d_lo, dn - r), min(d_hi, dn + r)
        if lo <= hi:
            d_lo, d_hi = lo, hi
    return t_lo, t_hi, d_lo, d_hi


def monte_carlo_plants(ident: Identification, n: int, rng: np.random.Generator,
                       spec: Spec | None = None) -> np.ndarray:
    """``n`` plant vectors from the theta box (identified friction curve), shape (n, NP).

    theta1 is uniform in the box (M = 1/theta1), within :func:`monte_carlo_support` (a defaulted payload
    or load bound is drawn only where the log supports it); the viscous coefficient B is
    uniform in :func:`viscous_range` and the disturbance force d_n = -offset
    uniform in :func:`force_range`, the ranges the box admits at every mass, so
    that theta2 = B / M and theta3 = d_n / M lie in the box for every drawn mass.
    (Drawing theta2, theta3 uniformly instead would pair the heaviest payload with
    B = theta2_max / theta1_min and forces theta3_max / theta1_min, up to
    theta1_max / theta1_min times what the box admits for the empty axis: a
    payload adds mass, not viscous friction or force.)
    """
    base = identified_plant(ident, spec)
    lo, hi, d_lo, d_hi = monte_carlo_support(ident)
    u = rng.random((n, 3))
    b_lo, b_hi = viscous_range(ident)
    out = np.tile(base, (n, 1))
    out[:, P_M] = 1.0 / (lo + (hi - lo) * u[:, 0])
    out[:, P_B] = b_lo + (b_hi - b_lo) * u[:, 1]
    out[:, P_OFFSET] = -(d_lo + (d_hi - d_lo) * u[:, 2])
    return clip_to_box(out, ident)  # only rounding (or the point-range fallback) can leave the box

