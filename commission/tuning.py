"""The tuning artifact (``tuning.json``), written by ``commission tune``.

Schema (kind ``"tuning"``, schema_version 1, keys sorted)::

    provenance        ident_sha256, log_sha256 (or null), tool_version, created_utc, seed, ident_path
    spec              the resolved spec (commission.spec layout: controller, trajectory, targets, pid, tune)
    identification    ident.json's content verbatim (rebuilds the scenario matrix exactly)
    plant             the identified plant model used in simulation: M, B, fc, fs, vs, xi, offset,
                      ripple_amp, ripple_pitch (u-unit, m, s), quantization (m)
    arc               every ArcGains field (controllers.arc); null stands for inf
                      (eps: term switched off; k1s_max, k2s_max, u_max: no cap)
    pid               every PidGains field (controllers.pid), plus pole (rad/s) and design_mass
    observer          pole, k1, k2, P (2x2, eq. 11), P_eigenvalues, lyapunov_residual, discrete_pole
                      (the pole the controller runs: k1, k2 must equal arc.k1, arc.k2; tune's
                      hold-out repair may move a defaulted pole, so it can differ from the spec's)
    theorem1          holds, ratios (2x3), min_ratio
    feasibility       {"arc": ..., "pid": ...}: holds, margin, rho_max (estimates frozen),
                      rho_adaptive_max (theta3 adaptation in the loop), rho_any_estimate_max
                      (informational: estimates at any box corner), worst_corner, worst_trajectory,
                      worst_t, n_points
    guarantees        {name: {"holds": bool, "detail": str}}: which guarantees of the paper hold
                      as chosen, and which are traded for implementability
    scores            {scenario: {"arc": score, "pid": score}}; score = e_M, e_F, e_rms (m), u_rms,
                      du_rms, u_peak (u-unit), c_u, diverged; indexes null when diverged
    search            optimiser (name and library version), n_evaluations, budget, seed,
                      generations, cost_initial, cost_best (objective, null where a candidate was
                      not simulated), free (name -> value), history (objective of every candidate,
                      evaluation order), violations and levels (each candidate's constraint
                      violation and level: 0 every constraint met, 1 the gate missed, 2 a stability
                      margin or discrete feasibility missed), screened (each candidate was far
                      off the gate on the screening scenarios and was simulated on those only;
                      its violation is the excess there), n_feasible, chosen_level,
                      chosen_violation, holdout_plants, holdout_failures (default-gate failures of
                      each feasible finalist on the hold-out plants, best objective first; see
                      commission.tune.select_on_holdout)

Loading is strict (:class:`commission.jsonio.Reader`): a missing or mistyped
field raises :class:`commission.errors.SchemaError` naming its JSON path.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from commission.artifacts import Identification, read_sha256
from commission.controllers.arc import RUNTIME_GUARDS, ArcGains
from commission.controllers.design import ObserverDesign, Theorem1Check
from commission.controllers.pid import PidGains
from commission.controllers.plant import NP, PLANT_NAMES, plant_vector
from commission.errors import SchemaError
from commission.jsonio import Reader, read_json, write_json_atomic
from commission.robustness import BoxRobustness, LoopMargins, MarginFloors
from commission.spec import RANGES, Spec, spec_from_mapping

TUNING_KIND = "tuning"
TUNING_SCHEMA_VERSION = 1

#: Plant-vector names in controllers.plant order.
SCORE_NAMES = ("e_M", "e_F", "e_rms", "u_rms", "du_rms", "c_u", "u_peak")
#: ArcGains fields that may be infinite (stored as JSON null).
_ARC_INF_OK = ("eps11", "eps12", "eps21", "eps22", "k1s_max", "k2s_max", "u_max")
_PID_INF_OK = ("u_max",)


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
class Score:
    """Section-4.2 indexes of one controller on one scenario (SI units) plus the peak input.

    Indexes are NaN when the run diverged.
    """

    e_M: float
    e_F: float
    e_rms: float
    u_rms: float
    du_rms: float
    c_u: float
    u_peak: float
    diverged: bool

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {k: _num_or_null(getattr(self, k)) for k in SCORE_NAMES}
        d["diverged"] = self.diverged
        return d

    @classmethod
    def from_reader(cls, r: Reader) -> "Score":
        vals = {k: r.num(k, optional=True) for k in SCORE_NAMES}
        return cls(**{k: (math.nan if v is None else v) for k, v in vals.items()}, diverged=r.bool_("diverged"))


@dataclass(frozen=True)
class FeasibilitySummary:
    """Discrete feasibility of one controller (see :func:`controllers.design.discrete_feasibility`).

    Attributes
    ----------
    holds : bool
        Every spectral radius < 1 - margin.
    margin : float
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

    @classmethod
    def from_reader(cls, r: Reader) -> "FeasibilitySummary":
        rho = r.num("rho_max", optional=True)
        return cls(holds=r.bool_("holds"), margin=r.num("margin", positive=True),  # type: ignore[arg-type]
                   rho_max=math.inf if rho is None else rho,
                   worst_corner=r.vec("worst_corner", 3),  # type: ignore[arg-type]
                   worst_trajectory=r.str_("worst_trajectory"),  # type: ignore[arg-type]
                   worst_t=r.num("worst_t", nonneg=True),  # type: ignore[arg-type]
                   n_points=r.int_("n_points"),
                   rho_adaptive_max=_nan(r.num("rho_adaptive_max", optional=True)),
                   rho_any_estimate_max=_nan(r.num("rho_any_estimate_max", optional=True)))


