"""Options shared by several commands: one definition of each flag.

The identify flags (``commission identify`` and ``commission run``): each factory returns a
fresh ``typer.Option`` (typer reads the parameter's default to build the command);
:func:`identify_options` turns the parsed flags into one
:class:`commission.identification.IdentifyOptions`, with every check in one place, and
:func:`with_identify_flags` gives a command all of them at once.  The validation flags
(``commission validate`` and ``commission run``) are given the same way by
:func:`with_validate_flags`, as one :class:`ValidateFlags`.
"""

from __future__ import annotations

import enum
import functools
import inspect
import math
import typing
from pathlib import Path
from typing import Any, Callable, List, NamedTuple, Optional, TypeVar

import typer

from commission.errors import UsageError
from commission.identification import BoundsOptions, IdentifyOptions, check_input_gain, parse_fix, payload_from_kg
from commission.logs import check_counts_per_rev, parse_mapping

F = TypeVar("F", bound=Callable[..., Any])


class Friction(str, enum.Enum):
    auto = "auto"
    coulomb = "coulomb"
    stribeck = "stribeck"


SIGN_KEY_HELP = ("Key file: sign controller.json with HMAC-SHA256 (default: the file named by $COMMISSION_SIGN_KEY; "
                 "load_controller(path, key=...) then refuses files not signed with it).")
SCHEDULER_HELP = ("Dask scheduler tcp://HOST:PORT to run the simulations on (default: COMMISSION_SCHEDULER, else "
                  "the spec's compute.scheduler, else local threads); needs pip install \"commission[dask]\"; "
                  "an unreachable one is exit 2.")
Q_UNIT_HELP = ("Unit of q (and q_ref) in a file without a q_unit attribute (CSV, v5 .mat, .npy/.npz): m, mm, um, "
               "or rad (a rotary axis); default m. Refused when it contradicts the file's attribute.")
COUNTS_PER_REV_HELP = ("Encoder counts per revolution: q (and q_ref) in the file are counts, read as rad "
                       "(q·2π/N; a rotary axis, e.g. 8192 for the ODrive runs), before --gear and --lead. "
                       "Refused with a --q-unit other than rad, or for a file that declares its q_unit.")
LEAD_HELP = ("Screw lead in m per rad of the screw (5 mm/rev: 0.005/(2π) = 7.958e-4): converts a rotary log's q "
             "(rad) to the carriage's position in m before identification; everything derived is then in m. "
             "Refused for a log not in rad.")
GEAR_HELP = ("Gear ratio, motor rad per load rad (> 0): the log's motor angle divided by it is the load's angle; "
             "with --lead, the screw's angle. Refused for a log not in rad.")
FRICTION_HELP = ("Friction model. auto: the Stribeck curve when the log supports it, else the Coulomb model "
                 "with a warning; stribeck: refuse a log that does not support it.")

class _Flag(NamedTuple):
    """One identify flag: the command's parameter, its type, default, metavar (None: typer's) and help."""

    param: str
    kind: Any
    default: Any
    metavar: Optional[str]
    help: str


