"""``commission export controller.json --target c --out-dir DIR``: the validated step as C99."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from commission.cli.errors import cli_errors
from commission.cli.main import app


@app.command("export")
@cli_errors
def export_command(
    controller: Path = typer.Argument(..., help="controller.json written by `commission validate`."),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for the C sources, test vectors and README."),
    target: str = typer.Option("c", "--target", help="c (C99 step, params, test vectors, replay program) or st (IEC 61131-3 function block FB_CommissionArc/FB_CommissionPid)."),
    kind: str = typer.Option("arc", "--controller", help="arc (controller.json) or pid (the validated PID baseline; needs --tuning)."),
    tuning: Optional[Path] = typer.Option(None, "--tuning", help="The tuning.json controller.json was validated from (sha256 checked): the test vectors then run on the validated scenarios; required for --controller pid."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing files in --out-dir."),
) -> None:
    """Write commission_<controller>.h/.c, its const parameters, test vectors, a replay program and a README.

    The C step is translated from the compiled Python step validate simulated (same operations in the same
    order, same packed layout, same fault logic). Build with -std=c99 -O2 -ffp-contract=off, never -ffast-math.
    A controller.json that load_controller refuses is refused here (exit 2, nothing written).
    """
    from commission.export import export_c

    for p in export_c(controller, out_dir, kind=kind, tuning_path=tuning, force=force, target=target):
        typer.echo(f"wrote {p}")
