"""``commission validate TUNING --out-dir DIR``: simulate the scenario matrix, check the gate,
write the report and (gate passed) controller.json."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import typer
from rich.console import Console
from rich.markup import escape

from commission.report import refusal_lines, summary_text
from commission.cli.errors import EXIT_GATE_FAILED, cli_errors
from commission.cli.main import app
from commission.cli.options import ValidateFlags, with_validate_flags
from commission.cli.progress import StageProgress
from commission.controller_config import load_sign_key
from commission.evidence import evidence_lines
from commission.formats.gate_toml import gate_help
from commission.next_steps import next_steps
from commission.validate import ValidationResult, run_validate


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
                     signed: bool, also_tried: str | None = None) -> None:
    """What to do next (commission.next_steps): the export and a first test, or the changes that pass."""
    typer.echo(next_steps(result, tuning, out_dir=str(out_dir), tuning_path=str(tuning_path),
                          signed=signed, also_tried=also_tried).text())


VALIDATE_HELP = f"""Simulate ARC and PID on every scenario; exit 0 and write controller.json only if every gate passes (else exit 1).

When only the PID comparison fails, the ARC is written flagged as controller_not_better.json (exit 1).

{escape(gate_help())}
Error limits are checked for the ARC on the scenarios that certify performance, the safety
criteria on every scenario (docs/interface.md section 6).
"""


@app.command("validate", help=VALIDATE_HELP)
@cli_errors
@with_validate_flags(seed_help="Seed of the Monte-Carlo plants.",
                     monte_carlo_help="Monte-Carlo plants drawn from the theta box (0-10000).")
def validate_command(
    tuning: Path = typer.Argument(..., help="tuning.json written by `commission tune`."),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for report.md, the figures, validation.json and controller.json."),
    v: ValidateFlags = None,  # type: ignore[assignment]  # every validation flag (with_validate_flags)
) -> None:
    """Simulate ARC and PID on every scenario (the command's help is :data:`VALIDATE_HELP`)."""
    from commission.cli.plots_validate import validation_plots

    err = Console(stderr=True)
    key = load_sign_key(v.sign_key)
    with StageProgress(err) as bar:
        outcome = run_validate(tuning, out_dir, gate_path=v.gate, force=v.force, seed=v.seed,
                               n_monte_carlo=v.monte_carlo, progress=bar.callback("simulating"), workers=v.workers,
                               figures=validation_plots, sign_key=key, scheduler=v.scheduler)
    print_outcome(outcome.result, outcome.tuning, outcome.written, out_dir, tuning, signed=key is not None)


def print_outcome(result: ValidationResult, tuning: Any, written: Sequence[Path], out_dir: Path, tuning_path: Path,
                  *, signed: bool, also_tried: str | None = None) -> None:
    """The summary, the files written, the next step, and on a failed gate why, then exit 1.

    ``validate`` and ``run`` end the same way (``run`` lists ident.json and tuning.json
    among ``written``).
    """
    print_summary(result)
    for p in written:
        typer.echo(f"wrote {p}")
    print_next_steps(result, tuning, out_dir, tuning_path, signed=signed, also_tried=also_tried)
    if not result.passed:
        for line in refusal_lines(result, tuning):
            typer.echo(line)
        typer.echo(f"no controller.json: the gate failed (see {Path(out_dir) / 'report.md'})")
        raise typer.Exit(EXIT_GATE_FAILED)
