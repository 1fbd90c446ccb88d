"""Issue 29, items 5 and 7 for files: the JSON artifacts are validated when loaded, never patched up.

- the one JSON reader refuses duplicate keys, over-long integers and non-finite numbers at parse
  time, naming the JSON path;
- ident.json (and the identification tuning.json embeds): a present optional field with a bad
  value is refused, naming its path; an absent one takes its documented default; units come from
  a fixed vocabulary;
- controller.json: the sample rate and u_max within the spec's plausible ranges;
- tuning.json travelling without its ident.json: the embedded identification is checked against
  ``provenance.ident_sha256``;
- :class:`commission.runtime.Controller` names a non-numeric argument with the project's error.
"""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from commission.artifacts import UNIT_VOCABULARY_Q, UNIT_VOCABULARY_U, Identification
from commission.cli.main import app
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.errors import SchemaError, UsageError
from commission.jsonio import MAX_INT_DIGITS, canonical_json, read_json, sha256_json, write_json_atomic
from commission.paper import reference_identification
from commission.runtime import Controller, load_controller
from commission.scenarios import resolve_quantization
from commission.spec import DEFAULT_QUANTIZATION, RANGES, default_spec
from commission.tune.defaults import log_sample_rate
from commission.tune.gains import base_arc_gains
from commission.tuning import Tuning
from commission.validate import check_provenance
from controller_docs import reseal

TUNING_DOC = json.loads((Path(__file__).parent / "data" / "tuning_paper_budget8.json").read_text())
runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def refused(r, fragment: str) -> None:
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], r.stderr
    assert "Traceback" not in r.output


# --------------------------------------------------------------------------- the JSON reader


@pytest.mark.parametrize("text, path, why", [
    ('{"a": {"b": 1, "b": 2}}', "$.a.b", "duplicate key"),
    ('{"a": [{"c": 1}, {"d": {"e": 2, "e": 2}}]}', "$.a[1].d.e", "duplicate key"),
    ('{"x": ' + "9" * 400 + "}", "$.x", "integer literal of 400 digits"),
    ('{"x": -' + "1" * (MAX_INT_DIGITS + 1) + "}", "$.x", f"integer literal of {MAX_INT_DIGITS + 1} digits"),
    ('{"x": [1, NaN]}', "$.x[1]", "NaN is not a JSON number"),
    ('{"x": Infinity}', "$.x", "Infinity is not a JSON number"),
    ('-Infinity', "$", "-Infinity is not a JSON number"),
    ('{"x": 1e999}', "$.x", "beyond the range of a float"),
])
def test_read_json_refuses_what_json_leaves_ambiguous_naming_the_path(tmp_path, text, path, why):
    p = tmp_path / "x.json"
    p.write_text(text)
    with pytest.raises(SchemaError) as exc:
        read_json(p)
    assert str(exc.value).startswith(f"{p}: {path}: ") and why in str(exc.value)


def test_read_json_keeps_the_largest_integers_the_tool_writes(tmp_path):
    p = tmp_path / "x.json"
    p.write_text('{"seed": 9223372036854775807, "n": -' + "9" * MAX_INT_DIGITS + ', "f": 1.5e300}')
    assert read_json(p) == {"seed": 2**63 - 1, "n": -int("9" * MAX_INT_DIGITS), "f": 1.5e300}


# --------------------------------------------------------------------------- ident.json


def _ident_doc(**extra):
    return reference_identification(source={"sha256": "ab" * 32, "sample_rate": 2500.0}, **extra).to_dict()


def _set(doc, dotted: str, value):
    node = doc
    *head, last = dotted.split(".")
    for k in head:
        node = node.setdefault(k, {})
    node[last] = value
    return doc


