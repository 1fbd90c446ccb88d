"""``commission run LOG --out-dir DIR``: identify, tune and validate in one command."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.markup import escape

from commission.report import refusal_lines
from commission.cli.errors import EXIT_GATE_FAILED, cli_errors
from commission.cli.options import SCHEDULER_HELP, with_identify_flags
from commission.cli.main import app
from commission.cli.progress import StageProgress
from commission.cli.validate_cmd import SIGN_KEY_HELP, print_next_steps, print_summary
from commission.controller_config import load_sign_key
from commission.formats.gate_toml import gate_help
from commission.identification import IdentifyOptions
from commission.tune import pid_pole_note
from commission.pipeline import run_all
from commission.validate import DEFAULT_MONTE_CARLO


RUN_HELP = f"""Identify the axis, tune the ARC, validate it; exit 0 with controller.json when every gate passes, else 1.

{escape(gate_help())}"""


@app.command("run", help=RUN_HELP)
@cli_errors
@with_identify_flags
def run_command(
    logs: List[Path] = typer.Argument(..., metavar="LOG...", help=(
        "Excitation log: .h5/.hdf5, .csv, .mat, .npy/.npz or an EPOS recorder CSV (docs/interface.md §1). "
        "Several files, or a folder: logs of one axis fitted together, each file its own segment.")),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for ident.json, tuning.json, report.md, figures, controller.json."),
    spec: Optional[Path] = typer.Option(None, "--spec", help="Tuning spec TOML (default: the paper's setting)."),
    gate: Optional[Path] = typer.Option(None, "--gate", help="Gate TOML (default: the table's defaults, below)."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing outputs in --out-dir."),
    seed: int = typer.Option(0, "--seed", help="Seed of the tuning search and of the Monte-Carlo plants."),
    monte_carlo: int = typer.Option(DEFAULT_MONTE_CARLO, "--monte-carlo", help="Monte-Carlo plants drawn from the theta box."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Simulation threads, 1-256 (default: one per CPU)."),
    sign_key: Optional[Path] = typer.Option(None, "--sign-key", help=SIGN_KEY_HELP),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="tcp://HOST:PORT", help=SCHEDULER_HELP),
    o: IdentifyOptions = None,  # type: ignore[assignment]  # every identify flag (with_identify_flags)
    plan: Optional[Path] = typer.Option(None, "--plan", metavar="PLAN_JSON", help=(
        "plan.json of `commission excite` that the one LOG was recorded from, passed to identify: the frequency "
        "response is measured on the plan's injection windows (default: a plan.json beside the LOG, if it is "
        "the LOG's plan).")),
) -> None:
    """Identify, tune and validate (the command's help is :data:`RUN_HELP`)."""
    from commission.cli.plots import identification_plots
    from commission.cli.plots_validate import validation_plots

    err = Console(stderr=True)
    if plan is not None:
        from commission.errors import UsageError
        from commission.excite import load_plan_json
        from commission.identification import expand_log_paths

        if len(expand_log_paths([str(p) for p in logs])) != 1:
            raise UsageError(f"--plan: takes one log recorded from the plan, got {len(logs)} paths")
        o = dataclasses.replace(o, plan=load_plan_json(plan), plan_path=str(plan))
    key = load_sign_key(sign_key)
    stages = {"identify": "identifying", "tune": "tuning", "validate": "validating"}
    with StageProgress(err) as bar:

        def cb(stage: str, done: int, total: int) -> None:
            bar.update(stages.get(stage, stage), done, total)

        outcome = run_all(logs, out_dir, identify=o, spec_path=spec, gate_path=gate, force=force, seed=seed,
                          n_monte_carlo=monte_carlo, progress=cb, workers=workers, figures=validation_plots,
                          sign_key=key, ident_figures=identification_plots, scheduler=scheduler)
    for w in json.loads(Path(outcome.ident).read_text()).get("warnings", []):
        err.print(f"warning: {w}", highlight=False)
    pid_note = pid_pole_note(outcome.validation.tuning)
    for note in (*outcome.notes, *(() if pid_note is None else (pid_note,))):
        err.print(f"note: {note}", highlight=False)
    v = outcome.validation
    print_summary(v.result)
    for p in (outcome.ident, outcome.tuning, *v.written):
        typer.echo(f"wrote {p}")
    print_next_steps(v.result, v.tuning, out_dir, Path(outcome.tuning), signed=key is not None)
    if not v.result.passed:
        for line in refusal_lines(v.result, v.tuning):
            typer.echo(line)
        typer.echo(f"no controller.json: the gate failed (see {Path(out_dir) / 'report.md'})")
        raise typer.Exit(EXIT_GATE_FAILED)
