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
"""

from __future__ import annotations

import ast
import difflib
import math
import numbers
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosserat_fem.errors import SceneError, show_value

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

_MAX_DEPTH = 100  # nesting limit of the expression tree (guards the recursive walkers)

_BINARY = {ast.Add: "add", ast.Sub: "sub", ast.Mult: "mul", ast.Div: "div", ast.Pow: "pow"}
_UNARY = {ast.UAdd: "pos", ast.USub: "neg"}

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


def _is_real(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


# ------------------------------------------------------------------------------------- parser
class _Parser:
    """Converts a Python AST into the internal tree, enforcing the whitelist."""

    def __init__(self, text: str, allowed: frozenset[str] | None, key: str) -> None:
        self.text = text
        self.allowed = allowed  # None: any identifier is accepted as a variable
        self.key = key
        self.names: set[str] = set()

    def fail(self, reason: str, node: ast.AST | None = None, hint: str = "") -> SceneError:
        where = f" at column {node.col_offset + 1}" if node is not None else ""
        return SceneError(f"{self.key}: {reason}{where} in {show_value(self.text)}{hint}")

    def convert(self, node: ast.AST, depth: int = 0) -> Node:
        if depth > _MAX_DEPTH:
            raise self.fail(f"expression nested deeper than {_MAX_DEPTH} levels")
        if isinstance(node, ast.Constant):
            return self.number(node)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            tree = (_BINARY[type(node.op)], *self.children([node.left, node.right], depth))
            return self.checked(tree, node)
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            return self.checked(
                (_UNARY[type(node.op)], self.convert(node.operand, depth + 1)), node
            )
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        raise self.fail(f"{self.describe(node)} not allowed", node)

    def children(self, kids: list[ast.expr], depth: int) -> list[Node]:
        return [self.convert(kid, depth + 1) for kid in kids]

    @staticmethod
    def describe(node: ast.AST) -> str:
        for kind, text in _REFUSED.items():
            if isinstance(node, kind):
                return text
        if isinstance(node, ast.BinOp):
            return f"operator {type(node.op).__name__!r} (only + - * / ** are allowed)"
        if isinstance(node, ast.UnaryOp):
            return f"operator {type(node.op).__name__!r} (only unary + - are allowed)"
        return f"construct {type(node).__name__!r}"

    def number(self, node: ast.Constant) -> Node:
        value = node.value
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(f"literal {value!r} not allowed (only numbers)", node)
        number = _finite_float(value)
        if number is None:
            raise self.fail("number literal is not finite", node)
        return ("num", number)

    def name(self, node: ast.Name) -> Node:
        ident = node.id
        if ident in FUNCTIONS:
            raise self.fail(f"function {ident!r} used without arguments; write {ident}(...)", node)
        if ident not in CONSTANTS and self.allowed is not None and ident not in self.allowed:
            raise self.fail(f"unknown name {ident!r}", node, self.suggest(ident))
        self.names.add(ident)
        return ("var", ident)

    def suggest(self, ident: str) -> str:
        pool = sorted(set(CONSTANTS) | (self.allowed or set()))
        close = difflib.get_close_matches(ident, pool, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return f"{hint}; allowed names: {', '.join(pool)}"

    def call(self, node: ast.Call, depth: int) -> Node:
        func = node.func
        if not isinstance(func, ast.Name):
            raise self.fail("only calls of plain function names are allowed", node)
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
        args = self.children(node.args, depth)
        return self.checked(("call", func.id, *args), node)

    def checked(self, tree: Node, node: ast.AST) -> Node:
        """Evaluate constant subtrees now, so that ``1/0`` or ``log(-1)`` fail at parse time."""
        if _free_names(tree):
            return tree
        try:
            value = _walk(tree, _constant_leaf, lambda op, args: _SCALAR_OPS[op](*args))
            finite = math.isfinite(value)
        except (ArithmeticError, ValueError) as exc:
            segment = ast.get_source_segment(self.text, node) or self.text
            raise self.fail(f"{segment!r} cannot be evaluated ({exc})", node) from None
        if not finite:
            segment = ast.get_source_segment(self.text, node) or self.text
            raise self.fail(f"{segment!r} is not finite", node)
        return tree


def _free_names(tree: Node) -> set[str]:
    """Variable names of the tree other than the built-in constants."""
    found: set[str] = set()

    def leaf(node: Node) -> None:
        if node[0] == "var" and node[1] not in CONSTANTS:
            found.add(node[1])

    _walk(tree, leaf, lambda op, args: None)
    return found


def _constant_leaf(node: Node) -> float:
    return node[1] if node[0] == "num" else CONSTANTS[node[1]]


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


def _parse_tree(
    value: object, allowed: frozenset[str] | None, key: str
) -> tuple[str, Node, frozenset[str]]:
    """Validate ``value`` (number or string) → (source, tree, names)."""
    if _is_real(value):
        number = _finite_float(value)
        if number is None:
            raise SceneError(f"{key}: must be a finite number, got {show_value(value)}")
        source = str(value) if isinstance(value, numbers.Integral) else repr(number)
        return source, ("num", number), frozenset()
    if not isinstance(value, str):
        raise SceneError(
            f"{key}: must be a number or an expression string, got {show_value(value)}"
        )
    text = value.strip()
    if not text:
        raise SceneError(f"{key}: empty expression string")
    try:
        body = ast.parse(text, mode="eval").body
    except SyntaxError as exc:
        column = _syntax_error_place(exc, text)
        raise SceneError(f"{key}: syntax error{column} in {show_value(text)} ({exc.msg})") from None
    except (RecursionError, MemoryError, ValueError) as exc:
        raise SceneError(f"{key}: cannot parse {show_value(text)} ({exc})") from None
    parser = _Parser(text, allowed, key)
    tree = parser.convert(body)
    return text, tree, frozenset(parser.names)


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
    """d expr / d name, an Expression of the same names (its source reads "d/dt(...)")."""
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