@dataclass(frozen=True)
class Guarantee:
    """One guarantee of the paper: does it hold as tuned, and why (or what was traded)."""

    holds: bool
    detail: str


@dataclass(frozen=True)
class SearchRecord:
    """Summary of the gain search.

    Attributes
    ----------
    n_evaluations : int
        Candidate gain sets evaluated.
    budget : int
        Requested budget (spec ``tune.budget``).
    seed : int
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
    n_feasible : int
        Candidates that met every constraint.
    violations : tuple of float
        Each candidate's constraint violation (0: met), evaluation order.
    levels : tuple of int
        Each candidate's constraint level (:data:`commission.tune.optimiser.FEASIBLE` = 0,
        ``GATE_MISSED`` = 1, ``STABILITY_MISSED`` = 2).
    chosen_level : int
        The chosen gains' level (0 unless no candidate met every constraint).
    chosen_violation : float
    screened : tuple of bool
        Each candidate was far off the gate on the screening scenarios
        (:data:`commission.tune.optimiser.SCREEN_EXCESS`) and was simulated on those only (its
        violation is the excess there).
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

    def to_dict(self) -> dict[str, Any]:
        return {"n_evaluations": self.n_evaluations, "budget": self.budget, "seed": self.seed,
                "cost_initial": _num_or_null(self.cost_initial), "cost_best": _num_or_null(self.cost_best),
                "free": {k: float(v) for k, v in self.free.items()},
                "history": [_num_or_null(c) for c in self.history],
                "holdout_plants": self.holdout_plants, "holdout_failures": list(self.holdout_failures),
                "optimiser": self.optimiser, "generations": self.generations, "n_feasible": self.n_feasible,
                "violations": [_num_or_null(v) for v in self.violations], "levels": list(self.levels),
                "chosen_level": self.chosen_level, "chosen_violation": _num_or_null(self.chosen_violation),
                "screened": [bool(b) for b in self.screened]}


def _gains_to_dict(g: Any) -> dict[str, Any]:
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


def _gains_from_reader(cls: type, r: Reader, inf_ok: tuple[str, ...], skip: tuple[str, ...] = ()) -> Any:
    known = {f.name for f in dataclasses.fields(cls)}
    for k in r.keys():
        if k not in known and k not in skip:
            raise r.fail("unknown field", f"{r.path}.{k}")
    kw: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if cls is ArcGains and f.name in RUNTIME_GUARDS:
            if r.has(f.name):
                raw = r.child(f.name).data
                kw[f.name] = (r.bool_(f.name) if f.name == "freeze_on_saturation"
                              else math.inf if raw is None else r.num(f.name))
            continue
        raw = r.child(f.name).data
        if "tuple" in str(f.type):  # the field's type decides, not the file's shape
            kw[f.name] = r.vec(f.name, 3)
        elif raw is None and f.name in inf_ok:
            kw[f.name] = math.inf
        else:
            kw[f.name] = r.num(f.name)
    try:
        return cls(**kw)
    except (ValueError, TypeError) as exc:
        raise r.fail(str(exc)) from None


@dataclass(frozen=True)
class Tuning:
    """Result of ``commission tune`` (module docstring for the JSON layout).

    Attributes
    ----------
    provenance : Provenance
    spec : Spec
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
    theorem1 : Theorem1Check
    feasibility : dict
        ``{"arc": FeasibilitySummary, "pid": FeasibilitySummary}``.
    guarantees : dict
        name -> :class:`Guarantee`.
    scores : dict
        scenario -> ``{"arc": Score, "pid": Score}``.
    search : SearchRecord
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
    scores: Mapping[str, Mapping[str, Score]]
    search: SearchRecord
    margins: tuple[LoopMargins, ...] = ()
    box: BoxRobustness | None = None
    validity: Mapping[str, Any] | None = None
    pid_yardstick: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        p = np.array(self.plant, dtype=np.float64)
        if p.shape != (NP,):
            raise ValueError(f"Tuning.plant: expected {NP} entries, got shape {p.shape}")
        p.setflags(write=False)
        object.__setattr__(self, "plant", p)

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
        pid = _gains_to_dict(self.pid)
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
            "arc": _gains_to_dict(self.arc),
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
        """Strict load; errors name the JSON path (``tuning.json: $.arc.g1: ...``)."""
        r = Reader(data, "$", source)
        r.header(TUNING_KIND, TUNING_SCHEMA_VERSION)
        pr = r.obj("provenance")
        prov = Provenance(ident_sha256=read_sha256(pr, "ident_sha256"),  # type: ignore[arg-type]
                          log_sha256=read_sha256(pr, "log_sha256", optional=True),
                          tool_version=pr.str_("tool_version"), created_utc=pr.str_("created_utc"),  # type: ignore[arg-type]
                          seed=pr.int_("seed"), ident_path=pr.str_("ident_path"))  # type: ignore[arg-type]
        sr = r.obj("spec")
        spec = spec_from_mapping(sr.data, source, prefix="$.spec.")
        ir = r.obj("identification")
        try:
            ident = Identification.from_dict(ir.data, source=source)
        except SchemaError as exc:
            # re-anchor the path under $.identification
            raise SchemaError(str(exc).replace(f"{source}: $", f"{source}: $.identification")) from None
        plr = r.obj("plant")
        # The mode and delay entries were added later: absent means a rigid, delay-free plant.
        default = plant_vector(1.0, 0.0)
        plant = np.array([plr.num(n) if i < 9 or plr.has(n) else default[i] for i, n in enumerate(PLANT_NAMES)],
                         dtype=np.float64)
        quant = plr.num("quantization", nonneg=True)
        lo, hi = RANGES[("controller", "quantization")]  # the spec's range for the same encoder step
        if not lo <= quant <= hi:  # type: ignore[operator]
            raise plr.fail(f"must be within [{lo:g}, {hi:g}] m, got {quant!r}", f"{plr.path}.quantization")
        arc = _gains_from_reader(ArcGains, r.obj("arc"), _ARC_INF_OK)
        pidr = r.obj("pid")
        pid = _gains_from_reader(PidGains, pidr, _PID_INF_OK, skip=("pole", "design_mass"))
        lo, hi = RANGES[("controller", "u_max")]  # a finite output limit is a plausible one, as in controller.json
        for section, gains in (("arc", arc), ("pid", pid)):
            if math.isfinite(gains.u_max) and not lo <= gains.u_max <= hi:
                raise r.fail(f"{gains.u_max!r} is outside the plausible range [{lo:g}, {hi:g}]", f"$.{section}.u_max")
        obr = r.obj("observer")
        P = _matrix(obr, "P", 2, 2)
        dp = obr.num("discrete_pole", optional=True)
        observer = ObserverDesign(pole=obr.num("pole", positive=True), k1=obr.num("k1", positive=True),  # type: ignore[arg-type]
                                  k2=obr.num("k2", positive=True), P=P,  # type: ignore[arg-type]
                                  P_eigenvalues=obr.vec("P_eigenvalues", 2),  # type: ignore[arg-type]
                                  lyapunov_residual=obr.num("lyapunov_residual", nonneg=True),  # type: ignore[arg-type]
                                  discrete_pole=math.nan if dp is None else dp)
        t1 = r.obj("theorem1")
        ratios = _matrix(t1, "ratios", 2, 3)
        mr = t1.num("min_ratio", optional=True)
        theorem1 = Theorem1Check(holds=t1.bool_("holds"), ratios=ratios,  # type: ignore[arg-type]
                                 min_ratio=math.inf if mr is None else mr)
        fr = r.obj("feasibility")
        feas = {k: FeasibilitySummary.from_reader(fr.obj(k)) for k in ("arc", "pid")}
        gr = r.obj("guarantees")
        guarantees = {k: Guarantee(gr.obj(k).bool_("holds"), gr.obj(k).str_("detail")) for k in gr.keys()}  # type: ignore[arg-type]
        scr = r.obj("scores")
        scores = {s: {c: Score.from_reader(scr.obj(s).obj(c)) for c in ("arc", "pid")} for s in scr.keys()}
        se = r.obj("search")
        fre = se.obj("free")
        search = SearchRecord(n_evaluations=se.int_("n_evaluations"), budget=se.int_("budget"), seed=se.int_("seed"),
                              cost_initial=_nan(se.num("cost_initial", optional=True)),
                              cost_best=_nan(se.num("cost_best", optional=True)),
                              free={k: fre.num(k) for k in fre.keys()},  # type: ignore[misc]
                              history=_nullable_list(se, "history"),
                              holdout_plants=se.int_("holdout_plants") if se.has("holdout_plants") else 0,
                              holdout_failures=_int_list(se, "holdout_failures"),
                              optimiser=se.str_("optimiser") if se.has("optimiser") else "",
                              generations=se.int_("generations") if se.has("generations") else 0,
                              n_feasible=se.int_("n_feasible") if se.has("n_feasible") else 0,
                              violations=_nullable_list(se, "violations") if se.has("violations") else (),
                              levels=_int_list(se, "levels") if se.has("levels") else (),
                              chosen_level=se.int_("chosen_level") if se.has("chosen_level") else 0,
                              chosen_violation=_nan(se.num("chosen_violation", optional=True))
                              if se.has("chosen_violation") else 0.0,
                              screened=_bool_list(se, "screened") if se.has("screened") else ())
        dm = pidr.num("design_mass", positive=True)
        if not any(math.isclose(dm, m, rel_tol=1e-9) for m in (1.0 / ident.theta.max[0], ident.value("M"))):  # type: ignore[arg-type]
            raise pidr.fail("equals neither 1/theta_max[0] (the paper's M_min) nor the identified M",
                            f"{pidr.path}.design_mass")
        for k in ("k1", "k2"):  # the controller runs arc.k1, arc.k2: the observer record must describe them
            if not math.isclose(getattr(observer, k), getattr(arc, k), rel_tol=1e-9):
                raise obr.fail(f"{getattr(observer, k):.12g} does not equal arc.{k} = {getattr(arc, k):.12g}",
                               f"{obr.path}.{k}")
        return cls(provenance=prov, spec=spec, identification=ident, plant=plant, quantization=quant,  # type: ignore[arg-type]
                   arc=arc, pid=pid, pid_pole=pidr.num("pole", positive=True),  # type: ignore[arg-type]
                   pid_design_mass=pidr.num("design_mass", positive=True),  # type: ignore[arg-type]
                   observer=observer, theorem1=theorem1, feasibility=feas, guarantees=guarantees,
                   scores=scores, search=search, margins=_margins(r), box=_box(r),
                   validity=_validity(r), pid_yardstick=_yardstick(r))

    @classmethod
    def load(cls, path: str) -> "Tuning":
        """Read and strictly validate ``tuning.json``."""
        return cls.from_dict(read_json(path), source=str(path))


