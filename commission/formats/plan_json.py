"""``plan.json``, the excitation plan (``commission excite``): its one table of fields.

Every field :meth:`commission.excite.plan.Plan.to_dict` writes is one
:class:`~commission.formats.json_table.Field` row of :data:`PLAN_FIELDS`; :data:`PlanJson` is the
strict model built from them, :func:`check_plan` the strict reader (``identify --plan`` and a
plan.json beside a log are read through it: :func:`commission.excite.load_plan_json`), and
docs/interface.md §10 (after the outputs of `excite`) and docs/schemas/plan.schema.json are generated from them
(``python -m commission.formats``).

What identify reads back (the segments' times and names, the injection's windows, the rate and
the sample count) is required or checked here; the rest is written for people and ``excite``'s
report.  "q" in a unit is ``units.q`` (limits.toml's ``axis.q_unit``), "u" ``units.u``.  Keys the
table does not name are accepted (additive evolution).  This module imports no simulation code.
"""

from __future__ import annotations

from typing import Any

from commission.formats.json_table import Field, build_json_model, check_json, header_rows, is_finite_number, rows
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
    *header_rows(PLAN_KIND, PLAN_SCHEMA_VERSION),
    *rows("""
units                   | object  | -       | -
    the units of the plan's columns (plan.csv, plan.h5)
units.t                 | string  | -       | -
    time
units.q                 | string  | -       | -
    position (q)
units.u                 | string  | -       | -
    command (u)
units.v                 | string  | -       | -
    speed, q/s
units.a                 | string  | -       | -
    acceleration, q/s^2
sample_rate             | number  | Hz      | positive
    drive rate: one plan row per sample (identify checks the log's)
samples                 | integer | samples | nonneg
    rows of the plan
duration_s              | number  | s       | positive
    length of the run
limits                  | object  | -       | -
    limits.toml's [limits] the plan keeps
limits.travel           | number  | q       | required positive
    the whole span, centred on the start position
limits.v_max            | number  | q/s     | required positive
    peak speed
limits.a_max            | number  | q/s^2   | required positive
    peak acceleration
limits.u_max            | number  | u       | required positive
    peak command
spec                    | any     | -       | -
    the resolved limits.toml, every key (null: not given; its table, §10)
segments                | objects | -       | required
    the plan's segments in time order
segments.*              | object  | -       | required
    one segment [t_start, t_end)
segments.*.name         | string  | -       | required
    bump, approach, ladder, moves, injection, sine F, ...
segments.*.purpose      | string  | -       | required
    what it is for, one line
segments.*.t_start      | number  | s       | required
    start
segments.*.t_end        | number  | s       | required
    end
segments.*.duration     | number  | s       | nonneg
    t_end - t_start
segments.*.windows_s    | any     | s       | -
    injection and stepped sine: the cruise windows [start, end] that carry the signal (identify reads the
    injection's)
segments.*.amplitude    | number  | u       | -
    bump, injection, stepped sine: the peak added command
segments.*.pulse_s      | number  | s       | positive
    bump: width of each pulse
segments.*.speed        | number  | q/s     | -
    ladder leg, moves, injection, stepped sine: the cruise speed
segments.*.leg_length   | number  | q       | -
    ladder leg: its length
segments.*.acceleration | number  | q/s^2   | -
    moves: their acceleration
segments.*.count        | integer | -       | nonneg
    moves: back-and-forth moves
segments.*.kind         | string  | -       | -
    injection: its signal
segments.*.band_hz      | numbers | Hz      | len=2
    injection: the band [low, high] it covers
segments.*.shaping      | number  | -       | -
    injection: multisine line amplitude ~ f^shaping (0: prbs)
segments.*.frequency_hz | number  | Hz      | positive
    stepped sine: its frequency
presimulation           | object  | -       | -
    the plan simulated on rigid models bracketing the mass
presimulation.models    | any     | -       | -
    each model: label, M (u s^2/q), B (u s/q), fc (u) and the holding loop's kp (u/q), kd (u s/q), ki (u/(q s))
""", {"units.t": dict(choices=('s',)),
      "units.q": dict(choices=Q_UNITS),
      "units.u": dict(choices=U_UNITS),
      "spec": dict(check=object_value),
      "segments.*.windows_s": dict(check=_windows),
      "segments.*.kind": dict(choices=('prbs', 'multisine'))}),
    *_peak_rows("presimulation.peaks"),
    *rows("""
presimulation.injection_scale        | number     | -       | nonneg
    fraction of the designed injection amplitude kept
presimulation.motion_scale           | number     | -       | nonneg
    fraction of the designed top speed and acceleration kept
presimulation.note                   | string     | -       | -
    what the models are
predicted_band                       | object     | -       | -
    the band identify is expected to back from a recording of this plan (commission.excite.band.BandPrediction;
    null: not predicted)
predicted_band.band_hz               | numbers    | Hz      | len=2
    [low, high] (null: none)
predicted_band.target_hz             | number     | Hz      | positive
    the band the recording must back (null: none given)
predicted_band.target_source         | string     | -       | -
    "evidence.target_hz" or "1.5 x evidence.first_mode_hz" (null: no target)
predicted_band.short                 | boolean    | -       | -
    the predicted band falls short of the target
predicted_band.n_averages            | integer    | -       | nonneg
    Welch windows over the injection
predicted_band.resolution_hz         | number     | Hz      | positive
    frequency resolution of identify's estimate
predicted_band.mass                  | number     | u s^2/q | positive
    the rigid model's mass the prediction used
predicted_band.encoder_step          | number     | q       | nonneg
    encoder step assumed or given
predicted_band.encoder_noise         | number     | q       | nonneg
    encoder noise, rms, assumed or given
predicted_band.encoder_step_assumed  | boolean    | -       | -
    limits.toml gave no axis.encoder_step
predicted_band.encoder_noise_assumed | boolean    | -       | -
    limits.toml gave no axis.encoder_noise
predicted_band.floor_psd             | number     | q^2/Hz  | nonneg
    the measurement's noise floor
predicted_band.remedies              | any        | -       | -
    when short: what would reach the target
predicted_band.rule                  | string     | -       | -
    the rule the band was predicted by
predicted_band.units                 | string map | -       | -
    field -> its unit, in the plan's units
"""),
)

#: The strict model of plan.json (pydantic, built from :data:`PLAN_FIELDS`).
PlanJson = build_json_model("PlanJson", PLAN_FIELDS, "plan.json: the excitation plan (commission excite).")


def check_plan(data: Any, source: str = "plan.json") -> dict[str, Any]:
    """A parsed plan.json checked against :data:`PLAN_FIELDS` (:func:`~commission.formats.json_table.check_json`)."""
    return check_json(data, PlanJson, PLAN_FIELDS, PLAN_KIND, PLAN_SCHEMA_VERSION, source)
