"""The whole validation report (``report.md``): :func:`report_markdown` and its sections.

No plotting here: the figures are drawn by the CLI (``cli/plots_validate.py``) and only linked
by name.  The report reads, in order: the verdict (:func:`_verdict_section`), the next steps
(:mod:`commission.next_steps`), the axis and both controllers (:func:`_axis_section`), the
identification (:mod:`commission.report.identification`), what the tables do not say
(:mod:`commission.report.discussion`), the stability margins (:mod:`commission.report.margins`),
the robustness summary, the gate's table, the performance indexes in the layout of Table 1 of
Xu & Yao (2001) and the parameter estimates (:mod:`commission.report.tables`), the figures and
the provenance.  Every section builder returns its lines; the report joins them.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from commission.evidence import evidence_limited_line, evidence_lines, excite_command, limits_toml
from commission.gate import safe_not_better, search_infeasible_line
from commission.next_steps import next_steps
from commission.report.discussion import discussion_markdown
from commission.report.identification import identification_markdown
from commission.report.labels import CASE_TITLE, FIGURE_CAPTIONS, IDENT_CAPTIONS
from commission.report.margins import margins_markdown
from commission.report.tables import (gate_table_markdown, monte_carlo_markdown, table1_markdown,
                                      theta_estimates_markdown)
from commission.report.text import md_code, md_text, num, vec
from commission.report.verdict import (failure_lines, lost_beyond_evidence, not_better_lines, robustness_lines, unseen_stribeck_checked,
                                       validity_lines)
from commission.scenarios.matrix import UNSEEN_STRIBECK
from commission.scenarios.trajectories import case_names, horizon_notes
from commission.tuning import Tuning, log_sha256_of
from commission.units import axis_units_context, nominal, unit as unit_of


def report_markdown(result: Any, tuning: Tuning, *, figures: Sequence[str] = (),
                    sources: Mapping[str, str | None] | None = None, tuning_sha256: str | None = None,
                    also_tried: str | None = None) -> str:
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
    also_tried : str, optional
        ``run``'s second try on the axis as identified, failed too (one sentence): the next steps
        say it first and no longer offer a narrower payload box.

    Every unit is the axis's (``result.units``: m or rad, :mod:`commission.units`).
    """
    with axis_units_context(result.units.get("q", "m")):
        return _report_markdown(result, tuning, figures=figures, sources=sources, tuning_sha256=tuning_sha256,
                                also_tried=also_tried)


def evidence_markdown(result: Any, tuning: Tuning) -> list[str]:
    """The report's first lines on what the certificate rests on (:mod:`commission.evidence`).

    The band the log backs, the robust-stability peak of each loop above it, and the
    ``commission excite`` command with a limits.toml sketch that would raise it.
    """
    ev = getattr(result, "evidence", None)
    if ev is None:
        return []
    lines = evidence_lines(ev, getattr(result, "evidence_rows", ()))
    out = [f"**Evidence.** {md_text(lines[0][len('evidence: '):])}", ""]
    out += [f"- {md_text(x)}" for x in lines[1:]]
    if (ev.source != "broadband" or not all(r.holds for r in getattr(result, "evidence_rows", ()))
            or lost_beyond_evidence(result)):
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
                     sources: Mapping[str, str | None] | None, tuning_sha256: str | None,
                     also_tried: str | None = None) -> str:
    sources = sources or {}
    L = _verdict_section(result, tuning)
    L.extend(next_steps(result, tuning, tuning_path=sources.get("tuning") or "tuning.json",
                        also_tried=also_tried).markdown())
    L.extend(_axis_section(result, tuning, sources))
    L.extend(identification_markdown(tuning, figures))
    L.extend(discussion_markdown(result, tuning))
    L.extend(margins_markdown(result, tuning))
    L.extend(_robustness_paragraph(result))
    L.extend(_gate_section(result.verdict))
    L.extend(_indexes_section(result, tuning))
    L.append("")
    L.extend(theta_estimates_markdown(result, tuning.identification, result.units.get("u", "u")))
    L.extend(_figures_section([f for f in figures if f not in IDENT_CAPTIONS]))
    L.append("")
    L.extend(_provenance_section(result, tuning, tuning_sha256))
    return "\n".join(L)


