"""The scenario matrix shared by ``commission tune`` and ``commission validate``.

A :class:`Scenario` is one closed-loop run: a plant (the
:mod:`commission.controllers.plant` vector), a desired trajectory, an input
disturbance, the initial position and the encoder resolution.  It is defined
only from an :class:`~commission.artifacts.Identification` and a
:class:`~commission.spec.Spec`, so that ``validate`` re-creates exactly the
plants ``tune`` optimised on, plus the Monte-Carlo sample.

Full matrix of :func:`scenario_matrix` (validate), for each trajectory
``case1`` (sinusoid through filter (58)) and ``case2`` (trapezoidal
back-and-forth moves), both scaled to the spec's envelope:

``<case>/nominal``
    The identified plant.
``<case>/payload_light``, ``<case>/payload_heavy``
    Mass at the theta_1 bounds: M = 1/theta_max[0] and M = 1/theta_min[0]
    (viscous B, friction and offset unchanged: a payload changes the mass only).
``<case>/friction_low``, ``<case>/friction_high``
    The identified friction curve B v + Ff(v) scaled by 0.8 and 1.2
    (B, fc, fs scaled; vs, xi kept).
``<case>/disturbance``
    The identified plant with an input step of ``delta_d * M`` u-unit (the
    Assumption-1 bound, as an input) on from 22 % to 72 % of the run (the
    paper's 2.2 s to 7.2 s of 10 s).
``<case>/delay+1``
    The identified plant with one more sample of input delay than identified
    (a drive's computation or bus delay that the log cannot show).
``<case>/stribeck``
    When the log resolved no Stribeck rise (a Coulomb-only fit): the identified plant with the
    reference axis's rise, fs = 1.2 fc at vs = 0.01 q-unit/s, xi = 2
    (:data:`~commission.scenarios.matrix.UNSEEN_STRIBECK`), which the machine most likely
    has and the log could not show.  Like ``delay+1`` it is the identified plant as it may
    really be: the gate compares the ARC with the yardstick on it (``arc_vs_pid_nominal``).
``<case>/mode_low``, ``<case>/mode_high``, ``<case>/mode_damping_half``
    When the plant has a structural mode: its frequency at 0.8 and 1.2 times
    and its damping halved (what the identification's errors and a changed
    load can do to it); a second identified mode moves with the first.  Without a known mode, the stability margins
    (:mod:`commission.robustness`) stand in for it.
``mc/NNN``
    ``n_monte_carlo`` plants from the theta box (a defaulted payload or load-force range only
    where the log supports it: :func:`monte_carlo_support`), alternating case1 and case2,
    drawn from the passed Generator: theta1 uniform in the box (M = 1/theta1),
    the viscous B and the disturbance force d_n = -offset uniform in the ranges
    the box admits at every mass (:func:`viscous_range`, :func:`force_range`),
    the identified friction curve.  Every drawn theta lies in the box.

Every non-Monte-Carlo scenario carries the tag ``"tune"``.  :func:`tuning_scenarios`
(what ``tune`` optimises on) is these 12, plus the 16 corners of the theta box
on both trajectories (``corner/<case>/<bits>``, tune-only: the deterministic
extremes of the box the Monte-Carlo sample draws from), plus the identified
plant with the largest force of :func:`force_range` of either sign
(``offset/<case>/lo|hi``, tune-only), plus ``spec.monte_carlo`` Monte-Carlo plants.

The machine's own moves (``user/...``)
--------------------------------------
When the spec gives the machine's moves (``[trajectory] file`` or ``[[trajectory.move]]``,
:mod:`commission.moves`), a third trajectory ``user`` joins Case 1 and Case 2 everywhere
above: ``user/nominal`` ... ``user/disturbance``, ``user/delay+1`` (and the mode variants),
the box corners, largest forces and interior payloads of tune (``corner/user/...``,
``offset/user/...``, ``payload/user/...``), and every third Monte-Carlo plant (the sample
cycles through case1, case2, user).  The profile is rendered as it is, without filter (58):
the drive follows its own generator's q, v, a; it is held at rest :data:`CASE2_TAIL` s after
its end.  Case 1 and Case 2 stay as the paper's reference scenarios, scaled to
``spec.case_v_max``/``case_a_max`` (the spec's ``reference_v_max``/``reference_a_max``;
``tune`` derives them for this drive when not given: :func:`commission.tune.defaults.reference_envelope`).

Trajectory scaling (paper: travel 0.4 m, v_max 1 m/s, a_max 12 m/s^2)
---------------------------------------------------------------------
v_max and a_max here are the reference envelope ``spec.case_v_max``, ``spec.case_a_max``
(the spec's v_max, a_max unless the machine's moves are given).
Case 1: amplitude A = travel/8 and omega = min(0.2 v_max / A, sqrt(a_max / (15 A)))
(both 4 rad/s for the paper's envelope, A = 0.05 m), 10 s or four periods,
whichever is longer.  Case 2: ``moves`` moves of ``travel`` at v_max, a_max
with ``dwell`` rests, then 2.1 s at rest (8 s for the paper's envelope), so
that e_F measures the standstill accuracy.

Modules
-------
* :mod:`~commission.scenarios.scenario`: one run (:class:`Scenario`, :class:`TrajectorySpec`,
  :class:`StepDisturbance`);
* :mod:`~commission.scenarios.identified`: the identified plant vector (:func:`identified_plant`,
  :func:`plant_dynamics`: modes and input delay);
* :mod:`~commission.scenarios.resolution`: the plant's sub-steps and the encoder's resolution and noise
  (:func:`plant_substeps`, :func:`resolve_quantization`, :func:`resolve_encoder_noise`);
* :mod:`~commission.scenarios.trajectories`: Case 1, Case 2 and the machine's moves, their horizons
  and the run-length refusals (:func:`trajectories`, :func:`check_run_length`);
* :mod:`~commission.scenarios.box`: the theta box as plants and the Monte-Carlo sample
  (:func:`force_range`, :func:`viscous_range`, :func:`monte_carlo_plants`);
* :mod:`~commission.scenarios.matrix`: the scenario sets (:func:`scenario_matrix`, :func:`tuning_scenarios`,
  the robustness, corner, offset and payload families, :func:`screening_indices`);
* :mod:`~commission.scenarios.payload`: the certified payload range (:func:`payload_heavy_at`,
  :func:`largest_safe_payload`).
"""

