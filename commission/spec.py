"""The tuning spec (``spec.toml``) of ``commission tune``: validated and resolved.

A spec states what the user wants from the axis: the controller sample rate,
the input limit, the trajectory envelope, and the accuracy and chattering
targets.  Every key is optional; an absent key takes its default, so an empty
file (or no ``--spec`` at all) reproduces the paper's setting (Xu & Yao 2001,
§4.3).

One definition
--------------
The keys, their types, defaults (or the rule of a derived default), ranges,
units and one-line docs are the rows of
:data:`commission.formats.spec_toml.SPEC_KEYS`, and nothing here repeats
them: :class:`Spec`'s fields and defaults, :data:`RANGES`, the strict model
that :func:`spec_from_mapping` validates with (pydantic, see
:mod:`commission.formats.table` for why), ``commission tune --help``,
docs/interface.md §6 and docs/schemas/spec.schema.json all come from those
rows.  This module adds what a single key cannot say: the rules across keys
(the bandwidth rule below, the envelope the machine's moves set, Case 2's
reach within ``travel``, a structural mode's fractions below 1), the derived
defaults that follow the sample rate, and the samples per trajectory.

Unknown keys, wrong types, values outside their ranges and a sample rate too
low for a requested bandwidth are rejected by :func:`load_spec` /
:func:`spec_from_mapping` with one :class:`commission.errors.SpecError` line
naming the TOML key path, before any simulation runs.

Bandwidth rule
--------------
A requested bandwidth omega (rad/s) needs ``omega / sample_rate <= MAX_OMEGA_T``
(the upper end of the ``omega h = 0.15 ... 0.5`` rule of thumb of Åström &
Wittenmark, *Computer-Controlled Systems*).  It is checked for the observer
pole, the PID pole and the fastest root of the reference filter (58).
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Any, Mapping

from pydantic import ValidationError

from commission.errors import SpecError, UsageError
from commission.infra.files import read_toml
from commission.formats.spec_toml import (DEFAULT_QUANTIZATION, MAX_SAMPLE_RATE, OBSERVER_POLE_FRACTION,
                                          PID_POLE_FRACTION, SPEC_FIELDS, SPEC_KEYS, SpecToml)
from commission.formats.table import Key, Scaled, first_error, sections
from commission.moves import MOVE_KEYS, UserProfile, parse_profile, profile_keys

__all__ = ["DEFAULT_QUANTIZATION", "MAX_SAMPLE_RATE", "OBSERVER_POLE_FRACTION", "PID_POLE_FRACTION", "MAX_OMEGA_T",
           "RANGES", "Spec", "spec_from_mapping", "load_spec", "default_spec", "check_range", "check_flags"]

#: Largest accepted omega*T for any requested bandwidth omega (rad/s) at period T (s).
MAX_OMEGA_T = 0.5

#: (section, key) -> the table's row, for the keys a :class:`Spec` holds.
_KEYS: dict[tuple[str, str], Key] = {(k.section, k.name): k for k in SPEC_FIELDS}


def _default(k: Key) -> Any:
    """A field's default in :class:`Spec`: the table's, or its :class:`Scaled` rule at the default rate."""
    if isinstance(k.rule, Scaled):
        section, name = k.rule.of.split(".")
        return k.rule.fraction * _KEYS[(section, name)].default
    return k.default


def _annotation(k: Key) -> str:
    typ = k.type.__name__
    return typ if k.default is not None or isinstance(k.rule, Scaled) else f"{typ} | None"


_SpecFields = dataclasses.make_dataclass(
    "_SpecFields",
    [(k.field_name, _annotation(k), dataclasses.field(default=_default(k))) for k in SPEC_FIELDS]
    + [("profile", "UserProfile | None", dataclasses.field(default=None))],
    frozen=True)
_SpecFields.__module__ = __name__


class Spec(_SpecFields):  # type: ignore[misc, valid-type]
    """A validated tuning spec with every default resolved.

    A frozen dataclass whose fields are the rows of
    :data:`commission.formats.spec_toml.SPEC_KEYS` (attribute ``Key.attr``, else the
    key name; units and defaults as there; ``None``: a default resolved later, from
    ident.json or by tune's search), plus

    profile : UserProfile or None
        The machine's own moves (``[trajectory] file`` or ``[[trajectory.move]]``), validated as
        the ``user/...`` scenarios; ``None``: only Case 1 and Case 2.
    """

    __slots__ = ()

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
        out: dict[str, dict[str, Any]] = {section: {} for section in sections(SPEC_FIELDS)}
        for k in SPEC_FIELDS:
            value = getattr(self, k.field_name)
            if value is not None:
                out[k.section][k.name] = value
        if self.profile is not None:
            out["trajectory"].update(self.profile.to_spec())
        return out


#: Most samples one simulated trajectory may hold (Case 1 or Case 2 at the controller rate):
#: 100 s at 2.5 kHz, 12 times the paper's longest.  Every scenario of tune and validate
#: keeps traces of this length, so this bounds their memory and time.
MAX_TRAJECTORY_SAMPLES = 250_000

#: Accepted range of every number of the spec, (lowest, highest), both inclusive: a view of the
#: table's ranges (read by the artifact loaders for the same quantities), plus one
#: ``[[trajectory.move]]`` table's (:data:`commission.moves.MOVE_KEYS`).
RANGES: dict[tuple[str, str], tuple[float, float]] = {
    **{(k.section, k.name): k.range for k in SPEC_FIELDS if k.range is not None},
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
    values = _given_values(data, source, prefix)

    def get(section: str, key: str) -> Any:
        if (section, key) == ("controller", "sample_rate") and sample_rate_default is not None:
            return values.get((section, key), float(sample_rate_default))
        return values.get((section, key), _KEYS[(section, key)].default)

    for key in ("mode_ratio", "mode_damping"):
        if values.get(("plant", key), 0.0) >= 1.0:
            raise _fail(source, f"{prefix}plant.{key}", f" = {values[('plant', key)]!r} must be below 1")
    fs = get("controller", "sample_rate")
    if ("controller", "sample_rate") not in values:  # the default may come from ident.json's log rate
        if not (isinstance(fs, (int, float)) and math.isfinite(fs) and fs > 0):
            raise _fail(source, f"{prefix}controller.sample_rate", f" = {fs!r} Hz (the log's rate): not a positive rate")
        check_range(source, f"{prefix}controller.sample_rate (the log's rate)", ("controller", "sample_rate"), fs,
                    _KEYS[("controller", "sample_rate")].unit)
    for k in SPEC_FIELDS:  # defaults that follow another key (the poles follow the rate): the table's rule
        if isinstance(k.rule, Scaled) and (k.section, k.name) not in values:
            values[(k.section, k.name)] = k.rule.fraction * get(*k.rule.of.split("."))
    obs, pid = get("controller", "observer_pole"), get("pid", "pole")
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
        for key, have in (("v_max", profile.v_peak), ("a_max", profile.a_peak), ("travel", profile.span)):
            unit = _KEYS[("trajectory", key)].unit
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
    return Spec(profile=profile, **{k.field_name: get(*key) for key, k in _KEYS.items()})


def _given_values(data: Mapping[str, Any], source: str, prefix: str) -> dict[tuple[str, str], Any]:
    """The keys the file gives, (section, key) -> value, checked one by one against the table's model.

    ``[compute]`` (where the work runs: :func:`commission.infra.executor.compute_scheduler`) and the
    machine's moves (:func:`commission.moves.parse_profile`) are read by their own readers.

    Raises
    ------
    SpecError
        The file's first bad key (:func:`commission.formats.table.first_error`).
    """
    checked = {s: t for s, t in data.items() if s != "compute"}
    try:
        model = SpecToml.model_validate(checked)
    except ValidationError as exc:
        raise SpecError(first_error(exc, checked, SPEC_KEYS, source=source, prefix=prefix,
                                    extra_known={"trajectory": profile_keys()})) from None
    values: dict[tuple[str, str], Any] = {}
    for section in model.model_fields_set:
        table = getattr(model, section)
        for key in table.model_fields_set:
            if (section, key) in _KEYS:
                values[(section, key)] = getattr(table, key)
    return values


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
