"""The tuning spec: documented defaults, and bad specs rejected before any simulation (exit 2, one line)."""

from __future__ import annotations

import json
import math
import re

import pytest
from typer.testing import CliRunner

from commission.tune.api import resolve_spec
from commission.tune.defaults import check_spec_against_ident, drive_need
from commission.tune.settings import DEFAULT_SETTINGS
from commission.artifacts import Estimate, Identification, ThetaBox
from commission.cli.main import app
from commission.errors import InputFileError, SpecError
from commission.spec import MAX_OMEGA_T, default_spec, load_spec, nominal_rate, spec_from_mapping

runner = CliRunner()


def ref_ident_doc() -> dict:
    """The CONTRACT §5 reference plant as an ident.json document (constructed, not identified)."""
    ident = Identification(
        units={"u": "V", "q": "m"},
        parameters={k: Estimate(v, 0.0) for k, v in
                    dict(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.0).items()},
        relative_error=0.0, condition_number=1.0, validation_relative_error=None,
        theta=ThetaBox((37.0, 10.1, 0.0), (8.3, 2.4, -50.0), (50.0, 17.5, 50.0)),
        delta_d=0.5 / 0.027, fric_level=0.1, fric_slope=900.0)
    return ident.to_dict()


def test_defaults_are_the_papers_setting():
    s = default_spec()
    assert s.sample_rate == 2500.0
    assert s.observer_pole == pytest.approx(200.0)  # paper: all observer roots at -200
    assert s.pid_pole == pytest.approx(300.0)  # paper: PID poles at -300
    assert (s.v_max, s.a_max, s.travel, s.dwell, s.moves) == (1.0, 12.0, 0.4, 0.5, 6)
    assert (s.beta1, s.beta2) == (100.0, 2500.0)
    assert s.u_max == 10.0 and s.quantization is None
    # an empty file gives the same spec, and the spec round-trips through its TOML layout
    assert spec_from_mapping({}) == s
    assert spec_from_mapping(s.to_dict()) == s


def test_derived_defaults_follow_the_sample_rate():
    s = spec_from_mapping({"controller": {"sample_rate": 5000}})
    assert s.observer_pole == pytest.approx(400.0) and s.pid_pole == pytest.approx(600.0)
    s2 = spec_from_mapping({}, sample_rate_default=1000.0)
    assert s2.sample_rate == 1000.0 and s2.observer_pole == pytest.approx(80.0)


@pytest.mark.parametrize("measured, nominal", [
    (2500.0000000058267, 2500.0),  # the sample log's rate as estimated from its time stamps
    (1000.0000001, 1000.0),
    (5000.02, 5000.0),             # 4 ppm: within a crystal's tolerance
    (5000.2, 5000.2),              # 40 ppm: a different rate, kept
    (2499.7, 2499.7),
    (4166.666667, 4166.666667),    # no round number of 4 digits explains it
])
def test_a_log_rate_within_jitter_of_a_round_rate_gives_the_round_rate(measured, nominal):
    assert nominal_rate(measured) == nominal
    # tune simulates the rate measured (controller.json states the nominal one)
    assert spec_from_mapping({}, sample_rate_default=measured).sample_rate == measured


def test_controller_json_states_the_round_rate_only_for_rounding_in_the_estimate():
    assert nominal_rate(2500.0000000058267, rel=1e-10) == 2500.0  # the sample log's estimated rate
    assert nominal_rate(5000.02, rel=1e-10) == 5000.02  # 4 ppm: a real difference, stated as validated


