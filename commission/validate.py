"""The ``commission validate`` pipeline: tuning.json -> report, gate verdict, controller.json.

Steps (numerics in :mod:`commission.controllers`; this module orchestrates):

1. Inputs are checked before any simulation: the gate TOML
   (:func:`commission.gate.load_gate`), tuning.json (strict schema), the seed
   and the Monte-Carlo count, and the output folder (an existing output file
   is refused without ``force``).
2. The scenario matrix (:func:`commission.scenarios.scenario_matrix`): the 12
   fixed scenarios (Case 1 and Case 2 x nominal, payload at both theta_1
   bounds, friction +-20 %, the delta_d disturbance step), the robustness
   scenarios (one more sample of input delay; a known mode moved and less damped) and
   ``n_monte_carlo`` plants drawn from the theta box with
   ``numpy.random.default_rng(seed)``.
3. Every scenario is simulated with the tuned ARC and with the PID baseline
   (:func:`commission.controllers.simulate.simulate`: exact ZOH plant with
   :func:`~commission.scenarios.plant_substeps` sub-steps, the encoder quantization of the tuning, the
   actuator limit ``spec.u_max``, abort when ``|q - q_d|`` exceeds the
   envelope's travel).  The runs are independent and the compiled loop
   releases the GIL, so they are spread over a thread pool (one thread per
   CPU by default); results do not depend on the number of threads.  The ARC
   is simulated with the gains *as read back from the controller.json
   layout*, runtime guards included (:func:`runtime_guards`), so what was
   validated is what is deployed.
4. The gate (:mod:`commission.gate`) is checked on every scenario, the
   robustness ones included, and on the stability margins of the ARC on the
   identified plant (:mod:`commission.robustness`,
   :func:`commission.gate.margin_checks`: gate.toml's margin keys, by default
   the tuning spec's ``[margins]``); the floors (:data:`commission.gate.FLOORS`:
   no divergence anywhere, the spec's margin floors, ...) hold whatever
   gate.toml says.  The robustness part is also listed apart in the report.
   Above the band the log backs, the ARC must keep robust stability ``||W T|| < 1``
   against the uncertainty weight of :mod:`commission.evidence`, and where the log
   measured the response, its modulus margin floor on the coherent measured bins
   (criterion ``margins``, scenarios ``evidence/...`` and ``measured/...``).
5. Outputs: ``validation.json`` (every index of every run, the gate and every
   check), ``report.md`` (+ the PNGs the CLI draws), and ``controller.json``
   only when every check passed.  With ``force`` and a failing gate a
   controller.json left by an earlier run is removed, so that the folder never
   pairs a failing report with a deployable file.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import time
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

import commission
from commission.blas import on_one_blas_thread
from commission.artifacts import Identification
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.plant import P_B, P_DELAY, P_FS, P_M, P_OFFSET, P_RIPPLE_AMP
from commission.controllers.pid import pid_pack
from commission.controllers.simulate import KIND_ARC, KIND_PID, SimResult, simulate
from commission.controllers.trajectory import Trajectory
from commission.errors import SchemaError, UsageError
from commission.executor import Executor, LocalExecutor, make_executor, resolve_scheduler
from commission.files import Outputs
from commission.gate import (MARGIN_KEYS, FloorContext, GateLimits, GateSpec, GateVerdict, evaluate_gate, load_gate,
                             box_checks, margin_checks, resolve_gate, safe_not_better, safety_failures)
from commission.montecarlo import MonteCarloSummary
from commission.jsonio import canonical_json, read_json, sha256_file, sha256_json, write_json_atomic, write_text_atomic
from commission.report import report_markdown
from commission.evidence import Evidence, RobustStability, evidence_checks, evidence_table
from commission.robustness import (CONTROLLERS, BoxArcCheck, BoxRobustness, LoopMargins, MarginFloors, margin_table,
                                   identified_performance, nominal_loops, payload_box, worst)
from commission.scenarios import (FRICTION_SCALE, case1_trajectory, case2_trajectory, check_run_length,
                                  PAYLOAD_BISECTIONS, force_range, largest_safe_payload, payload_heavy_at, plant_substeps,
                                  resolve_encoder_noise, scenario_matrix)
from commission.spec import Spec, check_flags, nominal_rate
from commission.tuning import Score, Tuning, log_sha256_of
from commission.units import axis_units_context

Progress = Callable[[int, int], None]

VALIDATION_KIND = "validation"
VALIDATION_SCHEMA_VERSION = 1
#: Monte-Carlo plants by default.
DEFAULT_MONTE_CARLO = 64

REPORT_NAME = "report.md"
VALIDATION_NAME = "validation.json"
CONTROLLER_NAME = "controller.json"
#: The ARC of a validation that failed only on the comparison with the PID yardstick
#: (:func:`commission.gate.safe_not_better`): loadable with ``load_controller``, flagged in
#: ``validated.flag``; never named controller.json (CONTRACT: that file means every gate passed).
FLAGGED_NAME = "controller_not_better.json"
#: Figures the CLI draws (cli/plots_validate.py); listed here so that --force checks cover them.
#: The tracking figure of the machine's own moves, drawn only when the spec gives them.
USER_FIGURE_NAME = "tracking_user.png"
FIGURE_NAMES = ("tracking_case1.png", "tracking_case2.png", "theta_hat.png", "control_input.png",
                "monte_carlo.png", "loops.png")


@dataclass(frozen=True)
class RunRecord:
    """ARC and PID on one scenario.

    Attributes
    ----------
    name : str
    tags : tuple of str
    arc, pid : Score
        Indexes (SI units; NaN when diverged) and the peak |u|.
    arc_t_abort, pid_t_abort : float
        Time of the abort, s (NaN when the run completed).
    theta_final : tuple of 3 float
        ARC estimates at the last sample.
    theta_true : tuple of 3 float
        The scenario plant's [1/M, B/M, -offset/M] (friction not included).
    """

    name: str
    tags: tuple[str, ...]
    arc: Score
    pid: Score
    arc_t_abort: float
    pid_t_abort: float
    theta_final: tuple[float, float, float]
    theta_true: tuple[float, float, float]

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "tags": list(self.tags), "arc": self.arc.to_dict(), "pid": self.pid.to_dict(),
                "arc_t_abort": _nn(self.arc_t_abort), "pid_t_abort": _nn(self.pid_t_abort),
                "theta_final": [_nn(x) for x in self.theta_final], "theta_true": list(self.theta_true)}


@dataclass(frozen=True)
class Trace:
    """Time histories of one fixed scenario, for the figures.

    Arrays stop at an abort (``y_arc`` and ``y_pid`` may be shorter than ``t``).

    Attributes
    ----------
    t, qd : numpy.ndarray
        Sample times (s) and desired position (m).
    y_arc, u_arc, y_pid, u_pid : numpy.ndarray
        Measured position (m) and applied command (u-unit).
    theta_hat : numpy.ndarray, shape (n, 3)
        ARC estimates.
    theta_true : tuple of 3 float
    """

    t: np.ndarray
    qd: np.ndarray
    y_arc: np.ndarray
    u_arc: np.ndarray
    y_pid: np.ndarray
    u_pid: np.ndarray
    theta_hat: np.ndarray
    theta_true: tuple[float, float, float]

    @property
    def e_arc(self) -> np.ndarray:
        """Measured ARC tracking error, m."""
        return self.y_arc - self.qd[: self.y_arc.shape[0]]

    @property
    def e_pid(self) -> np.ndarray:
        """Measured PID tracking error, m."""
        return self.y_pid - self.qd[: self.y_pid.shape[0]]


@dataclass(frozen=True)
class ValidationResult:
    """Everything ``validate`` computed.

    Attributes
    ----------
    runs : tuple of RunRecord
        In scenario-matrix order (fixed scenarios, then ``mc/NNN``).
    traces : dict
        Scenario name -> :class:`Trace`, for the fixed scenarios.
    verdict : GateVerdict
    units : dict
        ``{"u": command unit, "q": "m"}``.
    seed : int
    n_monte_carlo : int
    arc_gains : ArcGains
        The gains simulated (read back from the controller.json layout).
    quantization : float
        Encoder resolution simulated, m.
    e_abort : float
        Abort threshold on |q - q_d|, m.
    u_sat : float
        Actuator limit simulated, u-unit.
    elapsed : float
        Wall time of the simulations, s.
    workers : int
        Threads used.
    margins : tuple of LoopMargins
        Stability margins of both loops per plant (:mod:`commission.robustness`).
    margin_floors : MarginFloors
        The spec's floors they are held against.
    loops : tuple of ndarray
        ``(f_hz, L_arc, L_pid)`` on the identified plant, for the loop figure (not in JSON).
    box : BoxRobustness or None
        The ARC over the whole theta box (:class:`commission.robustness.BoxArcCheck`), gated as
        criterion ``margins_box``.
    robustness : GateVerdict or None
        The part of ``verdict`` on the robustness scenarios and the stability margins (required
        like every other check; listed apart in the report).
    executor : dict or None
        Where the simulations ran (:meth:`commission.executor.Executor.describe`); varies with the
        machine, so it is not written to validation.json (which is the same on every executor).
    monte_carlo_summary : dict or None
        Quantiles and worst plants of the Monte-Carlo sample (:mod:`commission.montecarlo`).
    evidence : Evidence or None
        What the certificate rests on: the band the log backs and the uncertainty weight above it
        (:mod:`commission.evidence`).
    evidence_rows : tuple of RobustStability
        Peak ``|W T|`` of the ARC (both linearisations) and the PID, and their margins on the
        measured response.
    validity : mapping or None
        The payload range certified when validate narrowed a defaulted one
        (:func:`certify_default_payload`); None: the tuning's own ``validity`` (or the whole box).
    """

    runs: tuple[RunRecord, ...]
    traces: Mapping[str, Trace]
    verdict: GateVerdict
    units: Mapping[str, str]
    seed: int
    n_monte_carlo: int
    arc_gains: ArcGains
    quantization: float
    e_abort: float
    u_sat: float
    elapsed: float
    workers: int
    margins: tuple[LoopMargins, ...] = ()
    margin_floors: MarginFloors = MarginFloors()
    loops: tuple[np.ndarray, ...] = ()
    robustness: GateVerdict | None = None
    executor: Mapping[str, Any] | None = None
    monte_carlo_summary: Mapping[str, Any] | None = None
    box: BoxRobustness | None = None
    evidence: Evidence | None = None
    evidence_rows: tuple[RobustStability, ...] = ()
    validity: Mapping[str, Any] | None = None

    @property
    def passed(self) -> bool:
        return self.verdict.passed

    def run(self, name: str) -> RunRecord:
        for r in self.runs:
            if r.name == name:
                return r
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": VALIDATION_KIND,
            "schema_version": VALIDATION_SCHEMA_VERSION,
            "passed": self.passed,
            "seed": self.seed,
            "monte_carlo": self.n_monte_carlo,
            "units": dict(self.units),
            "simulation": {"substeps": plant_substeps(1.0 / self.arc_gains.Ts), "quantization": self.quantization,
                           "e_abort": self.e_abort,
                           "u_sat": _nn(self.u_sat), "sample_period": self.arc_gains.Ts},
            "gate": self.verdict.limits.to_dict(),
            "failures": [c.to_dict() for c in self.verdict.failures],
            "worst": {k: c.to_dict() for k, c in self.verdict.worst().items()},
            "runs": [r.to_dict() for r in self.runs],
            "elapsed_s": self.elapsed,
            "monte_carlo_summary": None if self.monte_carlo_summary is None else dict(self.monte_carlo_summary),
            "robustness": None if self.robustness is None else {
                "passed": self.robustness.passed, "required": True,
                "failures": [c.to_dict() for c in self.robustness.failures],
                "checks": len(self.robustness.checks)},
            "margins": {"floors": self.margin_floors.to_dict(), "loops": [m.to_dict() for m in self.margins],
                        "worst": {c: (w.to_dict() if (w := worst(self.margins, c)) is not None else None)
                                  for c in CONTROLLERS}},
            **({} if self.box is None else {"box_robustness": self.box.to_dict(self.margin_floors)}),
            "evidence": None if self.evidence is None else {
                **self.evidence.to_dict(), "loops": [r.to_dict() for r in self.evidence_rows]},
            **({} if self.validity is None else {"validity": dict(self.validity)}),
        }


def _nn(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


#: Speed margin of the plausibility guard: the axis is taken to move at most this
#: many times the envelope's v_max in one sample.
GUARD_SPEED_MARGIN = 2.0
#: Acceleration margin of the plausibility guard: the axis is taken to accelerate at most this
#: many times the largest acceleration of the validated trajectories.
GUARD_ACCEL_MARGIN = 3.0
#: Encoder noise peaks counted in the error of one measurement, in standard deviations.
GUARD_NOISE_SIGMAS = 4.0
#: Fewest still samples (command at u_max, or an implausible y) that latch the frozen-encoder fault.
GUARD_FROZEN_MIN = 3
#: The tracking-error watchdog trips at this many times the gate's e_M.
GUARD_E_M_FACTOR = 2.0
#: Rejected samples in a row that latch a fault span at least this long, s.
GUARD_REJECT_TIME = 2e-3


def runtime_guards(tuning: Tuning, limits: GateLimits) -> dict[str, Any]:
    """The runtime guards of the deployed ARC (ArcGains fields), from the envelope and the gate.

    * ``dy_max = 2 v_max Ts + 2 LSB``: the axis moves at most
      :data:`GUARD_SPEED_MARGIN` x the envelope's v_max in one sample, and the
      encoder rounds each end by half a step (doubled).
    * ``accel_max = 3 a_env``, ``y_err = LSB/2 + 4 sigma``: the innovation bound
      of the prediction (:mod:`commission.controllers.arc`, "Runtime guards").
      a_env is the largest acceleration of the validated trajectories (Case 1's
      filter starts above the spec's a_max) or the spec's a_max if larger; the
      closed loop adds its own transients to it, hence :data:`GUARD_ACCEL_MARGIN`.
      y_err bounds the error of one reading: half an encoder step and
      :data:`GUARD_NOISE_SIGMAS` standard deviations of the simulated encoder noise.
    * ``u_free`` (:func:`holding_force`): the largest command that may leave the
      axis at rest -- friction, ripple, the box's constant forces, the disturbance step.
    * ``n_frozen_max = max(3, ceil(sqrt(64 y_err / a_rail) / Ts) + delay samples)``
      with a_rail = theta1_min (u_max - u_free): under a command at the rail the
      axis accelerates at least a_rail (the lightest-accelerating plant of the
      box, every holding force against it), so within that many samples after
      the plant's input delay its readings must spread over more than the 8 y_err
      a still run allows (a constant acceleration a spreads positions over at
      least a T^2/8 in a time T, whatever the initial speed).  A smaller push
      counts sqrt of its fraction of the rail's (the same spread takes 1/sqrt(a)
      as long); a rejected reading counts 1.  The delay counted is the identified one plus one
      sample: the gate certifies the loop with one more sample of delay (``<case>/delay+1``), so
      the guard must not take the later answer of such a drive for a frozen encoder.
    * ``dy_fault = travel``: no reading can move by the whole stroke in one sample.
    * ``n_reject_max = max(2, ceil(GUARD_REJECT_TIME / Ts))``: the prediction
      (tracking error held) carries the loop through at most 2 ms of glitches.
    * ``e_max = min(2 e_M, travel)`` with e_M the gate's resolved limit: a run
      in which the watchdog trips has already failed the gate's e_M by a factor
      2, so the watchdog never turns a passing validation into a failing one;
      it only stops a run-away on the machine.
    * ``freeze_on_saturation = True``: the gate fails a command that reaches
      u_max, so in a passing validation this never acts; on the machine it keeps
      theta_hat out of the box's corners while the drive is at its limit.

    None of them acts in a validation that passes: the speed bound is twice the
    envelope's, the acceleration bound three times the trajectories' (plus what the
    drive's own command steps explain), and the frozen count needs an implausible y
    or a command that must move the axis, held while the readings stay put.
    ``validate`` simulates with them (see :func:`deployable_gains`), so what it
    proved is what runs.
    """
    spec, Ts = tuning.spec, tuning.arc.Ts
    return guard_values(Ts, tuning.quantization, spec.v_max, spec.travel, limits.e_M,
                        a_max=envelope_acceleration(spec, Ts), u_free=holding_force(tuning.identification, tuning.plant),
                        noise_std=resolve_encoder_noise(tuning.identification, spec),
                        theta1_min=tuning.arc.theta_min[0], u_max=tuning.arc.u_max,
                        delay=float(tuning.plant[P_DELAY]) + Ts)  # the +1 sample the certificate covers


def holding_force(ident: Identification, plant: np.ndarray) -> float:
    """The largest command that may leave the axis at rest in the validated scenarios, u-unit.

    Static friction and force ripple of the identified plant at the friction scenarios' +20 %
    (:data:`commission.scenarios.FRICTION_SCALE`), plus the largest constant force the theta
    box admits at every mass (:func:`commission.scenarios.force_range`), plus the
    Assumption-1 disturbance step delta_d M.  A command beyond it accelerates the axis.

    Parameters
    ----------
    ident : Identification
    plant : numpy.ndarray
        The identified plant vector (:func:`commission.scenarios.identified_plant`).
    """
    lo, hi = force_range(ident)
    step = abs(ident.delta_d * ident.value("M")) if ident.delta_d is not None else 0.0
    return ((1.0 + FRICTION_SCALE) * (abs(float(plant[P_FS])) + abs(float(plant[P_RIPPLE_AMP])))
            + max(abs(lo), abs(hi)) + step)


def envelope_acceleration(spec: Spec, Ts: float) -> float:
    """Largest |q_d''| of the validated trajectories (Case 1, Case 2) sampled at ``Ts``, or the
    spec's a_max if larger, m/s^2 (Case 1's filter starts above a_max)."""
    a_env = float(spec.a_max)
    for traj in (case1_trajectory(spec), case2_trajectory(spec)):
        a_env = max(a_env, float(np.max(np.abs(traj.render(Ts, 0.0).ddqd))))
    return a_env


def guard_values(Ts: float, lsb: float, v_max: float, travel: float, e_M: float, *, a_max: float | None = None,
                 theta1_min: float | None = None, u_max: float | None = None, u_free: float = 0.0,
                 noise_std: float = 0.0, delay: float = 0.0) -> dict[str, Any]:
    """:func:`runtime_guards` from the numbers it uses.

    Parameters
    ----------
    Ts : float
        Sample period, s.
    lsb : float
        Encoder resolution, m.
    v_max : float
        Envelope speed, m/s.
    travel : float
        Envelope stroke, m.
    e_M : float
        The gate's resolved transient limit, m (inf: none).
    a_max : float, optional
        Largest acceleration of the validated trajectories, m/s^2
        (:func:`envelope_acceleration`).  Without it, and without ``theta1_min`` and
        ``u_max``, the innovation and frozen-encoder guards are left out (off).
    theta1_min : float, optional
        Lower bound of theta1 = 1/M, m/(u-unit s^2).
    u_max : float, optional
        Output limit, u-unit.
    u_free : float
        Largest command that may leave the axis at rest, u-unit (:func:`holding_force`).
    noise_std : float
        Encoder noise simulated, m rms.
    delay : float
        The plant's input delay, s.
    """
    e_max = min(GUARD_E_M_FACTOR * e_M, travel) if math.isfinite(e_M) else travel
    guards: dict[str, Any] = {
        "dy_max": GUARD_SPEED_MARGIN * v_max * Ts + 2.0 * lsb,
        "dy_fault": travel,
        "n_reject_max": float(max(2, math.ceil(GUARD_REJECT_TIME / Ts - 1e-9))),
        "e_max": e_max,
        "freeze_on_saturation": True,
    }
    if a_max is None or theta1_min is None or u_max is None:
        return guards
    y_err = 0.5 * lsb + GUARD_NOISE_SIGMAS * noise_std
    guards.update(accel_max=GUARD_ACCEL_MARGIN * a_max, y_err=y_err)
    push = 0.0 < u_free < u_max  # else no command is known to move the axis: only rejected readings count
    a_rail = theta1_min * (u_max - u_free if push else u_max)
    n_frozen = math.ceil(math.sqrt(64.0 * y_err / a_rail) / Ts - 1e-9) + math.ceil(delay / Ts - 1e-9)
    guards.update(n_frozen_max=float(max(GUARD_FROZEN_MIN, n_frozen)), u_free=u_free if push else 0.0)
    return guards


def deployable_gains(arc: ArcGains, guards: Mapping[str, Any] | None = None) -> ArcGains:
    """``arc`` with the runtime ``guards`` (:func:`runtime_guards`), after a round trip
    through the controller.json layout (what the runtime will run)."""
    if guards:
        arc = dataclasses.replace(arc, **guards)
    probe = ControllerConfig(gains=arc, sample_rate=1.0 / arc.Ts, units={"u": "V", "q": "m"}, validated={},
                             provenance=ControllerProvenance(None, "0" * 64, "0" * 64, "", ""))
    doc = json.loads(json.dumps(probe.to_dict()))
    # Infinite limits pass the round trip here; the floors (commission.gate.FLOORS) then refuse to emit them.
    back = ControllerConfig.from_dict(doc, "controller.json (round trip)", allow_unbounded=True).gains
    if not np.array_equal(arc_pack(back), arc_pack(arc)):  # pragma: no cover - a layout bug
        raise RuntimeError("controller.json layout does not reproduce the tuned ARC exactly")
    return back


@dataclass(frozen=True)
class _Outcome:
    score: Score
    t_abort: float
    theta_final: tuple[float, float, float]
    sim: SimResult | None


def _theta_true(plant: np.ndarray) -> tuple[float, float, float]:
    M = float(plant[P_M])
    return (1.0 / M, float(plant[P_B]) / M, -float(plant[P_OFFSET]) / M)


def _score(r: SimResult) -> Score:
    peak = float(np.max(np.abs(r.u))) if r.n_steps > 0 else math.nan
    if r.indexes is None:
        return Score(math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, peak, True)
    i = r.indexes
    return Score(i.e_M, i.e_F, i.e_rms, i.u_rms, i.du_rms, i.c_u, peak, False)


def _t_abort(r: SimResult, Ts: float) -> float:
    return r.n_steps * Ts if r.diverged else math.nan


#: Monte-Carlo plants per executor task: large enough that a task (2 x 16 simulations) outweighs
#: a Dask round trip, small enough that a lost worker costs little and the chunks spread evenly.
MC_CHUNK = 16


@dataclass(frozen=True)
class _SimContext:
    """What every simulation task reads (sent to a Dask worker once per validation)."""

    ctrl: Mapping[int, np.ndarray]
    refs: Mapping[tuple, Trajectory]
    Ts: float
    u_sat: float
    e_abort: float


def _simulate_one(ctx: _SimContext, s: Any, kind: int, keep: bool) -> _Outcome:
    ref = ctx.refs[(s.trajectory, s.y0)]
    d = s.disturbance.samples(ref.t)
    r = simulate(s.plant, kind, ctx.ctrl[kind], ref, substeps=plant_substeps(1.0 / ctx.Ts), quant=s.quantization,
                 disturbance=d if np.any(d) else None, noise=s.noise(ref.n), y0=s.y0, u_sat=ctx.u_sat,
                 e_abort=ctx.e_abort)
    th = r.theta_hat
    final = tuple(float(x) for x in th[-1]) if th is not None and th.shape[0] else (math.nan,) * 3
    score, t_abort = _score(r), _t_abort(r, ctx.Ts)
    k = latched_fault_start(r) if kind == KIND_ARC and not r.diverged else None
    if k is not None:
        # A latched runtime guard (the safe command 0 to the end) stops the machine: a safety failure on
        # every scenario, as an abort is (the error limits no longer catch it on a safety scenario).
        score, t_abort = dataclasses.replace(score, diverged=True), k * ctx.Ts
    return _Outcome(score, t_abort, final, r if keep else None)  # type: ignore[arg-type]


#: Trailing samples of an exactly-zero ARC command that count as a latched runtime fault (the step's
#: safe command): a running ARC's command (feedforward, friction compensation, robust terms) is never
#: exactly 0.0 for this long.
FAULT_ZERO_SAMPLES = 8


def latched_fault_start(r: SimResult) -> int | None:
    """The sample from which the ARC's command is exactly 0 to the end, when that is a latched fault
    (at least :data:`FAULT_ZERO_SAMPLES` samples, ending the run); else None."""
    u = r.u[: r.n_steps]
    if u.size < FAULT_ZERO_SAMPLES or np.any(u[-FAULT_ZERO_SAMPLES:] != 0.0):
        return None
    nz = np.flatnonzero(u != 0.0)
    return int(nz[-1]) + 1 if nz.size else 0


def _simulate_chunk(ctx: _SimContext, chunk: Sequence[tuple[Any, bool]]) -> list[tuple[_Outcome, _Outcome]]:
    """One executor task: ARC and PID on each scenario of ``chunk`` ((scenario, keep traces) pairs).

    A pure function of its arguments (the Monte-Carlo plant is in the scenario, the encoder
    noise is seeded by the scenario's name), so it gives the same answer on any worker.
    """
    return [(_simulate_one(ctx, s, KIND_ARC, keep), _simulate_one(ctx, s, KIND_PID, keep)) for s, keep in chunk]


def _simulate_matrix(ex: Executor, ctx: _SimContext, scenarios: Sequence[Any], units: Mapping[str, str],
                     progress: Progress | None) -> tuple[list[RunRecord], dict[str, Trace], dict[str, Any] | None]:
    """Run every scenario on ``ex``; fold the results in scenario order.

    Tasks: one per fixed scenario (their time histories come back for the figures), and one
    per :data:`MC_CHUNK` Monte-Carlo plants (only the scores come back, folded into the
    streaming :class:`commission.montecarlo.MonteCarloSummary` and the compact run records the
    gate checks).  ``progress(done, total)`` counts simulations (2 per scenario).
    """
    chunks: list[list[tuple[Any, bool]]] = []
    mc = [s for s in scenarios if "monte_carlo" in s.tags]
    for s in scenarios:
        if "monte_carlo" not in s.tags:
            chunks.append([(s, True)])
    for k in range(0, len(mc), MC_CHUNK):
        chunks.append([(s, False) for s in mc[k:k + MC_CHUNK]])
    order = [s for ch in chunks for s, _ in ch]
    total = 2 * len(order)
    done = [0]

    def tick(i: int) -> None:  # once per simulation of the finished task
        for _ in range(2 * len(chunks[i])):
            done[0] += 1
            if progress is not None:
                progress(done[0], total)

    if progress is not None:
        progress(0, total)
    summary = MonteCarloSummary(dict(units)) if mc else None
    by_name: dict[str, RunRecord] = {}
    traces: dict[str, Trace] = {}
    it = iter(order)
    for outs in ex.map(_simulate_chunk, ctx, chunks, progress=tick):
        for oa, op in outs:
            s = next(it)
            truth = _theta_true(s.plant)
            by_name[s.name] = RunRecord(s.name, s.tags, oa.score, op.score, oa.t_abort, op.t_abort, oa.theta_final,
                                        truth)
            if summary is not None and "monte_carlo" in s.tags:
                summary.add(s.name, oa.score, op.score)
            if oa.sim is not None and op.sim is not None:
                ref = ctx.refs[(s.trajectory, s.y0)]
                th = oa.sim.theta_hat
                traces[s.name] = Trace(t=ref.t, qd=ref.qd, y_arc=oa.sim.y, u_arc=oa.sim.u, y_pid=op.sim.y,
                                       u_pid=op.sim.u, theta_hat=th if th is not None else np.empty((0, 3)),
                                       theta_true=truth)
    runs = [by_name[s.name] for s in scenarios]  # scenario-matrix order
    return runs, traces, None if summary is None else summary.to_dict()


@on_one_blas_thread
def validate(tuning: Tuning, gate: GateSpec | None = None, *, seed: int = 0,
             n_monte_carlo: int = DEFAULT_MONTE_CARLO, progress: Progress | None = None,
             workers: int | None = None, executor: Executor | None = None) -> ValidationResult:
    """Simulate the scenario matrix with the tuned ARC and the PID baseline; check the gate.

    Parameters
    ----------
    tuning : Tuning
    gate : GateSpec, optional
        Default: every default of :mod:`commission.gate`.
    seed : int
        Seed of the Monte-Carlo sample (``numpy.random.default_rng(seed)``).
    n_monte_carlo : int
        Monte-Carlo plants from the theta box.
    progress : callable(done, total), optional
        Called once per simulation (``total`` = 2 x scenarios) as each task finishes, on the
        calling thread.
    workers : int, optional
        Threads of the local executor (default: ``os.cpu_count()``); ignored with ``executor``.
    executor : commission.executor.Executor, optional
        Where the simulations run (default: local threads).  The result does not depend on it
        (:func:`_simulate_matrix`).

    Returns
    -------
    ValidationResult
    """
    check_flags(seed=seed, monte_carlo=n_monte_carlo, workers=workers)
    gate = GateSpec() if gate is None else gate
    spec = tuning.spec
    limits: GateLimits = resolve_gate(gate, lsb=tuning.quantization, travel=spec.travel, u_max=spec.u_max,
                                       targets=spec.targets, yardstick=tuning.pid_yardstick)
    scenarios = scenario_matrix(tuning.identification, spec, rng=np.random.default_rng(seed),
                                n_monte_carlo=n_monte_carlo)
    arc = deployable_gains(tuning.arc, runtime_guards(tuning, limits))
    ctrl = {KIND_ARC: arc_pack(arc), KIND_PID: pid_pack(tuning.pid)}
    Ts = arc.Ts
    if abs(tuning.pid.Ts - Ts) > 1e-12 * Ts:
        raise UsageError(f"tuning: ARC and PID sample periods differ ({Ts} s vs {tuning.pid.Ts} s)")
    e_abort = spec.travel
    u_sat = spec.u_max
    refs: dict[tuple, Trajectory] = {}
    for s in scenarios:
        key = (s.trajectory, s.y0)
        if key not in refs:
            refs[key] = s.trajectory.render(Ts, s.y0)
    ex = LocalExecutor(workers) if executor is None else executor
    ctx = _SimContext(ctrl=ctrl, refs=refs, Ts=Ts, u_sat=u_sat, e_abort=e_abort)
    t0 = time.perf_counter()
    runs, traces, mc_summary = _simulate_matrix(ex, ctx, scenarios, dict(tuning.identification.units), progress)
    runs, traces, validity = certify_default_payload(ex, ctx, scenarios, runs, traces, tuning, limits)
    elapsed = time.perf_counter() - t0
    nworkers = ex.workers
    margins = margin_table(arc, tuning.pid, tuning.identification, spec)
    margin_floors = MarginFloors.from_spec(spec)
    # The gate's margin criteria: gate.toml's values where given, else the spec's floors; the spec's
    # floors are also a floor of FLOORS, so a gate.toml cannot lower them.
    gate_floors = dataclasses.replace(margin_floors, **{MARGIN_KEYS[k]: v for k, v in gate.margins.items()})
    floors = FloorContext(runs=[(r.name, r.arc, r.arc_t_abort) for r in runs],
                          limits={k: float(getattr(arc, k)) for k in ("u_max", "k1s_max", "k2s_max")},
                          drive_u_max=u_sat, margins=margins, margin_floors=margin_floors)
    with axis_units_context(tuning.identification.units.get("q", "m")):  # the failures' details in q's unit
        gated = evaluate_gate(limits, [(r.name, r.arc, r.pid, r.arc_t_abort) for r in runs], floors,
                              performance=performance_set(runs, tuning.identification), compare_nominal=True)
    # The whole box (theta_hat at each plant's theta: the floors; theta_hat anywhere: stability).
    box = BoxArcCheck(tuning.identification, spec)(arc)
    evidence, evidence_rows = evidence_table(arc, tuning.pid, tuning.identification, spec)
    verdict = GateVerdict(gated.checks + tuple(margin_checks(margins, gate_floors))
                          + tuple(box_checks(box, gate_floors))
                          + tuple(evidence_checks(evidence_rows, evidence, gate_floors.modulus)), limits)
    # The robustness part of the verdict, for the report: the robustness scenarios and the margins.
    rob_names = {r.name for r in runs if "robustness" in r.tags}
    robustness = GateVerdict(tuple(c for c in verdict.checks
                                   if c.scenario in rob_names
                                   or c.criterion in ("margins", "floor:margins", "margins_box")), limits)
    return ValidationResult(runs=tuple(runs), traces=traces, verdict=verdict,
                            units=dict(tuning.identification.units), seed=int(seed),
                            n_monte_carlo=int(n_monte_carlo), arc_gains=arc, quantization=tuning.quantization,
                            e_abort=e_abort, u_sat=u_sat, elapsed=elapsed, workers=nworkers,
                            margins=margins, margin_floors=margin_floors, robustness=robustness, box=box,
                            evidence=evidence, evidence_rows=evidence_rows,
                            loops=nominal_loops(arc, tuning.pid, tuning.identification, spec),
                            executor=ex.describe(), monte_carlo_summary=mc_summary, validity=validity)


def certify_default_payload(ex: Executor, ctx: _SimContext, scenarios: Sequence[Any], runs: list[RunRecord],
                            traces: dict[str, Trace], tuning: Tuning, limits: GateLimits
                            ) -> tuple[list[RunRecord], dict[str, Trace], dict[str, Any] | None]:
    """Certify the largest DEFAULTED payload the ARC holds safely (issue 30, Build 1; docs/robustness.md).

    When the payload range was defaulted (``bounds.payload_defaulted``: the user stated no payload) and
    the ARC fails a SAFETY criterion (:func:`commission.gate.safety_failures`: divergence, c_u, a clipped
    command) on a ``<case>/payload_heavy`` scenario, the heavy end is bisected
    (:func:`commission.scenarios.largest_safe_payload` on :func:`commission.scenarios.payload_heavy_at`,
    the same gains): the payload_heavy runs of the largest safe payload replace the failed ones, and the
    certified range becomes the certificate's ``validity`` (controller.json, validation.json, the report's
    first lines).  The controller is unchanged (its projection still spans the default box, whose margins
    the box check certifies); what is narrowed is the range the certificate claims.  A stated payload range
    is never narrowed: the gate refuses it, naming the corner.

    Returns
    -------
    runs, traces
        With the payload_heavy runs at the certified payload (unchanged when nothing was narrowed).
    validity : dict or None
        The ``validity`` record (:func:`commission.tune.box.validity_of`'s keys, plus ``narrowed_by``
        "validate"), None when nothing was narrowed.
    """
    ident = tuning.identification
    pb = payload_box(ident)
    if pb is None or not pb[3] or ident.theta is None:
        return runs, traces, None
    pmin, pmax, m0, _ = pb

    def unsafe(rs: Sequence[RunRecord]) -> list[Any]:
        return safety_failures(limits, [(r.name, r.arc, r.pid, r.arc_t_abort) for r in rs])

    bad = unsafe([r for r in runs if r.name.endswith("/payload_heavy") and "monte_carlo" not in r.tags])
    if not bad or not pmax > pmin:
        return runs, traces, None
    units = dict(ident.units)
    tried: dict[float, tuple[list[RunRecord], dict[str, Trace]]] = {}

    def safe(payload: float) -> bool:
        sims, tr, _ = _simulate_matrix(ex, ctx, payload_heavy_at(scenarios, m0 + payload), units, None)
        tried[payload] = (sims, tr)
        return not unsafe(sims)

    got = largest_safe_payload(pmin, pmax, safe)
    if got is None:
        return runs, traces, None
    sims, tr = tried[got]
    new = {r.name: r for r in sims}
    from commission.tune.box import mass_unit
    unit = mass_unit(ident)
    b = ident.extra["bounds"]
    earlier = tuning.validity or {}
    diverged = {c.scenario for c in bad if c.criterion == "divergence"}  # its c_u and peak say nothing more
    what = "; ".join(sorted({f"{c.criterion} at {c.scenario}" for c in bad
                             if c.criterion == "divergence" or c.scenario not in diverged}))
    validity = {"payload_range": [pmin, got], "mass_range": [float(b["mass_range"][0]), m0 + got], "unit": unit,
                "default_payload_range": list(earlier.get("default_payload_range", [pmin, pmax])),
                "payload_defaulted": True, "narrowed_by": "validate",
                "reason": (f"validate: with {pmax:.4g} {unit} of payload the ARC fails {what}; every safety check "
                           f"holds up to {got:.4g} {unit} (bisection to 1/{2 ** PAYLOAD_BISECTIONS} of the range)")
                + (f"; tune had narrowed the default before: {earlier['reason']}" if earlier.get("reason") else "")}
    return [new.get(r.name, r) for r in runs], {**traces, **tr}, validity


def performance_set(runs: Sequence[RunRecord], ident: Identification) -> frozenset[str]:
    """The validation's PERFORMANCE scenarios (:func:`commission.robustness.identified_performance`)."""
    return identified_performance([r.name for r in runs], ident)


