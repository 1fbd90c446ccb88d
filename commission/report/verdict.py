"""The verdict in words: the stdout summary and the lines both stdout and the report open with.

The scenario table and the verdict of ``commission validate`` / ``run`` (:func:`summary_text`,
:func:`verdict_text`), the failed checks (:func:`failure_lines`), what stdout says after a
refusal (:func:`refusal_lines`: "safe but not better" with the deployable choices, the search's
own refusal, a refusal for want of evidence), the payload range tune narrowed
(:func:`validity_lines`) and the robustness summary line (:func:`robustness_lines`).
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping

from commission.evidence import evidence_limited_line, excite_command
from commission.gate import BEYOND_EVIDENCE, safe_not_better, search_infeasible_line
from commission.controllers.metrics import INDEX_ROWS
from commission.report.text import index_cell, md_text, scaled
from commission.tuning import Tuning
from commission.units import unit as unit_of

#: The ARC's indexes in the stdout summary, in its column order (then its peak command and the PID's e_rms).
_SUMMARY_ARC = ("e_M", "e_F", "e_rms", "c_u")


def failure_lines(verdict: Any) -> list[str]:
    """Every failed check as ``criterion  scenario: detail``."""
    return [f"{c.criterion} {c.scenario}: {c.detail}" for c in verdict.failures]


def summary_rows(result: Any) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the stdout summary: each fixed scenario, then the Monte-Carlo aggregate."""
    s_, u_ = unit_of("small", result.units), result.units.get("u", "u-unit")
    head = ["scenario", f"ARC e_M {s_}", f"ARC e_F {s_}", f"ARC e_rms {s_}", "ARC c_u", f"ARC peak|u| {u_}",
            f"PID e_rms {s_}", "gate"]
    failed = {c.scenario for c in result.verdict.failures}
    rows: list[list[str]] = []

    def shown(value: float, key: str) -> str:
        return scaled(value, INDEX_ROWS[key].fmt, INDEX_ROWS[key].scale)

    for r in result.runs:
        if "monte_carlo" in r.tags:
            continue
        rows.append([r.name, *(index_cell(r.arc, k) for k in _SUMMARY_ARC), shown(r.arc.u_peak, "u_peak"),
                     index_cell(r.pid, "e_rms"), ("FAIL" if r.name in failed else "ok")])
    mc = [r for r in result.runs if "monte_carlo" in r.tags]
    if mc:
        def worst(ctrl: str, key: str) -> str:
            vals = [getattr(getattr(r, ctrl), key) for r in mc if not getattr(r, ctrl).diverged]
            vals = [x for x in vals if math.isfinite(x)]
            return shown(max(vals) if vals else math.nan, key)
        nfail = sum(1 for r in mc if r.name in failed)
        ndiv = sum(1 for r in mc if r.arc.diverged)
        rows.append([f"mc worst of {len(mc)}" + (f" ({ndiv} diverged)" if ndiv else ""),
                     *(worst("arc", k) for k in (*_SUMMARY_ARC, "u_peak")), worst("pid", "e_rms"),
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
    ] + _beyond_evidence_lines(result, ys, code, b)


def _beyond_evidence_lines(result: Any, ys: Mapping[str, Any], code: Callable[[str], str], b: str) -> list[str]:
    """The sentence for an ARC that lost to the PID beyond the evidence (:func:`lost_beyond_evidence`):
    what held it, and the recording that lifts it."""
    lost = lost_beyond_evidence(result)
    ub = ys.get("unbacked_pid") or {}
    if not lost or not ub:
        return []
    ev = getattr(result, "evidence", None)
    band = f"the log backs the model only up to {ev.top_hz:.3g} Hz" if ev is not None and ev.applies else \
        "the log backs only part of the band"
    return [f"{b}Missing evidence:{b} {band}, and the yardstick was slowed to that band. The identified plant admits "
            f"a PID at pole {float(ub['pole']):.4g} rad/s beyond it, the one a drive's auto-tuner would deliver, and "
            f"the ARC, held within the evidence, does not beat it on the identified plant "
            f"({', '.join(c.scenario for c in lost)}). To certify a faster ARC, record the run "
            f"{code(excite_command())} plans, and run again on that log."]


def lost_beyond_evidence(result: Any) -> list[Any]:
    """The failed ``<case>/beyond_evidence`` checks of a validation (:func:`commission.gate.arc_vs_pid_nominal_checks`)."""
    return [c for c in result.verdict.failures if c.scenario.endswith("/" + BEYOND_EVIDENCE)]


def refusal_lines(result: Any, tuning: Tuning) -> list[str]:
    """What stdout says after a failed gate, before pointing at report.md: "safe but not better" with
    the deployable choices (:func:`not_better_lines`), the search's own refusal
    (:func:`commission.gate.search_infeasible_line`) and a refusal for want of evidence
    (:func:`commission.evidence.evidence_limited_line`), each when it applies."""
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
    if hi > lo:
        what = f"for payloads {lo:.4g} to {hi:.4g} {v['unit']}"
    else:  # run's second try (commission.tune.box.as_identified_box)
        what = "for the axis as identified (no payload)" if lo == 0 else f"for a payload of {lo:.4g} {v['unit']}"
    return [f"**Certified {what} only** ({moving} up to "
            f"{v['mass_range'][1]:.4g} {v['unit']}), not the default {dlo:.4g} to {dhi:.4g} {v['unit']}: "
            f"{md_text(v.get('reason', ''))}. `controller.json` states this range under `validity`; state the "
            f"real payload with `commission identify --payload-max` (a range these gains do not hold is then refused).",
            ""]


def unseen_stribeck_checked(checks: Any) -> bool:
    """Whether ``checks`` (a verdict's) include the ``<case>/stribeck`` scenarios of a Coulomb-only fit."""
    return any(str(getattr(c, "scenario", "")).endswith("/stribeck") for c in checks)


def robustness_lines(result: Any) -> list[str]:
    """The robustness part of the verdict (robustness scenarios and margins), one summary line."""
    rob = getattr(result, "robustness", None)
    if rob is None:
        return []
    what = "one more sample of delay, the mode's variants, stability margins, the whole theta box"
    if unseen_stribeck_checked(rob.checks):
        what = "one more sample of delay, the Stribeck rise the log did not resolve, the mode's variants, " \
               "stability margins, the whole theta box"
    if rob.passed:
        return [f"robustness PASSED ({len(rob.checks)} checks: {what})"]
    return [f"robustness FAILED: {len(rob.failures)} of {len(rob.checks)} checks ({what}; listed above)"]
