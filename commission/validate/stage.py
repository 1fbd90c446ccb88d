"""The validate stage: every scenario simulated with the ARC and the PID, the gate and the
robustness checks evaluated (:func:`validate`), and the default payload range certified
(:func:`certify_default_payload`).
"""

from __future__ import annotations

import math
import time
import dataclasses
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from commission.infra.blas import on_one_blas_thread
from commission.artifacts import Identification
from commission.controllers.arc import arc_pack
from commission.controllers.plant import P_B, P_M, P_OFFSET
from commission.controllers.pid import pid_pack
from commission.controllers.simulate import KIND_ARC, KIND_PID, SimResult, simulate, simulate_batch
from commission.controllers.trajectory import Trajectory
from commission.errors import UsageError
from commission.infra.executor import Executor, LocalExecutor
from commission.gate import (MARGIN_KEYS, NOMINAL_COMPARISON_VARIANTS, FloorContext, GateLimits, GateSpec, GateVerdict,
                             arc_vs_pid_nominal_checks, evaluate_gate, box_checks, margin_checks, resolve_gate,
                             safety_failures)
from commission.montecarlo import MonteCarloSummary
from commission.evidence import evidence_checks, evidence_table
from commission.robustness import (BoxArcCheck, MarginFloors, margin_table, identified_performance, nominal_loops,
                                   payload_box)
from commission.scenarios import (PAYLOAD_BISECTIONS, largest_safe_payload, payload_heavy_at, plant_substeps,
                                  scenario_matrix)
from commission.spec import check_flags
from commission.controllers.metrics import Indexes
from commission.tuning import Tuning
from commission.units import axis_units_context
from commission.validate.results import DEFAULT_MONTE_CARLO, Progress, RunRecord, Trace, ValidationResult
from commission.validate.guards import deployable_gains, runtime_guards


@dataclass(frozen=True)
class _Outcome:
    score: Indexes
    t_abort: float
    theta_final: tuple[float, float, float]
    sim: SimResult | None


def _theta_true(plant: np.ndarray) -> tuple[float, float, float]:
    M = float(plant[P_M])
    return (1.0 / M, float(plant[P_B]) / M, -float(plant[P_OFFSET]) / M)


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


def _outcome(ctx: _SimContext, kind: int, score: Indexes, n_steps: int, diverged: bool, zero_from: int,
             theta_final: tuple[float, float, float], sim: SimResult | None) -> _Outcome:
    """A run's outcome from its record: an abort's time, and a latched runtime guard (the safe
    command 0 to the end stops the machine) read as an abort -- a safety failure on every
    scenario, as an abort is (the error limits no longer catch it on a safety scenario)."""
    t_abort = n_steps * ctx.Ts if diverged else math.nan
    k = latched_fault_from(n_steps, zero_from) if kind == KIND_ARC and not diverged else None
    if k is not None:
        score, t_abort = dataclasses.replace(score, diverged=True), k * ctx.Ts
    return _Outcome(score, t_abort, theta_final, sim)


def _disturbance(s: Any, ref: Trajectory) -> np.ndarray | None:
    d = s.disturbance.samples(ref.t)
    return d if np.any(d) else None


def _simulate_one(ctx: _SimContext, s: Any, kind: int) -> _Outcome:
    """One scenario's run, its traces kept (for the figures)."""
    ref = ctx.refs[(s.trajectory, s.y0)]
    r = simulate(s.plant, kind, ctx.ctrl[kind], ref, substeps=plant_substeps(1.0 / ctx.Ts), quant=s.quantization,
                 disturbance=_disturbance(s, ref), noise=s.noise(ref.n), y0=s.y0, u_sat=ctx.u_sat,
                 e_abort=ctx.e_abort)
    th = r.theta_hat
    final = tuple(float(x) for x in th[-1]) if th is not None and th.shape[0] else (math.nan,) * 3
    return _outcome(ctx, kind, r.score(), r.n_steps, r.diverged, _zero_from(r), final, r)  # type: ignore[arg-type]


def _simulate_together(ctx: _SimContext, group: Sequence[Any], dists: Sequence[np.ndarray | None],
                       kinds: tuple[int, ...] = (KIND_ARC, KIND_PID)) -> list[tuple[_Outcome, ...]]:
    """ARC and PID on scenarios that share a trajectory, a start, an encoder and which signals they
    carry (``dists``: each one's disturbance, all None or none), each controller as one
    :func:`commission.controllers.simulate.simulate_batch` on this task's thread (scores only).
    ``kinds``: the controllers of ``ctx`` run, in that order (each tuple of the result follows it;
    :func:`_simulate_pid` runs the PID alone).

    The batch steps two runs whose plants interleave in one loop (its ``interleave``), which
    overlaps them on the core; every run's values are its own :func:`simulate`'s to the last bit,
    so each outcome is :func:`_simulate_one`'s without the traces.
    """
    s0 = group[0]
    ref = ctx.refs[(s0.trajectory, s0.y0)]
    noises = [s.noise(ref.n) for s in group]
    plants = np.stack([s.plant for s in group])
    dist = None if dists[0] is None else np.stack(dists)  # type: ignore[arg-type]
    noise = None if noises[0] is None else np.stack(noises)  # type: ignore[arg-type]
    per_kind = []
    for kind in kinds:
        r = simulate_batch(plants, kind, ctx.ctrl[kind], ref, substeps=plant_substeps(1.0 / ctx.Ts),
                           quant=s0.quantization, disturbance=dist, noise=noise, y0=s0.y0, u_sat=ctx.u_sat,
                           e_abort=ctx.e_abort, workers=1)
        per_kind.append([_outcome(ctx, kind, sc, int(r.n_steps[i]), bool(r.diverged[i]), int(r.u_zero_from[i]),
                                  tuple(float(x) for x in r.theta_final[i]), None)  # type: ignore[arg-type]
                         for i, sc in enumerate(r.scores())])
    return list(zip(*per_kind))  # type: ignore[arg-type]