BAD_IDENT = [
    ("encoder.quantization", -1e-6, "must be within [0, 0.01] m"),
    ("encoder.quantization", 1.0, "must be within [0, 0.01] m"),
    ("encoder.quantization", "1um", "expected a finite number"),
    ("quantization", -1e-6, "must be within"),
    ("encoder.noise_std", -1.0, "must be within"),
    ("source.sample_rate", "fast", "expected a finite number"),
    ("source.sample_rate", 0, "expected a positive number"),
    ("source.sha256", "not-a-digest", "expected a sha256"),
    ("units.u", "parsec", "expected one of"),
    ("units.u", "v", "expected one of"),
    ("units.q", "mm", "expected one of"),
    ("units.extra", "V", "unknown field"),
    ("model.ripple_pitch", -0.03, "expected a positive number"),
    ("parameters.vs.value", -0.01, "expected a positive number"),
    ("parameters.xi.value", 0.0, "expected a positive number"),
    ("bounds.disturbance_bound_defaulted", "yes", "expected true or false"),
    ("not_identified", [], "expected an object"),
    ("warnings", "none", "expected a list of strings"),
]


@pytest.mark.parametrize("key, value, why", BAD_IDENT)
def test_a_present_bad_value_in_ident_json_is_refused_naming_its_path(key, value, why):
    with pytest.raises(SchemaError) as exc:
        Identification.from_dict(_set(_ident_doc(), key, value))
    assert f"ident.json: $.{key}: " in str(exc.value) and why in str(exc.value)


@pytest.mark.parametrize("key, value", [("encoder.quantization", -1e-6), ("source.sample_rate", "fast"),
                                        ("units.u", "parsec")])
def test_tune_refuses_the_edited_ident_json_of_the_issue(tmp_path, key, value):
    """What tune used to replace silently (1 um, 2500 Hz) or accept ('parsec') is exit 2, nothing written."""
    ipath = tmp_path / "ident.json"
    write_json_atomic(ipath, _set(_ident_doc(), key, value))
    (tmp_path / "spec.toml").write_text("[tune]\nbudget = 3\n")
    out = tmp_path / "out"
    refused(invoke("tune", ipath, "--out", out / "tuning.json", "--spec", tmp_path / "spec.toml"), f": $.{key}: ")
    assert not out.exists()


def test_absent_optional_fields_take_their_documented_defaults():
    doc = reference_identification().to_dict()  # no source, no encoder
    ident = Identification.from_dict(doc)
    assert resolve_quantization(ident, default_spec()) == DEFAULT_QUANTIZATION and log_sample_rate(ident) is None
    doc = _set(_set(_ident_doc(), "encoder.quantization", 5e-7), "source.sample_rate", 4000)
    ident = Identification.from_dict(doc)
    assert resolve_quantization(ident, default_spec()) == 5e-7 and log_sample_rate(ident) == 4000.0
    null = _set(_ident_doc(), "encoder.quantization", None)  # identify writes null: no step measured
    assert resolve_quantization(Identification.from_dict(null), default_spec()) == DEFAULT_QUANTIZATION


@pytest.mark.parametrize("u", UNIT_VOCABULARY_U)
@pytest.mark.parametrize("q", UNIT_VOCABULARY_Q)
def test_every_unit_the_tool_writes_is_read_back(u, q):
    assert Identification.from_dict(_set(_set(_ident_doc(), "units.u", u), "units.q", q)).units == {"u": u, "q": q}


def test_vocabulary_is_what_identify_accepts():
    from commission.identification import U_UNITS as IDENTIFY_U_UNITS

    assert set(UNIT_VOCABULARY_U) == set(IDENTIFY_U_UNITS) == {"V", "N", "A", "Nm", "%"}


# --------------------------------------------------------------------------- tuning.json


@pytest.mark.parametrize("edit, path", [
    (lambda d: _set(d["identification"], "encoder.quantization", -1e-6), "$.identification.encoder.quantization"),
    (lambda d: _set(d["identification"], "units.u", "parsec"), "$.identification.units.u"),
    (lambda d: _set(d, "plant.quantization", 0.5), "$.plant.quantization"),
    (lambda d: _set(d, "arc.u_max", 1e308), "$.arc.u_max"),
    (lambda d: _set(d, "provenance.ident_sha256", "x" * 64), "$.provenance.ident_sha256"),
])
def test_tuning_json_is_as_strict_as_ident_json(edit, path):
    doc = copy.deepcopy(TUNING_DOC)
    edit(doc)
    with pytest.raises(SchemaError, match="tuning\\.json: " + re.escape(path) + ": "):
        Tuning.from_dict(doc)