@pytest.mark.parametrize("data, match", [
    ({"controler": {"sample_rate": 2500.0}}, r"^spec\.toml: controler: unknown section"),
    ({"controller": {"sampel_rate": 2500.0}}, r"^spec\.toml: controller\.sampel_rate: unknown key"),
    ({"controller": {"sample_rate": -2500.0}}, r"^spec\.toml: controller\.sample_rate = -2500.0 Hz must be positive"),
    ({"controller": {"sample_rate": 0}}, r"controller\.sample_rate = 0.0 Hz must be positive"),
    ({"trajectory": {"v_max": -1.0}}, r"trajectory\.v_max = -1.0 m/s must be positive"),
    ({"trajectory": {"dwell": -0.1}}, r"trajectory\.dwell = -0.1 s must not be negative"),
    ({"trajectory": {"moves": 2.5}}, r"trajectory\.moves = 2.5: expected an integer"),
    ({"targets": {"c_u": "low"}}, r"targets\.c_u = 'low': expected a finite number"),
    ({"controller": {"sample_rate": 100.0, "observer_pole": 200.0}},
     r"controller\.sample_rate = 100 Hz is too low for observer poles at -200 rad/s \(need >= 400 Hz"),
    ({"controller": {"sample_rate": 500.0}, "pid": {"pole": 300.0}},
     r"controller\.sample_rate = 500 Hz is too low for PID poles at -300 rad/s \(need >= 600 Hz"),
    ({"controller": {"sample_rate": 90.0}},
     r"controller\.sample_rate = 90 Hz is too low for reference filter \(58\) poles at -50 rad/s"),
    ({"trajectory": {"v_max": 3.0, "a_max": 12.0, "travel": 0.4}}, r"trajectory\.v_max = 3 m/s cannot be reached"),
])
def test_bad_specs_name_the_key(data, match):
    with pytest.raises(SpecError, match=match):
        spec_from_mapping(data, "spec.toml")


def test_bandwidth_rule_boundary():
    # omega T = MAX_OMEGA_T exactly is accepted, just above it is not.
    fs = 200.0 / MAX_OMEGA_T
    assert spec_from_mapping({"controller": {"sample_rate": fs, "observer_pole": 200.0}}).sample_rate == fs
    with pytest.raises(SpecError, match="too low"):
        spec_from_mapping({"controller": {"sample_rate": fs * 0.999, "observer_pole": 200.0}})


def test_log_rate_default_is_named_in_the_error():
    with pytest.raises(SpecError, match=r"sample_rate = 300 Hz \(default: the log's rate\) is too low"):
        spec_from_mapping({"controller": {"observer_pole": 200.0}}, sample_rate_default=300.0)


def test_load_spec_files(tmp_path):
    p = tmp_path / "spec.toml"
    p.write_text("[controller]\nsample_rate = 4000\n[targets]\ne_f = 2e-5\n")
    s = load_spec(p)
    assert s.sample_rate == 4000.0 and s.e_f == 2e-5 and s.observer_pole == pytest.approx(320.0)
    (tmp_path / "broken.toml").write_text("[controller\n")
    with pytest.raises(SpecError, match="broken.toml: not valid TOML"):
        load_spec(tmp_path / "broken.toml")
    with pytest.raises(InputFileError, match="missing.toml: no such file"):
        load_spec(tmp_path / "missing.toml")
    assert load_spec(None) == default_spec()


# --------------------------------------------------------------------------- CLI: exit 2, one line, nothing run


@pytest.fixture()
def no_simulation(monkeypatch):
    """Fail the test if the tuning pipeline gets as far as simulating anything."""
    calls = []

    def boom(*a, **k):  # pragma: no cover - only runs when the check is broken
        calls.append(1)
        raise AssertionError("a simulation ran before the spec was rejected")

    monkeypatch.setattr("commission.tune.api.tune", boom)
    monkeypatch.setattr("commission.tune.objective.simulate_batch", boom)
    return calls


@pytest.mark.parametrize("toml, key, words", [
    ("[controller]\nsampel_rate = 2500\n", "controller.sampel_rate", "unknown key"),
    ("[controller]\nsample_rate = -2500\n", "controller.sample_rate", "must be positive"),
    ("[controller]\nsample_rate = 100\nobserver_pole = 200.0\n", "controller.sample_rate", "too low for observer poles"),
    ("[controller]\nu_max = 0.5\n", "controller.u_max", "is too small for this theta box"),
    ("[controller]\nu_max = 2.5\n[trajectory]\na_max = 12.0\n", "trajectory.a_max = 12", "is below the"),
])
def test_cli_rejects_bad_spec_before_simulating(tmp_path, no_simulation, toml, key, words):
    ident = tmp_path / "ident.json"
    ident.write_text(json.dumps(ref_ident_doc()))
    spec = tmp_path / "spec.toml"
    spec.write_text(toml)
    out = tmp_path / "tuning.json"
    r = runner.invoke(app, ["tune", str(ident), "--out", str(out), "--spec", str(spec)])
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1, r.output  # one line, no traceback, no progress bar
    assert lines[0].startswith("error: ") and str(spec) in lines[0]
    assert key in lines[0] and words in lines[0]
    assert not out.exists()
    assert no_simulation == []


