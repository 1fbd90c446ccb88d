"""Exception hierarchy.

Every error subclasses a builtin as well (as python-control does), so callers
that only know ``ValueError`` or ``FileNotFoundError`` still catch them.  The
CLI turns any :class:`CommissionError` into one line on stderr and exit code 2.
"""

from __future__ import annotations


class CommissionError(Exception):
    """Base class of every error this tool raises on purpose."""


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


class UsageError(CommissionError, ValueError):
    """A flag or an argument combination is invalid."""
