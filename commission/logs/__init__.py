"""Excitation logs: the loaders behind ``commission identify LOG``.

A log is one recording of one axis (CONTRACT §1): sample time ``t`` [s],
measured position ``q`` [m], actuator command ``u`` and, optionally, the
reference position ``q_ref`` [m].  :func:`load_log` reads it from HDF5, CSV or
MATLAB (v5 and v7.3) files, chosen by extension, and returns an immutable
:class:`ExcitationLog` in SI units with the input gain already applied.

Loading only checks what is needed to build the arrays (file readable,
channels present, 1-D, equal lengths, known units).  Whether the samples are
usable for a fit (finite, uniform time, long enough, not saturated) is the job
of :func:`commission.checks.check_log`.

Every failure is a :class:`~commission.errors.CommissionError` whose message
starts with the file name as the user gave it and names the channel, the name
in the file and the shape involved.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import select
import signal
import struct
import time
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Mapping

import h5py
import numpy as np
import scipy.io

from commission.errors import CommissionError, DataError, InputFileError, UsageError
from commission.files import MAX_LOG_BYTES, check_input_file, read_input_bytes
from commission.logs.epos import looks_like_epos, read_epos_arrays

__all__ = [
    "CHANNELS",
    "Q_UNITS",
    "U_UNITS",
    "ExcitationLog",
    "load_log",
    "parse_mapping",
]

#: Contract channel names, in the order they are resolved and reported.
CHANNELS: tuple[str, ...] = ("t", "q", "u", "q_ref")

#: Accepted ``q_unit`` values and how many of them make one metre.
#: ``rad`` marks a rotary axis (EPOS recorder files): q is an angle, taken as is.
Q_UNITS: dict[str, float] = {"m": 1.0, "mm": 1e3, "um": 1e6, "rad": 1.0}

#: Accepted ``u_unit`` values (the command as stored in the file).
#: ``Nm`` is a rotary axis's torque, ``%`` a drive's torque in percent of its rating.
U_UNITS: tuple[str, ...] = ("V", "N", "A", "Nm", "%")

#: A sample rate given with ``--sample-rate`` may differ from the one implied by
#: ``t`` by at most this fraction; more means one of the two is wrong.
SAMPLE_RATE_TOLERANCE = 0.01

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_EXTENSIONS = {".h5": "hdf5", ".hdf5": "hdf5", ".csv": "csv", ".mat": "mat"}
#: Values of ``--format``: one per reader module.
FORMATS: tuple[str, ...] = ("hdf5", "csv", "mat", "epos")


# --------------------------------------------------------------------------- #
# Data model
# --------------------------------------------------------------------------- #
@dataclass(frozen=True, eq=False)
class ExcitationLog:
    """One recording of one axis, in SI units, ready for the pre-fit checks.

    Arrays are float64 copies marked read-only, so a log cannot change after
    it was hashed and checked.  ``eq=False``: two logs compare by identity
    (element-wise array comparison has no single truth value).

    Parameters
    ----------
    t : numpy.ndarray, shape (n,)
        Sample time [s], as recorded (or ``arange(n) / sample_rate`` when the
        file has no time channel).
    q : numpy.ndarray, shape (n,)
        Measured position [m], converted from ``q_unit_in_file``.
    u : numpy.ndarray, shape (n,)
        Actuator command: the file's values in ``u_unit`` multiplied by
        ``input_gain`` (for EMPS, volts times 35.15 N/V gives newtons).
    q_ref : numpy.ndarray, shape (n,), or None
        Reference position [m], converted like ``q``; None if not recorded.
    u_unit : str
        Unit of the command stored in the file: ``'V'``, ``'N'`` or ``'A'``.
        When ``input_gain`` is not 1 the unit of ``u`` is this unit times the
        unit of the gain, which only the caller knows.
    q_unit_in_file : str
        Unit of ``q`` and ``q_ref`` in the file: ``'m'``, ``'mm'`` or ``'um'``.
    input_gain : float
        Factor already applied to ``u`` [unit of u per u_unit].
    source : str
        The file name as given by the user (prefix of every error message).
    sha256 : str
        Hex sha256 of the file's bytes (of the arrays for :meth:`from_arrays`).
    sample_rate : float
        Sample rate [Hz]: ``1 / median(diff(t))``, or the rate given when the
        file has no time channel.  NaN when ``t`` gives no positive finite step
        (such a log fails :func:`commission.checks.check_log`).
    """

    t: np.ndarray
    q: np.ndarray
    u: np.ndarray
    q_ref: np.ndarray | None
    u_unit: str
    q_unit_in_file: str
    input_gain: float
    source: str
    sha256: str
    sample_rate: float

    def __post_init__(self) -> None:
        n = None
        for name in CHANNELS:
            value = getattr(self, name)
            if value is None:
                if name != "q_ref":
                    raise DataError(f"{self.source}: channel {name!r} is required")
                continue
            arr = np.array(value, dtype=np.float64)  # a private copy, see class doc
            if arr.ndim != 1:
                raise DataError(
                    f"{self.source}: channel {name!r} has shape {arr.shape}; expected a 1-D array"
                )
            if n is None:
                n = arr.shape[0]
            elif arr.shape[0] != n:
                raise DataError(
                    f"{self.source}: channel {name!r} has shape {arr.shape} "
                    f"but channel 't' has shape ({n},)"
                )
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if self.u_unit not in U_UNITS:
            raise DataError(f"{self.source}: u_unit {self.u_unit!r} not supported (expected {', '.join(U_UNITS)})")
        if self.q_unit_in_file not in Q_UNITS:
            raise DataError(
                f"{self.source}: q_unit {self.q_unit_in_file!r} not supported (expected {', '.join(Q_UNITS)})"
            )

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])

    @classmethod
    def from_arrays(
        cls,
        t: np.ndarray,
        q: np.ndarray,
        u: np.ndarray,
        q_ref: np.ndarray | None = None,
        *,
        u_unit: str = "V",
        source: str = "<memory>",
    ) -> "ExcitationLog":
        """Build a log from arrays already in SI units (simulated data, tests).

        Parameters
        ----------
        t : array_like, shape (n,)
            Sample time [s].
        q : array_like, shape (n,)
            Measured position [m].
        u : array_like, shape (n,)
            Command [u_unit], taken as is (``input_gain`` is recorded as 1).
        q_ref : array_like, shape (n,), optional
            Reference position [m].
        u_unit : str
            ``'V'``, ``'N'`` or ``'A'``.
        source : str
            Name used in error messages.

        Returns
        -------
        ExcitationLog
            With ``sha256`` computed over the arrays' float64 bytes and
            ``sample_rate`` derived from ``t``.
        """
        arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (t, q, u)]
        arrays.append(None if q_ref is None else np.ascontiguousarray(q_ref, dtype=np.float64))
        h = hashlib.sha256(b"commission.ExcitationLog.v1")
        for name, arr in zip(CHANNELS, arrays):
            if arr is not None:
                h.update(f"{name}:{arr.shape}".encode())
                h.update(arr.astype("<f8", copy=False).tobytes())
        return cls(
            t=arrays[0], q=arrays[1], u=arrays[2], q_ref=arrays[3],
            u_unit=u_unit, q_unit_in_file="m", input_gain=1.0, source=source,
            sha256=h.hexdigest(), sample_rate=_rate_from_t(arrays[0]),
        )


# --------------------------------------------------------------------------- #
# Public functions
# --------------------------------------------------------------------------- #
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


def load_log(
    path: str | os.PathLike[str],
    *,
    mapping: Mapping[str, str] | None = None,
    input_gain: float = 1.0,
    sample_rate: float | None = None,
    q_unit: str | None = None,
    fmt: str | None = None,
) -> ExcitationLog:
    """Load an excitation log (CONTRACT §1) from HDF5, CSV or MATLAB.

    The format follows the extension: ``.h5``/``.hdf5`` (1-D datasets at the
    root, optional root attributes ``q_unit`` in {m, mm, um} and ``u_unit`` in
    {V, N, A}); ``.csv`` (a header row naming the columns, comma, semicolon or
    tab separated, ``#`` comment lines allowed); ``.mat`` (v5 read with
    :func:`scipy.io.loadmat`, v7.3 read as HDF5; the latter's root attributes
    ``q_unit``/``u_unit`` are honoured as for ``.h5``).  CSV and v5 MAT files
    carry no unit metadata: ``q`` is in m (or ``q_unit``) and ``u`` in V.  Column and row
    vectors (N×1, 1×N) are flattened, since MATLAB has no 1-D arrays.

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
    fmt : {"hdf5", "csv", "mat", "epos"}, optional
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

    if fmt is not None and fmt not in FORMATS:
        raise UsageError(f"--format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
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
            "(expected .h5, .hdf5, .csv or .mat); EPOS recorder files are recognised from their content "
            "and --format forces a format"
        )
    need_t = sample_rate is None
    if fmt == "epos":
        raw = _read_epos(data, label, mapping)
    elif fmt == "hdf5":
        raw = _read_hdf5(data, label, "HDF5", mapping, need_t, matlab=False)
    elif fmt == "csv":
        raw = _read_csv(data, label, mapping, need_t)
    elif _hdf5_offset(data) is not None:
        raw = _read_hdf5(data, label, "MATLAB v7.3", mapping, need_t, matlab=True)
    else:
        raw = _read_mat5(data, label, mapping, need_t)
    return _assemble(raw, label, gain, sample_rate, q_unit, hashlib.sha256(data).hexdigest())


