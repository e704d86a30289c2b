"""Safe arithmetic expressions of arc length ``s`` and time ``t`` (load components).

A load component in a scene is a number or a string such as
``"2e3*sin(pi*s/L)*sin(8*omega0*t)"``. Strings are parsed with :mod:`ast` and checked against a
strict whitelist; nothing is ever passed to ``eval``. Allowed are

* number literals (finite int/float), names, ``+ - * / **``, unary ``+ -``, parentheses;
* calls (positional arguments only) of ``sin cos tan asin acos atan sinh cosh tanh exp log
  sqrt abs`` (one argument), ``min max`` (two arguments), ``heaviside(x)`` (1 for x >= 0,
  else 0) and ``ramp(x)`` (= max(x, 0));
* the constants ``pi`` and ``e`` and the names the caller allows (typically ``s``, ``t``,
  ``L``, ``omega0`` and the scene's ``[parameters]``).

An :class:`Expression` can be evaluated with Python floats or numpy arrays
(:meth:`Expression.evaluate`) or turned into UFL (:meth:`Expression.to_ufl`). Constant
subexpressions are checked when parsing (``1/0`` or ``log(-1)`` are input errors) and folded to
floats in UFL.

Names are compared as written. Python's parser folds identifiers by Unicode NFKC, so a
fullwidth ``ｔ``, a mathematical ``𝑡`` or the ligature ``ﬁ`` would silently be read as ``t`` or
``fi``; such names are refused (:func:`check_name` does the same for the names a scene
declares). Non-ASCII names that NFKC leaves alone (Greek ``ω``) are allowed.

Chains and limits. A chain ``a + b - c + ...`` (or ``a * b / c * ...``) is not nesting, although
:mod:`ast` builds it as a left-deep tree. It is flattened without recursion into its signed
operands; up to :data:`BALANCE_ABOVE` (16) operands it is rebuilt left to right as written, so
short expressions give the same floating-point results as Python, and above that it is rebuilt
as a balanced tree of depth about log2(n), so that the recursive walkers here and in UFL/FFCx
stay shallow. The rebalanced chain is the same sum (product) in exact arithmetic; its round-off
is bounded like the left-to-right one's (n eps sum|terms| for n terms) but differs from it, and
an intermediate product may overflow where the written order would not (or the other way round).
True nesting (parentheses around an operation, calls, signs, powers) is limited instead:

* :data:`MAX_DEPTH` (100) levels of the internal tree. Every call, sign, power and nested chain
  adds one level; a chain of n operands adds n - 1 levels up to 16 operands and ceil(log2 n)
  above. It guards the recursive walkers (2-3 Python frames a level; a derivative is a few
  levels deeper than its expression; Python allows 1000 frames).
* :data:`MAX_NODES` (2000) numbers, names, operators and calls, counted on the text before it is
  parsed. It bounds the ``fem.form`` compile, whose time grows faster than linearly in the nodes
  (why 2000: docs/decisions.md, "Expressions: at most 2000 nodes"; held by
  tests/test_expression_fuzz.py::test_node_limit). The limit also keeps a flat chain well inside
  what Python's own parser can build: it constructs the left-deep AST recursively and fails near
  3000 levels (fewer when called from deep in a stack). A load known as data (a measured
  history, a long piecewise definition) needs no expression: a table
  (cosserat_fem/scene/load_data.py) of any length costs one DOLFINx Constant or Function in the
  form, whatever its rows, so the message of this limit names that alternative.
* :data:`MAX_LENGTH` (20000) characters: ten per node, room for long names and literals; it
  bounds the work done before the node count (and the length of number literals).

Every refusal is a :class:`SceneError` of one line: the key, a reason, the column and the text.
"""

from __future__ import annotations

import ast
import difflib
import math
import numbers
import re
import sys
import unicodedata
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple, TypeGuard

import numpy as np

from cosserat_fem.common.errors import SceneError, show_value

#: Built-in constants, always available.
CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}

#: Whitelisted functions and their number of arguments.
FUNCTIONS: dict[str, int] = {
    **{
        name: 1
        for name in (
            "sin cos tan asin acos atan sinh cosh tanh exp log sqrt abs heaviside ramp".split()
        )
    },
    "min": 2,
    "max": 2,
}

#: Names a user constant may not take (variables, built-in constants, functions).
RESERVED_NAMES: frozenset[str] = frozenset({"s", "t", *CONSTANTS, *FUNCTIONS})

#: Levels of the internal tree (guards the recursive walkers; see the module docstring).
MAX_DEPTH = 100
#: Numbers, names, operators and calls in one expression (bounds the FFCx compile time).
MAX_NODES = 2000
#: Characters of one expression string (after stripping blanks at both ends).
MAX_LENGTH = 20000
#: Chains of + - (or * /) with more operands than this are rebuilt as balanced trees.
BALANCE_ABOVE = 16

