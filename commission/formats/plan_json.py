"""``plan.json``, the excitation plan (``commission excite``): its one table of fields.

Every field :meth:`commission.excite.plan.Plan.to_dict` writes is one
:class:`~commission.formats.json_table.Field` row of :data:`PLAN_FIELDS`; :data:`PlanJson` is the
strict model built from them, :func:`check_plan` the strict reader (``identify --plan`` and a
plan.json beside a log are read through it: :func:`commission.excite.load_plan_json`), and
docs/interface.md §11 and docs/schemas/plan.schema.json are generated from them
(``python -m commission.formats``).

What identify reads back (the segments' times and names, the injection's windows, the rate and
the sample count) is required or checked here; the rest is written for people and ``excite``'s
report.  "q" in a unit is ``units.q`` (limits.toml's ``axis.q_unit``), "u" ``units.u``.  Keys the
table does not name are accepted (additive evolution).  This module imports no simulation code.
"""

from __future__ import annotations

from typing import Any

from pydantic import ValidationError

from commission.errors import SchemaError
from commission.formats.json_table import Field, build_json_model, check_header, json_error, is_finite_number
from commission.formats.limits_toml import Q_UNITS, U_UNITS
from commission.formats.tuning_json import object_value

PLAN_KIND = "excitation_plan"
#: Version of plan.json and of docs/schemas/plan.schema.json.
PLAN_SCHEMA_VERSION = 1


def _windows(v: Any) -> None:
    """``segments[].windows_s``: a list of ``[start, end]`` pairs, s."""
    if not isinstance(v, list):
        raise ValueError(("", "expected a list of [start, end] pairs"))
    for i, w in enumerate(v):
        if not (isinstance(w, list) and len(w) == 2 and all(is_finite_number(x) for x in w) and w[0] <= w[1]):
            raise ValueError((f"[{i}]", f"expected a [start, end] pair of finite numbers, got {w!r}"))


def _peak_rows(prefix: str) -> list[Field]:
    return [
        Field(prefix, "map", "", "quantity (u, travel, v, a) -> its peak over the models against its limit",
              required=True),
        Field(f"{prefix}.*", "object", "", "one quantity", required=True),
        Field(f"{prefix}.*.peak", "number", "its unit", "largest value over the models", required=True),
        Field(f"{prefix}.*.limit", "number", "its unit", "the limit of limits.toml it is held against",
              required=True),
        Field(f"{prefix}.*.unit", "string", "", "the unit of peak and limit", required=True),
        Field(f"{prefix}.*.note", "string", "", "how the peak is measured, where it needs saying"),
    ]


