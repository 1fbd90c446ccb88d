"""The logs as ``identify`` reads them: paths, unit conversion, resampling, joining, the plan beside a log.

Everything here happens before a fit: which files a folder holds (:func:`expand_log_paths`),
a rotary angle turned into the load's coordinate (:func:`convert_axis`), irregular time
stamps put on a uniform grid (:func:`resample_log`), a check that several logs are of one
axis, the logs laid end to end for display, and the ``plan.json`` of ``commission excite``
found beside a log (:func:`plan_beside`).  Also the names errors use for a log or a group.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from commission.errors import DataError, SchemaError, UsageError
from commission.logs import ExcitationLog


#: File extensions a folder given to ``identify`` is searched for.
LOG_EXTENSIONS = (".h5", ".hdf5", ".csv", ".mat", ".npy", ".npz")


def expand_log_paths(paths: Sequence[str]) -> list[str]:
    """The log files named by ``paths``: files as given, folders as their log files (sorted by name).

    The same file reached twice -- given twice, given with a folder that holds it,
    or through a symlink or a hard link -- is refused: its samples would be fitted
    twice, and the standard deviations (hence the theta box) would shrink by sqrt(2)
    with nothing to show for it.  Files are compared by device and inode, so every
    spelling of one file is caught.

    Raises
    ------
    UsageError
        A path that does not exist, a folder without a log file, or one file twice
        (naming both spellings).
    """
    out: list[str] = []
    seen: dict[tuple[int, int], str] = {}

    def add(name: str, via: str | None) -> None:
        spelled = name if via is None else f"{name} (in the folder {via})"
        try:
            st = os.stat(name)
        except OSError:
            st = None  # unreadable: the reader names it
        if st is not None:
            key = (st.st_dev, st.st_ino)
            if key in seen:
                raise UsageError(f"{seen[key]} and {spelled}: the same file given twice; "
                                 "give each log once (its samples would be fitted twice)")
            seen[key] = spelled
        out.append(name)

    for p in paths:
        path = Path(p)
        if path.is_dir():
            found = sorted((f for f in path.iterdir() if f.is_file() and f.suffix.lower() in LOG_EXTENSIONS),
                           key=lambda f: f.name)
            if not found:
                raise UsageError(f"{p}: a folder without log files ({', '.join(LOG_EXTENSIONS)})")
            for f in found:
                add(str(f), str(p))
        elif path.exists():
            add(str(p), None)
        else:
            raise UsageError(f"{p}: no such file or folder")
    return out


def convert_axis(logs: Sequence[ExcitationLog], lead: float | None, gear: float | None) -> list[ExcitationLog]:
    """A rotary log's motor angle as the load's angle (``--gear``) or the carriage's position (``--lead``).

    The encoder of a screw or geared drive usually sits on the motor, so the log holds the
    motor angle in rad, while the user may want the model (and every parameter, bound and
    figure after it) in the load's coordinate: the load angle ``q / gear`` [rad], or the
    carriage position ``q lead / gear`` [m] of a screw whose lead is ``lead`` m per rad of
    the screw (a 5 mm/rev screw: 0.005/(2π)).  ``q`` and ``q_ref`` are scaled; time and
    command are not, so M, B, the friction speeds and everything derived from them come
    out in the converted unit (M in u-unit·s²/m after ``--lead``).  Converting before the
    checks means the plausibility checks see the unit the model will use.

    Parameters
    ----------
    logs : sequence of ExcitationLog
        As loaded; all must be rotary (``q_unit_in_file == "rad"``) when ``lead`` or ``gear`` is given.
    lead : float or None
        m of carriage travel per rad of the load (the screw); None: stay rotary.
    gear : float or None
        Motor rad per load rad (> 0); None: 1.

    Returns
    -------
    list of ExcitationLog
        The logs, unchanged when neither is given; after ``lead`` their ``q_unit_in_file`` is ``"m"``.

    Raises
    ------
    UsageError
        A ratio that is not a positive finite number, or a log that is not in rad, named.
    """
    if lead is None and gear is None:
        return list(logs)
    for flag, v in (("--lead", lead), ("--gear", gear)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise UsageError(f"{flag} must be a positive finite number, got {v}")
    for lg in logs:
        if lg.q_unit_in_file != "rad":
            flag = "--lead" if lead is not None else "--gear"
            raise UsageError(f"{flag} converts a rotary log's angle (q in rad), but {lg.source}'s q is in "
                             f"{lg.q_unit_in_file}; drop {flag}, or give the log in rad (--q-unit rad)")
    k = (1.0 if lead is None else lead) / (1.0 if gear is None else gear)
    unit = "m" if lead is not None else "rad"
    return [dataclasses.replace(lg, q=lg.q * k, q_ref=None if lg.q_ref is None else lg.q_ref * k,
                                q_unit_in_file=unit) for lg in logs]


def _conversion_record(file_q_unit: str, lead: float | None, gear: float | None,
                       counts_per_rev: float | None = None) -> dict[str, object]:
    """ident.json's ``source.conversion``: what ``--counts-per-rev`` (on loading) and :func:`convert_axis` did.

    Written only when one of them did something.  One record for the whole chain,
    file unit to model unit (counts -> rad -> load rad -> m), each factor under its own
    key and null for a flag not given, so a reader can redo the conversion.
    """
    return {"from": file_q_unit, "to": "m" if lead is not None else "rad", "counts_per_rev": counts_per_rev,
            "lead_m_per_rad": lead, "gear_motor_rad_per_load_rad": gear}


def _file_q_unit(log: ExcitationLog, counts_per_rev: float | None) -> str:
    """ident.json's ``source.q_unit``: the unit of q in the file, ``"counts"`` under ``--counts-per-rev``."""
    return "counts" if counts_per_rev is not None else log.q_unit_in_file


