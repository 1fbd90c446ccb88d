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

from commission.formats.json_table import Field, build_json_model, cells, header_rows, is_finite_number, rows
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


def _mode(m: Any, mode: str) -> bool:
    """A mode's entries (``mode`` or ``mode2``) come together and its damping is below 1; False: no such mode."""
    if getattr(m, f"{mode}_hz") is None:
        return False
    for k in (f"{mode}_damping", f"{mode}_ratio", f"{mode}_load_side"):
        if getattr(m, k) is None:
            raise ValueError((f".{k}", "missing required field"))
    if not getattr(m, f"{mode}_damping") < 1:
        damping = getattr(m, f"{mode}_damping")
        raise ValueError((f".{mode}_damping", f"expected a damping ratio below 1, got {damping!r}"))
    return True


def _structural(m: Any) -> None:
    """``frequency_response.model``: a mode's entries come together; damping and load fractions below 1."""
    if not _mode(m, "mode"):
        return
    if not m.mode_ratio < 1:
        raise ValueError((".mode_ratio", f"expected a load fraction below 1, got {m.mode_ratio!r}"))
    if _mode(m, "mode2") and not m.mode_ratio + m.mode2_ratio < 1:
        raise ValueError((".mode2_ratio", f"expected mode_ratio + mode2_ratio below 1, got "
                                          f"{m.mode_ratio!r} + {m.mode2_ratio!r}"))


#: Parameter | unit | doc.
_PARAM_DOC = cells("""
M      | u s^2/q | mass M (on a rotary axis the inertia J)
B      | u s/q   | viscous friction
fc     | u       | Coulomb friction level
fs     | u       | static (Stribeck peak) friction level; null for the Coulomb model
vs     | q/s     | Stribeck velocity; null for the Coulomb model
xi     |         | Stribeck exponent; null for the Coulomb model
offset | u       | command offset (d_n = -offset)
""")


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


def _spread_rows() -> list[Field]:
    """How well each mode of the structural model is known (both modes alike)."""
    return [row for mode in ("mode", "mode2") for row in (
        Field(f"frequency_response.model.{mode}_hz_std", "any", "Hz", f"one standard deviation of {mode}_hz"),
        Field(f"frequency_response.model.{mode}_damping_std", "any", "", f"one standard deviation of {mode}_damping"),
        Field(f"frequency_response.model.{mode}_ratio_identified", "any", "",
              f"{mode}_ratio was identified (false: assumed)"))]


