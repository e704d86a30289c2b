"""The scene schema: every key of a scene file, its type, range, unit and default, and the
validation of a scene's raw data against it, ``--set`` overrides and TOML reading.

:data:`SCHEMA` is the table of tables; its leaves (:class:`Number`, :class:`Choice`, ...)
check one value each. :func:`check_scene` validates a scene's data (unknown keys get a
"did you mean"), every problem a single :class:`~cosserat_fem.errors.SceneError` whose
message starts with the dotted key at fault, states what is allowed and shows the offending
value. The resolved scene is cosserat_fem/resolved.py, building it cosserat_fem/scene.py.

Overrides: the value is read as a TOML value if possible (``1e-5``, ``true``, ``"bdf2"``,
``[0, 0, "1e3*t"]``), else taken as a bare string (``time.integrator=bdf2``); ``--unset KEY``
(:class:`Removal`, :data:`UNSET` in a mapping) removes a key or a table. Overriding one of
``rod.material.poisson_ratio`` / ``rod.material.shear_modulus`` removes the other, so that
either can be set from the command line whichever the file gives.
"""

from __future__ import annotations

import difflib
import keyword
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosserat_fem.errors import SceneError, show_value
from cosserat_fem.expressions import RESERVED_NAMES, check_name
from cosserat_fem.forms.conventions import END_LOAD_SCALINGS, END_LOAD_SIGNS, TORSION_INERTIAS
from cosserat_fem.forms.section import TORSION_CONSTANT_RULES
from cosserat_fem.io.probes import PROBE_FIELD_COLUMNS
from cosserat_fem.io.xdmf import FIELD_ARRAYS
from cosserat_fem.load_data import INTERPOLATIONS, OUTSIDE, S_INTERPOLATIONS
from cosserat_fem.safe_files import Unreadable, read_on_root

#: Names every load expression may use besides the [parameters] (``s`` only in distributed loads).
SCENE_CONSTANTS = ("L", "omega0")
#: Relative tolerance for "is an integer number of time steps".
STEP_TOLERANCE = 1e-9
#: What output.fields may ask the XDMF file to hold (the format's, cosserat_fem/io/xdmf.py). The
#: names of heavier modules' choices (the integrators, the Jacobian policies) are spelled out
#: here, so that reading a scene needs no UFL or DOLFINx; tests/unit/test_one_source.py holds
#: them equal to the implementers' registries.
XDMF_FIELDS = tuple(FIELD_ARRAYS)
#: What output.fields holds when a scene does not say: all but the directors.
XDMF_DEFAULT_FIELDS = XDMF_FIELDS[:4]
SUPPORTS = ("clamped", "free", "pinned", "spherical")
#: Upper bounds of keys whose size alone makes a run impossible here (cosserat_fem/budget.py
#: estimates the others): quadrature points per cell, Newton iterations per solve.
MAX_QUADRATURE = 100
MAX_NEWTON_ITERATIONS = 1000
#: limits.wall_time by default [s]: a day.
DEFAULT_WALL_TIME = 86400.0
#: The largest scene or sweep file read [bytes]: 16 MiB holds a sweep of the most members
#: (sweep_spec.MAX_MEMBERS, 100 000) as [[sweep.case]] tables of 160 bytes each; a scene
#: is a few kB (an expression stops at 20 000 characters).
MAX_INPUT_BYTES = 16 << 20
#: The deepest nesting of tables and lists read: a scene needs 3 (reference.points: a table,
#: the list, a point), a sweep 5 (sweep.vary, a key, its list of values, a vector, ...).
MAX_DEPTH = 32

_EXCLUSIVE = ("rod.material.poisson_ratio", "rod.material.shear_modulus")

#: The keys each section shape takes besides ``shape`` and ``shear_coefficient``.
SECTION_KEYS = {
    "rectangle": ("a", "b", "torsion_constant"),
    "circle": ("diameter",),
    "tube": ("outer_diameter", "inner_diameter"),
    "constants": ("area", "c11", "c22", "c33"),
}

#: The shapes of a rod at rest ([reference]) and the keys each takes besides ``shape``
#: (forms/reference.py; cosserat_fem/resolved.py ReferenceShape).
REFERENCE_KEYS = {
    "straight": (),
    "arc": ("radius",),
    "helix": ("radius", "pitch_angle"),
    "polyline": ("points", "binormal"),
    "curve": ("position", "director"),
}


# ================================================================================ primitives
def fmt(x: float) -> str:
    """A bound for messages: integers without ".0", else ``repr``."""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else repr(float(x))