# --------------------------------------------------------------------------- #
# Format readers.  Each returns a _Raw: per channel (vector, display shape,
# name in the file), plus the unit attributes found.
# --------------------------------------------------------------------------- #
@dataclass
class _Raw:
    vectors: dict[str, tuple[np.ndarray, tuple[int, ...], str]]
    q_unit: object = None
    u_unit: object = None


def _plan(
    label: str,
    has: Callable[[str], bool],
    available: list[str],
    mapping: Mapping[str, str],
    need_t: bool,
) -> dict[str, str]:
    """Decide which name in the file each channel comes from.

    Raises the "channel not found" error, listing what the file offers.
    """
    plan: dict[str, str] = {}
    for ch in CHANNELS:
        src = mapping.get(ch, ch)
        if has(src):
            plan[ch] = src
            continue
        if ch in mapping:
            raise DataError(
                f"{label}: channel {ch!r} mapped to {src!r}, which is not in the file "
                f"(available: {_list(available)})"
            )
        if ch == "q_ref" or (ch == "t" and not need_t):
            continue
        hint = f"use --map {ch}=NAME" + (" or --sample-rate HZ" if ch == "t" else "")
        raise DataError(f"{label}: channel {ch!r} not found (available: {_list(available)}); {hint}")
    return plan


