"""``commission run LOG --out-dir DIR``: identify, tune and validate in one command.

Also the independent closed-loop check of a deployed controller.json: the
controller is tuned from the log of an axis the repository does not contain
(:func:`commission.synth.rigid_random_axis`), loaded with
:func:`commission.runtime.load_controller`, and run against the TRUE axis in a
plain Python loop around the plant kernel -- none of the project's simulator,
scenario or metrics code is involved in that loop.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.controllers.plant import plant_advance
from commission.jsonio import read_json, sha256_file
from commission.runtime import load_controller
from commission.scenarios import case1_trajectory, case2_trajectory
from commission.spec import load_spec
from commission.synth import ExcitationPlan, rigid_random_axis, simulate_excitation, write_log_h5
from commission.pipeline import run_all
from commission.synth import AxisTruth
from commission.true_axis import Feedforward, judge_gains
from commission.tuning import Tuning
from commission.validate import FIGURE_NAMES

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5"
OUTPUTS = ("ident.json", "tuning.json", "validation.json", "report.md", "controller.json", *FIGURE_NAMES)

runner = CliRunner()
#: spec.toml stating the machine's lowest structural mode (commission/evidence.py): for the rigid
#: simulated axes of these tests, whose logs hold no broadband segment.
STATED_MODE = "[evidence]\nfirst_mode_hz = 5000.0\n"


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.mark.slow
def test_run_on_the_sample_log_leaves_every_file_and_says_its_verdict(tmp_path):
    """The sample (an excite plan recorded on a two-mass axis with delay, sample_data/truth.json) goes
    through the whole pipeline and every file is left with the verdict said plainly.  Since issue 30
    the gate judges the ARC against the margin-floored PID yardstick, over the whole payload box and
    within the evidence; the sample passes it, and what is emitted works on the sample's TRUE axis
    (truth.json, which the pipeline never reads): stable, c_u <= 1, below a PID calibrated on that axis,
    nominal and with one more sample of delay.  controller.json carries the provenance chain and loads."""
    out = tmp_path / "axis"
    r = invoke("run", SAMPLE, "--out-dir", out)
    assert r.exit_code == 0, r.output
    for f in OUTPUTS:
        assert (out / f).is_file(), f
    assert "robustness PASSED" in r.output
    assert "gate PASSED" in r.output and not (out / "controller_not_better.json").exists()
    # judged on the true axis, against a PID calibrated there
    truth_doc = json.loads((SAMPLE.parent / "truth.json").read_text())
    truth = AxisTruth.from_dict(truth_doc["axis"] if "axis" in truth_doc else truth_doc)
    tuning = Tuning.load(str(out / "tuning.json"))
    judged = judge_gains(truth, load_controller(out / "controller.json").config.gains, tuning.spec, emitted=True,
                         verdict="emitted", feedforward=Feedforward.identified(tuning.identification))
    pid = {(p.case, p.extra_delay): p for p in judged.pid.runs}
    for a in judged.arc_runs:
        p = pid[(a.case, a.extra_delay)]
        assert not a.diverged and a.c_u <= 1.0, a
        assert not p.diverged and a.e_rms < p.e_rms, (a, p)
    # the default ripple search finds the sample's 30-mm ripple, and with it the fit resolves the Stribeck
    # rise the ripple hid on the slow legs (fs 0.12 V, truth.json): validate's <case>/nominal then predicts
    # the emitted ARC on the true axis to within 3 % (with the ripple left out, Case 1 predicted 0.95 um for 3.1)
    fs = read_json(out / "ident.json")["parameters"]["fs"]
    assert fs is not None and fs["value"] == pytest.approx(truth_doc["axis"]["parameters"]["fs"]["value"], rel=0.02)
    predicted = {r["name"]: r["arc"]["e_rms"] for r in read_json(out / "validation.json")["runs"]}
    true_arc = {a.case: a.e_rms for a in judged.arc_runs if a.extra_delay == 0}
    assert set(true_arc) == {"case1", "case2"}
    for case, e_true in true_arc.items():
        assert predicted[f"{case}/nominal"] == pytest.approx(e_true, rel=0.03), case
        assert f"{case}/stribeck" not in predicted  # only for a rise the log did not resolve
    for name in ["controller.json"]:
        ctrl = read_json(out / name)
        assert ctrl["provenance"]["log_sha256"] == sha256_file(SAMPLE)
        assert ctrl["provenance"]["ident_sha256"] == sha256_file(out / "ident.json")
        assert ctrl["provenance"]["tuning_sha256"] == sha256_file(out / "tuning.json")
        load_controller(out / name)
        assert ctrl["sample_rate"] == 2500.0 and ctrl["control_law"]["paper"].startswith("Xu L., Yao B. (2001)")
    assert read_json(out / "tuning.json")["provenance"]["ident_sha256"] == sha256_file(out / "ident.json")
    # both loops' stability margins, per plant, in validation.json and tuning.json, and in the report
    val = read_json(out / "validation.json")["margins"]
    assert {r["controller"] for r in val["loops"]} == {"arc", "pid"} and len(val["loops"]) == 15
    assert val["worst"]["pid"]["delay_margin_samples"] > 0 and val["floors"]["modulus_margin"] == 0.5
    assert len(read_json(out / "tuning.json")["margins"]) == 15
    report = (out / "report.md").read_text()
    assert "## Stability margins" in report and "![loops.png](loops.png)" in report
    assert report.count("| nominal | ") == 3
    # the identification section with identify's own figures (written beside the report), and the reading aids
    assert "## Identification" in report and "| M (mass) | " in report and "V·s²/m |" in report
    for name in ("force_fit.png", "friction_curve.png", "residuals.png"):
        assert (out / name).is_file() and f"![{name}]({name})" in report
    assert "## Reading the results" in report and "**Parameter estimates.**" in report


def test_run_refuses_bad_input_before_writing(tmp_path):
    out = tmp_path / "axis"
    spec = tmp_path / "spec.toml"
    spec.write_text("[controller]\nsample_rate = -5\n")
    r = invoke("run", SAMPLE, "--out-dir", out, "--spec", spec)
    assert r.exit_code == 2 and "controller.sample_rate" in r.output and "Traceback" not in r.output
    gate = tmp_path / "gate.toml"
    gate.write_text("[gate]\ne_F = 0\n")
    r = invoke("run", SAMPLE, "--out-dir", out, "--gate", gate)
    assert r.exit_code == 2 and "gate.e_F = 0" in r.output
    r = invoke("run", tmp_path / "none.h5", "--out-dir", out)
    assert r.exit_code == 2 and "none.h5" in r.output
    r = invoke("run", SAMPLE, "--out-dir", out, "--map", "q=nonexistent")
    assert r.exit_code == 2 and "nonexistent" in r.output
    assert not out.exists()
    out.mkdir()
    (out / "ident.json").write_text("{}")
    r = invoke("run", SAMPLE, "--out-dir", out)
    assert r.exit_code == 2 and "ident.json: exists; pass --force" in r.output
    assert [p.name for p in out.iterdir()] == ["ident.json"]


class _Stop(Exception):
    pass


def test_run_tunes_the_same_inputs_as_identify_then_tune(tmp_path, monkeypatch):
    """``run`` and ``identify`` -> ``tune`` hand tune the same inputs: notes, seed, and which defaults it may move.

    (``run`` used to leave ``observer_free`` False, so its hold-out repair could never move a
    defaulted observer pole where ``tune``'s could.)  The tuning itself is stopped at its start.
    identify's clock is frozen: ident.json's sha256 covers its ``created_utc``, and the two
    identifications may fall in different seconds on a loaded machine.
    """
    import datetime
    from types import SimpleNamespace

    from commission.identification import record as identification_record
    from commission import tune as tune_mod

    class _Frozen(datetime.datetime):
        @classmethod
        def now(cls, tz=None):
            return datetime.datetime(2026, 1, 1, tzinfo=datetime.timezone.utc)

    monkeypatch.setattr(identification_record, "_dt", SimpleNamespace(datetime=_Frozen, timezone=datetime.timezone))

    seen = []

    def capture(inp, **_):
        seen.append(inp)
        raise _Stop

    monkeypatch.setattr(tune_mod, "tune_from", capture)
    spec = tmp_path / "spec.toml"
    spec.write_text("[targets]\ne_rms = 4e-6\n")
    with pytest.raises(_Stop):
        run_all(SAMPLE, tmp_path / "run", spec_path=spec, seed=3)
    r = invoke("identify", SAMPLE, "--out", tmp_path / "ident.json")
    assert r.exit_code == 0, r.output
    expected = tune_mod.load_tune_inputs(tmp_path / "ident.json", spec_path=spec, seed=3)
    (got,) = seen
    assert got.observer_free and got.pid_free  # neither pole is in the spec
    for field in ("spec", "ident_sha256", "log_sha256", "seed", "notes", "observer_free", "pid_free"):
        assert getattr(got, field) == getattr(expected, field), field
    assert got.ident.to_dict() | {"created_utc": None} == expected.ident.to_dict() | {"created_utc": None}
    assert not (tmp_path / "run").exists()  # nothing written when tuning does not complete


def true_axis_loop(ctrl, truth, traj, rng, substeps=10):
    """Closed loop of the loaded controller on the true axis, in plain Python.

    Encoder: round((x + n) / lsb) * lsb with the axis's noise; zero-order hold
    over ``substeps`` sub-steps; the drive clips at the axis's rail.
    Returns the measured error y - q_d (m) and the commands (u-unit).
    """
    p = truth.plant()
    Ts = ctrl.sample_period
    h = Ts / substeps
    n = traj.qd.shape[0]
    noise = rng.normal(0.0, truth.noise_std, n) if truth.noise_std > 0 else np.zeros(n)
    x, v = float(traj.qd[0]), 0.0
    e = np.empty(n)
    u = np.empty(n)
    for k in range(n):
        y = round((x + noise[k]) / truth.lsb) * truth.lsb
        if k == 0:
            ctrl.reset(y)
        c = ctrl.step(y, traj.qd[k], traj.dqd[k], traj.ddqd[k])
        c = min(max(c, -truth.u_max), truth.u_max)
        e[k], u[k] = y - traj.qd[k], c
        x, v = plant_advance(p, x, v, c, h, substeps)
    return e, u


@pytest.mark.slow
def test_controller_from_an_unseen_axis_tracks_the_true_axis_within_the_claimed_gate(tmp_path):
    rng = np.random.default_rng(20240611)
    truth = rigid_random_axis(rng, sample_rate=2500.0)
    log = tmp_path / "unseen_axis.h5"
    write_log_h5(log, simulate_excitation(truth, ExcitationPlan(), rng), q_unit="m", u_unit="V")
    # Default tuning budget: the controller is the one a user would get (a
    # 16-candidate search was too small to pass the gate on this axis).
    spec = tmp_path / "spec.toml"
    spec.write_text(STATED_MODE)  # the axis is rigid: no mode below 5 kHz is the truth
    out = tmp_path / "axis"
    r = invoke("run", log, "--out-dir", out, "--spec", spec, "--monte-carlo", 16)
    assert r.exit_code in (0, 1), r.output
    # controller.json when the whole gate passed; since issue 30, the ARC left deployable but flagged when
    # only the comparison with the PID yardstick failed: either must hold on the true axis what it claims
    name = "controller.json" if r.exit_code == 0 else "controller_not_better.json"
    if not (out / name).exists():
        pytest.xfail("issue 30 open: the gate refused this axis outright, nothing deployable to judge")
    doc = read_json(out / name)
    gate = doc["validated"]["gate"]
    predicted = doc["validated"]["nominal"]  # the ARC on the identified model
    ctrl = load_controller(out / name)
    s = load_spec(spec)
    for case, tr in (("case1", case1_trajectory(s)), ("case2", case2_trajectory(s))):
        traj = tr.render(ctrl.sample_period, 0.0)
        e, u = true_axis_loop(ctrl, truth, traj, np.random.default_rng(7))
        t = np.arange(e.size) * ctrl.sample_period
        e_M = np.max(np.abs(e))
        e_F = np.max(np.abs(e[t >= t[-1] - 2.0]))
        e_rms = np.sqrt(np.mean(e ** 2))
        assert e_M <= gate["e_M"], (case, e_M, gate["e_M"])
        assert e_F <= gate["e_F"], (case, e_F, gate["e_F"])
        assert e_rms <= gate["e_rms"], (case, e_rms, gate["e_rms"])
        assert np.max(np.abs(u)) < gate["u_max"]
        # and close to what validate predicted on the identified model (within 2x, plus one encoder step)
        assert e_rms <= 2.0 * predicted[case]["e_rms"] + truth.lsb, (case, e_rms, predicted[case]["e_rms"])
        # the axis really moved along the trajectory: the error is far below the motion itself
        assert e_rms < 1e-3 * np.ptp(traj.qd)


@pytest.mark.slow  # a whole run (identify, a short tune, validate)
def test_run_takes_a_folder_of_logs_of_one_axis_as_segments(tmp_path):
    """`commission run FOLDER`: the logs are fitted together, each its own segment, as identify does."""
    import json as _json

    from commission.synth import AxisTruth, ExcitationPlan, simulate_excitation, write_log_h5

    truth = AxisTruth(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, lsb=1e-6, sample_rate=2500.0)
    plan = ExcitationPlan(n_speeds=5, ms_duration=6.0, leg_max_time=0.8, injection_s=3.0)
    logs = tmp_path / "logs"
    logs.mkdir()
    for k in (1, 2):
        write_log_h5(logs / f"part{k}.h5", simulate_excitation(truth, plan, np.random.default_rng(k)))
    (tmp_path / "spec.toml").write_text("[tune]\nbudget = 8\n")
    r = invoke("run", logs, "--out-dir", tmp_path / "out", "--spec", tmp_path / "spec.toml")
    assert r.exit_code in (0, 1), r.output  # the short search may not pass the gate; never bad input
    doc = _json.loads((tmp_path / "out" / "ident.json").read_text())
    assert [Path(p).name for p in doc["source"]["path"]] == ["part1.h5", "part2.h5"]
    assert len(doc["model"]["segments"]) == 2
    assert doc["parameters"]["M"]["value"] == pytest.approx(0.027, rel=0.05)
