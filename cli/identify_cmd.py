"""``commission identify LOG``: least-squares identification and Assumption-1 bounds."""

from __future__ import annotations

import enum
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.table import Table

from commission.cli.errors import cli_errors
from commission.cli.main import app
from commission.errors import UsageError
from commission.files import Outputs
from commission.identification import (BoundsOptions, IdentifyOutcome, LegsOutcome, expand_log_paths, identify_legs,
                                       identify_log, parse_fix, payload_from_kg)
from commission.jsonio import write_json_atomic
from commission.logs import parse_mapping


class Friction(str, enum.Enum):
    auto = "auto"
    coulomb = "coulomb"
    stribeck = "stribeck"


#: Figures of ``--plot`` (:func:`commission.cli.plots.identification_plots`).
PLOT_NAMES = ("force_fit.png", "friction_curve.png", "residuals.png", "bode.png")
#: Figure of ``--plot`` for a friction test of several logs (:func:`commission.cli.plots_friction.friction_map_plot`).
LEGS_PLOT_NAMES = ("friction_map.png",)
Q_UNIT_HELP = ("Unit of q (and q_ref) in a file without a q_unit attribute (CSV, v5 .mat): m, mm or um; "
               "default m. Refused when it contradicts the file's attribute.")
FRICTION_HELP = ("Friction model. auto: the Stribeck curve when the log supports it, else the Coulomb model "
                 "with a warning; stribeck: refuse a log that does not support it.")


def bounds_options(
    k_sigma: float,
    model_margin: float,
    payload_min: Optional[float],
    payload_max: Optional[float],
    payload_min_kg: Optional[float],
    payload_max_kg: Optional[float],
    force_constant: Optional[float],
    disturbance_bound: Optional[float],
) -> BoundsOptions:
    """Turn the bound flags into :class:`BoundsOptions` (kg converted with the force constant)."""
    if (payload_min_kg is not None or payload_max_kg is not None) and force_constant is None:
        raise UsageError("--payload-min-kg/--payload-max-kg need --force-constant (N per u-unit)")
    if payload_min is not None and payload_min_kg is not None:
        raise UsageError("give either --payload-min or --payload-min-kg, not both")
    if payload_max is not None and payload_max_kg is not None:
        raise UsageError("give either --payload-max or --payload-max-kg, not both")
    if payload_min_kg is not None:
        payload_min = payload_from_kg(payload_min_kg, force_constant)  # type: ignore[arg-type]
    if payload_max_kg is not None:
        payload_max = payload_from_kg(payload_max_kg, force_constant)  # type: ignore[arg-type]
    for flag, v in (("--payload-min", payload_min), ("--payload-max", payload_max),
                    ("--disturbance-bound", disturbance_bound), ("--k-sigma", k_sigma)):
        if v is not None and v < 0:
            raise UsageError(f"{flag} must be >= 0, got {v}")
    if not 0 <= model_margin < 1:
        raise UsageError(f"--model-margin must be in [0, 1), got {model_margin}")
    return BoundsOptions(k_sigma=k_sigma, model_margin=model_margin, payload_min=payload_min or 0.0,
                         payload_max=payload_max, disturbance_bound=disturbance_bound)


