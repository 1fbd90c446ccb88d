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

from commission.cli.main import app
from commission.controllers.arc import RUNTIME_GUARDS, ArcGains, arc_pack
from commission.controllers.pid import G_KD, PidGains, pid_pack
from commission.errors import SchemaError
from commission.jsonio import sha256_file, write_json_atomic
from commission.paper import reference_identification
from commission.controllers.simulate import KIND_ARC, KIND_PID
from commission.scenarios import case1_trajectory, scenario_matrix, screening_indices, tuning_scenarios
from commission.spec import default_spec, spec_from_mapping
from commission.tune.api import load_tune_inputs, resolve_spec, tune
from commission.tune.baseline import PidChatter, deployable_pid, pid_baseline, pid_chatter, pid_pole_note
from commission.tune.candidate import FEASIBLE, GATE_MISSED, STABILITY_MISSED, Candidate, SearchResult
from commission.tune.constraints import margin_violation
from commission.tune.gains import apply_free, base_arc_gains
from commission.tune.objective import Evaluator, HoldoutGate, cost, gate_excess
from commission.tune.optimiser import Problem, search, select_on_holdout
from commission.tune.settings import DEFAULT_SETTINGS
from commission.robustness import LoopMargins, MarginFloors
from commission.controllers.margins import Margins
from commission.controllers.metrics import Indexes
from commission.tuning import Tuning

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
    assert pid_chatter(t) is None  # the paper's axis: the PID's c_u is far below 1
    scores = dict(t.scores)
    for name, c_u in (("case1/nominal", 1.3), ("case1/friction_low", 1.7)):
        scores[name] = {"arc": scores[name]["arc"], "pid": dataclasses.replace(scores[name]["pid"], c_u=c_u)}
    ch = pid_chatter(dataclasses.replace(t, scores=scores))
    assert ch == PidChatter(limit=1.0, count=2, worst=1.7, scenario="case1/friction_low")


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
    # the observer the controller runs: the defaulted pole (the paper's 200 rad/s: k1 = 400, k2 = 4e4)
    # is a coordinate of the search, within DEFAULT_SETTINGS.observer_factor_bounds
    ob = doc["observer"]
    assert (ob["k1"], ob["k2"]) == (doc["arc"]["k1"], doc["arc"]["k2"])
    assert ob["k1"] == pytest.approx(2 * ob["pole"]) and ob["k2"] == pytest.approx(ob["pole"] ** 2)
    lo, hi = DEFAULT_SETTINGS.observer_factor_bounds
    assert lo <= ob["pole"] / 200.0 <= hi
    assert doc["pid"]["design_mass"] == pytest.approx(1 / 50.0)
    # pid.pole defaulted: the PID is the yardstick, (57)'s triple pole of (56) at M_min at the pole it chose
    w, m = doc["pid"]["pole"], doc["pid"]["design_mass"]
    assert doc["pid_yardstick"]["method"] == "margin_search" and doc["pid_yardstick"]["pole"] == w
    assert doc["pid"]["Kp"] == pytest.approx(3 * w * w * m) and doc["pid"]["Ki"] == pytest.approx(w ** 3 * m)
    assert doc["theorem1"]["holds"] is True
    assert set(doc["feasibility"]) == {"arc", "pid"}
    for name in ("theorem1_condition", "projection_P1", "exact_observer_filters", "robust_gains_37_47",
                 "sampled_data_stability", "input_limit"):
        assert name in doc["guarantees"]
    assert doc["guarantees"]["robust_gains_37_47"]["holds"] is False  # traded: capped gains
    # fixed scenarios, one more sample of delay on each case, box corners, largest-force plants, payloads
    assert len(doc["scores"]) == 12 + 2 + 16 + 4 + 6
    assert "case1/delay+1" in doc["scores"] and "case2/delay+1" in doc["scores"]
    se = doc["search"]
    assert se["free"]["theta1_0"] == doc["arc"]["theta0"][0]
    assert se["n_evaluations"] == 3 and len(se["levels"]) == len(se["violations"]) == len(se["history"]) == 3
    assert se["optimiser"].startswith("CMA-ES (pycma")
    # a candidate's violation is 0 exactly when it met every constraint (level 0)
    assert all((lv == 0) == (v == 0) for lv, v in zip(se["levels"], se["violations"]))
    assert se["n_feasible"] == se["levels"].count(0)
    # the winner was chosen by the default gate on fresh Monte-Carlo plants among the feasible candidates
    if se["n_feasible"]:
        assert se["holdout_plants"] == DEFAULT_SETTINGS.holdout_plants and se["chosen_level"] == 0
        fails = se["holdout_failures"]
        assert 1 <= len(fails) <= 3 and all(isinstance(f, int) and f >= 0 for f in fails)
        assert "fresh plants" in output and "default gate, hold-out" in output
    else:
        # the finalists are then the candidates that kept the margins but missed the gate (judged on the
        # hold-out plants), else none (select_on_holdout)
        assert se["holdout_plants"] in (0, DEFAULT_SETTINGS.holdout_plants)
        assert se["chosen_level"] > 0 and se["chosen_violation"] > 0
        assert "no candidate of the search met every constraint" in output
    assert "Chosen gains" in output and "case1/nominal" in output
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
    # (objectives are NaN for candidates not simulated on every scenario: compare violations too)
    assert (a.search.history, a.search.violations) != (c.search.history, c.search.violations)
    assert len(c.search.history) == spec.budget
    # the structured starts (carried-over paper gains first) do not depend on the seed
    assert np.array_equal([a.search.cost_initial, c.search.cost_initial], [a.search.history[0]] * 2, equal_nan=True)
    assert np.array_equal(a.search.history[:4], c.search.history[:4], equal_nan=True)
    assert a.search.violations[:4] == c.search.violations[:4] and a.search.levels[:4] == c.search.levels[:4]


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


