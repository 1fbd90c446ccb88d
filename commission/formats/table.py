"""One table per input file: each key once, and everything else derived from it.

A format is a tuple of :class:`Key` rows (section, name, type, default or the rule
of a derived default, range, unit, one-line doc).  From the rows this module
builds

* a strict pydantic model (:func:`build_model`): unknown sections and keys,
  wrong types (a bool is not a number, a float is not an integer), non-finite
  numbers and values outside the inclusive range are refused;
* the error line of a refused value (:func:`first_error`), naming the key path
  (``controller.sample_rate = -2500.0 Hz must be positive``) in the order the
  file gives the keys, so that the first bad key of the file is the one named;
* the versioned JSON Schema (:func:`json_schema`) written to ``docs/schemas/``;
* the key list of a command's ``--help`` (:func:`help_lines`) and the Markdown
  table of ``docs/interface.md`` (:func:`markdown_table`).

Why pydantic (v2)
-----------------
It is already installed with typer (typer depends on it), so it adds no package.
Its validation errors are structured (``type``, ``loc``, ``input``, ``ctx``):
the path and the rule a value broke come from the library, not from parsing
message text (msgspec reports one error as a sentence), so the one-line errors
users and tests know stay exactly as they were.  Strict mode refuses
``true`` for a number and ``2.5`` for an integer, ``allow_inf_nan=False``
refuses inf and nan, and ``model_json_schema`` exports the schema with the
ranges, defaults and our ``unit`` and ``default_rule`` annotations.

The sign words of an error follow from the range: a key whose range starts
above 0, or is open at 0, "must be positive", one whose range starts at 0
"must not be negative", one open at both finite ends "must be between" them,
and a value past either end "is outside the accepted range".
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Annotated, Literal, Mapping, Sequence, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, create_model
from pydantic.json_schema import GenerateJsonSchema

#: Strict: no coercion (bool is not a number, 2.5 is not an integer), no unknown key, no inf/nan.
_CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


@dataclass(frozen=True)
class Scaled:
    """A default that is a fraction of another key's resolved value (``0.08 x controller.sample_rate``)."""

    fraction: float
    of: str

    def text(self) -> str:
        return f"{self.fraction:g} x {self.of}"


class Length:
    """The type of a length key: a number (metres) or a string ``"<number> <unit>"`` (``"20 um"``, ``"30 lsb"``).

    The model accepts a number within the key's range, or a string matching :attr:`PATTERN`
    whose number is within that range; the unit words and their factors are :attr:`UNITS` (to
    metres) and :attr:`RELATIVE` (resolved by the reader: encoder steps, percent of the travel).
    """

    UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9}
    RELATIVE = ("lsb", "%travel")
    PATTERN = r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(m|mm|um|µm|nm|lsb|%travel)\s*$"


