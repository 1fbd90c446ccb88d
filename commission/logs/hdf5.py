"""HDF5 logs (``.h5``, ``.hdf5``) and MATLAB v7.3 files (HDF5 inside), read in a forked child
process with a deadline, so that a damaged file cannot hang or crash the tool."""

from __future__ import annotations

import io
import json
import os
import select
import signal
import struct
import time
from typing import Mapping

import h5py
import numpy as np

from commission.errors import CommissionError, DataError, InputFileError, UsageError
from commission.logs.raw import _Raw, _plan, _vector, _what, _why
from commission.logs.mat import _MATLAB_NUMERIC


_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


#: Time allowed to read an HDF5 file in the isolated reader: this many seconds ...
HDF5_READ_TIMEOUT = 20.0


#: ... plus the file's size at this rate (bytes/s; the file is already in memory).
HDF5_READ_RATE = 20e6


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

