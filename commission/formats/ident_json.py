"""``ident.json``, the identification artifact: its one table of fields.

Every field :class:`commission.artifacts.Identification` reads, and every field the
identification writes that another stage reads, is one :class:`~commission.formats.json_table.Field`
row of :data:`IDENT_FIELDS`, with its JSON path, type, accepted values, unit and one-line doc.
:data:`IdentJson` is the strict model built from them; ``Identification.from_dict`` validates
through it, and docs/interface.md §2 and docs/schemas/ident.schema.json are generated from them
(``python -m commission.formats``).  The ranges of the encoder's step and noise are the spec's
rows for the same quantities (:data:`commission.formats.spec_toml.SPEC_KEYS`), so that a value
ident.json may carry is one the spec may state.

Rows of type ``any`` are fields written for people and reports (provenance, the frequency
response's curves, the model selection's table): named here with their unit so that the table
is complete, and read by the code the doc names.  Keys the table does not name are accepted
(additive evolution), except in ``units``.  "u" in a unit is the command unit ``units.u``,
"q" the position unit ``units.q`` (m, or rad on a rotary axis).
"""

from __future__ import annotations

from typing import Any

from commission.formats.json_table import Field, build_json_model, is_finite_number
from commission.formats.spec_toml import SPEC_KEYS
from commission.logs.model import U_UNITS

IDENT_KIND = "identification"
#: Version of ident.json and of docs/schemas/ident.schema.json.
IDENT_SCHEMA_VERSION = 1
#: Parameters of CONTRACT §2 in a stable order; the first four are required (null only when not identified).
PARAMETER_NAMES = ("M", "B", "fc", "fs", "vs", "xi", "offset")
REQUIRED_PARAMETERS = ("M", "B", "fc", "offset")
#: ``units.u``: exactly the command units this tool itself writes (:data:`commission.logs.model.U_UNITS`).
UNIT_VOCABULARY_U = U_UNITS
#: ``units.q``: a linear axis in m (a log in mm or um is converted on reading), a rotary one in rad.
UNIT_VOCABULARY_Q = ("m", "rad")

_SPEC = {(k.section, k.name): k for k in SPEC_KEYS}
_QUANT = _SPEC[("controller", "quantization")]
_NOISE = _SPEC[("plant", "noise_std")]


def _is_sha256(v: Any) -> bool:
    return isinstance(v, str) and len(v) == 64 and all(c in "0123456789abcdef" for c in v)


def _sha256_or_list(v: Any) -> None:
    """``source.sha256``: one digest, or one per file when several logs were fitted together."""
    for i, d in enumerate(v if isinstance(v, list) else [v]):
        if not _is_sha256(d):
            raise ValueError((f"[{i}]" if isinstance(v, list) else "",
                              f"expected a sha256 (64 lowercase hex digits), got {str(d)[:80]!r}"))


def _ripple_amp(v: Any) -> None:
    """``model.ripple_amp``: a number, or ``{value, std}`` (std >= 0)."""
    if isinstance(v, dict):
        for k in ("value", "std"):
            x = v.get(k)
            if x is None:
                raise ValueError((f".{k}", "missing required field"))
            if not is_finite_number(x):
                raise ValueError((f".{k}", f"expected a finite number, got {x!r}"))
        if v["std"] < 0:
            raise ValueError((".std", f"expected a non-negative number, got {v['std']!r}"))
    elif not is_finite_number(v):
        raise ValueError(("", f"expected a finite number, got {v!r}"))


def _narrowed(m: Any) -> None:
    if not m.theta3_min <= m.theta3_max:
        raise ValueError(("", f"theta3_min {m.theta3_min!r} exceeds theta3_max {m.theta3_max!r}"))