def test_a_defaulted_budget_is_kept_however_slow_a_candidate_is_to_simulate():
    """The paper's axis at 4 kHz on a 0.2 m/s, 4 m/s^2 envelope: one candidate simulates several times
    the paper axis' work, and the search still evaluates the default budget, without a note about it
    (a starved search certifies weak gains); a budget the spec gives is kept as given."""
    ident = ref_ident()
    data = {"controller": {"sample_rate": 4000.0}, "trajectory": {"v_max": 0.2, "a_max": 4.0}}
    slow = spec_from_mapping(data)
    paper = spec_from_mapping({})
    assert case1_trajectory(slow).duration * 4000.0 > 3 * case1_trajectory(paper).duration * paper.sample_rate
    n0 = default_spec().budget
    rs = resolve_spec(data, "s.toml", ident)
    assert rs.spec.budget == n0 and not any("tune.budget" in n for n in rs.notes)
    given = resolve_spec({**data, "tune": {"budget": 40}}, "s.toml", ident)
    assert given.spec.budget == 40


@pytest.mark.slow  # a whole tune (tens of seconds): in `pytest -m slow`
def test_progress_callback_and_base_gains():
    ident = ref_ident()
    spec = spec_from_mapping(SMALL)
    seen = []
    tune(ident, spec, rng=np.random.default_rng(0), seed=0, ident_sha256="0" * 64,
         progress=lambda done, total: seen.append((done, total)))
    # search candidates, hold-out, two final reports
    assert seen[-1][0] == seen[-1][1] == spec.budget + 3
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


def test_observer_pole_is_free_for_the_search_only_when_defaulted(tmp_path):
    """A spec that sets controller.observer_pole keeps it; otherwise the search may move it."""
    write_json_atomic(tmp_path / "ident.json", ref_ident().to_dict())
    assert load_tune_inputs(tmp_path / "ident.json").observer_free
    (tmp_path / "rate.toml").write_text("[controller]\nsample_rate = 2500\n")
    assert load_tune_inputs(tmp_path / "ident.json", spec_path=tmp_path / "rate.toml").observer_free
    (tmp_path / "pole.toml").write_text("[controller]\nobserver_pole = 200.0\n")
    assert not load_tune_inputs(tmp_path / "ident.json", spec_path=tmp_path / "pole.toml").observer_free


