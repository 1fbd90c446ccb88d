"""tuning.json: schema, strict loading with JSON paths, determinism, provenance, CLI success path."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import zlib
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from commission import tune as tune_mod
from commission.cli.main import app
from commission.controllers.arc import RUNTIME_GUARDS, ArcGains, arc_pack
from commission.controllers.pid import G_KD, PidGains, pid_pack
from commission.errors import SchemaError
from commission.jsonio import sha256_file, write_json_atomic
from commission.paper import reference_identification
from commission.controllers.simulate import KIND_ARC, KIND_PID
from commission.scenarios import case1_trajectory, case2_trajectory, plant_substeps, tuning_scenarios
from commission.spec import default_spec, spec_from_mapping
from commission.tune import (
    HOLDOUT_PLANTS,
    OBSERVER_FACTOR_BOUNDS,
    PID_POLE_STEP,
    PID_POLE_STEPS,
    REPAIR_BUDGET,
    REPAIR_NAMES,
    STEP_FLOOR,
    WORK_CAP,
    Evaluator,
    HoldoutGate,
    SearchResult,
    SearchRun,
    N_FREE,
    PID_MARGIN,
    REPAIR_CAP_FACTORS,
    REPAIR_POP,
    W_CHATTER,
    W_STEP,
    apply_free,
    base_arc_gains,
    cost,
    deployable_pid,
    free_of_repair,
    load_tune_inputs,
    pid_baseline,
    pid_pole_note,
    repair_budget,
    repair_coordinates,
    repair_on_holdout,
    search,
    search_extension,
    search_step,
    select_on_holdout,
    tune,
    with_observer,
)
from commission.tuning import Score, Tuning

SMALL = {"tune": {"budget": 3}}


ref_ident = reference_identification


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A 3-candidate tuning of the (constructed) reference plant, through the CLI."""
    d = tmp_path_factory.mktemp("tune")
    ident = ref_ident(source={"sha256": "ab" * 32, "sample_rate": 2500.0})
    write_json_atomic(d / "ident.json", ident.to_dict())
    (d / "spec.toml").write_text("[tune]\nbudget = 3\n")
    r = CliRunner().invoke(app, ["tune", str(d / "ident.json"), "--out", str(d / "tuning.json"),
                                 "--spec", str(d / "spec.toml"), "--seed", "3"])
    assert r.exit_code == 0, r.output
    return d, r.output


def test_pid_chatter_names_the_scenarios_where_the_baseline_exceeds_the_gate(small):
    d, _ = small
    t = Tuning.from_dict(json.loads((d / "tuning.json").read_text()))
    assert tune_mod.pid_chatter(t) is None  # the paper's axis: the PID's c_u is far below 1
    scores = dict(t.scores)
    for name, c_u in (("case1/nominal", 1.3), ("case1/friction_low", 1.7)):
        scores[name] = {"arc": scores[name]["arc"], "pid": dataclasses.replace(scores[name]["pid"], c_u=c_u)}
    ch = tune_mod.pid_chatter(dataclasses.replace(t, scores=scores))
    assert ch == tune_mod.PidChatter(limit=1.0, count=2, worst=1.7, scenario="case1/friction_low")


