"""The gain search: one constrained optimisation with one objective, by CMA-ES (pycma's ask/tell).

Problem
-------
Minimise the performance objective :func:`commission.tune.objective.cost` of the ARC on the
tuning scenarios over its free gains (``free_bounds`` of :class:`commission.tune.settings.TuneSettings`, in log
coordinates, and the observer pole when the spec left it free), subject to

* the stability margins of the ARC on the identified plant, mode and delay included, meeting
  the spec's ``[margins]`` floors (:func:`commission.tune.constraints.margin_violation`), and
  over the whole theta box (:class:`commission.robustness.BoxArcCheck`: the floors with
  theta_hat at each corner plant's theta, stability with theta_hat anywhere the projection
  allows; :func:`commission.tune.constraints.box_violation`), checked only where the
  identified plant's margins hold;
  robust stability above the band the log backs (:meth:`commission.evidence.EvidenceBound.violation`:
  ``||W T|| < 1 - SEARCH_ROOM`` at both linearisations, counted with the margins);
* validate's default gate on the tuning scenarios, robustness scenarios included
  (:func:`commission.tune.objective.gate_excess` at the settings' ``gate_margin``);
* discrete feasibility over the theta box (:func:`commission.tune.constraints.feasibility_violation`).

Constraint handling
-------------------
Feasibility-first ranking (Deb's rules): a candidate that meets every constraint ranks above
every one that does not, and is ranked by its objective; candidates that keep their margins but
miss the gate come next, ranked by their gate excess; candidates that miss a margin or discrete
feasibility come last, ranked by their violation.
CMA-ES only uses the ranking of each generation, so this is the whole constraint handler;
pycma's augmented-Lagrangian wrapper (``cma.ConstrainedFitnessAL``) needs many more
generations than a tuning budget of about a hundred simulations allows for its multipliers
to settle.  The constraints are evaluated cheapest first: a candidate that misses a margin
floor (a linearisation, milliseconds) is not simulated at all, and one whose gate excess on
validate's own fixed and robustness scenarios (:func:`commission.scenarios.screening_indices`,
the smaller part of the simulation) already exceeds the settings' ``screen_excess`` is not simulated on the rest
(:attr:`Candidate.screened`); it ranks after every fully simulated candidate of its level.
The excess only grows with more scenarios, so the order among candidates whose whole gate
excess is at most ``screen_excess`` -- the ones near feasibility, where the ranking steers
the search -- is exactly the order without the screen.  (A screen on any excess would rank a
candidate that barely misses the screen below one that passes it and misses the rest by far.)

The winner is the best feasible candidate by validate's default gate on plants the search
never saw (:class:`commission.tune.objective.HoldoutGate`, :func:`select_on_holdout`): the
objective is scored on the tuning scenarios only.

The candidates and their order are :mod:`commission.tune.candidate`; the budget's sizing is
:mod:`commission.tune.budget`; every knob is a field of :class:`commission.tune.settings.TuneSettings`
(:attr:`Problem.settings`).
"""

from __future__ import annotations

import dataclasses
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable, Sequence

import cma
import numpy as np

from commission.artifacts import Identification
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.design import KIND_ARC, FeasibilityReport, observer_design
from commission.gate import GateLimits
from commission.evidence import EvidenceBound
from commission.robustness import BoxArcCheck, IdentifiedPlantArcMargins, MarginFloors
from commission.scenarios import screening_indices
from commission.spec import Spec
from commission.controllers.metrics import Indexes
from commission.tune.candidate import FEASIBLE, GATE_MISSED, STABILITY_MISSED, Candidate, SearchResult
from commission.tune.constraints import box_violation, feasibility_violation, margin_violation
from commission.tune.gains import I_THETA1_0, N_FREE, apply_free, paper_implementable_start
from commission.tune.objective import Evaluator, HoldoutGate, Progress, cost, gate_excess
from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings


class Problem:
    """The constrained problem of the module docstring, evaluated a generation at a time.

    Parameters
    ----------
    base : ArcGains
        :func:`commission.tune.gains.base_arc_gains`.
    ev : Evaluator
        The tuning scenarios.
    spec : Spec
    ident : Identification
        The plant the margins are computed on (mode and delay included).
    reference : sequence of Indexes
        The PID baseline's scores on ``ev``'s scenarios.
    gate : GateLimits
        validate's default gate for this axis.
    feasible : callable(ArcGains) -> FeasibilityReport
        Discrete feasibility over the theta box.
    observer_free : bool
        The observer pole is a coordinate (the spec left it at its default).
    target_crossover_hz : float, optional
        The PID yardstick's crossover on the identified plant, Hz: :meth:`matched_starts` looks
        for ARC gains with the same bandwidth (None: no such start).
    observer_scale : float
        Factor on the default observer pole that the observer coordinate is centred on (its
        bounds ``observer_factor_bounds`` x this), dimensionless: the
        :func:`commission.tune.baseline.bandwidth_factor` of an axis whose plant sets its
        bandwidth.  Ignored when the observer is pinned by the spec.
    plant_sets_bandwidth : bool
        The yardstick sits below the rate-scaled grid (that bandwidth factor < 1): the carried-over
        gains were scaled down to it, and :meth:`matched_starts` may fall back to the slowest
        gains that keep every linear constraint (:meth:`_slowest_matched`).  On any other axis a
        yardstick the caps cannot match is left to the search from the carried-over gains.
    settings : TuneSettings
        The search's knobs (:data:`commission.tune.settings.DEFAULT_SETTINGS`).
    """

    def __init__(self, base: ArcGains, ev: Evaluator, spec: Spec, ident: Identification,
                 reference: Sequence[Indexes], gate: GateLimits,
                 feasible: Callable[[ArcGains], FeasibilityReport], *, observer_free: bool,
                 target_crossover_hz: float | None = None, observer_scale: float = 1.0,
                 plant_sets_bandwidth: bool = False, settings: TuneSettings = DEFAULT_SETTINGS) -> None:
        self.base, self.ev, self.spec, self.ident = base, ev, spec, ident
        self.plant_sets_bandwidth = plant_sets_bandwidth
        self.observer_scale = observer_scale if observer_free else 1.0
        self.settings = st = settings
        self.target_crossover_hz = target_crossover_hz
        self.reference, self.gate, self.feasible = list(reference), gate, feasible
        self.floors = MarginFloors.from_spec(spec)
        self.screen = screening_indices(ev.scenarios)
        on_screen = set(self.screen)
        self.rest = [i for i in range(len(ev.scenarios)) if i not in on_screen]
        self.margins = IdentifiedPlantArcMargins(ident, spec)
        self.box = BoxArcCheck(ident, spec)
        self.evidence = EvidenceBound(ident, spec)
        o = math.log(self.observer_scale)
        lo = np.append(st.free_log_lo, o + math.log(st.observer_factor_bounds[0]))
        hi = np.append(st.free_log_hi, o + math.log(st.observer_factor_bounds[1]))
        start = np.append(np.log(st.free_start), o)
        if spec.theta1_0 is not None:  # theta_hat1(0) pinned by the spec
            start[I_THETA1_0] = math.log(spec.theta1_0 / base.theta0[0])
        self.active = [i for i in range(N_FREE + 1)
                       if not ((i == I_THETA1_0 and spec.theta1_0 is not None) or (i == N_FREE and not observer_free))]
        self.full0 = np.clip(start, lo, hi) if spec.theta1_0 is None else np.where(
            np.arange(N_FREE + 1) == I_THETA1_0, start, np.clip(start, lo, hi))
        self.lo, self.hi = lo[self.active], hi[self.active]

    # -- coordinates
    def full(self, z: np.ndarray) -> np.ndarray:
        """Log coordinates of every gain (pinned ones at their values) from the search vector ``z``."""
        v = self.full0.copy()
        v[self.active] = np.clip(z, self.lo, self.hi)
        return v

    def z_of(self, x: Sequence[float], observer_factor: float = 1.0) -> np.ndarray:
        """The search vector of relative free gains ``x`` (clipped to the bounds)."""
        v = np.append(np.log(np.asarray(x, dtype=np.float64)), math.log(observer_factor * self.observer_scale))
        return np.clip(v[self.active], self.lo, self.hi)

    def gains(self, z: np.ndarray) -> tuple[np.ndarray, float, ArcGains]:
        v = self.full(z)
        x, f = np.exp(v[:N_FREE]), math.exp(v[N_FREE])
        g = apply_free(self.base, x)
        if f != 1.0:
            ob = observer_design(self.spec.observer_pole * f, g.Ts)
            g = dataclasses.replace(g, k1=ob.k1, k2=ob.k2)
        return x, f, g

    def stability_violation(self, g: ArcGains) -> float:
        """The linear constraints of :meth:`evaluate` (margins and evidence on the identified plant,
        then the whole box), summed (0: every one met)."""
        v = margin_violation(self.margins(g), self.floors, self.settings) + self.evidence.violation(g)
        return v if v > 0 else box_violation(self.box(g), self.floors, self.settings)

    def crossover_hz(self, g: ArcGains) -> float:
        """The ARC's highest finite crossover on the identified plant over its linearisations, Hz
        (nan: none found, an unstable loop)."""
        return max((r.margins.crossover_hz for r in self.margins(g) if math.isfinite(r.margins.crossover_hz)),
                   default=math.nan)

    def matched_starts(self) -> list[np.ndarray]:
        """Search vectors whose linear feedback matches the PID yardstick's bandwidth, best match first.

        The ARC has the PID's feedback structure (position and velocity-estimate feedback, the
        theta3 adaptation as its integral action) plus model compensation: with the same
        crossover under the same floors it should at least tie the PID, and the compensation does
        the rest.  Along each of the settings' ``match_directions`` (the observer factor, when
        free, and the K2/K1 cap ratio; then ``match_wide_ratios`` when those gave none) the cap
        scale of ``match_scales`` is bisected for the fastest loop on the identified plant that
        crosses over at most ``match_crossover_room`` x the target, then lowered to the first that keeps every linear constraint
        (:meth:`stability_violation`: the floors on the identified plant and over the whole box,
        the evidence bound), and its theta3 adaptation raised while they hold
        (:meth:`_integral_matched`): one start per direction.  When no direction gives one on an
        axis whose plant sets its bandwidth, the slowest gains that keep them
        (:meth:`_slowest_matched`).  Only linearisations, no simulation.
        """
        target = self.target_crossover_hz
        if target is None or not (math.isfinite(target) and target > 0):
            return []
        st = self.settings
        room = st.match_crossover_room * target  # the highest crossover a start may have, Hz
        scales = st.match_scales
        found: list[tuple[float, np.ndarray]] = []
        free_obs = N_FREE in self.active
        wide = tuple((1.0, r) for r in st.match_wide_ratios)
        for n_dir, (f, ratio) in enumerate((*st.match_directions, *wide)):
            if n_dir == len(st.match_directions) and found:
                break  # the first directions gave a start: no fallback
            if f != 1.0 and not free_obs:
                continue
            memo: dict[int, tuple[list[float], np.ndarray, ArcGains, float]] = {}

            def at(k: int) -> tuple[list[float], np.ndarray, ArcGains, float]:
                if k in memo:
                    return memo[k]
                x = list(st.free_start)
                x[0], x[1] = scales[k], scales[k] * ratio
                z = self.z_of(x, f)
                _, _, g = self.gains(z)
                memo[k] = (x, z, g, self.crossover_hz(g))
                return memo[k]

            # The crossover falls with the caps: bisect for the fastest scale within the room (an
            # unstable loop, no crossover found, counts as too fast), then walk down to the first
            # scale that keeps every linear constraint.
            lo, hi = 0, len(scales) - 1
            if not (at(hi)[3] <= room):
                continue
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if at(mid)[3] <= room:
                    hi = mid
                else:
                    lo = mid
            for k in range(hi if at(lo)[3] > room else lo, len(scales)):
                x, z, g, xo = at(k)
                if xo <= room and self.stability_violation(g) == 0.0:
                    g3 = st.match_g3 if n_dir < len(st.match_directions) else st.match_g3_wide
                    z, xo = self._integral_matched(x, f, z, xo, room, g3)
                    found.append((abs(math.log(xo / target)), z))
                    break
        if not found and self.plant_sets_bandwidth:
            # Only where the yardstick came from below the grid: on the grid, a yardstick slower
            # than every cap scale's loop is one the identified plant holds down (a mode or delay
            # fitted heavier than the axis' own), and starting the search at the slowest loop
            # would hand it an ARC that ties that yardstick rather than the machine's PID.
            found = self._slowest_matched(target)
        found.sort(key=lambda t: t[0])
        out: list[np.ndarray] = []
        for _, z in found:  # directions clipped to the same bounds give the same start: once
            if not any(np.allclose(z, o) for o in out):
                out.append(z)
        return out

    def _slowest_matched(self, target: float) -> list[tuple[float, np.ndarray]]:
        """The slowest gains along ``match_directions`` that keep every linear constraint, when
        no scale crosses over within the room of ``target`` (Hz): ``(log distance, search vector)``.

        An axis whose yardstick is far slower than the carried-over gains (a heavy axis with a
        low structural mode) can leave every cap scale above the yardstick's crossover: the ARC's
        adaptation and observer keep some loop gain whatever the caps.  The closest match is then
        the slowest loop that holds the floors, scanned from the lowest scale up.
        """
        st = self.settings
        scales = st.match_scales
        out: list[tuple[float, np.ndarray]] = []
        for f, ratio in st.match_directions:
            if f != 1.0 and N_FREE not in self.active:
                continue
            for k in range(len(scales) - 1, -1, -1):
                x = list(st.free_start)
                x[0], x[1] = scales[k], scales[k] * ratio
                z = self.z_of(x, f)
                _, _, g = self.gains(z)
                xo = self.crossover_hz(g)
                if math.isfinite(xo) and self.stability_violation(g) == 0.0:
                    z, xo = self._integral_matched(x, f, z, xo, xo * st.match_crossover_room, st.match_g3)
                    out.append((abs(math.log(xo / target)), z))
                    break
        return out

    def _integral_matched(self, x: list[float], f: float, z: np.ndarray, xo: float,
                          room: float, factors: Sequence[float]) -> tuple[np.ndarray, float]:
        """The fastest theta3 adaptation (the ARC's integral action) along ``factors`` (the
        settings' ``match_g3``, or ``match_g3_wide`` along the fallback ratios) that keeps every
        linear constraint and a crossover of at most ``room`` Hz at the matched caps ``x``:
        ``(search vector, crossover Hz)``.

        The PID's integral term holds its low-frequency loop gain far above the ARC's at the base
        adaptation rate, and a constant-force or friction mismatch is then rejected slowly; a
        faster theta3 adaptation is the ARC's way to the same, up to where the heavy corner of the
        box (its crossover lowest) loses its margins.
        """
        i_g3 = next(k for k, b in enumerate(self.settings.free_bounds) if b[0] == "G3")
        for m in factors:
            y = list(x)
            y[i_g3] = x[i_g3] * m
            zz = self.z_of(y, f)
            _, _, g = self.gains(zz)
            xx = self.crossover_hz(g)
            if not (xx <= room) or self.stability_violation(g) > 0.0:
                break
            z, xo = zz, xx
        return z, xo

    # -- evaluation
    def evaluate(self, Z: Sequence[np.ndarray]) -> list[Candidate]:
        """Every constraint and the objective of each search vector, cheapest first.

        Per candidate: the identified plant's margins and the evidence bound, then (only where
        they hold) the whole box, then (only where that holds) the screening scenarios, and the
        rest of the tuning set only for a candidate not already far off the gate there.  The
        simulations of a candidate that passed the linear checks run in the background
        (:meth:`_simulate_candidate`, compiled kernels without the GIL; as many candidates at a
        time as the simulations have threads) while the next candidates' linear checks run here:
        the two overlap on the cores instead of taking turns.
        Each scenario's run is the same whatever else runs beside it, so the scores are the ones
        a batch of all the candidates gives.
        """
        parts = [self.gains(np.asarray(z)) for z in Z]
        ref_screen = [self.reference[i] for i in self.screen]
        mv: list[float] = []
        pending = {}
        # As many candidates in flight as the simulations have threads: a candidate's batch leaves a
        # thread idle at its end, which the next candidate's runs fill.
        with ThreadPoolExecutor(max_workers=self.ev.workers or os.cpu_count() or 1) as pool:
            try:
                for i, (_, _, g) in enumerate(parts):
                    v = self.stability_violation(g)  # the whole box only where the identified plant's hold
                    mv.append(v)
                    if v == 0.0:
                        pending[i] = pool.submit(self._simulate_candidate, arc_pack(g), ref_screen)
                done = {i: fut.result() for i, fut in pending.items()}
            except BaseException:  # Ctrl-C or an error: the queued candidates are not simulated
                for fut in pending.values():
                    fut.cancel()
                raise
        first: dict[int, list[Indexes]] = {i: r[0] for i, r in done.items()}
        screen_excess = {i: r[1] for i, r in done.items()}
        scores: dict[int, list[Indexes]] = {}
        for i, (fs, _, rest) in done.items():
            if rest is None:
                continue
            sc: list[Indexes] = [None] * len(self.ev.scenarios)  # type: ignore[list-item]
            for j, s in zip(self.screen, fs):
                sc[j] = s
            for j, s in zip(self.rest, rest):
                sc[j] = s
            scores[i] = sc
        out = []
        for i, (x, f, g) in enumerate(parts):
            if i not in first:
                out.append(Candidate(x, f, g, STABILITY_MISSED, mv[i], math.nan, None, None))
                continue
            if i not in scores:
                out.append(Candidate(x, f, g, GATE_MISSED, screen_excess[i], math.nan, None, None, screened=True))
                continue
            sc = scores[i]
            obj = cost(sc, self.spec, self.reference, self.ev.weights, self.gate, self.settings)
            # Every tuning scenario, the stand-ins for validate's Monte-Carlo sample included: held to
            # the gate on validate's fixed scenarios only, the winners failed it on Monte-Carlo plants.
            excess = gate_excess(self.gate, sc, self.reference, margin=self.settings.gate_margin, yardstick_reach=True,
                                 settings=self.settings)
            if excess > 0:
                out.append(Candidate(x, f, g, GATE_MISSED, excess, obj, sc, None))
                continue
            rep = self.feasible(g)
            fv = feasibility_violation(rep)
            out.append(Candidate(x, f, g, FEASIBLE if fv == 0 else STABILITY_MISSED, fv, obj, sc, rep))
        return out

    def _simulate_candidate(self, pack: np.ndarray,
                            ref_screen: Sequence[Indexes]) -> tuple[list[Indexes], float, list[Indexes] | None]:
        """``(screen scores, their gate excess, the other scenarios' scores or None)`` of one gain set.

        The gate on the screening scenarios first; the rest only when the excess is at most
        ``settings.screen_excess`` (None otherwise).
        """
        first = self.ev.scores(KIND_ARC, [pack], self.screen)[0]
        excess = gate_excess(self.gate, first, ref_screen, margin=self.settings.gate_margin, yardstick_reach=True,
                             settings=self.settings)
        if not excess <= self.settings.screen_excess:
            return first, excess, None
        rest = self.ev.scores(KIND_ARC, [pack], self.rest)[0] if self.rest else []
        return first, excess, rest


