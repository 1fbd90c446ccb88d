"""What every format reader shares: the raw channels a reader found (:class:`_Raw`), the lookup of
contract names in the file, the vector checks, and the assembly of an :class:`ExcitationLog` in SI
units.  A reader module only parses its format into a :class:`_Raw`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from commission.errors import DataError, UsageError
from commission.logs.model import CHANNELS, Q_UNITS, SAMPLE_RATE_TOLERANCE, U_UNITS, ExcitationLog, _rate_from_t


@dataclass
class _Raw:
    vectors: dict[str, tuple[np.ndarray, tuple[int, ...], str]]
    q_unit: object = None
    u_unit: object = None
    q_from_velocity: bool = False


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


def _assemble(raw: _Raw, label: str, gain: float, sample_rate: float | None, q_unit_given: str | None,
              digest: str, counts_per_rev: float | None = None) -> ExcitationLog:
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

    if counts_per_rev is not None and raw.q_unit is not None:
        raise UsageError(f"--counts-per-rev {counts_per_rev:g} reads q as encoder counts, but {label} declares "
                         f"q_unit={raw.q_unit!r}: its q is not in counts; drop --counts-per-rev")
    if counts_per_rev is not None:
        q_unit_given = "rad"  # counts * 2π/N are an angle
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
    if counts_per_rev is not None:
        q = q * (2.0 * math.pi) / counts_per_rev
        q_ref = None if q_ref is None else q_ref * (2.0 * math.pi) / counts_per_rev
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
        input_gain=gain, source=label, sha256=digest, sample_rate=rate, q_from_velocity=raw.q_from_velocity,
    )
