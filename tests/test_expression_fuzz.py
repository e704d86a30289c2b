"""Fuzz-style tests of the safe expression parser (cosserat_fem/scene/expressions.py).

Bad and borderline inputs, most of them generated (seeded, so every run sees the same cases):
token soups, every character that Python's NFKC folding changes, chains of every operator
around the balancing threshold and the size limits, deep nesting of every kind, injection
attempts, long literals. The contract checked for each input (:func:`outcome`): parsing gives
either an Expression whose value matches an independent evaluation, or a SceneError of one line
that starts with the key and gives a non-empty reason; never any other exception.

Every test whose docstring names a defect failed on the parser before the fix (checked by
running this file against it): D4 look-alike names read as other names (Unicode NFKC), D14 a
flat sum taken for deep nesting and no size limits, D17 refusals without a reason (or with a
traceback).
"""

from __future__ import annotations

import ast
import math
import random
import re
import subprocess
import sys
import unicodedata
from functools import cache
from pathlib import Path

import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.scene import expressions
from cosserat_fem.scene.expressions import Expression, derivative

ROOT = Path(__file__).resolve().parents[1]
KEY = "loads.end.torque[2]"
NAMES = frozenset({"s", "t", "L", "omega0", "a"})
VALUES = {"s": 0.3, "t": 0.7, "L": 2.0, "omega0": 3.0, "a": 1.5}
EPS = sys.float_info.epsilon
# The documented limits (test_limits_are_the_documented_ones checks the module against them;
# read here so that every other test also runs, and fails for its own reason, on code without).
MAX_DEPTH, MAX_NODES, MAX_LENGTH, BALANCE_ABOVE = 100, 2000, 20000, 16
DEEP = f"nested deeper than {MAX_DEPTH} levels"

ERROR = "error"  # the outcome of an evaluation that raises (math domain, overflow, 1/0)


# ------------------------------------------------------------------------------ the contract
def outcome(text: object, names: frozenset[str] | None = NAMES, key: str = KEY):
    """Parse; return the Expression or the SceneError after checking the message contract:
    one line, ``key: `` first, a non-empty reason after it, and no empty ``()`` where a reason
    should be (the D17 symptom ``cannot parse "..." ()``). Any other exception propagates."""
    try:
        return Expression.parse(text, names, key)
    except SceneError as exc:
        message = str(exc)
        assert "\n" not in message and "\r" not in message, message
        assert message.startswith(f"{key}: "), message
        reason = message[len(key) + 2 :]
        assert reason.strip(), message
        assert not re.search(r"\(\s*\)$", message), f"empty reason: {message}"
        return exc


def refused(text: object, fragment: str = "", names: frozenset[str] | None = NAMES) -> str:
    """The message of the SceneError that ``text`` must give (containing ``fragment``)."""
    result = outcome(text, names)
    assert isinstance(result, SceneError), f"accepted: {str(text)[:80]!r}"
    assert fragment in str(result), str(result)
    return str(result)


def accepted(text: str, names: frozenset[str] | None = NAMES) -> Expression:
    result = outcome(text, names)
    assert isinstance(result, Expression), str(result)
    return result


def _heaviside(x: float) -> float:
    return 1.0 if x >= 0.0 else 0.0


REFERENCE_FUNCTIONS = {
    **{name: getattr(math, name) for name in "sin cos tan asin acos atan sinh cosh tanh".split()},
    **{name: getattr(math, name) for name in "exp log sqrt".split()},
    "abs": abs,
    "min": min,
    "max": max,
    "heaviside": _heaviside,
    "ramp": lambda x: x if x > 0.0 else 0.0,
}


def _real_pow(a: float, b: float) -> float:
    """Python's ``a ** b``, but a complex result (negative base, fractional power) is an error
    (the parser's language is real)."""
    value = a**b
    if isinstance(value, complex):
        raise ValueError("complex power")
    return value


class _Reference(ast.NodeTransformer):
    """int literals → floats, ``a ** b`` → ``_real_pow(a, b)``."""

    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        if isinstance(node.value, int) and not isinstance(node.value, bool):
            return ast.copy_location(ast.Constant(float(node.value)), node)
        return node

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        if isinstance(node.op, ast.Pow):
            call = ast.Call(ast.Name("_real_pow", ast.Load()), [node.left, node.right], [])
            return ast.copy_location(call, node)
        return node


def reference(text: str, values: dict[str, float]) -> float | str:
    """Python's own value of an accepted expression (int literals as floats, real powers, the
    math module, heaviside/ramp as documented), or ERROR. Only called on text the parser
    accepted, so it is whitelisted; it is still run without builtins."""
    tree = _Reference().visit(ast.parse(text, mode="eval"))
    code = compile(ast.fix_missing_locations(tree), "<reference>", "eval")
    env = {"__builtins__": {}, **REFERENCE_FUNCTIONS, "_real_pow": _real_pow, "pi": math.pi}
    env.update({"e": math.e, **values})
    try:
        return float(eval(code, env))  # noqa: S307 - test oracle on whitelisted text
    except (ArithmeticError, ValueError):
        return ERROR


