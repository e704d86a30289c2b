"""A scene key's declaration: its type, range, unit and default (:class:`Number`,
:class:`Choice`, ... each check one value), and :func:`key` / :func:`table`, which attach that
declaration to the field of the resolved scene the key becomes (cosserat_fem/scene/resolved.py). A
key is thus written once, on its resolved field: the schema (cosserat_fem/scene/schema.py,
``SCHEMA = Table.of(Scene)``), the resolved dataclasses and the scene reader
(cosserat_fem/scene/build.py, which builds every dataclass by keyword with :func:`build`) and the
scene writer (:func:`to_table`, ``Scene.to_dict``: each key's value as its spec's ``to_value``
writes it) all derive from that one line.

:func:`check_table` validates a table's raw data against its declaration, every problem one
:class:`~cosserat_fem.common.errors.SceneError` whose message starts with the dotted key at fault.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import keyword
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cosserat_fem.common.errors import SceneError, show_value
from cosserat_fem.forms.section import check_stiffness
from cosserat_fem.io.xdmf import FIELD_ARRAYS
from cosserat_fem.scene.expressions import RESERVED_NAMES, Expression, check_name
from cosserat_fem.scene.load_data import INTERPOLATIONS, OUTSIDE, S_INTERPOLATIONS, component_dict

#: Names every load expression may use besides the [parameters] (``s`` only in distributed loads).
SCENE_CONSTANTS = ("L", "omega0")
#: Relative tolerance for "is an integer number of time steps".
STEP_TOLERANCE = 1e-9
#: What output.fields may ask the XDMF file to hold (the format's, cosserat_fem/io/xdmf.py). The
#: names of heavier modules' choices (the integrators, the Jacobian policies) are spelled out
#: here, so that reading a scene needs no UFL or DOLFINx; tests/unit/scene/test_schema.py holds
#: them equal to the implementers' registries.
XDMF_FIELDS = tuple(FIELD_ARRAYS)
#: What output.fields holds when a scene does not say: all but the directors.
XDMF_DEFAULT_FIELDS = XDMF_FIELDS[:4]
#: Each end's support (scene/resolved.py Supports: "roller" and "sliding" leave z free).
SUPPORTS = ("clamped", "free", "pinned", "spherical", "roller", "sliding")
#: The one table of what each support holds: the components of the position (x, y, z) and of
#: the angles (θ, ψ, φ), each angle in the paper's chart a rotation about e1, e2, e3 at rest
#: (forms/kinematics.py). A pinned end given a hinge axis e_k holds the two angles but the
#: k-th instead (scene/resolved.py Supports.held). Everything else about supports derives
#: from it: the Dirichlet conditions (rod/model.py), the initial values checked, the end
#: torques refused (scene/build.py), the rigid-body modes and mechanisms (Supports).
HELD_BY_SUPPORT: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = {
    "clamped": ((0, 1, 2), (0, 1, 2)),
    "free": ((), ()),
    "pinned": ((0, 1, 2), (2,)),
    "spherical": ((0, 1, 2), ()),
    "roller": ((0, 1), (2,)),
    "sliding": ((0, 1), (0, 1, 2)),
}
#: A structure's node supports ([[structure.supports]], docs/structures.md): what each holds
#: is :data:`HELD_BY_SUPPORT`'s, a pinned node a hinge about its axis, a sliding node free
#: to move along its axis only.
STRUCTURE_SUPPORTS = ("clamped", "pinned", "spherical", "sliding", "free")
#: The joints between a structure's members other than rigid ([[structure.joints]]).
STRUCTURE_JOINTS = ("spherical", "hinge", "driven")
#: The rigid obstacles a rod may touch ([[contact.obstacles]], docs/contact.md).
CONTACT_OBSTACLES = ("plane", "sphere", "cylinder", "surface")
#: Upper bounds of keys whose size alone makes a run impossible here
#: (cosserat_fem/analysis/budget.py estimates the others): quadrature points per cell, Newton
#: iterations per solve.
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

#: The default of a vector key: zero.
ZERO3 = [0, 0, 0]

#: The keys each section shape takes besides ``shape`` and ``shear_coefficient``.
SECTION_KEYS = {
    "rectangle": ("a", "b", "torsion_constant"),
    "circle": ("diameter",),
    "tube": ("outer_diameter", "inner_diameter"),
    "constants": ("area", "c11", "c22", "c33"),
}

#: The shapes of a rod at rest ([reference]) and the keys each takes besides ``shape``
#: (forms/reference.py; cosserat_fem/scene/resolved.py ReferenceShape).
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

    def to_value(self, value: Any) -> Any:
        """The key's value as a scene file gives it, from the resolved field's ``value`` (the
        inverse of :meth:`check` and the reader's resolution): as it is by default; None
        leaves the key out (:func:`to_table`)."""
        return value


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

    def to_value(self, value: Any) -> Any:
        """ "auto" for None if the key may be "auto" (the reader resolves "auto" to None where
        the choice is made later: model.reference_frequency, limits.memory), else ``value``."""
        return "auto" if value is None and self.auto else value

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

    def to_value(self, value: Any) -> Any:
        """The list of the components: numbers as they are, an expression as its source, data
        (a table, a callable) as its dict (:func:`~cosserat_fem.scene.load_data.component_dict`)."""
        if value is None:
            return None
        return [x if isinstance(x, int | float) else component_dict(x) for x in value]


@dataclass(frozen=True, kw_only=True)
class NumberOrTimeExpression(Field):
    """A number or an expression string of t and the parameters; parsed later, when the names
    are known (a prescribed rotation's angle)."""

    unit: str = ""

    def describe(self) -> str:
        return f"a number or an expression string of t [{self.unit}]"

    def check(self, key: str, value: Any) -> Any:
        if isinstance(value, bool) or not isinstance(value, int | float | str):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return value

    def to_value(self, value: Any) -> Any:
        return None if value is None else value.source


@dataclass(frozen=True, kw_only=True)
class NumberVector(Field):
    """A list of 3 finite numbers (no expressions: a body's inertia, its offset)."""

    unit: str = ""

    def describe(self) -> str:
        return f"a list of 3 numbers [{self.unit}]"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list) or len(value) != 3:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        for i, x in enumerate(value):
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                raise SceneError(f"{key}[{i}]: must be a finite number, got {show_value(x)}")
        return tuple(float(x) for x in value)

    def to_value(self, value: Any) -> Any:
        return None if value is None else list(value)


@dataclass(frozen=True, kw_only=True)
class LoadVector(Vector):
    """A load's list of 3 components: numbers, expression strings, tables (an inline table
    checked against :data:`LOAD_TABLE`, defaults filled in) or, through the API, Python
    callables (cosserat_fem/scene/load_data.py); parsed later, when the names are known."""

    def describe(self) -> str:
        return (
            f"a list of 3 numbers, expression strings or tables {{table = ..., column = "
            f"...}} [{self.unit}]"
        )

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
                components[i] = check_table(f"{key}[{i}]", item, LOAD_TABLE)
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
                raise SceneError(
                    f"{key}[{i}]: must be a list of 3 numbers [{self.unit}], got "
                    f"{show_value(point)}"
                )
            points.append(
                tuple(
                    Number(unit=self.unit).check(f"{key}[{i}][{j}]", x) for j, x in enumerate(point)
                )
            )
        return points

    def to_value(self, value: Any) -> Any:
        """The points as lists."""
        return None if value is None else [list(point) for point in value]


@dataclass(frozen=True, kw_only=True)
class Names(Field):
    """A non-empty list of distinct non-empty strings (names of other entries)."""

    def describe(self) -> str:
        return "a non-empty list of distinct names"

    def check(self, key: str, value: Any) -> Any:
        """``value`` as a tuple; else SceneError naming ``key`` (and the index of a bad item)."""
        if not isinstance(value, list | tuple) or not value:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        for i, item in enumerate(value):
            Text(non_empty=True).check(f"{key}[{i}]", item)
            if item in value[:i]:
                raise SceneError(f"{key}[{i}]: {item!r} is given twice")
        return tuple(value)

    def to_value(self, value: Any) -> Any:
        return None if value is None else list(value)


@dataclass(frozen=True, kw_only=True)
class Tables(Field):
    """An array of tables (TOML ``[[name]]``), each checked against the table ``item``
    declares (a resolved dataclass, :meth:`Table.of`); the list may be empty unless
    ``required``."""

    item: type | None = None

    def describe(self) -> str:
        return "an array of tables [[...]]"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        assert self.item is not None, "declared with its item"
        spec = Table.of(self.item)
        return [check_table(f"{key}[{i}]", entry, spec) for i, entry in enumerate(value)]

    def to_value(self, value: Any) -> Any:
        """The tables of the resolved entries (:func:`to_table`)."""
        return None if value is None else [to_table(entry) for entry in value]


@dataclass(frozen=True, kw_only=True)
class SymmetricMatrix(Field):
    """A 6×6 symmetric positive definite matrix: a list of 6 rows of 6 entries, each a finite
    number or an expression string of s (a section varying along the rod; its names and its
    values are checked when the scene is built, cosserat_fem/scene/build.py). All numbers:
    symmetric to 1e-12 relative and positive definite here (cosserat_fem.forms.section
    ``check_stiffness``); with expressions, entry (j, i) must be entry (i, j) as written."""

    unit: str = ""

    def describe(self) -> str:
        return (
            f"a 6×6 symmetric positive definite matrix, 6 lists of 6 numbers or expression "
            f"strings [{self.unit}]"
        )

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list) or len(value) != 6:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        rows = []
        for i, row in enumerate(value):
            if not isinstance(row, list) or len(row) != 6:
                raise SceneError(
                    f"{key}[{i}]: must be a list of 6 numbers or expression strings (a row of "
                    f"a 6×6 matrix), got {show_value(row)}"
                )
            rows.append(tuple(_entry(f"{key}[{i}][{j}]", x) for j, x in enumerate(row)))
        if all(isinstance(x, float) for row in rows for x in row):
            try:
                check_stiffness(rows, key)
            except ValueError as err:
                raise SceneError(str(err)) from None
        for i in range(6):
            for j in range(i + 1, 6):
                a, b = rows[i][j], rows[j][i]
                if isinstance(a, float) != isinstance(b, float) or (
                    not isinstance(a, float) and a != b
                ):
                    raise SceneError(
                        f"{key}: not symmetric: [{i}][{j}] = {show_value(str(a))} but "
                        f"[{j}][{i}] = {show_value(str(b))}"
                    )
        return tuple(rows)

    def to_value(self, value: Any) -> Any:
        """The rows as lists, expressions as their sources."""
        if value is None:
            return None
        return [[x if isinstance(x, float) else x.source for x in row] for row in value]


