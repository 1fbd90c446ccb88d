"""``controller.json``, the deployable controller (``commission validate``): its one table of fields.

Every field :meth:`commission.controller_config.ControllerConfig.from_dict` reads is one
:class:`~commission.formats.json_table.Field` row of :data:`CONTROLLER_FIELDS`; :data:`ControllerJson`
is the strict model built from them (closed objects: a key the table does not name is refused,
the file feeding generated code), and docs/interface.md §4 and docs/schemas/controller.schema.json
are generated from them (``python -m commission.formats``).

Checks that relate fields or need the loader's context stay with the loader: the control-law
statement, ``sample_period`` against ``sample_rate``, the plausibility of the rate and of
``bounds.u_max`` (in the file's ``units.u``), a null limit (refused unless a round trip allows
it), the gains' own rules (:class:`commission.controllers.arc.ArcGains`), the checksum and the
signature.  This module imports no simulation code: the section names of the gains are written
here and tests/test_formats_controller_json.py checks them against ``ArcGains``.
"""

from __future__ import annotations

from typing import Any

from commission.formats.ident_json import UNIT_VOCABULARY_Q, UNIT_VOCABULARY_U
from commission.formats.json_table import Field, build_json_model, cells, header_rows, is_finite_number, rows

CONTROLLER_KIND = "controller"
#: Version of controller.json and of docs/schemas/controller.schema.json.
CONTROLLER_SCHEMA_VERSION = 1
CONTROLLER_TYPE = "arc-output-feedback"

#: ArcGains fields by section of controller.json (every field exactly once, Ts aside), with their units.
SECTIONS: dict[str, tuple[str, ...]] = {
    "observer": ("k1", "k2"),
    "gains": ("w1", "w2", "g1", "g2", "eps11", "eps12", "eps21", "eps22", "C_phi1", "C_phi2", "C_theta2"),
    "bounds": ("theta_min", "theta_max", "u_max", "k1s_max", "k2s_max"),
    "adaptation": ("Gamma",),
    "initial_estimates": ("theta0",),
}
#: ``friction_compensation`` key -> ArcGains field.
FRICTION = {"level": "fric_level", "slope": "fric_slope"}
#: The runtime guards of ArcGains (:data:`commission.controllers.arc.RUNTIME_GUARDS`), in its order.
RUNTIME_FIELDS = ("dy_max", "dy_fault", "n_reject_max", "e_max", "freeze_on_saturation",
                  "accel_max", "y_err", "n_frozen_max", "u_free")
#: Runtime keys added after the section existed: optional on load, each absent one off.
RUNTIME_ADDED = ("accel_max", "y_err", "n_frozen_max", "u_free")
#: May be null (infinite): a robust term switched off, a runtime guard off.
INF_OK = ("eps11", "eps12", "eps21", "eps22", "dy_max", "dy_fault", "n_reject_max", "e_max")
#: Limits that must be finite in a controller.json (null refused by the loader unless a round trip allows it).
LIMITS = ("u_max", "k1s_max", "k2s_max")
VECTORS = ("C_phi1", "C_phi2", "C_theta2", "Gamma", "theta_min", "theta_max", "theta0")

_THETA = "[q/(u s^2), 1/s, q/s^2]"
_UNITS = {"k1": "1/s", "k2": "1/s^2", "w1": "", "w2": "", "g1": "1/s", "g2": "1/s", "eps11": "as in (37)",
          "eps12": "as in (37)", "eps21": "as in (47)", "eps22": "as in (47)", "C_phi1": "", "C_phi2": "",
          "C_theta2": "", "theta_min": _THETA, "theta_max": _THETA, "u_max": "u", "k1s_max": "1/s",
          "k2s_max": "1/s", "Gamma": "per theta component", "theta0": _THETA}
_DOCS = {"k1": "A0 = [[-k1, 1], [-k2, 0]] of (10)", "k2": "A0 = [[-k1, 1], [-k2, 0]] of (10)",
         "w1": "weight of (19)", "w2": "weight of (19)", "g1": "linear part of the robust gain K1",
         "g2": "linear part of the robust gain K2", "eps11": "robust level (null: term off)",
         "eps12": "robust level (null: term off)", "eps21": "robust level (null: term off)",
         "eps22": "robust level (null: term off)", "C_phi1": "weighting matrix (diagonal)",
         "C_phi2": "weighting matrix (diagonal)", "C_theta2": "weighting matrix (diagonal)",
         "theta_min": "the Assumption-1 box, kept by projection: lower corner",
         "theta_max": "the Assumption-1 box: upper corner", "u_max": "symmetric output limit, finite",
         "k1s_max": "cap of the nonlinear gain K1, finite", "k2s_max": "cap of the nonlinear gain K2, finite",
         "Gamma": "diagonal adaptation rate of (19)", "theta0": "theta_hat(0)"}
#: Runtime guard | unit | doc.
_RUNTIME = cells("""
dy_max               | q       | measurement plausibility: largest accepted change of y per sample (null: off)
dy_fault             | q       | jump fault: a change of y beyond it latches a fault (null: off)
n_reject_max         | samples | implausible measurements in a row before a fault (null: off)
e_max                | q       | tracking watchdog: |y - q_d| beyond it latches a fault (null: off)
freeze_on_saturation |         | adaptation frozen while the command is at +-u_max
accel_max            | q/s^2   | plausible acceleration of the measurement prediction (absent or null: off)
y_err                | q       | largest error of one reading (absent: 0)
n_frozen_max         | samples | evidence of a frozen encoder that latches FAULT_FROZEN (absent or null: never)
u_free               | u       | largest command that may leave the axis at rest (absent: 0)
""")


