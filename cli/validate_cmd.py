"""``commission validate TUNING --out-dir DIR``: simulate the scenario matrix, check the gate,
write the report and (gate passed) controller.json."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import typer
from rich.console import Console
from rich.markup import escape

from commission.report import refusal_lines, summary_text
from commission.cli.errors import EXIT_GATE_FAILED, cli_errors
from commission.cli.main import app
from commission.cli.options import SCHEDULER_HELP
from commission.cli.progress import StageProgress
from commission.controller_config import load_sign_key
from commission.evidence import evidence_lines
from commission.formats.gate_toml import gate_help
from commission.next_steps import next_steps
from commission.validate import DEFAULT_MONTE_CARLO, ValidationResult, run_validate


SIGN_KEY_HELP = ("Key file: sign controller.json with HMAC-SHA256 (default: the file named by $COMMISSION_SIGN_KEY; "
                 "load_controller(path, key=...) then refuses files not signed with it).")


def print_summary(result: ValidationResult) -> None:
    """The scenario table (errors in um), the verdict and every failed criterion, on stdout.

    Plain fixed-width text rather than a rich table: it is never truncated or
    wrapped, whatever the terminal width, so every failure line stays whole.
    """
    ex = result.executor or {}
    where = (f"Dask scheduler {ex.get('scheduler')}, {result.workers} worker threads" if ex.get("kind") == "dask"
             else f"{result.workers} threads")
    typer.echo(f"Validation: ARC vs PID baseline on {len(result.runs)} scenarios "
               f"({result.elapsed:.1f} s on {where})")
    typer.echo(summary_text(result))
    if result.evidence is not None:  # what the certificate rests on (commission.evidence)
        typer.echo("\n".join(evidence_lines(result.evidence, result.evidence_rows)))


def print_next_steps(result: ValidationResult, tuning: Any, out_dir: Path, tuning_path: Path, *,
                     signed: bool) -> None:
    """What to do next (commission.next_steps): the export and a first test, or the changes that pass."""
    typer.echo(next_steps(result, tuning, out_dir=str(out_dir), tuning_path=str(tuning_path),
                          signed=signed).text())


VALIDATE_HELP = f"""Simulate ARC and PID on every scenario; exit 0 and write controller.json only if every gate passes (else exit 1).

When only the PID comparison fails, the ARC is written flagged as controller_not_better.json (exit 1).

{escape(gate_help())}
Error limits are checked for the ARC on the scenarios that certify performance, the safety
criteria on every scenario (docs/interface.md section 6).
"""


@app.command("validate", help=VALIDATE_HELP)
@cli_errors
def validate_command(
    tuning: Path = typer.Argument(..., help="tuning.json written by `commission tune`."),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for report.md, the figures, validation.json and controller.json."),
    gate: Optional[Path] = typer.Option(None, "--gate", help="Gate TOML (default: the table's defaults, below)."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing outputs in --out-dir."),
    seed: int = typer.Option(0, "--seed", help="Seed of the Monte-Carlo plants."),
    monte_carlo: int = typer.Option(DEFAULT_MONTE_CARLO, "--monte-carlo", help="Monte-Carlo plants drawn from the theta box (0-10000)."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Simulation threads, 1-256 (default: one per CPU)."),
    sign_key: Optional[Path] = typer.Option(None, "--sign-key", help=SIGN_KEY_HELP),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="tcp://HOST:PORT", help=SCHEDULER_HELP),
) -> None:
    """Simulate ARC and PID on every scenario (the command's help is :data:`VALIDATE_HELP`)."""
    from commission.cli.plots_validate import validation_plots

    err = Console(stderr=True)
    key = load_sign_key(sign_key)
    with StageProgress(err) as bar:
        outcome = run_validate(tuning, out_dir, gate_path=gate, force=force, seed=seed, n_monte_carlo=monte_carlo,
                               progress=bar.callback("simulating"), workers=workers, figures=validation_plots,
                               sign_key=key, scheduler=scheduler)
    print_summary(outcome.result)
    for p in outcome.written:
        typer.echo(f"wrote {p}")
    print_next_steps(outcome.result, outcome.tuning, out_dir, tuning, signed=key is not None)
    if not outcome.result.passed:
        for line in refusal_lines(outcome.result, outcome.tuning):
            typer.echo(line)
        typer.echo(f"no controller.json: the gate failed (see {Path(out_dir) / 'report.md'})")
        raise typer.Exit(EXIT_GATE_FAILED)
