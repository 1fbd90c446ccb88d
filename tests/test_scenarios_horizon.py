"""Validation and tuning horizons stay within the sample cap at any rate the spec accepts
(:func:`commission.scenarios.case1_trajectory`, ``case2_trajectory``, :func:`horizon_notes`)."""

from __future__ import annotations

import math

import pytest

from commission.scenarios import (CASE1_DURATION, case1_trajectory, case2_trajectory, check_run_length,
                                  horizon_notes, max_horizon)
from commission.spec import MAX_TRAJECTORY_SAMPLES, spec_from_mapping


def test_slow_envelope_at_20_khz_is_cut_to_the_cap_and_said():
    """A slow envelope (Case 1 of 4 periods = 63 s, Case 2 of 6 moves at 10 cm/s; whole at 1 kHz) at 10 and 20 kHz:
    the full runs exceed 250,000 samples; the runs used are within it, the notes say so, and the
    run-length check that used to refuse the spec before tuning accepts it."""
    slow = {"trajectory": {"v_max": 0.1, "a_max": 1.0, "travel": 0.4}}
    base = spec_from_mapping({**slow, "controller": {"sample_rate": 1000.0}})
    full1, full2 = case1_trajectory(base).duration, case2_trajectory(base).duration
    assert full1 == pytest.approx(4 * 2 * math.pi / case1_trajectory(base).omega) and full1 > CASE1_DURATION
    for rate in (10_000.0, 20_000.0):
        spec = spec_from_mapping({**slow, "controller": {"sample_rate": rate}})
        assert full1 * rate > MAX_TRAJECTORY_SAMPLES and full2 * rate > MAX_TRAJECTORY_SAMPLES
        c1, c2 = case1_trajectory(spec), case2_trajectory(spec)
        assert c1.duration * rate <= MAX_TRAJECTORY_SAMPLES and c2.duration * rate <= MAX_TRAJECTORY_SAMPLES
        assert c1.duration == max_horizon(rate) and c1.omega == case1_trajectory(base).omega
        assert 2 <= c2.moves < spec.moves
        check_run_length(spec, "spec.toml")  # no SpecError
        tr = c1.render(spec.period)
        assert len(tr.t) <= MAX_TRAJECTORY_SAMPLES + 1
        notes = horizon_notes(spec)
        assert len(notes) == 2 and "Case 1 runs" in notes[0] and f"{rate:g} Hz" in notes[0]
        assert f"Case 2 runs {c2.moves} of the 6 moves" in notes[1]
    assert horizon_notes(base) == ()
    paper = spec_from_mapping({})
    assert case1_trajectory(paper).duration == CASE1_DURATION and case2_trajectory(paper).moves == 6
