"""Unit tests of cosserat_fem/scene/expressions.py, the safe expressions of s and t.

* Values. An expression of at most BALANCE_ABOVE (16) operands a chain is evaluated as written,
  left to right, with Python's float operations and math's functions (``_SCALAR_OPS``): its
  scalar value is Python's own for the same text (``eval`` with math's names), exactly, since
  the operations are the same, in the same order, on the same machine.
* Arrays. The numpy evaluation of the same expressions differs only in numpy's functions
  (sin, exp, power, ...: the last digits are the CPU's and numpy's, SVML or libm, and
  ROUNDOFF_NOISE moves them by 4 ulps): each function's result is within 8 ulps of math's
  (4 of numpy's own, 4 of the noise). The value's relative change for a relative change of
  one function's result, summed over the functions (its condition number for these
  roundings), is at most 13.6 at the points (exp(−t/2) cos(ω0 t) + √s at s = 0.15, where
  the two terms partly cancel; measured by perturbing each function's result by 1e-7, the
  others 6.6 or less), so the values agree within 13.6 × 8 = 109 ulps = 2.4e-14 relative:
  asserted to 1e-13 (450 ulps).
* Long chains are rebalanced (depth ~log2 n), so a 1000-term sum parses although MAX_DEPTH is
  100, and it is the same sum: n s with s = 0.1 to n ε Σ|terms| (the rounding bound of any
  order of summation).
* Derivatives: d/dt and d/ds by the chain rule, against the closed forms at points, to 1e-14
  relative (a few roundings of terms of one sign).
* Refusals: one line starting with the key.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.scene.expressions import MAX_DEPTH, MAX_NODES, Expression, derivative

pytestmark = pytest.mark.unit

EPS = np.finfo(float).eps
NAMES = {"s", "t", "L", "omega0"}
POINT = {"s": 0.37, "t": 1.9, "L": 0.5, "omega0": 25.1327412287183}

TEXTS = [
    "2e3*sin(pi*s/L)*sin(8*omega0*t)",
    "-s**2 + 3*t - 1/7",
    "exp(-t/2)*cos(omega0*t) + sqrt(s)",
    "min(s, t) * max(s, -t) / (1 + abs(s - t))",
    "atan(s/L) + asin(s) - acos(s/2) + log(1 + t) + tanh(s) + sinh(t)/cosh(t) + tan(s)",
    "-(s - t)**3 + 2**-s - e**t",
    "(s + t) * (s - t) / (s * t) + 1e-3 * t ** 0.5",
]


def python_value(text: str, values: dict[str, float]) -> float:
    """The text evaluated by Python itself, with math's functions (the reference)."""
    names = {
        name: getattr(math, name)
        for name in "sin cos tan asin acos atan sinh cosh tanh exp log sqrt".split()
    }
    names.update(abs=abs, min=min, max=max, pi=math.pi, e=math.e, **values)
    return eval(text, {"__builtins__": {}}, names)  # noqa: S307 - our own fixed texts


@pytest.mark.parametrize("text", TEXTS)
def test_scalar_values_are_pythons(text):
    expression = Expression.parse(text, NAMES, key="loads.distributed.force[0]")
    assert expression.evaluate(**POINT) == python_value(text, POINT)


@pytest.mark.parametrize("text", TEXTS)
def test_array_values_agree_with_scalar_ones(text):
    expression = Expression.parse(text, NAMES)
    s = np.linspace(0.05, 0.45, 5)
    values = expression.evaluate(**{**POINT, "s": s})
    assert values.shape == (5,)
    scalar = [expression.evaluate(**{**POINT, "s": x}) for x in s]
    np.testing.assert_allclose(values, scalar, rtol=1e-13, atol=0)