#: Every identify flag, in the order --help lists them (:func:`opt`, :func:`with_identify_flags`).
_IDENTIFY: dict[str, _Flag] = {
    "--map": _Flag("map_", List[str], [], "NAME=SOURCE",
                   "NAME=SOURCE: contract channel -> name in the file (repeatable)."),
    "--input-gain": _Flag("input_gain", float, 1.0, None,
                          "Multiplies u before identification (e.g. N/V); other than 1 it needs --u-unit."),
    "--u-unit": _Flag("u_unit", Optional[str], None, None,
                      "Unit of u after --input-gain (V, N, A, Nm, %); default: the file's (only without "
                      "--input-gain)."),
    "--sample-rate": _Flag("sample_rate", Optional[float], None, "HZ",
                           "Hz, for a file without t."),
    "--q-unit": _Flag("q_unit", Optional[str], None, None, Q_UNIT_HELP),
    "--friction": _Flag("friction", Friction, Friction.auto, None, FRICTION_HELP),
    "--ripple-pitch": _Flag("ripple_pitch", List[str], [], "P",
                            "Force-ripple pitch P in m (rad on a rotary axis): fits sin/cos(2πq/P); repeatable, "
                            "one sinusoid per pitch (e.g. the harmonics of one cogging period); 'auto' (the "
                            "default): find it on the log's constant-velocity legs; 'none': no ripple."),
    "--validate-on": _Flag("validate_on", Optional[Path], None, "LOG2",
                           "Second log for the cross-test relative error; identify also takes a folder (its logs "
                           "read as the identification's: legs, or segments fitted together)."),
    "--k-sigma": _Flag("k_sigma", float, 3.0, None,
                       "Standard deviations covered by the theta box."),
    "--model-margin": _Flag("model_margin", float, 0.2, None,
                            "Relative margin on M and B for model error."),
    "--payload-min": _Flag("payload_min", Optional[float], None, None,
                           "Least added mass, u-unit·s²/m, or u-unit·s²/rad on a rotary axis (default 0)."),
    "--payload-max": _Flag("payload_max", Optional[float], None, None,
                           "Largest added mass, u-unit·s²/m, or u-unit·s²/rad on a rotary axis (default 3 M)."),
    "--payload-min-kg": _Flag("payload_min_kg", Optional[float], None, None,
                              "Least added mass in kg (needs --force-constant)."),
    "--payload-max-kg": _Flag("payload_max_kg", Optional[float], None, None,
                              "Largest added mass in kg (needs --force-constant)."),
    "--force-constant": _Flag("force_constant", Optional[float], None, None,
                              "N per u-unit, to convert kg payloads."),
    "--disturbance-bound": _Flag("disturbance_bound", Optional[float], None, None,
                                 "Largest load force, u-unit (default 10 max(fc, fs))."),
    "--format": _Flag("log_format", Optional[str], None, None,
                      "Force the log format: hdf5, csv, mat, epos or npy (default: from the content, then the "
                      "extension)."),
    "--resample": _Flag("resample", Optional[float], None, "HZ",
                        "Interpolate the log onto a uniform grid at HZ first (irregular time stamps, e.g. host "
                        "polling)."),
    "--fix": _Flag("fix", List[str], [], "NAME=VALUE",
                   "A known parameter, e.g. M=0.027 (u-unit·s²/m, or u-unit·s²/rad on a rotary axis): not fitted; "
                   "a log without acceleration content then still gives theta and its box."),
    "--lead": _Flag("lead", Optional[float], None, "M_PER_RAD", LEAD_HELP),
    "--gear": _Flag("gear", Optional[float], None, "RATIO", GEAR_HELP),
    "--counts-per-rev": _Flag("counts_per_rev", Optional[float], None, "N", COUNTS_PER_REV_HELP),
}


def opt(flag: str, table: Optional[dict[str, _Flag]] = None) -> Any:
    """A fresh ``typer.Option`` for the flag ``flag`` of ``table`` (default: the identify flags, :data:`_IDENTIFY`)."""
    f = (_IDENTIFY if table is None else table)[flag]
    return typer.Option(list(f.default) if isinstance(f.default, list) else f.default, flag, help=f.help,
                        **({"metavar": f.metavar} if f.metavar else {}))


class ValidateFlags(NamedTuple):
    """The validation flags of ``validate`` and ``run``, as the command receives them (:func:`with_validate_flags`).

    Attributes
    ----------
    gate : Path or None
        ``--gate``: the gate TOML (None: the table's defaults).
    force : bool
        ``--force``: overwrite existing outputs in ``--out-dir``.
    seed : int
        ``--seed``: seed of the Monte-Carlo plants (and, in ``run``, of the tuning search).
    monte_carlo : int
        ``--monte-carlo``: Monte-Carlo plants drawn from the theta box.
    workers : int or None
        ``--workers``: simulation threads (None: one per CPU).
    sign_key : Path or None
        ``--sign-key``: the key file that signs controller.json (None: the file named by
        ``$COMMISSION_SIGN_KEY``, if set).
    scheduler : str or None
        ``--scheduler``: the Dask scheduler's ``tcp://HOST:PORT`` (None: ``$COMMISSION_SCHEDULER``, else
        the spec's ``compute.scheduler``, else local threads).
    """

    gate: Optional[Path]
    force: bool
    seed: int
    monte_carlo: int
    workers: Optional[int]
    sign_key: Optional[Path]
    scheduler: Optional[str]