def test_cli_writes_a_schema_versioned_tuning(small):
    d, output = small
    doc = json.loads((d / "tuning.json").read_text())
    assert doc["kind"] == "tuning" and doc["schema_version"] == 1
    assert list(doc) == sorted(doc)  # sorted keys
    pv = doc["provenance"]
    assert pv["ident_sha256"] == sha256_file(d / "ident.json")
    assert pv["log_sha256"] == "ab" * 32 and pv["seed"] == 3 and pv["created_utc"].endswith("Z")
    # the runtime guards are validate's, not tune's: absent from tuning.json (= off)
    assert set(doc["arc"]) == {f.name for f in dataclasses.fields(ArcGains)} - set(RUNTIME_GUARDS)
    assert set(doc["pid"]) == {f.name for f in dataclasses.fields(PidGains)} | {"pole", "design_mass"}
    # the observer the controller runs: the paper's pole (200 rad/s: k1 = 400, k2 = 4e4) unless the
    # hold-out repair moved the defaulted pole, within OBSERVER_FACTOR_BOUNDS
    ob = doc["observer"]
    assert (ob["k1"], ob["k2"]) == (doc["arc"]["k1"], doc["arc"]["k2"])
    assert ob["k1"] == pytest.approx(2 * ob["pole"]) and ob["k2"] == pytest.approx(ob["pole"] ** 2)
    if ob["pole"] != 200.0:
        assert doc["search"]["repair_evaluations"] > 0
        assert OBSERVER_FACTOR_BOUNDS[0] <= ob["pole"] / 200.0 <= OBSERVER_FACTOR_BOUNDS[1]
    assert doc["pid"]["design_mass"] == pytest.approx(1 / 50.0)
    assert doc["pid"]["Kp"] == pytest.approx(5400.0) and doc["pid"]["Ki"] == pytest.approx(5.4e5)  # paper (57)
    assert doc["theorem1"]["holds"] is True
    assert set(doc["feasibility"]) == {"arc", "pid"}
    for name in ("theorem1_condition", "projection_P1", "exact_observer_filters", "robust_gains_37_47",
                 "sampled_data_stability", "input_limit"):
        assert name in doc["guarantees"]
    assert doc["guarantees"]["robust_gains_37_47"]["holds"] is False  # traded: capped gains
    # fixed scenarios, box corners, largest-force plants, payloads (not the robustness scenarios: validate's only)
    assert len(doc["scores"]) == 12 + 16 + 4 + 6
    assert doc["search"]["free"]["theta1_0"] == doc["arc"]["theta0"][0]
    assert doc["search"]["n_evaluations"] == 3
    # the winner was chosen by the default gate on fresh Monte-Carlo plants among the feasible candidates
    assert doc["search"]["holdout_plants"] == HOLDOUT_PLANTS
    fails = doc["search"]["holdout_failures"]
    assert 1 <= len(fails) <= 3 and all(isinstance(f, int) and f >= 0 for f in fails)
    # the repair runs exactly when every compared candidate still failed the hold-out gate
    se = doc["search"]
    if min(fails) == 0:
        assert se["repair_failures"] is None and se["repair_evaluations"] == 0 and se["repair_moves"] == []
        assert (ob["k1"], ob["k2"]) == (400.0, 4e4)
    else:
        assert 0 < se["repair_evaluations"] and se["repair_failures"] <= min(fails)
    assert "Chosen gains" in output and "case1/nominal" in output
    assert "fresh plants" in output and "default gate, hold-out" in output
    # stability margins per plant: the identified one and the four (theta1, theta2) box corners;
    # the PID once, the ARC at theta_hat(0) and at the plant's theta
    rows = doc["margins"]
    plants = {r["plant"] for r in rows}
    assert plants == {"nominal"} | {f"theta1_{a}/theta2_{b}" for a in ("min", "max") for b in ("min", "max")}
    for plant in plants:
        mine = [(r["controller"], r["theta_hat_at"]) for r in rows if r["plant"] == plant]
        assert sorted(mine) == [("arc", "initial"), ("arc", "plant"), ("pid", "")]
    nominal_pid = next(r for r in rows if r["plant"] == "nominal" and r["controller"] == "pid")
    # the paper's PID on the paper's (rigid) plant: stable with room (delay margin in samples)
    assert nominal_pid["stable"] and nominal_pid["delay_margin_samples"] > 1 and nominal_pid["gain_margin_db"] > 6


def test_roundtrip_and_strict_loading(small):
    d, _ = small
    t = Tuning.load(str(d / "tuning.json"))
    assert Tuning.from_dict(t.to_dict()).to_dict() == t.to_dict()
    # theta_hat2(0), theta_hat3(0): the nominal; theta_hat1(0): searched between 0.5x and 1x the nominal
    assert t.arc.theta0[1:] == (10.1, 0.0) and 0.5 * 37.0 <= t.arc.theta0[0] <= 37.0 and t.arc.u_max == 10.0
    doc = json.loads((d / "tuning.json").read_text())
    cases = [
        (lambda x: x["arc"].__setitem__("g1", "fast"), r"tuning\.json: \$\.arc\.g1: expected a finite number"),
        (lambda x: x["arc"].pop("Gamma"), r"\$\.arc\.Gamma: missing required field"),
        (lambda x: x["arc"].__setitem__("gain", 1.0), r"\$\.arc\.gain: unknown field"),
        (lambda x: x["arc"].__setitem__("g1", -1.0), r"\$\.arc: ArcGains\.g1: must be > 0"),
        (lambda x: x.__setitem__("kind", "identification"), r"\$\.kind: expected kind 'tuning'"),
        (lambda x: x["spec"]["controller"].__setitem__("sample_rate", -1), r"\$\.spec\.controller\.sample_rate"),
        (lambda x: x["identification"]["theta"].pop("min"), r"\$\.identification\.theta\.min: missing"),
        (lambda x: x["observer"]["P"].__setitem__(1, [1.0]), r"\$\.observer\.P\[1\]: expected a list of 2"),
        (lambda x: x["scores"]["case1/nominal"]["arc"].__setitem__("diverged", 0), r"diverged: expected true or false"),
        (lambda x: x["pid"].__setitem__("design_mass", 0.03), r"\$\.pid\.design_mass: does not equal"),
        (lambda x: x["observer"].__setitem__("k1", x["observer"]["k1"] * 1.1), r"\$\.observer\.k1: .* does not equal arc\.k1"),
    ]
    for mutate, msg in cases:
        bad = copy.deepcopy(doc)
        mutate(bad)
        with pytest.raises(SchemaError, match=msg):
            Tuning.from_dict(bad, source="tuning.json")