def test_theorem1_holds_anywhere_in_the_search_box():
    from commission.controllers.design import theorem1_check

    base = base_arc_gains(ref_ident(), spec_from_mapping({}))
    rng = np.random.default_rng(0)
    lo, hi = DEFAULT_SETTINGS.free_log_lo, DEFAULT_SETTINGS.free_log_hi
    for x in [lo, hi, *(lo + (hi - lo) * rng.random((50, len(DEFAULT_SETTINGS.free_bounds))))]:
        g = apply_free(base, np.exp(x))
        assert theorem1_check(g.w1, g.w2, g.C_phi1, g.C_phi2, g.C_theta2).min_ratio >= 5.0 - 1e-9
        assert g.g1 <= g.k1s_max and g.g2 <= g.k2s_max
        assert g.theta_min[0] <= g.theta0[0] <= base.theta0[0]  # theta_hat1(0) in the box, not above nominal


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


def _candidate(base, x, scores, objective, level=FEASIBLE):
    return Candidate(np.asarray(x, dtype=float), 1.0, apply_free(base, x), level, 0.0, objective, scores, None)


def test_holdout_selection_prefers_fewer_gate_failures(holdout_setup):
    """The selection rule on a synthetic two-candidate search result.

    Candidate 0 is given the better objective but carries :data:`BAD_X`.  Candidate 1 is the
    paper's gains carried over.  The hold-out gate must count more failures for candidate 0
    and choose candidate 1 despite its objective.  A candidate that misses a constraint is
    never a finalist while a feasible one exists; without one, the gate-missed candidates are.
    """
    ident, spec, base, ev, hg = holdout_setup
    x = np.array([BAD_X, [1.0] * 9])
    scores = ev.scores(KIND_ARC, [arc_pack(apply_free(base, xi)) for xi in x])
    infeasible = _candidate(base, [1.0] * 9, scores[1], -10.0, GATE_MISSED)
    res = SearchResult([_candidate(base, x[0], scores[0], 0.0), _candidate(base, x[1], scores[1], 1.0), infeasible],
                       1)
    ch = select_on_holdout(res, hg)
    assert ch.n_plants == DEFAULT_SETTINGS.holdout_plants and len(ch.failures) == 2
    assert ch.failures[0] > ch.failures[1]
    assert ch.chosen is res.candidates[1]
    # nothing feasible: the fully simulated gate-missed candidates are the finalists, judged the same way
    bad_missed = _candidate(base, x[0], scores[0], -20.0, GATE_MISSED)
    ch2 = select_on_holdout(SearchResult([bad_missed, infeasible], 1), hg)
    assert ch2.n_plants == DEFAULT_SETTINGS.holdout_plants
    assert ch2.failures[0] > ch2.failures[1] and ch2.chosen is infeasible
    # nothing simulated on every scenario: the least violation is returned, unjudged
    unsimulated = dataclasses.replace(infeasible, scores=None)
    assert select_on_holdout(SearchResult([unsimulated], 1), hg) == type(ch)(unsimulated, 0, ())


def _margins(gm=10.0, pm=45.0, dm=2.0, mm=0.7, stable=True, rho=0.9):
    return LoopMargins("nominal", "arc", (1.0, 1.0, 0.0), "initial",
                       Margins(gm, pm, dm, mm, 100.0, rho, stable))


def test_margin_violation_is_the_relative_shortfall_below_each_floor():
    """Closed form: (floor - margin) / floor for gain, phase and modulus, samples for the delay; 0 when met."""
    f = MarginFloors()
    assert margin_violation([_margins(), _margins(gm=math.inf, dm=math.inf)], f) == 0.0
    assert margin_violation([_margins(gm=3.0)], f) == pytest.approx(0.5)
    assert margin_violation([_margins(pm=15.0, dm=0.25)], f) == pytest.approx(0.5 + 0.75)
    assert margin_violation([_margins(mm=0.4), _margins(gm=-6.0)], f) == pytest.approx(0.2 + 2.0)
    assert margin_violation([_margins(stable=False, rho=1.5)], f) == pytest.approx(10.5)
    # the floors are the spec's: a lower delay floor is met by the same loop
    assert margin_violation([_margins(dm=0.6)], MarginFloors(delay_samples=0.5)) == 0.0


