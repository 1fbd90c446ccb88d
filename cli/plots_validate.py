"""PNG figures of ``commission validate`` (matplotlib, Agg backend).

Called only from the CLI layer with a :class:`commission.validate.ValidationResult`;
every number comes from the pipeline, nothing is computed here but unit scaling.

* ``tracking_case1.png`` -- tracking error of ARC and PID on each Case-1
  scenario (the paper's Figs. 2-4: nominal, payload, disturbance, plus the
  friction variants);
* ``tracking_case2.png`` -- the Case-2 trajectory (Fig. 5) and the tracking
  errors on each Case-2 scenario (Fig. 6);
* ``theta_hat.png`` -- convergence of theta_hat on the nominal and payload
  scenarios, with the plant's values dashed;
* ``control_input.png`` -- u of ARC and PID on the nominal scenarios;
* ``monte_carlo.png`` -- e_rms of ARC against PID on every scenario;
* ``loops.png`` -- the loop transfers of ARC and PID on the identified plant:
  Bode magnitude and phase, and the Nyquist curves near -1.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from commission.scenarios import CASES, VARIANTS  # noqa: E402
from commission.validate import ValidationResult  # noqa: E402

_ARC = dict(color="C3", lw=0.7, label="ARC")
_PID = dict(color="C0", lw=0.7, label="PID", alpha=0.8)


#: Points per drawn line: longer traces are reduced to per-bin min and max (peaks stay visible).
MAX_POINTS = 3000


def _envelope(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Min/max decimation of ``y(t)`` to about :data:`MAX_POINTS` points (drawing speed only)."""
    n = min(t.shape[0], y.shape[0])
    t, y = t[:n], y[:n]
    bins = MAX_POINTS // 2
    if n <= MAX_POINTS:
        return t, y
    w = n // bins
    m = w * bins
    yb = y[:m].reshape(bins, w)
    tb = t[:m].reshape(bins, w)
    lo, hi = np.argmin(yb, axis=1), np.argmax(yb, axis=1)
    first, second = np.minimum(lo, hi), np.maximum(lo, hi)
    rows = np.arange(bins)
    tt = np.column_stack([tb[rows, first], tb[rows, second]]).ravel()
    yy = np.column_stack([yb[rows, first], yb[rows, second]]).ravel()
    return np.concatenate([tt, t[m:]]), np.concatenate([yy, y[m:]])


def _plot(ax, t: np.ndarray, y: np.ndarray, **kw) -> None:
    ax.plot(*_envelope(t, y), **kw)