@pytest.mark.slow  # a whole tune (tens of seconds): in `pytest -m slow`
def test_same_seed_same_tuning_different_seed_different_search():
    ident = ref_ident()
    spec = spec_from_mapping({"tune": {"budget": 6}})  # 4 structured starts + 2 random draws
    kw = dict(ident_sha256="0" * 64, created_utc="2026-01-01T00:00:00Z", workers=2)
    a = tune(ident, spec, rng=np.random.default_rng(11), seed=11, **kw)
    b = tune(ident, spec, rng=np.random.default_rng(11), seed=11, workers=1,
             **{k: v for k, v in kw.items() if k != "workers"})
    c = tune(ident, spec, rng=np.random.default_rng(12), seed=12, **kw)
    assert a.to_dict() == b.to_dict()  # bit-identical, independent of the thread count
    assert a.search.history != c.search.history and len(c.search.history) == spec.budget
    # the structured starts (carried-over paper gains first) do not depend on the seed
    assert a.search.cost_initial == c.search.cost_initial == a.search.history[0]
    assert a.search.history[:4] == c.search.history[:4]


@pytest.mark.slow  # a whole tune (tens of seconds): in `pytest -m slow`
def test_spec_can_pin_theta_hat1_0():
    ident = ref_ident()
    spec = spec_from_mapping({"tune": {"budget": 6}, "controller": {"theta1_0": 30.0}})
    t = tune(ident, spec, rng=np.random.default_rng(1), seed=1, ident_sha256="0" * 64,
             created_utc="2026-01-01T00:00:00Z")
    assert t.arc.theta0 == (pytest.approx(30.0), 10.1, 0.0)
    assert t.search.free["theta1_0"] == pytest.approx(30.0)


def test_theta_hat1_0_outside_the_box_is_refused(tmp_path):
    from commission.errors import SpecError

    write_json_atomic(tmp_path / "ident.json", ref_ident().to_dict())
    (tmp_path / "spec.toml").write_text("[controller]\ntheta1_0 = 60.0\n")
    with pytest.raises(SpecError, match=r"controller\.theta1_0 = 60 lies outside the identified theta1 box"):
        load_tune_inputs(tmp_path / "ident.json", spec_path=tmp_path / "spec.toml")


def test_repair_budget_grows_as_a_simulation_gets_cheaper():
    # a simulation costs its samples: below 2.5 kHz the same wall time buys 2500 / f_s x the moves
    budgets = [repair_budget(spec_from_mapping({"controller": {"sample_rate": fs}})) for fs in (1000.0, 2000.0, 2500.0,
                                                                                                  5000.0)]
    assert budgets == [90, 45, REPAIR_BUDGET, REPAIR_BUDGET]


def test_default_budgets_shrink_with_the_work_of_a_candidate():
    ident = ref_ident()
    # closed form of the work: 19 scenarios on each trajectory (12 fixed, 16 corners, 4 offsets, 6 payloads),
    # every sample one ARC step plus the plant's sub-steps
    slow = spec_from_mapping({"controller": {"sample_rate": 4000.0}, "trajectory": {"v_max": 0.2, "a_max": 4.0}})
    n1 = round(case1_trajectory(slow).duration * 4000.0)
    n2 = round(case2_trajectory(slow).duration * 4000.0)
    work = 19 * (n1 + n2) * (tune_mod.ARC_STEP_WORK + plant_substeps(4000.0))
    assert tune_mod.candidate_work(ident, slow) == pytest.approx(work, rel=1e-12)
    scale = tune_mod.WORK_CAP / work
    assert 0.3 < scale < 1.0 and tune_mod.work_scale(ident, slow) == pytest.approx(scale, rel=1e-12)
    # a defaulted budget shrinks to whole generations, with a note naming the key; a given one is kept
    rs = tune_mod.resolve_spec({"controller": {"sample_rate": 4000.0}, "trajectory": {"v_max": 0.2, "a_max": 4.0}},
                               "s.toml", ident)
    assert rs.spec.budget == tune_mod.POP * round(96 * scale / tune_mod.POP) < 96
    assert any(n.startswith(f"tune.budget defaulted to {rs.spec.budget} instead of 96") for n in rs.notes)
    kept = tune_mod.resolve_spec({"controller": {"sample_rate": 4000.0}, "trajectory": {"v_max": 0.2, "a_max": 4.0},
                                  "tune": {"budget": 96}}, "s.toml", ident)
    assert kept.spec.budget == 96 and not any("tune.budget" in n for n in kept.notes)
    # the paper's axis on the default envelope is within the cap: nothing changes
    rs = tune_mod.resolve_spec({}, "s.toml", ident)
    assert tune_mod.work_scale(ident, rs.spec) == 1.0 and rs.spec.budget == 96
    # the repair gets two rounds (16) where the search had to shrink
    assert repair_budget(slow, scale) == tune_mod.MIN_REPAIR_BUDGET == 16 < repair_budget(slow, 1.0) == REPAIR_BUDGET


