"""PNG plots of the identification (matplotlib, Agg backend).

Called only from the CLI layer; the computation lives in
:mod:`commission.identification` and :mod:`commission.identify`.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from commission.identification import IdentifyOutcome, friction_curve  # noqa: E402
from commission.units import unit as unit_of  # noqa: E402


def identification_plots(outcome: IdentifyOutcome, out_dir: str | Path) -> list[Path]:
    """Write the three identification figures; return their paths.

    * ``force_fit.png``: measured against fitted force over time;
    * ``friction_curve.png``: identified friction curve over the friction map;
    * ``residuals.png``: residual histogram;
    * ``bode.png``: measured frequency response u -> q with its coherence, the
      rigid model and the fitted model (mode and delay).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fit, ident = outcome.fit, outcome.ident
    unit = ident.units["u"]
    paths = []

    fig, (ax, axr) = plt.subplots(2, 1, figsize=(10, 6), sharex=True, height_ratios=[3, 1])
    ax.plot(fit.t_decimated, fit.force_measured, lw=0.8, label="measured (decimated command)")
    ax.plot(fit.t_decimated, fit.force_fitted, lw=0.8, label="fitted model")
    ax.set_ylabel(f"force [{unit}]")
    ax.set_title(f"Inverse-dynamics fit: relative error {ident.relative_error:.4f}")
    ax.legend(loc="upper right")
    axr.plot(fit.t_decimated, fit.residuals, lw=0.6, color="C3")
    axr.set_ylabel(f"residual [{unit}]")
    axr.set_xlabel("t [s]")
    fig.tight_layout()
    paths.append(out / "force_fit.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 5))
    vmax = max(fit.v_max, 1e-6)
    v = np.linspace(-vmax, vmax, 2001)
    ax.plot(v, friction_curve(ident, v), color="k", lw=1.4, label="identified B v + Ff(v) + offset")
    comp = ident.fric_level * (2 / np.pi) * np.arctan(ident.fric_slope * v) + ident.value("B") * v + ident.value("offset")
    ax.plot(v, comp, "--", color="C2", lw=1.0, label="compensation (atan) + B v + offset")
    if fit.steady_velocity.size:
        ax.plot(fit.steady_velocity, fit.steady_force, "o", ms=4, color="C0", label="constant-velocity legs")
    ax.set_xlabel(f"velocity [{unit_of('v', ident.units)}]")
    ax.set_ylabel(f"friction [{unit}]")
    ax.set_title(f"Friction ({fit.friction}, {fit.method})")
    ax.axhline(0, color="0.8", lw=0.5)
    ax.axvline(0, color="0.8", lw=0.5)
    ax.legend(loc="upper left")
    fig.tight_layout()
    paths.append(out / "friction_curve.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.hist(fit.residuals, bins=60, color="C0", alpha=0.85)
    ax.set_xlabel(f"residual [{unit}]")
    ax.set_ylabel("count")
    ax.set_title(f"Residuals: std {fit.residual_std:.3g} {unit}")
    fig.tight_layout()
    paths.append(out / "residuals.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    if outcome.frequency is not None:  # None: M not identified, no rigid model to compare with
        paths.append(bode_plot(outcome, out / "bode.png"))
    return paths


def bode_plot(outcome: IdentifyOutcome, path: Path) -> Path:
    """Bode plot of the measured response (with coherence), the rigid model and the fitted model."""
    fr = outcome.frequency
    unit = outcome.ident.units["u"]
    fig, (axm, axp, axc) = plt.subplots(3, 1, figsize=(9, 8), sharex=True, height_ratios=[3, 2, 1])
    good = fr.coherence >= 0.5
    Hm = np.where(good, fr.H, np.nan)
    axm.loglog(fr.f, np.abs(fr.H), color="0.8", lw=0.6, label="measured (coherence < 0.5)")
    label = "measured H1 (broadband segments)" if fr.source == "broadband" else \
        "measured H1 (whole log; outside the band it shows the loop's answer to noise, not the plant)"
    axm.loglog(fr.f, np.abs(Hm), color="C0", lw=1.0, label=label)
    axm.loglog(fr.f, np.abs(fr.H_rigid), "--", color="k", lw=1.0, label="rigid model 1/(M s² + B s)")
    if fr.H_model is not None:
        axm.loglog(fr.f, np.abs(fr.H_model), color="C3", lw=1.0, label=f"fitted: {fr.fit.structure.replace('_', ' ')}")  # type: ignore[union-attr]
    if fr.band_hz is not None:
        for ax in (axm, axp, axc):
            ax.axvspan(fr.band_hz[0], fr.band_hz[1], color="C2", alpha=0.08)
    axm.set_ylabel(f"|q/u| [{unit_of('q/u', outcome.ident.units)}]")
    title = "Frequency response u → q"
    if fr.band_hz is not None:
        title += f"; rigid model backed {fr.band_hz[0]:.3g}–{fr.band_hz[1]:.3g} Hz (shaded)"
    axm.set_title(title)
    axm.legend(loc="lower left", fontsize=8)
    # Unwrapped model phases; the measured phase is drawn about the fitted (else rigid) curve so
    # that a wrap of +-360 degrees does not separate curves that agree.
    ref = fr.H_model if fr.H_model is not None else fr.H_rigid
    ref_deg = np.degrees(np.unwrap(np.angle(ref)))
    axp.semilogx(fr.f, np.where(good, ref_deg + np.degrees(np.angle(fr.H / ref)), np.nan), ".", ms=2, color="C0")
    axp.semilogx(fr.f, np.degrees(np.unwrap(np.angle(fr.H_rigid))), "--", color="k", lw=1.0)
    if fr.H_model is not None:
        axp.semilogx(fr.f, ref_deg, color="C3", lw=1.0)
    axp.set_ylabel("phase [deg]")
    axc.semilogx(fr.f, fr.coherence, color="C0", lw=0.8)
    axc.set_ylim(0, 1.05)
    axc.set_ylabel("coherence")
    axc.set_xlabel("frequency [Hz]")
    if fr.note:
        fig.text(0.01, 0.005, fr.note, fontsize=7, wrap=True)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