class _Quadratic:
    """A stub problem for :func:`search`: minimise |z - 1|^2 subject to z_0 <= 0.2 in [-2, 2]^3.

    The constrained optimum is (0.2, 1, 1) in closed form.  Candidates that break the
    constraint rank by its violation, as :class:`Problem` ranks them.
    """

    lo, hi = np.full(3, -2.0), np.full(3, 2.0)
    full0 = np.array([-1.0, -1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])

    def __init__(self):
        self.seen: list[np.ndarray] = []

    def z_of(self, x, observer_factor=1.0):
        return np.clip(np.log(np.asarray(x, dtype=float))[:3], self.lo, self.hi)

    def evaluate(self, Z):
        out = []
        for z in Z:
            z = np.clip(np.asarray(z), self.lo, self.hi)
            self.seen.append(z)
            v = max(0.0, z[0] - 0.2)
            out.append(Candidate(z, 1.0, None, FEASIBLE if v == 0 else GATE_MISSED, v,
                                 float(np.sum((z - 1.0) ** 2)), None, None))
        return out


def test_search_finds_the_constrained_optimum_of_a_known_problem():
    prob = _Quadratic()
    res = search(prob, 480, seed=7)
    best = res.ranked()[0]
    assert len(res.candidates) == 480 and res.n_feasible > 120
    assert best.level == FEASIBLE
    np.testing.assert_allclose(best.x, [0.2, 1.0, 1.0], atol=0.05)
    assert np.array_equal(prob.seen[0], prob.z_of(np.exp(prob.full0[:9])))  # the start is evaluated first
    again = search(_Quadratic(), 480, seed=7)
    assert [c.objective for c in again.candidates] == [c.objective for c in res.candidates]


def test_a_candidate_that_misses_a_margin_floor_is_not_simulated(holdout_setup):
    """The problem evaluates constraints cheapest first: BAD_X (caps x4, theta3 rate x1e4) misses
    the margin floors on the identified plant and is never simulated; the paper's gains are."""
    ident, spec, base, ev, hg = holdout_setup
    simulated: list[int] = []

    class Spy:
        weights = ev.weights
        scenarios = ev.scenarios
        workers = ev.workers

        def scores(self, kind, packs, only=None):
            simulated.append(len(packs))
            return ev.scores(kind, packs, only)

    pid_scores = hg.pid_scores[:len(ev.names)]
    prob = Problem(base, Spy(), spec, ident, pid_scores, hg.limits, lambda g: SimpleNamespace(
        holds=True, rho_max=0.5, margin=0.01, rho_adaptive_max=0.5), observer_free=False)
    bad, good = prob.evaluate([prob.z_of(BAD_X), prob.z_of([1.0] * 9)])
    assert simulated in ([1], [1, 1])  # the screen, then the rest if it passed there
    assert bad.level == STABILITY_MISSED and bad.violation > 0 and bad.scores is None
    assert good.level in (FEASIBLE, GATE_MISSED)
    assert (good.scores is None) == good.screened == (simulated == [1])
    assert math.isfinite(good.objective) != good.screened


def test_screening_scenarios_are_validates_fixed_and_robustness_ones(holdout_setup):
    """The screen is exactly the part of the tuning set that validate itself runs (not its Monte-Carlo plants)."""
    ident, spec, base, ev, hg = holdout_setup
    screen = [ev.names[i] for i in screening_indices(ev.scenarios)]
    matrix = scenario_matrix(ident, spec, rng=np.random.default_rng(0), n_monte_carlo=0)
    assert sorted(screen) == sorted(s.name for s in matrix)
    assert len(screen) < len(ev.names)


