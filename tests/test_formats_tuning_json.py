"""commission.formats.tuning_json: tuning.json's one table, its strict model, its schema and its docs.

Every field of the table is walked through docs/schemas/tuning.schema.json and docs/interface.md §3;
the names the table writes down (so as not to import simulation code) are checked against the
controllers; every required field is refused when absent, naming its JSON path; a load keeps the bytes.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import re
from pathlib import Path

import pytest

from commission.controllers.arc import RUNTIME_GUARDS, ArcGains
from commission.controllers.pid import PidGains
from commission.controllers.plant import PLANT_NAMES
from commission.errors import SchemaError
from commission.formats import generated as formats
from commission.formats import tuning_json as tj
from commission.jsonio import canonical_json
from commission.tuning import Tuning

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_FILE = ROOT / "docs" / "schemas" / "tuning.schema.json"
INTERFACE = ROOT / "docs" / "interface.md"
DOC = json.loads((ROOT / "tests" / "data" / "tuning_paper_budget8.json").read_text())


def test_the_names_the_table_writes_are_the_controllers():
    assert tj.PLANT_NAMES == PLANT_NAMES
    arc = [n for n, _, _ in tj.ARC_GAINS] + list(tj.ARC_VECTORS) + [n for n, _, _ in tj.ARC_TAIL]
    assert arc + [n for n, _ in tj.ARC_GUARDS] == [f.name for f in dataclasses.fields(ArcGains)]
    assert [n for n, _ in tj.ARC_GUARDS] == list(RUNTIME_GUARDS)
    assert [n for n, _, _ in tj.PID_GAINS] == [f.name for f in dataclasses.fields(PidGains)]


def test_a_load_saves_byte_identical():
    # the stored file predates the plant's second mode: its first load adds those entries at their defaults
    first = Tuning.from_dict(copy.deepcopy(DOC)).to_dict()
    assert {k: v for k, v in first["plant"].items() if k not in DOC["plant"]} == {
        "mode2_damping": 0.0, "mode2_hz": 0.0, "mode2_load_side": 0.0, "mode2_ratio": 0.0}
    assert canonical_json(Tuning.from_dict(copy.deepcopy(first)).to_dict()) == canonical_json(first)


def test_schema_file_and_docs_block_are_the_table():
    assert SCHEMA_FILE.read_text() == formats.schema_text(formats.schemas()["tuning.schema.json"]), (
        "docs/schemas/tuning.schema.json is stale: run `python -m commission.formats`")
    section = INTERFACE.read_text().split("## 3. `tuning.json`")[1].split("## 4.")[0]
    schema = json.loads(SCHEMA_FILE.read_text())
    assert len({f.path for f in tj.TUNING_FIELDS}) == len(tj.TUNING_FIELDS)
    for f in tj.TUNING_FIELDS:
        assert f"| `{f.path}` | {f.type} |" in section, f.path
        node = schema
        for part in f.path.split("."):
            node = _resolve(schema, node)
            node = node["additionalProperties"] if part == "*" else node["properties"][part]
        if f.name == "*":  # a map's entries: their object's schema, whose fields are the rows below
            assert set(_resolve(schema, node)["properties"]) == {g.name for g in tj.TUNING_FIELDS
                                                                  if g.parent == f.path}, f.path
            continue
        assert node["description"] == f.doc and node.get("unit", "") == f.unit, f.path


def _resolve(schema: dict, node: dict) -> dict:
    if "$ref" not in node and "anyOf" in node:
        node = next(a for a in node["anyOf"] if "$ref" in a or a.get("type") == "object")
    if "$ref" in node:
        node = schema["$defs"][node["$ref"].split("/")[-1]]
    return node


def _delete(doc: dict, path: str, key_of_star: dict) -> bool:
    node = doc
    *head, last = path.split(".")
    for k in head:
        k = key_of_star.get(id(node), k) if k == "*" else k
        if k == "*":
            k = next(iter(node))
        node = node[k]
    if last == "*" or last not in node:
        return False
    del node[last]
    return True


REQUIRED = [f for f in tj.TUNING_FIELDS if f.required and "*" not in f.path.rsplit(".", 1)[-1]]


@pytest.mark.parametrize("field", REQUIRED, ids=[f.path for f in REQUIRED])
def test_every_required_field_is_refused_when_absent_naming_its_path(field):
    doc = copy.deepcopy(DOC)
    assert _delete(doc, field.path, {}), field.path
    with pytest.raises(SchemaError) as exc:
        Tuning.from_dict(doc)
    pattern = re.escape("tuning.json: $." + field.path).replace(r"\*", r"[^.]+")
    assert re.match(pattern + ": missing required field$", str(exc.value)), str(exc.value)


@pytest.mark.parametrize("path, value, why", [
    ("observer.P", [[1.0, 0.0], [0.0]], "$.observer.P[1]: expected a list of 2 numbers"),
    ("theorem1.ratios", [[1.0, 2.0, "x"], [1.0, 1.0, 1.0]], "$.theorem1.ratios[0][2]: expected a finite number"),
    ("search.history", [1.0, None, "x"], "$.search.history[2]: expected a number or null, got 'x'"),
    ("search.levels", [0, -1], "$.search.levels[1]: expected a non-negative integer, got -1"),
    ("search.screened", [True, 1], "$.search.screened[1]: expected a boolean, got 1"),
    ("search.other_search", {}, "$.search.other_search.bandwidth_factor: expected a positive finite number"),
    ("search.other_search", {"bandwidth_factor": 0.5, "n_evaluations": 48, "n_feasible": -1},
     "$.search.other_search.n_feasible: expected a non-negative integer, got -1"),
    ("search.other_search", [1.0], "$.search.other_search: expected an object"),
    ("arc.g9", 1.0, "$.arc.g9: unknown field"),
    ("arc.Gamma", [1.0, 2.0], "$.arc.Gamma: expected 3 numbers, got 2"),
    ("pid.pole", 0.0, "$.pid.pole: expected a positive number, got 0.0"),
    ("feasibility.arc.worst_t", -1.0, "$.feasibility.arc.worst_t: expected a non-negative number"),
    ("validity", {"payload_range": [2.0, 1.0], "mass_range": [1.0, 2.0], "unit": "kg"},
     "$.validity.payload_range: expected a [min, max] pair"),
])
def test_rules_name_their_path(path, value, why):
    doc = copy.deepcopy(DOC)
    node = doc
    *head, last = path.split(".")
    for k in head:
        node = node[k]
    node[last] = value
    with pytest.raises(SchemaError) as exc:
        Tuning.from_dict(doc)
    assert str(exc.value).startswith("tuning.json: " + why), str(exc.value)


def test_a_map_entry_is_named_by_its_key():
    doc = copy.deepcopy(DOC)
    name = next(iter(doc["guarantees"]))
    doc["guarantees"][name]["holds"] = "yes"
    scen = next(iter(doc["scores"]))
    with pytest.raises(SchemaError, match=rf"\$\.guarantees\.{name}\.holds: expected true or false, got 'yes'"):
        Tuning.from_dict(doc)
    doc = copy.deepcopy(DOC)
    doc["scores"][scen]["pid"]["e_M"] = "x"
    with pytest.raises(SchemaError, match=r"\$\.scores\." + re.escape(scen) + r"\.pid\.e_M: expected a finite number, got 'x'"):
        Tuning.from_dict(doc)


NON_NULL_ANY = [f for f in tj.TUNING_FIELDS if f.type == "any" and f.required and not f.nullable
                and f.check is not None and "*" not in f.path]


@pytest.mark.parametrize("field", NON_NULL_ANY, ids=[f.path for f in NON_NULL_ANY])
def test_a_required_field_set_to_null_is_refused_naming_its_path(field):
    """An ``any`` row admits null by its type; its row does not (hypothesis found `theorem1.ratios = null`
    reaching the loader as a TypeError)."""
    doc = copy.deepcopy(DOC)
    node = doc
    *parents, leaf = field.path.split(".")
    for k in parents:
        node = node[k]
    node[leaf] = None
    with pytest.raises(SchemaError, match=re.escape(f"$.{field.path}: expected a value, got null")):
        Tuning.from_dict(doc)
