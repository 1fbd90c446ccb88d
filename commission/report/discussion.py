"""What the report's tables do not say ("Reading the results"): whether theta_hat converged and
how well the run excited it, the PID baseline's limit cycle at standstill, and the ARC's chattering
against the PID's."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from commission.report.text import num
from commission.tuning import Tuning
from commission.units import unit as unit_of


def _fixed_traces(result: Any) -> dict[str, Any]:
    """Traces of the gated fixed scenarios (not the robustness variants)."""
    tags = {r.name: r.tags for r in result.runs}
    return {n: tr for n, tr in getattr(result, "traces", {}).items() if "robustness" not in tags.get(n, ())}


def pid_limit_cycle(result: Any, min_dwell_s: float = 0.2) -> dict[str, tuple[float, float]]:
    """Scenarios where the PID baseline hunts at standstill: name -> (error amplitude m, command amplitude u-unit).

    A dwell is a stretch where the desired position does not move for at least
    ``min_dwell_s``; its first half is left for the transient to settle.  The baseline
    hunts when, in the second half of a dwell, its error crosses its mean at least 4
    times and swings over more than 2 encoder steps: a limit cycle of the integrator
    against stiction, not noise.
    """
    out: dict[str, tuple[float, float]] = {}
    lsb = float(getattr(result, "quantization", 0.0) or 0.0)
    for name, tr in _fixed_traces(result).items():
        n = min(tr.y_pid.shape[0], tr.qd.shape[0], tr.u_pid.shape[0])
        if n < 10:
            continue
        dt = float(tr.t[1] - tr.t[0])
        still = np.r_[False, np.abs(np.diff(tr.qd[:n])) <= 1e-12]
        edges = np.flatnonzero(np.diff(np.r_[0, still.astype(np.int8), 0]))
        e_amp = u_amp = 0.0
        for a, b in zip(edges[::2], edges[1::2]):
            if (b - a) * dt < min_dwell_s:
                continue
            mid = a + (b - a) // 2
            e = tr.y_pid[mid:b] - tr.qd[mid:b]
            crossings = int(np.sum(np.diff(np.sign(e - e.mean())) != 0))
            swing = float(np.ptp(e))
            if crossings >= 4 and swing > 2.0 * lsb:
                e_amp = max(e_amp, swing / 2.0)
                u_amp = max(u_amp, float(np.ptp(tr.u_pid[mid:b])) / 2.0)
        if e_amp > 0.0:
            out[name] = (e_amp, u_amp)
    return out


def theta_convergence(result: Any) -> dict[str, tuple[float, float, float]]:
    """Fraction of the initial estimation error each theta_hat component closed, per fixed scenario.

    ``1 - |theta_hat(end) - theta| / |theta_hat(0) - theta|``: 1 converged, 0 did not move
    towards the plant's value, negative moved away (nan where theta_hat(0) = theta).
    """
    out = {}
    for name, tr in _fixed_traces(result).items():
        th = tr.theta_hat
        if th.shape[0] < 2:
            continue
        fr = []
        for i in range(3):
            e0, e1 = abs(th[0, i] - tr.theta_true[i]), abs(th[-1, i] - tr.theta_true[i])
            fr.append(1.0 - e1 / e0 if e0 > 1e-12 * max(1.0, abs(tr.theta_true[i])) else math.nan)
        out[name] = (fr[0], fr[1], fr[2])
    return out


def excitation_level(tr: Any) -> float:
    """Persistence of excitation of the regressor of theta over a run, in [0, 1].

    The plant is ``qdd = theta1 u - theta2 qd + theta3 (+ friction)``, so theta is seen
    through ``phi = [u, -qd, 1]``.  Each column is scaled to unit rms and the smallest
    eigenvalue of their mean outer product is returned: 0 when the columns are
    collinear over the run (some direction of theta is not excited at all), 1 when
    they are orthogonal.
    """
    n = min(tr.u_arc.shape[0], tr.qd.shape[0])
    if n < 3:
        return math.nan
    dt = float(tr.t[1] - tr.t[0])
    qd_dot = np.gradient(tr.qd[:n], dt)
    phi = np.column_stack([tr.u_arc[:n], -qd_dot, np.ones(n)])
    rms = np.sqrt(np.mean(phi ** 2, axis=0))
    if np.any(rms == 0):
        return 0.0
    phi = phi / rms
    return float(np.linalg.eigvalsh(phi.T @ phi / n)[0])


def discussion_markdown(result: Any, tuning: Tuning) -> list[str]:
    """What the tables do not say: theta_hat's convergence and its excitation, the baseline's
    limit cycle, and the ARC's chattering against the PID's."""
    L = ["## Reading the results", ""]
    conv = theta_convergence(result)
    if conv:
        pe = {name: excitation_level(tr) for name, tr in _fixed_traces(result).items() if name.endswith("/nominal")}
        pe_text = ", ".join(f"{n.split('/')[0]} {num(v, 2)}" for n, v in pe.items())
        done = [n for n, f in conv.items() if all(not (x < 0.9) for x in f if math.isfinite(x))]
        f1 = [f[0] for f in conv.values() if math.isfinite(f[0])]
        L.append(f"- **Parameter estimates.** theta_hat converges to the plant's theta only under persistent "
                 f"excitation, and only as fast as the tracking error drives the adaptation (19): with the robust "
                 f"feedback holding the error near the encoder step, theta_hat moves slowly. Excitation level of the "
                 f"regressor [u, -q̇_d, 1] over the nominal runs (smallest eigenvalue of its normalised Gram matrix; "
                 f"0 = a direction of theta not excited, 1 = fully): {pe_text}. "
                 + (f"theta_hat closed at least 90 % of its initial error in {len(done)} of {len(conv)} fixed "
                    f"scenarios ({', '.join(done)}). " if done else
                    "theta_hat did not converge in any fixed scenario within its run (closed 90 % of its initial "
                    "error in none); ")
                 + (f"theta_hat_1 closed between {num(min(f1) * 100, 2)} % and {num(max(f1) * 100, 2)} % of its initial "
                    f"error. " if f1 else "")
                 + "The figure theta_hat.png shows what this trajectory does in its duration, not the limit; the "
                   "gate judges tracking, which does not need theta_hat = theta.")
    lc = pid_limit_cycle(result)
    if lc:
        unit = result.units.get("u", "u")
        worst = max(lc.items(), key=lambda kv: kv[1][0])
        L.append(f"- **The PID baseline hunts at standstill** in {len(lc)} scenario(s) ({', '.join(sorted(lc))}): "
                 f"in the dwells its error swings ±{num(worst[1][0] * 1e6, 2)} {unit_of('small', result.units)} with a ±{num(worst[1][1], 2)} {unit} "
                 f"command ({worst[0]}), a limit cycle of the integrator against stiction. It inflates the PID's e_F "
                 f"and e_rms there, so the ARC/PID ratios of those scenarios flatter the ARC.")
    fixed = [r for r in result.runs if "monte_carlo" not in r.tags and "robustness" not in r.tags
             and not r.arc.diverged and not r.pid.diverged and r.pid.c_u > 0]
    if fixed:
        ratio = max(fixed, key=lambda r: r.arc.c_u / r.pid.c_u)
        k = ratio.arc.c_u / ratio.pid.c_u
        if k > 1.0:
            lim = getattr(result.verdict.limits, "c_u", None)
            L.append(f"- **Chattering.** The ARC's c_u is up to {num(k, 2)}× the PID's ({ratio.name}: "
                     f"{num(ratio.arc.c_u, 2)} against {num(ratio.pid.c_u, 2)}): its nonlinear robust gains (K1 up to "
                     f"k1s_max = {num(result.arc_gains.k1s_max, 3)}, K2 up to k2s_max = {num(result.arc_gains.k2s_max, 3)} "
                     f"1/s) pass the encoder's quantisation to the command at a higher gain than the PID's. "
                     + (f"The gate bounds it at c_u ≤ {num(lim, 2)} on every scenario; " if lim is not None else "")
                     + "look at control_input.png before deploying on a drive that dislikes fast command steps.")
    if len(L) == 2:
        return []
    L.append("")
    return L
