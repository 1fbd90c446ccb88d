"""Translate the compiled step functions (numba-Python) into C99, statement by statement.

The ARC and PID steps exist once, as the ``@njit`` functions of
:mod:`commission.controllers.arc` and :mod:`commission.controllers.pid` that
``validate`` simulates and :mod:`commission.runtime` runs.  The exported C is
generated from their Python source, so it cannot drift from them: the same
operations in the same order (every binary operation is parenthesised as
Python's AST groups it, so the C compiler evaluates exactly Python's
left-to-right order), the same packed parameter and state layout (the
``P_*``/``S_*``/``G_*`` constants are read from the module, never retyped)
and the same fault logic.

Why a hand-written translator: no maintained library translates
numba-Python to C99 -- numba emits LLVM IR for the host, not portable C;
Cython's C needs the CPython runtime; Pythran and Shed Skin emit C++ with
their own runtimes.  The step functions use a small scalar subset of Python,
and this module translates exactly that subset and refuses anything else
with :class:`TranslationError` (function and line), so a change to a step
that the translator cannot follow fails the export and its test instead of
producing different C:

* parameters: the packed-parameter and state arrays (``double *``) and
  scalars (``double``); a function that returns a tuple gets an output array;
* statements: assignment to a name or an array element, ``+=``/``-=``,
  tuple unpacking of a call, ``if``/``elif``/``else``, ``for i in range(...)``,
  ``return``; docstrings are dropped;
* expressions: float and int literals, ``+ - * /``, unary ``-``, comparisons,
  ``and``/``or``/``not``, ``math.isfinite``, ``math.atan``, ``abs``,
  ``math.pi``, ``math.inf``, ``X.shape[0]`` of a state array, calls of the
  other translated functions, and module constants (ints and floats).

:class:`StTranslator` emits the same functions as methods of an IEC 61131-3
Structured Text function block (:mod:`commission.export.st_target`).

Every local is a ``double`` (Python floats are IEEE doubles, as numba
compiles them) except ``for`` loop counters and locals assigned an index
expression (int literals, int module constants and + - * of them), which are
``int``; a local that is both is refused.  Float literals are
written with ``repr`` (shortest round-trip), which C99 compilers read
exactly.
"""

from __future__ import annotations

import ast
import inspect
import math
import textwrap
from dataclasses import dataclass, field
from typing import Any, ClassVar, Mapping, Sequence


class TranslationError(ValueError):
    """A step function uses Python the C translator does not follow (names the function and line)."""


_MATH_CALLS = {"isfinite": "isfinite", "atan": "atan", "floor": "floor", "sqrt": "sqrt"}
_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_CMPOPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


def c_float(x: float) -> str:
    """A C99 double literal that reads back as exactly ``x``."""
    if math.isnan(x):
        return "NAN"
    if math.isinf(x):
        return "INFINITY" if x > 0 else "(-INFINITY)"
    r = repr(float(x))
    return r if ("." in r or "e" in r or "n" in r) else r + ".0"


@dataclass
class _Func:
    name: str
    node: ast.FunctionDef
    arrays: dict[str, bool]  # array parameter -> const
    tuple_len: int = 0  # > 0: returns a tuple of this length through `out`
    returns_value: bool = False


