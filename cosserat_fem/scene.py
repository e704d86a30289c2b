"""TOML scenes: schema, validation, ``--set`` overrides and the resolved :class:`Scene`.

A scene file describes one run (rod, material, supports, loads, time span, discretisation,
solver and output). :func:`load_scene` reads it, applies ``dotted.key=value`` overrides and
validates everything before any work is done; every problem is reported as a single
:class:`~cosserat_fem.errors.SceneError` whose message starts with the dotted key at fault,
states what is allowed and shows the offending value. The schema (keys, defaults, ranges) is
the table :data:`SCHEMA` below; ``scenes/cao_tucker_2008.toml`` is a commented example.

Overrides: the value is read as a TOML value if possible (``1e-5``, ``true``, ``"bdf2"``,
``[0, 0, "1e3*t"]``), else taken as a bare string (``time.integrator=bdf2``). Overriding one of
``rod.material.poisson_ratio`` / ``rod.material.shear_modulus`` removes the other, so that
either can be set from the command line whichever the file gives.
"""

from __future__ import annotations

import difflib
import keyword
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from cosserat_fem.errors import SceneError, show_value
from cosserat_fem.expressions import (
    RESERVED_NAMES,
    Expression,
    check_name,
    derivative,
    parse_vector,
)
from cosserat_fem.forms.groups import (
    TORSION_INERTIAS,
    Groups,
    RodConstants,
    dimensionless_groups,
    euler_bernoulli_omega0,
)
from cosserat_fem.forms.section import (
    TORSION_CONSTANT_RULES,
    Section,
    cowper_circle,
    rectangle,
    tube,
)

#: Names every load expression may use besides the [parameters] (``s`` only in distributed loads).
SCENE_CONSTANTS = ("L", "omega0")
#: Relative tolerance for "is an integer number of time steps".
STEP_TOLERANCE = 1e-9
CHECKPOINTS_PER_RUN = 10  # output.checkpoint_interval = "auto"
#: What output.fields may ask the XDMF file to hold (cosserat_fem/output.py).
XDMF_FIELDS = ("displacement", "angles", "strains", "forces")
SUPPORTS = ("clamped", "free", "pinned")
#: Upper bounds of keys whose size alone makes a run impossible here (cosserat_fem/budget.py
#: estimates the others): quadrature points per cell, Newton iterations per solve.
MAX_QUADRATURE = 100
MAX_NEWTON_ITERATIONS = 1000

_EXCLUSIVE = ("rod.material.poisson_ratio", "rod.material.shear_modulus")


# ======================================================================= resolved scene objects
@dataclass(frozen=True)
class SectionSpec:
    """Cross-section, SI units, by ``shape`` (the keys of :data:`SECTION_KEYS`):

    * rectangle: ``a`` along d1 (thickness), ``b`` along d2 (width) [m], c33 by the
      ``torsion_constant`` rule (the Saint-Venant series, or the paper's approximation);
    * circle: ``diameter`` [m]; tube: ``outer_diameter``, ``inner_diameter`` [m];
    * constants: ``area`` [m²], ``c11``, ``c22``, ``c33`` [m⁴] given explicitly.

    ``shear_coefficient`` κ is resolved: given, or 5/6 (rectangle) or Cowper's value for ν
    (circle, tube); "constants" needs it given.
    """

    shape: str
    shear_coefficient: float
    a: float | None = None
    b: float | None = None
    torsion_constant: str | None = None
    diameter: float | None = None
    outer_diameter: float | None = None
    inner_diameter: float | None = None
    area: float | None = None
    c11: float | None = None
    c22: float | None = None
    c33: float | None = None

    def constants(self) -> Section:
        """A, c11, c22, c33, κ (cosserat_fem.forms.section)."""
        k = self.shear_coefficient
        if self.shape == "rectangle":
            return rectangle(self.a, self.b, k, self.torsion_constant)
        if self.shape == "circle":
            return tube(self.diameter, 0.0, k)
        if self.shape == "tube":
            return tube(self.outer_diameter, self.inner_diameter, k)
        return Section(self.area, self.c11, self.c22, self.c33, k)

    def given(self) -> dict[str, Any]:
        """The keys of this shape (for to_dict)."""
        return {k: v for k, v in vars(self).items() if v is not None}


#: The keys each section shape takes besides ``shape`` and ``shear_coefficient``.
SECTION_KEYS = {
    "rectangle": ("a", "b", "torsion_constant"),
    "circle": ("diameter",),
    "tube": ("outer_diameter", "inner_diameter"),
    "constants": ("area", "c11", "c22", "c33"),
}


@dataclass(frozen=True)
class Material:
    """Linear elastic material; exactly one of ``poisson_ratio`` / ``shear_modulus_value``."""

    density: float
    young_modulus: float
    poisson_ratio: float | None
    shear_modulus_value: float | None

    @property
    def shear_modulus(self) -> float:
        """G [Pa]: as given, or E / (2 (1 + ν))."""
        if self.shear_modulus_value is not None:
            return self.shear_modulus_value
        if self.poisson_ratio is None:
            raise ValueError("Material: give poisson_ratio or shear_modulus_value")
        return self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True)
class Rod:
    """Straight rod of length ``length`` [m]."""

    length: float
    section: SectionSpec
    material: Material


@dataclass(frozen=True)
class ModelChoices:
    """Modelling choices; ``reference_frequency`` [rad/s] is None for "auto"."""

    reference_frequency: float | None
    torsion_inertia: str
    end_load_sign: str
    end_load_scaling: str


@dataclass(frozen=True)
class Supports:
    """Support of each end: "clamped" (p = q = 0), "free" (natural conditions), or "pinned":
    a fork bearing, the position and the twist φ held, the bending angles θ, ψ free (the end
    torque about d1, d2 is the given end torque, zero by default).

    ``start_motion``/``end_motion``: a prescribed translation (x, y, z)(t) [m] of a clamped or
    pinned end (base excitation; None: at rest); its directors do not turn.
    """

    start: str
    end: str
    start_motion: tuple[Expression, ...] | None = None
    end_motion: tuple[Expression, ...] | None = None

    def motion(self, end: str) -> tuple[Expression, ...] | None:
        return self.start_motion if end == "start" else self.end_motion


@dataclass(frozen=True)
class EndLoad:
    """Force [N] and torque [N m] on a free end, fixed directions e1, e2, e3; functions of t."""

    force: tuple[Expression, ...]
    torque: tuple[Expression, ...]