def test_cli_rejects_negative_seed_and_missing_ident(tmp_path, no_simulation):
    r = runner.invoke(app, ["tune", str(tmp_path / "nope.json"), "--out", str(tmp_path / "t.json")])
    assert r.exit_code == 2 and "nope.json: no such file" in r.output
    ident = tmp_path / "ident.json"
    ident.write_text(json.dumps(ref_ident_doc()))
    r = runner.invoke(app, ["tune", str(ident), "--out", str(tmp_path / "t.json"), "--seed", "-1"])
    assert r.exit_code == 2 and "--seed" in r.output


def _resolved(spec_data, name, ident):
    rs = resolve_spec(spec_data, name, ident)
    assert rs.ident is ident  # the paper's box fits these drives: never narrowed
    return rs.spec, rs.notes


def test_u_max_check_uses_the_most_demanding_plant():
    # Paper box: M_heavy = 1/8.3; Case 1 starts at q_dd(0) = beta1 * 0.2 v_max = 20 m/s^2 (> a_max = 12);
    # B = max(theta2_max / theta1_max = 0.35, 1.2 * 0.273); friction 1.2 * 0.12; force max(50/50, 0 + 0.5).
    ident = Identification.from_dict(ref_ident_doc())
    need = 20.0 / 8.3 + 0.35 * 1.0 + 1.2 * 0.12 + 1.0
    d = drive_need(ident)
    assert d.need(1.0, 12.0, 100.0) == pytest.approx(need, rel=1e-12)
    check_spec_against_ident(spec_from_mapping({"controller": {"u_max": need * 1.001}}), ident)
    # Case 1's start-up (20 m/s^2) exceeds any a_max the limit leaves: the hint must lower v_max too,
    # and following it must pass.
    with pytest.raises(SpecError, match=r"controller\.u_max = 3\.8 V is below .*trajectory\.a_max = 12 .*"
                                        r"set trajectory\.v_max <= ([0-9.]+) m/s with trajectory\.a_max <= ") as exc:
        check_spec_against_ident(spec_from_mapping({"controller": {"u_max": 3.8}}), ident)
    m = re.search(r"v_max <= ([0-9.e-]+) m/s with trajectory\.a_max <= ([0-9.e-]+) m/s\^2", str(exc.value))
    check_spec_against_ident(spec_from_mapping(
        {"controller": {"u_max": 3.8}, "trajectory": {"v_max": float(m.group(1)), "a_max": float(m.group(2))}}), ident)
    assert math.isclose(need, 3.9036, rel_tol=1e-4)


def test_defaulted_envelope_is_lowered_to_the_drive_and_set_keys_are_kept():
    doc = ref_ident_doc()
    ident = Identification.from_dict(doc)
    # the paper's setting fits a 10 V drive: nothing changes
    spec, notes = _resolved({}, "spec (defaults)", ident)
    assert (spec.v_max, spec.a_max, notes) == (1.0, 12.0, ())
    # a 3 V drive: the defaulted a_max (and v_max) are lowered so that the worst plant needs <= 0.7 u_max
    spec, notes = _resolved({"controller": {"u_max": 3.0}}, "s.toml", ident)
    d = drive_need(ident)
    assert spec.a_max < 12.0 and spec.v_max < 1.0 and len(notes) == 2
    assert d.need(spec.v_max, spec.a_max, spec.beta1) <= DEFAULT_SETTINGS.drive_headroom * 3.0 * (1 + 1e-12)
    assert spec.v_max ** 2 / spec.a_max <= spec.travel
    assert all(n.startswith("trajectory.") and "instead of" in n for n in notes)
    # a key the user set is never changed: the check names it instead
    with pytest.raises(SpecError, match=r"s\.toml: controller\.u_max = 3 V is below .* trajectory\.a_max = 12 "):
        resolve_spec({"controller": {"u_max": 3.0}, "trajectory": {"a_max": 12.0, "v_max": 1.0}},
                              "s.toml", ident)
    # a drive that cannot even hold the box's forces with headroom is refused, naming u_max
    with pytest.raises(SpecError, match=r"s\.toml: controller\.u_max = 1\.5 V is too small for this theta box"):
        resolve_spec({"controller": {"u_max": 1.5}}, "s.toml", ident)