def ours(expr: Expression, values: dict[str, float]) -> float | str:
    try:
        return expr.evaluate(**values)
    except ValueError:
        return ERROR


def same(a: float | str, b: float | str) -> bool:
    """Bit-identical values (nan equals nan), or both errors."""
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return (math.isnan(a) and math.isnan(b)) or a == b


def height(tree: tuple) -> int:
    """Levels of an internal tree (iterative, so it works on any tree)."""
    best, stack = 0, [(tree, 0)]
    while stack:
        node, level = stack.pop()
        best = max(best, level)
        if node[0] in ("num", "var"):
            continue
        children = node[2:] if node[0] == "call" else node[1:]
        stack.extend((child, level + 1) for child in children)
    return best


def node_count(tree: tuple) -> int:
    count, stack = 0, [tree]
    while stack:
        node = stack.pop()
        count += 1
        if node[0] == "call":
            stack.extend(node[2:])
        elif node[0] not in ("num", "var"):
            stack.extend(node[1:])
    return count


def test_limits_are_the_documented_ones() -> None:
    """The limits the other tests use are the module's (the docstring explains them)."""
    assert (expressions.MAX_DEPTH, expressions.MAX_NODES, expressions.MAX_LENGTH) == (
        MAX_DEPTH,
        MAX_NODES,
        MAX_LENGTH,
    )
    assert expressions.BALANCE_ABOVE == BALANCE_ABOVE


# ------------------------------------------------------------------------------ token soups
GOOD_TOKENS = [
    *"s t L omega0 a pi e sin cos exp log sqrt abs heaviside ramp min max".split(),
    *"0 1 2 0.5 1e3 1e-3 3.7e-5 .5 5. 1_0 0x1f".split(),
    *"+ - * / ** ( ) ( ) ( ) , + - *".split(),
]
HOSTILE_TOKENS = [
    *"q nan inf x __import__ __class__ lambda if else for in not and or".split(),
    *"tan asin acos atan sinh cosh tanh 1e308 1e400 1j 0b2 09".split(),
    *"( ) , . [ ] { } : := % // @ ~ < == ; = ! ' \" # \\ ...".split(),
    "ｔ",
    "𝑡",
    "ﬁ",
    "ω",
    "ℓ",
    "²",
    "＋",
    " ",
    "\n",
    "\t",
    "\0",
    "\ud800",
    "f'",
    "b'",
]


def test_token_soups_never_crash() -> None:
    """3000 random sequences of 1-12 tokens (80 % valid tokens, 20 % hostile ones). Accepted
    soups must evaluate exactly like Python: they are short (chains of at most 12 operands,
    below the balancing threshold of 16), so the same IEEE operations run in the same order
    and the results are bit-identical (or both raise)."""
    rng = random.Random(20240517)
    counts = {"accepted": 0, "refused": 0}
    for _ in range(3000):
        text = "".join(
            rng.choice(GOOD_TOKENS if rng.random() < 0.8 else HOSTILE_TOKENS)
            + rng.choice(["", "", " "])
            for _ in range(rng.randint(1, 12))
        )
        result = outcome(text)
        if isinstance(result, SceneError):
            counts["refused"] += 1
            continue
        counts["accepted"] += 1
        assert same(ours(result, VALUES), reference(result.source, VALUES)), text
    assert counts["accepted"] > 100 and counts["refused"] > 1000, counts


def _random_expression(rng: random.Random, depth: int) -> str:
    """A random valid expression (chains of at most 5 operands)."""
    if depth == 0 or rng.random() < 0.25:
        return rng.choice(
            [*sorted(NAMES), "pi", "e", repr(rng.uniform(-3, 3)), str(rng.randint(0, 9))]
        )
    kind = rng.random()
    sub = lambda: _random_expression(rng, depth - 1)  # noqa: E731
    if kind < 0.35:
        ops = [rng.choice("+-*/") for _ in range(rng.randint(1, 4))]
        # "+" keeps a chain in the first operand from joining this one (chains stay <= 5)
        return "(+" + sub() + "".join(f" {op} {sub()}" for op in ops) + ")"
    if kind < 0.45:
        return f"({sub()})**{rng.choice(['2', '0.5', '3', '-1', sub()])}"
    if kind < 0.55:
        return rng.choice("-+") + sub()
    name = rng.choice(sorted(expressions.FUNCTIONS))
    args = ", ".join(sub() for _ in range(expressions.FUNCTIONS[name]))
    return f"{name}({args})"


