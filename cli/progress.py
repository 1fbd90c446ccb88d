"""The progress bar of the long commands (tune, validate, run), on stderr."""

from __future__ import annotations

from typing import Callable

from rich.console import Console
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeElapsedColumn,
                           TimeRemainingColumn)
from commission.cli import verbosity


class StageProgress:
    """A rich progress bar that appears at the first progress report.

    Commands check all their inputs before any simulation; starting the bar
    at the first completed step (not at a ``0 of N`` announcement) means that
    a command refused for bad input prints only its one error line on stderr.
    Use as a context manager; one task per stage.
    """

    def __init__(self, console: Console | None = None) -> None:
        self._console = console or Console(stderr=True)
        self._bar: Progress | None = None
        self._tasks: dict[str, TaskID] = {}

    def __enter__(self) -> "StageProgress":
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()

    def update(self, stage: str, done: int, total: int) -> None:
        """Report ``done`` of ``total`` steps of ``stage``."""
        if verbosity.level() == verbosity.QUIET:
            return
        if self._bar is None:
            if done <= 0:
                return  # nothing done yet: inputs may still be refused
            # Elapsed, then the estimate of what remains (rich's, from the recent rate of steps).
            self._bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), console=self._console)
            self._bar.start()
        if stage not in self._tasks:
            self._tasks[stage] = self._bar.add_task(stage, total=None)
        self._bar.update(self._tasks[stage], completed=done, total=total)

    def callback(self, stage: str) -> Callable[[int, int], None]:
        """A ``progress(done, total)`` callback for one stage."""
        return lambda done, total: self.update(stage, done, total)
