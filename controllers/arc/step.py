"""The compiled sample of the ARC of Xu & Yao (2001), sec. 3: :func:`arc_step` and :func:`arc_reset`.

The law, evaluated once per sample k (period Ts) from the measured position y
and the desired q_d, dq_d, ddq_d; equation numbers are the paper's:

* Filters (18) and psi of (12), eta' = A0 eta + e2 y, lambda' = A0 lambda + e2 u*,
  psi' = A0 psi + e2, A0 = [[-k1, 1], [-k2, 0]] (10).  They are advanced
  exactly over each period (one matrix exponential in :func:`arc_pack`) for
  the input each one really has: u*_k is held over [t_k, t_k+1) by the DAC
  (zero-order hold), psi's input is the constant 1, and y, which is not held
  but moves, is interpolated linearly between y_k and y_k+1 (first-order
  hold, exact while the axis moves at constant velocity between samples).
  Holding y instead lags eta by half a sample: at constant velocity the ARC
  then tracks with a direction-dependent offset (measured in
  docs/implementability.md).
  xi_2 = -A0^2 eta, xi_1 = A0 eta, v = lambda (17).
* State estimate (13) x_hat = xi_2 - th2 xi_1 + th1 v + th3 psi (logged only).
* Step 1: z1 = y - q_d, alpha_1 = alpha_1a + alpha_1s with (25) and
  alpha_1s = -(K1/theta1min) z1, where K1 collects (27)-(28), (37) and (38)::

      K1 = g1 + ||C_phi1 Gamma phi1||^2 + ||theta_M||^2 ||phi1||^2/(4 eps11) + 1/(4 eps12)
      phi1 = [alpha_1a, -(xi_1,2 + y), psi_2]

* Step 2: z2 = v2 - alpha_1, u* = u*_a - K2 z2 (43) with
  u*_a = -(w1/w2) th1 z1 + k2 v1 + alpha1_dot_c, alpha1_dot_c from (39) with the
  exact partials of alpha_1 (analytic chain rule, :mod:`commission.controllers.arc.alpha1`) and::

      K2 = g2 + ||d alpha1/d theta_hat C_theta2||^2 + ||C_phi2 Gamma phi2||^2
           + ||theta_M||^2 ||phi2||^2/(4 eps21) + (d alpha1/dy)^2/(4 eps22)
      phi2 = e1 (w1/w2) z1 - (d alpha1/dy) omega,   omega = [v2, -(xi_1,2 + y), psi_2]

  then capped (``k1s_max``, ``k2s_max``) and, when ``k2s_max`` is finite,
  K2 <= V_LOOP_RATE_LIMIT/Ts + th1 d alpha1/dy (sampled v-loop guard, below).

* Adaptation (19)-(20), (50): tau = w1 phi1 z1 + w2 phi2 z2 and, in discrete
  time, theta_hat <- clip(theta_hat + Ts Gamma tau, theta_min, theta_max), a box
  projection that keeps P1 (theta_hat in Omega_theta) exactly.
* Output (5): u = u* + F_hat(dq_d), F_hat(v) = level (2/pi) atan(slope v), then
  the symmetric saturation u_max.  The lambda filter is driven by the u* the
  plant actually receives (u_sat - F_hat) so that (14) stays valid in saturation.

Ordering within a sample: advance the filters over the last period, compute u
from y_k and the current theta_hat, then update theta_hat for the next sample.
The state vector s is updated in place; :data:`S_THETA`, :data:`S_Z1`,
:data:`S_Z2`, :data:`S_XHAT`, ... index what a simulator may log.  A non-finite
input or intermediate value latches ``s[S_FAULT] = 1`` and the step returns 0
(drive disabled) until :func:`arc_reset`; it never raises inside the loop.

Runtime guards (what a drive engineer needs around the law)
-----------------------------------------------------------
Checked at the top of each sample, before anything is updated, each one
switched off by its default (``inf``, ``False``), which leaves the law above
unchanged bit for bit:

* Measurement plausibility: with n = 1 + r samples since the last accepted
  measurement y_good (r the samples rejected since), y is predicted as
  y_good + v n Ts, v being the velocity of the accepted pair *before* the last
  one.  A y is implausible (a glitch) when it is farther than ``dy_max n``
  from y_good (a speed beyond the envelope's) or when its innovation
  y - y_pred exceeds::

      b(n) = Ts^2 n (n + 3)/2 (accel_max + theta_max1 du (n + 3)/2) + y_err (2 + 2 n)

  what an acceleration up to ``accel_max`` (the validated envelope's, with a
  margin), the drive's own command steps (du the largest |u_k - u_k-1| of the
  last three samples, on the lightest plant of the box: theta_max1 = 1/M_min)
  and a reading error up to ``y_err`` per measurement can explain.  For n = 1
  the innovation is the change of the increments y_k - y_k-1 - (y_k-2 - y_k-3),
  Ts^2 times the accelerations of three periods, each weighted <= 1 and 2 in
  all; the command term covers the part of them that follows the command's
  steps in the window, the acceleration before it being the envelope's.  The delayed velocity is what makes the check robust: a
  glitch g among the accepted readings moves the next three innovations by
  -g, -g, +g, never more than the glitch itself, so the good readings after a
  glitch that passed are accepted too; a glitch that is rejected leaves the
  prediction on the readings before it.  A rejected sample runs on the
  prediction y = q_d + e_good (the tracking error of the last accepted sample
  held), and ``n_reject_max`` rejections in a row latch :data:`FAULT_GLITCH_RUN`.
  A y farther than ``dy_fault`` latches :data:`FAULT_JUMP` at once.
* Frozen encoder: a still run is a run of readings within 2 ``y_err`` of the
  one it started with.  Each of its samples adds evidence that the axis must
  have moved: 1 when the reading was rejected (the prediction moved away from
  it), sqrt(w) when the command held over the last period pushed a fraction
  w = (|u| - u_free)/(u_max - u_free) <= 1 of the rail's push beyond
  ``u_free``, the largest command that may leave the axis at rest (friction,
  constant and disturbance forces).  Evidence ``n_frozen_max`` latches
  :data:`FAULT_FROZEN`; a still sample without either (a still axis, held)
  clears it.  A constant acceleration a spreads the positions over at least
  a T^2/8 in a time T whatever the initial speed, and a push of w takes
  1/sqrt(w) as long as the rail's to spread them as far, hence the square root
  (validate sizes ``n_frozen_max`` on the rail's push).  A frozen encoder thus
  latches the fault within ``n_frozen_max`` samples once the command is at the
  rail, and within ``n_frozen_max`` samples of freezing while the axis moves
  faster than about accel_max Ts (n_frozen_max + 3)/2 (each reading rejected,
  the law running on the prediction, no sample at the rail).
  With the axis at rest and a command that stays below ``u_free`` no
  reading can be told from a still axis: the jump of the reading when the
  encoder recovers, the tracking watchdog or the push catches it.
* Tracking-error watchdog: an accepted |y - q_d| > ``e_max`` latches
  :data:`FAULT_TRACKING`.
* The adaptation is frozen in a rejected sample and, with
  ``freeze_on_saturation``, in a sample whose command is at +-u_max (the
  errors then do not answer the command, and would drive theta_hat into a
  corner of its box).
* A latched fault keeps theta_hat and the filters at their last good values,
  holds its reason code in ``s[S_FAULT]`` (``FAULT_*``, :data:`FAULT_REASONS`)
  and the step returns the safe command 0 (no force; the caller disables the
  drive on the flag) until :func:`arc_reset`.

The gains, their caps and why the paper's robust terms are capped: :mod:`commission.controllers.arc.gains`.
"""