def test_random_valid_expressions_match_python() -> None:
    """1500 random well-formed expressions: accepted with Python's value, bit-identical (short
    chains keep Python's left-to-right order, see test_token_soups_never_crash), or refused only
    because a constant part cannot be evaluated or is not finite (a documented input error). For
    accepted ones the node count is exact: MAX_NODES equal to it accepts, one less refuses."""
    rng = random.Random(7)
    accepted_count = 0
    for i in range(1500):
        text = _random_expression(rng, rng.randint(1, 5))
        result = outcome(text)
        if isinstance(result, SceneError):
            assert re.search(r"cannot be evaluated|is not finite", str(result)), str(result)
            continue
        accepted_count += 1
        for values in (VALUES, {**VALUES, "s": -1.7, "t": 12.5}):
            assert same(ours(result, values), reference(text, values)), text
        if i % 10 == 0:
            count = node_count(result.tree)
            limits = pytest.MonkeyPatch()
            try:
                limits.setattr(expressions, "MAX_NODES", count)
                assert isinstance(outcome(text), Expression)
                limits.setattr(expressions, "MAX_NODES", count - 1)
                refused(text, f"expression of {count} numbers, names and operators")
            finally:
                limits.undo()
    assert accepted_count > 1000


# ------------------------------------------------------------------------ D4: NFKC look-alikes
@cache
def _folding_identifier_characters() -> tuple[str, ...]:
    """Every character that may continue an identifier and that NFKC changes (about 3600)."""
    found = []
    for code in range(0x80, 0x110000):
        char = chr(code)
        if 0xD800 <= code <= 0xDFFF or not ("a" + char).isidentifier():
            continue
        if unicodedata.normalize("NFKC", char) != char:
            found.append(char)
    return tuple(found)


LOOKALIKES = {  # escapes, so that no editor or tool folds them on the way
    "fullwidth": "\uff54",  # t
    "fullwidth capital": "\uff2c",  # L
    "mathematical italic": "\U0001d461",  # t
    "mathematical bold": "\U0001d42c",  # s
    "mathematical double-struck": "\U0001d565",  # t
    "mathematical sans-serif": "\U0001d5ba",  # a
    "script small l": "\u2113",
    "ligature fi": "\ufb01",
    "ligature st": "\ufb06",
    "modifier (superscript) small a": "\u1d43",
    "subscript small a": "\u2090",
    "long s": "\u017f",
    "kelvin sign": "\u212a",  # K
    "ohm sign": "\u2126",  # Greek capital omega
    "micro sign": "\u00b5",  # Greek mu
    "roman numeral one": "\u2160",  # I
    "fullwidth digit in a name": "omega\uff10",  # omega0
    "mathematical digit in a name": "omega\U0001d7ce",  # omega0
    "keyword look-alike": "\uff4cambda",  # lambda
}


@pytest.mark.parametrize("written", list(LOOKALIKES.values()), ids=list(LOOKALIKES))
def test_lookalike_names_are_refused(written: str) -> None:
    """D4: a name written with a look-alike letter is refused, even when the name Python
    would read it as is allowed (``t``, ``s``...) and when any name is allowed; the message says
    what Python reads and where (in characters)."""
    folded = unicodedata.normalize("NFKC", written)
    for text, column in ((f"1e3*{written}", 5), (f"{written} + t", 1), (f"ω*{written}", 3)):
        for names in (NAMES | {written, folded, "ω"}, None):
            message = refused(text, "(Unicode NFKC)", names)
            assert f"the name {written!r} is read by Python as {folded!r}" in message
            assert f"at column {column} " in message and "write it as plain letters" in message


@pytest.mark.parametrize("function", ["ｓin", "𝑠in", "ｍax", "ｅxp", "ﬂoor"])
def test_lookalike_function_names_are_refused(function: str) -> None:
    """D4: a called function name is compared as written too (``ｓin`` is not ``sin``)."""
    refused(f"2*{function}(t)", "(Unicode NFKC)")
    refused(f"2*{function}(t)", "at column 3 ", names=None)


def test_every_nfkc_folding_identifier_character_is_refused() -> None:
    """D4, the whole class: every character NFKC changes, in every position of a name (after a
    letter, and first where it may start a name), is refused by the parser and by check_name;
    no exception type other than SceneError."""
    check_name = expressions.check_name
    chars = _folding_identifier_characters()
    assert len(chars) > 3000
    for char in chars:
        for name in (f"a{char}", *((char,) if char.isidentifier() else ())):
            folded = unicodedata.normalize("NFKC", name)
            for names in (None, NAMES | {name, folded}):
                assert "(Unicode NFKC)" in refused(f"t*{name}", names=names), name
            with pytest.raises(SceneError, match=r"^parameters\.x: the name .* \(Unicode NFKC\)"):
                check_name(name, "parameters.x")


def test_nfkc_folding_characters_outside_names_are_refused() -> None:
    """Characters NFKC changes that cannot be part of a name (``²``, ``＋``, ``①``, ``⑴``,
    no-break space...): never accepted, always a reasoned SceneError (Python: invalid
    character)."""
    rng = random.Random(3)
    others = [
        chr(code)
        for code in range(0xA0, 0x30000)
        if not 0xD800 <= code <= 0xDFFF
        and not ("a" + chr(code)).isidentifier()
        and unicodedata.normalize("NFKC", chr(code)) != chr(code)
    ]
    assert len(others) > 500
    for char in rng.sample(others, 400) + ["²", "＋", "①", "⑴", "\u00a0", "＊", "（"]:
        refused(f"t +{char}+ t")


