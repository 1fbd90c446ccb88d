"""The gain search: one constrained optimisation with one objective, by CMA-ES (pycma's ask/tell).

Problem
-------
Minimise the performance objective :func:`commission.tune.objective.cost` of the ARC on the
tuning scenarios over its free gains (:data:`commission.tune.gains.FREE_BOUNDS`, in log
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
  (:func:`commission.tune.objective.gate_excess` at :data:`commission.tune.constraints.GATE_MARGIN`);
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
the smaller part of the simulation) already exceeds :data:`SCREEN_EXCESS` is not simulated on the rest
(:attr:`Candidate.screened`); it ranks after every fully simulated candidate of its level.
The excess only grows with more scenarios, so the order among candidates whose whole gate
excess is at most :data:`SCREEN_EXCESS` -- the ones near feasibility, where the ranking steers
the search -- is exactly the order without the screen.  (A screen on any excess would rank a
candidate that barely misses the screen below one that passes it and misses the rest by far.)

The winner is the best feasible candidate by validate's default gate on plants the search
never saw (:class:`commission.tune.objective.HoldoutGate`, :func:`select_on_holdout`): the
objective is scored on the tuning scenarios only.
"""

from __future__ import annotations

import dataclasses
import math
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
from commission.scenarios import plant_substeps, screening_indices, tuning_scenarios
from commission.spec import Spec
from commission.tuning import Score
from commission.tune.constraints import GATE_MARGIN, box_violation, feasibility_violation, margin_violation
from commission.tune.gains import (
    CAP_LOW,
    EXTRA_STARTS,
    FREE_BOUNDS,
    FREE_LOG_HI,
    FREE_LOG_LO,
    FREE_START,
    I_THETA1_0,
    N_FREE,
    apply_free,
    paper_implementable_start,
)
from commission.tune.objective import Evaluator, HoldoutGate, Progress, cost, gate_excess

#: Candidates per CMA-ES generation (pycma's default for 9-10 coordinates is 10; 8 fills two
#: cores evenly in the batch simulator).
POP = 8

#: Initial standard deviation of each coordinate, log units, as a fraction of its range, at most
#: :data:`SIGMA_MAX` (a factor e): wide enough to leave the carried-over paper gains by a factor
#: of two or three in one generation, since the feasible gains of a delay-capped axis often lie
#: that far from them (docs/robustness.md).
SIGMA_FRACTION = 0.3
SIGMA_MAX = 1.0

#: Range of the factor on a *defaulted* observer pole (``controller.observer_pole``): a slower
#: observer leaves a light axis' delay margin room, a faster one passes more encoder noise.
OBSERVER_FACTOR_BOUNDS = (0.6, 1.25)

#: Directions of :meth:`Problem.matched_starts`: (observer factor, K2 cap / K1 cap as multiples of
#: the base's); a factor other than 1 only when the observer pole is free.
MATCH_DIRECTIONS = ((1.0, 1.0), (1.0, 2.0), (1.25, 1.0))

#: Further K2/K1 cap ratios tried by :meth:`Problem.matched_starts` when no direction of
#: :data:`MATCH_DIRECTIONS` gives a start.  The ARC's position gain is K1 / theta1min: on an axis
#: whose theta box is wide (a heavy axis with its default payload range) its rest loop ties the
#: PID's only with a K2 cap many times the K1 cap, and ratios 1 and 2 alone left such an axis no
#: matched start (the search then began from the unstable paper gains, and returned an ARC 10 x
#: worse than the yardstick).  A fallback, so that an axis the first directions serve keeps the
#: same start and pays nothing.
MATCH_WIDE_RATIOS = (4.0, 8.0, 16.0, 32.0)

#: Cap scales tried by :meth:`Problem.matched_starts`, largest (fastest loop) first, relative to
#: the base gains' caps (inside :data:`commission.tune.gains.FREE_BOUNDS`).
MATCH_SCALES = tuple(float(v) for v in np.geomspace(4.0, CAP_LOW, 25))

#: Factors on the base theta3 adaptation rate tried in turn by :meth:`Problem._integral_matched`
#: (up to the first that breaks a linear constraint).
MATCH_G3 = (2.0, 4.0, 8.0, 16.0, 32.0)

