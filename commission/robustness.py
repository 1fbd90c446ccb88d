"""Stability margins of the tuned loops over the identified plant set.

The margins themselves (definitions, how the ARC's adaptive and robust terms
are linearised) are :mod:`commission.controllers.margins`; this module chooses
where to evaluate them and records them for ``tuning.json``,
``validation.json`` and ``report.md``:

* **plants**: the identified plant (its mode and input delay included,
  :func:`commission.scenarios.plant_dynamics`) and the four (theta1, theta2)
  corners of the Assumption-1 box (mass ``1/theta1``, viscous ``theta2/theta1``);
* **PID**: linear but for its friction compensation, one loop per plant;
* **ARC**: linearised twice per plant, with the estimate at its initial value
  theta_hat(0) (the start-up, before any adaptation) and at the plant's own
  theta (what the adaptation tends to when the motion excites it), since the
  sampled loop's stability depends on the estimate (``controllers/arc.py``).

Floors (``[margins]`` of spec.toml; defaults 6 dB, 30 deg, one sample beyond
the identified delay and modulus 0.5, common practice for servo loops) are checked per loop; :func:`floor_violations` names each one missed,
and :func:`commission.gate.margin_checks` turns those of the identified plant into gate checks.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from commission.artifacts import Identification
from commission.blas import one_blas_thread
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import (NEUTRAL_TOL, Margins, frequency_grid, linearize_arc, linearize_pid, loop_margins,
                                            loop_response)
from commission.controllers.pid import PidGains, pid_pack
from commission.controllers.plant import P_B, P_M
from commission.scenarios import identified_plant
from commission.spec import Spec

CONTROLLERS = ("arc", "pid")


@dataclass(frozen=True)
class MarginFloors:
    """Smallest acceptable margins: dB, deg, samples beyond the identified delay, dimensionless."""

    gain_db: float = 6.0
    phase_deg: float = 30.0
    delay_samples: float = 1.0
    modulus: float = 0.5

    @classmethod
    def from_spec(cls, spec: Spec) -> "MarginFloors":
        return cls(gain_db=spec.min_gain_margin_db, phase_deg=spec.min_phase_margin_deg,
                   delay_samples=spec.min_delay_margin_samples, modulus=spec.min_modulus_margin)

    def to_dict(self) -> dict[str, float]:
        return {"gain_margin_db": self.gain_db, "phase_margin_deg": self.phase_deg,
                "delay_margin_samples": self.delay_samples, "modulus_margin": self.modulus}


def floor_violations(m: Margins, floors: MarginFloors) -> list[str]:
    """The floors ``m`` misses, each as ``"name value < floor unit"`` (empty: all met)."""
    out = []
    if not m.stable:
        out.append(f"unstable (spectral radius {m.spectral_radius:.4f})")
    for name, val, floor, unit in (("gain margin", m.gain_margin_db, floors.gain_db, "dB"),
                                   ("phase margin", m.phase_margin_deg, floors.phase_deg, "deg"),
                                   ("delay margin", m.delay_margin_samples, floors.delay_samples, "samples"),
                                   ("modulus margin", m.modulus_margin, floors.modulus, "")):
        if not val >= floor:
            out.append(f"{name} {val:.3g} < {floor:g} {unit}".rstrip())
    return out


@dataclass(frozen=True)
class LoopMargins:
    """The margins of one controller on one plant.

    Attributes
    ----------
    plant : str
        ``"nominal"`` or ``"theta1_min/theta2_max"`` (a box corner).
    controller : str
        ``"arc"`` or ``"pid"``.
    theta_hat : tuple of 3 float or None
        The ARC's estimate at the linearisation ([1/M, B/M, d_n/M]); None for the PID.
    theta_hat_at : str
        ``"initial"`` (theta_hat(0)), ``"plant"`` (the plant's theta) or ``""`` (PID).
    margins : Margins
    """

    plant: str
    controller: str
    theta_hat: tuple[float, float, float] | None
    theta_hat_at: str
    margins: Margins

    def to_dict(self) -> dict[str, Any]:
        d = {"plant": self.plant, "controller": self.controller, "theta_hat_at": self.theta_hat_at,
             "theta_hat": list(self.theta_hat) if self.theta_hat is not None else None}
        d.update(self.margins.to_dict())
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "LoopMargins":
        def num(k: str, inf: float = math.inf) -> float:
            v = d.get(k)
            return inf if v is None else float(v)

        m = Margins(gain_margin_db=num("gain_margin_db"), phase_margin_deg=num("phase_margin_deg"),
                    delay_margin_samples=num("delay_margin_samples"), modulus_margin=num("modulus_margin"),
                    crossover_hz=num("crossover_hz", math.nan), spectral_radius=float(d["spectral_radius"]),
                    stable=bool(d["stable"]))
        th = d.get("theta_hat")
        return cls(plant=str(d["plant"]), controller=str(d["controller"]),
                   theta_hat=None if th is None else tuple(float(x) for x in th),  # type: ignore[arg-type]
                   theta_hat_at=str(d.get("theta_hat_at", "")), margins=m)


def margin_plants(ident: Identification, spec: Spec) -> list[tuple[str, np.ndarray]]:
    """The identified plant and the four (theta1, theta2) corners of the box, with its mode and delay."""
    base = identified_plant(ident, spec)
    out = [("nominal", base)]
    lo, hi = ident.theta.min, ident.theta.max
    for n1, t1 in (("theta1_min", lo[0]), ("theta1_max", hi[0])):
        for n2, t2 in (("theta2_min", lo[1]), ("theta2_max", hi[1])):
            p = base.copy()
            p[P_M] = 1.0 / t1
            p[P_B] = max(t2 / t1, 0.0)
            out.append((f"{n1}/{n2}", p))
    return out


def _theta_of(p: np.ndarray, theta3: float) -> tuple[float, float, float]:
    return (1.0 / p[P_M], p[P_B] / p[P_M], theta3)


def _one_thread(fn):
    """Run ``fn`` with BLAS on one thread: its small dense problems lose more to threading than they gain."""
    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with one_blas_thread():
            return fn(*args, **kwargs)

    return wrapped


@_one_thread
def margin_table(arc: ArcGains, pid: PidGains, ident: Identification, spec: Spec) -> tuple[LoopMargins, ...]:
    """Margins of both loops on every plant of :func:`margin_plants` (module docstring)."""
    Ts = spec.period
    ap, pp = arc_pack(arc), pid_pack(pid)
    pid_lin = linearize_pid(pp)
    f = frequency_grid(Ts)
    th3 = ident.theta.nominal[2]
    arc_at: dict[tuple[float, ...], Any] = {}
    rows: list[LoopMargins] = []
    for name, p in margin_plants(ident, spec):
        sp = sampled_plant(p, Ts)
        rows.append(LoopMargins(name, "pid", None, "", loop_margins(pid_lin, sp, f)))
        for at, th in (("initial", tuple(arc.theta0)), ("plant", _theta_of(p, th3))):
            key = tuple(round(x, 12) for x in th)
            if key not in arc_at:
                arc_at[key] = linearize_arc(ap, th)
            rows.append(LoopMargins(name, "arc", th, at, loop_margins(arc_at[key], sp, f)))  # type: ignore[arg-type]
    return tuple(rows)


class IdentifiedPlantArcMargins:
    """The ARC's loops on the identified plant (the ones the gate holds to the floors), for many gain sets.

    The sampled plant and its frequency response are computed once, at construction: a search
    checks a hundred gain sets on the same plant.

    Parameters
    ----------
    ident : Identification
    spec : Spec
    """

    def __init__(self, ident: Identification, spec: Spec) -> None:
        self.name, p = margin_plants(ident, spec)[0]
        self.plant = sampled_plant(p, spec.period)
        self.f_hz = frequency_grid(spec.period)
        with one_blas_thread():
            self.response = self.plant.frequency_response(self.f_hz)
        self.theta_plant = _theta_of(p, ident.theta.nominal[2])

    @_one_thread
    def __call__(self, arc: ArcGains) -> tuple[LoopMargins, ...]:
        """Margins of ``arc`` linearised at its initial estimate and at the identified theta."""
        ap = arc_pack(arc)
        return tuple(LoopMargins(self.name, "arc", th, at,
                                 loop_margins(linearize_arc(ap, th), self.plant, self.f_hz, self.response))
                     for at, th in (("initial", tuple(arc.theta0)), ("plant", self.theta_plant)))


def worst(rows: tuple[LoopMargins, ...] | list[LoopMargins], controller: str) -> Margins | None:
    """Element-wise worst margins of ``controller`` over ``rows`` (None: no row)."""
    ms = [r.margins for r in rows if r.controller == controller]
    if not ms:
        return None
    return Margins(gain_margin_db=min(m.gain_margin_db for m in ms),
                   phase_margin_deg=min(m.phase_margin_deg for m in ms),
                   delay_margin_samples=min(m.delay_margin_samples for m in ms),
                   modulus_margin=min(m.modulus_margin for m in ms),
                   crossover_hz=max((m.crossover_hz for m in ms if math.isfinite(m.crossover_hz)), default=math.nan),
                   spectral_radius=max(m.spectral_radius for m in ms), stable=all(m.stable for m in ms))


@_one_thread
def nominal_loops(arc: ArcGains, pid: PidGains, ident: Identification,
                  spec: Spec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(f_hz, L_arc, L_pid)``: the loop transfers on the identified plant, for a Bode or Nyquist figure.

    The ARC is linearised at its initial estimate.
    """
    Ts = spec.period
    sp = sampled_plant(identified_plant(ident, spec), Ts)
    f = frequency_grid(Ts, 1500)
    return (f, loop_response(linearize_arc(arc_pack(arc), arc.theta0), sp, f),
            loop_response(linearize_pid(pid_pack(pid)), sp, f))


# --------------------------------------------------------------------------- the whole box

#: More input delay, samples, of the box check's delayed plants (:class:`BoxArcCheck`, (b)).
BOX_DELAY_EXTRA = 1.0

#: (b) with the extra delay for theta_hat at every corner of the projection box too (True), or only
#: at theta_hat(0) and the plant's theta (False, the default: the delayed loop with the estimate at the
#: far corner of the box is the light plant's loop gain multiplied by the box's whole mass ratio
#: *and* one more sample of lag, which no gains of the sample axis's search that beat the PID keep;
#: docs/robustness.md, "The whole box").
BOX_DELAY_ANY_ESTIMATE = False


def _corner_name(i1: int, i2: int) -> str:
    return f"{('theta1_min', 'theta1_max')[i1]}/{('theta2_min', 'theta2_max')[i2]}"


def box_plants(ident: Identification, spec: Spec,
               theta_min: tuple[float, ...] | None = None) -> list[tuple[str, np.ndarray]]:
    """Every plant the box check covers: the four (theta1, theta2) corners x the identified dynamics.

    At each corner (mass ``1/theta1``, viscous ``theta2/theta1``, the box's corners as in
    :func:`margin_plants`) the identified mode and delay and, with a mode, the mode's variants of
    :func:`commission.scenarios.robustness_scenarios` (frequency x0.8 and x1.2, half its damping).
    ``theta_min`` overrides the box's lower end (a narrowed payload range,
    :func:`certified_payload`).  Names ``"<corner>"`` or ``"<corner>/<variant>"``.
    """
    from commission.scenarios import MODE_DAMPING_FACTOR, MODE_FREQUENCY_FACTORS
    from commission.controllers.plant import P_MODE_DAMPING, P_MODE_HZ
    base = identified_plant(ident, spec)
    lo = ident.theta.min if theta_min is None else theta_min
    hi = ident.theta.max
    dyn: list[tuple[str, np.ndarray]] = [("", base)]
    if base[P_MODE_HZ] > 0:
        for name, k in zip(("mode_low", "mode_high"), MODE_FREQUENCY_FACTORS):
            p = base.copy()
            p[P_MODE_HZ] *= k
            dyn.append((name, p))
        p = base.copy()
        p[P_MODE_DAMPING] *= MODE_DAMPING_FACTOR
        dyn.append(("mode_damping_half", p))
    out = []
    for i1, t1 in enumerate((lo[0], hi[0])):
        for i2, t2 in enumerate((lo[1], hi[1])):
            for vname, b in dyn:
                p = b.copy()
                p[P_M] = 1.0 / t1
                p[P_B] = max(t2 / t1, 0.0)
                out.append((_corner_name(i1, i2) + (f"/{vname}" if vname else ""), p))
    return out


@dataclass(frozen=True)
class AnyEstimateWorst:
    """The least stable loop of the ARC with theta_hat frozen anywhere the projection allows.

    Attributes
    ----------
    plant : str
        Box plant (:func:`box_plants`), with ``"+1 sample"`` when one more sample of input delay.
    theta_hat : tuple of 3 float
        The estimate of that loop ([1/M, B/M, d_n/M]).
    theta_hat_at : str
        ``"box corner <theta1 end>/<theta2 end>"``, ``"initial"`` or ``"plant"``.
    spectral_radius : float
        Of the sampled closed loop, dimensionless (>= 1: unstable).
    loops : int
        Loops checked.
    """

    plant: str
    theta_hat: tuple[float, float, float]
    theta_hat_at: str
    spectral_radius: float
    loops: int

    @property
    def stable(self) -> bool:
        """Radius below 1 up to the neutral modes' tolerance (theta_hat1, theta_hat2 at rest sit on 1)."""
        return bool(self.spectral_radius < 1.0 + NEUTRAL_TOL)

    def to_dict(self) -> dict[str, Any]:
        return {"plant": self.plant, "theta_hat": list(self.theta_hat), "theta_hat_at": self.theta_hat_at,
                "spectral_radius": float(self.spectral_radius), "stable": self.stable, "loops": int(self.loops)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "AnyEstimateWorst":
        return cls(plant=str(d["plant"]), theta_hat=tuple(float(x) for x in d["theta_hat"]),  # type: ignore[arg-type]
                   theta_hat_at=str(d["theta_hat_at"]), spectral_radius=float(d["spectral_radius"]),
                   loops=int(d.get("loops", 0)))


@dataclass(frozen=True)
class BoxRobustness:
    """The ARC over the whole Assumption-1 box (module :func:`box_check`).

    Attributes
    ----------
    at_plant : tuple of LoopMargins
        (a) Per box plant, the ARC linearised with theta_hat at that plant's theta (where the
        adaptation goes), identified delay: held to the margin floors.
    any_estimate : AnyEstimateWorst
        (b) The least stable loop over every box plant, with and without one more sample of
        delay, and theta_hat at every corner of the projection box, theta_hat(0) and the plant's theta.
    """

    at_plant: tuple[LoopMargins, ...]
    any_estimate: AnyEstimateWorst

    def worst_at_plant(self, floors: MarginFloors) -> LoopMargins:
        """The row of (a) furthest below the floors (an unstable one first; then the most floors missed,
        then the smallest modulus margin)."""
        def key(r: LoopMargins) -> tuple:
            m = r.margins
            return (m.stable, 0.0 if m.stable else -m.spectral_radius, -len(floor_violations(m, floors)),
                    m.modulus_margin, m.delay_margin_samples)
        return min(self.at_plant, key=key)

    def holds(self, floors: MarginFloors) -> bool:
        return self.any_estimate.stable and all(not floor_violations(r.margins, floors) for r in self.at_plant)

    def to_dict(self, floors: MarginFloors) -> dict[str, Any]:
        w = self.worst_at_plant(floors)
        return {"at_plant": [r.to_dict() for r in self.at_plant],
                "at_plant_worst": {**w.to_dict(), "violations": floor_violations(w.margins, floors)},
                "any_estimate_worst": self.any_estimate.to_dict(),
                "holds": self.holds(floors)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "BoxRobustness":
        return cls(at_plant=tuple(LoopMargins.from_dict(r) for r in d["at_plant"]),
                   any_estimate=AnyEstimateWorst.from_dict(d["any_estimate_worst"]))


def _closed_loops(ctrls: list[Any], ss: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """Spectral radii of ``u = c`` closed on one plant realisation, one per controller (batched eig)."""
    Ap, Bp, Cp = ss
    n_p, n_c = Ap.shape[0], ctrls[0].Ac.shape[0]
    A = np.zeros((len(ctrls), n_p + n_c, n_p + n_c))
    for i, c in enumerate(ctrls):
        A[i, :n_p, :n_p] = Ap + c.Dc * (Bp @ Cp)
        A[i, :n_p, n_p:] = Bp @ c.Cc
        A[i, n_p:, :n_p] = c.Bc @ Cp
        A[i, n_p:, n_p:] = c.Ac
    return np.abs(np.linalg.eigvals(A)).max(axis=1)


class BoxArcCheck:
    """The box check of one axis, for many gain sets (the search's constraint and the gate's check).

    What is checked (docs/robustness.md, "The whole box"):

    (a) at every plant of :func:`box_plants`, with its load force ``d_n`` at either end of the range
        the box admits at every mass (:func:`commission.scenarios.force_range`), the ARC linearised
        with theta_hat at that plant's theta ``[1/M, B/M, d_n/M]`` (what the adaptation tends to)
        keeps the margin floors (the load enters the linear plant as a constant only, but the
        ARC's robust gain at rest grows with the load its model terms carry);
    (b) at every plant of :func:`box_plants` the sampled loop is stable with theta_hat frozen at
        each of the four (theta1, theta2) corners of the projection box, at theta_hat(0) and at
        the plant's theta (theta_hat3 at theta_hat(0)'s: the axis stays at rest whatever
        theta_hat1 and theta_hat2 are, since their regressors vanish there, but a theta_hat3 other
        than the plant's is a force error that moves it, so "frozen at rest" is no operating point
        for it; the plant's own load is (a)'s); and with :data:`BOX_DELAY_EXTRA` more samples of input delay, with
        theta_hat at theta_hat(0) and at the plant's theta (every corner too when
        :data:`BOX_DELAY_ANY_ESTIMATE`).

    The corner plants share their theta with the projection box's corners, so one linearisation
    per corner serves (a) and (b).  The sampled plants, their realisations and frequency
    responses are computed once, at construction.

    Parameters
    ----------
    ident : Identification
    spec : Spec
    theta_min : tuple of 3 float, optional
        The box's lower end, when narrowed.
    delay_any_estimate : bool
        (b) with the extra delay at every estimate too (default :data:`BOX_DELAY_ANY_ESTIMATE`).
    """

    def __init__(self, ident: Identification, spec: Spec, theta_min: tuple[float, ...] | None = None,
                 delay_any_estimate: bool = BOX_DELAY_ANY_ESTIMATE) -> None:
        Ts = spec.period
        self.delay_any_estimate = bool(delay_any_estimate)
        self.theta_min = tuple(ident.theta.min if theta_min is None else theta_min)
        self.theta_max = tuple(ident.theta.max)
        self.plants = box_plants(ident, spec, self.theta_min)
        self.f_hz = frequency_grid(Ts)
        self.th3 = ident.theta.nominal[2]
        with one_blas_thread():
            self.sampled = [sampled_plant(p, Ts) for _, p in self.plants]
            self.responses = [sp.frequency_response(self.f_hz) for sp in self.sampled]
            self.ss = [sp.state_space() for sp in self.sampled]
            self.ss_delay = [sampled_plant(p, Ts, BOX_DELAY_EXTRA).state_space() for _, p in self.plants]
        self.corners = [((self.theta_min, self.theta_max)[i1][0], (self.theta_min, self.theta_max)[i2][1])
                        for i1 in (0, 1) for i2 in (0, 1)]
        self.corner_names = [_corner_name(i1, i2) for i1 in (0, 1) for i2 in (0, 1)]
        from commission.scenarios import force_range
        self.loads = force_range(ident)  # the load force d_n every mass of the box admits, u-unit

    @_one_thread
    def __call__(self, arc: ArcGains, floors_only_if_stable: bool = False) -> BoxRobustness:
        """(a) and (b) for ``arc`` (class docstring)."""
        out = self._check(arc, None)
        assert out is not None
        return out

    @_one_thread
    def holds(self, arc: ArcGains, floors: MarginFloors) -> bool:
        """``self(arc).holds(floors)``, stopping at the first loop that settles it false.

        A row of (a) below a floor, or a loop of (b) whose spectral radius already reaches the
        neutral tolerance (the worst radius only grows), decides it: the rest is not computed.
        For a bisection or a list of start gains, most of which fail.
        """
        out = self._check(arc, floors)
        return out is not None and out.holds(floors)

    def _check(self, arc: ArcGains, stop: MarginFloors | None) -> BoxRobustness | None:
        """:meth:`__call__`; with ``stop``, None as soon as the check cannot hold for those floors."""
        ap = arc_pack(arc)
        th0 = tuple(float(x) for x in arc.theta0)
        ests: list[tuple[str, tuple[float, float, float]]] = [
            (f"box corner {n}", (t1, t2, th0[2])) for n, (t1, t2) in zip(self.corner_names, self.corners)]
        ests.append(("initial", th0))
        lin = {th: linearize_arc(ap, th) for _, th in ests}
        resp: dict[tuple[float, ...], np.ndarray] = {}  # K(f) once per estimate, for every plant it meets
        at_plant = []
        worst = (-math.inf, "", ests[0][1], "")
        n = 0
        for (name, p), sp, presp, ss, ssd in zip(self.plants, self.sampled, self.responses, self.ss, self.ss_delay):
            corner = name.split("/")[0] + "/" + name.split("/")[1]
            th_p = ests[self.corner_names.index(corner)][1]
            # (a) at the plant's theta, its load force at both ends of the range (theta3 = d_n M^-1): the
            # robust gain at rest grows with the load the model terms carry, so both ends are checked.
            for end, d in zip(("load_min", "load_max"), self.loads):
                th_l = (th_p[0], th_p[1], float(np.clip(d * th_p[0], self.theta_min[2], self.theta_max[2])))
                if th_l not in lin:
                    lin[th_l] = linearize_arc(ap, th_l)
                if th_l not in resp:
                    resp[th_l] = lin[th_l].frequency_response(self.f_hz)
                at_plant.append(LoopMargins(f"{name}/{end}", "arc", th_l, "plant",
                                            loop_margins(lin[th_l], sp, self.f_hz, presp, resp[th_l])))
                if stop is not None and floor_violations(at_plant[-1].margins, stop):
                    return None
            every = ests if th_p in (th for _, th in ests[:4]) else [*ests, ("plant", th_p)]
            # With one more sample of delay: theta_hat(0) and the plant's theta only, unless
            # delay_any_estimate (class docstring).
            delayed = every if self.delay_any_estimate else [e for e in every if e[1] in (th0, th_p)]
            for tag, real, use in (("", ss, every), (" +1 sample", ssd, delayed)):
                rho = _closed_loops([lin.get(th) or linearize_arc(ap, th) for _, th in use], real)
                n += rho.size
                k = int(np.argmax(rho))
                if rho[k] > worst[0]:
                    at = use[k][0]
                    if use[k][1] == th_p:
                        at = "plant"
                    worst = (float(rho[k]), name + tag, use[k][1], at)
                if stop is not None and not worst[0] < 1.0 + NEUTRAL_TOL:
                    return None
        return BoxRobustness(tuple(at_plant), AnyEstimateWorst(worst[1], worst[2], worst[3], worst[0], n))


def box_check(arc: ArcGains, ident: Identification, spec: Spec) -> BoxRobustness:
    """:class:`BoxArcCheck` of ``arc`` on ``ident``'s box (one gain set)."""
    return BoxArcCheck(ident, spec)(arc)



def identified_performance(names: Sequence[str], ident: Identification) -> frozenset[str]:
    """The PERFORMANCE scenarios among ``names`` for this identification (:func:`commission.gate.performance_scenarios`).

    The payload range counts as stated unless ident.json records it as defaulted
    (``bounds.payload_defaulted``, :func:`payload_box`), the load-force bound unless
    ``bounds.disturbance_bound_defaulted`` is true.  One answer for validate's gate and tune's
    search, so that the search holds the absolute error limits exactly where the gate does.
    """
    from commission.gate import performance_scenarios

    pb = payload_box(ident)
    bounds = ident.extra.get("bounds")
    dist_defaulted = isinstance(bounds, dict) and bounds.get("disturbance_bound_defaulted") is True
    return performance_scenarios(list(names), payload_stated=pb is None or not pb[3],
                                 disturbance_stated=not dist_defaulted)


def payload_box(ident: Identification) -> tuple[float, float, float, bool] | None:
    """``(payload_min, payload_max, heaviest mass without payload, defaulted)`` from ident.json's ``bounds``.

    None when ident.json does not record the payload range (written before ``bounds.payload_range``):
    such a box is treated as one the user stated (never narrowed).  Masses in u-unit s^2/m.
    """
    b = ident.extra.get("bounds")
    if not isinstance(b, dict) or not isinstance(b.get("payload_range"), list) or "mass_range" not in b:
        return None
    pmin, pmax = (float(x) for x in b["payload_range"])
    m_hi = 1.0 / ident.theta.min[0]
    return pmin, pmax, m_hi - pmax, bool(b.get("payload_defaulted", False))


def narrowed_theta_min(ident: Identification, m_hi: float) -> tuple[float, float, float]:
    """The box's lower end with the heaviest mass ``m_hi`` (u-unit s^2/m): theta1 = 1/M, theta2 = B_min/M."""
    b_lo = float(ident.extra["bounds"]["viscous_range"][0])
    return (1.0 / m_hi, max(b_lo / m_hi, 0.0), ident.theta.min[2])


def narrowed_ident(ident: Identification, payload_max: float) -> Identification:
    """``ident`` with its box's heavy end at ``payload_max`` (u-unit s^2/m) of payload (:func:`payload_box`).

    theta1_min = 1/M_hi and theta2_min = B_min/M_hi follow the heaviest mass; the other ends stay.
    ``bounds.mass_range`` and ``bounds.payload_range`` record the narrowed ranges.
    """
    pb = payload_box(ident)
    if pb is None:
        raise ValueError("narrowed_ident: ident.json records no payload range (bounds.payload_range)")
    pmin, _, m0, _ = pb
    th = narrowed_theta_min(ident, m0 + payload_max)
    bounds = dict(ident.extra["bounds"])
    bounds["mass_range"] = [float(bounds["mass_range"][0]), m0 + payload_max]
    bounds["payload_range"] = [pmin, float(payload_max)]
    extra = dict(ident.extra)
    extra["bounds"] = bounds
    return dataclasses.replace(ident, theta=dataclasses.replace(ident.theta, min=th), extra=extra)


#: Bisection steps of :func:`certified_payload` (the payload range to 2^-10 of the default's).
PAYLOAD_BISECTIONS = 10


def certified_payload(gains_for: Callable[[Identification], Sequence[ArcGains]], ident: Identification,
                      spec: Spec, floors: MarginFloors,
                      delay_any_estimate: bool = BOX_DELAY_ANY_ESTIMATE) -> tuple[float, BoxRobustness] | None:
    """The largest payload over which one of ``gains_for(box)`` holds the box check, by bisection.

    ``gains_for`` designs gain sets for a (narrowed) identification -- ``tune`` passes its search's
    start points, which are built on the box (the robust gains scale with its heaviest mass), so
    a box they hold is one the search starts feasible in.  The heavy end ``M_hi0 + payload``
    (:func:`payload_box`) shrinks until (a) and (b) of :class:`BoxArcCheck` hold for one of them; the
    other ends of the box stay.  The bisection assumes that a smaller payload range holds if a
    larger one does (the loops that fail are the heaviest plant's, and the light plant's with
    theta_hat at the heavy end: both ease as the range shrinks) and checks the range it returns.
    ``delay_any_estimate``: the check's (b) with one more sample of delay at every estimate.

    Returns
    -------
    (payload_max, box) or None
        u-unit s^2/m and the check on the narrowed box; None when the box fails even at the least
        payload (or ident.json does not record the payload range).
    """
    pb = payload_box(ident)
    if pb is None:
        return None
    pmin, pmax, _, _ = pb

    def check(p: float) -> BoxRobustness | None:
        idn = narrowed_ident(ident, p)
        chk = BoxArcCheck(idn, spec, delay_any_estimate=delay_any_estimate)
        for g in gains_for(idn):
            if chk.holds(g, floors):  # stops at the first failing loop; the whole check for the one that holds
                return chk(g)
        return None

    best = check(pmin)
    if best is None:
        return None
    lo, hi = pmin, pmax
    for _ in range(PAYLOAD_BISECTIONS):
        mid = 0.5 * (lo + hi)
        r = check(mid)
        if r is not None:
            lo, best = mid, r
        else:
            hi = mid
    return lo, best

__all__ = ["AnyEstimateWorst", "PAYLOAD_BISECTIONS", "certified_payload", "narrowed_ident", "narrowed_theta_min", "payload_box", "BOX_DELAY_EXTRA", "BoxArcCheck", "BoxRobustness", "CONTROLLERS", "box_check", "box_plants", "IdentifiedPlantArcMargins", "LoopMargins", "MarginFloors", "floor_violations",
           "margin_plants", "margin_table", "nominal_loops", "worst"]
