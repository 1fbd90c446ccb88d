"""``spec.toml``, the tuning spec of ``commission tune``: its one table of keys.

Every key of the file is one :class:`~commission.formats.table.Key` row of
:data:`SPEC_KEYS`; :mod:`commission.spec` builds the resolved ``Spec`` dataclass,
its defaults, the range checks and the loader from it, ``commission tune --help``
lists the rows, docs/interface.md §6 holds their table and
docs/schemas/spec.schema.json their JSON Schema (both generated:
``python -m commission.formats``, and tests compare them with the rows).
Ranges are inclusive; a key whose range starts above 0 must be positive.
"""

from __future__ import annotations

import math

from commission.formats.table import Key, Scaled, build_model

#: Highest controller rate accepted, Hz (the paper: 2.5 kHz; drives run current loops at 10-40 kHz).
MAX_SAMPLE_RATE = 100e3
#: Default observer pole as a fraction of the sample rate: p = 0.08 f_s (rad/s per Hz).
OBSERVER_POLE_FRACTION = 0.08
#: Default PID pole as a fraction of the sample rate: 0.12 f_s (paper: 300 rad/s at 2.5 kHz).
PID_POLE_FRACTION = 0.12
#: Encoder resolution when neither the spec nor ident.json gives one, m.
DEFAULT_QUANTIZATION = 1e-6
#: Version of docs/schemas/spec.schema.json (raised when a key changes meaning; new keys are additive).
SCHEMA_VERSION = 1

_W = 2 * math.pi * MAX_SAMPLE_RATE  # fastest pole any rate can carry, rad/s
_PLANT = "commission.scenarios.plant_dynamics"
_MOVES = "commission.moves.parse_profile"