def print_summary(outcome: IdentifyOutcome, console: Console) -> None:
    """One-screen summary: parameters +- std, fit, bounds, warnings."""
    ident, fit = outcome.ident, outcome.fit
    u, q = ident.units["u"], ident.units["q"]
    units = {"M": f"{u}·s²/{q}", "B": f"{u}·s/{q}", "fc": u, "fs": u, "vs": f"{q}/s", "xi": "-", "offset": u}
    t = Table(title=f"Identification of {outcome.log.source} ({fit.friction}, {fit.method})")
    for col in ("parameter", "value", "± std", "rel. std", "unit"):
        t.add_column(col, justify="right" if col != "parameter" else "left")
    missing = ident.not_identified()
    fixed = ident.extra.get("model", {}).get("fixed", {})  # type: ignore[union-attr]
    for name, est in ident.parameters.items():
        if est is None:
            if name in missing:
                t.add_row(name, "not identified", "", "", units[name])
            continue
        rel = f"{abs(est.std / est.value) * 100:.2f} %" if est.value else "-"
        t.add_row(name, f"{est.value:.6g}", "fixed" if name in fixed else f"{est.std:.3g}", rel, units[name])
    for h in ident.extra.get("model", {}).get("ripple_harmonics") or []:  # type: ignore[union-attr]
        if h["amp"]:
            t.add_row(f"ripple P={h['pitch']:.4g} {q}", f"{h['amp']['value']:.4g}", f"{h['amp']['std']:.2g}",
                      f"phase {h['phase']['value']:+.3f} rad", u)
    console.print(t)
    q = outcome.checks.quantization_step
    lines = [
        f"samples {outcome.log.t.size} at {outcome.log.sample_rate:.6g} Hz; encoder step "
        + (f"{q:.3g} m" if q else f"not on a grid (smallest step {outcome.checks.apparent_resolution:.3g} m)"),
        f"relative error {ident.relative_error:.4f}, condition number {ident.condition_number:.4g}"
        + (f", validation relative error {ident.validation_relative_error:.4f}"
           if ident.validation_relative_error is not None else ""),
    ]
    if ident.theta is not None:
        lines += [
            "theta nominal [" + ", ".join(f"{x:.4g}" for x in ident.theta.nominal) + "]",
            "theta min     [" + ", ".join(f"{x:.4g}" for x in ident.theta.min) + "]",
            "theta max     [" + ", ".join(f"{x:.4g}" for x in ident.theta.max) + "]",
            f"delta_d {ident.delta_d:.4g} m/s²",
        ]
    lines.append(f"friction compensation {ident.fric_level:.4g}·(2/π)·atan({ident.fric_slope:.4g}·v) {u}")
    if ident.theta is not None:
        lines.append(frequency_summary(ident.extra.get("frequency_response")))  # type: ignore[arg-type]
    for name, why in missing.items():
        lines.append(f"[yellow]not identified:[/] {name}: {why}; theta, its box and the frequency response need it "
                     "(identify --fix M=VALUE gives it)")
    for line in lines:
        console.print(line)
    for w in ident.extra.get("warnings", []):  # type: ignore[union-attr]
        console.print(f"[yellow]warning:[/] {w}")


def print_legs_summary(outcome: LegsOutcome, console: Console) -> None:
    """One-screen summary of a friction test: the curve's parameters, the map, what is not identified."""
    ident = outcome.ident
    u, q = ident.units["u"], ident.units["q"]
    units = {"M": f"{u}·s²/{q}", "B": f"{u}·s/{q}", "fc": u, "fs": u, "vs": f"{q}/s", "xi": "-", "offset": u}
    t = Table(title=f"Friction test: {len(outcome.logs) - len(outcome.excluded)} constant-speed legs "
                    f"({ident.extra['model']['friction']})")
    for col in ("parameter", "value", "± std", "unit"):
        t.add_column(col, justify="right" if col != "parameter" else "left")
    missing = ident.not_identified()
    for name, est in ident.parameters.items():
        if est is None:
            if name in missing:
                t.add_row(name, "not identified", "", units[name])
            continue
        fixed = name in ident.extra["model"].get("fixed", {})
        t.add_row(name, f"{est.value:.6g}", "fixed" if fixed else f"{est.std:.3g}", units[name])
    console.print(t)
    console.print(f"friction map: {outcome.fmap.velocity.size} legs, speeds "
                  f"{abs(outcome.fmap.velocity).min():.3g}-{abs(outcome.fmap.velocity).max():.3g} {q}/s; "
                  f"relative error of the curve {ident.relative_error:.4f}")
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
        text += f"; {m['kind']} {m['frequency_hz']:.4g} Hz (damping {m['damping']:.3g})"
    if fr.get("delay_samples") is not None:
        text += f"; input delay {fr['delay_samples']:.2f} samples"
    if fr.get("note"):
        # The note states the backed band itself.
        text = "frequency response: " + fr["note"]
    return text


