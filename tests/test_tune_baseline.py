"""The PID yardstick (:func:`commission.tune.baseline.pid_yardstick`): the fastest PID of (57)
that keeps the ARC's margin floors on the identified plant and stays stable with one more
sample of delay.  Linear checks are exact; the simulation is stubbed (c_u proportional to Kd)."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from commission.controllers.design import KIND_PID
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import closed_loop_radius, linearize_pid
from commission.controllers.pid import G_KD, pid_pack
from commission.paper import reference_identification
from commission.robustness import MarginFloors
from commission.scenarios import identified_plant
from commission.spec import spec_from_mapping
from commission.tune.baseline import (YardstickChoice, bandwidth_factor, pid_baseline, pid_candidates,
                                      pid_yardstick)
from commission.tune.settings import DEFAULT_SETTINGS

#: The yardstick's pole grid of the default settings, as fractions of the sample rate.
FRACTIONS = DEFAULT_SETTINGS.yardstick_pole_fractions
from commission.controllers.metrics import Indexes


def _evaluator(c_u_per_kd: float, n: int = 3) -> SimpleNamespace:
    """A stub Evaluator whose PID c_u is proportional to the packed Kd, on ``n`` scenarios."""
    calls = []

    def scores(kind, packs):
        assert kind == KIND_PID
        calls.append(len(packs))
        return [[Indexes(e_M=1e-5, e_F=1e-6, e_rms=1e-6, u_rms=1.0, du_rms=c_u_per_kd * p[G_KD],
                       c_u=c_u_per_kd * p[G_KD] * (1 + 0.1 * i), u_peak=1.0, diverged=False) for i in range(n)]
                for p in packs]
    return SimpleNamespace(scores=scores, weights=[1.0] * n, calls=calls)


def _independent_check(ident, spec, pole):
    """Stability of the PID at ``pole`` on the identified plant and with +1 sample, recomputed here."""
    g, _ = pid_baseline(ident, spec.__class__(**{**spec.__dict__, "pid_pole": pole}))
    lin = linearize_pid(pid_pack(g))
    p = identified_plant(ident, spec)
    return (closed_loop_radius(lin, sampled_plant(p, spec.period)),
            closed_loop_radius(lin, sampled_plant(p, spec.period, extra_delay=1.0)))


def _assert_a_yardstick(ident, spec, base, choice):
    """The chosen PID is stable on the identified plant and with +1 sample (recomputed here) and its
    recorded margins keep every floor of the spec."""
    r0, r1 = _independent_check(ident, spec, base.pole)
    assert r0 < 1.0 and r1 < 1.0
    floors = MarginFloors.from_spec(spec)
    m = choice.margins
    assert m.gain_margin_db >= floors.gain_db and m.phase_margin_deg >= floors.phase_deg
    assert m.delay_margin_samples >= floors.delay_samples and m.modulus_margin >= floors.modulus


def test_yardstick_keeps_the_floors_and_plus_one_sample_where_eq57_is_unstable():
    """Four samples of drive delay: the paper's PID at 0.12 f_s = 300 rad/s is unstable on the
    identified plant; the yardstick is stable there and with a fifth sample, and keeps every floor."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({"plant": {"delay_samples": 4.0}})
    r0, r1 = _independent_check(ident, spec, spec.pid_pole)
    assert r0 > 1.0 and r1 > 1.0  # eq. (57) at the default pole is no yardstick here
    base, choice = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert choice.method == "margin_search" and choice.is_yardstick and choice.violations == ()
    assert base.pole == choice.pole < spec.pid_pole
    _assert_a_yardstick(ident, spec, base, choice)
    # the fastest admissible pole of the grid: the next one up misses a floor
    grid = [f * spec.sample_rate for f in FRACTIONS]
    i = min(range(len(grid)), key=lambda k: abs(grid[k] - base.pole))
    assert not pid_candidates(ident, spec, [grid[i + 1]])[0].admissible