@pytest.mark.slow  # a whole tune (tens of seconds): in `pytest -m slow`
def test_progress_callback_and_base_gains():
    ident = ref_ident()
    spec = spec_from_mapping(SMALL)
    seen = []
    tune(ident, spec, rng=np.random.default_rng(0), seed=0, ident_sha256="0" * 64,
         progress=lambda done, total: seen.append((done, total)))
    # search candidates, hold-out, the repair's candidates (skipped steps jump), two final reports
    assert seen[-1][0] == seen[-1][1] == spec.budget + 1 + repair_budget(spec, tune_mod.work_scale(ident, spec)) + 2
    assert [s[0] for s in seen] == sorted(s[0] for s in seen)
    g = base_arc_gains(ident, spec)
    # theta1 nominal 37 and 2.5 kHz are the paper's axis: its gains carry over unchanged
    assert (g.g1, g.g2, g.w1, g.w2) == (pytest.approx(600.0), pytest.approx(850.0), 1.0, pytest.approx(0.1))
    assert g.Gamma == pytest.approx((5e5, 3e5, 2e6)) and g.C_theta2 == pytest.approx((1e5, 1e5, 1e5))


def test_log_rate_becomes_the_default_sample_rate(tmp_path):
    ident = ref_ident(source={"sha256": "cd" * 32, "sample_rate": 4000.0})
    write_json_atomic(tmp_path / "ident.json", ident.to_dict())
    inp = load_tune_inputs(tmp_path / "ident.json")
    assert inp.spec.sample_rate == 4000.0 and inp.spec.observer_pole == pytest.approx(320.0)
    assert inp.log_sha256 == "cd" * 32
    (tmp_path / "spec.toml").write_text("[controller]\nsample_rate = 2500\n")
    assert load_tune_inputs(tmp_path / "ident.json", spec_path=tmp_path / "spec.toml").spec.sample_rate == 2500.0


def test_observer_pole_is_free_for_the_repair_only_when_defaulted(tmp_path):
    """A spec that sets controller.observer_pole keeps it; otherwise the repair may move it."""
    write_json_atomic(tmp_path / "ident.json", ref_ident().to_dict())
    assert load_tune_inputs(tmp_path / "ident.json").observer_free
    (tmp_path / "rate.toml").write_text("[controller]\nsample_rate = 2500\n")
    assert load_tune_inputs(tmp_path / "ident.json", spec_path=tmp_path / "rate.toml").observer_free
    (tmp_path / "pole.toml").write_text("[controller]\nobserver_pole = 200.0\n")
    assert not load_tune_inputs(tmp_path / "ident.json", spec_path=tmp_path / "pole.toml").observer_free


def test_theorem1_holds_anywhere_in_the_search_box():
    from commission.controllers.design import theorem1_check
    from commission.tune import FREE_BOUNDS, apply_free

    base = base_arc_gains(ref_ident(), spec_from_mapping({}))
    rng = np.random.default_rng(0)
    lo = np.log([b[1] for b in FREE_BOUNDS])
    hi = np.log([b[2] for b in FREE_BOUNDS])
    for x in [lo, hi, *(lo + (hi - lo) * rng.random((50, len(FREE_BOUNDS))))]:
        g = apply_free(base, np.exp(x))
        assert theorem1_check(g.w1, g.w2, g.C_phi1, g.C_phi2, g.C_theta2).min_ratio >= 5.0 - 1e-9
        assert g.g1 <= g.k1s_max and g.g2 <= g.k2s_max
        assert g.theta_min[0] <= g.theta0[0] <= base.theta0[0]  # theta_hat1(0) in the box, not above nominal


def test_search_step_shrinks_to_its_floor():
    """Closed form: 1, 0.6, 0.36, 0.216, 0.1296, then the floor 0.1 (0.6**5 = 0.078 is below it)."""
    assert STEP_FLOOR == 0.1
    expected = [1.0, 0.6, 0.36, 0.216, 0.1296] + [0.1] * 7
    assert [search_step(k) for k in range(12)] == pytest.approx(expected, rel=1e-12)


