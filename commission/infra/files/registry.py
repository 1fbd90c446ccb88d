"""Which outputs this process has open, and which it has moved into place.

The CLI asks these when a command ends or a signal arrives (``cli/main.py``):
:func:`abort_unfinished` cleans up what an interrupt left open, and
:func:`committed_outputs` says whether the command's files are already in place.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Iterable

if TYPE_CHECKING:
    from commission.infra.files.outputs import Outputs

#: Outputs opened and neither committed nor aborted (:func:`abort_unfinished`).
LIVE: list["Outputs"] = []
#: Targets moved into place since :func:`forget_commits` (:func:`committed_outputs`).
COMMITTED: list[Path] = []


def committed_outputs() -> tuple[Path, ...]:
    """The targets whose files this process moved into place since :func:`forget_commits`.

    The CLI asks this when a signal arrives: once a set is in place the command is
    finished as far as the files go, and its exit code must say so (``cli/main.py``).
    """
    return tuple(COMMITTED)


def forget_commits() -> None:
    """Start a new record for :func:`committed_outputs` (the CLI calls it as each command starts)."""
    COMMITTED.clear()


def unfinished() -> tuple["Outputs", ...]:
    """The :class:`Outputs` opened and neither committed nor aborted yet."""
    return tuple(LIVE)


def abort_unfinished(keep: Iterable["Outputs"] = ()) -> None:
    """Abort every :class:`Outputs` still open but those in ``keep`` (staging, backups and locks removed).

    ``with outputs:`` aborts on any exception, but an interrupt can land between a
    statement and the ``with`` that would clean up after it; the CLI calls this when a
    command ends (keeping what was open before it started, :func:`unfinished`) so that
    no staging folder or lock file outlives the command.
    """
    kept = {id(o) for o in keep}
    for o in list(LIVE):
        if id(o) not in kept:
            o.abort()

