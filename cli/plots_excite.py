"""PNG plot of an excitation plan (matplotlib, Agg backend): q_ref, v_ref, u_inject and the injection's spectrum."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

from commission.excite import Plan  # noqa: E402


def plan_plot(plan: Plan, path: str | Path) -> Path:
    """Four panels: q_ref (q), v_ref (q/s), u_inject (u) against time with the segments shaded,
    and the Welch spectrum of u_inject over the injection segment (u^2/Hz)."""
    s = plan.spec
    q, u = s.q_unit, s.u_unit
    fig, ax = plt.subplots(4, 1, figsize=(10, 10), constrained_layout=True)
    for a, y, lab in ((ax[0], plan.q_ref, f"q_ref ({q})"), (ax[1], plan.v_ref, f"v_ref ({q}/s)"),
                      (ax[2], plan.u_inject, f"u_inject ({u})")):
        a.plot(plan.t, y, lw=0.6)
        a.set_ylabel(lab)
        a.set_xlabel("t (s)")
        for i, g in enumerate(plan.segments):
            if i % 2:
                a.axvspan(g.t_start, g.t_end, color="0.92", lw=0)
    for g in plan.segments:
        ax[0].text((g.t_start + g.t_end) / 2, float(np.max(plan.q_ref)), g.name, fontsize=6, ha="center",
                   va="bottom", rotation=90)
    inj = next((g for g in plan.segments if g.name == "injection"), None)
    if inj is not None:
        m = (plan.t >= inj.t_start) & (plan.t < inj.t_end) & (plan.u_inject != 0)
        x = plan.u_inject[m]
        if x.size > 64:
            f, pxx = signal.welch(x, fs=s.sample_rate, nperseg=min(4096, x.size))
            ax[3].loglog(f[1:], pxx[1:], lw=0.8)
    ax[3].set_xlabel("frequency (Hz)")
    ax[3].set_ylabel(f"u_inject PSD ({u}^2/Hz)")
    ax[3].set_title("injection spectrum")
    fig.suptitle(f"excitation plan: {plan.duration:.1f} s at {s.sample_rate:g} Hz")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return Path(path)