@dataclass
class Translator:
    """Translate ``functions`` of ``module`` into C.

    Parameters
    ----------
    module : module
        Where the functions and their constants live.
    functions : sequence of str
        Function names, callees before callers.
    arrays : mapping
        Array parameter name -> (C length macro of its ``shape[0]``, const?),
        e.g. ``{"p": ("NP", True), "s": ("NS", False)}``.
    prefix : str
        Prefix of every emitted C name (``commission_arc_``); constants are
        upper-cased (``COMMISSION_ARC_P_TS``).
    """

    module: Any
    functions: Sequence[str]
    arrays: Mapping[str, tuple[str, bool]]
    prefix: str
    used_constants: dict[str, Any] = field(default_factory=dict)
    _funcs: dict[str, _Func] = field(default_factory=dict)

    # The target's words for what every target writes alike (:meth:`expr`, :meth:`stmts`).
    ASSIGN: ClassVar[str] = "="
    NOT: ClassVar[str] = "!"
    AND: ClassVar[str] = " && "
    OR: ClassVar[str] = " || "
    CMPOPS: ClassVar[Mapping[type, str]] = _CMPOPS
    PI: ClassVar[str] = c_float(math.pi)
    INF: ClassVar[str] = "INFINITY"
    RETURN: ClassVar[str] = "return;"
    RETURN_ARRAY: ClassVar[str] = "out_"  # the caller's buffer of a tuple-returning function
    IF_WORDS: ClassVar[tuple[tuple[str, str], tuple[str, str], str, str]] = (
        ("if (", ") {"), ("} else if (", ") {"), "} else {", "}")

    def const_name(self, name: str) -> str:
        return f"{self.prefix.upper()}{name}"

    def func_name(self, name: str) -> str:
        return f"{self.prefix}k_{name.lstrip('_')}"

    # ------------------------------------------------------------------ parse
    def _parse(self, name: str) -> _Func:
        fn = getattr(self.module, name)
        py = getattr(fn, "py_func", fn)
        src = textwrap.dedent(inspect.getsource(py))
        tree = ast.parse(src)
        node = tree.body[0]
        if not isinstance(node, ast.FunctionDef):  # pragma: no cover - getsource of a function
            raise TranslationError(f"{name}: not a function")
        _, first_line = inspect.getsourcelines(py)
        ast.increment_lineno(tree, first_line - 1)
        arrays = {a.arg: self.arrays[a.arg][1] for a in node.args.args if a.arg in self.arrays}
        f = _Func(name, node, arrays)
        for sub in ast.walk(node):
            if isinstance(sub, ast.Return) and sub.value is not None:
                if isinstance(sub.value, ast.Tuple):
                    f.tuple_len = len(sub.value.elts)
                else:
                    f.returns_value = True
        if f.tuple_len and f.returns_value:
            raise TranslationError(f"{name}: returns both a tuple and a scalar")
        return f

    def fail(self, f: _Func, node: ast.AST, what: str) -> TranslationError:
        line = getattr(node, "lineno", "?")
        return TranslationError(f"{self.module.__name__}.{f.name}, line {line}: {what} is not translated to C "
                                f"(see commission.export.translate)")

    # ------------------------------------------------------------------ expressions
    def expr(self, f: _Func, e: ast.AST) -> str:
        if isinstance(e, ast.Constant):
            if isinstance(e.value, bool) or not isinstance(e.value, (int, float)):
                raise self.fail(f, e, f"the constant {e.value!r}")
            return c_float(e.value) if isinstance(e.value, float) else str(e.value)
        if isinstance(e, ast.Name):
            if e.id in self._locals or e.id in self._params:
                return e.id
            val = getattr(self.module, e.id, None)
            if isinstance(val, (int, float)) and not isinstance(val, bool):
                self.used_constants[e.id] = val
                return self.const_name(e.id)
            raise self.fail(f, e, f"the name {e.id!r}")
        if isinstance(e, ast.BinOp) and type(e.op) in _BINOPS:
            return f"({self.expr(f, e.left)} {_BINOPS[type(e.op)]} {self.expr(f, e.right)})"
        if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.USub):
            return f"(-{self.expr(f, e.operand)})"
        if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.Not):
            return f"({self.NOT}{self.expr(f, e.operand)})"
        if isinstance(e, ast.BoolOp):
            op = self.AND if isinstance(e.op, ast.And) else self.OR
            return "(" + op.join(self.expr(f, v) for v in e.values) + ")"
        if isinstance(e, ast.Compare):
            if len(e.ops) != 1 or type(e.ops[0]) not in self.CMPOPS:
                raise self.fail(f, e, "a chained or non-arithmetic comparison")
            return f"({self.expr(f, e.left)} {self.CMPOPS[type(e.ops[0])]} {self.expr(f, e.comparators[0])})"
        if isinstance(e, ast.Attribute) and isinstance(e.value, ast.Name) and e.value.id == "math":
            if e.attr == "pi":
                return self.PI
            if e.attr == "inf":
                return self.INF
            raise self.fail(f, e, f"math.{e.attr}")
        if isinstance(e, ast.Subscript):
            base = e.value
            if (isinstance(base, ast.Attribute) and base.attr == "shape" and isinstance(base.value, ast.Name)
                    and base.value.id in f.arrays and isinstance(e.slice, ast.Constant) and e.slice.value == 0):
                return self.const_name(self.arrays[base.value.id][0])
            if isinstance(base, ast.Name) and (base.id in f.arrays or base.id in self._tuples):
                if isinstance(e.slice, ast.Slice):
                    raise self.fail(f, e, "a slice")
                return f"{base.id}[{self.expr(f, e.slice)}]"
            raise self.fail(f, e, "this subscript")
        if isinstance(e, ast.Call):
            return self.call(f, e)
        raise self.fail(f, e, type(e).__name__)

    def call(self, f: _Func, e: ast.Call) -> str:
        if e.keywords:
            raise self.fail(f, e, "a keyword argument")
        args = [self.expr(f, a) for a in e.args]
        fn = e.func
        if isinstance(fn, ast.Attribute) and isinstance(fn.value, ast.Name) and fn.value.id == "math":
            if fn.attr in _MATH_CALLS:
                return f"{_MATH_CALLS[fn.attr]}({', '.join(args)})"
            raise self.fail(f, e, f"math.{fn.attr}()")
        if isinstance(fn, ast.Name) and fn.id == "abs":
            return f"fabs({args[0]})"
        if isinstance(fn, ast.Name) and fn.id in self._funcs:
            callee = self._funcs[fn.id]
            if callee.tuple_len:
                raise self.fail(f, e, f"{fn.id}() returns a tuple: only `a, b, ... = {fn.id}(...)`; this use")
            return f"{self.func_name(fn.id)}({', '.join(args)})"
        raise self.fail(f, e, f"the call {ast.unparse(fn)}()")

    def is_int(self, e: ast.AST) -> bool:
        """An index expression: int literals, int module constants, int locals, + - * of them."""
        if isinstance(e, ast.Constant):
            return isinstance(e.value, int) and not isinstance(e.value, bool)
        if isinstance(e, ast.Name):
            if e.id in self._locals:
                return self._locals[e.id] == "int"
            if e.id in self._params:
                return False
            v = getattr(self.module, e.id, None)
            return isinstance(v, int) and not isinstance(v, bool)
        if isinstance(e, ast.BinOp) and isinstance(e.op, (ast.Add, ast.Sub, ast.Mult)):
            return self.is_int(e.left) and self.is_int(e.right)
        if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.USub):
            return self.is_int(e.operand)
        return False

    # ------------------------------------------------------------------ statements
    def target(self, f: _Func, t: ast.AST, value: ast.AST | None = None) -> str:
        if isinstance(t, ast.Name):
            if t.id in f.arrays:
                raise self.fail(f, t, "rebinding an array parameter")
            if t.id not in self._params:
                kind = "int" if value is not None and self.is_int(value) else "double"
                if self._locals.setdefault(t.id, kind) != kind:
                    raise self.fail(f, t, f"{t.id} as both an int and a float")
            elif value is not None and self.is_int(value):
                raise self.fail(f, t, f"an int assigned to the float parameter {t.id}")
            return t.id
        if isinstance(t, ast.Subscript) and isinstance(t.value, ast.Name) and t.value.id in f.arrays:
            if f.arrays[t.value.id]:
                raise self.fail(f, t, f"writing the read-only array {t.value.id}")
            return self.expr(f, t)
        raise self.fail(f, t, "this assignment target")

    def _check_tuple_call(self, f: _Func, st: ast.stmt, t: ast.Tuple, v: ast.AST) -> None:
        """Refuse tuple unpacking of anything but a call of a translated function returning ``len(t.elts)`` values."""
        if not (isinstance(v, ast.Call) and isinstance(v.func, ast.Name) and v.func.id in self._funcs
                and self._funcs[v.func.id].tuple_len == len(t.elts)):
            raise self.fail(f, st, "tuple unpacking of anything but a translated tuple-returning call")

    def _check_range_loop(self, f: _Func, st: ast.For) -> None:
        """Refuse any loop but ``for i in range(a[, b])`` (without ``else``)."""
        if not (isinstance(st.target, ast.Name) and isinstance(st.iter, ast.Call)
                and isinstance(st.iter.func, ast.Name) and st.iter.func.id == "range"
                and 1 <= len(st.iter.args) <= 2 and not st.orelse):
            raise self.fail(f, st, "a loop other than `for i in range(a[, b])`")

    def _range_bounds(self, f: _Func, st: ast.For) -> tuple[str, str]:
        """The translated start and stop of a checked ``range`` loop (start "0" when only the stop is given)."""
        assert isinstance(st.iter, ast.Call)
        return ("0", self.expr(f, st.iter.args[0])) if len(st.iter.args) == 1 else (
            self.expr(f, st.iter.args[0]), self.expr(f, st.iter.args[1]))

    def _if_chain(self, f: _Func, st: ast.If, ind: int, head: tuple[str, str], elif_: tuple[str, str],
                  else_: str, end: str) -> list[str]:
        """An ``if``/``elif``/``else`` chain in the target's words: ``head`` and ``elif_`` wrap the test."""
        pad = "    " * ind
        out = [f"{pad}{head[0]}{self.expr(f, st.test)}{head[1]}"]
        out.extend(self.stmts(f, st.body, ind + 1))
        orelse = st.orelse
        while len(orelse) == 1 and isinstance(orelse[0], ast.If):
            out.append(f"{pad}{elif_[0]}{self.expr(f, orelse[0].test)}{elif_[1]}")
            out.extend(self.stmts(f, orelse[0].body, ind + 1))
            orelse = orelse[0].orelse
        if orelse:
            out.append(f"{pad}{else_}")
            out.extend(self.stmts(f, orelse, ind + 1))
        out.append(f"{pad}{end}")
        return out

    def _block(self, f: _Func, body: Sequence[ast.stmt], ind: int, head: str, end: str) -> list[str]:
        """``head``, the statements of ``body`` one level in, and ``end`` (a loop)."""
        pad = "    " * ind
        return [f"{pad}{head}", *self.stmts(f, body, ind + 1), f"{pad}{end}"]

    def _tuple_return(self, f: _Func, value: ast.Tuple, pad: str, array: str, assign: str, ret: str) -> list[str]:
        """``return a, b, ...``: each value into ``array[i]`` (the caller's buffer), then ``ret``."""
        return [*(f"{pad}{array}[{i}] {assign} {self.expr(f, el)};" for i, el in enumerate(value.elts)),
                f"{pad}{ret}"]

    def stmts(self, f: _Func, body: Sequence[ast.stmt], ind: int) -> list[str]:
        """The statements of ``body`` at indent level ``ind``; the target's words come from its hooks."""
        out: list[str] = []
        pad = "    " * ind
        for st in body:
            if isinstance(st, ast.Expr) and isinstance(st.value, ast.Constant) and isinstance(st.value.value, str):
                continue  # docstring
            if isinstance(st, ast.Assign):
                out.extend(self.assign(f, st, pad))
            elif isinstance(st, ast.AugAssign) and type(st.op) in (ast.Add, ast.Sub):
                op = _BINOPS[type(st.op)]
                tgt = self.target(f, st.target)
                # Python's x += e is x = x + e: one rounding, the same in C
                out.append(f"{pad}{tgt} {self.ASSIGN} ({tgt} {op} {self.expr(f, st.value)});")
            elif isinstance(st, ast.If):
                out.extend(self._if_chain(f, st, ind, *self.IF_WORDS))
            elif isinstance(st, ast.For):
                self._check_range_loop(f, st)
                out.extend(self.loop(f, st, ind))
            elif isinstance(st, ast.Return):
                if st.value is None:
                    out.append(f"{pad}{self.RETURN}")
                elif isinstance(st.value, ast.Tuple):
                    out.extend(self._tuple_return(f, st.value, pad, self.RETURN_ARRAY, self.ASSIGN, self.RETURN))
                else:
                    out.extend(self.return_value(f, st.value, pad))
            else:
                raise self.fail(f, st, f"the statement {type(st).__name__}")
        return out

    def assign(self, f: _Func, st: ast.Assign, pad: str) -> list[str]:
        """``x = e``, ``a, b = g(...)`` (a translated tuple-returning call) or ``t = (e1, e2)``."""
        out: list[str] = []
        if len(st.targets) != 1:
            raise self.fail(f, st, "a chained assignment")
        t = st.targets[0]
        if isinstance(t, ast.Tuple):
            v = st.value
            self._check_tuple_call(f, st, t, v)
            n = len(t.elts)
            self._tmp = max(self._tmp, n)
            args = [self.expr(f, a) for a in v.args] + ["tup_"]
            out.append(f"{pad}{self.func_name(v.func.id)}({', '.join(args)});")
            for i, el in enumerate(t.elts):
                out.append(f"{pad}{self.target(f, el)} = tup_[{i}];")
            return out
        if isinstance(t, ast.Name) and isinstance(st.value, ast.Tuple):
            if t.id in self._locals and t.id not in self._tuples:
                raise self.fail(f, st, f"{t.id} as both a scalar and a tuple")
            self._tuples[t.id] = len(st.value.elts)
            for i, el in enumerate(st.value.elts):
                out.append(f"{pad}{t.id}[{i}] = {self.expr(f, el)};")
            return out
        rhs = self.expr(f, st.value)
        out.append(f"{pad}{self.target(f, t, st.value)} = {rhs};")
        return out

    def loop(self, f: _Func, st: ast.For, ind: int) -> list[str]:
        """A checked ``for i in range(a[, b])`` loop; ``i`` must stay an int."""
        i = st.target.id
        if self._locals.get(i, "int") != "int":
            raise self.fail(f, st, f"{i} as both a loop counter and a float")
        self._locals[i] = "int"
        a, b = self._range_bounds(f, st)
        return self._block(f, st.body, ind, f"for ({i} = {a}; {i} < {b}; {i}++) {{", "}")

    def return_value(self, f: _Func, value: ast.expr, pad: str) -> list[str]:
        """``return e`` of one value."""
        return [f"{pad}return {self.expr(f, value)};"]

    # ------------------------------------------------------------------ functions
    def function(self, f: _Func) -> str:
        self._params = {a.arg for a in f.node.args.args}
        self._locals: dict[str, str] = {}
        self._tuples: dict[str, int] = {}
        self._tmp = 0
        if f.node.args.vararg or f.node.args.kwarg or f.node.args.kwonlyargs or f.node.args.defaults:
            raise self.fail(f, f.node, "*args, keyword-only or default arguments")
        body = self.stmts(f, f.node.body, 1)
        params = []
        for a in f.node.args.args:
            if a.arg in f.arrays:
                params.append(f"{'const ' if f.arrays[a.arg] else ''}double *{a.arg}")
            else:
                params.append(f"double {a.arg}")
        if f.tuple_len:
            params.append("double *out_")
        ret = "double" if f.returns_value else "void"
        decl = [f"    int {n};" for n, t in self._locals.items() if t == "int"]
        dbl = [n for n, t in self._locals.items() if t == "double" and n not in self._tuples]
        if dbl:
            decl.append("    double " + ", ".join(dbl) + ";")
        decl += [f"    double {n}[{k}];" for n, k in self._tuples.items()]
        if self._tmp:
            decl.append(f"    double tup_[{self._tmp}];")
        decl += [f"    (void){a.arg};" for a in f.node.args.args]  # some laws do not use every argument
        head = (f"/* translated from {self.module.__name__}.{f.name} */\n"
                f"static {ret} {self.func_name(f.name)}({', '.join(params)})\n{{")
        return "\n".join([head, *decl, *body, "}"])

    def translate(self) -> str:
        """C definitions of every function, callees first (``static``)."""
        self._funcs = {}
        for name in self.functions:
            self._funcs[name] = self._parse(name)
        return "\n\n".join(self.function(self._funcs[n]) for n in self.functions) + "\n"


