"""The report's stability-margin section: the plant model, one row per loop, and the whole theta box.

The margins are computed by :mod:`commission.robustness` (linearised at rest from the compiled
step); this module only words them and marks which rows the gate holds.
"""

from __future__ import annotations

from typing import Any

from commission.robustness import floor_violations
from commission.scenarios.identified import plant_dynamics
from commission.tuning import Tuning


def margins_markdown(result: Any, tuning: Tuning) -> list[str]:
    """The report's stability-margin section: the plant model, then one row per loop."""
    rows = getattr(result, "margins", ())
    if not rows:
        return []
    fl = result.margin_floors
    dyn = plant_dynamics(tuning.identification, tuning.spec)
    Ts = tuning.spec.period
    if dyn.get("mode_hz"):
        side = "load" if dyn.get("mode_load_side") else "motor"
        mode = (f"a structural mode at {dyn['mode_hz']:.4g} Hz, damping {dyn.get('mode_damping', 0.02):.3g}, "
                f"load fraction {dyn.get('mode_ratio', 0.5):.2f}, encoder on the {side} side")
    else:
        mode = "no structural mode (rigid body)"
    if dyn.get("mode2_hz"):
        mode += (f"; a second at {dyn['mode2_hz']:.4g} Hz, damping {dyn.get('mode2_damping', 0.02):.3g}, "
                 f"load fraction {dyn.get('mode2_ratio', 0.1):.2f}"
                 + (", the encoder on that load" if dyn.get("mode2_load_side") else ""))
    L = ["## Stability margins", "",
         f"Plant model: {mode}; input delay {dyn.get('delay', 0.0) / Ts:.2f} samples beyond the hold. "
         "Both loops are linearised at rest from the compiled step that runs on the machine "
         "(ARC: theta_hat at its initial value and at the plant's own theta, adaptation and robust gains "
         "at their rest values, friction compensation left out; `commission.controllers.margins`). "
         f"Floors: gain {fl.gain_db:g} dB, phase {fl.phase_deg:g} deg, delay {fl.delay_samples:g} samples "
         f"beyond the identified delay, modulus {fl.modulus:g}.", "",
         "| Plant | Loop | gain margin (dB) | phase margin (deg) | delay margin (samples) | modulus margin "
         "| crossover (Hz) | stable | floors |",
         "|---|---|---:|---:|---:|---:|---:|---|---|"]
    for r in rows:
        m = r.margins
        loop = "PID" if r.controller == "pid" else f"ARC (theta_hat {r.theta_hat_at})"
        miss = floor_violations(m, fl)
        L.append(f"| {r.plant} | {loop} | {m.gain_margin_db:.1f} | {m.phase_margin_deg:.0f} | "
                 f"{m.delay_margin_samples:.2f} | {m.modulus_margin:.2f} | {m.crossover_hz:.0f} | "
                 f"{'yes' if m.stable else '**no**'} | {_floor_cell(r, miss)} |")
    L.append("")
    L.append("Gated rows: the ARC on the identified plant (both estimates) and, at every box plant, the ARC with "
             "theta_hat at that plant's theta (where the adaptation goes; the table shows the identified load, "
             "the box check below gates both ends of the load-force range); the others are shown for comparison "
             "and marked *not gated* (the PID baseline, and the ARC's start-up estimate on a corner plant, whose "
             "stability the box check below covers).")
    L.append("")
    L.extend(box_markdown(result))
    return L


def _floor_cell(r: Any, miss: list[str]) -> str:
    """The floors column: what is gated says met or missed; the rest is marked *not gated*."""
    gated = r.controller == "arc" and (r.plant == "nominal" or r.theta_hat_at == "plant")
    if not miss:
        return "met" if gated else "met (not gated)"
    return ("**" + "; ".join(miss) + "**") if gated else "*not gated*: " + "; ".join(miss)


def box_markdown(result: Any) -> list[str]:
    """The box check's worst cases (:class:`commission.robustness.BoxRobustness`), gated as ``margins_box``."""
    box = getattr(result, "box", None)
    if box is None:
        return []
    fl = result.margin_floors
    w = box.worst_at_plant(fl)
    m = w.margins
    miss = floor_violations(m, fl)
    a = box.any_estimate
    return [f"**The whole theta box.** (a) At each of the {len(box.at_plant)} box plants (the 4 (theta1, theta2) "
            f"corners x the identified mode and its variants x both ends of the load-force range, identified "
            f"delay), the ARC with theta_hat at that plant's theta: worst {w.plant}, phase margin {m.phase_margin_deg:.3g} deg, delay margin "
            f"{m.delay_margin_samples:.3g} samples, modulus margin {m.modulus_margin:.3g}, spectral radius "
            f"{m.spectral_radius:.4f} ({'every floor met' if not miss else 'misses ' + '; '.join(miss)}). "
            f"(b) With theta_hat frozen at each corner of the projection box, at theta_hat(0) and at the plant's theta "
            f"on every box plant, and at theta_hat(0) and the plant's theta with one more sample of delay ({a.loops} "
            f"loops): largest spectral radius {a.spectral_radius:.4f} on {a.plant}, theta_hat at {a.theta_hat_at} "
            f"({'stable; a radius of 1.0000 is the neutral theta_hat1, theta_hat2 modes at rest' if a.stable else 'UNSTABLE'}).",
            ""]
