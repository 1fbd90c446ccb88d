"""commission.formats: every file format in one table, and every rendering of it agrees (issue #34, "one place").

One walk over all eight tables (spec.toml, gate.toml, limits.toml: the inputs; ident.json,
tuning.json, validation.json, controller.json, plan.json: the artifacts).  Every key of an input
is checked against the ``--help`` of the commands that read it, its row of the generated table in
docs/interface.md and its property in docs/schemas/; every field of an artifact against its row
in docs/interface.md and its node in docs/schemas/.  The generated files must be what the tables
render now, and a table with one default (an input) or one unit (an artifact) changed must
render a different help, docs table and schema.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.formats import generated
from commission.formats.controller_json import CONTROLLER_FIELDS, ControllerJson
from commission.formats.gate_toml import GATE_KEYS
from commission.formats.ident_json import IDENT_FIELDS, IdentJson
from commission.formats.json_table import Field, build_json_model, markdown_rows
from commission.formats.limits_toml import LIMITS_KEYS
from commission.formats.plan_json import PLAN_FIELDS, PlanJson
from commission.formats.spec_toml import SPEC_KEYS
from commission.formats.table import Key, build_model, help_lines, json_schema, markdown_table
from commission.formats.tuning_json import TUNING_FIELDS, TuningJson
from commission.formats.validation_json import VALIDATION_FIELDS, ValidationJson

ROOT = Path(__file__).resolve().parents[1]
INTERFACE = ROOT / "docs" / "interface.md"
SCHEMAS = ROOT / "docs" / "schemas"

#: Input file -> (its keys, its schema file, its docs block, the commands whose --help lists its keys, a key
#: whose default the change test moves, the new default).
INPUTS = {
    "spec.toml": (SPEC_KEYS, "spec.schema.json", "spec.toml keys", ("tune",), "tune.budget", 200),
    "gate.toml": (GATE_KEYS, "gate.schema.json", "gate.toml keys", ("validate", "run"), "gate.arc_vs_pid_median",
                  0.7),
    "limits.toml": (LIMITS_KEYS, "limits.schema.json", "limits.toml keys", ("excite",), "plan.n_speeds", 9),
}
#: Artifact -> (its fields, its strict model, its schema file, its docs block).
ARTIFACTS = {
    "ident.json": (IDENT_FIELDS, IdentJson, "ident.schema.json", "ident.json fields"),
    "tuning.json": (TUNING_FIELDS, TuningJson, "tuning.schema.json", "tuning.json fields"),
    "validation.json": (VALIDATION_FIELDS, ValidationJson, "validation.schema.json", "validation.json fields"),
    "controller.json": (CONTROLLER_FIELDS, ControllerJson, "controller.schema.json", "controller.json fields"),
    "plan.json": (PLAN_FIELDS, PlanJson, "plan.schema.json", "plan.json fields"),
}


def _help(command: str) -> str:
    r = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "250", "TERMINAL_WIDTH": "250"})
    assert r.exit_code == 0, r.output
    return " ".join(r.output.replace("│", " ").split())


def _block(name: str, text: str | None = None) -> dict[str, list[str]]:
    """First cell (the key or JSON path) -> the cells of its row in the generated block ``name``."""
    text = INTERFACE.read_text() if text is None else text
    block = text[text.index(f"<!-- generated: {name} "):text.index(f"<!-- end: {name} -->")]
    rows = {}
    for line in block.splitlines()[3:]:
        cells = [c.strip() for c in line.strip().strip("|").replace("\\|", "\x00").split("|")]
        rows[cells[0].strip("`")] = [c.replace("\x00", "|") for c in cells]
    return rows


def _resolve(schema: dict, node: dict) -> dict:
    """A property's own schema: through a nullable ``anyOf`` and a ``$ref``."""
    if "$ref" not in node and "anyOf" in node:
        node = next((a for a in node["anyOf"] if a.get("type") != "null"), node)
    if "$ref" in node:
        node = schema["$defs"][node["$ref"].split("/")[-1]]
    return node


def _node(schema: dict, f: Field, rows: dict[str, Field]) -> tuple[dict, dict]:
    """(the schema of the object holding ``f``, ``f``'s property there) by walking its JSON path."""
    holder, node, path = schema, schema, ""
    for part in f.path.split("."):
        holder = _resolve(schema, node)
        if part == "*":
            node = holder["items"] if rows[path].type == "objects" else holder["additionalProperties"]
        else:
            node = holder["properties"][part]
        path = f"{path}.{part}" if path else part
    return holder, node


# --------------------------------------------------------------------------- the generated files are the tables


@pytest.mark.parametrize("name", sorted(generated.schemas()))
def test_every_schema_file_is_its_table(name):
    assert (SCHEMAS / name).read_text() == generated.schema_text(generated.schemas()[name]), (
        f"docs/schemas/{name} is stale: run `python -m commission.formats`")


def test_every_docs_block_is_its_table():
    text = INTERFACE.read_text()
    assert set(generated.tables()) == {v[2] for v in INPUTS.values()} | {v[3] for v in ARTIFACTS.values()}
    assert generated.fill_markdown(text, generated.tables()) == text, (
        "docs/interface.md's generated blocks are stale: run `python -m commission.formats`")


