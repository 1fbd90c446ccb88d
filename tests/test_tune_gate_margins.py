"""Issue 30: what tune's search holds its candidates to is what validate's gate checks.

The search computes the ARC's margins on the identified plant with
:class:`commission.robustness.IdentifiedPlantArcMargins` and scores them with
:func:`commission.tune.constraints.margin_violation`; validate computes them with
:func:`commission.robustness.margin_table` and gates them with :func:`commission.gate.margin_checks`.
At a margin exactly at its floor both must give the same number and the same verdict.  And a
search that found nothing feasible must say so (:func:`commission.gate.search_infeasible_line`).
"""

from __future__ import annotations

import dataclasses

import pytest

from commission.gate import box_checks, margin_checks, search_infeasible_line
from commission.paper import reference_identification
from commission.robustness import BoxArcCheck, IdentifiedPlantArcMargins, MarginFloors, margin_table
from commission.spec import spec_from_mapping
from commission.tune.api import _search_guarantee
from commission.tune.baseline import pid_baseline
from commission.tune.box import start_gains
from commission.tune.constraints import box_violation, margin_violation
from commission.tuning import SearchRecord

SPEC = spec_from_mapping({})


@pytest.fixture(scope="module")
def axis():
    """The reference identification and the search's first start point on its box."""
    ident = reference_identification(delta_d=0.5)
    return ident, start_gains(ident, SPEC)[0]


def test_the_search_and_the_gate_compute_the_same_margins_on_the_identified_plant(axis):
    ident, g = axis
    search_rows = IdentifiedPlantArcMargins(ident, SPEC)(g)
    gate_rows = [r for r in margin_table(g, pid_baseline(ident, SPEC)[0], ident, SPEC)
                 if r.controller == "arc" and r.plant == "nominal"]
    assert [r.theta_hat_at for r in search_rows] == [r.theta_hat_at for r in gate_rows] == ["initial", "plant"]
    for s, v in zip(search_rows, gate_rows):
        assert s.theta_hat == v.theta_hat
        assert s.margins == v.margins  # the same number, not a close one


@pytest.mark.parametrize("nudge", [0.0, 1e-9])
def test_at_a_margin_exactly_on_its_floor_the_search_and_the_gate_agree(axis, nudge):
    """Floors set to the computed margins (then a hair above): feasible for both, then infeasible for both."""
    ident, g = axis
    rows = IdentifiedPlantArcMargins(ident, SPEC)(g)
    worst_mm = min(r.margins.modulus_margin for r in rows)
    floors = dataclasses.replace(MarginFloors(gain_db=0.0, phase_deg=0.0, delay_samples=0.0), modulus=worst_mm + nudge)
    search_ok = margin_violation(rows, floors) == 0.0
    gate_ok = all(c.passed for c in margin_checks(rows, floors))
    assert search_ok == gate_ok == (nudge == 0.0)


def test_the_box_constraint_and_the_box_gate_agree(axis):
    ident, g = axis
    floors = MarginFloors.from_spec(SPEC)
    box = BoxArcCheck(ident, SPEC)(g)
    assert (box_violation(box, floors) == 0.0) == all(c.passed for c in box_checks(box, floors)) == box.holds(floors)


def _record(level: int, n_feasible: int, violation: float) -> SearchRecord:
    return SearchRecord(n_evaluations=120, budget=120, seed=1, cost_initial=1.0, cost_best=1.0, free={},
                        history=(), holdout_plants=0, holdout_failures=(), optimiser="CMA-ES",
                        n_feasible=n_feasible, chosen_level=level, chosen_violation=violation)


def test_a_search_with_nothing_feasible_says_so_and_tuning_json_records_it():
    line = search_infeasible_line(_record(2, 0, 0.00365))
    assert line is not None and "no feasible gains" in line and "120 candidates" in line and "0.00365" in line
    g = _search_guarantee(_record(2, 0, 0.00365))
    assert not g.holds and g.detail == line
    assert search_infeasible_line(_record(1, 0, 0.2)) is not None
    assert search_infeasible_line(_record(0, 7, 0.0)) is None
    ok = _search_guarantee(_record(0, 7, 0.0))
    assert ok.holds and "7 of 120" in ok.detail