def _list(names: list[str], limit: int = 20) -> str:
    if not names:
        return "none"
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names)} in all)" if len(names) > limit else "")


def _what(ch: str, src: str) -> str:
    return f"channel {ch!r}" if src == ch else f"channel {ch!r} ({src!r})"


_KIND_NAMES = {"U": "holds text", "S": "holds text", "c": "is complex", "b": "is boolean",
               "V": "is a struct/record", "O": "holds objects (a cell array?)"}


def _vector(label: str, ch: str, src: str, arr: np.ndarray, shown: tuple[int, ...]) -> np.ndarray:
    """Check dtype and shape of one channel; flatten N×1 / 1×N to 1-D float64."""
    if arr.dtype.kind not in "fiu":
        kind = _KIND_NAMES.get(arr.dtype.kind, "is not numeric")
        raise DataError(
            f"{label}: {_what(ch, src)} {kind} (dtype {arr.dtype}); expected real numbers (float or integer)"
        )
    if arr.ndim == 1:
        vec = arr
    elif arr.ndim == 2 and 1 in arr.shape:
        vec = arr.reshape(-1)
    else:
        raise DataError(
            f"{label}: {_what(ch, src)} has shape {shown}; expected a 1-D array (or N×1 / 1×N)"
        )
    return np.asarray(vec, dtype=np.float64)