# --------------------------------------------------------------------------- controller.json


def validated_record(result: ValidationResult) -> dict[str, Any]:
    """The ``validated`` section of controller.json.

    ``gate``: the resolved limits; ``worst``: per criterion the worst value and
    its scenario; ``nominal``: the ARC's indexes on the identified plant per
    trajectory (``case1``, ``case2``), i.e. the performance the identified model predicts.
    """
    worst = result.verdict.worst()
    nominal = {r.tags[0]: r.arc.to_dict() for r in result.runs if "nominal" in r.tags}
    return {
        "gate": result.verdict.limits.to_dict(),
        "nominal": nominal,
        "worst": {k: {"scenario": c.scenario, "value": _nn(c.value), "limit": _nn(c.limit)} for k, c in worst.items()},
        "scenarios": len(result.runs),
        "monte_carlo": result.n_monte_carlo,
        "seed": result.seed,
        "simulation": {"substeps": plant_substeps(1.0 / result.arc_gains.Ts), "quantization": result.quantization,
                       "e_abort": result.e_abort,
                       "u_sat": _nn(result.u_sat)},
    }


#: controller.json states the nominal rate when the validated one is within this of it: rounding in a
#: rate estimated from time stamps, well inside the loader's 1e-9 check of sample_period x sample_rate.
NOMINAL_RATE_RTOL = 1e-10


