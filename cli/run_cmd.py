"""``commission run LOG --out-dir DIR``: identify, tune and validate in one command."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.markup import escape

from commission.cli.errors import cli_errors
from commission.cli.options import ValidateFlags, with_identify_flags, with_validate_flags
from commission.cli.main import app
from commission.cli.progress import StageProgress
from commission.cli.validate_cmd import print_outcome
from commission.controller_config import load_sign_key
from commission.formats.gate_toml import gate_help
from commission.identification import IdentifyOptions
from commission.tune import pid_pole_note
from commission.pipeline import run_all


RUN_HELP = f"""Identify the axis, tune the ARC, validate it; exit 0 with controller.json when every gate passes, else 1.

With no --payload-max, a default payload box that fails the gate is tried once more on the axis as identified (no payload); controller.json's validity then says so.

{escape(gate_help())}"""


@app.command("run", help=RUN_HELP)
@cli_errors
@with_identify_flags
@with_validate_flags(seed_help="Seed of the tuning search and of the Monte-Carlo plants.",
                     monte_carlo_help="Monte-Carlo plants drawn from the theta box.")
def run_command(
    logs: List[Path] = typer.Argument(..., metavar="LOG...", help=(
        "Excitation log: .h5/.hdf5, .csv, .mat, .npy/.npz or an EPOS recorder CSV (docs/interface.md §1). "
        "Several files, or a folder: logs of one axis fitted together, each file its own segment.")),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for ident.json, tuning.json, report.md, figures, controller.json."),
    spec: Optional[Path] = typer.Option(None, "--spec", help="Tuning spec TOML (default: the paper's setting)."),
    v: ValidateFlags = None,  # type: ignore[assignment]  # every validation flag (with_validate_flags)
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
    key = load_sign_key(v.sign_key)
    stages = {"identify": "identifying", "tune": "tuning", "validate": "validating"}
    with StageProgress(err) as bar:

        def cb(stage: str, done: int, total: int) -> None:
            bar.update(stages.get(stage, stage), done, total)

        outcome = run_all(logs, out_dir, identify=o, spec_path=spec, gate_path=v.gate, force=v.force, seed=v.seed,
                          n_monte_carlo=v.monte_carlo, progress=cb, workers=v.workers, figures=validation_plots,
                          sign_key=key, ident_figures=identification_plots, scheduler=v.scheduler)
    for w in json.loads(Path(outcome.ident).read_text()).get("warnings", []):
        err.print(f"warning: {w}", highlight=False)
    pid_note = pid_pole_note(outcome.validation.tuning)
    for note in (*outcome.notes, *(() if pid_note is None else (pid_note,))):
        err.print(f"note: {note}", highlight=False)
    val = outcome.validation
    print_outcome(val.result, val.tuning, (outcome.ident, outcome.tuning, *val.written), out_dir,
                  Path(outcome.tuning), signed=key is not None, also_tried=outcome.also_tried)