_DEPTH_RULE = (
    "each call, sign, power and parenthesised operation is one level; a chain a+b+... of n "
    f"terms counts n-1 levels up to {BALANCE_ABOVE} terms and about log2(n) above"
)

_BINARY = {ast.Add: "add", ast.Sub: "sub", ast.Mult: "mul", ast.Div: "div", ast.Pow: "pow"}
_UNARY = {ast.UAdd: "pos", ast.USub: "neg"}
_OPERATORS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
# Associative chains: operator → (the chain's operators, "same" op, "inverse" op).
_CHAINS: dict[type, tuple[tuple[type, ...], str, str]] = {
    **dict.fromkeys((ast.Add, ast.Sub), ((ast.Add, ast.Sub), "add", "sub")),
    **dict.fromkeys((ast.Mult, ast.Div), ((ast.Mult, ast.Div), "mul", "div")),
}

# One node of the internal tree per match, for valid expressions: a number, a name (a variable
# or a called function) or an operator. Non-ASCII characters count as name characters.
_TOKEN = re.compile(
    r"0[xXoObB]\w*"
    r"|(?:\d[\d_]*(?:\.[\d_]*)?|\.\d[\d_]*)(?:[eE][+-]?\d[\d_]*)?[jJ]?"
    r"|(?:[A-Za-z_]|[^\x00-\x7f\s])(?:\w|[^\x00-\x7f\s])*"
    r"|\*\*|[-+*/]"
)

# Internal tree: ("num", value) | ("var", name) | (op, child[, child]) | ("call", fname, *args)
Node = tuple[Any, ...]

_REFUSED = {
    ast.Attribute: "attribute access ('.')",
    ast.Subscript: "indexing ('[...]')",
    ast.Compare: "comparisons (use heaviside(x) for steps)",
    ast.BoolOp: "'and'/'or'",
    ast.IfExp: "'if ... else'",
    ast.Lambda: "lambda",
    ast.List: "lists",
    ast.Tuple: "tuples",
    ast.Dict: "dicts",
    ast.Set: "sets",
    ast.ListComp: "comprehensions",
    ast.SetComp: "comprehensions",
    ast.DictComp: "comprehensions",
    ast.GeneratorExp: "comprehensions",
    ast.Starred: "'*' unpacking",
    ast.NamedExpr: "':=' assignments",
    ast.JoinedStr: "strings",
    ast.Await: "await",
    ast.Yield: "yield",
    ast.YieldFrom: "yield",
}


# ----------------------------------------------------------------------------------- backends
def _heaviside(x: float) -> float:
    return 1.0 if x >= 0.0 else 0.0


def _ramp(x: float) -> float:
    return x if x > 0.0 else 0.0


_SCALAR_OPS: dict[str, Callable[..., Any]] = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b,
    "pow": math.pow,  # raises for 0**-1 and (-8)**(1/3) instead of returning complex
    "neg": lambda a: -a,
    "pos": lambda a: a,
    **{
        name: getattr(math, name)
        for name in "sin cos tan asin acos atan sinh cosh tanh exp".split()
    },
    "log": math.log,
    "sqrt": math.sqrt,
    "abs": abs,
    "min": min,
    "max": max,
    "heaviside": _heaviside,
    "ramp": _ramp,
}

_NUMPY_OPS: dict[str, Callable[..., Any]] = {
    **{k: _SCALAR_OPS[k] for k in ("add", "sub", "mul", "div", "neg", "pos")},
    "pow": np.power,
    **{name: getattr(np, name) for name in "sin cos tan sinh cosh tanh exp log sqrt abs".split()},
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "min": np.minimum,
    "max": np.maximum,
    "heaviside": lambda x: np.where(x >= 0.0, 1.0, 0.0),
    "ramp": lambda x: np.maximum(x, 0.0),
}


def _ufl_ops() -> dict[str, Callable[..., Any]]:
    """UFL counterparts of the operations (ufl imported lazily)."""
    import ufl

    return {
        **{k: _SCALAR_OPS[k] for k in ("add", "sub", "mul", "div", "neg", "pos")},
        "pow": lambda a, b: a**b,
        **{name: getattr(ufl, name) for name in "sin cos tan sinh cosh tanh exp sqrt".split()},
        "asin": ufl.asin,
        "acos": ufl.acos,
        "atan": ufl.atan,
        "log": ufl.ln,
        "abs": abs,
        "min": ufl.min_value,
        "max": ufl.max_value,
        "heaviside": lambda x: ufl.conditional(ufl.ge(x, 0.0), 1.0, 0.0),
        "ramp": lambda x: ufl.max_value(x, 0.0),
    }


