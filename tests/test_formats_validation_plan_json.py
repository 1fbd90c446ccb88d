"""commission.formats.validation_json and plan_json: the two artifacts' tables, their strict readers, the text tables.

The walk of every field through docs and schema is tests/test_formats_one_place.py's; here: a file the
tool wrote loads and holds no key its table does not name, a bad value is refused naming its JSON path,
and the text-table readers refuse what they cannot place.
"""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import pytest

from commission.errors import SchemaError
from commission.excite import load_plan_json
from commission.formats.json_table import rows, unnamed
from commission.formats.plan_json import PLAN_FIELDS, check_plan
from commission.formats.table import keys
from commission.formats.validation_json import RUN_KEYS, VALIDATION_FIELDS, check_validation

ROOT = Path(__file__).resolve().parents[1]
PLAN = json.loads((ROOT / "sample_data" / "plan.json").read_text())

#: A validation.json as validate writes it, cut to one run and one check (the layout is the point).
_CHECK = {"criterion": "e_rms", "scenario": "case1/nominal", "value": 1e-6, "limit": 2e-5, "passed": True,
          "detail": "1 um (limit 20 um)"}
_SCORE = {"e_M": 1e-5, "e_F": 1e-6, "e_rms": 1e-6, "u_rms": 0.1, "du_rms": 0.01, "c_u": 0.05, "u_peak": 0.7,
          "diverged": False}
VALIDATION = {
    "kind": "validation", "schema_version": 1, "passed": True, "seed": 0, "monte_carlo": 0,
    "units": {"u": "V", "q": "m"},
    "simulation": {"substeps": 10, "quantization": 1e-6, "e_abort": 0.4, "u_sat": 10.0, "sample_period": 4e-4},
    "gate": {"e_M": 8e-4, "e_F": 4e-5, "e_rms": 2e-5, "c_u": 1.0, "u_max": 10.0, "no_divergence": True,
             "arc_vs_pid_e_rms": 1.0, "arc_vs_pid_slack": 2.9e-7, "arc_vs_pid_every": False,
             "arc_vs_pid_median": 1.0, "arc_vs_pid_p90": 1.2, "arc_vs_pid_nominal": 1.0, "basis": {"c_u": "default: 1"},
             "lsb": 1e-6, "travel": 0.4, "absolute_limits": "yardstick", "defaulted_limits": ["c_u"]},
    "failures": [], "worst": {"e_rms": _CHECK},
    "runs": [{"name": "case1/nominal", "tags": ["nominal"], "arc": _SCORE, "pid": {**_SCORE, "e_M": None,
              "diverged": True}, "arc_t_abort": None, "pid_t_abort": 1.5, "theta_final": [33.0, None, 0.0],
              "theta_true": [33.3, 0.0, 0.0]}],
    "elapsed_s": 0.5, "monte_carlo_summary": None,
    "robustness": {"passed": True, "required": True, "failures": [], "checks": 3},
    "margins": {"floors": {"gain_margin_db": 6.0, "phase_margin_deg": 30.0, "delay_margin_samples": 1.0,
                           "modulus_margin": 0.5}, "loops": [], "worst": {"arc": None, "pid": None}},
    "evidence": None,
}


def _with(doc: dict, path: str, value: object) -> dict:
    """A copy of ``doc`` with the value at ``path`` (``runs[0].arc.e_rms``) replaced."""
    doc = copy.deepcopy(doc)
    node, parts = doc, re.findall(r"[^.\[\]]+", path)
    for p in parts[:-1]:
        node = node[int(p)] if p.isdigit() else node[p]
    node[parts[-1]] = value
    return doc


def test_a_written_layout_loads_and_every_key_is_named():
    assert check_validation(copy.deepcopy(VALIDATION)) == VALIDATION
    assert unnamed(VALIDATION, VALIDATION_FIELDS) == []
    assert set(VALIDATION["runs"][0]) == set(RUN_KEYS)
    assert load_plan_json(ROOT / "sample_data" / "plan.json") == PLAN and unnamed(PLAN, PLAN_FIELDS) == []
    # a key the table does not name is accepted (additive) and reported by unnamed
    extra = {**copy.deepcopy(VALIDATION), "later": 1}
    extra["runs"][0]["note"] = "x"
    assert check_validation(extra) and sorted(unnamed(extra, VALIDATION_FIELDS)) == ["$.later", "$.runs[0].note"]


def test_the_stored_tuning_and_its_identification_hold_no_key_their_tables_do_not_name():
    from commission.formats.ident_json import IDENT_FIELDS
    from commission.formats.tuning_json import TUNING_FIELDS

    doc = json.loads((ROOT / "tests" / "data" / "tuning_paper_budget8.json").read_text())
    assert unnamed(doc, TUNING_FIELDS) == [] and unnamed(doc["identification"], IDENT_FIELDS) == []