#: The same along the fallback ratios (:data:`MATCH_WIDE_RATIOS`): doubling up to the search
#: box's bound on G3 (:data:`commission.tune.gains.FREE_BOUNDS`).  On a wide box the matched
#: caps leave the ARC's integral action far below the PID's at x32 while the linear constraints
#: allow much more, and the ARC then loses to the yardstick in Case 2 for want of integral action.
#: Not along the first directions: there it moves the start of axes those directions already
#: serve (docs/robustness.md, "Where the search starts", has the measurements).
MATCH_G3_WIDE = tuple(2.0 ** k for k in range(1, 14))

#: Matched starts injected into the first generation besides the one that becomes its mean
#: (with the paper's and the two extra starts, the first generation is all structured starts).
MATCH_INJECTED = 4

#: The best matched start becomes CMA-ES's mean (else the carried-over paper gains stay the mean
#: and the matched starts are injected only).
MATCH_AS_MEAN = True

#: A matched start may cross over this much above the PID yardstick's crossover.
MATCH_CROSSOVER_ROOM = 1.05

#: Simulation work of one candidate (:func:`candidate_work`, plant sub-steps) above which a
#: *defaulted* budget shrinks in proportion (:func:`work_scaled_budget`).
WORK_CAP = 22e6

#: Cost of one ARC step in plant sub-steps.
ARC_STEP_WORK = 4

#: Floor of a work-scaled budget (six generations).
MIN_BUDGET = 48

#: Feasible candidates (best objective first) that :func:`select_on_holdout` judges on unseen plants.
HOLDOUT_CANDIDATES = 6

#: Constraint levels of a candidate: every constraint met, only the gate missed, a margin or
#: discrete feasibility missed.
FEASIBLE, GATE_MISSED, STABILITY_MISSED = 0, 1, 2

#: Offset between constraint levels in :meth:`Candidate.fitness` (the objective and the
#: violations stay far below it).
LEVEL_OFFSET = 1e6

#: Offset of a screened-out candidate within the gate-missed level (:meth:`Candidate.fitness`).
SCREEN_OFFSET = 0.3 * LEVEL_OFFSET

#: Gate excess on the screening scenarios (:func:`commission.tune.objective.gate_excess`, ln units
#: summed over indexes and scenarios) above which a candidate is not simulated on the rest: an
#: index 35 % over its limit, far from feasibility.  Low because the matched starts put most
#: candidates past the margins: a looser screen simulates many more in full for about the same
#: ARC-vs-PID quantiles (docs/robustness.md has the measurement).
SCREEN_EXCESS = 0.3


