"""Numbers and input text as the report shows them: rounded for people, escaped for Markdown.

The JSON files keep every digit; the report rounds (:func:`num`, :func:`vec`), shows a run that
diverged as such (:func:`index_cell`), and escapes whatever came from an input file
(:func:`md_code`, :func:`md_text`) so that it cannot become a link, markup or HTML.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from commission.controllers.metrics import INDEX_ROWS


def md_code(text: object) -> str:
    """Text from an input file as a Markdown code span: nothing inside it is a link, markup or HTML.

    A backtick would close the span, so it is shown as ``'``; line breaks become spaces."""
    return "`" + " ".join(str(text).replace("`", "'").split()) + "`"


def md_text(text: object) -> str:
    """Text from an input file in a Markdown paragraph: every character Markdown or HTML would
    interpret (links, emphasis, tables, tags, headings) escaped, line breaks as spaces."""
    out = " ".join(str(text).split())
    out = out.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    for ch in "\\`*_[]|#!":
        out = out.replace(ch, "\\" + ch)
    return out


def num(x: float, digits: int = 4) -> str:
    """A number rounded for people (the JSON files keep every digit)."""
    return f"{x:.{digits}g}" if math.isfinite(x) else str(x)


def vec(v: Sequence[float], digits: int = 4) -> str:
    """A vector of numbers rounded by :func:`num`, as ``[a, b, c]``."""
    return "[" + ", ".join(num(float(x), digits) for x in v) + "]"


def scaled(v: float, fmt: str, scale: float) -> str:
    """``v * scale`` in ``fmt``; ``div.`` for a non-finite value."""
    return fmt.format(v * scale) if math.isfinite(v) else "div."


def index_cell(score: Any, key: str, fmt: str | None = None) -> str:
    """One index of a run (:class:`commission.controllers.metrics.Indexes`) at its display scale and
    format (:data:`commission.controllers.metrics.INDEX_TABLE`; ``fmt`` overrides the format),
    ``diverged`` for a run that did."""
    if score.diverged:
        return "diverged"
    row = INDEX_ROWS[key]
    return scaled(getattr(score, key), fmt or row.fmt, row.scale)
