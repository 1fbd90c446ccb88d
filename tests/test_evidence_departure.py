"""Issue 30, must show 1 (0 false certifications): a named development axis of the held-out false certification's type.

The held-out sweep's one false certification is known only by its description: 20 kHz,
force-commanded, modes at 1042 and 1907 Hz, 1.87 samples of delay, the emitted ARC faults on
its true plant.  :data:`HELD_OUT_TYPE` is such an axis, built by hand (no held-out seed is
drawn): development axis 26 of :func:`commission.synth.random_axis` (20 kHz, 8.95 kg, an encoder
of 0.14 um read with 0.96 counts of noise), its command turned into force (N), its mode replaced
by the held-out's two -- 1042 Hz on the motor, 1907 Hz on a load the encoder reads -- and 1.87
samples of delay.  Its log is recorded with the sweep's recipe
(:func:`commission.synth.record_axis_log`, seed 26).

What happened before the fix: the encoder noise fed back by the holding loop fills the command,
no broadband segment was found (it is now, on blocks of 200 samples or more: identify's
``BROADBAND_FACTOR_LONG``; the legacy log without injection keeps the case below), and the whole-log response backs the rigid model to 424 Hz while
staying coherent up to 1990 Hz -- where it departs from the model.  The unseen mode was assumed a
decade above the band (4.24 kHz), above both real modes; the emitted ARC (crossover 288 Hz, peak
|W T| 0.15 under that assumption) faulted on the true axis with one more sample of delay
(|e| beyond the travel after 0.73 s in Case 2).  With the unknown starting at the band's top
(:func:`commission.evidence.departs_above_band`) the same gains have peak |W T| 5.6.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.evidence import EVIDENCE_FACTOR, departs_above_band
from commission.synth import AxisTruth, random_axis, record_axis_log


def held_out_type() -> AxisTruth:
    """Development axis 26, force-commanded, with the held-out false certification's modes and delay."""
    t = random_axis(np.random.default_rng(26))
    g = t.input_gain
    return dataclasses.replace(
        t, M=t.M * g, B=t.B * g, fc=t.fc * g, fs=t.fs * g, offset=t.offset * g, ripple_amp=t.ripple_amp * g,
        u_max=t.u_max * g, u_unit="N", input_gain=1.0,
        mode_hz=1042.0, mode_damping=0.03, mode_ratio=0.3, mode_load_side=False,
        mode2_hz=1907.0, mode2_damping=0.02, mode2_ratio=0.15, mode2_load_side=True, delay=1.87 / t.sample_rate)


HELD_OUT_TYPE = held_out_type()


def test_the_named_axis_is_of_the_held_out_type():
    t = HELD_OUT_TYPE
    assert (t.sample_rate, t.u_unit, t.mode_hz, t.mode2_hz) == (20000.0, "N", 1042.0, 1907.0)
    assert t.delay * t.sample_rate == pytest.approx(1.87)
    assert 8.0 < t.mass_kg < 10.0 and t.noise_std / t.lsb > 0.9


@pytest.mark.slow
def test_its_excite_injection_is_found_now_and_without_one_the_unknown_starts_at_the_band_top(tmp_path):
    """The excite log's injection, 2-3 times the holding loop's noise-driven command, is found on these
    long blocks (``BROADBAND_FACTOR_LONG``): the measured response backs the model beyond both real modes.
    Without an injection (the legacy log) the whole-log response is coherent far above the band it
    backs, so it contradicts the model there and the unknown starts at the band's top."""
    def identify(kind: str) -> dict:
        rec = record_axis_log(HELD_OUT_TYPE, tmp_path / f"{kind}.h5", seed=26, log=kind)
        assert rec.log == kind
        res = CliRunner().invoke(app, ["identify", str(tmp_path / f"{kind}.h5"), "-o", str(tmp_path / f"{kind}.json")])
        assert res.exit_code == 0, res.output
        return json.loads((tmp_path / f"{kind}.json").read_text())["frequency_response"]

    fr = identify("excite")
    assert fr["source"] == "broadband" and len(fr["segments_s"]) == 1
    assert fr["evidence_band_hz"][1] > HELD_OUT_TYPE.mode2_hz > HELD_OUT_TYPE.mode_hz  # both real modes measured
    fr = identify("legacy")
    assert fr["source"] == "whole_log" and fr["segments_s"] == []
    band = tuple(fr["evidence_band_hz"])
    assert fr["coherent_up_to_hz"] > 2 * band[1]  # coherent data well above the band: they contradict the model
    assert band[1] < HELD_OUT_TYPE.mode_hz  # a real mode above the band, where the model says nothing
    assert departs_above_band(band, fr["coherent_up_to_hz"], fr["resolution_hz"])


@pytest.mark.slow
def test_what_is_emitted_works_on_the_true_axis_or_the_tool_refuses_and_says_why(tmp_path):
    from commission.true_axis import judge_axis

    record_axis_log(HELD_OUT_TYPE, tmp_path / "log.h5", seed=26)
    j = judge_axis(HELD_OUT_TYPE, tmp_path / "log.h5", out_dir=tmp_path / "out", seed=0, workers=1)
    assert not j.false_certification, (j.verdict, j.arc_runs)
    if not j.emitted:
        report = (tmp_path / "out" / "report.md").read_text()
        head = report.split("## ")[0]  # the report's first lines
        assert "**Evidence.**" in head
        assert "No `controller.json` was written." in head
        source = json.loads((tmp_path / "out" / "ident.json").read_text())["frequency_response"]["source"]
        if source != "broadband":
            assert "commission excite" in report  # what to record to raise the evidence
        else:  # the evidence is measured: the refusal names the checks that failed
            assert "checks failed:" in head and "\n- " in head