from commission.scenarios.box import (clip_to_box, force_range, monte_carlo_plants, monte_carlo_support,
                                      theta3_range_for_forces, viscous_range)
from commission.scenarios.identified import identified_plant, plant_dynamics, plant_holds_fit
from commission.scenarios.matrix import (FRICTION_SCALE, MODE_DAMPING_FACTOR, MODE_FREQUENCY_FACTORS, UNSEEN_STRIBECK,
                                         VARIANTS, corner_scenarios, offset_scenarios, payload_scenarios, robustness_scenarios,
                                         scenario_matrix, screening_indices, tuning_scenarios,
                                         unseen_stribeck)
from commission.scenarios.payload import PAYLOAD_BISECTIONS, largest_safe_payload, payload_heavy_at
from commission.scenarios.resolution import plant_substeps, resolve_encoder_noise, resolve_quantization
from commission.scenarios.scenario import NO_DISTURBANCE, Scenario, StepDisturbance, TrajectorySpec
from commission.scenarios.trajectories import (CASE1_DURATION, CASE1_SPEED_FRACTION, CASE2_TAIL, CASES,
                                               case1_trajectory, case2_trajectory, case_names, check_run_length,
                                               check_user_length, horizon_notes, max_horizon, trajectories)

__all__ = [
    "Scenario", "TrajectorySpec", "StepDisturbance", "NO_DISTURBANCE", "identified_plant", "plant_dynamics",
    "plant_holds_fit",
    "plant_substeps", "resolve_quantization", "resolve_encoder_noise", "CASES", "CASE1_DURATION",
    "CASE1_SPEED_FRACTION", "CASE2_TAIL", "case1_trajectory", "case2_trajectory", "case_names", "trajectories",
    "max_horizon", "horizon_notes", "check_run_length", "check_user_length", "force_range",
    "theta3_range_for_forces", "viscous_range",
    "clip_to_box", "monte_carlo_support", "monte_carlo_plants", "VARIANTS", "FRICTION_SCALE",
    "MODE_FREQUENCY_FACTORS", "MODE_DAMPING_FACTOR", "UNSEEN_STRIBECK", "unseen_stribeck", "scenario_matrix", "robustness_scenarios", "corner_scenarios",
    "offset_scenarios", "payload_scenarios", "screening_indices", "tuning_scenarios", "PAYLOAD_BISECTIONS",
    "payload_heavy_at", "largest_safe_payload",
]