@dataclass(frozen=True, kw_only=True)
class NumberOrExpression(Field):
    """A number > 0 or an expression string of s (checked positive along the rod when the
    scene is built, cosserat_fem/scene/build.py)."""

    unit: str = ""

    def describe(self) -> str:
        return f"a number > 0 or an expression string of s [{self.unit}]"

    def check(self, key: str, value: Any) -> Any:
        if isinstance(value, str):
            return Expression.parse(value, None, key)
        return Number(interval=Interval(0.0, None, lo_open=True), unit=self.unit).check(key, value)

    def to_value(self, value: Any) -> Any:
        return value if value is None or isinstance(value, float) else value.source


@dataclass(frozen=True, kw_only=True)
class PositionExpression(NumberOrTimeExpression):
    """A number or an expression string of the position x, y, z [m] and the parameters;
    parsed later, when the names are known (a surface's signed distance)."""

    def describe(self) -> str:
        return f"an expression string of x, y, z [{self.unit}]"


@dataclass(frozen=True, kw_only=True)
class NumberOrExpressionVector(Field):
    """A list of 3 entries of :class:`NumberOrExpression`."""

    unit: str = ""

    def describe(self) -> str:
        return f"a list of 3 numbers > 0 or expression strings of s [{self.unit}]"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list) or len(value) != 3:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        entry = NumberOrExpression(unit=self.unit)
        return tuple(entry.check(f"{key}[{i}]", x) for i, x in enumerate(value))

    def to_value(self, value: Any) -> Any:
        entry = NumberOrExpression(unit=self.unit)
        return None if value is None else [entry.to_value(x) for x in value]