def test_search_late_generations_still_spread_at_the_floor():
    """The search's draws in its last generation are spread by the floor step, not 0.6**11.

    A stub evaluator scores every candidate the same, so no candidate beats the first
    feasible one and every generation is drawn around the start (log 1 = 0 on the k1, k2
    caps, far from their bounds 0.25-4: no clipping); stable sorting keeps the evaluation
    order.  The rms log-deviation of the caps of generation g estimates its step.
    """
    spec = default_spec()
    base = base_arc_gains(ref_ident(), spec)
    flat = Score(e_M=1e-5, e_F=1e-6, e_rms=1e-6, u_rms=1.0, du_rms=0.1, c_u=0.1, u_peak=1.0, diverged=False)
    ev = SimpleNamespace(scores=lambda kind, packs: [[flat] for _ in packs], weights=[1.0])
    res = search(base, ev, spec, np.random.default_rng(3), feasible=lambda g: SimpleNamespace(holds=True),
                 budget=96)
    caps = np.log(res.x[:, :2]).reshape(12, 8, 2)  # (generation, candidate, k1/k2 cap)
    rms = np.sqrt(np.mean(caps ** 2, axis=(1, 2)))
    assert 0.3 < rms[1] < 1.0  # step 0.6
    assert 0.05 < rms[11] < 0.2  # step 0.1; without the floor 0.6**11 = 0.004


def _hashed_scores(kind, packs):
    """Stub evaluator: one score per pack, its e_rms a fixed function of the pack's bytes."""
    out = []
    for p in packs:
        e = 1e-6 * (1.0 + (zlib.crc32(np.ascontiguousarray(p).tobytes()) % 1000) / 1000.0)
        out.append([Score(e_M=1e-5, e_F=1e-6, e_rms=e, u_rms=1.0, du_rms=0.1, c_u=0.1, u_peak=1.0, diverged=False)])
    return out


def test_a_continued_search_equals_the_larger_budget_at_once():
    """:class:`SearchRun`: 16 candidates, then 24 more, are the 40 of one search (tune's extension relies on it).

    The stub's costs differ between candidates, so the centre of each generation moves.
    """
    spec = default_spec()
    base = base_arc_gains(ref_ident(), spec)
    ev = SimpleNamespace(scores=_hashed_scores, weights=[1.0])
    holds = SimpleNamespace(holds=True)
    once = search(base, ev, spec, np.random.default_rng(5), feasible=lambda g: holds, budget=40)
    run = SearchRun(base, ev, spec, feasible=lambda g: holds)
    rng = np.random.default_rng(5)
    run.advance(16, rng)
    first = run.result()
    run.advance(24, rng)
    both = run.result()
    assert len(first.history) == 16 and first.history == once.history[:16]
    assert both.history == once.history and np.array_equal(both.x, once.x) and both.best == once.best
    assert len(set(once.history)) > 30  # the stub does tell the candidates apart


def test_search_extension_fills_the_work_of_the_slowest_default_search(monkeypatch):
    """Closed form: POP x floor((budget x WORK_CAP / work - budget) / POP), within [0, budget]; 0 if the budget was given."""
    spec = default_spec()
    ident = ref_ident()
    for work, expected in ((WORK_CAP * 96 / 140, 40),  # room 44 -> 40
                           (WORK_CAP * 96 / 176, 80),
                           (WORK_CAP / 3, 96),  # room 192: at most the budget again
                           (WORK_CAP, 0), (2 * WORK_CAP, 0)):
        monkeypatch.setattr("commission.tune.optimiser.candidate_work", lambda i, s, w=work: w)
        assert search_extension(spec, ident, given=False) == expected, work
        assert search_extension(spec, ident, given=True) == 0


@pytest.fixture(scope="module")
def holdout_setup():
    """Reference identification, default spec, its tuning evaluator, the PID and a hold-out gate."""
    ident = ref_ident()
    spec = default_spec()
    base = base_arc_gains(ident, spec)
    ev = Evaluator(tuning_scenarios(ident, spec, rng=np.random.default_rng(0)), spec)
    pid = pid_baseline(ident, spec)[0]
    pid_scores = ev.scores(KIND_PID, [pid_pack(pid)])[0]
    hg = HoldoutGate(ident, spec, ev, pid, pid_scores, rng=np.random.default_rng(1))
    return ident, spec, base, ev, hg


#: Destabilising relative free gains: both caps x4, theta3 adaptation x1e4, w2 x1e-3 (chatters, hits u_max).
BAD_X = [4.0, 4.0, 1.0, 1.0, 1.0, 1.0, 1e4, 1e-3, 1.0]