def test_yardstick_on_the_rigid_reference_is_the_fastest_admissible_pole_within_c_u():
    """Every admissible candidate is stable on the plant and with +1 sample (by construction);
    a c_u limit that the fastest admissible PIDs exceed moves the choice down the list."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({})
    cands = pid_candidates(ident, spec, [f * spec.sample_rate for f in FRACTIONS])
    ok = [c for c in cands if c.admissible]
    assert 0 < len(ok) < len(cands)
    assert all(c.margins.stable and c.radius_plus_one < 1.0 for c in ok)
    assert all(c.violations for c in cands if not c.margins.stable or c.radius_plus_one >= 1.0)
    fastest = max(c.pole for c in ok)
    base, choice = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert base.pole == pytest.approx(fastest) and choice.simulated == 1  # the fastest is within: no other simulated
    # c_u = k Kd x 1.2 on the worst scenario: the limit 1 admits Kd <= 1/(1.2 k)
    _, m_min = pid_baseline(ident, spec)
    k = 1.0 / (1.2 * 3.0 * m_min * 0.9 * fastest)  # the fastest pole reaches 1/0.9 of the limit
    base2, choice2 = pid_yardstick(ident, spec, _evaluator(k), 1.0, pole_free=True)
    assert base2.pole < fastest and max(s.c_u for s in base2.scores) <= 1.0
    assert 1.2 * k * 3.0 * m_min * sorted(c.pole for c in ok)[-1] > 1.0
    assert choice2.is_yardstick


def test_spec_pole_is_kept_and_flagged_when_it_misses_the_floors():
    """``[pid] pole`` given: the paper's formula at that pole, today's behaviour; its margins are
    recorded and it is not called a yardstick when it misses a floor.  The record round-trips."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({"pid": {"pole": 300.0}, "plant": {"delay_samples": 4.0}})
    base, choice = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=False)
    assert base.pole == 300.0 and choice.method == "spec_pole" and not choice.is_yardstick
    assert any("unstable" in v for v in choice.violations)
    again = YardstickChoice.from_dict(choice.to_dict())
    assert again.to_dict() == choice.to_dict()
    assert math.isclose(again.radius_plus_one, choice.radius_plus_one)


def test_the_recorded_yardstick_is_the_final_pid_where_the_evidence_bounds_the_loop():
    """A rigid log backed to 22 Hz (the sample's whole-log band): the fastest PID that keeps the margin
    floors reaches beyond the evidence (||W T|| >= 1).  The evidence bound is part of the yardstick's
    admissibility, so the recorded choice already holds it and pid_within_evidence keeps it: tuning.json's
    ``pid_yardstick`` and the PID that is validated are the same controller."""
    from commission.evidence import EvidenceBound
    from commission.tune.baseline import pid_within_evidence

    ident = reference_identification(frequency_response={"source": "whole_log", "band_hz": [8.0, 22.0]})
    spec = spec_from_mapping({})
    bound = EvidenceBound(ident, spec)
    assert bound.evidence.applies
    margin_only = [c for c in pid_candidates(ident, spec, [f * spec.sample_rate for f in FRACTIONS])
                   if c.admissible]
    fastest = max(c.pole for c in margin_only)
    assert not bound.pid_row(pid_baseline(ident, spec.__class__(**{**spec.__dict__, "pid_pole": fastest}))[0]).holds
    base, choice = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert choice.is_yardstick and base.pole == choice.pole < fastest
    assert bound.pid_row(base.gains).holds
    final = pid_within_evidence(base, ident, spec, _evaluator(1e-6), True)
    assert final is base


