"""maxon EPOS Studio data-recorder CSV: velocity and torque of a rotary drive.

The recorder writes ``;``-separated text: header lines (``Date:;...``,
``Sampling period:;<ms>``, ``Recorded samples:;<n>``, optional ``Scale:`` and
``Trigger:`` lines), a line naming the channels (``;Velocity actual value
averaged;Torque actual value averaged``), a unit line (``ms;rpm;%``) and the
data rows ``time_ms;velocity_rpm;torque_percent``.  The header length varies
between files, so the data start after the line that begins with ``ms;``.
Some files were re-saved by a spreadsheet with ``,,`` appended to every line
and a hand-edited first row carrying a note (``0.000;0;-1200,,was -8.9``):
such an annotated row is not a measurement and is dropped.

No position is recorded.  The axis is read as a rotary axis: ``q`` [rad] is
the trapezoidal integral of the motor velocity (rpm x 2 pi / 60), from 0 at
the first sample, and ``u`` keeps the file's unit (``%`` of the rated torque)
until ``--input-gain``/``--u-unit`` say otherwise.  Signs are the file's.

The parser is hand-written because the format mixes free-form header lines
with a numeric table and stray ``,,`` suffixes that the standard ``csv``
module and :func:`numpy.loadtxt` would reject; each data row is still parsed
with :func:`float`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import cumulative_trapezoid

from commission.errors import DataError, InputFileError

__all__ = ["RPM_TO_RAD_S", "looks_like_epos", "read_epos_arrays"]

#: Motor speed conversion, (rad/s) per rpm.
RPM_TO_RAD_S = math.pi / 30.0

#: How EPOS names its time, velocity and torque units on the unit line.
_TIME_UNITS = {"ms": 1e-3, "s": 1.0}


def _lines(data: bytes) -> list[str]:
    text = data.decode("utf-8-sig", errors="replace")
    return [line.split(",,", 1)[0].strip().strip('"') for line in text.splitlines()]


def looks_like_epos(data: bytes) -> bool:
    """True when ``data`` opens like an EPOS Studio recorder file.

    Recognised from the content: a ``Sampling period:`` header line within
    the first 40 lines and a unit line beginning with ``ms;``.
    """
    head = _lines(data[:8192])[:40]
    return (any(line.startswith("Sampling period:") for line in head)
            and any(line.startswith("ms;") for line in head))


def read_epos_arrays(data: bytes, label: str) -> dict[str, np.ndarray | str | float]:
    """Parse an EPOS recorder file into ``t`` [s], ``q`` [rad], ``u`` [file unit].

    Parameters
    ----------
    data : bytes
        The file's bytes.
    label : str
        File name as the user gave it, prefix of every error message.

    Returns
    -------
    dict
        ``t``, ``q``, ``u`` (float64 arrays of one length), ``u_unit`` (the
        torque channel's unit as written, e.g. ``"%"``), ``velocity_unit`` and
        ``sampling_period`` [s] from the header (NaN when absent).

    Raises
    ------
    InputFileError
        No ``ms;`` unit line, or a velocity unit other than rpm.
    DataError
        A data row that cannot be read (line number and cell named), fewer than
        two rows.
    """
    lines = _lines(data)
    unit_at = next((i for i, line in enumerate(lines) if line.startswith(("ms;", "s;"))), None)
    if unit_at is None:
        raise InputFileError(f"{label}: not an EPOS recorder file (no unit line beginning with 'ms;')")
    units = [c.strip() for c in lines[unit_at].split(";")]
    if len(units) < 3:
        raise InputFileError(f"{label}: line {unit_at + 1}: expected time;velocity;torque units, got {units}")
    if units[1] != "rpm":
        raise InputFileError(f"{label}: line {unit_at + 1}: velocity unit {units[1]!r} not supported (expected rpm)")
    period = math.nan
    for line in lines[:unit_at]:
        if line.startswith("Sampling period:"):
            try:
                period = float(line.split(";")[1]) * _TIME_UNITS[units[0]]
            except (IndexError, ValueError):
                pass
    rows: list[tuple[float, float, float]] = []
    raw_lines = data.decode("utf-8-sig", errors="replace").splitlines()
    for i in range(unit_at + 1, len(lines)):
        line = lines[i]
        if not line:
            continue
        if ",," in raw_lines[i] and raw_lines[i].split(",,", 1)[1].strip():
            continue  # a hand-annotated row ("...,,was -8.9"): not a measurement
        cells = line.split(";")
        if len(cells) < 3:
            raise DataError(f"{label}: line {i + 1}: {len(cells)} fields, expected time;velocity;torque")
        try:
            rows.append((float(cells[0]), float(cells[1]), float(cells[2])))
        except ValueError:
            bad = next(c for c in cells[:3] if not _is_float(c))
            raise DataError(f"{label}: line {i + 1}: cannot parse {bad!r} as a number") from None
    if len(rows) < 2:
        raise DataError(f"{label}: {len(rows)} data rows after the unit line; need at least 2")
    table = np.asarray(rows, dtype=np.float64)
    t = table[:, 0] * _TIME_UNITS[units[0]]
    w = table[:, 1] * RPM_TO_RAD_S
    q = np.concatenate([[0.0], cumulative_trapezoid(w, t)])
    return {"t": t, "q": q, "u": table[:, 2], "u_unit": units[2], "velocity_unit": units[1],
            "sampling_period": period}


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True
