"""Excitation logs: the loaders behind ``commission identify LOG``.

A log is one recording of one axis (CONTRACT §1): sample time ``t`` [s],
measured position ``q`` [m], actuator command ``u`` and, optionally, the
reference position ``q_ref`` [m].  :func:`load_log` reads it from HDF5, CSV,
MATLAB (v5 and v7.3) or NumPy (``.npy``, ``.npz``) files, chosen by extension, and returns an immutable
:class:`ExcitationLog` in SI units with the input gain already applied.

Loading only checks what is needed to build the arrays (file readable,
channels present, 1-D, equal lengths, known units).  Whether the samples are
usable for a fit (finite, uniform time, long enough, not saturated) is the job
of :func:`commission.checks.check_log`.

Every failure is a :class:`~commission.errors.CommissionError` whose message
starts with the file name as the user gave it and names the channel, the name
in the file and the shape involved.

One module per part: :mod:`~commission.logs.model` (the :class:`ExcitationLog`
and the contract's channels and units), :mod:`~commission.logs.raw` (what the
readers share: name lookup, vector checks, assembly in SI units), and one reader
per format: :mod:`~commission.logs.hdf5` (HDF5 and MATLAB v7.3, in a guarded
child process), :mod:`~commission.logs.mat` (MATLAB v5), :mod:`~commission.logs.csvfile`
(CSV), :mod:`~commission.logs.epos` with :mod:`~commission.logs.eposfile` (maxon
EPOS recorder files), :mod:`~commission.logs.npy` (NumPy ``.npy``/``.npz``, never
unpickled).  A new vendor format is one more reader module returning a ``_Raw``, and
one line in :func:`load_log`.
"""

from __future__ import annotations

import hashlib
import math
import os
from pathlib import Path
from typing import Iterable, Mapping

from commission.errors import InputFileError, UsageError
from commission.infra.files import MAX_LOG_BYTES, check_input_file, read_input_bytes
from commission.logs.csvfile import _read_csv
from commission.logs.epos import looks_like_epos
from commission.logs.eposfile import _read_epos
from commission.logs.hdf5 import _hdf5_offset, _read_hdf5
from commission.logs.mat import _read_mat5
from commission.logs.npy import _read_npy, _read_npz, looks_like_npz
from commission.logs.model import CHANNELS, Q_UNITS, SAMPLE_RATE_TOLERANCE, U_UNITS, ExcitationLog
from commission.logs.raw import _assemble, _Raw

__all__ = [
    "CHANNELS",
    "FORMATS",
    "Q_UNITS",
    "SAMPLE_RATE_TOLERANCE",
    "U_UNITS",
    "ExcitationLog",
    "check_counts_per_rev",
    "load_log",
    "parse_mapping",
]


_EXTENSIONS = {".h5": "hdf5", ".hdf5": "hdf5", ".csv": "csv", ".mat": "mat", ".npy": "npy", ".npz": "npy"}


#: Values of ``--format``: one per reader module.
FORMATS: tuple[str, ...] = ("hdf5", "csv", "mat", "epos", "npy")


def parse_mapping(items: Iterable[str]) -> dict[str, str]:
    """Parse repeated ``--map NAME=SOURCE`` options.

    Parameters
    ----------
    items : iterable of str
        Strings like ``"q=qm"``; ``NAME`` is a contract channel (t, q, u,
        q_ref) and ``SOURCE`` the variable/column/dataset name in the file
        (split at the first ``=``; surrounding blanks are ignored).

    Returns
    -------
    dict of str to str
        Contract name -> name in the file.

    Raises
    ------
    UsageError
        Bad syntax, an unknown channel, or one channel mapped twice to
        different names.
    """
    out: dict[str, str] = {}
    for item in items:
        name, sep, src = item.partition("=")
        name, src = name.strip(), src.strip()
        if not sep or not name or not src:
            raise UsageError(f"--map {item!r}: expected NAME=SOURCE, e.g. --map q=qm")
        if name not in CHANNELS:
            raise UsageError(
                f"--map {item!r}: unknown channel {name!r} (expected one of {', '.join(CHANNELS)})"
            )
        if name in out and out[name] != src:
            raise UsageError(f"--map {name}: given twice ({out[name]!r} and {src!r})")
        out[name] = src
    return out


