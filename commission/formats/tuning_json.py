"""``tuning.json``, the tuning artifact (``commission tune``): its one table of fields.

Every field :class:`commission.tuning.Tuning` reads is one
:class:`~commission.formats.json_table.Field` row of :data:`TUNING_FIELDS`; :data:`TuningJson`
is the strict model built from them, and docs/interface.md §3 and
docs/schemas/tuning.schema.json are generated from them (``python -m commission.formats``).

This module imports no simulation code: the names of the plant vector and of the controllers'
gains are written here, and tests/test_formats_tuning_json.py checks them against
:mod:`commission.controllers` (``PLANT_NAMES``, ``ArcGains``, ``PidGains``).  The embedded
``spec`` is checked by spec.toml's table and ``identification`` by ident.json's; ``margins``,
``box_robustness`` and ``pid_yardstick`` by the records of :mod:`commission.robustness` and
:mod:`commission.tune.baseline`.  A gain stored as ``null`` is infinite (a term switched off, no cap).
"""

from __future__ import annotations

from typing import Any

from commission.controllers.index_table import INDEX_TABLE
from commission.formats.json_table import Field, build_json_model, header_rows, is_finite_number, rows
from commission.formats.spec_toml import SPEC_KEYS

TUNING_KIND = "tuning"
#: Version of tuning.json and of docs/schemas/tuning.schema.json.
TUNING_SCHEMA_VERSION = 1
#: The plant vector of :mod:`commission.controllers.plant`, in its order; the first 9 are required
#: (the modes and delay were added later: absent means a rigid, delay-free plant).
PLANT_NAMES = ("M", "B", "fc", "fs", "vs", "xi", "offset", "ripple_amp", "ripple_pitch", "mode_hz",
               "mode_damping", "mode_ratio", "mode_load_side", "delay", "mode2_hz", "mode2_damping",
               "mode2_ratio", "mode2_load_side")
N_REQUIRED_PLANT = 9
#: ArcGains fields (:class:`commission.controllers.arc.ArcGains`): name, unit, may be null (infinite).
ARC_GAINS = (("Ts", "s", False), ("k1", "1/s", False), ("k2", "1/s^2", False), ("w1", "", False),
             ("w2", "", False), ("g1", "", False), ("g2", "", False), ("eps11", "", True), ("eps12", "", True),
             ("eps21", "", True), ("eps22", "", True))
ARC_VECTORS = ("C_phi1", "C_phi2", "C_theta2", "Gamma", "theta_min", "theta_max", "theta0")
ARC_TAIL = (("fric_level", "u", False), ("fric_slope", "s/q", False), ("k1s_max", "", True),
            ("k2s_max", "", True), ("u_max", "u", True))
#: The runtime guards: set by validate, absent (off) in tuning.json unless given.
ARC_GUARDS = (("dy_max", "q"), ("dy_fault", "q"), ("n_reject_max", "samples"), ("e_max", "q"),
              ("freeze_on_saturation", ""), ("accel_max", "q/s^2"), ("y_err", "q"), ("n_frozen_max", "samples"),
              ("u_free", "u"))
PID_GAINS = (("Ts", "s", False), ("M_hat", "u s^2/q", False), ("B_hat", "u s/q", False), ("Kp", "u/q", False),
             ("Ki", "u/(q s)", False), ("Kd", "u s/q", False), ("fric_level", "u", False),
             ("fric_slope", "s/q", False), ("u_max", "u", True))

_QUANT = next(k for k in SPEC_KEYS if (k.section, k.name) == ("controller", "quantization"))


def object_value(v: Any) -> None:
    if not isinstance(v, dict):
        raise ValueError(("", f"expected an object, got {type(v).__name__}"))


def _list(v: Any) -> None:
    if not isinstance(v, list):
        raise ValueError(("", "expected a list"))


