"""What the search minimises: the :class:`Evaluator` simulates a candidate on the tuning
scenarios (batch simulator, memoised), :func:`cost` turns the scores into one number
(log accuracy against the targets, soft penalties for chattering, saturation, divergence and
the PID baseline), :func:`gate_excess` (the gate constraint), and :class:`HoldoutGate`
judges finalists on plants the search never saw (:func:`gate_excess`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence
import numpy as np
from commission.artifacts import Identification
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.design import KIND_ARC, KIND_PID
from commission.controllers.pid import PidGains, pid_pack
from commission.controllers.simulate import simulate_batch
from commission.gate import ARC_VS_PID_QUANTILES, GateLimits, evaluate_gate, required_factor
from commission.scenarios import Scenario, plant_substeps, scenario_matrix
from commission.spec import Spec
from commission.controllers.metrics import Indexes
from commission.tune.defaults import default_gate_limits
from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings


Progress = Callable[[int, int], None]


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
    settings : TuneSettings
        ``corner_weight``.
    """

    def __init__(self, scenarios: Sequence[Scenario], spec: Spec, workers: int | None = None,
                 settings: TuneSettings = DEFAULT_SETTINGS) -> None:
        self.scenarios = list(scenarios)
        self.spec = spec
        self.workers = workers
        #: Objective weight per scenario: the box corners (tune-only stand-ins for the
        #: Monte-Carlo sample) and the robustness scenarios (constraints more than
        #: performance) count ``settings.corner_weight`` each, every other scenario 1.
        self.weights = [settings.corner_weight if ("corner" in s.tags or "robustness" in s.tags) else 1.0
                        for s in self.scenarios]
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

    def scores(self, kind: int, ctrl_ps: Sequence[np.ndarray],
               only: Sequence[int] | None = None) -> list[list[Indexes]]:
        """``scores[c][j]`` of candidate ``c`` on scenario ``only[j]`` (default: every scenario, in order)."""
        sel = list(range(len(self.scenarios))) if only is None else [int(i) for i in only]
        pos = {si: j for j, si in enumerate(sel)}
        nc, ns = len(ctrl_ps), len(sel)
        out: list[list[Indexes | None]] = [[None] * ns for _ in range(nc)]
        P = np.stack(ctrl_ps)
        for g in self.groups:
            rows = [j for j, si in enumerate(g.idx) if si in pos]
            if not rows:
                continue
            m = len(rows)
            plants = np.tile(g.plants[rows], (nc, 1))
            cps = np.repeat(P, m, axis=0)
            dist = None if g.dist is None else np.tile(g.dist[rows], (nc, 1))
            noise = None if g.noise is None else np.tile(g.noise[rows], (nc, 1))
            r = simulate_batch(plants, kind, cps, g.traj, substeps=plant_substeps(self.spec.sample_rate),
                               quant=g.quant, disturbance=dist, noise=noise, y0=self.scenarios[g.idx[0]].y0,
                               u_sat=self.spec.u_max, e_abort=self.spec.travel, workers=self.workers)
            # No traces: the kernel's u_peak (recorded samples, also before an abort) is all that is needed.
            recs = r.scores()
            for c in range(nc):
                for k, j in enumerate(rows):
                    out[c][pos[g.idx[j]]] = recs[c * m + k]
        return out  # type: ignore[return-value]