def test_check_name() -> None:
    """D4 for declared parameters: check_name refuses what NFKC changes, names the key and the
    folded name, and passes NFKC-stable names (ASCII, Greek)."""
    check_name = expressions.check_name
    with pytest.raises(SceneError) as info:
        check_name("ｔ", "parameters.ｔ")
    assert str(info.value) == (
        "parameters.ｔ: the name 'ｔ' is read by Python as 't' (Unicode NFKC); "
        "write it as plain letters"
    )
    for name in ("t", "omega0", "ω", "αβγ", "ω_2", "Ω", "x_é"):
        check_name(name, "parameters.x")


def test_nfkc_stable_non_ascii_names_stay_allowed() -> None:
    """Greek (and other NFKC-stable) names are used as written; the values are exact (one
    multiplication and one addition, as in Python)."""
    greek = [chr(c) for c in range(0x3B1, 0x3CA) if unicodedata.normalize("NFKC", chr(c)) == chr(c)]
    assert len(greek) == 25
    for name in greek:
        expr = accepted(f"2*{name} + t", NAMES | {name})
        assert expr.evaluate(**{name: 0.25}, t=0.5) == 2 * 0.25 + 0.5


def test_columns_count_characters() -> None:
    """Columns are characters, not UTF-8 bytes (ast's col_offset): ``q`` is the 3rd character
    of ``ω*q`` although it starts at byte 3."""
    assert "at column 3 " in refused("ω*q", "unknown name 'q'", NAMES | {"ω"})
    assert "at column 6 " in refused("ωω*ω/q", "unknown name 'q'", NAMES | {"ω", "ωω"})


# -------------------------------------------------------------------- D14: chains and limits
CHAIN_LENGTHS = [2, 3, 15, 16, 17, 18, 31, 32, 33, 100, 101, 102, 150, 500]


def _terms(rng: random.Random, n: int) -> tuple[list[str], list[float], list[str]]:
    """n random coefficients c_k > 0 (the chain is sum of ±c_k*t), as text and value, and
    the signs."""
    coefficients = [rng.uniform(0.01, 2.0) for _ in range(n)]
    signs = ["+"] + [rng.choice("+-") for _ in range(n - 1)]
    return [repr(c) for c in coefficients], coefficients, signs


@pytest.mark.parametrize("n", CHAIN_LENGTHS)
def test_sums_of_any_length_are_accepted_and_summed_within_round_off(n: int) -> None:
    """D14: a flat chain of + and - of n terms c_k*t is not nesting: accepted for every n up to
    the size limit, stored with height n (n-1 levels as written, 1 for the products c_k*t) up
    to 16 operands and at most ceil(log2 n) + 1 above. Up to 16 operands the result is
    bit-identical to
    Python's left-to-right sum; above, both sums of the same computed terms x_k err by at most
    (n-1) u sum|x_k| to first order (u = eps/2, any summation order, Higham 2002 ch. 4), so
    they differ by at most n eps sum|x_k|."""
    rng = random.Random(n)
    texts, coefficients, signs = _terms(rng, n)
    t = VALUES["t"]
    rest = zip(signs[1:], texts[1:], strict=True)
    source = texts[0] + "*t" + "".join(f" {sign} {c}*t" for sign, c in rest)
    expr = accepted(source)
    terms = [c * t for c in coefficients]
    left_to_right = terms[0]
    for sign, term in zip(signs[1:], terms[1:], strict=True):
        left_to_right = left_to_right + term if sign == "+" else left_to_right - term
    value = expr.evaluate(**VALUES)
    if n <= BALANCE_ABOVE:
        assert value == left_to_right == reference(source, VALUES)
        assert height(expr.tree) == n
    else:
        assert abs(value - left_to_right) <= n * EPS * sum(abs(x) for x in terms)
        assert height(expr.tree) <= math.ceil(math.log2(n)) + 1


@pytest.mark.parametrize("n", [*CHAIN_LENGTHS, 999, 1000])
@pytest.mark.parametrize("ops", ["+", "-", "+-"])
def test_integer_sums_are_exact(n: int, ops: str) -> None:
    """D14: with integer terms every partial sum is an exact integer (|sum| < 2^53), so any
    association must give exactly the written sum: no term lost, duplicated or sign-flipped by
    the rebalancing (-a - b = -(a + b), -a + b = b - a)."""
    rng = random.Random(n * 31 + len(ops))
    numbers = [rng.randint(0, 1000) for _ in range(n)]
    chosen = [rng.choice(ops) for _ in range(n - 1)]
    rest = list(zip(chosen, numbers[1:], strict=True))
    source = str(numbers[0]) + "".join(f"{op}{x}" for op, x in rest)
    total = numbers[0] + sum(x if op == "+" else -x for op, x in rest)
    assert accepted(source).evaluate() == total
    with_t = "t" + "".join(f"{op}t" for op in chosen)
    count = 1 + sum(1 if op == "+" else -1 for op in chosen)
    assert accepted(with_t).evaluate(t=0.5) == count * 0.5