def _walk(node: Node, leaf: Callable[[Node], Any], apply: Callable[[str, list], Any]) -> Any:
    """Evaluate the internal tree bottom-up: ``leaf`` for num/var, ``apply(op, args)`` else."""
    kind = node[0]
    if kind in ("num", "var"):
        return leaf(node)
    if kind == "call":
        return apply(node[1], [_walk(arg, leaf, apply) for arg in node[2:]])
    return apply(kind, [_walk(arg, leaf, apply) for arg in node[1:]])


def _is_real(value: object) -> TypeGuard[numbers.Real]:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


# ------------------------------------------------------------------------------------- names
def check_name(name: str, key: str) -> None:
    """Refuse a name that Python would read as another one (Unicode NFKC folding).

    Python folds identifiers by NFKC, so ``ｔ`` (fullwidth), ``𝑡`` (mathematical italic) or
    ``ﬁ`` (ligature) in an expression are read as ``t`` and ``fi``; a parameter declared with
    such a name could never be used as written and would silently shadow or alias another.
    Raises :class:`SceneError` starting with ``key``; NFKC-stable names (``ω``) pass. Whether
    ``name`` is an identifier at all is not checked here.
    """
    folded = unicodedata.normalize("NFKC", name)
    if folded != name:
        raise SceneError(
            f"{key}: the name {name!r} is read by Python as {folded!r} (Unicode NFKC); "
            "write it as plain letters"
        )


# ------------------------------------------------------------------------------------- parser
class _Built(NamedTuple):
    """A converted subtree: the tree, its height (a leaf is 0) and its value if constant."""

    tree: Node
    height: int
    value: float | None


class _Span(NamedTuple):
    """A source range in :mod:`ast` coordinates (lines from 1, UTF-8 byte columns): a group of
    operands inside a long chain, shown after ``lead``, the operator written before it."""

    lineno: int
    col_offset: int
    end_lineno: int
    end_col_offset: int
    lead: str = ""


class _Operand(NamedTuple):
    """A chain operand (or a merged group of operands ``first .. last - 1``): its value is
    ``built`` if not ``inverted``, else ``-built`` (for + -) or ``1/built`` (for * /)."""

    built: _Built
    inverted: bool
    first: int
    last: int