def test_a_candidate_that_misses_the_gate_on_the_screen_is_not_simulated_on_the_rest(holdout_setup):
    """A gain set far off validate's gate on the screening scenarios (feedback x0.05 misses accuracy there
    by more than the settings' screen_excess) is simulated on those only, records their excess as its
    violation, and ranks after any fully simulated candidate that missed the gate."""
    ident, spec, base, ev, hg = holdout_setup
    calls: list[tuple[int, int]] = []

    class Spy:
        weights = ev.weights
        scenarios = ev.scenarios
        workers = ev.workers

        def scores(self, kind, packs, only=None):
            calls.append((len(packs), len(ev.names) if only is None else len(only)))
            return ev.scores(kind, packs, only)

    pid_scores = hg.pid_scores[:len(ev.names)]
    prob = Problem(base, Spy(), spec, ident, pid_scores, hg.limits, lambda g: SimpleNamespace(
        holds=True, rho_max=0.5, margin=0.01, rho_adaptive_max=0.5), observer_free=False)
    soft = [1.0] * 9
    soft[0] = soft[1] = 0.05  # g1, g2: almost no feedback
    (c,) = prob.evaluate([prob.z_of(soft)])
    n_screen = len(screening_indices(ev.scenarios))
    assert calls == [(1, n_screen)]
    assert c.level == GATE_MISSED and c.screened and c.scores is None and math.isnan(c.objective)
    screen_scores = ev.scores(KIND_ARC, [arc_pack(c.gains)], screening_indices(ev.scenarios))[0]
    ref = [pid_scores[i] for i in screening_indices(ev.scenarios)]
    assert c.violation == pytest.approx(gate_excess(hg.limits, screen_scores, ref,
                                                    margin=DEFAULT_SETTINGS.gate_margin))
    assert c.violation > DEFAULT_SETTINGS.screen_excess
    full = dataclasses.replace(c, screened=False, violation=c.violation * 100.0)
    assert sorted([c, full], key=Candidate.rank_key)[0] is full
    assert full.fitness() < c.fitness() < Candidate(c.x, 1.0, c.gains, STABILITY_MISSED, 0.0, math.nan, None,
                                                    None).fitness()


