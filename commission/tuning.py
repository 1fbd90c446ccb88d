"""The tuning artifact (``tuning.json``), written by ``commission tune``.

Every field of the file is one row of :mod:`commission.formats.tuning_json` (its JSON path, type,
accepted values, unit and doc); docs/interface.md §3 and docs/schemas/tuning.schema.json are
generated from that table.  Loading is strict, through the table's model: a missing or mistyped
field raises :class:`commission.errors.SchemaError` naming its JSON path.  Saving writes sorted
keys (:func:`commission.jsonio.write_json_atomic`).  This module builds the controllers' objects
from the file, so it imports :mod:`commission.controllers`; the format's table does not.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from pydantic import ValidationError

from commission.artifacts import Identification
from commission.controllers.arc import RUNTIME_GUARDS, ArcGains
from commission.controllers.design import ObserverDesign, Theorem1Check
from commission.controllers.metrics import SCORE_NAMES, Indexes
from commission.controllers.pid import PidGains
from commission.controllers.plant import PLANT_NAMES, plant_vector
from commission.errors import SchemaError
from commission.formats.json_table import check_header, json_error
from commission.formats.tuning_json import TUNING_FIELDS, TUNING_KIND, TUNING_SCHEMA_VERSION, TuningJson
from commission.jsonio import read_json, write_json_atomic
from commission.robustness import BoxRobustness, LoopMargins, MarginFloors
from commission.scenarios.scenario import read_only_plant
from commission.spec import RANGES, Spec, spec_from_mapping



def _num_or_null(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class Provenance:
    """Where a tuning came from.

    Attributes
    ----------
    ident_sha256 : str
        sha256 of the ident.json bytes.
    log_sha256 : str or None
        sha256 of the excitation log, when ident.json records one.
    tool_version : str
        ``commission.__version__``.
    created_utc : str
        ISO-8601 UTC time of the run.
    seed : int
        Seed of the search's Generator.
    ident_path : str
        ident.json as given on the command line.
    """

    ident_sha256: str
    log_sha256: str | None
    tool_version: str
    created_utc: str
    seed: int
    ident_path: str




@dataclass(frozen=True)
class FeasibilitySummary:
    """Discrete feasibility of one controller (see :func:`controllers.design.discrete_feasibility`).

    What tuning.json keeps of a :class:`controllers.design.FeasibilityReport`: the worst point
    and the counts, not every radius checked.

    Attributes
    ----------
    holds : bool
        Every spectral radius < 1 - margin.
    margin : float
        Required margin of the frozen-estimate loop, dimensionless: each radius must be
        below ``1 - margin``.
    rho_max : float
        Largest spectral radius found (``inf``, stored as null, if a nominal run blew up).
    worst_corner : tuple of 3 float
        theta corner of ``rho_max``.
    worst_trajectory : str
        Trajectory name there (``case1`` / ``case2``).
    worst_t : float
        Time of that linearisation point, s.
    n_points : int
        Points checked (corners x trajectories x points along each).
    rho_adaptive_max : float
        Largest radius with the theta3 adaptation in the loop (must be < 1); NaN if not recorded.
    rho_any_estimate_max : float
        Informational, not part of ``holds``: the largest radius with the estimates
        frozen at any of the 8 corners of the box instead of the values reached
        (< 1: the loop is stable whatever theta_hat the projection allows); NaN if not computed.
    """

    holds: bool
    margin: float
    rho_max: float
    worst_corner: tuple[float, float, float]
    worst_trajectory: str
    worst_t: float
    n_points: int
    rho_adaptive_max: float = math.nan
    rho_any_estimate_max: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        return {"holds": self.holds, "margin": self.margin, "rho_max": _num_or_null(self.rho_max),
                "worst_corner": list(self.worst_corner), "worst_trajectory": self.worst_trajectory,
                "worst_t": self.worst_t, "n_points": self.n_points,
                "rho_adaptive_max": _num_or_null(self.rho_adaptive_max),
                "rho_any_estimate_max": _num_or_null(self.rho_any_estimate_max)}


@dataclass(frozen=True)
class Guarantee:
    """One guarantee of the paper: does it hold as tuned, and why (or what was traded)."""

    holds: bool
    detail: str


@dataclass(frozen=True)
class SearchRecord:
    """Summary of the gain search.

    tuning.json's ``search``: every candidate's objective, level and violation in evaluation
    order, but not its gains (only the chosen ones are kept, in ``arc``).

    Attributes
    ----------
    n_evaluations : int
        Candidate gain sets evaluated.
    budget : int
        Requested budget (spec ``tune.budget``).
    seed : int
        Seed of the search's Generator (the same as ``provenance.seed``).
    cost_initial, cost_best : float
        Objective of the starting point and of the chosen gains (lower is better; nan: not
        simulated because a stability constraint failed first).
    free : dict
        The free gains as chosen (name -> value).
    history : tuple of float
        Objective of every candidate in evaluation order (the first is the starting point).
    holdout_plants : int
        Monte-Carlo plants of the hold-out selection (0: not run).
    holdout_failures : tuple of int
        Default-gate failures of each feasible finalist there, best objective first.
    optimiser : str
        The optimiser and its constraint handling.
    generations : int
        CMA-ES generations run (each one asks, simulates and tells one population).
    n_feasible : int
        Candidates that met every constraint.
    violations : tuple of float
        Each candidate's constraint violation (0: met), evaluation order.
    levels : tuple of int
        Each candidate's constraint level (:data:`commission.tune.candidate.FEASIBLE` = 0,
        ``GATE_MISSED`` = 1, ``STABILITY_MISSED`` = 2).
    chosen_level : int
        The chosen gains' level (0 unless no candidate met every constraint).
    chosen_violation : float
        The chosen gains' constraint violation, dimensionless (0: met every constraint).
    screened : tuple of bool
        Each candidate was far off the gate on the screening scenarios
        (:attr:`commission.tune.settings.TuneSettings.screen_excess`) and was simulated on those only (its
        violation is the excess there).
    bandwidth_factor : float
        The factor the ARC's carried-over gains, adaptation rates and observer were scaled by in this
        search, dimensionless (1: the rate-scaled design; :func:`commission.tune.baseline.bandwidth_factor`).
    other_search : mapping or None
        A search at another factor whose result was not kept (``bandwidth_factor``, ``n_evaluations``,
        ``n_feasible``): the floors' bandwidth found no feasible gains and the noise-held yardstick's
        was searched too (:func:`commission.tune.baseline.noise_bandwidth_factor`).  None: one search.
    """

    n_evaluations: int
    budget: int
    seed: int
    cost_initial: float
    cost_best: float
    free: Mapping[str, float]
    history: tuple[float, ...] = ()
    holdout_plants: int = 0
    holdout_failures: tuple[int, ...] = ()
    optimiser: str = ""
    generations: int = 0
    n_feasible: int = 0
    violations: tuple[float, ...] = ()
    levels: tuple[int, ...] = ()
    chosen_level: int = 0
    chosen_violation: float = 0.0
    screened: tuple[bool, ...] = ()
    bandwidth_factor: float = 1.0
    other_search: Mapping[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"n_evaluations": self.n_evaluations, "budget": self.budget, "seed": self.seed,
                "cost_initial": _num_or_null(self.cost_initial), "cost_best": _num_or_null(self.cost_best),
                "free": {k: float(v) for k, v in self.free.items()},
                "history": [_num_or_null(c) for c in self.history],
                "holdout_plants": self.holdout_plants, "holdout_failures": list(self.holdout_failures),
                "optimiser": self.optimiser, "generations": self.generations, "n_feasible": self.n_feasible,
                "violations": [_num_or_null(v) for v in self.violations], "levels": list(self.levels),
                "chosen_level": self.chosen_level, "chosen_violation": _num_or_null(self.chosen_violation),
                "screened": [bool(b) for b in self.screened], "bandwidth_factor": float(self.bandwidth_factor),
                **({} if self.other_search is None else {"other_search": dict(self.other_search)})}


def gains_to_dict(g: Any) -> dict[str, Any]:
    """ArcGains or PidGains as tuning.json holds them: field by field, null for an infinite value (an
    ArcGains runtime guard only when set)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(g):
        v = getattr(g, f.name)
        if f.name in RUNTIME_GUARDS and isinstance(g, ArcGains):
            if v == f.default:
                continue  # set by validate, not by tune: absent means off
            out[f.name] = bool(v) if isinstance(v, bool) else _num_or_null(float(v))
            continue
        out[f.name] = [float(x) for x in v] if isinstance(v, tuple) else _num_or_null(float(v))
    return out