def _entry(key: str, value: Any) -> Any:
    """A number (float) or an expression string of s (Expression, names checked later)."""
    if isinstance(value, str):
        return Expression.parse(value, None, key)
    return Number().check(key, value)


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

    def to_value(self, value: Any) -> Any:
        return list(value)


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
    raise SceneError(
        f"{key}: a PETSc option's value must be a string, a finite number or true/"
        f'false ("" for an option without a value), got {show_value(value)}'
    )


@dataclass(frozen=True, kw_only=True)
class PetscOptions(Field):
    """The free-form [solver.petsc] table: PETSc option name (without "-" and the prefix
    ``cosserat_``) = value, for solver.nonlinear = "snes" (cosserat_fem/nls/snes.py). Checked here
    for form only (names, values: :func:`petsc_value`); whether PETSc knows an option is only
    known once it has set the solver up (an unused option is then a SceneError)."""

    def describe(self) -> str:
        return "a table of PETSc option name = value"

    def check(self, key: str, value: Any) -> Any:
        """{name: value as PETSc's database takes it}; SceneError naming ``key.name``."""
        if not isinstance(value, dict):
            raise SceneError(
                f"{key}: must be {self.describe()}, e.g. {{snes_linesearch_type = "
                f'"bt"}}, got {show_value(value)}'
            )
        options = {}
        for name, item in value.items():
            item_key = join_key(key, str(name))
            if not PETSC_OPTION_NAME.fullmatch(str(name)):
                raise SceneError(
                    f"{item_key}: a PETSc option's name is letters, digits and _, "
                    'without the leading "-" (e.g. snes_type)'
                )
            if str(name).startswith(PETSC_PREFIX):
                raise SceneError(
                    f"{item_key}: give the option without its prefix {PETSC_PREFIX!r} (it is added)"
                )
            options[str(name)] = petsc_value(item_key, item)
        return options

    def to_value(self, value: Any) -> Any:
        return dict(value)


