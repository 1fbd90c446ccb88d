"""commission.formats.ident_json: ident.json's one table, its strict model, its schema and its docs.

Every field of the table is walked: docs/schemas/ident.schema.json holds it at its JSON path
with its unit and doc, docs/interface.md §2 names it, and every number with a rule is refused
outside it with one error naming its JSON path.  Loading and saving keeps the bytes.
"""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import pytest

from commission.artifacts import Identification
from commission.errors import SchemaError
from commission.formats import generated as formats
from commission.formats.ident_json import IDENT_FIELDS
from commission.formats.json_table import build_json_model, markdown_rows
from commission.formats.table import json_schema
from commission.jsonio import canonical_json
from commission.paper import reference_identification

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_FILE = ROOT / "docs" / "schemas" / "ident.schema.json"
INTERFACE = ROOT / "docs" / "interface.md"


def _doc() -> dict:
    """A full ident.json: the paper's identification with every optional object the table checks."""
    d = reference_identification(source={"sha256": "ab" * 32, "sample_rate": 2500.0, "n_samples": 10}).to_dict()
    d["encoder"] = {"quantization": 1e-6, "noise_std": 1e-7, "apparent_resolution": 1e-6}
    d["model"] = {"ripple_pitch": 0.03, "ripple_amp": {"value": 0.1, "std": 0.01}}
    d["ripple"] = {"pitch": 0.03, "amplitude": 0.1}
    d["bounds"] = {"disturbance_bound": 1.0, "disturbance_bound_defaulted": True,
                   "narrowed_by_tune": {"theta3_min": -1.0, "theta3_max": 1.0, "u_max": 10.0}}
    d["frequency_response"] = {"model": {"delay_s": 1e-4, "mode_hz": 300.0, "mode_damping": 0.05,
                                         "mode_ratio": 0.2, "mode_load_side": True, "mode2_hz": 800.0,
                                         "mode2_damping": 0.05, "mode2_ratio": 0.1, "mode2_load_side": False}}
    d["log_sha256"], d["quantization"], d["warnings"] = "cd" * 32, 1e-6, ["a sentence"]
    return d


def _set(doc: dict, path: str, value) -> dict:
    node = doc
    *head, last = path.split(".")
    for k in head:
        node = node[k]
    node[last] = value
    return doc


def _schema_prop(schema: dict, path: str) -> dict:
    """The schema of the field at dotted ``path``, following ``$ref`` through nullable objects."""
    node = schema
    for part in path.split("."):
        if "$ref" not in node and "anyOf" in node:
            node = next(a for a in node["anyOf"] if "$ref" in a)
        if "$ref" in node:
            node = schema["$defs"][node["$ref"].split("/")[-1]]
        node = node["properties"][part]
    return node


def test_the_full_document_loads_and_saves_byte_identical():
    doc = _doc()
    assert canonical_json(Identification.from_dict(copy.deepcopy(doc)).to_dict()) == canonical_json(doc)
    sm = Identification.from_dict(doc).structural_model()
    assert (sm.mode_hz, sm.mode2_ratio, sm.mode_load_side) == (300.0, 0.1, True)


def test_schema_file_and_docs_block_are_the_table():
    assert SCHEMA_FILE.read_text() == formats.schema_text(formats.schemas()["ident.schema.json"]), (
        "docs/schemas/ident.schema.json is stale: run `python -m commission.formats`")
    text = INTERFACE.read_text()
    assert formats.fill_markdown(text, formats.tables()) == text


def test_every_field_is_in_the_schema_and_in_interface_md_section_2():
    schema = json.loads(SCHEMA_FILE.read_text())
    section = INTERFACE.read_text().split("## 2. `ident.json`")[1].split("## 3.")[0]
    assert len({f.path for f in IDENT_FIELDS}) == len(IDENT_FIELDS)  # every field once
    for f in IDENT_FIELDS:
        prop = _schema_prop(schema, f.path)
        assert prop["description"] == f.doc and prop.get("unit", "") == f.unit, f.path
        assert f"| `{f.path}` | {f.type} |" in section, f.path
        parent = schema if not f.parent else schema["$defs"][
            _schema_prop(schema, f.parent).get("$ref", next((a.get("$ref") for a in _schema_prop(
                schema, f.parent).get("anyOf", []) if "$ref" in a), "")).split("/")[-1]]
        assert (f.name in parent.get("required", [])) == f.required, f.path
        if f.sign == "positive":
            assert prop.get("exclusiveMinimum", _inner(prop).get("exclusiveMinimum")) == 0, f.path
        if f.range is not None:
            inner = _inner(prop)
            assert (inner["minimum"], inner["maximum"]) == f.range, f.path


