"""Another CPU's round-off, on this one: numpy's transcendental functions moved by 1 to N units
in the last place (ulp) for about half their arguments.

Why: numpy dispatches its float64 transcendentals by CPU (on AVX-512, SVML's sin, cos, exp,
log, power, arctan2, ...; elsewhere the C library's libm, as Python's math module and the
compiled forms use), each within 1-4 ulp of the exact value, so two machines' results differ
in the last bits, and on one of them numpy's sin need not be math's. A test that asserts such
bits (the place of the maximum of a constant, numpy's value equal to math's or to a compiled
form's) passes on the machine it was written on and fails on another.
``NPY_DISABLE_CPU_FEATURES`` cannot show it on a CPU without AVX-512: there the float64
functions do not depend on the CPU (only ``tanh`` changes when AVX2 is disabled).

How: with ``ROUNDOFF_NOISE=N`` (N ulps at most; 1 if not a number) in the environment,
tests/conftest.py calls :func:`install` in pytest's process and puts tests/roundoff on
``PYTHONPATH``, whose ``sitecustomize`` installs it in every subprocess (the CLI, demos,
mpirun's ranks). A hash of the arguments' magnitudes moves each result's magnitude towards
or away from zero, or keeps it, as a different library would: the same arguments give the
same result, so a computation repeated in the same order (a restart against an uninterrupted
run, serial against MPI where they share operations) is repeated bit for bit, as on one
machine, and symmetric functions stay symmetric. Results that every correct library gets
exactly (0, ±1, integers, infinities, NaN) are kept. Only numpy's module attributes are
replaced (code that bound ``from numpy import sin`` before :func:`install` keeps the
original); math and the C code of the compiled forms keep the C library's values, which
another C library would change alike (not emulated here).

Run: ``ROUNDOFF_NOISE=1 .venv/bin/python -m pytest -q -m "not long" tests``. Another BLAS
(OpenBLAS for the reference BLAS here) changes the last bits of matrix products, norms and
solves: ``LD_LIBRARY_PATH`` at an OpenBLAS whose libblas.so.3 it provides.
"""

from __future__ import annotations

import os

import numpy as np

#: numpy's float64 functions with a CPU-dispatched or library-dependent implementation.
NUMPY_FUNCTIONS = (
    "sin",
    "cos",
    "tan",
    "arcsin",
    "arccos",
    "arctan",
    "arctan2",
    "sinh",
    "cosh",
    "tanh",
    "arcsinh",
    "arccosh",
    "arctanh",
    "exp",
    "exp2",
    "expm1",
    "log",
    "log2",
    "log10",
    "log1p",
    "cbrt",
    "power",
)
_MIX = np.uint64(0x9E3779B97F4A7C15)
_installed = False


def _hash(args) -> np.ndarray:
    """A hash of the arguments' magnitudes, element by element over their broadcast."""
    h = np.zeros((), dtype=np.uint64)
    with np.errstate(over="ignore"):
        for a in args:
            bits = np.ascontiguousarray(np.abs(np.asarray(a, dtype=np.float64))).view(np.uint64)
            h = (h ^ bits) * _MIX
            h = h ^ (h >> np.uint64(29))
    return h


def ulps() -> int:
    """The largest perturbation [ulp]: ``ROUNDOFF_NOISE``'s value (1 for any other text)."""
    text = os.environ.get("ROUNDOFF_NOISE", "")
    return int(text) if text.isdigit() else 1


def perturbed(result, args, most: int | None = None):
    """``result`` with its magnitude moved by 1 to ``most`` (:func:`ulps`) units in the last
    place, towards or away from zero, for about half the arguments (a hash of their
    magnitudes decides): a symmetric function stays symmetric (sin(−x) = −sin(x)), as in
    every implementation; results every correct library gets exactly are kept."""
    value = np.asarray(result)
    if value.dtype != np.float64:
        return result
    most = ulps() if most is None else most
    h = _hash(args)
    way = (h >> np.uint64(62)).astype(np.int64) - 1  # -1 towards 0, +1 away, 0 and 2 kept
    count = 1 + ((h >> np.uint64(32)) % np.uint64(most)).astype(np.int64)
    keep = (way == 0) | (way == 2) | ~np.isfinite(value) | (value == np.round(value))
    target = np.where(way < 0, 0.0, np.copysign(np.inf, value))
    moved = np.array(value, dtype=np.float64, copy=True)
    for k in range(1, most + 1):
        step = ~keep & (count >= k)
        moved = np.where(step, np.nextafter(moved, target), moved)
    if np.ndim(result) == 0:
        return type(result)(moved) if isinstance(result, float) else moved[()]
    return moved


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


def install() -> None:
    """Replace numpy's functions above by their perturbed versions (once)."""
    global _installed
    if _installed:
        return
    for name in NUMPY_FUNCTIONS:
        setattr(np, name, _Noisy(getattr(np, name)))
    _installed = True


def requested() -> bool:
    """``ROUNDOFF_NOISE`` is set to a non-empty value other than 0."""
    return os.environ.get("ROUNDOFF_NOISE", "") not in ("", "0")
