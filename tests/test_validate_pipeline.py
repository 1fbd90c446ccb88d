"""``commission validate``: the scenario matrix with ARC and PID, the gate, the report and controller.json.

One short tuning (the paper's axis, CONTRACT §2 example, search budget 8) is
made once; the tests validate it, and deliberately broken copies of it.  Their
gate is set at 1.5x the worst values the good tuning reaches on the same
matrix (the documented defaults are exercised in test_validate_gate.py and on
the sample log in test_run_cli.py), so the broken copies must fail a gate
that the good tuning passes, whatever the tuning search currently finds.
"""

import copy
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from commission.formats.controller_json import CONTROLLER_FIELDS
from commission.formats.json_table import unnamed
from commission.formats.validation_json import VALIDATION_FIELDS, check_validation
from commission.cli.main import app
from commission.controllers.arc import arc_pack
from commission.controllers.simulate import KIND_ARC, simulate
from commission.jsonio import read_json, sha256_file, sha256_json, write_json_atomic
from commission.runtime import load_controller
from commission.scenarios import plant_substeps, scenario_matrix
from commission.tuning import Tuning
from commission.validate import FIGURE_NAMES, run_validate, validate
from reference_tuning import saved_reference_tuning

MC = 8
#: Margin of the test gate over the worst value the good tuning reached.
MARGIN = 1.5

runner = CliRunner()


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    d = tmp_path_factory.mktemp("tuning")
    t, path = saved_reference_tuning(d)
    # The gate of these tests: MARGIN x the worst value this (short, 8-candidate) tuning reaches
    # on the same matrix, so that the good tuning passes whatever the search finds, and the
    # broken copies below must fail a gate that the good one passes.
    r = validate(t, seed=0, n_monte_carlo=MC)
    runs = [x for x in r.runs if not x.arc.diverged]
    assert len(runs) == len(r.runs), "the good tuning diverged"
    worst = {k: max(getattr(x.arc, k) for x in runs) for k in ("e_F", "e_M", "e_rms", "c_u")}
    ratio = max(x.arc.e_rms / x.pid.e_rms for x in runs if not x.pid.diverged)
    gate = d / "gate.toml"
    gate.write_text("[gate]\n" + "".join(f"{k} = {MARGIN * v!r}\n" for k, v in worst.items())
                    + f"arc_vs_pid_e_rms = {max(1.0, MARGIN * ratio)!r}\n"
                    + f"arc_vs_pid_median = {max(1.0, MARGIN * ratio)!r}\narc_vs_pid_p90 = {max(1.2, MARGIN * ratio)!r}\n")
    return path, gate, worst


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_passing_validation_writes_report_figures_and_controller(tuned, tmp_path):
    tpath, gate, _ = tuned
    out = tmp_path / "val"
    r = invoke("validate", tpath, "--out-dir", out, "--gate", gate, "--monte-carlo", MC)
    assert r.exit_code == 0, r.output
    assert "gate PASSED" in r.output and "case2/payload_heavy" in r.output
    for name in ("report.md", "validation.json", "controller.json", *FIGURE_NAMES):
        assert (out / name).is_file(), name
    for name in FIGURE_NAMES:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    report = (out / "report.md").read_text()
    assert "**Gate: PASSED**" in report
    # one Table-1 block per case: a PID | ARC column pair per scenario, the paper's six rows
    assert report.count("| Controller | nominal PID | nominal ARC | payload_light PID |") == 2
    for row in ("| e_M (um) |", "| e_F (um) |", "| ‖e‖rms (um) |", "| ‖u‖rms (V) |", "| ‖Δu‖rms (V) |", "| c_u |"):
        assert report.count(row) >= 2, row
    for name in FIGURE_NAMES:
        assert f"]({name})" in report

    val = read_json(out / "validation.json")
    assert val["passed"] is True and len(val["runs"]) == 12 + 2 + MC and val["monte_carlo"] == MC
    # the file is its table's: it loads strictly and holds no key the table does not name
    assert check_validation(val) is val and unnamed(val, VALIDATION_FIELDS) == []
    tuning = Tuning.load(str(tpath))
    ctrl_doc = read_json(out / "controller.json")
    assert unnamed(ctrl_doc, CONTROLLER_FIELDS) == []  # every key controller.json holds is a row of its table
    prov = ctrl_doc["provenance"]
    assert prov["tuning_sha256"] == sha256_file(tpath)
    assert prov["ident_sha256"] == tuning.provenance.ident_sha256 and prov["log_sha256"] == "2" * 64
    assert ctrl_doc["validated"]["gate"] == val["gate"]
    assert ctrl_doc["validated"]["gate"]["e_rms"] == pytest.approx(MARGIN * tuned[2]["e_rms"])
    worst = ctrl_doc["validated"]["worst"]
    assert worst["e_rms"]["value"] <= worst["e_rms"]["limit"]
    assert worst["e_rms"]["value"] == max(run["arc"]["e_rms"] for run in val["runs"])

    # The emitted controller is the one simulated: replay case1/nominal bit for bit.
    ctrl = load_controller(out / "controller.json")
    scen = {s.name: s for s in scenario_matrix(tuning.identification, tuning.spec, rng=np.random.default_rng(0),
                                               n_monte_carlo=0)}["case1/nominal"]
    ref = scen.reference(tuning.arc.Ts)
    sim = simulate(scen.plant, KIND_ARC, arc_pack(tuning.arc), ref, substeps=plant_substeps(tuning.spec.sample_rate),
                   quant=scen.quantization, u_sat=tuning.spec.u_max, e_abort=tuning.spec.travel)
    ctrl.reset(sim.y[0])
    u = np.array([ctrl.step(sim.y[k], ref.qd[k], ref.dqd[k], ref.ddqd[k]) for k in range(ref.n)])
    assert np.array_equal(u, sim.u)
    run = next(x for x in val["runs"] if x["name"] == "case1/nominal")
    assert run["arc"]["u_peak"] == float(np.max(np.abs(sim.u)))
    assert run["arc"]["e_rms"] == pytest.approx(sim.indexes.e_rms, rel=1e-12)
    assert ctrl_doc["validated"]["nominal"]["case1"] == run["arc"]


