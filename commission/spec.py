"""The tuning spec (``spec.toml``) of ``commission tune``.

A spec states what the user wants from the axis: the controller sample rate,
the input limit, the trajectory envelope, and the accuracy and chattering
targets.  Every key is optional; an absent key takes the documented default
below, so an empty file (or no ``--spec`` at all) reproduces the paper's
setting (Xu & Yao 2001, §4.3).  Unknown keys, wrong types, non-positive rates
and a sample rate too low for a requested bandwidth are rejected by
:func:`load_spec` / :func:`spec_from_mapping` with one
:class:`commission.errors.SpecError` line naming the TOML key path, before
any simulation runs.

Keys and defaults
-----------------
``[controller]``
    ``sample_rate`` = 2500.0
        Controller rate, Hz (paper: 2.5 kHz).  ``commission tune`` defaults it
        to the excitation log's rate when ident.json records one
        (``source.sample_rate``), as measured: tune and validate simulate that
        period; controller.json states it as its nominal value
        (:func:`nominal_rate`).
    ``u_max`` = 10.0
        Input limit |u| <= u_max, u-unit (a +-10 V drive command).
    ``observer_pole``
        Double pole -p of the observer matrix A0 (10), rad/s.  Default
        ``OBSERVER_POLE_FRACTION * sample_rate`` = 0.08 * f_s (the paper's
        -200 rad/s at 2.5 kHz, giving k1 = 2p = 400, k2 = p^2 = 4e4).  A defaulted
        pole is a coordinate of tune's search (0.6-1.25x; see
        :data:`commission.tune.OBSERVER_FACTOR_BOUNDS`); a given one is kept.
    ``quantization``
        Encoder resolution used in simulation, m.  Default: the
        ``quantization`` recorded in ident.json if present, else 1e-6 m.
    ``theta1_0``
        The ARC's initial estimate theta_hat1(0) = 1/M_hat(0), m/(u-unit s^2);
        must lie in the identified theta box.  Default: chosen by the search
        between 0.5 x and 1 x the identified nominal theta1 (the paper started
        at 30 for a nominal 37: a lower start meets a payload sooner, see
        ``commission.tune``).  theta_hat2(0), theta_hat3(0) are the nominal.
``[trajectory]`` (the envelope; Case 1 and Case 2 are scaled to it)
    ``v_max`` = 1.0 (m/s), ``a_max`` = 12.0 (m/s^2), ``travel`` = 0.4 (m),
    ``dwell`` = 0.5 (s), ``moves`` = 6 (back-and-forth moves of Case 2),
    ``beta1`` = 100.0 (1/s) and ``beta2`` = 2500.0 (1/s^2): the reference
    filter (58).
    The machine's own moves, validated beside Case 1 and Case 2 (:mod:`commission.moves`):
    ``file`` (a CSV ``t,q[,v,a]``, the path relative to this file; ``file_sha256``: the
    digest tune read, which tuning.json records and validate checks) or
    ``[[trajectory.move]]`` tables (``to`` m, ``v_max`` m/s, ``a_max`` m/s^2, optional
    ``j_max`` m/s^3 and ``dwell`` s: S-curves).  With them, ``v_max``, ``a_max`` and
    ``travel`` default to the moves' peak |v|, peak |a| and span (given, they must cover
    them): the envelope of the runtime guard and the gate, not derived from u_max.
    ``reference_v_max`` (m/s), ``reference_a_max`` (m/s^2)
        The envelope Case 1 and Case 2 are scaled to (with ``travel``); default ``v_max``,
        ``a_max``.  With the machine's moves ``tune`` derives them when not given
        (:func:`commission.tune.defaults.reference_envelope`): the paper's cases stay the
        reference at an envelope this drive can move, while the moves set the envelope.
``[targets]``
    ``e_rms`` = 5e-6
        Accuracy target: rms tracking error, m (paper's ARC: 1.9-4.3 um).
    ``e_f`` = 10e-6
        Final tracking accuracy (max |e| over the last 2 s), m.
    ``c_u`` = 0.5
        Chattering target: ||du||_rms / ||u||_rms (paper's ARC: 0.19-0.32).
``[pid]``
    ``pole``
        Triple closed-loop pole of (56) at M_min, rad/s.  Default
        ``PID_POLE_FRACTION * sample_rate`` = 0.12 * f_s (the paper's -300 rad/s
        at 2.5 kHz).  ``tune`` runs a defaulted pole lower when the PID there
        exceeds validate's default c_u limit on a tuning scenario (a coarse
        encoder at a high rate): :func:`commission.tune.deployable_pid`.
``[tune]``
    ``budget`` = 144
        Candidate gain sets the search evaluates (each on the tuning scenarios,
        unless it misses a margin floor first; benchmarks/bench_tune.py times it).
        Left at its default, ``tune`` lowers it (to whole generations of 8, at
        least 48) where one candidate simulates more than 1.8 times the paper
        axis' work, as slow envelopes at 4-5 kHz do
        (:func:`commission.tune.work_scaled_budget`), and prints a ``note:``.
    ``monte_carlo`` = 0
        Monte-Carlo plants from the theta box added to the tuning subset.
    ``margin`` = 0.01
        Discrete feasibility: spectral radius of the linearised sampled loop
        (estimates frozen) must be below ``1 - margin`` at every corner of the
        theta box; with the theta3 adaptation in the loop it must be below 1.

``[plant]`` (dynamics beyond the rigid body; every key optional)
    ``mode_hz``, ``mode_damping``, ``mode_ratio``, ``encoder``
        A structural mode (resonance Hz, damping ratio, load fraction m2/M,
        encoder on the ``"motor"`` or ``"load"`` side; ``mode_hz = 0``: rigid).
        Default: the mode ident.json's ``frequency_response.model`` found.
    ``delay_samples``
        Input delay of the drive beyond the zero-order hold, samples.  Default:
        the identified one, else 0.
    ``noise_std``
        Encoder position noise before quantization, m rms.  Default: ident.json's
        ``encoder.noise_std`` if present, else 0 (quantization only).
    Both ``tune`` and ``validate`` simulate and linearise with them
    (:func:`commission.scenarios.plant_dynamics`).
``[margins]`` (floors of the stability margins, :mod:`commission.robustness`)
    ``gain_db`` = 6.0, ``phase_deg`` = 30.0, ``delay_samples`` = 1.0 (beyond the
    identified delay), ``modulus`` = 0.5.  Constraints of tune's search on the ARC
    linearised on the identified plant, and floors of validate's gate
    (:func:`commission.gate.margin_checks`), which no gate.toml can lower.
``[evidence]`` (the plant above the band the log backs, :mod:`commission.evidence`)
    ``first_mode_hz``: the lowest structural mode the machine can have above that band, Hz, when
    the user knows it (a FE model, the vendor's data); default: 10 x the band's top.
    ``damping`` = 0.05: the least damping assumed of that mode.  They set the uncertainty weight
    (|W| = 1 at the first mode, plateau 1 / (2 damping)) that tune's search and validate's
    gate hold both loops to.

Bandwidth rule
--------------
A requested bandwidth omega (rad/s) needs ``omega / sample_rate <= MAX_OMEGA_T``
= 0.5 (upper end of the ``omega h = 0.15 ... 0.5`` rule of thumb of Åström &
Wittenmark, *Computer-Controlled Systems*).  It is checked for the observer
pole, the PID pole and the fastest root of the reference filter (58).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields
from typing import Any, Mapping

from commission.errors import SpecError, UsageError
from commission.files import read_toml
from commission.moves import MOVE_KEYS, UserProfile, parse_profile, profile_keys

#: Default observer pole as a fraction of the sample rate: p = 0.08 f_s (rad/s per Hz).
OBSERVER_POLE_FRACTION = 0.08
#: Default PID pole as a fraction of the sample rate: 0.12 f_s (paper: 300 rad/s at 2.5 kHz).
PID_POLE_FRACTION = 0.12
#: Largest accepted omega*T for any requested bandwidth omega (rad/s) at period T (s).
MAX_OMEGA_T = 0.5
#: Encoder resolution when neither the spec nor ident.json gives one, m.
DEFAULT_QUANTIZATION = 1e-6

# (section, key) -> (type, default, must-be-positive, unit).  None default: derived.
_SCHEMA: dict[str, dict[str, tuple[type, Any, bool, str]]] = {
    "controller": {
        "sample_rate": (float, 2500.0, True, "Hz"),
        "u_max": (float, 10.0, True, "u-unit"),
        "observer_pole": (float, None, True, "rad/s"),
        "quantization": (float, None, False, "m"),
        "theta1_0": (float, None, True, "m/(u-unit s^2)"),
    },
    "trajectory": {
        "v_max": (float, 1.0, True, "m/s"),
        "a_max": (float, 12.0, True, "m/s^2"),
        "travel": (float, 0.4, True, "m"),
        "dwell": (float, 0.5, False, "s"),
        "moves": (int, 6, True, ""),
        "beta1": (float, 100.0, True, "1/s"),
        "beta2": (float, 2500.0, True, "1/s^2"),
        "reference_v_max": (float, None, True, "m/s"),
        "reference_a_max": (float, None, True, "m/s^2"),
    },
    "targets": {
        "e_rms": (float, 5e-6, True, "m"),
        "e_f": (float, 10e-6, True, "m"),
        "c_u": (float, 0.5, True, ""),
    },
    "pid": {
        "pole": (float, None, True, "rad/s"),
    },
    "tune": {
        "budget": (int, 144, True, ""),
        "monte_carlo": (int, 0, False, ""),
        "margin": (float, 0.01, True, ""),
    },
    "plant": {
        "mode_hz": (float, None, False, "Hz"),
        "mode_damping": (float, None, False, ""),
        "mode_ratio": (float, None, True, ""),
        "encoder": (str, None, False, ""),
        "delay_samples": (float, None, False, "samples"),
        "noise_std": (float, None, False, "m"),
    },
    "margins": {
        "gain_db": (float, 6.0, True, "dB"),
        "phase_deg": (float, 30.0, True, "deg"),
        "delay_samples": (float, 1.0, True, "samples"),
        "modulus": (float, 0.5, True, ""),
    },
    "evidence": {
        "first_mode_hz": (float, None, True, "Hz"),
        "damping": (float, 0.05, True, ""),
    },
}
#: Allowed values of the string keys.
_CHOICES = {("plant", "encoder"): ("motor", "load")}


@dataclass(frozen=True)
class Spec:
    """A validated tuning spec with every default resolved (see module docstring).

    Attributes
    ----------
    sample_rate : float
        Controller rate, Hz.
    u_max : float
        Input limit, u-unit.
    observer_pole : float
        Observer double pole magnitude p, rad/s (k1 = 2p, k2 = p^2).
    quantization : float or None
        Encoder resolution, m; ``None``: take it from ident.json, else 1e-6 m.
    theta1_0 : float or None
        Initial estimate theta_hat1(0), m/(u-unit s^2); ``None``: chosen by the search.
    v_max, a_max, travel, dwell : float
        Trajectory envelope: m/s, m/s^2, m, s (with the machine's moves: theirs, see ``profile``).
    moves : int
        Back-and-forth moves of the Case-2 trajectory.
    beta1, beta2 : float
        Reference filter (58) coefficients, 1/s and 1/s^2.
    e_rms, e_f : float
        Accuracy targets, m.
    c_u : float
        Chattering target, dimensionless.
    pid_pole : float
        PID triple pole magnitude, rad/s.
    budget : int
        Candidate gain sets the search simulates.
    monte_carlo : int
        Monte-Carlo plants in the tuning subset.
    margin : float
        Required stability margin: spectral radius < 1 - margin.
    plant_mode_hz, plant_mode_damping, plant_mode_ratio, plant_encoder, plant_delay_samples, plant_noise_std : optional
        ``[plant]``: the structural mode (Hz, -, load fraction, ``"motor"``/``"load"``) and input
        delay (samples) the user knows; ``None``: what ident.json's ``frequency_response`` found.
    min_gain_margin_db, min_phase_margin_deg, min_delay_margin_samples, min_modulus_margin : float
        ``[margins]``: the stability-margin floors, dB, deg, samples beyond the identified delay, -.
    evidence_first_mode_hz, evidence_damping : float or None, float
        ``[evidence]``: the lowest unseen mode, Hz (None: 10 x the backed band's top), and its least damping.
    reference_v_max, reference_a_max : float or None
        Envelope of Case 1 and Case 2, m/s and m/s^2; ``None``: ``v_max``, ``a_max``
        (:attr:`case_v_max`, :attr:`case_a_max`).
    profile : UserProfile or None
        The machine's own moves (``[trajectory] file`` or ``[[trajectory.move]]``), validated as the
        ``user/...`` scenarios; ``None``: only Case 1 and Case 2.
    """

    sample_rate: float = 2500.0
    u_max: float = 10.0
    observer_pole: float = OBSERVER_POLE_FRACTION * 2500.0
    quantization: float | None = None
    theta1_0: float | None = None
    v_max: float = 1.0
    a_max: float = 12.0
    travel: float = 0.4
    dwell: float = 0.5
    moves: int = 6
    beta1: float = 100.0
    beta2: float = 2500.0
    e_rms: float = 5e-6
    e_f: float = 10e-6
    c_u: float = 0.5
    pid_pole: float = PID_POLE_FRACTION * 2500.0
    budget: int = 144
    monte_carlo: int = 0
    margin: float = 0.01
    plant_mode_hz: float | None = None
    plant_mode_damping: float | None = None
    plant_mode_ratio: float | None = None
    plant_encoder: str | None = None
    plant_delay_samples: float | None = None
    plant_noise_std: float | None = None
    min_gain_margin_db: float = 6.0
    min_phase_margin_deg: float = 30.0
    min_delay_margin_samples: float = 1.0
    min_modulus_margin: float = 0.5
    reference_v_max: float | None = None
    reference_a_max: float | None = None
    profile: UserProfile | None = None
    evidence_first_mode_hz: float | None = None
    evidence_damping: float = 0.05

    @property
    def targets(self) -> dict[str, float]:
        """The ``[targets]`` accuracy values, m: ``{"e_rms": ..., "e_f": ...}`` (the gate's default limits follow them)."""
        return {"e_rms": self.e_rms, "e_f": self.e_f}

    @property
    def period(self) -> float:
        """Sample period T = 1/sample_rate, s."""
        return 1.0 / self.sample_rate

    @property
    def case_v_max(self) -> float:
        """Speed Case 1 and Case 2 are scaled to, m/s: ``reference_v_max``, else ``v_max``."""
        return self.v_max if self.reference_v_max is None else self.reference_v_max

    @property
    def case_a_max(self) -> float:
        """Acceleration Case 1 and Case 2 are scaled to, m/s^2: ``reference_a_max``, else ``a_max``."""
        return self.a_max if self.reference_a_max is None else self.reference_a_max

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Nested mapping in the TOML layout, every default resolved (a profile as the keys that re-create it)."""
        flat = {f.name: getattr(self, f.name) for f in fields(self)}
        out: dict[str, dict[str, Any]] = {}
        for section, keys in _SCHEMA.items():
            out[section] = {}
            for key in keys:
                attr = _ATTR.get((section, key), key)
                if flat[attr] is not None:
                    out[section][key] = flat[attr]
        if self.profile is not None:
            out["trajectory"].update(self.profile.to_spec())
        return out


#: Highest controller rate accepted, Hz (the paper: 2.5 kHz; drives run current loops at 10-40 kHz).
MAX_SAMPLE_RATE = 100e3
#: Most samples one simulated trajectory may hold (Case 1 or Case 2 at the controller rate):
#: 100 s at 2.5 kHz, 12 times the paper's longest.  Every scenario of tune and validate
#: keeps traces of this length, so this bounds their memory and time.
MAX_TRAJECTORY_SAMPLES = 250_000

#: Documented range of every number of the spec, (lowest, highest), both inclusive; the type
#: and sign rules of ``_SCHEMA`` apply as well.  Checked before any work starts.
RANGES: dict[tuple[str, str], tuple[float, float]] = {
    ("controller", "sample_rate"): (1.0, MAX_SAMPLE_RATE),
    ("controller", "u_max"): (1e-6, 1e6),
    ("controller", "observer_pole"): (1e-3, 2 * math.pi * MAX_SAMPLE_RATE),
    ("controller", "quantization"): (0.0, 1e-2),
    ("controller", "theta1_0"): (1e-12, 1e12),
    ("trajectory", "v_max"): (1e-6, 100.0),
    ("trajectory", "a_max"): (1e-6, 1e5),
    ("trajectory", "travel"): (1e-6, 100.0),
    ("trajectory", "dwell"): (0.0, 60.0),
    ("trajectory", "moves"): (1, 100),
    ("trajectory", "beta1"): (1e-3, 1e6),
    ("trajectory", "beta2"): (1e-3, 1e12),
    ("trajectory", "reference_v_max"): (1e-6, 100.0),
    ("trajectory", "reference_a_max"): (1e-6, 1e5),
    ("targets", "e_rms"): (1e-12, 1.0),
    ("targets", "e_f"): (1e-12, 1.0),
    ("targets", "c_u"): (1e-6, 100.0),
    ("pid", "pole"): (1e-3, 2 * math.pi * MAX_SAMPLE_RATE),
    ("tune", "budget"): (1, 10_000),
    ("tune", "monte_carlo"): (0, 1_000),
    ("tune", "margin"): (1e-6, 0.5),
    ("evidence", "first_mode_hz"): (1e-3, 1e6),
    ("evidence", "damping"): (1e-3, 0.5),
    ("plant", "mode_hz"): (0.0, 1e5),
    ("plant", "mode_damping"): (0.0, 10.0),
    ("plant", "mode_ratio"): (1e-3, 1e3),
    ("plant", "delay_samples"): (0.0, 20.0),
    ("plant", "noise_std"): (0.0, 1e-2),
    ("margins", "gain_db"): (1e-3, 40.0),
    ("margins", "phase_deg"): (1e-3, 89.0),
    ("margins", "delay_samples"): (1e-3, 20.0),
    ("margins", "modulus"): (1e-3, 1.0),
    # One [[trajectory.move]] table (commission.moves.MOVE_KEYS checks them).
    **{("trajectory.move", k): (lo, hi) for k, (_req, _unit, lo, hi) in MOVE_KEYS.items()},
}


#: Documented range of the numeric flags of tune, validate and run, (lowest, highest) inclusive.
FLAG_RANGES: dict[str, tuple[int, int]] = {
    "--seed": (0, 2**63 - 1),
    "--monte-carlo": (0, 10_000),
    "--workers": (1, 256),
}


def check_flags(**values: int | None) -> None:
    """Refuse a flag outside :data:`FLAG_RANGES` (keyword = flag without dashes, ``_`` for ``-``).

    Raises
    ------
    UsageError
        ``--monte-carlo: must be an integer in [0, 10000], got 100000000``.
    """
    for key, v in values.items():
        if v is None:
            continue
        flag = "--" + key.replace("_", "-")
        lo, hi = FLAG_RANGES[flag]
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise UsageError(f"{flag}: must be an integer in [{lo}, {hi}], got {v!r}")


def check_range(source: str, path: str, key: tuple[str, str], val: float, unit: str = "") -> None:
    """Refuse a spec number outside its documented range (:data:`RANGES`), naming the key."""
    lo, hi = RANGES[key]
    if not lo <= val <= hi:
        u = f" {unit}" if unit else ""
        raise SpecError(f"{source}: {path} = {val!r}{u} is outside the accepted range [{lo:g}, {hi:g}]{u}")


def check_trajectory_samples(source: str, prefix: str, sample_rate: float, durations: dict[str, float]) -> None:
    """Refuse a rate and envelope whose trajectories exceed :data:`MAX_TRAJECTORY_SAMPLES`.

    Parameters
    ----------
    durations : dict
        Trajectory name -> duration, s (:func:`commission.scenarios.case1_trajectory`, ``case2_trajectory``).
    """
    for name, d in durations.items():
        n = d * sample_rate
        if not n <= MAX_TRAJECTORY_SAMPLES:
            raise SpecError(
                f"{source}: {prefix}controller.sample_rate = {sample_rate:g} Hz with a {name} trajectory of "
                f"{d:.4g} s gives {n:.3g} samples per run, more than the {MAX_TRAJECTORY_SAMPLES} accepted; "
                f"lower the rate, or trajectory.moves, dwell or travel, or raise v_max/a_max")


# TOML key -> dataclass attribute where the names differ.
_ATTR = {("pid", "pole"): "pid_pole",
         **{("plant", k): f"plant_{k}" for k in ("mode_hz", "mode_damping", "mode_ratio", "encoder", "delay_samples",
                                                 "noise_std")},
         ("margins", "gain_db"): "min_gain_margin_db", ("margins", "phase_deg"): "min_phase_margin_deg",
         ("margins", "delay_samples"): "min_delay_margin_samples", ("margins", "modulus"): "min_modulus_margin",
         ("evidence", "first_mode_hz"): "evidence_first_mode_hz", ("evidence", "damping"): "evidence_damping"}


def default_spec() -> Spec:
    """The spec of an empty ``spec.toml`` (the paper's setting)."""
    return spec_from_mapping({}, "spec.toml")


def _fail(source: str, path: str, msg: str) -> SpecError:
    return SpecError(f"{source}: {path}{msg}")


#: Largest relative distance between a measured sample rate and its nominal value
#: (:func:`nominal_rate`): 10 ppm, the order of a drive's crystal tolerance.
NOMINAL_RATE_TOLERANCE = 1e-5


def nominal_rate(measured: float, digits: int = 4, rel: float = NOMINAL_RATE_TOLERANCE) -> float:
    """The round rate a measured sample rate stands for, Hz.

    A rate estimated from a log's time stamps is the nominal rate plus rounding
    and clock error (2500.0000000058 Hz).  ``controller.json`` states the rate the
    drive is programmed with; its ``sample_period`` stays the period validated
    (the two agree within the loader's 1e-9).
    The measured rate is rounded to 1, 2, ... ``digits`` significant digits and
    the first rounding within :data:`NOMINAL_RATE_TOLERANCE` of it is returned;
    a rate that no such round number explains (4166.67 Hz) is returned as
    measured.

    Parameters
    ----------
    measured : float
        Sample rate, Hz (positive, finite).
    digits : int
        Most significant digits a nominal rate has.
    rel : float
        Largest relative distance between the measured and the nominal rate.

    Returns
    -------
    float
        Hz.
    """
    if not (math.isfinite(measured) and measured > 0):
        return measured
    for d in range(1, digits + 1):
        r = float(f"{measured:.{d}g}")
        if abs(r - measured) <= rel * measured:
            return r
    return measured


def spec_from_mapping(data: Mapping[str, Any], source: str = "spec.toml", *, prefix: str = "",
                      sample_rate_default: float | None = None) -> Spec:
    """Validate a parsed spec and resolve its defaults.

    Parameters
    ----------
    data : mapping
        Parsed TOML (sections -> keys -> values).
    source : str
        File name used as the first word of every error.
    prefix : str
        Prepended to key paths in errors (e.g. ``"$.spec."`` inside tuning.json).
    sample_rate_default : float, optional
        Default of ``controller.sample_rate`` (Hz) instead of 2500, e.g. the
        rate of the excitation log recorded in ident.json.

    Returns
    -------
    Spec

    Raises
    ------
    SpecError
        Naming the key path: an unknown section or key, a wrong type, a
        non-positive rate or size, or a sample rate too low for a requested
        bandwidth (``controller.sample_rate``).
    """
    if not isinstance(data, Mapping):
        raise _fail(source, prefix.rstrip("."), f": expected a table, got {type(data).__name__}")
    values: dict[str, Any] = {}
    for section, table in data.items():
        if section == "compute":
            continue  # where the work runs, not what is computed: commission.executor.compute_scheduler
        if section not in _SCHEMA:
            raise _fail(source, f"{prefix}{section}", f": unknown section (known: {', '.join(_SCHEMA)})")
        if not isinstance(table, Mapping):
            raise _fail(source, f"{prefix}{section}", f": expected a table, got {table!r}")
        schema = _SCHEMA[section]
        for key, raw in table.items():
            path = f"{prefix}{section}.{key}"
            if section == "trajectory" and key in profile_keys():
                continue  # the machine's moves: parse_profile below
            if key not in schema:
                known = [*schema, *(profile_keys() if section == "trajectory" else ())]
                raise _fail(source, path, f": unknown key (known in [{section}]: {', '.join(known)})")
            typ, _default, positive, unit = schema[key]
            u = f" {unit}" if unit else ""
            if typ is str:
                choices = _CHOICES[(section, key)]
                if raw not in choices:
                    raise _fail(source, path, f" = {raw!r}: expected one of {', '.join(map(repr, choices))}")
                values[(section, key)] = raw
                continue
            if typ is int:
                if isinstance(raw, bool) or not isinstance(raw, int):
                    raise _fail(source, path, f" = {raw!r}: expected an integer")
                val: Any = int(raw)
            else:
                if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
                    raise _fail(source, path, f" = {raw!r}: expected a finite number{u and ' in' + u}")
                val = float(raw)
            if positive and not val > 0:
                raise _fail(source, path, f" = {val!r}{u} must be positive")
            if not positive and val < 0:
                raise _fail(source, path, f" = {val!r}{u} must not be negative")
            check_range(source, path, (section, key), val, unit)
            values[(section, key)] = val

    def get(section: str, key: str) -> Any:
        if (section, key) == ("controller", "sample_rate") and sample_rate_default is not None:
            return values.get((section, key), float(sample_rate_default))
        return values.get((section, key), _SCHEMA[section][key][1])

    for key in ("mode_ratio", "mode_damping"):
        if values.get(("plant", key), 0.0) >= 1.0:
            raise _fail(source, f"{prefix}plant.{key}", f" = {values[('plant', key)]!r} must be below 1")
    fs = get("controller", "sample_rate")
    if ("controller", "sample_rate") not in values:  # the default may come from ident.json's log rate
        if not (isinstance(fs, (int, float)) and math.isfinite(fs) and fs > 0):
            raise _fail(source, f"{prefix}controller.sample_rate", f" = {fs!r} Hz (the log's rate): not a positive rate")
        check_range(source, f"{prefix}controller.sample_rate (the log's rate)", ("controller", "sample_rate"), fs, "Hz")
    obs_req = ("controller", "observer_pole") in values
    pid_req = ("pid", "pole") in values
    obs = get("controller", "observer_pole") if obs_req else OBSERVER_POLE_FRACTION * fs
    pid = get("pid", "pole") if pid_req else PID_POLE_FRACTION * fs
    b1, b2 = get("trajectory", "beta1"), get("trajectory", "beta2")
    # Fastest root magnitude of s^2 + b1 s + b2 (real or complex pair).
    disc = b1 * b1 - 4.0 * b2
    filt = (b1 + math.sqrt(disc)) / 2.0 if disc >= 0 else math.sqrt(b2)
    for what, omega in (("observer poles", obs), ("PID poles", pid), ("reference filter (58) poles", filt)):
        need = bandwidth_rule(omega)
        if fs < need:
            dflt = (" (default: the log's rate)" if sample_rate_default is not None
                    and ("controller", "sample_rate") not in values else "")
            raise _fail(
                source,
                f"{prefix}controller.sample_rate",
                f" = {fs:g} Hz{dflt} is too low for {what} at -{omega:g} rad/s "
                f"(need >= {need:g} Hz: omega*T <= {MAX_OMEGA_T:g})",
            )
    traj = data.get("trajectory", {})
    profile = parse_profile(traj, source, prefix)
    if profile is not None:
        # The envelope is the moves' own unless given; a given one must cover them.
        for key, unit, have in (("v_max", "m/s", profile.v_peak), ("a_max", "m/s^2", profile.a_peak),
                                ("travel", "m", profile.span)):
            if ("trajectory", key) not in values:
                check_range(source, f"{prefix}trajectory.{key} (from {profile.label})", ("trajectory", key), have, unit)
                values[("trajectory", key)] = have
            elif values[("trajectory", key)] < have * (1.0 - 1e-9):
                what = {"v_max": "peak speed", "a_max": "peak acceleration", "travel": "span"}[key]
                raise _fail(source, f"{prefix}trajectory.{key}",
                            f" = {values[('trajectory', key)]:g} {unit} is below the {what} of {profile.label}, "
                            f"{have:.6g} {unit}; leave trajectory.{key} out (the moves then set it) or raise it")
    travel, vmax, amax = get("trajectory", "travel"), get("trajectory", "v_max"), get("trajectory", "a_max")
    rv, ra = get("trajectory", "reference_v_max"), get("trajectory", "reference_a_max")
    for key, val, top in (("reference_v_max", rv, vmax), ("reference_a_max", ra, amax)):
        if val is not None and val > top * (1.0 + 1e-9):
            raise _fail(source, f"{prefix}trajectory.{key}",
                        f" = {val:g} is above trajectory.{key[10:]} = {top:g}: the reference scenarios (Case 1, "
                        f"Case 2) stay within the envelope")
    if profile is None or (rv is not None and ra is not None):
        vmax_c, amax_c = (vmax if rv is None else rv), (amax if ra is None else ra)
        key = "v_max" if rv is None else "reference_v_max"
        if vmax_c * vmax_c / amax_c > travel:
            # Still a valid (triangular) Case 2, but v_max is then unreachable: say so now.
            raise _fail(
                source,
                f"{prefix}trajectory.{key}",
                f" = {vmax_c:g} m/s cannot be reached within trajectory.travel = {travel:g} m at "
                f"a_max = {amax_c:g} m/s^2 (need v_max^2/a_max <= travel)",
            )
    return Spec(
        sample_rate=fs,
        u_max=get("controller", "u_max"),
        observer_pole=obs,
        quantization=get("controller", "quantization"),
        theta1_0=get("controller", "theta1_0"),
        v_max=vmax,
        a_max=amax,
        travel=travel,
        dwell=get("trajectory", "dwell"),
        moves=get("trajectory", "moves"),
        beta1=b1,
        beta2=b2,
        reference_v_max=rv,
        reference_a_max=ra,
        profile=profile,
        e_rms=get("targets", "e_rms"),
        e_f=get("targets", "e_f"),
        c_u=get("targets", "c_u"),
        pid_pole=pid,
        budget=get("tune", "budget"),
        monte_carlo=get("tune", "monte_carlo"),
        margin=get("tune", "margin"),
        **{_ATTR[("plant", k)]: get("plant", k) for k in _SCHEMA["plant"]},
        **{_ATTR[("margins", k)]: get("margins", k) for k in _SCHEMA["margins"]},
        **{_ATTR[("evidence", k)]: get("evidence", k) for k in _SCHEMA["evidence"]},
    )


def read_spec_toml(path: str | os.PathLike[str] | None) -> tuple[dict[str, Any], str]:
    """Parse ``spec.toml`` (no validation); ``None`` gives an empty spec.

    Returns
    -------
    data : dict
        The parsed TOML.
    source : str
        The file name for error messages (``"spec (defaults)"`` for ``None``).

    Raises
    ------
    InputFileError
        The file is missing.
    SpecError
        The file is not valid TOML.
    """
    if path is None:
        return {}, "spec (defaults)"
    name = os.fspath(path)
    return read_toml(name), name


def load_spec(path: str | os.PathLike[str] | None, *, sample_rate_default: float | None = None) -> Spec:
    """Read and validate ``spec.toml``; ``None`` gives :func:`default_spec`.

    Parameters
    ----------
    path : path-like or None
    sample_rate_default : float, optional
        Default sample rate, Hz (see :func:`spec_from_mapping`).

    Raises
    ------
    InputFileError
        The file is missing.
    SpecError
        The TOML does not parse, or a key is bad (see :func:`spec_from_mapping`).
    """
    data, name = read_spec_toml(path)
    return spec_from_mapping(data, name, sample_rate_default=sample_rate_default)


def bandwidth_rule(omega: float) -> float:
    """Lowest sample rate (Hz) accepted for a bandwidth ``omega`` (rad/s)."""
    return omega / MAX_OMEGA_T