def test_holdout_selection_prefers_fewer_gate_failures(holdout_setup):
    """The selection rule on a synthetic two-candidate search result.

    Candidate 0 is given the lower cost but carries :data:`BAD_X`.  Candidate 1 is the
    paper's gains carried over.  The hold-out gate must count more failures for candidate 0
    and choose candidate 1 despite its cost.
    """
    ident, spec, base, ev, hg = holdout_setup
    x = np.array([BAD_X, [1.0] * 9])
    scores = ev.scores(KIND_ARC, [arc_pack(apply_free(base, xi)) for xi in x])
    holds = SimpleNamespace(holds=True)
    res = SearchResult(x=x, costs=np.array([0.0, 1.0]), scores=scores, feasibility=[holds, holds],
                       cost_initial=0.0, history=(0.0, 1.0), best=0)
    ch = select_on_holdout(res, base, hg, lambda g: holds)
    assert ch.n_plants == HOLDOUT_PLANTS and len(ch.failures) == 2
    assert ch.failures[0] > ch.failures[1]
    assert ch.chosen == 1


def test_holdout_selection_judges_each_candidate_once_with_a_memo(holdout_setup):
    """After the search's extension the six best are chosen again: the ones judged before
    come from the memo, and the choice equals judging all of them afresh."""
    ident, spec, base, ev, hg = holdout_setup
    judged: list[int] = []

    class Spy:
        n_plants = hg.n_plants

        def judge(self, gains, tune_scores=None):
            judged.append(len(gains))
            return hg.judge(gains, tune_scores)

    holds = SimpleNamespace(holds=True)
    x2 = np.array([BAD_X, [1.0] * 9])
    x3 = np.array([BAD_X, [1.2, 0.8, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0], [1.0] * 9])

    def result(x):
        scores = ev.scores(KIND_ARC, [arc_pack(apply_free(base, xi)) for xi in x])
        costs = np.arange(len(x), dtype=float)
        return SearchResult(x=x, costs=costs, scores=scores, feasibility=[holds] * len(x), cost_initial=0.0,
                            history=tuple(costs), best=0)

    memo: dict = {}
    select_on_holdout(result(x2), base, Spy(), lambda g: holds, memo)
    again = select_on_holdout(result(x3), base, Spy(), lambda g: holds, memo)
    assert judged == [2, 1]  # the middle candidate is the only new one
    fresh = select_on_holdout(result(x3), base, hg, lambda g: holds)
    assert (again.chosen, again.failures, again.excess) == (fresh.chosen, fresh.failures, fresh.excess)


def test_repair_coordinates_move_a_cap_and_keep_g():
    """Closed form of the repair's coordinates: a round trip is the identity inside the box,
    a lower k2 cap keeps the absolute g2 while g2 fits under it, and then clips g2 to the cap."""
    base = base_arc_gains(ref_ident(), default_spec())
    x = np.array([1.5, 2.0, 0.4, 0.5, 3.0, 0.2, 50.0, 2.0, 0.8])
    r = repair_coordinates(x, 0.9)
    assert r[2] == pytest.approx(math.log(1.5 * 0.4)) and r[3] == pytest.approx(math.log(2.0 * 0.5))
    x1, f = free_of_repair(r)
    np.testing.assert_allclose(x1, x, rtol=1e-12)
    assert f == pytest.approx(0.9)
    g0 = apply_free(base, x)
    r[1] -= math.log(1.5)  # k2 cap 2.0 -> 1.33 x base g2: g2 = 1.0 x base still fits
    g1 = apply_free(base, free_of_repair(r)[0])
    assert g1.k2s_max == pytest.approx(g0.k2s_max / 1.5) and g1.g2 == pytest.approx(g0.g2)
    r[1] -= math.log(2.0)  # cap 0.67 x base g2: g2 clipped to the cap (f2 = 1)
    g2 = apply_free(base, free_of_repair(r)[0])
    assert g2.g2 == pytest.approx(g2.k2s_max) and g2.g2 < g0.g2
    # a theta_hat1(0) pinned by the spec above the search box (t1 > 1) passes unchanged
    x[8] = 1.2
    assert free_of_repair(repair_coordinates(x, 1.0))[0][8] == pytest.approx(1.2)


