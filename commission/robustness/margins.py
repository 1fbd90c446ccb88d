"""The margins of the tuned loops on the identified plant and the four corners of the box.

Where the margins are evaluated (:func:`margin_plants`, :func:`margin_table`), the floors they are
held to (:class:`MarginFloors`, :func:`floor_violations`) and the record of one loop
(:class:`LoopMargins`); the margins themselves are :mod:`commission.controllers.margins`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from commission.artifacts import Identification
from commission.infra.blas import one_blas_thread
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import (Margins, frequency_grid, linearize_arc, linearize_pid, loop_margins,
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


def margin_rows(m: Margins, floors: MarginFloors) -> tuple[tuple[str, float, float, str], ...]:
    """``(name, margin, floor, unit)`` of the four margins of ``m``: what :func:`floor_violations`
    and the gate's margin checks (:func:`commission.gate.margin_checks`) compare."""
    return (("gain margin", m.gain_margin_db, floors.gain_db, "dB"),
            ("phase margin", m.phase_margin_deg, floors.phase_deg, "deg"),
            ("delay margin", m.delay_margin_samples, floors.delay_samples, "samples"),
            ("modulus margin", m.modulus_margin, floors.modulus, ""))


def floor_violations(m: Margins, floors: MarginFloors) -> list[str]:
    """The floors ``m`` misses, each as ``"name value < floor unit"`` (empty: all met)."""
    out = []
    if not m.stable:
        out.append(f"unstable (spectral radius {m.spectral_radius:.4f})")
    for name, val, floor, unit in margin_rows(m, floors):
        if not val >= floor:
            out.append(f"{name} {val:.3g} < {floor:g} {unit}".rstrip())
    return out


def corner_name(i1: int, i2: int) -> str:
    """``"theta1_min/theta2_max"``: the box corner at end ``i1`` of theta1 and ``i2`` of theta2 (0: min, 1: max)."""
    return f"{('theta1_min', 'theta1_max')[i1]}/{('theta2_min', 'theta2_max')[i2]}"


def corner_plant(base: np.ndarray, theta1: float, theta2: float) -> np.ndarray:
    """``base`` with the mass ``1/theta1`` and the viscous ``theta2/theta1`` of a box corner."""
    p = base.copy()
    p[P_M] = 1.0 / theta1
    p[P_B] = max(theta2 / theta1, 0.0)
    return p


def margin_plants(ident: Identification, spec: Spec) -> list[tuple[str, np.ndarray]]:
    """The identified plant and the four (theta1, theta2) corners of the box, with its mode and delay."""
    base = identified_plant(ident, spec)
    ends = (ident.theta.min, ident.theta.max)
    return [("nominal", base)] + [(corner_name(i1, i2), corner_plant(base, ends[i1][0], ends[i2][1]))
                                  for i1 in (0, 1) for i2 in (0, 1)]


def _theta_of(p: np.ndarray, theta3: float) -> tuple[float, float, float]:
    return (1.0 / p[P_M], p[P_B] / p[P_M], theta3)


def one_thread(fn):
    """Run ``fn`` with BLAS on one thread: its small dense problems lose more to threading than they gain."""
    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with one_blas_thread():
            return fn(*args, **kwargs)

    return wrapped


@one_thread
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

    @one_thread
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


@one_thread
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

