"""The ``commission tune`` pipeline: ident.json + spec -> tuning.json.

One module per part:

- :mod:`~commission.tune.settings`: every knob, :class:`~commission.tune.settings.TuneSettings`
  (frozen, each field documented with its unit) and its default instance ``DEFAULT_SETTINGS``;
- :mod:`~commission.tune.defaults`: spec defaulting against the axis (envelope, load force);
- :mod:`~commission.tune.box`: the payload and force ranges fitted to the drive and the box's
  guarantees;
- :mod:`~commission.tune.gains`: the base gains and the search's coordinates;
- :mod:`~commission.tune.baseline`: the PID of eq. (57) and its yardstick;
- :mod:`~commission.tune.objective`: the evaluator, the cost and the hold-out gate;
- :mod:`~commission.tune.constraints`: the search's constraints as violations;
- :mod:`~commission.tune.candidate`: the evaluated candidates and their feasibility-first order;
- :mod:`~commission.tune.budget`: the budget sized to one candidate's simulation work;
- :mod:`~commission.tune.optimiser`: the CMA-ES search and the hold-out choice;
- :mod:`~commission.tune.guarantees`: the statements tuning.json records;
- :mod:`~commission.tune.api`: the entry points (:func:`tune`, :func:`resolve_spec`,
  :func:`load_tune_inputs`, :func:`run_tune`, ...).

Dependencies point one way: settings <- defaults <- gains, objective <- baseline, candidate <-
optimiser <- api.  This package exports only what the rest of the code (``commission``, ``cli``,
``benchmarks``) uses; everything else is imported from the module that defines it.

Steps (all numerics in :mod:`commission.controllers`; this module only
orchestrates, checks inputs and builds the :class:`~commission.tuning.Tuning`):

1. Spec checks before any simulation (:mod:`commission.spec`, then
   :func:`check_spec_against_ident`: the input limit must cover the envelope
   on the heaviest plant of the box).  Defaults are fitted to the axis first
   (:func:`resolve_spec`): the envelope to the sample rate and the drive, and a
   *defaulted* load-force bound that leaves the drive no room for any envelope
   is narrowed (:func:`fit_disturbance_to_drive`).  With the machine's own moves
   (``[trajectory] file`` or ``[[trajectory.move]]``) the envelope is theirs, not fitted:
   they are checked against the drive (:func:`check_moves_against_drive`) and only the
   paper's Case 1 and Case 2 get a fitted envelope (:func:`reference_envelope`).
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
4. Free gains (:class:`FreeGains`), searched in log scale: the caps k1s_max, k2s_max on
   the total nonlinear gains that make (37)/(47) implementable, g1, g2 as fractions of the
   caps, the three entries of Gamma, the weight w2, the initial estimate theta_hat1(0)
   (between ``theta1_0_low`` of the settings and 1 x the identified nominal; a start below the nominal is
   what the paper did, 30 for 37) and, when the spec left it at its default, the observer
   pole.  (The eps terms stay at the carried-over paper values.)
5. **One constrained optimisation** (:mod:`~commission.tune.optimiser`, CMA-ES by pycma's
   ask/tell): minimise the performance objective (:func:`cost`: weighted mean over the
   tuning scenarios of ln(e_rms / targets.e_rms) with soft penalties, and the worst ARC/PID
   ratio) subject to the stability margins of the ARC on the identified plant (mode and delay
   included) meeting the spec's ``[margins]`` floors, validate's default gate on the tuning
   scenarios (robustness scenarios included: one more sample of delay, the mode at +-20 %
   and at half its damping) with room, and discrete feasibility over the theta box
   (:mod:`~commission.tune.constraints`).  The tuning scenarios
   (:func:`commission.scenarios.tuning_scenarios`) are validate's 12 fixed scenarios, the
   robustness ones, the 16 box corners, the 4 largest-force plants and 6 interior payloads.
   The winner is the feasible finalist with the fewest gate failures on
   ``holdout_plants`` fresh Monte-Carlo plants (:func:`select_on_holdout`).  The PID
   baseline (poles of (56) at M_min = 1/theta_max[0]) runs at the spec's pole or, when that was
   defaulted and its PID exceeds validate's c_u limit on a tuning scenario, at the fastest
   lower pole that does not (:func:`deployable_pid`), so that the ARC is compared with a PID a
   user could deploy.
6. tuning.json with provenance, every gain, the design reports, the
   guarantee statement and the scores of ARC and PID on every tuning scenario.
"""

from __future__ import annotations

from commission.tune.api import load_tune_inputs, resolve_spec, run_tune, tune, tune_from, tune_inputs
from commission.tune.baseline import pid_baseline, pid_chatter, pid_pole_note
from commission.tune.gains import base_arc_gains
from commission.tune.objective import Evaluator

__all__ = [
    "Evaluator",
    "base_arc_gains",
    "load_tune_inputs",
    "pid_baseline",
    "pid_chatter",
    "pid_pole_note",
    "resolve_spec",
    "run_tune",
    "tune",
    "tune_from",
    "tune_inputs",
]