def controller_config(result: ValidationResult, tuning: Tuning, tuning_sha256: str,
                      created_utc: str | None = None, *, flagged: bool = False) -> ControllerConfig:
    """The deployable controller of a passed validation.

    With ``flagged``, the ARC of a validation that failed only on the comparison with the PID
    yardstick (:func:`commission.gate.safe_not_better`): its ``validated`` record holds a ``flag``
    (``beats_yardstick`` false, the failed comparison checks and the yardstick's pole).

    Raises
    ------
    ValueError
        When the gate did not pass (a controller is never built from a failed validation), unless
        ``flagged`` and the validation is safe but not better.
    """
    if flagged and not safe_not_better(result.verdict):
        raise ValueError("controller_config: flagged only when the gate failed on the PID comparison alone")
    if not result.passed and not flagged:
        raise ValueError("controller_config: the gate failed; no controller is emitted")
    prov = ControllerProvenance(
        log_sha256=log_sha256_of(tuning),
        ident_sha256=tuning.provenance.ident_sha256,
        tuning_sha256=tuning_sha256,
        tool_version=commission.__version__,
        created_utc=created_utc or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    )
    # The nominal rate the drive is programmed with (2500, not 2500.0000000058 estimated from a log's
    # time stamps); sample_period stays the period validated, within the loader's 1e-9 of 1/sample_rate.
    rate = nominal_rate(tuning.spec.sample_rate, rel=NOMINAL_RATE_RTOL)
    record = validated_record(result)
    if flagged:
        record["flag"] = not_better_flag(result, tuning)
    return ControllerConfig(gains=result.arc_gains, sample_rate=rate,
                            units=dict(tuning.identification.units), validated=record,
                            provenance=prov, validity=certified_validity(result, tuning))


