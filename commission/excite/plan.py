"""The plan's segments: the friction ladder, the moves, the injection and the stepped sine."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from commission.controllers.trajectory import Move, scurve_schedule, scurve_segments
from commission.errors import SpecError
from commission.excite.limits import ExciteSpec, LOOP_DAMPING
from commission.formats.plan_json import PLAN_SCHEMA_VERSION
if TYPE_CHECKING:
    from commission.excite.band import BandPrediction


@dataclass(frozen=True)
class Segment:
    """One segment of a plan: ``[t_start, t_end)`` s, its purpose and its design figures."""

    name: str
    purpose: str
    t_start: float
    t_end: float
    info: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "purpose": self.purpose, "t_start": self.t_start, "t_end": self.t_end,
                "duration": self.t_end - self.t_start, **dict(self.info)}


@dataclass(frozen=True)
class Plan:
    """A sampled plan: one row per sample at ``spec.sample_rate``.

    Attributes
    ----------
    t : ndarray
        s, ``k / sample_rate``.
    q_ref, v_ref : ndarray
        Reference position (q, relative to the start) and velocity (q/s).
    a_ref : ndarray
        Reference acceleration, q/s^2 (not in plan.csv; the S-curve's own).
    u_inject : ndarray
        Command added to the holding loop's, u.
    segments : tuple of Segment
    spec : ExciteSpec
    models : tuple of dict
        The pre-simulation models (``M``, ``B``, ``fc``, gains).
    peaks : dict
        Pre-simulation peaks over the models: ``u``, ``q_min``, ``q_max``, ``v``, ``a``.
    injection_scale : float
        Fraction of the designed injection amplitude kept by the pre-simulation.
    motion_scale : float
        Fraction of the designed top speed and acceleration kept by the pre-simulation.
    """

    t: np.ndarray
    q_ref: np.ndarray
    v_ref: np.ndarray
    a_ref: np.ndarray
    u_inject: np.ndarray
    segments: tuple[Segment, ...]
    spec: ExciteSpec
    models: tuple[Mapping[str, float], ...] = ()
    peaks: Mapping[str, float] = field(default_factory=dict)
    injection_scale: float = 1.0
    motion_scale: float = 1.0
    prediction: "BandPrediction | None" = None

    @property
    def duration(self) -> float:
        """Length of the run, s."""
        return float(self.t[-1] + 1.0 / self.spec.sample_rate)

    def to_dict(self) -> dict[str, Any]:
        """plan.json (keys sorted by the writer)."""
        s = self.spec
        q, u = s.q_unit, s.u_unit
        lim = {"travel": s.travel, "v_max": s.v_max, "a_max": s.a_max, "u_max": s.u_max}
        half = s.travel / 2.0
        p = self.peaks
        checks = {
            "u": {"peak": p["u"], "limit": s.u_max, "unit": u},
            "travel": {"peak": max(-p["q_min"], p["q_max"]), "limit": half, "unit": q,
                       "note": "largest |q - start|; the limit is travel / 2 about the start"},
            "v": {"peak": p["v"], "limit": s.v_max, "unit": f"{q}/s"},
            "a": {"peak": p["a"], "limit": s.a_max, "unit": f"{q}/s^2"},
        }
        return {
            "kind": "excitation_plan",
            "schema_version": PLAN_SCHEMA_VERSION,
            "units": {"t": "s", "q": q, "u": u, "v": f"{q}/s", "a": f"{q}/s^2"},
            "sample_rate": s.sample_rate,
            "samples": int(self.t.size),
            "duration_s": self.duration,
            "limits": lim,
            "spec": s.to_dict(),
            "segments": [g.to_dict() for g in self.segments],
            "presimulation": {"models": [dict(m) for m in self.models], "peaks": checks,
                              "injection_scale": self.injection_scale, "motion_scale": self.motion_scale,
                              "note": "rigid models bracketing the mass, holding loop of [drive], no quantization"},
            "predicted_band": self.prediction.to_dict(q, u) if self.prediction is not None else None,
        }


def _half_span(spec: ExciteSpec) -> float:
    return (1.0 - spec.plan["margin"]) * spec.travel / 2.0


def mass_bracket(spec: ExciteSpec) -> tuple[float, float]:
    """The light and the heavy mass of the pre-simulation, u s^2/q (module docstring)."""
    r = spec.plan["mass_range"]
    if spec.mass is not None:
        return spec.mass / r, spec.mass * r
    heavy = (spec.u_max - (spec.friction or 0.0)) / spec.a_max
    return heavy / (5.0 * r), heavy


def loop_gains_for(spec: ExciteSpec, M: float) -> tuple[float, float, float]:
    """Holding-loop gains (u/q, u s/q, u/(q s)) on a model of mass ``M``."""
    if spec.kp is not None:
        return float(spec.kp), float(spec.kd or 0.0), float(spec.ki or 0.0)
    w = 2.0 * math.pi * float(spec.bandwidth_hz)  # type: ignore[arg-type]
    kp = M * w * w
    return kp, 2.0 * LOOP_DAMPING * M * w, kp * w / 10.0


def _move_accel(spec: ExciteSpec) -> float:
    """Acceleration of the moves, q/s^2: within 60 % of a_max and of the command budget on the heavy model."""
    _light, heavy = mass_bracket(spec)
    fc = spec.friction or 0.0
    budget = 0.5 * (spec.u_max - fc - (spec.viscous or 0.0) * spec.v_max)
    if budget <= 0:
        raise SpecError(f"{spec.source}: limits.u_max = {spec.u_max:g} {spec.u_unit} leaves no command for acceleration after "
                        f"friction and viscous force at v_max")
    return min(0.6 * spec.a_max, budget / heavy)


def ladder_speeds(spec: ExciteSpec, motion_scale: float = 1.0) -> tuple[np.ndarray, float]:
    """Speeds of the friction ladder (q/s) and its ramps' acceleration (q/s^2).

    The fastest is the largest below ``0.8 v_max`` (times ``motion_scale``, which the
    pre-simulation lowers) whose leg keeps ``min_cruise`` s of cruise within the span; the
    slowest is ``plan.v_min`` (default ``v_max / 100``).  The ramps' acceleration is
    :func:`_move_accel` times ``motion_scale``.

    Raises
    ------
    SpecError
        The travel is too short for the slowest leg (``min_cruise`` s at ``v_min``).
    """
    p = spec.plan
    a = _move_accel(spec) * motion_scale
    span = 2.0 * _half_span(spec)
    tc = p["min_cruise"]
    # v^2 / a + v tc <= span  (two ramps of v^2 / (2a) and a cruise of tc s)
    v_fit = a * (-tc + math.sqrt(tc * tc + 4.0 * span / a)) / 2.0
    v_lo = p["v_min"] if p["v_min"] is not None else spec.v_max / 100.0
    need = v_lo * v_lo / a + v_lo * tc
    q = spec.q_unit
    if need > span:
        raise SpecError(
            f"{spec.source}: limits.travel = {spec.travel:g} {q} is too short for the slowest friction-ladder leg: "
            f"{v_lo:g} {q}/s for plan.min_cruise = {tc:g} s needs {need / (1 - p['margin']):.4g} {q}; "
            f"raise travel or lower plan.v_min")
    v_hi = min(0.8 * spec.v_max * motion_scale, v_fit)
    if v_hi <= v_lo:
        return np.array([v_lo]), a
    return np.geomspace(v_lo, v_hi, int(p["n_speeds"])), a


def _multisine(n: int, fs: float, band: tuple[float, float], shaping: float) -> np.ndarray:
    """Unit-peak Schroeder-phase multisine of ``n`` samples, period ~0.5 s, lines over ``band`` Hz."""
    P = int(2 ** round(math.log2(max(fs * 0.5, 64))))
    k = np.arange(int(math.ceil(band[0] * P / fs)), int(math.floor(band[1] * P / fs)) + 1)
    k = k[k > 0]
    if k.size == 0:
        k = np.array([1])
    amp = (k / k[0]).astype(float) ** shaping
    K = k.size
    phase = -np.pi * np.arange(1, K + 1) * np.arange(K) / K  # Schroeder (1970)
    tau = np.arange(P) / P
    x = np.zeros(P)
    for ki, ai, ph in zip(k, amp, phase):
        x += ai * np.cos(2 * np.pi * ki * tau + ph)
    x /= np.max(np.abs(x))
    return np.resize(x, n)


def _prbs(n: int) -> np.ndarray:
    from scipy.signal import max_len_seq

    bits = max_len_seq(max(int(math.ceil(math.log2(n + 1))), 4))[0][:n]
    return 2.0 * bits.astype(float) - 1.0


def _ramp_time(v: float, a: float, j: float) -> float:
    """Time of an S-curve ramp from rest to ``v`` (q/s) under ``a`` (q/s^2) and ``j`` (q/s^3), s.

    As :func:`commission.controllers.trajectory.scurve_segments`: ``v/a + a/j`` when the
    acceleration reaches ``a``, else ``2 sqrt(v/j)``; the ramp covers ``v t / 2``.
    """
    return v / a + a / j if v * j >= a * a else 2.0 * math.sqrt(v / j)


@dataclass(frozen=True)
class _Moves:
    """The plan's moves before sampling: what :func:`design_plan` samples and fills with injection."""

    moves: list[Move]
    #: (name, purpose, info, number of moves) per segment, in order.
    seg_moves: list[tuple[str, str, dict[str, Any], int]]
    sine_legs: list[tuple[float, float]]  # (frequency [Hz], cruise [s]) of each stepped-sine leg
    u_bump: float  # amplitude of the mass doublet [command unit] (0 with a given mass)
    t_ramp: float  # S-curve ramp time to the injection speed [s]
    a_mv: float  # acceleration of the ladder moves [q unit/s^2]
    light: float  # lightest mass of the bracket [kg or kg m^2]
    heavy: float  # heaviest mass of the bracket [kg or kg m^2]


def _cruise_time(wanted: float, pos: float, s: float, v_inj: float, t_ramp: float) -> float:
    """The cruise [s] of a leg from ``pos`` toward the farther end of the span (the room there is s + |pos|)."""
    d_max = s + abs(pos) - v_inj * t_ramp
    return min(wanted, d_max / v_inj)


def _cruise_end(pos: float, cruise: float, v_inj: float, t_ramp: float) -> float:
    """Where a leg from ``pos`` cruising ``cruise`` s at ``v_inj`` ends (toward the farther end)."""
    return pos + (-1 if pos > 0 else 1) * (cruise * v_inj + v_inj * t_ramp)


def injection_speed_bounds(spec: ExciteSpec, motion_scale: float = 1.0) -> tuple[float, float]:
    """The injection's default cruise speed and the fastest it may be raised to, q/s.

    The default is a quarter of the way (in log) from the ladder's slowest speed to its fastest
    (:func:`ladder_speeds`), just past stiction; the fastest is the ladder's top speed, whose legs
    the plan already drives.
    """
    speeds, _ = ladder_speeds(spec, motion_scale)
    return _default_cruise(speeds), float(speeds[-1])


def _default_cruise(speeds: np.ndarray) -> float:
    """A quarter of the way (in log) from the ladder's slowest speed to its fastest, q/s."""
    return float(speeds[0] * (speeds[-1] / speeds[0]) ** 0.25)


def _plan_moves(spec: ExciteSpec, injection_scale: float, motion_scale: float,
                injection_speed: float | None = None) -> _Moves:
    """The bump, approach, friction ladder, moves, injection and stepped-sine legs and the return, in order.

    ``injection_speed`` (q/s): the cruise of the injection and stepped-sine legs; default
    ``plan.injection_speed``, else the first of :func:`injection_speed_bounds`
    (:func:`commission.excite.presim.plan_run` raises the latter where the injection's velocity
    swing would reach the cruise).
    """
    p = spec.plan
    fs = spec.sample_rate
    s = _half_span(spec)
    speeds, a_mv = ladder_speeds(spec, motion_scale)
    light, heavy = mass_bracket(spec)
    jt = p["jerk_time"]
    dwell = p["dwell"]
    moves: list[Move] = []
    # (name, purpose, info, number of moves) in order; times from the S-curve durations below.
    seg_moves: list[tuple[str, str, dict[str, Any], int]] = []
    pos = 0.0
    t_bump = 0.0
    u_bump = 0.0
    if spec.mass is None:
        # A doublet at rest: +u for tb, -u for tb (zero net impulse), u sized on the light model to move
        # at most a tenth of the span open-loop: x = u tb^2 / M.
        tb = 0.02
        u_bump = injection_scale * min(0.2 * (spec.u_max - (spec.friction or 0.0)), 0.1 * s * light / (tb * tb), 0.5 * light * spec.a_max)
        t_bump = 2 * tb + 0.5
        moves.append(Move(to=0.0, v_max=1.0, a_max=1.0, j_max=1.0 / jt, dwell=t_bump))
        seg_moves.append(("bump", "mass from a command doublet at rest (no [axis] mass given)",
                          {"amplitude": u_bump, "pulse_s": tb}, 1))

    def mv(to: float, v: float, a: float, dw: float) -> Move:
        return Move(to=to, v_max=v, a_max=a, j_max=a / jt, dwell=dw)

    moves.append(mv(-s, 0.5 * speeds[-1], a_mv, dwell))
    seg_moves.append(("approach", "move to one end of the span", {}, 1))
    pos = -s
    for i, v in enumerate(speeds):
        d = min(2 * s, v * p["leg_time"] + v * v / a_mv)
        moves += [mv(-s + d, v, a_mv, dwell), mv(-s, v, a_mv, dwell)]
        seg_moves.append((f"ladder {i + 1}", "friction ladder: constant-velocity leg forward and back "
                          "(Stribeck curve, B, friction map)", {"speed": float(v), "leg_length": float(d)}, 2))
    a_acc = a_mv
    v_acc = min(0.8 * spec.v_max * motion_scale, math.sqrt(a_acc * s))
    for k in range(int(p["moves"])):
        moves.append(mv(s if k % 2 == 0 else -s, v_acc, a_acc, 0.05))
    seg_moves.append(("moves", "acceleration-rich back-and-forth S-curves (M and B)",
                      {"speed": v_acc, "acceleration": a_acc, "count": int(p["moves"])}, int(p["moves"])))
    pos = s if int(p["moves"]) % 2 == 1 else -s
    # Cruises for the injection, just past stiction by default (injection_speed_bounds), faster when the
    # injection's velocity swing needs it (plan_run); both directions.
    if injection_speed is None:
        injection_speed = p.get("injection_speed")  # plan.injection_speed, when the user set it
    v_inj = _default_cruise(speeds) if injection_speed is None else float(injection_speed)
    t_ramp = _ramp_time(v_inj, a_mv, a_mv / jt)
    inj_legs = []
    remaining = p["injection_s"]
    while remaining > 1e-9:
        cruise = _cruise_time(remaining, pos, s, v_inj, t_ramp)
        if cruise < 0.1:
            raise SpecError(f"{spec.source}: limits.travel = {spec.travel:g} {spec.q_unit} is too short for the "
                            f"injection's cruise at {v_inj:.4g} {spec.q_unit}/s (0.1 s at least); raise travel or "
                            f"lower plan.v_min")
        target = _cruise_end(pos, cruise, v_inj, t_ramp)
        inj_legs.append(mv(target, v_inj, a_mv, dwell))
        pos = target
        remaining -= cruise
        if len(inj_legs) > 200:
            break
    moves += inj_legs
    seg_moves.append(("injection", "broadband injection on cruises (frequency response, modes, delay)",
                      {"speed": v_inj, "kind": p["injection"], "band_hz": list(p["band_hz"])
                       if p["injection"] == "multisine" else [0.0, fs / 2.0],
                       "shaping": p["shaping"] if p["injection"] == "multisine" else 0.0}, len(inj_legs)))
    sine_legs = []
    for f in p["stepped_sine_hz"]:
        cruise = _cruise_time(max(p["sine_cycles"] / f, 0.1), pos, s, v_inj, t_ramp)
        if cruise < 0.1:
            raise SpecError(f"{spec.source}: limits.travel = {spec.travel:g} {spec.q_unit} is too short for the "
                            f"stepped sine at {f:g} Hz on a cruise at {v_inj:.4g} {spec.q_unit}/s (0.1 s at least)")
        target = _cruise_end(pos, cruise, v_inj, t_ramp)
        moves.append(mv(target, v_inj, a_mv, dwell))
        sine_legs.append((f, cruise))
        seg_moves.append((f"sine {f:g} Hz", "stepped sine on a cruise (frequency response at one frequency)",
                          {"frequency_hz": f, "speed": v_inj}, 1))
        pos = target
    moves.append(mv(0.0, 0.5 * speeds[-1], a_mv, dwell))
    seg_moves.append(("return", "back to the start position", {}, 1))
    return _Moves(moves, seg_moves, sine_legs, u_bump, t_ramp, a_mv, light, heavy)


def _move_ends(moves: list[Move]) -> list[tuple[float, float, float]]:
    """Each move's (end time [s], S-curve duration [s], dwell [s]) from the start at 0."""
    ends = []
    t = 0.0
    x = 0.0
    for m in moves:
        dur, _j, _vp, _ap = scurve_segments(m.to - x, m.v_max, m.a_max, m.j_max)
        t += sum(dur) + m.dwell
        ends.append((t, sum(dur), m.dwell))
        x = m.to
    return ends


def design_plan(spec: ExciteSpec, *, injection_scale: float = 1.0, motion_scale: float = 1.0,
                injection_speed: float | None = None) -> Plan:
    """The plan's segments and samples (no pre-simulation: :func:`plan_run` does both).

    Parameters
    ----------
    spec : ExciteSpec
    injection_scale : float
        Fraction of the designed injection (and bump) amplitude (the pre-simulation lowers it).
    motion_scale : float
        Fraction of the designed top speed and acceleration of the moves (the pre-simulation lowers it).
    injection_speed : float, optional
        Cruise of the injection and stepped-sine legs, q/s (default: :func:`injection_speed_bounds`'s
        first; the pre-simulation raises it).
    """
    p = spec.plan
    fs = spec.sample_rate
    legs = _plan_moves(spec, injection_scale, motion_scale, injection_speed)
    moves, seg_moves, sine_legs, u_bump, t_ramp = (legs.moves, legs.seg_moves, legs.sine_legs, legs.u_bump,
                                                   legs.t_ramp)
    a_mv, light, heavy = legs.a_mv, legs.light, legs.heavy
    sched, _move_peaks = scurve_schedule(moves, start=0.0)
    ends = _move_ends(moves)  # each move's S-curve phases plus its dwell
    total = ends[-1][0]
    n = int(math.floor(total * fs)) + 1
    tt = np.arange(n) / fs
    qr, vr, ar = sched.sample(tt)
    u_inj = np.zeros(n)
    segments: list[Segment] = []
    i = 0
    t0 = 0.0
    inj_amp = injection_scale * p["injection_fraction"] * min(light * spec.a_max,
                                                             spec.u_max - (spec.friction or 0.0) - a_mv * heavy)
    inj_amp = max(inj_amp, 0.0)
    inj_mask = np.zeros(n, bool)
    sine_k = 0
    for name, purpose, info, count in seg_moves:
        t1 = ends[i + count - 1][0]
        info = dict(info)
        if name == "bump":
            tb = info["pulse_s"]
            k0, nb = int(round(0.1 * fs)), max(int(round(tb * fs)), 1)  # whole samples: zero net impulse
            u_inj[k0:k0 + nb], u_inj[k0 + nb:k0 + 2 * nb] = u_bump, -u_bump
        if name == "injection" or name.startswith("sine "):
            # the cruise of each leg: after its ramp, before its decel ramp
            windows = []
            for j in range(i, i + count):
                te, dmove, dw = ends[j]
                ts_ = te - dw - dmove
                ramp = t_ramp
                a_, b_ = ts_ + ramp, te - dw - ramp
                m = (tt >= a_) & (tt < b_)
                windows.append([float(a_), float(b_)])
                if name == "injection":
                    inj_mask |= m
                else:
                    f = sine_legs[sine_k][0]
                    u_inj[m] = inj_amp * np.sin(2 * np.pi * f * (tt[m] - a_))
            if name.startswith("sine "):
                sine_k += 1
            info["amplitude"] = inj_amp
            info["windows_s"] = windows
        segments.append(Segment(name, purpose, float(t0), float(t1), info))
        t0 = t1
        i += count
    k = int(np.count_nonzero(inj_mask))
    if k:
        sig = _multisine(k, fs, p["band_hz"], p["shaping"]) if p["injection"] == "multisine" else _prbs(k)
        u_inj[inj_mask] = inj_amp * sig
    return Plan(t=tt, q_ref=qr, v_ref=vr, a_ref=ar, u_inject=u_inj, segments=tuple(segments), spec=spec,
                injection_scale=injection_scale, motion_scale=motion_scale)


# --------------------------------------------------------------------------- pre-simulation
