"""What a fit returns (:class:`AxisFit`), and the model force it describes.

:func:`model_force` evaluates ``M qdd + B qd + Ff(qd) + offset`` (plus the ripple) at given
signals: the fitted model on the identification log, or on another (:func:`evaluate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from commission.identify.friction import stribeck_friction
from commission.identify.ls import FrictionModel, ripple_name, ripple_pitches


Method = Literal["dynamic", "steady+dynamic"]


#: Order of the parameters in :attr:`AxisFit.parameters`.
PARAMETER_ORDER = ("M", "B", "fc", "fs", "vs", "xi", "offset", "ripple_amp", "ripple_phase")


def _ordered(params: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """``params`` in :data:`PARAMETER_ORDER`, then the further ripple pitches' ``ripple_amp_k``, ``ripple_phase_k``."""
    out = {k: params[k] for k in PARAMETER_ORDER if k in params}
    out.update({k: params[k] for k in sorted(params, key=lambda n: (len(n), n))
                if k.startswith(("ripple_amp_", "ripple_phase_"))})
    return out


@dataclass(frozen=True)
class AxisFit:
    """Identified model of one axis.

    Attributes
    ----------
    friction : {"coulomb", "stribeck"}
        Friction model fitted.
    method : {"dynamic", "steady+dynamic"}
        How it was fitted (see the module docstring).
    parameters : dict of str to (float, float)
        ``name -> (value, std)``: ``M`` (u-unit s^2/m), ``B`` (u-unit s/m),
        ``fc`` (u-unit), Stribeck only ``fs`` (u-unit), ``vs`` (m/s), ``xi`` (-),
        ``offset`` (u-unit), with a ripple pitch ``ripple_amp`` (u-unit) and
        ``ripple_phase`` (rad, ripple = ``ripple_amp sin(2 pi q / P + ripple_phase)``);
        each further pitch P_k its ``ripple_amp_k``, ``ripple_phase_k`` (k = 2, 3, ...).
    relative_error : float
        ``||y - y_hat|| / ||y||`` on all decimated rows, fraction.
    condition_number : float
        2-norm condition number of the decimated full-model regressor.
    residual_std : float
        Sample standard deviation of the residuals, u-unit.
    residuals : ndarray
        ``y - y_hat`` at the decimated rows, u-unit.
    t_decimated : ndarray
        Times of the decimated rows, s.
    force_measured : ndarray
        Decimated command ``y``, u-unit.
    force_fitted : ndarray
        Decimated model force ``y_hat``, u-unit.
    steady_velocity, steady_force : ndarray
        Friction-map points (mean velocity m/s, mean command corrected for
        inertia and ripple, u-unit); empty when no constant-velocity legs were used.
    quantization : float or None
        Encoder step the position data show, m (None: not on a grid).
    velocity_resolution : float
        Half-width of the velocity error of a backward-difference estimate, m/s:
        ``quantization * sample_rate``, else ``sqrt(6)`` times the RMS of the
        backward-difference velocity about the filtered velocity.
    v_max : float
        Largest filtered speed in the log, m/s.
    sample_rate : float
        Hz.
    bandwidth_hz, cutoff_hz : float
        Preprocessing bandwidth and Butterworth cut-off, Hz.
    decimation, trim_start : int
        Preprocessing decimation factor and samples trimmed at the start.
    ripple_pitch : float, tuple of float or None
        Force-ripple pitch(es) used, m.
    reversal_speed : float
        Speed below which rows were left out of the mass fit, m/s (0 for ``"dynamic"``).
    warnings : tuple of str
        Human-readable caveats.
    not_identified : dict of str to str
        Parameters the log carries no information on, with the reason (``M`` of a log
        without usable acceleration, when allowed); they are absent from ``parameters``.
    model_rows : ndarray of bool or None
        The decimated rows the rigid-body model describes, away from reversals: those the mass
        fit used (``reversal_speed``), or for the ``"dynamic"`` method those faster than 5 % of
        the log's top speed within the anti-alias filter's reach.  None: every row (too few
        left).
    """

    friction: FrictionModel
    method: Method
    parameters: dict[str, tuple[float, float]]
    relative_error: float
    condition_number: float
    residual_std: float
    residuals: np.ndarray = field(repr=False)
    t_decimated: np.ndarray = field(repr=False)
    force_measured: np.ndarray = field(repr=False)
    force_fitted: np.ndarray = field(repr=False)
    steady_velocity: np.ndarray = field(repr=False)
    steady_force: np.ndarray = field(repr=False)
    quantization: float | None
    velocity_resolution: float
    v_max: float
    sample_rate: float
    bandwidth_hz: float
    cutoff_hz: float
    decimation: int
    trim_start: int
    ripple_pitch: float | tuple[float, ...] | None
    reversal_speed: float
    warnings: tuple[str, ...]
    not_identified: dict[str, str] = field(default_factory=dict)
    model_rows: np.ndarray | None = field(default=None, repr=False)

    def value(self, name: str) -> float:
        """Value of a parameter."""
        return self.parameters[name][0]


def _param_values(params: dict[str, tuple[float, float]]) -> dict[str, float]:
    return {k: v[0] for k, v in params.items()}


def model_force(p: dict[str, float], q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                ripple_pitch: float | tuple[float, ...] | None) -> np.ndarray:
    """Full-rate model force ``M qdd + B qd + Ff(qd) + offset + ripple(q)``, u-unit."""
    y = p.get("M", 0.0) * qdd + p["B"] * qd + stribeck_friction(qd, p["fc"], p.get("fs"), p.get("vs"), p.get("xi"))
    y = y + p["offset"]
    for k, pitch in enumerate(ripple_pitches(ripple_pitch)):
        amp = ripple_name("ripple_amp", k)
        if amp in p:
            y = y + p[amp] * np.sin(2.0 * np.pi * q / pitch + p[ripple_name("ripple_phase", k)])
    return y


def _friction_force(p: dict[str, float], qd: np.ndarray) -> np.ndarray:
    return p["B"] * qd + stribeck_friction(qd, p["fc"], p.get("fs"), p.get("vs"), p.get("xi")) + p["offset"]


def _ripple_params(a: float, b: float, cov: np.ndarray, k: int = 0) -> dict[str, tuple[float, float]]:
    """Amplitude and phase of ``a sin x + b cos x = A sin(x + phase)`` with delta-method std (``k``-th pitch)."""
    amp, phase = ripple_name("ripple_amp", k), ripple_name("ripple_phase", k)
    A = math.hypot(a, b)
    if A == 0:
        return {amp: (0.0, float(math.sqrt(max(cov[0, 0], 0.0)))), phase: (0.0, float("inf"))}
    g_amp = np.array([a / A, b / A])
    g_ph = np.array([-b / A**2, a / A**2])
    return {amp: (A, float(math.sqrt(max(g_amp @ cov @ g_amp, 0.0)))),
            phase: (math.atan2(b, a), float(math.sqrt(max(g_ph @ cov @ g_ph, 0.0))))}
