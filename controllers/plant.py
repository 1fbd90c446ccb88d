"""Sampled-data plant of a linear-motor axis (paper eq. 1-4), sub-stepped.

Model, in command units (the contract's sign convention)::

    M qdd = u + d(t) - offset - B qd - Ff(qd) - ripple(q)
    Ff(v) = [fc + (fs - fc) exp(-|v/vs|^xi)] sign(v)
    ripple(q) = A_r sin(2 pi q / pitch)

Stiction scheme (stated because a naive integrator chatters at v = 0): a
switch model (Karnopp/Leine) on a fixed-step semi-implicit Euler integrator.

* Sliding (v != 0): integrate with the friction of the current velocity.  If a
  step would carry v through zero, the axis stops exactly at v = 0 and enters
  the stuck state, instead of reversing with the wrong friction sign.
* Stuck (v == 0): the axis stays stuck while the net non-friction force is at
  most the static level fs (friction balances it); otherwise it breaks away
  with acceleration (F - fs sign F) / M.

With h a small fraction of the sample period (default 10 sub-steps), this
keeps stick-slip, reversals and break-away physical and bounded.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Layout of the plant parameter vector (float64[NP]).
P_M = 0  # mass, u-unit s^2/m
P_B = 1  # viscous, u-unit s/m
P_FC = 2  # Coulomb level, u-unit
P_FS = 3  # static (stiction) level, u-unit
P_VS = 4  # Stribeck velocity, m/s
P_XI = 5  # Stribeck exponent, -
P_OFFSET = 6  # constant force offset, u-unit (u_equiv = ... + offset)
P_RIPPLE_AMP = 7  # force-ripple amplitude, u-unit
P_RIPPLE_PITCH = 8  # force-ripple pitch, m (<= 0: no ripple)
NP = 9


def plant_vector(M: float, B: float, fc: float = 0.0, fs: float | None = None,
                 vs: float = 0.01, xi: float = 2.0, offset: float = 0.0,
                 ripple_amp: float = 0.0, ripple_pitch: float = 0.0) -> np.ndarray:
    """Pack plant parameters into the float64 vector the kernels take.

    Parameters
    ----------
    M : float
        Mass, u-unit s^2/m.
    B : float
        Viscous coefficient, u-unit s/m.
    fc, fs : float
        Coulomb and static friction levels, u-unit (``fs`` defaults to ``fc``).
    vs : float
        Stribeck velocity, m/s.
    xi : float
        Stribeck exponent.
    offset : float
        Constant force offset, u-unit.
    ripple_amp : float
        Force-ripple amplitude, u-unit.
    ripple_pitch : float
        Force-ripple pitch, m; 0 disables ripple.
    """
    if not (M > 0 and B >= 0 and fc >= 0 and vs > 0 and xi > 0):
        raise ValueError(f"plant_vector: need M > 0, B >= 0, fc >= 0, vs > 0, xi > 0; got M={M}, B={B}, fc={fc}, vs={vs}, xi={xi}")
    p = np.zeros(NP)
    p[P_M], p[P_B], p[P_FC] = M, B, fc
    p[P_FS] = fc if fs is None else fs
    p[P_VS], p[P_XI], p[P_OFFSET] = vs, xi, offset
    p[P_RIPPLE_AMP], p[P_RIPPLE_PITCH] = ripple_amp, ripple_pitch
    return p


@njit(cache=True)
def stribeck(p, v):
    """Nonlinear friction Ff(v) of the plant ``p`` (without the viscous part), u-unit."""
    if v == 0.0:
        return 0.0
    level = p[P_FC] + (p[P_FS] - p[P_FC]) * math.exp(-abs(v / p[P_VS]) ** p[P_XI])
    return level if v > 0.0 else -level


@njit(cache=True)
def ripple(p, x):
    """Force ripple at position ``x`` (m), u-unit."""
    if p[P_RIPPLE_PITCH] <= 0.0:
        return 0.0
    return p[P_RIPPLE_AMP] * math.sin(2.0 * math.pi * x / p[P_RIPPLE_PITCH])


@njit(cache=True)
def plant_advance(p, x, v, u, h, n):
    """Advance the plant over ``n`` sub-steps of ``h`` seconds under a held input.

    Parameters
    ----------
    p : float64[NP]
        Plant vector (:func:`plant_vector`).
    x, v : float
        Position (m) and velocity (m/s) at the start.
    u : float
        Held input including any disturbance, u-unit.
    h : float
        Sub-step, s.
    n : int
        Number of sub-steps.

    Returns
    -------
    x, v : float
        Position (m) and velocity (m/s) at the end.
    """
    M = p[P_M]
    for _ in range(n):
        F = u - p[P_OFFSET] - ripple(p, x)  # everything but friction and viscous
        if v == 0.0:
            if abs(F) <= p[P_FS]:
                continue  # stuck: static friction balances F
            a = (F - math.copysign(p[P_FS], F)) / M
            v = a * h
        else:
            a = (F - p[P_B] * v - stribeck(p, v)) / M
            v_new = v + a * h
            if v_new * v < 0.0:
                v_new = 0.0  # crossed zero: stop, next sub-step decides stick or slip
            v = v_new
        x += v * h
    return x, v
