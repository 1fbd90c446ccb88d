"""``commission run LOG --out-dir DIR``: identify, tune and validate in one command."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console

from commission.cli.errors import EXIT_GATE_FAILED, cli_errors
from commission.cli.identify_cmd import FRICTION_HELP, Q_UNIT_HELP, Friction, bounds_options
from commission.cli.main import app
from commission.cli.progress import StageProgress
from commission.cli.validate_cmd import SIGN_KEY_HELP, print_summary
from commission.controller_config import load_sign_key
from commission.logs import parse_mapping
from commission.tune import pid_pole_note
from commission.pipeline import run_all
from commission.validate import DEFAULT_MONTE_CARLO


@app.command("run")
@cli_errors
def run_command(
    log: Path = typer.Argument(..., help="Excitation log: .h5/.hdf5, .csv, .mat or an EPOS recorder CSV (docs/interface.md §1)."),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for ident.json, tuning.json, report.md, figures, controller.json."),
    map_: List[str] = typer.Option([], "--map", help="NAME=SOURCE: contract channel -> name in the file (repeatable)."),
    input_gain: float = typer.Option(1.0, "--input-gain", help="Multiplies u before identification (e.g. N/V)."),
    sample_rate: Optional[float] = typer.Option(None, "--sample-rate", help="Hz, for a file without t."),
    q_unit: Optional[str] = typer.Option(None, "--q-unit", help=Q_UNIT_HELP),
    friction: Friction = typer.Option(Friction.auto, "--friction", help=FRICTION_HELP),
    spec: Optional[Path] = typer.Option(None, "--spec", help="Tuning spec TOML (default: the paper's setting)."),
    gate: Optional[Path] = typer.Option(None, "--gate", help="Gate TOML (default: the documented defaults)."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing outputs in --out-dir."),
    seed: int = typer.Option(0, "--seed", help="Seed of the tuning search and of the Monte-Carlo plants."),
    monte_carlo: int = typer.Option(DEFAULT_MONTE_CARLO, "--monte-carlo", help="Monte-Carlo plants drawn from the theta box."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Simulation threads, 1-256 (default: one per CPU)."),
    sign_key: Optional[Path] = typer.Option(None, "--sign-key", help=SIGN_KEY_HELP),
    u_unit: Optional[str] = typer.Option(None, "--u-unit", help="As identify: unit of u after --input-gain."),
    ripple_pitch: Optional[float] = typer.Option(None, "--ripple-pitch", help="As identify: force-ripple pitch in m."),
    validate_on: Optional[Path] = typer.Option(None, "--validate-on", help="As identify: second log for the cross-test relative error."),
    k_sigma: float = typer.Option(3.0, "--k-sigma", help="As identify: standard deviations covered by the theta box."),
    model_margin: float = typer.Option(0.2, "--model-margin", help="As identify: relative margin on M and B."),
    payload_min: Optional[float] = typer.Option(None, "--payload-min", help="As identify: least added mass, u-unit·s²/m."),
    payload_max: Optional[float] = typer.Option(None, "--payload-max", help="As identify: largest added mass, u-unit·s²/m."),
    payload_min_kg: Optional[float] = typer.Option(None, "--payload-min-kg", help="As identify (needs --force-constant)."),
    payload_max_kg: Optional[float] = typer.Option(None, "--payload-max-kg", help="As identify (needs --force-constant)."),
    force_constant: Optional[float] = typer.Option(None, "--force-constant", help="As identify: N per u-unit."),
    disturbance_bound: Optional[float] = typer.Option(None, "--disturbance-bound", help="As identify: largest load force, u-unit."),
    log_format: Optional[str] = typer.Option(None, "--format", help="As identify: force the log format."),
) -> None:
    """Identify the axis, tune the ARC, validate it; exit 0 with controller.json when every gate passes, else 1."""
    from commission.cli.plots_validate import validation_plots

    err = Console(stderr=True)
    mapping = parse_mapping(map_)
    bounds = bounds_options(k_sigma, model_margin, payload_min, payload_max, payload_min_kg,
                            payload_max_kg, force_constant, disturbance_bound)
    stages = {"identify": "identifying", "tune": "tuning", "validate": "validating"}
    with StageProgress(err) as bar:

        def cb(stage: str, done: int, total: int) -> None:
            bar.update(stages.get(stage, stage), done, total)

        outcome = run_all(log, out_dir, mapping=mapping, input_gain=input_gain, sample_rate=sample_rate,
                          friction=friction.value, q_unit=q_unit, spec_path=spec, gate_path=gate, force=force, seed=seed,
                          n_monte_carlo=monte_carlo, progress=cb, workers=workers, figures=validation_plots,
                          sign_key=load_sign_key(sign_key), u_unit=u_unit, ripple_pitch=ripple_pitch,
                          validate_on=validate_on, bounds=bounds, fmt=log_format)
    for w in json.loads(Path(outcome.ident).read_text()).get("warnings", []):
        err.print(f"warning: {w}", highlight=False)
    pid_note = pid_pole_note(outcome.validation.tuning)
    for note in (*outcome.notes, *(() if pid_note is None else (pid_note,))):
        err.print(f"note: {note}", highlight=False)
    v = outcome.validation
    print_summary(v.result)
    for p in (outcome.ident, outcome.tuning, *v.written):
        typer.echo(f"wrote {p}")
    if not v.result.passed:
        typer.echo(f"no controller.json: the gate failed (see {Path(out_dir) / 'report.md'})")
        raise typer.Exit(EXIT_GATE_FAILED)