PLAN_FIELDS: tuple[Field, ...] = (
    Field("kind", "string", "", f'"{PLAN_KIND}"', required=True),
    Field("schema_version", "integer", "", f"1..{PLAN_SCHEMA_VERSION}: the version of this layout", required=True),
    Field("units", "object", "", "the units of the plan's columns (plan.csv, plan.h5)"),
    Field("units.t", "string", "", "time", choices=("s",)),
    Field("units.q", "string", "", "position (q)", choices=Q_UNITS),
    Field("units.u", "string", "", "command (u)", choices=U_UNITS),
    Field("units.v", "string", "", "speed, q/s"),
    Field("units.a", "string", "", "acceleration, q/s^2"),
    Field("sample_rate", "number", "Hz", "drive rate: one plan row per sample (identify checks the log's)",
          sign="positive"),
    Field("samples", "integer", "samples", "rows of the plan", sign="nonneg"),
    Field("duration_s", "number", "s", "length of the run", sign="positive"),
    Field("limits", "object", "", "limits.toml's [limits] the plan keeps"),
    Field("limits.travel", "number", "q", "the whole span, centred on the start position", required=True,
          sign="positive"),
    Field("limits.v_max", "number", "q/s", "peak speed", required=True, sign="positive"),
    Field("limits.a_max", "number", "q/s^2", "peak acceleration", required=True, sign="positive"),
    Field("limits.u_max", "number", "u", "peak command", required=True, sign="positive"),
    Field("spec", "any", "", "the resolved limits.toml, every key (null: not given; its table, §10)",
          check=object_value),
    Field("segments", "objects", "", "the plan's segments in time order", required=True),
    Field("segments.*", "object", "", "one segment [t_start, t_end)", required=True),
    Field("segments.*.name", "string", "", "bump, approach, ladder, moves, injection, sine F, ...", required=True),
    Field("segments.*.purpose", "string", "", "what it is for, one line", required=True),
    Field("segments.*.t_start", "number", "s", "start", required=True),
    Field("segments.*.t_end", "number", "s", "end", required=True),
    Field("segments.*.duration", "number", "s", "t_end - t_start", sign="nonneg"),
    Field("segments.*.windows_s", "any", "s", "injection and stepped sine: the cruise windows [start, end] that "
          "carry the signal (identify reads the injection's)", check=_windows),
    Field("segments.*.amplitude", "number", "u", "bump, injection, stepped sine: the peak added command"),
    Field("segments.*.pulse_s", "number", "s", "bump: width of each pulse", sign="positive"),
    Field("segments.*.speed", "number", "q/s", "ladder leg, moves, injection, stepped sine: the cruise speed"),
    Field("segments.*.leg_length", "number", "q", "ladder leg: its length"),
    Field("segments.*.acceleration", "number", "q/s^2", "moves: their acceleration"),
    Field("segments.*.count", "integer", "", "moves: back-and-forth moves", sign="nonneg"),
    Field("segments.*.kind", "string", "", "injection: its signal", choices=("prbs", "multisine")),
    Field("segments.*.band_hz", "numbers", "Hz", "injection: the band [low, high] it covers", length=2),
    Field("segments.*.shaping", "number", "", "injection: multisine line amplitude ~ f^shaping (0: prbs)"),
    Field("segments.*.frequency_hz", "number", "Hz", "stepped sine: its frequency", sign="positive"),
    Field("presimulation", "object", "", "the plan simulated on rigid models bracketing the mass"),
    Field("presimulation.models", "any", "", "each model: label, M (u s^2/q), B (u s/q), fc (u) and the holding "
          "loop's kp (u/q), kd (u s/q), ki (u/(q s))"),
    *_peak_rows("presimulation.peaks"),
    Field("presimulation.injection_scale", "number", "", "fraction of the designed injection amplitude kept",
          sign="nonneg"),
    Field("presimulation.motion_scale", "number", "", "fraction of the designed top speed and acceleration kept",
          sign="nonneg"),
    Field("presimulation.note", "string", "", "what the models are"),
    Field("predicted_band", "object", "", "the band identify is expected to back from a recording of this plan "
          "(commission.excite.band.BandPrediction; null: not predicted)"),
    Field("predicted_band.band_hz", "numbers", "Hz", "[low, high] (null: none)", length=2),
    Field("predicted_band.target_hz", "number", "Hz", "the band the recording must back (null: none given)",
          sign="positive"),
    Field("predicted_band.target_source", "string", "", "\"evidence.target_hz\" or \"1.5 x evidence.first_mode_hz\" (null: no target)"),
    Field("predicted_band.short", "boolean", "", "the predicted band falls short of the target"),
    Field("predicted_band.n_averages", "integer", "", "Welch windows over the injection", sign="nonneg"),
    Field("predicted_band.resolution_hz", "number", "Hz", "frequency resolution of identify's estimate",
          sign="positive"),
    Field("predicted_band.mass", "number", "u s^2/q", "the rigid model's mass the prediction used",
          sign="positive"),
    Field("predicted_band.encoder_step", "number", "q", "encoder step assumed or given", sign="nonneg"),
    Field("predicted_band.encoder_noise", "number", "q", "encoder noise, rms, assumed or given", sign="nonneg"),
    Field("predicted_band.encoder_step_assumed", "boolean", "", "limits.toml gave no axis.encoder_step"),
    Field("predicted_band.encoder_noise_assumed", "boolean", "", "limits.toml gave no axis.encoder_noise"),
    Field("predicted_band.floor_psd", "number", "q^2/Hz", "the measurement's noise floor", sign="nonneg"),
    Field("predicted_band.remedies", "any", "", "when short: what would reach the target"),
    Field("predicted_band.rule", "string", "", "the rule the band was predicted by"),
    Field("predicted_band.units", "string map", "", "field -> its unit, in the plan's units"),
)

#: The strict model of plan.json (pydantic, built from :data:`PLAN_FIELDS`).
PlanJson = build_json_model("PlanJson", PLAN_FIELDS, "plan.json: the excitation plan (commission excite).")


def check_plan(data: Any, source: str = "plan.json") -> dict[str, Any]:
    """``data`` (a parsed plan.json) checked strictly against the table; returned as it is.

    Raises
    ------
    SchemaError
        One line naming the JSON path of the first refused value.
    """
    check_header(data, PLAN_KIND, PLAN_SCHEMA_VERSION, source)
    try:
        PlanJson.model_validate(data)
    except ValidationError as exc:
        raise SchemaError(json_error(exc, PLAN_FIELDS, source=source)) from None
    return data
