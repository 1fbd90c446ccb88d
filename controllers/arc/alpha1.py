"""Step 1 of the law: alpha_1 of (25), (27), (37), (38) and its EXACT partial derivatives.

alpha_1 = alpha_1a + alpha_1s, z1 = y - q_d, alpha_1s = -(K1/theta1min) z1 and::

    K1 = g1 + ||C_phi1 Gamma phi1||^2 + ||theta_M||^2 ||phi1||^2/(4 eps11) + 1/(4 eps12)
    phi1 = [alpha_1a, -(xi_1,2 + y), psi_2]

Step 2 (:mod:`commission.controllers.arc.step`) needs d alpha_1/dt, which (39)
splits into a calculable part and the unknown one the robust terms bound; the
calculable part is built from the partials of alpha_1 with respect to every signal
it depends on (y, eta, psi_2, q_d, dq_d, theta_hat).  They are written out by the
analytic chain rule in :func:`_alpha1`, the compiled function the step calls,
rather than by finite differences, so that they are exact to rounding (the tests
check them against a Richardson-extrapolated long-double reference).  With the cap
K1 = min(K1, k1s_max) active the gradient of K1 is 0, and the partials are exact
for the capped function.  :func:`alpha1_and_partials` is the same for Python callers.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from commission.controllers.arc.layout import P_C12, P_G1, P_K1, P_K1MAX, P_K2, P_Q1, P_TMIN


@njit(cache=True)
def _alpha1(p, y, eta1, eta2, psi2, qd, dqd, th1, th2, th3):
    """alpha_1 = alpha_1a + alpha_1s of (25), (27), (37), (38) and its exact partials.

    Returns a flat tuple (no allocation inside the control loop)::

        alpha1, d/dy, d/deta1, d/deta2, d/dpsi2, d/dqd, d/ddqd,
        d/dth1, d/dth2, d/dth3, K1, phi1_1, phi1_2, phi1_3, z1

    K1 = g1 + ||C_phi1 Gamma phi1||^2 + ||theta_M||^2 ||phi1||^2 / (4 eps11) + 1/(4 eps12)
    collects k1s (28), h1 (36)-(37) and (38): alpha_1s = -(K1/theta1min) z1.
    With the cap K1 = min(K1, k1s_max) its gradient is 0 where the cap is active.
    """
    k1 = p[P_K1]
    k2 = p[P_K2]
    t1min = p[P_TMIN]
    # (17): xi_1 = A0 eta, xi_2 = -A0^2 eta (second components)
    xi12 = -k2 * eta1
    xi22 = k2 * (eta2 - k1 * eta1)
    sy = xi12 + y  # xi_1,2 + y
    z1 = y - qd
    # (25)
    num = xi22 - th2 * sy + th3 * psi2 - dqd
    a = -num / th1
    a_y = th2 / th1
    a_e1 = k2 * (k1 - th2) / th1
    a_e2 = -k2 / th1
    a_psi = -th3 / th1
    a_dqd = 1.0 / th1
    a_t1 = -a / th1
    a_t2 = sy / th1
    a_t3 = -psi2 / th1
    # phi1 = [alpha_1a, -(xi_1,2 + y), psi2] (26)
    f1 = a
    f2 = -sy
    f3 = psi2
    q1 = p[P_Q1]
    q2 = p[P_Q1 + 1]
    q3 = p[P_Q1 + 2]
    K1 = p[P_G1] + q1 * f1 * f1 + q2 * f2 * f2 + q3 * f3 * f3 + p[P_C12]
    if K1 > p[P_K1MAX]:
        K1 = p[P_K1MAX]
        c = 0.0  # the cap is a constant: no gradient
    else:
        c = 2.0
    # dK1/dx = 2 phi1^T Q1 dphi1/dx; dphi1/dx = [a_x, -dsy/dx, dpsi2/dx]
    K_y = c * (q1 * f1 * a_y - q2 * f2)  # dsy/dy = 1
    K_e1 = c * (q1 * f1 * a_e1 + q2 * f2 * k2)  # dsy/deta1 = -k2
    K_e2 = c * (q1 * f1 * a_e2)
    K_psi = c * (q1 * f1 * a_psi + q3 * f3)
    K_dqd = c * (q1 * f1 * a_dqd)
    K_t1 = c * (q1 * f1 * a_t1)
    K_t2 = c * (q1 * f1 * a_t2)
    K_t3 = c * (q1 * f1 * a_t3)
    r = z1 / t1min
    alpha1 = a - K1 * r
    d_y = a_y - K_y * r - K1 / t1min
    d_e1 = a_e1 - K_e1 * r
    d_e2 = a_e2 - K_e2 * r
    d_psi = a_psi - K_psi * r
    d_qd = K1 / t1min
    d_dqd = a_dqd - K_dqd * r
    d_t1 = a_t1 - K_t1 * r
    d_t2 = a_t2 - K_t2 * r
    d_t3 = a_t3 - K_t3 * r
    return (alpha1, d_y, d_e1, d_e2, d_psi, d_qd, d_dqd, d_t1, d_t2, d_t3,
            K1, f1, f2, f3, z1)


def alpha1_and_partials(p: np.ndarray, y: float, eta, psi2: float, qd: float, dqd: float, theta_hat):
    """alpha_1 of (25)+(27) and its exact partial derivatives (analytic chain rule).

    Parameters
    ----------
    p : numpy.ndarray
        Packed gains (:func:`arc_pack`).
    y : float
        Measured position, m.
    eta : array_like of 2 float
        Filter state eta of (18).
    psi2 : float
        Second component of the filter psi of (12).
    qd, dqd : float
        Desired position (m) and velocity (m/s).
    theta_hat : array_like of 3 float
        Parameter estimates.

    Returns
    -------
    alpha1 : float
    dy : float
        d alpha1 / d y.
    deta : numpy.ndarray
        d alpha1 / d eta, shape (2,).
    dpsi2 : float
    dqd_ : float
        d alpha1 / d q_d.
    ddqd_ : float
        d alpha1 / d dq_d.
    dtheta : numpy.ndarray
        d alpha1 / d theta_hat, shape (3,).
    """
    r = _alpha1(np.asarray(p, dtype=np.float64), float(y), float(eta[0]), float(eta[1]), float(psi2),
                float(qd), float(dqd), float(theta_hat[0]), float(theta_hat[1]), float(theta_hat[2]))
    return (r[0], r[1], np.array([r[2], r[3]]), r[4], r[5], r[6], np.array([r[7], r[8], r[9]]))

