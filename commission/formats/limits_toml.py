"""``limits.toml``, the machine's limits for ``commission excite``: its one table of keys.

Every key is one :class:`~commission.formats.table.Key` row of :data:`LIMITS_KEYS`;
:func:`commission.excite.limits.excite_spec_from_mapping` validates with the model
built from them and resolves the defaults from them, and docs/interface.md §10 and
docs/schemas/limits.schema.json are generated from them (``python -m commission.formats``).
A unit with ``q`` or ``u`` is the file's own: ``q`` is ``[axis] q_unit`` (m on a
linear axis, rad on a rotary one), ``u`` is ``[axis] u_unit``.
"""

from __future__ import annotations

import math

from commission.formats.table import Key, build_model

#: Accepted values of the unit keys.
Q_UNITS = ("m", "rad")
U_UNITS = ("V", "N", "A", "Nm", "%")
INJECTIONS = ("multisine", "prbs")
#: Version of docs/schemas/limits.schema.json.
SCHEMA_VERSION = 1

_INF = math.inf
_POS = dict(range=(0.0, _INF), open=(True, False))      # > 0
_NONNEG = dict(range=(0.0, _INF))                       # >= 0
_FRAC = dict(range=(0.0, 1.0), open=(True, True))       # in (0, 1)

LIMITS_KEYS: tuple[Key, ...] = (
    # [limits]: what the run may use
    Key("limits", "travel", float, None, unit="{q}", required=True, **_POS,
        doc="the whole span the run may use, centred on the start position (+-travel/2)"),
    Key("limits", "v_max", float, None, unit="{q}/s", required=True, **_POS, doc="peak speed"),
    Key("limits", "a_max", float, None, unit="{q}/s^2", required=True, **_POS, doc="peak acceleration"),
    Key("limits", "u_max", float, None, unit="{u}", required=True, **_POS, doc="peak command"),
    # [drive]
    Key("drive", "sample_rate", float, None, unit="Hz", required=True, **_POS,
        doc="drive rate; one plan row per sample"),
    Key("drive", "bandwidth_hz", float, None, unit="Hz", rule="absent: give it or kp, kd", **_POS,
        doc="bandwidth of the holding position loop (gains on the model's mass: kp = M w^2, kd = 2 0.7 M w, "
            "ki = kp w/10, w = 2 pi bandwidth_hz); 2 pi bandwidth_hz / sample_rate <= 0.5"),
    Key("drive", "kp", float, None, unit="{u}/{q}", rule="absent: give it or bandwidth_hz", **_POS,
        doc="the holding loop's proportional gain instead of bandwidth_hz (with kd)"),
    Key("drive", "kd", float, None, unit="{u} s/{q}", rule="absent: give it or bandwidth_hz", **_NONNEG,
        doc="the holding loop's derivative gain instead of bandwidth_hz (with kp)"),
    Key("drive", "ki", float, None, unit="{u}/({q} s)", rule="0 with kp, kd", **_NONNEG,
        doc="the holding loop's integral gain"),
    # [axis]: rough guesses
    Key("axis", "mass", float, None, unit="{u} s^2/{q}", rule="absent: the plan starts with a bump test", **_POS,
        doc="rough mass; without it the pre-simulation brackets it between the heaviest axis that reaches a_max "
            "with u_max (less friction) and that divided by 5 mass_range"),
    Key("axis", "friction", float, None, unit="{u}", rule="absent", **_NONNEG,
        doc="rough Coulomb level; must be below u_max"),
    Key("axis", "viscous", float, None, unit="{u} s/{q}", rule="absent", **_NONNEG, doc="rough viscous coefficient"),
    Key("axis", "q_unit", str, "m", None, "", "unit of the position: m on a linear axis, rad on a rotary one",
        choices=Q_UNITS),
    Key("axis", "u_unit", str, "V", None, "", "unit of the command", choices=U_UNITS),
    Key("axis", "encoder_step", float, None, unit="{q}", rule="1e-06 assumed, said on stdout", **_POS,
        doc="the encoder's resolution (quantization step), for the predicted band"),
    Key("axis", "encoder_noise", float, None, unit="{q}", rule="0 assumed, said on stdout", **_NONNEG,
        doc="the encoder's rms noise, for the predicted band"),
    # [evidence]
    Key("evidence", "target_hz", float, None, unit="Hz", rule="absent", **_POS,
        doc="top of the band the recording must back (e.g. 1.5 x the intended crossover); a shorter predicted "
            "band is warned"),
    Key("evidence", "first_mode_hz", float, None, unit="Hz", rule="absent", **_POS,
        doc="the lowest structural mode known or expected; the target is then at least 1.5 x it"),
    # [plan]
    Key("plan", "n_speeds", int, 8, unit="", **_POS, doc="friction-ladder speeds, log-spaced"),
    Key("plan", "v_min", float, None, unit="{q}/s", rule="limits.v_max / 100", **_POS, doc="slowest ladder speed"),
    Key("plan", "leg_time", float, 1.0, unit="s", **_POS,
        doc="target cruise time of a ladder leg (shorter where the span ends it)"),
    Key("plan", "min_cruise", float, 0.2, unit="s", **_POS,
        doc="shortest cruise of a leg; the fastest speed is the largest up to 0.8 v_max with this cruise in the span"),
    Key("plan", "moves", int, 6, unit="", **_POS, doc="back-and-forth S-curve moves for M and B"),
    Key("plan", "dwell", float, 0.2, unit="s", **_NONNEG, doc="rest after each leg"),
    Key("plan", "jerk_time", float, 0.02, unit="s", **_POS,
        doc="time to reach the moves' acceleration (j_max = a / jerk_time)"),
    Key("plan", "injection", str, "prbs", None, "",
        "prbs: one maximal-length-sequence bit per sample, flat to Nyquist; multisine: Schroeder phases",
        choices=INJECTIONS),
    Key("plan", "injection_s", float, 8.0, unit="s", **_POS,
        doc="total cruise time carrying the injection (slow legs both ways)"),
    Key("plan", "injection_fraction", float, 0.5, unit="", **_FRAC,
        doc="injection peak as a fraction of the light model's mass x a_max (and of the command left after "
            "friction and the moves)"),
    Key("plan", "band_hz", list, None, unit="Hz", rule="[min(2, 0.01 Nyquist), 0.8 Nyquist]", **_POS,
        doc="multisine band [low, high], the top below Nyquist"),
    Key("plan", "shaping", float, 1.0, unit="", range=(-_INF, _INF), doc="multisine line amplitude ~ f^shaping"),
    Key("plan", "stepped_sine_hz", list, (), unit="Hz", **_POS,
        doc="frequencies of an optional stepped sine, each on its own slow cruise, below Nyquist"),
    Key("plan", "sine_cycles", float, 20.0, unit="", **_POS, doc="cycles per stepped-sine frequency (at least 0.1 s)"),
    Key("plan", "margin", float, 0.1, unit="", **_FRAC, doc="fraction of the travel kept free at both ends"),
    Key("plan", "mass_range", float, 2.0, unit="", range=(1.0, _INF),
        doc="the pre-simulation's models are mass / mass_range and mass x mass_range"),
)

#: The strict model of limits.toml (pydantic, built from :data:`LIMITS_KEYS`).
LimitsToml = build_model("LimitsToml", LIMITS_KEYS, "limits.toml: the machine's limits for `commission excite`.")