#: Largest accepted --resample rate as a multiple of the log's median rate (interpolation adds no information).
MAX_RESAMPLE_FACTOR = 10.0


def resample_log(log: ExcitationLog, rate: float) -> ExcitationLog:
    """The log on the uniform grid ``t[0] + k / rate`` by linear interpolation (``--resample``).

    For logs whose time stamps are irregular (host polling over USB, dropped samples):
    q, u (and q_ref) are interpolated linearly between the recorded samples.  A rate
    far above the log's median rate adds samples but no information, so it is refused.

    Parameters
    ----------
    log : ExcitationLog
    rate : float
        Hz.
    """
    if not (math.isfinite(rate) and rate > 0):
        raise UsageError(f"--resample must be a positive rate in Hz, got {rate}")
    t = np.asarray(log.t)
    if t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise DataError(f"{log.source}: channel t: --resample needs strictly increasing finite time stamps")
    median_rate = 1.0 / float(np.median(np.diff(t)))
    if rate > MAX_RESAMPLE_FACTOR * median_rate:
        raise UsageError(f"--resample {rate:g} Hz is more than {MAX_RESAMPLE_FACTOR:g} x the log's median rate "
                         f"{median_rate:.4g} Hz")
    n = int(math.floor((t[-1] - t[0]) * rate + 1e-9)) + 1
    tu = t[0] + np.arange(n) / rate

    def interp(x: np.ndarray | None) -> np.ndarray | None:
        return None if x is None else np.interp(tu, t, x)

    return dataclasses.replace(log, t=tu, q=interp(log.q), u=interp(log.u), q_ref=interp(log.q_ref),
                               sample_rate=float(rate))


def _name(logs: Sequence[ExcitationLog], segment: int | None = None) -> str:
    """The file an error names: the offending segment's, the only log's, or the first and how many more."""
    if segment is not None:
        return logs[segment].source
    return logs[0].source if len(logs) == 1 else f"{logs[0].source} (and {len(logs) - 1} more logs fitted together)"


