"""NumPy logs: ``.npy`` (one array) and ``.npz`` (named arrays), read by numpy itself, never unpickled.

Channel names
-------------
A ``.npz`` archive names its arrays, so its channels are found as in an HDF5 or MAT file:
by the contract name, or by the name ``--map`` gives (``--map q=pos`` reads the member
``pos.npy``).  A ``.npy`` file holds one array:

- a structured (record) array names its fields, which are the channel names;
- a plain 2-D array has no names, so ``--map`` gives each channel's *index*:
  ``--map t=0 --map q=1 --map u=2``.  The channels run along the shorter axis (a
  ``(3, N)`` array has one channel per row, an ``(N, 3)`` one per column), which is
  unambiguous whenever there are fewer channels than samples; a square array is refused.
  Without an index for ``q`` and ``u`` (and ``t``, unless ``--sample-rate`` is given) the
  array is refused, naming what is missing: guessing that row 0 is time would silently
  swap channels of a file laid out otherwise.

Safety
------
Arrays are loaded with ``allow_pickle=False``: an object array (which only pickle can
rebuild) is refused, named, instead of running code from the file.  The file's bytes
are already bounded by :data:`commission.infra.files.MAX_LOG_BYTES`; an ``.npz`` is a zip
archive, so the uncompressed sizes its directory declares for the members to be read
are checked against the same limit before anything is decompressed, and each member's
``.npy`` header is checked against the size it declares.
"""

from __future__ import annotations

import io
import zipfile
from typing import Mapping

import numpy as np

from commission.errors import DataError, InputFileError
from commission.infra.files import MAX_LOG_BYTES
from commission.logs.model import CHANNELS
from commission.logs.raw import _KIND_NAMES, _Raw, _plan, _vector, _why


_NPY_MAGIC = b"\x93NUMPY"
_ZIP_MAGIC = b"PK\x03\x04"


def looks_like_npz(data: bytes) -> bool:
    """Whether ``data`` starts like a zip archive (an ``.npz``), not a bare ``.npy``."""
    return data[:4] == _ZIP_MAGIC


def _kind_error(label: str, what: str, dtype: np.dtype) -> DataError:
    if dtype.hasobject:
        return DataError(f"{label}: {what} holds Python objects (dtype {dtype}), which only pickle could rebuild; "
                         "refused (allow_pickle=False): save the channels as float or integer arrays")
    kind = _KIND_NAMES.get(dtype.kind, "is not numeric")
    return DataError(f"{label}: {what} {kind} (dtype {dtype}); expected real numbers (float or integer)")


def _load_npy(buf: bytes, label: str, what: str) -> np.ndarray:
    """One ``.npy`` array from ``buf``, without pickle; a refused dtype names ``what``."""
    fh = io.BytesIO(buf)
    try:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
    except Exception as exc:  # noqa: BLE001 - a damaged header fails in several numpy-specific ways
        raise InputFileError(f"{label}: not a readable NumPy file ({what}: {_why(exc)})") from None
    if dtype.hasobject:
        raise _kind_error(label, what, dtype)
    count = int(np.prod(shape, dtype=np.int64)) if shape else 1
    if count * dtype.itemsize > len(buf):
        raise InputFileError(f"{label}: not a readable NumPy file ({what}: shape {shape} of {dtype} needs "
                             f"{count * dtype.itemsize} bytes, the file holds {len(buf)})")
    try:
        arr = np.load(io.BytesIO(buf), allow_pickle=False)
    except Exception as exc:  # noqa: BLE001
        raise InputFileError(f"{label}: not a readable NumPy file ({what}: {_why(exc)})") from None
    return np.asarray(arr)