@pytest.mark.parametrize("n", CHAIN_LENGTHS)
def test_products_and_quotients_within_round_off(n: int) -> None:
    """D14 for * and /: factors in [0.5, 2], randomly multiplied or divided. Up to 16 operands
    bit-identical to Python; above, each of the n operations (t*x_0*...) of either order rounds
    once (relative error <= u), so the two products differ by at most about 2n u = n eps
    relative. With powers of two the product is exact in any order."""
    rng = random.Random(1000 + n)
    factors = [rng.uniform(0.5, 2.0) for _ in range(n)]
    ops = [rng.choice("*/") for _ in range(n - 1)]
    rest = list(zip(ops, factors[1:], strict=True))
    source = repr(factors[0]) + "".join(f" {op} {x!r}" for op, x in rest)
    left_to_right = factors[0]
    for op, x in rest:
        left_to_right = left_to_right * x if op == "*" else left_to_right / x
    expr = accepted(f"t*{source}")  # t = 1: the same value, but not a constant
    value = expr.evaluate(t=1.0)
    if n + 1 <= BALANCE_ABOVE:
        assert value == left_to_right
    else:
        assert abs(value - left_to_right) <= n * EPS * abs(left_to_right)
    powers = [rng.choice([0.5, 2.0, 4.0, 0.25]) for _ in range(n)]
    rest = list(zip(ops, powers[1:], strict=True))
    exact_source = repr(powers[0]) + "".join(f"{op}{x!r}" for op, x in rest)
    exact = powers[0]
    for op, x in rest:
        exact = exact * x if op == "*" else exact / x
    assert accepted(f"t*{exact_source}").evaluate(t=1.0) == exact


def test_short_chains_keep_the_written_association() -> None:
    """Up to 16 operands the tree is exactly Python's left-deep one, so results are Python's
    bit for bit (0.1 + 0.2 + 0.3 is not 0.1 + (0.2 + 0.3) in floating point)."""
    for ops in ("+-", "*/"):
        for n in range(2, BALANCE_ABOVE + 1):
            rng = random.Random(n)
            operators = [rng.choice(ops) for _ in range(n - 1)]
            source = "t" + "".join(f"{op}{rng.uniform(0.1, 0.9)!r}" for op in operators)
            expected = ast.parse(source, mode="eval").body
            tree = accepted(source).tree
            for _ in operators:  # the left spine, innermost last
                assert (
                    tree[0]
                    == {ast.Add: "add", ast.Sub: "sub", ast.Mult: "mul", ast.Div: "div"}[
                        type(expected.op)
                    ]
                )
                assert tree[2] == ("num", expected.right.value)
                tree, expected = tree[1], expected.left
            assert tree == ("var", "t")


def test_a_balanced_sum_differentiates_correctly() -> None:
    """D14: d/dt of sum_k c_k sin(k t) (150 terms, balanced) is sum_k c_k k cos(k t). Each term
    is computed with at most 4 roundings in either (k t, cos, two products), and the sums of
    150 terms differ by at most n eps sum|terms| in any order, so the bound is
    (n + 4) eps sum_k |c_k| k. The derivative tree stays balanced."""
    rng = random.Random(11)
    n = 150
    coefficients = [rng.uniform(-1.0, 1.0) for _ in range(n)]
    source = " + ".join(f"{c!r}*sin({k}*t)" for k, c in enumerate(coefficients, start=1))
    expr = accepted(source)
    assert height(expr.tree) <= math.ceil(math.log2(n)) + 3
    d = derivative(expr, "t")
    assert height(d.tree) <= 2 * (math.ceil(math.log2(n)) + 3)
    bound = (n + 4) * EPS * sum(abs(c) * k for k, c in enumerate(coefficients, start=1))
    for t in (0.0, 0.37, 1.9, -4.2):
        exact = math.fsum(c * k * math.cos(k * t) for k, c in enumerate(coefficients, start=1))
        assert abs(d.evaluate(t=t) - exact) <= bound
        # a central difference: truncation <= h^2/6 max|third derivative| <= h^2/6 sum|c_k| k^3,
        # and the two evaluations' round-off (<= n eps sum|c_k| each, as above) over 2h
        h = 1e-5
        fd = (expr.evaluate(t=t + h) - expr.evaluate(t=t - h)) / (2 * h)
        truncation = h**2 / 6 * sum(abs(c) * k**3 for k, c in enumerate(coefficients, start=1))
        round_off = n * EPS * sum(abs(c) for c in coefficients) / h
        assert abs(fd - exact) <= truncation + round_off