def translate(module: Any, functions: Sequence[str], arrays: Mapping[str, tuple[str, bool]],
              prefix: str) -> tuple[str, dict[str, Any]]:
    """C source of ``functions`` and the module constants it uses (see :class:`Translator`).

    Returns
    -------
    code : str
        ``static`` C functions named ``<prefix>k_<name>``.
    constants : dict
        Module constant name -> value, for the ``#define`` lines.
    """
    t = Translator(module, functions, arrays, prefix)
    code = t.translate()
    return code, dict(t.used_constants)



# --------------------------------------------------------------------------- IEC 61131-3 Structured Text

#: Words an ST identifier may not be (case-insensitive); a local of that name gets a suffix.
_ST_RESERVED = {"at", "by", "do", "if", "of", "or", "to", "and", "mod", "not", "xor", "var", "end", "int", "real",
                "lreal", "dint", "bool", "time", "date", "then", "else", "elsif", "for", "while", "case", "return",
                "exit", "step", "init", "fault", "this", "super", "method", "array", "string", "word", "byte",
                "true", "false", "repeat", "until", "constant", "retain", "function", "program", "task"}


def st_float(x: float) -> str:
    """An ST LREAL literal (digits '.' digits [E exponent]) that reads back as exactly ``x`` (finite)."""
    if not math.isfinite(x):
        raise ValueError(f"ST has no literal for {x}")
    r = repr(float(x))
    mant, _, exp = r.partition("e")
    if "." not in mant:
        mant += ".0"
    return f"{mant}E{exp}" if exp else mant