class _Source:
    """The text, split into lines the way :mod:`ast` counts them, for columns and segments."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.ascii = text.isascii()  # ASCII names are NFKC-stable
        self.lines = [line.encode("utf-8") for line in re.split(r"\r\n|\r|\n", text)]

    def line(self, lineno: int) -> bytes:
        return self.lines[lineno - 1] if 0 < lineno <= len(self.lines) else b""

    def place(self, where: Any) -> str:
        """`` at column N`` (characters, from 1) or `` at line L, column N``."""
        column = len(self.line(where.lineno)[: where.col_offset].decode("utf-8", "replace")) + 1
        if where.lineno > 1:
            return f" at line {where.lineno}, column {column}"
        return f" at column {column}"

    def segment(self, where: Any) -> str:
        """The text of a node or span, exactly as written."""
        first, last = where.lineno, where.end_lineno
        if first == last:
            raw = self.line(first)[where.col_offset : where.end_col_offset]
        else:
            parts = [self.line(first)[where.col_offset :]]
            parts += [self.line(k) for k in range(first + 1, last)]
            parts.append(self.line(last)[: where.end_col_offset])
            raw = b"\n".join(parts)
        return raw.decode("utf-8", "replace")

    def shown(self, where: Any) -> str:
        """The segment for a message: quoted, shortened, parentheses cut off at its ends
        restored, after the operator that precedes a group of a long chain."""
        text = self.segment(where)
        level = lowest = 0
        for char in text:
            level += (char == "(") - (char == ")")
            lowest = min(lowest, level)
        text = "(" * -lowest + text + ")" * (level - lowest)
        return _short(f"{where.lead} {text}" if getattr(where, "lead", "") else text)


def _short(text: str, limit: int = 60) -> str:
    """``repr`` of a (one-line) source segment, shortened in the middle if long."""
    text = " ".join(text.split())
    if len(text) > limit:
        text = text[: limit // 2 - 2] + " ... " + text[-(limit // 2 - 3) :]
    return repr(text)


class _Parser:
    """Converts a Python AST into the internal tree, enforcing the whitelist and the limits.

    Recursion follows true nesting only (bounded by :data:`MAX_DEPTH`); chains are walked
    iteratively. Heights and constant values are computed bottom-up, once per node.
    """

    def __init__(self, text: str, allowed: frozenset[str] | None, key: str) -> None:
        self.text = text
        self.source = _Source(text)
        self.allowed = allowed  # None: any identifier is accepted as a variable
        self.key = key
        self.names: set[str] = set()

    def fail(self, reason: str, where: Any = None, hint: str = "") -> SceneError:
        place = self.source.place(where) if where is not None else ""
        return SceneError(f"{self.key}: {reason}{place} in {show_value(self.text)}{hint}")

    def too_deep(self, where: Any, height: int | None = None) -> SceneError:
        """The SceneError for nesting beyond MAX_DEPTH at ``where`` (``height``: the levels
        found, if known)."""
        found = f"{height} levels" if height is not None else f"more than {MAX_DEPTH} levels"
        return self.fail(
            f"expression nested deeper than {MAX_DEPTH} levels (found {found}; {_DEPTH_RULE})",
            where,
        )

    def convert(self, node: ast.AST, depth: int = 0) -> _Built:
        """The internal tree of the AST ``node`` at nesting ``depth``; SceneError for anything
        outside the whitelist or deeper than MAX_DEPTH."""
        if depth > MAX_DEPTH:
            raise self.too_deep(node)
        if isinstance(node, ast.Constant):
            return self.number(node)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.BinOp) and type(node.op) in _CHAINS:
            return self.chain(node, depth)
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            left = self.convert(node.left, depth + 1)
            right = self.convert(node.right, depth + 1)
            return self.build(_BINARY[type(node.op)], (left, right), node)
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            operand = self.convert(node.operand, depth + 1)
            return self.build(_UNARY[type(node.op)], (operand,), node)
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        raise self.fail(f"{self.describe(node)} not allowed", node)

    @staticmethod
    def describe(node: ast.AST) -> str:
        """What a refused AST node is, in words, for a message."""
        for kind, text in _REFUSED.items():
            if isinstance(node, kind):
                return text
        if isinstance(node, ast.BinOp):
            return f"operator {type(node.op).__name__!r} (only + - * / ** are allowed)"
        if isinstance(node, ast.UnaryOp):
            return f"operator {type(node.op).__name__!r} (only unary + - are allowed)"
        return f"construct {type(node).__name__!r}"

    def number(self, node: ast.Constant) -> _Built:
        """A number literal as a leaf; SceneError for any other literal (bool, string, complex,
        ...) or a number beyond the float range."""
        value = node.value
        if isinstance(value, bool) or not isinstance(value, int | float):
            shown = repr(value)
            shown = shown if len(shown) <= 60 else f"{shown[:40]}...{shown[-15:]}"
            raise self.fail(f"literal {shown} not allowed (only numbers)", node)
        number = _finite_float(value)
        if number is None:
            raise self.fail("number literal is not finite (beyond ±1.8e308)", node)
        return _Built(("num", number), 0, number)

    def check_written(self, node: ast.Name) -> None:
        """Refuse a name whose text differs from what Python read (NFKC folding)."""
        if self.source.ascii:
            return
        written = self.source.segment(node)
        if written != node.id:
            raise self.fail(
                f"the name {written!r} is read by Python as {node.id!r} (Unicode NFKC)",
                node,
                "; write it as plain letters",
            )

    def name(self, node: ast.Name) -> _Built:
        """A name as a leaf (its value known for ``pi`` and ``e``), recorded in ``names``;
        SceneError for a function name without a call, a name not allowed, or one Python reads
        differently."""
        self.check_written(node)
        ident = node.id
        if ident in FUNCTIONS:
            raise self.fail(f"function {ident!r} used without arguments; write {ident}(...)", node)
        if ident not in CONSTANTS and self.allowed is not None and ident not in self.allowed:
            raise self.fail(f"unknown name {ident!r}", node, self.suggest(ident))
        self.names.add(ident)
        return _Built(("var", ident), 0, CONSTANTS.get(ident))

    def suggest(self, ident: str) -> str:
        pool = sorted(set(CONSTANTS) | (self.allowed or set()))
        close = difflib.get_close_matches(ident, pool, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return f"{hint}; allowed names: {', '.join(pool)}"

    def call(self, node: ast.Call, depth: int) -> _Built:
        """A call of a whitelisted function with its number of positional arguments; SceneError
        otherwise."""
        func = node.func
        if not isinstance(func, ast.Name):
            raise self.fail("only calls of plain function names are allowed", node)
        self.check_written(func)
        if func.id not in FUNCTIONS:
            close = difflib.get_close_matches(func.id, sorted(FUNCTIONS), n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            allowed = ", ".join(sorted(FUNCTIONS))
            raise self.fail(f"unknown function {func.id!r}", node, f"{hint}; allowed: {allowed}")
        if node.keywords:
            raise self.fail(f"keyword arguments not allowed in {func.id}()", node)
        arity = FUNCTIONS[func.id]
        if len(node.args) != arity:
            plural = "s" if arity > 1 else ""
            raise self.fail(
                f"{func.id}() takes {arity} argument{plural}, got {len(node.args)}", node
            )
        args = []
        for arg in node.args:
            args.append(self.convert(arg, depth + 1))
        return self.build(func.id, tuple(args), node, call=True)

    def chain(self, node: ast.BinOp, depth: int) -> _Built:
        """A chain of + - (or * /): flattened iteratively along the left spine of the AST,
        then rebuilt left to right (up to BALANCE_ABOVE operands) or balanced."""
        ops, same, inverse = _CHAINS[type(node.op)]
        spine: list[ast.BinOp] = []  # spine[i] is the written chain of operands 0 .. i+1
        current: ast.AST = node
        while isinstance(current, ast.BinOp) and isinstance(current.op, ops):
            spine.append(current)
            current = current.left
        spine.reverse()
        operands = [_Operand(self.convert(current, depth + 1), False, 0, 1)]
        for i, binop in enumerate(spine, start=1):
            inverted = isinstance(binop.op, ast.Sub | ast.Div)
            operands.append(_Operand(self.convert(binop.right, depth + 1), inverted, i, i + 1))

        def merge(a: _Operand, b: _Operand) -> _Operand:
            """Adjacent operands a, b (a written first) as one operand, with its source range for
            messages; an inverted operand goes into the operator: a + b, a - b, b - a or -(a + b)
            (likewise for * /)."""
            if a.first == 0:  # the written prefix: an AST node of its own
                where: Any = spine[b.last - 2]
            else:
                before, end = spine[a.first - 1], spine[b.last - 2]
                start, lead = before.right, _OPERATORS[type(before.op)]
                assert end.end_lineno is not None and end.end_col_offset is not None  # ast.parse's
                where = _Span(
                    start.lineno, start.col_offset, end.end_lineno, end.end_col_offset, lead
                )
            if not a.inverted:  # a + b, a - b (a * b, a / b)
                op, pair, inverted = (inverse if b.inverted else same), (a, b), False
            elif not b.inverted:  # -a + b = b - a (1/a * b = b / a)
                op, pair, inverted = inverse, (b, a), False
            else:  # -a - b = -(a + b) (1/a / b = 1/(a * b))
                op, pair, inverted = same, (a, b), True
            built = self.build(op, (pair[0].built, pair[1].built), where)
            return _Operand(built, inverted, a.first, b.last)

        if len(operands) <= BALANCE_ABOVE:  # as written: ((a + b) - c) + ...
            result = operands[0]
            for operand in operands[1:]:
                result = merge(result, operand)
        else:  # pairwise, level by level: depth ceil(log2 n)
            level = operands
            while len(level) > 1:
                merged = [merge(level[i], level[i + 1]) for i in range(0, len(level) - 1, 2)]
                level = merged + level[len(merged) * 2 :]
            result = level[0]
        assert not result.inverted  # the first operand is never inverted, nor any group of it
        return result.built

    def build(self, op: str, args: tuple[_Built, ...], where: Any, call: bool = False) -> _Built:
        """A new node: its height checked, and its value if the arguments are constant
        (so that ``1/0`` or ``log(-1)`` fail at parse time)."""
        trees = tuple(arg.tree for arg in args)
        tree = ("call", op, *trees) if call else (op, *trees)
        height = 1 + max(arg.height for arg in args)
        if height > MAX_DEPTH:
            raise self.too_deep(where, height)
        if any(arg.value is None for arg in args):
            return _Built(tree, height, None)
        try:
            value = _SCALAR_OPS[op](*(arg.value for arg in args))
            finite = math.isfinite(value)
        except (ArithmeticError, ValueError) as exc:
            segment = self.source.shown(where)
            raise self.fail(
                f"{segment} cannot be evaluated ({_reason(exc)})", where, self.pairwise(where)
            ) from None
        if not finite:
            segment = self.source.shown(where)
            raise self.fail(f"{segment} is not finite", where, self.pairwise(where))
        return _Built(tree, height, float(value))

    @staticmethod
    def pairwise(where: Any) -> str:
        """A note for a refused group of a long chain (its grouping is not the written one)."""
        if not isinstance(where, _Span):
            return ""
        return f" (a chain of more than {BALANCE_ABOVE} terms is evaluated pairwise)"


def _reason(exc: BaseException) -> str:
    """The message of an exception, or a description if it has none (MemoryError...)."""
    text = " ".join(str(exc).split())
    if text:
        return text
    return {
        "MemoryError": "the parser ran out of stack",
        "RecursionError": "maximum recursion depth exceeded",
    }.get(type(exc).__name__, type(exc).__name__)


def _finite_float(value: object) -> float | None:
    """``float(value)`` if that is finite, else None."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (OverflowError, TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def _syntax_error_place(exc: SyntaxError, text: str) -> str:
    """`` at column N`` (or line and column for multi-line text, or `` at the end``)."""
    line, offset = exc.lineno or 1, exc.offset or 0
    lines = text.splitlines() or [""]
    if line > 1:
        return f" at line {line}, column {offset}"
    return f" at column {offset}" if 0 < offset <= len(lines[0]) else " at the end"