def _structural(m: Any) -> None:
    """``frequency_response.model``: a mode's entries come together; damping and load fractions below 1."""
    if m.mode_hz is None:
        return
    for k in ("mode_damping", "mode_ratio", "mode_load_side"):
        if getattr(m, k) is None:
            raise ValueError((f".{k}", "missing required field"))
    if not m.mode_damping < 1:
        raise ValueError((".mode_damping", f"expected a damping ratio below 1, got {m.mode_damping!r}"))
    if not m.mode_ratio < 1:
        raise ValueError((".mode_ratio", f"expected a load fraction below 1, got {m.mode_ratio!r}"))
    if m.mode2_hz is None:
        return
    for k in ("mode2_damping", "mode2_ratio", "mode2_load_side"):
        if getattr(m, k) is None:
            raise ValueError((f".{k}", "missing required field"))
    if not m.mode2_damping < 1:
        raise ValueError((".mode2_damping", f"expected a damping ratio below 1, got {m.mode2_damping!r}"))
    if not m.mode_ratio + m.mode2_ratio < 1:
        raise ValueError((".mode2_ratio", f"expected mode_ratio + mode2_ratio below 1, got "
                                          f"{m.mode_ratio!r} + {m.mode2_ratio!r}"))


_PARAM_DOC = {
    "M": ("u s^2/q", "mass M (on a rotary axis the inertia J)"),
    "B": ("u s/q", "viscous friction"),
    "fc": ("u", "Coulomb friction level"),
    "fs": ("u", "static (Stribeck peak) friction level; null for the Coulomb model"),
    "vs": ("q/s", "Stribeck velocity; null for the Coulomb model"),
    "xi": ("", "Stribeck exponent; null for the Coulomb model"),
    "offset": ("u", "command offset (d_n = -offset)"),
}


def _parameter_rows() -> list[Field]:
    rows = [Field("parameters", "object", "", "the identified parameters, each {value, std}", required=True)]
    for name in PARAMETER_NAMES:
        unit, doc = _PARAM_DOC[name]
        req = name in REQUIRED_PARAMETERS
        rows += [
            Field(f"parameters.{name}", "object", "", doc + (" (null: see not_identified)" if req else ""),
                  required=req, nullable=req),
            Field(f"parameters.{name}.value", "number", unit, f"{name}, the estimate", required=True,
                  sign="positive" if name in ("vs", "xi") else None),
            Field(f"parameters.{name}.std", "number", unit, f"{name}, one standard deviation", required=True,
                  sign="nonneg"),
        ]
    return rows


