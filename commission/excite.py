"""``commission excite``: design the excitation run from the machine's limits, and prove it safe.

One recorded run should back everything ``identify`` reports, so the plan is a
sequence of segments, each made for one purpose:

* ``bump`` (only without ``[axis] mass``): a short command doublet at rest, held by
  the drive's loop, from which the mass can be read before anything larger runs;
* ``ladder``: a friction ladder, constant-velocity legs at log-spaced speeds, each
  forward and then back over the same stretch (ripple and offset cancel between the
  two directions), for the Stribeck curve, B and the friction map;
* ``moves``: back-and-forth S-curve moves (:func:`commission.controllers.trajectory.scurve_schedule`)
  at the largest acceleration the command budget allows, for M;
* ``injection``: a broadband command added to the holding loop's while the axis
  cruises slowly (friction keeps one sign): a Schroeder-phase multisine whose line
  amplitudes rise as ``f**shaping`` over ``band_hz``, or a PRBS of one bit per sample,
  for the frequency response, the modes and the delay;
* ``sine``: optionally, a stepped sine at chosen frequencies, on slow cruises too.

Every move is an S-curve of the project's trajectory generator; the position stays
within ``+-(1 - margin) travel / 2`` of the start.

Pre-simulation
--------------
The plan is played, before anything is written, through the holding loop of
``[drive]`` on a *conservative* rigid model: two masses bracket the axis (the given
``mass`` divided and multiplied by ``plan.mass_range``; without a mass, the heaviest
axis that still reaches ``a_max`` with ``u_max`` and that divided by ``5 mass_range``),
friction and viscous damping from ``[axis]`` when given, no quantization.  The loop is
the one of the synthetic logs (:func:`commission.synth._closed_loop`, a PID with the
derivative on the backward-difference velocity).  The command is not clipped in the
pre-simulation, so that its peak is seen.  Peak ``|u|``, the position range, peak
``|v|`` (backward difference) and peak ``|a|`` (second difference) are checked against
``[limits]``.  A broken limit in an injection segment (or the bump) lowers the
injection, one in another segment the moves' top speed and acceleration, by 0.9 times
the limit over the peak (by 5 % to a half; up to :data:`MAX_INJECTION_RETRIES` retries
in all); a loop that diverges, or a limit still broken, and the plan is refused naming
the limit, the segment and the model.

The band the plan will back
---------------------------
:func:`predict_band` says, before the machine time is spent, up to which frequency a recording
of the plan will back the model: the injection's spectrum on identify's bins against the
encoder's floor (``[axis] encoder_step``, ``encoder_noise``), through the holding loop on the
rigid model, gives the expected coherence, and identify's own band rule
(:func:`commission.identify.frf.backed_band`) the band.  Against ``[evidence] target_hz`` (or
1.5 times ``first_mode_hz``) a short band is warned with what would reach the target
(:func:`band_lines`).

:func:`simulate_plan` plays a plan on a known-truth :class:`commission.synth.AxisTruth`
through the same loop and returns a log in the CONTRACT §1 format (tests, sample data).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from commission.controllers.trajectory import Move, scurve_schedule, scurve_segments
from commission.errors import SchemaError, SpecError
from commission.files import read_toml

PLAN_SCHEMA_VERSION = 1
#: Pre-simulation: how often the injection is lowered before a plan is refused.
MAX_INJECTION_RETRIES = 4
#: Largest accepted 2 pi bandwidth_hz / sample_rate (Åström & Wittenmark's omega h <= 0.5, as spec.py).
MAX_OMEGA_T = 0.5
#: Damping ratio assumed for a loop given by its bandwidth.
LOOP_DAMPING = 0.7
#: Plant sub-steps per sample of the pre-simulation.
PRESIM_SUBSTEPS = 4
#: Accepted values of the unit keys.
Q_UNITS = ("m", "rad")
U_UNITS = ("V", "N", "A", "Nm", "%")
INJECTIONS = ("multisine", "prbs")

# section -> key -> (kind, default, rule, unit); kind: "f" float, "i" int, "s" str, "fl" list of floats.
# rule: "pos" > 0, "nonneg" >= 0, "frac" in (0, 1), None.  Default None: required or derived.
_REQUIRED = object()
_SCHEMA: dict[str, dict[str, tuple[str, Any, str | None, str]]] = {
    "limits": {
        "travel": ("f", _REQUIRED, "pos", "{q}"),
        "v_max": ("f", _REQUIRED, "pos", "{q}/s"),
        "a_max": ("f", _REQUIRED, "pos", "{q}/s^2"),
        "u_max": ("f", _REQUIRED, "pos", "{u}"),
    },
    "drive": {
        "sample_rate": ("f", _REQUIRED, "pos", "Hz"),
        "bandwidth_hz": ("f", None, "pos", "Hz"),
        "kp": ("f", None, "pos", "{u}/{q}"),
        "kd": ("f", None, "nonneg", "{u} s/{q}"),
        "ki": ("f", None, "nonneg", "{u}/({q} s)"),
    },
    "axis": {
        "mass": ("f", None, "pos", "{u} s^2/{q}"),
        "friction": ("f", None, "nonneg", "{u}"),
        "viscous": ("f", None, "nonneg", "{u} s/{q}"),
        "q_unit": ("s", "m", None, ""),
        "u_unit": ("s", "V", None, ""),
        "encoder_step": ("f", None, "pos", "{q}"),
        "encoder_noise": ("f", None, "nonneg", "{q}"),
    },
    "evidence": {
        "target_hz": ("f", None, "pos", "Hz"),
        "first_mode_hz": ("f", None, "pos", "Hz"),
    },
    "plan": {
        "n_speeds": ("i", 8, "pos", ""),
        "v_min": ("f", None, "pos", "{q}/s"),
        "leg_time": ("f", 1.0, "pos", "s"),
        "min_cruise": ("f", 0.2, "pos", "s"),
        "moves": ("i", 6, "pos", ""),
        "dwell": ("f", 0.2, "nonneg", "s"),
        "jerk_time": ("f", 0.02, "pos", "s"),
        "injection": ("s", "prbs", None, ""),
        "injection_s": ("f", 8.0, "pos", "s"),
        "injection_fraction": ("f", 0.5, "frac", ""),
        "band_hz": ("fl", None, None, "Hz"),
        "shaping": ("f", 1.0, None, ""),
        "stepped_sine_hz": ("fl", (), None, "Hz"),
        "sine_cycles": ("f", 20.0, "pos", ""),
        "margin": ("f", 0.1, "frac", ""),
        "mass_range": ("f", 2.0, "pos", ""),
    },
}
_CHOICES = {("axis", "q_unit"): Q_UNITS, ("axis", "u_unit"): U_UNITS, ("plan", "injection"): INJECTIONS}


@dataclass(frozen=True)
class ExciteSpec:
    """A validated ``limits.toml`` (every default resolved; see docs/interface.md).

    Units: ``q`` is m on a linear axis, rad on a rotary one (``q_unit``); ``u`` is ``u_unit``.

    Attributes
    ----------
    travel, v_max, a_max, u_max : float
        ``[limits]``: the whole span the run may use (q), peak speed (q/s), peak
        acceleration (q/s^2), peak command (u).
    sample_rate : float
        Drive rate, Hz; the plan has one row per sample.
    bandwidth_hz : float or None
        Bandwidth of the holding position loop, Hz (gains ``kp = M w^2``, ``kd = 2 * 0.7 M w``,
        ``ki = kp 2 pi bandwidth_hz / 10`` on the model's mass).
    kp, kd, ki : float or None
        The holding loop's gains instead: u/q, u s/q, u/(q s).
    mass, friction, viscous : float or None
        ``[axis]`` rough guesses: u s^2/q, u (Coulomb level), u s/q.
    q_unit, u_unit : str
    encoder_step, encoder_noise : float or None
        ``[axis]``: the encoder's resolution and its rms noise, q (None: 1 um step and no noise
        assumed by :func:`predict_band`, which says so).
    target_band_hz, first_mode_hz : float or None
        ``[evidence] target_hz``: the top of the band the recording must back, Hz (e.g. 1.5 times
        the intended crossover); ``[evidence] first_mode_hz``: the lowest structural mode known or
        expected, Hz (the band must then reach 1.5 times it).
    plan : dict
        ``[plan]`` options with defaults resolved.
    """

    travel: float
    v_max: float
    a_max: float
    u_max: float
    sample_rate: float
    bandwidth_hz: float | None = None
    kp: float | None = None
    kd: float | None = None
    ki: float | None = None
    mass: float | None = None
    friction: float | None = None
    viscous: float | None = None
    q_unit: str = "m"
    u_unit: str = "V"
    encoder_step: float | None = None
    encoder_noise: float | None = None
    target_band_hz: float | None = None
    first_mode_hz: float | None = None
    plan: Mapping[str, Any] = field(default_factory=dict)
    source: str = "limits.toml"

    def to_dict(self) -> dict[str, Any]:
        """The spec as plan.json's ``spec`` (every key, ``null`` when not given)."""
        return {
            "limits": {"travel": self.travel, "v_max": self.v_max, "a_max": self.a_max, "u_max": self.u_max},
            "drive": {"sample_rate": self.sample_rate, "bandwidth_hz": self.bandwidth_hz, "kp": self.kp,
                      "kd": self.kd, "ki": self.ki},
            "axis": {"mass": self.mass, "friction": self.friction, "viscous": self.viscous,
                     "q_unit": self.q_unit, "u_unit": self.u_unit, "encoder_step": self.encoder_step,
                     "encoder_noise": self.encoder_noise},
            "evidence": {"target_hz": self.target_band_hz, "first_mode_hz": self.first_mode_hz},
            "plan": {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.plan.items()},
        }


