"""``commission validate TUNING --out-dir DIR``: simulate the scenario matrix, check the gate,
write the report and (gate passed) controller.json."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import typer
from rich.console import Console

from commission.report import refusal_lines, summary_text
from commission.cli.errors import EXIT_GATE_FAILED, cli_errors
from commission.cli.main import app
from commission.cli.options import SCHEDULER_HELP
from commission.cli.progress import StageProgress
from commission.controller_config import load_sign_key
from commission.evidence import evidence_lines
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


@app.command("validate")
@cli_errors
def validate_command(
    tuning: Path = typer.Argument(..., help="tuning.json written by `commission tune`."),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for report.md, the figures, validation.json and controller.json."),
    gate: Optional[Path] = typer.Option(None, "--gate", help="Gate TOML (default: the documented defaults; see commission.gate)."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing outputs in --out-dir."),
    seed: int = typer.Option(0, "--seed", help="Seed of the Monte-Carlo plants."),
    monte_carlo: int = typer.Option(DEFAULT_MONTE_CARLO, "--monte-carlo", help="Monte-Carlo plants drawn from the theta box (0-10000)."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Simulation threads, 1-256 (default: one per CPU)."),
    sign_key: Optional[Path] = typer.Option(None, "--sign-key", help=SIGN_KEY_HELP),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="tcp://HOST:PORT", help=SCHEDULER_HELP),
) -> None:
    """Simulate ARC and PID on every scenario; exit 0 and write controller.json only if every gate passes (else exit 1).

    Gate TOML (--gate): one table named "gate"; every key optional; checked for the ARC on every scenario. e_F default max(30 LSB, 0.01 %travel); e_M max(200 LSB, 0.2 %travel); e_rms max(15 LSB, 0.005 %travel) -- numbers in m, or strings such as "20 um", "30 lsb", "0.01 %travel"; c_u 1.0; u_max the spec's (reaching it fails); no_divergence true; arc_vs_pid_median 1.0 and arc_vs_pid_p90 1.2 (median and 90th percentile, over the fixed scenarios and over the Monte-Carlo plants, of the factor f with ARC e_rms = f x PID e_rms + arc_vs_pid_slack, default "0.2887 lsb"); arc_vs_pid_e_rms, when given, checks that factor on every scenario. arc_vs_pid_nominal 1.0: per case, ARC e_rms / PID e_rms summed over the nominal and +1-sample scenarios must be below it (no slack: a tie is not a win). When only the PID comparison fails, the ARC is written flagged as controller_not_better.json (exit 1).
    """
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
