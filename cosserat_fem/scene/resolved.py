"""The resolved scene: a scene validated, with its defaults filled in, expressions parsed and
derived choices made ("auto" resolved), in SI units. Built by cosserat_fem/scene/build.py from data
the schema (cosserat_fem/scene/schema.py) has checked; :meth:`Scene.to_dict` gives the data back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from cosserat_fem.common.errors import SceneError, show_value
from cosserat_fem.forms.conventions import END_LOAD_SCALINGS, END_LOAD_SIGNS, TORSION_INERTIAS
from cosserat_fem.forms.general_form import STRAIN_COMPONENTS, retardation_times
from cosserat_fem.forms.groups import RodConstants, euler_bernoulli_omega0
from cosserat_fem.forms.section import (
    TORSION_CONSTANT_RULES,
    Section,
    SectionLaw,
    rectangle,
    tube,
)
from cosserat_fem.io.probes import PROBE_FIELD_COLUMNS
from cosserat_fem.scene.expressions import Expression, derivative
from cosserat_fem.scene.keys import (
    CONTACT_OBSTACLES,
    DEFAULT_WALL_TIME,
    HELD_BY_SUPPORT,
    MAX_NEWTON_ITERATIONS,
    MAX_QUADRATURE,
    NON_NEGATIVE,
    POSITIVE,
    REFERENCE_KEYS,
    SECTION_KEYS,
    STRUCTURE_JOINTS,
    STRUCTURE_SUPPORTS,
    SUPPORTS,
    XDMF_DEFAULT_FIELDS,
    XDMF_FIELDS,
    ZERO3,
    Choice,
    ChoiceList,
    Field,
    Flag,
    Interval,
    LoadVector,
    Names,
    Number,
    NumberOrExpression,
    NumberOrExpressionVector,
    NumberOrTimeExpression,
    NumberVector,
    Parameters,
    PetscOptions,
    Points,
    PositionExpression,
    SymmetricMatrix,
    Table,
    Tables,
    Text,
    Vector,
    declared_names,
    key,
    table,
    to_table,
)


@dataclass(frozen=True, kw_only=True)
class SectionSpec:
    """Cross-section, SI units, by ``shape`` (the keys of :data:`SECTION_KEYS`):

    * rectangle: ``a`` along d1 (thickness), ``b`` along d2 (width) [m], c33 by the
      ``torsion_constant`` rule (the Saint-Venant series, or the paper's approximation);
    * circle: ``diameter`` [m]; tube: ``outer_diameter``, ``inner_diameter`` [m];
    * constants: ``area`` [m²], ``c11``, ``c22``, ``c33`` [m⁴] given explicitly.

    ``shear_coefficient`` κ is resolved: given, or 5/6 (rectangle) or Cowper's value for ν
    (circle, tube); "constants" needs it given.

    ``stiffness`` (any shape, optional): a general section law (docs/sections.md), the 6×6
    symmetric positive definite K in the order (shear 1, shear 2, extension, bending 1,
    bending 2, torsion) [N, N m, N m²], BeamDyn's: n = K₁ Γ + K₁₂ κ, m = K₂₁ Γ + K₂ κ in the
    directors. It replaces the shape's diagonal law (13); the shape still gives the mass
    ρ A, the rotary inertias (unless rod.rotary_inertia) and the scaling (47) (ω0 "auto").
    """

    shape: str = key(Choice(choices=tuple(SECTION_KEYS), default="rectangle"))
    a: float | None = key(Number(interval=POSITIVE, unit="m"), default=None)
    b: float | None = key(Number(interval=POSITIVE, unit="m"), default=None)
    torsion_constant: str | None = key(Choice(choices=TORSION_CONSTANT_RULES), default=None)
    diameter: float | None = key(Number(interval=POSITIVE, unit="m"), default=None)
    outer_diameter: float | None = key(Number(interval=POSITIVE, unit="m"), default=None)
    inner_diameter: float | None = key(Number(interval=NON_NEGATIVE, unit="m"), default=None)
    area: float | None = key(Number(interval=POSITIVE, unit="m^2"), default=None)
    c11: float | None = key(Number(interval=POSITIVE, unit="m^4"), default=None)
    c22: float | None = key(Number(interval=POSITIVE, unit="m^4"), default=None)
    c33: float | None = key(Number(interval=POSITIVE, unit="m^4"), default=None)
    #: κ: given, or "auto" resolved by the shape (class docstring).
    shear_coefficient: float = key(
        Number(default="auto", interval=Interval(0.0, 1.0, lo_open=True), auto=True)
    )
    #: K [N | N m | N m²], the general section law (class docstring), or None: (13).
    stiffness: tuple[tuple[Any, ...], ...] | None = key(
        SymmetricMatrix(unit="N, N m, N m^2"), default=None
    )
    #: μ [kg/m] with ``stiffness``: a number or an expression of s; None: ρ A of the shape.
    mass_per_length: Any = key(NumberOrExpression(unit="kg/m"), default=None)
    #: (I11, I22, I33) [kg m] with ``stiffness``: numbers or expressions of s; None: the
    #: shape's (or rod.rotary_inertia).
    inertia: tuple[Any, Any, Any] | None = key(NumberOrExpressionVector(unit="kg m"), default=None)

    def law(self) -> SectionLaw | None:
        """The general section law of ``stiffness``, ``mass_per_length`` and ``inertia``
        (entries floats or Expressions of s, made UFL by cosserat_fem/rod/model.py), or
        None."""
        if self.stiffness is None:
            return None
        return SectionLaw(self.stiffness, self.mass_per_length, self.inertia)

    def expressions(self) -> list[tuple[str, Any]]:
        """(key, Expression) of every entry of the law given as an expression of s."""
        entries: list[tuple[str, Any]] = []
        if self.stiffness is not None:
            entries += [
                (f"rod.section.stiffness[{i}][{j}]", x)
                for i, row in enumerate(self.stiffness)
                for j, x in enumerate(row)
            ]
        entries.append(("rod.section.mass_per_length", self.mass_per_length))
        if self.inertia is not None:
            entries += [(f"rod.section.inertia[{i}]", x) for i, x in enumerate(self.inertia)]
        return [(k, x) for k, x in entries if x is not None and not isinstance(x, float)]

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


@dataclass(frozen=True, kw_only=True)
class ReferenceShape:
    """The rod at rest ([reference]; forms/reference.py holds the same shapes in UFL):

    * ``straight``: r0 = (0, 0, s), d0_i = e_i (the paper's);
    * ``arc`` of ``radius`` R [m]: r0 = (R (1 − cos(s/R)), 0, R sin(s/R)), d0_3 = r0',
      d0_2 = e2 (bent about d0_2, towards +e1);
    * ``helix`` of coil ``radius`` R [m] and ``pitch_angle`` α [rad]: r0 = (R (cos ks − 1),
      R sin ks, s sin α), k = cos α / R (axis x = −R, y = 0 along e3), in its Frenet frame
      (d0_1 the principal normal, d0_2 the binormal, d0_3 = r0');
    * ``polyline`` through ``points`` [m] (the first is the rod's start), straight segments
      whose frame jumps at the corners: d0_3 along the segment, d0_2 the unit ``binormal``
      (normal to every segment), d0_1 = d0_2 × d0_3;
    * ``curve``: r0 = ``position`` and d0_1 = ``director``, expressions of the arc length s [m]
      (and ``constants``: L and the scene's parameters): d0_3 = r0' (|r0'| = 1, s is the arc
      length), d0_1 ⊥ d0_3 a unit vector, d0_2 = d0_3 × d0_1 (checked by the scene).

    s is the arc length [m]; :meth:`positions` and :meth:`frames` evaluate them in NumPy (at a
    corner, the frame of the segment after it). ``closed``: the rod's two ends are joined, a
    ring (r0 and D0 the same at s = 0 and s = ℓ; its unknowns p(0) = p(ℓ):
    cosserat_fem/analysis/modal.py).
    """

    shape: str = key(Choice(choices=tuple(REFERENCE_KEYS), default="straight"), default="straight")
    radius: float | None = key(Number(interval=POSITIVE, unit="m"), default=None)
    pitch_angle: float | None = key(
        Number(
            interval=Interval(-math.pi / 2, math.pi / 2, lo_open=True, hi_open=True), unit="rad"
        ),
        default=None,
    )
    #: polyline: its corners (the first the start), and d0_2 on every segment
    points: tuple[tuple[float, float, float], ...] | None = key(Points(unit="m"), default=None)
    binormal: tuple[float, float, float] | None = key(Vector(unit="-"), default=None)
    #: curve: r0(s) and d0_1(s), expressions of the arc length s [m]
    position: tuple[Expression, Expression, Expression] | None = key(Vector(unit="m"), default=None)
    director: tuple[Expression, Expression, Expression] | None = key(Vector(unit="-"), default=None)
    #: the two ends joined (a ring): the curve must close; modes only, for now
    closed: bool = key(Flag(default=False), default=False)
    #: The values of the names a curve's expressions may use besides s (L, parameters).
    constants: dict[str, float] | None = field(default=None, compare=False)

    def curve_values(self, vector, s: np.ndarray, order: int = 0) -> np.ndarray:
        """A curve's expressions (or their ``order``-th derivative in s) at s, (len(s), 3)."""
        values = []
        for e in vector:
            for _ in range(order):
                e = derivative(e, "s")
            value = e.evaluate(s=s, **(self.constants or {}))
            values.append(np.broadcast_to(np.asarray(value, dtype=float), s.shape))
        return np.column_stack(values)

    def corners(self) -> np.ndarray:
        """The arc lengths [m] at which a polyline's segments start, and its length: (k + 1,)."""
        steps = np.linalg.norm(np.diff(np.asarray(self.points, dtype=float), axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(steps)])

    def segment_frames(self) -> np.ndarray:
        """A polyline's frame on each segment, (segments, 3, 3), rows d0_1, d0_2, d0_3."""
        pts = np.asarray(self.points, dtype=float)
        t = np.diff(pts, axis=0)
        t /= np.linalg.norm(t, axis=1)[:, None]
        b = np.asarray(self.binormal, dtype=float)
        b = np.broadcast_to(b / np.linalg.norm(b), t.shape)
        return np.stack([np.cross(b, t), b, t], axis=1)

    @property
    def curved(self) -> bool:
        """Whether the rod is not the paper's straight one."""
        return self.shape != "straight"

    def positions(self, s: np.ndarray) -> np.ndarray:
        """r0(s) [m], (len(s), 3)."""
        s = np.asarray(s, dtype=float)
        if self.shape == "arc":
            assert self.radius is not None, "an arc requires it (scene/keys.py)"
            a = s / self.radius
            return np.column_stack([self.radius * (1 - np.cos(a)), 0 * s, self.radius * np.sin(a)])
        if self.shape == "helix":
            assert self.radius is not None and self.pitch_angle is not None, "a helix requires them"
            k, R = math.cos(self.pitch_angle) / self.radius, self.radius
            return np.column_stack(
                [R * (np.cos(k * s) - 1), R * np.sin(k * s), s * math.sin(self.pitch_angle)]
            )
        if self.shape == "polyline":
            pts = np.asarray(self.points, dtype=float)
            return np.column_stack([np.interp(s, self.corners(), pts[:, i]) for i in range(3)])
        if self.shape == "curve":
            return self.curve_values(self.position, s)
        return np.column_stack([0 * s, 0 * s, s])

    def frames(self, s: np.ndarray) -> np.ndarray:
        """D0(s), (len(s), 3, 3), row i the reference director d0_i in the fixed basis."""
        s = np.asarray(s, dtype=float)
        D0 = np.zeros((s.size, 3, 3))
        if self.shape == "arc":
            assert self.radius is not None, "an arc requires it (scene/keys.py)"
            c, n = np.cos(s / self.radius), np.sin(s / self.radius)
            D0[:, 0, 0], D0[:, 0, 2], D0[:, 1, 1], D0[:, 2, 0], D0[:, 2, 2] = c, -n, 1, n, c
        elif self.shape == "helix":
            assert self.radius is not None and self.pitch_angle is not None, "a helix requires them"
            ca, sa = math.cos(self.pitch_angle), math.sin(self.pitch_angle)
            c, n = np.cos(ca / self.radius * s), np.sin(ca / self.radius * s)
            D0[:, 0] = np.column_stack([-c, -n, 0 * s])
            D0[:, 1] = np.column_stack([n * sa, -c * sa, ca + 0 * s])
            D0[:, 2] = np.column_stack([-n * ca, c * ca, sa + 0 * s])
        elif self.shape == "polyline":
            starts = self.corners()[1:-1]
            D0[:] = self.segment_frames()[np.searchsorted(starts, s, side="right")]
        elif self.shape == "curve":
            t, d1 = self.curve_values(self.position, s, 1), self.curve_values(self.director, s)
            D0[:, 0], D0[:, 1], D0[:, 2] = d1, np.cross(t, d1), t
        else:
            D0[:] = np.eye(3)
        return D0

    def turning(self, length: float) -> float:
        """The total turning of the tangent over [0, ``length``] [rad]: ∫ |r0''| ds."""
        if self.shape == "arc":
            assert self.radius is not None, "an arc requires it (scene/keys.py)"
            return length / self.radius
        if self.shape == "helix":
            assert self.radius is not None and self.pitch_angle is not None, "a helix requires them"
            return length * math.cos(self.pitch_angle) ** 2 / self.radius
        if self.shape == "polyline":
            t = self.segment_frames()[:, 2]
            return float(np.arccos(np.clip((t[1:] * t[:-1]).sum(axis=1), -1.0, 1.0)).sum())
        if self.shape == "curve":  # the trapezoidal rule on 4096 intervals
            s = np.linspace(0.0, length, 4097)
            bending = np.linalg.norm(self.curve_values(self.position, s, 2), axis=1)
            return float(np.sum(0.5 * (bending[1:] + bending[:-1]) * np.diff(s)))
        return 0.0


@dataclass(frozen=True, kw_only=True)
class Material:
    """Linear elastic material; exactly one of ``poisson_ratio`` / ``shear_modulus_value``."""

    density: float = key(Number(required=True, interval=POSITIVE, unit="kg/m^3"))
    young_modulus: float = key(Number(required=True, interval=POSITIVE, unit="Pa"))
    poisson_ratio: float | None = key(
        Number(interval=Interval(-1.0, 0.5, lo_open=True, hi_open=True))
    )
    shear_modulus_value: float | None = key(
        Number(interval=POSITIVE, unit="Pa"), name="shear_modulus"
    )

    @property
    def shear_modulus(self) -> float:
        """G [Pa]: as given, or E / (2 (1 + ν))."""
        if self.shear_modulus_value is not None:
            return self.shear_modulus_value
        if self.poisson_ratio is None:
            raise ValueError("Material: give poisson_ratio or shear_modulus_value")
        return self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True, kw_only=True)
class Rod:
    """Straight rod of length ``length`` [m]; ``rotary_inertia`` (I11, I22, I33) [kg m] per
    unit length, or None: those of the section, (46)."""

    length: float = key(Number(required=True, interval=POSITIVE, unit="m"))
    section: SectionSpec = table(SectionSpec)
    #: [I11, I22, I33] per unit length [kg m], the rotary inertias of (46) given apart from
    #: the section (absent: ρ c11, ρ c22, ρ (c11 + c22))
    rotary_inertia: tuple[float, float, float] | None = key(Vector(unit="kg m"), default=None)
    material: Material = table(Material)


@dataclass(frozen=True, kw_only=True)
class ModelChoices:
    """Modelling choices; ``reference_frequency`` [rad/s] is None for "auto"."""

    reference_frequency: float | None = key(
        Number(default="auto", interval=POSITIVE, unit="rad/s", auto=True)
    )
    torsion_inertia: str = key(Choice(choices=TORSION_INERTIAS, default="polar"))
    end_load_sign: str = key(Choice(choices=tuple(END_LOAD_SIGNS), default="balance"))
    end_load_scaling: str = key(Choice(choices=END_LOAD_SCALINGS, default="balance"))


@dataclass(frozen=True, kw_only=True)
class Supports:
    """Support of each end: "clamped" (p = q = 0), "free" (natural conditions), "pinned": a
    fork bearing, the position and the twist φ held, the bending angles θ, ψ free (the end
    torque about d1, d2 is the given end torque, zero by default), or "spherical": a ball
    joint, the position held, every rotation free. Two leave the axial position z free (the
    straight rod's rest tangent e3 at its ends), to load a column axially with both ends held:
    "roller", a fork on a roller (x, y and φ held; z, θ, ψ free), and "sliding", a clamp on a
    slide (x, y and the three angles held; z free). Their end load may act along e3 only (the
    free direction; a roller also takes a torque about e1, e2). Both need a straight rod (a
    rod curved at rest, or closed, refuses them by name).

    ``start_axis``/``end_axis``: the axis of a pinned end made a hinge (the position held,
    the rotation free about this axis only), along e1, e2 or e3 (the angles θ, ψ, φ are the
    rotations about these at rest, forms/kinematics.py, and a hinge about e_k holds the other
    two exactly: the rotation is then D_k(angle)ᵀ, about e_k alone; a slanted axis is not one
    of them and is refused; about e1 it turns by θ, so less than a quarter turn, the chart's
    limit, docs/decisions.md). None: a fork on a straight rod; on a rod curved at rest the scene
    sets the end's reference binormal d0_2 (the axis the rod bends about in its plane: e2 for
    an arc, the binormal of a polyline), refused by name if that is not along e1, e2 or e3
    (scene/build.py). ``chord``: r0(ℓ) − r0(0) [m] at rest (set by the scene; the rigid-body
    modes depend on it).

    ``start_motion``/``end_motion``: a prescribed translation (x, y, z)(t) [m] of a held end
    (base excitation; None: at rest).
    """

    start: str = key(Choice(choices=SUPPORTS, default="clamped"))
    end: str = key(Choice(choices=SUPPORTS, default="free"))
    start_motion: tuple[Expression, ...] | None = key(
        LoadVector(default=ZERO3, unit="m"), default=None
    )
    end_motion: tuple[Expression, ...] | None = key(
        LoadVector(default=ZERO3, unit="m"), default=None
    )
    start_axis: tuple[float, float, float] | None = key(Vector(unit="-"), default=None)
    end_axis: tuple[float, float, float] | None = key(Vector(unit="-"), default=None)
    chord: tuple[float, float, float] = field(default=(0.0, 0.0, 1.0), compare=False)

    def held(self, end: str) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The components of the position (x, y, z) and of the angles (θ, ψ, φ) the support
        at ``end`` holds: :data:`~cosserat_fem.scene.keys.HELD_BY_SUPPORT`, but a hinge about
        e_k (``<end>_axis``) holds the two angles other than the k-th."""
        position, angles = HELD_BY_SUPPORT[getattr(self, end)]
        axis = getattr(self, f"{end}_axis")
        if axis is not None:
            k = int(np.argmax(np.abs(axis)))
            angles = tuple(i for i in range(3) if i != k)
        return position, angles

    def held_components(self, end: str) -> tuple[int, ...]:
        """The components of U = (p, q) the support at ``end`` holds: the held ones of p
        (x, y, z, θ, ψ, φ) and their rates, 6 later."""
        position, angles = self.held(end)
        p = (*position, *(3 + a for a in angles))
        return (*p, *(6 + i for i in p))

    def rigid_body_modes(self) -> int:
        """How many rigid-body motions the supports leave: 6 less the rank of the held
        components of a small rigid motion (translation t, rotation ω about the start) at the
        ends, at rest: position component i at r is t_i + (ω × r)_i, angle a is ω_a (the
        angles' linearisation at rest: rotations about e1, e2, e3); the end at ``chord``.
        A free rod 6, a fork 2 (the rotations about it), a ball joint 3, two ball joints 1
        (the turn about the chord), a roller 3, a sliding end or two rollers 1 (along e3)."""
        chord = np.asarray(self.chord, dtype=float)
        chord = chord / max(float(np.linalg.norm(chord)), 1e-300)  # the rank is scale-free
        ends = (("start", np.zeros(3)), ("end", chord))
        return rigid_body_modes([(r, *self.held(end)) for end, r in ends])

    @property
    def mechanism(self) -> bool:
        """Whether the supports leave the rod a rigid-body motion (a pendulum, a free, a
        spinning or a sliding rod): :meth:`rigid_body_modes` > 0."""
        return self.rigid_body_modes() > 0

    def motion(self, end: str) -> tuple[Expression, ...] | None:
        return self.start_motion if end == "start" else self.end_motion


def rigid_body_modes(held: list[tuple[np.ndarray, tuple[int, ...], tuple[int, ...]]]) -> int:
    """How many rigid-body motions supports leave: 6 less the rank of the components they
    hold of a small rigid motion (translation t, rotation ω about the origin) at rest,
    ``held`` [(point r, position components, angle components)]: position component i at r
    is t_i + (ω × r)_i, angle a is ω_a (the angles' linearisation at rest: rotations about
    e1, e2, e3)."""
    rows = [row for r, position, angles in held for row in _held_rows(r, position, angles)]
    return 6 - (int(np.linalg.matrix_rank(np.array(rows))) if rows else 0)


def _held_rows(r: np.ndarray, position, angles) -> list[np.ndarray]:
    """The rows (over t, ω) of the position components ``position`` at r, t_i + (ω × r)_i,
    and of the angle components ``angles``, ω_a, of a small rigid motion (rigid_body_modes)."""
    rows = []
    for i in position:
        e = np.eye(3)[i]
        rows.append(np.concatenate([e, np.cross(r, e)]))  # (ω × r)·e = ω·(r × e)
    rows += [np.concatenate([np.zeros(3), np.eye(3)[a]]) for a in angles]
    return rows


@dataclass(frozen=True, kw_only=True)
class EndLoad:
    """Force [N] and torque [N m] on a free end, fixed directions e1, e2, e3; functions of t."""

    force: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N"))
    torque: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N m"))


@dataclass(frozen=True, kw_only=True)
class PointLoad:
    """Force [N] and torque [N m] at the node at arc length ``s`` [m] inside the rod, fixed
    directions e1, e2, e3; functions of t."""

    s: float = key(Number(required=True, interval=POSITIVE, unit="m"))
    force: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N"))
    torque: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N m"))


class FormLoad:
    """A load declared with its physics, so that a new kind of load is its declaration here, its
    form in forms/ and its test. A subclass is a frozen, kw_only dataclass whose fields declare
    its keys (:func:`~cosserat_fem.scene.keys.key`; its load vectors as
    :class:`~cosserat_fem.scene.keys.LoadVector`), made a field of :class:`Loads` with
    :func:`~cosserat_fem.scene.keys.table`; ``physics`` names its module in forms/, whose
    ``residual(load, context)`` gives its term of the weak form (the scene's
    ``model.RodModel.residual_terms`` adds it, under the load's key; the Jacobian is UFL's
    derivative of the form). The scene reader parses its load vectors (functions of t and the
    constants), calls :meth:`check`, and the scene's other parts (``load_components``, the
    plane) read it through :meth:`vectors` and :meth:`in_plane`; ``to_dict`` writes its
    declared keys as it writes any table's (:func:`~cosserat_fem.scene.keys.to_table`)."""

    physics: ClassVar[str]

    def vectors(self) -> dict[str, tuple[Expression, ...]]:
        """Its load vectors, by key."""
        return {
            name: getattr(self, f)
            for name, f in declared_names(type(self)).items()
            if isinstance(_spec(type(self), f), LoadVector)
        }

    def check(self, key: str, supports: Supports) -> None:
        """SceneError naming ``key`` (its dotted table) if the scene cannot carry it."""

    def in_plane(self, normal: tuple[int, ...], torques: tuple[int, ...]) -> bool:
        """Whether it keeps a motion in a plane (:data:`PLANES`: the force has no component
        along ``normal``, the torque none about ``torques``); by default it does not."""
        return False


def _spec(cls: type, name: str) -> Any:
    """The key spec the field ``name`` of ``cls`` declares."""
    return Table.of(cls).fields[{f: k for k, f in declared_names(cls).items()}[name]]


@dataclass(frozen=True, kw_only=True)
class FollowerEndLoad(FormLoad):
    """[loads.follower]: a force [N] and torque [N m] on the free ``end`` ("start" or "end")
    that turn with its directors: components along d1, d2, d3 of that end, functions of t
    (forms/follower.py)."""

    physics: ClassVar[str] = "follower"

    end: str = key(Choice(choices=("start", "end"), default="end"))
    force: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N"))
    torque: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N m"))

    def check(self, key: str, supports: Supports) -> None:
        """Only a free end carries it (a held end's support takes what it turns with)."""
        if getattr(supports, self.end) != "free":
            raise SceneError(
                f"{key}.end: a follower load needs a free end, but supports."
                f'{self.end} = "{getattr(supports, self.end)}"'
            )

    def in_plane(self, normal: tuple[int, ...], torques: tuple[int, ...]) -> bool:
        """In a plane of motion of the straight rod d2 = e2 (x-z) or d1 = e1 (y-z) and the other
        two directors stay in it: the director components leave it as the fixed ones do."""
        return all(self.force[i].is_zero for i in normal) and all(
            self.torque[i].is_zero for i in torques
        )


@dataclass(frozen=True, kw_only=True)
class SemitangentialEndTorque(FormLoad):
    """[loads.semitangential]: a conservative torque [N m] on ``end`` ("start" or "end") that
    turns by half the end's rotation (Ziegler's semitangential torque, forms/semitangential.py):
    ``torque`` its components at rest in the fixed basis e1, e2, e3, functions of t."""

    physics: ClassVar[str] = "semitangential"

    end: str = key(Choice(choices=("start", "end"), default="end"))
    torque: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N m"))

    def check(self, key: str, supports: Supports) -> None:
        """An end whose rotations are free takes it (free, spherical); one that holds φ
        (pinned, roller) only about e1, e2, as its dead torque; a clamp holds all three."""
        support = getattr(supports, self.end)
        if support not in ("free", "spherical", "pinned", "roller"):
            raise SceneError(
                f"{key}.end: a semitangential torque needs an end free to turn (free, "
                f'spherical, pinned or roller), but supports.{self.end} = "{support}"'
            )
        if support in ("pinned", "roller") and not self.torque[2].is_zero:
            raise SceneError(
                f"{key}.torque[2]: a {support} end holds its twist φ, so a torque about e3 "
                "there is taken by the support; give the torque about e1, e2 only"
            )

    def in_plane(self, normal: tuple[int, ...], torques: tuple[int, ...]) -> bool:
        """In a plane of motion (x-z: about e2 only; y-z: about e1 only) a torque normal to
        the plane stays normal to it (the rotation is about that normal)."""
        return all(self.torque[i].is_zero for i in torques)


@dataclass(frozen=True, kw_only=True)
class BodyData:
    """A rigid body (forms/rigid_body.py): ``mass`` m [kg]; its inertia tensor about its
    centre of mass [kg m²], principal-axis entries ``inertia`` (J11, J22, J33) and
    ``products`` (J23, J13, J12), and its centre's ``offset`` c [m] from the point it is
    fixed to, in the components of a frame at rest that its subclass names. Numbers."""

    mass: float = key(Number(interval=POSITIVE, unit="kg", required=True))
    inertia: tuple[float, ...] = key(NumberVector(default=ZERO3, unit="kg m^2"))
    products: tuple[float, ...] = key(NumberVector(default=ZERO3, unit="kg m^2"))
    offset: tuple[float, ...] = key(NumberVector(default=ZERO3, unit="m"))

    def inertia_tensor(self) -> list[list[float]]:
        """J_C [kg m²], rows in the frame at rest (class docstring)."""
        (j1, j2, j3), (j23, j13, j12) = self.inertia, self.products
        return [[j1, j12, j13], [j12, j2, j23], [j13, j23, j3]]

    def offset_vector(self) -> list[float]:
        """c [m], in the frame at rest (class docstring)."""
        return list(self.offset)

    def check_body(self, key: str) -> None:
        """An inertia tensor of a body (its entries are numbers: NumberVector): zero (a point
        mass) or positive definite with its principal moments obeying the triangle
        inequalities (J_i ≤ J_j + J_k: J = ∫ (|x|² I − x xᵀ) dm). SceneError naming ``key``."""
        J = np.array(self.inertia_tensor(), dtype=float)
        if not J.any():
            return
        moments = np.linalg.eigvalsh(J)
        scale = float(np.abs(moments).max())
        if moments[0] <= 1e-12 * scale:
            raise SceneError(
                f"{key}.inertia: not positive definite with the products (smallest principal "
                f"moment {moments[0]:.3g} kg m^2)"
            )
        if moments[2] > moments[0] + moments[1] + 1e-12 * scale:
            raise SceneError(
                f"{key}.inertia: not a rigid body's: the principal moments "
                f"{', '.join(f'{m:.3g}' for m in moments)} kg m^2 break J3 <= J1 + J2"
            )


@dataclass(frozen=True, kw_only=True)
class RigidBody(FormLoad, BodyData):
    """[loads.body]: a rigid body fixed to the ``end`` ("start" or "end") of the rod, whose
    weight (with [loads] gravity) and inertia act on it (forms/rigid_body.py); its inertia
    and offset (:class:`BodyData`) in the components of the end's directors at rest (d0_i;
    e_i for the straight rod)."""

    physics: ClassVar[str] = "rigid_body"

    end: str = key(Choice(choices=("start", "end"), default="end"))

    def check(self, key: str, supports: Supports) -> None:
        """:meth:`BodyData.check_body`."""
        self.check_body(key)

    def in_plane(self, normal: tuple[int, ...], torques: tuple[int, ...]) -> bool:
        """In a plane of motion the body keeps it if its centre lies in the plane (no offset
        along the normal) and its rotation about the plane's normal is a principal one (no
        product of inertia with that axis)."""
        (k,) = [i for i in range(3) if i not in torques]
        J = self.inertia_tensor()
        return all(self.offset[n] == 0 for n in normal) and all(
            J[k][i] == 0 for i in range(3) if i != k
        )


@dataclass(frozen=True, kw_only=True)
class Loads:
    """Distributed force [N/m] and torque [N m/m] (functions of s, t), end loads and a point
    load."""

    force_density: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N/m"))
    torque_density: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N m/m"))
    start: EndLoad | None = table(EndLoad, optional=True)
    end: EndLoad | None = table(EndLoad, optional=True)
    #: a force [N] and torque [N m] at the node s [m] inside the rod
    point: PointLoad | None = table(PointLoad, optional=True, default=None)
    #: [m/s²], adds ρ A g to the force
    gravity: tuple[float, float, float] = key(Vector(default=ZERO3, unit="m/s^2"))
    #: a force and torque that turn with an end's directors (forms/follower.py)
    follower: FollowerEndLoad | None = table(FollowerEndLoad, optional=True, default=None)
    #: a conservative torque that turns by half the end's rotation (forms/semitangential.py)
    semitangential: SemitangentialEndTorque | None = table(
        SemitangentialEndTorque, optional=True, default=None
    )
    #: a rigid body fixed to an end: its weight and inertia act there (forms/rigid_body.py)
    body: RigidBody | None = table(RigidBody, optional=True, default=None)

    @property
    def has_gravity(self) -> bool:
        return any(g != 0.0 for g in self.gravity)

    def form_loads(self) -> list[tuple[str, FormLoad]]:
        """(key, load) of the loads declared with their physics (:class:`FormLoad`) given."""
        return [
            (name, getattr(self, f))
            for name, f in declared_names(Loads).items()
            if isinstance(getattr(self, f), FormLoad)
        ]


@dataclass(frozen=True, kw_only=True)
class StructureNode:
    """A node of a structure ([[structure.nodes]]): its ``name`` and its ``position`` r0 [m]
    at rest, fixed basis."""

    name: str = key(Text(required=True, non_empty=True))
    position: tuple[float, float, float] = key(Vector(required=True, unit="m"))


@dataclass(frozen=True, kw_only=True)
class MemberSection:
    """A member's own section law ([structure.members.section], docs/structures.md), constant
    along it: the 6×6 ``stiffness`` K in :data:`~cosserat_fem.forms.section.LAW_ORDER` [N, N m,
    N m²] in the member's directors (numbers, symmetric positive definite), and optionally its
    ``mass_per_length`` μ [kg/m] and rotary ``inertia`` (I11, I22, I33) [kg m] (absent: the
    scene's, docs/sections.md)."""

    stiffness: tuple[tuple[float, ...], ...] = key(
        SymmetricMatrix(required=True, unit="N, N m, N m^2")
    )
    mass_per_length: float | None = key(Number(interval=POSITIVE, unit="kg/m"), default=None)
    inertia: tuple[float, float, float] | None = key(NumberVector(unit="kg m"), default=None)


@dataclass(frozen=True, kw_only=True)
class StructureMember:
    """A straight member ([[structure.members]]) from the node ``start`` (key ``from``) to the
    node ``end`` (key ``to``), ``elements`` cells; its rest frame D0: d0_3 along it, d0_1 the
    unit ``d1`` (normal to it; default: e2 × d0_3 normalised, or e1 × d0_3 for a member along
    e2), d0_2 = d0_3 × d0_1 (:meth:`frame`). The scene's [rod] section and material, or the
    member's own ``section`` law (:class:`MemberSection`)."""

    name: str = key(Text(required=True, non_empty=True))
    start: str = key(Text(required=True, non_empty=True), name="from")
    end: str = key(Text(required=True, non_empty=True), name="to")
    elements: int = key(Number(required=True, integer=True, interval=POSITIVE))
    d1: tuple[float, float, float] | None = key(Vector(unit="-"), default=None)
    section: MemberSection | None = table(MemberSection, optional=True, default=None)

    def frame(self, tangent: np.ndarray) -> np.ndarray:
        """D0 (3×3, rows d0_1, d0_2, d0_3) for the unit ``tangent`` d0_3 (class docstring)."""
        t = np.asarray(tangent, dtype=float)
        if self.d1 is not None:
            d1 = np.asarray(self.d1, dtype=float)
        else:
            d1 = np.cross([0.0, 1.0, 0.0], t)
            if np.linalg.norm(d1) < 1e-6:
                d1 = np.cross([1.0, 0.0, 0.0], t)
        d1 = d1 / np.linalg.norm(d1)
        return np.stack([d1, np.cross(t, d1), t])


@dataclass(frozen=True, kw_only=True)
class StructureSupport:
    """A support at a node ([[structure.supports]]): ``kind`` clamped (p = q = 0), pinned (the
    position held, a hinge about ``axis``, e1, e2 or e3, default e2: the angles about the
    other two held), spherical (the position held), sliding (the angles and the position
    across ``axis``, e1, e2 or e3, default e3, held: the node slides along it) or free; what
    each holds is HELD_BY_SUPPORT's (scene/keys.py).

    A clamped or sliding node may be turned: ``rotation`` α(t) [rad] about the unit
    ``rotation_axis`` n (fixed basis), its rotation Λ(t) = exp(α(t) n×) from the rest
    (Rodrigues), the angles held at Λ's in the node's chart (rod/model.py NodeRotation;
    docs/goto-ring.md). In statics α(static.time) is scaled by the load factor λ."""

    node: str = key(Text(required=True, non_empty=True))
    kind: str = key(Choice(choices=STRUCTURE_SUPPORTS, required=True))
    axis: tuple[float, float, float] | None = key(Vector(unit="-"), default=None)
    rotation: Expression | None = key(NumberOrTimeExpression(unit="rad"), default=None)
    rotation_axis: tuple[float, float, float] | None = key(Vector(unit="-"), default=None)

    def held(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The components of the position (x, y, z) and of the angles (θ, ψ, φ) held."""
        position, angles = HELD_BY_SUPPORT[self.kind]
        if self.kind == "pinned":
            k = int(np.argmax(np.abs(self.axis if self.axis is not None else (0, 1, 0))))
            angles = tuple(i for i in range(3) if i != k)
        if self.kind == "sliding":
            k = int(np.argmax(np.abs(self.axis if self.axis is not None else (0, 0, 1))))
            position = tuple(i for i in range(3) if i != k)
        return position, angles

    def held_components(self) -> tuple[int, ...]:
        """The components of U = (p, q) held: the positions and angles, and their rates."""
        position, angles = self.held()
        p = (*position, *(3 + a for a in angles))
        return (*p, *(6 + i for i in p))


#: The components of U = (p, q) a joint's copies share by identification, by kind
#: ([[structure.joints]]): the position (x, y, z)/ℓ and its rate; a hinge's and a driven
#: joint's rotations are tied by nonlinear rows besides (nls/constraints.py Joint), a
#: spherical joint's are free.
_POSITIONS = (0, 1, 2, 6, 7, 8)
JOINT_COMPONENTS: dict[str, tuple[int, ...]] = {
    "spherical": _POSITIONS,
    "hinge": _POSITIONS,
    "driven": _POSITIONS,
    "rigid": tuple(range(12)),  # a loaded junction's split (Structure.splits): no joint at all
}


@dataclass(frozen=True, kw_only=True)
class StructureJoint:
    """A joint at ``node`` ([[structure.joints]], docs/structures.md): the ``members`` it names
    (each with an end at the node) hold their own copy of the node, joined rigidly to one
    another, and that copy joins the node's other members (which keep the node: one of them at
    least) as ``kind`` says: spherical, the positions shared and the rotations free; hinge,
    the positions shared and the rotations free about ``axis`` n0 only (any nonzero vector
    of the rest frame, normalised: Λ_a n0 = Λ_b n0); driven, a hinge whose turn is
    prescribed, the copy turned from the node's members by exp(α [n0×]), α(t) = ``angle``
    [rad] (:data:`JOINT_COMPONENTS` the positions; the rotations by nonlinear rows,
    cosserat_fem/nls/constraints.py Joint; in statics α(static.time) scaled by the load
    factor λ). A support at the node holds its other members."""

    node: str = key(Text(required=True, non_empty=True))
    kind: str = key(Choice(choices=STRUCTURE_JOINTS, required=True))
    members: tuple[str, ...] = key(Names(required=True))
    axis: tuple[float, float, float] | None = key(Vector(unit="-"), default=None)
    angle: Expression | None = key(NumberOrTimeExpression(unit="rad"), default=None)


@dataclass(frozen=True, kw_only=True)
class NodeLoad:
    """A force [N] and torque [N m] at a node ([[structure.loads]]), functions of t: in fixed
    directions, or with ``follower`` turning with the node, their components in the fixed
    basis at rest turned by the node's rotation Λ (forms/follower.py ``turning``)."""

    node: str = key(Text(required=True, non_empty=True))
    force: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N"))
    torque: tuple[Expression, ...] = key(LoadVector(default=ZERO3, unit="N m"))
    follower: bool = key(Flag(), default=False)


@dataclass(frozen=True, kw_only=True)
class NodeBody(BodyData):
    """A rigid body fixed to a structure's ``node`` ([[structure.bodies]]): its inertia and
    offset (:class:`BodyData`) in the fixed basis at rest (the node's frame turns them with
    the node's rotation Λ, forms/rigid_body.py)."""

    node: str = key(Text(required=True, non_empty=True))


@dataclass(frozen=True, kw_only=True)
class Structure:
    """Straight rods joined at shared nodes ([structure], docs/structures.md), rigidly but where
    a joint says otherwise: a tree or a closed frame. ℓ (rod.length) is the members' total
    length."""

    nodes: tuple[StructureNode, ...] = key(Tables(item=StructureNode, required=True))
    members: tuple[StructureMember, ...] = key(Tables(item=StructureMember, required=True))
    supports: tuple[StructureSupport, ...] = key(
        Tables(item=StructureSupport, default=[]), default=()
    )
    loads: tuple[NodeLoad, ...] = key(Tables(item=NodeLoad, default=[]), default=())
    #: rigid bodies fixed to nodes (forms/rigid_body.py)
    bodies: tuple[NodeBody, ...] = key(Tables(item=NodeBody, default=[]), default=())
    #: joints other than rigid (:class:`StructureJoint`)
    joints: tuple[StructureJoint, ...] = key(Tables(item=StructureJoint, default=[]), default=())
    #: the node probes.csv follows (default: :meth:`probe_node`'s rule)
    probe: str | None = key(Text(non_empty=True), default=None)

    def positions(self) -> dict[str, np.ndarray]:
        """{node name: r0 [m]}."""
        return {n.name: np.asarray(n.position, dtype=float) for n in self.nodes}

    def lengths(self) -> np.ndarray:
        """The members' lengths [m]."""
        r0 = self.positions()
        return np.array([np.linalg.norm(r0[m.end] - r0[m.start]) for m in self.members])

    def probe_node(self) -> str:
        """The node probes.csv follows: ``probe``, else the first loaded node, else the first
        node without a support, else the first node; not a joint's (whose two copies turn
        apart; a load cannot be there) but when every node is one's."""
        if self.probe is not None:
            return self.probe
        held = {s.node for s in self.supports if s.kind != "free"}
        jointed = {j.node for j in self.joints}  # a joint's node has two rotations: none
        free = [n.name for n in self.nodes if n.name not in held | jointed]
        rest = [n.name for n in self.nodes if n.name not in jointed] + [self.nodes[0].name]
        return next(iter([x.node for x in self.loads] + free + rest))

    def rigid_body_modes(self) -> int:
        """How many rigid-body motions the supports and joints leave: the members joined
        rigidly form rigid groups (the graph of members cut at the joints' copies, each a
        small rigid motion (t, ω) of 6 unknowns); the supports hold components of their
        node's group (:func:`rigid_body_modes`'s rows) and each joint the differences of its
        two groups' motions at its node in the components it ties (JOINT_COMPONENTS: the
        position; a hinge also the turns across its axis, a driven joint all turns). The count is
        6 × groups less the rank of those rows: a mechanism's motions, e.g. a member between
        two spherical joints spinning about its own axis. The nodes' positions are scaled by
        the structure's size (the rank is scale-free)."""
        r0 = self.positions()
        size = max(1e-300, max(float(np.abs(x).max()) for x in r0.values()))
        joints = self.all_joints()
        copy_of = {(m, j.node): f"{j.node}#{k}" for k, j in enumerate(joints) for m in j.members}
        parent: dict[str, str] = {}

        def root(v: str) -> str:
            parent.setdefault(v, v)
            while parent[v] != v:
                v = parent[v]
            return v

        for m in self.members:
            a, b = (root(copy_of.get((m.name, n), n)) for n in (m.start, m.end))
            parent[a] = b
        groups = sorted({root(v) for v in list(parent)})
        column = {g: 6 * i for i, g in enumerate(groups)}

        def placed(group: str, rows: list[np.ndarray], sign: float = 1.0) -> list[np.ndarray]:
            out = []
            for row in rows:
                full = np.zeros(6 * len(groups))
                full[column[group] : column[group] + 6] = sign * row
                out.append(full)
            return out

        rows = []
        for s in self.supports:
            rows += placed(root(s.node), _held_rows(r0[s.node] / size, *s.held()))
        for k, j in enumerate(joints):
            tied = JOINT_COMPONENTS[j.kind]
            held = (
                tuple(i for i in tied if i < 3),
                tuple(i - 3 for i in tied if 3 <= i < 6),
            )
            local = _held_rows(r0[j.node] / size, *held)
            if j.kind in ("hinge", "driven"):  # the turns across the axis, or all three
                assert j.axis is not None, "a hinge's axis (scene/build.py)"
                n = np.asarray(j.axis) / np.linalg.norm(j.axis)
                turns = np.eye(3) - np.outer(n, n) if j.kind == "hinge" else np.eye(3)
                local += [np.concatenate([np.zeros(3), t]) for t in turns]
            one = placed(root(j.node), local)
            two = placed(root(f"{j.node}#{k}"), local, -1.0)
            rows += [x + y for x, y in zip(one, two, strict=True)]
        rank = int(np.linalg.matrix_rank(np.array(rows))) if rows else 0
        return 6 * len(groups) - rank

    def degree(self, node: str) -> int:
        """How many members meet at ``node``."""
        return sum((m.start == node) + (m.end == node) for m in self.members)

    def splits(self) -> tuple[StructureJoint, ...]:
        """The junctions of three or more members that carry a load or a body, split: the
        members at such a node after its first two (in the members' order) hold a copy of it
        tied in all twelve components (kind "rigid": the shared vertex it replaces, to
        round-off; nls/constraints.py), so that the node's own vertex joins two cells, whose
        interior facet carries the point measure dS (a facet of three cells has none)."""
        loaded = {x.node for x in self.loads} | {x.node for x in self.bodies}
        out = []
        for n in self.nodes:
            at = [m.name for m in self.members if n.name in (m.start, m.end)]
            if n.name in loaded and len(at) > 2:
                out.append(StructureJoint(node=n.name, kind="rigid", members=tuple(at[2:])))
        return tuple(out)

    def all_joints(self) -> tuple[StructureJoint, ...]:
        """The scene's joints, then :meth:`splits` (the mesh's copies, in this order)."""
        return self.joints + self.splits()


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


@dataclass(frozen=True, kw_only=True)
class RetardationTimes(Field):
    """``damping.retardation_time``: one number ≥ 0 [s] (τ_d, every strain component alike), or
    a list of six, μ_1..μ_6 in the section's strain order (docs/sections.md §1); kept as given,
    a float or a tuple of six floats (forms/general_form.py ``retardation_times`` makes six)."""

    def describe(self) -> str:
        return (
            f"a number >= 0 [s] or a list of {STRAIN_COMPONENTS} (shear 1, shear 2, extension, "
            "bending 1, bending 2, torsion)"
        )

    def check(self, key: str, value: Any) -> Any:
        number = Number(interval=NON_NEGATIVE, unit="s")
        if not isinstance(value, list):
            return number.check(key, value)
        if len(value) != STRAIN_COMPONENTS:
            raise SceneError(f"{key}: must be {self.describe()}, got {show_value(value)}")
        return tuple(number.check(f"{key}[{i}]", x) for i, x in enumerate(value))

    def to_value(self, value: Any) -> Any:
        return list(value) if isinstance(value, tuple) else value


@dataclass(frozen=True, kw_only=True)
class Damping:
    """Viscous damping densities: force −c_t ṙ [N/m] with ``translational`` c_t [N s/m²], and
    torque −c_r ω [N m/m] with ``rotational`` c_r [N s] (ω the angular velocity). For a
    slender rod c_t damps every bending mode alike: ζ_n = c_t / (2 ρ A ω_n).

    Kelvin–Voigt (material) damping with ``retardation_time`` τ_d [s]: E and G act on
    (1 + τ_d ∂t) of the strains, n = K (v − e3 + τ_d v̇), m = J (u + τ_d u̇); it damps each
    mode in proportion to its frequency, ζ_n = τ_d ω_n / 2. Or six times μ_1..μ_6 [s], one per
    strain component (shear 1, shear 2, extension, bending 1, bending 2, torsion), BeamDyn's
    stiffness-proportional damping: the viscous parts are diag(μ) K ε̇, and a mode of
    component i decays with ζ_n = μ_i ω_n / 2 (forms/general_form.py KelvinVoigtDamping)."""

    translational: float = key(Number(default=0.0, interval=NON_NEGATIVE, unit="N s/m^2"))
    rotational: float = key(Number(default=0.0, interval=NON_NEGATIVE, unit="N s"))
    retardation_time: float | tuple[float, ...] = key(RetardationTimes(default=0.0))

    @property
    def viscous(self) -> bool:
        return self.translational > 0.0 or self.rotational > 0.0

    @property
    def kelvin_voigt(self) -> bool:
        return any(retardation_times(self.retardation_time))

    @property
    def active(self) -> bool:
        return self.viscous or self.kelvin_voigt


@dataclass(frozen=True, kw_only=True)
class Initial:
    """The state at time.start as functions of s [m] (None: at rest, straight): position
    displacement [m], angles (θ, ψ, φ) [rad], velocity [m/s], angle rates [rad/s]."""

    displacement: tuple[Expression, ...] | None = key(Vector(default=ZERO3, unit="m"), default=None)
    angles: tuple[Expression, ...] | None = key(Vector(default=ZERO3, unit="rad"), default=None)
    velocity: tuple[Expression, ...] | None = key(Vector(default=ZERO3, unit="m/s"), default=None)
    angle_rates: tuple[Expression, ...] | None = key(
        Vector(default=ZERO3, unit="rad/s"), default=None
    )

    def fields(self) -> dict[str, tuple[Expression, ...]]:
        """The fields given, non-zero, by name."""
        return {
            name: value
            for name, value in vars(self).items()
            if value is not None and not all(e.is_zero for e in value)
        }


@dataclass(frozen=True, kw_only=True)
class Time:
    """Time span [s] and integrator."""

    start: float = key(Number(default=0.0, unit="s"))
    end: float = key(Number(required=True, unit="s"))
    step: float = key(Number(required=True, interval=POSITIVE, unit="s"))
    #: SDIRK3 and a frozen Jacobian: the fastest to an error of 1e-3 on the paper's scene
    #: (benchmarks/README.md), the defaults the README states.
    integrator: str = key(
        Choice(choices=("bdf2", "generalized-alpha", "sdirk3", "sdirk4"), default="sdirk3")
    )
    rho_inf: float = key(Number(default=0.5, interval=Interval(0.0, 1.0)))
    max_halvings: int = key(Number(default=6, integer=True, interval=Interval(0, 30)))
    adaptive: bool = key(Flag(default=False))
    rtol: float = key(Number(default=1e-4, interval=Interval(0.0, 1.0, True, True)))
    atol: float = key(Number(default=1e-10, interval=POSITIVE))
    max_step: float = key(Number(default=0.0, interval=NON_NEGATIVE, unit="s"))  # 0: no limit
    #: a step of BDF2 or generalized-α (ρ∞ < 1) that brings nodes into contact is solved
    #: again by the implicit midpoint rule, and so are the next ones (an impact's energy
    #: exact: cosserat_fem/timestepping/loop.py, "Impacts"); false: the method's own steps
    #: throughout, for landings without a jump of the velocity (a slow, overdamped contact
    #: such as a plectoneme's ply: docs/decisions.md, "Landings in an overdamped ply")
    impact_steps: bool = key(Flag(default=True))

    @property
    def n_steps(self) -> int:
        """Number of time steps, round((end - start) / step)."""
        return round((self.end - self.start) / self.step)


@dataclass(frozen=True, kw_only=True)
class StaticSettings:
    """Static solves (``cosserat-fem static``): the loads at ``time`` [s], applied in
    ``load_steps`` equal increments of the load factor; a failed increment is halved, down to
    2^-``max_bisections`` of the nominal increment."""

    load_steps: int = key(Number(default=1, integer=True, interval=Interval(lo=1)))
    #: 2^-30 of a load increment: below that no increment is worth trying.
    max_bisections: int = key(Number(default=10, integer=True, interval=Interval(0, 30)))
    time: float = key(Number(default=0.0, unit="s"))


@dataclass(frozen=True, kw_only=True)
class Discretisation:
    """Mesh and element: ``elements`` cells of Lagrange ``degree``; quadrature resolved."""

    elements: int = key(Number(default=20, integer=True, interval=Interval(lo=1)))
    degree: int = key(Number(default=2, integer=True, interval=Interval(1, 5)))
    #: Exact for polynomials of degree 100 (51 Gauss points a cell), ten times the default
    #: 2 * degree of degree 5; FFCx itself warns beyond 100 points. "auto": 2 * degree.
    quadrature_degree: int = key(
        Number(default="auto", integer=True, interval=Interval(1, MAX_QUADRATURE), auto=True)
    )
    #: "auto": solve the in-plane unknowns of a scene in x-z or y-z
    planar: str = key(Choice(choices=("auto", "off"), default="auto"))


@dataclass(frozen=True, kw_only=True)
class Solver:
    """Newton solver settings."""

    jacobian: str = key(Choice(choices=("full", "lagged", "frozen"), default="frozen"))
    lag: int = key(Number(default=10, integer=True, interval=Interval(lo=1)))
    refresh_iterations: int = key(Number(default=4, integer=True, interval=Interval(lo=1)))
    rtol: float = key(Number(default=1e-10, interval=Interval(0.0, 1.0, True, True)))
    atol: float = key(Number(default=1e-12, interval=POSITIVE))
    stol: float = key(Number(default=1e-8, interval=Interval(0.0, 1.0, True, True)))
    max_iterations: int = key(
        Number(default=25, integer=True, interval=Interval(1, MAX_NEWTON_ITERATIONS))
    )
    linear_solver: str = key(Choice(choices=("auto", "petsc", "mumps", "superlu"), default="auto"))
    #: the residual's assembler under the one Newton loop: "auto", the C assembler where it
    #: applies (native_newton.py); "python", DOLFINx's
    loop: str = key(Choice(choices=("auto", "python"), default="auto"))
    #: "newton" (the project's loop), "snes" (PETSc's SNES, cosserat_fem/nls/snes.py) or "auto"
    #: (SNES if ``petsc`` gives options: solvers.make_solver).
    nonlinear: str = key(Choice(choices=("auto", "newton", "snes"), default="auto"), default="auto")
    #: PETSc options for SNES, name (without "-" and the prefix cosserat_) = value as text.
    petsc: dict[str, str] = key(PetscOptions(default={}), default_factory=dict)


@dataclass(frozen=True, kw_only=True)
class Output:
    """Output directory (stored as written), XDMF and checkpoint settings.

    ``checkpoint_interval`` [s] is resolved: a positive multiple of the step, or 0 for a
    checkpoint at the end of the run only (cosserat_fem/io/checkpoint.py).
    """

    directory: str = key(Text(default="results", non_empty=True))
    xdmf: bool = key(Flag(default=True))
    xdmf_interval: float = key(Number(default=0.0, interval=NON_NEGATIVE, unit="s"))
    fields: tuple[str, ...] = key(ChoiceList(choices=XDMF_FIELDS, default=XDMF_DEFAULT_FIELDS))
    #: What probes.csv holds besides t, x, y, z, θ, ψ, φ (cosserat_fem/io/probes.py).
    probe_fields: tuple[str, ...] = key(
        ChoiceList(choices=tuple(PROBE_FIELD_COLUMNS), default=()), default=()
    )
    checkpoint: bool = key(Flag(default=True))
    checkpoint_interval: float = key(
        Number(default="auto", interval=NON_NEGATIVE, unit="s", auto=True)
    )

    def xdmf_every(self, step: float) -> int:
        """Steps between XDMF writes (1 if the interval is 0)."""
        if self.xdmf_interval == 0.0:
            return 1
        return max(1, round(self.xdmf_interval / step))


@dataclass(frozen=True, kw_only=True)
class Limits:
    """What a run may cost before it is refused (cosserat_fem/analysis/budget.py): ``wall_time``
    [s], the estimated wall time of the run and the most it may run before it stops with a
    checkpoint; ``memory`` [bytes], the estimated memory (None: "auto", the memory available
    on this machine). Raise them to run a very large case on purpose."""

    wall_time: float = key(Number(default=DEFAULT_WALL_TIME, interval=POSITIVE, unit="s"))
    memory: float | None = key(Number(default="auto", interval=POSITIVE, unit="bytes", auto=True))


@dataclass(frozen=True, kw_only=True)
class Obstacle:
    """A rigid obstacle ([[contact.obstacles]], docs/contact.md): the rod stays on the side of
    a ``plane`` through ``point`` [m] that its ``normal`` points to; outside a ``sphere`` of
    ``radius`` [m] about ``point``; outside an infinite ``cylinder`` of ``radius`` whose axis
    passes through ``point`` along ``axis``; where the signed ``distance`` of a ``surface``,
    an expression of x, y, z [m], is positive. ``normal`` and ``axis`` are made unit
    vectors."""

    kind: str = key(Choice(choices=CONTACT_OBSTACLES, required=True))
    point: tuple[float, float, float] | None = key(NumberVector(unit="m"), default=None)
    normal: tuple[float, float, float] | None = key(NumberVector(unit="-"), default=None)
    axis: tuple[float, float, float] | None = key(NumberVector(unit="-"), default=None)
    radius: float | None = key(Number(interval=POSITIVE, unit="m"), default=None)
    #: a ``surface``'s signed distance d(x, y, z) [m], > 0 on the rod's side, |∇d| = 1
    distance: Expression | None = key(PositionExpression(unit="m"), default=None)

    def keeps(self, normal: tuple[int, ...]) -> bool:
        """Whether a rod in the plane x_k = 0 (k in ``normal``, the plane's normal axes) is
        pushed within it: the plane's normal, the sphere's centre in it, the cylinder's axis
        along its normal."""
        if self.kind == "plane":
            assert self.normal is not None, "a plane has one (build.py)"
            return all(self.normal[k] == 0.0 for k in normal)
        if self.kind == "surface":  # d must not vary across the plane: no push out of it
            assert self.distance is not None, "a surface has one (build.py)"
            return not any(self.distance.depends_on("xyz"[k]) for k in normal)
        assert self.point is not None, "a sphere and a cylinder have one (build.py)"
        if self.kind == "sphere":
            return all(self.point[k] == 0.0 for k in normal)
        assert self.axis is not None, "a cylinder has one (build.py)"
        return all(self.axis[k] == 0.0 for k in range(3) if k not in normal)


@dataclass(frozen=True, kw_only=True)
class Contact:
    """Unilateral contact of the rod's surface with rigid ``obstacles``, with Coulomb friction
    (docs/contact.md): a point of the surface sticks while the tangential force is below
    ``static_friction`` times the normal force, and slides against it with
    ``kinetic_friction`` (by default the static coefficient) times the normal force. The
    surface is a tube of ``radius`` [m] about the centreline: "auto" is a circular section's
    radius (a tube's outer one). ``self_contact``: the rod's surface (a structure's members')
    does not pass through itself either, with the same friction."""

    obstacles: tuple[Obstacle, ...] = key(Tables(item=Obstacle, default=[]), default=())
    #: the rod's contact with itself, with the same friction (docs/contact.md, "Self contact")
    self_contact: bool = key(Flag(default=False), default=False)
    static_friction: float = key(Number(default=0.0, interval=NON_NEGATIVE, unit="-"))
    kinetic_friction: float | None = key(Number(interval=NON_NEGATIVE, unit="-"), default=None)
    radius: float | str = key(Number(default="auto", interval=POSITIVE, unit="m", auto=True))
    #: the most nodes that may come into or out of contact in one accepted time step (a step
    #: with more is rejected and halved: an impact front resolved in time); 0: any number
    max_changes: int = key(Number(default=0, integer=True, interval=NON_NEGATIVE))

    @property
    def kinetic(self) -> float:
        """The kinetic coefficient (the static one unless given)."""
        return self.static_friction if self.kinetic_friction is None else self.kinetic_friction


@dataclass(frozen=True, kw_only=True)
class Scene:
    """A validated scene; ``source`` (file name or "<dict>") and its digest do not take part
    in equality."""

    title: str = key(Text(default=""))
    parameters: dict[str, float] = key(Parameters())
    rod: Rod = table(Rod)
    #: The rod at rest (forms/reference.py): straight along e3 (the paper's), a circular arc
    #: in the e1-e3 plane bending towards +e1, a helix about an axis along e3, a polyline
    #: whose frame jumps at its corners, or a curve of expressions of s.
    reference: ReferenceShape = table(ReferenceShape, default_factory=ReferenceShape)
    model: ModelChoices = table(ModelChoices)
    supports: Supports = table(Supports)
    loads: Loads = table(Loads)
    damping: Damping = table(Damping)
    initial: Initial = table(Initial, default_factory=Initial)  # built last, from the rest
    time: Time = table(Time)
    static: StaticSettings = table(StaticSettings)
    discretisation: Discretisation = table(Discretisation)
    solver: Solver = table(Solver)
    output: Output = table(Output)
    limits: Limits = table(Limits)
    #: Several straight rods joined rigidly at nodes (docs/structures.md), or None: one rod.
    structure: Structure | None = table(Structure, optional=True, default=None)
    #: Contact with rigid obstacles (docs/contact.md), or None: no contact, nothing computed.
    contact: Contact | None = table(Contact, optional=True, default=None)
    source: str = field(default="<dict>", compare=False)
    #: SHA-256 of the file's bytes the scene was read from ("" for a dict): what every MPI
    #: rank parsed (schema.read_input), written to summary.json as ``scene_file_sha256``
    source_sha256: str = field(default="", compare=False)

    def rigid_body_modes(self) -> int:
        """How many rigid-body motions the supports leave: the structure's
        (Structure.rigid_body_modes) or the rod's (Supports.rigid_body_modes)."""
        if self.structure is not None:
            return self.structure.rigid_body_modes()
        return self.supports.rigid_body_modes()

    @property
    def mechanism(self) -> bool:
        """Whether the supports leave a rigid-body motion (:meth:`rigid_body_modes` > 0)."""
        return self.rigid_body_modes() > 0

    @property
    def omega0(self) -> float:
        """The reference frequency ω0 [rad/s]: as given, or :func:`auto_reference_frequency`."""
        given = self.model.reference_frequency
        return given if given is not None else auto_reference_frequency(self.rod)

    @property
    def probe_sigma(self) -> float:
        """The probe point σ = s/ℓ (probes.csv): the free end at s = ℓ, else the free end at
        s = 0, else mid-span."""
        if self.supports.end == "free":
            return 1.0
        if self.supports.start == "free":
            return 0.0
        return 0.5

    def plane(self) -> str | None:
        """The plane the motion stays in, "x-z" or "y-z" (checked in that order: a scene in
        both moves along the axis only, and x-z keeps clear of the chart limit |θ| < π/2),
        or None: asked for (discretisation.planar = "auto") and nothing leaves the plane; never
        with a section law that couples its strains (rod.section.stiffness off its diagonal:
        an extension may twist, a bending shear out of the plane)."""
        if self.discretisation.planar != "auto" or self.reference.curved or self.structure:
            return None
        K = self.rod.section.stiffness
        if K is not None and any(K[i][j] != 0.0 for i in range(6) for j in range(6) if i != j):
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
        vectors: list[tuple[tuple[Expression, ...] | None, tuple[int, ...]]] = [
            (loads.force_density, normal),
            (loads.torque_density, torques),
        ]
        for end in (loads.start, loads.end, loads.point):
            if end is not None:
                vectors += [(end.force, normal), (end.torque, torques)]
        vectors += [(m, normal) for m in (self.supports.start_motion, self.supports.end_motion)]
        if not all(load.in_plane(normal, torques) for _, load in loads.form_loads()):
            return False
        vectors += [(init.displacement, normal), (init.velocity, normal)]
        vectors += [(init.angles, angles), (init.angle_rates, angles)]
        if any(loads.gravity[i] != 0.0 for i in normal):
            return False
        if self.contact is not None and not all(o.keeps(normal) for o in self.contact.obstacles):
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
            inertia=self.rod.rotary_inertia,
            law=self.rod.section.law(),
        )

    def load_components(self) -> list[tuple[str, Any]]:
        """(dotted key ``loads.end.force[2]``, component) of every component of the loads
        (densities, end and point loads) and support motions: an Expression, or data
        (cosserat_fem/scene/load_data.py)."""
        loads, supports = self.loads, self.supports
        entries: list[tuple[str, Any]] = [("loads.force_density", loads.force_density)]
        entries.append(("loads.torque_density", loads.torque_density))
        for end in ("start", "end", "point"):
            load = getattr(loads, end)
            if load is not None:
                entries += [(f"loads.{end}.force", load.force)]
                entries += [(f"loads.{end}.torque", load.torque)]
            if end != "point" and supports.motion(end) is not None:
                entries += [(f"supports.{end}_motion", supports.motion(end))]
        for name, load in loads.form_loads():
            entries += [(f"loads.{name}.{k}", v) for k, v in load.vectors().items()]
        return [
            (f"{key}[{i}]", component)
            for key, vector in entries
            if vector is not None
            for i, component in enumerate(vector)
        ]

    def expression_names(self) -> dict[str, float]:
        """Constant values for load expressions: ``L``, ``omega0`` and the parameters."""
        return {"L": self.rod.length, "omega0": self.omega0, **self.parameters}

    def to_dict(self) -> dict[str, Any]:
        """The scene as the tables of a scene file, every key given, as its declaration writes
        it (:func:`~cosserat_fem.scene.keys.to_table`: expressions as their sources, tables and
        callables as their dicts, reference_frequency and limits.memory "auto" where so
        chosen, absent optional tables left out): plain, JSON-serialisable;
        ``scene_from_dict`` inverts it. A structure's scene leaves out the single rod's
        [reference], [supports] and [initial], which it refuses (docs/structures.md)."""
        table = to_table(self)
        if self.structure is not None:
            for name in ("reference", "supports", "initial"):
                table.pop(name, None)
        return table


def auto_reference_frequency(rod: Rod) -> float:
    """ω0 = 1.875² / L² · sqrt(E c22 / (ρ A)) (paper, §6: c22 = b a³/12, A = a b for its
    rectangle): the first cantilever bending frequency about d2."""
    mat = rod.material
    section = rod.section.constants()
    return euler_bernoulli_omega0(rod.length, section, mat.density, mat.young_modulus)
