"""``validation.json``, the validation's record (``commission validate``): its one table of fields.

Every field :meth:`commission.validate.ValidationResult.to_dict` writes is one
:class:`~commission.formats.json_table.Field` row of :data:`VALIDATION_FIELDS`;
:data:`ValidationJson` is the strict model built from them, :func:`check_validation` the strict
reader (``commission fleet`` reads the files it lists through it), and docs/interface.md §5 and
docs/schemas/validation.schema.json are generated from them (``python -m commission.formats``).
A run's keys (``runs.*``) are the rows :meth:`commission.validate.RunRecord.to_dict` writes.

Records that other modules write and read back are named here by the code that owns them, as
``any`` rows, and checked by it: the resolved gate's basis lines, the stability margins of each
loop (:class:`commission.robustness.LoopMargins`), the box check
(:class:`commission.robustness.BoxRobustness`), the evidence (:mod:`commission.evidence`) and
the Monte-Carlo summary (:mod:`commission.montecarlo`).  "u" in a unit is ``units.u``, "q"
``units.q``.  This module imports no simulation code.
"""

from __future__ import annotations

from typing import Any

from pydantic import ValidationError

from commission.errors import SchemaError
from commission.formats.ident_json import UNIT_VOCABULARY_Q, UNIT_VOCABULARY_U
from commission.formats.json_table import Field, build_json_model, check_header, json_error
from commission.formats.tuning_json import nullable_numbers, object_value, score_rows, validity_record

VALIDATION_KIND = "validation"
#: Version of validation.json and of docs/schemas/validation.schema.json.
VALIDATION_SCHEMA_VERSION = 1

_CHECK_UNIT = "the criterion's (detail states it)"


def _check_rows(prefix: str, what: str) -> list[Field]:
    """One gate check (:class:`commission.gate.CheckResult`) at ``prefix``."""
    return [
        Field(prefix, "object", "", what, required=True),
        Field(f"{prefix}.criterion", "string", "", "the criterion (e_M, c_u, floor:margins, ...)", required=True),
        Field(f"{prefix}.scenario", "string", "", "where it was checked (a scenario, a plant, a limit)",
              required=True),
        Field(f"{prefix}.value", "number", _CHECK_UNIT, "the value found (null: none, or not finite)",
              required=True, nullable=True),
        Field(f"{prefix}.limit", "number", _CHECK_UNIT, "the limit it was held against (null: none)",
              required=True, nullable=True),
        Field(f"{prefix}.passed", "boolean", "", "it held", required=True),
        Field(f"{prefix}.detail", "string", "", "value and limit in one readable line, with units", required=True),
    ]


