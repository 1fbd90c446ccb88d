"""PNG figures of ``commission validate`` (matplotlib, Agg backend).

Called only from the CLI layer with a :class:`commission.validate.ValidationResult`;
every number comes from the pipeline, nothing is computed here but unit scaling.

* ``tracking_case1.png`` -- tracking error of ARC and PID on each Case-1
  scenario (the paper's Figs. 2-4: nominal, payload, disturbance, plus the
  friction variants); no controller's peak is clipped (:func:`fit_error_axis`);
* ``tracking_case2.png`` -- the Case-2 trajectory (Fig. 5) and the tracking
  errors on each Case-2 scenario (Fig. 6);
* ``theta_hat.png`` -- theta_hat on every fixed scenario of each case, with
  the plant's values dashed and the box shaded (it converges only under
  persistent excitation; the report says how far it got);
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
from commission.units import unit as unit_of  # noqa: E402
from commission.validate import USER_FIGURE_NAME, ValidationResult  # noqa: E402

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


#: Above this ratio of the two controllers' peak errors the axis turns symmetric-log, linear within the smaller peak.
LOG_RATIO = 20.0


def fit_error_axis(ax, *errors: np.ndarray) -> None:
    """Limits that hold every controller's peak error (never clipped), readable for both.

    Linear when the peaks are within :data:`LOG_RATIO` of each other; otherwise a
    symmetric-log axis, linear up to the smaller peak, so the smaller error keeps its
    shape and the larger one is shown whole.
    """
    peaks = [float(np.max(np.abs(e[np.isfinite(e)]))) for e in errors if np.any(np.isfinite(e))]
    peaks = [p for p in peaks if p > 0]
    if not peaks:
        return
    hi, lo = max(peaks), min(peaks)
    lim = 1.1 * hi
    if hi > LOG_RATIO * lo:
        ax.set_yscale("symlog", linthresh=1.1 * lo)
    ax.set_ylim(-lim, lim)


def _tracking(result: ValidationResult, case: str, path: Path, with_trajectory: bool) -> Path:
    fig = tracking_figure(result, case, with_trajectory)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def tracking_figure(result: ValidationResult, case: str, with_trajectory: bool):
    """The tracking-error figure of one case (every fixed scenario: ARC and PID), not yet saved."""
    names = [f"{case}/{v}" for v in VARIANTS if f"{case}/{v}" in result.traces]
    rows = len(names) + (1 if with_trajectory else 0)
    fig, axes = plt.subplots(rows, 1, figsize=(9, 1.8 * rows + 0.6), sharex=True, squeeze=False)
    axes = axes[:, 0]
    k = 0
    if with_trajectory and names:
        tr = result.traces[names[0]]
        _plot(axes[0], tr.t, tr.qd * 1e3, color="k", lw=0.8)
        axes[0].set_ylabel(f"q_d [m{unit_of('q', result.units)}]")
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
        ax.set_ylabel(f"e [{unit_of('small', result.units)}]")
        fit_error_axis(ax, tr.e_arc * 1e6, tr.e_pid * 1e6)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    handles, labels = axes[k].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper right", fontsize=8, ncol=2, frameon=False)
    fig.subplots_adjust(left=0.1, right=0.97, top=0.93, bottom=0.08, hspace=0.65)
    return fig


def _theta(result: ValidationResult, path: Path) -> Path:
    """theta_hat on every fixed scenario of each case (one column per case), legends below the data."""
    tags = {r.name: r.tags for r in result.runs}
    labels = (f"theta_1 = 1/M [{unit_of('theta1', result.units)}]", "theta_2 = B/M [1/s]",
              f"theta_3 = d_n/M [{unit_of('theta3', result.units)}]")
    fig, axes = plt.subplots(3, len(CASES), figsize=(13, 8.5), sharex="col", squeeze=False)
    g = result.arc_gains
    for c, case in enumerate(CASES):
        names = [f"{case}/{v}" for v in VARIANTS if f"{case}/{v}" in result.traces
                 and "robustness" not in tags.get(f"{case}/{v}", ())]
        for j in range(3):
            ax = axes[j, c]
            ax.axhspan(g.theta_min[j], g.theta_max[j], color="0.92", zorder=-1)
            for k, name in enumerate(names):
                tr = result.traces[name]
                if tr.theta_hat.shape[0] == 0:
                    continue
                _plot(ax, tr.t, tr.theta_hat[:, j], color=f"C{k}", lw=0.9, label=name.split("/")[1])
                ax.axhline(tr.theta_true[j], color=f"C{k}", lw=0.8, ls="--")
            if c == 0:
                ax.set_ylabel(labels[j], fontsize=8)
            ax.grid(alpha=0.3)
        axes[0, c].set_title(f"{case}: theta_hat (solid), plant (dashed), box (grey)", fontsize=9)
        axes[-1, c].set_xlabel("t [s]")
        axes[-1, c].legend(loc="upper center", bbox_to_anchor=(0.5, -0.28), fontsize=8, ncol=3, frameon=False)
    fig.subplots_adjust(left=0.08, right=0.98, top=0.95, bottom=0.14, hspace=0.3, wspace=0.25)
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


def monte_carlo_figure(result: ValidationResult, path: Path) -> Path:
    """``monte_carlo.png``: e_rms of ARC against PID on every scenario, with the gate's lines inside the axes."""
    small = unit_of("small", result.units)
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
                    label=f"gate: ARC = {ratio:g} PID + {slack:.3g} {small}")
    lim = result.verdict.limits.e_rms * 1e6
    if allv:
        ax.set_xlim(lo, hi)
        # The gate's horizontal line is never on the border: the y range holds it with the same
        # margin (a factor 1.5 on the log axis) as the points.
        ax.set_ylim(min(lo, lim / 1.5) if lim > 0 else lo, max(hi, lim * 1.5))
        ax.set_xscale("log")
        ax.set_yscale("log")
    ax.axhline(lim, color="C2", lw=0.8, ls=":", label=f"gate e_rms {lim:.3g} {small}")
    ax.set_xlabel(f"PID ||e||rms [{small}]")
    ax.set_ylabel(f"ARC ||e||rms [{small}]")
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


def _tracking_figures(result: ValidationResult, out: Path) -> list[Path]:
    paths = [_tracking(result, case, out / f"tracking_{case}.png", with_trajectory=(case == "case2")) for case in CASES]
    if any(name.startswith("user/") for name in result.traces):  # the machine's own moves
        paths.append(_tracking(result, "user", out / USER_FIGURE_NAME, with_trajectory=True))
    return paths


def validation_plots(result: ValidationResult, out_dir: str | Path) -> list[Path]:
    """Write the validation figures into ``out_dir``; return their paths (names as in
    :data:`commission.validate.FIGURE_NAMES`).

    The tracking figures and the theta_hat figure (each about as long to draw as all the
    others together) are drawn in two forked child processes
    (:class:`commission.infra.background.ChildJob`) while this process draws the others:
    matplotlib holds the interpreter lock, so a thread would not run beside it.  Without
    ``fork`` the children's parts run here, as before.  The same files either way.
    """
    from commission.infra.background import ChildJob

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    children = [ChildJob(_tracking_figures, result, out)]
    try:
        children.append(ChildJob(_theta, result, out / "theta_hat.png"))
        rest = [_inputs(result, out / "control_input.png"), monte_carlo_figure(result, out / "monte_carlo.png")]
        if result.loops:
            rest.append(_loops(result, out / "loops.png"))
        tracking, theta = children[0].result(), children[1].result()
    except BaseException:
        for job in children:
            job.cancel()
        raise
    return [*tracking, theta, *rest]