def excite_spec_from_mapping(data: Mapping[str, Any], source: str = "limits.toml") -> ExciteSpec:
    """Validate a parsed ``limits.toml``; every error is one :class:`SpecError` line naming the key.

    Raises
    ------
    SpecError
        An unknown section or key, a wrong type, a missing required key, a value out of its
        range, ``bandwidth_hz`` together with gains (or neither), a sample rate too low for the
        bandwidth, ``friction`` not below ``u_max``, a band outside (0, Nyquist).
    """
    def fail(path: str, msg: str) -> SpecError:
        return SpecError(f"{source}: {path}{msg}")

    if not isinstance(data, Mapping):
        raise fail("", f"expected a table, got {type(data).__name__}")
    q_unit = data.get("axis", {}).get("q_unit", "m") if isinstance(data.get("axis"), Mapping) else "m"
    u_unit = data.get("axis", {}).get("u_unit", "V") if isinstance(data.get("axis"), Mapping) else "V"
    q_unit = q_unit if q_unit in Q_UNITS else "m"
    u_unit = u_unit if u_unit in U_UNITS else "V"
    vals: dict[tuple[str, str], Any] = {}
    for section, table in data.items():
        if section not in _SCHEMA:
            raise fail(section, f": unknown section (known: {', '.join(_SCHEMA)})")
        if not isinstance(table, Mapping):
            raise fail(section, f": expected a table, got {table!r}")
        for key, raw in table.items():
            path = f"{section}.{key}"
            if key not in _SCHEMA[section]:
                raise fail(path, f": unknown key (known in [{section}]: {', '.join(_SCHEMA[section])})")
            kind, _d, rule, unit = _SCHEMA[section][key]
            un = unit.format(q=q_unit, u=u_unit)
            u = f" {un}" if un else ""
            if kind == "s":
                if raw not in _CHOICES[(section, key)]:
                    raise fail(path, f" = {raw!r}: expected one of {', '.join(map(repr, _CHOICES[(section, key)]))}")
                vals[(section, key)] = raw
                continue
            if kind == "fl":
                if not isinstance(raw, list) or not all(
                        not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x) and x > 0
                        for x in raw):
                    raise fail(path, f" = {raw!r}: expected a list of positive numbers{u and ' in' + u}")
                vals[(section, key)] = tuple(float(x) for x in raw)
                continue
            if kind == "i":
                if isinstance(raw, bool) or not isinstance(raw, int):
                    raise fail(path, f" = {raw!r}: expected an integer")
                val: Any = int(raw)
            else:
                if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
                    raise fail(path, f" = {raw!r}: expected a finite number{u and ' in' + u}")
                val = float(raw)
            if rule == "pos" and not val > 0:
                raise fail(path, f" = {val!r}{u} must be positive")
            if rule == "nonneg" and val < 0:
                raise fail(path, f" = {val!r}{u} must not be negative")
            if rule == "frac" and not 0 < val < 1:
                raise fail(path, f" = {val!r} must be between 0 and 1")
            vals[(section, key)] = val
    for section, keys in _SCHEMA.items():
        for key, (_k, default, _r, _u) in keys.items():
            if default is _REQUIRED and (section, key) not in vals:
                raise fail(f"{section}.{key}", f": missing (required in [{section}])")
    g = lambda s, k: vals.get((s, k), None if _SCHEMA[s][k][1] is _REQUIRED else _SCHEMA[s][k][1])  # noqa: E731
    fs = g("drive", "sample_rate")
    has_bw = ("drive", "bandwidth_hz") in vals
    gains = [k for k in ("kp", "kd", "ki") if ("drive", k) in vals]
    if has_bw and gains:
        raise fail(f"drive.{gains[0]}", ": give either drive.bandwidth_hz or the gains kp, kd (ki), not both")
    if not has_bw and not gains:
        raise fail("drive", ": give the holding loop: bandwidth_hz (Hz), or kp and kd (and ki)")
    if gains and not {"kp", "kd"} <= set(gains):
        missing = "kp" if "kp" not in gains else "kd"
        raise fail(f"drive.{missing}", ": missing (the gains need kp and kd; ki defaults to 0)")
    if has_bw and 2 * math.pi * g("drive", "bandwidth_hz") / fs > MAX_OMEGA_T:
        raise fail("drive.sample_rate", f" = {fs:g} Hz is too low for drive.bandwidth_hz = "
                   f"{g('drive', 'bandwidth_hz'):g} Hz (need >= {2 * math.pi * g('drive', 'bandwidth_hz') / MAX_OMEGA_T:g} Hz:"
                   f" omega*T <= {MAX_OMEGA_T:g})")
    fr, umax = g("axis", "friction"), g("limits", "u_max")
    if fr is not None and fr >= umax:
        raise fail("axis.friction", f" = {fr:g} {u_unit} is not below limits.u_max = {umax:g} {u_unit}: "
                   "no motion is possible within u_max")
    plan = {k: g("plan", k) for k in _SCHEMA["plan"]}
    nyq = fs / 2.0
    band = plan["band_hz"]
    if band is None:
        band = (min(2.0, 0.01 * nyq), 0.8 * nyq)
    elif len(band) != 2 or not band[0] < band[1]:
        raise fail("plan.band_hz", f" = {list(band)!r}: expected [low, high] Hz with low < high")
    if band[1] >= nyq:
        raise fail("plan.band_hz", f" = {list(band)!r} Hz: the top must be below Nyquist, {nyq:g} Hz")
    plan["band_hz"] = tuple(float(b) for b in band)
    for f in plan["stepped_sine_hz"]:
        if f >= nyq:
            raise fail("plan.stepped_sine_hz", f": {f:g} Hz is not below Nyquist, {nyq:g} Hz")
    vmin = plan["v_min"]
    if vmin is not None and vmin >= g("limits", "v_max"):
        raise fail("plan.v_min", f" = {vmin:g} {q_unit}/s is not below limits.v_max = {g('limits', 'v_max'):g} {q_unit}/s")
    if plan["mass_range"] < 1.0:
        raise fail("plan.mass_range", f" = {plan['mass_range']:g} must be >= 1")
    return ExciteSpec(
        travel=g("limits", "travel"), v_max=g("limits", "v_max"), a_max=g("limits", "a_max"), u_max=umax,
        sample_rate=fs, bandwidth_hz=g("drive", "bandwidth_hz"), kp=g("drive", "kp"), kd=g("drive", "kd"),
        ki=(g("drive", "ki") or 0.0) if gains else None, mass=g("axis", "mass"), friction=fr,
        viscous=g("axis", "viscous"), q_unit=g("axis", "q_unit"), u_unit=g("axis", "u_unit"),
        encoder_step=g("axis", "encoder_step"), encoder_noise=g("axis", "encoder_noise"),
        target_band_hz=g("evidence", "target_hz"), first_mode_hz=g("evidence", "first_mode_hz"), plan=plan,
        source=source)