from __future__ import annotations

import math

from numba import njit

from commission.controllers.arc.alpha1 import _alpha1
from commission.controllers.arc.layout import (P_AD, P_A_MAX, P_BD, P_BD1, P_C22, P_CT2SQ, P_DY_FAULT,
    P_DY_MAX, P_E_MAX, P_FLEVEL, P_FREEZE_SAT, P_FSLOPE, P_G2, P_GAMMA, P_K1, P_K2, P_K2MAX, P_NFRZ_MAX,
    P_NREJ_MAX, P_Q2, P_THETA0, P_TMAX, P_TMIN, P_TS, P_UMAX, P_U_FREE, P_W1, P_W2, P_Y_ERR, S_ALPHA1,
    S_BOUND, S_DU, S_EGOOD, S_ETA, S_FAULT, S_FROZEN, S_INNOV, S_K1, S_K2, S_LAMBDA, S_NREJ, S_NSTILL,
    S_PRIMED, S_PSI, S_REJECTED, S_THETA, S_U, S_USPREV, S_USTAR, S_VLAST, S_VPREV, S_XHAT, S_YGOOD, S_YPREV,
    S_YSTILL, S_Z1, S_Z2, V_LOOP_RATE_LIMIT)


@njit(cache=True)
def arc_reset(p, s, y0):
    """Initialise at rest at the measured position ``y0`` (Remark 4).

    theta_hat = theta0, lambda = psi = 0 and eta at its rest value for the
    constant input y0, eta = -A0^-1 e2 y0 = (y0/k2) [1, k1].  For y0 = 0 this is
    the paper's all-zero initialisation; for any y0 it gives xi_1,2 + y = 0 and
    xi_2,2 = 0, hence alpha_1 = 0 = v_2 and z_2(0) = 0 when q_d(0) = y0 and
    dq_d(0) = 0, i.e. V_2(0) = 0 as Remark 4 intends, wherever the axis stands.

    Parameters
    ----------
    p : float64[NP]
        Packed gains.
    s : float64[NS]
        State, overwritten.
    y0 : float
        Measured position at start, m.
    """
    for i in range(s.shape[0]):
        s[i] = 0.0
    s[S_ETA] = y0 / p[P_K2]
    s[S_ETA + 1] = y0 * p[P_K1] / p[P_K2]
    for i in range(3):
        s[S_THETA + i] = p[P_THETA0 + i]
    s[S_YPREV] = y0
    s[S_YGOOD] = y0
    s[S_YSTILL] = y0
    s[S_XHAT] = y0
    s[S_XHAT + 1] = p[P_THETA0 + 1] * y0