def _joined(logs: Sequence[ExcitationLog]) -> ExcitationLog:
    """Several logs of one axis laid end to end (what summaries and plots show of a segmented fit).

    Times of a later log are shifted to follow the previous one by one sample
    period; positions and commands are as recorded.  Only for display: the fit
    treats every log as its own segment.  ``sha256`` is that of the logs' digests
    joined by commas (ident.json lists each file's own).
    """
    if len(logs) == 1:
        return logs[0]
    ts, end = [], None
    for lg in logs:
        shift = 0.0 if end is None else end + 1.0 / lg.sample_rate - float(lg.t[0])
        ts.append(lg.t + shift)
        end = float(ts[-1][-1])
    refs = [lg.q_ref for lg in logs]
    first = logs[0]
    return dataclasses.replace(
        first, t=np.concatenate(ts), q=np.concatenate([lg.q for lg in logs]), u=np.concatenate([lg.u for lg in logs]),
        q_ref=None if any(r is None for r in refs) else np.concatenate(refs),  # type: ignore[arg-type]
        source=" + ".join(lg.source for lg in logs),
        sha256=hashlib.sha256(",".join(lg.sha256 for lg in logs).encode()).hexdigest())


def _same_axis_units(logs: Sequence[ExcitationLog]) -> None:
    """Refuse logs that do not share their units (one axis: one u unit, all rotary or all linear)."""
    units = {(lg.u_unit, lg.q_unit_in_file == "rad") for lg in logs}
    if len(units) > 1:
        raise DataError(f"{logs[0].source}: the logs of one axis must share their units; found u in "
                        f"{sorted({u for u, _ in units})} and "
                        f"{'rotary and linear' if len({r for _, r in units}) > 1 else 'one'} axes")


def _units(u_unit: str | None, log: ExcitationLog) -> dict[str, str]:
    """ident.json's ``units``: u after the gain (``--u-unit``, else the file's), q in m or rad."""
    return {"u": u_unit or log.u_unit, "q": "rad" if log.q_unit_in_file == "rad" else "m"}


#: Name of the plan file ``identify`` looks for beside a log (``commission excite`` writes it).
PLAN_BESIDE_NAME = "plan.json"
#: A log matches the plan beside it when its sample count is within this fraction of the plan's.
PLAN_BESIDE_SAMPLES_TOL = 0.01


def plan_beside(path: str | os.PathLike[str], lg: ExcitationLog) -> tuple[dict[str, Any] | None, str | None, str | None]:
    """The ``plan.json`` of ``commission excite`` beside a log, when the log is a recording of it.

    ``identify LOG`` without ``--plan`` still measures the frequency response on the plan's
    injection windows when the log's folder holds a plan.json whose sample rate is the log's
    (within 1e-6) and whose sample count is the log's within ``PLAN_BESIDE_SAMPLES_TOL``
    (the log starts with the plan, as ``--plan`` assumes): the command's level does not
    always show the injection (on a noisy encoder the holding loop's answer to the noise is
    of the injection's size), the plan does.  A plan.json that does not load or does not
    match is left alone, with a note saying why.

    Returns
    -------
    (plan, path, note)
        The parsed plan and its path (None, None when none is used) and a sentence for the
        warnings (None when there is nothing to say).
    """
    from commission.excite import load_plan_json

    cand = os.path.join(os.path.dirname(os.path.abspath(os.fspath(path))), PLAN_BESIDE_NAME)
    if not os.path.isfile(cand):
        return None, None, None
    try:
        plan = load_plan_json(cand)
    except SchemaError as exc:
        return None, None, f"{cand} beside the log is not used: {exc}"
    fs_plan, n_plan = plan.get("sample_rate"), plan.get("samples")
    if (not isinstance(fs_plan, (int, float)) or not isinstance(n_plan, int)
            or abs(fs_plan - lg.sample_rate) > 1e-6 * fs_plan
            or abs(lg.t.size - n_plan) > PLAN_BESIDE_SAMPLES_TOL * n_plan):
        return None, None, (f"{cand} beside the log is not used: the log ({lg.t.size} samples at "
                            f"{lg.sample_rate:.6g} Hz) is not a recording of it ({n_plan} samples at {fs_plan} Hz); "
                            f"give --plan to use it anyway")
    wins = [w for g in plan["segments"] if g.get("name") == "injection" for w in g.get("windows_s", [])]
    if not wins:
        return None, None, None
    return plan, cand, None