@dataclass(frozen=True)
class Interval:
    """Allowed range; None = unbounded on that side."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def contains(self, x: float) -> bool:
        lo_ok = self.lo is None or (x > self.lo if self.lo_open else x >= self.lo)
        hi_ok = self.hi is None or (x < self.hi if self.hi_open else x <= self.hi)
        return lo_ok and hi_ok

    def describe(self) -> str:
        """The range in words, for messages: "in [lo, hi)", "> lo", "<= hi" or "finite"."""
        if self.lo is not None and self.hi is not None:
            left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
            return f"in {left}{fmt(self.lo)}, {fmt(self.hi)}{right}"
        if self.lo is not None:
            return f"{'>' if self.lo_open else '>='} {fmt(self.lo)}"
        if self.hi is not None:
            return f"{'<' if self.hi_open else '<='} {fmt(self.hi)}"
        return "finite"


POSITIVE = Interval(lo=0.0, lo_open=True)
NON_NEGATIVE = Interval(lo=0.0)
ANY = Interval()


@dataclass(frozen=True, kw_only=True)
class Field:
    """A leaf key: ``required`` or else ``default``."""

    required: bool = False
    default: Any = None

    def describe(self) -> str:
        raise NotImplementedError

    def check(self, key: str, value: Any) -> Any:
        raise NotImplementedError


@dataclass(frozen=True, kw_only=True)
class Number(Field):
    """A finite number in ``interval``; ``integer`` → int; ``auto`` → also the string "auto"."""

    interval: Interval = ANY
    unit: str = ""
    integer: bool = False
    auto: bool = False

    def describe(self) -> str:
        kind = "an integer" if self.integer else "a number"
        text = f"{kind} {self.interval.describe()}" if self.interval != ANY else kind
        text += f" [{self.unit}]" if self.unit else ""
        return f'"auto" or {text}' if self.auto else text

    def check(self, key: str, value: Any) -> Any:
        """``value`` as a float (an int if ``integer``), or "auto"; SceneError naming ``key``
        unless it is a finite number in the interval."""
        if self.auto and value == "auto":
            return "auto"
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        try:
            finite = math.isfinite(value)
        except OverflowError:  # an integer beyond any float (from a dict, not TOML)
            finite = False
        if not finite:
            raise SceneError(f"{key}: must be {self.describe()}, finite, got {show_value(value)}")
        if self.integer and not float(value).is_integer():
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        number = int(value) if self.integer else float(value)
        if not self.interval.contains(number):
            raise SceneError(self._range_message(key, value))
        return number

    def _range_message(self, key: str, value: Any) -> str:
        """The message for a number outside the interval, with the unit."""
        if self.auto:
            return f"{key}: must be {self.describe()}, got {show_value(value)}"
        rule = self.interval.describe()
        verb = "lie" if rule.startswith("in ") else "be"
        unit = f" [{self.unit}]" if self.unit else ""
        return f"{key}: must {verb} {rule}{unit}, got {show_value(value)}"


@dataclass(frozen=True, kw_only=True)
class Choice(Field):
    """One of a fixed set of strings."""

    choices: tuple[str, ...] = ()

    def describe(self) -> str:
        return "one of " + ", ".join(show_value(c) for c in self.choices)

    def check(self, key: str, value: Any) -> Any:
        """``value`` if it is one of the choices; else SceneError naming ``key``, with the
        closest choice as a hint."""
        if isinstance(value, str) and value in self.choices:
            return value
        hint = ""
        if isinstance(value, str):
            close = difflib.get_close_matches(value, self.choices, n=1, cutoff=0.5)
            hint = f" (did you mean {show_value(close[0])}?)" if close else ""
        raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}{hint}")


@dataclass(frozen=True, kw_only=True)
class Text(Field):
    """A string (non-empty if ``non_empty``)."""

    non_empty: bool = False

    def describe(self) -> str:
        return "a non-empty string" if self.non_empty else "a string"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, str) or (self.non_empty and not value.strip()):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return value


@dataclass(frozen=True, kw_only=True)
class Flag(Field):
    """A boolean."""

    def describe(self) -> str:
        return "true or false"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, bool):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return value


@dataclass(frozen=True, kw_only=True)
class Vector(Field):
    """A list of 3 numbers/expression strings; parsed later, when the names are known."""

    unit: str = ""

    def describe(self) -> str:
        return f"a list of 3 numbers or expression strings [{self.unit}]"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list) or len(value) != 3:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return list(value)


@dataclass(frozen=True, kw_only=True)
class LoadVector(Vector):
    """A load's list of 3 components: numbers, expression strings, tables (an inline table
    checked against :data:`LOAD_TABLE`, defaults filled in) or, through the API, Python
    callables (cosserat_fem/load_data.py); parsed later, when the names are known."""

    def describe(self) -> str:
        return (f"a list of 3 numbers, expression strings or tables {{table = ..., column = "
                f"...}} [{self.unit}]")  # fmt: skip

    def check(self, key: str, value: Any) -> Any:
        """The list, each inline table checked (SceneError naming ``key[i]``); a saved
        callable's name (``{callable = ...}``, from summary.json or a checkpoint) refused."""
        components = super().check(key, value)
        for i, item in enumerate(components):
            if isinstance(item, dict) and "callable" in item:
                raise SceneError(
                    f"{key}[{i}]: the load was the Python callable {show_value(item['callable'])}"
                    ", which a saved scene (a checkpoint, summary.json) cannot hold: a run with "
                    "a callable load cannot be restarted or rebuilt; run it again, giving the "
                    "callable through the API"
                )
            if isinstance(item, dict):
                components[i] = _check_table(f"{key}[{i}]", item, LOAD_TABLE)
        return components