IDENT_FIELDS: tuple[Field, ...] = (
    *header_rows(IDENT_KIND, IDENT_SCHEMA_VERSION),
    *rows("""
units          | object  | - | required closed
    the units of every other field
units.u        | string  | - | required
    command unit ("u" in the units below)
units.q        | string  | - | required
    position unit ("q" below): m, or rad on a rotary axis
""", {"units.u": dict(choices=UNIT_VOCABULARY_U), "units.q": dict(choices=UNIT_VOCABULARY_Q)}),
    *_parameter_rows(),
    *rows("""
not_identified                           | string map | -                       | -
    parameter -> why the log carries no information on it (that parameter is null; with M null, theta and delta_d
    are null and tune refuses the file)
fit                                      | object     | -                       | required
    the fit's quality
fit.relative_error                       | number     | -                       | required nonneg
    ||y - y_hat|| / ||y|| on the identification data (a fraction, not %)
fit.condition_number                     | number     | -                       | required positive
    of the column-scaled regressor
fit.validation_relative_error            | number     | -                       | nonneg
    the same on --validate-on LOG2, or null
theta                                    | object     | -                       | required nullable
    theta = [1/M, B/M, d_n/M] and its Assumption-1 box (null: M not identified)
theta.nominal                            | numbers    | [q/(u s^2), 1/s, q/s^2] | required len=3
    nominal theta
theta.min                                | numbers    | [q/(u s^2), 1/s, q/s^2] | required len=3
    lower corner of the box (min[0] > 0)
theta.max                                | numbers    | [q/(u s^2), 1/s, q/s^2] | required len=3
    upper corner of the box
delta_d                                  | number     | q/s^2                   | nonneg
    bound on the lumped uncertain disturbance |d - d_n|/M (the paper's delta_d); required with theta, null without
friction_compensation                    | object     | -                       | required
    F_hat(v) = level (2/pi) atan(slope v)
friction_compensation.level              | number     | u                       | required nonneg
    level of F_hat
friction_compensation.slope              | number     | s/q                     | required nonneg
    slope of F_hat
friction_compensation_rms_error          | any        | u                       | -
    rms of F_hat against the identified curve over the data's speeds (report)
log_sha256                               | sha256     | -                       | -
    sha256 of the excitation log (older files; now source.sha256)
quantization                             | number     | *                       | -
    the older place of encoder.quantization
encoder                                  | object     | -                       | -
    what the log says of the encoder
encoder.quantization                     | number     | *                       | -
    encoder step the tool uses (null: none measured; tune then assumes the spec's default)
encoder.noise_std                        | number     | *                       | -
    noise beyond quantization, rms (tune and validate simulate it unless [plant] noise_std says otherwise)
encoder.apparent_resolution              | number     | q                       | nonneg
    smallest step seen in q
encoder.noise_rms_total                  | any        | q                       | -
    rms of the whole measurement error (noise and quantization), from the spectrum of q - P u over 0.35-0.48 of
    the sample rate
encoder.quantization_noise_rms           | any        | q                       | -
    quantization / sqrt(12), the rounding's share (null: the log is not on a grid)
encoder.noise_band_hz                    | any        | Hz                      | -
    [low, high]: the band the floor was read in
source                                   | object     | -                       | -
    the log(s) identified
source.sample_rate                       | number     | Hz                      | positive
    sample rate as measured (tune's default rate)
source.n_samples                         | integer    | samples                 | nonneg
    samples in the log
source.sha256                            | any        | -                       | -
    sha256 of the log, or a list of them for several logs
source.path                              | any        | -                       | -
    the log's path, or a list of them
source.input_gain                        | any        | -                       | -
    --input-gain: u_equiv = input_gain u
source.mapping                           | any        | -                       | -
    the log's column mapping
source.q_unit                            | any        | -                       | -
    the file's position unit ("counts" under --counts-per-rev)
source.resampled_hz                      | any        | Hz                      | -
    the uniform rate of --resample, or null
source.conversion                        | any        | -                       | -
    with --counts-per-rev, --lead or --gear: {from, to, counts_per_rev, lead_m_per_rad,
    gear_motor_rad_per_load_rad}
validation_source                        | any        | -                       | -
    the --validate-on log(s), as source
model                                    | object     | -                       | -
    how the fit was made (method, decimation, cut-off, friction model, fixed parameters, segments,
    inverse_dynamics)
model.ripple_pitch                       | number     | q                       | positive
    the first --ripple-pitch, or the pitch --ripple-pitch auto found
model.ripple_amp                         | any        | u                       | -
    its amplitude amp sin(2 pi q/P + phase): a number or {value, std}
model.ripple_phase                       | any        | rad                     | -
    its phase
model.ripple_harmonics                   | any        | -                       | -
    every --ripple-pitch with its amp and phase ({value, std})
model.ripple_search                      | any        | -                       | -
    added: the ripple search on the constant-velocity legs (the default; --ripple-pitch auto): pitch (q, null: none stood
    out), amplitude (u), peak_over_median and explained (-), with the thresholds peak_needed and
    explained_needed, span and searched (q), legs, samples
model.fixed                              | any        | -                       | -
    parameters given with --fix NAME=VALUE (std 0)
model.segments                           | any        | samples                 | -
    several logs fitted together: the samples of each file
model.inverse_dynamics                   | any        | -                       | -
    identify --friction auto's richer model (docs/interface.md §2)
model.method                             | any        | -                       | -
    the fit: "steady+dynamic", "whole-log", ...
model.friction                           | any        | -                       | -
    the friction model fitted: coulomb or stribeck
model.friction_requested                 | any        | -                       | -
    --friction as given (auto, coulomb, stribeck)
model.decimation                         | any        | -                       | -
    samples per point of the dynamic fit
model.cutoff_hz                          | any        | Hz                      | -
    cut-off of the derivative filter
model.residual_std                       | any        | u                       | -
    standard deviation of the fit residual
model.steady_points                      | any        | -                       | -
    constant-speed points of the friction fit
model.v_max                              | any        | q/s                     | -
    largest speed in the data
model.velocity_resolution                | any        | q/s                     | -
    velocity step one encoder count makes at the sample rate
ripple                                   | object     | -                       | -
    the older place of the ripple
ripple.pitch                             | number     | q                       | required positive
    ripple pitch
ripple.amplitude                         | number     | u                       | -
    ripple amplitude
ripple.amp                               | number     | u                       | -
    ripple amplitude (older spelling)
bounds                                   | object     | -                       | -
    what the theta box covers and how it was set
bounds.disturbance_bound                 | number     | u                       | nonneg
    load-force bound
bounds.disturbance_bound_defaulted       | boolean    | -                       | -
    the load-force bound was defaulted
bounds.disturbance_range                 | any        | u                       | -
    [min, max] load force
bounds.mass_range                        | any        | u s^2/q                 | -
    [min, max] mass the box covers
bounds.viscous_range                     | any        | u s/q                   | -
    [min, max] viscous friction the box covers
bounds.payload_range                     | any        | u s^2/q                 | -
    the payload range the mass range includes
bounds.payload_defaulted                 | any        | -                       | -
    --payload-max was defaulted (3 M)
bounds.payload_narrowed_by_tune          | any        | -                       | -
    tuning.json only: the default payload range tune narrowed
bounds.viscous_clipped                   | any        | u s/q                   | -
    the fit's negative viscous coefficient clipped to the box: estimate, std, clipped_to
bounds.k_sigma                           | any        | -                       | -
    standard deviations the theta box spans about each estimate
bounds.model_margin                      | any        | -                       | -
    relative margin added to the box for what the model leaves out
bounds.narrowed_by_tune                  | object     | -                       | -
    tune (or fit_force_to_drive) narrowed a defaulted load-force bound
bounds.narrowed_by_tune.theta3_min       | number     | q/s^2                   | required
    theta3's lower end before
bounds.narrowed_by_tune.theta3_max       | number     | q/s^2                   | required
    theta3's upper end before
bounds.narrowed_by_tune.u_max            | number     | u                       | positive
    the drive limit it was narrowed to
warnings                                 | strings    | -                       | -
    plausibility warnings, one sentence each
created_utc                              | any        | -                       | -
    ISO-8601 UTC time of the identification
tool                                     | any        | -                       | -
    the tool that wrote the file: name, version
evidence                                 | any        | -                       | -
    only for a log without a broadband segment: missing, excite_command, limits_toml
frequency_response                       | object     | -                       | -
    the measured response and the structural model fitted to it
frequency_response.source                | any        | -                       | -
    the data measured: broadband, whole_log or none
frequency_response.band_hz               | any        | Hz                      | -
    [low, high] where the data back the rigid model
frequency_response.evidence_band_hz      | any        | Hz                      | -
    [low, high] the log backs for the model tune and validate use (null: none; docs/robustness.md)
frequency_response.coherent_up_to_hz     | any        | Hz                      | -
    highest frequency of coherent data
frequency_response.resolution_hz         | any        | Hz                      | -
    frequency resolution of the estimate
frequency_response.n_averages            | any        | -                       | -
    Welch windows averaged
frequency_response.segments_s            | any        | s                       | -
    the broadband segments, [start, end] each
frequency_response.modes                 | any        | -                       | -
    every mode the response holds: frequency_hz (Hz), damping, their std, depth, mode
frequency_response.delay_samples         | any        | samples                 | -
    input delay beyond the zero-order hold
frequency_response.fit_quality           | any        | -                       | -
    structure, model_rms_error, rigid_rms_error, n_modes, criterion
frequency_response.departures            | any        | -                       | -
    where the measured response departs from the fitted model beyond its uncertainty
frequency_response.measured              | any        | -                       | -
    the measured response thinned for reports: frequency, magnitude, phase, coherence (0 where the position reading is at the encoder's noise floor; null: no broadband segment)
frequency_response.units                 | any        | -                       | -
    the unit of each of these fields
frequency_response.plan                  | any        | -                       | -
    the plan.json whose injection windows were used (absent: none)
frequency_response.note                  | any        | -                       | -
    a sentence on how the response was measured, or null
frequency_response.model                 | object     | -                       | -
    the plant the simulator uses beyond the rigid body (null: none)
frequency_response.model.delay_s         | number     | s                       | required nonneg
    input delay beyond the zero-order hold
frequency_response.model.mode_hz         | number     | Hz                      | positive
    structural mode (null: none)
frequency_response.model.mode_damping    | number     | -                       | nonneg
    its damping ratio (< 1)
frequency_response.model.mode_ratio      | number     | -                       | positive
    load fraction m2/M (< 1)
frequency_response.model.mode_load_side  | boolean    | -                       | -
    the encoder reads the load side
frequency_response.model.mode2_hz        | number     | Hz                      | positive
    second appendage (null: none)
frequency_response.model.mode2_damping   | number     | -                       | nonneg
    its damping ratio (< 1)
frequency_response.model.mode2_ratio     | number     | -                       | positive
    load fraction m3/M (mode_ratio + mode2_ratio < 1)
frequency_response.model.mode2_load_side | boolean    | -                       | -
    the encoder reads the second appendage
frequency_response.model.n_modes         | any        | -                       | -
    modes in the model
frequency_response.model.delay_std_s     | any        | s                       | -
    one standard deviation of delay_s
frequency_response.model.mass_scale      | any        | -                       | -
    the fitted mass over the identified M
frequency_response.model.appendages      | any        | -                       | -
    true when the two modes were refitted as two appendages on the rigid body (absent: not)
friction_map                             | any        | -                       | -
    friction tests: velocity (q/s), force (u), std (u), n (samples) per leg
model_selection                          | any        | -                       | -
    identify --friction auto: the cross-validated choice of terms
position_simulation                      | any        | q                       | -
    with --validate-on: open-loop simulation rmse, reference_rmse
""", {"quantization": dict(unit=_QUANT.unit, range=_QUANT.range),
      "encoder.quantization": dict(unit=_QUANT.unit, range=_QUANT.range),
      "encoder.noise_std": dict(unit=_NOISE.unit, range=_NOISE.range),
      "source.sha256": dict(check=_sha256_or_list),
      "model.ripple_amp": dict(check=_ripple_amp),
      "bounds.narrowed_by_tune": dict(check=_narrowed),
      "frequency_response.model": dict(check=_structural)}),
    *_spread_rows(),
)

#: The strict model of ident.json (pydantic, built from :data:`IDENT_FIELDS`).
IdentJson = build_json_model("IdentJson", IDENT_FIELDS, "ident.json: the identification (commission identify).")
