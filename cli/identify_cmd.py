"""``commission identify LOG``: least-squares identification and Assumption-1 bounds."""

from __future__ import annotations

import dataclasses

from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from commission.units import mass_wording, parameter_label, parameter_units, unit
from commission.cli.errors import cli_errors
from commission.cli.main import app
from commission.errors import UsageError
from commission.infra.files import Outputs
from commission.cli.options import with_identify_flags
from commission.identification import (IDENT_FIGURE_NAMES, IdentifyOptions, IdentifyOutcome, LegsOutcome,
                                       expand_log_paths, identify_files, identify_log)
from commission.jsonio import write_json_atomic


#: Figures of ``--plot`` (:func:`commission.cli.plots.identification_plots`).
PLOT_NAMES = IDENT_FIGURE_NAMES
#: Figure of ``--plot`` for a friction test of several logs (:func:`commission.cli.plots_friction.friction_map_plot`).
LEGS_PLOT_NAMES = ("friction_map.png",)


def print_summary(outcome: IdentifyOutcome, console: Console) -> None:
    """One-screen summary: parameters +- std, fit, bounds, warnings."""
    ident, fit = outcome.ident, outcome.fit
    u, q = ident.units["u"], ident.units["q"]
    units = parameter_units(ident.units)
    labels = {"M": parameter_label("M", ident.units)}
    chosen = (ident.extra.get("model_selection") or {}).get("chosen")  # type: ignore[union-attr]
    t = Table(title=f"Identification of {outcome.log.source} ({fit.friction}"
                    + (f" + {', '.join(chosen)}" if chosen else "") + f", {fit.method})")
    for col in ("parameter", "value", "± std", "rel. std", "unit"):
        t.add_column(col, justify="right" if col != "parameter" else "left")
    missing = ident.not_identified()
    fixed = ident.extra.get("model", {}).get("fixed", {})  # type: ignore[union-attr]
    for name, est in ident.parameters.items():
        if est is None:
            if name in missing:
                t.add_row(labels.get(name, name), "not identified", "", "", units[name])
            continue
        rel = f"{abs(est.std / est.value) * 100:.2f} %" if est.value else "-"
        t.add_row(labels.get(name, name), f"{est.value:.6g}", "fixed" if name in fixed else f"{est.std:.3g}", rel,
                  units[name])
    for h in ident.extra.get("model", {}).get("ripple_harmonics") or []:  # type: ignore[union-attr]
        if h["amp"]:
            t.add_row(f"ripple P={h['pitch']:.4g} {q}", f"{h['amp']['value']:.4g}", f"{h['amp']['std']:.2g}",
                      f"phase {h['phase']['value']:+.3f} rad", u)
    console.print(t)
    _print_terms(ident, console)
    step = outcome.checks.quantization_step
    lines = [
        f"samples {outcome.log.t.size} at {outcome.log.sample_rate:.6g} Hz; encoder step "
        + (f"{step:.3g} {q}" if step else
           f"not on a grid (smallest step {outcome.checks.apparent_resolution:.3g} {q})"),
        f"relative error {ident.relative_error:.4f}, condition number {ident.condition_number:.4g}"
        + (f", validation relative error {ident.validation_relative_error:.4f}"
           if ident.validation_relative_error is not None else ""),
    ]
    if ident.theta is not None:
        theta_units = escape(f"in [{units['theta1']}, {units['theta2']}, {units['theta3']}]")  # not rich markup
        lines += [
            "theta nominal [" + ", ".join(f"{x:.4g}" for x in ident.theta.nominal) + "] " + theta_units,
            "theta min     [" + ", ".join(f"{x:.4g}" for x in ident.theta.min) + "] " + theta_units,
            "theta max     [" + ", ".join(f"{x:.4g}" for x in ident.theta.max) + "] " + theta_units,
            f"delta_d {ident.delta_d:.4g} {units['delta_d']}",
        ]
    lines.append(f"friction compensation {ident.fric_level:.4g}·(2/π)·atan({ident.fric_slope:.4g}·v) {u} "
                 f"(v in {unit('v', ident.units)}, slope in s/{q})")
    if ident.theta is not None:
        lines.append(frequency_summary(ident.extra.get("frequency_response")))  # type: ignore[arg-type]
    ps = ident.extra.get("position_simulation")
    if isinstance(ps, dict) and ps.get("rmse") is not None:
        ref = ps.get("reference_rmse")
        lines.append(f"position simulation on the validation log: RMSE {ps['rmse'] * 1e3:.4g} m{q}"
                     + (f" (IDIM-LS model: {ref * 1e3:.4g} m{q})" if ref is not None else "")
                     + f", beside the force relative error {ident.validation_relative_error:.4f}"
                     + f" (open loop, {ps['init_samples']}-sample initialisation window)")
    for name, why in missing.items():
        lines.append(f"[yellow]not identified:[/] {name}: {why}; theta, its box and the frequency response need it "
                     f"(identify --fix M=VALUE gives the {mass_wording(ident.units)[0]} in {units['M']})")
    for line in lines:
        console.print(line)
    for w in ident.extra.get("warnings", []):  # type: ignore[union-attr]
        console.print(f"[yellow]warning:[/] {w}")
    ev = ident.extra.get("evidence")
    if isinstance(ev, dict):
        console.print(escape(evidence_text(ev)), soft_wrap=True)


