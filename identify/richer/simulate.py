"""A fitted model run forward: the force it predicts and the open-loop position under a logged command."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from commission.identify.ls import readonly_copy, ripple_name
from commission.identify.signals import DEFAULT_BANDWIDTH_HZ
from commission.identify.richer.settings import SIM_INIT_SAMPLES, STRIBECK_XI
from commission.identify.richer.result import RichFit


def force_model(fit: RichFit, q: float, v: float) -> float:
    """Force of every term but the mass, ``F - M qdd`` at position ``q`` (m) and velocity ``v`` (m/s), u-unit."""
    s = (v > 0) - (v < 0)
    f = fit.value("B") * v + fit.value("fc") * s + fit.value("offset") + fit.value("dB") * abs(v) \
        + fit.value("cd") * v * abs(v)
    if fit.vs is not None:
        f += fit.value("dfs") * math.exp(-(abs(v) / fit.vs) ** STRIBECK_XI) * s
    z = q - fit.q_center
    f += fit.value("kq1") * z + fit.value("kq2") * z * z
    for k, p in enumerate(fit.ripple_pitch):
        ph = 2.0 * math.pi * q / p
        f += fit.value(ripple_name("ripple_sin", k)) * math.sin(ph) + fit.value(ripple_name("ripple_cos", k)) * math.cos(ph)
    return f


@dataclass(frozen=True)
class PositionSimulation:
    """Open-loop simulation of an identified model under a log's command (the benchmark's output-error metric).

    What :func:`simulate_position` returns.  An output-error score, unlike the force
    residual of the fit, lets model errors accumulate through the dynamics, which is
    how the published friction benchmarks compare models.

    Attributes
    ----------
    rmse : float
        RMS of ``q_sim - q_measured`` after the initialisation window, m.
    q_sim : ndarray
        Simulated position at the log's samples, m (the measured one in the window).
    init_samples : int
        Initialisation window, samples.
    """

    rmse: float
    q_sim: np.ndarray = field(repr=False)
    init_samples: int


def simulate_position(fit: RichFit, t: np.ndarray, q: np.ndarray, u: np.ndarray, *,
                      init_samples: int = SIM_INIT_SAMPLES, substeps: int = 10,
                      cutoff_hz: float = 5 * DEFAULT_BANDWIDTH_HZ) -> PositionSimulation:
    """Simulate ``M qdd = u(t - tau) - (F - M qdd)(q, qd)`` under the log's command; position RMSE.

    The command is held (zero-order hold) and acts ``fit.delay_samples`` after the
    hold; the state starts from the zero-phase filtered position and its central
    difference at the end of the initialisation window (the first ``init_samples``
    samples), and the error is scored from there to the end.  Coulomb-type terms
    at rest follow a stick-slip switch: the axis stays at rest while the remaining
    force is at most the break-away level ``fc + dfs`` (the model's friction as the
    speed goes to zero), and a step that would carry the speed through zero stops
    the axis instead.  Semi-implicit Euler with ``substeps`` steps per sample.

    Parameters
    ----------
    fit : RichFit
    t, q, u : ndarray, shape (N,)
        s (uniform), m, u-unit.
    init_samples : int
        Initialisation window, samples.
    substeps : int
        Integration steps per sample.
    cutoff_hz : float
        Cut-off of the filter giving the initial state, Hz.

    Returns
    -------
    PositionSimulation
    """
    from commission.identify.signals import zero_phase_lowpass

    t = np.asarray(t, float)
    q = np.asarray(q, float)
    u = np.asarray(u, float)
    n = t.size
    Ts = float(np.median(np.diff(t)))
    k0 = int(init_samples)
    if not 2 <= k0 < n - 2:
        raise ValueError(f"init_samples={init_samples} must lie in [2, {n - 3}]")
    qf = zero_phase_lowpass(q, min(cutoff_hz, 0.4 / Ts), 1.0 / Ts)
    x, v = float(qf[k0]), float((qf[k0 + 1] - qf[k0 - 1]) / (2 * Ts))
    M = fit.value("M")
    B, fc, off, dB, cd = (fit.value(n_) for n_ in ("B", "fc", "offset", "dB", "cd"))
    dfs = fit.value("dfs")
    vs = fit.vs if fit.vs is not None else 1.0
    kq1, kq2, qc = fit.value("kq1"), fit.value("kq2"), fit.q_center
    rip = [(p, fit.value(ripple_name("ripple_sin", k)), fit.value(ripple_name("ripple_cos", k)))
           for k, p in enumerate(fit.ripple_pitch)]
    brk = fc + dfs
    h = Ts / substeps
    d = fit.delay_samples
    out = np.empty(n)
    out[:k0 + 1] = q[:k0 + 1]
    for k in range(k0, n - 1):
        for j in range(substeps):
            # Command acting at time (k + (j + 0.5)/substeps) Ts: u[i] acts over [i + d, i + 1 + d).
            i = int(math.floor(k + (j + 0.5) / substeps - d))
            ui = u[min(max(i, 0), n - 1)]
            f_pos = off + kq1 * (x - qc) + kq2 * (x - qc) ** 2
            for p, a, b in rip:
                ph = 2.0 * math.pi * x / p
                f_pos += a * math.sin(ph) + b * math.cos(ph)
            drive = ui - f_pos
            if v == 0.0:
                if abs(drive) <= brk:
                    continue
                s = 1.0 if drive > 0 else -1.0
                v_new = (drive - s * brk) / M * h
            else:
                s = 1.0 if v > 0 else -1.0
                fr = B * v + s * fc + dB * abs(v) + cd * v * abs(v) + s * dfs * math.exp(-(abs(v) / vs) ** STRIBECK_XI)
                v_new = v + (drive - fr) / M * h
                if v_new * v < 0:
                    v_new = 0.0
            v = v_new
            x += v * h
        out[k + 1] = x
    e = out[k0 + 1:] - q[k0 + 1:]
    return PositionSimulation(rmse=float(np.sqrt(np.mean(e * e))), q_sim=readonly_copy(out), init_samples=k0)


def published_form(M: float, B: float, fc: float, offset: float, cov: np.ndarray | None, sample_rate: float) -> RichFit:
    """The IDIM-LS model (no delay beyond the published alignment: ``tau = 0``) as a :class:`RichFit`, for simulation."""
    theta = np.array([M, B, fc, offset], float)
    cov = np.zeros((4, 4)) if cov is None else np.asarray(cov, float)
    z = np.zeros(0)
    return RichFit(terms=(), names=("M", "B", "fc", "offset"), units=("u s^2/m", "u s/m", "u", "u"),
                   theta=readonly_copy(theta), std=readonly_copy(np.sqrt(np.diag(cov))), cov=readonly_copy(cov),
                   delay_samples=-0.5, delay_std_samples=0.0, vs=None, vs_std=None, q_center=0.0, ripple_pitch=(),
                   relative_error=math.nan, condition_number=math.nan, residuals=z, force_measured=z, force_fitted=z,
                   sample_rate=float(sample_rate))