def load_excite_spec(path: str | os.PathLike[str]) -> ExciteSpec:
    """Read and validate ``limits.toml`` (:func:`excite_spec_from_mapping`)."""
    return excite_spec_from_mapping(read_toml(path), os.fspath(path))


# --------------------------------------------------------------------------- the plan


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


def design_plan(spec: ExciteSpec, *, injection_scale: float = 1.0, motion_scale: float = 1.0) -> Plan:
    """The plan's segments and samples (no pre-simulation: :func:`plan_run` does both).

    Parameters
    ----------
    spec : ExciteSpec
    injection_scale : float
        Fraction of the designed injection (and bump) amplitude (the pre-simulation lowers it).
    motion_scale : float
        Fraction of the designed top speed and acceleration of the moves (the pre-simulation lowers it).
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
    # Slow cruises for the injection, just past stiction: a quarter of the way (in log) from the ladder's
    # slowest speed to its fastest, whatever the number of speeds; both directions.
    v_inj = float(speeds[0] * (speeds[-1] / speeds[0]) ** 0.25)
    t_ramp = _ramp_time(v_inj, a_mv, a_mv / jt)
    inj_legs = []
    remaining = p["injection_s"]
    while remaining > 1e-9:
        # toward the farther end of the span: the room there is s + |pos|
        d_max = s + abs(pos) - v_inj * t_ramp
        cruise = min(remaining, d_max / v_inj)
        if cruise < 0.1:
            raise SpecError(f"{spec.source}: limits.travel = {spec.travel:g} {spec.q_unit} is too short for the "
                            f"injection's cruise at {v_inj:.4g} {spec.q_unit}/s (0.1 s at least); raise travel or "
                            f"lower plan.v_min")
        target = pos + (-1 if pos > 0 else 1) * (cruise * v_inj + v_inj * t_ramp)
        inj_legs.append(mv(target, v_inj, a_mv, dwell))
        pos = target
        remaining -= cruise
        if len(inj_legs) > 200:
            break
    moves += inj_legs
    seg_moves.append(("injection", "broadband injection on slow cruises (frequency response, modes, delay)",
                      {"speed": v_inj, "kind": p["injection"], "band_hz": list(p["band_hz"])
                       if p["injection"] == "multisine" else [0.0, fs / 2.0],
                       "shaping": p["shaping"] if p["injection"] == "multisine" else 0.0}, len(inj_legs)))
    sine_legs = []
    for f in p["stepped_sine_hz"]:
        cruise = max(p["sine_cycles"] / f, 0.1)
        d_max = s + abs(pos) - v_inj * t_ramp
        cruise = min(cruise, d_max / v_inj)
        if cruise < 0.1:
            raise SpecError(f"{spec.source}: limits.travel = {spec.travel:g} {spec.q_unit} is too short for the "
                            f"stepped sine at {f:g} Hz on a cruise at {v_inj:.4g} {spec.q_unit}/s (0.1 s at least)")
        target = pos + (-1 if pos > 0 else 1) * (cruise * v_inj + v_inj * t_ramp)
        moves.append(mv(target, v_inj, a_mv, dwell))
        sine_legs.append((f, cruise))
        seg_moves.append((f"sine {f:g} Hz", "stepped sine on a slow cruise (frequency response at one frequency)",
                          {"frequency_hz": f, "speed": v_inj}, 1))
        pos = target
    moves.append(mv(0.0, 0.5 * speeds[-1], a_mv, dwell))
    seg_moves.append(("return", "back to the start position", {}, 1))

    sched, _move_peaks = scurve_schedule(moves, start=0.0)
    # Move boundaries: each move's S-curve phases plus its dwell.
    ends = []
    t = 0.0
    x = 0.0
    for m in moves:
        dur, _j, _vp, _ap = scurve_segments(m.to - x, m.v_max, m.a_max, m.j_max)
        t += sum(dur) + m.dwell
        ends.append((t, sum(dur), m.dwell))
        x = m.to
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


def _model_truth(spec: ExciteSpec, M: float, *, lsb: float = 1e-12, u_max: float | None = None):
    from commission.synth import AxisTruth

    fc = spec.friction or 0.0
    return AxisTruth(M=M, B=spec.viscous or 0.0, fc=fc, fs=fc, vs=0.01, xi=2.0, lsb=lsb,
                     sample_rate=spec.sample_rate, u_max=u_max if u_max is not None else 1e6 * spec.u_max)


def play(plan: Plan, truth: Any, gains: tuple[float, float, float], rng: np.random.Generator | None = None,
         substeps: int = PRESIM_SUBSTEPS) -> dict[str, np.ndarray]:
    """Play ``plan`` on ``truth`` through the holding loop (PID on the reference, ``u_inject`` added).

    Returns
    -------
    dict
        ``t`` (s), ``q`` (q, the encoder's reading), ``u`` (u: the whole command, clipped at
        ``truth.u_max``), ``q_ref`` (q): a CONTRACT §1 log.
    """
    from commission.synth import _closed_loop

    n = plan.t.size
    noise = rng.normal(0.0, truth.noise_std, n) if (rng is not None and truth.noise_std > 0) else np.zeros(n)
    q = np.empty(n)
    u = np.empty(n)
    kp, kd, ki = gains
    _closed_loop(truth.plant(), plan.q_ref, plan.v_ref, plan.u_inject, noise, truth.lsb, truth.period,
                 int(substeps), kp, kd, ki, truth.u_max, q, u)
    return {"t": plan.t.copy(), "q": q, "u": u, "q_ref": plan.q_ref.copy()}


def simulate_plan(plan: Plan, truth: Any, rng: np.random.Generator, *, substeps: int = 10) -> dict[str, np.ndarray]:
    """Record ``plan`` on a known-truth axis (:class:`commission.synth.AxisTruth`).

    The holding loop is the plan's ``[drive]``: its gains, or the bandwidth designed on the
    true mass (as a drive tuned to its axis).  ``truth.sample_rate`` must be the plan's.

    Returns
    -------
    dict
        A CONTRACT §1 log (``t``, ``q``, ``u``, ``q_ref``), for :func:`commission.synth.write_log_h5`.
    """
    if abs(truth.sample_rate - plan.spec.sample_rate) > 1e-9 * plan.spec.sample_rate:
        raise ValueError(f"simulate_plan: truth.sample_rate = {truth.sample_rate} Hz, the plan's is "
                         f"{plan.spec.sample_rate} Hz")
    return play(plan, truth, loop_gains_for(plan.spec, truth.M), rng, substeps)


def _peaks(log: Mapping[str, np.ndarray], T: float) -> dict[str, np.ndarray]:
    q = log["q"]
    v = np.zeros_like(q)
    v[1:] = np.diff(q) / T
    a = np.zeros_like(q)
    a[2:] = np.diff(q, 2) / (T * T)
    return {"u": np.abs(log["u"]), "q": q, "v": np.abs(v), "a": np.abs(a)}


class PlanRefused(SpecError):
    """The limits cannot be met by any plan, or the pre-simulation breaks one."""


def presimulate(plan: Plan) -> tuple[dict[str, float], list[dict[str, float]], str | None]:
    """Play the plan on the conservative models; return (peaks, models, first violation or None)."""
    return _presimulate(plan)[:3]


def _presimulate(plan: Plan) -> tuple[dict[str, float], list[dict[str, float]], str | None, float]:
    """:func:`presimulate`, and the broken limit over its peak (1 when none is broken)."""
    s = plan.spec
    T = 1.0 / s.sample_rate
    half = s.travel / 2.0
    peaks = {"u": 0.0, "q_min": 0.0, "q_max": 0.0, "v": 0.0, "a": 0.0}
    models = []
    violation = None
    ratio = 1.0
    for label, M in zip(("light", "heavy"), mass_bracket(s)):
        gains = loop_gains_for(s, M)
        truth = _model_truth(s, M)
        log = play(plan, truth, gains)
        pk = _peaks(log, T)
        # The pre-simulation clips the command at 1e6 u_max only: a command past 1e5 u_max is a loop
        # that diverges, not a plan that asks too much.
        runaway = np.flatnonzero(~np.isfinite(pk["u"]) | (pk["u"] >= 1e5 * s.u_max))
        bad = int(runaway[0]) if runaway.size else None
        models.append({"label": label, "M": M, "B": s.viscous or 0.0, "fc": s.friction or 0.0,
                       "kp": gains[0], "kd": gains[1], "ki": gains[2]})
        peaks["u"] = max(peaks["u"], float(np.max(pk["u"])))
        peaks["q_min"] = min(peaks["q_min"], float(np.min(pk["q"])))
        peaks["q_max"] = max(peaks["q_max"], float(np.max(pk["q"])))
        peaks["v"] = max(peaks["v"], float(np.max(pk["v"])))
        peaks["a"] = max(peaks["a"], float(np.max(pk["a"])))
        if violation is not None:
            continue
        checks = [("limits.u_max", pk["u"], s.u_max, s.u_unit),
                  ("limits.travel", np.abs(pk["q"]), half, s.q_unit),
                  ("limits.v_max", pk["v"], s.v_max, f"{s.q_unit}/s"),
                  ("limits.a_max", pk["a"], s.a_max, f"{s.q_unit}/s^2")]
        if bad is not None:
            k = int(np.flatnonzero(pk["u"] > s.u_max)[0]) if np.any(pk["u"] > s.u_max) else bad
            tk = float(plan.t[k])
            seg = next((g.name for g in plan.segments if g.t_start <= tk < g.t_end), plan.segments[-1].name)
            violation = (f"limits.u_max: the holding loop diverges on the {label} model (M = {M:.4g} "
                         f"{s.u_unit} s^2/{s.q_unit}): |u| passes u_max in segment '{seg}' at t = {tk:.4g} s "
                         f"(sample {k}) and grows without bound; check [drive] (its gains) or [axis] mass")
            continue
        for key, x, lim, unit in checks:
            over = np.flatnonzero(x > lim)
            if over.size:
                k = int(over[0])
                tk = float(plan.t[k])
                seg = next((g.name for g in plan.segments if g.t_start <= tk < g.t_end), plan.segments[-1].name)
                what = "|q - start|" if key == "limits.travel" else f"|{key[7]}|"
                lim_s = f"{lim:.4g} {unit}" + (" (travel / 2)" if key == "limits.travel" else "")
                ratio = min(ratio, lim / float(np.max(x)))
                violation = (f"{key}: the pre-simulation breaks it in segment '{seg}' at t = {tk:.4g} s "
                             f"(sample {k}): {what} = {float(np.max(x)):.4g} {unit} > {lim_s}, on the {label} "
                             f"model (M = {M:.4g} {s.u_unit} s^2/{s.q_unit})")
                break
    return peaks, models, violation, ratio


def plan_run(spec: ExciteSpec, progress: Any = None) -> Plan:
    """Design the plan and pre-simulate it, lowering the injection (or the moves) while it breaks a limit.

    Raises
    ------
    PlanRefused
        No plan keeps within the limits (named, with the segment).
    """
    scale = motion = 1.0
    for attempt in range(MAX_INJECTION_RETRIES + 1):
        try:
            plan = design_plan(spec, injection_scale=scale, motion_scale=motion)
        except SpecError:
            if attempt == 0:
                raise
            break  # slower moves no longer fit the travel: refuse with the violation that asked for them
        if progress is not None:
            progress(f"pre-simulating {plan.duration:.1f} s of plan (attempt {attempt + 1}) ...")
        peaks, models, violation, ratio = _presimulate(plan)
        if violation is None:
            done = Plan(t=plan.t, q_ref=plan.q_ref, v_ref=plan.v_ref, a_ref=plan.a_ref, u_inject=plan.u_inject,
                        segments=plan.segments, spec=spec, models=tuple(models), peaks=peaks, injection_scale=scale,
                        motion_scale=motion)
            return dataclasses.replace(done, prediction=predict_band(done))
        if "diverges" in violation:
            break
        injected = any(g.name in ("injection", "bump") or g.name.startswith("sine ") for g in plan.segments
                       if f"segment '{g.name}'" in violation)
        # Lower the injection, or else the moves' speed and acceleration, in proportion to the excess
        # (at least by 5 %, at most by half).
        step = min(max(0.9 * ratio, 0.5), 0.95)
        if injected:
            scale *= step
        else:
            motion *= step
    raise PlanRefused(f"{spec.source}: plan refused: {violation}")


# --------------------------------------------------------------------------- the band the plan will back


#: Encoder assumed when ``[axis] encoder_step`` is not given: a 1 um (or 1 urad) scale, q-unit.
ASSUMED_ENCODER_STEP = 1e-6
#: The target band is this many times ``[evidence] first_mode_hz`` (must show 1 of issue 31).
MODE_BAND_FACTOR = 1.5


@dataclass(frozen=True)
class BandPrediction:
    """The band a recording of the plan is expected to back, before it is run (:func:`predict_band`).

    Attributes
    ----------
    f_hz : ndarray
        identify's analysis bins over the injection windows, Hz.
    coherence : ndarray
        Expected coherence u -> q per bin (1).
    band_hz : (float, float) or None
        The band of :func:`commission.identify.frf.backed_band` on the expected coherence, Hz.
    n_averages : int
        Welch windows identify will average.
    resolution_hz : float
        Bin spacing, Hz.
    mass : float
        Mass of the rigid model predicted on, u s^2/q.
    encoder_step, encoder_noise : float
        The encoder floor used, q-unit (step, rms noise), and whether each was given.
    floor_psd : float
        One-sided density of the floor, q^2/Hz.
    target_hz : float or None
        The band's top that is needed, Hz, and ``target_source`` what set it.
    """

    f_hz: np.ndarray
    coherence: np.ndarray
    band_hz: tuple[float, float] | None
    n_averages: int
    resolution_hz: float
    mass: float
    encoder_step: float
    encoder_noise: float
    step_given: bool
    noise_given: bool
    floor_psd: float
    target_hz: float | None = None
    target_source: str | None = None
    remedies: Mapping[str, Any] = field(default_factory=dict)

    @property
    def top_hz(self) -> float:
        """Top of the predicted band, Hz (0: none)."""
        return float(self.band_hz[1]) if self.band_hz is not None else 0.0

    @property
    def short(self) -> bool:
        """The predicted band falls short of the target."""
        return self.target_hz is not None and self.top_hz < self.target_hz

    def to_dict(self, q_unit: str, u_unit: str) -> dict[str, Any]:
        """plan.json's ``predicted_band`` (additive key)."""
        return {
            "band_hz": list(self.band_hz) if self.band_hz is not None else None,
            "target_hz": self.target_hz, "target_source": self.target_source, "short": self.short,
            "n_averages": int(self.n_averages), "resolution_hz": self.resolution_hz, "mass": self.mass,
            "encoder_step": self.encoder_step, "encoder_noise": self.encoder_noise,
            "encoder_step_assumed": not self.step_given, "encoder_noise_assumed": not self.noise_given,
            "floor_psd": self.floor_psd, "remedies": dict(self.remedies),
            "rule": "expected coherence of the closed-loop H1 estimate >= BAND_COHERENCE (identify's band rule, "
                    "commission.identify.frf.backed_band) on the rigid model of [axis] mass",
            "units": {"band_hz": "Hz", "target_hz": "Hz", "resolution_hz": "Hz", "mass": f"{u_unit} s^2/{q_unit}",
                      "encoder_step": q_unit, "encoder_noise": f"{q_unit} rms", "floor_psd": f"{q_unit}^2/Hz"},
        }