def certified_validity(result: ValidationResult, tuning: Tuning) -> dict[str, Any] | None:
    """The payload range the certificate claims: validate's narrowing, else tune's, else None (the whole box)."""
    v = result.validity if result.validity is not None else tuning.validity
    return None if v is None else dict(v)


def not_better_flag(result: ValidationResult, tuning: Tuning) -> dict[str, Any]:
    """The ``validated.flag`` of a flagged ARC: what it failed and what the PID yardstick is."""
    ys = tuning.pid_yardstick or {}
    return {"beats_yardstick": False, "verdict": "safe_not_better",
            "failed": [c.to_dict() for c in result.verdict.failures],
            "pid_pole": tuning.pid_pole, "pid_yardstick_method": ys.get("method", "unrecorded"),
            "pid_gains": {"Kp": tuning.pid.Kp, "Ki": tuning.pid.Ki, "Kd": tuning.pid.Kd,
                          "M_hat": tuning.pid.M_hat, "B_hat": tuning.pid.B_hat}}


# --------------------------------------------------------------------------- file-level pipeline


@dataclass(frozen=True)
class ValidateOutcome:
    """What :func:`run_validate` wrote.

    Attributes
    ----------
    result : ValidationResult
    tuning : Tuning
    written : tuple of Path
        Every file written, in order.
    controller : Path or None
        controller.json when the gate passed.
    """

    result: ValidationResult
    tuning: Tuning
    written: tuple[Path, ...]
    controller: Path | None


