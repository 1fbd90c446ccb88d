"""The report's identification section: parameters with their spread and units, fit quality,
the frequency response and the identification figures."""

from __future__ import annotations

from typing import Sequence

from commission.report.labels import IDENT_CAPTIONS, PARAM_WHAT
from commission.report.text import md_code, md_text, num, vec
from commission.tuning import Tuning
from commission.units import mass_wording, parameter_units


def identification_markdown(tuning: Tuning, figures: Sequence[str] = ()) -> list[str]:
    """The report's identification section: parameters ± std with units, fit quality, the
    frequency response, and the identification figures present among ``figures``."""
    ident = tuning.identification
    u, q = ident.units.get("u", "u"), ident.units.get("q", "m")
    src = ident.extra.get("source") if isinstance(ident.extra.get("source"), dict) else {}
    model = ident.extra.get("model") if isinstance(ident.extra.get("model"), dict) else {}
    rotary = q == "rad"
    L = ["## Identification", ""]
    head = f"From {md_code(src.get('path', 'the log'))}"
    if src.get("n_samples") and src.get("sample_rate"):
        head += f" ({src['n_samples']} samples at {num(float(src['sample_rate']), 6)} Hz)"
    head += (f"; friction model {md_text(model.get('friction', '?'))} ({md_text(model.get('method', '?'))} method). "
             f"Fit: relative error {num(ident.relative_error, 3)} (fraction of ‖u‖), condition number "
             f"{num(ident.condition_number, 3)}")
    if ident.validation_relative_error is not None:
        head += f", cross-test relative error {num(ident.validation_relative_error, 3)}"
    if rotary:
        what, unit = mass_wording(ident.units)
        head += (f". A rotary axis: M is the {what} seen by the command, in {unit}, and B the viscous friction "
                 f"in {u}·s/rad")
    L += [head + ".", "", "| Parameter | Value | ± std | Relative std | Unit |", "|---|---:|---:|---:|---|"]
    for name, est in ident.parameters.items():
        if est is None:
            continue
        unit, what = parameter_units(ident.units).get(name, ""), PARAM_WHAT.get(name, name)
        if name == "M" and rotary:
            what = "inertia J"
        rel = f"{abs(est.std / est.value) * 100:.2g} %" if est.value else "-"
        L.append(f"| {name} ({what}) | {num(est.value)} | {num(est.std, 2)} | {rel} | {unit} |")
    if ident.theta is not None:
        L += ["", f"theta = [1/M, B/M, d_n/M]{' (M the inertia J)' if rotary else ''} in [{q}/({u}·s²), 1/s, {q}/s²]: nominal {vec(ident.theta.nominal)}, "
                  f"box min {vec(ident.theta.min)}, max {vec(ident.theta.max)}; delta_d = {num(ident.delta_d or 0.0, 3)} "
                  f"{q}/s². Friction compensation {num(ident.fric_level, 3)}·(2/π)·atan({num(ident.fric_slope, 3)}·v) {u}."]
    fr = ident.extra.get("frequency_response")
    if isinstance(fr, dict):
        if fr.get("note"):
            L += ["", f"Frequency response: {md_text(fr['note'])}"]
        else:
            band = fr.get("band_hz")
            text = (f"Frequency response: the rigid model is backed from {num(band[0], 3)} to {num(band[1], 3)} Hz"
                    if band else "Frequency response: no band backs the rigid model")
            for m in fr.get("modes") or []:
                text += f"; {md_text(m['kind'])} at {num(m['frequency_hz'], 4)} Hz, damping {num(m['damping'], 2)}"
            if fr.get("delay_samples") is not None:
                text += f"; input delay {num(fr['delay_samples'], 2)} samples"
            L += ["", text + "."]
    shown = [f for f in figures if f in IDENT_CAPTIONS]
    if shown:
        no_legs = not model.get("steady_points")
        for f in shown:
            caption = IDENT_CAPTIONS[f"{f}/no legs" if no_legs and f"{f}/no legs" in IDENT_CAPTIONS else f]
            L += ["", f"![{f}]({f})", "", caption]
    else:
        L += ["", "Identification figures: `commission identify LOG --plot DIR` (`commission run` writes them "
                  "beside this report)."]
    L.append("")
    return L
