"""Run a validated ``controller.json`` in Python (CONTRACT §3).

::

    from commission.runtime import load_controller
    ctrl = load_controller("controller.json")   # refuses a file whose checksum or schema fails
    ctrl.reset(y0)                              # initial measured position, m
    u = ctrl.step(y, qd, dqd, ddqd)             # one sample

:class:`Controller` packs the gains once with
:func:`commission.controllers.arc.arc_pack` and calls the compiled
:func:`commission.controllers.arc.arc_step` -- the very kernel ``commission
validate`` simulated -- so the same inputs give the same command bit for bit.

Faults and the safe output
--------------------------
The compiled step guards itself (:mod:`commission.controllers.arc`, "Runtime
guards", with the limits validate chose and simulated: ``controller.json``
``runtime``): an implausible measurement is replaced by a prediction and does
not adapt theta_hat; a jump beyond the stroke, a run of implausible
measurements, an encoder that stays frozen while the command must move the
axis, a tracking error beyond the watchdog or a non-finite value latches a
fault.  Then :attr:`Controller.fault` is True,
:attr:`Controller.fault_reason` names the cause, and :meth:`Controller.step`
returns the **safe command 0** (no force) until :meth:`Controller.reset`;
theta_hat keeps its last good value.  The caller should disable the drive
(or hand over to its brake/fallback) when ``fault`` is set: 0 V on a
vertical or inclined axis does not hold the load.
"""

from __future__ import annotations

import os

import numpy as np

from commission.controller_config import ControllerConfig
from commission.controllers.arc import (FAULT_REASONS, S_FAULT, S_REJECTED, S_THETA, arc_new_state, arc_pack,
                                        arc_reset, arc_step)
from commission.errors import UsageError


class Controller:
    """A discrete output-feedback ARC, ready to run at ``sample_rate``.

    Call :meth:`reset` once with the measured position at start (the axis at
    rest, q_d(0) = y0), then :meth:`step` once per sample, exactly every
    ``sample_period`` seconds; hold the returned command until the next sample.

    Parameters
    ----------
    config : ControllerConfig
        A validated controller (see :func:`load_controller`).
    """

    def __init__(self, config: ControllerConfig) -> None:
        self.config = config
        self._p = arc_pack(config.gains)
        self._s = arc_new_state(self._p)
        self._ready = False

    @property
    def sample_rate(self) -> float:
        """Controller rate, Hz."""
        return self.config.sample_rate

    @property
    def sample_period(self) -> float:
        """Sample period, s."""
        return self.config.gains.Ts

    @property
    def theta_hat(self) -> np.ndarray:
        """Current parameter estimates [1/M, B/M, d_n/M] (a copy)."""
        return self._s[S_THETA:S_THETA + 3].copy()

    @property
    def fault(self) -> bool:
        """True once a fault has latched (the step then returns the safe command 0)."""
        return self._s[S_FAULT] != 0.0

    @property
    def fault_code(self) -> int:
        """The latched fault's reason code (``FAULT_*`` of :mod:`commission.controllers.arc`; 0: none)."""
        return int(self._s[S_FAULT])

    @property
    def fault_reason(self) -> str:
        """The latched fault's reason, e.g. ``"tracking error beyond e_max"`` (``"none"``: no fault)."""
        return FAULT_REASONS[self.fault_code]

    @property
    def rejected(self) -> bool:
        """True when the last sample's measurement was rejected as a glitch (a prediction was used)."""
        return self._s[S_REJECTED] != 0.0

    def reset(self, y0: float) -> None:
        """Start at rest at the measured position ``y0`` (m): filters at rest, theta_hat = theta0.

        Raises
        ------
        UsageError
            ``y0`` is not a finite number (a ``ValueError``, so callers that catch that still do).
        """
        try:
            y0 = float(y0)
        except (TypeError, ValueError, OverflowError):
            raise UsageError(_not_a_number("reset", ("y0",), (y0,))) from None
        if not np.isfinite(y0):
            raise UsageError(f"reset: y0 must be a finite position in m, got {y0}")
        arc_reset(self._p, self._s, y0)
        self._ready = True

    def step(self, y: float, qd: float, dqd: float, ddqd: float) -> float:
        """One sample: the command to hold until the next sample.

        Parameters
        ----------
        y : float
            Measured position, m.
        qd, dqd, ddqd : float
            Desired position (m), velocity (m/s) and acceleration (m/s^2): anything
            ``float()`` converts; a non-finite value latches a fault (module docstring).

        Returns
        -------
        float
            Command, u-unit (``config.units["u"]``), within ``+-u_max``.  Once a
            fault latches (:attr:`fault`, :attr:`fault_reason`) it is the safe
            command 0 until :meth:`reset`.

        Raises
        ------
        UsageError
            An argument ``float()`` refuses (``'abc'``, None, a list), named: a caller's bug, not
            a measurement, so it is not turned into a fault.  A ``ValueError``, as before.
        """
        if not self._ready:
            raise UsageError("step: call reset(y0) first")
        try:  # the conversion the kernel needs anyway; the names are looked up only on failure
            a = (float(y), float(qd), float(dqd), float(ddqd))
        except (TypeError, ValueError, OverflowError):
            raise UsageError(_not_a_number("step", ("y", "qd", "dqd", "ddqd"), (y, qd, dqd, ddqd))) from None
        return float(arc_step(self._p, self._s, *a))


#: Units of the arguments of :meth:`Controller.step` and :meth:`Controller.reset`, for the messages.
_ARG_UNITS = {"y": "m", "y0": "m", "qd": "m", "dqd": "m/s", "ddqd": "m/s^2"}


def _not_a_number(method: str, names: tuple[str, ...], values: tuple[object, ...]) -> str:
    """The message for the first of ``values`` that ``float()`` refuses, naming its argument."""
    for name, v in zip(names, values):
        try:
            float(v)  # type: ignore[arg-type]
        except (TypeError, ValueError, OverflowError):
            return f"{method}: {name} must be a number in {_ARG_UNITS[name]}, got {type(v).__name__} {v!r:.60}"
    return f"{method}: the arguments must be numbers"  # pragma: no cover - float() failed on one of them


def load_controller(path: str | os.PathLike[str], key: bytes | None = None) -> Controller:
    """Load ``controller.json`` and return a runnable :class:`Controller`.

    Parameters
    ----------
    path : path
    key : bytes, optional
        The site's signing key (:func:`commission.controller_config.load_sign_key` reads a key
        file): the file must then carry a valid HMAC-SHA256 signature under it.  Without a
        key only the checksum is verified, which catches damage but not a deliberate edit
        (see :mod:`commission.controller_config`).

    Raises
    ------
    InputFileError
        The file is missing.
    SchemaError
        The file is not valid JSON, a field is missing or out of range (the
        message names its JSON path; a null or non-finite u_max, k1s_max or
        k2s_max included), the checksum does not match, or -- with ``key`` --
        the file is unsigned or its signature does not match the key.
    """
    return Controller(ControllerConfig.load(os.fspath(path), key=key))