FigureWriter = Callable[[ValidationResult, Path], Sequence[Path]]


def _identification_as_identified(tuning: Tuning) -> dict[str, Any]:
    """tuning.json's embedded identification as ident.json held it: tune's theta3 narrowing undone.

    ``tune`` may narrow the theta3 box (:func:`commission.tune.narrow_disturbance_box`) and
    records the box it started from in ``bounds.narrowed_by_tune``; restoring that box and
    dropping the record gives back the identification tune read.  A record that does not
    contain the narrowed box is left as it is (and the comparison that follows then fails).
    """
    embedded = json.loads(json.dumps(tuning.identification.to_dict()))
    _undo_payload_narrowing(embedded)
    narrowed = (embedded.get("bounds") or {}).pop("narrowed_by_tune", None)
    if isinstance(narrowed, dict):
        lo, hi = embedded["theta"]["min"][2], embedded["theta"]["max"][2]
        t3min, t3max = narrowed.get("theta3_min"), narrowed.get("theta3_max")
        if (isinstance(t3min, (int, float)) and isinstance(t3max, (int, float)) and t3min <= lo <= hi <= t3max
                and _narrowed_as_recorded(narrowed, lo, hi, embedded["theta"]["max"][0])):
            embedded["theta"]["min"][2], embedded["theta"]["max"][2] = t3min, t3max
    return embedded