def _alone(tmp_path, doc):
    doc["provenance"]["ident_path"] = str(tmp_path / "gone" / "ident.json")
    p = tmp_path / "tuning.json"
    write_json_atomic(p, doc)
    return p


def test_a_tuning_travelling_alone_is_checked_against_its_ident_sha256(tmp_path):
    p = _alone(tmp_path, copy.deepcopy(TUNING_DOC))
    check_provenance(Tuning.load(str(p)), str(p))  # as tune wrote it: passes
    doc = copy.deepcopy(TUNING_DOC)
    theta = doc["identification"]["theta"]
    for i in (1, 2):  # theta2, theta3 box shrunk to +-0.1 % (theta1's is tied to pid.design_mass)
        theta["min"][i] = theta["nominal"][i] - 1e-3 * max(abs(theta["nominal"][i]), 1.0)
        theta["max"][i] = theta["nominal"][i] + 1e-3 * max(abs(theta["nominal"][i]), 1.0)
    p = _alone(tmp_path, doc)
    out = tmp_path / "out"
    refused(invoke("validate", p, "--out-dir", out, "--monte-carlo", 0), ": $.identification: hashes to")
    assert not out.exists()


def test_tune_narrowing_is_undone_before_the_hash_and_only_tunes(tmp_path):
    identified = copy.deepcopy(TUNING_DOC["identification"])
    identified["bounds"] = {"disturbance_bound": 1.0, "disturbance_bound_defaulted": True}
    doc = copy.deepcopy(TUNING_DOC)
    doc["provenance"]["ident_sha256"] = sha256_json(identified)  # the ident.json identify wrote
    emb = doc["identification"] = copy.deepcopy(identified)
    m_light = 1.0 / emb["theta"]["max"][0]
    emb["theta"]["min"][2], emb["theta"]["max"][2] = -5.0, 5.0  # tune's narrowing, and its record
    emb["bounds"]["narrowed_by_tune"] = {"theta3_min": -50.0, "theta3_max": 50.0, "u_max": 10.0,
                                         "force_range": [-1.0, 1.0], "narrowed_force_range": [-5 * m_light, 5 * m_light]}
    p = _alone(tmp_path, doc)
    check_provenance(Tuning.load(str(p)), str(p))
    emb["theta"]["min"][2], emb["theta"]["max"][2] = -0.5, 0.5  # shrunk further by hand, the record untouched
    p = _alone(tmp_path, doc)
    with pytest.raises(SchemaError, match=r"\$\.identification: hashes to"):
        check_provenance(Tuning.load(str(p)), str(p))


# --------------------------------------------------------------------------- controller.json


@pytest.fixture(scope="module")
def controller_doc():
    g = base_arc_gains(reference_identification(delta_d=0.5), default_spec())
    prov = ControllerProvenance(log_sha256="a" * 64, ident_sha256="b" * 64, tuning_sha256="c" * 64,
                                tool_version="test", created_utc="2001-06-01T00:00:00Z")
    return ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"}, validated={},
                            provenance=prov).to_dict()


def _write(tmp_path, doc):
    p = tmp_path / "controller.json"
    write_json_atomic(p, doc)
    return p


@pytest.mark.parametrize("rate", [1e-3, 1e9])
def test_load_controller_refuses_an_implausible_sample_rate(tmp_path, controller_doc, rate):
    doc = copy.deepcopy(controller_doc)
    doc["sample_rate"], doc["sample_period"] = rate, 1.0 / rate
    with pytest.raises(SchemaError, match=r"\$\.sample_rate: .* outside the plausible range \[1, 100000\] Hz"):
        load_controller(_write(tmp_path, reseal(doc)))