def search(problem: Problem, budget: int, seed: int, progress: Progress | None = None,
           progress_total: int | None = None, settings: TuneSettings = DEFAULT_SETTINGS) -> SearchResult:
    """CMA-ES over the problem's coordinates for ``budget`` candidates (the last generation cut).

    The first generation holds the mean -- the best of :meth:`Problem.matched_starts` (the ARC
    whose loop crosses over where the PID yardstick's does, every linear constraint met), or the
    carried-over paper gains when there is none --, up to ``match_injected`` further matched
    starts, :func:`commission.tune.gains.paper_implementable_start` and
    the settings' ``extra_starts`` (injected), and CMA-ES draws around the mean.
    ``seed`` seeds pycma's sampler (so the same seed gives the same tuning).  CMA-ES is told
    :meth:`Candidate.fitness`, the feasibility-first order as one number comparable across
    generations (which the elitist selection needs).  ``settings`` are the knobs the problem
    was built with (:attr:`Problem.settings`).
    """
    width = problem.hi - problem.lo
    st = settings
    pop = st.population
    stds = np.clip(st.sigma_fraction * np.where(width > 0, width, 1.0), 1e-3, st.sigma_max)
    z0 = problem.z_of(np.exp(problem.full0[:N_FREE]), math.exp(problem.full0[N_FREE]))
    # Elitist: the best candidate so far stays in the recombination, as a (1+lambda) search keeps its
    # parent; with about a dozen generations the non-elitist mean wandered off the few feasible points.
    opts = {"bounds": [list(problem.lo), list(problem.hi)], "popsize": pop, "seed": int(seed), "CMA_elitist": True,
            "CMA_stds": list(stds), "verbose": -9, "verb_log": 0, "verb_disp": 0, "verb_filenameprefix": "",
            "tolfun": 0, "tolx": 0, "tolfunhist": 0, "tolstagnation": int(1e9), "maxfevals": math.inf}
    # (a stand-in problem without a linear model has no matched start)
    matched = problem.matched_starts() if hasattr(problem, "matched_starts") else []
    n_mean = 1 if (matched and st.match_as_mean) else 0
    if n_mean:  # the mean where the ARC's loop ties the PID yardstick's (Problem.matched_starts)
        z0 = matched[0]
    es = cma.CMAEvolutionStrategy(list(z0), 1.0, opts)
    injected = [*matched[n_mean:n_mean + st.match_injected],
                *(problem.z_of(s) for s in (paper_implementable_start(st), *st.extra_starts))]
    es.inject(injected[:pop - 1], force=True)
    cands: list[Candidate] = []
    total = progress_total if progress_total is not None else budget
    generations = 0
    while len(cands) < budget:
        Z = es.ask()
        if not cands:
            Z[-1] = z0.copy()  # the start itself is a candidate (cost_initial)
            Z.insert(0, Z.pop())
        Z = Z[:budget - len(cands)]
        got = problem.evaluate(Z)
        cands.extend(got)
        generations += 1
        if len(Z) == pop:
            es.tell(Z, [c.fitness() for c in got])
        if progress is not None:
            progress(len(cands), total)
    return SearchResult(cands, generations)


