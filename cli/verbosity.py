"""How much the commands print: ``--quiet``, the default, ``--verbose`` (options of ``commission``).

``--quiet`` sends stdout (tables, summaries, ``wrote`` lines) to the null
device and switches off the progress bars; errors, warnings and notes still
go to stderr, and the exit code says what happened.
"""

from __future__ import annotations

import os
import sys
from typing import TextIO

QUIET, NORMAL, VERBOSE = 0, 1, 2
_level = NORMAL
_saved: TextIO | None = None


def level() -> int:
    """The current level: :data:`QUIET`, :data:`NORMAL` or :data:`VERBOSE`."""
    return _level


def set_level(value: int) -> None:
    """Set the level; :data:`QUIET` redirects ``sys.stdout`` until :func:`restore_stdout`."""
    global _level, _saved
    restore_stdout()
    _level = value
    if value == QUIET:
        _saved = sys.stdout
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - closed by restore_stdout


def restore_stdout() -> None:
    """Undo the redirection of :func:`set_level` (and reset the level to normal)."""
    global _level, _saved
    if _saved is not None:
        null, sys.stdout = sys.stdout, _saved
        _saved = None
        if null is not sys.stdout:
            null.close()
    _level = NORMAL
