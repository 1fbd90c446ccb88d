"""commission.formats.gate_toml: gate.toml's one table, and everything derived from it (issue #34, "one place")."""

import dataclasses
import json
import math
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.errors import SpecError
from commission.formats import generated as formats
from commission.formats.gate_toml import GATE, GATE_KEYS, MARGIN_KEYS, ErrorDefault, gate_help
from commission.formats.table import Length, build_model, help_lines, json_schema, markdown_table
from commission.gate import GateSpec, gate_from_mapping, resolve_gate
from commission.robustness import MarginFloors

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_FILE = ROOT / "docs" / "schemas" / "gate.schema.json"
INTERFACE = ROOT / "docs" / "interface.md"


def _help(command: str) -> str:
    r = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "250", "TERMINAL_WIDTH": "250"})
    assert r.exit_code == 0, r.output
    return " ".join(r.output.replace("│", " ").split())


def _doc_rows(text: str) -> dict[str, list[str]]:
    block = text[text.index("<!-- generated: gate.toml keys"):text.index("<!-- end: gate.toml keys -->")]
    rows = {}
    for line in block.splitlines()[3:]:
        cells = [c.strip() for c in line.strip().strip("|").replace("\\|", "\x00").split("|")]
        rows[cells[0].strip("`")] = [c.replace("\x00", "|") for c in cells]
    return rows


def test_schema_file_is_the_table():
    assert SCHEMA_FILE.read_text() == formats.schema_text(formats.schemas()["gate.schema.json"]), (
        "docs/schemas/gate.schema.json is stale: run `python -m commission.formats`")


def test_every_gate_key_agrees_in_help_docs_and_schema():
    helps = {c: _help(c) for c in ("validate", "run")}
    rows = _doc_rows(INTERFACE.read_text())
    schema = json.loads(SCHEMA_FILE.read_text())
    section = schema["$defs"][schema["properties"]["gate"]["$ref"].split("/")[-1]]
    assert section["additionalProperties"] is False
    assert set(rows) == {k.path for k in GATE_KEYS} == {f"gate.{n}" for n in section["properties"]}
    for k in GATE_KEYS:
        default = k.default_text()
        for c, text in helps.items():  # the key, its default, and its doc in both commands' help
            assert " ".join(f"{k.path} = {default}".split()) in text, (c, k.path)
            assert " ".join(k.doc.split()) in text, (c, k.path)
        cells = rows[k.path]
        assert (cells[1], cells[2], cells[3], cells[4], cells[5]) == (
            k.type_text(), default, k.range_text(), k.unit, k.doc), k.path
        prop = section["properties"][k.name]
        assert prop["description"] == k.doc and prop.get("unit", "") == k.unit, k.path
        if k.default is not None:
            assert prop["default"] == k.default and "default_rule" not in prop, k.path
        else:
            assert "default" not in prop and prop["default_rule"] == default, k.path
        number = prop["anyOf"][0] if k.type is Length else prop
        if k.range is not None:
            assert number["exclusiveMinimum" if k.open[0] else "minimum"] == k.range[0], k.path
        if k.type is Length:
            assert prop["anyOf"][1]["pattern"] == Length.PATTERN


