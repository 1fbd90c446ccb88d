"""Text of the validation report (``report.md``) and of the stdout summary.

No plotting here: the figures are drawn by the CLI (``cli/plots_validate.py``)
and only linked by name.  The performance-index tables follow the layout of
Table 1 of Xu & Yao (2001): one column pair (PID, ARC) per scenario, rows
e_M, e_F, ‖e‖rms (um), ‖u‖rms, ‖Δu‖rms (u-unit) and c_u.  Markdown
tables use "‖" (U+2016) for the norm bars, since "|" separates cells.
"""

from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from commission.next_steps import next_steps
from commission.units import axis_units_context, mass_wording, nominal, parameter_units, unit as unit_of
from commission.gate import CRITERIA, DEFAULT_ARC_VS_PID_NOMINAL, safe_not_better, search_infeasible_line
from commission.robustness import floor_violations
from commission.scenarios import VARIANTS, case_names, horizon_notes, plant_dynamics
from commission.tuning import Score, Tuning, log_sha256_of

#: Row label, Score field, scale, format (Table 1 of the paper).
TABLE1_ROWS = (
    ("e_M ({s})", "e_M", 1e6, "{:.3g}"),
    ("e_F ({s})", "e_F", 1e6, "{:.3g}"),
    ("‖e‖rms ({s})", "e_rms", 1e6, "{:.3g}"),
    ("‖u‖rms ({u})", "u_rms", 1.0, "{:.3g}"),
    ("‖Δu‖rms ({u})", "du_rms", 1.0, "{:.3g}"),
    ("c_u", "c_u", 1.0, "{:.2f}"),
)
_CASE_TITLE = {"case1": "Case 1 (sinusoid through filter (58))", "case2": "Case 2 (back-and-forth point-to-point moves)",
               "user": "The machine's own moves (spec [trajectory] file or [[trajectory.move]])"}
_CRITERION_TEXT = {
    "divergence": "no divergence",
    "e_F": "e_F (final accuracy, last 2 s)",
    "e_M": "e_M (largest error)",
    "e_rms": "‖e‖rms",
    "c_u": "c_u (chattering)",
    "u_peak": "peak command below u_max",
    "arc_vs_pid_e_rms": "ARC ‖e‖rms / PID ‖e‖rms",
    "arc_vs_pid_median": "ARC vs PID ‖e‖rms factor, median per group",
    "arc_vs_pid_p90": "ARC vs PID ‖e‖rms factor, 90th percentile per group",
    "arc_vs_pid_nominal": "ARC / PID ‖e‖rms on the identified plant, per case (nominal and +1 sample)",
    "margins": "ARC stability margins, identified plant (floor / margin)",
    "margins_box": "ARC over the theta box: floors with theta_hat at each plant's theta (floor / margin), "
                   "stability with theta_hat anywhere (spectral radius)",
}


def _fmt(v: float, fmt: str, scale: float) -> str:
    return fmt.format(v * scale) if math.isfinite(v) else "div."


def _cell(score: Score, key: str, scale: float, fmt: str) -> str:
    if score.diverged:
        return "diverged"
    return _fmt(getattr(score, key), fmt, scale)