def test_defaulted_load_bound_is_narrowed_to_the_drive_and_a_given_one_is_not():
    # The paper's box on a 2 V drive: friction (+20 %) 0.144 V plus the box's 1 V load force leave no room
    # for even the smallest default envelope (0.1 m/s, 1 m/s^2: 0.28 V of 1.4 V) at its default.
    doc = ref_ident_doc()
    doc["bounds"] = {"disturbance_bound": 1.2, "disturbance_bound_defaulted": True}
    ident = Identification.from_dict(doc)
    rs = resolve_spec({"controller": {"u_max": 2.0}}, "s.toml", ident)
    budget = DEFAULT_SETTINGS.drive_headroom * 2.0
    # closed form: the load force may take the settings' disturbance_share of the budget minus the friction,
    # about d_n = 0,
    # and theta3 binds at the lightest mass 1/50
    reach = DEFAULT_SETTINGS.disturbance_share * budget - 1.2 * 0.12
    assert rs.ident.theta.min[2] == pytest.approx(-reach * 50.0, rel=1e-12)
    assert rs.ident.theta.max[2] == pytest.approx(reach * 50.0, rel=1e-12)
    assert rs.ident.theta.min[:2] == ident.theta.min[:2] and rs.ident.theta.max[:2] == ident.theta.max[:2]
    assert drive_need(rs.ident).const == pytest.approx(DEFAULT_SETTINGS.disturbance_share * budget, rel=1e-12)
    assert rs.ident.extra["bounds"]["narrowed_by_tune"]["theta3_max"] == 50.0
    assert drive_need(rs.ident).need(rs.spec.v_max, rs.spec.a_max, rs.spec.beta1) <= budget * (1 + 1e-12)
    assert rs.notes[0].startswith("theta3 box narrowed from [-50, 50] to [-27.8, 27.8] m/s^2")
    # plus v_max and a_max lowered (and the budget, which the slower envelope shrinks: see test_tune_artifact)
    assert "--disturbance-bound" in rs.notes[0] and len([n for n in rs.notes if "tune.budget" not in n]) == 3
    # the narrowed identification round-trips through tuning.json's copy
    assert Identification.from_dict(json.loads(json.dumps(rs.ident.to_dict()))).theta == rs.ident.theta
    # a bound the user gave is never narrowed: refused as before, naming u_max
    doc["bounds"]["disturbance_bound_defaulted"] = False
    with pytest.raises(SpecError, match=r"s\.toml: controller\.u_max = 2 V is too small for this theta box"):
        resolve_spec({"controller": {"u_max": 2.0}}, "s.toml", Identification.from_dict(doc))
    # nor is one that fits the drive at its default
    doc["bounds"]["disturbance_bound_defaulted"] = True
    assert resolve_spec({}, "s.toml", Identification.from_dict(doc)).notes == ()
    # friction above the share (0.6 V of 1.4 V): the share rule declines, and the range is narrowed to the
    # load step delta_d M about d_n instead of a refusal (issue 30, commission.tune.box.fit_force_to_drive)
    doc["parameters"]["fs"]["value"] = 0.5
    idn = Identification.from_dict(doc)
    rs = resolve_spec({"controller": {"u_max": 2.0}}, "s.toml", idn)
    step = idn.delta_d * idn.value("M")
    assert rs.ident.theta.max[2] == pytest.approx(step * 50.0, rel=1e-12)  # theta3 binds at the lightest mass
    assert "certified for that load range only" in rs.notes[0]
    assert drive_need(rs.ident).need(rs.spec.v_max, rs.spec.a_max, rs.spec.beta1) <= budget * (1 + 1e-12)
    # friction alone above the budget: still refused, naming u_max
    doc["parameters"]["fs"]["value"] = 1.2
    with pytest.raises(SpecError, match=r"controller\.u_max = 2 V is too small"):
        resolve_spec({"controller": {"u_max": 2.0}}, "s.toml", Identification.from_dict(doc))


def _suggested_u_max(exc: SpecError) -> float:
    m = re.search(r"controller\.u_max >= ([0-9.e+]+) V, only if the drive really has it", str(exc))
    assert m, str(exc)
    return float(m.group(1))