def _kd_chatter_evaluator(c_u_per_kd: float, n: int = 3) -> SimpleNamespace:
    """A stub Evaluator whose PID c_u is proportional to the packed Kd, on ``n`` scenarios."""

    def scores(kind, packs):
        assert kind == KIND_PID
        return [[Indexes(e_M=1e-5, e_F=1e-6, e_rms=1e-6, u_rms=1.0, du_rms=c_u_per_kd * p[G_KD] * (1 + 0.1 * i),
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
    step = DEFAULT_SETTINGS.pid_pole_step
    k = next(k for k in range(1, DEFAULT_SETTINGS.pid_pole_steps + 1) if step ** k <= 0.8 * (1 - 1e-12))
    out = deployable_pid(ident, spec, _kd_chatter_evaluator(c), 1.0, pole_free=True)
    assert out.pole == pytest.approx(w0 * step ** k) and k == 5  # 0.95^5 = 0.774
    assert out.gains.Kd == pytest.approx(3.0 * m_min * out.pole)
    assert max(s.c_u for s in out.scores) <= 1.0 < 1.2 * c * 3.0 * m_min * w0 * step ** (k - 1)
    # a pole set in the spec is kept, and so is the default when no grid pole meets the limit
    kept = deployable_pid(ident, spec, _kd_chatter_evaluator(c), 1.0, pole_free=False)
    assert kept.pole == w0 and max(s.c_u for s in kept.scores) > 1.0
    hopeless = deployable_pid(ident, spec, _kd_chatter_evaluator(10 * c), 1.0, pole_free=True)
    assert hopeless.pole == w0 and hopeless.gains == pid_baseline(ident, spec)[0]
    # within the limit at the default pole: nothing changes
    calm = deployable_pid(ident, spec, _kd_chatter_evaluator(0.7 * c), 1.0, pole_free=True)  # worst 0.875
    assert calm.pole == w0


def test_pid_pole_note_only_when_the_baseline_moved(small):
    """The CLI's tuning of the reference plant (pid.pole defaulted) judges the ARC against the
    yardstick (the fastest PID that keeps the margin floors), recorded in tuning.json and named in
    the note; without that record, the note appears only when the baseline's pole was lowered."""
    d, output = small
    t = Tuning.from_dict(json.loads((d / "tuning.json").read_text()))
    ys = t.pid_yardstick
    assert ys is not None and ys["method"] == "margin_search" and ys["is_yardstick"] and ys["pole"] == t.pid_pole
    note = pid_pole_note(t)
    assert note is not None and "PID yardstick" in note and "PID yardstick" in output
    old = dataclasses.replace(t, pid_yardstick=None, pid_pole=t.spec.pid_pole)
    assert pid_pole_note(old) is None
    moved = dataclasses.replace(old, pid_pole=0.8 * t.spec.pid_pole)
    note = pid_pole_note(moved)
    assert note is not None and "pid.pole = 240 rad/s instead of the defaulted 300" in note


def test_cost_charges_a_transient_and_an_average_worse_than_the_pids():
    """Closed form of the two ARC-vs-PID terms of :func:`cost` on one scenario (no gate, all
    other terms zero: e_rms at its target, e_F and c_u below theirs, u below u_max):
    e_M above the PID's costs w_step + w_chatter ln(e_M / e_M_pid), e_rms above pid_margin x
    the PID's costs w_step + w_chatter ln(e_rms / (m e_rms_pid)) (the default settings); the minimax term is
    ln(e_rms / e_rms_pid).  Session 11's soft tuning lost the reference axis's start-up to the
    PID (e_M 34 against 15 um) because only the second term existed."""
    st = DEFAULT_SETTINGS
    spec = default_spec()

    def score(e_M: float, e_rms: float) -> Indexes:
        return Indexes(e_M=e_M, e_F=0.1 * spec.e_f, e_rms=e_rms, u_rms=1.0, du_rms=0.1 * spec.c_u,
                     c_u=0.1 * spec.c_u, u_peak=0.5 * spec.u_max, diverged=False)

    pid = [score(20e-6, 2 * spec.e_rms)]
    minimax = math.log(0.5)
    assert cost([score(10e-6, spec.e_rms)], spec, pid) == pytest.approx(minimax)
    assert cost([score(20e-6, spec.e_rms)], spec, pid) == pytest.approx(minimax)  # a tie is no loss
    assert cost([score(50e-6, spec.e_rms)], spec, pid) == pytest.approx(
        minimax + st.w_step + st.w_chatter * math.log(2.5))
    worse = 1.5 * 2 * spec.e_rms
    assert cost([score(10e-6, worse)], spec, pid) == pytest.approx(
        math.log(worse / spec.e_rms) + st.w_step + st.w_chatter * math.log(worse / (st.pid_margin * 2 * spec.e_rms))
        + math.log(1.5))
    # without a reference there is nothing to lose to
    assert cost([score(50e-6, spec.e_rms)], spec) == pytest.approx(0.0)


def test_pid_yardstick_record_is_additive_and_strict(small):
    """An older tuning.json without ``pid_yardstick`` still loads; a malformed record is refused by path."""
    d, _ = small
    doc = json.loads((d / "tuning.json").read_text())
    assert Tuning.from_dict(doc).pid_yardstick == doc["pid_yardstick"]
    old = {k: v for k, v in doc.items() if k != "pid_yardstick"}
    assert Tuning.from_dict(old).pid_yardstick is None
    bad = {**doc, "pid_yardstick": {**doc["pid_yardstick"], "pole": "fast"}}
    with pytest.raises(SchemaError, match=r"\$\.pid_yardstick"):
        Tuning.from_dict(bad)


def test_a_candidates_scores_do_not_depend_on_what_is_simulated_beside_it(holdout_setup):
    """The search simulates each candidate on its own, in the background (Problem.evaluate): its
    scores are the ones a batch of several candidates gives, row for row."""
    ident, spec, base, ev, hg = holdout_setup
    a, b = arc_pack(base), arc_pack(apply_free(base, [1.0] * 4 + [0.5] * 5))
    idx = screening_indices(ev.scenarios)[:6]
    together = ev.scores(KIND_ARC, [a, b], idx)
    assert together == [ev.scores(KIND_ARC, [a], idx)[0], ev.scores(KIND_ARC, [b], idx)[0]]
    assert together[0] != together[1]
