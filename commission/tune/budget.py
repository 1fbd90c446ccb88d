"""How many candidates the search can afford: a *defaulted* ``tune.budget`` sized to the work.

One candidate's simulation work on the tuning set (:func:`candidate_work`, in plant sub-steps)
sets the wall time of the search; where it exceeds
:attr:`~commission.tune.settings.TuneSettings.work_cap` (a slow envelope or a high sample rate) a
defaulted budget shrinks in proportion, in whole generations (:func:`work_scaled_budget`, called
by :func:`commission.tune.api.resolve_spec` before any simulation).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from commission.artifacts import Identification
from commission.scenarios import plant_substeps, tuning_scenarios
from commission.spec import Spec
from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings


def candidate_work(ident: Identification, spec: Spec, settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """Simulation work of one candidate on the tuning set, in plant sub-steps.

    Sum over :func:`commission.scenarios.tuning_scenarios` of samples x
    (``settings.arc_step_work`` + :func:`commission.scenarios.plant_substeps`): the wall time of
    the search is proportional to it.
    """
    per_sample = settings.arc_step_work + plant_substeps(spec.sample_rate)
    scen = tuning_scenarios(ident, spec, rng=np.random.default_rng(0))
    return float(sum(round(s.trajectory.duration * spec.sample_rate) * per_sample for s in scen))


def work_scale(ident: Identification, spec: Spec, settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """min(1, ``settings.work_cap`` / :func:`candidate_work`): the share of the default budget that fits."""
    return min(1.0, settings.work_cap / candidate_work(ident, spec, settings))


def work_scaled_budget(spec: Spec, ident: Identification, given: bool,
                       settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[Spec, tuple[str, ...]]:
    """Shrink a *defaulted* ``tune.budget`` where one candidate costs more than ``settings.work_cap``.

    The budget becomes ``population x round(budget x scale / population)``, at least
    ``settings.min_budget``.
    A budget the user set is kept.
    """
    if given:
        return spec, ()
    work = candidate_work(ident, spec, settings)
    pop = settings.population
    n = max(settings.min_budget, pop * int(round(spec.budget * min(1.0, settings.work_cap / work) / pop)))
    if n >= spec.budget:
        return spec, ()
    return dataclasses.replace(spec, budget=n), (
        f"tune.budget defaulted to {n} instead of {spec.budget}: one candidate simulates "
        f"{work / settings.work_cap:.2g} x the work the default budget is sized for "
        f"(slow envelope or high sample rate); set tune.budget to search longer",)


__all__ = ["candidate_work", "work_scale", "work_scaled_budget"]