def _nominal_mass(spec: ExciteSpec) -> float:
    if spec.mass is not None:
        return float(spec.mass)
    light, heavy = mass_bracket(spec)
    return math.sqrt(light * heavy)


def _injection_psd(plan: Plan) -> tuple[np.ndarray, np.ndarray, int]:
    """identify's bins, the injection's one-sided density on them (u^2/Hz) and the number of windows."""
    from scipy import signal

    from commission.identify.frf import RESOLUTION_HZ

    fs = plan.spec.sample_rate
    ranges = injection_ranges({"segments": [g.to_dict() for g in plan.segments]}, plan.t)
    nper = int(round(fs / RESOLUTION_HZ))
    while nper > 32 and sum(max(0, 1 + ((b - a) - nper) // (nper - nper // 2)) for a, b in ranges) < 8:
        nper //= 2  # as identify.frf.frequency_response: at least 8 windows in all
    step = nper - nper // 2
    acc, n_avg, f = 0.0, 0, None
    for a, b in ranges:
        if b - a < nper:
            continue
        k = 1 + (b - a - nper) // step
        f, p = signal.welch(plan.u_inject[a:b], fs=fs, window="hann", nperseg=nper, noverlap=nper // 2,
                            detrend="linear")
        acc = acc + k * p
        n_avg += k
    if f is None:
        return np.zeros(0), np.zeros(0), 0
    keep = (f > 0) & (f < fs / 2.0)
    return f[keep], np.asarray(acc)[keep] / n_avg, n_avg


def expected_coherence(f_hz: np.ndarray, psd_inject: np.ndarray, floor_psd: float, M: float, B: float,
                       gains: tuple[float, float, float], fs: float, n_averages: int
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Expected coherence of identify's H1 estimate u -> q in the holding loop, and its ratio to the model.

    Returns ``(gamma^2, R)`` per bin: ``R = E[H1] / P`` with
    ``E[H1] = (P Pii - conj(C) Pnn) / (Pii + |C|^2 Pnn)``, which tends to ``-1 / C`` where the
    loop's answer to the noise dominates the command (coherent, but not the plant: identify's band
    rule ends the band there by the model's disagreement, and so does the prediction).

    The encoder's reading is ``q_m = P u + n`` (``n``: its noise and quantization, white, one-sided
    density ``floor_psd``); the recorded command is ``u = S u_i - C S n`` with ``S = 1 / (1 + C P)``,
    ``C`` the holding loop's PID (derivative on the backward difference, as the drive's and the
    simulator's) and ``P`` the rigid body behind the zero-order hold.  Then
    ``gamma^2 = |P Pii - conj(C) Pnn|^2 / ((Pii + |C|^2 Pnn)(|P|^2 Pii + Pnn))``: the loop's answer to
    the noise is in ``u`` too, which lowers the coherence below the open-loop SNR / (1 + SNR).  The
    Welch estimate over ``n_averages`` windows is biased up by about ``(1 - gamma^2)^2 / n`` (Carter,
    Knapp & Nuttall 1973): the only place where the injection's duration enters.
    """
    from commission.controllers.linear import rigid_frequency_response

    T = 1.0 / fs
    P = rigid_frequency_response(M, B, T, f_hz)
    z1 = np.exp(-2j * np.pi * f_hz * T)
    kp, kd, ki = gains
    C = kp + kd * (1.0 - z1) / T + ki * T / (1.0 - z1)
    Pii, Pnn = np.asarray(psd_inject, float), float(floor_psd)
    num = np.abs(P * Pii - np.conj(C) * Pnn) ** 2
    den = (Pii + np.abs(C) ** 2 * Pnn) * (np.abs(P) ** 2 * Pii + Pnn)
    with np.errstate(divide="ignore", invalid="ignore"):
        g2 = np.where(den > 0, num / den, 0.0)
    g2 = np.clip(np.nan_to_num(g2), 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        R = (P * Pii - np.conj(C) * Pnn) / ((Pii + np.abs(C) ** 2 * Pnn) * P)
    R = np.where(np.isfinite(R), R, 0.0)
    return np.clip(g2 + (1.0 - g2) ** 2 / max(int(n_averages), 1), 0.0, 1.0), R


def predict_band(plan: Plan) -> BandPrediction:
    """The band a recording of ``plan`` will back, from its injection's spectrum against the encoder floor.

    The injection's density is taken on the bins identify will use (its resolution, its windows:
    :func:`injection_ranges`), the response on the rigid model of the nominal mass (``[axis] mass``,
    else the geometric mean of :func:`mass_bracket`) in the holding loop of ``[drive]``, the floor
    ``(encoder_noise^2 + encoder_step^2 / 12) * 2 / sample_rate`` (white up to Nyquist); the expected
    coherence and the expected estimate over the model (:func:`expected_coherence`) go through
    identify's own band rule (:func:`commission.identify.frf.backed_band`).  A structural mode is not
    in the model: above a motor-side mode the motor moves more than the rigid body (the band is then
    a little higher), below an anti-resonance less.

    When ``[evidence] band_hz`` or ``first_mode_hz`` sets a target the band misses, ``remedies`` holds
    what would reach it, each computed the same way: the injection's amplitude factor (and the
    ``a_max`` of the injection segment that allows it), the encoder floor's factor (the step and
    noise), and the band of a four times longer injection.
    """
    from commission.identify.frf import backed_band

    s = plan.spec
    fs = s.sample_rate
    step = s.encoder_step if s.encoder_step is not None else ASSUMED_ENCODER_STEP
    noise = s.encoder_noise if s.encoder_noise is not None else 0.0
    floor = (noise * noise + step * step / 12.0) * 2.0 / fs
    M = _nominal_mass(s)
    B = s.viscous or 0.0
    gains = loop_gains_for(s, M)
    f, Pii, n_avg = _injection_psd(plan)

    def predicted(scale_inj: float = 1.0, scale_floor: float = 1.0, n: int = n_avg):
        g2, R = expected_coherence(f, Pii * scale_inj, floor * scale_floor, M, B, gains, fs, n)
        return g2, (backed_band(f, R, g2) if f.size else None)

    def top(scale_inj: float = 1.0, scale_floor: float = 1.0, n: int = n_avg) -> tuple[np.ndarray, float]:
        g2, band = predicted(scale_inj, scale_floor, n)
        return g2, (float(band[1]) if band is not None else 0.0)

    g2, band = predicted()
    band_t = (float(band[0]), float(band[1])) if band is not None else None
    target, source = None, None
    if s.target_band_hz is not None:
        target, source = float(s.target_band_hz), "evidence.band_hz"
    if s.first_mode_hz is not None and (target is None or MODE_BAND_FACTOR * s.first_mode_hz > target):
        target, source = MODE_BAND_FACTOR * float(s.first_mode_hz), f"{MODE_BAND_FACTOR:g} x evidence.first_mode_hz"
    if target is not None:
        target = min(target, float(f[-1])) if f.size else target
    remedies: dict[str, Any] = {}
    reached = band_t[1] if band_t is not None else 0.0
    if target is not None and reached < target and f.size:
        def solve(fun) -> float | None:
            lo, hi = 0.0, math.log(1e6)
            if fun(math.exp(hi)) < target:
                return None
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if fun(math.exp(mid)) < target else (lo, mid)
            return math.exp(hi)
        k_amp = solve(lambda k: top(scale_inj=k * k)[1])
        k_floor = solve(lambda k: top(scale_floor=1.0 / (k * k))[1])
        inj = next((g for g in plan.segments if g.name == "injection"), None)
        amp = float(inj.info.get("amplitude", 0.0)) if inj is not None else 0.0
        remedies = {
            "injection_amplitude_factor": k_amp,
            "injection_amplitude": amp * k_amp if k_amp is not None else None,
            "a_max_for_injection": s.a_max * k_amp if k_amp is not None else None,
            "encoder_floor_factor": (1.0 / k_floor) if k_floor is not None else None,
            "encoder_step": step / k_floor if k_floor is not None else None,
            "encoder_noise": noise / k_floor if k_floor is not None else None,
            "longer_injection_s": 4.0 * s.plan["injection_s"],
            "longer_injection_band_top_hz": top(n=4 * n_avg)[1],
        }
    return BandPrediction(f, g2, band_t, int(n_avg), float(f[1] - f[0]) if f.size > 1 else math.nan, M,
                          step, noise, s.encoder_step is not None, s.encoder_noise is not None, floor,
                          target, source, remedies)


def band_lines(plan: Plan) -> list[str]:
    """What ``excite`` prints about the band its plan will back: the prediction, what was assumed, and a
    warning with the remedies (figures from :func:`predict_band`) when it falls short of the target."""
    pr = plan.prediction
    if pr is None:
        return []
    s = plan.spec
    q, u = s.q_unit, s.u_unit
    assumed = []
    if not pr.step_given:
        assumed.append(f"encoder_step {pr.encoder_step:g} {q}")
    if not pr.noise_given:
        assumed.append(f"encoder_noise {pr.encoder_noise:g} {q} rms")
    enc = f"encoder step {pr.encoder_step:.3g} {q}, noise {pr.encoder_noise:.3g} {q} rms"
    band = (f"{pr.band_hz[0]:.4g} - {pr.band_hz[1]:.4g} Hz" if pr.band_hz is not None else "no band")
    out = [f"predicted band the recording will back: {band} (expected coherence >= 0.8 on {pr.resolution_hz:.3g} Hz "
           f"bins, {pr.n_averages} windows; rigid model M = {pr.mass:.4g} {u} s^2/{q}; {enc})"]
    if assumed:
        out.append(f"note: assumed {', '.join(assumed)} ([axis] keys not given); give them for a sharper prediction")
    if pr.target_hz is None:
        out.append("note: no target band ([evidence] target_hz or first_mode_hz): the band is not checked")
    elif pr.short:
        r = pr.remedies
        ways = []
        if r.get("injection_amplitude_factor") is not None:
            room = s.u_max - (s.friction or 0.0)
            within = (f"within u_max {s.u_max:g} {u}" if r["injection_amplitude"] <= room else
                      f"beyond u_max {s.u_max:g} {u} less friction: not reachable by the injection alone")
            ways.append(f"an injection {r['injection_amplitude_factor']:.3g} times larger "
                        f"({r['injection_amplitude']:.4g} {u}: a_max >= {r['a_max_for_injection']:.4g} {q}/s^2 "
                        f"for the injection segment, {within})")
        if r.get("encoder_floor_factor") is not None:
            ways.append(f"an encoder floor {1 / r['encoder_floor_factor']:.3g} times lower (step "
                        f"{r['encoder_step']:.3g} {q}, noise {r['encoder_noise']:.3g} {q} rms)")
        top4 = r.get("longer_injection_band_top_hz")
        if top4 is not None:
            helps = "helps" if top4 >= pr.target_hz else ("barely helps" if top4 > pr.top_hz else "does not help")
            ways.append(f"a 4 times longer injection ({r['longer_injection_s']:g} s) reaches {top4:.4g} Hz: {helps}")
        out.append(f"warning: the plan is predicted to back the model up to {pr.top_hz:.4g} Hz, short of "
                   f"{pr.target_hz:.4g} Hz ({pr.target_source}); to reach it: " + "; ".join(ways))
    else:
        out.append(f"the predicted band reaches the target {pr.target_hz:.4g} Hz ({pr.target_source})")
    return out


# --------------------------------------------------------------------------- the limits.toml sketch


#: Holding-loop bandwidth written into a limits.toml sketch when nothing better is known, Hz.
SKETCH_BANDWIDTH_HZ = 10.0


def limits_toml_sketch(*, travel: float, v_max: float, a_max: float, u_max: float, sample_rate: float,
                       M: float | None = None, B: float | None = None, fc: float | None = None,
                       q_unit: str = "m", u_unit: str = "V", notes: Mapping[str, str] | None = None,
                       bandwidth_hz: float = SKETCH_BANDWIDTH_HZ) -> str:
    """The one builder of a ``limits.toml`` sketch for ``commission excite`` (what a log or a spec knows).

    ``identify`` (a log without a broadband segment: :func:`commission.next_steps.excite_advice`)
    and ``validate``'s evidence lines (:func:`commission.evidence.limits_toml`) both write it, so the
    file a user copies is the same whoever prints it, and :func:`excite_spec_from_mapping` accepts
    it as it is: ``[drive] bandwidth_hz`` is written (an assumption, commented: no file of this tool
    knows the holding loop), ``friction`` only below ``u_max`` (excite refuses it otherwise).  On a
    rotary axis (``q_unit = "rad"``) the identified inertia is a comment: excite's ``[axis]`` key
    carries the linear axis's name, and without it the plan starts with its bump test.

    Parameters
    ----------
    travel, v_max, a_max : float
        q, q/s, q/s^2 (q: m, or rad on a rotary axis).
    u_max : float
        u-unit.
    sample_rate : float
        Hz.
    M, B, fc : float or None
        Identified mass (u s^2/q), viscous (u s/q) and Coulomb level (u); None or out of range: left out.
    q_unit, u_unit : str
    notes : mapping of str to str, optional
        Where a value comes from, per key (``travel``, ``v_max``, ``a_max``, ``u_max``, ``sample_rate``,
        ``mass``, ``friction``, ``viscous``): written as the line's comment after its unit.
    bandwidth_hz : float
        The holding loop's bandwidth written, Hz.
    """
    qs = "rad" if q_unit == "rad" else "m"
    why = dict(notes or {})

    def line(key: str, value: float, unit: str, fmt: str = ".4g") -> str:
        note = f": {why[key]}" if key in why else ""
        return f"{key} = {value:{fmt}}  # {unit}{note}"

    lines = ["[limits]", line("travel", travel, qs), line("v_max", v_max, f"{qs}/s"),
             line("a_max", a_max, f"{qs}/s^2"), line("u_max", u_max, u_unit), "",
             "[drive]", line("sample_rate", sample_rate, "Hz", ".6g"),
             f"bandwidth_hz = {bandwidth_hz:g}  # Hz: the holding position loop's (an assumption; or give kp, kd)",
             "", "[axis]"]
    if M is not None and math.isfinite(M) and M > 0:
        if qs == "rad":
            lines.append(f"# inertia J = {M:.4g} {u_unit} s^2/rad identified (excite's [axis] key for it is optional)")
        else:
            lines.append(line("mass", M, f"{u_unit} s^2/{qs}"))
    if fc is not None and math.isfinite(fc) and 0 <= fc < u_max:
        lines.append(line("friction", fc, u_unit))
    if B is not None and math.isfinite(B) and B >= 0:
        lines.append(line("viscous", B, f"{u_unit} s/{qs}"))
    lines += [f'q_unit = "{qs}"', f'u_unit = "{u_unit}"']
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- files


PLAN_COLUMNS = ("t", "q_ref", "v_ref", "u_inject")


def plan_columns(plan: Plan) -> dict[str, np.ndarray]:
    """plan.csv's columns, in order."""
    return {"t": plan.t, "q_ref": plan.q_ref, "v_ref": plan.v_ref, "u_inject": plan.u_inject}