def _undo_payload_narrowing(embedded: dict[str, Any]) -> None:
    """Undo tune's narrowing of a defaulted payload range (``bounds.payload_narrowed_by_tune``,
    :func:`commission.tune.box.narrow_default_payload`) in place.

    Restored only when the record is consistent with a narrowing (the recorded box's lower ends
    at or below the embedded ones, the embedded theta1_min = 1/M_hi of the embedded mass range,
    the narrowed payload within the default one); otherwise the record is left, and the
    comparison that follows fails.
    """
    bounds = embedded.get("bounds")
    rec = bounds.get("payload_narrowed_by_tune") if isinstance(bounds, dict) else None
    if not isinstance(rec, dict):
        return
    try:
        t1, t2 = float(rec["theta1_min"]), float(rec["theta2_min"])
        dpay, dmass = [float(x) for x in rec["default_payload_range"]], [float(x) for x in rec["default_mass_range"]]
        pay, mass = [float(x) for x in bounds["payload_range"]], [float(x) for x in bounds["mass_range"]]
        tmin = embedded["theta"]["min"]
        ok = (t1 <= tmin[0] and t2 <= tmin[1] and dpay[0] == pay[0] and pay[1] <= dpay[1]
              and math.isclose(1.0 / tmin[0], mass[1], rel_tol=1e-9) and dmass[0] == mass[0])
    except (KeyError, TypeError, ValueError, IndexError, ZeroDivisionError):
        return
    if not ok:
        return
    bounds.pop("payload_narrowed_by_tune")
    tmin[0], tmin[1] = t1, t2
    bounds["payload_range"], bounds["mass_range"] = dpay, dmass


