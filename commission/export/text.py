"""What text from an input file may become in generated code: checked forms and escaped free text.

Everything ``commission export`` writes is code or documentation a target
compiler, a PLC IDE or a Markdown viewer reads.  A string taken from
controller.json must never be able to change what that code is: a unit of
``V */ extern int puts(...); ... /*`` would otherwise close the comment it is
printed in and add a function that runs before ``main``.  The checksum is no
protection (anyone can recompute it) and a signature only says who emitted
the file, so the export treats every string as hostile, by two rules:

* **A field with a fixed form is checked, and refused otherwise**
  (:func:`checked_provenance`): the sha256 fields are exactly 64 lowercase
  hex digits, ``created_utc`` an ISO-8601 UTC time stamp, ``tool_version`` a
  PEP 440 version.  Such a value, once accepted, is made of letters, digits
  and ``.:+-`` only; refusing rather than escaping keeps a damaged provenance
  from reaching a target looking like a real one.  Numbers (sample rate and
  period, the parameters) are never copied as text: they are floats the
  export formats itself.
* **Free text is escaped** for the language it lands in (:func:`c_comment`,
  :func:`st_comment`, :func:`markdown_code`).  Only a conservative set of
  printable ASCII (:data:`SAFE`) is copied; every other character becomes
  ``{U+XXXX}``.  The set is chosen so that no sequence of its characters means
  anything to the readers of the generated files:

  - no ``*`` and no ``/``: no ``*/`` ending a C comment, no ``/*`` or ``//``
    opening one, no ``(*`` or ``*)`` opening or ending an ST comment;
  - no ``?``: no C trigraph such as ``??/`` (a backslash), which the C
    preprocessor replaces *before* comments are removed, even inside them;
  - no backslash: a backslash before a line end splices two lines, also
    before comments are removed; the escape itself is therefore not ``\\u00b7``
    but ``{U+00B7}`` (braces are not in :data:`SAFE`, so an escape cannot be
    confused with literal text);
  - no line break, no control character, no NUL: nothing can start a new
    line, so nothing can become a ``#define`` or ``#error`` directive, and a
    NUL cannot truncate a file for a tool that reads C strings;
  - no ``#``, quotes, backtick, ``<``, ``>``, ``&``, ``$`` or ``;``: no
    directive, string literal, Markdown code-span end, HTML tag, ST string
    escape or statement end, whatever the text is later pasted into.

  Free text is also bounded (:data:`MAX_FREE_TEXT` characters are copied; the
  rest is counted, not shown), so a megabyte-long unit cannot produce a
  source line beyond a compiler's limits.

The three functions share the one rule above on purpose: one small set that
is safe in all three languages is easier to check than three tailored ones.
They are separate functions so that each call site says which language it
writes, and so that a target whose comment syntax differs can get its own
rule without touching the others.  :func:`check_comment_line` is the last
line of defence: the targets pass every comment line they write through it,
so a future line that forgets to escape a field fails the export instead of
reaching a compiler.
"""

from __future__ import annotations

import re
import string
from typing import Any

from commission.errors import SchemaError

#: Characters of free text copied as they are (module docstring); everything else is escaped.
SAFE = frozenset(string.ascii_letters + string.digits + " ._-+^()%[]:,=")
#: Characters an escaped text may contain: :data:`SAFE` and the braces of ``{U+XXXX}``.
ESCAPED = SAFE | {"{", "}"}
#: Characters of free text copied at most; the rest is counted (``{+N more characters}``).
MAX_FREE_TEXT = 80

#: ``provenance`` fields holding a sha256 (``log_sha256`` may be null: no log recorded).
SHA256_FIELDS = ("tuning_sha256", "ident_sha256", "log_sha256")
_SHA256 = re.compile(r"[0-9a-f]{64}", re.ASCII)
#: ISO-8601 time stamp in UTC or with an offset, seconds and optional fraction (validate writes
#: ``2001-06-01T00:00:00Z``).
_ISO_UTC = re.compile(r"\d{4}-(0[1-9]|1[0-2])-(0[1-9]|[12]\d|3[01])T([01]\d|2[0-3]):[0-5]\d:[0-5]\d(\.\d{1,9})?"
                      r"(Z|[+-]([01]\d|2[0-3]):[0-5]\d)", re.ASCII)
