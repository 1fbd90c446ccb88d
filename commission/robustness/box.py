"""The ARC over the whole Assumption-1 box: :class:`BoxArcCheck` (the search's constraint and the
gate's ``margins_box`` check), its plants (:func:`box_plants`) and its record (:class:`BoxRobustness`).

docs/robustness.md, "The whole box", states what is checked and why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from commission.artifacts import Identification
from commission.infra.blas import one_blas_thread
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import (NEUTRAL_TOL, closed_loop_radii, frequency_grid, linearize_arc, loop_margins,
                                            loop_margins_batch)
from commission.robustness.margins import (LoopMargins, MarginFloors, one_thread, corner_name, corner_plant,
                                           floor_violations)
from commission.scenarios import identified_plant
from commission.spec import Spec

#: More input delay, samples, of the box check's delayed plants (:class:`BoxArcCheck`, (b)).
BOX_DELAY_EXTRA = 1.0

#: (b) with the extra delay for theta_hat at every corner of the projection box too (True), or only
#: at theta_hat(0) and the plant's theta (False, the default: the delayed loop with the estimate at the
#: far corner of the box is the light plant's loop gain multiplied by the box's whole mass ratio
#: *and* one more sample of lag, which no gains of the sample axis's search that beat the PID keep;
#: docs/robustness.md, "The whole box").
BOX_DELAY_ANY_ESTIMATE = False


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


def box_plants(ident: Identification, spec: Spec,
               theta_min: tuple[float, ...] | None = None) -> list[tuple[str, np.ndarray]]:
    """Every plant the box check covers: the four (theta1, theta2) corners x the identified dynamics.

    At each corner (mass ``1/theta1``, viscous ``theta2/theta1``, the box's corners as in
    :func:`commission.robustness.margins.margin_plants`) the identified mode and delay and, with a
    mode, the mode's variants of :func:`commission.scenarios.robustness_scenarios` (frequency x0.8
    and x1.2, half its damping).  ``theta_min`` overrides the box's lower end (a narrowed payload
    range, :func:`commission.robustness.payload.certified_payload`).  Names ``"<corner>"`` or
    ``"<corner>/<variant>"``.
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
                out.append((corner_name(i1, i2) + (f"/{vname}" if vname else ""), corner_plant(b, t1, t2)))
    return out


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
        self.corner_names = [corner_name(i1, i2) for i1 in (0, 1) for i2 in (0, 1)]
        from commission.scenarios import force_range
        self.loads = force_range(ident)  # the load force d_n every mass of the box admits, u-unit

    @one_thread
    def __call__(self, arc: ArcGains, floors_only_if_stable: bool = False) -> BoxRobustness:
        """(a) and (b) for ``arc`` (class docstring)."""
        return self._check_all(arc)

    @one_thread
    def holds(self, arc: ArcGains, floors: MarginFloors) -> bool:
        """``self(arc).holds(floors)``, stopping at the first loop that settles it false.

        A row of (a) below a floor, or a loop of (b) whose spectral radius already reaches the
        neutral tolerance (the worst radius only grows), decides it: the rest is not computed.
        For a bisection or a list of start gains, most of which fail.
        """
        out = self._check(arc, floors)
        return out is not None and out.holds(floors)

    def _estimates(self, arc: ArcGains) -> tuple[np.ndarray, tuple[float, ...], list, dict]:
        """The packed gains, theta_hat(0), the estimates (b) holds at every plant (the projection box's
        four (theta1, theta2) corners with theta_hat3(0), and theta_hat(0)) and their linearisations."""
        ap = arc_pack(arc)
        th0 = tuple(float(x) for x in arc.theta0)
        ests: list[tuple[str, tuple[float, float, float]]] = [
            (f"box corner {n}", (t1, t2, th0[2])) for n, (t1, t2) in zip(self.corner_names, self.corners)]
        ests.append(("initial", th0))
        return ap, th0, ests, {th: linearize_arc(ap, th) for _, th in ests}

    def _at_plant(self, name: str, ests: list, th0: tuple[float, ...]) -> tuple[tuple[float, ...], list, list, list]:
        """For box plant ``name``: its theta, (a)'s estimates (its load force at both ends of the range,
        theta3 = d_n M^-1: the robust gain at rest grows with the load the model terms carry, so both ends
        are checked), (b)'s estimates, and those (b) checks with one more sample of delay (theta_hat(0)
        and the plant's theta only, unless ``delay_any_estimate``: class docstring)."""
        corner = name.split("/")[0] + "/" + name.split("/")[1]
        th_p = ests[self.corner_names.index(corner)][1]
        loads = [(end, (th_p[0], th_p[1], float(np.clip(d * th_p[0], self.theta_min[2], self.theta_max[2]))))
                 for end, d in zip(("load_min", "load_max"), self.loads)]
        every = ests if th_p in (th for _, th in ests[:4]) else [*ests, ("plant", th_p)]
        delayed = every if self.delay_any_estimate else [e for e in every if e[1] in (th0, th_p)]
        return th_p, loads, every, delayed

    def _check_all(self, arc: ArcGains) -> BoxRobustness:
        """:meth:`__call__`: what :meth:`_check` computes without ``stop``, the same values to the last
        bit, with the loops batched: (a)'s margins in one :func:`loop_margins_batch`, every closed
        loop's spectral radius ((a)'s and (b)'s) in one :func:`closed_loop_radii` per matrix size.
        The search checks every candidate to the end, so stopping early saves it nothing, and one
        call per kind of work instead of one per loop cuts numpy's and LAPACK's fixed cost per call
        (docs/scaling.md, "Fourth pass")."""
        ap, th0, ests, lin = self._estimates(arc)
        a_rows: list[tuple[int, str, tuple[float, float, float]]] = []  # (plant, row name, theta_hat)
        b_groups: list[tuple[int, str, bool, list]] = []  # (plant, name, one more sample, estimates)
        for i, (name, _) in enumerate(self.plants):
            th_p, loads, every, delayed = self._at_plant(name, ests, th0)
            for end, th_l in loads:
                if th_l not in lin:
                    lin[th_l] = linearize_arc(ap, th_l)
                a_rows.append((i, f"{name}/{end}", th_l))
            b_groups.append((i, name, False, every))
            b_groups.append((i, name + " +1 sample", True, delayed))
        lin_of = [lin[th] for _, _, th in a_rows]
        ctrls = [*lin_of]
        reals = [self.ss[i] for i, _, _ in a_rows]
        for i, _, late, use in b_groups:
            for _, th in use:
                ctrls.append(lin.get(th) or linearize_arc(ap, th))
                reals.append(self.ss_delay[i] if late else self.ss[i])
        radii = closed_loop_radii(ctrls, reals)
        margins = loop_margins_batch([c.frequency_response(self.f_hz) for c in lin_of],
                                     [self.responses[i] for i, _, _ in a_rows], self.f_hz, self.sampled[0].Ts,
                                     radii[:len(a_rows)])
        at_plant = tuple(LoopMargins(row, "arc", th_l, "plant", m) for (_, row, th_l), m in zip(a_rows, margins))
        worst = (-math.inf, "", ests[0][1], "")
        n, at_b = 0, len(a_rows)
        for i, label, _, use in b_groups:
            rho = radii[at_b:at_b + len(use)]
            at_b += len(use)
            n += rho.size
            k = int(np.argmax(rho))
            if rho[k] > worst[0]:
                th_p = self._at_plant(self.plants[i][0], ests, th0)[0]
                at = "plant" if use[k][1] == th_p else use[k][0]
                worst = (float(rho[k]), label, use[k][1], at)
        return BoxRobustness(at_plant, AnyEstimateWorst(worst[1], worst[2], worst[3], worst[0], n))

    def _check(self, arc: ArcGains, stop: MarginFloors | None) -> BoxRobustness | None:
        """:meth:`__call__`; with ``stop``, None as soon as the check cannot hold for those floors."""
        ap, th0, ests, lin = self._estimates(arc)
        resp: dict[tuple[float, ...], np.ndarray] = {}  # K(f) once per estimate, for every plant it meets
        at_plant = []
        worst = (-math.inf, "", ests[0][1], "")
        n = 0
        for (name, p), sp, presp, ss, ssd in zip(self.plants, self.sampled, self.responses, self.ss, self.ss_delay):
            th_p, loads, every, delayed = self._at_plant(name, ests, th0)
            for end, th_l in loads:
                if th_l not in lin:
                    lin[th_l] = linearize_arc(ap, th_l)
                if th_l not in resp:
                    resp[th_l] = lin[th_l].frequency_response(self.f_hz)
                at_plant.append(LoopMargins(f"{name}/{end}", "arc", th_l, "plant",
                                            loop_margins(lin[th_l], sp, self.f_hz, presp, resp[th_l])))
                if stop is not None and floor_violations(at_plant[-1].margins, stop):
                    return None
            for tag, real, use in (("", ss, every), (" +1 sample", ssd, delayed)):
                rho = closed_loop_radii([lin.get(th) or linearize_arc(ap, th) for _, th in use], [real] * len(use))
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