@pytest.mark.parametrize("path, value, want", [
    ("runs[0].arc.e_rms", "x", "$.runs[0].arc.e_rms: expected a finite number, got 'x'"),
    ("runs[0].theta_final", [1.0, "a", None], "$.runs[0].theta_final[1]: expected a number or null, got 'a'"),
    ("runs[0].theta_true", [1.0, 2.0], "$.runs[0].theta_true: expected 3 numbers, got 2"),
    ("failures", {}, "$.failures: expected a list of objects, got dict"),
    ("worst.e_rms.passed", 1, "$.worst.e_rms.passed: expected true or false, got 1"),
    ("units.q", "mm", "$.units.q: expected one of ['m', 'rad'], got 'mm'"),
    ("simulation.substeps", 0, "$.simulation.substeps: expected a positive number, got 0"),
    ("robustness.failures", [{"criterion": "c_u"}], "$.robustness.failures[0].scenario: missing required field"),
])
def test_a_bad_validation_value_is_named_by_its_json_path(path, value, want):
    with pytest.raises(SchemaError, match="^" + re.escape(f"v.json: {want}") + "$"):
        check_validation(_with(VALIDATION, path, value), "v.json")


@pytest.mark.parametrize("path, value, want", [
    ("segments[1].t_end", "x", "$.segments[1].t_end: expected a finite number, got 'x'"),
    ("segments[0].name", None, "$.segments[0].name: missing required field"),
    ("kind", "validation", "$.kind: expected kind 'excitation_plan', got 'validation'"),
    ("schema_version", 2, "$.schema_version: unsupported schema_version 2 (this tool reads 1..1)"),
    ("presimulation.peaks.u.limit", True, "$.presimulation.peaks.u.limit: expected a finite number, got True"),
])
def test_a_bad_plan_value_is_named_by_its_json_path(path, value, want):
    with pytest.raises(SchemaError, match="^" + re.escape(f"p.json: {want}") + "$"):
        check_plan(_with(PLAN, path, value), "p.json")


def test_the_injection_windows_are_checked_pair_by_pair():
    doc = copy.deepcopy(PLAN)
    inj = next(g for g in doc["segments"] if g["name"] == "injection")
    i = doc["segments"].index(inj)
    inj["windows_s"] = [[0.0, 1.0], [2.0, 1.0]]
    with pytest.raises(SchemaError, match=re.escape(f"$.segments[{i}].windows_s[1]: expected a [start, end] pair")):
        check_plan(doc)


def test_the_text_tables_refuse_what_they_cannot_place():
    got = rows("""
a     | object | -  | required closed
    an object
a.b   | number | Hz | nonneg len=2
    a number whose doc
    goes on
""", {"a.b": {"range": (0.0, 5.0)}})
    assert [(f.path, f.required, f.closed, f.sign, f.length, f.range, f.doc) for f in got] == [
        ("a", True, True, None, None, None, "an object"), ("a.b", False, False, "nonneg", 2, (0.0, 5.0),
                                                           "a number whose doc goes on")]
    with pytest.raises(ValueError, match=r"rows the table does not hold: \['a\.c'\]"):
        rows("a | object | - | -\n    x\n", {"a.c": {}})
    with pytest.raises(KeyError):
        rows("a | number | - | sometimes\n    x\n")
    # a unit that is another table's is written "*" and given by extra, and only then
    assert rows("a | number | * | -\n    x\n", {"a": {"unit": "m"}})[0].unit == "m"
    for text, extra in (("a | number | * | -\n", {}), ("a | number | s | -\n", {"a": {"unit": "m"}})):
        with pytest.raises(ValueError, match=r"a unit is '\*' exactly when extra gives it: \['a'\]"):
            rows(text, extra)
    k = keys("""
s.n | integer | 8        | (0, inf) | - | -
    a count
s.r | number  | required | [0, 1)   | m | -
    a length
""")
    assert [(x.path, x.type, x.default, x.range, x.open, x.required, x.doc) for x in k] == [
        ("s.n", int, 8, (0.0, float("inf")), (True, False), False, "a count"),
        ("s.r", float, None, (0.0, 1.0), (False, True), True, "a length")]
    assert [x.range_text() for x in k] == ["(0, inf)", "[0, 1)"]


@pytest.mark.parametrize("module", sorted(p.name for p in (ROOT / "commission" / "formats").glob("*.py")))
def test_no_format_module_imports_simulation_code(module):
    src = (ROOT / "commission" / "formats" / module).read_text()
    imports = re.findall(r"^\s*(?:from|import) (commission\.[\w.]+)", src, re.M)
    # The one exception is the indexes' table: pure data, no numpy or numba.
    assert all(m.split(".")[1] in ("formats", "errors", "logs") or m == "commission.controllers.index_table"
               for m in imports), imports
