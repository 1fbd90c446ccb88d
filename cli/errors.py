"""The one place that turns :class:`CommissionError` into exit code 2."""

from __future__ import annotations

import functools
from typing import Callable, TypeVar

import typer

from commission.errors import CommissionError

F = TypeVar("F", bound=Callable[..., object])

EXIT_OK = 0
EXIT_GATE_FAILED = 1
EXIT_BAD_INPUT = 2


def cli_errors(fn: F) -> F:
    """Decorate a command: a CommissionError becomes one stderr line and exit 2.

    The message already names the file, field or flag; no traceback is shown.
    Commands write their outputs only after all checks pass, so nothing is
    half-written when this fires.
    """

    @functools.wraps(fn)
    def wrapper(*args: object, **kwargs: object) -> object:
        try:
            return fn(*args, **kwargs)
        except CommissionError as exc:
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None

    return wrapper  # type: ignore[return-value]
