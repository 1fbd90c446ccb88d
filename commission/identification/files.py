"""``commission identify LOG...``: one log, a friction test of several, or several logs fitted as segments.

:func:`identify_files` reads the logs once and hands them to :func:`identify_log` (one log,
or segments of one axis) or :func:`identify_legs` (a friction test, :func:`classify_logs`).
"""

from __future__ import annotations

from typing import Mapping, Sequence

from commission.errors import UsageError
from commission.identification.legs import LegsOutcome, classify_logs, identify_legs
from commission.identification.options import check_input_gain
from commission.identification.segments import IdentifyOutcome, identify_log
from commission.logs import ExcitationLog, load_log
from commission.units import axis_units_context


def identify_files(paths: Sequence[str], *, validate_on: Sequence[str] = (), ripple_pitch: float | Sequence[float]
                   | None = None, resample: float | None = None, **options: object) -> IdentifyOutcome | LegsOutcome:
    """Identify one axis from one log or several (``commission identify LOG...``).

    One log: :func:`identify_log`.  Several logs are read once and then

    - constant-speed legs in both directions (:func:`classify_logs`): a friction test,
      :func:`identify_legs` (``ripple_pitch`` and ``resample`` are refused: one
      leg per file gives one map point, no ripple or time base to fit);
    - otherwise (a log with excitation among them, or constant-speed runs all one
      way): fitted together, each log its own segment, :func:`identify_log` with the
      list of paths; the first warning says which files are which.

    Parameters
    ----------
    paths : sequence of str
        Log files, folders already expanded (:func:`expand_log_paths`).
    validate_on : sequence of str
        Logs for the cross-test relative error (folders expanded), read the same way.
    ripple_pitch, resample, **options
        As in :func:`identify_log` (``mapping``, ``input_gain``, ``sample_rate``,
        ``friction``, ``bounds``, ``u_unit``, ``q_unit``, ``fmt``, ``fix``, ``lead``, ``gear``,
        ``counts_per_rev``).

    Returns
    -------
    IdentifyOutcome or LegsOutcome
    """
    paths = list(paths)
    if not paths:
        raise UsageError("identify: no log file given")
    if len(paths) == 1:
        return identify_log(paths[0], validate_on=list(validate_on) or None, ripple_pitch=ripple_pitch,
                            resample=resample, **options)  # type: ignore[arg-type]
    check_input_gain(options.get("input_gain", 1.0), options.get("u_unit"))  # type: ignore[arg-type]
    load = {k: options.get(k) for k in ("mapping", "sample_rate", "q_unit", "fmt", "counts_per_rev")}
    gain = float(options.get("input_gain", 1.0))  # type: ignore[arg-type]
    logs = [load_log(p, input_gain=gain, **load) for p in paths]  # type: ignore[arg-type]
    val_logs = [load_log(p, input_gain=gain, **load) for p in validate_on]  # type: ignore[arg-type]
    rotary = options.get("lead") is None and logs[0].q_unit_in_file == "rad"
    with axis_units_context("rad" if rotary else "m"):  # the numerics' messages in the axis's unit
        return _identify_loaded(paths, logs, val_logs, validate_on=validate_on, ripple_pitch=ripple_pitch,
                                resample=resample, options=options)


def _identify_loaded(paths: list[str], logs: list[ExcitationLog], val_logs: list[ExcitationLog], *,
                     validate_on: Sequence[str], ripple_pitch: float | Sequence[float] | None,
                     resample: float | None, options: Mapping[str, object]) -> IdentifyOutcome | LegsOutcome:
    """:func:`identify_files` once its logs are read: a friction test or segments of one fit."""
    kind, note = classify_logs(logs)
    if kind == "legs":
        for flag, value in (("--ripple-pitch", ripple_pitch or None), ("--resample", resample)):
            if value is not None:
                raise UsageError(f"{flag}: not available for a friction test of several logs ({note}; one map "
                                 "point per leg, no ripple or time base to fit): drop it, or give one file")
        legs_kw = {k: options[k] for k in ("mapping", "input_gain", "sample_rate", "friction", "fix", "bounds",
                                            "u_unit", "q_unit", "fmt", "lead", "gear", "counts_per_rev")
                   if k in options}
        return identify_legs(paths, validate_on=list(validate_on), _loaded=(logs, val_logs),
                             **legs_kw)  # type: ignore[arg-type]
    out = identify_log(paths, validate_on=list(validate_on), ripple_pitch=ripple_pitch, resample=resample,
                       _loaded=(logs, val_logs), **options)  # type: ignore[arg-type]
    out.ident.extra.setdefault("warnings", []).insert(0, note)  # type: ignore[union-attr]
    return out