def test_existing_output_needs_force_and_nothing_is_written(tuned, tmp_path):
    tpath, gate, _ = tuned
    out = tmp_path / "val"
    out.mkdir()
    (out / "controller.json").write_text("old")
    r = invoke("validate", tpath, "--out-dir", out, "--gate", gate, "--monte-carlo", 0)
    assert r.exit_code == 2
    assert "controller.json: exists; pass --force to overwrite" in r.output
    assert "Traceback" not in r.output
    assert sorted(p.name for p in out.iterdir()) == ["controller.json"]
    assert (out / "controller.json").read_text() == "old"


def test_failures_are_all_listed_and_no_controller_is_written(tuned, tmp_path):
    tpath, _, worst = tuned
    strict = tmp_path / "strict.toml"  # half the good tuning's worst e_rms and e_M: some runs must fail
    strict.write_text(f"[gate]\ne_rms = {worst['e_rms'] / 2!r}\ne_M = {worst['e_M'] / 2!r}\n")
    out = tmp_path / "val"
    out.mkdir()
    (out / "controller.json").write_text("stale")
    r = invoke("validate", tpath, "--out-dir", out, "--gate", strict, "--monte-carlo", MC, "--force")
    assert r.exit_code == 1, r.output
    assert not (out / "controller.json").exists()  # --force removed the stale one
    val = read_json(out / "validation.json")
    assert val["passed"] is False
    fails = val["failures"]
    assert {f["criterion"] for f in fails} >= {"e_rms", "e_M"}
    text = " ".join(r.output.split())  # undo the terminal's line wrapping
    report = (out / "report.md").read_text()
    assert f"gate FAILED: {len(fails)} of" in text
    for f in fails:
        line = f"{f['criterion']} {f['scenario']}: {f['detail']}"
        assert line in text, line
        assert f"- {line}" in report
    assert "**No `controller.json` was written.**" in report