#: The options prefix of the SNES solver (cosserat_fem/nls/snes.py): ``-cosserat_snes_type`` in
#: PETSc's terms is ``snes_type`` in [solver.petsc].
PETSC_PREFIX = "cosserat_"


@dataclass(frozen=True)
class Table:
    """A table of fields; an ``optional`` table resolves to None when absent."""

    fields: Mapping[str, Field | Table | Parameters]
    optional: bool = False
    #: The resolved dataclass that declares the table (:meth:`of`), or None.
    resolved: type | None = dataclasses.field(default=None, compare=False)

    @classmethod
    def of(cls, resolved: type, optional: bool = False) -> Table:
        """The table a resolved dataclass declares: each of its fields made by :func:`key` or
        :func:`table`, in the order of the fields, under its scene key (the field's name
        unless the declaration names another); fields without a declaration (derived
        values) are not keys."""
        fields = {name: spec for name, _, spec in declarations(resolved)}
        return cls(fields, optional, resolved)

    def to_value(self, value: Any) -> dict[str, Any] | None:
        """The sub-table of the resolved ``value`` (:func:`to_table`); None (left out) for an
        optional table that is absent."""
        return None if value is None else to_table(value)


#: The metadata entries of a resolved field that a key declares: its spec, its scene name.
_DECLARATION = "cosserat_fem.key"
_KEY_NAME = "cosserat_fem.key_name"


def key(spec: Field | Parameters | Table, *, name: str | None = None, **options: Any) -> Any:
    """A resolved dataclass's field that is the scene key ``spec`` declares (its type, range,
    unit, default): :meth:`Table.of` reads it, :func:`build` fills it by name. ``name``: the
    key's name in the scene file when it differs from the field's; ``options``: those of
    ``dataclasses.field`` (``default``, ``default_factory``) for the resolved value."""
    return dataclasses.field(metadata={_DECLARATION: spec, _KEY_NAME: name}, **options)


def table(resolved: type, *, optional: bool = False, **options: Any) -> Any:
    """A field that is the sub-table of keys the dataclass ``resolved`` declares (None when an
    ``optional`` table is absent)."""
    return key(Table.of(resolved, optional), **options)


@functools.cache
def declarations(resolved: type) -> tuple[tuple[str, str, Any], ...]:
    """(scene key name, field name, spec) of each field of the dataclass ``resolved`` that
    declares a key (:func:`key`, :func:`table`), in the order of the fields (once a class:
    a class's fields do not change)."""
    return tuple(
        (f.metadata.get(_KEY_NAME) or f.name, f.name, f.metadata[_DECLARATION])
        for f in dataclasses.fields(resolved)
        if _DECLARATION in f.metadata
    )