IDENT_FIELDS: tuple[Field, ...] = (
    Field("kind", "string", "", f'"{IDENT_KIND}"', required=True),
    Field("schema_version", "integer", "", f"1..{IDENT_SCHEMA_VERSION}: the version of this layout", required=True),
    Field("units", "object", "", "the units of every other field", required=True, closed=True),
    Field("units.u", "string", "", "command unit (\"u\" in the units below)", required=True,
          choices=UNIT_VOCABULARY_U),
    Field("units.q", "string", "", "position unit (\"q\" below): m, or rad on a rotary axis", required=True,
          choices=UNIT_VOCABULARY_Q),
    *_parameter_rows(),
    Field("not_identified", "string map", "", "parameter -> why the log carries no information on it "
          "(that parameter is null; with M null, theta and delta_d are null and tune refuses the file)"),
    Field("fit", "object", "", "the fit's quality", required=True),
    Field("fit.relative_error", "number", "", "||y - y_hat|| / ||y|| on the identification data (a fraction, "
          "not %)", required=True, sign="nonneg"),
    Field("fit.condition_number", "number", "", "of the column-scaled regressor", required=True, sign="positive"),
    Field("fit.validation_relative_error", "number", "", "the same on --validate-on LOG2, or null", sign="nonneg"),
    Field("theta", "object", "", "theta = [1/M, B/M, d_n/M] and its Assumption-1 box (null: M not identified)",
          required=True, nullable=True),
    Field("theta.nominal", "numbers", "[q/(u s^2), 1/s, q/s^2]", "nominal theta", required=True, length=3),
    Field("theta.min", "numbers", "[q/(u s^2), 1/s, q/s^2]", "lower corner of the box (min[0] > 0)",
          required=True, length=3),
    Field("theta.max", "numbers", "[q/(u s^2), 1/s, q/s^2]", "upper corner of the box", required=True, length=3),
    Field("delta_d", "number", "q/s^2", "bound on the lumped uncertain disturbance |d - d_n|/M (the paper's "
          "delta_d); required with theta, null without", sign="nonneg"),
    Field("friction_compensation", "object", "", "F_hat(v) = level (2/pi) atan(slope v)", required=True),
    Field("friction_compensation.level", "number", "u", "level of F_hat", required=True, sign="nonneg"),
    Field("friction_compensation.slope", "number", "s/q", "slope of F_hat", required=True, sign="nonneg"),
    Field("friction_compensation_rms_error", "any", "u", "rms of F_hat against the identified curve over the "
          "data's speeds (report)"),
    Field("log_sha256", "sha256", "", "sha256 of the excitation log (older files; now source.sha256)"),
    Field("quantization", "number", _QUANT.unit, "the older place of encoder.quantization", range=_QUANT.range),
    Field("encoder", "object", "", "what the log says of the encoder"),
    Field("encoder.quantization", "number", _QUANT.unit, "encoder step the tool uses (null: none measured; tune then "
          "assumes the spec's default)", range=_QUANT.range),
    Field("encoder.noise_std", "number", _NOISE.unit, "noise beyond quantization, rms (tune and validate simulate it "
          "unless [plant] noise_std says otherwise)", range=_NOISE.range),
    Field("encoder.apparent_resolution", "number", "q", "smallest step seen in q", sign="nonneg"),
    Field("encoder.noise_rms_total", "any", "q", "rms of the whole measurement error (noise and quantization), "
          "from the spectrum of q - P u over 0.35-0.48 of the sample rate"),
    Field("encoder.quantization_noise_rms", "any", "q", "quantization / sqrt(12), the rounding's share (null: "
          "the log is not on a grid)"),
    Field("encoder.noise_band_hz", "any", "Hz", "[low, high]: the band the floor was read in"),
    Field("source", "object", "", "the log(s) identified"),
    Field("source.sample_rate", "number", "Hz", "sample rate as measured (tune's default rate)", sign="positive"),
    Field("source.n_samples", "integer", "samples", "samples in the log", sign="nonneg"),
    Field("source.sha256", "any", "", "sha256 of the log, or a list of them for several logs",
          check=_sha256_or_list),
    Field("source.path", "any", "", "the log's path, or a list of them"),
    Field("source.input_gain", "any", "", "--input-gain: u_equiv = input_gain u"),
    Field("source.mapping", "any", "", "the log's column mapping"),
    Field("source.q_unit", "any", "", "the file's position unit (\"counts\" under --counts-per-rev)"),
    Field("source.resampled_hz", "any", "Hz", "the uniform rate of --resample, or null"),
    Field("source.conversion", "any", "", "with --counts-per-rev, --lead or --gear: {from, to, counts_per_rev, "
          "lead_m_per_rad, gear_motor_rad_per_load_rad}"),
    Field("validation_source", "any", "", "the --validate-on log(s), as source"),
    Field("model", "object", "", "how the fit was made (method, decimation, cut-off, friction model, fixed "
          "parameters, segments, inverse_dynamics)"),
    Field("model.ripple_pitch", "number", "q", "the first --ripple-pitch", sign="positive"),
    Field("model.ripple_amp", "any", "u", "its amplitude amp sin(2 pi q/P + phase): a number or {value, std}",
          check=_ripple_amp),
    Field("model.ripple_phase", "any", "rad", "its phase"),
    Field("model.ripple_harmonics", "any", "", "every --ripple-pitch with its amp and phase ({value, std})"),
    Field("model.fixed", "any", "", "parameters given with --fix NAME=VALUE (std 0)"),
    Field("model.segments", "any", "samples", "several logs fitted together: the samples of each file"),
    Field("model.inverse_dynamics", "any", "", "identify --friction auto's richer model (docs/interface.md §2)"),
    Field("ripple", "object", "", "the older place of the ripple"),
    Field("ripple.pitch", "number", "q", "ripple pitch", required=True, sign="positive"),
    Field("ripple.amplitude", "number", "u", "ripple amplitude"),
    Field("ripple.amp", "number", "u", "ripple amplitude (older spelling)"),
    Field("bounds", "object", "", "what the theta box covers and how it was set"),
    Field("bounds.disturbance_bound", "number", "u", "load-force bound", sign="nonneg"),
    Field("bounds.disturbance_bound_defaulted", "boolean", "", "the load-force bound was defaulted"),
    Field("bounds.disturbance_range", "any", "u", "[min, max] load force"),
    Field("bounds.mass_range", "any", "u s^2/q", "[min, max] mass the box covers"),
    Field("bounds.viscous_range", "any", "u s/q", "[min, max] viscous friction the box covers"),
    Field("bounds.payload_range", "any", "u s^2/q", "the payload range the mass range includes"),
    Field("bounds.payload_defaulted", "any", "", "--payload-max was defaulted (3 M)"),
    Field("bounds.payload_narrowed_by_tune", "any", "", "tuning.json only: the default payload range tune "
          "narrowed"),
    Field("bounds.viscous_clipped", "any", "u s/q", "the fit's negative viscous coefficient clipped to the "
          "box: estimate, std, clipped_to"),
    Field("bounds.narrowed_by_tune", "object", "", "tune (or fit_force_to_drive) narrowed a defaulted "
          "load-force bound", check=_narrowed),
    Field("bounds.narrowed_by_tune.theta3_min", "number", "q/s^2", "theta3's lower end before", required=True),
    Field("bounds.narrowed_by_tune.theta3_max", "number", "q/s^2", "theta3's upper end before", required=True),
    Field("bounds.narrowed_by_tune.u_max", "number", "u", "the drive limit it was narrowed to", sign="positive"),
    Field("warnings", "strings", "", "plausibility warnings, one sentence each"),
    Field("evidence", "any", "", "only for a log without a broadband segment: missing, excite_command, "
          "limits_toml"),
    Field("frequency_response", "object", "", "the measured response and the structural model fitted to it"),
    Field("frequency_response.model", "object", "", "the plant the simulator uses beyond the rigid body "
          "(null: none)", check=_structural),
    Field("frequency_response.model.delay_s", "number", "s", "input delay beyond the zero-order hold",
          required=True, sign="nonneg"),
    Field("frequency_response.model.mode_hz", "number", "Hz", "structural mode (null: none)", sign="positive"),
    Field("frequency_response.model.mode_damping", "number", "", "its damping ratio (< 1)", sign="nonneg"),
    Field("frequency_response.model.mode_ratio", "number", "", "load fraction m2/M (< 1)", sign="positive"),
    Field("frequency_response.model.mode_load_side", "boolean", "", "the encoder reads the load side"),
    Field("frequency_response.model.mode2_hz", "number", "Hz", "second appendage (null: none)",
          sign="positive"),
    Field("frequency_response.model.mode2_damping", "number", "", "its damping ratio (< 1)", sign="nonneg"),
    Field("frequency_response.model.mode2_ratio", "number", "", "load fraction m3/M (mode_ratio + mode2_ratio "
          "< 1)", sign="positive"),
    Field("frequency_response.model.mode2_load_side", "boolean", "", "the encoder reads the second appendage"),
    Field("friction_map", "any", "", "friction tests: velocity (q/s), force (u), std (u), n (samples) per leg"),
    Field("model_selection", "any", "", "identify --friction auto: the cross-validated choice of terms"),
    Field("position_simulation", "any", "q", "with --validate-on: open-loop simulation rmse, reference_rmse"),
)

#: The strict model of ident.json (pydantic, built from :data:`IDENT_FIELDS`).
IdentJson = build_json_model("IdentJson", IDENT_FIELDS, "ident.json: the identification (commission identify).")