def validate_flags(seed_help: str, monte_carlo_help: str) -> dict[str, _Flag]:
    """The validation flags, in the order --help lists them; ``run`` and ``validate`` word two helps their own way."""
    from commission.validate import DEFAULT_MONTE_CARLO

    return {
        "--gate": _Flag("gate", Optional[Path], None, None, "Gate TOML (default: the table's defaults, below)."),
        "--force": _Flag("force", bool, False, None, "Overwrite existing outputs in --out-dir."),
        "--seed": _Flag("seed", int, 0, None, seed_help),
        "--monte-carlo": _Flag("monte_carlo", int, DEFAULT_MONTE_CARLO, None, monte_carlo_help),
        "--workers": _Flag("workers", Optional[int], None, None, "Simulation threads, 1-256 (default: one per CPU)."),
        "--sign-key": _Flag("sign_key", Optional[Path], None, None, SIGN_KEY_HELP),
        "--scheduler": _Flag("scheduler", Optional[str], None, "tcp://HOST:PORT", SCHEDULER_HELP),
    }


def bounds_options(
    k_sigma: float,
    model_margin: float,
    payload_min: Optional[float],
    payload_max: Optional[float],
    payload_min_kg: Optional[float],
    payload_max_kg: Optional[float],
    force_constant: Optional[float],
    disturbance_bound: Optional[float],
) -> BoundsOptions:
    """Turn the bound flags into :class:`BoundsOptions` (kg converted with the force constant)."""
    if (payload_min_kg is not None or payload_max_kg is not None) and force_constant is None:
        raise UsageError("--payload-min-kg/--payload-max-kg need --force-constant (N per u-unit)")
    if payload_min is not None and payload_min_kg is not None:
        raise UsageError("give either --payload-min or --payload-min-kg, not both")
    if payload_max is not None and payload_max_kg is not None:
        raise UsageError("give either --payload-max or --payload-max-kg, not both")
    if payload_min_kg is not None:
        payload_min = payload_from_kg(payload_min_kg, force_constant)  # type: ignore[arg-type]
    if payload_max_kg is not None:
        payload_max = payload_from_kg(payload_max_kg, force_constant)  # type: ignore[arg-type]
    for flag, v in (("--payload-min", payload_min), ("--payload-max", payload_max),
                    ("--disturbance-bound", disturbance_bound), ("--k-sigma", k_sigma)):
        if v is not None and v < 0:
            raise UsageError(f"{flag} must be >= 0, got {v}")
    if not 0 <= model_margin < 1:
        raise UsageError(f"--model-margin must be in [0, 1), got {model_margin}")
    return BoundsOptions(k_sigma=k_sigma, model_margin=model_margin, payload_min=payload_min or 0.0,
                         payload_max=payload_max, disturbance_bound=disturbance_bound)


def parse_ripple_pitch(values: List[str]) -> tuple[tuple[float, ...], bool]:
    """``--ripple-pitch`` values: ``(pitches, search)``; bad: :class:`UsageError`.

    None given or ``auto`` alone: search the logs' legs for the pitch (the default); ``none``
    alone: no ripple; otherwise the pitches (q-unit, each > 0).
    """
    words = [v.strip().lower() for v in values]
    for word in ("auto", "none"):
        if word in words and len(values) > 1:
            raise UsageError(f"--ripple-pitch: give either {word} or the pitches, not both")
    if not values or words == ["auto"]:
        return (), True
    if words == ["none"]:
        return (), False
    out = []
    for v in values:
        try:
            p = float(v)
        except ValueError:
            raise UsageError(f"--ripple-pitch: expected a pitch in m (rad on a rotary axis), auto or none, got {v!r}"
                             ) from None
        if not (math.isfinite(p) and p > 0):
            raise UsageError(f"--ripple-pitch must be > 0 (m, or rad on a rotary axis), got {v}")
        out.append(p)
    return tuple(out), False


