"""commission.formats.controller_json: controller.json's one table, the loader on it, the generated files."""

import copy
import dataclasses
import json
from pathlib import Path

import pytest

from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.controllers.arc import RUNTIME_GUARDS, ArcGains
from commission.errors import SchemaError
from commission.formats import generated as formats
from commission.formats.controller_json import (CONTROLLER_FIELDS, FRICTION, RUNTIME_FIELDS, SECTIONS,
                                                ControllerJson)
from commission.jsonio import sha256_json
from commission.paper import reference_identification
from commission.spec import default_spec
from commission.tune.gains import base_arc_gains

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_FILE = ROOT / "docs" / "schemas" / "controller.schema.json"
INTERFACE = ROOT / "docs" / "interface.md"


@pytest.fixture(scope="module")
def controller_doc():
    """A controller.json of the reference axis with every runtime guard set (the runtime section written)."""
    g = base_arc_gains(reference_identification(delta_d=0.5), default_spec())
    g = dataclasses.replace(g, dy_max=1e-3, dy_fault=0.4, n_reject_max=3.0, e_max=1e-3, freeze_on_saturation=True,
                            y_err=1e-6, u_free=0.1)
    prov = ControllerProvenance(log_sha256=None, ident_sha256="b" * 64, tuning_sha256="c" * 64,
                                tool_version="test", created_utc="2001-06-01T00:00:00Z")
    return ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"}, validated={"seed": 0},
                            provenance=prov, validity={"payload_range": [0.0, 1.0], "mass_range": [1.0, 2.0],
                                                       "unit": "V s^2/m"}).to_dict()


def _rehash(doc):
    doc = {k: v for k, v in doc.items() if k != "checksum"}
    doc["checksum"] = {"algorithm": "sha256", "value": sha256_json(doc)}
    return doc


def test_the_table_names_every_arc_gain_once():
    named = [n for names in SECTIONS.values() for n in names] + list(FRICTION.values()) + list(RUNTIME_FIELDS)
    assert sorted(named) == sorted(f.name for f in dataclasses.fields(ArcGains) if f.name != "Ts")
    assert RUNTIME_FIELDS == tuple(RUNTIME_GUARDS)


def test_generated_files_are_the_table():
    assert SCHEMA_FILE.read_text() == formats.schema_text(formats.schemas()["controller.schema.json"]), (
        "docs/schemas/controller.schema.json is stale: run `python -m commission.formats`")
    text = INTERFACE.read_text()
    assert formats.fill_markdown(text, formats.tables()) == text
    block = text[text.index("<!-- generated: controller.json fields"):text.index("<!-- end: controller.json fields")]
    schema = json.loads(SCHEMA_FILE.read_text())
    for f in CONTROLLER_FIELDS:  # every field: its row in the docs, its property in the schema
        assert f"| `{f.path}` | {f.type} |" in block, f.path
        node = schema
        for part in f.path.split("."):
            ref = node.get("$ref") or next((a["$ref"] for a in node.get("anyOf", []) if "$ref" in a), None)
            node = schema["$defs"][ref.split("/")[-1]] if ref else node
            node = node["properties"][part]
        assert node["description"] == f.doc and node.get("unit", "") == f.unit, f.path


def test_the_loader_reads_the_table_and_refuses_a_key_it_does_not_name(controller_doc):
    back = ControllerConfig.from_dict(controller_doc)
    assert back.to_dict() == controller_doc  # loads and writes back byte for byte
    ControllerJson.model_validate(controller_doc)
    closed = [f.path for f in CONTROLLER_FIELDS if f.closed and f.path in controller_doc]
    assert {"units", "observer", "gains", "bounds", "adaptation", "initial_estimates",
            "friction_compensation"} <= set(closed)
    for path in closed + [""]:
        doc = copy.deepcopy(controller_doc)
        (doc[path] if path else doc)["zz"] = 1.0
        with pytest.raises(SchemaError, match=r"^controller\.json: \$" + (rf"\.{path}" if path else "")
                           + r"\.zz: unknown field$"):
            ControllerConfig.from_dict(_rehash(doc))


def test_the_checksum_is_still_checked_after_every_other_field(controller_doc):
    doc = copy.deepcopy(controller_doc)
    doc["gains"]["g1"] = "fast"
    doc.pop("checksum")
    with pytest.raises(SchemaError, match=r"\$\.gains\.g1: expected a finite number, got 'fast'$"):
        ControllerConfig.from_dict(doc)
    doc["gains"]["g1"] = controller_doc["gains"]["g1"]
    with pytest.raises(SchemaError, match=r"\$\.checksum: missing required field$"):
        ControllerConfig.from_dict(doc)
