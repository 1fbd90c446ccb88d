"""Issue 29, must-show 2: a hostile unit is refused at the first step that reads it, and no file carries it.

The unit below closes a C comment and defines a constructor that runs before ``main``: copied
into a generated comment it compiles cleanly and executes.  ``units.u`` is a fixed vocabulary
(:data:`commission.artifacts.UNIT_VOCABULARY_U`), so wherever the string is planted -- ident.json,
tuning.json's embedded identification, controller.json with its checksum (and signature)
recomputed -- the command reading it exits 2 naming its JSON path, and writes nothing.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.controller_config import SIGN_KEY_ENV, ControllerConfig, ControllerProvenance
from commission.errors import SchemaError
from commission.jsonio import write_json_atomic
from commission.paper import reference_identification
from commission.runtime import load_controller
from commission.tuning import Tuning
from commission.validate import deployable_gains
from controller_docs import reseal

HOSTILE = ('V */ extern int puts(const char *); static void __attribute__((constructor)) x(void)'
           '{puts("INJECTED");} /*')
SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5"
TUNING_DOC = json.loads((Path(__file__).parent / "data" / "tuning_paper_budget8.json").read_text())
runner = CliRunner()


def invoke(*args, env=None):
    return runner.invoke(app, [str(a) for a in args], env=env)


def refused_naming(r, json_path: str) -> None:
    """Exit 2, one line on stderr naming ``json_path``, no traceback."""
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f": {json_path}: " in lines[0], r.stderr
    assert "Traceback" not in r.output


def assert_nothing_carries_the_payload(folder: Path) -> None:
    """No file under ``folder`` (hidden staging files included) holds the payload; none was written at all."""
    files = [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []
    assert not [p for p in files if b"INJECTED" in p.read_bytes()]
    assert files == []


@pytest.fixture()
def hostile_ident(tmp_path):
    doc = reference_identification(source={"sha256": "ab" * 32, "sample_rate": 2500.0}).to_dict()
    doc["units"]["u"] = HOSTILE
    p = tmp_path / "ident.json"
    write_json_atomic(p, doc)
    return p


def test_identify_refuses_the_unit_as_a_flag(tmp_path):
    out = tmp_path / "out"
    r = invoke("identify", SAMPLE, "--u-unit", HOSTILE, "--input-gain", "2", "--out", out / "ident.json")
    assert r.exit_code == 2 and "--u-unit" in r.stderr, r.output
    assert_nothing_carries_the_payload(out)


def test_tune_refuses_the_unit_planted_in_ident_json(tmp_path, hostile_ident):
    out = tmp_path / "out"
    (tmp_path / "spec.toml").write_text("[tune]\nbudget = 3\n")
    r = invoke("tune", hostile_ident, "--out", out / "tuning.json", "--spec", tmp_path / "spec.toml")
    refused_naming(r, "$.units.u")
    assert_nothing_carries_the_payload(out)


def test_tune_accepts_every_unit_of_the_vocabulary_as_far_as_the_units_go(hostile_ident):
    """The same file with each unit the tool can write loads: the refusal above is the vocabulary's."""
    from commission.artifacts import UNIT_VOCABULARY_U, Identification

    doc = json.loads(hostile_ident.read_text())
    for unit in UNIT_VOCABULARY_U:
        doc["units"]["u"] = unit
        assert Identification.from_dict(copy.deepcopy(doc)).units["u"] == unit


def test_validate_refuses_the_unit_planted_in_tuning_json(tmp_path):
    doc = copy.deepcopy(TUNING_DOC)
    doc["identification"]["units"]["u"] = HOSTILE
    doc["provenance"]["ident_path"] = "not-here/ident.json"
    tpath = tmp_path / "tuning.json"
    write_json_atomic(tpath, doc)
    out = tmp_path / "out"
    refused_naming(invoke("validate", tpath, "--out-dir", out, "--monte-carlo", 0), "$.identification.units.u")
    assert_nothing_carries_the_payload(out)


@pytest.fixture(scope="module")
def controller_doc():
    t = Tuning.from_dict(copy.deepcopy(TUNING_DOC))
    cfg = ControllerConfig(gains=deployable_gains(t.arc), sample_rate=t.spec.sample_rate, units={"u": "V", "q": "m"},
                           validated={}, provenance=ControllerProvenance(None, "1" * 64, "2" * 64, "t", "now"))
    return cfg.to_dict()


def _plant(doc, key: bytes | None = None):
    """``doc`` with the hostile unit, its signature (under ``key``) and checksum recomputed."""
    doc = copy.deepcopy(doc)
    doc["units"]["u"] = HOSTILE
    doc.pop("signature", None)
    return reseal(doc, key)


def test_load_controller_and_export_refuse_the_unit_planted_in_controller_json(tmp_path, controller_doc):
    cpath = tmp_path / "controller.json"
    write_json_atomic(cpath, _plant(controller_doc))
    with pytest.raises(SchemaError, match=r"\$\.units\.u: expected one of"):
        load_controller(cpath)
    for target in ("c", "st"):
        out = tmp_path / f"export_{target}"
        refused_naming(invoke("export", cpath, "--out-dir", out, "--target", target), "$.units.u")
        assert_nothing_carries_the_payload(out)


def test_a_signed_controller_with_the_unit_is_refused_with_the_key(tmp_path, controller_doc):
    key = b"k" * 32
    kpath = tmp_path / "site.key"
    kpath.write_bytes(key)
    cpath = tmp_path / "controller.json"
    write_json_atomic(cpath, _plant(controller_doc, key))  # a valid signature over the hostile content
    with pytest.raises(SchemaError, match=r"\$\.units\.u: expected one of"):
        load_controller(cpath, key=key)
    out = tmp_path / "export"
    refused_naming(invoke("export", cpath, "--out-dir", out, env={SIGN_KEY_ENV: str(kpath)}), "$.units.u")
    assert_nothing_carries_the_payload(out)