@dataclass(frozen=True, kw_only=True)
class Points(Field):
    """A list of at least two points, each a list of 3 finite numbers."""

    unit: str = ""

    def describe(self) -> str:
        return f"a list of at least 2 points, each a list of 3 numbers [{self.unit}]"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list) or len(value) < 2:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        points = []
        for i, point in enumerate(value):
            if not isinstance(point, list) or len(point) != 3:
                raise SceneError(f"{key}[{i}]: must be a list of 3 numbers [{self.unit}], got "
                                 f"{show_value(point)}")  # fmt: skip
            points.append(tuple(Number(unit=self.unit).check(f"{key}[{i}][{j}]", x)
                                for j, x in enumerate(point)))  # fmt: skip
        return points


@dataclass(frozen=True, kw_only=True)
class ChoiceList(Field):
    """A list of distinct strings, each one of ``choices`` (kept in the given order)."""

    choices: tuple[str, ...] = ()

    def describe(self) -> str:
        return "a list of distinct strings from " + ", ".join(show_value(c) for c in self.choices)

    def check(self, key: str, value: Any) -> Any:
        """``value`` as a tuple if it is a list of distinct choices; else SceneError naming
        ``key`` (and the index of a bad item)."""
        if not isinstance(value, list | tuple) or len(set(map(str, value))) != len(value):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        for i, item in enumerate(value):
            Choice(choices=self.choices).check(f"{key}[{i}]", item)
        return tuple(value)