def _broken(doc, how):
    d = copy.deepcopy(doc)
    arc = d["arc"]
    if how == "gains_x10":
        for k in ("g1", "g2", "k1s_max", "k2s_max"):
            arc[k] *= 10.0
    elif how == "gamma_x100":
        arc["Gamma"] = [g * 100.0 for g in arc["Gamma"]]
    elif how == "box_believes_heavier":  # theta1 = 1/M in [1, 3]: M in [0.33, 1], 12-37x the true 0.027
        arc["theta_min"][0], arc["theta_max"][0], arc["theta0"][0] = 1.0, 3.0, 2.0
    elif how == "box_believes_lighter":  # theta1 in [100, 300]: M in [0.0033, 0.01], 3-8x too light
        arc["theta_min"][0], arc["theta_max"][0], arc["theta0"][0] = 100.0, 300.0, 150.0
    return d


@pytest.mark.parametrize("how", ["gains_x10", "gamma_x100", "box_believes_heavier", "box_believes_lighter"])
def test_broken_tunings_fail_the_gate_the_good_one_passes(tuned, tmp_path, how):
    tpath, gate, _ = tuned
    bad = tmp_path / "tuning.json"
    write_json_atomic(bad, _broken(read_json(tpath), how))
    out = tmp_path / "val"
    o = run_validate(bad, out, gate_path=gate, n_monte_carlo=MC)
    assert not o.result.passed and o.controller is None
    assert not (out / "controller.json").exists()
    nominal = [c for c in o.result.verdict.failures if c.scenario.endswith("/nominal")]
    assert nominal, "the broken controller must fail on the identified plant itself"
    if how == "gains_x10":  # and through the CLI: exit 1
        r = invoke("validate", bad, "--out-dir", tmp_path / "cli", "--gate", gate, "--monte-carlo", 0)
        assert r.exit_code == 1 and not (tmp_path / "cli" / "controller.json").exists()


@pytest.mark.parametrize(
    "gate_text, match",
    [('[gate]\ne_F = -1\n', "gate.e_F = -1"), ('[gate]\ne_rms = "3 parsecs"\n', "gate.e_rms = '3 parsecs'"),
     ('[gate]\nspeed = 1\n', "gate.speed: unknown key"), ("[gate\n", "not valid TOML")],
)
def test_bad_gate_is_exit_2_naming_the_key_and_writes_nothing(tuned, tmp_path, gate_text, match):
    tpath, _, _ = tuned
    g = tmp_path / "gate.toml"
    g.write_text(gate_text)
    out = tmp_path / "val"
    r = invoke("validate", tpath, "--out-dir", out, "--gate", g)
    assert r.exit_code == 2
    assert match in r.output and "Traceback" not in r.output
    assert not out.exists()


def test_bad_inputs_are_exit_2(tuned, tmp_path):
    tpath, _, _ = tuned
    doc = read_json(tpath)
    doc["arc"]["g1"] = "fast"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    r = invoke("validate", bad, "--out-dir", tmp_path / "a")
    assert r.exit_code == 2 and "$.arc.g1: expected a finite number" in r.output
    r = invoke("validate", tmp_path / "missing.json", "--out-dir", tmp_path / "a")
    assert r.exit_code == 2 and "no such file" in r.output
    r = invoke("validate", tpath, "--out-dir", tmp_path / "a", "--monte-carlo", -1)
    assert r.exit_code == 2 and "--monte-carlo" in r.output
    assert not (tmp_path / "a").exists()


def test_results_do_not_depend_on_threads_and_progress_counts_every_run(tuned):
    t = Tuning.load(str(tuned[0]))
    calls = []
    r1 = validate(t, seed=3, n_monte_carlo=2, workers=1, progress=lambda d, n: calls.append((d, n)))
    r2 = validate(t, seed=3, n_monte_carlo=2, workers=2)
    assert calls[0] == (0, 32) and calls[-1] == (32, 32) and len(calls) == 33
    d1, d2 = r1.to_dict(), r2.to_dict()
    for d in (d1, d2):
        d.pop("elapsed_s")
    assert d1 == d2
    # a different seed draws different Monte-Carlo plants
    r3 = validate(t, seed=4, n_monte_carlo=2, workers=2)
    assert r3.run("mc/000").theta_true != r1.run("mc/000").theta_true