def test_step_functions():
    """heaviside is 1 from 0 on (inclusive), ramp is max(x, 0); the same on arrays."""
    step = Expression("heaviside(t - 1)")
    assert [step.evaluate(t=t) for t in (0.0, 1.0 - 1e-16, 1.0, 2.0)] == [0.0, 0.0, 1.0, 1.0]
    ramp = Expression("ramp(t - 1)")
    assert [ramp.evaluate(t=t) for t in (0.0, 1.0, 3.5)] == [0.0, 0.0, 2.5]
    t = np.array([0.0, 1.0, 3.5])
    assert step.evaluate(t=t).tolist() == [0.0, 1.0, 1.0]
    assert ramp.evaluate(t=t).tolist() == [0.0, 0.0, 2.5]


def test_properties():
    assert Expression.parse(0).is_zero and Expression.parse("0.0").is_zero
    assert not Expression.parse("0*s").is_zero  # literally zero only
    assert Expression.parse("2*pi").is_constant and not Expression.parse("t").is_constant
    expression = Expression.parse("s*omega0 + pi", NAMES)
    assert expression.names == {"s", "omega0", "pi"}
    assert expression.depends_on("s") and not expression.depends_on("t")
    assert Expression.parse("  s + 1 ") == Expression.parse("s + 1")  # equal sources
    with pytest.raises(ValueError, match="no value given for t"):
        Expression.parse("t*s").evaluate(s=1.0)


def test_a_long_chain_is_rebalanced_and_the_same_sum():
    """999 operands (1997 nodes, under MAX_NODES): as written it would nest 998 levels,
    beyond MAX_DEPTH; rebalanced it parses, and sums to 999 s within 999 ε Σ|terms|."""
    n = 999
    assert n - 1 > MAX_DEPTH and 2 * n - 1 <= MAX_NODES
    expression = Expression.parse(" + ".join(["s"] * n), {"s"})
    value = expression.evaluate(s=0.1)
    assert abs(value - n * 0.1) <= n * EPS * (n * 0.1)
    product = Expression.parse(" * ".join(["s"] * 40), {"s"})  # 2^40 exactly: no rounding
    assert product.evaluate(s=2.0) == 2.0**40


def test_derivatives():
    expression = Expression.parse("2e3*sin(pi*s/L)*sin(8*omega0*t) + t**3*s", NAMES)
    s, t, length, omega0 = POINT["s"], POINT["t"], POINT["L"], POINT["omega0"]
    d_dt = 2e3 * math.sin(math.pi * s / length) * 8 * omega0 * math.cos(8 * omega0 * t)
    d_dt += 3 * t**2 * s
    d_ds = 2e3 * math.pi / length * math.cos(math.pi * s / length) * math.sin(8 * omega0 * t)
    d_ds += t**3
    assert derivative(expression, "t").evaluate(**POINT) == pytest.approx(d_dt, rel=1e-14)
    assert derivative(expression, "s").evaluate(**POINT) == pytest.approx(d_ds, rel=1e-14)
    assert derivative(expression, "L").names <= expression.names


@pytest.mark.parametrize(
    ("value", "words"),
    [
        ("1/0", "key.x: "),
        ("log(-1)", "key.x: "),
        ("s + u", "key.x: "),  # a name not allowed
        ("__import__('os')", "key.x: "),
        ("s.real", "key.x: "),
        ("sin(s, t)", "key.x: "),
        ("ｔ + 1", "key.x: "),  # a fullwidth t, which Python would read as t
        ("s +", "key.x: syntax error"),
        ("", "key.x: empty expression string"),
        (math.nan, "key.x: must be a finite number, got nan"),
        ([1], "key.x: must be a number or an expression string, got [1]"),
        (" + ".join(["s"] * 1001), "key.x: expression of 2001 numbers, names and operators"),
    ],
)
def test_refusals_are_one_line_naming_the_key(value, words):
    with pytest.raises(SceneError) as raised:
        Expression.parse(value, {"s", "t"}, key="key.x")
    message = str(raised.value)
    assert message.startswith(words) and "\n" not in message