def _inner(prop: dict) -> dict:
    return next((a for a in prop.get("anyOf", []) if a.get("type") != "null"), prop)


def test_changing_a_row_changes_schema_and_docs():
    changed = tuple(dataclasses.replace(f, unit="parsec") if f.path == "delta_d" else f for f in IDENT_FIELDS)
    schema = json_schema(build_json_model("IdentJson", changed, ""), "x", 1)
    assert schema["properties"]["delta_d"]["unit"] == "parsec"
    assert "| `delta_d` | number | >= 0 | parsec |" in markdown_rows(changed)
    assert formats.fill_markdown(INTERFACE.read_text(), {"ident.json fields": markdown_rows(changed)}) != \
        INTERFACE.read_text()


RULED = [f for f in IDENT_FIELDS if f.type in ("number", "integer") and (f.sign or f.range)]


@pytest.mark.parametrize("field", RULED, ids=[f.path for f in RULED])
def test_every_ruled_number_is_refused_outside_its_rule_naming_its_path(field):
    bad = -1 if field.sign == "nonneg" or field.range else 0
    if field.range is not None:
        bad = field.range[1] * 2 + 1
    with pytest.raises(SchemaError) as exc:
        Identification.from_dict(_set(_doc(), field.path, bad))
    line = str(exc.value)
    assert line.startswith(f"ident.json: $.{field.path}: ") and "\n" not in line, line
    with pytest.raises(SchemaError, match=rf"\$\.{field.path.replace('.', '[.]')}: expected a"):
        Identification.from_dict(_set(_doc(), field.path, "abc"))


@pytest.mark.parametrize("path, value, why", [
    ("theta.min", [1.0, 2.0], "$.theta.min: expected 3 numbers, got 2"),
    ("theta.max", [1.0, 2.0, "x"], "$.theta.max[2]: expected a finite number, got 'x'"),
    ("source.sha256", ["ab" * 32, "zz"], "$.source.sha256[1]: expected a sha256"),
    ("model.ripple_amp", {"value": 1.0, "std": -1.0}, "$.model.ripple_amp.std: expected a non-negative number"),
    ("bounds.narrowed_by_tune", {"theta3_min": 2.0, "theta3_max": 1.0}, "$.bounds.narrowed_by_tune: theta3_min 2.0 "
                                                                       "exceeds theta3_max 1.0"),
    ("frequency_response.model.mode_damping", 1.0, "$.frequency_response.model.mode_damping: expected a damping "
                                                   "ratio below 1"),
    ("frequency_response.model.mode2_ratio", 0.9, "$.frequency_response.model.mode2_ratio: expected mode_ratio + "
                                                  "mode2_ratio below 1"),
    ("frequency_response.model.mode_ratio", None, "$.frequency_response.model.mode_ratio: missing required field"),
    ("fit.relative_error", None, "$.fit.relative_error: missing required field"),
    ("kind", "tuning", "$.kind: expected kind 'identification'"),
    ("schema_version", 2, "$.schema_version: unsupported schema_version 2"),
])
def test_rules_beyond_a_number_name_their_path(path, value, why):
    with pytest.raises(SchemaError) as exc:
        Identification.from_dict(_set(_doc(), path, value))
    assert str(exc.value).startswith("ident.json: " + why), str(exc.value)


def test_older_and_newer_files_load_additive_keys_kept():
    lean = reference_identification().to_dict()  # schema_version 1, no source, encoder, bounds, ...
    assert Identification.from_dict(lean).extra == {}
    newer = _set(_doc(), "a_key_of_a_later_version", {"x": 1})
    newer["encoder"]["another"] = 2
    ident = Identification.from_dict(copy.deepcopy(newer))
    assert canonical_json(ident.to_dict()) == canonical_json(newer)
    with pytest.raises(SchemaError, match=r"\$\.units\.extra: unknown field"):
        Identification.from_dict(_set(_doc(), "units.extra", "V"))