def test_a_fallback_beyond_the_evidence_is_never_recorded_as_a_yardstick():
    """A rigid log backed to 6 Hz only: every PID of the grid keeps the floors on the identified plant
    but reaches beyond the evidence.  The evidence, not the plant, limits this axis, so the grid is not
    continued below 0.02 f_s (a PID slowed to the log's band measures the log, not the machine) and the
    paper's pole is the fallback.  That PID keeps every margin floor on the identified plant (the floors
    alone would call it a yardstick), but its ||W T|| is far above 1: the record names the evidence it
    misses and is no yardstick, so validate does not hold the ARC to it."""
    from commission.evidence import EvidenceBound

    ident = reference_identification(delta_d=0.5, frequency_response={"source": "whole_log", "band_hz": [3.0, 6.0]})
    spec = spec_from_mapping({})
    grid = [f * spec.sample_rate for f in FRACTIONS]
    assert any(c.admissible for c in pid_candidates(ident, spec, grid))  # the model admits the grid
    base, choice = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert choice.method == "none_admissible" and choice.admissible == 0
    assert choice.candidates == len(FRACTIONS)  # not continued below the grid
    assert bandwidth_factor(choice, spec) == 1.0  # no yardstick: the rate-scaled design stays
    floors_only = pid_candidates(ident, spec, [base.pole])[0]
    assert floors_only.admissible  # the margin floors alone would accept it
    row = EvidenceBound(ident, spec).pid_row(base.gains)
    assert not row.holds and row.peak > 1.0
    assert not choice.is_yardstick
    assert choice.violations == (f"beyond the evidence (peak ||W T|| {row.peak:.3g} >= 1)",)
    # the continued grid would have admitted a PID of the log's band: the rule, not the grid, stops it
    low = [f * spec.sample_rate for f in DEFAULT_SETTINGS.yardstick_low_fractions]
    bound = EvidenceBound(ident, spec)
    slow = [pid_baseline(ident, dataclasses.replace(spec, pid_pole=w))[0] for w in low]
    assert any(bound.pid_row(g).holds for g in slow)