def write_plan_csv(path: str | os.PathLike[str], plan: Plan) -> None:
    """``t,q_ref,v_ref,u_inject``, one row per sample, 12 significant digits."""
    cols = plan_columns(plan)
    arr = np.column_stack([cols[c] for c in PLAN_COLUMNS])
    np.savetxt(path, arr, delimiter=",", header=",".join(PLAN_COLUMNS), comments="", fmt="%.12g")


def write_plan_h5(path: str | os.PathLike[str], plan: Plan) -> None:
    """The columns of plan.csv as 1-D float64 datasets at the root; units as root attributes."""
    import h5py

    with h5py.File(path, "w") as f:
        for name, col in plan_columns(plan).items():
            f.create_dataset(name, data=np.asarray(col, np.float64))
        f.attrs["q_unit"] = plan.spec.q_unit
        f.attrs["u_unit"] = plan.spec.u_unit
        f.attrs["sample_rate"] = plan.spec.sample_rate


def injection_ranges(plan: Mapping[str, Any], t: np.ndarray, trim_s: float = 0.05) -> list[tuple[int, int]]:
    """Sample ranges ``[i0, i1)`` of a log recorded from ``plan`` (plan.json) that carry its broadband injection.

    The log's time is taken to start with the plan's (``t - t[0]`` against the plan's ``t``);
    each injection window (``segments[].windows_s``) is trimmed by ``trim_s`` s at both ends.

    Raises
    ------
    UsageError
        The log ends before the plan's injection does, or the plan has no injection segment.
    """
    from commission.errors import UsageError

    tt = np.asarray(t, float) - float(t[0])
    wins = [w for g in plan["segments"] if g["name"] == "injection" for w in g.get("windows_s", [])]
    if not wins:
        raise UsageError("--plan: the plan has no injection segment with windows_s")
    end = max(b for _a, b in wins)
    if tt[-1] < end - trim_s:
        raise UsageError(f"--plan: the log ends at {tt[-1]:.4g} s, before the plan's injection does "
                         f"({end:.4g} s): not a recording of this plan")
    out = []
    for a, b in wins:
        i0, i1 = int(np.searchsorted(tt, a + trim_s)), int(np.searchsorted(tt, b - trim_s))
        if i1 > i0:
            out.append((i0, i1))
    return out