def _verdict_section(result: Any, tuning: Tuning) -> list[str]:
    """The title, the gate's verdict, what the certificate rests on, and what was (not) written and why."""
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
        missing = evidence_limited_line(result)
        if missing is not None:
            L.extend([f"**{md_text(missing)}**", ""])
        L.append(f"**No `controller.json` was written.** {len(v.failures)} checks failed:")
        L.append("")
        for line in failure_lines(v):
            L.append(f"- {line}")
    L.append("")
    return L


def _axis_section(result: Any, tuning: Tuning, sources: Mapping[str, str | None]) -> list[str]:
    """"Axis and controller": the inputs, the identified box, encoder and envelope, both controllers' gains."""
    unit = result.units.get("u", "u")
    ident = tuning.identification
    spec = tuning.spec
    L: list[str] = []
    L.append("## Axis and controller")
    L.append("")
    L.append(f"- tuning: {md_code(sources.get('tuning') or 'tuning.json')}; gate: {md_code(sources.get('gate') or 'defaults')}")
    L.append(f"- identified model: see Identification below; theta box min {vec(ident.theta.min)}, "
             f"max {vec(ident.theta.max)}, nominal {vec(ident.theta.nominal)}; delta_d = {num(ident.delta_d)} "
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
    L.append(f"- ARC: observer k1 = {num(g.k1)} 1/s, k2 = {num(g.k2)} 1/s^2; g1 = {num(g.g1)} 1/s, g2 = {num(g.g2)} 1/s, "
             f"k1s_max = {num(g.k1s_max)} 1/s, k2s_max = {num(g.k2s_max)} 1/s; Gamma = {vec(g.Gamma, 3)} "
             f"(adaptation rates of (19): theta_i's unit per unit of tau_i, per s); "
             f"theta0 = {vec(g.theta0)} [{unit_of('theta1', result.units)}, 1/s, {unit_of('a')}]; "
             f"u_max = {g.u_max:g} {unit}")
    p = tuning.pid
    q = unit_of("q")
    L.append(f"- PID baseline (57): Kp = {p.Kp:.4g} {unit}/{q}, Ki = {p.Ki:.4g} {unit}/({q}·s), "
             f"Kd = {p.Kd:.4g} {unit}·s/{q}, M_hat = {p.M_hat:.4g} {unit}·s²/{q}, B_hat = {p.B_hat:.4g} {unit}·s/{q}")
    L.extend(yardstick_lines(tuning))
    for note in horizon_notes(spec):
        L.append(f"- horizon: {note}")
    L.append("")
    return L


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
    fa = ys.get("fastest_admissible_pole")
    held = (f" (the gate's c_u held it below {float(fa):.4g} rad/s, the fastest pole the floors admit)"
            if fa is not None and float(fa) > tuning.pid_pole * (1 + 1e-9) else "")
    return [f"- PID yardstick: {how}; pole {tuning.pid_pole:.4g} rad/s{held}, crossover "
            f"{g('crossover_hz', '{:.3g}')} Hz, "
            f"gain margin {g('gain_margin_db', '{:.3g}')} dB, phase margin {g('phase_margin_deg', '{:.3g}')} deg, "
            f"delay margin {g('delay_margin_samples', '{:.3g}')} samples, modulus margin "
            f"{g('modulus_margin', '{:.3g}')}, spectral radius with +1 sample "
            f"{float(ys.get('radius_plus_one_sample', float('nan'))):.4f}{flag}", *arc_bandwidth_lines(tuning)]


def arc_bandwidth_lines(tuning: Tuning) -> list[str]:
    """The report's line on the ARC's design bandwidth when its carried-over design was scaled down
    (tuning.json ``search.bandwidth_factor`` < 1, ``search.other_search``); none at the rate-scaled design."""
    se = tuning.search
    bw, other = float(se.bandwidth_factor), se.other_search
    if bw >= 1.0 and not other:
        return []
    line = f"- ARC design bandwidth: the carried-over gains, adaptation rates and observer scaled by {bw:.3g}"
    if other and float(other["bandwidth_factor"]) > bw:
        line += (f" -- the PID yardstick's, held down by the encoder's noise: at the floors' bandwidth (factor "
                 f"{float(other['bandwidth_factor']):.3g}) no gains met every constraint in "
                 f"{int(other['n_evaluations'])} candidates, and the search at this bandwidth came closer (feasible "
                 f"gains, or a smaller violation)")
    elif other:
        line += (f" (the floors' bandwidth, where no gains met every constraint); a second search at the noise-held "
                 f"yardstick's (factor {float(other['bandwidth_factor']):.3g}, {int(other['n_evaluations'])} "
                 f"candidates) came no closer")
    else:
        line += " -- the fastest PID the margin floors admit lies below the rate-scaled grid: the plant sets the bandwidth"
    return [line]


def _robustness_paragraph(result: Any) -> list[str]:
    """The robustness part of the verdict in one paragraph (none without robustness checks)."""
    L: list[str] = []
    rl = robustness_lines(result)
    if rl:
        rise = (f"; the Stribeck rise at low speed that the log did not resolve (fs = {UNSEEN_STRIBECK[0]:g} fc, the "
                "ARC compared with the yardstick there too)" if unseen_stribeck_checked(result.robustness.checks) else "")
        L.append("**Robustness.** The gate's criteria on the robustness scenarios (one more sample "
                 f"of input delay than identified; with a mode, its frequency x0.8 and x1.2 and half its damping{rise}) "
                 "and the ARC's margins on the identified plant and over the whole theta box, required like every "
                 "other check (no divergence "
                 "and the spec's margin floors whatever gate.toml says): " + rl[0])
        L.append("")
    return L


def _gate_section(v: Any) -> list[str]:
    """The gate's table: every criterion with its limit, how it was set and the worst scenario."""
    L: list[str] = []
    L.append("## Gate")
    L.append("")
    L.append("Every criterion is checked for the ARC on every scenario; errors are measured on the encoder "
             "(e = y - q_d).")
    L.append("")
    L.append(gate_table_markdown(v))
    L.append("")
    return L


def _indexes_section(result: Any, tuning: Tuning) -> list[str]:
    """The performance indexes: one Table-1 table per trajectory, then the Monte-Carlo plants."""
    unit = result.units.get("u", "u")
    spec = tuning.spec
    L: list[str] = []
    L.append("## Performance indexes (layout of Table 1 of Xu & Yao 2001)")
    L.append("")
    L.append("e_M = max |e|, e_F = max |e| over the last 2 s, ‖e‖rms and ‖u‖rms over the run, "
             "‖Δu‖rms = rms of the input increments (eq. 54), c_u = ‖Δu‖rms / ‖u‖rms.")
    for case in case_names(spec):
        L.append("")
        L.append(f"### {CASE_TITLE[case]}")
        L.append("")
        L.append(table1_markdown(result, case, unit))
    L.extend(monte_carlo_markdown(result, unit))
    return L


def _figures_section(figures: Sequence[str]) -> list[str]:
    """The validation's figures with their captions (none when none was drawn)."""
    if not figures:
        return []
    L = ["", "## Figures"]
    for f in figures:
        L.append("")
        L.append(f"![{f}]({f})")
        L.append("")
        L.append(FIGURE_CAPTIONS.get(f, f))
    return L


def _provenance_section(result: Any, tuning: Tuning, tuning_sha256: str | None) -> list[str]:
    """Where the inputs came from (hashes, tool version, seeds) and what the validation ran."""
    L = ["## Provenance", ""]
    pv = tuning.provenance
    L.append(f"- excitation log sha256: {log_sha256_of(tuning) or 'not recorded'}")
    L.append(f"- ident.json sha256: {pv.ident_sha256}")
    if tuning_sha256:
        L.append(f"- tuning.json sha256: {tuning_sha256}")
    L.append(f"- tuning created {md_text(pv.created_utc)} by commission {md_text(pv.tool_version)} (seed {pv.seed})")
    L.append(f"- validation: {len(result.runs) * 2} simulations in {result.elapsed:.1f} s on {result.workers} threads; "
             f"Monte-Carlo seed {result.seed}")
    L.append("")
    return L