def _syntax_reason(exc: SyntaxError) -> str:
    """Python's message, except for its advice on the int-literal limit (meant for programs)."""
    message = " ".join(str(exc.msg).split()) or "invalid syntax"
    if "integer string conversion" in message:  # Python's 4300-digit limit of int literals
        digits = re.search(r"value has (\d+) digits", message)
        found = f", found {digits.group(1)}" if digits else ""
        return f"an integer literal has more than {sys.get_int_max_str_digits()} digits{found}"
    return message


def _show_number(value: object) -> str:
    """``show_value`` of a number, or its size if it is an int too long to print."""
    try:
        return show_value(value)
    except ValueError:  # an int too long for str() (Python's 4300-digit limit)
        if not isinstance(value, int):
            raise
        return f"an integer of about {int(int(value).bit_length() * math.log10(2)) + 1} digits"


def _parse_tree(
    value: object, allowed: frozenset[str] | None, key: str
) -> tuple[str, Node, frozenset[str]]:
    """Validate ``value`` (number or string) → (source, tree, names)."""
    if _is_real(value):
        number = _finite_float(value)
        if number is None:
            raise SceneError(f"{key}: must be a finite number, got {_show_number(value)}")
        source = str(value) if isinstance(value, numbers.Integral) else repr(number)
        return source, ("num", number), frozenset()
    if not isinstance(value, str):
        raise SceneError(
            f"{key}: must be a number or an expression string, got {show_value(value)}"
        )
    text = value.strip()
    if not text:
        raise SceneError(f"{key}: empty expression string")
    shown = show_value(text)
    if len(text) > MAX_LENGTH:
        raise SceneError(
            f"{key}: expression of {len(text)} characters, more than the limit of {MAX_LENGTH}, "
            f"in {shown}"
        )
    count = sum(1 for _ in _TOKEN.finditer(text))
    if count > MAX_NODES:
        raise SceneError(
            f"{key}: expression of {count} numbers, names and operators, more than the limit of "
            f"{MAX_NODES} (a bigger one takes long to compile; a load given by data, e.g. a "
            f'measured history, is a table: {{table = "file.csv", column = "..."}}, '
            f"docs/loads.md), in {shown}"
        )
    try:
        with warnings.catch_warnings():  # "invalid decimal literal" etc.: not for our stderr
            warnings.simplefilter("ignore")
            body = ast.parse(text, mode="eval").body
    except SyntaxError as exc:
        column = _syntax_error_place(exc, text)
        reason = _syntax_reason(exc)
        raise SceneError(f"{key}: syntax error{column} in {shown} ({reason})") from None
    except (RecursionError, MemoryError) as exc:
        raise SceneError(
            f"{key}: cannot parse {shown}: too deeply nested or too long a chain for Python's "
            f"parser ({_reason(exc)})"
        ) from None
    except (ValueError, OverflowError) as exc:  # null bytes, lone surrogates
        raise SceneError(f"{key}: cannot parse {shown} ({_reason(exc)})") from None
    parser = _Parser(text, allowed, key)
    try:
        built = parser.convert(body)
    except RecursionError:  # only when called with little of the recursion limit left
        raise SceneError(
            f"{key}: cannot parse {shown}: nested more deeply than the recursion limit allows "
            "here (maximum recursion depth exceeded)"
        ) from None
    return text, built.tree, frozenset(parser.names)


