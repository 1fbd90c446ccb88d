"""The one place that turns :class:`CommissionError` into exit code 2."""

from __future__ import annotations

import functools
from typing import Callable, TypeVar

import typer

from commission.errors import CommissionError, one_line

F = TypeVar("F", bound=Callable[..., object])

EXIT_OK = 0
EXIT_GATE_FAILED = 1
EXIT_BAD_INPUT = 2


def cli_errors(fn: F) -> F:
    """Decorate a command: a CommissionError becomes one stderr line and exit 2.

    The message already names the file, field or flag; no traceback is shown.
    Commands write their outputs only after all checks pass, so nothing is
    half-written when this fires: a failure to write (a full disk) comes here as
    :class:`commission.errors.OutputError` once :class:`commission.infra.files.Outputs`
    has put everything back.  An :class:`OSError` that says the disk cannot take a
    file (:data:`commission.infra.files.WRITE_ERRNOS`) but escaped ``Outputs`` is
    reported the same way, as one line, rather than as an internal error.
    """

    @functools.wraps(fn)
    def wrapper(*args: object, **kwargs: object) -> object:
        try:
            return fn(*args, **kwargs)
        except CommissionError as exc:
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None
        except OSError as exc:
            from commission.infra.files import WRITE_ERRNOS

            if exc.errno not in WRITE_ERRNOS:
                raise
            where = f"{exc.filename}: " if exc.filename is not None else ""
            typer.echo(one_line(f"error: {where}cannot write ({exc.strerror or exc})"), err=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None

    return wrapper  # type: ignore[return-value]