@pytest.mark.parametrize("u_max", [1e308, 1e7, 1e-9])
def test_load_controller_refuses_an_implausible_u_max(tmp_path, controller_doc, u_max):
    doc = copy.deepcopy(controller_doc)
    doc["bounds"]["u_max"] = u_max
    lo, hi = RANGES[("controller", "u_max")]
    with pytest.raises(SchemaError, match=r"\$\.bounds\.u_max: .* V is outside the plausible range "
                                          + re.escape(f"[{lo:g}, {hi:g}] V")):
        load_controller(_write(tmp_path, reseal(doc)))


def test_export_refuses_an_unclamped_controller(tmp_path, controller_doc):
    doc = copy.deepcopy(controller_doc)
    doc["bounds"]["u_max"] = 1e308
    out = tmp_path / "out"
    refused(invoke("export", _write(tmp_path, reseal(doc)), "--out-dir", out), ": $.bounds.u_max: ")
    assert not out.exists() or not any(out.iterdir())


def test_load_controller_names_a_huge_integer_instead_of_overflowing(tmp_path, controller_doc):
    doc = copy.deepcopy(controller_doc)
    doc["bounds"]["u_max"] = int("9" * 400)
    p = tmp_path / "controller.json"
    p.write_text(canonical_json(reseal(doc)))
    with pytest.raises(SchemaError, match=r"controller\.json: \$\.bounds\.u_max: an integer literal of 400 digits"):
        load_controller(p)


def test_a_signed_controller_with_a_duplicate_key_is_refused(tmp_path, controller_doc):
    key = b"k" * 32
    doc = reseal(copy.deepcopy(controller_doc), key)
    text = canonical_json(doc)
    # a second u_max before the signed one: Python would keep the last (the signed value) and verify
    text = text.replace('"u_max": ', '"u_max": 1e308,\n    "u_max": ', 1)
    p = tmp_path / "controller.json"
    p.write_text(text)
    with pytest.raises(SchemaError, match=r"\$\.bounds\.u_max: duplicate key"):
        load_controller(p, key=key)
    p.write_text(canonical_json(doc))
    load_controller(p, key=key)  # the file as signed verifies


def test_controller_units_and_digests_are_whitelisted(tmp_path, controller_doc):
    for edit, path in ((lambda d: _set(d, "units.u", "V\n#define X"), r"\$\.units\.u"),
                       (lambda d: _set(d, "units.q", "in"), r"\$\.units\.q"),
                       (lambda d: _set(d, "provenance.tuning_sha256", "*/" + "0" * 62), r"\$\.provenance\.tuning_sha256")):
        doc = copy.deepcopy(controller_doc)
        edit(doc)
        with pytest.raises(SchemaError, match=path + ": expected"):
            load_controller(_write(tmp_path, reseal(doc)))


# --------------------------------------------------------------------------- runtime


@pytest.fixture(scope="module")
def ctrl(controller_doc, tmp_path_factory):
    c = load_controller(_write(tmp_path_factory.mktemp("ctrl"), copy.deepcopy(controller_doc)))
    c.reset(0.0)
    return c


@pytest.mark.parametrize("args, name", [(("abc", 0, 0, 0), "y"), ((0, None, 0, 0), "qd"), ((0, 0, [1], 0), "dqd"),
                                        ((0, 0, 0, 10**400), "ddqd")])
def test_step_names_a_non_numeric_argument(ctrl, args, name):
    with pytest.raises(UsageError, match=rf"^step: {name} must be a number") as exc:
        ctrl.step(*args)
    assert isinstance(exc.value, ValueError)
    assert not ctrl.fault  # a caller's bug, refused: not a measurement fault


def test_reset_names_a_non_numeric_position(controller_doc, tmp_path):
    c = Controller(ControllerConfig.from_dict(copy.deepcopy(controller_doc)))
    with pytest.raises(UsageError, match=r"^reset: y0 must be a number in m, got str 'abc'"):
        c.reset("abc")
    with pytest.raises(UsageError, match="call reset"):
        c.step(0.0, 0.0, 0.0, 0.0)  # the refused reset did not start it