# --------------------------------------------------------------------------------- Expression
@dataclass(frozen=True)
class Expression:
    """A validated expression of ``s``, ``t`` and named constants.

    Create it with :meth:`Expression.parse` (or ``Expression("...")``, which accepts any
    variable names). Two expressions are equal when their sources are equal.

    Attributes:
        source: the text as written (stripped); numbers given as numbers are stored as their
            ``str``/``repr``.
        names: the variable names used (including ``pi``/``e`` if used; not function names).
    """

    source: str
    names: frozenset[str] = field(default=frozenset(), compare=False)
    _tree: Node | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self._tree is None:
            source, tree, names = _parse_tree(self.source, None, "expression")
            object.__setattr__(self, "source", source)
            object.__setattr__(self, "names", names)
            object.__setattr__(self, "_tree", tree)

    # -- construction -------------------------------------------------------------------
    @classmethod
    def parse(
        cls, value: object, allowed_names: Iterable[str] | None = None, key: str = "expression"
    ) -> Expression:
        """Parse a number or string, allowing ``pi``, ``e`` and ``allowed_names``.

        ``allowed_names`` is the complete set of variables besides ``pi`` and ``e`` (pass
        ``{"s", "t", ...}`` explicitly); ``None`` accepts any name. Raises :class:`SceneError`
        whose message starts with ``key``.
        """
        allowed = None if allowed_names is None else frozenset(allowed_names)
        source, tree, names = _parse_tree(value, allowed, key)
        return cls(source, names, tree)

    # -- properties ---------------------------------------------------------------------
    def __str__(self) -> str:
        return self.source

    @property
    def tree(self) -> Node:
        """The internal tree (nested tuples); read-only."""
        assert self._tree is not None
        return self._tree

    @property
    def is_zero(self) -> bool:
        """True iff the expression is the literal number 0 (``0``, ``"0"``, ``"0.0"``)."""
        return self.tree == ("num", 0.0)

    @property
    def is_constant(self) -> bool:
        """True if it uses no variable other than ``pi`` and ``e``."""
        return not (self.names - CONSTANTS.keys())

    def depends_on(self, name: str) -> bool:
        """Whether the variable ``name`` occurs in the expression."""
        return name in self.names

    # -- evaluation ---------------------------------------------------------------------
    def _values(self, values: Mapping[str, object]) -> dict[str, object]:
        missing = sorted(self.names - CONSTANTS.keys() - values.keys())
        if missing:
            raise ValueError(f"no value given for {', '.join(missing)} in {self.source!r}")
        return {**CONSTANTS, **values}

    def evaluate(self, **values: Any) -> Any:
        """Evaluate with Python floats (→ ``float``) or numpy arrays (→ ``ndarray``).

        Extra values are ignored. Scalar evaluation raises ``ValueError`` on math errors
        (``log(-1)``, ``1/0``, overflow); array evaluation gives ``nan``/``inf`` there. Array
        results are broadcast to the shape of the array arguments.
        """
        env = self._values(values)
        arrays = [np.asarray(v, dtype=float) for v in values.values() if isinstance(v, np.ndarray)]
        if arrays:
            return self._evaluate_array(env, arrays)
        try:
            result = _walk(self.tree, lambda n: self._leaf(n, env), self._apply_scalar)
        except (ArithmeticError, ValueError) as exc:
            shown = ", ".join(f"{k}={values[k]!r}" for k in sorted(self.names & values.keys()))
            raise ValueError(f"cannot evaluate {self.source!r} at {shown}: {exc}") from None
        return float(result)

    def _evaluate_array(self, env: dict[str, object], arrays: list[np.ndarray]) -> np.ndarray:
        """The tree evaluated with numpy (math errors give nan/inf), broadcast to the shape of
        ``arrays``."""
        env = {
            k: np.asarray(v, dtype=float) if isinstance(v, np.ndarray) else v
            for k, v in env.items()
        }
        with np.errstate(all="ignore"):
            result = _walk(
                self.tree, lambda n: self._leaf(n, env), lambda op, args: _NUMPY_OPS[op](*args)
            )
        return np.array(np.broadcast_arrays(np.asarray(result, dtype=float), *arrays)[0])

    @staticmethod
    def _leaf(node: Node, env: Mapping[str, object]) -> object:
        return node[1] if node[0] == "num" else env[node[1]]

    @staticmethod
    def _apply_scalar(op: str, args: list) -> float:
        return _SCALAR_OPS[op](*(float(a) for a in args))

    def to_ufl(self, symbols: Mapping[str, object]) -> Any:
        """Convert to UFL, mapping names to UFL objects or numbers (``pi``, ``e`` default).

        Subexpressions whose operands are all numbers are folded to Python floats, so the
        result is a ``float`` when every symbol used is a number.
        """
        ops = _ufl_ops()
        env = self._values(symbols)
        env = {k: float(v) if _is_real(v) else v for k, v in env.items()}

        def apply(op: str, args: list) -> Any:
            if all(isinstance(a, float) for a in args):
                return self._apply_scalar(op, args)
            return ops[op](*args)

        return _walk(self.tree, lambda n: self._leaf(n, env), apply)