@app.command("identify")
@cli_errors
def identify_command(
    logs: List[Path] = typer.Argument(..., metavar="LOG...", help=(
        "Excitation log: .h5/.hdf5, .csv, .mat or an EPOS recorder CSV (docs/interface.md §1). Several files, "
        "or a folder, are the constant-speed legs of a friction test, one leg per file.")),
    out: Path = typer.Option(Path("ident.json"), "--out", "-o", help="Where to write ident.json."),
    map_: List[str] = typer.Option([], "--map", help="NAME=SOURCE: contract channel -> name in the file (repeatable)."),
    input_gain: float = typer.Option(1.0, "--input-gain", help="Multiplies u before identification (e.g. N/V)."),
    u_unit: Optional[str] = typer.Option(None, "--u-unit", help="Unit of u after --input-gain (V, N, A); default: the file's."),
    sample_rate: Optional[float] = typer.Option(None, "--sample-rate", help="Hz, for a file without t."),
    q_unit: Optional[str] = typer.Option(None, "--q-unit", help=Q_UNIT_HELP),
    friction: Friction = typer.Option(Friction.auto, "--friction", help=FRICTION_HELP),
    ripple_pitch: List[float] = typer.Option([], "--ripple-pitch", help="Force-ripple pitch P in m (rad on a rotary axis): fits sin/cos(2πq/P); repeatable, one sinusoid per pitch (e.g. the harmonics of one cogging period)."),
    validate_on: Optional[Path] = typer.Option(None, "--validate-on", help="Second log for the cross-test relative error."),
    k_sigma: float = typer.Option(3.0, "--k-sigma", help="Standard deviations covered by the theta box."),
    model_margin: float = typer.Option(0.2, "--model-margin", help="Relative margin on M and B for model error."),
    payload_min: Optional[float] = typer.Option(None, "--payload-min", help="Least added mass, u-unit·s²/m (default 0)."),
    payload_max: Optional[float] = typer.Option(None, "--payload-max", help="Largest added mass, u-unit·s²/m (default 3 M)."),
    payload_min_kg: Optional[float] = typer.Option(None, "--payload-min-kg", help="Least added mass in kg (needs --force-constant)."),
    payload_max_kg: Optional[float] = typer.Option(None, "--payload-max-kg", help="Largest added mass in kg (needs --force-constant)."),
    force_constant: Optional[float] = typer.Option(None, "--force-constant", help="N per u-unit, to convert kg payloads."),
    disturbance_bound: Optional[float] = typer.Option(None, "--disturbance-bound", help="Largest load force, u-unit (default 10 max(fc, fs))."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Directory for PNG plots (force fit, friction curve, residuals, Bode plot)."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing --out file and --plot figures."),
    log_format: Optional[str] = typer.Option(None, "--format", help="Force the log format: hdf5, csv, mat or epos (default: from the content, then the extension)."),
    resample: Optional[float] = typer.Option(None, "--resample", metavar="HZ", help="Interpolate the log onto a uniform grid at HZ first (irregular time stamps, e.g. host polling)."),
    fix: List[str] = typer.Option([], "--fix", metavar="NAME=VALUE", help="A known parameter, e.g. M=0.027 (u-unit·s²/m): a friction test of constant-speed legs then gives theta and its box."),
) -> None:
    """Identify M, B, friction and offset from a position-only excitation log; write ident.json.

    Several logs (or a folder) are read as the legs of a friction test: the friction map and curve are
    identified, and M is reported as not identified unless --fix gives it."""
    bounds = bounds_options(k_sigma, model_margin, payload_min, payload_max, payload_min_kg,
                            payload_max_kg, force_constant, disturbance_bound)
    mapping = parse_mapping(map_)
    fixed = parse_fix(fix)
    files = expand_log_paths([str(p) for p in logs])
    legs = len(files) > 1
    if legs:
        for flag, value in (("--validate-on", validate_on), ("--ripple-pitch", ripple_pitch or None), ("--resample", resample)):
            if value is not None:
                raise UsageError(f"{flag}: not available for a friction test of several logs (one leg per file)")
    # Outputs checked (not an input, not a folder, --force, writable, locked) before any computation.
    outputs = Outputs(force=force, inputs=(*files, validate_on))
    outputs.add_file(out, "--out")
    if plot is not None:
        outputs.add_dir(plot, LEGS_PLOT_NAMES if legs else PLOT_NAMES, "--plot")
    console = Console(stderr=False)
    with outputs:
        with console.status("identifying ...", spinner="dots"):
            if legs:
                outcome: IdentifyOutcome | LegsOutcome = identify_legs(
                    files, mapping=mapping, input_gain=input_gain, sample_rate=sample_rate,
                    friction=friction.value, fix=fixed, bounds=bounds, u_unit=u_unit, q_unit=q_unit,
                    fmt=log_format)
            else:
                outcome = identify_log(
                    files[0], mapping=mapping, input_gain=input_gain, sample_rate=sample_rate,
                    friction=friction.value, ripple_pitch=tuple(ripple_pitch) or None,
                    validate_on=str(validate_on) if validate_on else None, bounds=bounds, u_unit=u_unit,
                    q_unit=q_unit, fmt=log_format, resample=resample, fix=fixed,
                )
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