@dataclass(frozen=True)
class Candidate:
    """One evaluated gain set.

    Attributes
    ----------
    x : numpy.ndarray
        Relative free gains, shape (N_FREE,) (:func:`commission.tune.gains.apply_free`).
    observer_factor : float
        Factor on the spec's observer pole.
    gains : ArcGains
    level : int
        :data:`FEASIBLE`, :data:`GATE_MISSED` or :data:`STABILITY_MISSED`.
    violation : float
        Summed violation of the constraints of its level (0 when feasible).
    objective : float
        :func:`commission.tune.objective.cost` (nan: not simulated on every tuning scenario).
    scores : list of Score or None
        On the tuning scenarios (None: not simulated on all of them).
    feasibility : FeasibilityReport or None
        Discrete feasibility (None: not checked, a constraint before it missed).
    screened : bool
        Its gate excess on the screening scenarios exceeded :data:`SCREEN_EXCESS` and it was
        simulated on those only; ``violation`` is that excess (a lower bound of the whole).
    """

    x: np.ndarray
    observer_factor: float
    gains: ArcGains
    level: int
    violation: float
    objective: float
    scores: list[Score] | None
    feasibility: FeasibilityReport | None
    screened: bool = False

    def fitness(self) -> float:
        """The ranking of :meth:`rank_key` as one number, comparable across generations (what CMA-ES is told).

        The objective of a feasible candidate lies far below :data:`LEVEL_OFFSET`; each level
        adds it once more to the violation, and a screened-out candidate :data:`SCREEN_OFFSET`.
        """
        if self.level == FEASIBLE:
            return min(self.objective, 0.25 * LEVEL_OFFSET)
        return (self.level * LEVEL_OFFSET + (SCREEN_OFFSET if self.screened else 0.0)
                + min(self.violation, 0.25 * LEVEL_OFFSET))

    def rank_key(self) -> tuple[int, bool, float]:
        """Feasibility-first order: the level, screened-out last within it, then the objective
        (feasible) or the violation."""
        return (self.level, self.screened, self.objective if self.level == FEASIBLE else self.violation)


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
    reference : sequence of Score
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
    """

    def __init__(self, base: ArcGains, ev: Evaluator, spec: Spec, ident: Identification,
                 reference: Sequence[Score], gate: GateLimits,
                 feasible: Callable[[ArcGains], FeasibilityReport], *, observer_free: bool,
                 target_crossover_hz: float | None = None) -> None:
        self.base, self.ev, self.spec, self.ident = base, ev, spec, ident
        self.target_crossover_hz = target_crossover_hz
        self.reference, self.gate, self.feasible = list(reference), gate, feasible
        self.floors = MarginFloors.from_spec(spec)
        self.screen = screening_indices(ev.scenarios)
        on_screen = set(self.screen)
        self.rest = [i for i in range(len(ev.scenarios)) if i not in on_screen]
        self.margins = IdentifiedPlantArcMargins(ident, spec)
        self.box = BoxArcCheck(ident, spec)
        self.evidence = EvidenceBound(ident, spec)
        lo = np.append(FREE_LOG_LO, math.log(OBSERVER_FACTOR_BOUNDS[0]))
        hi = np.append(FREE_LOG_HI, math.log(OBSERVER_FACTOR_BOUNDS[1]))
        start = np.append(np.log(FREE_START), 0.0)
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
        v = np.append(np.log(np.asarray(x, dtype=np.float64)), math.log(observer_factor))
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
        v = margin_violation(self.margins(g), self.floors) + self.evidence.violation(g)
        return v if v > 0 else box_violation(self.box(g), self.floors)

    def matched_starts(self) -> list[np.ndarray]:
        """Search vectors whose linear feedback matches the PID yardstick's bandwidth, best match first.

        The ARC has the PID's feedback structure (position and velocity-estimate feedback, the
        theta3 adaptation as its integral action) plus model compensation: with the same
        crossover under the same floors it should at least tie the PID, and the compensation does
        the rest.  Along each of :data:`MATCH_DIRECTIONS` (the observer factor, when free, and the
        K2/K1 cap ratio) the cap scale of :data:`MATCH_SCALES` is bisected for the fastest loop
        on the identified plant that crosses over at most :data:`MATCH_CROSSOVER_ROOM` x the
        target, then lowered to the first that keeps every linear constraint
        (:meth:`stability_violation`: the floors on the identified plant and over the whole box,
        the evidence bound), and its theta3 adaptation raised while they hold
        (:meth:`_integral_matched`): one start per direction.  Only linearisations, no
        simulation.
        """
        target = self.target_crossover_hz
        if target is None or not (math.isfinite(target) and target > 0):
            return []
        found: list[tuple[float, np.ndarray]] = []
        free_obs = N_FREE in self.active
        wide = tuple((1.0, r) for r in MATCH_WIDE_RATIOS)
        for n_dir, (f, ratio) in enumerate((*MATCH_DIRECTIONS, *wide)):
            if n_dir == len(MATCH_DIRECTIONS) and found:
                break  # the first directions gave a start: no fallback
            if f != 1.0 and not free_obs:
                continue
            memo: dict[int, tuple[list[float], np.ndarray, ArcGains, float]] = {}

            def at(k: int) -> tuple[list[float], np.ndarray, ArcGains, float]:
                if k in memo:
                    return memo[k]
                x = list(FREE_START)
                x[0], x[1] = MATCH_SCALES[k], MATCH_SCALES[k] * ratio
                z = self.z_of(x, f)
                _, _, g = self.gains(z)
                xo = max((r.margins.crossover_hz for r in self.margins(g) if math.isfinite(r.margins.crossover_hz)),
                         default=math.nan)
                memo[k] = (x, z, g, xo)
                return memo[k]

            # The crossover falls with the caps: bisect for the fastest scale within the room (an
            # unstable loop, no crossover found, counts as too fast), then walk down to the first
            # scale that keeps every linear constraint.
            lo, hi = 0, len(MATCH_SCALES) - 1
            if not (at(hi)[3] <= MATCH_CROSSOVER_ROOM * target):
                continue
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if at(mid)[3] <= MATCH_CROSSOVER_ROOM * target:
                    hi = mid
                else:
                    lo = mid
            for k in range(hi if at(lo)[3] > MATCH_CROSSOVER_ROOM * target else lo, len(MATCH_SCALES)):
                x, z, g, xo = at(k)
                if xo <= MATCH_CROSSOVER_ROOM * target and self.stability_violation(g) == 0.0:
                    z, xo = self._integral_matched(x, f, z, xo, target,
                                                   MATCH_G3 if n_dir < len(MATCH_DIRECTIONS) else MATCH_G3_WIDE)
                    found.append((abs(math.log(xo / target)), z))
                    break
        found.sort(key=lambda t: t[0])
        out: list[np.ndarray] = []
        for _, z in found:  # directions clipped to the same bounds give the same start: once
            if not any(np.allclose(z, o) for o in out):
                out.append(z)
        return out

    def _integral_matched(self, x: list[float], f: float, z: np.ndarray, xo: float,
                          target: float, factors: Sequence[float] = MATCH_G3) -> tuple[np.ndarray, float]:
        """The fastest theta3 adaptation (the ARC's integral action) along ``factors`` (:data:`MATCH_G3`,
        or :data:`MATCH_G3_WIDE` along the fallback ratios) that keeps
        every linear constraint at the matched caps ``x``: ``(search vector, crossover Hz)``.

        The PID's integral term holds its low-frequency loop gain far above the ARC's at the base
        adaptation rate, and a constant-force or friction mismatch is then rejected slowly; a
        faster theta3 adaptation is the ARC's way to the same, up to where the heavy corner of the
        box (its crossover lowest) loses its margins.
        """
        i_g3 = next(k for k, b in enumerate(FREE_BOUNDS) if b[0] == "G3")
        for m in factors:
            y = list(x)
            y[i_g3] = x[i_g3] * m
            zz = self.z_of(y, f)
            _, _, g = self.gains(zz)
            rows = self.margins(g)
            xx = max((r.margins.crossover_hz for r in rows if math.isfinite(r.margins.crossover_hz)),
                     default=math.nan)
            if not (xx <= MATCH_CROSSOVER_ROOM * target) or self.stability_violation(g) > 0.0:
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
        (:meth:`_simulate_candidate`, compiled kernels without the GIL) while the next
        candidates' linear checks run here: the two overlap on the cores instead of taking turns.
        Each scenario's run is the same whatever else runs beside it, so the scores are the ones
        a batch of all the candidates gives.
        """
        parts = [self.gains(np.asarray(z)) for z in Z]
        ref_screen = [self.reference[i] for i in self.screen]
        mv: list[float] = []
        pending = {}
        with ThreadPoolExecutor(max_workers=1) as pool:
            try:
                for i, (_, _, g) in enumerate(parts):
                    v = margin_violation(self.margins(g), self.floors) + self.evidence.violation(g)
                    # The whole box only where the identified plant's margins hold (the cheaper check first).
                    if not v > 0:
                        v = box_violation(self.box(g), self.floors)
                    mv.append(v)
                    if v == 0.0:
                        pending[i] = pool.submit(self._simulate_candidate, arc_pack(g), ref_screen)
                done = {i: fut.result() for i, fut in pending.items()}
            except BaseException:  # Ctrl-C or an error: the queued candidates are not simulated
                for fut in pending.values():
                    fut.cancel()
                raise
        first: dict[int, list[Score]] = {i: r[0] for i, r in done.items()}
        screen_excess = {i: r[1] for i, r in done.items()}
        scores: dict[int, list[Score]] = {}
        for i, (fs, _, rest) in done.items():
            if rest is None:
                continue
            sc: list[Score] = [None] * len(self.ev.scenarios)  # type: ignore[list-item]
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
            obj = cost(sc, self.spec, self.reference, self.ev.weights, self.gate)
            # Every tuning scenario, the stand-ins for validate's Monte-Carlo sample included: held to
            # the gate on validate's fixed scenarios only, the winners failed it on Monte-Carlo plants.
            excess = gate_excess(self.gate, sc, self.reference, margin=GATE_MARGIN, yardstick_reach=True)
            if excess > 0:
                out.append(Candidate(x, f, g, GATE_MISSED, excess, obj, sc, None))
                continue
            rep = self.feasible(g)
            fv = feasibility_violation(rep)
            out.append(Candidate(x, f, g, FEASIBLE if fv == 0 else STABILITY_MISSED, fv, obj, sc, rep))
        return out

    def _simulate_candidate(self, pack: np.ndarray,
                            ref_screen: Sequence[Score]) -> tuple[list[Score], float, list[Score] | None]:
        """``(screen scores, their gate excess, the other scenarios' scores or None)`` of one gain set.

        The gate on the screening scenarios first; the rest only when the excess is at most
        :data:`SCREEN_EXCESS` (None otherwise).
        """
        first = self.ev.scores(KIND_ARC, [pack], self.screen)[0]
        excess = gate_excess(self.gate, first, ref_screen, margin=GATE_MARGIN, yardstick_reach=True)
        if not excess <= SCREEN_EXCESS:
            return first, excess, None
        rest = self.ev.scores(KIND_ARC, [pack], self.rest)[0] if self.rest else []
        return first, excess, rest