def _narrowed_as_recorded(narrowed: Mapping[str, Any], lo: float, hi: float, theta1_max: float) -> bool:
    """The narrowed theta3 box is the one tune recorded as a force range (``narrowed_force_range``,
    theta3 x the lightest mass 1/theta1_max), so that a box shrunk further by hand inside the
    narrowing is not taken for tune's; a record without the force range is taken as it is."""
    rec = narrowed.get("narrowed_force_range")
    if rec is None:
        return True
    if not (isinstance(rec, list) and len(rec) == 2 and all(isinstance(x, (int, float)) for x in rec)):
        return False
    m_light = 1.0 / theta1_max
    return all(math.isclose(r, v * m_light, rel_tol=1e-9, abs_tol=1e-300) for r, v in zip(rec, (lo, hi)))


def check_provenance(tuning: Tuning, tuning_path: str) -> None:
    """Check tuning.json's embedded identification against the ident.json it was tuned from.

    The embedded identification sets the plant box that validate simulates, so an edit there
    (a box shrunk to +-0.1 %) would validate a controller for an axis nobody identified.

    - **ident.json at hand**: it is looked for where ``provenance.ident_path`` says
      (relative to the working folder) and beside tuning.json under the same name.  Its
      sha256 must be ``provenance.ident_sha256``, and the embedded identification must be
      that file's content, up to the theta3 narrowing that tune records
      (``bounds.narrowed_by_tune``: within the file's box, and the box tune recorded).
    - **ident.json not at hand** (tuning.json travels alone): ident.json as this tool writes
      it is the canonical JSON (:func:`commission.jsonio.canonical_json`) of its content, and
      tune embeds that content verbatim, so the canonical JSON of the embedded
      identification, narrowing undone, hashes to ``provenance.ident_sha256``.  A mismatch
      is refused: the embedded identification was edited after tune, or tune read an
      ident.json this tool did not write (then give validate that file, beside tuning.json).
      An unkeyed hash catches edits, not an author who recomputes it: a signed
      controller.json (``--sign-key``) is what proves origin.

    Raises
    ------
    SchemaError
        Naming ``$.provenance.ident_sha256`` (ident.json changed since the tuning) or
        ``$.identification`` (tuning.json's identification edited).
    """
    rec = tuning.provenance.ident_path
    cands = [Path(rec), Path(tuning_path).parent / Path(rec).name]
    found = next((c for c in cands if c.is_file()), None)
    embedded = _identification_as_identified(tuning)
    if found is None:
        actual = sha256_json(embedded)
        if actual != tuning.provenance.ident_sha256:
            raise SchemaError(
                f"{tuning_path}: $.identification: hashes to {actual[:16]}..., not to $.provenance.ident_sha256 "
                f"{tuning.provenance.ident_sha256[:16]}..., and {rec} is not at hand to compare with: tuning.json "
                f"was edited after tune (the validated plant box would not be the identified one), or it was tuned "
                f"from an ident.json this tool did not write (put that ident.json beside tuning.json)")
        return
    actual = sha256_file(found)
    if actual != tuning.provenance.ident_sha256:
        raise SchemaError(f"{tuning_path}: $.provenance.ident_sha256: {tuning.provenance.ident_sha256[:16]}... is not "
                          f"the sha256 of {found} ({actual[:16]}...): that identification is not the one this tuning "
                          f"was made from (tune again, or validate with the matching ident.json)")
    from commission.artifacts import Identification

    ident = Identification.from_dict(read_json(found), source=str(found)).to_dict()
    if json.loads(canonical_json(embedded)) != json.loads(canonical_json(ident)):
        raise SchemaError(f"{tuning_path}: $.identification: differs from {found}, whose sha256 the tuning records: "
                          f"tuning.json was edited after tune (the validated plant box would not be the identified one)")


