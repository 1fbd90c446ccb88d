"""The commissioning run simulated: the holding loop (:func:`_closed_loop`, a PID with feedforward
around the sub-stepped plant, also the loop of ``commission excite``'s pre-simulation), its gains
(:func:`loop_gains`) and the whole log (:func:`simulate_excitation`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from commission.controllers.plant import NX, P_DELAY, plant_output, plant_start
from commission.controllers.simulate import _segment as hold_segment
from commission.synth.truth import AxisTruth
from commission.synth.excitation import ExcitationPlan


@njit(cache=True)
def _closed_loop(p, q_ref, qd_ref, u_ff, noise, lsb, T, nsub, kp, kd, ki, u_max, q_out, u_out):
    """PID + feedforward around the sub-stepped plant; fills q_out, u_out in place.

    The logged ``u`` is the command the controller issues; the plant receives it
    ``p[P_DELAY]`` later, switching the held command inside the sample as the
    sampled loop of :func:`commission.controllers.simulate.closed_loop_kernel`
    does (with its hold helper, so both loops apply a delay the same way).
    """
    tau = p[P_DELAY] / T
    n_d = int(math.floor(tau + 1e-9))
    f = tau - n_d
    if f < 1e-9:
        f = 0.0
    nh = n_d + 2
    hist = np.zeros(nh)  # hist[j % nh] = command issued at sample j
    st = np.empty(NX)
    plant_start(p, st, q_ref[0])
    integ = 0.0
    q_prev = math.floor(plant_output(p, st) / lsb + 0.5) * lsb
    for k in range(q_ref.size):
        qm = math.floor((plant_output(p, st) + noise[k]) / lsb + 0.5) * lsb
        e = q_ref[k] - qm
        vel = (qm - q_prev) / T if k > 0 else 0.0  # backward difference, as on a drive
        integ_new = integ + e * T
        u_lin = kp * e + kd * (qd_ref[k] - vel) + ki * integ_new + u_ff[k]
        u = min(max(u_lin, -u_max), u_max)
        if u == u_lin:
            integ = integ_new  # conditional integration: no wind-up on the rail
        q_out[k] = qm
        u_out[k] = u
        hist[k % nh] = u
        u_late = hist[(k - n_d) % nh] if k >= n_d else 0.0
        u_early = hist[(k - n_d - 1) % nh] if k >= n_d + 1 else 0.0
        hold_segment(p, st, u_early, u_max, 0.0, f * T, nsub, T)
        hold_segment(p, st, u_late, u_max, 0.0, (1.0 - f) * T, nsub, T)
        q_prev = qm


def loop_gains(truth: AxisTruth, plan: ExcitationPlan) -> tuple[float, float, float]:
    """PID gains the simulated commissioning loop uses.

    Designed on the guessed mass ``M_g = plan.guess_factor * truth.M`` for the
    bandwidth ``w = 2 pi plan.bandwidth_hz`` and damping ``plan.damping``.

    Parameters
    ----------
    truth : AxisTruth
        The simulated axis (only ``M`` is used).
    plan : ExcitationPlan
        Loop design fields ``bandwidth_hz``, ``damping``, ``integral_hz``, ``guess_factor``.

    Returns
    -------
    kp : float
        u-unit/m.
    kd : float
        u-unit s/m.
    ki : float
        u-unit/(m s).
    """
    Mg = plan.guess_factor * truth.M
    w = 2.0 * math.pi * plan.bandwidth_hz
    kp = Mg * w * w
    return kp, 2.0 * plan.damping * Mg * w, kp * 2.0 * math.pi * plan.integral_hz


def simulate_excitation(truth: AxisTruth, plan: ExcitationPlan,
                        rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Simulate a closed-loop excitation run and return its log.

    A discrete PID (derivative on the backward-difference velocity, integral
    with anti-windup, gains from :func:`loop_gains`) plus a rough feedforward
    tracks ``plan.reference(truth.sample_rate)``; on the injection legs a PRBS
    of ``+-guess_factor M injection_accel`` is added to the command (and to the
    logged ``u``).  The command is held over each sample period, ``truth.delay``
    late, while :func:`~commission.controllers.plant.plant_step` advances
    ``plan.substeps`` sub-steps per sample.  The encoder reads
    ``round((x + n) / lsb) * lsb`` with ``n ~ N(0, noise_std^2)`` from ``rng``.

    Parameters
    ----------
    truth : AxisTruth
        The simulated axis.
    plan : ExcitationPlan
        Reference and loop design.
    rng : numpy.random.Generator
        Source of the position noise (drawn only when ``truth.noise_std > 0``).

    Returns
    -------
    dict of str to ndarray
        ``t`` (s), ``q`` (m, on the LSB grid), ``u`` (u-unit, within
        ``+-u_max``), ``q_ref`` (m); float64, one length.
    """
    ref = plan.reference(truth.sample_rate)
    n = ref.t.size
    noise = rng.normal(0.0, truth.noise_std, n) if truth.noise_std > 0 else np.zeros(n)
    g = plan.guess_factor
    u_ff = (g * truth.M * ref.qdd + g * truth.B * ref.qd
            + g * truth.fc * (2.0 / np.pi) * np.arctan(900.0 * ref.qd))
    if ref.injection:
        u_ff = u_ff + g * truth.M * plan.injection_accel * plan.injection_signal(ref.t)
    kp, kd, ki = loop_gains(truth, plan)
    q = np.empty(n)
    u = np.empty(n)
    _closed_loop(truth.plant(), ref.q, ref.qd, u_ff, noise, truth.lsb, truth.period,
                 int(plan.substeps), kp, kd, ki, truth.u_max, q, u)
    return {"t": ref.t, "q": q, "u": u, "q_ref": ref.q.copy()}