def _tracking(result: ValidationResult, case: str, path: Path, with_trajectory: bool) -> Path:
    names = [f"{case}/{v}" for v in VARIANTS if f"{case}/{v}" in result.traces]
    rows = len(names) + (1 if with_trajectory else 0)
    fig, axes = plt.subplots(rows, 1, figsize=(9, 1.8 * rows + 0.6), sharex=True, squeeze=False)
    axes = axes[:, 0]
    k = 0
    if with_trajectory and names:
        tr = result.traces[names[0]]
        _plot(axes[0], tr.t, tr.qd * 1e3, color="k", lw=0.8)
        axes[0].set_ylabel("q_d [mm]")
        axes[0].set_title(f"{case}: desired trajectory")
        k = 1
    for i, name in enumerate(names):
        ax = axes[k + i]
        tr = result.traces[name]
        _plot(ax, tr.t, tr.e_pid * 1e6, **_PID)
        _plot(ax, tr.t, tr.e_arc * 1e6, **_ARC)
        r = result.run(name)
        flag = " (ARC diverged)" if r.arc.diverged else ""
        ax.set_title(f"{name}{flag}", fontsize=9, loc="left")
        ax.set_ylabel("e [um]")
        # Clip the view to the ARC's range (as the paper's Fig. 3 chops the PID error).
        ea = np.abs(tr.e_arc[np.isfinite(tr.e_arc)])
        ep = np.abs(tr.e_pid[np.isfinite(tr.e_pid)])
        lim = max(np.max(ea) if ea.size else 0.0, np.percentile(ep, 99) if ep.size else 0.0) * 1.1e6
        if lim > 0 and math.isfinite(lim):
            ax.set_ylim(-lim, lim)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[k].legend(loc="upper right", fontsize=8, ncol=2)
    fig.subplots_adjust(left=0.1, right=0.97, top=0.94, bottom=0.08, hspace=0.55)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _theta(result: ValidationResult, path: Path) -> Path:
    names = [n for n in ("case1/nominal", "case1/payload_heavy", "case1/payload_light", "case2/nominal")
             if n in result.traces]
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=False)
    labels = ("theta_1 = 1/M", "theta_2 = B/M [1/s]", "theta_3 = d_n/M [m/s^2]")
    for j, ax in enumerate(axes):
        for c, name in enumerate(names):
            tr = result.traces[name]
            th = tr.theta_hat
            if th.shape[0] == 0:
                continue
            _plot(ax, tr.t, th[:, j], color=f"C{c}", lw=0.9, label=name)
            ax.axhline(tr.theta_true[j], color=f"C{c}", lw=0.8, ls="--")
        g = result.arc_gains
        ax.axhspan(g.theta_min[j], g.theta_max[j], color="0.9", zorder=-1)
        ax.set_ylabel(labels[j])
        ax.grid(alpha=0.3)
    axes[0].set_title("ARC parameter estimates (dashed: plant value; grey: the theta box)")
    axes[0].legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("t [s]")
    fig.subplots_adjust(left=0.1, right=0.97, top=0.94, bottom=0.08, hspace=0.55)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _inputs(result: ValidationResult, path: Path) -> Path:
    names = [n for n in ("case1/nominal", "case1/disturbance", "case2/nominal") if n in result.traces]
    unit = result.units.get("u", "u")
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 2.2 * len(names) + 0.5), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        tr = result.traces[name]
        _plot(ax, tr.t, tr.u_pid, **_PID)
        _plot(ax, tr.t, tr.u_arc, **_ARC)
        ax.set_title(name, fontsize=9, loc="left")
        ax.set_ylabel(f"u [{unit}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8, ncol=2)
    axes[-1, 0].set_xlabel("t [s]")
    fig.subplots_adjust(left=0.1, right=0.97, top=0.94, bottom=0.08, hspace=0.55)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _scatter(result: ValidationResult, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(6, 5.5))
    pts = {"fixed": ([], []), "monte_carlo": ([], [])}
    div = []
    for r in result.runs:
        key = "monte_carlo" if "monte_carlo" in r.tags else "fixed"
        if r.arc.diverged or r.pid.diverged:
            div.append(r.name)
            continue
        pts[key][0].append(r.pid.e_rms * 1e6)
        pts[key][1].append(r.arc.e_rms * 1e6)
    ax.scatter(*pts["monte_carlo"], s=14, color="C0", label=f"Monte-Carlo plants ({result.n_monte_carlo})")
    ax.scatter(*pts["fixed"], s=24, color="C3", marker="s", label="fixed scenarios")
    allv = [v for a, b in pts.values() for v in a + b if v > 0]
    if allv:
        lo, hi = min(allv) / 1.5, max(allv) * 1.5
        ax.plot([lo, hi], [lo, hi], color="k", lw=0.8)
        ratio = result.verdict.limits.arc_vs_pid_e_rms
        slack = result.verdict.limits.arc_vs_pid_slack * 1e6
        if ratio != 1.0 or slack > 0:
            xs = np.geomspace(lo, hi, 64)
            ax.plot(xs, ratio * xs + slack, color="k", lw=0.8, ls="--",
                    label=f"gate: ARC = {ratio:g} PID + {slack:.3g} um")
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_xscale("log")
        ax.set_yscale("log")
    lim = result.verdict.limits.e_rms * 1e6
    ax.axhline(lim, color="C2", lw=0.8, ls=":", label=f"gate e_rms {lim:.3g} um")
    ax.set_xlabel("PID ||e||rms [um]")
    ax.set_ylabel("ARC ||e||rms [um]")
    title = "ARC vs PID on every scenario (below the diagonal: ARC better)"
    if div:
        title += f"\n{len(div)} scenario(s) with a diverged run not shown"
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3, which="both")
    fig.subplots_adjust(left=0.1, right=0.97, top=0.94, bottom=0.08, hspace=0.55)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _loops(result: ValidationResult, path: Path) -> Path:
    f, l_arc, l_pid = result.loops
    fig = plt.figure(figsize=(10, 5.2))
    ax_m = fig.add_subplot(2, 2, 1)
    ax_p = fig.add_subplot(2, 2, 3, sharex=ax_m)
    ax_n = fig.add_subplot(1, 2, 2)
    for L, style in ((l_pid, _PID), (l_arc, _ARC)):
        ax_m.semilogx(f, 20 * np.log10(np.abs(L)), **style)
        ph = np.degrees(np.unwrap(np.angle(L)))
        cross = np.nonzero(np.abs(L) < 1)[0]
        at = ph[cross[0]] if cross.size else ph[0]
        ph -= 360.0 * np.ceil(at / 360.0)  # the phase at the crossover in (-360, 0]: -180 is the critical line
        ax_p.semilogx(f, ph, **{**style, "label": None})
        ax_n.plot(L.real, L.imag, **style)
    ax_m.axhline(0.0, color="k", lw=0.6)
    ax_p.axhline(-180.0, color="k", lw=0.6)
    ax_m.set_ylabel("|L| [dB]")
    ax_p.set_ylabel("angle L [deg]")
    ax_p.set_xlabel("f [Hz]")
    ax_m.legend(loc="lower left", fontsize=8)
    mm = result.margin_floors.modulus
    th = np.linspace(0, 2 * np.pi, 200)
    ax_n.plot(-1 + mm * np.cos(th), mm * np.sin(th), color="k", lw=0.6, ls="--",
              label=f"|1 + L| = {mm:g} (modulus floor)")
    ax_n.plot([-1], [0], "k+", ms=10)
    ax_n.set_xlim(-3, 1.5)
    ax_n.set_ylim(-2.5, 2.0)
    ax_n.set_aspect("equal")
    ax_n.set_xlabel("Re L")
    ax_n.set_ylabel("Im L")
    ax_n.legend(loc="lower right", fontsize=7)
    for ax in (ax_m, ax_p, ax_n):
        ax.grid(alpha=0.3)
    fig.suptitle("Loop transfer at the plant input, identified plant (ARC at theta_hat(0))", fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.98, top=0.92, bottom=0.1, wspace=0.25, hspace=0.15)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def validation_plots(result: ValidationResult, out_dir: str | Path) -> list[Path]:
    """Write the validation figures into ``out_dir``; return their paths (names as in
    :data:`commission.validate.FIGURE_NAMES`)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for case in CASES:
        paths.append(_tracking(result, case, out / f"tracking_{case}.png", with_trajectory=(case == "case2")))
    paths.append(_theta(result, out / "theta_hat.png"))
    paths.append(_inputs(result, out / "control_input.png"))
    paths.append(_scatter(result, out / "monte_carlo.png"))
    if result.loops:
        paths.append(_loops(result, out / "loops.png"))
    return paths
