"""Schema-versioned JSON for the artifacts, with strict loading.

Artifacts are frozen dataclasses.  They are saved with sorted keys and an
explicit ``kind`` and ``schema_version`` (never pickle).  Reading is strict
(:func:`read_json`); each artifact's fields are then checked by the model of
its one table (:mod:`commission.formats`), a missing or mistyped field raising
:class:`SchemaError` naming its JSON path, e.g.
``ident.json: $.parameters.M.value: expected a finite number, got 'abc'``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Callable

from commission.errors import SchemaError, UsageError
from commission.infra.files import MAX_JSON_BYTES, read_input_bytes


def sha256_file(path: str | os.PathLike[str]) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def canonical_json(obj: Any) -> str:
    """Deterministic JSON text: sorted keys, 2-space indent, no NaN allowed."""
    return json.dumps(obj, sort_keys=True, indent=2, allow_nan=False) + "\n"


def sha256_json(obj: Any) -> str:
    """sha256 of the canonical JSON text of ``obj``."""
    return hashlib.sha256(canonical_json(obj).encode()).hexdigest()


def write_atomic(path: str | os.PathLike[str], write: Callable[[str], None]) -> None:
    """Run ``write(tmp)`` on a temp file beside ``path``, then rename it over ``path``.

    Readers never see a half-written file; on any failure the temp file is
    removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        # mkstemp creates 0600; artifacts are ordinary files (0666 less the umask).
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` atomically (:func:`write_atomic`)."""
    write_atomic(path, lambda tmp: Path(tmp).write_text(text))


def write_json_atomic(path: str | os.PathLike[str], obj: Any, *, overwrite: bool = True) -> None:
    """Write ``obj`` as canonical JSON via a temp file and an atomic rename.

    Nothing is left half-written: on any failure the temp file is removed.
    """
    path = Path(path)
    if not overwrite and path.exists():
        raise UsageError(f"{path}: exists; pass --force to overwrite")
    write_text_atomic(path, canonical_json(obj))


#: Longest integer literal accepted in a JSON artifact, digits (sign excluded).  The largest
#: integer this tool writes is a seed below 2**63 (19 digits); a longer literal is no plausible
#: value, and one of a few hundred digits would overflow when a reader converts it to float.
MAX_INT_DIGITS = 20


class _Refused:
    """Stands in the parsed tree for a literal refused at parse time, until its JSON path is found."""

    __slots__ = ("why",)

    def __init__(self, why: str) -> None:
        self.why = why


class _Duplicated(dict):
    """An object whose text names ``key`` more than once (the parsed dict keeps the last value)."""

    key: str = ""


def _parse_int(text: str) -> int | _Refused:
    digits = len(text) - (text[0] in "+-")
    if digits > MAX_INT_DIGITS:
        return _Refused(f"an integer literal of {digits} digits ({text[:12]}...): at most {MAX_INT_DIGITS} "
                        "accepted")
    return int(text)


def _parse_float(text: str) -> float | _Refused:
    v = float(text)
    if math.isinf(v):
        return _Refused(f"the number {text[:24]} is beyond the range of a float")
    return v


def _parse_constant(name: str) -> _Refused:
    return _Refused(f"{name} is not a JSON number (a non-finite value is never valid in an artifact)")


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    obj = dict(pairs)
    if len(obj) == len(pairs):
        return obj
    seen: set[str] = set()
    dup = _Duplicated(obj)
    dup.key = next(k for k, _ in pairs if k in seen or seen.add(k))  # type: ignore[func-returns-value]
    return dup


def _first_refused(tree: Any) -> tuple[str, str] | None:
    """JSON path and reason of the first refused literal or duplicate key of ``tree``, in document order.

    Iterative (an explicit stack), so that a tree as deep as the parser allows does not
    exhaust the recursion limit here.
    """
    stack: list[tuple[str, Any]] = [("$", tree)]
    while stack:
        path, node = stack.pop()
        if isinstance(node, _Refused):
            return path, node.why
        if isinstance(node, _Duplicated):
            return f"{path}.{node.key}", "duplicate key (the object names it twice; which one counts is ambiguous)"
        if isinstance(node, dict):
            stack.extend(reversed([(f"{path}.{k}", v) for k, v in node.items()]))
        elif isinstance(node, list):
            stack.extend(reversed([(f"{path}[{i}]", v) for i, v in enumerate(node)]))
    return None


def read_json(path: str | os.PathLike[str]) -> Any:
    """Read a JSON file; a missing, oversized, non-regular or malformed file raises one clear error.

    Every JSON artifact is read here, and the parse itself is strict, so that no reader
    downstream sees what JSON (RFC 8259) leaves ambiguous or Python's parser tolerates:

    - a key repeated within one object (Python keeps the last value silently, while a
      signature or checksum computed by another parser, or a person reading the file,
      may see the first);
    - an integer literal longer than :data:`MAX_INT_DIGITS` digits (a 400-digit integer
      overflows a float conversion far from the file that held it);
    - the literals ``NaN``, ``Infinity`` and ``-Infinity``, which are not JSON, and a number
      such as ``1e999`` that only a non-finite float could hold.

    Each is reported with the JSON path where it occurs.  The parse marks such values and the
    path is looked up only when one was found, so that a good file costs one parse.

    Raises
    ------
    InputFileError
        Missing, a folder, FIFO or device, or larger than :data:`commission.infra.files.MAX_JSON_BYTES`.
    SchemaError
        Not UTF-8, not JSON, nested deeper than the parser's recursion limit, or holding one
        of the values above (``x.json: $.bounds.u_max: duplicate key ...``).
    """
    p = Path(path)
    data = read_input_bytes(p, MAX_JSON_BYTES)  # a regular file of bounded size: no FIFO, no /dev/zero
    refused: list[bool] = []

    def parse_int(text: str) -> int | _Refused:
        v = _parse_int(text)
        if isinstance(v, _Refused):
            refused.append(True)
        return v

    def parse_float(text: str) -> float | _Refused:
        v = _parse_float(text)
        if isinstance(v, _Refused):
            refused.append(True)
        return v

    def parse_constant(name: str) -> _Refused:
        refused.append(True)
        return _parse_constant(name)

    def object_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        obj = _object(pairs)
        if isinstance(obj, _Duplicated):
            refused.append(True)
        return obj

    try:
        tree = json.loads(data.decode("utf-8"), parse_int=parse_int, parse_float=parse_float,
                          parse_constant=parse_constant, object_pairs_hook=object_pairs)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SchemaError(f"{p}: not valid JSON ({exc})") from None
    except RecursionError:
        raise SchemaError(f"{p}: not valid JSON (nested too deeply)") from None
    if refused:
        where = _first_refused(tree)
        if where is not None:
            raise SchemaError(f"{p}: {where[0]}: {where[1]}")
    return tree