def load_plan_json(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read plan.json strictly (for ``identify --plan``): kind, schema version, segments with times.

    Returns
    -------
    dict
        The parsed plan.json.

    Raises
    ------
    SchemaError
        Naming the JSON path of a bad field.
    """
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8") as fh:
            d = json.load(fh)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SchemaError(f"{name}: not a readable plan.json ({exc})") from None
    if not isinstance(d, dict) or d.get("kind") != "excitation_plan":
        raise SchemaError(f"{name}: $.kind: expected 'excitation_plan'")
    if not isinstance(d.get("schema_version"), int) or d["schema_version"] > PLAN_SCHEMA_VERSION:
        raise SchemaError(f"{name}: $.schema_version = {d.get('schema_version')!r}: expected an integer "
                          f"<= {PLAN_SCHEMA_VERSION}")
    segs = d.get("segments")
    if not isinstance(segs, list):
        raise SchemaError(f"{name}: $.segments: expected a list")
    for i, g in enumerate(segs):
        for key in ("t_start", "t_end"):
            v = g.get(key) if isinstance(g, dict) else None
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise SchemaError(f"{name}: $.segments[{i}].{key} = {v!r}: expected a finite number (s)")
        if not isinstance(g.get("name"), str) or not isinstance(g.get("purpose"), str):
            raise SchemaError(f"{name}: $.segments[{i}]: expected string 'name' and 'purpose'")
    return d
