"""PID with feedforward and friction compensation, eq. (57) of Xu & Yao (2001).

Discrete law, evaluated once per sample ``k`` (period ``Ts``)::

    v_k  = (y_k - y_{k-1}) / Ts                      # backward difference
    e_k  = y_k - qd_k
    I_k  = I_{k-1} + Ts e_k                          # rectangle rule, includes e_k
    u_k  = M_hat ddqd_k + B_hat v_k + F_hat(v_k)
           - Kp e_k - Ki I_k - Kd (v_k - dqd_k)
    F_hat(v) = level (2/pi) atan(slope v)            # CONTRACT sec. 2 form
    u_k  = clip(u_k, -u_max, u_max)

The paper's friction term ``(0.2/pi) atan(900 qdot)`` is ``level = 0.1``,
``slope = 900``.  There is no anti-windup: the paper's law has none.

The controller is a pair (packed parameters ``p``, mutable state ``s``) so
that the simulator can call :func:`pid_step` inside its compiled loop with the
same signature as ``arc_step``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

# Layout of the packed parameter vector.
G_TS = 0  # sample period, s
G_M = 1  # feedforward mass, u-unit s^2/m
G_B = 2  # feedforward viscous, u-unit s/m
G_KP = 3  # u-unit/m
G_KI = 4  # u-unit/(m s)
G_KD = 5  # u-unit s/m
G_FLEVEL = 6  # friction-compensation level, u-unit
G_FSLOPE = 7  # friction-compensation slope, s/m
G_UMAX = 8  # output limit, u-unit (inf: none)
NG = 9

# Layout of the state vector.
S_YPREV = 0  # previous measured position, m
S_INT = 1  # integral of e, m s
S_FAULT = 2  # 0, or 1 once an input was not finite (latched until pid_reset)
NS = 3
#: The entries of the state carrying the dynamics (what a linearisation perturbs).
PID_DYNAMIC = (S_YPREV, S_INT)


@dataclass(frozen=True)
class PidGains:
    """Gains of the PID law (57).

    Attributes
    ----------
    Ts : float
        Sample period, s.
    M_hat : float
        Fixed mass estimate used for the acceleration feedforward, u-unit s^2/m.
    B_hat : float
        Fixed viscous estimate multiplying the measured velocity, u-unit s/m.
    Kp : float
        Proportional gain, u-unit/m.
    Ki : float
        Integral gain, u-unit/(m s).
    Kd : float
        Derivative gain, u-unit s/m.
    fric_level : float
        Friction-compensation level, u-unit (``F_hat(v) = level (2/pi) atan(slope v)``).
    fric_slope : float
        Friction-compensation slope, s/m.
    u_max : float
        Symmetric output limit, u-unit; ``inf`` for none.
    """

    Ts: float
    M_hat: float
    B_hat: float
    Kp: float
    Ki: float
    Kd: float
    fric_level: float = 0.0
    fric_slope: float = 0.0
    u_max: float = math.inf

    def __post_init__(self) -> None:
        for name in ("Ts", "M_hat", "B_hat", "Kp", "Ki", "Kd", "fric_level", "fric_slope"):
            val = getattr(self, name)
            if not math.isfinite(val):
                raise ValueError(f"PidGains.{name}: must be finite, got {val}")
        if not self.Ts > 0:
            raise ValueError(f"PidGains.Ts: must be > 0 s, got {self.Ts}")
        if not self.u_max > 0:
            raise ValueError(f"PidGains.u_max: must be > 0, got {self.u_max}")


def pid_place_poles(M: float, pole: float) -> tuple[float, float, float]:
    """Gains that put all three roots of (56) at ``pole``.

    ``s^3 + (Kd/M) s^2 + (Kp/M) s + Ki/M = (s - pole)^3`` gives
    ``Kd = -3 pole M``, ``Kp = 3 pole^2 M``, ``Ki = -pole^3 M``.

    Parameters
    ----------
    M : float
        Design mass, u-unit s^2/m (the paper uses ``M_min = 0.02``).
    pole : float
        Triple closed-loop pole, rad/s; must be negative (paper: -300).

    Returns
    -------
    Kp, Ki, Kd : float
        u-unit/m, u-unit/(m s), u-unit s/m.
    """
    if not M > 0:
        raise ValueError(f"pid_place_poles: M must be > 0, got {M}")
    if not pole < 0:
        raise ValueError(f"pid_place_poles: pole must be < 0 rad/s, got {pole}")
    return 3.0 * pole * pole * M, -pole ** 3 * M, -3.0 * pole * M


def pid_pack(g: PidGains) -> np.ndarray:
    """Pack :class:`PidGains` into the float64 vector :func:`pid_step` takes."""
    p = np.empty(NG)
    p[G_TS], p[G_M], p[G_B] = g.Ts, g.M_hat, g.B_hat
    p[G_KP], p[G_KI], p[G_KD] = g.Kp, g.Ki, g.Kd
    p[G_FLEVEL], p[G_FSLOPE], p[G_UMAX] = g.fric_level, g.fric_slope, g.u_max
    return p


def pid_new_state(p: np.ndarray) -> np.ndarray:
    """A fresh state vector for the packed gains ``p`` (call :func:`pid_reset` before use)."""
    if p.shape != (NG,):
        raise ValueError(f"pid_new_state: p must have shape ({NG},), got {p.shape}")
    return np.zeros(NS)


@njit(cache=True)
def pid_reset(p, s, y0):
    """Start at rest at the measured position ``y0`` (m): zero velocity and integral."""
    s[S_YPREV] = y0
    s[S_INT] = 0.0
    s[S_FAULT] = 0.0


@njit(cache=True)
def pid_step(p, s, y, qd, dqd, ddqd):
    """One sample of (57).

    Parameters
    ----------
    p : float64[NG]
        Packed gains (:func:`pid_pack`).
    s : float64[NS]
        State, updated in place.
    y : float
        Measured position, m.
    qd, dqd, ddqd : float
        Desired position (m), velocity (m/s) and acceleration (m/s^2).

    Returns
    -------
    float
        Command, u-unit.  A non-finite input latches ``s[S_FAULT] = 1`` and the
        step returns the safe command 0 until :func:`pid_reset` (the state keeps
        its last good values).
    """
    if s[S_FAULT] != 0.0:
        return 0.0
    if not (math.isfinite(y) and math.isfinite(qd) and math.isfinite(dqd) and math.isfinite(ddqd)):
        s[S_FAULT] = 1.0
        return 0.0
    Ts = p[G_TS]
    v = (y - s[S_YPREV]) / Ts
    e = y - qd
    s[S_INT] += Ts * e
    s[S_YPREV] = y
    u = (p[G_M] * ddqd + p[G_B] * v
         + p[G_FLEVEL] * (2.0 / math.pi) * math.atan(p[G_FSLOPE] * v)
         - p[G_KP] * e - p[G_KI] * s[S_INT] - p[G_KD] * (v - dqd))
    umax = p[G_UMAX]
    if u > umax:
        u = umax
    elif u < -umax:
        u = -umax
    return u