def check_counts_per_rev(counts_per_rev: float | None, q_unit: str | None) -> None:
    """Refuse a ``--counts-per-rev`` that is not a positive finite number, or that ``--q-unit`` contradicts.

    Encoder counts converted at ``2π/N`` rad per count are a rotary angle, so the only
    ``--q-unit`` that agrees with the flag is ``rad`` (redundant, accepted); a linear unit
    says the user thinks the same numbers are lengths, and one of the two flags is wrong.

    Raises
    ------
    UsageError
        Naming ``--counts-per-rev`` and, for a contradiction, the ``--q-unit`` given.
    """
    if counts_per_rev is None:
        return
    n = float(counts_per_rev)
    if not (math.isfinite(n) and n > 0):
        raise UsageError(f"--counts-per-rev must be a positive finite number (encoder counts per revolution), "
                         f"got {counts_per_rev}")
    if q_unit is not None and q_unit != "rad":
        raise UsageError(f"--counts-per-rev {counts_per_rev:g} turns q from encoder counts into rad, but --q-unit "
                         f"{q_unit} says q is a length: drop one of the two")


def load_log(
    path: str | os.PathLike[str],
    *,
    mapping: Mapping[str, str] | None = None,
    input_gain: float = 1.0,
    sample_rate: float | None = None,
    q_unit: str | None = None,
    fmt: str | None = None,
    counts_per_rev: float | None = None,
) -> ExcitationLog:
    """Load an excitation log (CONTRACT §1) from HDF5, CSV, MATLAB or NumPy.

    The format follows the extension: ``.h5``/``.hdf5`` (1-D datasets at the
    root, optional root attributes ``q_unit`` in {m, mm, um} and ``u_unit`` in
    {V, N, A}); ``.csv`` (a header row naming the columns, comma, semicolon or
    tab separated, ``#`` comment lines allowed); ``.mat`` (v5 read with
    :func:`scipy.io.loadmat`, v7.3 read as HDF5; the latter's root attributes
    ``q_unit``/``u_unit`` are honoured as for ``.h5``).  CSV and v5 MAT files
    carry no unit metadata: ``q`` is in m (or ``q_unit``) and ``u`` in V.  Column and row
    vectors (N×1, 1×N) are flattened, since MATLAB has no 1-D arrays.  ``.npz`` (named
    arrays) and ``.npy`` (a record array's fields, or a plain 2-D array's rows or columns
    by index: ``--map t=0 --map q=1 --map u=2``) carry no units either; see
    :mod:`commission.logs.npy`.

    Parameters
    ----------
    path : str or os.PathLike
        The log file.
    mapping : mapping of str to str, optional
        Contract name (t, q, u, q_ref) -> name in the file, e.g.
        ``{"q": "qm", "u": "vir"}`` for EMPS.  Unmapped channels are looked up
        under their own name.  A mapped channel must exist, even ``q_ref``.
        In HDF5 files a name may be a path (``"run1/q"``).
    input_gain : float
        Multiplies ``u`` [unit of u per u_unit]; finite and nonzero.
    sample_rate : float, optional
        Sample rate [Hz].  Required when the file has no time channel
        (``t = arange(n) / sample_rate``).  When the file has one, the rate is
        only cross-checked: ``t`` is kept, and a rate that differs from
        ``1 / median(diff(t))`` by more than 1 % is an error.
    q_unit : {"m", "mm", "um"}, optional
        Unit of ``q`` (and ``q_ref``) in the file, for files without a ``q_unit``
        attribute (CSV, v5 MAT, HDF5 without it); default m.  A file whose
        attribute names another unit is refused (``--q-unit`` contradicts it).
    fmt : {"hdf5", "csv", "mat", "epos", "npy"}, optional
        Forces the format (``--format``).  Default: a maxon EPOS Studio
        recorder file is recognised from its content
        (:mod:`commission.logs.epos`: rotary axis, q in rad integrated from
        the velocity, u in the file's unit), anything else by its extension.

    Returns
    -------
    ExcitationLog
        Arrays in SI units, ``u`` multiplied by ``input_gain``.

    Raises
    ------
    InputFileError
        Missing file, unknown extension, or bytes not readable as the format
        the extension names.
    DataError
        A channel missing or not numeric, not a vector, lengths that differ,
        an unknown unit attribute, an empty log.
    UsageError
        Bad ``mapping`` key, ``input_gain``, ``sample_rate`` or ``q_unit``, a
        ``sample_rate`` that contradicts ``t``, or a ``q_unit`` that contradicts
        the file's attribute.
    """
    label = os.fspath(path)
    mapping, gain, sample_rate = _checked_options(mapping, input_gain, sample_rate, q_unit, counts_per_rev, fmt)
    p = Path(path)
    forced = fmt
    fmt = fmt or _EXTENSIONS.get(p.suffix.lower())
    check_input_file(p, MAX_LOG_BYTES, "log file")  # missing, a folder, a FIFO or device, too large
    # Read once, bounded: the hash is then exactly of the bytes that were parsed.
    data = read_input_bytes(p, MAX_LOG_BYTES)

    if forced is None and looks_like_epos(data):
        fmt = "epos"
    if fmt is None:
        raise InputFileError(
            f"{label}: unknown log format {p.suffix or '(no extension)'!r} "
            "(expected .h5, .hdf5, .csv, .mat, .npy or .npz); EPOS recorder files are recognised from their content "
            "and --format forces a format"
        )
    raw = _read_format(data, fmt, label, mapping, need_t=sample_rate is None)
    return _assemble(raw, label, gain, sample_rate, q_unit, hashlib.sha256(data).hexdigest(),
                     counts_per_rev=None if counts_per_rev is None else float(counts_per_rev))


