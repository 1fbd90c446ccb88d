"""CSV logs: a header row naming the columns, comma, semicolon or tab separated."""

from __future__ import annotations

import csv
import io
from typing import Mapping

import numpy as np

from commission.errors import DataError, InputFileError
from commission.logs.raw import _Raw, _plan, _what, _why


def _read_csv(data: bytes, label: str, mapping: Mapping[str, str], need_t: bool) -> _Raw:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{label}: not a readable CSV file (not UTF-8 text at byte {exc.start})") from None
    if "\x00" in text:
        raise InputFileError(f"{label}: not a readable CSV file (contains NUL bytes)")
    lines = text.splitlines()
    header_at = next(
        (i for i, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")), None
    )
    if header_at is None:
        raise InputFileError(f"{label}: not a readable CSV file (no header row)")
    header_line = lines[header_at]
    delimiter = max(",;\t", key=header_line.count)  # ',' when there is a single column
    try:
        names = [h.strip() for h in next(csv.reader([header_line], delimiter=delimiter))]
    except csv.Error as exc:
        raise InputFileError(f"{label}: not a readable CSV file (header: {exc})") from None
    available = [n for n in names if n]
    plan = _plan(label, lambda name: name in names, available, mapping, need_t)
    for ch, src in plan.items():
        if names.count(src) > 1:
            raise DataError(f"{label}: {_what(ch, src)}: column {src!r} appears {names.count(src)} times")

    cols = [names.index(src) for src in plan.values()]
    body = lines[header_at + 1:]
    if not any(line.strip() and not line.lstrip().startswith("#") for line in body):
        raise DataError(f"{label}: no data rows after the header")
    try:
        table = np.loadtxt(
            io.StringIO("\n".join(body)), delimiter=delimiter, usecols=cols, comments="#",
            quotechar='"', ndmin=2, dtype=np.float64,
        )
    except ValueError as exc:
        # loadtxt's message is vague about where; rescan slowly to name the cell.
        _locate_bad_cell(label, body, header_at + 2, delimiter, cols, names)
        raise InputFileError(f"{label}: not a readable CSV file ({_why(exc)})") from None
    vectors = {}
    for j, (ch, src) in enumerate(plan.items()):
        vec = table[:, j]
        vectors[ch] = (vec, vec.shape, src)
    return _Raw(vectors)


def _locate_bad_cell(
    label: str, body: list[str], first_line: int, delimiter: str, cols: list[int], names: list[str]
) -> None:
    """Raise DataError for the first row/cell of ``body`` that cannot be read."""
    for offset, line in enumerate(body):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        lineno = first_line + offset
        try:
            row = next(csv.reader([line.split("#", 1)[0]], delimiter=delimiter))
        except csv.Error as exc:
            raise DataError(f"{label}: line {lineno}: {exc}") from None
        if len(row) <= max(cols):
            raise DataError(
                f"{label}: line {lineno}: {len(row)} fields, but column {names[max(cols)]!r} "
                f"is field {max(cols) + 1}"
            )
        for c in cols:
            cell = row[c].strip()
            try:
                float(cell)
            except ValueError:
                what = "empty cell" if not cell else f"cannot parse {cell!r} as a number"
                raise DataError(f"{label}: line {lineno}, column {names[c]!r}: {what}") from None