@njit(cache=True)
def _fault(s, reason):
    """Latch the fault with its reason code (``FAULT_*``) and return the safe command 0.

    theta_hat and the filters keep the values of the last good sample.
    """
    s[S_FAULT] = reason
    s[S_USTAR] = 0.0
    s[S_U] = 0.0
    return 0.0


@njit(cache=True)
def arc_step(p, s, y, qd, dqd, ddqd):
    """One sample of the discrete output-feedback ARC.

    One function on purpose: it is the single step that the simulator, validate, the
    runtime and the exported C share, and :mod:`commission.export.translate` turns its
    source into C statement by statement, so splitting it would add C functions and
    calls to the translated code for no change in what it computes.

    Parameters
    ----------
    p : float64[NP]
        Packed gains (:func:`arc_pack`).
    s : float64[NS]
        State (:func:`arc_new_state`, :func:`arc_reset`), updated in place.
    y : float
        Measured position at this sample, m.
    qd, dqd, ddqd : float
        Desired position (m), velocity (m/s) and acceleration (m/s^2).

    Returns
    -------
    float
        Command u = u* + F_hat(dq_d), saturated at u_max, u-unit; held until
        the next sample.  Always finite: once a fault latches (``s[S_FAULT]``
        holds its ``FAULT_*`` reason code) the step returns the safe command 0
        until :func:`arc_reset`, and theta_hat keeps its last good value.
    """
    if s[S_FAULT] != 0.0:
        return 0.0
    if not (math.isfinite(y) and math.isfinite(qd) and math.isfinite(dqd) and math.isfinite(ddqd)):
        return _fault(s, 1.0)
    # --- runtime guards: measurement plausibility, frozen encoder, then the tracking-error watchdog
    rejected = 0.0
    if s[S_PRIMED] != 0.0:
        jump = abs(y - s[S_YGOOD])
        if jump > p[P_DY_FAULT]:
            return _fault(s, 2.0)
        # samples since the last accepted measurement, and the prediction from it with the
        # velocity of the pair before (a glitch among the last accepted cannot bend it)
        n = 1.0 + s[S_NREJ]
        innov = y - (s[S_YGOOD] + s[S_VPREV] * p[P_TS] * n)
        # what the envelope's acceleration, the drive's own recent command steps (on the
        # lightest plant of the box) and the reading errors can explain
        du = s[S_DU]
        if s[S_DU + 1] > du:
            du = s[S_DU + 1]
        if s[S_DU + 2] > du:
            du = s[S_DU + 2]
        bound = (p[P_TS] * p[P_TS] * (n * (n + 3.0) / 2.0) * (p[P_A_MAX] + p[P_TMAX] * du * ((n + 3.0) / 2.0))
                 + p[P_Y_ERR] * (2.0 + 2.0 * n))
        s[S_INNOV] = innov
        s[S_BOUND] = bound
        if jump > p[P_DY_MAX] * n or abs(innov) > bound:
            s[S_NREJ] = n
            rejected = 1.0
        else:
            s[S_NREJ] = 0.0
            v = (y - s[S_YGOOD]) / (p[P_TS] * n)
            if n == 1.0:
                s[S_VPREV] = s[S_VLAST]
            else:
                s[S_VPREV] = v
            s[S_VLAST] = v
        # frozen encoder: a reading that stays put while the axis must move counts -- 1 when the
        # prediction says it moved (y rejected), sqrt(w) when the command held over the last
        # period pushed w = (|u| - u_free)/(u_max - u_free) of the rail's push beyond the forces
        # that may hold the axis (1 at the rail; the time to move a given distance goes as 1/sqrt(a));
        # u_free = 0 (unknown) leaves the push out
        if abs(y - s[S_YSTILL]) > 2.0 * p[P_Y_ERR]:
            s[S_YSTILL] = y
            s[S_NSTILL] = 0.0
        else:
            w = 0.0
            if rejected != 0.0:
                w = 1.0
            elif p[P_U_FREE] > 0.0 and p[P_UMAX] > p[P_U_FREE] and abs(s[S_U]) > p[P_U_FREE]:
                w = (abs(s[S_U]) - p[P_U_FREE]) / (p[P_UMAX] - p[P_U_FREE])
                if w > 1.0:
                    w = 1.0
                w = math.sqrt(w)
            if w > 0.0:
                s[S_NSTILL] = s[S_NSTILL] + w
                if s[S_NSTILL] >= p[P_NFRZ_MAX]:
                    return _fault(s, 5.0)
            else:
                s[S_NSTILL] = 0.0
        if s[S_NREJ] >= p[P_NREJ_MAX]:
            return _fault(s, 3.0)
        if rejected != 0.0:
            # an implausible y: go on with the prediction "the tracking error is what it last was"
            y = qd + s[S_EGOOD]
    if rejected == 0.0:
        s[S_YGOOD] = y
        s[S_EGOOD] = y - qd
    if abs(y - qd) > p[P_E_MAX]:
        return _fault(s, 4.0)
    s[S_REJECTED] = rejected
    k1 = p[P_K1]
    k2 = p[P_K2]
    w1 = p[P_W1]
    w2 = p[P_W2]
    Ts = p[P_TS]
    # --- filters (18) and psi of (12), advanced exactly over the last period:
    # u* of the previous sample was held (ZOH), psi's input is the constant 1,
    # and y moved from y_k-1 to y_k, taken as linear in between (FOH): a held y
    # would lag eta by half a sample and offset the tracking at constant velocity.
    if s[S_PRIMED] != 0.0:
        a11 = p[P_AD]
        a12 = p[P_AD + 1]
        a21 = p[P_AD + 2]
        a22 = p[P_AD + 3]
        b1 = p[P_BD]
        b2 = p[P_BD + 1]
        yp = s[S_YPREV]
        e1 = s[S_ETA]
        e2 = s[S_ETA + 1]
        dy = y - yp
        s[S_ETA] = a11 * e1 + a12 * e2 + b1 * yp + p[P_BD1] * dy
        s[S_ETA + 1] = a21 * e1 + a22 * e2 + b2 * yp + p[P_BD1 + 1] * dy
        up = s[S_USPREV]
        l1 = s[S_LAMBDA]
        l2 = s[S_LAMBDA + 1]
        s[S_LAMBDA] = a11 * l1 + a12 * l2 + b1 * up
        s[S_LAMBDA + 1] = a21 * l1 + a22 * l2 + b2 * up
        q1 = s[S_PSI]
        q2 = s[S_PSI + 1]
        s[S_PSI] = a11 * q1 + a12 * q2 + b1
        s[S_PSI + 1] = a21 * q1 + a22 * q2 + b2
    s[S_PRIMED] = 1.0
    s[S_YPREV] = y
    eta1 = s[S_ETA]
    eta2 = s[S_ETA + 1]
    v1 = s[S_LAMBDA]
    v2 = s[S_LAMBDA + 1]
    psi1 = s[S_PSI]
    psi2 = s[S_PSI + 1]
    th1 = s[S_THETA]
    th2 = s[S_THETA + 1]
    th3 = s[S_THETA + 2]
    # (17) and the state estimate (13) (logged)
    xi11 = -k1 * eta1 + eta2
    xi12 = -k2 * eta1
    xi21 = -(k1 * k1 - k2) * eta1 + k1 * eta2
    xi22 = k2 * (eta2 - k1 * eta1)
    s[S_XHAT] = xi21 - th2 * xi11 + th1 * v1 + th3 * psi1
    s[S_XHAT + 1] = xi22 - th2 * xi12 + th1 * v2 + th3 * psi2
    # --- step 1: alpha_1 (25), (27), (37), (38) and its partials
    (alpha1, a_y, a_e1, a_e2, a_psi, a_qd, a_dqd, a_t1, a_t2, a_t3,
     K1, f1, f2, f3, z1) = _alpha1(p, y, eta1, eta2, psi2, qd, dqd, th1, th2, th3)
    sy = xi12 + y
    # --- step 2: calculable part of d alpha_1/dt (39)
    yd_hat = xi22 + th1 * v2 - th2 * sy + th3 * psi2  # xi_2,2 + theta_hat^T omega
    deta1 = -k1 * eta1 + eta2  # (18)
    deta2 = -k2 * eta1 + y
    dpsi2 = -k2 * psi1 + 1.0  # (12)
    alpha1_dot_c = (a_y * yd_hat + a_e1 * deta1 + a_e2 * deta2 + a_psi * dpsi2
                    + a_qd * dqd + a_dqd * ddqd)
    z2 = v2 - alpha1
    # phi2 (45) with omega = [v2, -(xi_1,2 + y), psi2]
    g1_ = (w1 / w2) * z1 - a_y * v2
    g2_ = a_y * sy
    g3_ = -a_y * psi2
    # K2 = k2s (43) + h2/(4 eps21) + (d alpha1/dy)^2/(4 eps22) of (47), capped
    ct = P_CT2SQ
    K2 = (p[P_G2]
          + p[ct] * a_t1 * a_t1 + p[ct + 1] * a_t2 * a_t2 + p[ct + 2] * a_t3 * a_t3
          + p[P_Q2] * g1_ * g1_ + p[P_Q2 + 1] * g2_ * g2_ + p[P_Q2 + 2] * g3_ * g3_
          + p[P_C22] * a_y * a_y)
    if K2 > p[P_K2MAX]:
        K2 = p[P_K2MAX]
    if p[P_K2MAX] < math.inf:
        # Sampled v-loop guard (docstring of arc.gains): u* feeds back v2 = lambda_2, the
        # ZOH-integrated u*, with rate R = K2 - th1 d(alpha1)/dy; its sampled pole is
        # about 1 - R Ts, so K2 is lowered until R Ts <= V_LOOP_RATE_LIMIT.
        kb = V_LOOP_RATE_LIMIT / Ts + th1 * a_y
        if kb < 0.0:
            kb = 0.0
        if K2 > kb:
            K2 = kb
    # (43)
    u_a = -(w1 / w2) * th1 * z1 + k2 * v1 + alpha1_dot_c
    ustar = u_a - K2 * z2
    # (5): u = u* + F_hat(dq_d), then the output limit
    fhat = p[P_FLEVEL] * (2.0 / math.pi) * math.atan(p[P_FSLOPE] * dqd)
    u = ustar + fhat
    umax = p[P_UMAX]
    u_applied_star = ustar
    saturated = 0.0
    if u > umax:
        u = umax
        u_applied_star = u - fhat
        saturated = 1.0
    elif u < -umax:
        u = -umax
        u_applied_star = u - fhat
        saturated = 1.0
    # adaptation function (50)
    tau1 = w1 * f1 * z1 + w2 * g1_ * z2
    tau2 = w1 * f2 * z1 + w2 * g2_ * z2
    tau3 = w1 * f3 * z1 + w2 * g3_ * z2
    if not (math.isfinite(u) and math.isfinite(ustar) and math.isfinite(tau1)
            and math.isfinite(tau2) and math.isfinite(tau3)):
        return _fault(s, 1.0)
    # (19)-(20) in discrete time: a box projection keeps P1 exactly.  Frozen while y
    # is a prediction (a glitch) and, with P_FREEZE_SAT, while the command is at the
    # limit: the errors then are not the plant's response to u and would drive
    # theta_hat into a corner of the box.
    frozen = rejected
    if p[P_FREEZE_SAT] != 0.0 and saturated != 0.0:
        frozen = 1.0
    s[S_FROZEN] = frozen
    if frozen == 0.0:
        tau = (tau1, tau2, tau3)
        for i in range(3):
            th = s[S_THETA + i] + Ts * p[P_GAMMA + i] * tau[i]
            lo = p[P_TMIN + i]
            hi = p[P_TMAX + i]
            if th > hi:
                th = hi
            elif th < lo:
                th = lo
            s[S_THETA + i] = th
    # the lambda filter is driven by the u* the plant actually receives
    s[S_USPREV] = u_applied_star
    s[S_Z1] = z1
    s[S_Z2] = z2
    s[S_ALPHA1] = alpha1
    s[S_K1] = K1
    s[S_K2] = K2
    s[S_USTAR] = ustar
    s[S_DU + 2] = s[S_DU + 1]
    s[S_DU + 1] = s[S_DU]
    s[S_DU] = abs(u - s[S_U])
    s[S_U] = u
    return u

