"""`commission excite`: the plan, its files, its refusals, its pre-simulation and the loop back to identify."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from commission.formats.json_table import unnamed
from commission.formats.plan_json import PLAN_FIELDS
from commission.cli.main import app
from commission.errors import SpecError
from commission.excite import (PlanRefused, excite_spec_from_mapping, load_excite_spec, load_plan_json, loop_gains_for, mass_bracket,
                               plan_run, play, simulate_plan)
from commission.excite.presim import _model_truth

runner = CliRunner()

SMALL = """\
[limits]
travel = 0.2
v_max = 0.4
a_max = 20.0
u_max = 10.0
[drive]
sample_rate = 1000.0
bandwidth_hz = 30.0
[axis]
mass = 0.03
friction = 0.1
[plan]
n_speeds = 4
moves = 2
injection_s = 3.0
"""


def _spec_file(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "limits.toml"
    p.write_text(text)
    return p


def test_cli_writes_plan_files(tmp_path):
    out = tmp_path / "plan"
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, SMALL)), "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.iterdir()) == ["plan.csv", "plan.h5", "plan.json", "plan.png"]
    header = (out / "plan.csv").read_text().splitlines()[0]
    assert header == "t,q_ref,v_ref,u_inject"
    csv = np.loadtxt(out / "plan.csv", delimiter=",", skiprows=1)
    t = csv[:, 0]
    assert np.allclose(np.diff(t), 1e-3, rtol=0, atol=1e-9)  # one row per sample at 1 kHz
    plan = json.loads((out / "plan.json").read_text())
    assert plan["kind"] == "excitation_plan" and plan["schema_version"] == 1
    assert plan["samples"] == t.size
    assert plan["duration_s"] == pytest.approx(t[-1] + 1e-3)
    with h5py.File(out / "plan.h5") as f:
        assert set(f) == {"t", "q_ref", "v_ref", "u_inject"}
        for i, name in enumerate(("t", "q_ref", "v_ref", "u_inject")):
            assert np.allclose(f[name][:], csv[:, i], rtol=1e-10, atol=1e-12)
        assert f.attrs["u_unit"] == "V" and f.attrs["q_unit"] == "m"
    names = [g["name"] for g in plan["segments"]]
    assert any(n.startswith("ladder") for n in names) and "moves" in names and "injection" in names
    # segments tile the run
    for a, b in zip(plan["segments"], plan["segments"][1:]):
        assert a["t_end"] == pytest.approx(b["t_start"])
    # the printed duration is the file's, with its unit; the peaks are printed with units
    assert re.search(rf"plan: {plan['duration_s']:.2f} s", r.output), r.output
    assert re.search(r"\|u\| [\d.e+-]+ V <= u_max 10 V", r.output), r.output
    assert re.search(r"\|a\| [\d.e+-]+ m/s\^2 <= a_max 20 m/s\^2", r.output), r.output
    # the pre-simulation's peaks are within the limits and stated in plan.json
    for key, chk in plan["presimulation"]["peaks"].items():
        assert chk["peak"] <= chk["limit"], key
    assert load_plan_json(out / "plan.json")["segments"] == plan["segments"]
    assert unnamed(plan, PLAN_FIELDS) == []  # every key written is a row of plan.json's table
    # the band the plan will back is said before the run, and what was assumed for it (no encoder keys)
    pb = plan["predicted_band"]
    assert pb["encoder_step_assumed"] and pb["encoder_noise_assumed"] and pb["target_hz"] is None
    assert pb["band_hz"][0] < pb["band_hz"][1] < 500.0
    assert "predicted band the recording will back:" in r.output and "note: assumed encoder_step 1e-06 m" in r.output
    # the folder is not overwritten without --force (checked before any work), and is with it
    before = (out / "plan.json").read_bytes()
    r = runner.invoke(app, ["excite", "--spec", str(tmp_path / "limits.toml"), "--out-dir", str(out)])
    assert r.exit_code == 2 and "--force" in r.stderr, r.output
    assert (out / "plan.json").read_bytes() == before
    r = runner.invoke(app, ["excite", "--spec", str(tmp_path / "limits.toml"), "--out-dir", str(out), "--force"])
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("edit, pattern", [
    (("travel = 0.2", "travel = 0.0005"), r"limits\.travel = 0\.0005 m is too short for the slowest friction-ladder leg"),
    (("friction = 0.1", "friction = 12.0"), r"axis\.friction = 12 V is not below limits\.u_max = 10 V"),
    (("friction = 0.1", "friction = 6.0"),  # stick-slip: the breakaway accelerates past a_max
     r"plan refused: limits\.a_max: the pre-simulation breaks it in segment 'ladder \d' at t = [\d.]+ s "
     r"\(sample \d+\): \|a\| = [\d.]+ m/s\^2 > 20 m/s\^2, on the light model"),
    (("bandwidth_hz = 30.0", "kp = 3e5\nkd = 300.0"),
     r"plan refused: limits\.u_max: the holding loop diverges on the light model .* segment 'approach'"),
    (("bandwidth_hz = 30.0", "bandwidth_hz = 100.0"), r"drive\.sample_rate = 1000 Hz is too low for drive\.bandwidth_hz"),
    (("u_max = 10.0", "u_max = 10.0\nspeed = 3"), r"limits\.speed: unknown key"),
    (("a_max = 20.0", "a_max = \"fast\""), r"limits\.a_max = 'fast': expected a finite number in m/s\^2"),
    (("u_max = 10.0\n", ""), r"limits\.u_max: missing"),
])
def test_refusals_exit_2_nothing_written(tmp_path, edit, pattern):
    text = SMALL.replace(*edit)
    assert text != SMALL
    out = tmp_path / "plan"
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, text)), "--out-dir", str(out)])
    assert r.exit_code == 2, r.output
    err = r.stderr.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert re.search(pattern, err), err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["limits.toml"]


def _checked_peaks(plan) -> dict[str, float]:
    """Peaks of the plan replayed here on its own conservative models (independent of plan.peaks)."""
    s = plan.spec
    T = 1.0 / s.sample_rate
    worst = {"u": 0.0, "q": 0.0, "v": 0.0, "a": 0.0}
    for M in mass_bracket(s):
        log = play(plan, _model_truth(s, M), loop_gains_for(s, M))
        q = log["q"]
        worst["u"] = max(worst["u"], float(np.max(np.abs(log["u"]))))
        worst["q"] = max(worst["q"], float(np.max(np.abs(q))))
        worst["v"] = max(worst["v"], float(np.max(np.abs(np.diff(q)))) / T)
        worst["a"] = max(worst["a"], float(np.max(np.abs(np.diff(q, 2)))) / T / T)
    return worst


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(travel=st.floats(0.002, 1.0), v_max=st.floats(0.01, 3.0), a_max=st.floats(0.5, 200.0),
       u_max=st.floats(0.5, 100.0), fs=st.sampled_from([1000.0, 2500.0, 4000.0]),
       bw_frac=st.floats(0.005, 0.05), mass=st.one_of(st.none(), st.floats(0.005, 20.0)),
       friction_frac=st.one_of(st.none(), st.floats(0.0, 0.5)),
       injection=st.sampled_from(["prbs", "multisine"]))
def test_emitted_plan_never_exceeds_a_limit(travel, v_max, a_max, u_max, fs, bw_frac, mass, friction_frac,
                                             injection):
    axis = {}
    if mass is not None:
        axis["mass"] = mass
    if friction_frac is not None:
        axis["friction"] = friction_frac * u_max
    data = {"limits": {"travel": travel, "v_max": v_max, "a_max": a_max, "u_max": u_max},
            "drive": {"sample_rate": fs, "bandwidth_hz": bw_frac * fs}, "axis": axis,
            "plan": {"n_speeds": 4, "moves": 2, "injection_s": 2.0, "injection": injection}}
    try:
        plan = plan_run(excite_spec_from_mapping(data))
    except (PlanRefused, SpecError) as exc:
        assert str(exc).startswith("limits.toml: "), exc  # one line naming the file, then the key
        return
    s = plan.spec
    # the reference itself keeps within the limits
    assert np.max(np.abs(plan.q_ref)) <= s.travel / 2
    assert np.max(np.abs(plan.v_ref)) <= s.v_max
    assert np.max(np.abs(plan.a_ref)) <= s.a_max
    assert np.max(np.abs(plan.u_inject)) <= s.u_max
    # and so does its pre-simulation, replayed
    w = _checked_peaks(plan)
    assert w["u"] <= s.u_max and w["q"] <= s.travel / 2 and w["v"] <= s.v_max and w["a"] <= s.a_max, (w, s)


# Must show 1 (issue 31): three known-truth axes with different modes, rates and encoders, one with two
# modes.  The truth is the simulator's plant (commission.synth.AxisTruth), generated independently of the
# fit; a mode's true frequency and damping are those of the true plant's poles (two appendages on one
# motor couple: the 450 Hz and 1 kHz appendages of B resonate at 445.8 Hz and 1049.8 Hz).
# What the data can back is set by physics: the injection's acceleration is bounded by a_max, so the
# motion it makes at f falls as a_max / (2 pi f)^2 against the encoder's noise floor.  Measured with
# these plans: a 500 Hz mode on a 1 um scale with 0.5 um noise and a_max = 20 m/s^2 is backed to
# ~595 Hz (1.2x); with 0.1 um / 0.2 um (A below) past 750 Hz.  C's 5 um scale at 1 kHz and a_max = 10 m/s^2
# backs 205-210 Hz with a 130 Hz mode, 315 Hz with a 300 Hz one (found at 299 Hz, but not backed to 450 Hz;
# with today's plan 135-145 Hz over seeds 0-4: test_predicted_band_agrees_with_identify_on_known_truth), so its
# mode is 130 Hz.  Seeds 0-4 of the recording: A's band 760-815 Hz, B's 1755-1815 Hz, C's 205-210 Hz,
# C's damping 15-20 % high (the 5 Hz bins smooth its 16 Hz wide peak).  Figures: docs/interface.md §10.
LOOP_AXES = {
    "A 2.5 kHz, motor-side 500 Hz mode, 0.1 um scale, 0.2 um noise, 0.5-sample delay": (
        {"limits": {"travel": 0.3, "v_max": 0.5, "a_max": 20.0, "u_max": 10.0},
         "drive": {"sample_rate": 2500.0, "bandwidth_hz": 40.0}, "axis": {"mass": 0.03, "friction": 0.1,
                                                                   "encoder_step": 0.1e-6, "encoder_noise": 0.2e-6}},
        dict(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, lsb=0.1e-6, noise_std=0.2e-6, sample_rate=2500.0,
             mode_hz=500.0, mode_damping=0.03, mode_ratio=0.3, delay=0.5 / 2500.0)),
    "B 8 kHz, N, 450 Hz motor-side and 1 kHz bracket modes, 10 nm scale, 20 nm noise, 1.2-sample delay": (
        {"limits": {"travel": 0.5, "v_max": 1.0, "a_max": 30.0, "u_max": 100.0},
         "drive": {"sample_rate": 8000.0, "bandwidth_hz": 60.0}, "axis": {"mass": 1.0, "u_unit": "N",
                                                                    "encoder_step": 1e-8, "encoder_noise": 2e-8}},
        dict(M=1.2, B=8.0, fc=4.0, fs=5.0, vs=0.02, xi=2.0, lsb=1e-8, noise_std=2e-8, sample_rate=8000.0, u_unit="N",
             u_max=100.0, mode_hz=450.0, mode_damping=0.03, mode_ratio=0.3, delay=1.2 / 8000.0,
             mode2_hz=1000.0, mode2_damping=0.04, mode2_ratio=0.15, mode2_load_side=True)),
    "C 1 kHz, 5 um scale, 1 um noise, motor-side 130 Hz mode, 0.3-sample delay": (
        {"limits": {"travel": 0.2, "v_max": 0.3, "a_max": 10.0, "u_max": 10.0},
         "drive": {"sample_rate": 1000.0, "bandwidth_hz": 20.0}, "axis": {"mass": 0.1, "encoder_step": 5e-6,
                                                                   "encoder_noise": 1e-6}},
        dict(M=0.08, B=0.5, fc=0.3, fs=0.35, vs=0.005, xi=1.5, lsb=5e-6, noise_std=1e-6, sample_rate=1000.0,
             mode_hz=130.0, mode_damping=0.06, mode_ratio=0.3, delay=0.3 / 1000.0)),
}


def _true_modes(truth) -> list[tuple[float, float]]:
    """(Hz, damping ratio) of the true plant's structural modes, as coupled, lowest first."""
    from commission.controllers.linear import structural_modes

    return structural_modes(truth.plant())


