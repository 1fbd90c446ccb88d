"""Excitation logs written in the format of CONTRACT section 1: HDF5 (:func:`write_log_h5`) and CSV
(:func:`write_log_csv`), checked channel by channel first.
"""

from __future__ import annotations

import os
from typing import Any, Mapping

import numpy as np

from commission.errors import DataError, UsageError
from commission.jsonio import write_atomic
from commission.synth.truth import LOG_CHANNELS, Q_UNITS, U_UNITS


def _checked_channels(data: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Validate a log against CONTRACT section 1; return float64 arrays in file order."""
    unknown = sorted(set(data) - set(LOG_CHANNELS))
    if unknown:
        raise DataError(f"log: unknown channel {unknown[0]!r} (contract names: {', '.join(LOG_CHANNELS)})")
    for name in ("t", "q", "u"):
        if name not in data:
            raise DataError(f"log: required channel {name!r} is missing")
    out: dict[str, np.ndarray] = {}
    for name in LOG_CHANNELS:
        if name not in data:
            continue
        a = np.asarray(data[name], dtype=np.float64)
        if a.ndim != 1:
            raise DataError(f"{name}: expected a 1-D array, got shape {a.shape}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise DataError(f"{name}: sample {bad[0]} is {float(a[bad[0]])!r}")
        out[name] = a
    n = out["t"].size
    for name, a in out.items():
        if a.size != n:
            raise DataError(f"{name}: {a.size} samples, but t has {n}")
    if n < 2:
        raise DataError(f"t: need at least 2 samples, got {n}")
    t = out["t"]
    dec = np.flatnonzero(np.diff(t) <= 0)
    if dec.size:
        i = int(dec[0]) + 1
        raise DataError(f"t: not strictly increasing at index {i} (t[{i}]={float(t[i])!r} <= t[{i - 1}]={float(t[i - 1])!r})")
    return out


def write_log_h5(path: str | os.PathLike[str], data: Mapping[str, Any], *,
                 q_unit: str = "m", u_unit: str = "V") -> None:
    """Write an excitation log as HDF5 (CONTRACT section 1).

    1-D float64 datasets ``t``, ``q``, ``u`` and, if present, ``q_ref`` at the
    root (gzip + shuffle, transparent to any HDF5 reader); root attributes
    ``q_unit`` and ``u_unit``.  Written to a temporary file and renamed, so
    a failure leaves nothing behind.

    Parameters
    ----------
    path : path-like
        Output file (``.h5`` or ``.hdf5``).
    data : mapping of str to array
        Channels ``t`` (s), ``q`` (``q_unit``), ``u`` (``u_unit``), optional ``q_ref``.
    q_unit : {'m', 'mm', 'um'}
        Unit of ``q`` and ``q_ref``.
    u_unit : {'V', 'N', 'A'}
        Unit of ``u``.

    Raises
    ------
    DataError
        A channel is missing, unknown, not 1-D, non-finite, of another length,
        or ``t`` is not strictly increasing.
    UsageError
        An unknown unit.
    """
    import h5py  # pipeline layer only

    if q_unit not in Q_UNITS:
        raise UsageError(f"q_unit: {q_unit!r} is not one of {', '.join(Q_UNITS)}")
    if u_unit not in U_UNITS:
        raise UsageError(f"u_unit: {u_unit!r} is not one of {', '.join(U_UNITS)}")
    chans = _checked_channels(data)

    def write(tmp: str) -> None:
        with h5py.File(tmp, "w") as f:
            for name, a in chans.items():
                f.create_dataset(name, data=a, dtype="f8", compression="gzip",
                                 compression_opts=4, shuffle=True)
            f.attrs["q_unit"] = q_unit
            f.attrs["u_unit"] = u_unit

    write_atomic(path, write)


def write_log_csv(path: str | os.PathLike[str], data: Mapping[str, Any], *, digits: int = 12) -> None:
    """Write an excitation log as CSV (CONTRACT section 1).

    A header row ``t,q,u[,q_ref]`` then one row per sample, each value with
    ``digits`` significant digits (``%.12g`` keeps 0.01 nm on a 1 m stroke
    and prints grid values such as 0.0004 or 1.5e-06 exactly).

    Parameters
    ----------
    path : path-like
        Output file (``.csv``).
    data : mapping of str to array
        Channels ``t`` (s), ``q`` (m), ``u`` (u-unit), optional ``q_ref`` (m).
    digits : int
        Significant digits per value (1-17).

    Raises
    ------
    DataError
        As :func:`write_log_h5`.
    UsageError
        ``digits`` out of range.
    """
    if not (isinstance(digits, int) and 1 <= digits <= 17):
        raise UsageError(f"digits: need an integer 1-17, got {digits!r}")
    chans = _checked_channels(data)
    cols = np.column_stack(list(chans.values()))

    def write(tmp: str) -> None:
        with open(tmp, "w", newline="\n") as fh:
            np.savetxt(fh, cols, fmt=f"%.{digits}g", delimiter=",",
                       header=",".join(chans), comments="")

    write_atomic(path, write)
