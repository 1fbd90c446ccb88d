"""Errors raised by the identification numerics.

Both subclass :class:`ValueError` so that callers who only know the builtin
still catch them; the pipeline layer (``commission``) re-raises them as its own
``DataError``/``IdentifiabilityError`` with the file name attached.
"""

from __future__ import annotations


class SignalError(ValueError):
    """An input array is malformed: wrong shape, non-finite sample, bad time base.

    Attributes
    ----------
    segment : int or None
        Index of the offending log when several are fitted together as segments
        (the pipeline names its file), else None.
    """

    def __init__(self, message: str, *, segment: int | None = None) -> None:
        super().__init__(message)
        self.segment = segment


class NotIdentifiableError(ValueError):
    """The excitation in the log cannot identify a parameter of the requested model."""


class StribeckNotIdentifiableError(NotIdentifiableError):
    """The log shows no Stribeck curve it can support (the Coulomb model may still fit it)."""


class MassNotIdentifiableError(NotIdentifiableError):
    """The log carries no usable acceleration content: M is not identified (the rest may be)."""