@dataclass(frozen=True)
class Loads:
    """Distributed force [N/m] and torque [N m/m] (functions of s, t) and end loads."""

    force_density: tuple[Expression, ...]
    torque_density: tuple[Expression, ...]
    start: EndLoad | None
    end: EndLoad | None
    gravity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m/s², adds ρ A g to the force

    @property
    def has_gravity(self) -> bool:
        return any(g != 0.0 for g in self.gravity)


#: Planes of motion (Scene.plane): the normal e_k, the axes of torques that leave the plane
#: and the angles (θ, ψ, φ) = (0, 1, 2) that stay zero in it.
PLANES = {"x-z": ((1,), (0, 2), (0, 2)), "y-z": ((0,), (1, 2), (1, 2))}


def _in_plane(normal: tuple[int, ...], angles: tuple[int, ...]) -> tuple[int, ...]:
    """The components of U = (p, q) that a plane keeps: the translations but its normal, the
    angles it does not hold at zero, and their rates."""
    p = [i for i in range(3) if i not in normal] + [3 + a for a in range(3) if a not in angles]
    return (*p, *(6 + i for i in p))


#: The components of U = (p, q) solved in each plane (x-z: x, z, ψ; y-z: y, z, θ; + rates).
PLANAR = {name: _in_plane(normal, angles) for name, (normal, _, angles) in PLANES.items()}


@dataclass(frozen=True)
class Damping:
    """Viscous damping densities: force −c_t ṙ [N/m] with ``translational`` c_t [N s/m²], and
    torque −c_r ω [N m/m] with ``rotational`` c_r [N s] (ω the angular velocity). For a
    slender rod c_t damps every bending mode alike: ζ_n = c_t / (2 ρ A ω_n).

    Kelvin–Voigt (material) damping with ``retardation_time`` τ_d [s]: E and G act on
    (1 + τ_d ∂t) of the strains, n = K (v − e3 + τ_d v̇), m = J (u + τ_d u̇); it damps each
    mode in proportion to its frequency, ζ_n = τ_d ω_n / 2 (forms/general_form.py)."""

    translational: float = 0.0
    rotational: float = 0.0
    retardation_time: float = 0.0

    @property
    def viscous(self) -> bool:
        return self.translational > 0.0 or self.rotational > 0.0

    @property
    def kelvin_voigt(self) -> bool:
        return self.retardation_time > 0.0

    @property
    def active(self) -> bool:
        return self.viscous or self.kelvin_voigt


@dataclass(frozen=True)
class Initial:
    """The state at time.start as functions of s [m] (None: at rest, straight): position
    displacement [m], angles (θ, ψ, φ) [rad], velocity [m/s], angle rates [rad/s]."""

    displacement: tuple[Expression, ...] | None = None
    angles: tuple[Expression, ...] | None = None
    velocity: tuple[Expression, ...] | None = None
    angle_rates: tuple[Expression, ...] | None = None

    def fields(self) -> dict[str, tuple[Expression, ...]]:
        """The fields given, non-zero, by name."""
        return {
            name: value
            for name, value in vars(self).items()
            if value is not None and not all(e.is_zero for e in value)
        }


@dataclass(frozen=True)
class Time:
    """Time span [s] and integrator."""

    start: float
    end: float
    step: float
    integrator: str
    rho_inf: float
    max_halvings: int = 6
    adaptive: bool = False
    rtol: float = 1e-4
    atol: float = 1e-10
    max_step: float = 0.0  # 0: no limit

    @property
    def n_steps(self) -> int:
        """Number of time steps, round((end - start) / step)."""
        return round((self.end - self.start) / self.step)


@dataclass(frozen=True)
class StaticSettings:
    """Static solves (``cosserat-fem static``): the loads at ``time`` [s], applied in
    ``load_steps`` equal increments of the load factor; a failed increment is halved, down to
    2^-``max_bisections`` of the nominal increment."""

    load_steps: int
    max_bisections: int
    time: float


@dataclass(frozen=True)
class Discretisation:
    """Mesh and element: ``elements`` cells of Lagrange ``degree``; quadrature resolved."""

    elements: int
    degree: int
    quadrature_degree: int
    planar: str = "auto"  # "auto": solve the in-plane unknowns of a scene in x-z or y-z


@dataclass(frozen=True)
class Solver:
    """Newton solver settings."""

    jacobian: str
    lag: int
    refresh_iterations: int
    rtol: float
    atol: float
    stol: float
    max_iterations: int
    linear_solver: str


@dataclass(frozen=True)
class Output:
    """Output directory (stored as written), XDMF and checkpoint settings.

    ``checkpoint_interval`` [s] is resolved: a positive multiple of the step, or 0 for a
    checkpoint at the end of the run only (cosserat_fem/checkpoint.py).
    """

    directory: str
    xdmf: bool
    xdmf_interval: float
    fields: tuple[str, ...] = XDMF_FIELDS
    checkpoint: bool = True
    checkpoint_interval: float = 0.0

    def xdmf_every(self, step: float) -> int:
        """Steps between XDMF writes (1 if the interval is 0)."""
        if self.xdmf_interval == 0.0:
            return 1
        return max(1, round(self.xdmf_interval / step))


@dataclass(frozen=True)
class Limits:
    """What a run may cost before it is refused (cosserat_fem/budget.py): ``wall_time`` [s],
    the estimated wall time of the run and the most it may run before it stops with a
    checkpoint; ``memory`` [bytes], the estimated memory (None: "auto", the memory available
    on this machine). Raise them to run a very large case on purpose."""

    wall_time: float = 86400.0
    memory: float | None = None