@pytest.mark.parametrize("name", list(LOOP_AXES))
def test_known_truth_loop_identify_recovers_axis(tmp_path, name):
    """Must show 1: plan from the limits, record the plan on a known-truth axis, identify the log as a user does
    (`commission identify LOG` with the plan.json that `excite` wrote beside it)."""
    from commission.synth import AxisTruth, write_log_h5

    spec_d, truth_d = LOOP_AXES[name]
    truth = AxisTruth(**truth_d)
    spec = excite_spec_from_mapping(spec_d)
    plan_dir = tmp_path / "run"
    toml = "".join(f"[{sec}]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in kv.items()) for sec, kv in spec_d.items())
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, toml)), "--out-dir", str(plan_dir)])
    assert r.exit_code == 0, r.output
    plan = plan_run(spec)
    assert plan.t.size == json.loads((plan_dir / "plan.json").read_text())["samples"]
    assert 20.0 < plan.duration < 120.0  # minutes, not hours
    log = simulate_plan(plan, truth, np.random.default_rng(1))
    # 0 limit violations in the recording: the command and the encoder's reading ...
    T = 1 / truth.sample_rate
    assert np.max(np.abs(log["u"])) <= spec.u_max
    assert np.max(np.abs(log["q"])) <= spec.travel / 2
    assert np.max(np.abs(np.diff(log["q"]))) / T <= spec.v_max
    # ... and the axis's rigid-body motion: the same run without noise, on a fine scale and without the
    # structural modes (the reading's second difference is the encoder noise's; a_max bounds the body's
    # acceleration, not the vibration of a lightly damped mode, which the injection rings at its
    # resonance: the motor side then reads 1.4-2.8 a_max, microns at hundreds of Hz; docs/interface.md §10)
    rigid = dataclasses.replace(truth, noise_std=0.0, lsb=1e-12, mode_hz=0.0, mode2_hz=0.0)
    clean = simulate_plan(plan, rigid, np.random.default_rng(1))
    assert np.max(np.abs(np.diff(clean["q"], 2))) / T**2 <= spec.a_max
    assert np.max(np.abs(np.diff(clean["q"]))) / T <= spec.v_max
    assert np.max(np.abs(clean["q"])) <= spec.travel / 2 and np.max(np.abs(clean["u"])) <= spec.u_max
    write_log_h5(plan_dir / "log.h5", log, u_unit=truth.u_unit)
    out = tmp_path / "ident.json"
    r = runner.invoke(app, ["identify", str(plan_dir / "log.h5"), "--out", str(out)])
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    p, fr, enc = d["parameters"], d["frequency_response"], d["encoder"]
    assert fr["plan"] == str((plan_dir / "plan.json").resolve()) and fr["source"] == "broadband"
    res = sorted((m["frequency_hz"], m["damping"]) for m in fr["modes"] if m["kind"] == "resonance")
    true = _true_modes(truth)
    band = fr["evidence_band_hz"]
    predicted = json.loads((plan_dir / "plan.json").read_text())["predicted_band"]["band_hz"]
    print(f"loop {name}: predicted band {predicted} Hz, identify's {band} Hz: "
          f"{100 * (predicted[1] / band[1] - 1):+.1f} %")
    print(f"loop {name}: duration {plan.duration:.1f} s;",
          ", ".join(f"{k} {100 * (p[k]['value'] / getattr(truth, k) - 1):+.2f} %" for k in ("M", "B", "fc")),
          f"; modes {[(round(f, 1), round(z, 4)) for f, z in res]} (truth {[(round(f, 1), round(z, 4)) for f, z in true]});"
          f" delay {fr['delay_samples']:.3f} samples (truth {truth.delay * truth.sample_rate:g}); band {band} Hz;"
          f" noise {enc['noise_std']:.3g} m (truth {truth.noise_std:g})")
    # M within 1.5 %: the injection's cruise now runs above the mass regression's reversal speed, so its
    # rows enter that regression, and axis C's 130 Hz motor-side mode, just above the regression's 100 Hz
    # cutoff, moves its M by 1.0 % (0.3 % on the slow cruise excite planned before); B and fc within 1 %.
    for k, tol in (("M", 0.015), ("B", 0.01), ("fc", 0.01)):
        assert p[k]["value"] == pytest.approx(getattr(truth, k), rel=tol), k
    assert len(res) == len(true), (res, true)
    for (f, z), (ft, zt) in zip(res, true):
        assert f == pytest.approx(ft, rel=0.05) and z == pytest.approx(zt, rel=0.30), (res, true)
    assert fr["delay_samples"] == pytest.approx(truth.delay * truth.sample_rate, abs=0.2)
    assert enc["noise_std"] == pytest.approx(truth.noise_std, rel=0.20)
    assert band is not None and band[1] >= 1.5 * true[-1][0], (band, true)
    assert not fr["departures"]