#: Trailing samples of an exactly-zero ARC command that count as a latched runtime fault (the step's
#: safe command): a running ARC's command (feedforward, friction compensation, robust terms) is never
#: exactly 0.0 for this long.
FAULT_ZERO_SAMPLES = 8


def latched_fault_from(n_steps: int, zero_from: int) -> int | None:
    """The sample from which a run's recorded ARC command is exactly 0 to the end (``zero_from`` of
    ``n_steps`` recorded samples), when that is a latched fault (at least :data:`FAULT_ZERO_SAMPLES`
    samples, ending the run); else None."""
    return int(zero_from) if n_steps - zero_from >= FAULT_ZERO_SAMPLES else None


def _zero_from(r: SimResult) -> int:
    """Where ``r``'s recorded command's trailing run of exact zeros starts (``n_steps``: none)."""
    nz = np.flatnonzero(r.u[: r.n_steps] != 0.0)
    return int(nz[-1]) + 1 if nz.size else 0


def latched_fault_start(r: SimResult) -> int | None:
    """The sample from which the ARC's command is exactly 0 to the end, when that is a latched fault
    (:func:`latched_fault_from`); else None."""
    return latched_fault_from(r.n_steps, _zero_from(r))


def _simulate_chunk(ctx: _SimContext, chunk: Sequence[tuple[Any, bool]]) -> list[tuple[_Outcome, _Outcome]]:
    """One executor task: ARC and PID on each scenario of ``chunk`` ((scenario, keep traces) pairs).

    A pure function of its arguments (the Monte-Carlo plant is in the scenario, the encoder
    noise is seeded by the scenario's name), so it gives the same answer on any worker.  The
    scenarios whose traces are not kept run in batches of those that can share one
    (:func:`_simulate_together`); the values are the same as one at a time.
    """
    out: list[tuple[_Outcome, _Outcome] | None] = [None] * len(chunk)
    groups: dict[tuple, list[tuple[int, np.ndarray | None]]] = {}
    for i, (s, keep) in enumerate(chunk):
        if keep:
            out[i] = (_simulate_one(ctx, s, KIND_ARC), _simulate_one(ctx, s, KIND_PID))
            continue
        d = _disturbance(s, ctx.refs[(s.trajectory, s.y0)])
        key = (s.trajectory, s.y0, s.quantization, s.noise_std > 0.0, d is not None)
        groups.setdefault(key, []).append((i, d))
    for rows in groups.values():
        got = _simulate_together(ctx, [chunk[i][0] for i, _ in rows], [d for _, d in rows])
        for (i, _), pair in zip(rows, got):
            out[i] = pair
    return out  # type: ignore[return-value]


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
    executor : commission.infra.executor.Executor, optional
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
        beyond = beyond_evidence_checks(ex, ctx, scenarios, runs, tuning, limits)
    # The whole box (theta_hat at each plant's theta: the floors; theta_hat anywhere: stability).
    box = BoxArcCheck(tuning.identification, spec)(arc)
    evidence, evidence_rows = evidence_table(arc, tuning.pid, tuning.identification, spec)
    verdict = GateVerdict(gated.checks + tuple(beyond) + tuple(margin_checks(margins, gate_floors))
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


def beyond_evidence_checks(ex: Executor, ctx: _SimContext, scenarios: Sequence[Any], runs: Sequence[RunRecord],
                           tuning: Tuning, limits: GateLimits) -> list[Any]:
    """The ARC against the PID beyond the evidence on the identified plant (criterion ``arc_vs_pid_nominal``).

    Where only the evidence bound held the PID yardstick down, tune records the faster PID the
    identified plant admits (tuning.json ``pid_yardstick.unbacked_pid``,
    :func:`commission.tune.baseline.unbacked_pid`).  That PID is run on the scenarios the nominal
    comparison sums (:data:`commission.gate.NOMINAL_COMPARISON_VARIANTS`), with the same encoder
    noise as the ARC's runs, and the ARC must beat it there as it must beat the yardstick
    (:func:`commission.gate.arc_vs_pid_nominal_checks` with ``beyond``).  A loss is a comparison
    failure: the ARC is safe and written flagged, and the report says that a log backing a higher
    band is what a faster ARC needs.  No checks without the record.
    """
    from commission.tune.baseline import pid_gains_of  # the record's reader lives with its writer

    ub = (tuning.pid_yardstick or {}).get("unbacked_pid")
    if not ub:
        return []
    arc_of = {r.name: r for r in runs}
    sel = [s for s in scenarios if "monte_carlo" not in s.tags and "/" in s.name
           and s.name.rsplit("/", 1)[-1] in NOMINAL_COMPARISON_VARIANTS and s.name in arc_of]
    fast = dataclasses.replace(ctx, ctrl={**ctx.ctrl, KIND_PID: pid_pack(pid_gains_of(ub["gains"]))})
    outs = list(ex.map(_simulate_pid, fast, sel))
    rows = [(s.name, arc_of[s.name].arc, o.score, arc_of[s.name].arc_t_abort) for s, o in zip(sel, outs)]
    return arc_vs_pid_nominal_checks(limits, rows, beyond=float(ub["pole"]))


def _simulate_pid(ctx: _SimContext, s: Any) -> _Outcome:
    """The PID of ``ctx`` on one scenario, scores only (an executor task)."""
    return _simulate_together(ctx, [s], [_disturbance(s, ctx.refs[(s.trajectory, s.y0)])], kinds=(KIND_PID,))[0][0]


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