SPEC_KEYS: tuple[Key, ...] = (
    # [controller]
    Key("controller", "sample_rate", float, 2500.0, (1.0, MAX_SAMPLE_RATE), "Hz",
        "controller rate (the paper: 2.5 kHz); controller.json states its nominal value",
        rule="the log's rate recorded in ident.json, else {default}"),
    Key("controller", "u_max", float, 10.0, (1e-6, 1e6), "u-unit", "input limit |u| <= u_max (a +-10 V drive command)"),
    Key("controller", "observer_pole", float, None, (1e-3, _W), "rad/s",
        "double pole -p of the observer (k1 = 2p, k2 = p^2); a defaulted one is a coordinate of tune's search",
        rule=Scaled(OBSERVER_POLE_FRACTION, "controller.sample_rate")),
    Key("controller", "quantization", float, None, (0.0, 1e-2), "m", "encoder resolution used in simulation",
        rule=f"ident.json's quantization, else {DEFAULT_QUANTIZATION:g} m"),
    Key("controller", "theta1_0", float, None, (1e-12, 1e12), "m/(u-unit s^2)",
        "the ARC's initial estimate theta_hat1(0) = 1/M_hat(0), within the identified theta box",
        rule="chosen by tune's search below the identified nominal"),
    # [trajectory]: the envelope; Case 1 and Case 2 are scaled to it
    Key("trajectory", "v_max", float, 1.0, (1e-6, 100.0), "m/s", "speed of the envelope",
        rule="{default}; with moves: their peak |v|"),
    Key("trajectory", "a_max", float, 12.0, (1e-6, 1e5), "m/s^2", "acceleration of the envelope",
        rule="{default}; with moves: their peak |a|"),
    Key("trajectory", "travel", float, 0.4, (1e-6, 100.0), "m", "stroke of the envelope",
        rule="{default}; with moves: their span"),
    Key("trajectory", "dwell", float, 0.5, (0.0, 60.0), "s", "rest between the moves of Case 2"),
    Key("trajectory", "moves", int, 6, (1, 100), "", "back-and-forth moves of Case 2"),
    Key("trajectory", "beta1", float, 100.0, (1e-3, 1e6), "1/s", "reference filter (58): s^2 + beta1 s + beta2"),
    Key("trajectory", "beta2", float, 2500.0, (1e-3, 1e12), "1/s^2", "reference filter (58): s^2 + beta1 s + beta2"),
    Key("trajectory", "reference_v_max", float, None, (1e-6, 100.0), "m/s",
        "speed Case 1 and Case 2 are scaled to", rule="trajectory.v_max; with moves: derived by tune"),
    Key("trajectory", "reference_a_max", float, None, (1e-6, 1e5), "m/s^2",
        "acceleration Case 1 and Case 2 are scaled to", rule="trajectory.a_max; with moves: derived by tune"),
    Key("trajectory", "file", str, None, None, "",
        "the machine's own moves: a CSV t,q[,v,a], the path relative to the spec", rule="none", checked_by=_MOVES),
    Key("trajectory", "file_sha256", str, None, None, "",
        "digest of trajectory.file that tune read (tuning.json records it, validate checks it)", rule="none",
        checked_by=_MOVES),
    Key("trajectory", "move", list, None, None, "",
        "[[trajectory.move]] tables: to m, v_max m/s, a_max m/s^2, optional j_max m/s^3, dwell s",
        rule="none", checked_by=_MOVES),
    # [targets]
    Key("targets", "e_rms", float, 5e-6, (1e-12, 1.0), "m", "accuracy target: rms tracking error"),
    Key("targets", "e_f", float, 10e-6, (1e-12, 1.0), "m", "final tracking accuracy: max |e| over the last 2 s"),
    Key("targets", "c_u", float, 0.5, (1e-6, 100.0), "", "chattering target: ||du||_rms / ||u||_rms"),
    # [pid]
    Key("pid", "pole", float, None, (1e-3, _W), "rad/s", "triple closed-loop pole of the PID baseline (56) at M_min",
        rule=Scaled(PID_POLE_FRACTION, "controller.sample_rate"), attr="pid_pole"),
    # [tune]
    Key("tune", "budget", int, 144, (1, 10_000), "", "candidate gain sets the search evaluates"),
    Key("tune", "monte_carlo", int, 0, (0, 1_000), "", "Monte-Carlo plants from the theta box added to tuning"),
    Key("tune", "margin", float, 0.01, (1e-6, 0.5), "",
        "discrete feasibility: spectral radius below 1 - margin at every theta-box corner"),
    # [plant]: dynamics beyond the rigid body
    Key("plant", "mode_hz", float, None, (0.0, 1e5), "Hz", "structural mode's resonance (0: rigid)",
        rule="ident.json's frequency_response model", attr="plant_mode_hz"),
    Key("plant", "mode_damping", float, None, (0.0, 10.0), "", "structural mode's damping ratio (below 1)",
        rule="ident.json's frequency_response model", attr="plant_mode_damping"),
    Key("plant", "mode_ratio", float, None, (1e-3, 1e3), "", "structural mode's load fraction m2/M (below 1)",
        rule="ident.json's frequency_response model", attr="plant_mode_ratio"),
    Key("plant", "encoder", str, None, None, "", "side the encoder reads", choices=("motor", "load"),
        rule="ident.json's frequency_response model", attr="plant_encoder"),
    Key("plant", "delay_samples", float, None, (0.0, 20.0), "samples",
        "input delay of the drive beyond the zero-order hold", rule="the identified one, else 0",
        attr="plant_delay_samples"),
    Key("plant", "noise_std", float, None, (0.0, 1e-2), "m", "encoder position noise before quantization, rms",
        rule="ident.json's encoder.noise_std, else 0", attr="plant_noise_std"),
    # [margins]: floors of the stability margins (tune's constraints, validate's gate)
    Key("margins", "gain_db", float, 6.0, (1e-3, 40.0), "dB", "gain margin floor", attr="min_gain_margin_db"),
    Key("margins", "phase_deg", float, 30.0, (1e-3, 89.0), "deg", "phase margin floor",
        attr="min_phase_margin_deg"),
    Key("margins", "delay_samples", float, 1.0, (1e-3, 20.0), "samples",
        "delay margin floor, beyond the identified delay", attr="min_delay_margin_samples"),
    Key("margins", "modulus", float, 0.5, (1e-3, 1.0), "", "modulus margin floor: min |1 + L|",
        attr="min_modulus_margin"),
    # [evidence]: the plant above the band the log backs
    Key("evidence", "first_mode_hz", float, None, (1e-3, 1e6), "Hz",
        "lowest structural mode the machine can have above the band the log backs",
        rule="10 x the backed band's top", attr="evidence_first_mode_hz"),
    Key("evidence", "damping", float, 0.05, (1e-3, 0.5), "", "least damping assumed of that mode",
        attr="evidence_damping"),
    # [compute]: where the work runs, not what is computed (not part of tuning.json's spec)
    Key("compute", "scheduler", str, None, None, "", "Dask scheduler address tcp://HOST:PORT of run's simulations",
        rule="local threads", checked_by="commission.infra.executor.compute_scheduler"),
)

#: The keys the ``Spec`` dataclass holds (read by the table's model, not by another reader).
SPEC_FIELDS: tuple[Key, ...] = tuple(k for k in SPEC_KEYS if k.checked_by is None)

#: The strict model of spec.toml (pydantic, built from :data:`SPEC_KEYS`).
SpecToml = build_model("SpecToml", SPEC_KEYS, "spec.toml: the tuning spec of `commission tune`; every key optional.")