def test_plan_beside_the_log_only_when_it_is_its_recording(tmp_path):
    """identify uses a plan.json beside the log only when the log has its sample rate and length."""
    from commission.identification import identify_log
    from commission.synth import AxisTruth, write_log_h5

    out = tmp_path / "run"
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, SMALL)), "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    plan = plan_run(load_excite_spec(tmp_path / "limits.toml"))
    truth = AxisTruth(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, lsb=1e-6, sample_rate=1000.0,
                      mode_hz=250.0, mode_damping=0.03, mode_ratio=0.3)
    log = simulate_plan(plan, truth, np.random.default_rng(0))
    write_log_h5(out / "log.h5", log)
    fr = identify_log(str(out / "log.h5")).ident.to_dict()["frequency_response"]
    wins = [w for g in plan.segments if g.name == "injection" for w in g.info["windows_s"]]
    assert fr["plan"] == str(out / "plan.json") and len(fr["segments_s"]) == len(wins)
    for (a, b), (wa, wb) in zip(fr["segments_s"], wins):
        assert wa < a < b < wb
    # a log of another length beside it: not its recording, the plan is left alone and said so
    half = {k: v[: v.size // 2] for k, v in log.items()}
    write_log_h5(out / "log.h5", half)
    d = identify_log(str(out / "log.h5")).ident.to_dict()
    assert "plan" not in d["frequency_response"]
    assert any("beside the log is not used" in w and "give --plan" in w for w in d["warnings"])


def test_plan_json_loader_names_bad_field(tmp_path):
    p = tmp_path / "plan.json"
    p.write_text(json.dumps({"kind": "excitation_plan", "schema_version": 1,
                             "segments": [{"name": "a", "purpose": "b", "t_start": 0.0, "t_end": "x"}]}))
    with pytest.raises(Exception, match=r"\$\.segments\[0\]\.t_end"):
        load_plan_json(p)


def test_without_mass_plan_starts_with_bump():
    spec = excite_spec_from_mapping({
        "limits": {"travel": 0.2, "v_max": 0.4, "a_max": 20.0, "u_max": 10.0},
        "drive": {"sample_rate": 1000.0, "bandwidth_hz": 30.0}, "plan": {"n_speeds": 3, "injection_s": 2.0}})
    plan = plan_run(spec)
    first = plan.segments[0]
    assert first.name == "bump"
    m = (plan.t >= first.t_start) & (plan.t < first.t_end)
    assert np.max(plan.u_inject[m]) > 0 and np.min(plan.u_inject[m]) < 0
    assert abs(float(np.sum(plan.u_inject[m]))) < 1e-9 * float(np.sum(np.abs(plan.u_inject[m])))  # zero net impulse
    assert np.all(plan.q_ref[m] == 0.0)  # at rest


def test_identify_plan_uses_the_plans_injection_windows(tmp_path):
    """`identify --plan plan.json` measures the frequency response on the plan's injection windows."""
    from commission.synth import AxisTruth, write_log_h5

    out = tmp_path / "plan"
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, SMALL)), "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    plan_d = load_plan_json(out / "plan.json")
    spec = load_excite_spec(tmp_path / "limits.toml")
    plan = plan_run(spec)
    assert np.allclose(plan.u_inject, np.loadtxt(out / "plan.csv", delimiter=",", skiprows=1)[:, 3], rtol=1e-11, atol=0)
    truth = AxisTruth(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, lsb=1e-6, sample_rate=1000.0,
                      mode_hz=250.0, mode_damping=0.03, mode_ratio=0.3)
    log = tmp_path / "log.h5"
    write_log_h5(log, simulate_plan(plan, truth, np.random.default_rng(0)))
    r = runner.invoke(app, ["identify", str(log), "--plan", str(out / "plan.json"), "--out", str(tmp_path / "i.json")])
    assert r.exit_code == 0, r.output
    fr = json.loads((tmp_path / "i.json").read_text())["frequency_response"]
    wins = [w for g in plan_d["segments"] if g["name"] == "injection" for w in g["windows_s"]]
    assert fr["source"] == "broadband" and len(fr["segments_s"]) == len(wins)
    for (a, b), (wa, wb) in zip(fr["segments_s"], wins):
        assert wa < a < b < wb
    print("identify --plan, 1 kHz axis, 250 Hz mode:", fr["modes"], fr["delay_samples"], fr["band_hz"])
    # a log that ends before the plan's injection does is not a recording of this plan
    short = {k: v[: int(plan.segments[2].t_end * 1000)] for k, v in simulate_plan(plan, truth,
                                                                                  np.random.default_rng(0)).items()}
    write_log_h5(tmp_path / "short.h5", short)
    r = runner.invoke(app, ["identify", str(tmp_path / "short.h5"), "--plan", str(out / "plan.json"),
                            "--out", str(tmp_path / "s.json")])
    assert r.exit_code == 2 and "--plan: the log ends at" in r.stderr, r.output
    assert not (tmp_path / "s.json").exists()