def test_an_axis_whose_plant_sets_its_bandwidth_gets_a_yardstick_below_the_rate_grid():
    """A load-side mode at 60 Hz (damping 0.02) on the reference axis: no PID of the rate-scaled grid
    (0.02-0.4 f_s, 50-1000 rad/s) keeps the floors, so the grid is continued below it.  The yardstick
    found there keeps every floor and +1 sample (recomputed independently), the next faster pole of the
    continued grid does not, and the ARC's carried-over design is scaled by its pole over the grid's
    lowest (the rigid axis keeps factor 1)."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({"plant": {"mode_hz": 60.0, "mode_damping": 0.02, "mode_ratio": 0.2,
                                        "encoder": "load"}})
    grid = [f * spec.sample_rate for f in FRACTIONS]
    assert not any(c.admissible for c in pid_candidates(ident, spec, grid))
    base, choice = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert choice.method == "margin_search" and choice.is_yardstick and base.pole == choice.pole < grid[0]
    _assert_a_yardstick(ident, spec, base, choice)
    low = [f * spec.sample_rate for f in DEFAULT_SETTINGS.yardstick_low_fractions]
    i = min(range(len(low)), key=lambda k: abs(low[k] - base.pole))
    assert i > 0 and not pid_candidates(ident, spec, [low[i - 1]])[0].admissible
    assert math.isclose(bandwidth_factor(choice, spec), base.pole / grid[0])
    rigid = spec_from_mapping({})
    _, on_grid = pid_yardstick(ident, rigid, _evaluator(1e-6), 1.0, pole_free=True)
    assert on_grid.pole >= grid[0] and bandwidth_factor(on_grid, rigid) == 1.0


def _mode_ident(n_modes):
    """The reference axis with a 60-Hz load-side mode found in its log's response by a fit of ``n_modes``
    modes (the simulator's plant holds the first)."""
    model = {"mode_hz": 60.0, "mode_damping": 0.02, "mode_ratio": 0.2, "mode_load_side": True, "n_modes": n_modes}
    return reference_identification(delta_d=0.5, frequency_response={"source": "broadband", "model": model})


def test_the_grid_is_continued_only_on_a_plant_that_holds_every_fitted_mode():
    """The 60-Hz load mode rules out every pole of the grid.  Fitted alone, the plant is the fit and the
    grid is continued below it (as with the spec's [plant] mode above); fitted among three modes the
    simulator cannot hold, the plant is neither the data nor the fit, its missed floors no measure of
    the machine, and the grid is not continued: no yardstick, factor 1."""
    from commission.scenarios import plant_holds_fit

    spec = spec_from_mapping({})
    grid = [f * spec.sample_rate for f in FRACTIONS]
    held, dropped = _mode_ident(1), _mode_ident(3)
    assert plant_holds_fit(held, spec) and not plant_holds_fit(dropped, spec)
    assert plant_holds_fit(reference_identification(delta_d=0.5), spec)  # no fitted response: nothing dropped
    for ident in (held, dropped):  # the same plant either way: the grid's floors fail on both
        assert not any(c.admissible for c in pid_candidates(ident, spec, grid))
    base, choice = pid_yardstick(held, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert choice.method == "margin_search" and choice.is_yardstick and base.pole < grid[0]
    _, refused = pid_yardstick(dropped, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert refused.method == "none_admissible" and refused.candidates == len(FRACTIONS)
    assert not refused.is_yardstick and bandwidth_factor(refused, spec) == 1.0


@pytest.mark.parametrize("where", ["grid", "below"])
def test_a_yardstick_whose_fastest_poles_chatter_is_the_fastest_admissible_pole_within_c_u(where):
    """c_u (stubbed: proportional to Kd = 3 M w) above the limit on the eight fastest admissible poles
    and on more: the yardstick is still the fastest admissible pole within c_u -- further down the
    grid, or below it -- found by bisection, not by simulating every pole; never a chattering PID
    while one within c_u exists.  The floors admit the grid here, so the ARC's rate-scaled design is
    kept either way (bandwidth_factor 1): the encoder's noise, not the plant, held the PID down."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({})
    st = DEFAULT_SETTINGS
    fs = spec.sample_rate
    grid = pid_candidates(ident, spec, [f * fs for f in FRACTIONS])
    ok = sorted((c.pole for c in grid if c.admissible), reverse=True)
    low = pid_candidates(ident, spec, [f * fs for f in st.yardstick_low_fractions])
    allowed = sorted([c.pole for c in grid + low if c.admissible], reverse=True)
    n_tried = st.yardstick_batch * st.yardstick_batches
    assert len(ok) > n_tried + 3
    w_lim = 1.0001 * ok[n_tried + 3] if where == "grid" else 0.6 * min(ok)
    _, m_min = pid_baseline(ident, spec)
    k = 1.0 / (1.2 * 3.0 * m_min * w_lim)  # the worst scenario's c_u reaches 1 at w_lim
    ev = _evaluator(k)
    base, choice = pid_yardstick(ident, spec, ev, 1.0, pole_free=True)
    expected = max(w for w in allowed if w <= w_lim)
    assert base.pole == pytest.approx(expected, rel=1e-12) and choice.pole == base.pole
    assert max(s.c_u for s in base.scores) <= 1.0 and choice.is_yardstick
    faster = [w for w in allowed if w > expected]
    assert 1.2 * k * 3.0 * m_min * min(faster) > 1.0  # the next faster admissible pole chatters
    assert n_tried < choice.simulated < n_tried + 10 and sum(ev.calls) == choice.simulated
    assert choice.fastest_admissible == pytest.approx(ok[0], rel=1e-12)
    assert (base.pole < ok[-1]) == (where == "below") and bandwidth_factor(choice, spec) == 1.0
    _assert_a_yardstick(ident, spec, base, choice)


def test_a_plant_limited_yardstick_held_further_down_by_c_u_scales_the_arc_by_the_floors_pole():
    """The 60-Hz load mode of the test above rules out the grid; the fastest pole below it that keeps
    the floors chatters (stubbed c_u reaching the limit at 0.6 of that pole), so the yardstick is a
    slower pole.  The ARC's design is scaled by what the floors allow -- the fastest admissible pole
    over the grid's lowest -- not by the noise-held pole, and the record says both."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({"plant": {"mode_hz": 60.0, "mode_damping": 0.02, "mode_ratio": 0.2,
                                        "encoder": "load"}})
    grid = [f * spec.sample_rate for f in FRACTIONS]
    _, free = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    w_floor = free.pole  # within c_u with a negligible noise: the fastest the floors admit
    assert free.fastest_admissible == pytest.approx(w_floor) and w_floor < grid[0]
    _, m_min = pid_baseline(ident, spec)
    held_base, held = pid_yardstick(ident, spec, _evaluator(1.0 / (1.2 * 3.0 * m_min * 0.6 * w_floor)), 1.0,
                                    pole_free=True)
    assert held.is_yardstick and held.pole < 0.6 * w_floor * 1.0001
    assert max(s.c_u for s in held_base.scores) <= 1.0
    assert held.fastest_admissible == pytest.approx(w_floor, rel=1e-12)
    assert math.isclose(bandwidth_factor(held, spec), w_floor / grid[0])
    assert not math.isclose(bandwidth_factor(held, spec), held.pole / grid[0])
    # the record keeps it, and a record written before it was kept reads as the chosen pole
    d = held.to_dict()
    assert d["fastest_admissible_pole"] == pytest.approx(w_floor)
    assert YardstickChoice.from_dict(d) == held
    old = {k: v for k, v in d.items() if k != "fastest_admissible_pole"}
    assert YardstickChoice.from_dict(old).fastest_admissible is None
    assert math.isclose(bandwidth_factor(YardstickChoice.from_dict(old), spec), held.pole / grid[0])


