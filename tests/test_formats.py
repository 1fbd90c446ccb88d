"""commission.formats: spec.toml's one table, and everything derived from it (issue #34, "one place").

Every key of the table is walked: ``commission tune --help``, docs/interface.md §6 and
docs/schemas/spec.schema.json must state its name, default (or the rule of a derived
default), range and unit as the table does; ``Spec``'s defaults and ``RANGES`` must be the
table's; and a table with one default changed must change all three renderings.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from commission.formats import generated as formats
from commission.cli.main import app
from commission.cli.tune_cmd import help_text
from commission.errors import SpecError
from commission.formats.spec_toml import SPEC_FIELDS, SPEC_KEYS
from commission.formats.table import Key, Scaled, build_model, help_lines, json_schema, markdown_table
from commission.spec import RANGES, Spec, default_spec, spec_from_mapping

ROOT = Path(__file__).resolve().parents[1]
SCHEMA_FILE = ROOT / "docs" / "schemas" / "spec.schema.json"
INTERFACE = ROOT / "docs" / "interface.md"
NUMERIC = [k for k in SPEC_FIELDS if k.range is not None]


def _cli_help() -> str:
    r = CliRunner().invoke(app, ["tune", "--help"], env={"COLUMNS": "250", "TERMINAL_WIDTH": "250"})
    assert r.exit_code == 0, r.output
    return r.output


def _doc_rows(text: str, name: str = "spec.toml keys") -> dict[str, list[str]]:
    """Key path -> the cells of its row in the generated table ``name`` of docs/interface.md."""
    begin = text.index(f"<!-- generated: {name}")
    block = text[begin:text.index(f"<!-- end: {name} -->")]
    rows = {}
    for line in block.splitlines()[3:]:
        cells = [c.strip() for c in line.strip().strip("|").replace("\\|", "\x00").split("|")]
        rows[cells[0].strip("`")] = [c.replace("\x00", "|") for c in cells]
    return rows


# --------------------------------------------------------------------------- the generated files do not drift


@pytest.mark.parametrize("name", ["spec.schema.json", "limits.schema.json"])
def test_schema_files_are_the_tables(name):
    assert (ROOT / "docs" / "schemas" / name).read_text() == formats.schema_text(formats.schemas()[name]), (
        f"docs/schemas/{name} is stale: run `python -m commission.formats`")


def test_interface_md_table_is_the_tables():
    text = INTERFACE.read_text()
    assert formats.fill_markdown(text, formats.tables()) == text, (
        "docs/interface.md's generated tables are stale: run `python -m commission.formats`")


# --------------------------------------------------------------------------- one place: every key walked


def test_every_key_agrees_in_help_docs_and_schema():
    help_out = _cli_help()
    rows = _doc_rows(INTERFACE.read_text())
    schema = json.loads(SCHEMA_FILE.read_text())
    assert set(rows) == {k.path for k in SPEC_KEYS}
    for k in SPEC_KEYS:
        default = k.default_text()
        # CLI help: the key and its default (with its unit) on one line
        assert f"  {k.path} = {default}" in help_out, k.path
        # docs/interface.md: name, default, unit, range
        cells = rows[k.path]
        assert cells[2] == default and cells[4] == k.unit, (k.path, cells)
        assert cells[3] == ("" if k.range is None else f"[{k.range[0]:g}, {k.range[1]:g}]"), k.path
        # the schema: the section's property with its default (or rule), unit and range
        ref = schema["properties"][k.section]["$ref"].split("/")[-1]
        prop = schema["$defs"][ref]["properties"][k.name]
        assert prop.get("unit", "") == k.unit, k.path
        if k.default is not None:
            assert prop["default"] == k.default, k.path
        else:
            assert "default" not in prop and prop["default_rule"] == default, k.path
        if k.range is not None:
            assert (prop["minimum"], prop["maximum"]) == k.range, k.path
        assert prop["description"] == k.doc
        assert schema["$defs"][ref]["additionalProperties"] is False


def test_changing_a_default_in_the_table_changes_help_docs_and_schema():
    changed = tuple(dataclasses.replace(k, default=200) if k.path == "tune.budget" else k for k in SPEC_KEYS)
    model = build_model("SpecToml", changed, "modified")
    budget_schema = json_schema(model, "x", 1)["$defs"]["SpecToml_tune"]["properties"]["budget"]
    assert budget_schema["default"] == 200
    assert "  tune.budget = 200" in help_text(changed).splitlines()
    assert "  tune.budget = 144" in help_text(SPEC_KEYS).splitlines()
    assert "| `tune.budget` | integer | 200 |" in markdown_table(changed)
    assert formats.fill_markdown(INTERFACE.read_text(), {"spec.toml keys": markdown_table(changed)}) != \
        INTERFACE.read_text()
    # a derived default follows its rule: a new fraction shows in all three as well
    scaled = tuple(dataclasses.replace(k, rule=Scaled(0.1, "controller.sample_rate")) if k.path == "pid.pole" else k
                   for k in SPEC_KEYS)
    assert "  pid.pole = 0.1 x controller.sample_rate rad/s" in help_lines(scaled)
    assert "| 0.1 x controller.sample_rate rad/s |" in markdown_table(scaled)
    pole = json_schema(build_model("S", scaled, ""), "x", 1)["$defs"]["S_pid"]["properties"]["pole"]
    assert pole["default_rule"] == "0.1 x controller.sample_rate rad/s"


def test_spec_defaults_and_ranges_are_the_tables():
    spec = Spec()
    assert spec == default_spec()  # an empty spec.toml
    names = [f.name for f in dataclasses.fields(Spec)]
    assert names == [k.field_name for k in SPEC_FIELDS] + ["profile"]
    for k in SPEC_FIELDS:
        if isinstance(k.rule, Scaled):
            assert getattr(spec, k.field_name) == pytest.approx(k.rule.fraction * 2500.0), k.path
        else:
            assert getattr(spec, k.field_name) == k.default, k.path
        if k.range is not None:
            assert RANGES[(k.section, k.name)] == k.range
    # the paper's setting (Xu & Yao 2001, §4.3): poles -200 (observer) and -300 (PID) at 2.5 kHz
    assert (spec.observer_pole, spec.pid_pole) == (pytest.approx(200.0), pytest.approx(300.0))


def test_resolved_spec_round_trips_through_its_layout():
    spec = spec_from_mapping({"controller": {"sample_rate": 4000}, "plant": {"encoder": "load"}})
    d = spec.to_dict()
    assert d["controller"]["observer_pole"] == pytest.approx(320.0) and d["plant"] == {"encoder": "load"}
    assert spec_from_mapping(d) == spec


# --------------------------------------------------------------------------- strict loading names the key


@pytest.mark.parametrize("k", NUMERIC, ids=lambda k: k.path)
def test_every_number_outside_its_range_is_refused_naming_the_key(k: Key):
    lo, hi = k.range
    above = hi * 2 if k.type is float else hi + 1
    path = re.escape(f"s.toml: {k.path} = ")
    with pytest.raises(SpecError, match="^" + path + re.escape(f"{above!r}") + ".* is outside the accepted range "
                                        + re.escape(f"[{lo:g}, {hi:g}]")):
        spec_from_mapping({k.section: {k.name: above}}, "s.toml")
    below, word = (-1, "must not be negative") if lo == 0 else (0, "must be positive")
    with pytest.raises(SpecError, match="^" + path + re.escape(f"{k.type(below)!r}") + f".* {word}$"):
        spec_from_mapping({k.section: {k.name: below}}, "s.toml")
    wrong = [True, "1", math.inf] if k.type is float else [True, 2.5, "1"]
    for raw in wrong:
        with pytest.raises(SpecError, match="^" + path + re.escape(f"{raw!r}") + ": expected an? "):
            spec_from_mapping({k.section: {k.name: raw}}, "s.toml")


def test_the_first_bad_key_of_the_file_is_named_and_the_prefix_kept():
    data = {"targets": {"c_u": 0.5, "e_f": -1.0}, "controller": {"sampel_rate": 1.0}}
    with pytest.raises(SpecError, match=r"^tuning\.json: \$\.spec\.targets\.e_f = -1\.0 m must be positive$"):
        spec_from_mapping(data, "tuning.json", prefix="$.spec.")
    with pytest.raises(SpecError, match=r"plant\.encoder = 'side': expected one of 'motor', 'load'$"):
        spec_from_mapping({"plant": {"encoder": "side"}})
    with pytest.raises(SpecError, match=r"trajectory\.speed: unknown key \(known in \[trajectory\]: v_max, .*"
                                        r"reference_a_max, file, file_sha256, move\)$"):
        spec_from_mapping({"trajectory": {"speed": 1.0}})
    with pytest.raises(SpecError, match=r"^spec\.toml: pid: expected a table, got 3$"):
        spec_from_mapping({"pid": 3})
    # [compute] is read by the executor, not here: accepted as it is
    assert spec_from_mapping({"compute": {"scheduler": "tcp://h:1"}}) == default_spec()


def test_readme_quotes_the_tables_defaults_and_ranges():
    text = " ".join((ROOT / "README.md").read_text().split())
    keys = {k.path: k for k in SPEC_KEYS}
    assert f"{keys['tune.budget'].default} candidates unless the spec sets `tune.budget`" in text
    lo, hi = keys["controller.sample_rate"].range
    assert f"`controller.sample_rate` {lo:g} Hz–{hi / 1e3:g} kHz" in text
    for path, shown in (("trajectory.dwell", "`trajectory.dwell` ≤ {:g} s"), ("trajectory.moves", "`moves` ≤ {:g}"),
                        ("tune.budget", "`tune.budget` ≤ {:,}"), ("tune.margin", "`tune.margin` ≤ {:g}")):
        assert shown.format(keys[path].range[1]) in text, path


# --------------------------------------------------------------------------- limits.toml (commission excite)

from commission.excite import excite_spec_from_mapping  # noqa: E402
from commission.formats.limits_toml import LIMITS_KEYS  # noqa: E402

LIMITS_FILE = ROOT / "docs" / "schemas" / "limits.schema.json"
MINIMAL = {"limits": {"travel": 0.2, "v_max": 0.5, "a_max": 5.0, "u_max": 10.0},
           "drive": {"sample_rate": 2000.0, "bandwidth_hz": 10.0}}


def _bounds(k: Key) -> dict:
    lo, hi = k.range
    out = {}
    if math.isfinite(lo):
        out["exclusiveMinimum" if k.open[0] else "minimum"] = lo
    if math.isfinite(hi):
        out["exclusiveMaximum" if k.open[1] else "maximum"] = hi
    return out


def test_every_limits_key_agrees_in_help_docs_and_schema():
    r = CliRunner().invoke(app, ["excite", "--help"], env={"COLUMNS": "250", "TERMINAL_WIDTH": "250"})
    help_out = " ".join(r.output.replace("│", " ").split())
    rows = _doc_rows(INTERFACE.read_text(), "limits.toml keys")
    schema = json.loads(LIMITS_FILE.read_text())
    assert set(rows) == {k.path for k in LIMITS_KEYS}
    assert schema["required"] == ["limits", "drive"]
    for k in LIMITS_KEYS:
        assert (k.path if k.required else k.name) in help_out, k.path
        cells = rows[k.path]
        assert (cells[2], cells[3], cells[4]) == (k.default_text(), k.range_text(), k.shown_unit), (k.path, cells)
        sec = schema["$defs"][schema["properties"][k.section]["$ref"].split("/")[-1]]
        prop = sec["properties"][k.name]
        assert prop.get("unit", "") == k.shown_unit and prop["description"] == k.doc, k.path
        assert (k.name in sec.get("required", [])) == k.required, k.path
        if k.default is not None:
            assert prop["default"] == (list(k.default) if isinstance(k.default, tuple) else k.default), k.path
        else:
            assert "default" not in prop, k.path
        if k.range is not None:
            where = prop["items"] if k.type is list else prop
            assert {b: where[b] for b in where if "imum" in b} == _bounds(k), k.path


def test_changing_a_limits_default_changes_docs_and_schema_and_the_loader_follows_the_table():
    changed = tuple(dataclasses.replace(k, default=9) if k.path == "plan.n_speeds" else k for k in LIMITS_KEYS)
    assert "| `plan.n_speeds` | integer | 9 |" in markdown_table(changed)
    assert json_schema(build_model("L", changed, ""), "x", 1)["$defs"]["L_plan"]["properties"]["n_speeds"][
        "default"] == 9
    spec = excite_spec_from_mapping(MINIMAL)
    for k in LIMITS_KEYS:
        if k.section == "plan" and k.name not in ("band_hz",):  # band_hz: derived from Nyquist
            assert spec.plan[k.name] == k.default, k.path
    assert (spec.q_unit, spec.u_unit) == ("m", "V")


@pytest.mark.parametrize("k", [k for k in LIMITS_KEYS if k.range is not None and math.isfinite(k.range[0])],
                         ids=lambda k: k.path)
def test_every_limits_number_below_its_range_is_refused_naming_the_key(k: Key):
    data = json.loads(json.dumps(MINIMAL))
    data.setdefault(k.section, {})[k.name] = [-1.0] if k.type is list else k.type(k.range[0] - 1)
    with pytest.raises(SpecError, match="^" + re.escape(f"limits.toml: {k.path} = ")):
        excite_spec_from_mapping(data)


def test_limits_errors_name_the_key_in_the_files_units():
    def refused(section, key, value, **extra):
        data = json.loads(json.dumps(MINIMAL))
        data.setdefault(section, {})[key] = value
        for s, t in extra.items():
            data.setdefault(s, {}).update(t)
        with pytest.raises(SpecError) as exc:
            excite_spec_from_mapping(data)
        return str(exc.value)

    assert refused("limits", "v_max", -1.0, axis={"q_unit": "rad"}) == "limits.toml: limits.v_max = -1.0 rad/s must be positive"
    assert refused("drive", "kd", -1.0) == "limits.toml: drive.kd = -1.0 V s/m must not be negative"
    assert refused("plan", "margin", 1.0) == "limits.toml: plan.margin = 1.0 must be between 0 and 1"
    assert refused("plan", "band_hz", [1.0, True]) == \
        "limits.toml: plan.band_hz = [1.0, True]: expected a list of positive numbers in Hz"
    assert refused("plan", "mass_range", 0.5) == "limits.toml: plan.mass_range = 0.5 is outside the accepted range [1, inf)"
    assert refused("plan", "injection", "sine") == \
        "limits.toml: plan.injection = 'sine': expected one of 'multisine', 'prbs'"
    with pytest.raises(SpecError, match=r"^limits\.toml: limits\.u_max: missing \(required in \[limits\]\)$"):
        excite_spec_from_mapping({"limits": {k: v for k, v in MINIMAL["limits"].items() if k != "u_max"},
                                  "drive": MINIMAL["drive"]})


# --------------------------------------------------------------------------- any table: one of our errors, or a spec

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_values = st.one_of(st.booleans(), st.integers(-2**70, 2**70), st.floats(allow_nan=True, allow_infinity=True),
                    st.text(max_size=4), st.sampled_from(["m", "rad", "prbs", "V"]),
                    st.lists(st.one_of(st.floats(allow_nan=True), st.booleans(), st.text(max_size=2)), max_size=3),
                    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(changes=st.lists(st.tuples(st.sampled_from([k.path for k in LIMITS_KEYS] + ["plan.zzz", "zzz.a"]), _values),
                        max_size=4))
def test_any_limits_table_gives_one_named_error_or_a_spec(changes):
    data = json.loads(json.dumps(MINIMAL))
    for path, value in changes:
        section, key = path.split(".")
        data.setdefault(section, {})[key] = value
    try:
        excite_spec_from_mapping(data)
    except SpecError as exc:  # one line, naming the file and then a section the file has (or a key of it)
        msg = str(exc)
        assert msg.startswith("limits.toml: ") and "\n" not in msg, msg
        named = msg[len("limits.toml: "):].split(" ")[0].split(":")[0].split(".")[0]
        assert named in data, msg