def _gains(cls: type, m: Any, source: str, path: str) -> Any:
    """ArcGains or PidGains from their validated section: null stands for inf; an absent runtime guard is off."""
    kw: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        v = getattr(m, f.name)
        if cls is ArcGains and f.name in RUNTIME_GUARDS:
            if v is not None:
                kw[f.name] = v
            continue
        kw[f.name] = tuple(v) if isinstance(v, list) else math.inf if v is None else v
    try:
        return cls(**kw)
    except (ValueError, TypeError) as exc:
        raise SchemaError(f"{source}: {path}: {exc}") from None


@dataclass(frozen=True)
class Tuning:
    """Result of ``commission tune`` (module docstring for the JSON layout).

    Attributes
    ----------
    provenance : Provenance
        The inputs' hashes, this tool's version, the time and the seed (key ``provenance``).
    spec : Spec
        The tuning spec tune ran with (its defaults fitted to the axis: :func:`commission.tune.resolve_spec`).
    identification : Identification
        The identification the gains were tuned for.
    plant : numpy.ndarray
        float64[NP] identified plant vector (controllers.plant layout), read-only.
    quantization : float
        Encoder resolution used in simulation, m.
    arc : ArcGains
        The tuned discrete ARC.
    pid : PidGains
        The PID baseline (57), poles of (56) at M_min.
    pid_pole : float
        PID triple pole magnitude the baseline runs at, rad/s: ``spec.pid_pole``, or lower
        when a defaulted pole chattered beyond validate's c_u (:func:`commission.tune.deployable_pid`).
    pid_design_mass : float
        M_min = 1/theta_max[0], u-unit s^2/m.
    observer : ObserverDesign
        The velocity observer of (10): its pole (rad/s), gains and Lyapunov matrix.
    theorem1 : Theorem1Check
        The paper's Theorem 1 condition on the chosen gains (holds, and its smallest ratio).
    feasibility : dict
        ``{"arc": FeasibilitySummary, "pid": FeasibilitySummary}``.
    guarantees : dict
        name -> :class:`Guarantee`.
    scores : dict
        scenario -> ``{"arc": Indexes, "pid": Indexes}``.
    search : SearchRecord
        How the gains were found (:class:`SearchRecord`).
    margins : tuple of LoopMargins
        Stability margins of both loops per plant (:mod:`commission.robustness`);
        empty in a tuning.json written before they were recorded.
    box : BoxRobustness or None
        The ARC over the whole theta box (:class:`commission.robustness.BoxArcCheck`), key
        ``box_robustness``; None in a tuning.json written before it was recorded.
    validity : mapping or None
        Key ``validity``: present when tune narrowed a *defaulted* payload range to the one the
        gains certify (:func:`commission.tune.api.certify_box`): ``payload_range`` [min, max] and
        ``mass_range`` [min, max] in ``unit`` (u-unit s^2/m), ``default_payload_range`` and a ``reason``.
    pid_yardstick : mapping or None
        How the PID baseline was chosen and its margins on the identified plant
        (:meth:`commission.tune.baseline.YardstickChoice.to_dict`: ``method``, ``pole`` rad/s,
        ``candidates``, ``admissible``, ``simulated``, ``margins``, ``radius_plus_one_sample``,
        ``violations``, ``is_yardstick``); None in a tuning.json written before it was recorded.
    """

    provenance: Provenance
    spec: Spec
    identification: Identification
    plant: np.ndarray
    quantization: float
    arc: ArcGains
    pid: PidGains
    pid_pole: float
    pid_design_mass: float
    observer: ObserverDesign
    theorem1: Theorem1Check
    feasibility: Mapping[str, FeasibilitySummary]
    guarantees: Mapping[str, Guarantee]
    scores: Mapping[str, Mapping[str, Indexes]]
    search: SearchRecord
    margins: tuple[LoopMargins, ...] = ()
    box: BoxRobustness | None = None
    validity: Mapping[str, Any] | None = None
    pid_yardstick: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "plant", read_only_plant(self.plant, "Tuning"))

    @property
    def delta_d(self) -> float:
        """Assumption-1 bound on |d~|, m/s^2."""
        return self.identification.delta_d

    @property
    def theta(self):
        """The theta box (:class:`commission.artifacts.ThetaBox`)."""
        return self.identification.theta

    def to_dict(self) -> dict[str, Any]:
        pv = self.provenance
        plant = {name: float(self.plant[i]) for i, name in enumerate(PLANT_NAMES)}
        plant["quantization"] = self.quantization
        pid = gains_to_dict(self.pid)
        pid["pole"] = self.pid_pole
        pid["design_mass"] = self.pid_design_mass
        ob = self.observer
        return {
            "kind": TUNING_KIND,
            "schema_version": TUNING_SCHEMA_VERSION,
            "provenance": {"ident_sha256": pv.ident_sha256, "log_sha256": pv.log_sha256,
                           "tool_version": pv.tool_version, "created_utc": pv.created_utc,
                           "seed": pv.seed, "ident_path": pv.ident_path},
            "spec": self.spec.to_dict(),
            "identification": self.identification.to_dict(),
            "plant": plant,
            "arc": gains_to_dict(self.arc),
            "pid": pid,
            "observer": {"pole": ob.pole, "k1": ob.k1, "k2": ob.k2, "P": [list(r) for r in ob.P],
                         "P_eigenvalues": list(ob.P_eigenvalues), "lyapunov_residual": ob.lyapunov_residual,
                         "discrete_pole": _num_or_null(ob.discrete_pole)},
            "theorem1": {"holds": self.theorem1.holds, "ratios": [list(r) for r in self.theorem1.ratios],
                         "min_ratio": _num_or_null(self.theorem1.min_ratio)},
            "feasibility": {k: v.to_dict() for k, v in self.feasibility.items()},
            "guarantees": {k: {"holds": g.holds, "detail": g.detail} for k, g in self.guarantees.items()},
            "scores": {s: {c: sc.to_dict() for c, sc in row.items()} for s, row in self.scores.items()},
            "search": self.search.to_dict(),
            "margins": [m.to_dict() for m in self.margins],
            **({} if self.box is None else {"box_robustness": self.box.to_dict(MarginFloors.from_spec(self.spec))}),
            **({} if self.validity is None else {"validity": dict(self.validity)}),
            **({} if self.pid_yardstick is None else {"pid_yardstick": dict(self.pid_yardstick)}),
        }

    def save(self, path: str) -> None:
        """Write atomically with sorted keys."""
        write_json_atomic(path, self.to_dict())

    @classmethod
    def from_dict(cls, data: Any, source: str = "tuning.json") -> "Tuning":
        """Strict load through the table's model (:data:`commission.formats.tuning_json.TuningJson`).

        Errors name the JSON path (``tuning.json: $.arc.g1: ...``); the embedded spec and
        identification are checked by their own tables under ``$.spec.`` and ``$.identification``.
        What relates two fields (the observer's gains and the ARC's, the PID design mass and
        the theta box) is checked here, after the fields.
        """
        def fail(path: str, msg: str) -> SchemaError:
            return SchemaError(f"{source}: {path}: {msg}")

        check_header(data, TUNING_KIND, TUNING_SCHEMA_VERSION, source)
        try:
            m = TuningJson.model_validate(data)
        except ValidationError as exc:
            raise SchemaError(json_error(exc, TUNING_FIELDS, source=source)) from None
        pv = m.provenance
        prov = Provenance(ident_sha256=pv.ident_sha256, log_sha256=pv.log_sha256, tool_version=pv.tool_version,
                          created_utc=pv.created_utc, seed=pv.seed, ident_path=pv.ident_path)
        spec = spec_from_mapping(data["spec"], source, prefix="$.spec.")
        ident = Identification.from_dict(data["identification"], source=source, prefix="$.identification")
        default = plant_vector(1.0, 0.0)  # the entries added later: absent means a rigid, delay-free plant
        plant = np.array([default[i] if getattr(m.plant, n) is None else getattr(m.plant, n)
                          for i, n in enumerate(PLANT_NAMES)], dtype=np.float64)
        arc = _gains(ArcGains, m.arc, source, "$.arc")
        pid = _gains(PidGains, m.pid, source, "$.pid")
        lo, hi = RANGES[("controller", "u_max")]  # a finite output limit is a plausible one, as in controller.json
        for section, gains in (("arc", arc), ("pid", pid)):
            if math.isfinite(gains.u_max) and not lo <= gains.u_max <= hi:
                raise fail(f"$.{section}.u_max", f"{gains.u_max!r} is outside the plausible range [{lo:g}, {hi:g}]")
        ob = m.observer
        observer = ObserverDesign(pole=ob.pole, k1=ob.k1, k2=ob.k2, P=tuple(tuple(map(float, r)) for r in ob.P),
                                  P_eigenvalues=tuple(ob.P_eigenvalues), lyapunov_residual=ob.lyapunov_residual,
                                  discrete_pole=_nan(ob.discrete_pole))
        t1 = m.theorem1
        theorem1 = Theorem1Check(holds=t1.holds, ratios=tuple(tuple(map(float, r)) for r in t1.ratios),
                                 min_ratio=math.inf if t1.min_ratio is None else t1.min_ratio)
        feas = {k: _feasibility(getattr(m.feasibility, k)) for k in ("arc", "pid")}
        guarantees = {k: Guarantee(g.holds, g.detail) for k, g in m.guarantees.items()}
        scores = {s: {c: _score(getattr(row, c)) for c in ("arc", "pid")} for s, row in m.scores.items()}
        se = m.search
        search = SearchRecord(n_evaluations=se.n_evaluations, budget=se.budget, seed=se.seed,
                              cost_initial=_nan(se.cost_initial), cost_best=_nan(se.cost_best), free=dict(se.free),
                              history=_floats(se.history), holdout_plants=se.holdout_plants or 0,
                              holdout_failures=tuple(se.holdout_failures or ()), optimiser=se.optimiser or "",
                              generations=se.generations or 0, n_feasible=se.n_feasible or 0,
                              violations=_floats(se.violations), levels=tuple(se.levels or ()),
                              chosen_level=se.chosen_level or 0,
                              chosen_violation=0.0 if se.chosen_violation is None else se.chosen_violation,
                              screened=tuple(se.screened or ()),
                              bandwidth_factor=1.0 if se.bandwidth_factor is None else se.bandwidth_factor,
                              other_search=None if se.other_search is None else dict(se.other_search))
        if not math.isclose(m.pid.design_mass, 1.0 / ident.theta.max[0], rel_tol=1e-9):  # type: ignore[union-attr]
            raise fail("$.pid.design_mass", "does not equal 1/theta_max[0] of the identification")
        for k in ("k1", "k2"):  # the controller runs arc.k1, arc.k2: the observer record must describe them
            if not math.isclose(getattr(observer, k), getattr(arc, k), rel_tol=1e-9):
                raise fail(f"$.observer.{k}", f"{getattr(observer, k):.12g} does not equal arc.{k} = "
                                              f"{getattr(arc, k):.12g}")
        return cls(provenance=prov, spec=spec, identification=ident, plant=plant, quantization=m.plant.quantization,
                   arc=arc, pid=pid, pid_pole=m.pid.pole, pid_design_mass=m.pid.design_mass,
                   observer=observer, theorem1=theorem1, feasibility=feas, guarantees=guarantees,
                   scores=scores, search=search, margins=_margins(data, source),
                   box=_record(data, "box_robustness", BoxRobustness.from_dict, source),
                   validity=None if data.get("validity") is None else dict(data["validity"]),
                   pid_yardstick=_record(data, "pid_yardstick", _yardstick_record, source))

    @classmethod
    def load(cls, path: str) -> "Tuning":
        """Read and strictly validate ``tuning.json``."""
        return cls.from_dict(read_json(path), source=str(path))


