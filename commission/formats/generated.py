"""The files generated from the format tables: docs/schemas/*.schema.json and docs/interface.md's key tables.

``python -m commission.formats`` rewrites them (:func:`write_generated`); tests compare them with the tables.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from commission.formats import (controller_json, gate_toml, ident_json, limits_toml, plan_json, spec_toml, tuning_json,
                                validation_json)
from commission.formats.json_table import markdown_rows
from commission.formats.table import json_schema, markdown_table

#: Marker lines around a generated table in a Markdown file: ``<!-- generated: NAME -->`` ... ``<!-- end: NAME -->``.
_BEGIN, _END = "<!-- generated: {name} (python -m commission.formats; do not edit) -->", "<!-- end: {name} -->"


def schemas() -> dict[str, dict]:
    """File name in docs/schemas/ -> its JSON Schema."""
    return {"spec.schema.json": json_schema(spec_toml.SpecToml, "commission/spec.schema.json",
                                            spec_toml.SCHEMA_VERSION),
            "gate.schema.json": json_schema(gate_toml.GateToml, "commission/gate.schema.json",
                                            gate_toml.SCHEMA_VERSION),
            "limits.schema.json": json_schema(limits_toml.LimitsToml, "commission/limits.schema.json",
                                              limits_toml.SCHEMA_VERSION),
            "ident.schema.json": json_schema(ident_json.IdentJson, "commission/ident.schema.json",
                                             ident_json.IDENT_SCHEMA_VERSION),
            "controller.schema.json": json_schema(controller_json.ControllerJson, "commission/controller.schema.json",
                                                  controller_json.CONTROLLER_SCHEMA_VERSION),
            "tuning.schema.json": json_schema(tuning_json.TuningJson, "commission/tuning.schema.json",
                                              tuning_json.TUNING_SCHEMA_VERSION),
            "validation.schema.json": json_schema(validation_json.ValidationJson, "commission/validation.schema.json",
                                                  validation_json.VALIDATION_SCHEMA_VERSION),
            "plan.schema.json": json_schema(plan_json.PlanJson, "commission/plan.schema.json",
                                            plan_json.PLAN_SCHEMA_VERSION)}


def schema_text(schema: dict) -> str:
    """A schema as written to disk: sorted keys, 2-space indent, one trailing newline."""
    return json.dumps(schema, sort_keys=True, indent=2) + "\n"


def tables() -> dict[str, str]:
    """Name of a generated Markdown table in docs/interface.md -> its text."""
    return {"spec.toml keys": markdown_table(spec_toml.SPEC_KEYS),
            "gate.toml keys": markdown_table(gate_toml.GATE_KEYS),
            "limits.toml keys": markdown_table(limits_toml.LIMITS_KEYS),
            "ident.json fields": markdown_rows(ident_json.IDENT_FIELDS),
            "tuning.json fields": markdown_rows(tuning_json.TUNING_FIELDS),
            "controller.json fields": markdown_rows(controller_json.CONTROLLER_FIELDS),
            "validation.json fields": markdown_rows(validation_json.VALIDATION_FIELDS),
            "plan.json fields": markdown_rows(plan_json.PLAN_FIELDS)}


def fill_markdown(text: str, generated: dict[str, str]) -> str:
    """``text`` with every generated table between its markers replaced by ``generated[name]``."""
    for name, body in generated.items():
        begin, end = _BEGIN.format(name=name), _END.format(name=name)
        pattern = re.compile(re.escape(begin) + r"\n.*?" + re.escape(end), re.S)
        if not pattern.search(text):
            raise ValueError(f"no '{begin}' ... '{end}' block")
        text = pattern.sub(lambda _m: f"{begin}\n{body}{end}", text)
    return text


def write_generated(root: Path) -> list[Path]:
    """Rewrite the generated files under a checkout's ``root``; returns the files written."""
    out = []
    folder = root / "docs" / "schemas"
    folder.mkdir(parents=True, exist_ok=True)
    for name, schema in schemas().items():
        (folder / name).write_text(schema_text(schema))
        out.append(folder / name)
    doc = root / "docs" / "interface.md"
    doc.write_text(fill_markdown(doc.read_text(), tables()))
    out.append(doc)
    return out
