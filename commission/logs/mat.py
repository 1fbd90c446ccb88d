"""MATLAB v5 logs (``.mat``): the file's structure walked before :func:`scipy.io.loadmat` reads it."""

from __future__ import annotations

import io
import struct
import warnings
import zlib
from typing import Mapping

import numpy as np
import scipy.io

from commission.errors import InputFileError
from commission.logs.raw import _Raw, _plan, _vector, _why


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


_MI_MATRIX, _MI_COMPRESSED = 14, 15
_MI_DATA = {1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18}


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

