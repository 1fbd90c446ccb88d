"""The limits file (``limits.toml``): its checks across keys, and the sketch other commands write.

The keys themselves (type, default, range, unit, doc) are one table,
:data:`commission.formats.limits_toml.LIMITS_KEYS`; :func:`excite_spec_from_mapping`
validates each key with the model built from it and adds the rules that join keys
(the holding loop's two forms, the bandwidth rule, friction below u_max, bands
below Nyquist, v_min below v_max).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any, Mapping

from pydantic import ValidationError

from commission.errors import SpecError
from commission.infra.files import read_toml
from commission.formats.limits_toml import INJECTIONS, LIMITS_KEYS, Q_UNITS, U_UNITS, LimitsToml
from commission.formats.table import Key, first_error

#: Pre-simulation: how often the injection is lowered before a plan is refused.
MAX_INJECTION_RETRIES = 4
#: Largest swing of the velocity about the injection's cruise on the pre-simulation's *light* model,
#: as a fraction of the cruise speed (:func:`commission.excite.presim.plan_run`).  The injection rides
#: on a cruise so that friction keeps one sign and acts as a constant force; where the injection's own
#: velocity swing reaches the cruise speed the velocity crosses zero and Coulomb friction acts on the
#: modes as a nonlinear damper (the identified damping reads high, the frequency low).  The holding
#: loop's gains scale with the model's mass, so the swing scales as 1/M: on the light model
#: (``mass / plan.mass_range``) it is ``mass_range`` times the stated mass's, and a swing kept within
#: the cruise there stays within half of it (the default range 2) on an axis of the stated mass --
#: room for a motor-side mode's resonance, which the rigid models do not hold.
INJECTION_SWING_FRACTION = 1.0
#: Raises of the injection's cruise speed at most (:func:`commission.excite.presim.plan_run`).
MAX_SPEED_RAISES = 3
#: Largest accepted 2 pi bandwidth_hz / sample_rate (Åström & Wittenmark's omega h <= 0.5, as spec.py).
MAX_OMEGA_T = 0.5
#: Damping ratio assumed for a loop given by its bandwidth.
LOOP_DAMPING = 0.7
#: Plant sub-steps per sample of the pre-simulation.
PRESIM_SUBSTEPS = 4
#: Keys of limits.toml: one table (:data:`commission.formats.limits_toml.LIMITS_KEYS`), read here.
_KEYS: dict[tuple[str, str], Key] = {(k.section, k.name): k for k in LIMITS_KEYS}


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
    q_unit: str = _KEYS[("axis", "q_unit")].default
    u_unit: str = _KEYS[("axis", "u_unit")].default
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
    try:
        model = LimitsToml.model_validate(data)
    except ValidationError as exc:
        raise SpecError(first_error(exc, data, LIMITS_KEYS, source=source, prefix="",
                                    units={"q": q_unit, "u": u_unit})) from None
    vals: dict[tuple[str, str], Any] = {}
    for section in model.model_fields_set:
        table = getattr(model, section)
        for key in table.model_fields_set:
            v = getattr(table, key)
            vals[(section, key)] = tuple(float(x) for x in v) if isinstance(v, list) else v
    for k in LIMITS_KEYS:
        if k.required and (k.section, k.name) not in vals:
            raise fail(k.path, f": missing (required in [{k.section}])")
    g = lambda s, k: vals.get((s, k), _KEYS[(s, k)].default)  # noqa: E731
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
    plan = {k.name: g("plan", k.name) for k in LIMITS_KEYS if k.section == "plan"}
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