def test_a_long_sum_reaches_ufl_shallow() -> None:
    """D14: a 500-term sum (1999 nodes) goes through to_ufl and UFL's own recursive evaluation
    (which exceeds Python's recursion limit on a 499-deep left chain, as measured); the value
    equals evaluate() exactly when folded (same tree, same operations), and to 1e-13 relative
    through UFL (which may reorder a sum)."""
    import ufl

    source = "+".join(f"{k % 7 + 1}*t" for k in range(500))
    expr = accepted(source)
    assert height(expr.tree) == 1 + math.ceil(math.log2(500))
    assert expr.to_ufl({"t": 0.5}) == expr.evaluate(t=0.5)
    mesh = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.interval, 1))
    t_const = ufl.Constant(mesh)
    as_ufl = expr.to_ufl({"t": t_const})
    value = float(as_ufl((0.0,), {t_const: 0.5}))
    assert value == pytest.approx(expr.evaluate(t=0.5), rel=1e-13)


def _sized(shape: str, n: int) -> str:
    """An expression of exactly n nodes (numbers, names, operators, calls) of a given shape."""
    if shape in ("sum", "product"):  # t+t+...: 2k+1 nodes; -t+t+...: 2k+2
        op = "+" if shape == "sum" else "*"
        return ("t" if n % 2 else "-t") + f"{op}t" * ((n - 1) // 2 if n % 2 else (n - 2) // 2)
    # sin(t)/sin(t)/...: 2 + 3k nodes; a leading sign adds 1, a trailing +t adds 2
    k, rest = divmod(n - 2, 3)
    return ("-" if rest == 1 else "") + "sin(t)" + "/sin(t)" * k + ("+t" if rest == 2 else "")


@pytest.mark.parametrize("shape", ["sum", "product", "calls"])
def test_node_limit(shape: str) -> None:
    """D14: the size limit is exact (the nodes of the tree: numbers, names, operators, calls)
    and its message says the limit and what was found, and names the alternative for a load
    given by data (a measured history), a table (issue 25 E24)."""
    for n in (MAX_NODES - 1, MAX_NODES):
        assert node_count(accepted(_sized(shape, n)).tree) == n
    for n in (MAX_NODES + 1, MAX_NODES + 2, 2 * MAX_NODES):
        message = refused(_sized(shape, n), f"more than the limit of {MAX_NODES}")
        assert f"expression of {n} numbers, names and operators" in message
        assert '{table = "file.csv", column = "..."}' in message  # the alternative for data


def test_length_limit() -> None:
    """D14: the text-length limit is exact, counted after stripping blanks at both ends, and
    the message says the limit and the length found."""
    padded = "t" + " " * (MAX_LENGTH - 3) + "+t"
    assert len(padded) == MAX_LENGTH
    assert accepted(f"  {padded}  ").evaluate(t=0.25) == 0.5
    message = refused(padded + "0", f"limit of {MAX_LENGTH}")
    assert f"expression of {MAX_LENGTH + 1} characters" in message


# ---------------------------------------------------------------- D17: nesting and reasons
# One level of nesting around x: (text before, text after, its value as a function of x).
WRAPPERS = {
    "unary minus": ("-", "", lambda x: -x),
    "unary plus": ("+", "", lambda x: x),
    "parentheses": ("(1+", ")", lambda x: 1.0 + x),
    "product in parentheses": ("0.5*(", ")", lambda x: 0.5 * x),
    "calls": ("sin(", ")", math.sin),
    "two-argument calls": ("min(2, ", ")", lambda x: min(2.0, x)),
    "powers": ("(", ")**1", lambda x: math.pow(x, 1.0)),
}
NEST_KINDS = [*WRAPPERS, "power chain", "mixed"]
# for "mixed": a bare sign before "0.5*(" would sign the 0.5 only (the same value, a level less)
MIXED = {k: w for k, w in WRAPPERS.items() if not k.startswith("unary")}
MIXED["signed"] = ("-(", ")", lambda x: -x)


def _nest(kind: str, levels: int, seed: int = 0) -> tuple[str, object]:
    """``t`` nested ``levels`` deep, and its value as a function of t (the same operations in
    the same order as the parser's tree). "power chain" is t**1**...**1 (right-associative,
    without parentheses); "mixed" draws a wrapper at random for each level."""
    if kind == "power chain":
        return "t" + "**1" * levels, lambda t: t
    rng = random.Random(seed)
    chosen = [kind if kind != "mixed" else rng.choice(list(MIXED)) for _ in range(levels)]
    wrappers = {**WRAPPERS, **MIXED}
    before = "".join(wrappers[k][0] for k in reversed(chosen))
    after = "".join(wrappers[k][1] for k in chosen)

    def value(t: float) -> float:
        for k in chosen:
            t = wrappers[k][2](t)
        return t

    return before + "t" + after, value


@pytest.mark.parametrize("kind", NEST_KINDS)
def test_nesting_at_the_depth_limit(kind: str) -> None:
    """D14: every kind of true nesting is accepted up to MAX_DEPTH levels with the right value
    (the same operations as the math-module loop: exact), and refused one level deeper with a
    message that says the limit and how levels count (now that chains count differently)."""
    for levels in (1, 2, MAX_DEPTH - 1, MAX_DEPTH):
        text, value = _nest(kind, levels, seed=levels)
        expr = accepted(text)
        assert height(expr.tree) == levels
        assert expr.evaluate(t=0.3) == value(0.3)
    text, _ = _nest(kind, MAX_DEPTH + 1)
    message = refused(text, DEEP)
    assert "a chain a+b+... of n terms counts n-1 levels up to 16 terms" in message


@pytest.mark.parametrize("kind", NEST_KINDS)
def test_derivatives_at_the_depth_limit(kind: str) -> None:
    """The recursive walkers cope with the deepest accepted expressions: the derivative (a few
    levels deeper) is built and evaluated, and agrees with a central difference (h = 1e-6) to
    its round-off, at most about MAX_DEPTH eps (1 + |f|) / h (each of the 100 levels may add
    an ulp to f(t +- h)), plus a truncation error h^2/6 max|third derivative|, far below that."""
    text, value = _nest(kind, MAX_DEPTH, seed=MAX_DEPTH)
    expr = accepted(text)
    d = derivative(expr, "t").evaluate(t=0.3)
    h = 1e-6
    fd = (expr.evaluate(t=0.3 + h) - expr.evaluate(t=0.3 - h)) / (2 * h)
    assert abs(d - fd) <= MAX_DEPTH * EPS * (1 + abs(value(0.3))) / h


@pytest.mark.parametrize(
    ("terms", "levels", "ok"),
    [
        (16, 85, True),
        (16, 86, False),
        (17, 95, True),
        (17, 96, False),
        (900, 90, True),
        (900, 91, False),
    ],
)
def test_chains_inside_nesting(terms: int, levels: int, ok: bool) -> None:
    """D14: a chain counts n-1 levels up to 16 terms (as written) and ceil(log2 n) above
    (balanced), so 16 terms inside 85 calls make 100 levels, 17 terms (5 levels) fit inside
    95 calls, and 900 terms (10 levels) inside 90; one call more is refused."""
    text = "sin(" * levels + "+".join(["t"] * terms) + ")" * levels
    if ok:
        expr = accepted(text)
        assert height(expr.tree) == MAX_DEPTH
        assert expr.evaluate(t=0.5) == _iterate_sin(terms * 0.5, levels)
    else:
        refused(text, DEEP)


def _iterate_sin(x: float, levels: int) -> float:
    for _ in range(levels):
        x = math.sin(x)
    return x


@pytest.mark.parametrize("kind", NEST_KINDS)
@pytest.mark.parametrize("levels", [150, 199, 200, 201, 1000, 3000, 10_000, 100_000])
def test_deep_nesting_always_has_a_reason(kind: str, levels: int) -> None:
    """D17: far beyond the limit each kind is refused with a reason: the depth limit, Python's
    nesting limit of parentheses (200), the node limit or the length limit; never a traceback,
    never an empty reason (10000 unary minus signs gave ``cannot parse "..." ()``)."""
    text, _ = _nest(kind, levels, seed=levels)
    message = refused(text)
    assert re.search(
        rf"{DEEP}|too many nested parentheses|limit of {MAX_NODES}\b|limit of {MAX_LENGTH}\b",
        message,
    ), message


def test_python_parser_limits_have_reasons(monkeypatch: pytest.MonkeyPatch) -> None:
    """D17: with the node and length limits lifted, Python's parser itself gives up (its stack:
    MemoryError with no message; its recursion limit while building a deep AST: 3000 signs or
    a flat sum of 20000 terms); the refusals still say why."""
    monkeypatch.setattr(expressions, "MAX_NODES", 10**9, raising=False)
    monkeypatch.setattr(expressions, "MAX_LENGTH", 10**9, raising=False)
    texts = ("-" * 10_000 + "t", "-" * 3000 + "t", "+".join(["t"] * 20_000), "2**" * 5000 + "t")
    for text in texts:
        message = refused(text)
        assert re.search(r"for Python's parser \(\S", message), message


@pytest.mark.parametrize(
    ("zeros", "fragment"),
    [
        (100_000, f"expression of 100003 characters, more than the limit of {MAX_LENGTH}"),
        (5000, "an integer literal has more than 4300 digits, found 5001"),
        (4300, "an integer literal has more than 4300 digits, found 4301"),
        (4299, "is not finite"),
        (400, "is not finite"),
    ],
)
def test_long_integer_literals(zeros: int, fragment: str) -> None:
    """D17: ``1`` followed by many zeros: the length limit, Python's 4300-digit limit of int
    literals (said plainly, not as Python's advice to call sys.set_int_max_str_digits), or
    beyond the float range."""
    message = refused("1" + "0" * zeros + "*t", fragment)
    assert "set_int_max_str_digits" not in message


def test_long_and_extreme_float_literals() -> None:
    """Float literals are Python's: many digits are fine (1.000...0 is 1.0), an underflow is 0
    (as float() gives), an overflow is refused as not finite."""
    rng = random.Random(5)
    for _ in range(50):
        digits = "".join(rng.choice("0123456789") for _ in range(rng.randint(1, 5000)))
        for text in (f"0.{digits}", f"{digits[:300]}.5", f"1.{digits}e-320", f".{digits}e5"):
            result = outcome(text + "*t")
            expected = float(text)
            if math.isfinite(expected):
                assert isinstance(result, Expression) and result.evaluate(t=1.0) == expected
            else:
                assert "is not finite" in str(result)
    assert accepted("1e-400*t").evaluate(t=1.0) == 0.0
    refused("1e400*t", "is not finite")
    refused("0x" + "f" * 300 + "*t", "is not finite")
    assert accepted("0x1f*t + 1_000").evaluate(t=1.0) == 31 + 1000


@pytest.mark.parametrize("count", [0, 1, 2, 3, 10, 1000, 1999, 5000, 100_000])
@pytest.mark.parametrize("function", ["sin", "min"])
def test_numbers_of_arguments(function: str, count: int) -> None:
    """D17: any number of arguments other than the arity is refused with a reason (the arity,
    or the node limit for huge argument lists)."""
    text = f"{function}(" + ", ".join(["t"] * count) + ")"
    if count == expressions.FUNCTIONS[function]:
        accepted(text)
    else:
        refused(text)


# ------------------------------------------------------------------------------- injections
INJECTIONS = [
    "__import__('os')",
    "__import__",
    "().__class__.__bases__[0].__subclasses__()",
    "t.real",
    "sin.__call__(t)",
    "(lambda: 1)()",
    "lambda: t",
    "[x for x in (1,)]",
    "{x for x in (1,)}",
    "{x: 1 for x in (1,)}",
    "sum(x for x in (1,))",
    "(x for x in (1,))",
    "f'{t}'",
    "f'{__import__(\"os\")}'",
    "(y := 1)",
    "b'x'",
    "'x'",
    "1j",
    "2 + 3j",
    "t*1J",
    "...",
    "None",
    "True",
    "nan",
    "inf",
    "-inf",
    "float('nan')",
    "eval('1')",
    "exec('1')",
    "open('/etc/passwd')",
    "globals()",
    "t if t else 1",
    "t and 1",
    "not t",
    "t < 1",
    "t[0]",
    "*t",
    "sin(*t)",
    "sin(**t)",
    "sin(x=t)",
    "t % 1",
    "t // 1",
    "t @ t",
    "~t",
    "t << 1",
    "await t",
    "(yield t)",
    "t; 1",
    "import os",
    "t\nimport os",
    "[t]",
    "(t, t)",
    "{t: t}",
    "{t}",
    "1\0",
    "t\ud800",
    "\\",
]


@pytest.mark.parametrize("text", INJECTIONS)
@pytest.mark.parametrize("names", [NAMES, None], ids=["names", "any-name"])
def test_injections_are_refused(text: str, names: frozenset[str] | None) -> None:
    """Nothing outside the whitelist gets through, whatever names are allowed (``nan``, ``inf``
    and ``__import__`` are not numbers or functions; with any name allowed they are plain
    variables that need a value)."""
    if names is None and text.lstrip("-").isidentifier() and text not in ("None", "True"):
        assert accepted(text, None).names == {text.lstrip("-")}  # a variable, nothing else
        return
    refused(text, names=names)


def test_non_strings() -> None:
    """D17: numbers and non-numbers given directly: finite numbers pass; others are refused with
    a reason, including an int too long for str() (Python's 4300-digit limit; it raised
    ValueError from the error message itself)."""
    assert accepted(3).evaluate() == 3.0
    for value in (10**400, 10**5000, -(10**5000), math.nan, math.inf, None, [1], b"1", 1j, True):
        refused(value)
    assert "an integer of about 5001 digits" in refused(10**5000)


# ------------------------------------------------------------------------------------- CLI
def _validate(*overrides: str) -> subprocess.CompletedProcess:
    args = [sys.executable, "-m", "cosserat_fem.cli", "validate", "scenes/cao_tucker_2008.toml"]
    for override in overrides:
        args += ["--set", override]
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_cli_accepts_a_long_sum_and_refuses_a_lookalike() -> None:
    """D14 and D4 end to end: a 150-term end torque validates (exit 0); a load that writes the
    fullwidth ``ａ`` for the declared parameter ``a`` is refused with exit status 2 and exactly
    one stderr line naming the key."""
    long_sum = "+".join(["t"] * 150)
    done = _validate(f'loads.end.torque=[0,0,"{long_sum}"]')
    assert done.returncode == 0, done.stderr
    done = _validate("parameters.a=1", 'loads.end.torque=[0,0,"ａ*t"]')
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert "loads.end.torque[2]: the name 'ａ' is read by Python as 'a' (Unicode NFKC)" in lines[0]
