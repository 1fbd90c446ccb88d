"""The excitation log as the rest of the tool sees it: :class:`ExcitationLog` and the contract's channels and units."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

from commission.errors import DataError


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
    q_from_velocity : bool
        ``q`` was integrated from a recorded velocity (an EPOS recorder file), not measured:
        the velocity's quantum (1 rpm) then limits how steady a constant-speed leg can look
        (:func:`commission.identify.steady.find_steady_segments`, ``v_quantum``).
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
    q_from_velocity: bool = False

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


def _rate_from_t(t: np.ndarray) -> float:
    """``1 / median(dt)`` [Hz] over the finite positive steps; NaN if there are none."""
    # A broken t (inf, huge values) is reported by check_log, not as numpy warnings here.
    with np.errstate(over="ignore", invalid="ignore"):
        dt = np.diff(t)
        dt = dt[np.isfinite(dt) & (dt > 0)]
        rate = float(1.0 / np.median(dt)) if dt.size else math.nan
    return rate if math.isfinite(rate) and rate > 0 else math.nan