@dataclass(frozen=True)
class Scene:
    """A validated scene; ``source`` (file name or "<dict>") does not take part in equality."""

    title: str
    parameters: dict[str, float]
    rod: Rod
    model: ModelChoices
    supports: Supports
    loads: Loads
    time: Time
    discretisation: Discretisation
    solver: Solver
    output: Output
    static: StaticSettings = field(default_factory=lambda: StaticSettings(1, 10, 0.0))
    damping: Damping = field(default_factory=Damping)
    initial: Initial = field(default_factory=Initial)
    limits: Limits = field(default_factory=Limits)
    source: str = field(default="<dict>", compare=False)

    @property
    def omega0(self) -> float:
        """The reference frequency ω0 [rad/s]: as given, or :func:`auto_reference_frequency`."""
        given = self.model.reference_frequency
        return given if given is not None else auto_reference_frequency(self.rod)

    def plane(self) -> str | None:
        """The plane the motion stays in, "x-z" or "y-z" (checked in that order: a scene in
        both moves along the axis only, and x-z keeps clear of the chart limit |θ| < π/2),
        or None: asked for (discretisation.planar = "auto") and nothing leaves the plane."""
        if self.discretisation.planar != "auto":
            return None
        return next((name for name in PLANES if self._stays_in(name)), None)

    def absent_terms(self) -> list[str]:
        """The load and damping terms that are zero, so not in the form (``skipped_terms``
        of summary.json, ``validate``)."""
        loads, damping = self.loads, self.damping
        absent = [
            name
            for name, exprs in (
                ("force_density", loads.force_density),
                ("torque_density", loads.torque_density),
            )
            if exprs is None or all(e.is_zero for e in exprs)
        ]
        absent += [] if loads.has_gravity else ["gravity"]
        absent += [] if damping.viscous else ["damping"]
        return absent + ([] if damping.kelvin_voigt else ["kelvin_voigt"])

    def _stays_in(self, plane: str) -> bool:
        """Nothing leaves the plane: no force or support motion along its normal e_k (e2 for
        x-z, e1 for y-z), no torque about the other two axes (distributed, at the ends), no
        gravity along e_k, no initial displacement or velocity along e_k, no initial angles
        or rates other than the in-plane one (ψ for x-z, θ for y-z)."""
        normal, torques, angles = PLANES[plane]
        loads, init = self.loads, self.initial
        vectors = [(loads.force_density, normal), (loads.torque_density, torques)]
        for end in (loads.start, loads.end):
            if end is not None:
                vectors += [(end.force, normal), (end.torque, torques)]
        vectors += [(m, normal) for m in (self.supports.start_motion, self.supports.end_motion)]
        vectors += [(init.displacement, normal), (init.velocity, normal)]
        vectors += [(init.angles, angles), (init.angle_rates, angles)]
        if any(loads.gravity[i] != 0.0 for i in normal):
            return False
        return all(v is None or all(v[i].is_zero for i in idx) for v, idx in vectors)

    def rod_constants(self) -> RodConstants:
        """Physical constants of the rod, with ω0 resolved (section 6 when "auto")."""
        mat = self.rod.material
        return RodConstants(
            length=self.rod.length,
            section=self.rod.section.constants(),
            density=mat.density,
            young_modulus=mat.young_modulus,
            shear_modulus=mat.shear_modulus,
            omega0=self.omega0,
            torsion_inertia=self.model.torsion_inertia,
        )

    def expression_names(self) -> dict[str, float]:
        """Constant values for load expressions: ``L``, ``omega0`` and the parameters."""
        return {"L": self.rod.length, "omega0": self.omega0, **self.parameters}

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable dict with resolved defaults; ``scene_from_dict`` inverts it."""
        return _scene_to_dict(self)


def auto_reference_frequency(rod: Rod) -> float:
    """ω0 = 1.875² / L² · sqrt(E c22 / (ρ A)) (paper, §6: c22 = b a³/12, A = a b for its
    rectangle): the first cantilever bending frequency about d2."""
    mat = rod.material
    section = rod.section.constants()
    return euler_bernoulli_omega0(rod.length, section, mat.density, mat.young_modulus)


# ========================================================================== schema primitives
def _fmt(x: float) -> str:
    """A bound for messages: integers without ".0", else ``repr``."""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else repr(float(x))


@dataclass(frozen=True)
class _Interval:
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
        if self.lo is not None and self.hi is not None:
            left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
            return f"in {left}{_fmt(self.lo)}, {_fmt(self.hi)}{right}"
        if self.lo is not None:
            return f"{'>' if self.lo_open else '>='} {_fmt(self.lo)}"
        if self.hi is not None:
            return f"{'<' if self.hi_open else '<='} {_fmt(self.hi)}"
        return "finite"


POSITIVE = _Interval(lo=0.0, lo_open=True)
NON_NEGATIVE = _Interval(lo=0.0)
ANY = _Interval()


@dataclass(frozen=True, kw_only=True)
class _Field:
    """A leaf key: ``required`` or else ``default``."""

    required: bool = False
    default: Any = None

    def describe(self) -> str:
        raise NotImplementedError

    def check(self, key: str, value: Any) -> Any:
        raise NotImplementedError


@dataclass(frozen=True, kw_only=True)
class _Number(_Field):
    """A finite number in ``interval``; ``integer`` → int; ``auto`` → also the string "auto"."""

    interval: _Interval = ANY
    unit: str = ""
    integer: bool = False
    auto: bool = False

    def describe(self) -> str:
        kind = "an integer" if self.integer else "a number"
        text = f"{kind} {self.interval.describe()}" if self.interval != ANY else kind
        text += f" [{self.unit}]" if self.unit else ""
        return f'"auto" or {text}' if self.auto else text

    def check(self, key: str, value: Any) -> Any:
        if self.auto and value == "auto":
            return "auto"
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        if not math.isfinite(value):
            raise SceneError(f"{key}: must be {self.describe()}, finite, got {show_value(value)}")
        if self.integer and not float(value).is_integer():
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        number = int(value) if self.integer else float(value)
        if not self.interval.contains(number):
            raise SceneError(self._range_message(key, value))
        return number

    def _range_message(self, key: str, value: Any) -> str:
        if self.auto:
            return f"{key}: must be {self.describe()}, got {show_value(value)}"
        rule = self.interval.describe()
        verb = "lie" if rule.startswith("in ") else "be"
        unit = f" [{self.unit}]" if self.unit else ""
        return f"{key}: must {verb} {rule}{unit}, got {show_value(value)}"


@dataclass(frozen=True, kw_only=True)
class _Choice(_Field):
    """One of a fixed set of strings."""

    choices: tuple[str, ...] = ()

    def describe(self) -> str:
        return "one of " + ", ".join(show_value(c) for c in self.choices)

    def check(self, key: str, value: Any) -> Any:
        if isinstance(value, str) and value in self.choices:
            return value
        hint = ""
        if isinstance(value, str):
            close = difflib.get_close_matches(value, self.choices, n=1, cutoff=0.5)
            hint = f" (did you mean {show_value(close[0])}?)" if close else ""
        raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}{hint}")


@dataclass(frozen=True, kw_only=True)
class _Text(_Field):
    """A string (non-empty if ``non_empty``)."""

    non_empty: bool = False

    def describe(self) -> str:
        return "a non-empty string" if self.non_empty else "a string"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, str) or (self.non_empty and not value.strip()):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return value


@dataclass(frozen=True, kw_only=True)
class _Flag(_Field):
    """A boolean."""

    def describe(self) -> str:
        return "true or false"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, bool):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return value


@dataclass(frozen=True, kw_only=True)
class _Vector(_Field):
    """A list of 3 numbers/expression strings; parsed later, when the names are known."""

    unit: str = ""

    def describe(self) -> str:
        return f"a list of 3 numbers or expression strings [{self.unit}]"

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list) or len(value) != 3:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return list(value)


@dataclass(frozen=True, kw_only=True)
class _ChoiceList(_Field):
    """A list of distinct strings, each one of ``choices`` (kept in the given order)."""

    choices: tuple[str, ...] = ()

    def describe(self) -> str:
        return "a list of distinct strings from " + ", ".join(show_value(c) for c in self.choices)

    def check(self, key: str, value: Any) -> Any:
        if not isinstance(value, list | tuple) or len(set(map(str, value))) != len(value):
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        for i, item in enumerate(value):
            _Choice(choices=self.choices).check(f"{key}[{i}]", item)
        return tuple(value)


@dataclass(frozen=True)
class _Table:
    """A table of fields; an ``optional`` table resolves to None when absent."""

    fields: Mapping[str, _Field | _Table | _Parameters]
    optional: bool = False


@dataclass(frozen=True)
class _Parameters:
    """The free-form [parameters] table: identifier = finite number."""


_ZERO3 = [0, 0, 0]
_END_LOAD = _Table(
    {
        "force": _Vector(default=_ZERO3, unit="N"),
        "torque": _Vector(default=_ZERO3, unit="N m"),
    },
    optional=True,
)

#: The scene schema (nested tables; leaves carry type, range and default).
SCHEMA = _Table(
    {
        "title": _Text(default=""),
        "parameters": _Parameters(),
        "rod": _Table(
            {
                "length": _Number(required=True, interval=POSITIVE, unit="m"),
                "section": _Table(
                    {
                        "shape": _Choice(choices=tuple(SECTION_KEYS), default="rectangle"),
                        "a": _Number(interval=POSITIVE, unit="m"),
                        "b": _Number(interval=POSITIVE, unit="m"),
                        "torsion_constant": _Choice(choices=TORSION_CONSTANT_RULES),
                        "diameter": _Number(interval=POSITIVE, unit="m"),
                        "outer_diameter": _Number(interval=POSITIVE, unit="m"),
                        "inner_diameter": _Number(interval=NON_NEGATIVE, unit="m"),
                        "area": _Number(interval=POSITIVE, unit="m^2"),
                        "c11": _Number(interval=POSITIVE, unit="m^4"),
                        "c22": _Number(interval=POSITIVE, unit="m^4"),
                        "c33": _Number(interval=POSITIVE, unit="m^4"),
                        "shear_coefficient": _Number(
                            default="auto", interval=_Interval(0.0, 1.0, lo_open=True), auto=True
                        ),
                    }
                ),
                "material": _Table(
                    {
                        "density": _Number(required=True, interval=POSITIVE, unit="kg/m^3"),
                        "young_modulus": _Number(required=True, interval=POSITIVE, unit="Pa"),
                        "poisson_ratio": _Number(
                            interval=_Interval(-1.0, 0.5, lo_open=True, hi_open=True)
                        ),
                        "shear_modulus": _Number(interval=POSITIVE, unit="Pa"),
                    }
                ),
            }
        ),
        "model": _Table(
            {
                "reference_frequency": _Number(
                    default="auto", interval=POSITIVE, unit="rad/s", auto=True
                ),
                "torsion_inertia": _Choice(choices=TORSION_INERTIAS, default="polar"),
                "end_load_sign": _Choice(choices=("balance", "printed"), default="balance"),
                "end_load_scaling": _Choice(choices=("balance", "printed"), default="balance"),
            }
        ),
        "supports": _Table(
            {
                "start": _Choice(choices=SUPPORTS, default="clamped"),
                "end": _Choice(choices=SUPPORTS, default="free"),
                "start_motion": _Vector(default=_ZERO3, unit="m"),
                "end_motion": _Vector(default=_ZERO3, unit="m"),
            }
        ),
        "loads": _Table(
            {
                "force_density": _Vector(default=_ZERO3, unit="N/m"),
                "torque_density": _Vector(default=_ZERO3, unit="N m/m"),
                "start": _END_LOAD,
                "end": _END_LOAD,
                "gravity": _Vector(default=_ZERO3, unit="m/s^2"),
            }
        ),
        "damping": _Table(
            {
                "translational": _Number(default=0.0, interval=NON_NEGATIVE, unit="N s/m^2"),
                "rotational": _Number(default=0.0, interval=NON_NEGATIVE, unit="N s"),
                "retardation_time": _Number(default=0.0, interval=NON_NEGATIVE, unit="s"),
            }
        ),
        "initial": _Table(
            {
                "displacement": _Vector(default=_ZERO3, unit="m"),
                "angles": _Vector(default=_ZERO3, unit="rad"),
                "velocity": _Vector(default=_ZERO3, unit="m/s"),
                "angle_rates": _Vector(default=_ZERO3, unit="rad/s"),
            }
        ),
        "time": _Table(
            {
                "start": _Number(default=0.0, unit="s"),
                "end": _Number(required=True, unit="s"),
                "step": _Number(required=True, interval=POSITIVE, unit="s"),
                # SDIRK3 and a frozen Jacobian: the fastest to an error of 1e-3 on the paper's
                # scene (benchmarks/README.md), the defaults the README states.
                "integrator": _Choice(
                    choices=("bdf2", "generalized-alpha", "sdirk3", "sdirk4"), default="sdirk3"
                ),
                "rho_inf": _Number(default=0.5, interval=_Interval(0.0, 1.0)),
                "max_halvings": _Number(default=6, integer=True, interval=_Interval(0, 30)),
                "adaptive": _Flag(default=False),
                "rtol": _Number(default=1e-4, interval=_Interval(0.0, 1.0, True, True)),
                "atol": _Number(default=1e-10, interval=POSITIVE),
                "max_step": _Number(default=0.0, interval=NON_NEGATIVE, unit="s"),
            }
        ),
        "static": _Table(
            {
                "load_steps": _Number(default=1, integer=True, interval=_Interval(lo=1)),
                # 2^-30 of a load increment: below that no increment is worth trying.
                "max_bisections": _Number(default=10, integer=True, interval=_Interval(0, 30)),
                "time": _Number(default=0.0, unit="s"),
            }
        ),
        "discretisation": _Table(
            {
                "elements": _Number(default=20, integer=True, interval=_Interval(lo=1)),
                "degree": _Number(default=2, integer=True, interval=_Interval(1, 5)),
                # Exact for polynomials of degree 100 (51 Gauss points a cell), ten times the
                # default 2 * degree of degree 5; FFCx itself warns beyond 100 points.
                "quadrature_degree": _Number(
                    default="auto", integer=True, interval=_Interval(1, MAX_QUADRATURE), auto=True
                ),
                "planar": _Choice(choices=("auto", "off"), default="auto"),
            }
        ),
        "solver": _Table(
            {
                "jacobian": _Choice(choices=("full", "lagged", "frozen"), default="frozen"),
                "lag": _Number(default=10, integer=True, interval=_Interval(lo=1)),
                "refresh_iterations": _Number(default=4, integer=True, interval=_Interval(lo=1)),
                "rtol": _Number(default=1e-10, interval=_Interval(0.0, 1.0, True, True)),
                "atol": _Number(default=1e-12, interval=POSITIVE),
                "stol": _Number(default=1e-8, interval=_Interval(0.0, 1.0, True, True)),
                "max_iterations": _Number(
                    default=25, integer=True, interval=_Interval(1, MAX_NEWTON_ITERATIONS)
                ),
                "linear_solver": _Choice(
                    choices=("auto", "petsc", "mumps", "superlu"), default="auto"
                ),
            }
        ),
        "output": _Table(
            {
                "directory": _Text(default="results", non_empty=True),
                "xdmf": _Flag(default=True),
                "xdmf_interval": _Number(default=0.0, interval=NON_NEGATIVE, unit="s"),
                "fields": _ChoiceList(choices=XDMF_FIELDS, default=XDMF_FIELDS),
                "checkpoint": _Flag(default=True),
                "checkpoint_interval": _Number(
                    default="auto", interval=NON_NEGATIVE, unit="s", auto=True
                ),
            }
        ),
        "limits": _Table(
            {
                "wall_time": _Number(default=Limits.wall_time, interval=POSITIVE, unit="s"),
                "memory": _Number(default="auto", interval=POSITIVE, unit="bytes", auto=True),
            }
        ),
    }
)


# ============================================================================ generic checking
def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _leaf_paths(table: _Table, prefix: str = "") -> list[str]:
    """All dotted keys of the schema (tables included)."""
    paths = []
    for name, spec in table.fields.items():
        key = _join(prefix, name)
        paths.append(key)
        if isinstance(spec, _Table):
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


def _check_table(key: str, data: Any, spec: _Table) -> dict[str, Any]:
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
    if isinstance(spec, _Parameters):
        return _check_parameters(key, data.get(name, {}))
    if isinstance(spec, _Table):
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
        out[name] = _Number().check(item, value)
    return out


# ================================================================================= overrides
def _lookup_spec(path: list[str]) -> Any:
    """The schema entry at a dotted path (``parameters.X`` accepted); SceneError if unknown."""
    spec: Any = SCHEMA
    for depth, name in enumerate(path):
        key = ".".join(path[: depth + 1])
        if isinstance(spec, _Parameters):
            if depth != len(path) - 1:
                raise SceneError(f"{key}: parameters are numbers, not tables")
            return _Number()
        if not isinstance(spec, _Table):
            raise SceneError(f"{key}: unknown key; {'.'.join(path[:depth])} is not a table")
        if name not in spec.fields:
            raise _unknown_key(key, list(spec.fields))
        spec = spec.fields[name]
    return spec


def _override_value(text: str) -> Any:
    """A TOML value if ``text`` parses as one, else the bare string."""
    try:
        document = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        return text
    return document["v"] if list(document) == ["v"] else text


Overrides = Sequence[str] | Mapping[str, Any]


def apply_overrides(data: dict[str, Any], overrides: Overrides) -> dict[str, Any]:
    """Return a copy of ``data`` with the overrides applied in order: ``dotted.key=value``
    strings (the command line's ``--set``; the value read as TOML), or a mapping of dotted
    keys to values (the Python API)."""
    result = _copy_tables(data)
    items = overrides.items() if isinstance(overrides, Mapping) else map(_split, overrides)
    for key, value in items:
        key = str(key).strip()
        path = [part.strip() for part in key.split(".")]
        spec = _lookup_spec(path)
        if isinstance(spec, _Table | _Parameters):
            raise SceneError(f"{key}: is a table; set one of its keys instead (--set {key}.X=...)")
        _set_path(result, path, value)
        if key in _EXCLUSIVE:
            other = _EXCLUSIVE[1 - _EXCLUSIVE.index(key)]
            _table_at(result, path[:-1]).pop(other.rpartition(".")[2], None)
    return result


def _split(text: str) -> tuple[str, Any]:
    """(key, value) of a ``dotted.key=value`` override."""
    raw_key, sep, raw_value = text.partition("=")
    if not sep or not raw_key.strip():
        raise SceneError(f"--set {text!r}: expected dotted.key=value")
    return raw_key.strip(), _override_value(raw_value.strip())


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


# ==================================================================================== building
def _build_section(raw: dict[str, Any], poisson_ratio: float) -> SectionSpec:
    shape = raw["shape"]
    keys = SECTION_KEYS[shape]
    for name, value in raw.items():
        if value is not None and name not in (*keys, "shape", "shear_coefficient"):
            raise SceneError(
                f"rod.section.{name}: not a key of shape {shape!r}, which takes "
                f"{', '.join(keys)} (and shear_coefficient)"
            )
    values = dict(raw)
    if shape == "rectangle" and values["torsion_constant"] is None:
        values["torsion_constant"] = "series"
    for name in keys:
        if values[name] is None:
            raise SceneError(f"rod.section.{name}: required for shape {shape!r} (a number > 0)")
    if shape == "tube" and not values["inner_diameter"] < values["outer_diameter"]:
        raise SceneError(
            f"rod.section.inner_diameter: must be < outer_diameter = "
            f"{_fmt(values['outer_diameter'])} [m], got {show_value(values['inner_diameter'])}"
        )
    if values["shear_coefficient"] == "auto":
        if shape == "constants":
            raise SceneError(
                'rod.section.shear_coefficient: required for shape "constants" (in (0, 1])'
            )
        ratio = values["inner_diameter"] / values["outer_diameter"] if shape == "tube" else 0.0
        values["shear_coefficient"] = (
            5.0 / 6.0 if shape == "rectangle" else cowper_circle(poisson_ratio, ratio)
        )
    return SectionSpec(**values)


def _build_rod(raw: dict[str, Any]) -> Rod:
    mat = raw["material"]
    nu, g = mat["poisson_ratio"], mat["shear_modulus"]
    if (nu is None) == (g is None):
        state = (
            f"both are given (poisson_ratio = {show_value(nu)}, shear_modulus = {show_value(g)})"
            if nu is not None
            else "neither is given"
        )
        raise SceneError(
            f"rod.material: exactly one of poisson_ratio (in (-1, 0.5)) and shear_modulus "
            f"(> 0, Pa) must be given, but {state}"
        )
    material = Material(mat["density"], mat["young_modulus"], nu, g)
    if not (math.isfinite(material.shear_modulus) and material.shear_modulus > 0.0):
        raise SceneError(
            f"rod.material: the shear modulus E/(2 (1 + nu)) = {material.shear_modulus:.3g} Pa "
            f"is not a positive finite number in double precision (young_modulus = "
            f"{show_value(material.young_modulus)})"
        )
    poisson = material.young_modulus / (2.0 * material.shear_modulus) - 1.0
    uses_poisson = raw["section"]["shape"] in ("circle", "tube")
    if uses_poisson and raw["section"]["shear_coefficient"] == "auto" and not -1.0 < poisson < 0.5:
        # Cowper's shear coefficient is a formula in nu for an isotropic section.
        raise SceneError(
            f"rod.material.shear_modulus: E/(2 G) - 1 = {poisson:.6g} is not a Poisson ratio "
            "in (-1, 0.5), which Cowper's shear coefficient of a circle or tube needs; give "
            "rod.section.shear_coefficient"
        )
    return Rod(raw["length"], _build_section(raw["section"], poisson), material)


def _build_model(raw: dict[str, Any]) -> ModelChoices:
    frequency = raw["reference_frequency"]
    return ModelChoices(
        reference_frequency=None if frequency == "auto" else frequency,
        torsion_inertia=raw["torsion_inertia"],
        end_load_sign=raw["end_load_sign"],
        end_load_scaling=raw["end_load_scaling"],
    )


def _build_supports(raw: dict[str, Any], constants: set[str]) -> Supports:
    kinds = (raw["start"], raw["end"])
    if "clamped" not in kinds and kinds != ("pinned", "pinned"):
        raise SceneError(
            'supports: one end must be "clamped", or both "pinned"; otherwise the rod has '
            "rigid-body motions (a free or pendulum mechanism) and the problem is singular, "
            f'got start = "{kinds[0]}", end = "{kinds[1]}"'
        )
    motions = {}
    for end, kind in zip(("start", "end"), kinds, strict=True):
        key = f"supports.{end}_motion"
        vector = parse_vector(raw[f"{end}_motion"], {"t", *constants}, key)
        motions[end] = None if all(e.is_zero for e in vector) else vector
        if motions[end] is not None and kind == "free":
            raise SceneError(
                f"{key}: a prescribed motion needs a held end (clamped or pinned), but "
                f'supports.{end} = "free"'
            )
    return Supports(raw["start"], raw["end"], motions["start"], motions["end"])


def _build_loads(raw: dict[str, Any], supports: Supports, constants: set[str]) -> Loads:
    names = {"s", "t", *constants}
    force = parse_vector(raw["force_density"], names, "loads.force_density")
    torque = parse_vector(raw["torque_density"], names, "loads.torque_density")
    ends = {}
    for end in ("start", "end"):
        ends[end] = _build_end_load(raw[end], end, getattr(supports, end), names)
    gravity = _constant_vector(raw["gravity"], constants, "loads.gravity")
    return Loads(force, torque, ends["start"], ends["end"], gravity)


def _constant_vector(raw: list, constants: set[str], key: str) -> tuple[float, float, float]:
    """Three numbers (expressions of the constants only)."""
    vector = parse_vector(raw, set(constants), key)
    return tuple(float(e.evaluate()) for e in vector)


def _build_initial(
    raw: dict[str, Any], supports: Supports, values: dict[str, float], t0: float
) -> Initial:
    """Initial fields of s [m]. Where a support holds the rod they must take its values at
    t0 (else the first step would jump to them): all of p and q at a clamped end, position,
    velocity, φ and its rate at a pinned one; zero, or the support's prescribed motion and its
    rate for x, y, z."""
    fields = {}
    for name in ("displacement", "angles", "velocity", "angle_rates"):
        vector = parse_vector(raw[name], {"s", *values}, f"initial.{name}")
        fields[name] = None if all(e.is_zero for e in vector) else vector
    length = values["L"]
    # What "equal" means for each field: 1e-12 of its value or of its scale (m, rad, m/s,
    # rad/s: the length, a radian, and their rates at omega0).
    scale = {"displacement": length, "angles": 1.0}
    scale.update(velocity=length * values["omega0"], angle_rates=values["omega0"])
    for end, s_end in (("start", 0.0), ("end", length)):
        kind = getattr(supports, end)
        if kind == "free":
            continue
        motion = supports.motion(end)
        held = {"displacement": (0, 1, 2), "velocity": (0, 1, 2)}
        held.update({"angles": (0, 1, 2), "angle_rates": (0, 1, 2)} if kind == "clamped" else {})
        held.update({"angles": (2,), "angle_rates": (2,)} if kind == "pinned" else {})
        for name, components in held.items():
            for i in components:
                want = 0.0
                if motion is not None and name in ("displacement", "velocity"):
                    e = motion[i] if name == "displacement" else derivative(motion[i], "t")
                    key = f"supports.{end}_motion[{i}]"
                    want = _finite_value(e, key, f"t = {_fmt(t0)} s", t=t0, **values)
                got = 0.0
                if fields[name] is not None:
                    key, where = f"initial.{name}[{i}]", f"s = {_fmt(s_end)} m"
                    got = _finite_value(fields[name][i], key, where, s=s_end, **values)
                if abs(got - want) > 1e-12 * max(abs(want), scale[name]):
                    source = show_value(fields[name][i].source) if fields[name] else "0"
                    what = "its prescribed motion" if motion is not None else "0"
                    raise SceneError(
                        f"initial.{name}[{i}]: must equal {what} ({want:.6g}) at the {kind} "
                        f"{end} (s = {_fmt(s_end)} m), got {got:.6g} from {source}"
                    )
    return Initial(**fields)


def _finite_value(e: Expression, key: str, where: str, **values: float) -> float:
    """The value of ``e`` at ``values``; SceneError naming ``key`` if it is not finite."""
    try:
        value = float(e.evaluate(**values))
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise SceneError(f"{key}: {show_value(e.source)} is not finite at {where}")
    return value


def _build_end_load(
    raw: dict[str, Any] | None, end: str, support: str, names: set[str]
) -> EndLoad | None:
    if raw is None:
        return None
    key = f"loads.{end}"
    if support == "clamped":
        raise SceneError(
            f"{key}: end loads are only allowed on a free or pinned end, "
            f'but supports.{end} = "{support}" (remove [{key}] or set supports.{end} = "free")'
        )
    vectors = {}
    for name in ("force", "torque"):
        vector = parse_vector(raw[name], names, f"{key}.{name}")
        for i, component in enumerate(vector):
            if component.depends_on("s"):
                raise SceneError(
                    f"{key}.{name}[{i}]: end loads may depend on t and constants only, "
                    f"not on the arc length s, got {show_value(component.source)}"
                )
        vectors[name] = vector
    if support == "pinned" and not all(e.is_zero for e in vectors["force"]):
        raise SceneError(
            f"{key}.force: a pinned end holds its position, so an end force there is taken by "
            "the support; give only an end torque (about e1, e2; the twist is held too)"
        )
    return EndLoad(vectors["force"], vectors["torque"])


def _integral_ratio(span: float, step: float) -> bool:
    """Whether span / step is a whole number (within STEP_TOLERANCE), and finite."""
    ratio = span / step
    return math.isfinite(ratio) and abs(ratio - round(ratio)) <= STEP_TOLERANCE * ratio


def _build_time(raw: dict[str, Any], fixed: frozenset[str] = frozenset()) -> Time:
    """The time span; ``fixed``: keys the caller may not change (a restart keeps time.step and
    time.start), so that a message does not suggest them."""
    start, end, step = raw["start"], raw["end"], raw["step"]
    if not end > start:
        raise SceneError(
            f"time.end: must be > time.start = {_fmt(start)} [s], got {show_value(end)}"
        )
    span = end - start
    if not math.isfinite(span / step):
        raise SceneError(
            f"time.end: (time.end - time.start) / time.step = {span / step:g} steps is out of "
            f"the range of double precision (time.start = {show_value(start)}, "
            f"time.end = {show_value(end)}, time.step = {show_value(step)})"
        )
    if step > span * (1.0 + STEP_TOLERANCE) and "time.step" not in fixed:
        raise SceneError(
            f"time.step: must be <= time.end - time.start = {span!r} [s], got {show_value(step)}"
        )
    if not _integral_ratio(span, step):
        below = start + max(1, math.floor(span / step)) * step
        above = start + math.ceil(span / step) * step
        ends = f"time.end = {below:.10g} or {above:.10g}"
        if "time.step" in fixed:
            raise SceneError(
                f"time.end: time.end - time.start must be a whole number of steps of "
                f"time.step = {step!r} s (fixed on a restart), got {span!r} s = "
                f"{span / step:.10g} steps (e.g. {ends})"
            )
        raise SceneError(
            f"time.step: (time.end - time.start) / time.step must be an integer (within "
            f"{STEP_TOLERANCE:g} relative), got {span!r} / {step!r} = {span / step!r} "
            f"(e.g. time.step = {span / math.ceil(span / step):.10g}, or {ends})"
        )
    return Time(
        start,
        end,
        step,
        raw["integrator"],
        raw["rho_inf"],
        raw["max_halvings"],
        raw["adaptive"],
        raw["rtol"],
        raw["atol"],
        raw["max_step"],
    )


def _build_discretisation(raw: dict[str, Any]) -> Discretisation:
    quadrature = raw["quadrature_degree"]
    if quadrature == "auto":
        quadrature = 2 * raw["degree"]
    return Discretisation(raw["elements"], raw["degree"], quadrature, raw["planar"])


def _build_output(raw: dict[str, Any], time: Time) -> Output:
    interval = raw["xdmf_interval"]
    # Checked only when fields are written: with xdmf = false the interval is unused.
    if (
        raw["xdmf"]
        and interval > 0.0
        and not (
            interval >= time.step * (1.0 - STEP_TOLERANCE) and _integral_ratio(interval, time.step)
        )
    ):
        raise SceneError(
            f"output.xdmf_interval: must be 0 (every step) or an integer multiple of "
            f"time.step = {time.step!r} [s], got {show_value(interval)}"
        )
    checkpoint_interval = raw["checkpoint_interval"]
    if checkpoint_interval == "auto":  # about ten checkpoints a run, on the step grid
        checkpoint_interval = max(1, round(time.n_steps / CHECKPOINTS_PER_RUN)) * time.step
    elif (
        raw["checkpoint"]
        and checkpoint_interval > 0.0
        and not (
            checkpoint_interval >= time.step * (1.0 - STEP_TOLERANCE)
            and _integral_ratio(checkpoint_interval, time.step)
        )
    ):
        raise SceneError(
            f"output.checkpoint_interval: must be 0 (at the end only), 'auto' or an integer "
            f"multiple of time.step = {time.step!r} [s], got {show_value(checkpoint_interval)}"
        )
    return Output(
        raw["directory"],
        raw["xdmf"],
        interval,
        raw["fields"],
        raw["checkpoint"],
        float(checkpoint_interval),
    )


def _build_limits(raw: dict[str, Any]) -> Limits:
    memory = raw["memory"]
    return Limits(raw["wall_time"], None if memory == "auto" else float(memory))


#: The groups of (48) that are positive for every valid rod (the others may be any sign).
_POSITIVE_GROUPS = frozenset(
    "g0 nu01 nu02 g1 g2 g3 nu11 nu13 nu14 nu21 nu23 nu24 nu31".split()
)


def _check_derived(scene: Scene) -> None:
    """The constants derived from valid inputs must be positive, finite numbers: a section of
    a = 1e-200 m has c22 = b a³/12 = 0 in double precision, one of 1e200 m an infinite c22,
    and the groups (48) combine every input. SceneError naming the keys they come from."""
    spec = scene.rod.section
    given = ", ".join(
        f"rod.section.{k} = {_fmt(v)}" for k, v in spec.given().items() if _is_number(v)
    )
    try:
        section = spec.constants()
    except (ArithmeticError, ValueError) as exc:
        raise SceneError(
            f"rod.section: the section constants cannot be computed from {given} "
            f"({_arithmetic(exc)})"
        ) from None
    constants = {"area": (section.area, "m^2")}
    constants.update({c: (getattr(section, c), "m^4") for c in ("c11", "c22", "c33")})
    for name, (value, unit) in constants.items():
        if not (math.isfinite(value) and value > 0.0):
            raise SceneError(
                f"rod.section: the derived {name} = {value:.3g} {unit} is not a positive finite "
                f"number in double precision (from {given})"
            )
    try:
        omega0 = scene.omega0
    except (ArithmeticError, ValueError):
        omega0 = math.nan
    if not (math.isfinite(omega0) and omega0 > 0.0):
        raise SceneError(
            "model.reference_frequency: omega0 = 1.875^2/L^2 sqrt(E c22/(rho A)) from rod.* is "
            f"not a positive finite number ({omega0:.3g} rad/s); give it explicitly"
        )
    try:
        bad = _bad_groups(dimensionless_groups(scene.rod_constants()))
    except (ArithmeticError, ValueError) as exc:
        bad = [_arithmetic(exc)]
    if bad:
        raise SceneError(
            f"rod: the dimensionless groups of (48) are not finite ({bad[0]}): rod.length, "
            "rod.section, rod.material and model.reference_frequency are out of the range of "
            "double precision together"
        )


def _arithmetic(exc: Exception) -> str:
    """What an arithmetic failure was, in words (OverflowError's text is an errno tuple)."""
    if isinstance(exc, OverflowError):
        return "overflow"
    if isinstance(exc, ZeroDivisionError):
        return "division by zero"
    return str(exc) or type(exc).__name__


def _bad_groups(groups: Groups) -> list[str]:
    bad = []
    for name, value in groups.as_dict().items():
        positive = name not in _POSITIVE_GROUPS or value > 0.0
        if not (math.isfinite(value) and positive):
            bad.append(f"{name} = {value:.3g}")
    return bad


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def scene_from_dict(
    data: dict[str, Any],
    source: str = "<dict>",
    overrides: Overrides = (),
    fixed: Sequence[str] = (),
) -> Scene:
    """Validate a scene given as nested dicts (as from TOML) and resolve it.

    ``overrides`` (``dotted.key=value``) are applied first; ``fixed``: keys the caller may
    not change (a restart's), which messages then do not suggest. Raises :class:`SceneError`.
    """
    if not isinstance(data, dict):
        raise SceneError(f"{source}: a scene must be a table of keys, got {show_value(data)}")
    raw = _check_table("", apply_overrides(data, overrides), SCHEMA)
    parameters = raw["parameters"]
    rod = _build_rod(raw["rod"])
    supports = _build_supports(raw["supports"], {*SCENE_CONSTANTS, *parameters})
    loads = _build_loads(raw["loads"], supports, {*SCENE_CONSTANTS, *parameters})
    time = _build_time(raw["time"], frozenset(fixed))
    scene = Scene(
        title=raw["title"],
        parameters=parameters,
        rod=rod,
        model=_build_model(raw["model"]),
        supports=supports,
        loads=loads,
        time=time,
        discretisation=_build_discretisation(raw["discretisation"]),
        solver=Solver(**raw["solver"]),
        output=_build_output(raw["output"], time),
        static=StaticSettings(**raw["static"]),
        damping=Damping(**raw["damping"]),
        limits=_build_limits(raw["limits"]),
        source=source,
    )
    _check_derived(scene)
    initial = _build_initial(raw["initial"], supports, scene.expression_names(), time.start)
    return replace(scene, initial=initial)


def read_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file; every failure (missing, unreadable, malformed) is a SceneError."""
    try:
        with open(path, "rb") as stream:
            return tomllib.load(stream)
    except FileNotFoundError:
        raise SceneError(f"{path}: scene file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: malformed TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise SceneError(f"{path}: cannot read scene file ({exc.strerror})") from None


def load_scene(path: str | Path, overrides: Overrides = ()) -> Scene:
    """Read, override and validate a TOML scene file."""
    return scene_from_dict(read_toml(path), source=str(path), overrides=overrides)


# =================================================================================== to_dict
def _vector(values: tuple[Expression, ...]) -> list[str]:
    return [e.source for e in values]


def _end_load_dict(load: EndLoad) -> dict[str, Any]:
    return {"force": _vector(load.force), "torque": _vector(load.torque)}


def _material_dict(material: Material) -> dict[str, Any]:
    out: dict[str, Any] = {"density": material.density, "young_modulus": material.young_modulus}
    if material.poisson_ratio is not None:
        out["poisson_ratio"] = material.poisson_ratio
    else:
        out["shear_modulus"] = material.shear_modulus_value
    return out


def _loads_dict(loads: Loads) -> dict[str, Any]:
    out: dict[str, Any] = {
        "force_density": _vector(loads.force_density),
        "torque_density": _vector(loads.torque_density),
    }
    for end in ("start", "end"):
        load = getattr(loads, end)
        if load is not None:
            out[end] = _end_load_dict(load)
    out["gravity"] = list(loads.gravity)
    return out


def _fields(obj: Any) -> dict[str, Any]:
    return dict(vars(obj))


def _scene_to_dict(scene: Scene) -> dict[str, Any]:
    model = _fields(scene.model)
    if model["reference_frequency"] is None:
        model["reference_frequency"] = "auto"
    return {
        "title": scene.title,
        "parameters": dict(scene.parameters),
        "rod": {
            "length": scene.rod.length,
            "section": scene.rod.section.given(),
            "material": _material_dict(scene.rod.material),
        },
        "model": model,
        "supports": {
            "start": scene.supports.start,
            "end": scene.supports.end,
            **{
                f"{end}_motion": _vector(scene.supports.motion(end))
                for end in ("start", "end")
                if scene.supports.motion(end) is not None
            },
        },
        "loads": _loads_dict(scene.loads),
        "time": _fields(scene.time),
        "discretisation": _fields(scene.discretisation),
        "solver": _fields(scene.solver),
        "output": {**_fields(scene.output), "fields": list(scene.output.fields)},
        "static": _fields(scene.static),
        "damping": _fields(scene.damping),
        "initial": {k: _vector(v) for k, v in vars(scene.initial).items() if v is not None},
        "limits": {
            "wall_time": scene.limits.wall_time,
            "memory": "auto" if scene.limits.memory is None else scene.limits.memory,
        },
    }