@pytest.mark.slow  # a hold-out repair (tens of seconds): in `pytest -m slow`
def test_repair_moves_away_from_destabilising_gains(holdout_setup):
    """Starting from :data:`BAD_X`, the repair's local search must cut the hold-out gate's failures.

    Every accepted move names coordinates of REPAIR_NAMES (``ob``: the observer pole), the
    failures drop, and the result is what the hold-out gate says of the final gains
    (re-judged here, with the observer pole the repair reports).  With ``observer_free``
    False the observer pole is the spec's, and no move names it.
    """
    ident, spec, base, ev, hg = holdout_setup
    x0 = np.array(BAD_X)
    (s0, f0, e0), = hg.judge([apply_free(base, x0)])
    assert f0 > 0
    holds = SimpleNamespace(holds=True)
    names = set(REPAIR_NAMES)
    for free in (False, True):
        rep = repair_on_holdout(x0, s0, f0, e0, holds, base, hg, spec, lambda g: holds, np.random.default_rng(3),
                                observer_free=free, budget=24)
        assert rep.evaluations <= 24 and rep.moves
        for m in rep.moves:
            assert {part.split()[0] for part in m.split(", ")} <= names, m
        assert rep.failures < f0
        g = with_observer(apply_free(base, rep.x), rep.observer_pole)
        (s1, f1, e1), = hg.judge([g])
        assert (f1, e1) == (rep.failures, pytest.approx(rep.excess))
        assert [a.e_rms for a in s1] == [a.e_rms for a in rep.scores]
        if not free:
            assert rep.observer_pole == spec.observer_pole
            assert not any("ob " in m for m in rep.moves)
        else:
            assert OBSERVER_FACTOR_BOUNDS[0] <= rep.observer_pole / spec.observer_pole <= OBSERVER_FACTOR_BOUNDS[1]


def _kd_chatter_evaluator(c_u_per_kd: float, n: int = 3) -> SimpleNamespace:
    """A stub Evaluator whose PID c_u is proportional to the packed Kd, on ``n`` scenarios."""

    def scores(kind, packs):
        assert kind == KIND_PID
        return [[Score(e_M=1e-5, e_F=1e-6, e_rms=1e-6, u_rms=1.0, du_rms=c_u_per_kd * p[G_KD] * (1 + 0.1 * i),
                       c_u=c_u_per_kd * p[G_KD] * (1 + 0.1 * i), u_peak=1.0, diverged=False) for i in range(n)]
                for p in packs]
    return SimpleNamespace(scores=scores, weights=[1.0] * n)


def test_deployable_pid_takes_the_fastest_grid_pole_within_the_c_u_limit():
    """Closed form: with c_u = c Kd (x1.2 on the worst scenario) and Kd = 3 M_min w, the
    chosen pole is the largest w0 0.95^k with 1.2 c 3 M_min w <= limit."""
    ident = ref_ident()
    spec = default_spec()
    _, m_min = pid_baseline(ident, spec)
    w0 = spec.pid_pole
    c = 1.0 / (1.2 * 3.0 * m_min * 0.8 * w0)  # the worst scenario reaches the limit 1 at 0.8 w0
    k = next(k for k in range(1, PID_POLE_STEPS + 1) if PID_POLE_STEP ** k <= 0.8 * (1 - 1e-12))
    out = deployable_pid(ident, spec, _kd_chatter_evaluator(c), 1.0, pole_free=True)
    assert out.pole == pytest.approx(w0 * PID_POLE_STEP ** k) and k == 5  # 0.95^5 = 0.774
    assert out.gains.Kd == pytest.approx(3.0 * m_min * out.pole)
    assert max(s.c_u for s in out.scores) <= 1.0 < 1.2 * c * 3.0 * m_min * w0 * PID_POLE_STEP ** (k - 1)
    # a pole set in the spec is kept, and so is the default when no grid pole meets the limit
    kept = deployable_pid(ident, spec, _kd_chatter_evaluator(c), 1.0, pole_free=False)
    assert kept.pole == w0 and max(s.c_u for s in kept.scores) > 1.0
    hopeless = deployable_pid(ident, spec, _kd_chatter_evaluator(10 * c), 1.0, pole_free=True)
    assert hopeless.pole == w0 and hopeless.gains == pid_baseline(ident, spec)[0]
    # within the limit at the default pole: nothing changes
    calm = deployable_pid(ident, spec, _kd_chatter_evaluator(0.7 * c), 1.0, pole_free=True)  # worst 0.875
    assert calm.pole == w0


def test_pid_pole_note_only_when_the_baseline_moved(small):
    """The tuning of the reference plant keeps the paper's pole (its PID's c_u is about 0.3)."""
    d, output = small
    t = Tuning.from_dict(json.loads((d / "tuning.json").read_text()))
    assert t.pid_pole == t.spec.pid_pole and pid_pole_note(t) is None and "PID baseline runs at" not in output
    moved = dataclasses.replace(t, pid_pole=0.8 * t.spec.pid_pole)
    note = pid_pole_note(moved)
    assert note is not None and "pid.pole = 240 rad/s instead of the defaulted 300" in note