def _matrix(rows: int, cols: int):
    def check(m: Any) -> None:
        if not isinstance(m, list) or len(m) != rows:
            raise ValueError(("", f"expected a {rows}x{cols} matrix (list of {rows} rows)"))
        for i, row in enumerate(m):
            if not isinstance(row, list) or len(row) != cols:
                raise ValueError((f"[{i}]", f"expected a list of {cols} numbers"))
            for j, x in enumerate(row):
                if not is_finite_number(x):
                    raise ValueError((f"[{i}][{j}]", f"expected a finite number, got {x!r}"))
    return check


def _list_of(ok, what: str):
    def check(v: Any) -> None:
        if not isinstance(v, list):
            raise ValueError(("", f"expected a list of {what}s"))
        for i, x in enumerate(v):
            if not ok(x):
                raise ValueError((f"[{i}]", f"expected a {what}, got {x!r}"))
    return check


def nullable_numbers(v: Any) -> None:
    if not isinstance(v, list):
        raise ValueError(("", "expected a list of numbers"))
    for i, x in enumerate(v):
        if x is not None and not is_finite_number(x):
            raise ValueError((f"[{i}]", f"expected a number or null, got {x!r}"))


def _pair(x: Any) -> bool:
    return isinstance(x, list) and len(x) == 2 and all(is_finite_number(e) for e in x) and x[0] <= x[1]


def validity_record(v: Any) -> None:
    object_value(v)
    for k in ("payload_range", "mass_range"):
        if not _pair(v.get(k)):
            raise ValueError((f".{k}", f"expected a [min, max] pair of finite numbers, got {v.get(k)!r}"))
    if not isinstance(v.get("unit"), str):
        raise ValueError((".unit", "missing required field" if v.get("unit") is None
                          else f"expected a string, got {v['unit']!r}"))


def other_search_record(v: Any) -> None:
    """``search.other_search``: a positive finite ``bandwidth_factor`` and non-negative integer counts."""
    object_value(v)
    f = v.get("bandwidth_factor")
    if not (is_finite_number(f) and f > 0):
        raise ValueError((".bandwidth_factor", f"expected a positive finite number, got {f!r}"))
    for k in ("n_evaluations", "n_feasible"):
        n = v.get(k)
        if not (isinstance(n, int) and not isinstance(n, bool) and n >= 0):
            raise ValueError((f".{k}", f"expected a non-negative integer, got {n!r}"))


_NONNEG_INT = _list_of(lambda x: isinstance(x, int) and not isinstance(x, bool) and x >= 0, "non-negative integer")
_BOOLS = _list_of(lambda x: isinstance(x, bool), "boolean")


def score_rows(prefix: str) -> list[Field]:
    rows = [Field(prefix, "object", "", f"the {prefix.rsplit('.', 1)[-1].upper()} loop's score", required=True)]
    rows += [Field(f"{prefix}.{r.name}", "number", r.unit, f"index {r.name} (null: diverged)") for r in INDEX_TABLE]
    return rows + [Field(f"{prefix}.diverged", "boolean", "", "the run diverged", required=True)]


def _gain_rows(section: str, owner: str, gains: tuple[tuple[str, str, bool], ...]) -> list[Field]:
    """The scalar gains of a controller (``(name, unit, may be null)`` rows of ``owner``), each required."""
    return [Field(f"{section}.{n}", "number", u, f"{owner}.{n}" + (" (null: infinite)" if inf else ""),
                  required=True, nullable=inf) for n, u, inf in gains]