#: A PEP 440 version (``0.1.0``, ``1.2rc1``, ``0.1.0.dev3+g1a2b3c``), at most 64 characters.
_VERSION = re.compile(r"v?\d{1,9}(\.\d{1,9}){0,5}((a|b|rc)\d{1,9})?(\.post\d{1,9})?(\.dev\d{1,9})?"
                      r"(\+[A-Za-z0-9]{1,32}(\.[A-Za-z0-9]{1,32}){0,5})?", re.ASCII)


def _escape(text: str) -> str:
    """``text`` with every character outside :data:`SAFE` as ``{U+XXXX}``, bounded (module docstring)."""
    if not isinstance(text, str):
        text = str(text)
    head, rest = text[:MAX_FREE_TEXT], len(text) - MAX_FREE_TEXT
    out = "".join(c if c in SAFE else f"{{U+{ord(c):04X}}}" for c in head)
    return out + (f"{{+{rest} more characters}}" if rest > 0 else "")


def c_comment(text: str) -> str:
    """Free text for a C99 block comment (``/* ... */``), one line, :data:`ESCAPED` characters only."""
    return _escape(text)


def st_comment(text: str) -> str:
    """Free text for an IEC 61131-3 Structured Text comment (``(* ... *)``), one line, :data:`ESCAPED` only."""
    return _escape(text)


def markdown_code(text: str) -> str:
    """Free text for a Markdown paragraph, as an inline code span (nothing in it is a link or markup)."""
    return f"`{_escape(text)}`"


#: What a comment line of each target must never contain, whatever produced it.
_COMMENT_HAZARDS = {
    "c": ("*/", "/*", "//", "??", "\\"),
    "st": ("*)", "(*", "//"),
}


def check_comment_line(line: str, target: str) -> str:
    """``line``, after checking it cannot leave the comment it is written into (module docstring).

    Every character is printable ASCII, and none of the target's comment
    delimiters (for C also trigraphs and the backslash) occurs.

    Raises
    ------
    RuntimeError
        A line the export itself built unsafely: a bug in the export, not bad input.
    """
    bad = [c for c in line if not (" " <= c <= "~")]
    hazards = [h for h in _COMMENT_HAZARDS[target] if h in line]
    if bad or hazards:
        raise RuntimeError(f"export bug: a generated {target} comment line would leave its comment "
                           f"({hazards or bad!r}): {line[:120]!r}")
    return line


def checked_provenance(provenance: Any, source: str = "controller.json") -> dict[str, str | None]:
    """The ``provenance`` fields of a controller, each checked against its fixed form (module docstring).

    Parameters
    ----------
    provenance : ControllerProvenance
    source : str
        File name for the messages.

    Returns
    -------
    dict
        Field name -> its (unchanged) value; ``log_sha256`` may be None.

    Raises
    ------
    SchemaError
        ``controller.json: $.provenance.created_utc: ...`` naming the first field
        not of its form; the value is quoted escaped, never raw.
    """
    out: dict[str, str | None] = {}
    for name in ("tuning_sha256", "ident_sha256", "log_sha256", "tool_version", "created_utc"):
        v = getattr(provenance, name)
        if name == "log_sha256" and v is None:
            out[name] = None
            continue
        if name in SHA256_FIELDS:
            pattern, what = _SHA256, "64 lowercase hex digits (a sha256)"
        elif name == "created_utc":
            pattern, what = _ISO_UTC, "an ISO-8601 time stamp such as 2001-06-01T00:00:00Z"
        else:
            pattern, what = _VERSION, "a version such as 0.1.0"
        if not isinstance(v, str) or pattern.fullmatch(v) is None:
            shown = _escape(v) if isinstance(v, str) else type(v).__name__
            raise SchemaError(f"{source}: $.provenance.{name}: expected {what}, got {shown!r}; "
                              f"export copies no unchecked text into generated code")
        out[name] = v
    return out


__all__ = ["SAFE", "ESCAPED", "MAX_FREE_TEXT", "c_comment", "st_comment", "markdown_code", "check_comment_line",
           "checked_provenance"]
