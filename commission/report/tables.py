"""The report's tables: the indexes in the layout of Table 1 of Xu & Yao (2001), the Monte-Carlo
summary, the parameter estimates at the end of each fixed scenario, and the gate's criteria.

Table 1's layout: one column pair (PID, ARC) per scenario, rows e_M, e_F, ‖e‖rms (um),
‖u‖rms, ‖Δu‖rms (u-unit) and c_u; labels, scales and formats from
:data:`commission.controllers.metrics.INDEX_TABLE`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from commission.controllers.metrics import INDEX_ROWS
from commission.gate import CRITERIA, DEFAULT_ARC_VS_PID_NOMINAL
from commission.report.labels import CRITERION_TEXT, MONTE_CARLO, MONTE_CARLO_FORMAT, TABLE1, index_heading
from commission.report.text import index_cell, scaled
from commission.scenarios.matrix import VARIANTS
from commission.units import unit as unit_of


def table1_markdown(result: Any, case: str, unit: str) -> str:
    """Markdown table of one case in the layout of Table 1 (PID | ARC per scenario)."""
    runs = {r.name: r for r in result.runs}
    names = [f"{case}/{v}" for v in VARIANTS if f"{case}/{v}" in runs]
    head = "| Controller | " + " | ".join(f"{n.split('/')[1]} PID | {n.split('/')[1]} ARC" for n in names) + " |"
    sep = "|---|" + "---:|" * (2 * len(names))
    lines = [head, sep]
    for key in TABLE1:
        cells = [c for n in names for c in (index_cell(runs[n].pid, key), index_cell(runs[n].arc, key))]
        lines.append(f"| {index_heading(key, unit_of('small', result.units), unit)} | " + " | ".join(cells) + " |")
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
        for key in MONTE_CARLO:
            vals = np.array([getattr(s, key) for s in ok], dtype=float)
            vals = vals[np.isfinite(vals)]
            d[key] = (float(np.median(vals)), float(np.max(vals))) if vals.size else (math.nan, math.nan)
        out[ctrl] = d
    out["arc_better"] = sum(1 for r in mc if not r.arc.diverged and (r.pid.diverged or r.arc.e_rms <= r.pid.e_rms))
    return out


def monte_carlo_markdown(result: Any, unit: str) -> list[str]:
    """The Monte-Carlo plants' table (median and worst of ARC and PID, :func:`monte_carlo_summary`); none without them."""
    mc = monte_carlo_summary(result)
    if not mc["n"]:
        return []
    L = ["", f"### Monte-Carlo plants ({mc['n']}, theta uniform in the box, seed {result.seed})", "",
         "| | ARC median | ARC worst | PID median | PID worst |", "|---|---:|---:|---:|---:|"]
    small = unit_of("small")
    for key in MONTE_CARLO:
        cells = [scaled(x, MONTE_CARLO_FORMAT, INDEX_ROWS[key].scale) for ctrl in ("arc", "pid") for x in mc[ctrl][key]]
        L.append(f"| {index_heading(key, small, unit)} | " + " | ".join(cells) + " |")
    L.append(f"| diverged | {mc['arc']['diverged']} | | {mc['pid']['diverged']} | |")
    L.append("")
    L.append(f"ARC e_rms no worse than PID on {mc['arc_better']} of {mc['n']} plants.")
    return L


def theta_estimates_markdown(result: Any, ident: Any, unit: str) -> list[str]:
    """The parameter estimates at the end of each fixed scenario against the plant's theta."""
    q = ident.units.get('q', 'm')
    L = ["## Parameter estimates at the end of each fixed scenario", "",
         "theta = [1/M, B/M, d_n/M]; 'plant' is the scenario's [1/M, B/M, -offset/M] (friction not included, "
         "so theta_3 also absorbs the friction-compensation error).", "",
         f"Units: theta_1 {q}/({unit}·s²), theta_2 1/s, theta_3 {q}/s².", "",
         "| Scenario | theta_hat_1 | plant | theta_hat_2 | plant | theta_hat_3 | plant |",
         "|---|---:|---:|---:|---:|---:|---:|"]
    for r in result.runs:
        if "monte_carlo" in r.tags:
            continue
        cells = []
        for i in range(3):
            cells += [scaled(r.theta_final[i] + 0.0, "{:.4g}", 1.0), f"{r.theta_true[i] + 0.0:.4g}"]
        L.append(f"| {r.name} | " + " | ".join(cells) + " |")
    return L


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
    reported = key in getattr(limits, "comparison_reported", ())
    if key in ("arc_vs_pid_median", "arc_vs_pid_p90"):
        text = f"{getattr(limits, key):.3g}"
        return f"reported (default {text})" if reported else text
    if key == "arc_vs_pid_nominal":
        text = f"below {getattr(limits, key, DEFAULT_ARC_VS_PID_NOMINAL):.3g} (no slack)"
        return f"reported (default {text})" if reported else text
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
        lines.append(f"| {CRITERION_TEXT[key]} | {_limit_text(key, verdict.limits)} | "
                     f"{_basis_text(key, verdict.limits)} | {where} | {_value_text(w)} | "
                     f"{nfail} of {len(checks)} |")
    return "\n".join(lines)