def identify_options(*, map_: List[str], input_gain: float, u_unit: Optional[str], sample_rate: Optional[float],
                     q_unit: Optional[str], friction: Friction, ripple_pitch: List[str],
                     validate_on: Optional[Path], k_sigma: float, model_margin: float,
                     payload_min: Optional[float], payload_max: Optional[float], payload_min_kg: Optional[float],
                     payload_max_kg: Optional[float], force_constant: Optional[float],
                     disturbance_bound: Optional[float], log_format: Optional[str], resample: Optional[float],
                     fix: List[str], lead: Optional[float] = None, gear: Optional[float] = None,
                     counts_per_rev: Optional[float] = None) -> IdentifyOptions:
    """The parsed identify flags as one :class:`IdentifyOptions` (bad values: :class:`UsageError`).

    Checked here, before any output is touched: ``--input-gain`` other than 1 needs
    ``--u-unit`` (:func:`commission.identification.check_input_gain`), so that every
    artifact labels u with its unit after the gain; ``--counts-per-rev`` is a positive finite
    number that no ``--q-unit`` contradicts (:func:`commission.logs.check_counts_per_rev`).
    """
    check_input_gain(input_gain, u_unit)
    check_counts_per_rev(counts_per_rev, q_unit)
    pitches, find_ripple = parse_ripple_pitch(ripple_pitch)
    return IdentifyOptions(
        mapping=parse_mapping(map_), input_gain=input_gain, sample_rate=sample_rate, friction=friction.value,
        ripple_pitch=pitches, find_ripple=find_ripple, validate_on=str(validate_on) if validate_on is not None else None,
        bounds=bounds_options(k_sigma, model_margin, payload_min, payload_max, payload_min_kg, payload_max_kg,
                              force_constant, disturbance_bound),
        u_unit=u_unit, q_unit=q_unit, fmt=log_format, resample=resample, fix=parse_fix(fix), lead=lead, gear=gear,
        counts_per_rev=counts_per_rev)


def with_flags(slot: str, table: dict[str, _Flag], build: Callable[..., Any]) -> Callable[[F], F]:
    """Give a typer command every flag of ``table`` in place of its parameter ``slot``, built into ``slot``.

    typer sees the flags where ``slot`` stands in the command's signature (so --help lists
    them there, in the table's order), and the command receives ``build(**flags)`` as
    ``slot``; ``build``'s checks run before the command's body.
    """

    def decorate(fn: F) -> F:
        sig = inspect.signature(fn)
        hints = typing.get_type_hints(fn)
        params: list[inspect.Parameter] = []
        for p in sig.parameters.values():
            if p.name == slot:
                params += [inspect.Parameter(f.param, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=opt(flag, table),
                                             annotation=f.kind) for flag, f in table.items()]
            else:
                params.append(p.replace(annotation=hints.get(p.name, p.annotation)))
        names = [f.param for f in table.values()]

        @functools.wraps(fn)
        def wrapper(**kwargs: Any) -> Any:
            built = build(**{name: kwargs.pop(name) for name in names})
            return fn(**{slot: built}, **kwargs)

        # typer reads the signature and the type hints: both name the flags, with evaluated types.
        ret = hints.get("return", None)
        wrapper.__signature__ = sig.replace(parameters=params, return_annotation=ret)  # type: ignore[attr-defined]
        wrapper.__annotations__ = {**{p.name: p.annotation for p in params}, "return": ret}
        return wrapper  # type: ignore[return-value]

    return decorate


def with_identify_flags(fn: F) -> F:
    """Give a typer command every identify flag in place of its parameter ``o``, parsed into ``o``.

    ``identify`` and ``run`` take the same flags: they are declared once here (their
    defaults and help in :data:`_IDENTIFY`), typer sees them where ``o`` stands in the
    command's signature, and the command receives them as one
    :class:`commission.identification.IdentifyOptions` (:func:`identify_options`, whose
    checks run before the command's body).
    """
    return with_flags("o", _IDENTIFY, identify_options)(fn)


def with_validate_flags(seed_help: str, monte_carlo_help: str) -> Callable[[F], F]:
    """Give a typer command the validation flags (:func:`validate_flags`) in place of its parameter ``v``.

    ``validate`` and ``run`` validate the same way: the command receives the flags as one
    :class:`ValidateFlags`.
    """
    return with_flags("v", validate_flags(seed_help, monte_carlo_help), ValidateFlags)
