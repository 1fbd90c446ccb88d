"""Every knob of ``commission tune`` in one frozen object: :class:`TuneSettings`.

The search, its objective, its constraints, the PID baseline and the fitting of a defaulted spec
to the axis read their knobs from one :class:`TuneSettings` (:data:`DEFAULT_SETTINGS` unless a
caller passes another): :func:`commission.tune.api.tune` and
:func:`commission.tune.api.resolve_spec` take it as ``settings`` and hand it on, so that a study
(or a test) changes a knob by ``dataclasses.replace(DEFAULT_SETTINGS, ...)`` instead of patching
a module.  Each field is documented once, here (the ``#:`` line above it), with its unit; the
modules that read a field say what it does there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The paper's reference axis (Xu & Yao 2001, §4.3), a fact and not a knob: theta1 = 37
#: m/(u-unit s^2) (``PAPER_THETA1``), sampled at 2500 Hz (``PAPER_RATE``), its estimate started
#: at theta_hat1(0) = 30 m/(u-unit s^2) (``PAPER_THETA1_0``).  The reference of the gain scaling.
PAPER_THETA1, PAPER_RATE, PAPER_THETA1_0 = 37.0, 2500.0, 30.0


@dataclass(frozen=True)
class TuneSettings:
    """The knobs of ``commission tune``, one documented field each (defaults: :data:`DEFAULT_SETTINGS`).

    Frozen: a variant is ``dataclasses.replace(DEFAULT_SETTINGS, field=value)``.  Derived values
    (:attr:`cap_low`, :attr:`theta1_0_low`, :attr:`match_scales`, :attr:`free_log_lo`,
    :attr:`free_log_hi`) are properties, so that they follow the fields they come from.
    """

    # ---- the search (commission.tune.optimiser)
    #: Candidates per CMA-ES generation (pycma's default for 9-10 coordinates is 10; 8 fills two
    #: cores evenly in the batch simulator).
    population: int = 8
    #: Initial standard deviation of each search coordinate as a fraction of its range, log units
    #: (at most ``sigma_max``): wide enough to leave the carried-over paper gains by a factor of two
    #: or three in one generation, since the feasible gains of a delay-capped axis often lie that
    #: far from them (docs/robustness.md).
    sigma_fraction: float = 0.3
    #: Largest initial standard deviation of a coordinate, log units (1: a factor e).
    sigma_max: float = 1.0
    #: Range of the factor on a *defaulted* observer pole (``controller.observer_pole``),
    #: dimensionless: a slower observer leaves a light axis' delay margin room, a faster one passes
    #: more encoder noise.
    observer_factor_bounds: tuple[float, float] = (0.6, 1.25)
    #: Search box of the free gains relative to :func:`commission.tune.gains.base_arc_gains`,
    #: ``(name, low, high)``, dimensionless multiples, in the order of
    #: :func:`commission.tune.gains.apply_free`.  k1, k2: the caps as multiples of the base g1, g2
    #: (low end: :attr:`cap_low`); f1, f2: g as a fraction of its cap; G1..G3: the Gamma entries as
    #: multiples of the base Gamma; w2: the weight w2 of (41) as a multiple of the base (w1 = 1
    #: fixed: only w1/w2 matters; a small w2 lets the theta3 adaptation, the loop's integral action
    #: tau3 = w1 psi2 z1 + w2 phi2_3 z2, run much faster before its loop loses stability, at the
    #: price of more chattering: the search trades them); t1: theta_hat1(0) as a multiple of the
    #: identified nominal (low end: :attr:`theta1_0_low`; clipped to the box).
    free_bounds: tuple[tuple[str, float, float], ...] = (
        ("k1", 0.05, 4.0), ("k2", 0.05, 4.0), ("f1", 0.05, 1.0), ("f2", 0.05, 1.0),
        ("G1", 1e-2, 30.0), ("G2", 1e-2, 30.0), ("G3", 1e-2, 1e4), ("w2", 1e-3, 10.0),
        ("t1", 0.5, 1.0))
    #: Starting point (relative free gains): the paper's g1, g2 as caps (robust terms bounded by
    #: g), paper Gamma and w2, theta_hat(0) = the identified nominal.
    free_start: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    #: Structured starting points of generation 0 besides ``free_start`` and
    #: :func:`commission.tune.gains.paper_implementable_start` (relative free gains): a small w2 with
    #: a faster theta3 adaptation (the integral action); a larger K2 cap, w2 and theta3 rate with
    #: the paper's theta_hat1(0) / theta1 = 30/37.
    extra_starts: tuple[tuple[float, ...], ...] = (
        (1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 10.0, 0.1, 1.0),
        (1.0, 3.0, 1.0, 1.0, 1.0, 1.0, 3.0, 3.0, PAPER_THETA1_0 / PAPER_THETA1))

    # ---- the matched starts (commission.tune.optimiser.Problem.matched_starts)
    #: Directions of :meth:`commission.tune.optimiser.Problem.matched_starts`: (observer factor,
    #: K2 cap / K1 cap as multiples of the base's); a factor other than 1 only when the observer
    #: pole is free.
    match_directions: tuple[tuple[float, float], ...] = ((1.0, 1.0), (1.0, 2.0), (1.25, 1.0))
    #: The best matched start becomes CMA-ES's mean (else the carried-over paper gains stay the mean
    #: and the matched starts are injected only).
    match_as_mean: bool = True
    #: Further K2/K1 cap ratios the matched starts try when no direction of ``match_directions``
    #: gives a start, dimensionless.  The ARC's position gain is K1 / theta1min: on an axis whose
    #: theta box is wide (a heavy axis with its default payload range) its rest loop ties the PID's
    #: only with a K2 cap many times the K1 cap, and ratios 1 and 2 alone left such an axis no
    #: matched start (the search then began from the unstable paper gains).  A fallback, so that an
    #: axis the first directions serve keeps the same start and pays nothing.
    match_wide_ratios: tuple[float, ...] = (4.0, 8.0, 16.0, 32.0)
    #: Largest cap scale the matched starts try, relative to the base gains' caps.
    match_scale_max: float = 4.0
    #: Cap scales tried, geometric from ``match_scale_max`` down to :attr:`cap_low`
    #: (:attr:`match_scales`).
    match_scale_count: int = 25
    #: Factors on the base theta3 adaptation rate the matched starts try in turn (up to the first
    #: that breaks a linear constraint), dimensionless.
    match_g3: tuple[float, ...] = (2.0, 4.0, 8.0, 16.0, 32.0)
    #: The same along ``match_wide_ratios``: doubling up to the search box's bound on G3.  On a
    #: wide box the matched caps leave the ARC's integral action far below the PID's at x32 while
    #: the linear constraints allow much more, and the ARC then loses to the yardstick in Case 2 for
    #: want of integral action.  Not along the first directions: there it moves the start of axes
    #: those directions already serve (docs/robustness.md, "Where the search starts").
    match_g3_wide: tuple[float, ...] = tuple(2.0 ** k for k in range(1, 14))
    #: Matched starts injected into the first generation besides the one that becomes its mean
    #: (with the paper's and the two extra starts, the first generation is all structured starts).
    match_injected: int = 4
    #: A matched start may cross over this factor above the PID yardstick's crossover.
    match_crossover_room: float = 1.05

    # ---- the screen and the hold-out choice (commission.tune.optimiser)
    #: Gate excess on the screening scenarios (:func:`commission.tune.objective.gate_excess`, ln
    #: units summed over indexes and scenarios) above which a candidate is not simulated on the
    #: rest: an index 35 % over its limit, far from feasibility.  Low because the matched starts put
    #: most candidates past the margins: a looser screen simulates many more in full for about the
    #: same ARC-vs-PID quantiles (docs/robustness.md).
    screen_excess: float = 0.3
    #: Finalists (best objective first) that :func:`commission.tune.optimiser.select_on_holdout`
    #: judges on unseen plants.
    holdout_candidates: int = 6
    #: Monte-Carlo plants of the hold-out sample (drawn from tune's Generator, not validate's).
    holdout_plants: int = 32

    # ---- the objective's penalties (commission.tune.objective.cost)
    #: Penalty weight of the accuracy target in :func:`commission.tune.objective.cost` (per
    #: scenario, in units of ln e_rms, as every ``w_*``).
    w_target: float = 2.0
    #: Penalty weight of the chattering target and of a loss to the PID.
    w_chatter: float = 10.0
    #: Step penalty of a missed target or a loss to the PID.
    w_step: float = 1.0
    #: Penalty of a command that reached u_max.
    w_saturation: float = 2.0
    #: Cost of a diverged run.
    w_diverged: float = 20.0

    # ---- the objective's comparison with the PID baseline (commission.tune.objective.cost)
    #: The ARC is asked to beat the PID's e_rms by this factor on every tuning scenario (soft
    #: constraint), so that validation's "ARC no worse than PID" holds on plants between them.
    pid_margin: float = 0.9
    #: Weight of the worst ARC/PID e_rms ratio over the scenarios (the objective's minimax term
    #: without a gate).
    w_worst: float = 1.0
    #: Objective weight of each box-corner and robustness scenario (the fixed scenarios weigh 1):
    #: the corners mostly act through the penalties (divergence, no worse than the PID).
    corner_weight: float = 0.25
    #: Weight of the gate's ARC-vs-PID quantiles in the objective
    #: (:func:`commission.tune.objective.quantile_excess`).
    w_quantile: float = 4.0

    # ---- the constraints (commission.tune.constraints, commission.tune.objective.gate_excess)
    #: Excess counted for a diverged run by the gate excess and the quantile excess, ln units.
    diverged_excess: float = 10.0
    #: Gate indexes are held to this fraction of their limits inside the search: room for the
    #: Monte-Carlo plants validate draws and the search never saw.
    gate_margin: float = 0.95
    #: Violation of an unstable loop in the margin constraints, plus its spectral radius above 1,
    #: dimensionless.
    unstable: float = 10.0

    # ---- the PID baseline (commission.tune.baseline)
    #: A *defaulted* PID pole whose baseline exceeds validate's default c_u limit on the tuning
    #: scenarios is lowered along ``pid_pole x pid_pole_step**k``, k = 1 .. ``pid_pole_steps``
    #: (:func:`commission.tune.baseline.deployable_pid`).
    pid_pole_step: float = 0.95
    #: Steps of that lowering (down to 0.54 x at the default step).
    pid_pole_steps: int = 12
    #: Largest factor the PID's pole is lowered by to hold the evidence bound
    #: (:func:`commission.tune.baseline.pid_within_evidence`).
    evidence_pole_floor: float = 0.25
    #: Pole factor of each step of that lowering.
    evidence_pole_step: float = 0.9
    #: Poles the PID yardstick search tries, as fractions of the sample rate (rad/s per Hz): 0.02 f_s
    #: to 0.4 f_s, geometric (the paper's 300 rad/s at 2.5 kHz is 0.12 f_s; 0.5 f_s is the spec's
    #: bandwidth rule :data:`commission.spec.MAX_OMEGA_T`).
    yardstick_pole_fractions: tuple[float, ...] = tuple(float(x) for x in np.geomspace(0.02, 0.4, 33))
    #: Poles tried below that grid, fastest first, when none of it is admissible (fractions of the
    #: sample rate, the same geometric step continued down to 5e-4 f_s): an axis whose bandwidth a
    #: low structural mode or a heavy load sets, not its sample rate.  Its yardstick then scales
    #: the ARC's carried-over gains and observer (:func:`commission.tune.baseline.bandwidth_factor`).
    yardstick_low_fractions: tuple[float, ...] = tuple(float(x) for x in np.geomspace(0.02, 0.0005, 41)[1:])
    #: Yardstick candidates simulated at once (fastest first) when looking for one within the
    #: gate's c_u: one, so that the search stops at the first that is (usually the fastest
    #: admissible pole).  Each candidate's scenarios run in parallel all the same.
    yardstick_batch: int = 1
    #: Batches simulated, fastest first, before the yardstick's c_u boundary is bisected among the
    #: slower admissible poles (:func:`commission.tune.baseline.pid_yardstick`).
    yardstick_batches: int = 8

    # ---- a defaulted spec fitted to the axis (commission.tune.defaults, commission.tune.box)
    #: When the spec leaves the envelope to its defaults, the feedforward of the worst plant may use
    #: at most this fraction of u_max (the rest is left to the feedback: start-up transients,
    #: unlearnt loads).
    drive_headroom: float = 0.7
    #: Smallest v_max :func:`commission.tune.defaults.default_envelope` derives, m/s (rad/s on a
    #: rotary axis); below it the box is refused instead.
    min_default_v_max: float = 0.1
    #: Smallest a_max it derives, m/s^2 (rad/s^2 on a rotary axis).
    min_default_a_max: float = 1.0
    #: Share of the feedforward budget (``drive_headroom x u_max``) that a *defaulted* load-force
    #: bound is narrowed to when, at its default, not even the smallest default envelope fits
    #: (:func:`commission.tune.defaults.fit_disturbance_to_drive`).
    disturbance_share: float = 0.5
    #: Bisection steps of :func:`commission.tune.box.fit_payload_to_drive` (the payload range to
    #: 2^-20 of the default's).
    drive_bisections: int = 20

    @property
    def cap_low(self) -> float:
        """Lowest cap multiple the search considers (the low end of k1 in ``free_bounds``).

        An axis whose PID yardstick crosses over far below the carried-over paper gains'
        bandwidth (a low rate against a structural mode) needs caps of a tenth of the base to keep
        its margins (the matched starts); a quarter left such axes no gains that tie the PID's loop.
        """
        return self.free_bounds[0][1]

    @property
    def theta1_0_low(self) -> float:
        """Lowest theta_hat1(0) the search considers, as a fraction of the identified nominal theta1
        (the low end of t1 in ``free_bounds``; further clipped to the box).

        theta_hat1(0) below the nominal trades a slower start on the empty axis for a faster one
        under payload (a payload only lowers theta1 = 1/M); above the nominal nothing is gained.
        """
        return next(b[1] for b in self.free_bounds if b[0] == "t1")

    @property
    def match_scales(self) -> tuple[float, ...]:
        """Cap scales the matched starts try, largest (fastest loop) first, relative to the base
        gains' caps: ``match_scale_count`` geometric from ``match_scale_max`` to :attr:`cap_low`."""
        return tuple(float(v) for v in np.geomspace(self.match_scale_max, self.cap_low, self.match_scale_count))

    @property
    def free_log_lo(self) -> np.ndarray:
        """The low ends of ``free_bounds`` in log space (a fresh array)."""
        return np.log([b[1] for b in self.free_bounds])

    @property
    def free_log_hi(self) -> np.ndarray:
        """The high ends of ``free_bounds`` in log space (a fresh array)."""
        return np.log([b[2] for b in self.free_bounds])


#: The settings ``commission tune`` runs with.
DEFAULT_SETTINGS = TuneSettings()

__all__ = ["DEFAULT_SETTINGS", "PAPER_RATE", "PAPER_THETA1", "PAPER_THETA1_0", "TuneSettings"]