def _pair(v: Any) -> None:
    if not (isinstance(v, list) and len(v) == 2 and all(is_finite_number(e) for e in v) and 0 <= v[0] <= v[1]):
        raise ValueError(("", f"expected a [min, max] pair of finite numbers >= 0, got {v!r}"))


def _gain_rows(section: str) -> list[Field]:
    rows = []
    for n in SECTIONS[section]:
        if n in VECTORS:
            rows.append(Field(f"{section}.{n}", "numbers", _UNITS[n], _DOCS[n], required=True, length=3))
        else:
            rows.append(Field(f"{section}.{n}", "number", _UNITS[n], _DOCS[n], required=True,
                              nullable=n in INF_OK or n in LIMITS, sign="positive" if n in LIMITS else None))
    return rows


CONTROLLER_FIELDS: tuple[Field, ...] = (
    *header_rows(CONTROLLER_KIND, CONTROLLER_SCHEMA_VERSION),
    Field("controller", "string", "", f'"{CONTROLLER_TYPE}" (Xu & Yao 2001, sec. 3)', required=True),
    *rows("""
control_law    | any     | -  | -
    the paper, its equations by number and the filter structure this file parameterises; must be
    commission.controller_config.CONTROL_LAW (optional)
sample_rate    | number  | Hz | required positive
    the nominal rate: the validated rate, or its round value when they differ only by the rounding of a rate
    estimated from time stamps (1e-10); within spec.toml's controller.sample_rate range
sample_period  | number  | s  | required positive
    the exact period validated; = 1/sample_rate
units          | object  | -  | required closed
    command and position units
units.u        | string  | -  | required
    command unit
units.q        | string  | -  | required
    position unit
observer       | object  | -  | required closed
    the observer of (10)
""", {"units.u": dict(choices=UNIT_VOCABULARY_U), "units.q": dict(choices=UNIT_VOCABULARY_Q)}),
    *_gain_rows("observer"),
    Field("gains", "object", "", "the robust gains and weights", required=True, closed=True),
    *_gain_rows("gains"),
    Field("bounds", "object", "", "the box, the output limit and the gain caps; bounds.u_max within spec.toml's "
          "controller.u_max range", required=True, closed=True),
    *_gain_rows("bounds"),
    Field("adaptation", "object", "", "the adaptation law (19)", required=True, closed=True),
    *_gain_rows("adaptation"),
    Field("initial_estimates", "object", "", "theta_hat(0)", required=True, closed=True),
    *_gain_rows("initial_estimates"),
    *rows("""
friction_compensation       | object | -   | required closed
    F_hat(v) = level (2/pi) atan(slope v) added to the output
friction_compensation.level | number | u   | required nonneg
    level of F_hat
friction_compensation.slope | number | s/q | required nonneg
    slope of F_hat
runtime                     | object | -   | closed
    the runtime guards of the compiled step (absent: every guard off)
"""),
    *(Field(f"runtime.{n}", "boolean" if n == "freeze_on_saturation" else "number", _RUNTIME[n][0],
            _RUNTIME[n][1], required=n not in RUNTIME_ADDED, nullable=n != "freeze_on_saturation")
      for n in RUNTIME_FIELDS),
    *rows("""
validated                | object | -       | required
    what validate checked: the resolved gate, the worst value per criterion, the metrics on the identified plant,
    what was simulated (read by reports and export)
validated.gate           | any    | -       | -
    the resolved gate (validation.json gate)
validated.worst          | any    | -       | -
    criterion -> its worst value, limit and scenario
validated.nominal        | any    | -       | -
    trajectory -> the ARC's indexes on the identified plant (q, u)
validated.simulation     | any    | -       | -
    what was simulated: substeps, quantization (q), e_abort (q), u_sat (u)
validated.scenarios      | any    | -       | -
    scenarios simulated
validated.monte_carlo    | any    | -       | -
    Monte-Carlo plants among them
validated.seed           | any    | -       | -
    seed of the Monte-Carlo sample
provenance               | object | -       | required
    where the controller came from
provenance.log_sha256    | sha256 | -       | required nullable
    sha256 of the excitation log (null: not recorded)
provenance.ident_sha256  | sha256 | -       | required
    sha256 of ident.json
provenance.tuning_sha256 | sha256 | -       | required
    sha256 of the tuning.json validated
provenance.tool_version  | string | -       | required
    commission.__version__ (its form checked by export)
provenance.created_utc   | string | -       | required
    ISO-8601 UTC time of the validation (its form checked by export)
validity                 | object | -       | -
    present only when tune or validate narrowed a defaulted payload range to what the gains certify (absent: the
    whole box of bounds)
validity.payload_range   | any    | u s^2/q | required
    [min, max] payload certified
validity.mass_range      | any    | u s^2/q | required
    [min, max] mass certified
validity.unit            | string | -       | required
    unit of the ranges
checksum                 | object | -       | required
    sha256 over every other field (canonical JSON)
checksum.algorithm       | any    | -       | required
    "sha256" (checked with the value)
checksum.value           | any    | -       | required
    64 lowercase hex digits
signature                | object | -       | closed
    optional HMAC-SHA256 over every field but checksum and signature (--sign-key)
signature.algorithm      | any    | -       | required
    "hmac-sha256"
signature.value          | any    | -       | required
    64 lowercase hex digits
""", {"validity.payload_range": dict(check=_pair), "validity.mass_range": dict(check=_pair)}),
)

#: The strict model of controller.json (pydantic, built from :data:`CONTROLLER_FIELDS`).
ControllerJson = build_json_model("ControllerJson", CONTROLLER_FIELDS,
                                  "controller.json: the deployable controller.", root_closed=True)