@dataclass
class StTranslator(Translator):
    """The same functions as METHODs of one IEC 61131-3 function block (TwinCAT/CODESYS dialect).

    Differences from the C: the packed arrays ``p`` and ``s`` are members of
    the function block (array parameters are dropped from the signatures and
    calls); a tuple is returned through the member array ``ret``; names
    are made unique case-insensitively (ST is case-insensitive: ``k1`` and
    ``K1`` of the Python become ``k1`` and ``K1_2``); ``math.isfinite(x)`` is
    ``(x - x) = 0.0`` (true exactly for finite IEEE values); ``math.inf`` is
    the member ``INF``, made infinite at ``Init`` (ST has no literal for it).
    """

    ASSIGN: ClassVar[str] = ":="
    NOT: ClassVar[str] = "NOT "
    AND: ClassVar[str] = " AND "
    OR: ClassVar[str] = " OR "
    CMPOPS: ClassVar[Mapping[type, str]] = {**_CMPOPS, ast.Eq: "=", ast.NotEq: "<>"}
    PI: ClassVar[str] = st_float(math.pi)
    INF: ClassVar[str] = "INF"  # the member made infinite at Init
    RETURN: ClassVar[str] = "RETURN;"
    RETURN_ARRAY: ClassVar[str] = "ret"
    IF_WORDS: ClassVar[tuple[tuple[str, str], tuple[str, str], str, str]] = (
        ("IF ", " THEN"), ("ELSIF ", " THEN"), "ELSE", "END_IF;")

    def _names(self, f: _Func) -> dict[str, str]:
        # the packed arrays are the function block's members p and s; ret and INF are members too
        seen: dict[str, str] = {"p": "p", "s": "s", "ret": "ret", "inf": "INF"}
        out: dict[str, str] = {a: a for a in f.arrays}
        for node in ast.walk(f.node):
            n = node.arg if isinstance(node, ast.arg) else node.id if isinstance(node, ast.Name) else None
            if n is None or n in out or (isinstance(node, ast.Name) and not (n in self._params or self._is_local(f, n))):
                continue
            new = n
            k = 2
            while new.lower() in seen or new.lower() in _ST_RESERVED or new.endswith("_"):
                new = f"{n.rstrip('_')}_{k}"
                k += 1
            seen[new.lower()] = n
            out[n] = new
        return out

    def _is_local(self, f: _Func, n: str) -> bool:
        return not isinstance(getattr(self.module, n, None), (int, float)) and n not in ("math", "abs", "range") \
            and n not in self._funcs

    def func_name(self, name: str) -> str:
        return f"k_{name.lstrip('_')}"

    def expr(self, f: _Func, e: ast.AST) -> str:
        if isinstance(e, ast.Constant) and isinstance(e.value, float):
            return st_float(e.value)
        if isinstance(e, ast.Name) and (e.id in self._locals or e.id in self._params):
            return self._map[e.id]
        if isinstance(e, ast.Name):
            val = getattr(self.module, e.id, None)
            if isinstance(val, float):
                self.used_constants[e.id] = val
                return st_float(val)
            return super().expr(f, e)
        if isinstance(e, ast.Subscript) and isinstance(e.value, ast.Name) and e.value.id in self._tuples:
            return f"{self._map.get(e.value.id, e.value.id)}[{self.expr(f, e.slice)}]"
        return super().expr(f, e)

    def call(self, f: _Func, e: ast.Call) -> str:
        fn = e.func
        if isinstance(fn, ast.Attribute) and isinstance(fn.value, ast.Name) and fn.value.id == "math":
            if fn.attr == "isfinite":
                x = self.expr(f, e.args[0])
                return f"(({x} - {x}) = 0.0)"
            if fn.attr == "atan":
                return f"ATAN({self.expr(f, e.args[0])})"
        if isinstance(fn, ast.Name) and fn.id == "abs":
            return f"ABS({self.expr(f, e.args[0])})"
        if isinstance(fn, ast.Name) and fn.id in self._funcs:
            callee = self._funcs[fn.id]
            args = [self.expr(f, a) for a, p in zip(e.args, callee.node.args.args) if p.arg not in callee.arrays]
            return f"{self.func_name(fn.id)}({', '.join(args)})"
        return super().call(f, e)

    def target(self, f: _Func, t: ast.AST, value: ast.AST | None = None) -> str:
        name = super().target(f, t, value)
        if isinstance(t, ast.Name):
            return self._map[t.id]
        return name

    def assign(self, f: _Func, st: ast.Assign, pad: str) -> list[str]:
        out: list[str] = []
        if isinstance(st.targets[0], ast.Tuple):
            t, v = st.targets[0], st.value
            self._check_tuple_call(f, st, t, v)
            out.append(f"{pad}{self.call(f, v)};")
            for i, el in enumerate(t.elts):
                out.append(f"{pad}{self.target(f, el)} := ret[{i}];")
        elif isinstance(st.targets[0], ast.Name) and isinstance(st.value, ast.Tuple):
            name = st.targets[0].id
            self._tuples[name] = len(st.value.elts)
            self._map.setdefault(name, name)
            for i, el in enumerate(st.value.elts):
                out.append(f"{pad}{self._map[name]}[{i}] := {self.expr(f, el)};")
        else:
            rhs = self.expr(f, st.value)
            out.append(f"{pad}{self.target(f, st.targets[0], st.value)} := {rhs};")
        return out

    def loop(self, f: _Func, st: ast.For, ind: int) -> list[str]:
        self._locals[st.target.id] = "int"
        i = self._map[st.target.id]
        a, b = self._range_bounds(f, st)
        return self._block(f, st.body, ind, f"FOR {i} := {a} TO {b} - 1 DO", "END_FOR;")

    def return_value(self, f: _Func, value: ast.expr, pad: str) -> list[str]:
        return [f"{pad}{self.func_name(f.name)} := {self.expr(f, value)};", f"{pad}RETURN;"]

    def function(self, f: _Func) -> str:
        self._params = {a.arg for a in f.node.args.args}
        self._locals = {}
        self._tuples = {}
        self._tmp = 0
        self._map = self._names(f)
        body = self.stmts(f, f.node.body, 1)
        name = self.func_name(f.name)
        head = f"METHOD PRIVATE {name}" + (" : LREAL" if f.returns_value else "")
        ins = [f"    {self._map[a.arg]} : LREAL;" for a in f.node.args.args if a.arg not in f.arrays]
        loc = [f"    {self._map[n]} : {'DINT' if t == 'int' else 'LREAL'};" for n, t in self._locals.items()
               if n not in self._tuples]
        loc += [f"    {self._map[n]} : ARRAY[0..{k - 1}] OF LREAL;" for n, k in self._tuples.items()]
        parts = [f"(* translated from {self.module.__name__}.{f.name} *)", head]
        if ins:
            parts += ["VAR_INPUT", *ins, "END_VAR"]
        if loc:
            parts += ["VAR", *loc, "END_VAR"]
        return "\n".join([*parts, *body, "END_METHOD"])

    def translate(self) -> str:
        self._funcs = {}
        for name in self.functions:
            self._funcs[name] = self._parse(name)
        return "\n\n".join(self.function(self._funcs[n]) for n in self.functions) + "\n"

    def ret_len(self) -> int:
        return max([f.tuple_len for f in self._funcs.values()] + [1])