def _read_npy(data: bytes, label: str, mapping: Mapping[str, str], need_t: bool) -> _Raw:
    """Channels of a ``.npy`` file: the fields of a record array, or rows/columns of a 2-D array by index."""
    if not data.startswith(_NPY_MAGIC):
        raise InputFileError(f"{label}: not a readable NumPy .npy file (no NUMPY header)")
    arr = _load_npy(data, label, "the array")
    if arr.dtype.names:  # a record array names its channels
        names = list(arr.dtype.names)
        plan = _plan(label, lambda name: name in names, names, mapping, need_t)
        vectors = {}
        for ch, src in plan.items():
            col = arr[src]
            vectors[ch] = (_vector(label, ch, src, col, col.shape), col.shape, src)
        return _Raw(vectors)
    if arr.dtype.kind not in "fiu":
        raise _kind_error(label, "the array", arr.dtype)
    if arr.ndim != 2:
        raise DataError(f"{label}: the array has shape {arr.shape}; a .npy log is a 2-D array with one channel "
                        "per row or per column (e.g. shape (3, N) with --map t=0 --map q=1 --map u=2), or a "
                        "record array with named fields")
    rows, cols = arr.shape
    if rows == cols:
        raise DataError(f"{label}: the array has shape {arr.shape}: square, so it cannot tell channels from "
                        "samples; store it as (channels, samples) with fewer channels than samples")
    by_row = rows < cols
    n_ch = min(rows, cols)
    axis = "row" if by_row else "column"
    required = [ch for ch in CHANNELS if ch in ("q", "u") or (ch == "t" and need_t)]
    missing = [ch for ch in required if ch not in mapping]
    if missing:
        raise DataError(
            f"{label}: a 2-D array of shape {arr.shape} ({n_ch} {axis}s of {max(rows, cols)} samples) has no "
            f"channel names; give the {axis} of each: {' '.join(f'--map {ch}={axis.upper()}' for ch in missing)} "
            f"(0-based, e.g. {' '.join(f'--map {ch}={i}' for i, ch in enumerate(required))})"
            + (" or --sample-rate HZ for t" if "t" in missing else ""))
    vectors = {}
    for ch in CHANNELS:
        if ch not in mapping:
            continue
        src = mapping[ch]
        try:
            k = int(src)
        except ValueError:
            k = -1
        if not (src.strip().isdigit() and 0 <= k < n_ch):
            raise DataError(f"{label}: channel {ch!r} mapped to {src!r}, but a plain 2-D array has no names: "
                            f"expected a {axis} index 0..{n_ch - 1} (shape {arr.shape})")
        vec = arr[k] if by_row else arr[:, k]
        vectors[ch] = (np.asarray(vec, dtype=np.float64), arr.shape, f"{axis} {k}")
    return _Raw(vectors)


def _read_npz(data: bytes, label: str, mapping: Mapping[str, str], need_t: bool) -> _Raw:
    """Channels of an ``.npz`` archive: one named array each (``--map q=NAME`` reads ``NAME.npy``)."""
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
        members = {info.filename: info for info in zf.infolist()}
    except Exception as exc:  # noqa: BLE001 - a damaged archive fails in many zipfile-specific ways
        raise InputFileError(f"{label}: not a readable NumPy .npz file ({_why(exc)})") from None
    names = sorted(n[:-4] for n in members if n.endswith(".npy"))
    plan = _plan(label, lambda name: name in names, names, mapping, need_t)
    declared = sum(members[src + ".npy"].file_size for src in set(plan.values()))
    if declared > MAX_LOG_BYTES:
        raise InputFileError(f"{label}: its arrays {', '.join(sorted(set(plan.values())))} unpack to {declared} "
                             f"bytes, over the {MAX_LOG_BYTES}-byte limit of a log")
    vectors = {}
    for ch, src in plan.items():
        info = members[src + ".npy"]
        try:
            with zf.open(info) as fh:
                buf = fh.read(info.file_size + 1)
        except Exception as exc:  # noqa: BLE001 - zipfile, zlib, CRC and header errors alike
            raise InputFileError(f"{label}: array {src!r} is unreadable ({_why(exc)})") from None
        if len(buf) > info.file_size:
            raise InputFileError(f"{label}: array {src!r} unpacks to more than the {info.file_size} bytes "
                                 "its archive declares")
        arr = _load_npy(buf, label, f"channel {ch!r} ({src!r})" if src != ch else f"channel {ch!r}")
        if arr.dtype.names:
            raise _kind_error(label, f"channel {ch!r} ({src!r})" if src != ch else f"channel {ch!r}", arr.dtype)
        vectors[ch] = (_vector(label, ch, src, arr, arr.shape), arr.shape, src)
    return _Raw(vectors)