def test_cost_charges_a_transient_and_an_average_worse_than_the_pids():
    """Closed form of the two ARC-vs-PID terms of :func:`cost` on one scenario (no gate, all
    other terms zero: e_rms at its target, e_F and c_u below theirs, u below u_max):
    e_M above the PID's costs W_STEP + W_CHATTER ln(e_M / e_M_pid), e_rms above PID_MARGIN x
    the PID's costs W_STEP + W_CHATTER ln(e_rms / (m e_rms_pid)); the minimax term is
    ln(e_rms / e_rms_pid).  Session 11's soft tuning lost the reference axis's start-up to the
    PID (e_M 34 against 15 um) because only the second term existed."""
    spec = default_spec()

    def score(e_M: float, e_rms: float) -> Score:
        return Score(e_M=e_M, e_F=0.1 * spec.e_f, e_rms=e_rms, u_rms=1.0, du_rms=0.1 * spec.c_u,
                     c_u=0.1 * spec.c_u, u_peak=0.5 * spec.u_max, diverged=False)

    pid = [score(20e-6, 2 * spec.e_rms)]
    minimax = math.log(0.5)
    assert cost([score(10e-6, spec.e_rms)], spec, pid) == pytest.approx(minimax)
    assert cost([score(20e-6, spec.e_rms)], spec, pid) == pytest.approx(minimax)  # a tie is no loss
    assert cost([score(50e-6, spec.e_rms)], spec, pid) == pytest.approx(
        minimax + W_STEP + W_CHATTER * math.log(2.5))
    worse = 1.5 * 2 * spec.e_rms
    assert cost([score(10e-6, worse)], spec, pid) == pytest.approx(
        math.log(worse / spec.e_rms) + W_STEP + W_CHATTER * math.log(worse / (PID_MARGIN * 2 * spec.e_rms))
        + math.log(1.5))
    # without a reference there is nothing to lose to
    assert cost([score(50e-6, spec.e_rms)], spec) == pytest.approx(0.0)


def test_repair_first_lowers_the_caps_when_the_gains_chatter():
    """A stub hold-out gate whose only failure is chatter unless the k2 cap is 0.87-0.93 x the
    chosen one (below that the ARC would lose to the PID): the narrow band of random axis 16.

    When a tuning scenario's c_u exceeds the gate's, the repair's first round is the line
    search of :data:`REPAIR_CAP_FACTORS` (the k2 cap, then both caps; every other gain kept),
    which lands in the band; without chatter the first round is the random joint draw."""
    spec = default_spec()
    base = base_arc_gains(ref_ident(), spec)
    x0 = np.ones(N_FREE)
    g0 = apply_free(base, x0)
    seen: list[ArcGains] = []

    def judge(gains):
        seen.extend(gains)
        out = []
        for g in gains:
            r = g.k2s_max / g0.k2s_max
            out.append(([], 0 if 0.87 < r < 0.93 else 1, abs(math.log(r / 0.9))))
        return out

    hg = SimpleNamespace(judge=judge, limits=SimpleNamespace(c_u=1.0))
    holds = SimpleNamespace(holds=True)

    def chat(c_u):
        return [Score(e_M=1e-5, e_F=1e-6, e_rms=1e-6, u_rms=1.0, du_rms=c_u, c_u=c_u, u_peak=1.0, diverged=False)]

    rep = repair_on_holdout(x0, chat(1.04), 1, 0.04, holds, base, hg, spec, lambda g: holds,
                            np.random.default_rng(0), observer_free=False, budget=2 * REPAIR_POP)
    first = seen[:REPAIR_POP]
    assert [g.k2s_max / g0.k2s_max for g in first] == pytest.approx(list(REPAIR_CAP_FACTORS) * 2)
    assert [g.k1s_max / g0.k1s_max for g in first] == pytest.approx([1.0] * 4 + list(REPAIR_CAP_FACTORS))
    for g in first:
        assert (g.Gamma, g.w2, g.theta0, g.k1, g.k2) == (g0.Gamma, g0.w2, g0.theta0, g0.k1, g0.k2)
        assert g.g2 == pytest.approx(min(g0.g2, g.k2s_max))
    assert rep.moves[0] == "k2 /1.11" and rep.failures == 0
    seen.clear()
    repair_on_holdout(x0, chat(0.5), 1, 0.04, holds, base, hg, spec, lambda g: holds,
                      np.random.default_rng(0), observer_free=False, budget=2 * REPAIR_POP)
    assert all(g.Gamma != g0.Gamma for g in seen[:REPAIR_POP])