def _why(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _hdf5_offset(data: bytes) -> int | None:
    """Offset of the HDF5 superblock (0, 512, 1024, ...), as the library searches it."""
    offset = 0
    while offset + len(_HDF5_SIGNATURE) <= len(data):
        if data[offset:offset + len(_HDF5_SIGNATURE)] == _HDF5_SIGNATURE:
            return offset
        offset = 512 if offset == 0 else offset * 2
    return None


def _attr_text(value: object) -> object:
    if isinstance(value, (bytes, np.bytes_)):
        try:
            return bytes(value).decode()
        except UnicodeDecodeError:
            return value
    if isinstance(value, np.str_):
        return str(value)
    return value


#: Time allowed to read an HDF5 file in the isolated reader: this many seconds ...
HDF5_READ_TIMEOUT = 20.0
#: ... plus the file's size at this rate (bytes/s; the file is already in memory).
HDF5_READ_RATE = 20e6
#: Error classes a child reader may report; anything else becomes an InputFileError.
_CHILD_ERRORS = {cls.__name__: cls for cls in (DataError, InputFileError, UsageError)}


class _Unparsed:
    """A non-text unit attribute, carried from the child reader by its ``repr``."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _read_hdf5(
    data: bytes, label: str, kind: str, mapping: Mapping[str, str], need_t: bool, *, matlab: bool
) -> _Raw:
    """Read an HDF5 (or MATLAB v7.3) log in a forked child process, with a deadline.

    A damaged file can send libhdf5 into an endless loop inside one C call, which
    nothing in this process could interrupt: a one-byte change to the free-space
    record of the global heap that holds a variable-length string attribute
    (``q_unit``) does it with h5py 3.16 / HDF5 2.0.  The child reads the file and
    sends back the validated vectors (``.npy`` bytes, never pickle) or the error;
    past :data:`HDF5_READ_TIMEOUT` + size / :data:`HDF5_READ_RATE` seconds it is
    killed and the file refused.  A child that dies
    (a crash in the library) is refused the same way.  Without ``os.fork``
    (Windows) the file is read in this process, unguarded.
    """
    if not hasattr(os, "fork"):
        return _read_hdf5_here(data, label, kind, mapping, need_t, matlab=matlab)
    timeout = HDF5_READ_TIMEOUT + len(data) / HDF5_READ_RATE
    rfd, wfd = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child; its result is checked through the parent
        try:
            os.close(rfd)
            try:
                blob = _encode_raw(_read_hdf5_here(data, label, kind, mapping, need_t, matlab=matlab))
            except CommissionError as exc:
                blob = _encode_error(exc)
            except BaseException as exc:  # noqa: BLE001 - reported to the parent as unreadable
                blob = _encode_error(InputFileError(f"{label}: not a readable {kind} file ({_why(exc)})"))
            with os.fdopen(wfd, "wb") as out:
                out.write(blob)
        finally:
            os._exit(0)  # no atexit handlers, no flushing of the parent's buffers
    os.close(wfd)
    chunks: list[bytes] = []
    deadline = time.monotonic() + timeout
    done = False
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0.0 or not select.select([rfd], [], [], left)[0]:
                break
            chunk = os.read(rfd, 1 << 20)
            if not chunk:
                done = True
                break
            chunks.append(chunk)
    finally:
        os.close(rfd)
        if not done:
            os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    if not done:
        raise InputFileError(
            f"{label}: not a readable {kind} file (the HDF5 library did not finish reading it "
            f"within {timeout:.0f} s; the file is probably damaged)"
        )
    return _decode_raw(b"".join(chunks), label, kind)


def _encode_raw(raw: _Raw) -> bytes:
    def unit(v: object) -> object:
        return v if v is None or isinstance(v, str) else {"repr": repr(v)}

    blobs, vectors = [], []
    for ch, (arr, shown, src) in raw.vectors.items():
        buf = io.BytesIO()
        np.save(buf, arr, allow_pickle=False)
        blobs.append(buf.getvalue())
        vectors.append([ch, list(shown), src, len(blobs[-1])])
    head = json.dumps({"q_unit": unit(raw.q_unit), "u_unit": unit(raw.u_unit), "vectors": vectors}).encode()
    return b"R" + struct.pack("<Q", len(head)) + head + b"".join(blobs)


def _encode_error(exc: CommissionError) -> bytes:
    name = type(exc).__name__ if type(exc).__name__ in _CHILD_ERRORS else "InputFileError"
    return b"E" + json.dumps({"class": name, "message": str(exc)}).encode()


def _decode_raw(blob: bytes, label: str, kind: str) -> _Raw:
    if blob[:1] == b"E":
        err = json.loads(blob[1:])
        raise _CHILD_ERRORS[err["class"]](err["message"])
    if blob[:1] != b"R" or len(blob) < 9:
        raise InputFileError(f"{label}: not a readable {kind} file (the HDF5 reader stopped without a result)")
    (n,) = struct.unpack("<Q", blob[1:9])
    head = json.loads(blob[9:9 + n])

    def unit(v: object) -> object:
        return _Unparsed(v["repr"]) if isinstance(v, dict) else v

    vectors, pos = {}, 9 + n
    for ch, shown, src, size in head["vectors"]:
        arr = np.load(io.BytesIO(blob[pos:pos + size]), allow_pickle=False)
        vectors[ch] = (arr, tuple(shown), src)
        pos += size
    return _Raw(vectors, unit(head["q_unit"]), unit(head["u_unit"]))


def _read_hdf5_here(
    data: bytes, label: str, kind: str, mapping: Mapping[str, str], need_t: bool, *, matlab: bool
) -> _Raw:
    try:
        fh = h5py.File(io.BytesIO(data), "r")
    except Exception as exc:  # noqa: BLE001 - any library failure means "not this format"
        raise InputFileError(f"{label}: not a readable {kind} file ({_why(exc)})") from None
    try:
        with fh:
            # MATLAB keeps internals in '#refs#' / '#subsystem#'; they are not variables.
            # Groups are listed as "name/": a mapping may name a dataset inside one.
            available = sorted(
                k + "/" if fh.get(k, getclass=True) is h5py.Group else k
                for k in fh.keys() if not k.startswith("#")
            )

            def has(name: str) -> bool:
                return not name.startswith("#") and name in fh

            plan = _plan(label, has, available, mapping, need_t)
            vectors = {}
            for ch, src in plan.items():
                obj = fh[src]
                if not isinstance(obj, h5py.Dataset):
                    raise DataError(f"{label}: {_what(ch, src)} is an HDF5 group, not a dataset")
                shown = tuple(reversed(obj.shape)) if matlab else tuple(obj.shape)
                if matlab:
                    cls = _attr_text(obj.attrs.get("MATLAB_class", "double"))
                    if not isinstance(cls, str) or cls not in _MATLAB_NUMERIC:
                        raise DataError(
                            f"{label}: {_what(ch, src)} has MATLAB class {cls!r}; expected a numeric array"
                        )
                    if obj.attrs.get("MATLAB_empty", 0):
                        # An empty MATLAB array is stored as its dimensions; it has no samples.
                        raise DataError(f"{label}: {_what(ch, src)} is empty")
                arr = np.asarray(obj[()])
                vectors[ch] = (_vector(label, ch, src, arr, shown), shown, src)
            return _Raw(vectors, _attr_text(fh.attrs.get("q_unit")), _attr_text(fh.attrs.get("u_unit")))
    except CommissionError:
        raise
    except Exception as exc:  # noqa: BLE001 - corrupt objects fail in many library-specific ways
        raise InputFileError(f"{label}: not a readable {kind} file ({_why(exc)})") from None


_MATLAB_NUMERIC = {
    "double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
}


def _read_mat5(data: bytes, label: str, mapping: Mapping[str, str], need_t: bool) -> _Raw:
    if len(data) >= 128 and data[:4].count(0) == 0:  # scipy's test for "v5, not v4"
        _check_mat5_structure(data, label)
    try:
        with warnings.catch_warnings():
            # loadmat warns (not fails) on some oddities, e.g. duplicate names; the
            # checks below are what decides.
            warnings.simplefilter("ignore")
            contents = scipy.io.loadmat(io.BytesIO(data), squeeze_me=False, struct_as_record=True)
    except Exception as exc:  # noqa: BLE001 - corrupt files fail in many library-specific ways
        raise InputFileError(f"{label}: not a readable MATLAB file ({_why(exc)})") from None
    available = sorted(k for k in contents if not k.startswith("__"))
    plan = _plan(label, lambda name: name in available, available, mapping, need_t)
    vectors = {}
    for ch, src in plan.items():
        if isinstance(contents[src], str):
            # loadmat turns a variable it cannot decode into a "Read error: ..." string.
            raise InputFileError(f"{label}: MATLAB variable {src!r} is unreadable ({contents[src]})")
        arr = np.asarray(contents[src])
        vectors[ch] = (_vector(label, ch, src, arr, arr.shape), arr.shape, src)
    return _Raw(vectors)


# MAT v5 data-element types scipy has a dtype for, and the array classes it reads.
_MI_DATA = {1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18}
_MI_MATRIX, _MI_COMPRESSED = 14, 15
# Tagged data elements that precede the nested miMATRIX elements, per array class
# (flags, dims, name, then class-specific ones); None: no nested matrices.
_MX_LEADING_DATA = {1: 3, 2: 5, 3: 6, 4: None, 5: None, 16: 3, 17: 4,
                    **{mc: None for mc in range(6, 16)}}


def _check_mat5_structure(data: bytes, label: str) -> None:
    """Walk the element tree of a MAT v5 file before scipy reads it.

    scipy's compiled reader indexes a fixed table with the data type read from
    the file, without a bounds check: one corrupt type byte crashes the whole
    process (segfault) instead of raising.  This walk checks every element's
    type and size against the layout scipy will follow, so corrupt files fail
    here with an InputFileError.
    """
    order = "<" if data[126:128] == b"IM" else ">"  # scipy's own byte-order guess

    def bad(msg: str) -> InputFileError:
        return InputFileError(f"{label}: not a readable MATLAB file (corrupt v5 structure: {msg})")

    def elements(buf: bytes, start: int, end: int, where: str, pad: bool = True) -> list[tuple[int, int, int, bool]]:
        """(type, payload start, payload size, is_small) of each element in buf[start:end].

        Inside an array scipy skips to the next 8-byte boundary after each
        element; between top-level variables it does not (``pad=False``).
        """
        out = []
        pos = start
        while pos < end:
            if end - pos < 8:
                raise bad(f"truncated element tag at byte {pos} of {where}")
            first, second = struct.unpack(order + "II", buf[pos:pos + 8])
            if first >> 16:  # small data element: type and size packed in 4 bytes
                size = first >> 16
                if size > 4:
                    raise bad(f"small element of {size} bytes at byte {pos} of {where}")
                out.append((first & 0xFFFF, pos + 4, size, True))
                pos += 8
                continue
            if second > end - pos - 8:
                raise bad(f"element at byte {pos} of {where} claims {second} bytes, {end - pos - 8} left")
            out.append((first, pos + 8, second, False))
            pos += 8 + second + (-second % 8 if pad else 0)
        return out

    def matrix(buf: bytes, start: int, size: int, where: str, depth: int) -> None:
        if depth > 32:
            raise bad(f"arrays nested deeper than 32 levels in {where}")
        if size == 0:  # an empty matrix has no sub-elements
            return
        subs = elements(buf, start, start + size, where)
        mtype, fstart, fsize, small = subs[0]
        if mtype != 6 or fsize < 8 or small:
            raise bad(f"array flags missing in {where}")
        flags = struct.unpack(order + "I", buf[fstart:fstart + 4])[0]
        mclass = flags & 0xFF
        if mclass not in _MX_LEADING_DATA:
            raise bad(f"unknown array class {mclass} in {where}")
        lead = _MX_LEADING_DATA[mclass]
        # scipy reads numeric/char/sparse parts without checking their type, so
        # they must all be here: flags, dims, name, then real (+ imaginary),
        # or row indices, column pointers, real (+ imaginary) for sparse.
        complex_part = flags >> 11 & 1
        need = {4: 4, 5: 6 + complex_part}.get(mclass, 4 + complex_part if lead is None else 0)
        if len(subs) < need:
            raise bad(f"array of class {mclass} has {len(subs)} of its {need} parts in {where}")
        for i, (etype, estart, esize, _) in enumerate(subs):
            if lead is None or i < lead:
                if etype not in _MI_DATA:
                    raise bad(f"unknown data type {etype} in {where}")
            elif etype != _MI_MATRIX:
                raise bad(f"expected a nested array, got type {etype} in {where}")
            else:
                matrix(buf, estart, esize, where, depth + 1)

    for etype, start, size, small in elements(data, 128, len(data), "the file", pad=False):
        where = f"the variable at byte {start - 8}"
        if small or etype not in (_MI_MATRIX, _MI_COMPRESSED):
            raise bad(f"top-level element of type {etype} at byte {start - 8}")
        if etype == _MI_MATRIX:
            matrix(data, start, size, where, 0)
            continue
        try:
            inner = zlib.decompressobj().decompress(data[start:start + size])
        except zlib.error as exc:
            raise bad(f"compressed {where}: {exc}") from None
        # scipy reads exactly one full-format miMATRIX from the decompressed stream.
        itype, isize = struct.unpack(order + "II", inner[:8]) if len(inner) >= 8 else (0, 0)
        if itype != _MI_MATRIX:
            raise bad(f"compressed {where} does not hold an array")
        if isize > len(inner) - 8:
            raise bad(f"compressed {where} claims {isize} bytes, {len(inner) - 8} decompressed")
        matrix(inner, 8, isize, f"compressed {where}", 0)


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


def _read_epos(data: bytes, label: str, mapping: Mapping[str, str]) -> _Raw:
    if mapping:
        raise UsageError(f"{label}: --map does not apply to an EPOS recorder file (its channels are fixed)")
    arrays = read_epos_arrays(data, label)
    vectors = {ch: (arrays[ch], arrays[ch].shape, src)  # type: ignore[union-attr]
               for ch, src in (("t", "time"), ("q", "integrated velocity"), ("u", "torque"))}
    return _Raw(vectors, q_unit="rad", u_unit=arrays["u_unit"])


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


# --------------------------------------------------------------------------- #
# Common assembly: lengths, units, gain, time base.
# --------------------------------------------------------------------------- #
def _assemble(raw: _Raw, label: str, gain: float, sample_rate: float | None, q_unit_given: str | None,
              digest: str) -> ExcitationLog:
    vec = raw.vectors
    q, q_shape, q_src = vec["q"]
    n = q.shape[0]
    for ch, (arr, shape, src) in vec.items():
        if arr.shape[0] != n:
            raise DataError(
                f"{label}: {_what(ch, src)} has shape {shape} but {_what('q', q_src)} has shape "
                f"{q_shape}; channels must have the same number of samples"
            )
    if n == 0:
        raise DataError(f"{label}: {_what('q', q_src)} is empty")

    q_unit = (q_unit_given or "m") if raw.q_unit is None else raw.q_unit
    u_unit = "V" if raw.u_unit is None else raw.u_unit
    if not isinstance(q_unit, str) or q_unit not in Q_UNITS:
        raise DataError(f"{label}: attribute q_unit={q_unit!r} not supported (expected {', '.join(Q_UNITS)})")
    if q_unit_given is not None and q_unit != q_unit_given:
        raise UsageError(f"--q-unit {q_unit_given} disagrees with {label}: its attribute q_unit={q_unit!r}")
    if not isinstance(u_unit, str) or u_unit not in U_UNITS:
        raise DataError(f"{label}: attribute u_unit={u_unit!r} not supported (expected {', '.join(U_UNITS)})")

    # Divide by the exact power of ten: q_mm / 1000 is the correctly rounded metre value.
    per_metre = Q_UNITS[q_unit]
    q = q / per_metre if per_metre != 1.0 else q
    q_ref = vec["q_ref"][0] if "q_ref" in vec else None
    if q_ref is not None and per_metre != 1.0:
        q_ref = q_ref / per_metre
    u = vec["u"][0]
    u = u * gain if gain != 1.0 else u

    if "t" in vec:
        t = vec["t"][0]
        rate = _rate_from_t(t)
        off = abs(rate - sample_rate) / sample_rate if sample_rate is not None else 0.0
        if off > SAMPLE_RATE_TOLERANCE:  # False for a NaN rate: check_log reports a broken t
            raise UsageError(
                f"--sample-rate {sample_rate:g} Hz disagrees with {label}: its {_what('t', vec['t'][2])} "
                f"gives {rate:.6g} Hz (1/median dt); drop --sample-rate or correct it"
            )
    else:
        assert sample_rate is not None  # _plan demanded t otherwise
        t = np.arange(n, dtype=np.float64) / sample_rate
        rate = sample_rate

    return ExcitationLog(
        t=t, q=q, u=u, q_ref=q_ref, u_unit=u_unit, q_unit_in_file=q_unit,
        input_gain=gain, source=label, sha256=digest, sample_rate=rate,
    )


def _rate_from_t(t: np.ndarray) -> float:
    """``1 / median(dt)`` [Hz] over the finite positive steps; NaN if there are none."""
    # A broken t (inf, huge values) is reported by check_log, not as numpy warnings here.
    with np.errstate(over="ignore", invalid="ignore"):
        dt = np.diff(t)
        dt = dt[np.isfinite(dt) & (dt > 0)]
        rate = float(1.0 / np.median(dt)) if dt.size else math.nan
    return rate if math.isfinite(rate) and rate > 0 else math.nan