def _record(data: Mapping[str, Any], key: str, parse: Callable[[Any], Any], source: str) -> Any:
    """An optional record read by its own type's ``from_dict`` (None when absent or null); a malformed
    one is named by its JSON path.  The table has checked its shape (an object, a list)."""
    if data.get(key) is None:
        return None
    try:
        return parse(data[key])
    except (KeyError, TypeError, ValueError, AttributeError) as exc:  # AttributeError: an entry not an object
        raise SchemaError(f"{source}: $.{key}: bad record ({exc})") from None


def _margins(data: Mapping[str, Any], source: str) -> tuple[LoopMargins, ...]:
    """The optional ``margins`` list; an entry that does not parse is named by its JSON path."""
    out = []
    for i, row in enumerate(data.get("margins") or ()):
        try:
            out.append(LoopMargins.from_dict(row))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise SchemaError(f"{source}: $.margins[{i}]: bad entry ({exc})") from None
    return tuple(out)


def _yardstick_record(d: Any) -> dict[str, Any]:
    from commission.tune.baseline import YardstickChoice  # the record's type lives with the stage that makes it
    return YardstickChoice.from_dict(d).to_dict()


def _score(m: Any) -> Indexes:
    return Indexes(**{k: _nan(getattr(m, k)) for k in SCORE_NAMES}, diverged=m.diverged)


def _feasibility(m: Any) -> FeasibilitySummary:
    return FeasibilitySummary(holds=m.holds, margin=m.margin, rho_max=math.inf if m.rho_max is None else m.rho_max,
                              worst_corner=tuple(m.worst_corner), worst_trajectory=m.worst_trajectory,
                              worst_t=m.worst_t, n_points=m.n_points, rho_adaptive_max=_nan(m.rho_adaptive_max),
                              rho_any_estimate_max=_nan(m.rho_any_estimate_max))


def _floats(v: list | None) -> tuple[float, ...]:
    """A list where null stands for NaN (a candidate not simulated); absent: empty."""
    return () if v is None else tuple(math.nan if x is None else float(x) for x in v)


def _nan(x: float | None) -> float:
    return math.nan if x is None else x


def log_sha256_of(tuning: Tuning) -> str | None:
    """sha256 of the excitation log: the tuning's provenance, else ident.json's ``source.sha256``."""
    if tuning.provenance.log_sha256:
        return tuning.provenance.log_sha256
    src = tuning.identification.extra.get("source")
    if isinstance(src, dict) and isinstance(src.get("sha256"), str):
        return src["sha256"]
    return None
