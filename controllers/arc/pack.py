"""Packing :class:`~commission.controllers.arc.gains.ArcGains` for the compiled step.

Everything that does not change from sample to sample is computed once here
(:func:`arc_pack`): the exact sampled-data filter matrices of (18) and (12) for a
first-order-hold input (one matrix exponential, Van Loan), 1/(4 eps), ||theta_M||^2
and the quadratic weights of the nonlinear gains K1 and K2.  :func:`arc_new_state`
allocates the state vector the step updates in place.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from commission.controllers.arc.gains import ArcGains, ArcGainsError
from commission.controllers.arc.layout import (NP, NS, P_AD, P_A_MAX, P_BD, P_BD1, P_C11, P_C12, P_C21, P_C22,
    P_CPHI1, P_CPHI2, P_CT2SQ, P_CTH2, P_DY_FAULT, P_DY_MAX, P_E_MAX, P_FLEVEL, P_FREEZE_SAT, P_FSLOPE, P_G1,
    P_G2, P_GAMMA, P_K1, P_K1MAX, P_K2, P_K2MAX, P_NFRZ_MAX, P_NREJ_MAX, P_Q1, P_Q2, P_THETA0, P_THM2, P_TMAX,
    P_TMIN, P_TS, P_UMAX, P_U_FREE, P_W1, P_W2, P_Y_ERR)


def _filter_matrices(k1: float, k2: float, Ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact hold matrices of x' = A0 x + e2 r over one period Ts (s).

    With r going linearly from r0 to r1 over the period (a first-order hold),
    x(Ts) = Ad x(0) + Bd r0 + Bd1 (r1 - r0), where Ad = expm(A0 Ts),
    Bd = int_0^Ts expm(A0 s) ds e2 and Bd1 = int_0^Ts expm(A0 (Ts - s)) e2 s/Ts ds;
    a held input (zero-order hold) is r1 = r0.  All three are read from one
    matrix exponential of the augmented system [x, r, r'] (Van Loan).

    Returns
    -------
    Ad : numpy.ndarray, shape (2, 2)
    Bd, Bd1 : numpy.ndarray, shape (2,)
    """
    F = np.zeros((4, 4))
    F[0, 0], F[0, 1], F[1, 0] = -k1 * Ts, Ts, -k2 * Ts  # A0 Ts
    F[1, 2] = Ts  # e2 Ts
    F[2, 3] = 1.0  # r' Ts = (r1 - r0), constant over the period
    E = expm(F)
    return E[:2, :2].copy(), E[:2, 2].copy(), E[:2, 3].copy()


def _inv4(eps: float) -> float:
    """1/(4 eps), 0 for a switched-off term (eps = inf)."""
    return 0.0 if math.isinf(eps) else 1.0 / (4.0 * eps)


def arc_pack(g: ArcGains) -> np.ndarray:
    """Pack :class:`ArcGains` into the float64 vector the compiled kernels take.

    Everything that does not change from sample to sample is computed here once:
    the exact sampled-data filter matrices (one matrix exponential), 1/(4 eps),
    ||theta_M||^2 and the quadratic weights of the nonlinear gains.

    Parameters
    ----------
    g : ArcGains
        Controller gains.

    Returns
    -------
    numpy.ndarray
        float64[NP].
    """
    p = np.zeros(NP)
    p[P_TS], p[P_K1], p[P_K2] = g.Ts, g.k1, g.k2
    p[P_W1], p[P_W2], p[P_G1], p[P_G2] = g.w1, g.w2, g.g1, g.g2
    p[P_C11], p[P_C12] = _inv4(g.eps11), _inv4(g.eps12)
    p[P_C21], p[P_C22] = _inv4(g.eps21), _inv4(g.eps22)
    p[P_CPHI1:P_CPHI1 + 3] = g.C_phi1
    p[P_CPHI2:P_CPHI2 + 3] = g.C_phi2
    p[P_CTH2:P_CTH2 + 3] = g.C_theta2
    p[P_GAMMA:P_GAMMA + 3] = g.Gamma
    p[P_TMIN:P_TMIN + 3] = g.theta_min
    p[P_TMAX:P_TMAX + 3] = g.theta_max
    p[P_THETA0:P_THETA0 + 3] = g.theta0
    p[P_FLEVEL], p[P_FSLOPE] = g.fric_level, g.fric_slope
    p[P_K1MAX], p[P_K2MAX], p[P_UMAX] = g.k1s_max, g.k2s_max, g.u_max
    thm = np.asarray(g.theta_max) - np.asarray(g.theta_min)
    thm2 = float(thm @ thm)
    p[P_THM2] = thm2
    cg1 = np.asarray(g.C_phi1) * np.asarray(g.Gamma)
    cg2 = np.asarray(g.C_phi2) * np.asarray(g.Gamma)
    p[P_Q1:P_Q1 + 3] = cg1 * cg1 + p[P_C11] * thm2
    p[P_Q2:P_Q2 + 3] = cg2 * cg2 + p[P_C21] * thm2
    p[P_CT2SQ:P_CT2SQ + 3] = np.asarray(g.C_theta2) ** 2
    Ad, Bd, Bd1 = _filter_matrices(g.k1, g.k2, g.Ts)
    p[P_AD:P_AD + 4] = Ad.ravel()
    p[P_BD:P_BD + 2] = Bd
    p[P_BD1:P_BD1 + 2] = Bd1
    p[P_DY_MAX], p[P_DY_FAULT], p[P_NREJ_MAX], p[P_E_MAX] = g.dy_max, g.dy_fault, g.n_reject_max, g.e_max
    p[P_FREEZE_SAT] = 1.0 if g.freeze_on_saturation else 0.0
    p[P_A_MAX], p[P_Y_ERR], p[P_NFRZ_MAX], p[P_U_FREE] = g.accel_max, g.y_err, g.n_frozen_max, g.u_free
    return p


def arc_new_state(p: np.ndarray) -> np.ndarray:
    """A zeroed state vector for the packed gains ``p`` (call :func:`arc_reset` before use).

    Parameters
    ----------
    p : numpy.ndarray
        float64[NP] from :func:`arc_pack`.

    Returns
    -------
    numpy.ndarray
        float64[NS] of zeros.
    """
    p = np.asarray(p)
    if p.shape != (NP,) or p.dtype != np.float64:
        raise ArcGainsError(f"arc_new_state: p must be float64 with shape ({NP},), got {p.dtype} {p.shape}")
    return np.zeros(NS)
