"""Exception hierarchy.

Every error subclasses a builtin as well (as python-control does), so callers
that only know ``ValueError`` or ``FileNotFoundError`` still catch them.  The
CLI turns any :class:`CommissionError` into one line on stderr and exit code 2.
"""

from __future__ import annotations


#: Characters that would break an error message over lines (``str.splitlines`` splits on all of them).
_LINE_BREAKS = {c: repr(c)[1:-1] for c in "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"}


def one_line(text: str) -> str:
    """``text`` with every line break escaped (``\\n``), so that an error stays one line on stderr.

    Messages quote what the user gave (a JSON key, a CSV header, a TOML key), which may hold a newline.
    """
    return "".join(_LINE_BREAKS.get(c, c) for c in text)


class CommissionError(Exception):
    """Base class of every error this tool raises on purpose; its message is always one line."""

    def __init__(self, *args: object) -> None:
        super().__init__(*(one_line(a) if isinstance(a, str) else a for a in args))


class DataError(CommissionError, ValueError):
    """A log or an array is unusable (non-finite, non-monotone, too short ...)."""


class IdentifiabilityError(DataError):
    """The excitation cannot identify a parameter of the requested model."""


class SchemaError(CommissionError, ValueError):
    """A JSON artifact or a TOML spec does not match its schema."""


class SpecError(SchemaError):
    """A user spec (tune spec, validation gate) has a bad key or value."""


class InputFileError(CommissionError, FileNotFoundError):
    """An input file is missing or not readable as the format its name says."""


class OutputError(CommissionError, OSError):
    """An output could not be written or moved into place (a full disk, a read-only file system).

    Raised by :class:`commission.infra.files.Outputs` after it has put everything back: the
    message says which output and why, and nothing was written or replaced.
    """


class UsageError(CommissionError, ValueError):
    """A flag or an argument combination is invalid."""