def cost(scores: Sequence[Indexes], spec: Spec, reference: Sequence[Indexes] | None = None,
         weights: Sequence[float] | None = None, gate: GateLimits | None = None,
         settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """Objective of one candidate (lower is better): see the module docstring, step 4.

    Per scenario::

        ln(e_rms / targets.e_rms)                                   objective
        + w_target  ln(e_F / targets.e_f)^+                          accuracy target
        + w_chatter ln(c_u / targets.c_u)^+ + w_step [c_u > target]  chattering target
        + w_saturation [|u| reached u_max]                           input limit
        + w_chatter ln(e_rms / (m e_rms_ref))^+ + w_step [e_rms > m ref]   better than the PID
                                                                     by the margin m = pid_margin
        + w_chatter ln(e_M / e_M_ref)^+ + w_step [e_M > e_M_ref]     and on the transient

    averaged over the scenarios with ``weights`` (default equal), plus, with ``gate`` given,
    ``w_quantile`` x :func:`quantile_excess` at ``pid_margin``: the gate's own ARC-vs-PID
    judgement (median and 90th percentile of its factor over the scenarios), so that the search
    minimises what the gate checks; without ``gate``,
    ``w_worst max_s ln(e_rms / (e_rms_ref + slack))`` (the scenario where the ARC gains least
    over the PID counts again).  A diverged run
    counts w_diverged.  ``reference`` are the PID baseline's scores on the same
    scenarios (optional).

    ``gate`` (optional) are validate's default gate limits for this axis.  Their ARC-vs-PID
    ``slack`` (m; the encoder's quantization-noise rms,
    :data:`commission.gate.DEFAULT_ARC_VS_PID_SLACK_LSB`) and quantile limits enter the
    quantile term only (as in the gate, the slack keeps a scenario where both controllers sit
    at the quantization floor from counting; in the per-scenario margin penalty it made the
    search settle for less).  The gate's absolute limits are not part of the objective: they
    are a constraint of the search (:mod:`commission.tune.constraints`).

    The weights ``w_*`` and the margin ``pid_margin`` are fields of ``settings``
    (:class:`~commission.tune.settings.TuneSettings`).
    """
    st = settings
    total = 0.0
    wsum = 0.0
    worst = -math.inf
    slack = 0.0 if gate is None else gate.arc_vs_pid_slack
    for i, s in enumerate(scores):
        w = 1.0 if weights is None else float(weights[i])
        wsum += w
        if s.diverged or not math.isfinite(s.e_rms) or s.e_rms <= 0:
            total += w * st.w_diverged
            continue
        j = math.log(s.e_rms / spec.e_rms)
        if reference is not None:
            r = reference[i]
            if not r.diverged and math.isfinite(r.e_rms) and r.e_rms > 0:
                worst = max(worst, math.log(s.e_rms / (r.e_rms + slack)))
                ref = st.pid_margin * r.e_rms
                if ref < s.e_rms:
                    j += st.w_step + st.w_chatter * math.log(s.e_rms / ref)
            if not r.diverged and math.isfinite(r.e_M) and 0 < r.e_M < s.e_M:
                # The transient too (the start-up against unlearnt estimates): e_rms alone let the
                # search trade the empty axis's start-up for a softer command.
                j += st.w_step + st.w_chatter * math.log(s.e_M / r.e_M)
        if s.e_F > 0:
            j += st.w_target * max(0.0, math.log(s.e_F / spec.e_f))
        if not (math.isfinite(s.c_u) and s.c_u >= 0):
            j += st.w_step + st.w_chatter
        elif s.c_u > spec.c_u:
            j += st.w_step + st.w_chatter * math.log(s.c_u / spec.c_u)
        if s.u_peak >= spec.u_max * (1.0 - 1e-9):
            j += st.w_saturation
        total += w * j
    out = total / wsum if wsum > 0 else 0.0
    if gate is not None and reference is not None:
        # What the gate judges (the median and 90th percentile of the ARC/PID factor), not the single
        # worst scenario: the minimax term chased the plant where no controller beats the PID.
        out += st.w_quantile * quantile_excess(gate, scores, reference, st.pid_margin, settings)
    elif math.isfinite(worst):
        out += st.w_worst * worst
    return out


def quantile_excess(gate: GateLimits, arc: Sequence[Indexes], pid: Sequence[Indexes], margin: float = 1.0,
                    settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """How far the ARC misses the gate's ARC-vs-PID quantiles on these scenarios (0: within), ln units.

    The factors are the gate's own (:func:`commission.gate.required_factor`, with the gate's slack)
    and so are the quantiles (:data:`commission.gate.ARC_VS_PID_QUANTILES`, numpy's ``"higher"``
    method); each quantile ``q`` counts ``ln(q / (margin limit))^+`` against its limit
    (``arc_vs_pid_median``, ``arc_vs_pid_p90``), an infinite one (a diverged run among the
    quantile's scenarios) ``settings.diverged_excess``.  ``margin`` < 1 asks for room: the tuning
    scenarios stand in for validate's Monte-Carlo plants.
    """
    f = np.array([required_factor(a, p, gate.arc_vs_pid_slack) for a, p in zip(arc, pid)])
    if f.size == 0:
        return 0.0
    total = 0.0
    for key, q in ARC_VS_PID_QUANTILES.items():
        v = float(np.quantile(f, q, method="higher"))
        lim = margin * float(getattr(gate, key))
        if not math.isfinite(v):
            total += settings.diverged_excess
        elif v > lim > 0:
            total += math.log(v / lim)
    return total


def meets_targets(scores: Sequence[Indexes], spec: Spec) -> bool:
    """Every run finite, within e_f and c_u targets and below the input limit."""
    return all(not s.diverged and s.e_F <= spec.e_f and s.c_u <= spec.c_u and s.u_peak < spec.u_max
               for s in scores)


class HoldoutGate:
    """validate's default gate on the tuning scenarios plus fresh Monte-Carlo plants.

    The search scores candidates on the tuning scenarios only; what decides deployment is
    the gate on validate's matrix, whose Monte-Carlo plants the search never saw.  This
    stands in for it inside ``tune``: ``settings.holdout_plants`` plants drawn from tune's own
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
    pid_scores : sequence of Indexes
        The PID's scores on ``ev``'s scenarios.
    rng : numpy.random.Generator
        Draws the hold-out plants.
    workers : int, optional
        Batch-simulator threads.
    n_plants : int, optional
        Hold-out Monte-Carlo plants (default ``settings.holdout_plants``).
    settings : TuneSettings
    """

    def __init__(self, ident: Identification, spec: Spec, ev: Evaluator, pid: PidGains,
                 pid_scores: Sequence[Indexes], *, rng: np.random.Generator, workers: int | None = None,
                 n_plants: int | None = None, settings: TuneSettings = DEFAULT_SETTINGS) -> None:
        n = settings.holdout_plants if n_plants is None else n_plants
        plants = [s for s in scenario_matrix(ident, spec, rng=rng, n_monte_carlo=n) if "monte_carlo" in s.tags]
        self.ev = ev
        self.settings = settings
        self.ev_h = Evaluator(plants, spec, workers=workers, settings=settings)
        self.pid_scores = [*pid_scores, *self.ev_h.scores(KIND_PID, [pid_pack(pid)])[0]]
        self.limits = default_gate_limits(ident, spec)
        self.names = [*ev.names, *self.ev_h.names]

    @property
    def n_plants(self) -> int:
        return len(self.ev_h.scenarios)

    def judge(self, gains: Sequence[ArcGains],
              tune_scores: Sequence[Sequence[Indexes]] | None = None) -> list[tuple[list[Indexes], int, float]]:
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
            out.append((t, len(evaluate_gate(self.limits, runs).failures),
                        gate_excess(self.limits, arc, self.pid_scores, settings=self.settings)))
        return out


def gate_excess(limits: GateLimits, arc: Sequence[Indexes], pid: Sequence[Indexes],
                margin: float = 1.0, *, yardstick_reach: bool = False,
                settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """Summed log-excess of the ARC's indexes over ``margin`` x their gate limits (0: all within).

    Per scenario: ``sum ln(index / (margin limit))^+`` over e_F, e_M, e_rms, c_u, the peak
    |u| (against u_max: a clipped command counts ln(1/margin)) and, when the gate compares
    scenario by scenario (``limits.arc_vs_pid_every``), the ARC-vs-PID e_rms (against ``factor x
    PID + slack``); a diverged run counts ``settings.diverged_excess``.  Otherwise (validate's default,
    which judges the comparison by quantiles) the constraint is the ARC's own limits, what makes
    it *safe*; beating the PID yardstick is the objective's (:func:`cost`).  Held as a constraint,
    an unreachable comparison with a strong yardstick left every candidate "gate missed", never
    checked for discrete feasibility: the search then returned gains unstable over the box.
    A smooth companion of the failure count (0 exactly when every index is within ``margin``
    of its limit): the search's gate constraint (:mod:`commission.tune.constraints`).

    ``yardstick_reach`` (the search's constraint, not the gate): on a scenario where the PID
    yardstick itself misses an absolute error limit (e_F, e_M, e_rms), the ARC is held to the
    PID's value there instead (no worse than the yardstick).  The box-corner stand-ins for the
    Monte-Carlo sample are harsher than any plant validate draws; where no PID meets a limit
    there, every candidate missed the constraint, the search ranked them all by that excess
    alone and the ARC-vs-PID objective never decided (docs/robustness.md, "Tune's defaults,
    measured").  validate's gate is unchanged.
    """
    total = 0.0
    every = getattr(limits, "arc_vs_pid_every", True)
    for a, p in zip(arc, pid):
        if a.diverged or not math.isfinite(a.e_rms):
            total += settings.diverged_excess
            continue
        lim_f, lim_m, lim_r = limits.e_F, limits.e_M, limits.e_rms
        if yardstick_reach and not p.diverged:
            lim_f, lim_m, lim_r = (max(lim, v / margin) if math.isfinite(v) else lim
                                   for lim, v in ((lim_f, p.e_F), (lim_m, p.e_M), (lim_r, p.e_rms)))
        ratios = [a.e_F / lim_f, a.e_M / lim_m, a.e_rms / lim_r, a.c_u / limits.c_u,
                  a.u_peak / limits.u_max]
        if not p.diverged and math.isfinite(p.e_rms):
            if every:
                ratios.append(a.e_rms / (limits.arc_vs_pid_e_rms * p.e_rms + limits.arc_vs_pid_slack))
        for r in ratios:
            if not math.isfinite(r):  # an index undefined (NaN) or unbounded counts as a diverged run
                total += settings.diverged_excess
            elif r > margin:
                total += math.log(r / margin)
    return total
