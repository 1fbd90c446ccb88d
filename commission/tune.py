"""The ``commission tune`` pipeline: ident.json + spec -> tuning.json.

Steps (all numerics in :mod:`commission.controllers`; this module only
orchestrates, checks inputs and builds the :class:`~commission.tuning.Tuning`):

1. Spec checks before any simulation (:mod:`commission.spec`, then
   :func:`check_spec_against_ident`: the input limit must cover the envelope
   on the heaviest plant of the box).  Defaults are fitted to the axis first
   (:func:`resolve_spec`): the envelope to the sample rate and the drive, and a
   *defaulted* load-force bound that leaves the drive no room for any envelope
   is narrowed (:func:`fit_disturbance_to_drive`).
2. Observer: double pole of A0 (10) at ``-spec.observer_pole``; k1 = 2p,
   k2 = p^2; P of (11) (:func:`controllers.design.observer_design`).
3. Base ARC gains (:func:`base_arc_gains`): the paper's §4.3 gains carried
   over to this axis.  Gains in 1/s scale with the sample rate (r = f_s / 2.5 kHz),
   and every gain whose unit involves the command unit scales with
   c = 37 / theta1_nominal (the ARC law is invariant when u is re-scaled by c
   and w2, C_phi, C_theta2, Gamma, eps22 follow; see the function).  The
   Theorem-1 condition is invariant under this map.  theta_hat(0) = the
   identified nominal theta (theta_hat1(0) is then searched, step 4); bounds =
   the identified box; friction compensation = the identified one; output
   limit = ``spec.u_max``.
4. Free gains, searched in log scale (:class:`FreeGains`): the caps k1s_max,
   k2s_max on the total nonlinear gains that make (37)/(47) implementable,
   g1, g2 as fractions of the caps, the three entries of Gamma, the
   weight w2 and the initial estimate theta_hat1(0) (between
   :data:`THETA1_0_LOW` and 1 x the identified nominal, inside the box;
   ``controller.theta1_0`` of the spec pins it).  A start below the nominal
   is what the paper did (30 for 37): a payload only lowers theta1, and the
   start-up against an unlearnt payload decides e_M and e_rms on the heavy
   plants, while the empty axis forgives a moderately low start.  (The eps
   terms stay at the carried-over paper values: with
   bounded gains they only decide how often a cap is active.)  The search
   (:func:`search`) is a seeded coarse-to-fine random search: generation 0 is
   the carried-over paper gains (as printed, caps at g1, g2), the arc module's
   implementable paper gains, :data:`EXTRA_STARTS` and random points;
   each later generation draws ``POP`` candidates around the best *feasible*
   one so far, the step shrinking by ``SHRINK`` down to :data:`STEP_FLOOR`, for ``spec.budget``
   candidates.  The objective is a surrogate; the winner is then chosen among
   the :data:`HOLDOUT_CANDIDATES` best feasible candidates by validate's
   default gate on the tuning scenarios plus :data:`HOLDOUT_PLANTS` fresh
   Monte-Carlo plants the search never saw (:class:`HoldoutGate`,
   :func:`select_on_holdout`).  When every one of them fails there and the budget
   was defaulted, the search continues (:class:`SearchRun`) up to the work of the
   slowest defaulted search (:func:`search_extension`) and the winner is chosen
   again among all candidates; when they still fail,
   :func:`repair_on_holdout` runs a short local search on that gate
   (a line search lowering the caps when the gains chatter, then random joint moves of
   the free gains and of a defaulted observer pole).  Each
   candidate is simulated on the tuning scenarios of
   :func:`commission.scenarios.tuning_scenarios` (validate's 12 fixed
   scenarios, the 16 box corners, the 4 largest-force plants at the
   identified mass and 6 interior payloads) with the batch
   simulator.  Objective
   (:func:`cost`): weighted mean over the scenarios of ln(e_rms /
   targets.e_rms), plus penalties for e_F above ``targets.e_f``, c_u above
   ``targets.c_u``, the input reaching u_max, e_rms not below PID_MARGIN x
   the PID baseline's, e_M above the PID baseline's, divergence; plus the worst ARC/PID e_rms ratio; plus
   :data:`W_GATE` per check of the default gate failed on these scenarios.
5. Discrete feasibility (:func:`controllers.design.discrete_feasibility`:
   the sampled loop linearised at the 8 corners of the theta box along both
   trajectories, spectral radius < 1 - margin with the estimates frozen and
   < 1 with the theta3 adaptation in the loop) is a constraint of the search,
   checked lazily on the candidates that would improve on the best feasible
   one.  The chosen gains are also checked with theta_hat at every box
   corner (reported, informational).  The PID baseline (poles of (56) at
   M_min = 1/theta_max[0]) is checked and scored the same way; it runs at the
   spec's pole or, when that was defaulted and its PID exceeds validate's c_u
   limit on a tuning scenario, at the fastest lower pole that does not
   (:func:`deployable_pid`), so that the ARC is compared with a PID a user could deploy.
6. tuning.json with provenance, every gain, the design reports, the
   guarantee statement and the scores of ARC and PID on every tuning scenario.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import math
import os
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

import commission
from commission.artifacts import Identification
from commission.controllers.arc import ArcGains, arc_pack, paper_gains_as_printed, paper_gains_implementable
from commission.controllers.design import (
    KIND_ARC,
    KIND_PID,
    DesignError,
    FeasibilityReport,
    discrete_feasibility,
    observer_design,
    theorem1_check,
)
from commission.controllers.pid import PidGains, pid_pack, pid_place_poles
from commission.controllers.plant import P_B, P_FC, P_FS, P_M, P_OFFSET, P_RIPPLE_AMP
from commission.controllers.simulate import simulate_batch
from commission.errors import IdentifiabilityError, SpecError, UsageError
from commission.gate import GateLimits, GateSpec, evaluate_gate, resolve_gate
from commission.jsonio import read_json, sha256_file
from commission.robustness import margin_table
from commission.scenarios import (
    check_run_length,
    CASE1_SPEED_FRACTION,
    FRICTION_SCALE,
    Scenario,
    case1_trajectory,
    case2_trajectory,
    force_range,
    identified_plant,
    plant_substeps,
    resolve_quantization,
    scenario_matrix,
    tuning_scenarios,
    viscous_range,
)
from commission.spec import Spec, read_spec_toml, spec_from_mapping
from commission.tuning import FeasibilitySummary, Guarantee, Provenance, Score, SearchRecord, Tuning

Progress = Callable[[int, int], None]

#: The paper's axis: theta1 = 37 at 2.5 kHz; the reference of the gain scaling.
PAPER_THETA1 = 37.0
PAPER_RATE = 2500.0
#: Candidates per generation of the search, and the step shrink per generation.
POP = 8
SHRINK = 0.6
#: Smallest log-step of the search (a factor 1.1 per axis).  Without it the step reached 0.6**5 = 0.08
#: by the sixth generation and the last half of the budget only polished the first local minimum: on
#: two of the light 4-5 kHz axes that failed the gate the best cost stopped moving after the fourth generation.
STEP_FLOOR = 0.1
#: Simulation work of one search candidate (:func:`candidate_work`, plant sub-steps) above which a
#: *defaulted* search budget shrinks in proportion (:func:`work_scale`) and the repair gets one round.  It is 1.8x the
#: paper's axis on the default envelope (12e6); slow envelopes at 4-5 kHz reach 30-41e6, where 96
#: candidates took 109-131 s on 2 cores against the 120-s target.  (It was 2x; with :data:`STEP_FLOOR` the slow
#: worst case's 56 candidates took 112-125 s, so it gets 48.)
WORK_CAP = 22e6
#: Cost of one ARC step in plant sub-steps (about 190 ns against 50 ns, measured at 4 kHz).
ARC_STEP_WORK = 4
#: Floor of a work-scaled search budget (6 generations).
MIN_BUDGET = 48
#: Repair budget where the search budget is work-scaled (two rounds of :data:`REPAIR_POP`).
MIN_REPAIR_BUDGET = 16
#: Penalty weights of the objective (per scenario, in units of ln e_rms).
W_TARGET = 2.0
W_CHATTER = 10.0
W_STEP = 1.0
W_SATURATION = 2.0
W_DIVERGED = 20.0
#: The ARC is asked to beat the PID's e_rms by this factor on every tuning scenario (soft
#: constraint), so that validation's "ARC no worse than PID" holds on plants between them.
PID_MARGIN = 0.9
#: Weight of the worst ARC/PID e_rms ratio over the scenarios (minimax term of the objective).
W_WORST = 1.0
#: Objective added per check of validate's default gate that a candidate fails on a tuning scenario.
W_GATE = 0.5
#: Objective weight of each of the 16 box-corner scenarios (the 12 fixed scenarios weigh 1):
#: the corners mostly act through the penalties (divergence, no worse than the PID).
CORNER_WEIGHT = 0.25
#: Lowest theta_hat1(0) the search considers, as a fraction of the identified nominal theta1
#: (further clipped to the box).  theta_hat1(0) below the nominal trades a slower start on the
#: empty axis for a faster one under payload (a payload only lowers theta1 = 1/M); above the
#: nominal nothing is gained.
THETA1_0_LOW = 0.5
#: The paper's theta_hat1(0) (§4.3), for a nominal theta1 of 37.
PAPER_THETA1_0 = 30.0
#: Structured starting points of generation 0 besides FREE_START and :func:`paper_implementable_start`
#: (relative free gains): a small w2 with a faster theta3 adaptation (the integral action, see FREE_BOUNDS);
#: a larger K2 cap, w2 and theta3 rate with the paper's theta_hat1(0) / theta1 = 30/37.
EXTRA_STARTS = ((1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 10.0, 0.1, 1.0),
                (1.0, 3.0, 1.0, 1.0, 1.0, 1.0, 3.0, 3.0, PAPER_THETA1_0 / PAPER_THETA1))


def paper_implementable_start() -> tuple[float, ...]:
    """:func:`controllers.arc.paper_gains_implementable` as relative free gains.

    Its caps, g and Gamma relative to the printed paper gains (the base of
    :func:`base_arc_gains` for the paper's axis), clipped to :data:`FREE_BOUNDS`.
    """
    pr, im = paper_gains_as_printed(), paper_gains_implementable()
    x = (im.k1s_max / pr.g1, im.k2s_max / pr.g2, im.g1 / im.k1s_max, im.g2 / im.k2s_max,
         im.Gamma[0] / pr.Gamma[0], im.Gamma[1] / pr.Gamma[1], im.Gamma[2] / pr.Gamma[2], im.w2 / pr.w2,
         im.theta0[0] / PAPER_THETA1)
    return tuple(min(max(v, b[1]), b[2]) for v, b in zip(x, FREE_BOUNDS))


# --------------------------------------------------------------------------- spec vs ident


#: When the spec leaves the envelope to its defaults, the feedforward of the worst plant may use at
#: most this fraction of u_max (the rest is left to the feedback: start-up transients, unlearnt loads).
DRIVE_HEADROOM = 0.7
#: Smallest envelope :func:`default_envelope` derives (m/s, m/s^2); below it the box is refused instead.
MIN_DEFAULT_V_MAX = 0.1
MIN_DEFAULT_A_MAX = 1.0


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


def drive_need(ident: Identification) -> DriveNeed:
    """The :class:`DriveNeed` of an identification's scenario matrix."""
    p = identified_plant(ident)
    k = 1.0 + FRICTION_SCALE
    d_lo, d_hi = force_range(ident)
    force = max(abs(d_lo), abs(d_hi), abs(p[P_OFFSET]) + ident.delta_d * p[P_M])
    return DriveNeed(mass=1.0 / ident.theta.min[0], viscous=max(viscous_range(ident)[1], k * p[P_B]),
                     const=k * max(p[P_FC], p[P_FS]) + p[P_RIPPLE_AMP] + force)


def check_spec_against_ident(spec: Spec, ident: Identification, source: str = "spec.toml") -> None:
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
    need = d.need(spec.v_max, spec.a_max, spec.beta1)
    if need > spec.u_max:
        u = ident.units.get("u", "u-unit")
        # Remedies in order: a smaller envelope (values that pass when followed: Case 1's start-up
        # acceleration counts), a narrower box, and only then a larger drive.
        a_ok = d.a_max(spec.u_max, spec.v_max)
        a1 = spec.beta1 * CASE1_SPEED_FRACTION * spec.v_max
        v_ok = d.v_max(spec.u_max, spec.beta1)
        if a_ok > 0 and a_ok >= a1:
            hint = f"set trajectory.a_max <= {_floor3(a_ok):.3g} m/s^2 at this v_max"
        elif v_ok > 0:
            v_fix = _floor3(v_ok)
            hint = (f"Case 1's start-up alone needs {a1:.3g} m/s^2 at this v_max, so no a_max fits; set "
                    f"trajectory.v_max <= {v_fix:.3g} m/s with trajectory.a_max <= "
                    f"{_floor3(d.a_max(spec.u_max, v_fix)):.3g} m/s^2")
        else:
            hint = f"no envelope fits: even at rest the plant needs {d.const:.3g} {u}"
        raise SpecError(
            f"{source}: controller.u_max = {spec.u_max:g} {u} is below the {need:.3g} {u} needed for "
            f"trajectory.a_max = {spec.a_max:g} m/s^2 and v_max = {spec.v_max:g} m/s on the most demanding "
            f"plant of the theta box (M = {d.mass:.3g}, B = {d.viscous:.3g}); {hint}; else narrow the box "
            f"(commission identify --payload-max, --disturbance-bound); raise controller.u_max only if the "
            f"drive really has it")


def _floor3(x: float) -> float:
    """``x`` > 0 rounded down to 3 significant digits, so that the printed value still fits."""
    step = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.floor(x * (1 - 1e-12) / step) * step


#: Share of the feedforward budget (DRIVE_HEADROOM x u_max) that a *defaulted* load-force bound
#: is narrowed to when, at its default, not even the smallest default envelope fits (see
#: :func:`fit_disturbance_to_drive`).
DISTURBANCE_SHARE = 0.5


def fit_disturbance_to_drive(spec: Spec, ident: Identification,
                             given: set[str]) -> tuple[Identification, tuple[str, ...]]:
    """Narrow the theta3 box of a *defaulted* load-force bound to what the drive can reject.

    ``commission identify`` bounds the load force by ``10 max(fc, fs)`` when the user does not
    say (``--disturbance-bound``): the paper's box allows about eleven times its stiction.  On a
    heavy axis with high friction that default alone can exceed the drive (10 x 1.1 V of
    stiction on a 10 V rail): no controller rejects a load the motor cannot push, and the
    spec used to be refused.  When the bound was defaulted (``bounds.disturbance_bound_defaulted``
    in ident.json) and even the smallest default envelope (:data:`MIN_DEFAULT_V_MAX`,
    :data:`MIN_DEFAULT_A_MAX`) does not fit in the feedforward budget ``DRIVE_HEADROOM x u_max``
    on the most demanding plant, the force range is narrowed symmetrically about the identified
    offset force until friction, ripple and constant force take :data:`DISTURBANCE_SHARE` of the
    budget; the rest is left to the envelope (:func:`default_envelope`).  theta3's bounds
    follow at the lightest mass, where they bind (:func:`commission.scenarios.force_range`).

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
    budget = DRIVE_HEADROOM * spec.u_max
    d = drive_need(ident)
    v_min = min(spec.v_max, MIN_DEFAULT_V_MAX)
    a_min = min(spec.a_max, MIN_DEFAULT_A_MAX)
    if d.need(v_min, a_min, spec.beta1) <= budget:
        return ident, ()
    p = identified_plant(ident)
    d_lo, d_hi = force_range(ident)
    step = abs(p[P_OFFSET]) + ident.delta_d * p[P_M]
    force = max(abs(d_lo), abs(d_hi), step)
    fixed = d.const - force  # friction (+20 %) and ripple
    allowed = DISTURBANCE_SHARE * budget - fixed  # largest |constant force| left for the box
    dn = -p[P_OFFSET]
    reach = allowed - abs(dn)  # half-width of the narrowed force range about d_n
    if not (reach > 0 and allowed >= step and max(abs(d_lo), abs(d_hi)) > allowed):
        return ident, ()  # friction alone is too much: default_envelope refuses, naming u_max
    m_light = 1.0 / ident.theta.max[0]
    lo = max(ident.theta.min[2], (dn - reach) / m_light)
    hi = min(ident.theta.max[2], (dn + reach) / m_light)
    theta = dataclasses.replace(ident.theta, min=(*ident.theta.min[:2], lo), max=(*ident.theta.max[:2], hi))
    u = ident.units.get("u", "u-unit")
    old_bound = bounds.get("disturbance_bound")
    new_bounds = dict(bounds)
    new_bounds["narrowed_by_tune"] = {
        "theta3_min": ident.theta.min[2], "theta3_max": ident.theta.max[2],
        "force_range": [d_lo, d_hi], "narrowed_force_range": [lo * m_light, hi * m_light],
        "u_max": spec.u_max}
    extra = dict(ident.extra)
    extra["bounds"] = new_bounds
    out = dataclasses.replace(ident, theta=theta, extra=extra)
    was = f" ({old_bound:.3g} {u}, the default 10 max(fc, fs))" if isinstance(old_bound, (int, float)) else ""
    note = (f"theta3 box narrowed from [{ident.theta.min[2]:.4g}, {ident.theta.max[2]:.4g}] to [{lo:.4g}, {hi:.4g}] "
            f"m/s^2 (constant load force {lo * m_light:.3g}..{hi * m_light:.3g} {u}): the defaulted load-force "
            f"bound{was} leaves controller.u_max = {spec.u_max:g} {u} no room for even v_max = {v_min:g} m/s, "
            f"a_max = {a_min:g} m/s^2 on the most demanding plant; it now takes {DISTURBANCE_SHARE:g} of the "
            f"{budget:.3g} {u} feedforward budget.  State the real load with commission identify "
            f"--disturbance-bound")
    return out, (note,)


def rate_scaled_envelope(spec: Spec, given: set[str]) -> tuple[Spec, tuple[str, ...]]:
    """Scale a *defaulted* envelope to a sample rate below the paper's 2.5 kHz.

    The defaults (1 m/s, 12 m/s^2) are the paper's envelope at its 2.5 kHz.  Every loop
    gain that can be implemented scales with the rate r = f_s / 2.5 kHz (observer poles,
    caps, the PID's poles), so the tracking error of a given trajectory grows as 1/r^2
    for the acceleration-driven part and 1/r for the velocity-driven part.  Below 2.5 kHz a
    defaulted a_max is therefore scaled by r^2 and v_max by r, which keeps the demand
    relative to the loop's bandwidth at the paper's (1 kHz: 0.4 m/s, 1.92 m/s^2).  Without
    it, 1 kHz axes of :func:`commission.synth.random_axis` miss the default gate's e_rms
    limit (20 um) by 1.1-2x on their heavy plants, with the ARC still ahead of the PID.
    Keys the user set are kept; at or above 2.5 kHz nothing changes.
    """
    r = spec.sample_rate / PAPER_RATE
    if r >= 1.0:
        return spec, ()
    v = spec.v_max if "v_max" in given else spec.v_max * r
    a = spec.a_max if "a_max" in given else spec.a_max * r * r
    return dataclasses.replace(spec, v_max=v, a_max=a), _envelope_notes(
        spec, v, a, f"the sample rate {spec.sample_rate:g} Hz is {r:.3g} x the paper's {PAPER_RATE:g} Hz "
                    f"(the envelope scales as r for v_max, r^2 for a_max)")


def _envelope_notes(spec: Spec, v: float, a: float, why: str) -> tuple[str, ...]:
    """One note per envelope key that (v, a) changes from ``spec``'s."""
    return tuple(f"trajectory.{k} defaulted to {new:.3g} {unit} instead of {old:g}: {why}"
                 for k, old, new, unit in (("v_max", spec.v_max, v, "m/s"), ("a_max", spec.a_max, a, "m/s^2"))
                 if new != old)


def default_envelope(spec: Spec, ident: Identification, given: set[str],
                     source: str = "spec (defaults)") -> tuple[Spec, tuple[str, ...]]:
    """Lower the *defaulted* envelope (v_max, a_max) to what the drive can move on the worst plant.

    The paper's 1 m/s and 12 m/s^2 ask a heavy axis (with its payload bound) for more
    than a +-10 V drive gives.  A key the user set (``given`` holds ``"v_max"``,
    ``"a_max"``) is never changed: :func:`check_spec_against_ident` then accepts or
    rejects it.  Defaulted keys are lowered so that the worst plant's feedforward
    (:func:`drive_need`) uses at most :data:`DRIVE_HEADROOM` x u_max: a_max first; v_max
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
    budget = DRIVE_HEADROOM * spec.u_max
    if d.need(spec.v_max, spec.a_max, spec.beta1) <= budget or {"v_max", "a_max"} <= given:
        return spec, ()
    free = budget - d.const
    u = ident.units.get("u", "u-unit")
    refuse = SpecError(
        f"{source}: controller.u_max = {spec.u_max:g} {u} is too small for this theta box: its most demanding "
        f"plant (M = {d.mass:.3g}, B = {d.viscous:.3g}) needs {d.const:.3g} {u} for friction and constant forces "
        f"alone, leaving less than v_max = {MIN_DEFAULT_V_MAX:g} m/s, a_max = {MIN_DEFAULT_A_MAX:g} m/s^2 within "
        f"{DRIVE_HEADROOM:g} x u_max; raise u_max, set trajectory.v_max/a_max, or narrow the box "
        f"(commission identify --payload-max, --disturbance-bound)")
    if free <= 0:
        raise refuse
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
    if ("v_max" not in given and v < MIN_DEFAULT_V_MAX) or ("a_max" not in given and a < MIN_DEFAULT_A_MAX):
        raise refuse
    if v * v / a > spec.travel:
        raise SpecError(
            f"{source}: trajectory.v_max = {v:g} m/s cannot be reached within trajectory.travel = "
            f"{spec.travel:g} m at the a_max = {a:.3g} m/s^2 this drive allows on the most demanding plant "
            f"of the theta box (need v_max^2/a_max <= travel)")
    return dataclasses.replace(spec, v_max=v, a_max=a), _envelope_notes(
        spec, v, a, f"the most demanding plant of the theta box (M = {d.mass:.3g}, B = {d.viscous:.3g}) needs "
                    f"<= {DRIVE_HEADROOM:g} x controller.u_max = {budget:.3g} {u} of feedforward")


# --------------------------------------------------------------------------- gains


@dataclass(frozen=True)
class FreeGains:
    """The gains the search chooses (absolute values).

    Attributes
    ----------
    k1s_max, k2s_max : float
        Caps on the total nonlinear gains K1 (28)+(37)+(38) and K2 (43)+(47), 1/s:
        the bound that makes the robust terms implementable.
    g1, g2 : float
        Minimum nonlinear gains of (28) and (43), 1/s (<= the caps).
    Gamma : tuple of 3 float
        Diagonal adaptation rate of (19).
    w2 : float
        Weight of (41) (w1 = 1).
    theta1_0 : float
        Initial estimate theta_hat1(0), m/(u-unit s^2) (inside the theta box).
    """

    k1s_max: float
    k2s_max: float
    g1: float
    g2: float
    Gamma: tuple[float, float, float]
    w2: float
    theta1_0: float

    def as_dict(self) -> dict[str, float]:
        return {"k1s_max": self.k1s_max, "k2s_max": self.k2s_max, "g1": self.g1, "g2": self.g2,
                "Gamma1": self.Gamma[0], "Gamma2": self.Gamma[1], "Gamma3": self.Gamma[2], "w2": self.w2,
                "theta1_0": self.theta1_0}


#: Search box of the free gains, relative to :func:`base_arc_gains`: (name, low, high).
#: k1, k2: caps as multiples of the base g1, g2; f1, f2: g as a fraction of its cap;
#: G1..G3: Gamma entries as multiples of the base Gamma; w2: the weight w2 of (41) as a
#: multiple of the base (w1 = 1 fixed: only w1/w2 matters).  A small w2 lets the theta3
#: adaptation (the loop's integral action, tau3 = w1 psi2 z1 + w2 phi2_3 z2) run much faster
#: before its loop loses stability, at the price of more chattering: the search trades them.
#: t1: theta_hat1(0) as a multiple of the identified nominal (clipped to the box; see THETA1_0_LOW).
FREE_BOUNDS = (("k1", 0.25, 4.0), ("k2", 0.25, 4.0), ("f1", 0.05, 1.0), ("f2", 0.05, 1.0),
               ("G1", 1e-2, 30.0), ("G2", 1e-2, 30.0), ("G3", 1e-2, 1e4), ("w2", 1e-3, 10.0),
               ("t1", THETA1_0_LOW, 1.0))
#: Starting point (relative): the paper's g1, g2 as caps (robust terms bounded by g), paper Gamma and w2,
#: theta_hat(0) = the identified nominal.
FREE_START = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
N_FREE = len(FREE_BOUNDS)
#: Index of theta_hat1(0) in the free vector.
I_THETA1_0 = 8
#: :data:`FREE_BOUNDS` in log space (read-only; copy before pinning a coordinate).
FREE_LOG_LO = np.log([b[1] for b in FREE_BOUNDS])
FREE_LOG_HI = np.log([b[2] for b in FREE_BOUNDS])


def base_arc_gains(ident: Identification, spec: Spec) -> ArcGains:
    """The paper's §4.3 ARC gains carried over to this axis (module docstring, step 3).

    With c = 37 / theta1_nominal (command-unit scale) and r = f_s / 2500 Hz:
    w1 = 1, w2 = 0.1 / c^2; g1 = 600 r, g2 = 850 r (1/s); eps11 = 5e-5, eps12 = 5e-5 / r,
    eps21 = 1e-3, eps22 = c^2 r; C_phi1 = 1e-5 [5 c, 0.5, 10]; C_phi2 = 1e-5 [5, 0.5/c, 10/c];
    C_theta2 = 1e5 [1/c^2, 1/c, 1/c]; Gamma = 1e5 [5/c^2, 3, 20]; caps k1s_max = g1,
    k2s_max = g2 (the robust terms bounded: see :data:`FREE_START`).
    """
    c = PAPER_THETA1 / ident.theta.nominal[0]
    r = spec.sample_rate / PAPER_RATE
    ob = observer_design(spec.observer_pole, spec.period)
    g1, g2 = 600.0 * r, 850.0 * r
    return ArcGains(
        Ts=spec.period, k1=ob.k1, k2=ob.k2, w1=1.0, w2=0.1 / c ** 2, g1=g1, g2=g2,
        eps11=5e-5, eps12=5e-5 / r, eps21=1e-3, eps22=c ** 2 * r,
        C_phi1=(5e-5 * c, 5e-6, 1e-4), C_phi2=(5e-5, 5e-6 / c, 1e-4 / c),
        C_theta2=(1e5 / c ** 2, 1e5 / c, 1e5 / c),
        Gamma=(5e5 / c ** 2, 3e5, 2e6),
        theta_min=tuple(ident.theta.min), theta_max=tuple(ident.theta.max),  # type: ignore[arg-type]
        theta0=tuple(ident.theta.nominal),  # type: ignore[arg-type]
        fric_level=ident.fric_level, fric_slope=ident.fric_slope,
        k1s_max=g1, k2s_max=g2, u_max=spec.u_max,
    )


def apply_free(base: ArcGains, x: Sequence[float]) -> ArcGains:
    """ARC gains for the relative free gains ``x`` (order of :data:`FREE_BOUNDS`)."""
    k1 = base.g1 * x[0]
    k2 = base.g2 * x[1]
    # Theorem 1 needs c_theta2_r^2 >= w_k w2 / (2 c_phi_kr^2): a larger w2 scales C_theta2 by
    # sqrt(w2 / w2_base), which keeps every ratio of the condition at least the base's (5).
    ct = math.sqrt(max(1.0, x[7]))
    # theta_hat1(0) as a multiple of the nominal (base.theta0), kept inside the box.
    th10 = min(max(base.theta0[0] * x[8], base.theta_min[0]), base.theta_max[0])
    return dataclasses.replace(
        base, k1s_max=k1, k2s_max=k2, g1=k1 * x[2], g2=k2 * x[3],
        Gamma=(base.Gamma[0] * x[4], base.Gamma[1] * x[5], base.Gamma[2] * x[6]), w2=base.w2 * x[7],
        C_theta2=tuple(c * ct for c in base.C_theta2),  # type: ignore[arg-type]
        theta0=(th10, base.theta0[1], base.theta0[2]))


def free_gains(arc: ArcGains) -> FreeGains:
    """The free gains of ``arc``."""
    return FreeGains(k1s_max=arc.k1s_max, k2s_max=arc.k2s_max, g1=arc.g1, g2=arc.g2, Gamma=arc.Gamma, w2=arc.w2,
                     theta1_0=arc.theta0[0])


#: A *defaulted* PID pole whose baseline exceeds validate's default c_u limit on the tuning
#: scenarios is lowered along ``pid_pole x PID_POLE_STEP**k``, k = 1 .. PID_POLE_STEPS (down to 0.54 x).
PID_POLE_STEP = 0.95
PID_POLE_STEPS = 12


def pid_baseline(ident: Identification, spec: Spec) -> tuple[PidGains, float]:
    """The paper's PID (57): poles of (56) at ``-spec.pid_pole`` for M_min = 1/theta_max[0].

    Feedforward M_hat, B_hat = the identified M, B; friction compensation = the
    identified one; output limit ``spec.u_max``.  Returns ``(gains, M_min)``.
    """
    m_min = 1.0 / ident.theta.max[0]
    Kp, Ki, Kd = pid_place_poles(m_min, -spec.pid_pole)
    return PidGains(Ts=spec.period, M_hat=ident.value("M"), B_hat=max(ident.value("B"), 0.0), Kp=Kp, Ki=Ki,
                    Kd=Kd, fric_level=ident.fric_level, fric_slope=ident.fric_slope, u_max=spec.u_max), m_min


# --------------------------------------------------------------------------- evaluation


@dataclass(frozen=True)
class _Group:
    """Scenarios sharing one rendered trajectory (one batch-simulator call)."""

    idx: tuple[int, ...]
    traj: object
    plants: np.ndarray
    dist: np.ndarray | None
    quant: float
    noise: np.ndarray | None = None


class Evaluator:
    """Scores controllers on a fixed scenario list with the batch simulator.

    Trajectories are rendered once; each :meth:`scores` call runs one batch per
    trajectory over (candidates x scenarios).

    Parameters
    ----------
    scenarios : list of Scenario
    spec : Spec
        Sample rate and actuator limit ``u_max``.
    workers : int, optional
        Threads of the batch simulator.
    """

    def __init__(self, scenarios: Sequence[Scenario], spec: Spec, workers: int | None = None) -> None:
        self.scenarios = list(scenarios)
        self.spec = spec
        self.workers = workers
        #: Objective weight per scenario: the box corners (tune-only stand-ins for the
        #: Monte-Carlo sample) count CORNER_WEIGHT each, every other scenario 1.
        self.weights = [CORNER_WEIGHT if "corner" in s.tags else 1.0 for s in self.scenarios]
        groups: dict[tuple, list[int]] = {}
        for i, s in enumerate(self.scenarios):
            groups.setdefault((s.trajectory, s.y0, s.quantization, s.noise_std > 0), []).append(i)
        self.groups: list[_Group] = []
        for (tr, y0, qz, noisy), idx in groups.items():
            traj = tr.render(spec.period, y0)
            plants = np.stack([self.scenarios[i].plant for i in idx])
            d = np.stack([self.scenarios[i].disturbance.samples(traj.t) for i in idx])
            nz = np.stack([self.scenarios[i].noise(traj.n) for i in idx]) if noisy else None
            self.groups.append(_Group(tuple(idx), traj, plants, d if np.any(d) else None, qz, nz))

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.scenarios]

    def scores(self, kind: int, ctrl_ps: Sequence[np.ndarray]) -> list[list[Score]]:
        """``scores[c][s]`` of candidate ``c`` on scenario ``s``."""
        nc, ns = len(ctrl_ps), len(self.scenarios)
        out: list[list[Score | None]] = [[None] * ns for _ in range(nc)]
        P = np.stack(ctrl_ps)
        for g in self.groups:
            m = len(g.idx)
            plants = np.tile(g.plants, (nc, 1))
            cps = np.repeat(P, m, axis=0)
            dist = None if g.dist is None else np.tile(g.dist, (nc, 1))
            noise = None if g.noise is None else np.tile(g.noise, (nc, 1))
            r = simulate_batch(plants, kind, cps, g.traj, substeps=plant_substeps(self.spec.sample_rate),
                               quant=g.quant, disturbance=dist, noise=noise, y0=self.scenarios[g.idx[0]].y0,
                               u_sat=self.spec.u_max, e_abort=self.spec.travel, workers=self.workers)
            # No traces: the kernel's u_peak (recorded samples, also before an abort) is all that is needed.
            for c in range(nc):
                for j, si in enumerate(g.idx):
                    row = c * m + j
                    out[c][si] = Score(float(r.e_M[row]), float(r.e_F[row]), float(r.e_rms[row]),
                                       float(r.u_rms[row]), float(r.du_rms[row]), float(r.c_u[row]),
                                       float(r.u_peak[row]), bool(r.diverged[row]))
        return out  # type: ignore[return-value]


@dataclass(frozen=True)
class PidBaseline:
    """The PID baseline of (57) as tune runs it (:func:`deployable_pid`).

    Attributes
    ----------
    gains : PidGains
    pole : float
        Triple closed-loop pole of (56), rad/s.
    design_mass : float
        M_min = 1/theta_max[0], u-unit s^2/m.
    scores : list of Score
        On the tuning scenarios, in the Evaluator's order.
    """

    gains: PidGains
    pole: float
    design_mass: float
    scores: list[Score]


def deployable_pid(ident: Identification, spec: Spec, ev: Evaluator, c_u_limit: float,
                   pole_free: bool) -> PidBaseline:
    """The paper's PID (57) at ``spec.pid_pole``, or at the fastest pole the gate's c_u allows.

    The baseline the ARC must beat should be one a user could deploy.  The default pole,
    0.12 f_s, carries the paper's -300 rad/s at 2.5 kHz to other rates; the PID's
    backward-difference derivative turns each encoder step q into a velocity step q f_s, so
    on a coarse encoder at a high rate that PID chatters beyond validate's c_u limit by
    itself (random axes 0 and 27 of :func:`commission.synth.random_axis`, 0.82-0.84 um at
    4 kHz: c_u 1.12 and 1.17 at 480 rad/s, limit 1).  When the pole was defaulted
    (``pole_free``) and that PID exceeds ``c_u_limit`` on a tuning scenario, the pole is
    lowered to the fastest of ``spec.pid_pole x PID_POLE_STEP**k`` (k = 1 ..
    :data:`PID_POLE_STEPS`) whose PID stays within it on every tuning scenario: the
    strongest PID of the paper's family that the gate's chattering limit accepts.  The
    candidates are simulated in one batch.  When none does, or the pole was set in the
    spec, the spec's pole is kept (``tune`` then warns when its gate fails).
    """
    pid, m_min = pid_baseline(ident, spec)
    scores = ev.scores(KIND_PID, [pid_pack(pid)])[0]

    def within(sc: Sequence[Score]) -> bool:
        return all(math.isfinite(s.c_u) and s.c_u <= c_u_limit and not s.diverged for s in sc)

    if not pole_free or within(scores):
        return PidBaseline(pid, spec.pid_pole, m_min, scores)
    poles = [spec.pid_pole * PID_POLE_STEP ** k for k in range(1, PID_POLE_STEPS + 1)]
    cands = [pid_baseline(ident, dataclasses.replace(spec, pid_pole=w))[0] for w in poles]
    for w, g, sc in zip(poles, cands, ev.scores(KIND_PID, [pid_pack(g) for g in cands])):
        if within(sc):
            return PidBaseline(g, w, m_min, sc)
    return PidBaseline(pid, spec.pid_pole, m_min, scores)


def cost(scores: Sequence[Score], spec: Spec, reference: Sequence[Score] | None = None,
         weights: Sequence[float] | None = None, gate: GateLimits | None = None) -> float:
    """Objective of one candidate (lower is better): see the module docstring, step 4.

    Per scenario::

        ln(e_rms / targets.e_rms)                                   objective
        + W_TARGET  ln(e_F / targets.e_f)^+                          accuracy target
        + W_CHATTER ln(c_u / targets.c_u)^+ + W_STEP [c_u > target]  chattering target
        + W_SATURATION [|u| reached u_max]                           input limit
        + W_CHATTER ln(e_rms / (m e_rms_ref))^+ + W_STEP [e_rms > m ref]   better than the PID
                                                                     by the margin m = PID_MARGIN
        + W_CHATTER ln(e_M / e_M_ref)^+ + W_STEP [e_M > e_M_ref]     and on the transient

    averaged over the scenarios with ``weights`` (default equal), plus
    ``W_WORST max_s ln(e_rms / (e_rms_ref + slack))``: the scenario where the ARC gains least
    over the PID (often the heavy payload) counts again, so the search does not
    trade it away for the easy scenarios.  A diverged run
    counts W_DIVERGED.  ``reference`` are the PID baseline's scores on the same
    scenarios (optional).

    ``gate`` (optional) are validate's default gate limits for this axis.  Their ARC-vs-PID
    ``slack`` (m; the encoder's quantization-noise rms,
    :data:`commission.gate.DEFAULT_ARC_VS_PID_SLACK_LSB`) enters the minimax term only: there
    it keeps a scenario where both controllers sit at the quantization floor from dominating
    the objective.  (In the per-scenario margin penalty it made the search settle for less on
    the paper's axis: Case 2 e_rms 1.75 um against 0.61 um without it.)  And every check the
    gate would fail on these scenarios adds :data:`W_GATE`, unweighted: the targets above are
    stricter than the gate, and where they cannot be met (c_u on a coarse encoder, where the
    PID itself sits near the gate's c_u limit) their smooth penalties do not say on which side
    of the gate's threshold a candidate lands.
    """
    total = 0.0
    wsum = 0.0
    worst = -math.inf
    slack = 0.0 if gate is None else gate.arc_vs_pid_slack
    for i, s in enumerate(scores):
        w = 1.0 if weights is None else float(weights[i])
        wsum += w
        if s.diverged or not math.isfinite(s.e_rms) or s.e_rms <= 0:
            total += w * W_DIVERGED
            continue
        j = math.log(s.e_rms / spec.e_rms)
        if reference is not None:
            r = reference[i]
            if not r.diverged and math.isfinite(r.e_rms) and r.e_rms > 0:
                worst = max(worst, math.log(s.e_rms / (r.e_rms + slack)))
                ref = PID_MARGIN * r.e_rms
                if ref < s.e_rms:
                    j += W_STEP + W_CHATTER * math.log(s.e_rms / ref)
            if not r.diverged and math.isfinite(r.e_M) and 0 < r.e_M < s.e_M:
                # The transient too (the start-up against unlearnt estimates): e_rms alone let the
                # search trade the empty axis's start-up for a softer command.
                j += W_STEP + W_CHATTER * math.log(s.e_M / r.e_M)
        if s.e_F > 0:
            j += W_TARGET * max(0.0, math.log(s.e_F / spec.e_f))
        if not (math.isfinite(s.c_u) and s.c_u >= 0):
            j += W_STEP + W_CHATTER
        elif s.c_u > spec.c_u:
            j += W_STEP + W_CHATTER * math.log(s.c_u / spec.c_u)
        if s.u_peak >= spec.u_max * (1.0 - 1e-9):
            j += W_SATURATION
        total += w * j
    out = total / wsum if wsum > 0 else 0.0
    if math.isfinite(worst):
        out += W_WORST * worst
    if gate is not None and reference is not None:
        runs = [(str(i), a, p, math.nan) for i, (a, p) in enumerate(zip(scores, reference))]
        out += W_GATE * len(evaluate_gate(gate, runs).failures)
    return out


def meets_targets(scores: Sequence[Score], spec: Spec) -> bool:
    """Every run finite, within e_f and c_u targets and below the input limit."""
    return all(not s.diverged and s.e_F <= spec.e_f and s.c_u <= spec.c_u and s.u_peak < spec.u_max
               for s in scores)


# --------------------------------------------------------------------------- search


@dataclass(frozen=True)
class SearchResult:
    """Every candidate of the search, best first.

    Attributes
    ----------
    x : numpy.ndarray
        Relative free gains, shape (n, N_FREE), sorted by cost.
    costs : numpy.ndarray
        Cost of each, shape (n,).
    scores : list of list of Score
        Scores of each on the evaluator's scenarios.
    feasibility : list of FeasibilityReport or None
        Discrete-feasibility report of each candidate that was checked (None: not checked).
    cost_initial : float
        Cost of :data:`FREE_START`.
    history : tuple of float
        Every cost in evaluation order.
    best : int or None
        Index (in the sorted order) of the lowest-cost candidate whose feasibility
        holds; None when no checked candidate holds.
    """

    x: np.ndarray
    costs: np.ndarray
    scores: list[list[Score]]
    feasibility: list[FeasibilityReport | None]
    cost_initial: float
    history: tuple[float, ...]
    best: int | None


def search_step(generation: int) -> float:
    """Log-step of the search's ``generation`` (0 first): 1, then x``SHRINK`` per generation, floored at :data:`STEP_FLOOR`."""
    step = 1.0
    for _ in range(generation):  # repeated products, as the search has always computed them
        step = max(step * SHRINK, STEP_FLOOR)
    return step


class SearchRun:
    """The state of one search (:func:`search`), which :meth:`advance` can continue.

    Continuing after whole generations (a multiple of ``POP``, as every defaulted budget
    is) with the same Generator is the same as having asked for the larger budget at once:
    every candidate depends only on the Generator's draws and the candidates before it, and
    the step of each generation only on its index (:func:`search_step`).  :func:`tune`
    continues a search whose best candidates fail the hold-out gate
    (:func:`search_extension`); it draws the hold-out plants from the Generator in between,
    so its continued candidates are not those of a larger budget at once.
    """

    def __init__(self, base: ArcGains, ev: Evaluator, spec: Spec, *,
                 feasible: Callable[[ArcGains], FeasibilityReport], reference: Sequence[Score] | None = None,
                 gate: GateLimits | None = None) -> None:
        self.base, self.ev, self.spec, self.feasible = base, ev, spec, feasible
        self.reference, self.gate = reference, gate
        lo, hi = FREE_LOG_LO.copy(), FREE_LOG_HI.copy()
        if spec.theta1_0 is not None:  # theta_hat1(0) fixed by the spec: pin its axis
            lo[I_THETA1_0] = hi[I_THETA1_0] = math.log(spec.theta1_0 / base.theta0[0])
        self.lo, self.hi = lo, hi
        self.x0 = np.clip(np.log(FREE_START), lo, hi)
        self.X: list[np.ndarray] = []
        self.C: list[float] = []
        self.S: list[list[Score]] = []
        self.F: dict[int, FeasibilityReport] = {}
        self.best_i: int | None = None
        self.generation = 0

    def advance(self, n_more: int, rng: np.random.Generator, progress: Progress | None = None,
                progress_total: int | None = None) -> None:
        """Simulate ``n_more`` further candidates (whole generations of ``POP``, the last one cut)."""
        X, C, S, F, lo, hi = self.X, self.C, self.S, self.F, self.lo, self.hi
        budget = len(X) + n_more
        total = progress_total if progress_total is not None else budget
        while len(X) < budget:
            n = min(POP, budget - len(X))
            step = search_step(self.generation)
            self.generation += 1
            center = self.x0 if self.best_i is None else X[self.best_i]
            if not X:
                fixed = [self.x0] + [np.clip(np.log(e), lo, hi) for e in (paper_implementable_start(), *EXTRA_STARTS)]
                cand = fixed[:n] + [np.clip(self.x0 + step * rng.standard_normal(N_FREE), lo, hi)
                                    for _ in range(n - len(fixed[:n]))]
            else:
                cand = [np.clip(center + step * rng.standard_normal(N_FREE), lo, hi) for _ in range(n)]
            gains = [apply_free(self.base, np.exp(c)) for c in cand]
            sc = self.ev.scores(KIND_ARC, [arc_pack(g) for g in gains])
            first = len(X)
            for c, sco in zip(cand, sc):
                X.append(c)
                C.append(cost(sco, self.spec, self.reference, self.ev.weights, self.gate))
                S.append(sco)
            bound = C[self.best_i] if self.best_i is not None else math.inf
            for i in sorted(range(first, len(X)), key=lambda i: C[i]):
                if not C[i] < bound:
                    break
                if any(r.diverged for r in S[i]):
                    continue  # a run that aborted is never chosen: skip its feasibility check
                F[i] = self.feasible(gains[i - first])
                if F[i].holds:
                    self.best_i = i
                    break
            if progress is not None:
                progress(len(X), total)

    def result(self) -> SearchResult:
        """Every candidate so far, best first."""
        C = self.C
        order = [int(i) for i in np.argsort(C, kind="stable")]
        rank = {i: r for r, i in enumerate(order)}
        return SearchResult(x=np.exp(np.array(self.X)[order]), costs=np.array(C)[order],
                            scores=[self.S[i] for i in order], feasibility=[self.F.get(i) for i in order],
                            cost_initial=C[0], history=tuple(C),
                            best=None if self.best_i is None else rank[self.best_i])


def search(base: ArcGains, ev: Evaluator, spec: Spec, rng: np.random.Generator, *,
           feasible: Callable[[ArcGains], FeasibilityReport], budget: int | None = None,
           reference: Sequence[Score] | None = None, progress: Progress | None = None,
           progress_total: int | None = None, gate: GateLimits | None = None) -> SearchResult:
    """Coarse-to-fine seeded random search of the free gains in log space, feasibility-constrained.

    Generation 0 holds :data:`FREE_START`, :func:`paper_implementable_start`,
    :data:`EXTRA_STARTS` and random points
    drawn with a log-step of 1 (a factor e) per axis around the start; each later generation draws ``POP``
    points around the best *feasible* candidate so far with the step of :func:`search_step`
    (shrunk by ``SHRINK`` down to :data:`STEP_FLOOR`), clipped to :data:`FREE_BOUNDS`.  Feasibility (``feasible``, the
    discrete check over the theta box) is evaluated lazily: after each
    generation, the candidates that beat the best feasible cost are checked in
    order of cost until one holds.  Stops after ``budget`` candidates (:class:`SearchRun` continues one).
    """
    run = SearchRun(base, ev, spec, feasible=feasible, reference=reference, gate=gate)
    run.advance(spec.budget if budget is None else budget, rng, progress, progress_total)
    return run.result()


# --------------------------------------------------------------------------- hold-out selection and repair

#: Candidates (best cost first, discrete feasibility holding) that :func:`select_on_holdout` compares.
HOLDOUT_CANDIDATES = 6
#: Monte-Carlo plants of the hold-out sample (drawn from tune's Generator, not validate's).
HOLDOUT_PLANTS = 32
#: The repair's random local search (:func:`repair_on_holdout`): candidates per round; the
#: initial log-step (0.2: a factor 1.22 per coordinate at one sigma); while more than REPAIR_NEAR
#: checks fail, every second draw of a round takes REPAIR_WIDE x the step; the step of an accepted
#: draw carries on (at most REPAIR_MAX_STEP), and a round with none shrinks it by REPAIR_SHRINK
#: (floor REPAIR_MIN_STEP).  Measured on :func:`commission.synth.random_axis` (tune seed 0):
#: with a single step of 0.5 the repair accepted at most one move on the six failing 4-5 kHz axes
#: (0, 1, 16, 19, 23, 27; near a thin stability margin most such draws fail more); with 0.2,
#: axes 1 and 23 (one hold-out failure) passed but axis 11 (1 kHz, 26 failures, which passed
#: with x3 single-gain moves before) did not; with half the draws wide in every round, axis 11
#: passed and axes 1 and 23 did not (half the budget went to wide draws).
REPAIR_POP = 8
REPAIR_STEP = 0.2
REPAIR_WIDE = 3.0
REPAIR_MAX_STEP = 0.4
REPAIR_NEAR = 4
REPAIR_SHRINK = 0.85
REPAIR_MIN_STEP = 0.08
#: Factors of the repair's first round when the chosen gains chatter beyond the gate's c_u on a
#: tuning scenario (:func:`repair_on_holdout`): the k2 cap, then both caps, times each.
REPAIR_CAP_FACTORS = (0.95, 0.9, 0.85, 0.8)
#: Range of the factor the repair may apply to a *defaulted* observer pole (controller.observer_pole).
#: Below about 0.5 x the default (0.08 f_s) the heavy plants of a coarse-encoder axis lose stability
#: (axis 0 of :func:`commission.synth.random_axis`: 332 gate failures at 0.5 x); a faster observer
#: passes more encoder noise into the velocity estimate.
OBSERVER_FACTOR_BOUNDS = (0.6, 1.25)
#: Candidates :func:`repair_on_holdout` may simulate at 2.5 kHz and above (four and a half rounds of
#: :data:`REPAIR_POP`); below, :func:`repair_budget` raises it with the falling cost of a simulation.
REPAIR_BUDGET = 36
#: The repair's secondary objective measures each index against this fraction of its gate limit,
#: so that once nothing fails it still prefers gains with room to spare on plants it has not seen.
REPAIR_MARGIN = 0.9
#: Excess counted for a diverged run in the repair's secondary objective (ln units).
REPAIR_DIVERGED_EXCESS = 10.0


def repair_budget(spec: Spec, scale: float = 1.0) -> int:
    """Candidates the hold-out repair may simulate: :data:`REPAIR_BUDGET` x max(1, 2.5 kHz / f_s).

    A simulation's cost is proportional to its samples, so below the paper's rate the same
    wall time buys more moves (90 at 1 kHz).  A 1 kHz axis of
    :func:`commission.synth.random_axis` (seed 11) starts the repair at 26 hold-out failures;
    with 90 candidates it ended at 2, and the result passed validate's gate.
    Where one search candidate is already too expensive (``scale`` = :func:`work_scale` < 1),
    the repair gets two rounds, :data:`MIN_REPAIR_BUDGET`: each of its candidates is judged
    on the tuning scenarios plus the hold-out plants, 1.8x a search candidate's work.  (The
    paper's axis at 4 kHz with a 0.2 m/s envelope, whose hold-out fails: 21 repair
    candidates took it to 122 s.)
    """
    if scale < 1.0:
        return MIN_REPAIR_BUDGET
    return int(round(REPAIR_BUDGET * max(1.0, PAPER_RATE / spec.sample_rate)))


def candidate_work(ident: Identification, spec: Spec) -> float:
    """Simulation work of one search candidate on the tuning set, in plant sub-steps.

    Sum over :func:`commission.scenarios.tuning_scenarios` of samples x
    (:data:`ARC_STEP_WORK` + :func:`commission.scenarios.plant_substeps`): the wall time of
    the search is proportional to it.  Slow envelopes make it large (Case 1 lasts four of
    its periods, Case 2 six moves of the stroke), and so do high sample rates.
    """
    per_sample = ARC_STEP_WORK + plant_substeps(spec.sample_rate)
    # The Generator only draws spec.monte_carlo plants; durations do not depend on them.
    scen = tuning_scenarios(ident, spec, rng=np.random.default_rng(0))
    return float(sum(round(s.trajectory.duration * spec.sample_rate) * per_sample for s in scen))


def work_scale(ident: Identification, spec: Spec) -> float:
    """min(1, :data:`WORK_CAP` / :func:`candidate_work`): the share of the default budgets that fits."""
    return min(1.0, WORK_CAP / candidate_work(ident, spec))


def work_scaled_budget(spec: Spec, ident: Identification, given: bool) -> tuple[Spec, tuple[str, ...]]:
    """Shrink a *defaulted* ``tune.budget`` where one candidate costs more than :data:`WORK_CAP`.

    96 candidates on a 4 kHz axis whose envelope is 0.2 m/s simulate 3.4x the paper axis'
    work each and took 131 s on 2 cores (target: 120 s).  The budget becomes
    ``POP x round(budget x scale / POP)``, at least :data:`MIN_BUDGET`; the hold-out repair
    gets one round (:func:`repair_budget`).  A budget the user set is kept.
    """
    if given:
        return spec, ()
    work = candidate_work(ident, spec)
    n = max(MIN_BUDGET, POP * int(round(spec.budget * min(1.0, WORK_CAP / work) / POP)))
    if n >= spec.budget:
        return spec, ()
    return dataclasses.replace(spec, budget=n), (
        f"tune.budget defaulted to {n} instead of {spec.budget}: one candidate simulates "
        f"{work / WORK_CAP:.2g} x the work the default budget is sized for "
        f"(slow envelope or high sample rate); set tune.budget to search longer",)


def search_extension(spec: Spec, ident: Identification, given: bool) -> int:
    """Candidates a *defaulted* search may continue with when its best fail the hold-out gate.

    The surrogate objective is scored on the tuning scenarios only; where the best
    candidates still fail validate's default gate on the hold-out plants
    (:func:`select_on_holdout`), :func:`tune` continues the search (:class:`SearchRun`) up to
    the work of the slowest defaulted search, ``budget x WORK_CAP``: ``POP x floor((budget x
    WORK_CAP / candidate_work - budget) / POP)``, at most ``budget`` more.  Light
    4-5 kHz axes (15e6 per candidate) get 40; the paper's axis (12e6) 80; a work-scaled
    budget (:func:`work_scaled_budget`) none.  (Random axes of
    :func:`commission.synth.random_axis`: on seed 11, 1 kHz, the first 96 candidates' best
    failed 6 hold-out checks and needed the repair; the best of 192 fail none.  On seed 0,
    4 kHz, 3 and then none.)  A budget the user set is kept: 0.
    """
    if given:
        return 0
    room = spec.budget * WORK_CAP / candidate_work(ident, spec) - spec.budget
    return max(0, min(spec.budget, POP * int(room // POP)))


@dataclass(frozen=True)
class PidChatter:
    """Where the PID baseline exceeds the default gate's c_u on the tuning scenarios.

    Attributes
    ----------
    limit : float
        The gate's c_u limit.
    count : int
        Scenarios where the PID's c_u exceeds it.
    worst : float
        The PID's largest c_u.
    scenario : str
        Where it occurs.
    """

    limit: float
    count: int
    worst: float
    scenario: str


def pid_chatter(tuning: Tuning) -> PidChatter | None:
    """The PID baseline's c_u above the default gate's limit on the recorded tuning scores, or None.

    When the paper's PID, placed at M_min, already chatters beyond the limit, the encoder's
    step at this sample rate, not the ARC's tuning, sets the chattering floor.
    """
    limit = default_gate_limits(tuning.identification, tuning.spec).c_u
    over = [(row["pid"].c_u, name) for name, row in tuning.scores.items()
            if math.isfinite(row["pid"].c_u) and row["pid"].c_u > limit]
    if not over:
        return None
    worst, name = max(over)
    return PidChatter(limit=limit, count=len(over), worst=worst, scenario=name)


def pid_pole_note(tuning: Tuning) -> str | None:
    """One line for the user when the PID baseline runs below the spec's pole (:func:`deployable_pid`)."""
    if not tuning.pid_pole < tuning.spec.pid_pole:
        return None
    return (f"the PID baseline runs at pid.pole = {tuning.pid_pole:.3g} rad/s instead of the defaulted "
            f"{tuning.spec.pid_pole:.3g}: there it exceeds validate's default c_u limit on a tuning scenario "
            f"(encoder step {tuning.quantization * 1e6:.3g} um at {tuning.spec.sample_rate:g} Hz); "
            f"set pid.pole to compare with another PID")


def default_gate_limits(ident: Identification, spec: Spec) -> GateLimits:
    """validate's default gate (an empty ``gate.toml``) resolved for this axis and spec."""
    return resolve_gate(GateSpec(), lsb=resolve_quantization(ident, spec), travel=spec.travel, u_max=spec.u_max)


class HoldoutGate:
    """validate's default gate on the tuning scenarios plus fresh Monte-Carlo plants.

    The search scores candidates on the tuning scenarios only; what decides deployment is
    the gate on validate's matrix, whose Monte-Carlo plants the search never saw.  This
    stands in for it inside ``tune``: :data:`HOLDOUT_PLANTS` plants drawn from tune's own
    Generator (independent of validate's seeded sample), the PID baseline scored on them
    once, and the default :class:`~commission.gate.GateSpec` resolved for this axis.

    Parameters
    ----------
    ident : Identification
    spec : Spec
    ev : Evaluator
        The search's evaluator (tuning scenarios).
    pid : PidGains
        The PID baseline.
    pid_scores : sequence of Score
        The PID's scores on ``ev``'s scenarios.
    rng : numpy.random.Generator
        Draws the hold-out plants.
    workers : int, optional
        Batch-simulator threads.
    n_plants : int
        Hold-out Monte-Carlo plants.
    """

    def __init__(self, ident: Identification, spec: Spec, ev: Evaluator, pid: PidGains,
                 pid_scores: Sequence[Score], *, rng: np.random.Generator, workers: int | None = None,
                 n_plants: int = HOLDOUT_PLANTS) -> None:
        plants = [s for s in scenario_matrix(ident, spec, rng=rng, n_monte_carlo=n_plants) if "monte_carlo" in s.tags]
        self.ev = ev
        self.ev_h = Evaluator(plants, spec, workers=workers)
        self.pid_scores = [*pid_scores, *self.ev_h.scores(KIND_PID, [pid_pack(pid)])[0]]
        self.limits = default_gate_limits(ident, spec)
        self.names = [*ev.names, *self.ev_h.names]

    @property
    def n_plants(self) -> int:
        return len(self.ev_h.scenarios)

    def judge(self, gains: Sequence[ArcGains],
              tune_scores: Sequence[Sequence[Score]] | None = None) -> list[tuple[list[Score], int, float]]:
        """``(tuning-scenario scores, gate failures, excess)`` of each candidate.

        ``tune_scores`` (the candidates' scores on the tuning scenarios, when already
        simulated) saves that half of the work.  ``excess`` is :func:`gate_excess`.
        """
        packs = [arc_pack(g) for g in gains]
        ts = [list(s) for s in tune_scores] if tune_scores is not None else self.ev.scores(KIND_ARC, packs)
        hs = self.ev_h.scores(KIND_ARC, packs)
        out = []
        for t, h in zip(ts, hs):
            arc = [*t, *h]
            runs = [(n, a, p, math.nan) for n, a, p in zip(self.names, arc, self.pid_scores)]
            out.append((t, len(evaluate_gate(self.limits, runs).failures), gate_excess(self.limits, arc,
                                                                                    self.pid_scores)))
        return out


def gate_excess(limits: GateLimits, arc: Sequence[Score], pid: Sequence[Score],
                margin: float = REPAIR_MARGIN) -> float:
    """Summed log-excess of the ARC's indexes over ``margin`` x their gate limits (0: all within).

    Per scenario: ``sum ln(index / (margin limit))^+`` over e_F, e_M, e_rms, c_u, the peak
    |u| (against u_max: a clipped command counts ln(1/margin)) and the ARC-vs-PID e_rms
    (against ``factor x PID + slack``); a diverged run counts :data:`REPAIR_DIVERGED_EXCESS`.
    A smooth companion of the failure count: it tells apart two gain sets that fail
    equally often, by how far they miss.
    """
    total = 0.0
    for a, p in zip(arc, pid):
        if a.diverged or not math.isfinite(a.e_rms):
            total += REPAIR_DIVERGED_EXCESS
            continue
        ratios = [a.e_F / limits.e_F, a.e_M / limits.e_M, a.e_rms / limits.e_rms, a.c_u / limits.c_u,
                  a.u_peak / limits.u_max]
        if not p.diverged and math.isfinite(p.e_rms):
            ratios.append(a.e_rms / (limits.arc_vs_pid_e_rms * p.e_rms + limits.arc_vs_pid_slack))
        for r in ratios:
            if not math.isfinite(r):  # an index undefined (NaN) or unbounded counts as a diverged run
                total += REPAIR_DIVERGED_EXCESS
            elif r > margin:
                total += math.log(r / margin)
    return total


@dataclass(frozen=True)
class HoldoutChoice:
    """Outcome of :func:`select_on_holdout`.

    Attributes
    ----------
    chosen : int
        Index into the search result (cost order).
    n_plants : int
        Hold-out plants simulated.
    failures : tuple of int
        Default-gate failures (tuning scenarios + hold-out plants) of each compared
        candidate, in cost order; the chosen one has the fewest (ties: lower cost).
    feasibility : FeasibilityReport or None
        The chosen candidate's discrete-feasibility report, when it was checked.
    excess : float
        The chosen candidate's :func:`gate_excess` (nan when nothing was compared).
    """

    chosen: int
    n_plants: int
    failures: tuple[int, ...]
    feasibility: FeasibilityReport | None
    excess: float = math.nan


def select_on_holdout(res: SearchResult, base: ArcGains, hg: HoldoutGate,
                      feasible: Callable[[ArcGains], FeasibilityReport],
                      memo: dict[tuple[str, bytes], Any] | None = None) -> HoldoutChoice:
    """Choose among the best feasible candidates by validate's default gate on unseen plants.

    The objective is a smooth surrogate, scored on the tuning scenarios only.  So the
    :data:`HOLDOUT_CANDIDATES` lowest-cost candidates whose discrete feasibility holds are
    judged by ``hg`` (the default gate over the tuning scenarios and the hold-out plants):
    the candidate with the fewest failures wins, ties going to the lower cost.

    ``memo`` (keyed by a candidate's relative free gains) keeps feasibility reports and
    judgements across calls with the same ``hg``: after the search's extension most of
    the six best were judged already, and a judgement depends only on the gains.
    """
    memo = {} if memo is None else memo
    order: list[int] = []
    reps: dict[int, FeasibilityReport] = {}
    for i in range(len(res.costs)):
        if len(order) == HOLDOUT_CANDIDATES:
            break
        if any(r.diverged for r in res.scores[i]):
            continue
        key = ("feasibility", res.x[i].tobytes())
        rep = res.feasibility[i] or memo.get(key) or feasible(apply_free(base, res.x[i]))
        memo[key] = reps[i] = rep
        if rep.holds:
            order.append(i)
    if not order:  # nothing feasible: report the best candidate, failing
        i = res.best if res.best is not None else 0
        return HoldoutChoice(i, 0, (), reps.get(i, res.feasibility[i]))
    keys = {i: ("judgement", res.x[i].tobytes()) for i in order}
    todo = [i for i in order if keys[i] not in memo]
    if todo:
        for i, j in zip(todo, hg.judge([apply_free(base, res.x[i]) for i in todo], [res.scores[i] for i in todo])):
            memo[keys[i]] = j
    judged = [memo[keys[i]] for i in order]
    best = min(range(len(order)), key=lambda k: (judged[k][1], k))
    return HoldoutChoice(order[best], hg.n_plants, tuple(j[1] for j in judged), reps[order[best]],
                         judged[best][2])


@dataclass(frozen=True)
class RepairResult:
    """Outcome of :func:`repair_on_holdout`.

    Attributes
    ----------
    x : numpy.ndarray
        Relative free gains after the accepted moves, shape (N_FREE,).
    observer_pole : float
        Observer pole of the result, rad/s (the spec's unless the repair moved a defaulted one).
    scores : list of Score
        Their scores on the tuning scenarios.
    failures : int
        Default-gate failures on the tuning scenarios + hold-out plants after the moves.
    excess : float
        Their :func:`gate_excess`.
    moves : tuple of str
        Accepted moves in order, one string per move naming each coordinate it changed by more
        than 5 %, e.g. ``"k2 /1.31, w2 x1.6, ob /1.12"`` (names of :data:`REPAIR_NAMES`: g1, g2
        as multiples of their base values, ``ob`` the observer pole).
    evaluations : int
        Candidates simulated.
    feasibility : FeasibilityReport
        Discrete-feasibility report of the result.
    """

    x: np.ndarray
    observer_pole: float
    scores: list[Score]
    failures: int
    excess: float
    moves: tuple[str, ...]
    evaluations: int
    feasibility: FeasibilityReport


def with_observer(g: ArcGains, pole: float) -> ArcGains:
    """``g`` with the observer gains k1 = 2 p, k2 = p^2 of a double pole at ``-pole`` (rad/s)."""
    ob = observer_design(pole, g.Ts)
    return dataclasses.replace(g, k1=ob.k1, k2=ob.k2)


#: Names of the repair's coordinates (:func:`repair_coordinates`).
REPAIR_NAMES = ("k1", "k2", "g1", "g2", "G1", "G2", "G3", "w2", "t1", "ob")
I_F1, I_F2 = 2, 3


def repair_coordinates(x: np.ndarray, observer_factor: float) -> np.ndarray:
    """The repair's log coordinates of relative free gains ``x`` and an observer-pole factor.

    As :data:`FREE_BOUNDS` but with g1, g2 as multiples of their base values instead of
    fractions of their caps, and the observer-pole factor appended: a move of a cap then
    keeps g (up to the cap).  On a coarse encoder the chatter follows the cap more than g
    (axis 16 of :func:`commission.synth.random_axis`: the k2 cap x0.7 with g2 kept cut
    validate's failures from 14 to 6); that is one move here and two (k2 down, f2 up) in
    the search's coordinates.
    """
    r = np.log(np.append(np.asarray(x, dtype=np.float64), observer_factor))
    r[I_F1] += r[0]
    r[I_F2] += r[1]
    return r


def free_of_repair(r: np.ndarray) -> tuple[np.ndarray, float]:
    """Inverse of :func:`repair_coordinates`: ``(x, observer_factor)``.

    g1, g2 above their caps are clipped to them (f1, f2 within :data:`FREE_BOUNDS`); every
    other coordinate passes unchanged, so a theta_hat1(0) pinned by the spec outside the
    search box stays pinned.
    """
    z = np.array(r[:N_FREE], dtype=np.float64)
    for i, k in ((I_F1, 0), (I_F2, 1)):
        z[i] = min(max(z[i] - z[k], FREE_LOG_LO[i]), FREE_LOG_HI[i])
    return np.exp(z), math.exp(r[N_FREE])


def _move_name(before: np.ndarray, after: np.ndarray) -> str:
    """The repair coordinates a move changed by more than 5 %, as ``"k2 /1.31, ob x1.1"``."""
    parts = []
    for name, u, v in zip(REPAIR_NAMES, before, after):
        r = math.exp(v - u)
        if r > 1.05:
            parts.append(f"{name} x{r:.3g}")
        elif r < 1 / 1.05:
            parts.append(f"{name} /{1 / r:.3g}")
    return ", ".join(parts) or "(< 5 % on every gain)"


def repair_on_holdout(x0: np.ndarray, scores0: Sequence[Score], failures0: int, excess0: float,
                      feasibility0: FeasibilityReport, base: ArcGains, hg: HoldoutGate, spec: Spec,
                      feasible: Callable[[ArcGains], FeasibilityReport], rng: np.random.Generator, *,
                      observer_free: bool, budget: int = REPAIR_BUDGET,
                      progress: Callable[[int], None] | None = None) -> RepairResult:
    """Random local search that minimises the hold-out gate's failures from the chosen gains.

    When the chosen gains still fail the default gate on the hold-out (plants between the
    tuning scenarios: a payload the theta1 adaptation over-learns, chatter just above
    the limit), the surrogate objective has no say left; the gate itself is then
    minimised.  When the chosen gains exceed the gate's c_u on a tuning scenario, the
    first round is a line search: the k2 cap, then both caps, times each of
    :data:`REPAIR_CAP_FACTORS`, every other gain kept.  Each other round draws
    :data:`REPAIR_POP` candidates around the current gains,
    log-normal on every coordinate of :func:`repair_coordinates` at once, inside
    :data:`FREE_BOUNDS`, with the current step (initially :data:`REPAIR_STEP`); while
    more than :data:`REPAIR_NEAR` checks fail, half of them with :data:`REPAIR_WIDE` x it.  The step of an accepted draw carries on (at most
    :data:`REPAIR_MAX_STEP`); a round that accepts none shrinks it by :data:`REPAIR_SHRINK`
    (floor :data:`REPAIR_MIN_STEP`).  When ``observer_free`` (the
    spec's observer pole was defaulted) the observer pole is a coordinate too, within
    :data:`OBSERVER_FACTOR_BOUNDS` of the spec's; a pinned theta_hat1(0) stays pinned.
    The candidates are simulated on the tuning scenarios and the hold-out plants; the best
    by (gate failures, :func:`gate_excess`) is taken if it beats the current gains and
    its discrete feasibility holds.  It stops when nothing fails or exceeds
    :data:`REPAIR_MARGIN` of a limit, or after ``budget`` candidates.

    Why joint moves: on a coarse encoder the chatter limit and the ARC-vs-PID limit bind
    together and the stability margin is thin, so the gains that pass differ from the
    chosen ones by small amounts in several coordinates at once.  The earlier repair moved
    one gain at a time by x/÷ 3, 1.7, 1.3 and left axes 1 and 23 of
    :func:`commission.synth.random_axis` at one failure on validate's matrix; with these
    joint moves both pass, and axis 11 (1 kHz, 26 hold-out failures) still does.
    """
    flo, fhi = FREE_LOG_LO, FREE_LOG_HI
    # bounds in repair coordinates: g as a multiple of its base spans f_lo x cap_lo .. cap_hi
    lo = np.append(flo, math.log(OBSERVER_FACTOR_BOUNDS[0]))
    hi = np.append(fhi, math.log(OBSERVER_FACTOR_BOUNDS[1]))
    lo[I_F1], hi[I_F1] = flo[0] + flo[I_F1], fhi[0]
    lo[I_F2], hi[I_F2] = flo[1] + flo[I_F2], fhi[1]
    fixed = [k for k in range(N_FREE + 1) if (k == I_THETA1_0 and spec.theta1_0 is not None)
             or (k == N_FREE and not observer_free)]
    z = repair_coordinates(x0, 1.0)
    lo[fixed], hi[fixed] = z[fixed], z[fixed]

    def gains(c: np.ndarray) -> ArcGains:
        x, f = free_of_repair(c)
        g = apply_free(base, x)
        return g if f == 1.0 else with_observer(g, spec.observer_pole * f)

    key = (failures0, excess0)
    scores, rep = list(scores0), feasibility0
    moves: list[str] = []
    n, step = 0, REPAIR_STEP

    def try_round(cand: list[np.ndarray]) -> int | None:
        """Judge ``cand``; take the best that beats the current gains and is feasible."""
        nonlocal z, scores, rep, key, n
        cand_gains = [gains(c) for c in cand]
        judged = hg.judge(cand_gains)
        n += len(cand)
        if progress is not None:
            progress(n)
        for j in sorted(range(len(cand)), key=lambda j: (judged[j][1], judged[j][2])):
            if not (judged[j][1], judged[j][2]) < key:
                return None
            r = feasible(cand_gains[j])
            if r.holds:
                moves.append(_move_name(z, cand[j]))
                z, scores, rep = cand[j], judged[j][0], r
                key = (judged[j][1], judged[j][2])
                return j
        return None

    if (budget >= 2 * REPAIR_POP and key != (0, 0.0)
            and any(math.isfinite(a.c_u) and a.c_u > hg.limits.c_u for a in scores0)):
        # Chatter on a tuning scenario: at the quantization floor c_u follows the caps more
        # than anything else (repair_coordinates), and the random joint moves below, which
        # perturb every gain by ~step, rarely hit the narrow band between the c_u limit and the
        # ARC-vs-PID limit (axis 16 of commission.synth.random_axis: the k2 cap x0.95 or x0.89
        # alone passes validate, x0.82 loses to the PID).  So the first round is a line search:
        # the k2 cap, and both caps, lowered by REPAIR_CAP_FACTORS, every other gain kept.
        k1, k2 = REPAIR_NAMES.index("k1"), REPAIR_NAMES.index("k2")
        cand = []
        for idx in ((k2,), (k1, k2)):
            for f in REPAIR_CAP_FACTORS:
                c = z.copy()
                c[list(idx)] += math.log(f)
                cand.append(np.clip(c, lo, hi))
        try_round(cand)
    while n < budget and key != (0, 0.0):
        m = min(REPAIR_POP, budget - n)
        far = key[0] > REPAIR_NEAR  # many failures: the passing gains may be a x3 move away
        steps = [step * (REPAIR_WIDE if far and j % 2 else 1.0) for j in range(m)]
        accepted = try_round([np.clip(z + steps[j] * rng.standard_normal(N_FREE + 1), lo, hi) for j in range(m)])
        # the step of the accepted draw carries on (a wide one widens the search); none: shrink
        step = (min(steps[accepted], REPAIR_MAX_STEP) if accepted is not None
                else max(REPAIR_MIN_STEP, step * REPAIR_SHRINK))
    x, f = free_of_repair(z)
    return RepairResult(x, spec.observer_pole * f, scores, key[0], key[1], tuple(moves), n, rep)


# --------------------------------------------------------------------------- report


def _summary(rep: FeasibilityReport, names: Sequence[str],
             robust: FeasibilityReport | None = None) -> FeasibilitySummary:
    w = rep.worst
    return FeasibilitySummary(holds=rep.holds, margin=rep.margin, rho_max=rep.rho_max, worst_corner=w.corner,
                              worst_trajectory=names[w.trajectory], worst_t=w.t, n_points=len(rep.points),
                              rho_adaptive_max=rep.rho_adaptive_max,
                              rho_any_estimate_max=robust.rho_max if robust is not None else math.nan)


def guarantees(arc: ArcGains, t1, feas: FeasibilitySummary) -> dict[str, Guarantee]:
    """Which of the paper's guarantees hold as tuned, and which are traded for implementability."""
    return {
        "theorem1_condition": Guarantee(
            t1.holds, f"c_phi_kr^2 >= w_k w2 / (2 c_theta2_r^2) for k = 1, 2, r = 1..3: smallest ratio "
                      f"{t1.min_ratio:.3g} (>= 1 holds)"),
        "projection_P1": Guarantee(
            True, "theta_hat stays in the identified box exactly: each discrete adaptation step is clipped to "
                  "[theta_min, theta_max]"),
        "projection_P2_continuous": Guarantee(
            False, "traded: the discontinuous projection (19)-(20) is replaced by clipping the Euler step "
                   "theta_hat + Ts Gamma tau to the box (for diagonal Gamma the Gamma^-1-weighted projection); "
                   "the continuous-time argument (A.8) does not carry over verbatim"),
        "exact_observer_filters": Guarantee(
            True, "filters (12), (18) advanced by exact matrix exponentials each sample (the sampled inputs "
                  "held as the controllers.arc law states); observer poles at -p give k1 = 2p, k2 = p^2 and P of (11)"),
        "robust_gains_37_47": Guarantee(
            math.isinf(arc.k1s_max) and math.isinf(arc.k2s_max),
            f"traded: the nonlinear gains K1 (28)+(37)+(38) and K2 (43)+(47) are capped at k1s_max = "
            f"{arc.k1s_max:.4g} 1/s and k2s_max = {arc.k2s_max:.4g} 1/s; conditions (33), (35), (46) hold only "
            f"while a cap is inactive, so the prescribed final accuracy of (51) is not guaranteed"),
        "sampled_data_stability": Guarantee(
            feas.holds, f"Theorem 1 is continuous-time; instead the sampled loop (exact ZOH plant + discrete "
                        f"controller; friction, ripple, quantization, saturation and sign nonlinearities excluded) "
                        f"is linearised at the 8 corners of the theta box along both trajectories, with theta_hat "
                        f"at the value reached and at each box corner: spectral radius <= {feas.rho_max:.4g} with "
                        f"the estimates frozen (need < {1 - feas.margin:.4g}), <= {feas.rho_adaptive_max:.6g} with "
                        f"the theta3 adaptation in the loop (need < 1)"),
        "stability_for_any_estimate_in_box": Guarantee(
            feas.rho_any_estimate_max < 1.0,
            f"informational: with theta_hat frozen at any of the 8 corners of the box (which the projection "
            f"allows) instead of the values the runs reached, the largest spectral radius is "
            f"{feas.rho_any_estimate_max:.4g} (< 1: stable whatever the estimate)"),
        "input_limit": Guarantee(
            math.isinf(arc.u_max), f"traded: the paper assumes an unbounded input; here |u| <= u_max = "
                                   f"{arc.u_max:g} (the lambda filter is driven by the applied u*)"),
        "zero_initial_V2_remark4": Guarantee(
            True, "q_d(0) = y(0), filters at rest at y(0): z1(0) = z2(0) = 0, i.e. V2(0) = 0"),
    }


# --------------------------------------------------------------------------- pipeline


def tune(ident: Identification, spec: Spec, *, rng: np.random.Generator, seed: int, ident_sha256: str,
         ident_path: str = "ident.json", log_sha256: str | None = None, progress: Progress | None = None,
         workers: int | None = None, created_utc: str | None = None, observer_free: bool = False,
         pid_free: bool = False, extension: int = 0) -> Tuning:
    """Tune the ARC (and the PID baseline) for an identified axis.

    Parameters
    ----------
    ident : Identification
    spec : Spec
        Already validated (:func:`commission.spec.load_spec`).
    rng : numpy.random.Generator
        The only source of randomness (search and Monte-Carlo plants).
    seed : int
        Recorded in the provenance.
    ident_sha256 : str
        sha256 of ident.json.
    ident_path : str
        Recorded in the provenance.
    log_sha256 : str, optional
        Of the excitation log, when known.
    progress : callable(done, total), optional
        Called after each search generation and each final stage.
    workers : int, optional
        Batch-simulator threads.
    created_utc : str, optional
        Time stamp (default: now).
    observer_free : bool
        ``spec.observer_pole`` was defaulted, not given: the hold-out repair may move it
        (:func:`repair_on_holdout`).  The pole used is the one recorded in ``observer``.
    pid_free : bool
        ``spec.pid_pole`` was defaulted: the PID baseline may run at a lower pole
        (:func:`deployable_pid`), recorded in ``pid_pole``.
    extension : int
        Candidates the search continues with when its best fail the hold-out gate
        (:func:`search_extension`; 0: never).

    Returns
    -------
    Tuning
    """
    check_spec_against_ident(spec, ident)
    scen = tuning_scenarios(ident, spec, rng=rng)
    ev = Evaluator(scen, spec, workers=workers)
    observer = observer_design(spec.observer_pole, spec.period)
    base = base_arc_gains(ident, spec)
    # progress steps: the search's candidates (with its extension), the hold-out, the repair's candidates,
    # two reports
    n_repair = repair_budget(spec, work_scale(ident, spec))
    n_search = spec.budget + extension
    total = n_search + 1 + n_repair + 2
    gate = default_gate_limits(ident, spec)
    baseline = deployable_pid(ident, spec, ev, gate.c_u, pid_free)
    pid, m_min, pid_scores = baseline.gains, baseline.design_mass, baseline.scores
    traj_names = ["case1", "case2"]
    trajs = [case1_trajectory(spec).render(spec.period), case2_trajectory(spec).render(spec.period)]

    def feasible(g: ArcGains) -> FeasibilityReport:
        return discrete_feasibility(KIND_ARC, arc_pack(g), ident.theta.min, ident.theta.max, trajs,
                                    margin=spec.margin)

    run = SearchRun(base, ev, spec, feasible=feasible, reference=pid_scores, gate=gate)
    run.advance(spec.budget, rng, progress, total)
    res = run.result()
    hg = HoldoutGate(ident, spec, ev, pid, pid_scores, rng=rng, workers=workers)
    memo: dict[tuple[str, bytes], Any] = {}
    holdout = select_on_holdout(res, base, hg, feasible, memo)
    extended = 0
    if extension > 0 and holdout.failures and min(holdout.failures) > 0:
        # The surrogate's best still fail the gate on unseen plants: search on, then choose again among all.
        run.advance(extension, rng, progress, total)
        res, extended = run.result(), extension
        holdout = select_on_holdout(res, base, hg, feasible, memo)
    chosen_i = holdout.chosen
    chosen_rep = holdout.feasibility or feasible(apply_free(base, res.x[chosen_i]))
    x_chosen, arc_scores = res.x[chosen_i], res.scores[chosen_i]
    if progress is not None:
        progress(n_search + 1, total)
    repaired: RepairResult | None = None
    if holdout.failures and min(holdout.failures) > 0 and chosen_rep.holds:
        repaired = repair_on_holdout(
            x_chosen, arc_scores, min(holdout.failures), holdout.excess, chosen_rep, base, hg, spec, feasible, rng,
            observer_free=observer_free, budget=n_repair, progress=None if progress is None else (lambda k: progress(n_search + 1 + k, total)))
        x_chosen, arc_scores, chosen_rep = repaired.x, repaired.scores, repaired.feasibility
    chosen = apply_free(base, x_chosen)
    if repaired is not None and repaired.observer_pole != spec.observer_pole:
        observer = observer_design(repaired.observer_pole, spec.period)
        chosen = dataclasses.replace(chosen, k1=observer.k1, k2=observer.k2)  # as with_observer, designed once
    if progress is not None:
        progress(n_search + 1 + n_repair, total)
    pid_rep = discrete_feasibility(KIND_PID, pid_pack(pid), ident.theta.min, ident.theta.max, trajs,
                                   margin=spec.margin)
    if progress is not None:
        progress(total - 1, total)
    t1 = theorem1_check(chosen.w1, chosen.w2, chosen.C_phi1, chosen.C_phi2, chosen.C_theta2)
    robust = discrete_feasibility(KIND_ARC, arc_pack(chosen), ident.theta.min, ident.theta.max, trajs,
                                  margin=spec.margin, estimate_corners=True)
    feas = {"arc": _summary(chosen_rep, traj_names, robust), "pid": _summary(pid_rep, traj_names)}
    scores = {name: {"arc": a, "pid": p} for name, a, p in zip(ev.names, arc_scores, pid_scores)}
    prov = Provenance(ident_sha256=ident_sha256, log_sha256=log_sha256, tool_version=commission.__version__,
                      created_utc=created_utc or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                      seed=int(seed), ident_path=ident_path)
    record = SearchRecord(n_evaluations=len(res.costs), budget=spec.budget, seed=int(seed),
                          cost_initial=res.cost_initial,
                          cost_best=float(res.costs[chosen_i]) if repaired is None else cost(
                              arc_scores, spec, pid_scores, ev.weights, gate),
                          free=free_gains(chosen).as_dict(), history=res.history,
                          holdout_plants=holdout.n_plants, holdout_failures=holdout.failures, extension=extended,
                          repair_moves=() if repaired is None else repaired.moves,
                          repair_evaluations=0 if repaired is None else repaired.evaluations,
                          repair_failures=None if repaired is None else repaired.failures)
    out = Tuning(provenance=prov, spec=spec, identification=ident, plant=identified_plant(ident, spec),
                 quantization=resolve_quantization(ident, spec), arc=chosen, pid=pid, pid_pole=baseline.pole,
                 pid_design_mass=m_min, observer=observer, theorem1=t1, feasibility=feas,
                 guarantees=guarantees(chosen, t1, feas["arc"]), scores=scores, search=record,
                 margins=margin_table(chosen, pid, ident, spec))
    if progress is not None:
        progress(total, total)
    return out


def _log_sha256(ident: Identification) -> str | None:
    """The excitation log's sha256 if ident.json records one (``extra.source.sha256``)."""
    src = ident.extra.get("source")
    if isinstance(src, dict) and isinstance(src.get("sha256"), str):
        return src["sha256"]
    v = ident.extra.get("log_sha256")
    return v if isinstance(v, str) else None


def log_sample_rate(ident: Identification) -> float | None:
    """The excitation log's sample rate (Hz) if ident.json records one (``extra.source.sample_rate``)."""
    src = ident.extra.get("source")
    if isinstance(src, dict):
        v = src.get("sample_rate")
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0:
            return float(v)
    return None


@dataclass(frozen=True)
class TuneInputs:
    """Everything ``commission tune`` reads, checked (see :func:`load_tune_inputs`)."""

    ident: Identification
    spec: Spec
    ident_path: str
    ident_sha256: str
    log_sha256: str | None
    seed: int
    notes: tuple[str, ...] = ()
    observer_free: bool = False
    pid_free: bool = False
    extension: int = 0


@dataclass(frozen=True)
class ResolvedSpec:
    """What ``tune`` runs with, after the defaults were fitted to the axis (:func:`resolve_spec`).

    Attributes
    ----------
    spec : Spec
    ident : Identification
        The identification tune designs for: the input one, or a copy whose theta3 box was
        narrowed to the drive (:func:`fit_disturbance_to_drive`).
    notes : tuple of str
        One line per default that was lowered or narrowed.
    observer_free : bool
        ``controller.observer_pole`` was not given: tune's hold-out repair may move it.
    pid_free : bool
        ``pid.pole`` was not given: tune may lower the PID baseline's pole (:func:`deployable_pid`).
    extension : int
        :func:`search_extension` (0 where ``tune.budget`` was given).
    """

    spec: Spec
    ident: Identification
    notes: tuple[str, ...]
    observer_free: bool = False
    pid_free: bool = False
    extension: int = 0


def resolve_spec(spec_data: dict, spec_name: str, ident: Identification, *,
                 ident_name: str = "ident.json") -> ResolvedSpec:
    """The spec ``tune`` runs with, for this identification; no simulation runs here.

    The sample rate defaults to the log's (:func:`log_sample_rate`), the envelope's
    defaulted keys are scaled to that rate (:func:`rate_scaled_envelope`), a defaulted
    load-force bound that leaves no room for any envelope is narrowed
    (:func:`fit_disturbance_to_drive`), the envelope's defaulted keys are lowered to
    what the drive can move (:func:`default_envelope`),
    then :func:`check_spec_against_ident` and the observer design check the result.

    Raises
    ------
    IdentifiabilityError
        The identification lacks what tune needs (a parameter not identified), naming it.
    SpecError
        Naming the key.
    """
    gaps = ident.tuning_gaps(ident_name)
    if gaps:
        raise IdentifiabilityError(gaps[0])
    spec = spec_from_mapping(spec_data, spec_name, sample_rate_default=log_sample_rate(ident))
    traj = spec_data.get("trajectory")
    given = set(traj) if isinstance(traj, dict) else set()
    spec, rate_notes = rate_scaled_envelope(spec, given)
    ident, box_notes = fit_disturbance_to_drive(spec, ident, given)
    spec, notes = default_envelope(spec, ident, given, spec_name)
    tune_keys = spec_data.get("tune")
    budget_given = isinstance(tune_keys, dict) and "budget" in tune_keys
    spec, budget_notes = work_scaled_budget(spec, ident, budget_given)
    check_spec_against_ident(spec, ident, spec_name)
    check_run_length(spec, spec_name)  # the envelope may have been lowered, lengthening the runs
    try:
        observer_design(spec.observer_pole, spec.period)
    except DesignError as exc:
        raise SpecError(f"{spec_name}: controller.observer_pole: {exc}") from None
    ctrl = spec_data.get("controller")
    observer_free = not (isinstance(ctrl, dict) and "observer_pole" in ctrl)
    pid = spec_data.get("pid")
    pid_free = not (isinstance(pid, dict) and "pole" in pid)
    return ResolvedSpec(spec, ident, rate_notes + box_notes + notes + budget_notes, observer_free, pid_free,
                        search_extension(spec, ident, budget_given))


def load_tune_inputs(ident_path: str | os.PathLike[str], *, spec_path: str | os.PathLike[str] | None = None,
                     seed: int = 0) -> TuneInputs:
    """Read and check every input of ``commission tune``; no simulation runs here.

    Raises
    ------
    InputFileError, SchemaError, SpecError, UsageError
        Bad input (the CLI's exit 2), naming the file and the key.
    """
    if seed < 0:
        raise UsageError(f"--seed: must be a non-negative integer, got {seed}")
    ident_path = os.fspath(ident_path)
    spec_data, spec_name = read_spec_toml(spec_path)  # parse errors before reading ident.json
    spec_from_mapping(spec_data, spec_name)  # every key checked at the documented defaults
    ident = Identification.from_dict(read_json(ident_path), source=ident_path)
    rs = resolve_spec(spec_data, spec_name, ident, ident_name=str(ident_path))
    return tune_inputs(rs, ident_path=ident_path, ident_sha256=sha256_file(ident_path), log_sha256=_log_sha256(ident),
                       seed=seed)


def tune_inputs(rs: ResolvedSpec, *, ident_path: str, ident_sha256: str, log_sha256: str | None,
                seed: int) -> TuneInputs:
    """The :class:`TuneInputs` of a resolved spec.

    ``commission tune`` (:func:`load_tune_inputs`) and ``commission run``
    (:func:`commission.pipeline.run_all`) both build their inputs here and tune them with
    :func:`tune_from`, so that the same log and spec give the same tuning either way
    (``observer_free`` and ``pid_free`` included).
    """
    return TuneInputs(ident=rs.ident, spec=rs.spec, ident_path=ident_path, ident_sha256=ident_sha256,
                      log_sha256=log_sha256, seed=int(seed), notes=rs.notes, observer_free=rs.observer_free,
                      pid_free=rs.pid_free, extension=rs.extension)


def tune_from(inp: TuneInputs, *, progress: Progress | None = None, workers: int | None = None) -> Tuning:
    """:func:`tune` on checked inputs, seeded with ``inp.seed`` (a fresh ``numpy.random.default_rng``)."""
    return tune(inp.ident, inp.spec, rng=np.random.default_rng(inp.seed), seed=inp.seed,
                ident_sha256=inp.ident_sha256, ident_path=inp.ident_path, log_sha256=inp.log_sha256,
                progress=progress, workers=workers, observer_free=inp.observer_free, pid_free=inp.pid_free,
                extension=inp.extension)


def run_tune(ident_path: str | os.PathLike[str], out_path: str | os.PathLike[str], *,
             spec_path: str | os.PathLike[str] | None = None, seed: int = 0,
             progress: Progress | None = None, workers: int | None = None,
             inputs: TuneInputs | None = None) -> Tuning:
    """File-level pipeline of ``commission tune``: read, check, tune, write.

    Every input check (:func:`load_tune_inputs`: ident.json schema, spec keys
    and values, spec against the identification) runs before any simulation;
    nothing is written unless tuning completes.  ``inputs`` (already loaded)
    skips the reading.

    Raises
    ------
    InputFileError, SchemaError, SpecError, UsageError
        Bad input (the CLI's exit 2).
    """
    inp = inputs if inputs is not None else load_tune_inputs(ident_path, spec_path=spec_path, seed=seed)
    try:
        t = tune_from(inp, progress=progress, workers=workers)
    except DesignError as exc:  # a design input the spec checks let through: still bad input, exit 2
        raise SpecError(f"{os.fspath(spec_path) if spec_path else 'spec'}: {exc}") from None
    t.save(os.fspath(out_path))
    return t