def table1_markdown(result: Any, case: str, unit: str) -> str:
    """Markdown table of one case in the layout of Table 1 (PID | ARC per scenario)."""
    runs = {r.name: r for r in result.runs}
    names = [f"{case}/{v}" for v in VARIANTS if f"{case}/{v}" in runs]
    head = "| Controller | " + " | ".join(f"{n.split('/')[1]} PID | {n.split('/')[1]} ARC" for n in names) + " |"
    sep = "|---|" + "---:|" * (2 * len(names))
    lines = [head, sep]
    for label, key, scale, fmt in TABLE1_ROWS:
        cells = []
        for n in names:
            r = runs[n]
            cells += [_cell(r.pid, key, scale, fmt), _cell(r.arc, key, scale, fmt)]
        lines.append(f"| {label.format(u=unit, s=unit_of('small', result.units))} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def monte_carlo_summary(result: Any) -> dict[str, Any]:
    """Median and worst of the ARC and PID indexes over the Monte-Carlo plants."""
    mc = [r for r in result.runs if "monte_carlo" in r.tags]
    out: dict[str, Any] = {"n": len(mc)}
    if not mc:
        return out
    for ctrl in ("arc", "pid"):
        scores = [getattr(r, ctrl) for r in mc]
        ok = [s for s in scores if not s.diverged]
        d: dict[str, Any] = {"diverged": len(scores) - len(ok)}
        for key in ("e_M", "e_F", "e_rms", "c_u", "u_peak"):
            vals = np.array([getattr(s, key) for s in ok], dtype=float)
            vals = vals[np.isfinite(vals)]
            d[key] = (float(np.median(vals)), float(np.max(vals))) if vals.size else (math.nan, math.nan)
        out[ctrl] = d
    out["arc_better"] = sum(1 for r in mc if not r.arc.diverged and (r.pid.diverged or r.arc.e_rms <= r.pid.e_rms))
    return out


def _limit_text(key: str, limits: Any) -> str:
    if key == "divergence":
        return "required" if limits.no_divergence else "not checked"
    if key in ("e_F", "e_M", "e_rms"):
        text = f"{getattr(limits, key) * 1e6:.3g} {unit_of('small')}"
        mode = getattr(limits, "absolute", "fixed") if key in getattr(limits, "defaulted", ()) else "fixed"
        return {"yardstick": f"max({text}, the PID yardstick's)", "reported": f"reported (default {text})"}.get(mode, text)
    if key == "c_u":
        return f"{limits.c_u:.3g}"
    if key == "u_peak":
        return f"{limits.u_max:.4g}"
    if key in ("margins", "margins_box"):
        return "1 (every floor met)" if key == "margins" else "1 (every floor met; radius < 1)"
    if key in ("arc_vs_pid_median", "arc_vs_pid_p90"):
        return f"{getattr(limits, key):.3g}"
    if key == "arc_vs_pid_nominal":
        return f"below {getattr(limits, key, DEFAULT_ARC_VS_PID_NOMINAL):.3g} (no slack)"
    slack = getattr(limits, "arc_vs_pid_slack", 0.0)
    return f"{limits.arc_vs_pid_e_rms:.3g} x PID" + (f" + {slack * 1e6:.3g} {unit_of('small')}" if slack > 0 else "")


def _basis_key(key: str) -> str:
    return {"divergence": "no_divergence", "u_peak": "u_max"}.get(key, key)


def _basis_text(key: str, limits: Any) -> str:
    if key in ("margins", "margins_box"):
        return "spec.toml [margins]"
    return limits.basis.get(_basis_key(key), "")


def _value_text(c: Any) -> str:
    if c.criterion == "divergence":
        return "none" if c.passed else f"at t = {c.value:.4g} s"
    if c.criterion in ("e_F", "e_M", "e_rms"):
        if not math.isfinite(c.value):
            return "n/a (diverged)"
        text = f"{c.value * 1e6:.3g} {unit_of('small')}"
        if "yardstick" in c.detail and math.isfinite(c.limit):  # a limit set by the yardstick there
            text += f" (limit there {c.limit * 1e6:.3g} {unit_of('small')}, the PID yardstick's)"
        return text
    if not math.isfinite(c.value):
        return "n/a (diverged)"
    return f"{c.value:.3g}"


def gate_table_markdown(verdict: Any) -> str:
    """One row per criterion: limit, how it was set, worst scenario and value, pass/fail count."""
    worst = verdict.worst()
    lines = ["| Criterion | Limit | Set by | Worst scenario | Worst value | Failed |", "|---|---|---|---|---|---:|"]
    for key in CRITERIA:
        checks = [c for c in verdict.checks if c.criterion == key]
        if not checks:
            continue
        w = worst[key]
        nfail = sum(1 for c in checks if not c.passed)
        where = w.scenario if not (key == "divergence" and w.passed) else "-"
        lines.append(f"| {_CRITERION_TEXT[key]} | {_limit_text(key, verdict.limits)} | "
                     f"{_basis_text(key, verdict.limits)} | {where} | {_value_text(w)} | "
                     f"{nfail} of {len(checks)} |")
    return "\n".join(lines)


def failure_lines(verdict: Any) -> list[str]:
    """Every failed check as ``criterion  scenario: detail``."""
    return [f"{c.criterion} {c.scenario}: {c.detail}" for c in verdict.failures]


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


#: Parameter -> description (units: :func:`commission.units.parameter_units`).
_PARAM_WHAT = {"M": "mass", "B": "viscous friction", "fc": "Coulomb level", "fs": "static level",
               "vs": "Stribeck velocity", "xi": "Stribeck exponent", "offset": "command offset"}
#: Figures of the identification (``identify --plot``; ``run`` writes them beside the report).
_IDENT_CAPTIONS = {
    "force_fit.png": "Inverse-dynamics fit: measured against fitted force, and the residual, over the log.",
    "friction_curve.png": "Identified friction curve over the constant-velocity legs, with the atan compensation.",
    "friction_curve.png/no legs": "Identified friction curve, with the atan compensation (the log holds no "
                                  "constant-velocity leg to plot over it).",
    "residuals.png": "Histogram of the fit's residuals.",
    "bode.png": "Measured frequency response u -> q with its coherence, against the rigid and the fitted model.",
}


def md_code(text: object) -> str:
    """Text from an input file as a Markdown code span: nothing inside it is a link, markup or HTML.

    A backtick would close the span, so it is shown as ``'``; line breaks become spaces."""
    return "`" + " ".join(str(text).replace("`", "'").split()) + "`"


def md_text(text: object) -> str:
    """Text from an input file in a Markdown paragraph: every character Markdown or HTML would
    interpret (links, emphasis, tables, tags, headings) escaped, line breaks as spaces."""
    out = " ".join(str(text).split())
    out = out.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    for ch in "\\`*_[]|#!":
        out = out.replace(ch, "\\" + ch)
    return out


def _g(x: float, digits: int = 4) -> str:
    """A number rounded for people (the JSON files keep every digit)."""
    return f"{x:.{digits}g}" if math.isfinite(x) else str(x)


def _vec(v: Sequence[float], digits: int = 4) -> str:
    return "[" + ", ".join(_g(float(x), digits) for x in v) + "]"


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
        head += f" ({src['n_samples']} samples at {_g(float(src['sample_rate']), 6)} Hz)"
    head += (f"; friction model {md_text(model.get('friction', '?'))} ({md_text(model.get('method', '?'))} method). "
             f"Fit: relative error {_g(ident.relative_error, 3)} (fraction of ‖u‖), condition number "
             f"{_g(ident.condition_number, 3)}")
    if ident.validation_relative_error is not None:
        head += f", cross-test relative error {_g(ident.validation_relative_error, 3)}"
    if rotary:
        what, unit = mass_wording(ident.units)
        head += (f". A rotary axis: M is the {what} seen by the command, in {unit}, and B the viscous friction "
                 f"in {u}·s/rad")
    L += [head + ".", "", "| Parameter | Value | ± std | Relative std | Unit |", "|---|---:|---:|---:|---|"]
    for name, est in ident.parameters.items():
        if est is None:
            continue
        unit, what = parameter_units(ident.units).get(name, ""), _PARAM_WHAT.get(name, name)
        if name == "M" and rotary:
            what = "inertia J"
        rel = f"{abs(est.std / est.value) * 100:.2g} %" if est.value else "-"
        L.append(f"| {name} ({what}) | {_g(est.value)} | {_g(est.std, 2)} | {rel} | {unit} |")
    if ident.theta is not None:
        L += ["", f"theta = [1/M, B/M, d_n/M]{' (M the inertia J)' if rotary else ''} in [{q}/({u}·s²), 1/s, {q}/s²]: nominal {_vec(ident.theta.nominal)}, "
                  f"box min {_vec(ident.theta.min)}, max {_vec(ident.theta.max)}; delta_d = {_g(ident.delta_d or 0.0, 3)} "
                  f"{q}/s². Friction compensation {_g(ident.fric_level, 3)}·(2/π)·atan({_g(ident.fric_slope, 3)}·v) {u}."]
    fr = ident.extra.get("frequency_response")
    if isinstance(fr, dict):
        if fr.get("note"):
            L += ["", f"Frequency response: {md_text(fr['note'])}"]
        else:
            band = fr.get("band_hz")
            text = (f"Frequency response: the rigid model is backed from {_g(band[0], 3)} to {_g(band[1], 3)} Hz"
                    if band else "Frequency response: no band backs the rigid model")
            for m in fr.get("modes") or []:
                text += f"; {md_text(m['kind'])} at {_g(m['frequency_hz'], 4)} Hz, damping {_g(m['damping'], 2)}"
            if fr.get("delay_samples") is not None:
                text += f"; input delay {_g(fr['delay_samples'], 2)} samples"
            L += ["", text + "."]
    shown = [f for f in figures if f in _IDENT_CAPTIONS]
    if shown:
        no_legs = not model.get("steady_points")
        for f in shown:
            caption = _IDENT_CAPTIONS[f"{f}/no legs" if no_legs and f"{f}/no legs" in _IDENT_CAPTIONS else f]
            L += ["", f"![{f}]({f})", "", caption]
    else:
        L += ["", "Identification figures: `commission identify LOG --plot DIR` (`commission run` writes them "
                  "beside this report)."]
    L.append("")
    return L


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
        pe_text = ", ".join(f"{n.split('/')[0]} {_g(v, 2)}" for n, v in pe.items())
        done = [n for n, f in conv.items() if all(not (x < 0.9) for x in f if math.isfinite(x))]
        f1 = [f[0] for f in conv.values() if math.isfinite(f[0])]
        L.append(f"- **Parameter estimates.** theta_hat converges to the plant's theta only under persistent "
                 f"excitation, and only as fast as the tracking error drives the adaptation (19): with the robust "
                 f"feedback holding the error near the encoder step, theta_hat moves slowly. Excitation level of the "
                 f"regressor [u, -q̇_d, 1] over the nominal runs (smallest eigenvalue of its normalised Gram matrix; "
                 f"0 = a direction of theta not excited, 1 = fully): {pe_text}. "
                 + (f"theta_hat closed at least 90 % of its initial error in {len(done)} of {len(conv)} fixed "
                    f"scenarios ({', '.join(done)}). " if done else
                    f"theta_hat did not converge in any fixed scenario within its run (closed 90 % of its initial "
                    f"error in none); ")
                 + (f"theta_hat_1 closed between {_g(min(f1) * 100, 2)} % and {_g(max(f1) * 100, 2)} % of its initial "
                    f"error. " if f1 else "")
                 + "The figure theta_hat.png shows what this trajectory does in its duration, not the limit; the "
                   "gate judges tracking, which does not need theta_hat = theta.")
    lc = pid_limit_cycle(result)
    if lc:
        unit = result.units.get("u", "u")
        worst = max(lc.items(), key=lambda kv: kv[1][0])
        L.append(f"- **The PID baseline hunts at standstill** in {len(lc)} scenario(s) ({', '.join(sorted(lc))}): "
                 f"in the dwells its error swings ±{_g(worst[1][0] * 1e6, 2)} {unit_of('small', result.units)} with a ±{_g(worst[1][1], 2)} {unit} "
                 f"command ({worst[0]}), a limit cycle of the integrator against stiction. It inflates the PID's e_F "
                 f"and e_rms there, so the ARC/PID ratios of those scenarios flatter the ARC.")
    fixed = [r for r in result.runs if "monte_carlo" not in r.tags and "robustness" not in r.tags
             and not r.arc.diverged and not r.pid.diverged and r.pid.c_u > 0]
    if fixed:
        ratio = max(fixed, key=lambda r: r.arc.c_u / r.pid.c_u)
        k = ratio.arc.c_u / ratio.pid.c_u
        if k > 1.0:
            lim = getattr(result.verdict.limits, "c_u", None)
            L.append(f"- **Chattering.** The ARC's c_u is up to {_g(k, 2)}× the PID's ({ratio.name}: "
                     f"{_g(ratio.arc.c_u, 2)} against {_g(ratio.pid.c_u, 2)}): its nonlinear robust gains (K1 up to "
                     f"k1s_max = {_g(result.arc_gains.k1s_max, 3)}, K2 up to k2s_max = {_g(result.arc_gains.k2s_max, 3)} "
                     f"1/s) pass the encoder's quantisation to the command at a higher gain than the PID's. "
                     + (f"The gate bounds it at c_u ≤ {_g(lim, 2)} on every scenario; " if lim is not None else "")
                     + "look at control_input.png before deploying on a drive that dislikes fast command steps.")
    if len(L) == 2:
        return []
    L.append("")
    return L


def report_markdown(result: Any, tuning: Tuning, *, figures: Sequence[str] = (),
                    sources: Mapping[str, str | None] | None = None, tuning_sha256: str | None = None) -> str:
    """The whole report.md.

    Parameters
    ----------
    result : ValidationResult
    tuning : Tuning
    figures : sequence of str
        PNG file names in the report's folder.
    sources : mapping
        ``{"tuning": path, "gate": path or None}`` as given on the command line.
    tuning_sha256 : str, optional
        sha256 of the tuning.json validated.

    Every unit is the axis's (``result.units``: m or rad, :mod:`commission.units`).
    """
    with axis_units_context(result.units.get("q", "m")):
        return _report_markdown(result, tuning, figures=figures, sources=sources, tuning_sha256=tuning_sha256)


def evidence_markdown(result: Any, tuning: Tuning) -> list[str]:
    """The report's first lines on what the certificate rests on (:mod:`commission.evidence`).

    The band the log backs, the robust-stability peak of each loop above it, and the
    ``commission excite`` command with a limits.toml sketch that would raise it.
    """
    from commission.evidence import evidence_lines, excite_command, limits_toml

    ev = getattr(result, "evidence", None)
    if ev is None:
        return []
    lines = evidence_lines(ev, getattr(result, "evidence_rows", ()))
    out = [f"**Evidence.** {md_text(lines[0][len('evidence: '):])}", ""]
    out += [f"- {md_text(x)}" for x in lines[1:]]
    if ev.source != "broadband" or not all(r.holds for r in getattr(result, "evidence_rows", ())):
        out += ["", f"To raise it, record the run that `{excite_command()}` plans (a broadband injection "
                "while the axis moves slowly), with this `limits.toml` (the spec's envelope and the log's "
                "rate; check the holding loop's `bandwidth_hz`, an assumption):", "", "```toml",
                limits_toml(tuning.spec, tuning.identification).rstrip("\n"), "```"]
    out.append("")
    return out


def _search_miss_lines(tuning: Tuning) -> list[str]:
    """The search's own refusal, said before the failed checks when it found nothing feasible
    (:func:`commission.gate.search_infeasible_line`; none when it did)."""
    miss = search_infeasible_line(tuning.search)
    return [] if miss is None else [f"**{md_text(miss)}**", ""]


def _report_markdown(result: Any, tuning: Tuning, *, figures: Sequence[str],
                     sources: Mapping[str, str | None] | None, tuning_sha256: str | None) -> str:
    sources = sources or {}
    unit = result.units.get("u", "u")
    ident = tuning.identification
    spec = tuning.spec
    v = result.verdict
    nfix = sum(1 for r in result.runs if "monte_carlo" not in r.tags)
    L: list[str] = []
    L.append("# Validation report")
    L.append("")
    status = "PASSED" if v.passed else "FAILED"
    L.append(f"**Gate: {status}** -- {len(v.checks)} checks on {len(result.runs)} scenarios "
             f"({nfix} fixed + {result.n_monte_carlo} Monte-Carlo plants), ARC and PID baseline.")
    L.append("")
    L.extend(validity_lines(result if getattr(result, "validity", None) else tuning))
    L.extend(evidence_markdown(result, tuning))
    if v.passed:
        L.append("`controller.json` was written next to this report; load it with "
                 "`commission.runtime.load_controller`.")
    elif safe_not_better(v):
        L.extend(_search_miss_lines(tuning))
        L.extend(not_better_lines(result, tuning, markdown=True))
        L.append("")
        for line in failure_lines(v):
            L.append(f"- {line}")
    else:
        L.extend(_search_miss_lines(tuning))
        from commission.evidence import evidence_limited_line  # evidence imports this module's helpers

        missing = evidence_limited_line(result)
        if missing is not None:
            L.extend([f"**{md_text(missing)}**", ""])
        L.append(f"**No `controller.json` was written.** {len(v.failures)} checks failed:")
        L.append("")
        for line in failure_lines(v):
            L.append(f"- {line}")
    L.append("")
    L.extend(next_steps(result, tuning, tuning_path=sources.get("tuning") or "tuning.json").markdown())
    L.append("## Axis and controller")
    L.append("")
    L.append(f"- tuning: {md_code(sources.get('tuning') or 'tuning.json')}; gate: {md_code(sources.get('gate') or 'defaults')}")
    L.append(f"- identified model: see Identification below; theta box min {_vec(ident.theta.min)}, "
             f"max {_vec(ident.theta.max)}, nominal {_vec(ident.theta.nominal)}; delta_d = {_g(ident.delta_d)} "
             f"{unit_of('a')}")
    bounds = ident.extra.get("bounds")
    narrowed = bounds.get("narrowed_by_tune") if isinstance(bounds, dict) else None
    if isinstance(narrowed, dict) and all(isinstance(narrowed.get(k), (int, float))
                                          for k in ("theta3_min", "theta3_max", "u_max")):
        lo, hi = narrowed["theta3_min"], narrowed["theta3_max"]
        L.append(f"- **theta3 narrowed by tune** from [{lo:.4g}, {hi:.4g}] {unit_of('a')}: identify's defaulted load-force "
                 f"bound left the {narrowed['u_max']:g} {unit} drive no room for any envelope; loads outside the box above were not validated "
                 f"(state the real one with `commission identify --disturbance-bound`)")
    L.append(f"- sample rate {nominal(spec.sample_rate, '{:g}')} Hz; encoder resolution "
             f"{result.quantization * 1e6:.3g} {unit_of('small')}; "
             f"actuator limit {spec.u_max:g} {unit}; plant sub-steps per sample {result.to_dict()['simulation']['substeps']}")
    # not v: that is the verdict, used below
    uq, uv, ua = unit_of("q"), unit_of("v"), unit_of("a")
    if spec.profile is None:
        L.append(f"- envelope: travel {spec.travel:g} {uq}, v_max {spec.v_max:g} {uv}, a_max {spec.a_max:g} {ua} "
                 f"(Case 1 and Case 2 scaled to it); abort when |q - q_d| > {result.e_abort:g} {uq}")
    else:
        L.append(f"- envelope from the machine's moves ({md_text(spec.profile.describe())}): travel {spec.travel:g} {uq}, "
                 f"v_max {spec.v_max:g} {uv}, a_max {spec.a_max:g} {ua} (the runtime guard's and the gate's; not "
                 f"derived from u_max); the paper's Case 1 and Case 2 as reference scenarios at v_max "
                 f"{spec.case_v_max:.4g} {uv}, a_max {spec.case_a_max:.4g} {ua}; abort when |q - q_d| > "
                 f"{result.e_abort:g} {uq}")
    g = result.arc_gains
    L.append(f"- ARC: observer k1 = {_g(g.k1)} 1/s, k2 = {_g(g.k2)} 1/s^2; g1 = {_g(g.g1)} 1/s, g2 = {_g(g.g2)} 1/s, "
             f"k1s_max = {_g(g.k1s_max)} 1/s, k2s_max = {_g(g.k2s_max)} 1/s; Gamma = {_vec(g.Gamma, 3)} "
             f"(adaptation rates of (19): theta_i's unit per unit of tau_i, per s); "
             f"theta0 = {_vec(g.theta0)} [{unit_of('theta1', result.units)}, 1/s, {unit_of('a')}]; "
             f"u_max = {g.u_max:g} {unit}")
    p = tuning.pid
    q = unit_of("q")
    L.append(f"- PID baseline (57): Kp = {p.Kp:.4g} {unit}/{q}, Ki = {p.Ki:.4g} {unit}/({q}·s), "
             f"Kd = {p.Kd:.4g} {unit}·s/{q}, M_hat = {p.M_hat:.4g} {unit}·s²/{q}, B_hat = {p.B_hat:.4g} {unit}·s/{q}")
    L.extend(yardstick_lines(tuning))
    for note in horizon_notes(spec):
        L.append(f"- horizon: {note}")
    L.append("")
    L.extend(identification_markdown(tuning, figures))
    L.extend(discussion_markdown(result, tuning))
    L.extend(margins_markdown(result, tuning))
    rl = robustness_lines(result)
    if rl:
        L.append("**Robustness.** The gate's criteria on the robustness scenarios (one more sample "
                 "of input delay than identified; with a mode, its frequency x0.8 and x1.2 and half its damping) "
                 "and the ARC's margins on the identified plant and over the whole theta box, required like every "
                 "other check (no divergence "
                 "and the spec's margin floors whatever gate.toml says): " + rl[0])
        L.append("")
    L.append("## Gate")
    L.append("")
    L.append("Every criterion is checked for the ARC on every scenario; errors are measured on the encoder "
             "(e = y - q_d).")
    L.append("")
    L.append(gate_table_markdown(v))
    L.append("")
    L.append("## Performance indexes (layout of Table 1 of Xu & Yao 2001)")
    L.append("")
    L.append("e_M = max |e|, e_F = max |e| over the last 2 s, ‖e‖rms and ‖u‖rms over the run, "
             "‖Δu‖rms = rms of the input increments (eq. 54), c_u = ‖Δu‖rms / ‖u‖rms.")
    for case in case_names(spec):
        L.append("")
        L.append(f"### {_CASE_TITLE[case]}")
        L.append("")
        L.append(table1_markdown(result, case, unit))
    mc = monte_carlo_summary(result)
    if mc["n"]:
        L.append("")
        L.append(f"### Monte-Carlo plants ({mc['n']}, theta uniform in the box, seed {result.seed})")
        L.append("")
        L.append("| | ARC median | ARC worst | PID median | PID worst |")
        L.append("|---|---:|---:|---:|---:|")
        small = unit_of("small")
        for key, label, scale in (("e_M", f"e_M ({small})", 1e6), ("e_F", f"e_F ({small})", 1e6),
                                  ("e_rms", f"‖e‖rms ({small})", 1e6), ("c_u", "c_u", 1.0),
                                  ("u_peak", f"peak command ({unit})", 1.0)):
            a, b = mc["arc"][key], mc["pid"][key]
            L.append(f"| {label} | {_fmt(a[0], '{:.3g}', scale)} | {_fmt(a[1], '{:.3g}', scale)} | "
                     f"{_fmt(b[0], '{:.3g}', scale)} | {_fmt(b[1], '{:.3g}', scale)} |")
        L.append(f"| diverged | {mc['arc']['diverged']} | | {mc['pid']['diverged']} | |")
        L.append("")
        L.append(f"ARC e_rms no worse than PID on {mc['arc_better']} of {mc['n']} plants.")
    L.append("")
    L.append("## Parameter estimates at the end of each fixed scenario")
    L.append("")
    L.append("theta = [1/M, B/M, d_n/M]; 'plant' is the scenario's [1/M, B/M, -offset/M] (friction not included, "
             "so theta_3 also absorbs the friction-compensation error).")
    L.append("")
    L.append(f"Units: theta_1 {ident.units.get('q', 'm')}/({unit}·s²), theta_2 1/s, theta_3 {ident.units.get('q', 'm')}/s².")
    L.append("")
    L.append("| Scenario | theta_hat_1 | plant | theta_hat_2 | plant | theta_hat_3 | plant |")
    L.append("|---|---:|---:|---:|---:|---:|---:|")
    for r in result.runs:
        if "monte_carlo" in r.tags:
            continue
        cells = []
        for i in range(3):
            cells += [_fmt(r.theta_final[i] + 0.0, "{:.4g}", 1.0), f"{r.theta_true[i] + 0.0:.4g}"]
        L.append(f"| {r.name} | " + " | ".join(cells) + " |")
    figures = [f for f in figures if f not in _IDENT_CAPTIONS]
    if figures:
        L.append("")
        L.append("## Figures")
        captions = {
            "tracking_case1.png": "Tracking errors, ARC vs PID, Case 1 scenarios (as the paper's Figs. 2-4); "
                                  "every axis holds both controllers' peaks (a symmetric-log axis where one is "
                                  "more than 20 times the other).",
            "tracking_user.png": "Desired trajectory and tracking errors, ARC vs PID, on the machine's own moves "
                                 "(the user/... scenarios).",
            "tracking_case2.png": "Desired trajectory and tracking errors, ARC vs PID, Case 2 scenarios "
                                  "(as the paper's Figs. 5-6).",
            "theta_hat.png": "The ARC's parameter estimates theta_hat on every fixed scenario of each case (dashed: "
                             "the plant's values; grey: the theta box). They converge only under persistent "
                             "excitation: see 'Reading the results'.",
            "control_input.png": "Control input u of ARC and PID on the nominal scenarios.",
            "monte_carlo.png": "e_rms of ARC against PID on every scenario (below the diagonal: ARC better).",
            "loops.png": "Loop transfers L = -K P of ARC and PID on the identified plant (mode and delay "
                         "included): Bode magnitude and phase, and the Nyquist curves near -1 with the "
                         "modulus-margin circle.",
        }
        for f in figures:
            L.append("")
            L.append(f"![{f}]({f})")
            L.append("")
            L.append(captions.get(f, f))
    L.append("")
    L.append("## Provenance")
    L.append("")
    pv = tuning.provenance
    L.append(f"- excitation log sha256: {log_sha256_of(tuning) or 'not recorded'}")
    L.append(f"- ident.json sha256: {pv.ident_sha256}")
    if tuning_sha256:
        L.append(f"- tuning.json sha256: {tuning_sha256}")
    L.append(f"- tuning created {md_text(pv.created_utc)} by commission {md_text(pv.tool_version)} (seed {pv.seed})")
    L.append(f"- validation: {len(result.runs) * 2} simulations in {result.elapsed:.1f} s on {result.workers} threads; "
             f"Monte-Carlo seed {result.seed}")
    L.append("")
    return "\n".join(L)


def summary_rows(result: Any) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the stdout summary: each fixed scenario, then the Monte-Carlo aggregate."""
    s_, u_ = unit_of("small", result.units), result.units.get("u", "u-unit")
    head = ["scenario", f"ARC e_M {s_}", f"ARC e_F {s_}", f"ARC e_rms {s_}", "ARC c_u", f"ARC peak|u| {u_}",
            f"PID e_rms {s_}", "gate"]
    failed = {c.scenario for c in result.verdict.failures}
    rows: list[list[str]] = []

    def s(score: Score, key: str, scale: float, fmt: str) -> str:
        return _cell(score, key, scale, fmt)

    for r in result.runs:
        if "monte_carlo" in r.tags:
            continue
        rows.append([r.name, s(r.arc, "e_M", 1e6, "{:.3g}"), s(r.arc, "e_F", 1e6, "{:.3g}"),
                     s(r.arc, "e_rms", 1e6, "{:.3g}"), s(r.arc, "c_u", 1.0, "{:.2f}"),
                     _fmt(r.arc.u_peak, "{:.3g}", 1.0), s(r.pid, "e_rms", 1e6, "{:.3g}"),
                     ("FAIL" if r.name in failed else "ok")])
    mc = [r for r in result.runs if "monte_carlo" in r.tags]
    if mc:
        def worst(ctrl: str, key: str) -> float:
            vals = [getattr(getattr(r, ctrl), key) for r in mc if not getattr(r, ctrl).diverged]
            vals = [x for x in vals if math.isfinite(x)]
            return max(vals) if vals else math.nan
        nfail = sum(1 for r in mc if r.name in failed)
        ndiv = sum(1 for r in mc if r.arc.diverged)
        rows.append([f"mc worst of {len(mc)}" + (f" ({ndiv} diverged)" if ndiv else ""),
                     _fmt(worst("arc", "e_M"), "{:.3g}", 1e6), _fmt(worst("arc", "e_F"), "{:.3g}", 1e6),
                     _fmt(worst("arc", "e_rms"), "{:.3g}", 1e6), _fmt(worst("arc", "c_u"), "{:.2f}", 1.0),
                     _fmt(worst("arc", "u_peak"), "{:.3g}", 1.0), _fmt(worst("pid", "e_rms"), "{:.3g}", 1e6),
                     f"FAIL ({nfail})" if nfail else "ok"])
    return head, rows


def summary_text(result: Any) -> str:
    """Plain-text stdout summary: the scenario table, then the verdict and every failure."""
    head, rows = summary_rows(result)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    lines = ["  ".join(h.rjust(w) if i else h.ljust(w) for i, (h, w) in enumerate(zip(head, widths)))]
    for r in rows:
        lines.append("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))))
    lines.append(verdict_text(result))
    return "\n".join(lines)


def yardstick_lines(tuning: Tuning) -> list[str]:
    """The report's line on how the PID yardstick was chosen (tuning.json ``pid_yardstick``; none in older files)."""
    ys = tuning.pid_yardstick
    if not ys:
        return []
    m = ys.get("margins", {})

    def g(k: str, fmt: str) -> str:
        v = m.get(k)
        return "inf" if v is None else fmt.format(v)

    how = {"margin_search": f"the fastest of {ys.get('candidates')} poles of (57) ({ys.get('admissible')} admissible) "
                            "that keeps the spec's margin floors on the identified plant, is stable with one more "
                            "sample of delay and stays within the gate's c_u",
           "spec_pole": "the spec's [pid] pole (the paper's formula (57))",
           "none_admissible": "no pole of (57) keeps the margin floors on the identified plant: the paper's "
                              "default pole"}.get(str(ys.get("method")), str(ys.get("method")))
    flag = "" if ys.get("is_yardstick") else (" -- **not a fair yardstick**: " + "; ".join(ys.get("violations", [])))
    return [f"- PID yardstick: {how}; pole {tuning.pid_pole:.4g} rad/s, crossover {g('crossover_hz', '{:.3g}')} Hz, "
            f"gain margin {g('gain_margin_db', '{:.3g}')} dB, phase margin {g('phase_margin_deg', '{:.3g}')} deg, "
            f"delay margin {g('delay_margin_samples', '{:.3g}')} samples, modulus margin "
            f"{g('modulus_margin', '{:.3g}')}, spectral radius with +1 sample "
            f"{float(ys.get('radius_plus_one_sample', float('nan'))):.4f}{flag}"]


def not_better_lines(result: Any, tuning: Tuning, *, markdown: bool = False) -> list[str]:
    """What a safe ARC that does not beat the PID yardstick leaves the user (:func:`commission.gate.safe_not_better`).

    Two sentences: the verdict in plain words, and the two deployable choices (the flagged ARC,
    ``controller_not_better.json``, and the validated PID yardstick through ``commission export
    --controller pid``).
    """
    p = tuning.pid
    unit = result.units.get("u", "u")
    q = unit_of("q", result.units)  # called outside the report's units context too (the CLI)
    b = "**" if markdown else ""
    code = (lambda x: f"`{x}`") if markdown else (lambda x: x)
    ys = tuning.pid_yardstick or {}
    how = ("the fastest PID of (57) that keeps the margin floors on the identified plant and +1 sample"
           if ys.get("method") == "margin_search" else "the PID of (57) at the spec's pole")
    return [
        f"{b}Safe, but not better than the PID yardstick.{b} The ARC held every floor and every limit "
        f"(no divergence, c_u, peak command and stability margins on every scenario; the error limits on the "
        f"identified plant and the ranges the user stated); it failed only the "
        f"comparison with the PID yardstick ({how}, pole {tuning.pid_pole:.4g} rad/s). No "
        f"{code('controller.json')} was written (exit code 1).",
        f"Deployable instead: the ARC, flagged (validated.flag.beats_yardstick = false), in "
        f"{code('controller_not_better.json')} (loads with {code('commission.runtime.load_controller')}); or the "
        f"validated PID yardstick, Kp = {p.Kp:.4g} {unit}/{q}, Ki = {p.Ki:.4g} {unit}/({q}·s), Kd = {p.Kd:.4g} "
        f"{unit}·s/{q} with M_hat = {p.M_hat:.4g}, B_hat = {p.B_hat:.4g}, exported by "
        f"{code('commission export controller_not_better.json --controller pid --tuning tuning.json --target c --out-dir DIR')}.",
    ]


def refusal_lines(result: Any, tuning: Tuning) -> list[str]:
    """What stdout says after a failed gate, before pointing at report.md: "safe but not better" with
    the deployable choices (:func:`not_better_lines`), the search's own refusal
    (:func:`commission.gate.search_infeasible_line`) and a refusal for want of evidence
    (:func:`commission.evidence.evidence_limited_line`), each when it applies."""
    from commission.evidence import evidence_limited_line  # evidence imports this module's helpers

    out = not_better_lines(result, tuning) if safe_not_better(result.verdict) else []
    out += [x for x in (search_infeasible_line(tuning.search), evidence_limited_line(result)) if x is not None]
    return out


def verdict_text(result: Any, tuning: Tuning | None = None) -> str:
    """``gate PASSED`` or ``gate FAILED: N checks`` followed by one line per failure."""
    v = result.verdict
    n = len(result.runs)
    if v.passed:
        lines = [f"gate PASSED ({len(v.checks)} checks on {n} scenarios)"]
    else:
        lines = [f"gate FAILED: {len(v.failures)} of {len(v.checks)} checks on {n} scenarios"]
        if safe_not_better(v) and tuning is not None:
            lines += not_better_lines(result, tuning)
        lines += [f"  {line}" for line in failure_lines(v)]
    lines += robustness_lines(result)
    return "\n".join(lines)


def validity_lines(tuning: Any) -> list[str]:
    """The report's first lines on a payload range that tune narrowed (``tuning.validity``), else none."""
    v = getattr(tuning, "validity", None)
    if not v:
        return []
    lo, hi = v["payload_range"]
    dlo, dhi = v.get("default_payload_range", [lo, hi])
    moving = "inertia" if str(v["unit"]).endswith("/rad") else "moving mass"
    return [f"**Certified for payloads {lo:.4g} to {hi:.4g} {v['unit']} only** ({moving} up to "
            f"{v['mass_range'][1]:.4g} {v['unit']}), not the default {dlo:.4g} to {dhi:.4g} {v['unit']}: "
            f"{md_text(v.get('reason', ''))}. `controller.json` states this range under `validity`; state the "
            f"real payload with `commission identify --payload-max` (a range these gains do not hold is then refused).",
            ""]


def robustness_lines(result: Any) -> list[str]:
    """The robustness part of the verdict (robustness scenarios and margins), one summary line."""
    rob = getattr(result, "robustness", None)
    if rob is None:
        return []
    what = "one more sample of delay, the mode's variants, stability margins, the whole theta box"
    if rob.passed:
        return [f"robustness PASSED ({len(rob.checks)} checks: {what})"]
    return [f"robustness FAILED: {len(rob.failures)} of {len(rob.checks)} checks ({what}; listed above)"]