def declared_names(resolved: type) -> dict[str, str]:
    """{scene key name: field name} of the fields of ``resolved`` that declare a key."""
    return {name: field for name, field, _ in declarations(resolved)}


def to_table(resolved: object) -> dict[str, Any]:
    """The table of a scene file that gives the resolved dataclass instance ``resolved`` (what
    :func:`build` built it from, every key given): each declared field under its key's name,
    its value as the key's spec writes it (``to_value``: a sub-table by recursion, an
    expression as its source, "auto" where so chosen), a key whose value is None (an absent
    optional table or vector, a shape's unused key, the one of two exclusive keys not given)
    left out. Plain, JSON-serialisable values (lists, dicts, numbers, strings); a field that
    declares no key (a derived value) is not written. ``Scene.to_dict`` is this of the scene.
    """
    kind: type = type(resolved)  # as declarations takes it (a type[object] is not Hashable)
    values = {
        name: spec.to_value(getattr(resolved, field)) for name, field, spec in declarations(kind)
    }
    return {name: value for name, value in values.items() if value is not None}


def build(resolved: type, raw: Mapping[str, Any], **resolved_values: Any) -> Any:
    """``resolved`` built by keyword from the checked table ``raw`` (:func:`check_table`):
    each declared field from the key it declares, ``resolved_values`` (field name = value)
    for the fields whose value the reader resolves (a sub-table, "auto", a parsed expression).
    Nothing is built by position, so the order of the fields decides nothing."""
    values = {field: raw[name] for name, field in declared_names(resolved).items()}
    values.update(resolved_values)
    return resolved(**values)


@dataclass(frozen=True)
class Parameters:
    """The free-form [parameters] table: identifier = finite number."""

    def to_value(self, value: Any) -> dict[str, float]:
        return dict(value)


#: A load component given by a table file (cosserat_fem/scene/load_data.py, docs/loads.md): the
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


# ============================================================================ generic checking
def join_key(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def leaf_paths(table: Table, prefix: str = "") -> list[str]:
    """All dotted keys of the schema (tables included)."""
    paths = []
    for name, spec in table.fields.items():
        key = join_key(prefix, name)
        paths.append(key)
        if isinstance(spec, Table):
            paths.extend(leaf_paths(spec, key))
    return paths


def unknown_key(key: str, siblings: Sequence[str], root: Table | None = None) -> SceneError:
    """Error for an unknown key, with a did-you-mean from this level or the whole of ``root``
    (the table the dotted key starts from)."""
    prefix, _, name = key.rpartition(".")
    close = difflib.get_close_matches(name, siblings, n=1, cutoff=0.6)
    hint = join_key(prefix, close[0]) if close else None
    if hint is None and root is not None:
        paths = leaf_paths(root)
        close = difflib.get_close_matches(key, paths, n=1, cutoff=0.75)
        by_name = [p for p in paths if p.rpartition(".")[2] == name]
        hint = close[0] if close else (by_name[0] if by_name else None)
    text = f"{key}: unknown key"
    text += f" (did you mean {hint!r}?)" if hint else ""
    allowed = ", ".join(siblings)
    return SceneError(f"{text}; allowed {'in ' + prefix if prefix else 'at top level'}: {allowed}")


def check_table(key: str, data: Any, spec: Table, root: Table | None = None) -> dict[str, Any]:
    """Validate one table: unknown keys, then each field in schema order; defaults filled in.
    ``root``: the table ``key`` is dotted from, for a did-you-mean (None: ``spec``)."""
    root = spec if root is None else root
    if not isinstance(data, dict):
        raise SceneError(f"{key}: must be a table, got {show_value(data)}")
    for name in data:
        if name not in spec.fields:
            raise unknown_key(join_key(key, name), list(spec.fields), root)
    return {
        name: _check_entry(join_key(key, name), data, name, sub, root)
        for name, sub in spec.fields.items()
    }


def _check_entry(key: str, data: dict[str, Any], name: str, spec: Any, root: Table) -> Any:
    """Validate ``data[name]`` (absent → default, None, or a missing-key error)."""
    present = name in data
    if isinstance(spec, Parameters):
        return _check_parameters(key, data.get(name, {}))
    if isinstance(spec, Table):
        if not present and spec.optional:
            return None
        return check_table(key, data.get(name, {}), spec, root)
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
        item = join_key(key, name)
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
