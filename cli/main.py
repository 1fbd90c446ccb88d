"""Entry point of the ``commission`` console script."""

from __future__ import annotations

import typer

from commission import __version__

app = typer.Typer(
    name="commission",
    help="Commission a precision linear-motor axis: identify -> tune -> validate (Xu & Yao 2001 ARC).",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


@app.callback(invoke_without_command=True)
def _root(
    version: bool = typer.Option(False, "--version", help="Print the version and exit."),
) -> None:
    if version:
        typer.echo(__version__)
        raise typer.Exit(0)


def _register() -> None:
    # Each command module adds itself to ``app``; imported here so that
    # ``commission --help`` lists every command.
    from commission.cli import commands  # noqa: F401


_register()


def main() -> None:
    """Console-script entry."""
    app()
