"""Another machine's round-off, on this one: numpy's and math's transcendental functions moved
by one unit in the last place (ulp) for about half their arguments.

Why: numpy dispatches its float64 transcendentals by CPU (on AVX-512, SVML's sin, cos, exp,
log, power, arctan2, ...; elsewhere libm), and libm differs between libraries; each is within
1-4 ulp of the exact value, so two machines' results differ in the last bits. A test that
asserts such bits (the place of the maximum of a constant, an exact equality of two
computations) passes on the machine it was written on and fails on another.
``NPY_DISABLE_CPU_FEATURES`` cannot show it on a CPU without AVX-512: there the float64
functions do not depend on the CPU (only ``tanh`` changes when AVX2 is disabled).

How: with ``ROUNDOFF_NOISE=1`` in the environment, tests/conftest.py calls :func:`install` in
pytest's process and puts tests/roundoff on ``PYTHONPATH``, whose ``sitecustomize`` installs it
in every subprocess (the CLI, demos, mpirun's ranks). Each result is moved to a neighbouring
float (down, up, or not at all) by a hash of its arguments' bits, as a different library
would: the same arguments give the same result, so a computation repeated in the same order
(a restart against an uninterrupted run, serial against MPI where they share operations) is
repeated bit for bit, as on one machine. Results that every correct library gets exactly (0,
±1, integers, infinities, NaN) are kept. Only the module attributes are replaced: code that
bound ``from numpy import sin`` before :func:`install` keeps the original.

Run: ``ROUNDOFF_NOISE=1 .venv/bin/python -m pytest -q -m "not long" tests``.
"""

from __future__ import annotations

import math
import os

import numpy as np

#: numpy's float64 functions with a CPU-dispatched or library-dependent implementation.
NUMPY_FUNCTIONS = (
    "sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh",
    "arcsinh", "arccosh", "arctanh", "exp", "exp2", "expm1", "log", "log2", "log10", "log1p",
    "cbrt", "power",
)  # fmt: skip
#: math's (libm's) functions: another C library rounds some of them differently.
MATH_FUNCTIONS = (
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh",
    "acosh", "atanh", "exp", "expm1", "log", "log2", "log10", "log1p", "pow",
)  # fmt: skip
_MIX = np.uint64(0x9E3779B97F4A7C15)
_installed = False


def _direction(args) -> np.ndarray:
    """-1, 0 or +1 for each element of the arguments' broadcast: a hash of their bits."""
    h = np.zeros((), dtype=np.uint64)
    with np.errstate(over="ignore"):
        for a in args:
            bits = np.ascontiguousarray(np.asarray(a, dtype=np.float64)).view(np.uint64)
            h = (h ^ bits) * _MIX
            h = h ^ (h >> np.uint64(29))
    return (h >> np.uint64(62)).astype(np.int64) - 1  # 0..3 -> -1, 0, 1, 2 (2: kept)


def perturbed(result, args):
    """``result`` moved by one ulp where :func:`_direction` of ``args`` says, except where
    every correct library is exact."""
    value = np.asarray(result)
    if value.dtype != np.float64:
        return result
    step = _direction(args)
    step = np.where((step == 2) | ~np.isfinite(value) | (value == np.round(value)), 0, step)
    moved = np.where(step == 0, value, np.nextafter(value, np.where(step < 0, -np.inf, np.inf)))
    if np.ndim(result) == 0:
        return type(result)(moved) if isinstance(result, float) else moved[()]
    return moved.astype(np.float64, copy=False)


class _Noisy:
    """A numpy ufunc whose float64 calls are :func:`perturbed`; its attributes are the
    ufunc's. Calls with ``out=`` or a non-float64 result are the ufunc's own."""

    def __init__(self, ufunc):
        self._ufunc = ufunc
        self.__name__ = ufunc.__name__
        self.__doc__ = ufunc.__doc__

    def __call__(self, *args, **kwargs):
        result = self._ufunc(*args, **kwargs)
        if "out" in kwargs or isinstance(result, tuple):
            return result
        return perturbed(result, args[: self._ufunc.nin])

    def __getattr__(self, name):
        return getattr(self._ufunc, name)


def _noisy_math(function):
    def call(*args):
        return float(perturbed(function(*args), args))

    call.__name__ = function.__name__
    return call


def install() -> None:
    """Replace numpy's and math's functions above by their perturbed versions (once)."""
    global _installed
    if _installed:
        return
    for name in NUMPY_FUNCTIONS:
        setattr(np, name, _Noisy(getattr(np, name)))
    for name in MATH_FUNCTIONS:
        setattr(math, name, _noisy_math(getattr(math, name)))
    _installed = True


def requested() -> bool:
    """``ROUNDOFF_NOISE`` is set to a non-empty value other than 0."""
    return os.environ.get("ROUNDOFF_NOISE", "") not in ("", "0")
