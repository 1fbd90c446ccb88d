"""The ARC's design bandwidth: the floors set it; a PID yardstick held down by the encoder's noise
sets it only when no gains at the floors' bandwidth are feasible.

:func:`commission.tune.baseline.noise_bandwidth_factor` is checked on yardstick records built by
:func:`commission.tune.baseline.pid_yardstick` (stubbed c_u, exact linear checks), and
:func:`commission.tune.api.tune` end to end on the reference identification with the yardstick
and the search's outcome forced (the search itself runs), through tuning.json's ``search`` record.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import commission.tune.api as api
from commission.paper import reference_identification
from commission.spec import spec_from_mapping
from commission.tune.baseline import bandwidth_factor, noise_bandwidth_factor, pid_baseline, pid_yardstick
from commission.tune.settings import DEFAULT_SETTINGS
from commission.tuning import Tuning
from test_tune_baseline import _evaluator

#: tune's own stages, before any test patches them
_REAL = (api.pid_yardstick, api.search, api.base_arc_gains)

MODE = {"plant": {"mode_hz": 60.0, "mode_damping": 0.02, "mode_ratio": 0.2, "encoder": "load"}}


def _low(spec):
    return DEFAULT_SETTINGS.yardstick_pole_fractions[0] * spec.sample_rate


def test_the_noise_factor_is_the_noise_held_pole_below_the_grid_and_nothing_else():
    """A yardstick the floors admit (negligible c_u): no noise factor, on the grid or below it.  The same
    plants with a c_u that holds the PID below the floors' pole and below the grid: the noise factor is
    the held pole over the grid's lowest, while the design factor stays the floors' (1 on the grid)."""
    ident = reference_identification(delta_d=0.5)
    for spec in (spec_from_mapping({}), spec_from_mapping(MODE)):
        _, free = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
        assert noise_bandwidth_factor(free, spec) is None
        _, m_min = pid_baseline(ident, spec)
        w_lim = 0.5 * min(free.pole, _low(spec))  # c_u reaches the limit there (worst scenario 1.2 x)
        _, held = pid_yardstick(ident, spec, _evaluator(1.0 / (1.2 * 3.0 * m_min * w_lim)), 1.0, pole_free=True)
        assert held.is_yardstick and held.pole <= w_lim * 1.0001 and held.fastest_admissible == free.pole
        assert noise_bandwidth_factor(held, spec) == pytest.approx(held.pole / _low(spec), rel=1e-12)
        assert bandwidth_factor(held, spec) == pytest.approx(min(1.0, free.pole / _low(spec)), rel=1e-12)
        assert noise_bandwidth_factor(held, spec) < bandwidth_factor(held, spec)
    # a record without the floors' pole (older tuning.json) gives none
    old = dataclasses.replace(held, fastest_admissible=None)
    assert noise_bandwidth_factor(old, spec) is None


def _tune_with(monkeypatch, outcome):
    """tune() on the reference identification with a noise-held yardstick at 0.8 x the grid's lowest
    pole, a budget of 8, and the search at each factor of ``outcome`` (factor -> violation) forced:
    0 marks the candidates simulated on every scenario feasible, v > 0 marks every candidate
    infeasible (level 1) with violation v (the gains are the search's own).  Returns the tuning, the
    factors the carried-over design was built at and the progress reports."""
    from commission.tune.candidate import FEASIBLE, GATE_MISSED, SearchResult

    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({"tune": {"budget": 8}})
    factors: list[float] = []
    real_yardstick, real_search, real_base = _REAL

    def yardstick(*a, **k):
        base, choice = real_yardstick(*a, **k)
        return base, dataclasses.replace(choice, pole=0.8 * _low(spec), fastest_admissible=choice.pole)

    def base_gains(ident_, spec_, factor=1.0):
        factors.append(factor)
        return real_base(ident_, spec_, factor)

    def search(problem, *a, **k):
        res = real_search(problem, *a, **k)
        v = next(v for f, v in outcome.items() if abs(factors[-1] - f) < 1e-12)
        return SearchResult([dataclasses.replace(c, level=FEASIBLE, violation=0.0) if v == 0 and c.scores is not None
                             else c if v == 0 else dataclasses.replace(c, level=GATE_MISSED, violation=v)
                             for c in res.candidates], res.generations)

    monkeypatch.setattr(api, "pid_yardstick", yardstick)
    monkeypatch.setattr(api, "base_arc_gains", base_gains)
    monkeypatch.setattr(api, "search", search)
    seen: list[tuple[int, int]] = []
    t = api.tune(ident, spec, rng=np.random.default_rng(0), seed=0, ident_sha256="0" * 64,
                 progress=lambda d, n: seen.append((d, n)), pid_free=True, observer_free=True)
    return t, factors, seen


@pytest.mark.slow
def test_the_arc_is_searched_again_at_the_noise_held_bandwidth_only_when_the_floors_give_nothing(monkeypatch):
    """Floors' bandwidth infeasible, the noise factor (0.8) feasible: the second search is kept, the
    first recorded in ``search.other_search``; the progress total grows by the second budget and never
    runs backwards.  Both infeasible: the search whose best candidate has the smaller violation is kept
    (the search's own order), the other recorded.  The floors' bandwidth feasible: one search, no
    record.  The records survive tuning.json's strict round trip."""
    t, factors, seen = _tune_with(monkeypatch, {1.0: 0.5, 0.8: 0.0})
    assert factors == [1.0, pytest.approx(0.8)]
    assert t.search.bandwidth_factor == pytest.approx(0.8) and t.search.n_feasible > 0
    assert t.search.other_search == {"bandwidth_factor": 1.0, "n_evaluations": 8, "n_feasible": 0}
    done = [d for d, _ in seen]
    assert done == sorted(done) and seen[-1][0] == seen[-1][1] == 2 * 8 + 3
    back = Tuning.from_dict(json.loads(json.dumps(t.to_dict())))
    assert back.search.other_search == t.search.other_search and back.search.bandwidth_factor == pytest.approx(0.8)

    closer, _, _ = _tune_with(monkeypatch, {1.0: 0.5, 0.8: 0.1})
    assert closer.search.bandwidth_factor == pytest.approx(0.8) and closer.search.n_feasible == 0
    assert closer.search.chosen_violation == pytest.approx(0.1)
    assert closer.search.other_search == {"bandwidth_factor": 1.0, "n_evaluations": 8, "n_feasible": 0}
    farther, factors2, _ = _tune_with(monkeypatch, {1.0: 0.1, 0.8: 0.5})
    assert factors2 == [1.0, pytest.approx(0.8)] and farther.search.bandwidth_factor == 1.0
    assert farther.search.chosen_violation == pytest.approx(0.1)
    assert farther.search.other_search == {"bandwidth_factor": pytest.approx(0.8), "n_evaluations": 8,
                                           "n_feasible": 0}

    one, factors3, seen3 = _tune_with(monkeypatch, {1.0: 0.0})
    assert factors3 == [1.0] and one.search.other_search is None and one.search.bandwidth_factor == 1.0
    assert seen3[-1][0] == seen3[-1][1] == 8 + 3
    assert "other_search" not in one.to_dict()["search"]


def test_the_report_says_why_the_arc_was_scaled_and_that_the_yardstick_was_noise_held():
    """The report's yardstick lines (commission.report.document.yardstick_lines) name the floors' pole
    when c_u held the PID below it, and the ARC's design factor with its reason: the noise-held
    yardstick after an infeasible floors' search, both searches infeasible, or the plant (floors below
    the grid).  At the rate-scaled design with an unheld yardstick they add nothing."""
    from types import SimpleNamespace
    from commission.report.document import yardstick_lines

    ys = {"method": "margin_search", "candidates": 73, "admissible": 56, "margins": {}, "is_yardstick": True,
          "radius_plus_one_sample": 0.5, "fastest_admissible_pole": 1629.0}

    def t(bw, other, fa=1629.0):
        return SimpleNamespace(pid_yardstick={**ys, "fastest_admissible_pole": fa}, pid_pole=83.4,
                               search=SimpleNamespace(bandwidth_factor=bw, other_search=other))
    noise = yardstick_lines(t(0.2085, {"bandwidth_factor": 1.0, "n_evaluations": 48, "n_feasible": 0}))
    assert len(noise) == 2 and "held it below 1629 rad/s" in noise[0]
    assert "scaled by 0.208" in noise[1] and "factor 1) no gains met every constraint in 48 candidates" in noise[1]
    assert "came closer" in noise[1]
    both = yardstick_lines(t(1.0, {"bandwidth_factor": 0.2085, "n_evaluations": 48, "n_feasible": 0}))
    assert "scaled by 1" in both[1] and "(factor 0.208, 48 candidates) came no closer" in both[1]
    plant = yardstick_lines(t(0.4, None, fa=83.4))
    assert "held it" not in plant[0] and "the plant sets the bandwidth" in plant[1]
    assert len(yardstick_lines(t(1.0, None, fa=83.4))) == 1
