"""``limits.toml``, the machine's limits for ``commission excite``: its one table of keys.

Every key is one :class:`~commission.formats.table.Key` row of :data:`LIMITS_KEYS`;
:func:`commission.excite.limits.excite_spec_from_mapping` validates with the model
built from them and resolves the defaults from them, and docs/interface.md §10 and
docs/schemas/limits.schema.json are generated from them (``python -m commission.formats``).
A unit with ``q`` or ``u`` is the file's own: ``q`` is ``[axis] q_unit`` (m on a
linear axis, rad on a rotary one), ``u`` is ``[axis] u_unit``.
"""

from __future__ import annotations

from commission.formats.table import Key, build_model, keys

#: Accepted values of the unit keys.
Q_UNITS = ("m", "rad")
U_UNITS = ("V", "N", "A", "Nm", "%")
INJECTIONS = ("multisine", "prbs")
#: Version of docs/schemas/limits.schema.json.
SCHEMA_VERSION = 1

LIMITS_KEYS: tuple[Key, ...] = keys("""
limits.travel           | number  | required | (0, inf)    | {q}         | -
    the whole span the run may use, centred on the start position (+-travel/2)
limits.v_max            | number  | required | (0, inf)    | {q}/s       | -
    peak speed
limits.a_max            | number  | required | (0, inf)    | {q}/s^2     | -
    peak acceleration
limits.u_max            | number  | required | (0, inf)    | {u}         | -
    peak command
drive.sample_rate       | number  | required | (0, inf)    | Hz          | -
    drive rate; one plan row per sample
drive.bandwidth_hz      | number  | -        | (0, inf)    | Hz          | absent: give it or kp, kd
    bandwidth of the holding position loop (gains on the model's mass: kp = M w^2, kd = 2 0.7 M w, ki = kp w/10, w
    = 2 pi bandwidth_hz); 2 pi bandwidth_hz / sample_rate <= 0.5
drive.kp                | number  | -        | (0, inf)    | {u}/{q}     | absent: give it or bandwidth_hz
    the holding loop's proportional gain instead of bandwidth_hz (with kd)
drive.kd                | number  | -        | [0, inf)    | {u} s/{q}   | absent: give it or bandwidth_hz
    the holding loop's derivative gain instead of bandwidth_hz (with kp)
drive.ki                | number  | -        | [0, inf)    | {u}/({q} s) | 0 with kp, kd
    the holding loop's integral gain
axis.mass               | number  | -        | (0, inf)    | {u} s^2/{q} | absent: the plan starts with a bump test
    rough mass; without it the pre-simulation brackets it between the heaviest axis that reaches a_max with u_max
    (less friction) and that divided by 5 mass_range
axis.friction           | number  | -        | [0, inf)    | {u}         | absent
    rough Coulomb level; must be below u_max
axis.viscous            | number  | -        | [0, inf)    | {u} s/{q}   | absent
    rough viscous coefficient
axis.q_unit             | string  | 'm'      | -           | -           | -
    unit of the position: m on a linear axis, rad on a rotary one
axis.u_unit             | string  | 'V'      | -           | -           | -
    unit of the command
axis.encoder_step       | number  | -        | (0, inf)    | {q}         | 1e-06 assumed, said on stdout
    the encoder's resolution (quantization step), for the predicted band
axis.encoder_noise      | number  | -        | [0, inf)    | {q}         | 0 assumed, said on stdout
    the encoder's rms noise, for the predicted band
evidence.target_hz      | number  | -        | (0, inf)    | Hz          | absent
    top of the band the recording must back (e.g. 1.5 x the intended crossover); a shorter predicted band is
    warned
evidence.first_mode_hz  | number  | -        | (0, inf)    | Hz          | absent
    the lowest structural mode known or expected; the target is then at least 1.5 x it
plan.n_speeds           | integer | 8        | (0, inf)    | -           | -
    friction-ladder speeds, log-spaced
plan.v_min              | number  | -        | (0, inf)    | {q}/s       | limits.v_max / 100
    slowest ladder speed
plan.leg_time           | number  | 1.0      | (0, inf)    | s           | -
    target cruise time of a ladder leg (shorter where the span ends it)
plan.min_cruise         | number  | 0.2      | (0, inf)    | s           | -
    shortest cruise of a leg; the fastest speed is the largest up to 0.8 v_max with this cruise in the span
plan.moves              | integer | 6        | (0, inf)    | -           | -
    back-and-forth S-curve moves for M and B
plan.dwell              | number  | 0.2      | [0, inf)    | s           | -
    rest after each leg
plan.jerk_time          | number  | 0.02     | (0, inf)    | s           | -
    time to reach the moves' acceleration (j_max = a / jerk_time)
plan.injection          | string  | 'prbs'   | -           | -           | -
    prbs: one maximal-length-sequence bit per sample, flat to Nyquist; multisine: Schroeder phases
plan.injection_s        | number  | 8.0      | (0, inf)    | s           | -
    total cruise time carrying the injection (legs both ways)
plan.injection_speed    | number  | -        | (0, inf)    | {q}/s       | raised until friction keeps one sign
    cruise of the injection and stepped-sine legs; by default a quarter of the way (in log) up the ladder, raised
    where the injection's velocity swing on the light model would reach it (up to half the ladder's top speed)
plan.injection_fraction | number  | 0.5      | (0, 1)      | -           | -
    injection peak as a fraction of the light model's mass x a_max (and of the command left after friction and the
    moves)
plan.band_hz            | list    | -        | (0, inf)    | Hz          | [min(2, 0.01 Nyquist), 0.8 Nyquist]
    multisine band [low, high], the top below Nyquist
plan.shaping            | number  | 1.0      | (-inf, inf) | -           | -
    multisine line amplitude ~ f^shaping
plan.stepped_sine_hz    | list    | ()       | (0, inf)    | Hz          | -
    frequencies of an optional stepped sine, each on its own cruise, below Nyquist
plan.sine_cycles        | number  | 20.0     | (0, inf)    | -           | -
    cycles per stepped-sine frequency (at least 0.1 s)
plan.margin             | number  | 0.1      | (0, 1)      | -           | -
    fraction of the travel kept free at both ends
plan.mass_range         | number  | 2.0      | [1, inf)    | -           | -
    the pre-simulation's models are mass / mass_range and mass x mass_range
""", {"axis.q_unit": dict(choices=Q_UNITS), "axis.u_unit": dict(choices=U_UNITS),
      "plan.injection": dict(choices=INJECTIONS)})

#: The strict model of limits.toml (pydantic, built from :data:`LIMITS_KEYS`).
LimitsToml = build_model("LimitsToml", LIMITS_KEYS, "limits.toml: the machine's limits for `commission excite`.")
