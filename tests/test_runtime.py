"""controller.json and its runtime: exact replay of the simulated controller, refusal of bad files."""

import copy
import dataclasses
import hashlib
import json
import math

import numpy as np
import pytest

from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.controllers.plant import plant_vector
from commission.controllers.simulate import KIND_ARC, simulate, step_disturbance
from commission.controllers.arc import arc_pack
from commission.controllers.trajectory import back_and_forth, sinusoid
from commission.errors import InputFileError, SchemaError, UsageError
from commission.jsonio import read_json, write_json_atomic
from commission.paper import reference_identification
from commission.runtime import load_controller
from commission.spec import default_spec
from commission.tune.gains import base_arc_gains

PLANT = plant_vector(0.027, 0.273, 0.10, 0.12, 0.01, 2.0, 0.0, 0.01, 0.03)


@pytest.fixture(scope="module")
def gains():
    return base_arc_gains(reference_identification(delta_d=0.5), default_spec())


def config(g, **validated):
    prov = ControllerProvenance(log_sha256="a" * 64, ident_sha256="b" * 64, tuning_sha256="c" * 64,
                                tool_version="test", created_utc="2001-06-01T00:00:00Z")
    return ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"},
                            validated=dict(validated), provenance=prov)


def write(tmp_path, g, name="controller.json"):
    p = tmp_path / name
    write_json_atomic(p, config(g).to_dict())
    return p


def replay(ctrl, sim, traj):
    ctrl.reset(sim.y[0])
    return np.array([ctrl.step(sim.y[k], traj.qd[k], traj.dqd[k], traj.ddqd[k]) for k in range(sim.n_steps)])


@pytest.mark.parametrize("case", ["case1_disturbance", "case2_offset_start", "case1_saturating"])
def test_loaded_controller_replays_the_simulation_bit_for_bit(tmp_path, gains, case):
    g = gains
    y0 = 0.0
    dist = None
    if case == "case1_disturbance":
        traj = sinusoid(10.0, g.Ts)
        dist = step_disturbance(traj.t, [(2.2, 7.2, 0.5)])
    elif case == "case2_offset_start":
        y0 = 0.0123456
        traj = back_and_forth(8.0, g.Ts, start=y0)
    else:
        g = dataclasses.replace(g, u_max=0.25)  # the ARC's own output limit is active
        traj = sinusoid(4.0, g.Ts)
    sim = simulate(PLANT, KIND_ARC, arc_pack(g), traj, quant=1e-6, disturbance=dist, y0=y0)
    assert not sim.diverged and sim.n_steps == traj.n
    if case == "case1_saturating":
        assert np.max(np.abs(sim.u)) == 0.25  # the limit was reached, so clipping is part of the replay
    ctrl = load_controller(write(tmp_path, g))
    u = replay(ctrl, sim, traj)
    assert np.array_equal(u, sim.u)
    assert np.array_equal(ctrl.theta_hat, sim.theta_hat[-1])


def test_runtime_api(tmp_path, gains):
    ctrl = load_controller(str(write(tmp_path, gains)))
    assert ctrl.sample_rate == pytest.approx(2500.0) and ctrl.sample_period == gains.Ts
    with pytest.raises(UsageError, match="call reset"):
        ctrl.step(0.0, 0.0, 0.0, 0.0)
    with pytest.raises(UsageError, match="y0 must be a finite"):
        ctrl.reset(math.nan)
    ctrl.reset(0.001)
    assert np.array_equal(ctrl.theta_hat, np.array(gains.theta0))
    u = ctrl.step(0.001, 0.001, 0.0, 0.0)
    assert isinstance(u, float) and math.isfinite(u)
    # a non-finite measurement latches the fault: the command is 0 until reset
    assert ctrl.step(math.nan, 0.0, 0.0, 0.0) == 0.0
    assert ctrl.step(0.001, 0.001, 0.0, 0.0) == 0.0
    ctrl.reset(0.001)
    assert ctrl.step(0.001, 0.001, 0.0, 0.0) == u


def test_file_layout_and_checksum_definition(tmp_path, gains):
    g = dataclasses.replace(gains, eps11=math.inf)
    p = write(tmp_path, g)
    doc = read_json(p)
    for section in ("observer", "gains", "bounds", "adaptation", "initial_estimates", "friction_compensation",
                    "provenance", "validated", "checksum"):
        assert section in doc
    assert doc["sample_rate"] == 2500.0 and doc["sample_period"] == g.Ts
    assert doc["observer"] == {"k1": g.k1, "k2": g.k2}
    assert doc["gains"]["eps11"] is None  # a term switched off: inf as null
    assert doc["adaptation"]["Gamma"] == list(g.Gamma)
    assert set(doc["provenance"]) == {"log_sha256", "ident_sha256", "tuning_sha256", "tool_version", "created_utc"}
    # the checksum is sha256 of the sorted, 2-space-indented JSON of everything else
    body = {k: v for k, v in doc.items() if k != "checksum"}
    text = json.dumps(body, sort_keys=True, indent=2) + "\n"
    assert doc["checksum"] == {"algorithm": "sha256", "value": hashlib.sha256(text.encode()).hexdigest()}
    assert ControllerConfig.load(str(p)).gains == g


