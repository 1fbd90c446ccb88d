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

from commission.gate import CRITERIA
from commission.robustness import floor_violations
from commission.scenarios import CASES, VARIANTS, plant_dynamics
from commission.tuning import Score, Tuning, log_sha256_of

#: Row label, Score field, scale, format (Table 1 of the paper).
TABLE1_ROWS = (
    ("e_M (um)", "e_M", 1e6, "{:.3g}"),
    ("e_F (um)", "e_F", 1e6, "{:.3g}"),
    ("‖e‖rms (um)", "e_rms", 1e6, "{:.3g}"),
    ("‖u‖rms ({u})", "u_rms", 1.0, "{:.3g}"),
    ("‖Δu‖rms ({u})", "du_rms", 1.0, "{:.3g}"),
    ("c_u", "c_u", 1.0, "{:.2f}"),
)
_CASE_TITLE = {"case1": "Case 1 (sinusoid through filter (58))", "case2": "Case 2 (back-and-forth point-to-point moves)"}
_CRITERION_TEXT = {
    "divergence": "no divergence",
    "e_F": "e_F (final accuracy, last 2 s)",
    "e_M": "e_M (largest error)",
    "e_rms": "‖e‖rms",
    "c_u": "c_u (chattering)",
    "u_peak": "peak command below u_max",
    "arc_vs_pid_e_rms": "ARC ‖e‖rms / PID ‖e‖rms",
    "margins": "ARC stability margins, identified plant (floor / margin)",
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
        lines.append(f"| {label.format(u=unit)} | " + " | ".join(cells) + " |")
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
        return f"{getattr(limits, key) * 1e6:.3g} um"
    if key == "c_u":
        return f"{limits.c_u:.3g}"
    if key == "u_peak":
        return f"{limits.u_max:.4g}"
    if key == "margins":
        return "1 (every floor met)"
    slack = getattr(limits, "arc_vs_pid_slack", 0.0)
    return f"{limits.arc_vs_pid_e_rms:.3g} x PID" + (f" + {slack * 1e6:.3g} um" if slack > 0 else "")


def _basis_key(key: str) -> str:
    return {"divergence": "no_divergence", "u_peak": "u_max"}.get(key, key)


def _basis_text(key: str, limits: Any) -> str:
    if key == "margins":
        return "spec.toml [margins]"
    return limits.basis.get(_basis_key(key), "")


def _value_text(c: Any) -> str:
    if c.criterion == "divergence":
        return "none" if c.passed else f"at t = {c.value:.4g} s"
    if c.criterion in ("e_F", "e_M", "e_rms"):
        return f"{c.value * 1e6:.3g} um" if math.isfinite(c.value) else "n/a (diverged)"
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
                 f"{'yes' if m.stable else '**no**'} | {'met' if not miss else '**' + '; '.join(miss) + '**'} |")
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
    """
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
    if v.passed:
        L.append("`controller.json` was written next to this report; load it with "
                 "`commission.runtime.load_controller`.")
    else:
        L.append(f"**No `controller.json` was written.** {len(v.failures)} checks failed:")
        L.append("")
        for line in failure_lines(v):
            L.append(f"- {line}")
    L.append("")
    L.append("## Axis and controller")
    L.append("")
    L.append(f"- tuning: `{sources.get('tuning') or 'tuning.json'}`; gate: `{sources.get('gate') or 'defaults'}`")
    par = ", ".join(f"{k} = {e.value:.4g}" for k, e in ident.parameters.items() if e is not None)
    L.append(f"- identified model ({unit}, m, s): {par}")
    L.append(f"- theta box: min {list(ident.theta.min)}, max {list(ident.theta.max)}, "
             f"nominal {list(ident.theta.nominal)}; delta_d = {ident.delta_d:.4g} m/s^2")
    bounds = ident.extra.get("bounds")
    narrowed = bounds.get("narrowed_by_tune") if isinstance(bounds, dict) else None
    if isinstance(narrowed, dict) and all(isinstance(narrowed.get(k), (int, float))
                                          for k in ("theta3_min", "theta3_max", "u_max")):
        lo, hi = narrowed["theta3_min"], narrowed["theta3_max"]
        L.append(f"- **theta3 narrowed by tune** from [{lo:.4g}, {hi:.4g}] m/s^2: identify's defaulted load-force "
                 f"bound left the {narrowed['u_max']:g} {unit} drive no room for any envelope; loads outside the box above were not validated "
                 f"(state the real one with `commission identify --disturbance-bound`)")
    L.append(f"- sample rate {spec.sample_rate:g} Hz; encoder resolution {result.quantization * 1e6:.3g} um; "
             f"actuator limit {spec.u_max:g} {unit}; plant sub-steps per sample {result.to_dict()['simulation']['substeps']}")
    L.append(f"- envelope: travel {spec.travel:g} m, v_max {spec.v_max:g} m/s, a_max {spec.a_max:g} m/s^2 "
             f"(Case 1 and Case 2 scaled to it); abort when |q - q_d| > {result.e_abort:g} m")
    g = result.arc_gains
    L.append(f"- ARC: k1 = {g.k1:.4g}, k2 = {g.k2:.4g}, g1 = {g.g1:.4g}, g2 = {g.g2:.4g}, "
             f"k1s_max = {g.k1s_max:.4g}, k2s_max = {g.k2s_max:.4g}, Gamma = {[float(f'{x:.4g}') for x in g.Gamma]}, "
             f"theta0 = {[float(f'{x:.4g}') for x in g.theta0]}, u_max = {g.u_max:g}")
    p = tuning.pid
    L.append(f"- PID baseline (57): Kp = {p.Kp:.4g}, Ki = {p.Ki:.4g}, Kd = {p.Kd:.4g}, M_hat = {p.M_hat:.4g}, "
             f"B_hat = {p.B_hat:.4g}")
    L.append("")
    L.extend(margins_markdown(result, tuning))
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
    for case in CASES:
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
        for key, label, scale in (("e_M", "e_M (um)", 1e6), ("e_F", "e_F (um)", 1e6),
                                  ("e_rms", "‖e‖rms (um)", 1e6), ("c_u", "c_u", 1.0),
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
    L.append("| Scenario | theta_hat_1 | plant | theta_hat_2 | plant | theta_hat_3 | plant |")
    L.append("|---|---:|---:|---:|---:|---:|---:|")
    for r in result.runs:
        if "monte_carlo" in r.tags:
            continue
        cells = []
        for i in range(3):
            cells += [_fmt(r.theta_final[i] + 0.0, "{:.4g}", 1.0), f"{r.theta_true[i] + 0.0:.4g}"]
        L.append(f"| {r.name} | " + " | ".join(cells) + " |")
    if figures:
        L.append("")
        L.append("## Figures")
        captions = {
            "tracking_case1.png": "Tracking errors, ARC vs PID, Case 1 scenarios (as the paper's Figs. 2-4).",
            "tracking_case2.png": "Desired trajectory and tracking errors, ARC vs PID, Case 2 scenarios "
                                  "(as the paper's Figs. 5-6).",
            "theta_hat.png": "Convergence of the ARC parameter estimates theta_hat (dashed: the plant's values).",
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
    L.append(f"- tuning created {pv.created_utc} by commission {pv.tool_version} (seed {pv.seed})")
    L.append(f"- validation: {len(result.runs) * 2} simulations in {result.elapsed:.1f} s on {result.workers} threads; "
             f"Monte-Carlo seed {result.seed}")
    L.append("")
    return "\n".join(L)


def summary_rows(result: Any) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the stdout summary: each fixed scenario, then the Monte-Carlo aggregate."""
    head = ["scenario", "ARC e_M um", "ARC e_F um", "ARC e_rms um", "ARC c_u", "ARC peak|u|", "PID e_rms um", "gate"]
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
                     "FAIL" if r.name in failed else "ok"])
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


def verdict_text(result: Any) -> str:
    """``gate PASSED`` or ``gate FAILED: N checks`` followed by one line per failure."""
    v = result.verdict
    if v.passed:
        return f"gate PASSED ({len(v.checks)} checks on {len(result.runs)} scenarios)"
    lines = [f"gate FAILED: {len(v.failures)} of {len(v.checks)} checks on {len(result.runs)} scenarios"]
    lines += [f"  {line}" for line in failure_lines(v)]
    return "\n".join(lines)
