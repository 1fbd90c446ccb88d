"""The friction-map figure of a friction test (``identify LEG... --plot DIR``), matplotlib Agg."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from commission.identification import LegsOutcome, friction_curve  # noqa: E402
from commission.units import unit  # noqa: E402


def friction_map_plot(outcome: LegsOutcome, path: Path) -> Path:
    """Each leg's median command ± its spread against its mean speed, and the fitted curve.

    Two panels: the whole map on linear axes, and |force| against |speed| on a
    logarithmic speed axis, where the slow legs (the Stribeck region) are visible.
    """
    ident, fmap = outcome.ident, outcome.fmap
    u = ident.units["u"]
    v, F, sd = fmap.velocity, fmap.force, fmap.std
    fig, (ax, axl) = plt.subplots(1, 2, figsize=(12, 5))
    vmax = float(np.max(np.abs(v)))
    grid = np.linspace(-vmax, vmax, 4001)
    grid = grid[grid != 0.0]
    curve = friction_curve(ident, grid)
    ax.errorbar(v, F, yerr=sd, fmt="o", ms=4, capsize=2, color="C0", label="legs: median ± std of the command")
    ax.plot(grid, curve, color="k", lw=1.2, label=f"fitted B v + Ff(v) + offset ({ident.extra['model']['friction']})")
    ax.axhline(0, color="0.8", lw=0.5)
    ax.axvline(0, color="0.8", lw=0.5)
    ax.set_xlabel(f"mean speed [{unit('v', ident.units)}]")
    ax.set_ylabel(f"command [{u}]")
    ax.set_title(f"Friction map: {v.size} legs, relative error {ident.relative_error:.3f}")
    ax.legend(loc="best", fontsize=8)
    for sign, color, label in ((1.0, "C0", "forward"), (-1.0, "C3", "backward")):
        sel = np.sign(v) == sign
        if np.any(sel):
            axl.errorbar(np.abs(v[sel]), np.abs(F[sel]), yerr=sd[sel], fmt="o", ms=4, capsize=2, color=color,
                         label=f"{label} legs")
            g = np.geomspace(np.abs(v[sel]).min(), np.abs(v[sel]).max(), 400)
            axl.plot(g, np.abs(friction_curve(ident, sign * g)), color=color, lw=1.0)
    axl.set_xscale("log")
    axl.set_xlabel(f"|speed| [{unit('v', ident.units)}] (log)")
    axl.set_ylabel(f"|command| [{u}]")
    axl.set_title("Low-speed detail (Stribeck region)")
    axl.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
