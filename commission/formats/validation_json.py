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

from commission.formats.ident_json import UNIT_VOCABULARY_Q, UNIT_VOCABULARY_U
from commission.formats.json_table import Field, build_json_model, check_json, header_rows, rows
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
    *header_rows(VALIDATION_KIND, VALIDATION_SCHEMA_VERSION),
    *rows("""
passed                   | boolean    | - | required
    every check of the gate held (controller.json was written)
seed                     | integer    | - | required nonneg
    seed of the Monte-Carlo sample (--seed)
monte_carlo              | integer    | - | required nonneg
    Monte-Carlo plants simulated (--monte-carlo)
units                    | object     | - | required closed
    command and position units of the other fields
units.u                  | string     | - | required
    command unit ("u")
units.q                  | string     | - | required
    position unit ("q")
simulation               | object     | - | required
    what every scenario was simulated with
simulation.substeps      | integer    | - | required positive
    plant sub-steps per controller sample
simulation.quantization  | number     | q | required nonneg
    encoder step simulated
simulation.e_abort       | number     | q | required positive
    a run aborts when |q - q_d| exceeds it (the travel)
simulation.u_sat         | number     | u | required nullable positive
    actuator limit simulated (null: none)
simulation.sample_period | number     | s | required positive
    controller sample period
gate                     | object     | - | required
    the resolved gate every check used (commission.gate.GateLimits)
gate.e_M                 | number     | q | -
    limit on the maximal tracking error
gate.e_F                 | number     | q | -
    limit on the final tracking error
gate.e_rms               | number     | q | -
    limit on the rms tracking error
gate.c_u                 | number     | - | -
    limit on the control-input chattering
gate.u_max               | number     | u | -
    limit on the peak command
gate.no_divergence       | boolean    | - | -
    no run may diverge
gate.arc_vs_pid_e_rms    | number     | - | -
    ARC e_rms / PID e_rms on every run (null or absent: off)
gate.arc_vs_pid_slack    | number     | q | -
    slack added to f x PID e_rms in the comparisons
gate.arc_vs_pid_every    | boolean    | - | -
    arc_vs_pid_e_rms holds on every run
gate.arc_vs_pid_median   | number     | - | -
    limit on the median ARC/PID e_rms ratio (Monte Carlo)
gate.arc_vs_pid_p90      | number     | - | -
    limit on the 90th percentile of that ratio
gate.arc_vs_pid_nominal  | number     | - | -
    limit on ARC/PID e_rms on the identified plant
gate.absolute_limits     | string     | - | -
    where the absolute error limits came from ("fixed", "yardstick", "reported")
gate.lsb                 | number     | q | -
    encoder step the defaults were resolved with
gate.travel              | number     | q | -
    travel the defaults were resolved with
gate.basis               | string map | - | -
    limit -> where its value came from (gate.toml, a default's rule)
gate.defaulted_limits    | strings    | - | -
    the limits that took their default
gate.comparison_reported | strings    | - | -
    comparison criteria reported, not gated: no PID keeps the margin floors (no yardstick)
failures                 | objects    | - | required
    every check that failed, in the order checked (empty: passed)
""", {"units.u": dict(choices=UNIT_VOCABULARY_U), "units.q": dict(choices=UNIT_VOCABULARY_Q)}),
    *_check_rows("failures.*", "one failed check"),
    Field("worst", "map", "", "criterion -> its worst check over every scenario", required=True),
    *_check_rows("worst.*", "the worst check of a criterion"),
    *rows("""
runs        | objects | - | required
    ARC and PID on every scenario, in scenario-matrix order (fixed, robustness, mc/NNN)
runs.*      | object  | - | required
    one scenario (commission.validate.RunRecord)
runs.*.name | string  | - | required
    the scenario (case1/nominal, mc/007, ...)
runs.*.tags | strings | - | required
    its tags (nominal, monte_carlo, robustness, ...)
"""),
    *score_rows("runs.*.arc"),
    *score_rows("runs.*.pid"),
    *rows("""
runs.*.arc_t_abort  | number  | s                       | required nullable
    time the ARC's run aborted (null: it completed)
runs.*.pid_t_abort  | number  | s                       | required nullable
    time the PID's run aborted (null: it completed)
runs.*.theta_final  | any     | [q/(u s^2), 1/s, q/s^2] | required
    the ARC's estimates at the last sample (null entries: not finite)
runs.*.theta_true   | numbers | [q/(u s^2), 1/s, q/s^2] | required len=3
    the scenario plant's [1/M, B/M, -offset/M] (friction not included)
elapsed_s           | number  | s                       | required nonneg
    wall time of the simulations (varies from run to run)
monte_carlo_summary | any     | -                       | -
    quantiles and worst plants of the Monte-Carlo sample (commission.montecarlo.MonteCarloSummary; null: no
    Monte-Carlo plant)
robustness          | object  | -                       | -
    the part of the verdict on the robustness scenarios and the margins (null: not checked)
robustness.passed   | boolean | -                       | required
    every check of that part held
robustness.required | boolean | -                       | required
    the part is required like every other check
robustness.failures | objects | -                       | required
    its failed checks
""", {"runs.*.theta_final": dict(check=nullable_numbers)}),
    *_check_rows("robustness.failures.*", "one failed check"),
    *rows("""
robustness.checks                   | integer | -       | required nonneg
    checks in that part
margins                             | object  | -       | -
    stability margins of both loops on the identified plant
margins.floors                      | object  | -       | required
    the spec's margin floors they are held against
margins.floors.gain_margin_db       | number  | dB      | required
    gain-margin floor
margins.floors.phase_margin_deg     | number  | deg     | required
    phase-margin floor
margins.floors.delay_margin_samples | number  | samples | required
    delay-margin floor
margins.floors.modulus_margin       | number  | -       | required
    modulus-margin floor
margins.loops                       | any     | -       | required
    each loop per plant (commission.robustness.LoopMargins)
margins.worst                       | any     | -       | required
    controller -> its worst margins (null: no loop)
box_robustness                      | any     | -       | -
    the ARC over the whole theta box (commission.robustness.BoxRobustness; absent: not checked)
evidence                            | any     | -       | -
    the band the log backs, the uncertainty weight above it and each loop's robust stability (commission.evidence;
    null: none)
validity                            | any     | u s^2/q | -
    validate narrowed a defaulted payload range: payload_range, mass_range [min, max] in unit,
    default_payload_range, narrowed_by, reason (absent: not narrowed)
""", {"margins.worst": dict(check=object_value),
      "box_robustness": dict(check=object_value),
      "validity": dict(check=validity_record)}),
)

#: The strict model of validation.json (pydantic, built from :data:`VALIDATION_FIELDS`).
ValidationJson = build_json_model("ValidationJson", VALIDATION_FIELDS,
                                  "validation.json: the validation (commission validate).")
#: The rows of one run, in the table's order (what :meth:`RunRecord.to_dict` writes).
RUN_KEYS: tuple[str, ...] = tuple(f.name for f in VALIDATION_FIELDS if f.parent == "runs.*")


def check_validation(data: Any, source: str = "validation.json") -> dict[str, Any]:
    """A parsed validation.json checked against :data:`VALIDATION_FIELDS`
    (:func:`~commission.formats.json_table.check_json`)."""
    return check_json(data, ValidationJson, VALIDATION_FIELDS, VALIDATION_KIND, VALIDATION_SCHEMA_VERSION, source)
