"""What the controller design takes from an identification: Assumption-1 bounds and friction compensation.

Paper (Xu & Yao 2001) eq. 6-8: with the friction compensation of eq. 5 the plant is
``M qdd = u* - B qd + d``; its parameters ``theta = [1/M, B/M, d_n/M]`` lie in a
known box and the remainder ``d_tilde = (d - d_n)/M`` is bounded by ``delta_d``.
Here ``d_n = -offset`` (contract §2: ``u = ... + offset``, so the offset acts as a
constant disturbance ``-offset``).

Units: ``theta1`` in m/(u-unit s^2), ``theta2`` in 1/s, ``theta3`` and ``delta_d``
in m/s^2 (u-unit: the command unit, e.g. V).

How the box is built (interval arithmetic over three independent ranges):

* mass ``M in [(M - k s_M)(1 - margin) + payload_min, (M + k s_M)(1 + margin) + payload_max]``;
* viscous ``B in [max(0, (B - k s_B)(1 - margin)), (B + k s_B)(1 + margin)]``;
* disturbance ``d in [d_n - k s_off - D, d_n + k s_off + D]``;

and ``theta1 = 1/M``, ``theta2 = B/M``, ``theta3 = d/M`` over those ranges.

Defaults, and why:

* ``k_sigma = 3``: the statistical part, three standard deviations;
* ``model_margin = 0.2``: +-20 % on ``M`` and ``B``.  Standard deviations only cover
  noise; the model error between identification methods and operating points is
  larger (on EMPS, methods differ by up to 1 % in ``B``; viscous friction drifts
  with temperature by tens of percent);
* ``payload_max = 3 M``: a payload up to three times the identified moving mass.
  The paper's 9.1 kg load took its axis from ``theta1 = 37`` to ``10`` (x3.7 in
  mass); its box ``theta1 in [8.3, 50]`` allows x4.5.  ``payload_min = 0``: the
  identified axis is the empty one, payloads only add mass (``theta1`` decreases);
* ``disturbance_bound = 10 * max(fc, fs)``: load forces and friction-compensation
  errors are of the order of the friction; the paper's ``theta3 in [-50, 50]`` at
  ``M = 0.027`` is ``|d| <= 1.35 V``, about eleven times its 0.12 V stiction.
  With these defaults the paper's plant gets ``theta1 in [8.8, 46]``,
  ``theta2 in [1.9, 15]``, ``theta3 in [-56, 56]`` against the paper's
  ``[8.3, 50]``, ``[2.4, 17.5]``, ``[-50, 50]``.

``delta_d`` is the ``quantile`` (0.999) of ``|r - mean(r)|/M`` over the decimated
inverse-dynamics residuals ``r`` of the identification log (``mean(r)`` is the part
of ``d_n`` the offset missed), on the rows away from reversals (:attr:`AxisFit.model_rows`:
with a friction ladder the rows the mass was fitted on; stiction at a reversal is friction,
which the friction scenarios and the holding force count).  It covers what the identified
model does not explain while moving (noise, unmodelled dynamics, misfit of the friction
curve); it does not
include the error of the atan friction compensation, which the tuner may add
(:attr:`commission.identify.friction.FrictionCompensation.rms_error`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from commission.identify.fit import AxisFit
from commission.identify.friction import FrictionCompensation, friction_compensation_curve


@dataclass(frozen=True)
class ThetaBounds:
    """Assumption 1 of the paper (eq. 8) for one axis.

    Attributes
    ----------
    nominal : tuple of 3 float
        ``[1/M, B/M, -offset/M]`` at the identified values.
    theta_min, theta_max : tuple of 3 float
        Box ``Omega_theta``.
    delta_d : float
        Bound of ``|d_tilde|``, m/s^2.
    mass_range : tuple of 2 float
        ``M`` range the box covers, u-unit s^2/m.
    viscous_range : tuple of 2 float
        ``B`` range, u-unit s/m.
    disturbance_range : tuple of 2 float
        ``d_n`` range, u-unit.
    disturbance_bound : float
        The load-force bound ``D`` the box was built with, u-unit.
    disturbance_bound_defaulted : bool
        True when ``D`` is the default ``10 max(fc, fs)`` (not given by the caller).
    payload_range : tuple of 2 float
        ``(payload_min, payload_max)`` the mass range includes, u-unit s^2/m.
    payload_defaulted : bool
        True when ``payload_max`` is the default ``3 M`` (not given by the caller).
    """

    nominal: tuple[float, float, float]
    theta_min: tuple[float, float, float]
    theta_max: tuple[float, float, float]
    delta_d: float
    mass_range: tuple[float, float]
    viscous_range: tuple[float, float]
    disturbance_range: tuple[float, float]
    disturbance_bound: float
    disturbance_bound_defaulted: bool
    payload_range: tuple[float, float] = (0.0, 0.0)
    payload_defaulted: bool = False


def theta_bounds(fit: AxisFit, **kwargs: Any) -> ThetaBounds:
    """Nominal ``theta`` and the Assumption-1 box of an :class:`AxisFit`.

    :func:`theta_bounds_from` with the fit's parameters and its residuals on the rows the
    rigid-body model describes (:attr:`AxisFit.model_rows`: away from reversals, where the mass
    was fitted); keyword arguments as there.  The rows at reversals carry the filtered friction
    column's error and the stiction phases, which the holding force (static friction) and the
    friction compensation's own error cover; counted in ``delta_d`` they would ask the drive to
    hold a load step of about the friction level again at every moment.
    """
    r = fit.residuals if fit.model_rows is None else fit.residuals[fit.model_rows]
    return theta_bounds_from(fit.parameters, r, **kwargs)


def theta_bounds_from(parameters: Mapping[str, tuple[float, float]], residuals: np.ndarray, *,
                      k_sigma: float = 3.0, model_margin: float = 0.2, payload_min: float = 0.0,
                      payload_max: float | None = None, disturbance_bound: float | None = None,
                      quantile: float = 0.999) -> ThetaBounds:
    """Nominal ``theta`` and the Assumption-1 box from identified parameters.

    Parameters
    ----------
    parameters : mapping of str to (float, float)
        ``name -> (value, std)`` with at least ``M``, ``B``, ``fc`` and ``offset``
        (:attr:`AxisFit.parameters`; ``M`` may be a value the user fixed, std 0).
    residuals : ndarray
        Force residuals of the fit, u-unit: their ``quantile`` over ``M`` gives ``delta_d``.
    k_sigma : float
        Standard deviations added around ``M``, ``B`` and ``offset``.
    model_margin : float
        Relative margin on ``M`` and ``B`` for model error (0.2 = +-20 %).
    payload_min, payload_max : float
        Range of the mass added in operation, u-unit s^2/m (same unit as ``M``);
        ``payload_max`` defaults to ``3 M``.
    disturbance_bound : float, optional
        Largest constant disturbance force besides the offset, u-unit
        (default ``10 * max(fc, fs)``).
    quantile : float
        Quantile of the normalised residuals used for ``delta_d``.

    Returns
    -------
    ThetaBounds
    """
    p = parameters
    M, sM = p["M"]
    B, sB = p["B"]
    off, soff = p["offset"]
    if not M > 0:
        raise ValueError(f"M must be > 0, got {M}")
    if not (k_sigma >= 0 and 0 <= model_margin < 1 and 0 < quantile <= 1):
        raise ValueError(f"need k_sigma >= 0, 0 <= model_margin < 1, 0 < quantile <= 1; got "
                         f"{k_sigma}, {model_margin}, {quantile}")
    pmax = 3.0 * M if payload_max is None else float(payload_max)
    if not 0 <= payload_min <= pmax:
        raise ValueError(f"need 0 <= payload_min <= payload_max, got {payload_min}, {pmax}")
    level = max(p["fc"][0], p["fs"][0]) if "fs" in p else p["fc"][0]
    D = 10.0 * abs(level) if disturbance_bound is None else float(disturbance_bound)
    if D < 0:
        raise ValueError(f"disturbance_bound must be >= 0, got {D}")

    m_lo = (M - k_sigma * sM) * (1.0 - model_margin) + payload_min
    m_hi = (M + k_sigma * sM) * (1.0 + model_margin) + pmax
    if not m_lo > 0:
        raise ValueError(f"the mass range reaches zero (M={M}, std {sM}, k_sigma={k_sigma}); lower k_sigma")
    b_lo = max(0.0, (B - k_sigma * sB) * (1.0 - model_margin))
    b_hi = max(b_lo, (B + k_sigma * sB) * (1.0 + model_margin))
    dn = -off
    d_lo, d_hi = dn - k_sigma * soff - D, dn + k_sigma * soff + D
    th3 = [d_lo / m_lo, d_lo / m_hi, d_hi / m_lo, d_hi / m_hi]
    r = np.asarray(residuals)
    delta_d = float(np.quantile(np.abs(r - r.mean()), quantile)) / M
    return ThetaBounds(nominal=(1.0 / M, B / M, dn / M),
                       theta_min=(1.0 / m_hi, b_lo / m_hi, min(th3)),
                       theta_max=(1.0 / m_lo, b_hi / m_lo, max(th3)),
                       delta_d=delta_d, mass_range=(m_lo, m_hi), viscous_range=(b_lo, b_hi),
                       disturbance_range=(d_lo, d_hi), disturbance_bound=D,
                       disturbance_bound_defaulted=disturbance_bound is None,
                       payload_range=(float(payload_min), pmax), payload_defaulted=payload_max is None)


def friction_compensation(fit: AxisFit, *, v_resolution: float | None = None,
                          v_max: float | None = None) -> FrictionCompensation:
    """``level (2/pi) atan(slope v)`` fitted to the identified nonlinear friction.

    Only the Coulomb/Stribeck part ``Ff`` is fitted; the viscous part is ``theta2``'s.

    Parameters
    ----------
    fit : AxisFit
    v_resolution : float, optional
        Velocity error half-width of the controller's velocity estimate, m/s
        (default ``fit.velocity_resolution``: one encoder count per sample of the log).
    v_max : float, optional
        Top of the fitted speed range, m/s (default the largest speed in the log).

    Returns
    -------
    FrictionCompensation
    """
    p = fit.parameters
    vr = fit.velocity_resolution if v_resolution is None else float(v_resolution)
    vm = fit.v_max if v_max is None else float(v_max)
    return friction_compensation_curve(p["fc"][0], p["fs"][0] if "fs" in p else None,
                                       p["vs"][0] if "vs" in p else None, p["xi"][0] if "xi" in p else None,
                                       v_max=vm, v_resolution=vr)