def test_changing_a_default_in_the_table_changes_help_docs_schema_and_the_resolved_gate():
    changed = tuple(dataclasses.replace(k, default=0.7) if k.name == "arc_vs_pid_median" else k for k in GATE_KEYS)
    assert "| `gate.arc_vs_pid_median` | number | 0.7 |" in markdown_table(changed)
    assert json_schema(build_model("G", changed, ""), "x", 1)["$defs"]["G_gate"]["properties"][
        "arc_vs_pid_median"]["default"] == 0.7
    assert formats.fill_markdown(INTERFACE.read_text(), {"gate.toml keys": markdown_table(changed)}) != \
        INTERFACE.read_text()
    rule = dataclasses.replace(GATE["e_F"], rule=ErrorDefault(40.0, 1e-4, "e_f"))
    assert "  gate.e_F = max(40 LSB, 0.01 % travel, 4 x targets.e_f)" in help_lines([rule])[0]
    # the resolver reads the rows: every defaulted limit is the row's rule or default
    lim = resolve_gate(GateSpec(), lsb=1e-6, travel=0.4, u_max=7.0, targets={"e_rms": 5e-6, "e_f": 10e-6})
    for name in ("e_F", "e_M", "e_rms"):
        r = GATE[name].rule
        tgt = {"e_f": 10e-6, "e_rms": 5e-6}.get(r.target or "", 0.0)
        assert getattr(lim, name) == pytest.approx(max(r.lsb * 1e-6, r.travel * 0.4, r.factor * tgt))
        assert lim.basis[name] == f"default: {r.formula()}"
    assert (lim.c_u, lim.arc_vs_pid_median, lim.arc_vs_pid_p90, lim.arc_vs_pid_nominal, lim.no_divergence) == tuple(
        GATE[n].default for n in ("c_u", "arc_vs_pid_median", "arc_vs_pid_p90", "arc_vs_pid_nominal", "no_divergence"))
    assert lim.u_max == 7.0 and lim.arc_vs_pid_slack == pytest.approx(1e-6 / math.sqrt(12))
    # the margin keys default to the spec's [margins] rows, which are the floors' attributes
    assert set(MARGIN_KEYS.values()) == {f.name for f in dataclasses.fields(MarginFloors)}


@pytest.mark.parametrize("k", GATE_KEYS, ids=lambda k: k.name)
def test_every_key_is_read_and_refused_naming_it(k):
    good = {bool: False, Length: "3 um"}.get(k.type, 2.5)
    g = gate_from_mapping({"gate": {k.name: good}}, "g.toml")
    got = g.margins[k.name] if k.name in MARGIN_KEYS else getattr(g, k.name)
    if k.type is Length:
        assert (got.value, got.unit, got.text) == (pytest.approx(3e-6), "m", "3 um")
    else:
        assert got == good and type(got) is type(good)
    bad = "yes" if k.type is bool else -1.0
    with pytest.raises(SpecError, match="^" + re.escape(f"g.toml: gate.{k.name} = {bad!r}: ")):
        gate_from_mapping({"gate": {k.name: bad}}, "g.toml")


def test_error_lines_are_the_files_lines():
    def line(value, key="e_F"):
        with pytest.raises(SpecError) as exc:
            gate_from_mapping({"gate": {key: value}}, "gate.toml")
        return str(exc.value)

    assert line(-1.0) == "gate.toml: gate.e_F = -1.0: must be a positive finite length in m"
    assert line(-1, "arc_vs_pid_slack") == "gate.toml: gate.arc_vs_pid_slack = -1: must be a non-negative finite length in m"
    assert line("0 um") == "gate.toml: gate.e_F = '0 um': must be positive"
    assert line("-1 lsb", "arc_vs_pid_slack") == "gate.toml: gate.arc_vs_pid_slack = '-1 lsb': must be non-negative"
    assert line("12 furlongs") == ('gate.toml: gate.e_F = \'12 furlongs\': expected "<number> <unit>" with unit m, '
                                   'mm, um, nm, lsb or %travel')
    assert line(True).startswith("gate.toml: gate.e_F = True: expected a length")
    assert line([1]) == 'gate.toml: gate.e_F = [1]: expected a number (m) or a string like "20 um"'
    assert line(0, "u_max") == "gate.toml: gate.u_max = 0: expected a positive finite number in u-unit"
    assert line(math.inf, "c_u") == "gate.toml: gate.c_u = inf: expected a positive finite number"
    assert line(1, "no_divergence") == "gate.toml: gate.no_divergence = 1: expected true or false"
    with pytest.raises(SpecError, match=r"^g: gate\.zz: unknown key \(known: " + re.escape(", ".join(GATE)) + r"\)$"):
        gate_from_mapping({"gate": {"e_F": -1, "zz": 1}}, "g")
    assert gate_from_mapping({}, "g") == GateSpec(source="g")
    assert gate_from_mapping({"gate": {"e_F": "0.02 %travel"}}).e_F.unit == "%travel"


def test_help_is_the_tables_lines():
    assert gate_help().count("\n  gate.") == len(GATE_KEYS)
