"""The ``commission tune`` pipeline: ident.json + spec -> tuning.json.

One module per part: :mod:`~commission.tune.defaults` (spec defaulting against the
axis), :mod:`~commission.tune.gains` (the base gains and the search's coordinates),
:mod:`~commission.tune.baseline` (the PID of eq. (57)), :mod:`~commission.tune.objective`
(the evaluator, the cost and the hold-out gate), :mod:`~commission.tune.optimiser`
(the search, the hold-out choice and the repair), :mod:`~commission.tune.guarantees`
and :mod:`~commission.tune.api` (the entry points).  Dependencies point one way:
defaults <- gains, objective <- baseline, optimiser <- api.

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

from commission.tune.defaults import (
    PAPER_THETA1,
    PAPER_RATE,
    DRIVE_HEADROOM,
    MIN_DEFAULT_V_MAX,
    MIN_DEFAULT_A_MAX,
    DriveNeed,
    drive_need,
    check_spec_against_ident,
    DISTURBANCE_SHARE,
    fit_disturbance_to_drive,
    rate_scaled_envelope,
    default_envelope,
    default_gate_limits,
    log_sample_rate,
)
from commission.tune.gains import (
    THETA1_0_LOW,
    PAPER_THETA1_0,
    EXTRA_STARTS,
    paper_implementable_start,
    FreeGains,
    FREE_BOUNDS,
    FREE_START,
    N_FREE,
    I_THETA1_0,
    FREE_LOG_LO,
    FREE_LOG_HI,
    base_arc_gains,
    apply_free,
    free_gains,
)
from commission.tune.objective import (
    Progress,
    W_TARGET,
    W_CHATTER,
    W_STEP,
    W_SATURATION,
    W_DIVERGED,
    PID_MARGIN,
    W_WORST,
    W_GATE,
    CORNER_WEIGHT,
    HOLDOUT_PLANTS,
    REPAIR_MARGIN,
    REPAIR_DIVERGED_EXCESS,
    Evaluator,
    cost,
    meets_targets,
    HoldoutGate,
    gate_excess,
)
from commission.tune.baseline import (
    PID_POLE_STEP,
    PID_POLE_STEPS,
    pid_baseline,
    PidBaseline,
    deployable_pid,
    PidChatter,
    pid_chatter,
    pid_pole_note,
)
from commission.tune.optimiser import (
    POP,
    SHRINK,
    STEP_FLOOR,
    WORK_CAP,
    ARC_STEP_WORK,
    MIN_BUDGET,
    MIN_REPAIR_BUDGET,
    SearchResult,
    search_step,
    SearchRun,
    search,
    HOLDOUT_CANDIDATES,
    REPAIR_POP,
    REPAIR_STEP,
    REPAIR_WIDE,
    REPAIR_MAX_STEP,
    REPAIR_NEAR,
    REPAIR_SHRINK,
    REPAIR_MIN_STEP,
    REPAIR_CAP_FACTORS,
    OBSERVER_FACTOR_BOUNDS,
    REPAIR_BUDGET,
    repair_budget,
    candidate_work,
    work_scale,
    work_scaled_budget,
    search_extension,
    HoldoutChoice,
    select_on_holdout,
    RepairResult,
    with_observer,
    REPAIR_NAMES,
    I_F1,
    I_F2,
    repair_coordinates,
    free_of_repair,
    repair_on_holdout,
)
from commission.tune.guarantees import (
    guarantees,
)
from commission.tune.api import (
    tune,
    TuneInputs,
    ResolvedSpec,
    resolve_spec,
    load_tune_inputs,
    tune_inputs,
    tune_from,
    run_tune,
)

__all__ = [
    "PAPER_THETA1",
    "PAPER_RATE",
    "DRIVE_HEADROOM",
    "MIN_DEFAULT_V_MAX",
    "MIN_DEFAULT_A_MAX",
    "DriveNeed",
    "drive_need",
    "check_spec_against_ident",
    "DISTURBANCE_SHARE",
    "fit_disturbance_to_drive",
    "rate_scaled_envelope",
    "default_envelope",
    "default_gate_limits",
    "log_sample_rate",
    "THETA1_0_LOW",
    "PAPER_THETA1_0",
    "EXTRA_STARTS",
    "paper_implementable_start",
    "FreeGains",
    "FREE_BOUNDS",
    "FREE_START",
    "N_FREE",
    "I_THETA1_0",
    "FREE_LOG_LO",
    "FREE_LOG_HI",
    "base_arc_gains",
    "apply_free",
    "free_gains",
    "Progress",
    "W_TARGET",
    "W_CHATTER",
    "W_STEP",
    "W_SATURATION",
    "W_DIVERGED",
    "PID_MARGIN",
    "W_WORST",
    "W_GATE",
    "CORNER_WEIGHT",
    "HOLDOUT_PLANTS",
    "REPAIR_MARGIN",
    "REPAIR_DIVERGED_EXCESS",
    "Evaluator",
    "cost",
    "meets_targets",
    "HoldoutGate",
    "gate_excess",
    "PID_POLE_STEP",
    "PID_POLE_STEPS",
    "pid_baseline",
    "PidBaseline",
    "deployable_pid",
    "PidChatter",
    "pid_chatter",
    "pid_pole_note",
    "POP",
    "SHRINK",
    "STEP_FLOOR",
    "WORK_CAP",
    "ARC_STEP_WORK",
    "MIN_BUDGET",
    "MIN_REPAIR_BUDGET",
    "SearchResult",
    "search_step",
    "SearchRun",
    "search",
    "HOLDOUT_CANDIDATES",
    "REPAIR_POP",
    "REPAIR_STEP",
    "REPAIR_WIDE",
    "REPAIR_MAX_STEP",
    "REPAIR_NEAR",
    "REPAIR_SHRINK",
    "REPAIR_MIN_STEP",
    "REPAIR_CAP_FACTORS",
    "OBSERVER_FACTOR_BOUNDS",
    "REPAIR_BUDGET",
    "repair_budget",
    "candidate_work",
    "work_scale",
    "work_scaled_budget",
    "search_extension",
    "HoldoutChoice",
    "select_on_holdout",
    "RepairResult",
    "with_observer",
    "REPAIR_NAMES",
    "I_F1",
    "I_F2",
    "repair_coordinates",
    "free_of_repair",
    "repair_on_holdout",
    "guarantees",
    "tune",
    "TuneInputs",
    "ResolvedSpec",
    "resolve_spec",
    "load_tune_inputs",
    "tune_inputs",
    "tune_from",
    "run_tune",
]