def test_report_states_a_theta3_box_that_tune_narrowed(tuned, tmp_path):
    tpath, gate, _ = tuned
    doc = read_json(tpath)
    bounds = doc["identification"].setdefault("bounds", {})
    bounds["narrowed_by_tune"] = {"theta3_min": -120.0, "theta3_max": 110.0, "u_max": 10.0,
                                  "force_range": [-3.0, 2.8], "narrowed_force_range": [-1.0, 1.0]}
    # as tune writes it: ident_sha256 is the hash of the identification before the narrowing
    before = copy.deepcopy(doc["identification"])
    before["bounds"].pop("narrowed_by_tune")
    before["theta"]["min"][2], before["theta"]["max"][2] = -120.0, 110.0
    doc["provenance"]["ident_sha256"] = sha256_json(before)
    narrowed = tmp_path / "tuning.json"
    narrowed.write_text(json.dumps(doc))
    out = tmp_path / "val"
    r = invoke("validate", narrowed, "--out-dir", out, "--gate", gate, "--monte-carlo", MC)
    assert r.exit_code in (0, 1), r.output
    report = (out / "report.md").read_text()
    assert "**theta3 narrowed by tune** from [-120, 110] m/s²" in report
    assert "the 10 V drive no room for any envelope" in report
    # an untouched tuning says nothing of the kind
    r = invoke("validate", tpath, "--out-dir", tmp_path / "plain", "--gate", gate, "--monte-carlo", MC)
    assert "narrowed" not in (tmp_path / "plain" / "report.md").read_text()


@pytest.mark.parametrize("level", [0, 2])
def test_a_refusal_of_gains_the_search_found_infeasible_says_so_first(tuned, tmp_path, level):
    """tuning.json's ``search.chosen_level`` 2 (no candidate met the search's constraints): the report's
    refusal and the CLI say it before the failed checks; a feasible search's refusal does not."""
    tpath, _, worst = tuned
    doc = read_json(tpath)
    doc["search"]["chosen_level"], doc["search"]["chosen_violation"] = level, (0.00365 if level else 0.0)
    t2 = tmp_path / "tuning.json"
    write_json_atomic(t2, doc)
    strict = tmp_path / "strict.toml"
    strict.write_text(f"[gate]\ne_rms = {worst['e_rms'] / 2!r}\n")
    out = tmp_path / "val"
    r = invoke("validate", t2, "--out-dir", out, "--gate", strict, "--monte-carlo", MC)
    assert r.exit_code == 1, r.output
    text = " ".join(r.output.split())
    report = (out / "report.md").read_text()
    said = "The gain search found no feasible gains"
    if level:
        n = doc["search"]["n_evaluations"]
        assert f"{said}: none of its {n} candidates" in text and "0.00365" in text
        assert report.index(said) < report.index("**No `controller.json` was written.**")
    else:
        assert said not in text and said not in report


def test_monte_carlo_records_are_each_plants_own_run(tuned):
    """validate simulates its Monte-Carlo plants a chunk at a time, two plants stepped together where
    they can be: every plant's record is still the one its own single run gives, in plant order."""
    from commission.controllers.pid import pid_pack
    from commission.controllers.simulate import KIND_PID

    t = Tuning.load(str(tuned[0]))
    n = 19  # more than one chunk, and an odd one out
    r = validate(t, seed=5, n_monte_carlo=n, workers=2)
    scen = [s for s in scenario_matrix(t.identification, t.spec, rng=np.random.default_rng(5), n_monte_carlo=n)
            if "monte_carlo" in s.tags]
    assert len(scen) == n
    for s in scen:
        ref = s.reference(t.arc.Ts)
        d = s.disturbance.samples(ref.t)
        run = r.run(s.name)
        sims = {kind: simulate(s.plant, kind, pack, ref, substeps=plant_substeps(t.spec.sample_rate),
                               quant=s.quantization, disturbance=d if np.any(d) else None, noise=s.noise(ref.n),
                               y0=s.y0, u_sat=t.spec.u_max, e_abort=t.spec.travel)
                for kind, pack in ((KIND_ARC, arc_pack(t.arc)), (KIND_PID, pid_pack(t.pid)))}
        assert (run.arc, run.pid) == (sims[KIND_ARC].score(), sims[KIND_PID].score()), s.name
        assert run.theta_final == tuple(float(x) for x in sims[KIND_ARC].theta_hat[-1]), s.name
