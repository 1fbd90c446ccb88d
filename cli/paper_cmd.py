"""``commission paper-table``: reproduce Table 1 of Xu & Yao (2001) on the reference plant."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from commission.cli.errors import cli_errors
from commission.cli.main import app
from commission.infra.files import Outputs
from commission.jsonio import write_json_atomic
from commission.paper import format_table, run_paper_table


@app.command("paper-table")
@cli_errors
def paper_table(
    out: Optional[Path] = typer.Option(
        None, "--out", help="Write the table as JSON: {scenario: {controller: {e_M, e_F, e_rms (um), "
                            "u_rms, du_rms (V), c_u, diverged}}}."),
    substeps: int = typer.Option(10, "--substeps", min=1, max=100, help="Plant sub-steps per 0.4 ms sample (1-100)."),
    with_paper: bool = typer.Option(True, "--paper/--no-paper", help="Also print the published Table 1."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing --out file."),
) -> None:
    """Simulate Sets 1-3 and Case 2 with the paper's PID and ARC; print Table 1.

    Reference plant and scenarios: CONTRACT sec. 5.  A diverged run is shown
    as '-' and stored with null indexes and "diverged": true.
    """
    outputs = Outputs(force=force)
    if out is not None:
        outputs.add_file(out, "--out")
    with outputs:
        table = run_paper_table(substeps=substeps)
        if out is not None:
            write_json_atomic(outputs.path(out), table.as_json())
    typer.echo(format_table(table, with_paper=with_paper))
    if out is not None:
        typer.echo(f"wrote {out}")
