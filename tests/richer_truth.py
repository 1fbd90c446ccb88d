"""Known-truth closed-loop logs for the delay-aware inverse dynamics (tests only).

A small dedicated simulation, because the plant simulator (controllers/plant.py) has
no direction-dependent friction: a mass with viscous and Coulomb friction whose levels
may differ by direction, a constant force, a command held over the sample and acting
``delay`` samples after the hold, a stick-slip switch at rest (semi-implicit Euler,
sub-stepped), an encoder quantised to ``lsb``, under a PD loop with feedforward that
tracks smooth moves with many reversals.
"""

from __future__ import annotations

import math

import numpy as np


def truth_log(*, M=95.0, B_pos=200.0, B_neg=200.0, fc_pos=20.0, fc_neg=20.0, offset=0.0, delay=0.0,
              fs=1000.0, duration=24.0, lsb=5e-8, seed=0, substeps=10):
    """(t, q, u) of a simulated closed-loop log; SI units (m, N)."""
    rng = np.random.default_rng(seed)
    n = int(duration * fs)
    t = np.arange(n) / fs
    # Reference: a sum of smooth sines (reversals at varied speeds and positions).
    f = np.array([0.23, 0.61, 1.3, 2.7])
    a = np.array([0.05, 0.012, 0.004, 0.0012])
    ph = rng.uniform(0, 2 * np.pi, f.size)
    w = 2 * np.pi * f
    qr = (a * np.sin(w * t[:, None] + ph)).sum(1)
    vr = (a * w * np.cos(w * t[:, None] + ph)).sum(1)
    ar = (-a * w * w * np.sin(w * t[:, None] + ph)).sum(1)
    wn = 2 * np.pi * 15.0
    kp, kd = M * wn * wn, 2 * 0.7 * M * wn
    h = 1.0 / (fs * substeps)
    x, v = float(qr[0]), float(vr[0])
    q = np.empty(n)
    u = np.empty(n)
    hist = [0.0] * 8  # commands issued, most recent last
    qm_prev = round(x / lsb) * lsb
    for k in range(n):
        qm = round(x / lsb) * lsb
        v_est = (qm - qm_prev) * fs if k else v
        qm_prev = qm
        ff = M * ar[k] + 200.0 * vr[k] + 20.0 * math.tanh(vr[k] / 1e-3)
        u[k] = ff + kp * (qr[k] - qm) + kd * (vr[k] - v_est)
        q[k] = qm
        hist.append(u[k])
        hist.pop(0)
        for j in range(substeps):
            # The command u[i] acts over [i + delay, i + 1 + delay) samples.
            back = math.floor((j + 0.5) / substeps - delay)
            F = hist[-1 + back] if back <= 0 else hist[-1]
            drive = F - offset
            if v == 0.0:
                brk = fc_pos if drive > 0 else fc_neg
                if abs(drive) <= brk:
                    continue
                s = 1.0 if drive > 0 else -1.0
                v = (drive - s * brk) / M * h
            else:
                fr = B_pos * v + fc_pos if v > 0 else B_neg * v - fc_neg
                v_new = v + (drive - fr) / M * h
                v = 0.0 if v_new * v < 0 else v_new
            x += v * h
    return t, q, u
