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
    sign_key: Optional[Path] = typer.Option(None, "--sign-key", help="Key file: controller.json must carry a valid HMAC-SHA256 signature under it, as load_controller(path, key=...) requires (default: the file named by $COMMISSION_SIGN_KEY)."),
    require_signature: bool = typer.Option(False, "--require-signature", help="Export only signed controllers: refuse when no key is given (--sign-key or $COMMISSION_SIGN_KEY); an unsigned file is refused whenever a key is given."),
) -> None:
    """Write commission_<controller>.h/.c, its const parameters, test vectors, a replay program and a README.

    The C step is translated from the compiled Python step validate simulated (same operations in the same
    order, same packed layout, same fault logic). Build with -std=c99 -O2 -ffp-contract=off, never -ffast-math.
    A controller.json that load_controller refuses is refused here (exit 2, nothing written); with a key
    (--sign-key or $COMMISSION_SIGN_KEY) an unsigned, re-signed or edited file is refused too. No text of
    controller.json reaches the generated code unchecked: provenance strings must have their fixed form,
    the unit is escaped. The files are written under a lock and moved into place together.
    """
    import os

    from commission.controller_config import SIGN_KEY_ENV, load_sign_key
    from commission.export import export_c

    key = load_sign_key(sign_key)
    key_file = sign_key if sign_key is not None else (os.environ.get(SIGN_KEY_ENV) if key is not None else None)
    for p in export_c(controller, out_dir, kind=kind, tuning_path=tuning, force=force, target=target, key=key,
                      require_signature=require_signature, inputs=(key_file,)):
        typer.echo(f"wrote {p}")