VALIDATION_FIELDS: tuple[Field, ...] = (
    Field("kind", "string", "", f'"{VALIDATION_KIND}"', required=True),
    Field("schema_version", "integer", "", f"1..{VALIDATION_SCHEMA_VERSION}: the version of this layout",
          required=True),
    Field("passed", "boolean", "", "every check of the gate held (controller.json was written)", required=True),
    Field("seed", "integer", "", "seed of the Monte-Carlo sample (--seed)", required=True, sign="nonneg"),
    Field("monte_carlo", "integer", "", "Monte-Carlo plants simulated (--monte-carlo)", required=True,
          sign="nonneg"),
    Field("units", "object", "", "command and position units of the other fields", required=True, closed=True),
    Field("units.u", "string", "", "command unit (\"u\")", required=True, choices=UNIT_VOCABULARY_U),
    Field("units.q", "string", "", "position unit (\"q\")", required=True, choices=UNIT_VOCABULARY_Q),
    Field("simulation", "object", "", "what every scenario was simulated with", required=True),
    Field("simulation.substeps", "integer", "", "plant sub-steps per controller sample", required=True,
          sign="positive"),
    Field("simulation.quantization", "number", "q", "encoder step simulated", required=True, sign="nonneg"),
    Field("simulation.e_abort", "number", "q", "a run aborts when |q - q_d| exceeds it (the travel)",
          required=True, sign="positive"),
    Field("simulation.u_sat", "number", "u", "actuator limit simulated (null: none)", required=True,
          nullable=True, sign="positive"),
    Field("simulation.sample_period", "number", "s", "controller sample period", required=True, sign="positive"),
    Field("gate", "object", "", "the resolved gate every check used (commission.gate.GateLimits)", required=True),
    Field("gate.e_M", "number", "q", "limit on the maximal tracking error"),
    Field("gate.e_F", "number", "q", "limit on the final tracking error"),
    Field("gate.e_rms", "number", "q", "limit on the rms tracking error"),
    Field("gate.c_u", "number", "", "limit on the control-input chattering"),
    Field("gate.u_max", "number", "u", "limit on the peak command"),
    Field("gate.lsb", "number", "q", "encoder step the defaults were resolved with"),
    Field("gate.travel", "number", "q", "travel the defaults were resolved with"),
    Field("gate.basis", "string map", "", "limit -> where its value came from (gate.toml, a default's rule)"),
    Field("gate.defaulted_limits", "strings", "", "the limits that took their default"),
    Field("failures", "objects", "", "every check that failed, in the order checked (empty: passed)",
          required=True),
    *_check_rows("failures.*", "one failed check"),
    Field("worst", "map", "", "criterion -> its worst check over every scenario", required=True),
    *_check_rows("worst.*", "the worst check of a criterion"),
    Field("runs", "objects", "", "ARC and PID on every scenario, in scenario-matrix order (fixed, robustness, "
          "mc/NNN)", required=True),
    Field("runs.*", "object", "", "one scenario (commission.validate.RunRecord)", required=True),
    Field("runs.*.name", "string", "", "the scenario (case1/nominal, mc/007, ...)", required=True),
    Field("runs.*.tags", "strings", "", "its tags (nominal, monte_carlo, robustness, ...)", required=True),
    *score_rows("runs.*.arc"),
    *score_rows("runs.*.pid"),
    Field("runs.*.arc_t_abort", "number", "s", "time the ARC's run aborted (null: it completed)", required=True,
          nullable=True),
    Field("runs.*.pid_t_abort", "number", "s", "time the PID's run aborted (null: it completed)", required=True,
          nullable=True),
    Field("runs.*.theta_final", "any", "[q/(u s^2), 1/s, q/s^2]", "the ARC's estimates at the last sample "
          "(null entries: not finite)", required=True, check=nullable_numbers),
    Field("runs.*.theta_true", "numbers", "[q/(u s^2), 1/s, q/s^2]", "the scenario plant's [1/M, B/M, "
          "-offset/M] (friction not included)", required=True, length=3),
    Field("elapsed_s", "number", "s", "wall time of the simulations (varies from run to run)", required=True,
          sign="nonneg"),
    Field("monte_carlo_summary", "any", "", "quantiles and worst plants of the Monte-Carlo sample "
          "(commission.montecarlo.MonteCarloSummary; null: no Monte-Carlo plant)"),
    Field("robustness", "object", "", "the part of the verdict on the robustness scenarios and the margins "
          "(null: not checked)"),
    Field("robustness.passed", "boolean", "", "every check of that part held", required=True),
    Field("robustness.required", "boolean", "", "the part is required like every other check", required=True),
    Field("robustness.failures", "objects", "", "its failed checks", required=True),
    *_check_rows("robustness.failures.*", "one failed check"),
    Field("robustness.checks", "integer", "", "checks in that part", required=True, sign="nonneg"),
    Field("margins", "object", "", "stability margins of both loops on the identified plant"),
    Field("margins.floors", "object", "", "the spec's margin floors they are held against", required=True),
    Field("margins.floors.gain_margin_db", "number", "dB", "gain-margin floor", required=True),
    Field("margins.floors.phase_margin_deg", "number", "deg", "phase-margin floor", required=True),
    Field("margins.floors.delay_margin_samples", "number", "samples", "delay-margin floor", required=True),
    Field("margins.floors.modulus_margin", "number", "", "modulus-margin floor", required=True),
    Field("margins.loops", "any", "", "each loop per plant (commission.robustness.LoopMargins)", required=True),
    Field("margins.worst", "any", "", "controller -> its worst margins (null: no loop)", required=True,
          check=object_value),
    Field("box_robustness", "any", "", "the ARC over the whole theta box (commission.robustness.BoxRobustness; "
          "absent: not checked)", check=object_value),
    Field("evidence", "any", "", "the band the log backs, the uncertainty weight above it and each loop's robust "
          "stability (commission.evidence; null: none)"),
    Field("validity", "any", "u s^2/q", "validate narrowed a defaulted payload range: payload_range, mass_range "
          "[min, max] in unit, default_payload_range, narrowed_by, reason (absent: not narrowed)",
          check=validity_record),
)

#: The strict model of validation.json (pydantic, built from :data:`VALIDATION_FIELDS`).
ValidationJson = build_json_model("ValidationJson", VALIDATION_FIELDS,
                                  "validation.json: the validation (commission validate).")
#: The rows of one run, in the table's order (what :meth:`RunRecord.to_dict` writes).
RUN_KEYS: tuple[str, ...] = tuple(f.name for f in VALIDATION_FIELDS if f.parent == "runs.*")


def check_validation(data: Any, source: str = "validation.json") -> dict[str, Any]:
    """``data`` (a parsed validation.json) checked strictly against the table; returned as it is.

    Raises
    ------
    SchemaError
        One line naming the JSON path of the first refused value.
    """
    check_header(data, VALIDATION_KIND, VALIDATION_SCHEMA_VERSION, source)
    try:
        ValidationJson.model_validate(data)
    except ValidationError as exc:
        raise SchemaError(json_error(exc, VALIDATION_FIELDS, source=source)) from None
    return data