@dataclass(frozen=True)
class HoldoutChoice:
    """Outcome of :func:`select_on_holdout`.

    Attributes
    ----------
    chosen : Candidate
        The winner: its gains, objective, violation and level.
    n_plants : int
        Hold-out plants simulated (0: nothing feasible to judge).
    failures : tuple of int
        Default-gate failures (tuning scenarios + hold-out plants) of each judged candidate,
        best objective first; the chosen one has the fewest (ties: better objective).
    """

    chosen: Candidate
    n_plants: int
    failures: tuple[int, ...]


def select_on_holdout(res: SearchResult, hg: HoldoutGate, settings: TuneSettings = DEFAULT_SETTINGS) -> HoldoutChoice:
    """The winner: among the ``settings.holdout_candidates`` best finalists, the fewest gate failures on unseen plants.

    The finalists are the best feasible candidates; with none, the best that kept every
    stability margin and were simulated on every tuning scenario but missed the gate there
    (tune's gate is validate's at ``settings.gate_margin`` on more
    plants, so such a candidate may still pass validate, and the unseen plants tell which is
    likeliest to).  With neither, the one that misses its constraints least is returned (and
    the validation gate will say what it misses).
    """
    ranked = res.ranked()
    n = settings.holdout_candidates
    finalists = [c for c in ranked if c.level == FEASIBLE][:n]
    if not finalists:
        finalists = [c for c in ranked if c.level == GATE_MISSED and c.scores is not None][:n]
    if not finalists:
        return HoldoutChoice(ranked[0], 0, ())
    judged = hg.judge([c.gains for c in finalists], [c.scores for c in finalists])  # type: ignore[misc]
    best = min(range(len(finalists)), key=lambda k: (judged[k][1], k))
    return HoldoutChoice(finalists[best], hg.n_plants, tuple(j[1] for j in judged))


__all__ = ["HoldoutChoice", "Problem", "search", "select_on_holdout"]