#: A PETSc option's name as [solver.petsc] gives it: without the leading "-" and the prefix.
PETSC_OPTION_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def petsc_value(key: str, value: Any) -> str:
    """The text PETSc's options database takes for an option's ``value`` from a scene: a
    string as it is ("" for an option without a value, e.g. ``snes_monitor = ""``), an integer
    or a finite number in Python's shortest repr, a boolean as ``true``/``false``; SceneError
    naming ``key`` for anything else (a list, a table, NaN, a string with a control character).
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float) and math.isfinite(value):
        return repr(value)
    if isinstance(value, str) and value.isprintable():
        return value
    raise SceneError(f"{key}: a PETSc option's value must be a string, a finite number or true/"
                     f"false (\"\" for an option without a value), got {show_value(value)}")


@dataclass(frozen=True, kw_only=True)
class PetscOptions(Field):
    """The free-form [solver.petsc] table: PETSc option name (without "-" and the prefix
    ``cosserat_``) = value, for solver.nonlinear = "snes" (cosserat_fem/snes.py). Checked here
    for form only (names, values: :func:`petsc_value`); whether PETSc knows an option is only
    known once it has set the solver up (an unused option is then a SceneError)."""

    def describe(self) -> str:
        return "a table of PETSc option name = value"

    def check(self, key: str, value: Any) -> Any:
        """{name: value as PETSc's database takes it}; SceneError naming ``key.name``."""
        if not isinstance(value, dict):
            raise SceneError(f"{key}: must be {self.describe()}, e.g. {{snes_linesearch_type = "
                             f'"bt"}}, got {show_value(value)}')  # fmt: skip
        options = {}
        for name, item in value.items():
            item_key = _join(key, str(name))
            if not PETSC_OPTION_NAME.fullmatch(str(name)):
                raise SceneError(f"{item_key}: a PETSc option's name is letters, digits and _, "
                                 'without the leading "-" (e.g. snes_type)')  # fmt: skip
            if str(name).startswith(PETSC_PREFIX):
                raise SceneError(f"{item_key}: give the option without its prefix "
                                 f"{PETSC_PREFIX!r} (it is added)")  # fmt: skip
            options[str(name)] = petsc_value(item_key, item)
        return options


#: The options prefix of the SNES solver (cosserat_fem/snes.py): ``-cosserat_snes_type`` in
#: PETSc's terms is ``snes_type`` in [solver.petsc].
PETSC_PREFIX = "cosserat_"


@dataclass(frozen=True)
class Table:
    """A table of fields; an ``optional`` table resolves to None when absent."""

    fields: Mapping[str, Field | Table | Parameters]
    optional: bool = False


@dataclass(frozen=True)
class Parameters:
    """The free-form [parameters] table: identifier = finite number."""


#: A load component given by a table file (cosserat_fem/load_data.py, docs/loads.md): the
#: keys of its inline table, e.g. ``{table = "tip.csv", column = "F"}``.
LOAD_TABLE = Table(
    {
        # the CSV file, relative to the scene file: columns t [s], optionally s [m], values
        "table": Text(required=True, non_empty=True),
        # the value column, in the unit of the load it gives
        "column": Text(required=True, non_empty=True),
        "interpolation": Choice(choices=tuple(INTERPOLATIONS), default="linear"),  # in t
        "s_interpolation": Choice(choices=S_INTERPOLATIONS, default="linear"),  # a grid's
        "outside": Choice(choices=OUTSIDE, default="refuse"),
        # the SHA-256 the file's content must have (optional; summary.json records it)
        "sha256": Text(non_empty=True),
    }
)

_ZERO3 = [0, 0, 0]
_END_LOAD = Table(
    {
        "force": LoadVector(default=_ZERO3, unit="N"),
        "torque": LoadVector(default=_ZERO3, unit="N m"),
    },
    optional=True,
)

_POINT_LOAD = Table(
    {
        "s": Number(required=True, interval=POSITIVE, unit="m"),
        "force": LoadVector(default=_ZERO3, unit="N"),
        "torque": LoadVector(default=_ZERO3, unit="N m"),
    },
    optional=True,
)

#: The scene schema (nested tables; leaves carry type, range and default).
SCHEMA = Table(
    {
        "title": Text(default=""),
        "parameters": Parameters(),
        "rod": Table(
            {
                "length": Number(required=True, interval=POSITIVE, unit="m"),
                "section": Table(
                    {
                        "shape": Choice(choices=tuple(SECTION_KEYS), default="rectangle"),
                        "a": Number(interval=POSITIVE, unit="m"),
                        "b": Number(interval=POSITIVE, unit="m"),
                        "torsion_constant": Choice(choices=TORSION_CONSTANT_RULES),
                        "diameter": Number(interval=POSITIVE, unit="m"),
                        "outer_diameter": Number(interval=POSITIVE, unit="m"),
                        "inner_diameter": Number(interval=NON_NEGATIVE, unit="m"),
                        "area": Number(interval=POSITIVE, unit="m^2"),
                        "c11": Number(interval=POSITIVE, unit="m^4"),
                        "c22": Number(interval=POSITIVE, unit="m^4"),
                        "c33": Number(interval=POSITIVE, unit="m^4"),
                        "shear_coefficient": Number(
                            default="auto", interval=Interval(0.0, 1.0, lo_open=True), auto=True
                        ),
                    }
                ),
                # [I11, I22, I33] per unit length [kg m], the rotary inertias of (46) given
                # apart from the section (absent: ρ c11, ρ c22, ρ (c11 + c22))
                "rotary_inertia": Vector(unit="kg m"),
                "material": Table(
                    {
                        "density": Number(required=True, interval=POSITIVE, unit="kg/m^3"),
                        "young_modulus": Number(required=True, interval=POSITIVE, unit="Pa"),
                        "poisson_ratio": Number(
                            interval=Interval(-1.0, 0.5, lo_open=True, hi_open=True)
                        ),
                        "shear_modulus": Number(interval=POSITIVE, unit="Pa"),
                    }
                ),
            }
        ),
        # The rod at rest (forms/reference.py): straight along e3 (the paper's), a circular
        # arc in the e1-e3 plane bending towards +e1, a helix about an axis along e3, a
        # polyline whose frame jumps at its corners, or a curve of expressions of s.
        "reference": Table(
            {
                "shape": Choice(choices=tuple(REFERENCE_KEYS), default="straight"),
                "radius": Number(interval=POSITIVE, unit="m"),
                "pitch_angle": Number(
                    interval=Interval(-math.pi / 2, math.pi / 2, lo_open=True, hi_open=True),
                    unit="rad",
                ),
                # polyline: its corners (the first the start), and d0_2 on every segment
                "points": Points(unit="m"),
                "binormal": Vector(unit="-"),
                # curve: r0(s) and d0_1(s), expressions of the arc length s [m]
                "position": Vector(unit="m"),
                "director": Vector(unit="-"),
                # the two ends joined (a ring): the curve must close; modes only, for now
                "closed": Flag(default=False),
            }
        ),
        "model": Table(
            {
                "reference_frequency": Number(
                    default="auto", interval=POSITIVE, unit="rad/s", auto=True
                ),
                "torsion_inertia": Choice(choices=TORSION_INERTIAS, default="polar"),
                "end_load_sign": Choice(choices=tuple(END_LOAD_SIGNS), default="balance"),
                "end_load_scaling": Choice(choices=END_LOAD_SCALINGS, default="balance"),
            }
        ),
        "supports": Table(
            {
                "start": Choice(choices=SUPPORTS, default="clamped"),
                "end": Choice(choices=SUPPORTS, default="free"),
                "start_motion": LoadVector(default=_ZERO3, unit="m"),
                "end_motion": LoadVector(default=_ZERO3, unit="m"),
            }
        ),
        "loads": Table(
            {
                "force_density": LoadVector(default=_ZERO3, unit="N/m"),
                "torque_density": LoadVector(default=_ZERO3, unit="N m/m"),
                "start": _END_LOAD,
                "end": _END_LOAD,
                # a force [N] and torque [N m] at the node s [m] inside the rod
                "point": _POINT_LOAD,
                "gravity": Vector(default=_ZERO3, unit="m/s^2"),
            }
        ),
        "damping": Table(
            {
                "translational": Number(default=0.0, interval=NON_NEGATIVE, unit="N s/m^2"),
                "rotational": Number(default=0.0, interval=NON_NEGATIVE, unit="N s"),
                "retardation_time": Number(default=0.0, interval=NON_NEGATIVE, unit="s"),
            }
        ),
        "initial": Table(
            {
                "displacement": Vector(default=_ZERO3, unit="m"),
                "angles": Vector(default=_ZERO3, unit="rad"),
                "velocity": Vector(default=_ZERO3, unit="m/s"),
                "angle_rates": Vector(default=_ZERO3, unit="rad/s"),
            }
        ),
        "time": Table(
            {
                "start": Number(default=0.0, unit="s"),
                "end": Number(required=True, unit="s"),
                "step": Number(required=True, interval=POSITIVE, unit="s"),
                # SDIRK3 and a frozen Jacobian: the fastest to an error of 1e-3 on the paper's
                # scene (benchmarks/README.md), the defaults the README states.
                "integrator": Choice(
                    choices=("bdf2", "generalized-alpha", "sdirk3", "sdirk4"), default="sdirk3"
                ),
                "rho_inf": Number(default=0.5, interval=Interval(0.0, 1.0)),
                "max_halvings": Number(default=6, integer=True, interval=Interval(0, 30)),
                "adaptive": Flag(default=False),
                "rtol": Number(default=1e-4, interval=Interval(0.0, 1.0, True, True)),
                "atol": Number(default=1e-10, interval=POSITIVE),
                "max_step": Number(default=0.0, interval=NON_NEGATIVE, unit="s"),
            }
        ),
        "static": Table(
            {
                "load_steps": Number(default=1, integer=True, interval=Interval(lo=1)),
                # 2^-30 of a load increment: below that no increment is worth trying.
                "max_bisections": Number(default=10, integer=True, interval=Interval(0, 30)),
                "time": Number(default=0.0, unit="s"),
            }
        ),
        "discretisation": Table(
            {
                "elements": Number(default=20, integer=True, interval=Interval(lo=1)),
                "degree": Number(default=2, integer=True, interval=Interval(1, 5)),
                # Exact for polynomials of degree 100 (51 Gauss points a cell), ten times the
                # default 2 * degree of degree 5; FFCx itself warns beyond 100 points.
                "quadrature_degree": Number(
                    default="auto", integer=True, interval=Interval(1, MAX_QUADRATURE), auto=True
                ),
                "planar": Choice(choices=("auto", "off"), default="auto"),
            }
        ),
        "solver": Table(
            {
                "jacobian": Choice(choices=("full", "lagged", "frozen"), default="frozen"),
                "lag": Number(default=10, integer=True, interval=Interval(lo=1)),
                "refresh_iterations": Number(default=4, integer=True, interval=Interval(lo=1)),
                "rtol": Number(default=1e-10, interval=Interval(0.0, 1.0, True, True)),
                "atol": Number(default=1e-12, interval=POSITIVE),
                "stol": Number(default=1e-8, interval=Interval(0.0, 1.0, True, True)),
                "max_iterations": Number(
                    default=25, integer=True, interval=Interval(1, MAX_NEWTON_ITERATIONS)
                ),
                "linear_solver": Choice(
                    choices=("auto", "petsc", "mumps", "superlu"), default="auto"
                ),
                # "auto": Newton's inner loop in C where it applies (cosserat_fem/native_newton.py)
                "loop": Choice(choices=("auto", "python"), default="auto"),
                # The nonlinear solver: the project's Newton loop (newton.py), or PETSc's SNES
                # configured by solver.petsc (snes.py); "auto": SNES if solver.petsc gives options
                "nonlinear": Choice(choices=("auto", "newton", "snes"), default="auto"),
                "petsc": PetscOptions(default={}),
            }
        ),
        "output": Table(
            {
                "directory": Text(default="results", non_empty=True),
                "xdmf": Flag(default=True),
                "xdmf_interval": Number(default=0.0, interval=NON_NEGATIVE, unit="s"),
                "fields": ChoiceList(choices=XDMF_FIELDS, default=XDMF_DEFAULT_FIELDS),
                "probe_fields": ChoiceList(choices=tuple(PROBE_FIELD_COLUMNS), default=()),
                "checkpoint": Flag(default=True),
                "checkpoint_interval": Number(
                    default="auto", interval=NON_NEGATIVE, unit="s", auto=True
                ),
            }
        ),
        "limits": Table(
            {
                "wall_time": Number(default=DEFAULT_WALL_TIME, interval=POSITIVE, unit="s"),
                "memory": Number(default="auto", interval=POSITIVE, unit="bytes", auto=True),
            }
        ),
    }
)


# ============================================================================ generic checking
def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _leaf_paths(table: Table, prefix: str = "") -> list[str]:
    """All dotted keys of the schema (tables included)."""
    paths = []
    for name, spec in table.fields.items():
        key = _join(prefix, name)
        paths.append(key)
        if isinstance(spec, Table):
            paths.extend(_leaf_paths(spec, key))
    return paths


def _unknown_key(key: str, siblings: Sequence[str]) -> SceneError:
    """Error for an unknown key, with a did-you-mean from this level or the whole schema."""
    prefix, _, name = key.rpartition(".")
    close = difflib.get_close_matches(name, siblings, n=1, cutoff=0.6)
    hint = _join(prefix, close[0]) if close else None
    if hint is None:
        paths = _leaf_paths(SCHEMA)
        close = difflib.get_close_matches(key, paths, n=1, cutoff=0.75)
        by_name = [p for p in paths if p.rpartition(".")[2] == name]
        hint = close[0] if close else (by_name[0] if by_name else None)
    text = f"{key}: unknown key"
    text += f" (did you mean {hint!r}?)" if hint else ""
    allowed = ", ".join(siblings)
    return SceneError(f"{text}; allowed {'in ' + prefix if prefix else 'at top level'}: {allowed}")


def _check_table(key: str, data: Any, spec: Table) -> dict[str, Any]:
    """Validate one table: unknown keys, then each field in schema order; defaults filled in."""
    if not isinstance(data, dict):
        raise SceneError(f"{key}: must be a table, got {show_value(data)}")
    for name in data:
        if name not in spec.fields:
            raise _unknown_key(_join(key, name), list(spec.fields))
    return {
        name: _check_entry(_join(key, name), data, name, sub) for name, sub in spec.fields.items()
    }


def _check_entry(key: str, data: dict[str, Any], name: str, spec: Any) -> Any:
    """Validate ``data[name]`` (absent → default, None, or a missing-key error)."""
    present = name in data
    if isinstance(spec, Parameters):
        return _check_parameters(key, data.get(name, {}))
    if isinstance(spec, Table):
        if not present and spec.optional:
            return None
        return _check_table(key, data.get(name, {}), spec)
    if present:
        return spec.check(key, data[name])
    if spec.required:
        raise SceneError(f"{key}: required key is missing ({spec.describe()})")
    return spec.default


def _check_parameters(key: str, data: Any) -> dict[str, float]:
    """[parameters]: identifier names, not reserved, finite numbers."""
    if not isinstance(data, dict):
        raise SceneError(f"{key}: must be a table of name = number, got {show_value(data)}")
    reserved = RESERVED_NAMES | set(SCENE_CONSTANTS)
    out = {}
    for name, value in data.items():
        item = _join(key, name)
        if not name.isidentifier() or keyword.iskeyword(name):
            raise SceneError(f"{item}: parameter names must be identifiers, got {name!r}")
        # Python reads identifiers in expressions by NFKC: as written the name could never
        # be used, or would silently be another one (a fullwidth t would be the time t).
        check_name(name, item)
        if name in reserved:
            raise SceneError(
                f"{item}: {name!r} is reserved; not allowed: {', '.join(sorted(reserved))}"
            )
        out[name] = Number().check(item, value)
    return out


# ================================================================================= overrides
def _lookup_spec(path: list[str]) -> Any:
    """The schema entry at a dotted path (``parameters.X`` accepted); SceneError if unknown."""
    spec: Any = SCHEMA
    for depth, name in enumerate(path):
        key = ".".join(path[: depth + 1])
        if isinstance(spec, Parameters):
            if depth != len(path) - 1:
                raise SceneError(f"{key}: parameters are numbers, not tables")
            return Number()
        if isinstance(spec, PetscOptions):
            if depth != len(path) - 1:
                raise SceneError(f"{key}: a PETSc option's value is not a table")
            return Text()
        if not isinstance(spec, Table):
            raise SceneError(f"{key}: unknown key; {'.'.join(path[:depth])} is not a table")
        if name not in spec.fields:
            raise _unknown_key(key, list(spec.fields))
        spec = spec.fields[name]
    return spec


def _override_value(key: str, text: str) -> Any:
    """A TOML value if ``text`` parses as one, else the bare string; SceneError naming
    ``key`` if it nests too deep for the TOML reader."""
    try:
        document = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:
        raise SceneError(f"{key}: nested deeper than {MAX_DEPTH} levels of tables and "
                         "lists") from None  # fmt: skip
    return document["v"] if list(document) == ["v"] else text


Overrides = Sequence[str] | Mapping[str, Any]


class Removal(str):
    """An override that removes its key, the command line's ``--unset KEY``: the key itself, a
    ``str``, so that a list of overrides stays a list of strings, in the order given."""


class _Unset:
    def __repr__(self) -> str:
        return "UNSET"


#: The value that removes a key in a mapping of overrides (``{"rod.section.a": UNSET}``, the
#: Python API's ``cf.UNSET``), as a :class:`Removal` does in a list.
UNSET = _Unset()


def remove_key(data: dict[str, Any], key: str) -> None:
    """Remove the dotted ``key``, a value or a whole table, from ``data`` (the overrides'
    ``--unset KEY`` and :data:`UNSET`): so that a table can change its shape from the command
    line (``--unset rod.section.a --unset rod.section.b --set rod.section.shape=circle``) and a
    default or an absent table be had again. SceneError for a key the schema does not have
    (with a did-you-mean) or the scene does not hold: nothing is removed silently."""
    path = [part.strip() for part in key.split(".")]
    _lookup_spec(path)
    table: Any = data
    for name in path[:-1]:
        table = table.get(name) if isinstance(table, dict) else None
    if not isinstance(table, dict) or path[-1] not in table:
        raise SceneError(f"{key}: not in the scene, nothing to remove (--unset)")
    del table[path[-1]]


def apply_overrides(data: dict[str, Any], overrides: Overrides) -> dict[str, Any]:
    """Return a copy of ``data`` with the overrides applied in order: ``dotted.key=value``
    strings (the command line's ``--set``; the value read as TOML) and :class:`Removal` overrides
    (``--unset``), or a mapping of dotted keys to values (the Python API; :data:`UNSET`
    removes a key)."""
    result = _copy_tables(data)
    items = overrides.items() if isinstance(overrides, Mapping) else map(_split, overrides)
    for key, value in items:
        key = str(key).strip()
        if value is UNSET:
            remove_key(result, key)
            continue
        path = [part.strip() for part in key.split(".")]
        spec = _lookup_spec(path)
        check_depth(value, key, len(path) + 1)
        if isinstance(spec, Table | Parameters):
            raise SceneError(f"{key}: is a table; set one of its keys instead (--set {key}.X=...)")
        _set_path(result, path, value)
        if key in _EXCLUSIVE:
            other = _EXCLUSIVE[1 - _EXCLUSIVE.index(key)]
            _table_at(result, path[:-1]).pop(other.rpartition(".")[2], None)
    return result


def _split(text: str) -> tuple[str, Any]:
    """(key, value) of a ``dotted.key=value`` override, (key, UNSET) of a :class:`Removal`."""
    if isinstance(text, Removal):
        return str(text), UNSET
    raw_key, sep, raw_value = text.partition("=")
    if not sep or not raw_key.strip():
        raise SceneError(f"--set {text!r}: expected dotted.key=value")
    return raw_key.strip(), _override_value(raw_key.strip(), raw_value.strip())


def _copy_tables(data: Any) -> Any:
    """Copy nested dicts (values shared otherwise)."""
    return {k: _copy_tables(v) for k, v in data.items()} if isinstance(data, dict) else data


def _table_at(data: dict[str, Any], path: list[str]) -> dict[str, Any]:
    """The table at ``path``, created if absent; SceneError if something else is there."""
    table = data
    for depth, name in enumerate(path):
        table = table.setdefault(name, {})
        if not isinstance(table, dict):
            key = ".".join(path[: depth + 1])
            raise SceneError(f"{key}: must be a table, got {show_value(table)}")
    return table


def _set_path(data: dict[str, Any], path: list[str], value: Any) -> None:
    _table_at(data, path[:-1])[path[-1]] = value


def read_input(path: str | Path, what: str = "scene file", comm=None,
               same_name: bool = True) -> bytes:  # fmt: skip
    """The bytes of the input file ``path`` (a scene or a sweep file), read once: rank 0 of
    ``comm`` (default MPI's world) reads it and every rank gets its bytes, so that every rank
    parses the same input (a file edited while the job starts, or a copy per node, cannot
    give the ranks different scenes). Collective. SceneError on every rank if the ranks name
    different files (unless not ``same_name``: a name made from rank 0's input, which may
    resolve otherwise on another rank), or if the file is not a regular file of at most
    :data:`MAX_INPUT_BYTES` (a FIFO, ``/dev/zero``: cosserat_fem/safe_files.py)."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD if comm is None else comm
    name = str(path)
    if comm.size > 1 and same_name:
        names = comm.allgather(name)
        other = next((r for r, n in enumerate(names) if n != names[0]), None)
        if other is not None:
            raise SceneError(f"{names[0]}: the MPI ranks name different {what}s (rank "
                             f"{other}: {names[other]!r}); give every rank the same file")
    try:
        return read_on_root(path, MAX_INPUT_BYTES, comm)
    except Unreadable as exc:
        raise SceneError(f"{name}: {what} {exc}") from None


def parse_toml(raw: bytes, path: str | Path) -> dict[str, Any]:
    """The TOML document ``raw`` (the content of ``path``); every failure (not UTF-8,
    malformed, nested deeper than :data:`MAX_DEPTH`) is a SceneError naming ``path``."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: malformed TOML: {exc}") from None
    except RecursionError:
        raise SceneError(f"{path}: nested deeper than {MAX_DEPTH} levels of tables and "
                         "lists") from None  # fmt: skip
    check_depth(data, str(path))
    return data