def evidence_text(ev: dict) -> str:
    """ident.json's ``evidence`` as the console prints it (:class:`commission.next_steps.ExciteAdvice`)."""
    from commission.next_steps import ExciteAdvice

    return ExciteAdvice(tuple(ev["missing"]), ev["excite_command"], ev["limits_toml"]).text()


def _num(x: float | None, spec: str) -> str:
    """A number for the terms table; null (a flat profile: no finite std) as "-"."""
    return "-" if x is None else format(x, spec)


def _print_terms(ident, console: Console) -> None:
    """The delay-aware inverse dynamics' terms (every coefficient with its unit) and the selection's choice."""
    sel = ident.extra.get("model_selection")
    if not isinstance(sel, dict):
        return
    u = ident.units["u"]
    q = ident.units["q"]
    chosen = sel.get("chosen") or []
    console.print(f"terms chosen by {sel['folds']}-fold blocked cross-validation on the identification log: "
                  + (", ".join(chosen) if chosen else "none (the base model)"))
    inv = ident.extra.get("model", {}).get("inverse_dynamics")  # type: ignore[union-attr]
    if not isinstance(inv, dict):
        return
    t = Table(title="inverse dynamics (u = F(t + (0.5 + delay) Ts))")
    for col in ("coefficient", "value", "± std", "unit"):
        t.add_column(col, justify="right" if col != "coefficient" else "left")
    def un(s: str) -> str:
        return s.replace("u", u, 1).replace("/m", f"/{q}") if s.startswith("u") else s.replace("m", q, 1)
    for nm, c in {**inv["coefficients"], **inv["derived"]}.items():
        t.add_row(nm, f"{c['value']:.6g}", _num(c["std"], ".3g"), un(c["unit"]))
    if "delay" in inv["terms"]:
        t.add_row("delay", f"{inv['delay_samples']:.3f}", _num(inv["delay_std_samples"], ".3f"),
                  "samples beyond the hold")
    if inv.get("vs") is not None:
        t.add_row("vs (xi = 2)", f"{inv['vs']:.4g}", _num(inv["vs_std"], ".2g"), f"{q}/s")
    if any(k in inv["coefficients"] for k in ("kq1", "kq2")):
        t.add_row("q_center", f"{inv['q_center']:.6g}", "", q)
    console.print(t)


def print_legs_summary(outcome: LegsOutcome, console: Console) -> None:
    """One-screen summary of a friction test: the curve's parameters, the map, what is not identified."""
    ident = outcome.ident
    u, q = ident.units["u"], ident.units["q"]
    units = parameter_units(ident.units)
    labels = {"M": parameter_label("M", ident.units)}
    t = Table(title=f"Friction test: {len(outcome.logs) - len(outcome.excluded)} constant-speed legs "
                    f"({ident.extra['model']['friction']})")
    for col in ("parameter", "value", "± std", "unit"):
        t.add_column(col, justify="right" if col != "parameter" else "left")
    missing = ident.not_identified()
    for name, est in ident.parameters.items():
        if est is None:
            if name in missing:
                t.add_row(labels.get(name, name), "not identified", "", units[name])
            continue
        fixed = name in ident.extra["model"].get("fixed", {})
        t.add_row(labels.get(name, name), f"{est.value:.6g}", "fixed" if fixed else f"{est.std:.3g}", units[name])
    console.print(t)
    console.print(f"friction map: {outcome.fmap.velocity.size} legs, speeds "
                  f"{abs(outcome.fmap.velocity).min():.3g}-{abs(outcome.fmap.velocity).max():.3g} {q}/s; "
                  f"relative error of the curve {ident.relative_error:.4f}"
                  + (f", on the --validate-on legs {ident.validation_relative_error:.4f}"
                     if ident.validation_relative_error is not None else ""))
    for name, why in missing.items():
        console.print(f"[yellow]not identified:[/] {name}: {why}")
    for w in ident.extra.get("warnings", []):  # type: ignore[union-attr]
        console.print(f"[yellow]warning:[/] {w}")


def frequency_summary(fr: dict | None) -> str:
    """One line on the frequency response section of ident.json."""
    if not fr:
        return "frequency response: not measured"
    band = fr.get("band_hz")
    text = "frequency response: " + (f"rigid model backed {band[0]:.4g}-{band[1]:.4g} Hz" if band
                                     else "no band backs the rigid model")
    for m in fr.get("modes", []):
        sd = m.get("frequency_std_hz")
        text += (f"; {m['kind']} {m['frequency_hz']:.4g}" + (f" ± {sd:.2g}" if sd is not None else "")
                 + f" Hz (damping {m['damping']:.3g})")
    if fr.get("delay_samples") is not None:
        text += f"; input delay {fr['delay_samples']:.2f} samples"
    if fr.get("note"):
        # Without modes the note states the backed band itself; with them it says what the model leaves out.
        text = ("frequency response: " + fr["note"]) if not fr.get("modes") else f"{text}; {fr['note']}"
    ev = fr.get("evidence_band_hz")
    if fr.get("source") == "broadband" and ev:
        text += f"; the data back the fitted model {ev[0]:.4g}-{ev[1]:.4g} Hz"
    if fr.get("plan"):
        text += f"; measured on the injection windows of {fr['plan']}"
    return text