def output_names() -> tuple[str, ...]:
    """Every file ``validate`` may write into its output folder."""
    return (REPORT_NAME, VALIDATION_NAME, CONTROLLER_NAME, FLAGGED_NAME, *FIGURE_NAMES, USER_FIGURE_NAME)


def run_validate(tuning_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                 gate_path: str | os.PathLike[str] | None = None, force: bool = False, seed: int = 0,
                 n_monte_carlo: int = DEFAULT_MONTE_CARLO, progress: Progress | None = None,
                 workers: int | None = None, figures: FigureWriter | None = None,
                 sign_key: bytes | None = None, scheduler: str | None = None,
                 executor: Executor | None = None) -> ValidateOutcome:
    """File-level pipeline of ``commission validate`` (module docstring).

    Every input check runs before any simulation (the flags' ranges, the gate,
    tuning.json and its provenance, the trajectories' length, the output
    folder, which is then locked), and the files are moved into place together
    when the simulations are done (:class:`commission.files.Outputs`).

    Parameters
    ----------
    tuning_path : path
        tuning.json.
    out_dir : path
        Folder for report.md, validation.json, the figures and controller.json.
    gate_path : path, optional
        gate.toml (default: the documented defaults).
    force : bool
        Overwrite existing outputs.
    seed, n_monte_carlo, progress, workers
        As in :func:`validate`.
    figures : callable(result, out_dir) -> paths, optional
        Draws the figures (the CLI passes its matplotlib writer); report.md links what it returns.
    sign_key : bytes, optional
        Signs controller.json with HMAC-SHA256 (:mod:`commission.controller_config`).
    scheduler : str, optional
        ``--scheduler``: a Dask scheduler address; else ``COMMISSION_SCHEDULER``; else local
        threads (:func:`commission.executor.resolve_scheduler`).  Connected to after the input
        checks and before any simulation.
    executor : commission.executor.Executor, optional
        An open executor instead (a library caller's; not closed here).

    Raises
    ------
    InputFileError, SchemaError, SpecError, UsageError
        Bad input (exit 2); nothing is written.  An unreachable scheduler is a
        :class:`commission.executor.SchedulerError` (a UsageError) naming its address.
    """
    check_flags(seed=seed, monte_carlo=n_monte_carlo, workers=workers)
    gate = load_gate(gate_path)
    tpath = os.fspath(tuning_path)
    tuning = Tuning.from_dict(read_json(tpath), source=tpath)
    check_run_length(tuning.spec, tpath, "$.spec.")
    check_provenance(tuning, tpath)
    # Resolve now so that a gate that cannot apply to this tuning fails before any simulation.
    resolve_gate(gate, lsb=tuning.quantization, travel=tuning.spec.travel, u_max=tuning.spec.u_max,
                 targets=tuning.spec.targets)
    outputs = Outputs(force=force, inputs=(tpath, gate_path))
    out = outputs.add_dir(out_dir, output_names(), "--out-dir")
    tuning_sha = sha256_file(tpath)
    own = executor is None
    ex = make_executor(resolve_scheduler(scheduler), workers) if own else executor
    try:
        with outputs:  # locked and proved writable before the simulations; moved into place at the end
            result = validate(tuning, gate, seed=seed, n_monte_carlo=n_monte_carlo, progress=progress,
                              workers=workers, executor=ex)
            staged = write_outputs(result, tuning, tuning_sha, outputs.staging(out), figures=figures,
                                   sources={"tuning": tpath, "gate": os.fspath(gate_path) if gate_path else None},
                                   sign_key=sign_key)
    finally:
        if own:
            ex.close()
    written = [outputs.final(p) for p in staged]
    ctrl = out / CONTROLLER_NAME
    return ValidateOutcome(result, tuning, tuple(written), ctrl if result.passed else None)


def write_outputs(result: ValidationResult, tuning: Tuning, tuning_sha256: str, out: Path, *,
                  figures: FigureWriter | None = None, sources: Mapping[str, str | None] | None = None,
                  sign_key: bytes | None = None, extra_figures: Sequence[Path] = ()) -> list[Path]:
    """Write validation.json, the figures, report.md and (gate and floors passed) controller.json into ``out``.

    ``out`` is the staging folder of :class:`commission.files.Outputs` in the commands;
    ``extra_figures`` are figures already written there (``run``'s identification
    figures), which the report links.
    """
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    write_json_atomic(out / VALIDATION_NAME, result.to_dict())
    written.append(out / VALIDATION_NAME)
    figs = [*extra_figures, *(figures(result, out) if figures is not None else [])]
    written.extend(figs)
    text = report_markdown(result, tuning, figures=[p.name for p in figs], sources=sources or {},
                           tuning_sha256=tuning_sha256)
    write_text_atomic(out / REPORT_NAME, text)
    written.append(out / REPORT_NAME)
    ctrl = out / CONTROLLER_NAME
    if result.passed:
        write_json_atomic(ctrl, controller_config(result, tuning, tuning_sha256).to_dict(sign_key=sign_key))
        written.append(ctrl)
    elif ctrl.exists():
        ctrl.unlink()  # never leave a deployable file next to a failing report
    flagged = out / FLAGGED_NAME
    if safe_not_better(result.verdict):
        write_json_atomic(flagged, controller_config(result, tuning, tuning_sha256, flagged=True)
                          .to_dict(sign_key=sign_key))
        written.append(flagged)
    elif flagged.exists():
        flagged.unlink()
    return written


__all__ = [
    "DEFAULT_MONTE_CARLO", "RunRecord", "Trace", "ValidationResult", "ValidateOutcome", "validate",
    "controller_config", "validated_record", "not_better_flag", "FLAGGED_NAME", "run_validate", "write_outputs", "output_names", "check_provenance",
    "deployable_gains", "runtime_guards", "guard_values", "envelope_acceleration", "holding_force",
    "log_sha256_of", "latched_fault_start", "performance_set",
]
