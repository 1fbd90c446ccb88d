"""Bounded reads of input files: regular files only, refused over a limit before and during the read.

:func:`check_input_file` and :func:`read_input_bytes` accept only regular files (a
symlink is followed, but what it points to must be a regular file): a FIFO would
block the tool forever and a device such as ``/dev/zero`` would feed it without end.
A file larger than its limit is refused before it is read, and the read itself stops
at the limit (a file growing while it is read cannot exhaust memory).
:func:`read_toml` reads a spec or gate file (UTF-8 TOML).
"""

from __future__ import annotations

import os
import stat
from typing import Any

from commission.errors import InputFileError, SpecError

try:  # Python >= 3.11
    import tomllib as _toml
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as _toml  # type: ignore[no-redef]

#: Largest excitation log read, bytes (a 10-million-sample HDF5 log of four channels is 320 MB).
MAX_LOG_BYTES = 2 * 1024**3
#: Largest JSON artifact read, bytes (tuning.json of a long search is below 1 MB).
MAX_JSON_BYTES = 64 * 1024**2
#: Largest spec or gate TOML read, bytes.
MAX_TOML_BYTES = 1024**2


def _mib(n: int) -> str:
    return f"{n / 1024**2:.4g} MiB"


def check_input_file(path: str | os.PathLike[str], limit: int, what: str = "file") -> os.stat_result:
    """Refuse a missing input, a folder, a FIFO, a socket or a device, or one over ``limit`` bytes.

    Returns
    -------
    os.stat_result
        Of the file (symlinks followed).

    Raises
    ------
    InputFileError
        Naming the file and what it is.
    """
    name = os.fspath(path)
    try:
        st = os.stat(name)
    except FileNotFoundError:
        raise InputFileError(f"{name}: no such file") from None
    except OSError as exc:
        raise InputFileError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputFileError(f"{name}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode)
                or stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise InputFileError(f"{name}: is {kind}; give a regular file")
    if st.st_size > limit:
        raise InputFileError(f"{name}: {_mib(st.st_size)} is larger than the {_mib(limit)} this tool reads")
    return st


def read_input_bytes(path: str | os.PathLike[str], limit: int) -> bytes:
    """The bytes of a regular input file of at most ``limit`` bytes (:func:`check_input_file`).

    The file is opened without blocking, checked again on the open descriptor
    (it may have been swapped for a FIFO since the first check), and read up to
    ``limit + 1`` bytes, so a file that grows while it is read is refused too.
    """
    name = os.fspath(path)
    check_input_file(name, limit)
    try:
        fd = os.open(name, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise InputFileError(f"{name}: cannot read ({exc.strerror or exc})") from None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise InputFileError(f"{name}: is not a regular file; give a regular file")
        try:
            data = fh.read(limit + 1)
        except OSError as exc:
            raise InputFileError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise InputFileError(f"{name}: larger than the {_mib(limit)} this tool reads")
    return data


def read_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Parse a UTF-8 TOML file (a tune spec or a gate).

    Raises
    ------
    InputFileError
        Missing, not a regular file, or too large.
    SpecError
        Not UTF-8 (naming the byte offset) or not valid TOML.
    """
    name = os.fspath(path)
    data = read_input_bytes(name, MAX_TOML_BYTES)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError(f"{name}: not UTF-8 text (byte {exc.start}: {data[exc.start:exc.start + 1]!r})") from None
    try:
        return _toml.loads(text)
    except _toml.TOMLDecodeError as exc:
        raise SpecError(f"{name}: not valid TOML ({exc})") from None
    except RecursionError:
        raise SpecError(f"{name}: nested too deeply") from None


__all__ = ["MAX_LOG_BYTES", "MAX_JSON_BYTES", "MAX_TOML_BYTES", "check_input_file", "read_input_bytes",
           "read_toml"]