@dataclass(frozen=True)
class Key:
    """One key of an input file.

    Attributes
    ----------
    section, name : str
        TOML table and key: ``[section] name = ...``.
    type : type
        ``float``, ``int``, ``bool``, ``str`` (with ``choices``: one of them), :class:`Length` or
        ``list`` (an array of tables); a key with ``checked_by`` is read by another reader.
    default : object
        The value of an absent key; ``None`` when the default is derived (``rule``).
    range : (float, float) or None
        Inclusive accepted range of a number.
    unit : str
        Unit of the value ("" for a dimensionless one).
    doc : str
        One line: what the key is.
    rule : Scaled or str or object or None
        A derived default: a :class:`Scaled` fraction of another key (resolved by the loader),
        an object with a ``text()`` method that says the rule (its reader resolves it), or a sentence (resolved where the data is, e.g. from ident.json); ``{default}`` in the
        sentence is replaced by the formatted ``default``.
    choices : tuple of str
        Allowed values of a ``str`` key.
    attr : str or None
        Name of the attribute in the resolved object; default: ``name``.
    checked_by : str or None
        Where a key outside the number/choice types is checked (its model type is then any value).
    open : (bool, bool)
        Whether the low and the high end of ``range`` are excluded (``(0, inf)`` open at 0: positive).
    required : bool
        The file must give the key (its section then too); the loader checks it after the values.
    """

    section: str
    name: str
    type: type
    default: Any
    range: tuple[float, float] | None
    unit: str
    doc: str
    rule: Any = None
    choices: tuple[str, ...] = ()
    attr: str | None = None
    checked_by: str | None = None
    open: tuple[bool, bool] = (False, False)
    required: bool = False

    @property
    def path(self) -> str:
        return f"{self.section}.{self.name}"

    @property
    def field_name(self) -> str:
        return self.attr or self.name

    @property
    def shown_unit(self) -> str:
        """The unit as docs show it: a unit that depends on the file (``{q}/s``) with the symbols q, u."""
        return self.unit.format(q="q", u="u")

    def default_text(self) -> str:
        """The default as a user reads it: a value with its unit, or the rule."""
        unit = f" {self.shown_unit}" if self.shown_unit else ""
        if self.required:
            return "required"
        if isinstance(self.rule, Scaled):
            return self.rule.text() + unit
        if self.rule is not None and not isinstance(self.rule, str):
            return self.rule.text()
        value = "" if self.default is None else fmt(self.default) + unit
        if isinstance(self.rule, str):
            return self.rule.format(default=value)
        return value if value else "absent"

    def range_text(self) -> str:
        """``[1, 100000]``, ``(0, inf)``: the accepted range, brackets saying which ends are included."""
        if self.range is None:
            return ""
        lo, hi = self.range
        return f"{'(' if self.open[0] or lo == -math.inf else '['}{lo:g}, {hi:g}{')' if self.open[1] or hi == math.inf else ']'}"

    def type_text(self) -> str:
        if self.choices:
            return " | ".join(f'"{c}"' for c in self.choices)
        if self.type is list:
            return "array of tables" if self.checked_by else "list of numbers"
        return {float: "number", int: "integer", str: "string", bool: "boolean", Length: "length"}[self.type]


#: The type words of a text table (:func:`keys`).
_TYPE_WORDS = {"number": float, "integer": int, "string": str, "boolean": bool, "list": list}


def _range_of(text: str) -> tuple[tuple[float, float] | None, tuple[bool, bool]]:
    """``(0, inf)`` -> ((0, inf), (True, False)): a bracket excludes a finite end (as :meth:`Key.range_text`)."""
    if text == "-":
        return None, (False, False)
    lo, hi = (float(v) for v in text[1:-1].split(","))
    return (lo, hi), (text[0] == "(" and math.isfinite(lo), text[-1] == ")" and math.isfinite(hi))


def keys(text: str, extra: Mapping[str, Mapping[str, Any]] | None = None) -> tuple[Key, ...]:
    """Keys written as a text table: ``section.name | type | default | range | unit | rule``, its doc below.

    ``type`` is number, integer, string, boolean or list; ``default`` a Python literal, ``required``
    or ``-`` (none); ``range`` as :meth:`Key.range_text` writes it (a bracket includes a finite end,
    a parenthesis excludes it) or ``-``; ``unit`` and ``rule`` ``-`` for none; the indented lines
    below a key are its doc.  ``extra`` maps a key's path to the attributes that are not text
    (``choices``).  The table reads as the docs render it, one literal rather than a run of calls.
    """
    import ast

    out: list[dict[str, Any]] = []
    for line in text.strip("\n").splitlines():
        if line[:1].isspace():
            out[-1]["doc"] = f"{out[-1]['doc']} {line.strip()}".strip()
            continue
        path, typ, default, rng, unit, rule = (c.strip() for c in line.split("|"))
        section, name = path.split(".")
        row: dict[str, Any] = {"section": section, "name": name, "type": _TYPE_WORDS[typ], "doc": "",
                               "default": None if default in ("-", "required") else ast.literal_eval(default),
                               "required": default == "required", "unit": "" if unit == "-" else unit,
                               "rule": None if rule == "-" else rule}
        row["range"], row["open"] = _range_of(rng)
        out.append(row)
    extra = extra or {}
    unknown = set(extra) - {f"{r['section']}.{r['name']}" for r in out}
    if unknown:
        raise ValueError(f"extra attributes for keys the table does not hold: {sorted(unknown)}")
    return tuple(Key(**r, **extra.get(f"{r['section']}.{r['name']}", {})) for r in out)