def test_a_drive_too_small_is_refused_with_each_term_and_the_u_max_that_does_hold_the_least_box():
    """The refusal's advice, followed, passes: the ``controller.u_max`` it names is accepted for the same
    log and spec, 3 % less is refused (known truth: the reference plant with its friction raised)."""
    doc = ref_ident_doc()
    doc["bounds"] = {"disturbance_bound": 1.2, "disturbance_bound_defaulted": True}
    doc["parameters"]["fs"]["value"] = 1.2  # friction (+20 %) 1.44 V: more than 0.7 x 2 V at rest
    ident = Identification.from_dict(doc)
    with pytest.raises(SpecError) as err:
        resolve_spec({"controller": {"u_max": 2.0}}, "s.toml", ident)
    text = str(err.value)
    assert "friction +20 % 1.44 V" in text and "the default bound 10 max(fc, fs)" in text
    assert "M = 0.12 V·s^2/m" in text and "V·s/m" in text  # units on the box's mass and viscous terms
    assert "the load force cut to that load step, as the tool tries before refusing" in text
    assert "a log the identified model explains better" in text  # friction alone leaves no room
    assert "--payload-max" not in text and "a slower envelope" not in text  # neither would fit
    u_ok = _suggested_u_max(err.value)
    rs = resolve_spec({"controller": {"u_max": u_ok}}, "s.toml", ident)
    assert rs.spec.v_max > 0 and rs.spec.a_max > 0
    with pytest.raises(SpecError, match="is too small for this theta box"):
        resolve_spec({"controller": {"u_max": 0.97 * u_ok}}, "s.toml", ident)
    # a stated load-force bound the drive cannot hold: lowering it is offered, with a value that fits
    doc["parameters"]["fs"]["value"] = 0.12
    doc["bounds"] = {"disturbance_bound": 1.2, "disturbance_bound_defaulted": False}
    with pytest.raises(SpecError) as err:
        resolve_spec({"controller": {"u_max": 2.0}}, "s.toml", Identification.from_dict(doc))
    assert "the bound ident.json states, commission identify --disturbance-bound" in str(err.value)
    assert re.search(r"a lower load-force bound, commission identify --disturbance-bound [0-9.]+ \(V; now 1\.2\)",
                     str(err.value)), str(err.value)


def test_defaulted_envelope_scales_with_a_sample_rate_below_the_papers():
    ident = Identification.from_dict(ref_ident_doc())
    # 1 kHz is r = 0.4 of the paper's 2.5 kHz: v_max x r, a_max x r^2, each with a note
    spec, notes = _resolved({"controller": {"sample_rate": 1000.0}}, "s.toml", ident)
    assert spec.v_max == pytest.approx(0.4) and spec.a_max == pytest.approx(12.0 * 0.16)
    assert len(notes) == 2 and all("sample rate 1000 Hz is 0.4 x the paper's 2500 Hz" in n for n in notes)
    # a key the user set is kept; the other one still scales
    spec, notes = _resolved({"controller": {"sample_rate": 1000.0}, "trajectory": {"a_max": 3.0}},
                                        "s.toml", ident)
    assert (spec.v_max, spec.a_max) == (pytest.approx(0.4), 3.0) and len(notes) == 1
    # at and above the paper's rate nothing changes
    for fs in (2500.0, 5000.0):
        spec, notes = _resolved({"controller": {"sample_rate": fs}}, "s.toml", ident)
        assert (spec.v_max, spec.a_max, notes) == (1.0, 12.0, ())


def test_cli_prints_a_note_for_each_lowered_default(tmp_path, monkeypatch):
    # Stop right after the inputs are resolved: the note must be printed before any simulation.
    def stop(*a, **k):
        raise SystemExit(0)

    monkeypatch.setattr("commission.cli.tune_cmd.run_tune", stop)
    ident = tmp_path / "ident.json"
    ident.write_text(json.dumps(ref_ident_doc()))
    spec = tmp_path / "spec.toml"
    spec.write_text("[controller]\nu_max = 3.0\n")
    r = runner.invoke(app, ["tune", str(ident), "--out", str(tmp_path / "t.json"), "--spec", str(spec)])
    notes = [ln for ln in r.output.splitlines() if ln.startswith("note: ")]
    assert len(notes) == 2, r.output
    assert "trajectory.v_max defaulted to" in notes[0] and "trajectory.a_max defaulted to" in notes[1]
    assert not (tmp_path / "t.json").exists()