# ------------------------------------------------------------------------------- derivative
_ZERO, _ONE = ("num", 0.0), ("num", 1.0)


def _add(a: Node, b: Node) -> Node:
    return b if a == _ZERO else a if b == _ZERO else ("add", a, b)


def _sub(a: Node, b: Node) -> Node:
    return a if b == _ZERO else ("neg", b) if a == _ZERO else ("sub", a, b)


def _mul(a: Node, b: Node) -> Node:
    if _ZERO in (a, b):
        return _ZERO
    return b if a == _ONE else a if b == _ONE else ("mul", a, b)


def _div(a: Node, b: Node) -> Node:
    return _ZERO if a == _ZERO else a if b == _ONE else ("div", a, b)


def _call(name: str, *args: Node) -> Node:
    return ("call", name, *args)


def _step(x: Node) -> Node:
    return _call("heaviside", x)


def _derivative(node: Node, name: str) -> Node:
    """d node / d name as a tree (zeros folded). heaviside' = 0: a jump has no derivative
    here, so a prescribed motion with a step gets no velocity at the step."""
    kind = node[0]
    if kind == "num":
        return _ZERO
    if kind == "var":
        return _ONE if node[1] == name else _ZERO
    if kind in ("add", "sub"):
        da, db = (_derivative(c, name) for c in node[1:])
        return _add(da, db) if kind == "add" else _sub(da, db)
    if kind in ("neg", "pos"):
        d = _derivative(node[1], name)
        return d if kind == "pos" or d == _ZERO else ("neg", d)
    if kind == "mul":
        a, b = node[1:]
        return _add(_mul(_derivative(a, name), b), _mul(a, _derivative(b, name)))
    if kind == "div":
        a, b = node[1:]
        da, db = _derivative(a, name), _derivative(b, name)
        return _sub(_div(da, b), _div(_mul(a, db), ("mul", b, b)))
    if kind == "pow":
        a, b = node[1:]
        da, db = _derivative(a, name), _derivative(b, name)
        if db == _ZERO:  # a^b, b free of the variable: b a^(b−1) a'
            return _mul(_mul(b, ("pow", a, ("sub", b, _ONE))), da)
        return _mul(node, _add(_mul(db, _call("log", a)), _div(_mul(b, da), a)))
    fname, args = node[1], node[2:]
    if fname in ("min", "max"):
        a, b = args
        first = _step(("sub", b, a) if fname == "min" else ("sub", a, b))
        return _add(
            _mul(first, _derivative(a, name)),
            _mul(("sub", _ONE, first), _derivative(b, name)),
        )
    (a,) = args
    da = _derivative(a, name)
    if da == _ZERO or fname == "heaviside":
        return _ZERO
    outer = {
        "sin": lambda: _call("cos", a),
        "cos": lambda: ("neg", _call("sin", a)),
        "tan": lambda: ("div", _ONE, ("pow", _call("cos", a), ("num", 2.0))),
        "asin": lambda: ("div", _ONE, _call("sqrt", ("sub", _ONE, ("mul", a, a)))),
        "acos": lambda: ("neg", ("div", _ONE, _call("sqrt", ("sub", _ONE, ("mul", a, a))))),
        "atan": lambda: ("div", _ONE, ("add", _ONE, ("mul", a, a))),
        "sinh": lambda: _call("cosh", a),
        "cosh": lambda: _call("sinh", a),
        "tanh": lambda: ("div", _ONE, ("pow", _call("cosh", a), ("num", 2.0))),
        "exp": lambda: node,
        "log": lambda: ("div", _ONE, a),
        "sqrt": lambda: ("div", _ONE, ("mul", ("num", 2.0), node)),
        "abs": lambda: ("sub", _step(a), _step(("neg", a))),
        "ramp": lambda: _step(a),
    }[fname]()
    return _mul(outer, da)


def derivative(expr: Expression, name: str) -> Expression:
    """d expr / d name, an Expression of the same names (its source reads "d/dt(...)"); a
    load given by a table, its interpolant's derivative (cosserat_fem/scene/load_data.py)."""
    if not isinstance(expr, Expression):
        return expr.derivative(name)
    return Expression(f"d/d{name}({expr.source})", expr.names, _derivative(expr.tree, name))


def parse_vector(
    value: object, allowed_names: Iterable[str] | None, key: str
) -> tuple[Expression, Expression, Expression]:
    """Parse a list of 3 numbers/expression strings; component keys are ``key[i]``."""
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise SceneError(
            f"{key}: must be a list of 3 numbers or expression strings, got {show_value(value)}"
        )
    allowed = None if allowed_names is None else frozenset(allowed_names)
    x, y, z = (Expression.parse(v, allowed, f"{key}[{i}]") for i, v in enumerate(value))
    return x, y, z