def fmt(value: Any) -> str:
    """A default as written in help and docs (``2500``, ``1e-05``, ``"motor"``)."""
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    return f"{value:g}"


def sections(keys: Sequence[Key]) -> dict[str, list[Key]]:
    """Section -> its keys, in table order."""
    out: dict[str, list[Key]] = {}
    for k in keys:
        out.setdefault(k.section, []).append(k)
    return out


def _annotation(k: Key) -> Any:
    if k.checked_by is not None:
        return Any
    if k.choices:
        return Literal[k.choices]  # type: ignore[valid-type]
    bounds: dict[str, float] = {}
    if k.range is not None:
        lo, hi = k.range
        if math.isfinite(lo):
            bounds["gt" if k.open[0] else "ge"] = lo
        if math.isfinite(hi):
            bounds["lt" if k.open[1] else "le"] = hi
    if k.type is list:  # a list of numbers, each within the range
        return list[Annotated[float, Field(**bounds)]]
    if k.type is Length:  # a number (m) or "<number> <unit>" with that number within the range
        return Union[Annotated[float, Field(**bounds)],
                     Annotated[str, Field(pattern=Length.PATTERN), AfterValidator(_length_text(k))]]
    return Annotated[k.type, Field(**bounds)]


def _length_text(k: Key) -> Any:
    """The check of a length string's number against the key's range (the pattern checked the form)."""
    lo, hi = k.range if k.range is not None else (-math.inf, math.inf)

    def check(text: str) -> str:
        m = re.match(Length.PATTERN, text)
        v = float(m.group(1)) if m else math.nan
        if not (math.isfinite(v) and (v > lo if k.open[0] else v >= lo) and (v < hi if k.open[1] else v <= hi)):
            raise ValueError(f"{v!r} is outside {k.range_text()}")
        return text

    return check


def _field(k: Key) -> Any:
    extra: dict[str, Any] = {"unit": k.shown_unit} if k.unit else {}
    if k.rule is not None:
        extra["default_rule"] = k.default_text()
    if k.checked_by is not None:
        extra.update(checked_by=k.checked_by, type={str: "string", list: "array"}[k.type])

    def schema_extra(schema: dict[str, Any]) -> None:
        if k.default is None:
            schema.pop("default", None)
        schema.update(extra)

    default = list(k.default) if isinstance(k.default, tuple) else k.default
    return Field(default=default, description=k.doc, json_schema_extra=schema_extra)


def build_model(name: str, keys: Sequence[Key], doc: str) -> type[BaseModel]:
    """The strict pydantic model of a file: one sub-model per section.

    Every key is optional in the model; the schema lists the ``required`` ones and the
    loader checks them after the values, so that a bad value is named before a missing key.
    """
    secs = {}
    for section, ks in sections(keys).items():
        required = [k.name for k in ks if k.required]
        config = ConfigDict(**_CONFIG, json_schema_extra={"required": required}) if required else _CONFIG
        sub = create_model(f"{name}_{section}", __config__=config,
                           **{k.name: (_annotation(k), _field(k)) for k in ks})
        secs[section] = (sub, Field(default=None, description=f"[{section}]", json_schema_extra=_no_default))
    needed = list(dict.fromkeys(k.section for k in keys if k.required))
    model = create_model(name, __config__=ConfigDict(**_CONFIG, json_schema_extra={"required": needed})
                         if needed else _CONFIG, **secs)
    model.__doc__ = doc
    return model


def _no_default(schema: dict[str, Any]) -> None:
    schema.pop("default", None)  # an absent section: every key at its default


class _NoTitles(GenerateJsonSchema):
    """No generated ``title`` per property (the key name says it)."""

    def field_title_should_be_set(self, schema: Any) -> bool:
        return False