# --------------------------------------------------------------------------- every key of every input walked


@pytest.mark.parametrize("file", sorted(INPUTS))
def test_every_input_key_agrees_in_help_docs_and_schema(file):
    keys, schema_name, block, commands, _, _ = INPUTS[file]
    helps = {c: _help(c) for c in commands}
    rows = _block(block)
    schema = json.loads((SCHEMAS / schema_name).read_text())
    assert list(rows) == [k.path for k in keys], "docs rows: one per key, in table order"
    assert len({k.path for k in keys}) == len(keys)
    for k in keys:
        for c, text in helps.items():  # spec and gate: "key = default"; excite names its keys by section
            shown = f"{k.path} = {k.default_text()}" if file != "limits.toml" else (
                k.path if k.required else k.name)
            assert " ".join(shown.split()) in text, (file, c, k.path)
        assert rows[k.path][1:] == [k.type_text(), k.default_text(), k.range_text(), k.shown_unit, k.doc], (
            file, k.path)
        section = _resolve(schema, schema["properties"][k.section])
        prop = section["properties"][k.name]
        assert prop["description"] == k.doc and prop.get("unit", "") == k.shown_unit, (file, k.path)
        assert (k.name in section.get("required", [])) == k.required, (file, k.path)
        if k.default is not None:
            want = list(k.default) if isinstance(k.default, tuple) else k.default
            assert prop["default"] == want, (file, k.path)
        else:
            assert "default" not in prop, (file, k.path)
        if k.rule is not None:
            assert prop["default_rule"] == k.default_text(), (file, k.path)
        assert section["additionalProperties"] is False, file


# --------------------------------------------------------------------------- every field of every artifact walked


@pytest.mark.parametrize("file", sorted(ARTIFACTS))
def test_every_artifact_field_agrees_in_docs_and_schema(file):
    fields, _, schema_name, block = ARTIFACTS[file]
    rows = _block(block)
    by_path = {f.path: f for f in fields}
    schema = json.loads((SCHEMAS / schema_name).read_text())
    assert list(rows) == [f.path for f in fields] and len(by_path) == len(fields), "one docs row per field"
    for f in fields:
        req = ("yes, may be null" if f.nullable else "yes") if f.required else ""
        assert rows[f.path][1:] == [f.type, f.rule_text(), f.unit, req, f.doc], (file, f.path)
        holder, node = _node(schema, f, by_path)
        if f.name == "*":  # a map's or a list's entries: an object of exactly the rows below it
            assert set(_resolve(schema, node)["properties"]) == {g.name for g in fields if g.parent == f.path}
            continue
        assert node["description"] == f.doc and node.get("unit", "") == f.unit, (file, f.path)
        assert (f.name in holder.get("required", [])) == f.required, (file, f.path)
        if f.type in ("object", "map", "objects"):
            own = _resolve(schema, node)
            if f.type == "object":
                assert (own.get("additionalProperties") is False) == f.closed, (file, f.path)
                named = {g.name for g in fields if g.parent == f.path}
                assert set(own.get("properties", {})) == named, (file, f.path)


# --------------------------------------------------------------------------- a change in a table changes all three


def _changed_key(keys: tuple[Key, ...], path: str, default: Any) -> tuple[Key, ...]:
    assert any(k.path == path for k in keys)
    return tuple(dataclasses.replace(k, default=default) if k.path == path else k for k in keys)


@pytest.mark.parametrize("file", sorted(INPUTS))
def test_changing_an_input_default_changes_help_docs_and_schema(file):
    keys, schema_name, block, _, path, new = INPUTS[file]
    changed = _changed_key(keys, path, new)
    k = next(k for k in changed if k.path == path)
    old = next(k for k in keys if k.path == path)
    section, name = path.split(".")
    before = json_schema(build_model("T", keys, ""), "x", 1)["$defs"][f"T_{section}"]["properties"][name]
    after = json_schema(build_model("T", changed, ""), "x", 1)["$defs"][f"T_{section}"]["properties"][name]
    assert (before["default"], after["default"]) == (old.default, new)
    assert f"| `{path}` | {k.type_text()} | {k.default_text()} |" in markdown_table(changed)
    text = INTERFACE.read_text()
    moved = generated.fill_markdown(text, {block: markdown_table(changed)})
    assert moved != text and _block(block, moved)[path][2] == k.default_text() != old.default_text()
    if file != "limits.toml":  # spec's and gate's help print "key = default"; excite's names the keys only
        assert f"  {path} = {k.default_text()}" in help_lines(changed)
        assert f"  {path} = {k.default_text()}" not in help_lines(keys)


@pytest.mark.parametrize("file", sorted(ARTIFACTS))
def test_changing_an_artifact_row_changes_docs_and_schema(file):
    fields, _, _, block = ARTIFACTS[file]
    f = next(f for f in fields if f.type == "number")
    changed = tuple(dataclasses.replace(g, unit="furlong") if g is f else g for g in fields)
    schema = json_schema(build_json_model("X", changed, ""), "x", 1)
    assert _node(schema, f, {g.path: g for g in changed})[1]["unit"] == "furlong"
    assert _block(block, generated.fill_markdown(INTERFACE.read_text(), {block: markdown_rows(changed)}))[
        f.path][3] == "furlong"
