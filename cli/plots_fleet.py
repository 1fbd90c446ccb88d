"""The fleet figure (``commission fleet``): each axis's identified parameters against the fleet's median, Agg."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from commission.fleet import FLEET_FIGURE, OUTLIER_PARAMETERS, OUTLIER_Z  # noqa: E402


def fleet_plot(doc: Mapping[str, Any], out: Path) -> Path | None:
    """One panel per compared parameter: value / median per axis, the outlier band, flagged axes in red.

    Returns None when fewer than the minimum number of axes were identified (no statistics).
    """
    stats = doc.get("statistics") or {}
    keys = [k for k in OUTLIER_PARAMETERS if stats.get(k)]
    rows = [r for r in doc["axes"] if r.get("parameters")]
    if not keys or not rows:
        return None
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 0.32 * len(rows) + 2.2), sharey=True)
    axes = list(axes) if len(keys) > 1 else [axes]
    names = [r["name"] for r in rows]
    for ax, k in zip(axes, keys):
        st = stats[k]
        med, band = st["median"], OUTLIER_Z * st["scale"]
        ax.axvspan((med - band) / med, (med + band) / med, color="0.9", label=f"median ± {OUTLIER_Z} scale")
        ax.axvline(1.0, color="0.5", lw=0.8)
        for i, r in enumerate(rows):
            v = r["parameters"][k]["value"]
            flagged = k in ((r.get("outlier") or {}).get("parameters") or [])
            ax.plot(v / med, i, "o", color="C3" if flagged else "C0", ms=6 if flagged else 4)
        ax.set_title(f"{k}: median {med:.4g} {st['unit']}", fontsize=9)
        ax.set_xlabel(f"{k} / fleet median (1)")
        ax.grid(axis="x", lw=0.3)
    axes[0].set_yticks(range(len(names)), names, fontsize=8)
    axes[0].invert_yaxis()
    axes[0].legend(loc="lower left", fontsize=7)
    fig.suptitle("Fleet: identified parameters per axis (red: flagged outlier)", fontsize=10)
    fig.tight_layout()
    path = out / FLEET_FIGURE
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