def json_schema(model: type[BaseModel], schema_id: str, version: int) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a file, with its ``$id`` and ``version``."""
    out = model.model_json_schema(schema_generator=_NoTitles)
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": schema_id, "version": version, **out}


def first_error(exc: ValidationError, data: Mapping[str, Any], keys: Sequence[Key], *, source: str, prefix: str,
                extra_known: Mapping[str, Sequence[str]] = {}, units: Mapping[str, str] = {}) -> str:
    """The one error line of a refused file: its first bad key in the file's order.

    Parameters
    ----------
    exc : ValidationError
        The model's errors.
    data : mapping
        The validated input (sections -> keys -> values).
    source, prefix : str
        File name (first word) and key-path prefix (``$.spec.`` inside tuning.json).
    extra_known : mapping
        Section -> keys read outside the table, listed with the known keys of an unknown-key error.
    units : mapping
        Values of the symbols of a unit that depends on the file (``{"q": "rad", "u": "V"}``).
    """
    by_path = {(k.section, k.name): k for k in keys}
    secs = list(sections(keys))

    def order(e: Any) -> tuple[int, int]:
        loc = e["loc"]
        sec = list(data).index(loc[0]) if loc[0] in data else len(data)
        tbl = data.get(loc[0])
        key = list(tbl).index(loc[1]) if len(loc) > 1 and isinstance(tbl, Mapping) and loc[1] in tbl else 0
        return sec, key

    e = min(exc.errors(), key=order)
    loc, raw, kind = e["loc"], e["input"], e["type"]
    section = str(loc[0])
    if len(loc) == 1:
        if kind == "extra_forbidden":
            return f"{source}: {prefix}{section}: unknown section (known: {', '.join(secs)})"
        return f"{source}: {prefix}{section}: expected a table, got {raw!r}"
    name = str(loc[1])
    path = f"{source}: {prefix}{section}.{name}"
    if kind == "extra_forbidden":
        known = [k.name for k in sections(keys)[section] if k.checked_by is None] + list(extra_known.get(section, ()))
        return f"{path}: unknown key (known in [{section}]: {', '.join(known)})"
    k = by_path[(section, name)]
    unit = k.unit.format(**units) if units else k.unit
    u = f" {unit}" if unit else ""
    if k.type is list:
        raw = data[section][name]
        lo = k.range[0] if k.range is not None else -math.inf
        what = "positive numbers" if lo == 0 and k.open[0] else "numbers"
        return f"{path} = {raw!r}: expected a list of {what}{u and ' in' + u}"
    if k.choices:
        return f"{path} = {raw!r}: expected one of {', '.join(map(repr, k.choices))}"
    if k.type is int and (isinstance(raw, bool) or not isinstance(raw, int)):
        return f"{path} = {raw!r}: expected an integer"
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
        return f"{path} = {raw!r}: expected a finite number{u and ' in' + u}"
    val = k.type(raw)
    lo, hi = k.range  # type: ignore[misc]
    if all(k.open) and math.isfinite(lo) and math.isfinite(hi):
        return f"{path} = {val!r} must be between {lo:g} and {hi:g}"
    if (lo > 0 or (lo == 0 and k.open[0])) and not val > 0:
        return f"{path} = {val!r}{u} must be positive"
    if lo >= 0 and val < 0:
        return f"{path} = {val!r}{u} must not be negative"
    return f"{path} = {val!r}{u} is outside the accepted range {k.range_text()}{u}"


def help_lines(keys: Sequence[Key]) -> list[str]:
    """Two ``--help`` lines per key: ``section.key = default unit``, then what it is, indented."""
    return [line for k in keys for line in (f"  {k.path} = {k.default_text()}", f"      {k.doc}")]


def markdown_table(keys: Sequence[Key]) -> str:
    """The Markdown table of docs/interface.md: key, type, default, range, unit, doc."""
    rows = ["| key | type | default | range | unit | what |", "|---|---|---|---|---|---|"]
    for k in keys:
        rows.append(f"| `{k.path}` | {_md(k.type_text())} | {_md(k.default_text())} | {k.range_text()} | "
                    f"{k.shown_unit} | "
                    f"{_md(k.doc)} |")
    return "\n".join(rows) + "\n"


def _md(text: str) -> str:
    """Text for a Markdown table cell (a ``|`` escaped)."""
    return text.replace("|", "\\|")