def _yardstick(r: Reader) -> dict[str, Any] | None:
    """The optional ``pid_yardstick`` record (absent in older files); a malformed one is named by its path."""
    if not r.has("pid_yardstick"):
        return None
    y = r.child("pid_yardstick")
    from commission.tune.baseline import YardstickChoice
    try:
        return YardstickChoice.from_dict(y.data).to_dict()
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise y.fail(f"bad record ({exc})") from None


def _margins(r: Reader) -> tuple[LoopMargins, ...]:
    """The optional ``margins`` list; an entry that does not parse is named by its JSON path."""
    if not r.has("margins"):
        return ()
    lst = r.child("margins")
    if not isinstance(lst.data, list):
        raise lst.fail("expected a list")
    out = []
    for i, row in enumerate(lst.data):
        try:
            out.append(LoopMargins.from_dict(row))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:  # AttributeError: an entry not an object
            raise lst.fail(f"bad entry ({exc})", f"{lst.path}[{i}]") from None
    return tuple(out)


def _box(r: Reader) -> BoxRobustness | None:
    """The optional ``box_robustness`` record (None: a tuning.json written before it)."""
    if not r.has("box_robustness"):
        return None
    b = r.obj("box_robustness")
    try:
        return BoxRobustness.from_dict(b.data)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise b.fail(f"bad entry ({exc})") from None