def test_when_no_admissible_pole_is_within_c_u_the_slowest_simulated_is_kept():
    """A c_u limit no pole of the family meets, down to the slowest below the grid: the fallback is the
    slowest of the first batches, as before, after a bisection (a handful of simulations more)."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({})
    st = DEFAULT_SETTINGS
    ok = sorted((c.pole for c in pid_candidates(ident, spec, [f * spec.sample_rate for f in FRACTIONS])
                 if c.admissible), reverse=True)
    n_tried = st.yardstick_batch * st.yardstick_batches
    ev = _evaluator(1e6)
    base, choice = pid_yardstick(ident, spec, ev, 1.0, pole_free=True)
    assert base.pole == pytest.approx(ok[n_tried - 1]) and n_tried < choice.simulated <= n_tried + 7
    assert max(s.c_u for s in base.scores) > 1.0 and sum(ev.calls) == choice.simulated


def test_poles_too_slow_to_track_do_not_hide_the_ones_within_c_u():
    """c_u above the limit on the fast poles, and runs that lose the trajectory (diverged) on the slowest
    ones: the yardstick is still the fastest admissible pole within c_u between them."""
    ident = reference_identification(delta_d=0.5)
    spec = spec_from_mapping({})
    fs = spec.sample_rate
    grid = pid_candidates(ident, spec, [f * fs for f in FRACTIONS])
    low = pid_candidates(ident, spec, [f * fs for f in DEFAULT_SETTINGS.yardstick_low_fractions])
    allowed = sorted([c.pole for c in grid + low if c.admissible], reverse=True)
    w_lim, w_slow = 0.01 * fs, 0.002 * fs  # chatter above w_lim, diverge below w_slow
    _, m_min = pid_baseline(ident, spec)

    def scores(kind, packs):
        out = []
        for p in packs:
            w = p[G_KD] / (3.0 * m_min)
            out.append([Indexes(e_M=1e-5, e_F=1e-6, e_rms=1e-6, u_rms=1.0, du_rms=w / w_lim, c_u=w / w_lim,
                                u_peak=1.0, diverged=w < w_slow) for _ in range(2)])
        return out
    base, choice = pid_yardstick(ident, spec, SimpleNamespace(scores=scores, weights=[1.0, 1.0]), 1.0,
                                 pole_free=True)
    assert base.pole == pytest.approx(max(w for w in allowed if w <= w_lim), rel=1e-12)
    assert not any(s.diverged for s in base.scores) and max(s.c_u for s in base.scores) <= 1.0
