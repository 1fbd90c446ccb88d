"""The limits file (``limits.toml``): its keys, their checks, and the sketch other commands write."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Any, Mapping

from commission.errors import SpecError
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
