"""The scenario sets: validate's matrix (:func:`scenario_matrix`: the fixed scenarios, the
robustness ones and the Monte-Carlo plants) and tune's (:func:`tuning_scenarios`: those plus the
box corners, the largest forces and the interior payloads).  Names, tags and order are described
in :mod:`commission.scenarios`.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from commission.artifacts import Identification
from commission.controllers.plant import (
    P_DELAY,
    P_MODE2_DAMPING,
    P_MODE2_HZ,
    P_MODE_DAMPING,
    P_MODE_HZ,
    P_B,
    P_FC,
    P_FS,
    P_M,
    P_OFFSET,
    P_VS,
    P_XI,
)
from commission.scenarios.box import clip_to_box, force_range, monte_carlo_plants, viscous_range
from commission.scenarios.identified import identified_plant
from commission.scenarios.resolution import resolve_encoder_noise, resolve_quantization
from commission.scenarios.scenario import NO_DISTURBANCE, Scenario, StepDisturbance
from commission.scenarios.trajectories import trajectories
from commission.spec import Spec

#: Fraction of the run at which the disturbance step switches on / off (paper: 2.2 s, 7.2 s of 10 s).
DISTURBANCE_ON = 0.22
DISTURBANCE_OFF = 0.72
#: Friction scaling of the friction scenarios (+-20 % of the identified curve).
FRICTION_SCALE = 0.2

#: The fixed scenarios' variants of the identified plant, on every trajectory.
VARIANTS = ("nominal", "payload_light", "payload_heavy", "friction_low", "friction_high", "disturbance")


def _variant(base: np.ndarray, variant: str, ident: Identification) -> np.ndarray:
    p = base.copy()
    if variant == "payload_light":
        p[P_M] = 1.0 / ident.theta.max[0]
    elif variant == "payload_heavy":
        p[P_M] = 1.0 / ident.theta.min[0]
    elif variant in ("friction_low", "friction_high"):
        k = 1.0 - FRICTION_SCALE if variant == "friction_low" else 1.0 + FRICTION_SCALE
        for i in (P_B, P_FC, P_FS):
            p[i] *= k
    return p


def disturbance_step(ident: Identification, duration: float) -> StepDisturbance:
    """The Assumption-1-sized step: ``delta_d * M`` u-unit over 22 %..72 % of ``duration``."""
    return StepDisturbance(ident.delta_d * ident.value("M"), DISTURBANCE_ON * duration,
                           DISTURBANCE_OFF * duration)


def scenario_matrix(ident: Identification, spec: Spec, *, rng: np.random.Generator,
                    n_monte_carlo: int = 64) -> list[Scenario]:
    """The full validation matrix (:mod:`commission.scenarios`), deterministic for a given ``rng`` state.

    Parameters
    ----------
    ident : Identification
        Identified model, theta box and delta_d.
    spec : Spec
        Envelope, sample rate (trajectories are rendered later at ``1/spec.sample_rate``).
    rng : numpy.random.Generator
        Source of the Monte-Carlo sample (drawn only when ``n_monte_carlo > 0``).
    n_monte_carlo : int
        Monte-Carlo plants from the theta box (default 64).

    Returns
    -------
    list of Scenario
        The 12 fixed scenarios (tag ``"tune"``) followed by ``mc/000`` ...
    """
    if n_monte_carlo < 0:
        raise ValueError(f"n_monte_carlo: must be >= 0, got {n_monte_carlo}")
    base = identified_plant(ident, spec)
    qz = resolve_quantization(ident, spec)
    nz = resolve_encoder_noise(ident, spec)
    trajs = dict(trajectories(spec))
    cases = tuple(trajs)
    out: list[Scenario] = []
    for case in cases:
        tr = trajs[case]
        for variant in VARIANTS:
            dist = disturbance_step(ident, tr.duration) if variant == "disturbance" else NO_DISTURBANCE
            out.append(Scenario(f"{case}/{variant}", _variant(base, variant, ident), tr, dist, 0.0,
                                (case, variant, "tune"), qz, nz))
    out.extend(robustness_scenarios(ident, spec))
    if n_monte_carlo:
        plants = monte_carlo_plants(ident, n_monte_carlo, rng, spec)
        for i in range(n_monte_carlo):
            case = cases[i % len(cases)]
            out.append(Scenario(f"mc/{i:03d}", plants[i], trajs[case], NO_DISTURBANCE, 0.0,
                                (case, "monte_carlo"), qz, nz))
    return out


#: Factors on the mode's frequency in the robustness scenarios.
MODE_FREQUENCY_FACTORS = (0.8, 1.2)
#: Factor on its damping.
MODE_DAMPING_FACTOR = 0.5
#: The Stribeck rise assumed where the log resolved none (``<case>/stribeck``): static level over
#: Coulomb level, Stribeck velocity (q-unit/s) and exponent.  The reference axis's curve (CONTRACT
#: section 5: fs = 1.2 fc, vs = 0.01 m/s, xi = 2); on a rotary axis vs reads as 0.01 rad/s.
UNSEEN_STRIBECK = (1.2, 0.01, 2.0)


def robustness_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """Dynamics the identified model may have wrong, on both trajectories (:mod:`commission.scenarios`).

    Tagged ``"robustness"``: ``validate`` gates them like every other scenario, and ``tune``
    holds its search to the gate on them (:func:`tuning_scenarios`).
    """
    base = identified_plant(ident, spec)
    variants: list[tuple[str, np.ndarray]] = []
    p = base.copy()
    p[P_DELAY] += spec.period
    variants.append(("delay+1", p))
    if base[P_FS] <= base[P_FC] and base[P_FC] > 0.0:
        variants.append(("stribeck", unseen_stribeck(base)))
    if base[P_MODE_HZ] > 0:
        # Every identified mode moves together (a second one too, P_MODE2_HZ = 0 without it).
        for name, k in zip(("mode_low", "mode_high"), MODE_FREQUENCY_FACTORS):
            p = base.copy()
            p[P_MODE_HZ] *= k
            p[P_MODE2_HZ] *= k
            variants.append((name, p))
        p = base.copy()
        p[P_MODE_DAMPING] *= MODE_DAMPING_FACTOR
        p[P_MODE2_DAMPING] *= MODE_DAMPING_FACTOR
        variants.append(("mode_damping_half", p))
    return _on_every_trajectory(ident, spec, "", variants, ("robustness",))


def unseen_stribeck(base: np.ndarray) -> np.ndarray:
    """The plant ``base`` (Coulomb friction only) with the Stribeck rise :data:`UNSEEN_STRIBECK`.

    Why: a Coulomb-only fit means the log did not resolve a rise at low speed (too few slow
    samples, force ripple on the slow legs), not that the machine has none; almost every
    machine has one.  At reversals, where the axis crosses the low speeds, it is what an
    ARC's friction compensation and a PID's integrator meet (docs/robustness.md, "Friction the
    log did not resolve", has what it changes).
    Only the curve's shape below the Coulomb level's speeds changes: fc, B and everything
    else stay as identified.
    """
    ratio, vs, xi = UNSEEN_STRIBECK
    p = base.copy()
    p[P_FS] = ratio * base[P_FC]
    p[P_VS] = vs
    p[P_XI] = xi
    return p


def _on_every_trajectory(ident: Identification, spec: Spec, prefix: str, plants: Sequence[tuple[str, np.ndarray]],
                         tags: tuple[str, ...]) -> list[Scenario]:
    """Each of ``plants`` (``(name, plant vector)``) on every trajectory of :func:`trajectories`, at rest
    from 0 without disturbance, with the identified encoder: ``<prefix><case>/<name>``, tagged ``(case, *tags)``."""
    qz = resolve_quantization(ident, spec)
    nz = resolve_encoder_noise(ident, spec)
    return [Scenario(f"{prefix}{case}/{name}", p, tr, NO_DISTURBANCE, 0.0, (case, *tags), qz, nz)
            for case, tr in trajectories(spec) for name, p in plants]


def corner_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """The 8 corners of the Monte-Carlo domain on both trajectories (16 runs), identified friction.

    ``corner/<case>/<b1><b2><b3>`` with ``b = 0`` for the lower, ``1`` for the upper end of
    theta1, the viscous B of :func:`viscous_range` and the force d_n of :func:`force_range`:
    M = 1/theta1, offset = -d_n.  These are the deterministic extremes of the domain that the
    validation's Monte-Carlo sample (:func:`monte_carlo_plants`) draws from.
    """
    base = identified_plant(ident, spec)
    lo, hi = ident.theta.min, ident.theta.max
    b_lo, b_hi = viscous_range(ident)
    d_lo, d_hi = force_range(ident)
    corners: list[tuple[str, np.ndarray]] = []
    for b in range(8):
        bits = ((b >> 2) & 1, (b >> 1) & 1, b & 1)
        p = base.copy()
        p[P_M] = 1.0 / (hi[0] if bits[0] else lo[0])
        p[P_B] = b_hi if bits[1] else b_lo
        p[P_OFFSET] = -(d_hi if bits[2] else d_lo)
        corners.append((f"{bits[0]}{bits[1]}{bits[2]}", clip_to_box(p[None, :], ident)[0]))
    return _on_every_trajectory(ident, spec, "corner/", corners, ("corner", "tune"))


def offset_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """The identified plant with the largest unknown force the box admits, both signs, both trajectories.

    ``offset/<case>/lo`` and ``offset/<case>/hi``: offset = -d_n with d_n at the
    lower and upper end of :func:`force_range`, every other parameter as
    identified (theta3 = d_n / M stays inside the box since M >= 1/theta1_max).
    These are the Monte-Carlo plants where the ARC and the PID come closest: the
    start-up transient against an unlearnt force decides e_rms, and the ARC's
    integral action (theta3 adaptation) is limited by the stability of its loop.
    """
    base = identified_plant(ident, spec)
    d_lo, d_hi = force_range(ident)
    ends: list[tuple[str, np.ndarray]] = []
    for end, d in (("lo", d_lo), ("hi", d_hi)):
        p = base.copy()
        p[P_OFFSET] = -d
        ends.append((end, p))
    return _on_every_trajectory(ident, spec, "offset/", ends, ("offset", "tune"))


#: Interior payloads of :func:`payload_scenarios`: M = M_nominal (M_heavy / M_nominal)^k for these k.
PAYLOAD_STEPS = (0.25, 0.5, 0.75)


def payload_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """The identified plant carrying interior payloads, both trajectories (6 runs).

    ``payload/<case>/<k>``: M = M_nominal (M_heavy / M_nominal)^k for k in
    :data:`PAYLOAD_STEPS` (geometric steps between the identified mass and the heaviest of
    the box, 1/theta_min[0]); everything else as identified (a payload adds mass only).
    Why: on a payload between the ends the theta1 estimate can drift the wrong way (towards
    a lighter axis, while theta2 falls to its bound) when its adaptation rate is high, and
    the ARC can lose to the PID there while the corners are fine (measured: docs/robustness.md,
    "Why the tuning set holds interior payloads").  The validation's Monte-Carlo sample draws
    such plants; the box corners alone do not show the drift to the search.
    """
    base = identified_plant(ident, spec)
    m0, m_heavy = base[P_M], 1.0 / ident.theta.min[0]
    payloads: list[tuple[str, np.ndarray]] = []
    for k in PAYLOAD_STEPS:
        p = base.copy()
        p[P_M] = m0 * (m_heavy / m0) ** k if m_heavy > m0 else m0
        payloads.append((f"{k:g}", clip_to_box(p[None, :], ident)[0]))
    return _on_every_trajectory(ident, spec, "payload/", payloads, ("payload", "tune"))


def screening_indices(scenarios: Sequence[Scenario]) -> list[int]:
    """Indices of ``validate``'s fixed and robustness scenarios in a tuning set (the search's screen).

    Everything but the tune-only stand-ins (box corners, largest-force and interior payload
    plants) and Monte-Carlo plants: the part of the tuning set that validate itself runs, on
    which a candidate far off the gate is already far off, so the search simulates the rest
    only for the others (:mod:`commission.tune.optimiser`).
    """
    extra = {"corner", "offset", "payload", "monte_carlo"}
    return [i for i, s in enumerate(scenarios) if not extra.intersection(s.tags)]


def tuning_scenarios(ident: Identification, spec: Spec, *, rng: np.random.Generator,
                     n_monte_carlo: int | None = None) -> list[Scenario]:
    """The set ``tune`` optimises on.

    Every fixed scenario of :func:`scenario_matrix` (tag ``"tune"``), the robustness scenarios
    of :func:`robustness_scenarios` (one more sample of delay, the mode's variants), the 16 box corners of
    :func:`corner_scenarios` (a deterministic stand-in for the validation's
    Monte-Carlo sample, whose worst plants sit near the corners), the 4
    largest-force plants of :func:`offset_scenarios`, the 6 interior payloads of
    :func:`payload_scenarios`, and ``spec.monte_carlo`` (or ``n_monte_carlo``)
    Monte-Carlo plants drawn from ``rng``.
    """
    n = spec.monte_carlo if n_monte_carlo is None else n_monte_carlo
    matrix = scenario_matrix(ident, spec, rng=rng, n_monte_carlo=n)
    fixed = [s for s in matrix if "tune" in s.tags or "robustness" in s.tags]
    mc = [s for s in matrix if "monte_carlo" in s.tags]
    return fixed + corner_scenarios(ident, spec) + offset_scenarios(ident, spec) + payload_scenarios(ident, spec) + mc