def test_stepped_sine_segments_carry_their_frequency():
    spec = excite_spec_from_mapping({
        "limits": {"travel": 0.2, "v_max": 0.4, "a_max": 20.0, "u_max": 10.0},
        "drive": {"sample_rate": 1000.0, "bandwidth_hz": 30.0}, "axis": {"mass": 0.03},
        "plan": {"n_speeds": 3, "moves": 2, "injection_s": 1.0, "stepped_sine_hz": [40.0, 170.0]}})
    plan = plan_run(spec)
    sines = [g for g in plan.segments if g.name.startswith("sine ")]
    assert [g.info["frequency_hz"] for g in sines] == [40.0, 170.0]
    for g in sines:
        (a, b), = g.info["windows_s"]
        m = (plan.t >= a) & (plan.t < b)
        x = plan.u_inject[m]
        assert b - a >= 20 / g.info["frequency_hz"] - 2e-3  # sine_cycles = 20 by default
        spec_x = np.abs(np.fft.rfft(x * np.hanning(x.size)))
        f = np.fft.rfftfreq(x.size, 1e-3)
        assert f[np.argmax(spec_x)] == pytest.approx(g.info["frequency_hz"], abs=1000.0 / x.size + 1e-9)
        assert np.all(plan.u_inject[(plan.t >= g.t_start) & (plan.t < g.t_end) & ~m] == 0.0)