def read_toml(path: str | Path, what: str = "scene file", comm=None) -> dict[str, Any]:
    """Read a TOML file once for every rank (:func:`read_input`) and parse it
    (:func:`parse_toml`); every failure is a SceneError naming the file. Collective."""
    return parse_toml(read_input(path, what, comm), path)


def check_depth(data: Any, where: str, depth: int = 1) -> None:
    """SceneError if tables and lists nest deeper than :data:`MAX_DEPTH` in ``data`` (itself
    at level ``depth``), naming ``where`` and the keys of the tables on the way (checked
    without recursion: a document nested thousands deep, which TOML's dotted keys allow,
    must not exhaust Python's stack)."""
    stack: list[tuple[Any, int, str]] = [(data, depth, "")]
    while stack:
        value, level, key = stack.pop()
        if level > MAX_DEPTH:
            raise SceneError(f"{where}: {key + ': ' if key else ''}nested deeper than "
                             f"{MAX_DEPTH} levels of tables and lists")  # fmt: skip
        if isinstance(value, dict):
            items = [(_join(key, str(name)) if len(key) < 60 else key, item)
                     for name, item in value.items()]  # fmt: skip
        else:
            items = [(key, item) for item in value] if isinstance(value, list | tuple) else []
        stack += [(item, level + 1, inner) for inner, item in items
                  if isinstance(item, dict | list | tuple)]  # fmt: skip


def check_scene(data: dict[str, Any]) -> dict[str, Any]:
    """The scene's data validated against :data:`SCHEMA`, defaults filled in (raw values:
    expressions are still strings; cosserat_fem/scene.py builds the resolved scene)."""
    return _check_table("", data, SCHEMA)


def leaf_keys() -> list[str]:
    """Every dotted key of the schema (tables included)."""
    return _leaf_paths(SCHEMA)