def _checked_options(mapping: Mapping[str, str] | None, input_gain: float, sample_rate: float | None,
                     q_unit: str | None, counts_per_rev: float | None,
                     fmt: str | None) -> tuple[dict[str, str], float, float | None]:
    """The options of :func:`load_log` checked (UsageError naming the flag); returns (mapping, gain, rate)."""
    mapping = dict(mapping or {})
    for key, src in mapping.items():
        if key not in CHANNELS:
            raise UsageError(
                f"--map {key}={src}: unknown channel {key!r} (expected one of {', '.join(CHANNELS)})"
            )
    gain = float(input_gain)
    if not math.isfinite(gain) or gain == 0.0:
        raise UsageError(f"--input-gain: expected a finite nonzero number, got {input_gain!r}")
    if sample_rate is not None:
        sample_rate = float(sample_rate)
        if not math.isfinite(sample_rate) or sample_rate <= 0.0:
            raise UsageError(f"--sample-rate: expected a finite positive rate in Hz, got {sample_rate!r}")
    if q_unit is not None and q_unit not in Q_UNITS:
        raise UsageError(f"--q-unit: expected one of {', '.join(Q_UNITS)}, got {q_unit!r}")
    check_counts_per_rev(counts_per_rev, q_unit)

    if fmt is not None and fmt not in FORMATS:
        raise UsageError(f"--format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
    return mapping, gain, sample_rate


def _read_format(data: bytes, fmt: str, label: str, mapping: dict[str, str], *, need_t: bool) -> _Raw:
    """The channels of ``data`` read by the reader of ``fmt`` (a ``.mat`` file: v7.3 as HDF5, else v5)."""
    if fmt == "epos":
        return _read_epos(data, label, mapping)
    elif fmt == "hdf5":
        return _read_hdf5(data, label, "HDF5", mapping, need_t, matlab=False)
    elif fmt == "csv":
        return _read_csv(data, label, mapping, need_t)
    elif fmt == "npy":
        return (_read_npz if looks_like_npz(data) else _read_npy)(data, label, mapping, need_t)
    elif _hdf5_offset(data) is not None:
        return _read_hdf5(data, label, "MATLAB v7.3", mapping, need_t, matlab=True)
    else:
        return _read_mat5(data, label, mapping, need_t)