def _validity(r: Reader) -> dict[str, Any] | None:
    """The optional ``validity`` record: the certified payload and mass ranges, each a [min, max] pair."""
    if not r.has("validity"):
        return None
    v = r.obj("validity")
    for k in ("payload_range", "mass_range"):
        x = v.data.get(k)
        if not (isinstance(x, list) and len(x) == 2 and all(isinstance(e, (int, float)) and math.isfinite(e)
                                                         for e in x) and x[0] <= x[1]):
            raise v.fail(f"expected a [min, max] pair of finite numbers, got {x!r}", f"{v.path}.{k}")
    v.str_("unit")
    return dict(v.data)


def _matrix(r: Reader, key: str, rows: int, cols: int) -> tuple[tuple[float, ...], ...]:
    """A rows x cols list of lists of finite numbers at ``key``; errors name ``key[i][j]``."""
    m = r.child(key)
    if not isinstance(m.data, list) or len(m.data) != rows:
        raise r.fail(f"expected a {rows}x{cols} matrix (list of {rows} rows)", m.path)
    return tuple(_row(m, i, row, cols) for i, row in enumerate(m.data))


def _row(m: Reader, i: int, row: Any, cols: int) -> tuple[float, ...]:
    p = f"{m.path}[{i}]"
    if not isinstance(row, list) or len(row) != cols:
        raise m.fail(f"expected a list of {cols} numbers", p)
    for j, x in enumerate(row):
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise m.fail(f"expected a finite number, got {x!r}", f"{p}[{j}]")
    return tuple(float(x) for x in row)