def test_the_file_states_its_control_law_and_a_file_without_the_statement_loads(tmp_path, gains):
    doc = read_json(write(tmp_path, gains))
    law = doc["control_law"]
    assert law["paper"].startswith("Xu L., Yao B. (2001)") and "Automatica 37" in law["paper"]
    # equations by number, and the filter structure
    assert "(18)" in law["observer_filters"] and "A0 = [[-k1, 1], [-k2, 0]]" in law["observer_filters"]
    assert "(43)" in law["step2"] and "(19)" in law["adaptation"] and "(5)" in law["output"]
    # the statement is additive: a file written before it existed still loads
    del doc["control_law"]
    p = tmp_path / "old.json"
    p.write_text(json.dumps(_rehash(doc)))
    assert load_controller(p).config.gains == gains


def _rehash(doc):
    body = {k: v for k, v in doc.items() if k != "checksum"}
    text = json.dumps(body, sort_keys=True, indent=2) + "\n"
    doc["checksum"] = {"algorithm": "sha256", "value": hashlib.sha256(text.encode()).hexdigest()}
    return doc


@pytest.mark.parametrize(
    "edit",
    [
        lambda d: d["gains"].__setitem__("g1", d["gains"]["g1"] * 0.9999),
        lambda d: d["bounds"]["theta_max"].__setitem__(0, 500.0),
        lambda d: d["provenance"].__setitem__("tool_version", "9.9"),
        lambda d: d["validated"].__setitem__("extra", 1),
    ],
)
def test_tampered_file_is_refused_by_checksum(tmp_path, gains, edit):
    p = write(tmp_path, gains)
    doc = read_json(p)
    edit(doc)
    p.write_text(json.dumps(doc))
    with pytest.raises(SchemaError, match=r"controller\.json: \$\.checksum: mismatch"):
        load_controller(p)


@pytest.mark.parametrize(
    "edit, path",
    [
        (lambda d: d["gains"].pop("g1"), r"\$\.gains\.g1: missing required field"),
        (lambda d: d["gains"].__setitem__("g2", -850.0), r"\$\.gains\.g2: ArcGains\.g2: must be > 0"),
        (lambda d: d["bounds"]["theta_min"].__setitem__(1, "low"), r"\$\.bounds\.theta_min\[1\]: expected a finite number"),
        (lambda d: d["bounds"].__setitem__("theta_max", [50.0, 17.5]), r"\$\.bounds\.theta_max: expected 3 numbers"),
        (lambda d: d["initial_estimates"].__setitem__("theta0", [99.0, 10.0, 0.0]),
         r"\$\.initial_estimates\.theta0: ArcGains\.theta0\[0\]: 99\.0 outside"),
        (lambda d: d["observer"].__setitem__("k1", None), r"\$\.observer\.k1: missing required field"),
        (lambda d: d.__setitem__("sample_period", 1e-3), r"\$\.sample_period: 0\.001 s does not match sample_rate"),
        (lambda d: d.__setitem__("kind", "tuning"), r"\$\.kind: expected kind 'controller'"),
        (lambda d: d.__setitem__("schema_version", 7), r"\$\.schema_version: unsupported schema_version 7"),
        (lambda d: d["gains"].__setitem__("gamma", 1.0), r"\$\.gains\.gamma: unknown field"),
        (lambda d: d["friction_compensation"].__setitem__("level", -0.1), r"\$\.friction_compensation\.level: expected a non-negative"),
        (lambda d: d["provenance"].pop("tuning_sha256"), r"\$\.provenance\.tuning_sha256: missing required field"),
        (lambda d: d["control_law"].__setitem__("step2", "u* = -K2 z2"),
         r"\$\.control_law: describes a control law this runtime does not implement"),
    ],
)
def test_schema_broken_file_is_refused_naming_the_json_path(tmp_path, gains, edit, path):
    # Re-hash after the edit, so that only the schema check can refuse it.
    p = write(tmp_path, gains)
    doc = read_json(p)
    edit(doc)
    p.write_text(json.dumps(_rehash(doc)))
    with pytest.raises(SchemaError, match=path):
        load_controller(p)


def test_missing_or_malformed_checksum_and_file(tmp_path, gains):
    doc = config(gains).to_dict()
    d = copy.deepcopy(doc)
    d.pop("checksum")
    with pytest.raises(SchemaError, match=r"\$\.checksum: missing required field"):
        ControllerConfig.from_dict(d)
    d = copy.deepcopy(doc)
    d["checksum"]["algorithm"] = "md5"
    with pytest.raises(SchemaError, match=r"\$\.checksum\.algorithm: unsupported algorithm 'md5'"):
        ControllerConfig.from_dict(d)
    d = copy.deepcopy(doc)
    d["checksum"]["value"] = "xyz"
    with pytest.raises(SchemaError, match=r"\$\.checksum\.value: expected 64 lowercase hex digits"):
        ControllerConfig.from_dict(d)
    with pytest.raises(InputFileError, match="no such file"):
        load_controller(tmp_path / "nope.json")
    (tmp_path / "garbage.json").write_text("{not json")
    with pytest.raises(SchemaError, match="not valid JSON"):
        load_controller(tmp_path / "garbage.json")