@dataclass(frozen=True)
class SearchResult:
    """Every candidate of the search, in evaluation order.

    Attributes
    ----------
    candidates : list of Candidate
    generations : int
    """

    candidates: list[Candidate]
    generations: int

    def ranked(self) -> list[Candidate]:
        """Best first (feasibility-first order)."""
        return sorted(self.candidates, key=Candidate.rank_key)

    @property
    def n_feasible(self) -> int:
        return sum(c.level == FEASIBLE for c in self.candidates)


def search(problem: Problem, budget: int, seed: int, progress: Progress | None = None,
           progress_total: int | None = None) -> SearchResult:
    """CMA-ES over the problem's coordinates for ``budget`` candidates (the last generation cut).

    The first generation holds the mean -- the best of :meth:`Problem.matched_starts` (the ARC
    whose loop crosses over where the PID yardstick's does, every linear constraint met), or the
    carried-over paper gains when there is none --, up to :data:`MATCH_INJECTED` further matched
    starts, :func:`commission.tune.gains.paper_implementable_start` and
    :data:`commission.tune.gains.EXTRA_STARTS` (injected), and CMA-ES draws around the mean.
    ``seed`` seeds pycma's sampler (so the same seed gives the same tuning).  CMA-ES is told
    :meth:`Candidate.fitness`, the feasibility-first order as one number comparable across
    generations (which the elitist selection needs).
    """
    width = problem.hi - problem.lo
    stds = np.clip(SIGMA_FRACTION * np.where(width > 0, width, 1.0), 1e-3, SIGMA_MAX)
    z0 = problem.z_of(np.exp(problem.full0[:N_FREE]), math.exp(problem.full0[N_FREE]))
    # Elitist: the best candidate so far stays in the recombination, as a (1+lambda) search keeps its
    # parent; with about a dozen generations the non-elitist mean wandered off the few feasible points.
    opts = {"bounds": [list(problem.lo), list(problem.hi)], "popsize": POP, "seed": int(seed), "CMA_elitist": True,
            "CMA_stds": list(stds), "verbose": -9, "verb_log": 0, "verb_disp": 0, "verb_filenameprefix": "",
            "tolfun": 0, "tolx": 0, "tolfunhist": 0, "tolstagnation": int(1e9), "maxfevals": math.inf}
    # (a stand-in problem without a linear model has no matched start)
    matched = problem.matched_starts() if hasattr(problem, "matched_starts") else []
    n_mean = 1 if (matched and MATCH_AS_MEAN) else 0
    if n_mean:  # the mean where the ARC's loop ties the PID yardstick's (Problem.matched_starts)
        z0 = matched[0]
    es = cma.CMAEvolutionStrategy(list(z0), 1.0, opts)
    injected = [*matched[n_mean:n_mean + MATCH_INJECTED],
                *(problem.z_of(s) for s in (paper_implementable_start(), *EXTRA_STARTS))]
    es.inject(injected[:POP - 1], force=True)
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
        if len(Z) == POP:
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
    n_plants : int
        Hold-out plants simulated (0: nothing feasible to judge).
    failures : tuple of int
        Default-gate failures (tuning scenarios + hold-out plants) of each judged candidate,
        best objective first; the chosen one has the fewest (ties: better objective).
    """

    chosen: Candidate
    n_plants: int
    failures: tuple[int, ...]


def select_on_holdout(res: SearchResult, hg: HoldoutGate) -> HoldoutChoice:
    """The winner: among the :data:`HOLDOUT_CANDIDATES` best finalists, the fewest gate failures on unseen plants.

    The finalists are the best feasible candidates; with none, the best that kept every
    stability margin and were simulated on every tuning scenario but missed the gate there
    (tune's gate is validate's at :data:`commission.tune.constraints.GATE_MARGIN` on more
    plants, so such a candidate may still pass validate, and the unseen plants tell which is
    likeliest to).  With neither, the one that misses its constraints least is returned (and
    the validation gate will say what it misses).
    """
    ranked = res.ranked()
    finalists = [c for c in ranked if c.level == FEASIBLE][:HOLDOUT_CANDIDATES]
    if not finalists:
        finalists = [c for c in ranked if c.level == GATE_MISSED and c.scores is not None][:HOLDOUT_CANDIDATES]
    if not finalists:
        return HoldoutChoice(ranked[0], 0, ())
    judged = hg.judge([c.gains for c in finalists], [c.scores for c in finalists])  # type: ignore[misc]
    best = min(range(len(finalists)), key=lambda k: (judged[k][1], k))
    return HoldoutChoice(finalists[best], hg.n_plants, tuple(j[1] for j in judged))


def candidate_work(ident: Identification, spec: Spec) -> float:
    """Simulation work of one candidate on the tuning set, in plant sub-steps.

    Sum over :func:`commission.scenarios.tuning_scenarios` of samples x
    (:data:`ARC_STEP_WORK` + :func:`commission.scenarios.plant_substeps`): the wall time of
    the search is proportional to it.
    """
    per_sample = ARC_STEP_WORK + plant_substeps(spec.sample_rate)
    scen = tuning_scenarios(ident, spec, rng=np.random.default_rng(0))
    return float(sum(round(s.trajectory.duration * spec.sample_rate) * per_sample for s in scen))


def work_scale(ident: Identification, spec: Spec) -> float:
    """min(1, :data:`WORK_CAP` / :func:`candidate_work`): the share of the default budget that fits."""
    return min(1.0, WORK_CAP / candidate_work(ident, spec))


def work_scaled_budget(spec: Spec, ident: Identification, given: bool) -> tuple[Spec, tuple[str, ...]]:
    """Shrink a *defaulted* ``tune.budget`` where one candidate costs more than :data:`WORK_CAP`.

    The budget becomes ``POP x round(budget x scale / POP)``, at least :data:`MIN_BUDGET`.
    A budget the user set is kept.
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


__all__ = ["ARC_STEP_WORK", "Candidate", "FEASIBLE", "GATE_MISSED", "HOLDOUT_CANDIDATES",
           "HoldoutChoice", "MATCH_AS_MEAN", "MATCH_CROSSOVER_ROOM", "MATCH_DIRECTIONS", "MATCH_G3", "MATCH_G3_WIDE",
           "MATCH_INJECTED", "MATCH_SCALES", "MATCH_WIDE_RATIOS", "MIN_BUDGET", "OBSERVER_FACTOR_BOUNDS", "POP", "Problem", "SIGMA_FRACTION",
           "SCREEN_EXCESS", "SCREEN_OFFSET", "SIGMA_MAX", "STABILITY_MISSED", "SearchResult", "WORK_CAP", "candidate_work", "search",
           "select_on_holdout", "work_scale", "work_scaled_budget"]
