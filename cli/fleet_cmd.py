"""``commission fleet MANIFEST --out-dir DIR``: commission every axis of a manifest (commission.fleet)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.console import Console

from commission.cli.errors import cli_errors
from commission.cli.main import app
from commission.cli.options import SCHEDULER_HELP


@app.command("fleet")
@cli_errors
def fleet_command(
    manifest: Path = typer.Argument(..., help="Fleet manifest: TOML (an axis table per axis: name, log, spec, "
                                              "gate) or CSV (columns name,log,spec,gate); paths relative to it."),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder: <name>/ per axis (run's files), fleet.json, "
                                                        "fleet.md, fleet.png."),
    seed: int = typer.Option(0, "--seed", help="Seed of every axis's tuning search and Monte-Carlo plants."),
    monte_carlo: Optional[int] = typer.Option(None, "--monte-carlo", help="Monte-Carlo plants per axis (default 64)."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Simulation threads of each axis's run, 1-256 "
                                                                  "(default: one per CPU)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", metavar="tcp://HOST:PORT", help=SCHEDULER_HELP
                                            + " On a cluster each axis is one task."),
    force: bool = typer.Option(False, "--force", help="Write into an --out-dir that holds files but no fleet.json."),
) -> None:
    """Commission many axes (one `run` each); exit 0 only if every axis passed, 1 if a gate failed or an axis errored.

    A rerun into the same --out-dir skips the axes whose inputs (log, spec, gate, seed, --monte-carlo) are unchanged and whose files are complete.
    """
    from commission.cli.plots import identification_plots
    from commission.cli.plots_fleet import fleet_plot
    from commission.cli.plots_validate import validation_plots
    from commission.infra.executor import LocalExecutor, make_executor, resolve_scheduler
    from commission.fleet import load_manifest, run_fleet, verdict_text

    err = Console(stderr=True)
    load_manifest(manifest)  # a bad manifest is exit 2 before connecting anywhere
    address = resolve_scheduler(scheduler)
    ex = make_executor(address) if address else LocalExecutor(1)

    def progress(row, done, total):
        what = verdict_text(row) + (" (unchanged, kept)" if row.get("resumed") else "")
        extra = f": {row['error']}" if row["status"] == "error" else ""
        err.print(f"[{done}/{total}] {row['name']}: {what} in {row['elapsed_s']:.1f} s{extra}", highlight=False,
                  markup=False)

    try:
        doc, written = run_fleet(manifest, out_dir, seed=seed, n_monte_carlo=monte_carlo, workers=workers,
                                 executor=ex, figures=validation_plots, ident_figures=identification_plots,
                                 fleet_figure=fleet_plot, force=force, progress=progress)
    finally:
        ex.close()
    s = doc["summary"]
    typer.echo(f"fleet: {s['axes']} axes, {s['passed']} passed, {s['failed']} failed the gate, {s['errors']} errors; "
               f"outliers: {', '.join(s['outliers']) or 'none'}")
    for r in doc["axes"]:
        if r["status"] == "error":
            typer.echo(f"  {r['name']}: ERROR {r['error']}")
    for p in written:
        typer.echo(f"wrote {p}")
    raise typer.Exit(s["exit_code"])