def _feasibility_rows(prefix: str) -> list[Field]:
    return [
        Field(prefix, "object", "", f"discrete feasibility of the {prefix[-3:].upper()} loop", required=True),
        Field(f"{prefix}.holds", "boolean", "", "every spectral radius < 1 - margin", required=True),
        Field(f"{prefix}.margin", "number", "", "the required margin", required=True, sign="positive"),
        Field(f"{prefix}.rho_max", "number", "", "largest spectral radius, estimates frozen (null: a nominal "
              "run blew up)"),
        Field(f"{prefix}.worst_corner", "numbers", "[q/(u s^2), 1/s, q/s^2]", "theta corner of rho_max",
              required=True, length=3),
        Field(f"{prefix}.worst_trajectory", "string", "", "trajectory there (case1, case2)", required=True),
        Field(f"{prefix}.worst_t", "number", "s", "time of that linearisation point", required=True, sign="nonneg"),
        Field(f"{prefix}.n_points", "integer", "", "points checked", required=True),
        Field(f"{prefix}.rho_adaptive_max", "number", "", "largest radius with the theta3 adaptation in the loop"),
        Field(f"{prefix}.rho_any_estimate_max", "number", "", "informational: estimates at any box corner"),
    ]


TUNING_FIELDS: tuple[Field, ...] = (
    *header_rows(TUNING_KIND, TUNING_SCHEMA_VERSION),
    *rows("""
provenance              | object  | - | required
    where the tuning came from
provenance.ident_sha256 | sha256  | - | required
    sha256 of the ident.json bytes
provenance.log_sha256   | sha256  | - | -
    sha256 of the excitation log, when ident.json records one
provenance.tool_version | string  | - | required
    commission.__version__
provenance.created_utc  | string  | - | required
    ISO-8601 UTC time of the run
provenance.seed         | integer | - | required
    seed of the search's generator
provenance.ident_path   | string  | - | required
    ident.json as given on the command line
spec                    | any     | - | required
    the resolved spec (spec.toml's layout; checked by its table, §6)
identification          | any     | - | required
    ident.json's content verbatim (checked by its table, §2)
plant                   | object  | - | required
    the identified plant the simulation used
""", {"spec": dict(check=object_value), "identification": dict(check=object_value)}),
    *(Field(f"plant.{n}", "number", "", f"plant vector entry {n} (commission.controllers.plant)",
            required=i < N_REQUIRED_PLANT) for i, n in enumerate(PLANT_NAMES)),
    Field("plant.quantization", "number", _QUANT.unit, "encoder step simulated", required=True,
          range=_QUANT.range),
    Field("arc", "object", "", "the tuned discrete ARC (every ArcGains field)", required=True, closed=True),
    *_gain_rows("arc", "ArcGains", ARC_GAINS),
    *(Field(f"arc.{n}", "numbers", "", f"ArcGains.{n}", required=True, length=3) for n in ARC_VECTORS),
    *_gain_rows("arc", "ArcGains", ARC_TAIL),
    *(Field(f"arc.{n}", "boolean" if n == "freeze_on_saturation" else "number", u,
            f"runtime guard {n}, set by validate (absent or null: off)")
      for n, u in ARC_GUARDS),
    Field("pid", "object", "", "the PID baseline (every PidGains field, pole and design mass)", required=True,
          closed=True),
    *_gain_rows("pid", "PidGains", PID_GAINS),
    *rows("""
pid.pole                   | number  | rad/s   | required positive
    triple pole the baseline runs at
pid.design_mass            | number  | u s^2/q | required positive
    M_min = 1/theta_max[0] of the identification
observer                   | object  | -       | required
    the observer the controller runs (eq. 11)
observer.pole              | number  | rad/s   | required positive
    observer pole
observer.k1                | number  | 1/s     | required positive
    gain k1 (= arc.k1)
observer.k2                | number  | 1/s^2   | required positive
    gain k2 (= arc.k2)
observer.P                 | any     | -       | required
    2x2 Lyapunov matrix P (eq. 11)
observer.P_eigenvalues     | numbers | -       | required len=2
    eigenvalues of P
observer.lyapunov_residual | number  | -       | required nonneg
    residual of the Lyapunov equation
observer.discrete_pole     | number  | -       | -
    the discrete pole the controller runs (null: not recorded)
theorem1                   | object  | -       | required
    Theorem 1's conditions
theorem1.holds             | boolean | -       | required
    every ratio >= 1
theorem1.ratios            | any     | -       | required
    2x3 ratios
theorem1.min_ratio         | number  | -       | -
    smallest ratio (null: infinite)
feasibility                | object  | -       | required
    discrete feasibility of both loops
""", {"observer.P": dict(check=_matrix(2, 2)), "theorem1.ratios": dict(check=_matrix(2, 3))}),
    *_feasibility_rows("feasibility.arc"),
    *_feasibility_rows("feasibility.pid"),
    *rows("""
guarantees          | map     | - | required
    name -> which guarantee of the paper holds as tuned
guarantees.*        | object  | - | required
    one guarantee
guarantees.*.holds  | boolean | - | required
    it holds
guarantees.*.detail | string  | - | required
    why, or what was traded
scores              | map     | - | required
    scenario -> the scores of both loops
scores.*            | object  | - | required
    one scenario
"""),
    *score_rows("scores.*.arc"),
    *score_rows("scores.*.pid"),
    *rows("""
search                  | object     | - | required
    the gain search
search.n_evaluations    | integer    | - | required
    candidates evaluated
search.budget           | integer    | - | required
    requested budget (spec tune.budget)
search.seed             | integer    | - | required
    seed
search.cost_initial     | number     | - | -
    objective of the starting point (null: not simulated)
search.cost_best        | number     | - | -
    objective of the chosen gains (null: not simulated)
search.free             | number map | - | required
    the free gains as chosen (name -> value)
search.history          | any        | - | -
    objective of every candidate, evaluation order (null: not simulated)
search.holdout_plants   | integer    | - | -
    Monte-Carlo plants of the hold-out selection (0: not run)
search.holdout_failures | any        | - | -
    default-gate failures of each feasible finalist, best first
search.optimiser        | string     | - | -
    the optimiser and its constraint handling
search.generations      | integer    | - | -
    generations run
search.n_feasible       | integer    | - | -
    candidates that met every constraint
search.violations       | any        | - | -
    each candidate's constraint violation (0: met)
search.levels           | any        | - | -
    each candidate's level: 0 met, 1 gate missed, 2 stability missed
search.chosen_level     | integer    | - | -
    the chosen gains' level
search.chosen_violation | number     | - | -
    the chosen gains' violation
search.screened         | any        | - | -
    each candidate was simulated on the screening scenarios only
search.bandwidth_factor | number     | - | -
    *added*: the factor the ARC's carried-over design was scaled by in the search kept (1: rate-scaled)
search.other_search     | any        | - | -
    *added*: a search at another factor, not kept: bandwidth_factor, n_evaluations, n_feasible
margins                 | any        | - | -
    stability margins of both loops per plant (commission.robustness.LoopMargins)
box_robustness          | any        | - | -
    the ARC over the whole theta box (commission.robustness.BoxRobustness)
validity                | any        | - | -
    tune narrowed a defaulted payload range: payload_range, mass_range [min, max] in unit, default_payload_range,
    reason
pid_yardstick           | any        | - | -
    how the PID baseline was chosen (commission.tune.baseline.YardstickChoice)
""", {"search.history": dict(check=nullable_numbers),
      "search.holdout_failures": dict(check=_NONNEG_INT),
      "search.violations": dict(check=nullable_numbers),
      "search.levels": dict(check=_NONNEG_INT),
      "search.screened": dict(check=_BOOLS),
      "search.other_search": dict(check=other_search_record),
      "margins": dict(check=_list),
      "box_robustness": dict(check=object_value),
      "validity": dict(check=validity_record)}),
)

#: The strict model of tuning.json (pydantic, built from :data:`TUNING_FIELDS`).
TuningJson = build_json_model("TuningJson", TUNING_FIELDS, "tuning.json: the tuning (commission tune).")
