"""The candidates of the gain search and their feasibility-first order.

A :class:`Candidate` is one evaluated gain set with its constraint level (:data:`FEASIBLE`,
:data:`GATE_MISSED`, :data:`STABILITY_MISSED`), its violation and its objective;
:meth:`Candidate.rank_key` is Deb's feasibility-first order and :meth:`Candidate.fitness` the
same order as one number that CMA-ES is told (:mod:`commission.tune.optimiser`).
:class:`SearchResult` holds every candidate of one search.  The levels and offsets below encode
the order; they are not knobs of the search (those are :class:`commission.tune.settings.TuneSettings`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from commission.controllers.arc import ArcGains
from commission.controllers.design import FeasibilityReport
from commission.controllers.metrics import Indexes

#: Constraint levels of a candidate: every constraint met, only the gate missed, a margin or
#: discrete feasibility missed.
FEASIBLE, GATE_MISSED, STABILITY_MISSED = 0, 1, 2

#: Offset between constraint levels in :meth:`Candidate.fitness` (the objective and the
#: violations stay far below it).
LEVEL_OFFSET = 1e6

#: Offset of a screened-out candidate within the gate-missed level (:meth:`Candidate.fitness`).
SCREEN_OFFSET = 0.3 * LEVEL_OFFSET


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
        The ARC that ``x`` and ``observer_factor`` give (the gains simulated).
    level : int
        :data:`FEASIBLE`, :data:`GATE_MISSED` or :data:`STABILITY_MISSED`.
    violation : float
        Summed violation of the constraints of its level (0 when feasible).
    objective : float
        :func:`commission.tune.objective.cost` (nan: not simulated on every tuning scenario).
    scores : list of Indexes or None
        On the tuning scenarios (None: not simulated on all of them).
    feasibility : FeasibilityReport or None
        Discrete feasibility (None: not checked, a constraint before it missed).
    screened : bool
        Its gate excess on the screening scenarios exceeded :attr:`~commission.tune.settings.TuneSettings.screen_excess` and it was
        simulated on those only; ``violation`` is that excess (a lower bound of the whole).
    """

    x: np.ndarray
    observer_factor: float
    gains: ArcGains
    level: int
    violation: float
    objective: float
    scores: list[Indexes] | None
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


__all__ = ["Candidate", "FEASIBLE", "GATE_MISSED", "LEVEL_OFFSET", "SCREEN_OFFSET", "STABILITY_MISSED", "SearchResult"]