def test_rotary_axis_words_its_units(tmp_path):
    text = """\
[limits]
travel = 6.0
v_max = 20.0
a_max = 400.0
u_max = 2.0
[drive]
sample_rate = 1000.0
kp = 8.0
kd = 0.05
[axis]
mass = 2e-4
q_unit = "rad"
u_unit = "Nm"
[plan]
n_speeds = 3
moves = 2
injection_s = 1.0
"""
    out = tmp_path / "plan"
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, text)), "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    plan = json.loads((out / "plan.json").read_text())
    assert plan["units"] == {"t": "s", "q": "rad", "u": "Nm", "v": "rad/s", "a": "rad/s^2"}
    assert plan["presimulation"]["models"][0]["kp"] == 8.0  # the given gains, on both models
    assert re.search(r"\|v\| [\d.e+-]+ rad/s <= v_max 20 rad/s", r.output), r.output
    assert re.search(r"\|u\| [\d.e+-]+ Nm <= u_max 2 Nm", r.output), r.output
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, text.replace("kd = 0.05", "kd = -1.0"))),
                            "--out-dir", str(tmp_path / "p2")])
    assert r.exit_code == 2 and "drive.kd = -1.0 Nm s/rad must not be negative" in r.stderr, r.output


def test_run_passes_plan_to_identify(tmp_path):
    """`commission run --plan plan.json` hands the plan to identify: a log that ends before the plan's injection
    is refused by identify's --plan check (exit 2, nothing written), and several logs with --plan are refused."""
    from commission.synth import AxisTruth, write_log_h5

    out = tmp_path / "plan"
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, SMALL)), "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    plan = plan_run(load_excite_spec(tmp_path / "limits.toml"))
    truth = AxisTruth(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, lsb=1e-6, sample_rate=1000.0)
    log = simulate_plan(plan, truth, np.random.default_rng(0))
    inj = next(g for g in plan.segments if g.name == "injection")
    short = {k: v[: int(inj.t_start * 1000)] for k, v in log.items()}
    write_log_h5(tmp_path / "short.h5", short)
    r = runner.invoke(app, ["run", str(tmp_path / "short.h5"), "--plan", str(out / "plan.json"),
                            "--out-dir", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--plan: the log ends at" in r.stderr, r.output
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())
    write_log_h5(tmp_path / "b.h5", short)
    r = runner.invoke(app, ["run", str(tmp_path / "short.h5"), str(tmp_path / "b.h5"), "--plan",
                            str(out / "plan.json"), "--out-dir", str(tmp_path / "o2")])
    assert r.exit_code == 2 and "--plan: takes one log" in r.stderr, r.output
    assert not (tmp_path / "o2").exists()


def test_one_limits_toml_sketch_for_identify_and_the_evidence_lines():
    """Item 4 of issue 31: identify's sketch (next_steps.excite_advice) and the evidence lines' (evidence.limits_toml)
    are one builder's: the same values give the same file, and excite accepts it as it is."""
    import tomllib

    from commission.evidence import limits_toml
    from commission.next_steps import excite_advice
    from commission.spec import spec_from_mapping

    spec = spec_from_mapping({"trajectory": {"travel": 0.3, "v_max": 0.5, "a_max": 6.0},
                              "controller": {"sample_rate": 4000.0, "u_max": 5.0}})

    class _E:
        def __init__(self, v):
            self.value = v

    class _Ident:
        parameters = {"M": _E(0.027), "B": _E(0.273), "fc": _E(0.1)}
        units = {"q": "m", "u": "V"}

    a = tomllib.loads(limits_toml(spec, _Ident()))
    b = tomllib.loads(excite_advice({"source": "whole_log", "band_hz": [2.0, 22.0]}, travel=0.3, v_peak=0.5,
                                    a_peak=6.0, u_peak=4.0, u_max=5.0, u_max_source="given", sample_rate=4000.0,
                                    M=0.027, B=0.273, fc=0.1, q_unit="m", u_unit="V").limits_toml)
    assert a == b
    s = excite_spec_from_mapping(a)
    assert (s.travel, s.u_max, s.mass, s.friction, s.bandwidth_hz) == (0.3, 5.0, 0.027, 0.1, 10.0)


@pytest.mark.parametrize("name,noise", [("A", 1e-6), ("B", 1e-7), ("C", 1e-6)])
def test_level_detector_finds_an_excite_injection_on_a_noisy_encoder(tmp_path, name, noise):
    """Item 2 of issue 31: without a plan (none given, none beside the log) the command's level still shows the
    injection of an excite plan where the holding loop's answer to encoder noise is large (the detector's
    factor of 10 over that background missed all three, the 8 kHz two-mode axis among them: 4-9 times here)."""
    from commission.identification import identify_log
    from commission.synth import AxisTruth, write_log_h5

    spec_d, truth_d = next(v for k, v in LOOP_AXES.items() if k.startswith(name))
    truth = AxisTruth(**{**truth_d, "noise_std": noise})
    plan = plan_run(excite_spec_from_mapping(spec_d))
    write_log_h5(tmp_path / "log.h5", simulate_plan(plan, truth, np.random.default_rng(2)), u_unit=truth.u_unit)
    fr = identify_log(str(tmp_path / "log.h5"), u_unit=truth.u_unit).ident.to_dict()["frequency_response"]
    wins = [w for g in plan.segments if g.name == "injection" for w in g.info["windows_s"]]
    assert "plan" not in fr and fr["source"] == "broadband" and len(fr["segments_s"]) == len(wins), fr["segments_s"]
    for (a, b), (wa, wb) in zip(fr["segments_s"], wins):
        assert wa <= a < b <= wb and b - a > 0.9 * (wb - wa) - 0.3
    res = sorted(m["frequency_hz"] for m in fr["modes"] if m["kind"] == "resonance")
    true = [f for f, _z in _true_modes(truth)]
    assert len(res) == len(true) and all(f == pytest.approx(ft, rel=0.05) for f, ft in zip(res, true)), (res, true)


# Issue 31, excite3: the band a plan will back, said before the run.  Known truth: the band identify reports
# from the simulated recording.  "rigid": recorded on the very model the prediction is computed on (the rigid
# body of [axis] mass in the holding loop, the axis's encoder): a check of the expected-coherence formula and
# its use of identify's band rule.  "truth": the known-truth axis itself (mass 20 % off the spec's, a
# structural mode): what a user gets.  The coarse axis is C's limits and encoder with a 300 Hz motor-side
# mode, the target 1.5 x 300 Hz from [evidence] first_mode_hz.  Figures: docs/interface.md §10.
COARSE_300 = ({**LOOP_AXES[next(k for k in LOOP_AXES if k.startswith("C"))][0], "evidence": {"first_mode_hz": 300.0}},
              {**LOOP_AXES[next(k for k in LOOP_AXES if k.startswith("C"))][1], "mode_hz": 300.0})


@pytest.mark.parametrize("name, model", [("A", "rigid"), ("C", "rigid"), ("coarse", "truth")])
def test_predicted_band_agrees_with_identify_on_known_truth(tmp_path, name, model):
    from commission.identification import identify_log
    from commission.synth import AxisTruth, write_log_h5

    spec_d, truth_d = COARSE_300 if name == "coarse" else next(v for k, v in LOOP_AXES.items() if k.startswith(name))
    toml = "".join(f"[{sec}]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in kv.items()) for sec, kv in spec_d.items())
    plan_dir = tmp_path / "run"
    r = runner.invoke(app, ["excite", "--spec", str(_spec_file(tmp_path, toml)), "--out-dir", str(plan_dir)],
                      env={"COLUMNS": "400"})
    assert r.exit_code == 0, r.output
    pred = json.loads((plan_dir / "plan.json").read_text())["predicted_band"]
    top = pred["band_hz"][1]
    assert re.search(rf"predicted band the recording will back: [\d.]+ - {top:.4g} Hz", r.output), r.output
    assert not pred["encoder_step_assumed"] and not pred["encoder_noise_assumed"]
    plan = plan_run(excite_spec_from_mapping(spec_d))
    truth = AxisTruth(**truth_d)
    if model == "rigid":
        truth = dataclasses.replace(truth, M=pred["mass"], B=spec_d["axis"].get("viscous", 0.0), mode_hz=0.0,
                                    mode2_hz=0.0, delay=0.0)
    write_log_h5(plan_dir / "log.h5", simulate_plan(plan, truth, np.random.default_rng(1)), u_unit=truth.u_unit)
    fr = identify_log(str(plan_dir / "log.h5"), u_unit=truth.u_unit).ident.to_dict()["frequency_response"]
    band, rigid = fr["evidence_band_hz"], fr["band_hz"]
    print(f"predicted band, {name} ({model}): {top:g} Hz; identify's {band} Hz: {100 * (top / band[1] - 1):+.1f} %; "
          f"its rigid band {rigid} Hz: {100 * (top / rigid[1] - 1):+.1f} %")
    if model == "rigid":
        assert top == pytest.approx(band[1], rel=0.20)
    else:
        # The prediction is the rigid body's band: the band where the data back the rigid model.  The
        # axis's motor-side mode raises the motor's response above the rigid body's, so identify's fitted
        # model is backed further (the coarse axis: to its 300 Hz resonance): the prediction is a floor.
        assert top == pytest.approx(rigid[1], rel=0.20) and top <= band[1]
    if name == "coarse":
        # short of 1.5 x 300 Hz: warned, naming the frequency reached and the remedies with figures
        assert pred["short"] and pred["target_hz"] == pytest.approx(450.0)
        line = next(ln for ln in r.output.splitlines() if ln.startswith("warning:"))
        assert f"up to {top:.4g} Hz, short of 450 Hz (1.5 x evidence.first_mode_hz)" in line, line
        assert re.search(r"an injection [\d.]+ times larger \([\d.]+ V: a_max >= [\d.]+ m/s\^2", line), line
        assert re.search(r"an encoder floor [\d.]+ times lower \(step [\d.e-]+ m, noise [\d.e-]+ m rms\)", line), line
        assert "longer injection" in line
        rem = pred["remedies"]
        assert rem["injection_amplitude_factor"] > 1 and rem["encoder_floor_factor"] < 1
        # the remedies reach the target by the same computation (its rule, not a copy of it)
        from commission.excite import predict_band

        s = plan.spec
        finer = dataclasses.replace(plan, spec=dataclasses.replace(s, encoder_step=rem["encoder_step"] * 0.99,
                                                                   encoder_noise=rem["encoder_noise"] * 0.99))
        assert predict_band(finer).top_hz >= 450.0 - pred["resolution_hz"]
    else:
        assert not pred["short"] and pred["target_hz"] is None and "warning:" not in r.output


def test_predicted_band_ends_with_the_injections_band():
    """Above a multisine's band the command is the holding loop's answer to the encoder noise: coherent with
    q (u = -C q) but not the plant.  The position there is at the encoder's floor, so identify's estimate
    gives those bins coherence 0 (they measure nothing of the plant) and the band ends with the injection's;
    so does the prediction."""
    spec_d = json.loads(json.dumps(LOOP_AXES[next(k for k in LOOP_AXES if k.startswith("A"))][0]))
    spec_d["plan"] = {"injection": "multisine", "band_hz": [2.0, 300.0]}
    pr = plan_run(excite_spec_from_mapping(spec_d)).prediction
    assert 280.0 <= pr.band_hz[1] <= 300.0, pr.band_hz
    above = pr.f_hz > 400.0
    assert np.all(pr.coherence[above] == 0.0)  # the loop's answer to the noise: coherent, but not a measurement
    assert pr.encoder_step == 0.1e-6 and pr.encoder_noise == 0.2e-6