@app.command("identify")
@cli_errors
@with_identify_flags
def identify_command(
    logs: List[Path] = typer.Argument(..., metavar="LOG...", help=(
        "Excitation log: .h5/.hdf5, .csv, .mat, .npy/.npz (a 2-D .npy by index: --map t=0 --map q=1 --map u=2) "
        "or an EPOS recorder CSV (docs/interface.md §1). Several files, or a folder: the constant-speed legs "
        "of a friction test (one leg per file, both directions), or else logs of one axis fitted together, "
        "each file its own segment.")),
    out: Path = typer.Option(Path("ident.json"), "--out", "-o", help="Where to write ident.json."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Directory for PNG plots (force fit, friction curve, residuals, Bode plot; a friction test: its map)."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing --out file and --plot figures."),
    o: IdentifyOptions = None,  # type: ignore[assignment]  # every identify flag (with_identify_flags)
    plan: Optional[Path] = typer.Option(None, "--plan", metavar="PLAN_JSON", help=(
        "plan.json of `commission excite` that the one LOG was recorded from: the frequency response is "
        "measured on the plan's injection windows (the log's time starts with the plan's).")),
    u_max: Optional[float] = typer.Option(None, "--u-max", min=0.0, help=(
        "The drive's command limit, in u's unit after --input-gain: for the `commission excite` limits.toml "
        "sketch that a log without a broadband segment gets.")),
    max_modes: Optional[int] = typer.Option(None, "--max-modes", min=0, help=(
        "Most structural modes the frequency response keeps (default: as many as the data hold, up to 4; "
        "each must lower the information criterion). Modes beyond it are warned about, named by frequency.")),
    terms: str = typer.Option("auto", "--terms", help="With --friction auto, on a whole-log fit: the delay-aware "
                              "inverse dynamics' switchable terms (delay, viscous_asym, stribeck, position, drag) "
                              "that blocked cross-validation on the identification log chooses among: auto (all), "
                              "none, or a comma-separated subset."),
) -> None:
    """Identify M, B, friction and offset from a position-only excitation log; write ident.json.

    Several logs (or a folder) that are all constant-speed legs are a friction test: the friction map and
    curve are identified, and M is reported as not identified unless --fix gives it. Otherwise several logs
    are fitted together, each its own segment: nothing is filtered across the joins between files."""
    o = dataclasses.replace(o, terms=terms)
    files = expand_log_paths([str(p) for p in logs])
    val_files = expand_log_paths([o.validate_on]) if o.validate_on else []
    several = len(files) > 1
    # Outputs checked (not an input, not a folder, --force, writable, locked) before any computation.
    # Several logs are a friction test or segments of a fit: which one is known once they are read,
    # so --plot declares the figures of both.
    plan_data = None
    if plan is not None:
        from commission.excite import load_plan_json

        if several:
            raise UsageError(f"--plan: takes one log recorded from the plan, got {len(files)}")
        plan_data = load_plan_json(plan)
    outputs = Outputs(force=force, inputs=(*files, *val_files, *((plan,) if plan is not None else ())))
    outputs.add_file(out, "--out")
    if plot is not None:
        outputs.add_dir(plot, PLOT_NAMES + LEGS_PLOT_NAMES if several else PLOT_NAMES, "--plot")
    console = Console(stderr=False)
    with outputs:
        with console.status("identifying ...", spinner="dots"):
            kw = o.kwargs()
            del kw["validate_on"]
            if max_modes is not None:
                kw["max_modes"] = max_modes
            if u_max is not None:
                kw["u_max"] = u_max
            outcome: IdentifyOutcome | LegsOutcome = (
                identify_files(files, validate_on=val_files, **kw) if several  # type: ignore[arg-type]
                else identify_log(files[0], validate_on=val_files or None, plan=plan_data,
                                  plan_path=str(plan) if plan is not None else None, **kw))  # type: ignore[arg-type]
        write_json_atomic(outputs.path(out), outcome.ident.to_dict())
        figures = []
        if plot is not None:
            if isinstance(outcome, LegsOutcome):
                from commission.cli.plots_friction import friction_map_plot

                figures = [outputs.final(friction_map_plot(outcome, outputs.staging(plot) / LEGS_PLOT_NAMES[0]))]
            else:
                from commission.cli.plots import identification_plots

                figures = [outputs.final(p) for p in identification_plots(outcome, outputs.staging(plot))]
    if isinstance(outcome, LegsOutcome):
        print_legs_summary(outcome, console)
    else:
        print_summary(outcome, console)
    console.print(f"wrote {out}")
    for p in figures:
        console.print(f"wrote {p}")
