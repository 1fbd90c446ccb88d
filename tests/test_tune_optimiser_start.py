"""The search starts where the ARC's loop ties the PID yardstick's, and minimises what the gate judges.

:meth:`commission.tune.optimiser.Problem.matched_starts` (linearisations only) and
:func:`commission.tune.objective.quantile_excess` (the gate's ARC-vs-PID quantiles) are checked
against independent computations: the margins and the box check recomputed through the public
robustness classes, the quantiles by hand.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from commission.gate import GateLimits, required_factor
from commission.paper import reference_identification
from commission.robustness import BoxArcCheck, IdentifiedPlantArcMargins, MarginFloors
from commission.spec import spec_from_mapping
from commission.tune.baseline import pid_candidates
from commission.tune.constraints import box_violation, margin_violation
from commission.tune.objective import quantile_excess
from commission.tune.optimiser import Problem
from commission.tune.settings import DEFAULT_SETTINGS
from commission.controllers.metrics import Indexes


class _NoScenarios:
    scenarios: list = []
    weights: list = []


def _problem(target, settings=DEFAULT_SETTINGS, observer_scale=1.0, plant_sets_bandwidth=False):
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({}, "spec (defaults)")
    gate = GateLimits(e_F=1.0, e_M=1.0, e_rms=1.0, c_u=1.0, u_max=spec.u_max, no_divergence=True,
                      arc_vs_pid_e_rms=1.0, basis={}, lsb=1e-6, travel=1.0)
    return ident, spec, Problem(_base(ident, spec), _NoScenarios(), spec, ident, [], gate, lambda g: None,
                                observer_free=True, target_crossover_hz=target, settings=settings,
                                observer_scale=observer_scale, plant_sets_bandwidth=plant_sets_bandwidth)


def _base(ident, spec):
    from commission.tune.gains import base_arc_gains
    return base_arc_gains(ident, spec)


def test_matched_starts_tie_the_yardstick_bandwidth_within_every_linear_constraint():
    """Each matched start crosses over at most match_crossover_room x the PID's crossover on the
    identified plant, keeps the margin floors there and over the whole box (checked again through
    the public classes), and the best match comes first."""
    ident0, spec0, _ = _problem(None)
    pid = pid_candidates(ident0, spec0, [0.1 * spec0.sample_rate])[0].margins.crossover_hz
    ident, spec, prob = _problem(pid)
    starts = prob.matched_starts()
    assert starts, "no ARC gains match the yardstick's bandwidth on the reference plant"
    floors = MarginFloors.from_spec(spec)
    pm, box = IdentifiedPlantArcMargins(ident, spec), BoxArcCheck(ident, spec)
    gaps = []
    for z in starts:
        _, _, g = prob.gains(z)
        rows = pm(g)
        xo = max(r.margins.crossover_hz for r in rows)
        assert xo <= DEFAULT_SETTINGS.match_crossover_room * pid
        assert margin_violation(rows, floors) == 0.0
        assert box_violation(box(g), floors) == 0.0
        gaps.append(abs(math.log(xo / pid)))
    assert gaps == sorted(gaps)
    # no target (a spec that pinned nothing to match): no start, the search keeps its old one
    assert _problem(None)[2].matched_starts() == []


def _s(e_rms: float, diverged: bool = False) -> Indexes:
    return Indexes(e_M=1e-6, e_F=1e-6, e_rms=e_rms, u_rms=1.0, du_rms=0.1, c_u=0.1, u_peak=1.0, diverged=diverged)


def test_quantile_excess_is_the_gates_quantiles_in_log_units():
    """Median and 90th percentile (numpy's "higher") of the gate's required factor, each counted
    ln(q / (margin limit)) above its limit; a diverged ARC inside a quantile counts diverged_excess."""
    gate = GateLimits(e_F=1.0, e_M=1.0, e_rms=1.0, c_u=1.0, u_max=10.0, no_divergence=True, arc_vs_pid_e_rms=1.0,
                      basis={}, lsb=1e-6, travel=1.0, arc_vs_pid_slack=0.0, arc_vs_pid_median=1.0, arc_vs_pid_p90=1.2)
    pid = [_s(1e-6)] * 10
    ratios = [0.5, 0.6, 0.7, 0.8, 0.9, 1.1, 1.2, 1.3, 1.5, 2.0]
    arc = [_s(r * 1e-6) for r in ratios]
    f = [required_factor(a, p, 0.0) for a, p in zip(arc, pid)]
    med, p90 = sorted(f)[5], sorted(f)[9]  # "higher": the 6th and the 10th of ten
    assert quantile_excess(gate, arc, pid) == pytest.approx(math.log(med / 1.0) + math.log(p90 / 1.2))
    assert quantile_excess(gate, arc, pid, margin=0.9) == pytest.approx(
        math.log(med / 0.9) + math.log(p90 / (0.9 * 1.2)))
    assert quantile_excess(gate, [_s(0.5e-6)] * 10, pid) == 0.0  # every factor within: nothing owed
    # one diverged run among ten lies above the median but inside the 90th percentile
    bad = [*arc[:9], _s(1e-6, diverged=True)]
    assert quantile_excess(gate, bad, pid) == pytest.approx(math.log(med) + DEFAULT_SETTINGS.diverged_excess)
    assert np.isfinite(quantile_excess(gate, [], []))


def test_gate_excess_holds_the_arc_to_the_yardstick_where_the_yardstick_misses_a_limit():
    """With ``yardstick_reach`` the search's gate constraint asks no more than the PID yardstick
    reaches on a scenario where the PID itself misses an absolute limit (and as much as the gate
    elsewhere); without it, it is the gate's limits exactly."""
    from commission.tune.objective import gate_excess
    gate = GateLimits(e_F=1.0, e_M=10e-6, e_rms=1.0, c_u=1.0, u_max=10.0, no_divergence=True, arc_vs_pid_e_rms=1.0,
                      basis={}, lsb=1e-6, travel=1.0, arc_vs_pid_every=False)

    def s(e_M: float) -> Indexes:
        return Indexes(e_M=e_M, e_F=1e-7, e_rms=1e-7, u_rms=1.0, du_rms=0.1, c_u=0.1, u_peak=1.0, diverged=False)

    pid = [s(12e-6), s(5e-6)]  # the PID misses e_M on the first scenario, meets it on the second
    arc = [s(11e-6), s(5e-6)]
    assert gate_excess(gate, arc, pid) == pytest.approx(math.log(11 / 10))
    assert gate_excess(gate, arc, pid, yardstick_reach=True) == 0.0  # better than the yardstick there
    worse = [s(13e-6), s(11e-6)]  # worse than the PID on the first, over the limit on the second
    assert gate_excess(gate, worse, pid, margin=0.95, yardstick_reach=True) == pytest.approx(
        math.log(13 / 12) + math.log(11 / 9.5))


def test_matched_starts_fall_back_to_wide_cap_ratios_only_where_the_first_directions_give_none():
    """Where no direction of the settings' match_directions gives a start (here: none to try), the wide
    K2/K1 cap ratios of match_wide_ratios do, each start keeping every linear constraint (checked again
    through the public classes) within the crossover room; where the first directions serve (the
    reference plant), no wide ratio is tried and the starts are theirs alone."""
    ident0, spec0, _ = _problem(None)
    pid = pid_candidates(ident0, spec0, [0.1 * spec0.sample_rate])[0].margins.crossover_hz
    ident, spec, prob = _problem(pid)
    served = prob.matched_starts()
    assert served and all(np.exp(z[1] - z[0]) <= 2.0 + 1e-9 for z in served)  # K2/K1 multiples of the first directions
    _, _, no_directions = _problem(pid, dataclasses.replace(DEFAULT_SETTINGS, match_directions=()))
    wide = no_directions.matched_starts()
    assert wide, "no wide-ratio start on the reference plant"
    floors = MarginFloors.from_spec(spec)
    pm, box = IdentifiedPlantArcMargins(ident, spec), BoxArcCheck(ident, spec)
    for z in wide:
        _, _, g = prob.gains(z)
        assert g.k2s_max / g.k1s_max >= 4.0 * (prob.base.g2 / prob.base.g1) * (1 - 1e-9) or np.isclose(
            z[1], prob.hi[1])  # a wide ratio, unless the K2 cap sits on its bound
        rows = pm(g)
        assert max(r.margins.crossover_hz for r in rows) <= DEFAULT_SETTINGS.match_crossover_room * pid
        assert margin_violation(rows, floors) == 0.0
        assert box_violation(box(g), floors) == 0.0


def test_a_target_below_every_cap_scale_gets_the_slowest_gains_that_keep_the_constraints():
    """A yardstick crossing over at 0.1 Hz, far below any loop the ARC's caps give on the reference
    plant, on an axis whose plant sets its bandwidth: no scale is within the room, so each first
    direction gives the slowest gains that keep every linear constraint (checked again through the
    public classes), and the next lower cap scale along it, where there is one, does not."""
    ident, spec, prob = _problem(0.1, plant_sets_bandwidth=True)
    starts = prob.matched_starts()
    assert starts
    floors = MarginFloors.from_spec(spec)
    pm, box = IdentifiedPlantArcMargins(ident, spec), BoxArcCheck(ident, spec)
    scales = DEFAULT_SETTINGS.match_scales
    for z in starts:
        x, f, g = prob.gains(z)
        rows = pm(g)
        assert max(r.margins.crossover_hz for r in rows) > DEFAULT_SETTINGS.match_crossover_room * 0.1
        assert margin_violation(rows, floors) == 0.0 and box_violation(box(g), floors) == 0.0
        k = int(np.argmin(np.abs(np.log(scales) - math.log(x[0]))))
        assert math.isclose(x[0], scales[k], rel_tol=1e-9)
        if k + 1 < len(scales):
            lower = list(x)
            lower[0], lower[1] = scales[k + 1], scales[k + 1] * x[1] / x[0]
            _, _, gl = prob.gains(prob.z_of([float(v) for v in lower], f / prob.observer_scale))
            rl = pm(gl)
            assert margin_violation(rl, floors) > 0.0 or box_violation(box(gl), floors) > 0.0


def test_a_yardstick_on_the_grid_that_no_cap_scale_matches_gives_no_start():
    """The same 0.1-Hz yardstick on an axis whose yardstick came from the rate-scaled grid: the
    identified plant, not the axis, holds it down, so no start is made (the search begins at the
    carried-over gains) -- while a yardstick the caps can match still gets its matched starts."""
    assert _problem(0.1, plant_sets_bandwidth=False)[2].matched_starts() == []
    ident0, spec0, _ = _problem(None)
    pid = pid_candidates(ident0, spec0, [0.1 * spec0.sample_rate])[0].margins.crossover_hz
    assert _problem(pid, plant_sets_bandwidth=False)[2].matched_starts()


def test_the_observer_coordinate_is_centred_on_the_bandwidth_scale():
    """An axis whose plant sets its bandwidth (:func:`commission.tune.baseline.bandwidth_factor` 0.25):
    the observer coordinate starts at 0.25 x the default pole and its bounds are the settings' factors
    times 0.25; at scale 1 (every other axis) the default pole and the settings' bounds."""
    lo_f, hi_f = DEFAULT_SETTINGS.observer_factor_bounds
    for scale in (1.0, 0.25):
        ident, spec, prob = _problem(None, observer_scale=scale)
        x0, f0, g0 = prob.gains(prob.z_of(DEFAULT_SETTINGS.free_start))
        assert math.isclose(f0, scale) and math.isclose(g0.k1, 2.0 * spec.observer_pole * scale)
        assert math.isclose(math.exp(prob.lo[-1]), lo_f * scale) and math.isclose(math.exp(prob.hi[-1]), hi_f * scale)
        assert math.isclose(prob.gains(np.full(len(prob.lo), 50.0))[1], hi_f * scale)


def test_the_carried_over_gains_scale_with_the_bandwidth_factor():
    """base_arc_gains at factor 0.25: g1, g2, their caps and Gamma a quarter of the rate-scaled ones;
    everything else (observer, eps, C terms, theta box) unchanged."""
    from commission.tune.gains import base_arc_gains
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({}, "spec (defaults)")
    one, low = base_arc_gains(ident, spec), base_arc_gains(ident, spec, 0.25)
    for name in ("g1", "g2", "k1s_max", "k2s_max"):
        assert math.isclose(getattr(low, name), 0.25 * getattr(one, name))
    assert np.allclose(low.Gamma, 0.25 * np.asarray(one.Gamma), rtol=1e-12, atol=0.0)
    scaled = {"g1", "g2", "k1s_max", "k2s_max", "Gamma"}
    assert {k: v for k, v in dataclasses.asdict(low).items() if k not in scaled} == \
        {k: v for k, v in dataclasses.asdict(one).items() if k not in scaled}