def _checked_list(r: Reader, key: str, ok: Callable[[Any], bool], what: str) -> tuple:
    """An optional list whose every item passes ``ok`` (``what`` names the item type); absent: empty."""
    if not r.has(key):
        return ()
    m = r.child(key)
    if not isinstance(m.data, list):
        raise r.fail(f"expected a list of {what}s", m.path)
    for i, v in enumerate(m.data):
        if not ok(v):
            raise r.fail(f"expected a {what}, got {v!r}", f"{m.path}[{i}]")
    return tuple(m.data)


def _int_list(r: Reader, key: str) -> tuple[int, ...]:
    """An optional list of non-negative integers; absent: empty."""
    return _checked_list(r, key, lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0,
                         "non-negative integer")


def _bool_list(r: Reader, key: str) -> tuple[bool, ...]:
    """An optional list of booleans; absent: empty."""
    return _checked_list(r, key, lambda v: isinstance(v, bool), "boolean")


def _nullable_list(r: Reader, key: str) -> tuple[float, ...]:
    """An optional list of numbers where null stands for NaN (a diverged candidate); absent: empty."""
    if not r.has(key):
        return ()
    m = r.child(key)
    if not isinstance(m.data, list):
        raise r.fail("expected a list of numbers", m.path)
    out = []
    for i, v in enumerate(m.data):
        if v is None:
            out.append(math.nan)
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise r.fail(f"expected a number or null, got {v!r}", f"{m.path}[{i}]")
        else:
            out.append(float(v))
    return tuple(out)


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
