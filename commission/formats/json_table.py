"""One table per JSON artifact: each field once, by its JSON path, and the strict model built from it.

The TOML inputs (:mod:`commission.formats.table`) are two levels deep (``[section] key``);
the JSON artifacts nest deeper (``$.frequency_response.model.mode_hz``) and hold arrays
(``$.theta.min[2]``).  A :class:`Field` row therefore names its dotted path below ``$``; the
rows of one file build a tree of strict pydantic models (:func:`build_json_model`), one per
object, whose fields are the rows below it.

Additive evolution (CONTRACT: new keys, older files still load): an object accepts keys the
table does not name, unless its row is ``closed`` (a fixed vocabulary such as ``$.units``,
where an unknown key would be a unit the tool could not have written).  A field absent or
``null`` takes its documented default unless the row is ``required``.

The error line of a refused file (:func:`json_error`) names the JSON path of the first
refused value and the rule it broke in the words the artifacts' readers have always used
(``ident.json: $.parameters.vs.value: expected a positive number, got -0.01``), from the
structured pydantic error (its ``type``, ``loc`` and ``input``) and the row: no message text
is parsed.  A check that relates two fields (a theta box whose nominal lies inside it) is not
a field's and stays with the artifact's loader.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Annotated, Callable, Literal, Optional, Sequence

from commission.errors import SchemaError
from pydantic import AfterValidator, BaseModel, ConfigDict, Field as PField, ValidationError, create_model

#: The JSON types of a row (its ``type``) and what they accept.
TYPES = {
    "number": "a finite number",
    "integer": "an integer",
    "string": "a string",
    "boolean": "true or false",
    "object": "an object of the fields below it",
    "sha256": "64 lowercase hex digits",
    "numbers": "a list of finite numbers",
    "strings": "a list of strings",
    "string map": "an object of name -> string",
    "number map": "an object of name -> finite number",
    "map": "an object of name -> an object of the fields below NAME.*",
    "objects": "a list of objects of the fields below NAME.*",
    "any": "any JSON value (read by the code named in the doc)",
}

_SHA256 = r"^[0-9a-f]{64}$"


@dataclass(frozen=True)
class Field:
    """One field of a JSON artifact.

    Attributes
    ----------
    path : str
        Dotted path below ``$`` (``fit.relative_error``).
    type : str
        One of :data:`TYPES`.
    unit : str
        Unit of the value ("" for a dimensionless one or a non-number).
    doc : str
        One line: what the field is.
    required : bool
        The file must hold the key (its value may still be ``null`` when ``nullable``).
    nullable : bool
        A required key may be ``null``.
    sign : str or None
        ``"positive"`` (> 0) or ``"nonneg"`` (>= 0) for a number or integer.
    range : (float, float) or None
        Inclusive range of a number (the spec's range for the same quantity).
    choices : tuple of str
        Allowed values of a string.
    length : int or None
        Exact length of a list of numbers.
    closed : bool
        An object that refuses keys the table does not name.
    check : callable or None
        A rule beyond the type (``value -> None``; raises ``ValueError(message)``, or
        ``ValueError((subpath, message))`` naming an element such as ``[1]``).
    """

    path: str
    type: str
    unit: str
    doc: str
    required: bool = False
    nullable: bool = False
    sign: str | None = None
    range: tuple[float, float] | None = None
    choices: tuple[str, ...] = ()
    length: int | None = None
    closed: bool = False
    check: Callable[[Any], None] | None = None

    @property
    def name(self) -> str:
        return self.path.rsplit(".", 1)[-1]

    @property
    def parent(self) -> str:
        return self.path.rsplit(".", 1)[0] if "." in self.path else ""

    def rule_text(self) -> str:
        """The accepted values beyond the type, as docs show them."""
        parts = []
        if self.choices:
            parts.append("one of " + ", ".join(f'"{c}"' for c in self.choices))
        if self.sign:
            parts.append({"positive": "> 0", "nonneg": ">= 0"}[self.sign])
        if self.range:
            parts.append(f"[{self.range[0]:g}, {self.range[1]:g}]")
        if self.length:
            parts.append(f"{self.length} entries")
        if self.closed:
            parts.append("no other key")
        return ", ".join(parts)


#: The flags of a text row (:func:`rows`) and the Field attribute each sets.
_FLAGS = {"required": ("required", True), "nullable": ("nullable", True), "closed": ("closed", True),
          "positive": ("sign", "positive"), "nonneg": ("sign", "nonneg")}


def rows(text: str, extra: dict[str, dict[str, Any]] | None = None) -> list[Field]:
    """Fields written as a text table: ``path | type | unit | flags``, its doc on the indented lines below.

    ``unit`` is ``-`` for none and ``*`` where ``extra`` gives it (a unit that is another table's);
    ``flags`` a space-separated list of ``required``, ``nullable``,
    ``closed``, ``positive``, ``nonneg`` and ``len=N`` (``-`` for none).  ``extra`` maps a path to
    the attributes that are not text (``choices``, ``range``, ``check``).  The table reads as the
    docs render it, and one table is one literal rather than a run of calls.
    """
    out: list[dict[str, Any]] = []
    for line in text.strip("\n").splitlines():
        if line[:1].isspace():
            out[-1]["doc"] = f"{out[-1]['doc']} {line.strip()}".strip()
            continue
        path, typ, unit, flags = (c.strip() for c in line.split("|"))
        row: dict[str, Any] = {"path": path, "type": typ, "unit": {"-": "", "*": None}.get(unit, unit), "doc": ""}
        for flag in flags.split():
            if flag.startswith("len="):
                row["length"] = int(flag[4:])
            elif flag != "-":
                key, value = _FLAGS[flag]
                row[key] = value
        out.append(row)
    extra = extra or {}
    unknown = set(extra) - {r["path"] for r in out}
    if unknown:
        raise ValueError(f"extra attributes for rows the table does not hold: {sorted(unknown)}")
    given = [r["path"] for r in out if (r["unit"] is None) != ("unit" in extra.get(r["path"], {}))]
    if given:
        raise ValueError(f"a unit is '*' exactly when extra gives it: {given}")
    return [Field(**{**r, **extra.get(r["path"], {})}) for r in out]


def header_rows(kind: str, version: int) -> list[Field]:
    """The two rows every artifact opens with: its ``kind`` and its ``schema_version`` (checked first:
    :func:`check_header`)."""
    return [Field("kind", "string", "", f'"{kind}"', required=True),
            Field("schema_version", "integer", "", f"1..{version}: the version of this layout", required=True)]


def cells(text: str, columns: int = 3) -> dict[str, tuple[str, ...]]:
    """A text table of ``name | cell | ...`` lines: name -> its other cells (stripped; the last may hold ``|``)."""
    out = {}
    for line in text.strip("\n").splitlines():
        name, *rest = (c.strip() for c in line.split("|", columns - 1))
        out[name] = tuple(rest)
    return out


def _bounds(f: Field) -> dict[str, float]:
    out: dict[str, float] = {}
    if f.sign == "positive":
        out["gt"] = 0
    elif f.sign == "nonneg":
        out["ge"] = 0
    if f.range is not None:
        out["ge"], out["le"] = f.range
    return out


def _check(f: Field) -> Any:
    def run(v: Any) -> Any:
        if v is None:
            if f.required and not f.nullable:  # an ``any`` field admits null by its type, not by its row
                raise ValueError(("", "expected a value, got null"))
            return v
        if f.check is not None:
            f.check(v)
        return v
    return AfterValidator(run)


def _leaf(f: Field) -> Any:
    if f.type == "number":
        return Annotated[float, PField(**_bounds(f))]
    if f.type == "integer":
        return Annotated[int, PField(**_bounds(f))]
    if f.type == "string":
        return Literal[f.choices] if f.choices else str  # type: ignore[valid-type]
    if f.type == "boolean":
        return bool
    if f.type == "sha256":
        return Annotated[str, PField(pattern=_SHA256)]
    if f.type == "numbers":
        n = {} if f.length is None else {"min_length": f.length, "max_length": f.length}
        return Annotated[list[Annotated[float, PField(**_bounds(f))]], PField(**n)]
    if f.type == "strings":
        return list[str]
    if f.type == "string map":
        return dict[str, str]
    if f.type == "number map":
        return dict[str, float]
    if f.type == "any":
        return Any
    raise ValueError(f"{f.path}: unknown type {f.type!r}")


def _annotation_and_default(f: Field, sub: type[BaseModel] | None) -> tuple[Any, Any]:
    ann = sub if sub is not None else _leaf(f)
    if f.check is not None:
        ann = Annotated[ann, _check(f)]
    extra: dict[str, Any] = {"unit": f.unit} if f.unit else {}

    def schema_extra(schema: dict[str, Any]) -> None:
        schema.pop("default", None)
        schema.update(extra)

    if f.required:
        ann = Optional[ann] if f.nullable else ann
        return ann, PField(description=f.doc, json_schema_extra=schema_extra)
    return Optional[ann], PField(default=None, description=f.doc, json_schema_extra=schema_extra)


def build_json_model(name: str, fields: Sequence[Field], doc: str, *, root_closed: bool = False) -> type[BaseModel]:
    """The strict pydantic model of a JSON artifact: one sub-model per ``object`` row, built bottom-up."""
    by_parent: dict[str, list[Field]] = {}
    for f in fields:
        by_parent.setdefault(f.parent, []).append(f)
    objects = {f.path: f for f in fields if f.type in ("object", "map", "objects")}

    def model(path: str, closed: bool) -> type[BaseModel]:
        cfg = ConfigDict(strict=True, allow_inf_nan=False, extra="forbid" if closed else "allow")
        members = {}
        for f in by_parent.get(path, []):
            if f.name == "*":  # the value row of a map: built by the map's row
                continue
            sub = model(f.path, f.closed) if f.type == "object" else None
            if f.type in ("map", "objects"):
                star = objects[f.path + ".*"]
                item = model(star.path, star.closed)
                sub = dict[str, item] if f.type == "map" else list[item]  # type: ignore[misc, assignment, valid-type]
            members[f.name] = _annotation_and_default(f, sub)
        title = name + "".join(p[:1].upper() + p[1:] for p in path.replace("_", ".").replace("*", "item").split(".")
                               if p)
        return create_model(title, __config__=cfg, **members)

    missing = [p for p in by_parent if p and p not in objects]
    if missing:
        raise ValueError(f"{name}: fields below {missing} without an object row")
    out = model("", root_closed)
    out.__doc__ = doc
    return out


def sub_model(model: type[BaseModel], path: str) -> type[BaseModel]:
    """The model of the object at dotted ``path`` inside ``model`` (``frequency_response.model``)."""
    for part in path.split("."):
        ann = model.model_fields[part].annotation
        model = next(a for a in _walk(ann) if isinstance(a, type) and issubclass(a, BaseModel))
    return model


def _walk(ann: Any) -> list[Any]:
    import typing
    out = [ann]
    for a in typing.get_args(ann):
        out += _walk(a)
    return out


def check_header(data: Any, kind: str, version: int, source: str, prefix: str = "$") -> None:
    """``kind`` and ``schema_version`` of an artifact root, before its fields: a file of another kind
    or a newer layout is named as such rather than by the first field it lacks."""
    def fail(path: str, msg: str) -> SchemaError:
        return SchemaError(f"{source}: {prefix}{path}: {msg}")
    if not isinstance(data, dict):
        raise fail("", f"expected an object, got {type(data).__name__}")
    for key in ("kind", "schema_version"):
        if data.get(key) is None:
            raise fail(f".{key}", "missing required field")
    k, v = data["kind"], data["schema_version"]
    if not isinstance(k, str):
        raise fail(".kind", f"expected a string, got {k!r}")
    if k != kind:
        raise fail(".kind", f"expected kind {kind!r}, got {k!r}")
    if isinstance(v, bool) or not isinstance(v, int):
        raise fail(".schema_version", f"expected an integer, got {v!r}")
    if v > version or v < 1:
        raise fail(".schema_version", f"unsupported schema_version {v} (this tool reads 1..{version})")


def check_json(data: Any, model: type[BaseModel], fields: Sequence[Field], kind: str, version: int,
               source: str) -> Any:
    """``data`` (a parsed artifact) checked strictly against its table's ``model``; returned as it is.

    Raises
    ------
    SchemaError
        One line naming the JSON path of the first refused value (the header first).
    """
    check_header(data, kind, version, source)
    try:
        model.model_validate(data)
    except ValidationError as exc:
        raise SchemaError(json_error(exc, fields, source=source)) from None
    return data


def unnamed(data: Any, fields: Sequence[Field]) -> list[str]:
    """The JSON paths of the keys in ``data`` that no row names (below ``object``, ``map`` and ``objects``
    rows; an ``any`` row's value is its owner's).  Empty: the table describes every key the file holds."""
    rows_ = {f.path: f for f in fields}
    out: list[str] = []

    def walk(value: Any, path: str, where: str) -> None:
        if not isinstance(value, dict):
            return
        for k, v in value.items():
            row = rows_.get(f"{path}.{k}" if path else k)
            if row is None:
                out.append(f"{where}.{k}")
            elif row.type == "object":
                walk(v, row.path, f"{where}.{k}")
            elif row.type in ("map", "objects") and isinstance(v, (dict, list)):
                items = v.items() if isinstance(v, dict) else ((f"[{i}]", x) for i, x in enumerate(v))
                for name, x in items:
                    walk(x, f"{row.path}.*", f"{where}.{k}" + (name if isinstance(v, list) else f".{name}"))

    walk(data, "", "$")
    return out


def json_path(loc: Sequence[Any]) -> str:
    """``("theta", "min", 2)`` -> ``$.theta.min[2]``."""
    return "$" + "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in loc)


def json_error(exc: ValidationError, fields: Sequence[Field], *, source: str, prefix: str = "$",
               later: Sequence[str] = ()) -> str | None:
    """The one error line of a refused artifact: its first refused value, by JSON path.

    ``prefix`` anchors the paths (``$.identification`` for the identification tuning.json embeds).
    ``later`` names top-level fields the loader checks after every other one (controller.json's
    checksum): their errors are left to it, and None is returned when only they were refused.
    """
    rows = {f.path: f for f in fields}
    errors = [e for e in exc.errors() if not (e["loc"] and e["loc"][0] in later)]
    if not errors:
        return None
    e = errors[0]
    loc = [p for p in e["loc"]]
    v, kind = e["input"], e["type"]
    f = _row(rows, loc)
    if kind == "value_error":
        err = e["ctx"]["error"]
        arg = err.args[0] if err.args else str(err)
        sub, msg = arg if isinstance(arg, tuple) else ("", arg)
        return f"{source}: {prefix}{json_path(loc)[1:]}{sub}: {msg}"
    path = f"{source}: {prefix}{json_path(loc)[1:]}"
    return f"{path}: {_why(kind, v, f, e)}"


def _row(rows: dict[str, Field], loc: Sequence[Any]) -> Field | None:
    """The row of a location: a map's entry (``guarantees.stable``) or a list's element (``runs[3]``)
    standing for ``guarantees.*`` / ``runs.*``; an element of a list of numbers for the list."""
    path = ""
    for k in loc:
        star = f"{path}.*" if path else "*"
        if isinstance(k, int):
            path = star if star in rows else path
            continue
        nxt = f"{path}.{k}" if path else k
        path = star if nxt not in rows and star in rows else nxt
    return rows.get(path)


def _why(kind: str, v: Any, f: Field | None, e: Any) -> str:
    if kind == "missing" or (v is None and kind not in ("model_type", "model_attributes_type", "dict_type")):
        return "missing required field"  # a required number, string, ... given as null: as if absent
    if kind == "extra_forbidden":
        return "unknown field"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"expected an object, got {type(v).__name__}"
    if kind in ("float_type", "finite_number", "float_parsing"):
        return f"expected a finite number, got {v!r}"
    if kind in ("int_type", "int_from_float"):
        return f"expected an integer, got {v!r}"
    if kind == "string_type":
        return f"expected a string, got {v!r}"
    if kind == "bool_type":
        return f"expected true or false, got {v!r}"
    if kind == "literal_error":
        return f"expected one of {list(f.choices) if f else e['ctx']['expected']}, got {v!r}"
    if kind == "string_pattern_mismatch":
        return f"expected a sha256 (64 lowercase hex digits), got {str(v)[:80]!r}"
    if kind == "list_type":
        what = {"strings": "strings", "objects": "objects"}.get(f.type if f is not None else "", "numbers")
        return f"expected a list of {what}, got {type(v).__name__}"
    if kind in ("too_short", "too_long"):
        return f"expected {f.length if f else '?'} numbers, got {len(v)}"
    if f is not None and f.range is not None and kind in ("greater_than_equal", "less_than_equal"):
        unit = f" {f.unit}" if f.unit else ""
        return f"must be within [{f.range[0]:g}, {f.range[1]:g}]{unit}, got {v!r}"
    if kind == "greater_than":
        return f"expected a positive number, got {v!r}"
    if kind == "greater_than_equal":
        noun = "integer" if f is not None and f.type == "integer" else "number"
        return f"expected a non-negative {noun}, got {v!r}"
    return e["msg"]  # a rule no row above names: pydantic's own sentence


def markdown_rows(fields: Sequence[Field]) -> str:
    """The Markdown table of docs/interface.md: JSON path, type, rule, unit, required, doc."""
    rows = ["| field | type | accepted | unit | required | what |", "|---|---|---|---|---|---|"]
    for f in fields:
        req = ("yes, may be null" if f.nullable else "yes") if f.required else ""
        rows.append(f"| `{f.path}` | {f.type} | {_md(f.rule_text())} | {_md(f.unit)} | {req} | {_md(f.doc)} |")
    return "\n".join(rows) + "\n"


def _md(text: str) -> str:
    return text.replace("|", "\\|")


def is_finite_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
