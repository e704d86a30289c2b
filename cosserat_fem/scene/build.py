"""TOML scenes: from a scene file (or its data) and ``--set`` overrides to the resolved
:class:`Scene`.

A scene file describes one run (rod, material, supports, loads, time span, discretisation,
solver and output). :func:`load_scene` reads it, applies ``dotted.key=value`` overrides and
validates everything before any work is done (the schema: cosserat_fem/scene/schema.py); the
building here resolves the rest: section constants, the derived constants and their range,
expressions parsed with the scene's names, initial fields against the supports, the time grid.
Every problem is a single :class:`~cosserat_fem.common.errors.SceneError` naming the dotted key.
``scenes/cao_tucker_2008.toml`` is a commented example. The resolved scene's classes
(cosserat_fem/scene/resolved.py) are importable from here too.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from cosserat_fem.common.errors import SceneError, show_value
from cosserat_fem.forms.groups import Groups, dimensionless_groups
from cosserat_fem.forms.section import cowper_circle
from cosserat_fem.scene.expressions import Expression, derivative, parse_vector
from cosserat_fem.scene.keys import (
    REFERENCE_KEYS,
    SCENE_CONSTANTS,
    SECTION_KEYS,
    STEP_TOLERANCE,
    LoadVector,
    Table,
    build,
    declared_names,
    fmt,
    to_table,
)
from cosserat_fem.scene.load_data import TableStore, check_span, is_data, parse_load_vector
from cosserat_fem.scene.resolved import (  # noqa: F401 - the resolved scene, importable from here
    PLANAR,
    PLANES,
    Contact,
    Damping,
    Discretisation,
    EndLoad,
    FormLoad,
    Initial,
    Limits,
    Loads,
    Material,
    MemberSection,
    ModelChoices,
    NodeBody,
    NodeLoad,
    Obstacle,
    Output,
    PointLoad,
    ReferenceShape,
    Rod,
    Scene,
    SectionSpec,
    Solver,
    StaticSettings,
    Structure,
    StructureJoint,
    StructureMember,
    StructureNode,
    StructureSupport,
    Supports,
    Time,
    auto_reference_frequency,
)
from cosserat_fem.scene.schema import (  # noqa: F401 - read_toml and the overrides, from here too
    Overrides,
    apply_overrides,
    check_depth,
    check_scene,
    parse_toml,
    read_input,
    read_toml,
)

CHECKPOINTS_PER_RUN = 10  # output.checkpoint_interval = "auto"


# ==================================================================================== building
def _build_section(raw: dict[str, Any], poisson_ratio: float) -> SectionSpec:
    """[rod.section] resolved: only and all the keys of its shape; a rectangle's torsion_constant
    "series" by default; shear_coefficient "auto" as 5/6 (rectangle) or Cowper's value for
    ν = ``poisson_ratio`` (circle, tube). SceneError naming the key."""
    shape = raw["shape"]
    keys = SECTION_KEYS[shape]
    for name, value in raw.items():
        if value is not None and name not in (*keys, "shape", "shear_coefficient", *LAW_KEYS):
            raise SceneError(
                f"rod.section.{name}: not a key of shape {shape!r}, which takes "
                f"{', '.join(keys)} (and shear_coefficient, {', '.join(LAW_KEYS)}; --unset "
                f"rod.section.{name} "
                "removes "
                "it)"
            )
    for name in LAW_KEYS[1:]:
        if raw.get(name) is not None and raw.get("stiffness") is None:
            raise SceneError(f"rod.section.{name}: only with rod.section.stiffness (a 6×6 law)")
    values = dict(raw)
    if shape == "rectangle" and values["torsion_constant"] is None:
        values["torsion_constant"] = "series"
    for name in keys:
        if values[name] is None:
            raise SceneError(f"rod.section.{name}: required for shape {shape!r} (a number > 0)")
    if shape == "tube" and not values["inner_diameter"] < values["outer_diameter"]:
        raise SceneError(
            f"rod.section.inner_diameter: must be < outer_diameter = "
            f"{fmt(values['outer_diameter'])} [m], got {show_value(values['inner_diameter'])}"
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
    return build(SectionSpec, values)


def _build_reference(raw: dict[str, Any], constants: dict[str, float]) -> ReferenceShape:
    """[reference] resolved: only and all the keys of its shape (REFERENCE_KEYS); a curve's
    expressions of s and ``constants`` (L, the parameters). SceneError naming the key."""
    shape = raw["shape"]
    keys = REFERENCE_KEYS[shape]
    for name, value in raw.items():
        if value is not None and name not in (*keys, "shape", "closed"):
            takes = f"takes {', '.join(keys)}" if keys else "takes no other key"
            raise SceneError(
                f"reference.{name}: not a key of shape {shape!r}, which {takes} "
                f"(--unset reference.{name} removes it)"
            )
    values = {k: v for k, v in raw.items() if v is not None}
    if shape == "polyline":
        values["binormal"] = _binormal(values.get("binormal", [0, 1, 0]))
        values["points"] = tuple(values.get("points") or ())
    if shape == "curve":
        for name in ("position", "director"):
            if values.get(name) is not None:
                values[name] = parse_vector(values[name], {"s", *constants}, f"reference.{name}")
        values["constants"] = dict(constants)
    for name in keys:
        if values.get(name) is None or values.get(name) == ():
            raise SceneError(f"reference.{name}: required for shape {shape!r}")
    return ReferenceShape(**values)


def _binormal(raw: list) -> tuple[float, float, float]:
    """reference.binormal as three finite numbers, not all zero."""
    values = []
    for i, x in enumerate(raw):
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
            raise SceneError(
                f"reference.binormal[{i}]: must be a finite number, got {show_value(x)}"
            )
        values.append(float(x))
    if not any(values):
        raise SceneError("reference.binormal: must not be zero, got [0, 0, 0]")
    x, y, z = values  # three: the schema's Vector checked the length
    return x, y, z


def _build_rod(raw: dict[str, Any]) -> Rod:
    """[rod]: length [m], section, material with exactly one of ν and G [Pa]; G must be positive
    and finite, E/(2 G) − 1 a Poisson ratio where Cowper's κ needs one. SceneError naming the
    key."""
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
    material = build(Material, mat)
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
    inertia = raw["rotary_inertia"]
    if inertia is not None:
        for i, value in enumerate(inertia):
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not (ok and math.isfinite(value) and value > 0.0):
                raise SceneError(
                    f"rod.rotary_inertia[{i}]: must be a positive number [kg m] (a mass moment "
                    f"of inertia per unit length), got {show_value(value)}"
                )
        inertia = tuple(float(v) for v in inertia)
    section = _build_section(raw["section"], poisson)
    return build(Rod, raw, section=section, material=material, rotary_inertia=inertia)


def _build_model(raw: dict[str, Any]) -> ModelChoices:
    """[model]; reference_frequency "auto" as None (ω0 [rad/s] from the rod,
    :func:`auto_reference_frequency`)."""
    frequency = raw["reference_frequency"]
    return build(ModelChoices, raw, reference_frequency=None if frequency == "auto" else frequency)


def _build_supports(raw: dict[str, Any], constants: set[str], tables: TableStore) -> Supports:
    """[supports]: any pair of supports (a mechanism, e.g. pinned–free or free–free, runs and
    has modes about the straight rod, its rigid-body modes first; static paths and modes about
    a static state refuse it); motions [m] as expressions of t and ``constants`` or tables of t
    (read from ``tables``), None if zero, refused at a free end."""
    kinds = (raw["start"], raw["end"])
    motions = {}
    for end, kind in zip(("start", "end"), kinds, strict=True):
        key = f"supports.{end}_motion"
        vector = parse_load_vector(raw[f"{end}_motion"], {"t", *constants}, key, tables, True)
        motions[end] = None if all(e.is_zero for e in vector) else vector
        if motions[end] is not None and kind in ("free", "roller", "sliding"):
            raise SceneError(
                f"{key}: a prescribed motion needs an end held in x, y and z (clamped, pinned or "
                f'spherical), but supports.{end} = "{kind}"'
            )
    axes = {f"{end}_axis": _hinge_axis(raw, end) for end in ("start", "end")}
    return build(Supports, raw, start_motion=motions["start"], end_motion=motions["end"], **axes)


def _hinge_axis(raw: dict[str, Any], end: str) -> tuple[float, float, float] | None:
    """supports.<end>_axis (Supports): None if absent, else three finite numbers along e1, e2
    or e3 (either sign), at a pinned end only; SceneError naming the key."""
    key, axis = f"supports.{end}_axis", raw[f"{end}_axis"]
    if axis is None:
        return None
    if raw[end] != "pinned":
        raise SceneError(
            f'{key}: only a pinned end has a hinge axis, but supports.{end} = "{raw[end]}"'
        )
    for i, x in enumerate(axis):
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
            raise SceneError(f"{key}[{i}]: must be a finite number, got {show_value(x)}")
    if not any(axis):
        raise SceneError(f"{key}: a hinge axis must not be zero, got {show_value(axis)}")
    if sum(x != 0 for x in axis) != 1:
        raise SceneError(
            f"{key}: a hinge axis must lie along e1, e2 or e3 (the angles θ, ψ, φ turn about "
            f"these; a slanted hinge is none of them), e.g. [0, 1, 0], got {show_value(axis)}"
        )
    x, y, z = (float(c) for c in axis)
    return x, y, z


def _build_loads(
    raw: dict[str, Any], supports: Supports, constants: set[str], tables: TableStore
) -> Loads:
    """[loads]: force [N/m] and torque [N m/m] densities of s, t and ``constants`` (or data:
    tables read from ``tables``, callables; cosserat_fem/scene/load_data.py), end loads
    (:func:`_build_end_load`), gravity [m/s²] of the constants only."""
    names = {"s", "t", *constants}
    force = parse_load_vector(raw["force_density"], names, "loads.force_density", tables)
    torque = parse_load_vector(raw["torque_density"], names, "loads.torque_density", tables)
    ends = {}
    for end in ("start", "end"):
        ends[end] = _build_end_load(raw[end], end, getattr(supports, end), names, tables)
    gravity = _constant_vector(raw["gravity"], constants, "loads.gravity")
    point = None
    if raw["point"] is not None:
        vectors = {}
        for name in ("force", "torque"):
            key = f"loads.point.{name}"
            vectors[name] = _point_vector(raw["point"][name], names, key, tables, "a point load")
        point = build(PointLoad, raw["point"], **vectors)
    declared = {}
    for name, spec in Table.of(Loads).fields.items():
        if (
            isinstance(spec, Table)
            and spec.resolved is not None
            and issubclass(spec.resolved, FormLoad)
            and raw[name]
        ):
            field = declared_names(Loads)[name]
            declared[field] = _build_form_load(
                spec, raw[name], f"loads.{name}", supports, names, tables
            )
    return build(
        Loads,
        raw,
        force_density=force,
        torque_density=torque,
        gravity=gravity,
        point=point,
        **ends,
        **declared,
    )


def _point_vector(
    raw: list, names: set[str], key: str, tables: TableStore, what: str
) -> tuple[Expression, ...]:
    """The load vector ``raw`` of a load at a point (an end, a node): functions of t and the
    constants; SceneError naming ``key[i]`` for a dependence on the arc length s."""
    vector = parse_load_vector(raw, names, key, tables)
    for i, component in enumerate(vector):
        if component.depends_on("s"):
            raise SceneError(
                f"{key}[{i}]: {what} may depend on t and constants only, not on "
                f"the arc length s, got {show_value(component.source)}"
            )
    return vector


def _build_form_load(
    spec: Table,
    raw: dict[str, Any],
    key: str,
    supports: Supports,
    names: set[str],
    tables: TableStore,
) -> FormLoad:
    """A load declared with its physics (resolved.FormLoad): its load vectors parsed as
    functions of t and the constants (not of s: it acts at a point), then its own check."""
    assert spec.resolved is not None, "a form load's table is Table.of its dataclass"
    vectors = {}
    for name, item in spec.fields.items():
        if isinstance(item, LoadVector):
            vector = _point_vector(raw[name], names, f"{key}.{name}", tables, "a load at an end")
            vectors[declared_names(spec.resolved)[name]] = vector
    load = build(spec.resolved, raw, **vectors)
    load.check(key, supports)
    return load


def _constant_vector(raw: list, constants: set[str], key: str) -> tuple[float, float, float]:
    """Three numbers (expressions of the constants only)."""
    x, y, z = (float(e.evaluate()) for e in parse_vector(raw, set(constants), key))
    return x, y, z


def _build_initial(
    raw: dict[str, Any], supports: Supports, values: dict[str, float], t0: float
) -> Initial:
    """Initial fields of s [m]. Where a support holds the rod they must take its values at
    t0 (else the first step would jump to them): all of p and q at a clamped end, position,
    velocity, φ and its rate at a pinned one (each support's: Supports.held); zero,
    or the support's prescribed motion and its rate for x, y, z."""
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
        position, angles = supports.held(end)
        held = {"displacement": position, "velocity": position}
        held.update(angles=angles, angle_rates=angles)
        for name, components in held.items():
            for i in components:
                want = 0.0
                if motion is not None and name in ("displacement", "velocity"):
                    e = motion[i] if name == "displacement" else derivative(motion[i], "t")
                    key = f"supports.{end}_motion[{i}]"
                    want = _finite_value(e, key, f"t = {fmt(t0)} s", t=t0, **values)
                got, given = 0.0, fields[name]
                if given is not None:
                    key, where = f"initial.{name}[{i}]", f"s = {fmt(s_end)} m"
                    got = _finite_value(given[i], key, where, s=s_end, **values)
                if abs(got - want) > 1e-12 * max(abs(want), scale[name]):
                    source = show_value(given[i].source) if given else "0"
                    what = "its prescribed motion" if motion is not None else "0"
                    if motion is not None and is_data(motion[i]):  # a value to copy
                        what = (
                            f"the {'rate' if name == 'velocity' else 'value'} at t = "
                            f"{fmt(t0)} s of its prescribed {motion[i].source}, {want!r}"
                        )
                    raise SceneError(
                        f"initial.{name}[{i}]: must equal {what} ({want:.6g}) at the {kind} "
                        f"{end} (s = {fmt(s_end)} m), got {got:.6g} from {source}"
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
    raw: dict[str, Any] | None, end: str, support: str, names: set[str], tables: TableStore
) -> EndLoad | None:
    """[loads.<end>] (force [N], torque [N m], expressions of t and constants), None if absent;
    SceneError at a clamped end, for a dependence on s, for a force at a pinned or
    spherical end and for a force across the free axial direction e3 of a roller or sliding
    end (a torque about an axis an end holds: :func:`_check_end_torques`)."""
    if raw is None:
        return None
    key = f"loads.{end}"
    if support == "clamped":
        raise SceneError(
            f"{key}: end loads are only allowed on a free, pinned, spherical, roller or sliding "
            f'end, but supports.{end} = "{support}" (remove [{key}] or set supports.{end} = "free")'
        )
    vectors = {}
    for name in ("force", "torque"):
        vectors[name] = _point_vector(raw[name], names, f"{key}.{name}", tables, "end loads")
    if support in ("pinned", "spherical") and not all(e.is_zero for e in vectors["force"]):
        held = "about e1, e2; the twist is held too" if support == "pinned" else "any axis"
        raise SceneError(
            f"{key}.force: a {support} end holds its position, so an end force there is taken "
            f"by the support; give only an end torque ({held})"
        )
    if support in ("roller", "sliding") and not all(e.is_zero for e in vectors["force"][:2]):
        raise SceneError(
            f"{key}.force: a {support} end holds x and y, so only the axial force along e3 (its "
            f"free direction) may act there; give force = [0, 0, P]"
        )
    return build(EndLoad, raw, **vectors)


def _check_end_torques(loads: Loads, supports: Supports) -> None:
    """SceneError naming loads.<end>.torque[i] for a torque about an axis e_i whose angle the
    end holds (Supports.held: φ at a fork or roller, all at a sliding end, the two across a
    hinge's axis): the support takes it."""
    names = ("θ (about e1)", "ψ (about e2)", "φ (about e3)")
    for end in ("start", "end"):
        load = getattr(loads, end)
        if load is None:
            continue
        held = supports.held(end)[1]
        for i in held:
            if not load.torque[i].is_zero:
                free = [f"e{k + 1}" for k in range(3) if k not in held]
                kind = getattr(supports, end)
                raise SceneError(
                    f"loads.{end}.torque[{i}]: a {kind} end holds its angle {names[i]}, so a "
                    f"torque about e{i + 1} there is taken by the support; give the torque "
                    f"about {', '.join(free) or 'no axis'} only, got "
                    f"{show_value(load.torque[i].source)}"
                )


def _integral_ratio(span: float, step: float) -> bool:
    """Whether span / step is a whole number (within STEP_TOLERANCE), and finite."""
    ratio = span / step
    return math.isfinite(ratio) and abs(ratio - round(ratio)) <= STEP_TOLERANCE * ratio


def check_later_end(end: Any, after: float) -> None:
    """SceneError unless time.end = ``end`` is later than ``after`` [s], the time of the
    checkpoint a restart continues from (cosserat_fem/io/checkpoint.py)."""
    if not (_is_number(end) and end > after):
        raise SceneError(
            f"time.end: the checkpoint is at t = {after:.10g} s; give a later end to continue "
            f"(--set time.end=...), got {show_value(end)}"
        )


def _build_time(
    raw: dict[str, Any], fixed: frozenset[str] = frozenset(), after: float | None = None
) -> Time:
    """The time span; ``fixed``: keys the caller may not change (a restart keeps time.step and
    time.start), so that a message does not suggest them; ``after`` [s]: a restart's
    checkpoint, which time.end must pass (the ends a message suggests do too)."""
    start, end, step = raw["start"], raw["end"], raw["step"]
    if after is not None:
        check_later_end(end, after)
    if not end > start:
        raise SceneError(
            f"time.end: must be > time.start = {fmt(start)} [s], got {show_value(end)}"
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
        ends = _nearest_ends(start, span, step, after)
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
    return build(Time, raw)


def _nearest_ends(start: float, span: float, step: float, after: float | None) -> str:
    """ "time.end = A or B": the whole numbers of steps nearest to ``span`` (below and above,
    at least one step, and later than ``after`` when a restart gives it)."""
    first = 1
    if after is not None:  # the first end on the step grid later than the checkpoint
        first = max(first, math.floor((after - start) / step) + 1)
        while not start + first * step > after:
            first += 1
    below = start + max(first, math.floor(span / step)) * step
    above = start + max(first, math.ceil(span / step)) * step
    return f"time.end = {below:.10g}" + (f" or {above:.10g}" if above != below else "")


def _build_solver(raw: dict) -> Solver:
    """[solver]; SceneError if PETSc options are given to the project's Newton loop, which
    reads none (they configure SNES: solver.nonlinear = "snes" or "auto")."""
    if raw["nonlinear"] == "newton" and raw["petsc"]:
        name = next(iter(raw["petsc"]))
        raise SceneError(
            f"solver.petsc.{name}: PETSc options configure SNES, but solver.nonlinear "
            '= "newton" (the project\'s loop) reads none; set solver.nonlinear = '
            '"snes" or "auto"'
        )
    return build(Solver, raw)


def _build_discretisation(raw: dict[str, Any]) -> Discretisation:
    quadrature = raw["quadrature_degree"]
    if quadrature == "auto":
        quadrature = 2 * raw["degree"]
    return build(Discretisation, raw, quadrature_degree=quadrature)


def _build_output(raw: dict[str, Any], time: Time) -> Output:
    """[output]: xdmf_interval and checkpoint_interval [s] checked as 0 or whole multiples of
    time.step; checkpoint_interval "auto" as about 1/CHECKPOINTS_PER_RUN of the run, on the step
    grid."""
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
    return build(Output, raw, checkpoint_interval=float(checkpoint_interval))


def _build_limits(raw: dict[str, Any]) -> Limits:
    memory = raw["memory"]
    return build(Limits, raw, memory=None if memory == "auto" else float(memory))


#: The groups of (48) that are positive for every valid rod (the others may be any sign).
_POSITIVE_GROUPS = frozenset("g0 nu01 nu02 g1 g2 g3 nu11 nu13 nu14 nu21 nu23 nu24 nu31".split())


def _check_derived(scene: Scene) -> None:
    """The constants derived from valid inputs must be positive, finite numbers: a section of
    a = 1e-200 m has c22 = b a³/12 = 0 in double precision, one of 1e200 m an infinite c22,
    and the groups (48) combine every input. SceneError naming the keys they come from."""
    spec = scene.rod.section
    given = ", ".join(
        f"rod.section.{k} = {fmt(v)}" for k, v in to_table(spec).items() if _is_number(v)
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
        inertia = ", rod.rotary_inertia" if scene.rod.rotary_inertia is not None else ""
        raise SceneError(
            f"rod: the dimensionless groups of (48) are not finite ({bad[0]}): rod.length, "
            f"rod.section, rod.material{inertia} and model.reference_frequency are out of the "
            "range of double precision together"
        )


def _arithmetic(exc: Exception) -> str:
    """What an arithmetic failure was, in words (OverflowError's text is an errno tuple)."""
    if isinstance(exc, OverflowError):
        return "overflow"
    if isinstance(exc, ZeroDivisionError):
        return "division by zero"
    return str(exc) or type(exc).__name__


def _bad_groups(groups: Groups) -> list[str]:
    """``name = value`` of each group of (48) that is not finite, or not positive where it must
    be (_POSITIVE_GROUPS)."""
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
    tables: TableStore | None = None,
    after: float | None = None,
) -> Scene:
    """Validate a scene given as nested dicts (as from TOML) and resolve it.

    ``overrides`` (``dotted.key=value``) are applied first; ``fixed``: keys the caller may
    not change (a restart's), which messages then do not suggest; ``tables``: where the
    tables of loads given by data are read (default: by this process, relative paths from
    the working directory); ``after`` [s]: the time of a restart's checkpoint, which time.end
    must pass. Raises :class:`SceneError`.
    """
    if not isinstance(data, dict):
        raise SceneError(f"{source}: a scene must be a table of keys, got {show_value(data)}")
    check_depth(data, source)
    merged = apply_overrides(data, overrides)
    tables = tables if tables is not None else TableStore()
    merged = structure_from_file(merged, tables)
    given = _structure_given(merged)
    raw = check_scene(merged)
    parameters = raw["parameters"]
    structure = None
    if raw["structure"] is not None:
        structure = _build_structure(raw["structure"], {*SCENE_CONSTANTS, *parameters}, tables)
        _fill_structure(raw, structure, given)
    rod = _build_rod(raw["rod"])
    supports = _build_supports(raw["supports"], {*SCENE_CONSTANTS, *parameters}, tables)
    loads = _build_loads(raw["loads"], supports, {*SCENE_CONSTANTS, *parameters}, tables)
    time = _build_time(raw["time"], frozenset(fixed), after)
    scene = Scene(
        title=raw["title"],
        parameters=parameters,
        rod=rod,
        model=_build_model(raw["model"]),
        supports=supports,
        loads=loads,
        time=time,
        discretisation=_build_discretisation(raw["discretisation"]),
        solver=_build_solver(raw["solver"]),
        output=_build_output(raw["output"], time),
        static=build(StaticSettings, raw["static"]),
        damping=build(Damping, raw["damping"]),
        limits=_build_limits(raw["limits"]),
        structure=structure,
        contact=_build_contact(raw["contact"], rod, {*SCENE_CONSTANTS, *parameters}),
        source=source,
    )
    _check_derived(scene)
    _check_structure_scene(scene)
    _check_contact_scene(scene)
    _check_section_law(scene)
    reference = _build_reference(raw["reference"], scene.expression_names())
    _check_reference(scene, reference)
    supports = _place_supports(supports, reference, rod.length)
    _check_end_torques(loads, supports)
    scene = replace(scene, supports=supports)
    _check_point_load(scene)
    _check_body_probe(scene)
    for _, component in scene.load_components():
        check_span(component, time.start, time.end, scene.static.time, rod.length)
    initial = _build_initial(raw["initial"], supports, scene.expression_names(), time.start)
    return replace(scene, initial=initial, reference=reference)


# =================================================================================== structures
#: The keys of a single rod that a structure gives otherwise (docs/structures.md): refused.
_ROD_ONLY = {
    "reference": "a structure's members are straight between their nodes; give no [reference]",
    "supports": "a structure is held at its nodes: [[structure.supports]]",
    "initial": "initial fields on a structure are not supported yet (it starts at rest)",
    "loads.start": "a structure is loaded at its nodes: [[structure.loads]]",
    "loads.end": "a structure is loaded at its nodes: [[structure.loads]]",
    "loads.point": "a structure is loaded at its nodes: [[structure.loads]]",
    "loads.follower": "a structure's loads that turn are node loads with follower = true",
    "loads.semitangential": "semitangential torques on a structure are not supported yet",
    "loads.body": "a rigid body at a structure's node is not supported yet (a single rod's "
    "end carries one: docs/rigid-bodies.md)",
}


def structure_from_file(data: dict[str, Any], tables: TableStore) -> dict[str, Any]:
    """``data`` with a [structure] ``file`` of line cells (a path relative to the scene's
    folder, read with meshio: cosserat_fem/io/line_mesh.py) replaced by the ``nodes`` and
    ``members`` it holds, each line cell a member of ``elements`` (default 1) elements, so
    that the scene holds the geometry itself. SceneError naming the key."""
    table = data.get("structure")
    if not isinstance(table, dict) or "file" not in table:
        if isinstance(table, dict) and "elements" in table:
            raise SceneError("structure.elements: the elements of each line cell of a file")
        return data
    name = table["file"]
    if not isinstance(name, str) or not name:
        raise SceneError(f"structure.file: a file of line cells, got {show_value(name)}")
    for given in ("nodes", "members"):
        if given in table:
            raise SceneError(
                f"structure.{given}: the structure's geometry comes from structure.file; give "
                "nodes and members either in the file or in the scene"
            )
    elements = table.get("elements", 1)
    if isinstance(elements, bool) or not isinstance(elements, int) or elements < 1:
        raise SceneError(f"structure.elements: a whole number ≥ 1, got {show_value(elements)}")
    from cosserat_fem.io.line_mesh import read_line_mesh

    comm = tables.comm
    if comm is None or comm.size == 1:
        geometry = read_line_mesh(tables.path(name), elements)
    else:  # rank 0 reads, every rank takes its nodes and members (one geometry, agreed)
        from cosserat_fem.common.parallel import agree

        geometry, problem = None, None
        if comm.rank == 0:
            try:
                geometry = read_line_mesh(tables.path(name), elements)
            except SceneError as exc:
                problem = exc
        agree(comm, problem)
        geometry = comm.bcast(geometry, root=0)
    assert geometry is not None, "read on rank 0, or agreed failed"
    rest = {k: v for k, v in table.items() if k not in ("file", "elements")}
    return {**data, "structure": {**rest, **geometry}}


def _structure_given(data: dict[str, Any]) -> dict[str, bool]:
    """For a scene with a [structure]: refuse the keys of a single rod it gives otherwise
    (:data:`_ROD_ONLY`), and whether it gives rod.length and discretisation.elements (which
    the structure sets: the members' total length and elements). Without one: {}."""
    if not isinstance(data, dict) or "structure" not in data:
        return {}
    for dotted, why in _ROD_ONLY.items():
        table: Any = data
        for part in dotted.split("."):
            table = table.get(part) if isinstance(table, dict) else None
        if table is not None:
            raise SceneError(f"{dotted}: {why}")
    given = {}
    for table_name, name in (("rod", "length"), ("discretisation", "elements")):
        table = data.get(table_name)
        given[name] = isinstance(table, dict) and name in table
        if isinstance(table, dict) and not given[name]:
            data[table_name] = {**table, name: 1}  # a placeholder, set by _fill_structure
    return given


def _fill_structure(raw: dict[str, Any], structure: Structure, given: dict[str, bool]) -> None:
    """Set rod.length to the members' total length and discretisation.elements to their
    total elements; SceneError naming the key if the scene gives another."""
    total = float(structure.lengths().sum())
    elements = sum(m.elements for m in structure.members)
    if given["length"] and abs(raw["rod"]["length"] - total) > 1e-9 * total:
        raise SceneError(
            f"rod.length: a structure's length is its members' total, {total:.10g} m; leave "
            f"the key out or give that, got {fmt(raw['rod']['length'])}"
        )
    if given["elements"] and raw["discretisation"]["elements"] != elements:
        raise SceneError(
            f"discretisation.elements: a structure's elements are its members', {elements} "
            f"in all; leave the key out, got {raw['discretisation']['elements']}"
        )
    raw["rod"] = {**raw["rod"], "length": total}
    raw["discretisation"] = {**raw["discretisation"], "elements": elements}


def _unit_axis(raw: Any, key: str, nonzero: bool = True) -> tuple[float, float, float]:
    """Three finite numbers, not all zero if ``nonzero``; SceneError naming ``key``."""
    for i, x in enumerate(raw):
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
            raise SceneError(f"{key}[{i}]: must be a finite number, got {show_value(x)}")
    if nonzero and not any(raw):
        raise SceneError(f"{key}: must not be zero, got {show_value(raw)}")
    x, y, z = (float(c) for c in raw)
    return x, y, z


def _member_section(raw: dict[str, Any] | None, key: str) -> MemberSection | None:
    """A member's own section law (resolved.MemberSection): numbers only (a member's section is
    constant along it; the schema checked K symmetric positive definite when all numbers),
    inertias finite and positive. SceneError naming the key."""
    if raw is None:
        return None
    for i, row in enumerate(raw["stiffness"]):
        for j, x in enumerate(row):
            if not isinstance(x, float):
                raise SceneError(
                    f"{key}.stiffness[{i}][{j}]: must be a number (a member's section is "
                    f"constant along it), got {show_value(str(x))}"
                )
    inertia = raw["inertia"]
    if inertia is not None:
        inertia = _unit_axis(inertia, f"{key}.inertia")
        for i, x in enumerate(inertia):
            if x <= 0.0:
                raise SceneError(f"{key}.inertia[{i}]: must be > 0, got {show_value(x)}")
    return build(MemberSection, raw, inertia=inertia)


def _build_structure(raw: dict[str, Any], constants: set[str], tables: TableStore) -> Structure:
    """[structure] (resolved.Structure): nodes with unique names and finite positions, no two
    at one place (so that a member has a length), members between two different known nodes,
    with a d1 normal to
    them; every node on a member, the members connected; supports and loads at known nodes,
    one support a node, loads functions of t and the constants at nodes that join at most
    two members (the point-load measure, docs/structures.md). SceneError naming the key."""
    nodes = []
    for i, entry in enumerate(raw["nodes"]):
        position = _unit_axis(entry["position"], f"structure.nodes[{i}].position", False)
        nodes.append(build(StructureNode, entry, position=position))
    names = [n.name for n in nodes]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise SceneError(f"structure.nodes[{i}].name: {name!r} is given twice")
    if not nodes:
        raise SceneError("structure.nodes: a structure needs nodes ([[structure.nodes]])")
    r0 = {n.name: np.asarray(n.position, dtype=float) for n in nodes}
    size = max(1.0, max(float(np.abs(x).max()) for x in r0.values()))
    points = np.array([n.position for n in nodes], dtype=float)
    for i in range(1, len(nodes)):
        near = np.linalg.norm(points[:i] - points[i], axis=1) <= 1e-12 * size
        if near.any():
            other = names[int(np.argmax(near))]
            raise SceneError(
                f"structure.nodes[{i}].position: the place of node {other!r}; a joint is one "
                f"node (members meeting there name it), got {show_value(list(nodes[i].position))}"
            )
    members = []
    for i, entry in enumerate(raw["members"]):
        key = f"structure.members[{i}]"
        for end in ("from", "to"):
            if entry[end] not in r0:
                raise SceneError(
                    f"{key}.{end}: unknown node {entry[end]!r}; the nodes are {', '.join(names)}"
                )
        if entry["from"] == entry["to"]:
            raise SceneError(f"{key}.to: a member joins two different nodes, got {entry['to']!r}")
        chord = r0[entry["to"]] - r0[entry["from"]]  # not zero: two nodes, two places
        length = float(np.linalg.norm(chord))
        d1 = None if entry["d1"] is None else _unit_axis(entry["d1"], f"{key}.d1")
        if d1 is not None and abs(np.dot(d1, chord)) > 1e-9 * length * np.linalg.norm(d1):
            raise SceneError(f"{key}.d1: must be normal to the member, got {show_value(d1)}")
        section = _member_section(entry["section"], f"{key}.section")
        members.append(build(StructureMember, entry, d1=d1, section=section))
    if not members:
        raise SceneError("structure.members: a structure needs members ([[structure.members]])")
    member_names = [m.name for m in members]
    for i, name in enumerate(member_names):
        if name in member_names[:i]:
            raise SceneError(f"structure.members[{i}].name: {name!r} is given twice")
    joined = {m.start for m in members} | {m.end for m in members}
    for i, name in enumerate(names):
        if name not in joined:
            raise SceneError(f"structure.nodes[{i}]: node {name!r} is joined to no member")
    reached, front = {names[0]}, [names[0]]
    while front:
        node = front.pop()
        for m in members:
            for a, b in ((m.start, m.end), (m.end, m.start)):
                if a == node and b not in reached:
                    reached.add(b)
                    front.append(b)
    if len(reached) < len(names):
        lost = next(n for n in names if n not in reached)
        raise SceneError(
            f"structure.members: the structure is not connected: node {lost!r} cannot be "
            f"reached from node {names[0]!r}"
        )
    supports: list[StructureSupport] = []
    for i, entry in enumerate(raw["supports"]):
        key = f"structure.supports[{i}]"
        if entry["node"] not in r0:
            raise SceneError(f"{key}.node: unknown node {entry['node']!r}")
        if entry["node"] in [s.node for s in supports]:
            raise SceneError(f"{key}.node: node {entry['node']!r} has a support already")
        axis = entry["axis"]
        if axis is not None:
            axis = _unit_axis(axis, f"{key}.axis")
            if entry["kind"] not in ("pinned", "sliding"):
                raise SceneError(
                    f"{key}.axis: only a pinned node (its hinge) or a sliding node has an axis"
                )
            if sum(x != 0 for x in axis) != 1:
                raise SceneError(f"{key}.axis: the axis must lie along e1, e2 or e3")
        rotation = _node_rotation(entry, key, {"t", *constants})
        supports.append(build(StructureSupport, entry, axis=axis, **rotation))
    joints = _structure_joints(raw["joints"], members, r0, {"t", *constants})
    if raw["probe"] is not None and raw["probe"] not in r0:
        raise SceneError(f"structure.probe: unknown node {raw['probe']!r}")
    if raw["probe"] in {j.node for j in joints}:
        raise SceneError(
            f"structure.probe: node {raw['probe']!r} is a joint's, whose copies turn apart; "
            "probe a node next to it"
        )
    structure = Structure(
        nodes=tuple(nodes),
        members=tuple(members),
        supports=tuple(supports),
        probe=raw["probe"],
        joints=joints,
    )
    names_t = {"t", *constants}
    loads = []
    for i, entry in enumerate(raw["loads"]):
        key = f"structure.loads[{i}]"
        _check_point_node(structure, entry["node"], key, "a load", "load")
        vectors = {}
        for name in ("force", "torque"):
            vector = _point_vector(entry[name], names_t, f"{key}.{name}", tables, "a node load")
            if any(is_data(e) for e in vector):
                raise SceneError(f"{key}.{name}: loads given by data on a structure: not yet")
            vectors[name] = vector
        loads.append(build(NodeLoad, entry, **vectors))
    bodies = []
    for i, entry in enumerate(raw["bodies"]):
        key = f"structure.bodies[{i}]"
        _check_point_node(structure, entry["node"], key, "a rigid body", "carry it at")
        body = build(NodeBody, entry)
        body.check_body(key)
        bodies.append(body)
    return replace(structure, loads=tuple(loads), bodies=tuple(bodies))


def _structure_joints(
    raw: list[dict[str, Any]],
    members: list[StructureMember],
    r0: dict[str, np.ndarray],
    names: set[str],
) -> tuple[StructureJoint, ...]:
    """[[structure.joints]] (resolved.StructureJoint): at a known node, naming members with an
    end there, each in one joint of the node, and leaving the node one member at least; a
    driven joint's angle an expression of ``names``. SceneError naming the key."""
    joints = []
    named: dict[str, set[str]] = {}
    for i, entry in enumerate(raw):
        key = f"structure.joints[{i}]"
        node = entry["node"]
        if node not in r0:
            raise SceneError(f"{key}.node: unknown node {node!r}")
        at = [m.name for m in members if node in (m.start, m.end)]
        for k, name in enumerate(entry["members"]):
            if name not in at:
                raise SceneError(
                    f"{key}.members[{k}]: {name!r} is not a member at node {node!r}; "
                    f"those are {', '.join(at)}"
                )
            if name in named.get(node, set()):
                raise SceneError(
                    f"{key}.members[{k}]: {name!r} is in another joint at node {node!r}"
                )
            named.setdefault(node, set()).add(name)
        if named[node] >= set(at):
            raise SceneError(
                f"{key}.members: a joint joins the members it names to the node's others; "
                f"node {node!r} keeps none of {', '.join(at)}"
            )
        axis = entry["axis"]
        angle = entry["angle"]
        if entry["kind"] == "driven":
            if angle is None:
                raise SceneError(f"{key}.angle: a driven joint needs its angle (rad, of t)")
            angle = Expression.parse(angle, names, f"{key}.angle")
        elif angle is not None:
            raise SceneError(f"{key}.angle: only a driven joint has an angle")
        if entry["kind"] in ("hinge", "driven"):
            if axis is None:
                raise SceneError(f"{key}.axis: a {entry['kind']} joint needs its axis, [0, 0, 1]")
            axis = _unit_axis(axis, f"{key}.axis")
        elif axis is not None:
            raise SceneError(f"{key}.axis: only a hinge or a driven joint has an axis")
        joints.append(build(StructureJoint, entry, axis=axis, angle=angle))
    return tuple(joints)


def _node_rotation(entry: dict[str, Any], key: str, names: set[str]) -> dict[str, Any]:
    """A structure support's prescribed rotation (StructureSupport.rotation, rotation_axis):
    the angle α(t) [rad] parsed (a number or an expression of t and the parameters) and the
    axis normalised, both or neither given, at a node whose angles are held (clamped or
    sliding); None for both if absent. SceneError naming the key."""
    angle, axis = entry["rotation"], entry["rotation_axis"]
    if angle is None and axis is None:
        return {"rotation": None, "rotation_axis": None}
    if angle is None:
        raise SceneError(f"{key}.rotation_axis: given without a rotation (the angle, of t)")
    if axis is None:
        raise SceneError(f"{key}.rotation: needs rotation_axis (the axis it turns about)")
    if entry["kind"] not in ("clamped", "sliding"):
        raise SceneError(
            f"{key}.rotation: a prescribed rotation needs a node whose angles are held "
            f'(clamped or sliding), but kind = "{entry["kind"]}"'
        )
    n = np.asarray(_unit_axis(axis, f"{key}.rotation_axis"))
    alpha = Expression.parse(angle, names, f"{key}.rotation")
    x, y, z = (float(c) for c in n / np.linalg.norm(n))
    return {"rotation": alpha, "rotation_axis": (x, y, z)}


def _check_point_node(structure: Structure, node: str, key: str, what: str, verb: str) -> None:
    """A node that something at a point (``what``) may be at: a known node, not a joint's
    (the point's measure is a leaf's ds or the interior facet dS of a chain; a junction of
    more members is split to a chain, resolved.Structure.splits). SceneError naming
    ``key``.node otherwise."""
    if node not in structure.positions():
        raise SceneError(f"{key}.node: unknown node {node!r}")
    if node in {j.node for j in structure.joints}:
        raise SceneError(
            f"{key}.node: {what} at node {node!r}, a joint's, is not supported yet (which "
            f"copy would it act on?); {verb} a node next to it"
        )


# ====================================================================================== contact
#: What each obstacle needs (docs/contact.md).
_OBSTACLE_KEYS = {
    "plane": ("point", "normal"),
    "sphere": ("point", "radius"),
    "cylinder": ("point", "axis", "radius"),
    "surface": ("distance",),
}


def _build_contact(raw: dict[str, Any] | None, rod: Rod, names: set[str]) -> Contact | None:
    """The [contact] table: each obstacle with the keys its kind needs and no other, its
    directions made unit, a surface's distance parsed (an expression of x, y, z and the
    scene's constants ``names``); the surface's radius resolved ("auto": a circle's or a
    tube's outer radius); SceneError naming the key."""
    if raw is None:
        return None
    obstacles = []
    for i, entry in enumerate(raw["obstacles"]):
        name = f"contact.obstacles[{i}]"
        needs = _OBSTACLE_KEYS[entry["kind"]]
        for k in ("point", "normal", "axis", "radius", "distance"):
            if k in needs and entry[k] is None:
                raise SceneError(f"{name}.{k}: a {entry['kind']} needs it")
            if k not in needs and entry[k] is not None:
                raise SceneError(f"{name}.{k}: a {entry['kind']} takes no {k}")
        values = dict(entry)
        for k in ("normal", "axis"):
            if entry[k] is not None:
                v = np.asarray(entry[k], dtype=float)
                norm = float(np.linalg.norm(v))
                if norm == 0.0:
                    raise SceneError(f"{name}.{k}: must not be the zero vector")
                values[k] = tuple(float(x) for x in v / norm)
        if entry["distance"] is not None:
            values["distance"] = Expression.parse(
                entry["distance"], {"x", "y", "z", *names}, f"{name}.distance"
            )
            if not values["distance"].names & {"x", "y", "z"}:
                raise SceneError(
                    f"{name}.distance: must depend on the position x, y, z, got "
                    f"{entry['distance']!r}"
                )
        obstacles.append(build(Obstacle, values))
    if not obstacles and not raw["self_contact"]:
        raise SceneError(
            "contact.obstacles: give one obstacle at least ([[contact.obstacles]]), or "
            "self_contact = true"
        )
    radius = raw["radius"]
    if radius == "auto":
        section = rod.section
        if section.shape == "circle" and section.diameter is not None:
            radius = section.diameter / 2
        elif section.shape == "tube" and section.outer_diameter is not None:
            radius = section.outer_diameter / 2
        else:
            raise SceneError(
                f"contact.radius: give the surface's radius [m]; \"auto\" takes a circle's or "
                f"a tube's, and the section is a {section.shape}"
            )
    return build(Contact, {**raw, "radius": radius}, obstacles=tuple(obstacles))


def _check_contact_scene(scene: Scene) -> None:
    """What contact does not support yet, refused by name (docs/contact.md, "Limits"); its
    outputs asked of a scene without it."""
    if scene.contact is None:
        for key in ("fields", "probe_fields"):
            if "contact" in getattr(scene.output, key):
                raise SceneError(f"output.{key}: contact needs a [contact] table")
        return
    for i, support in enumerate(scene.structure.supports if scene.structure else ()):
        # self contact alone takes it: its node is no slave, nor are its cells' nodes, and the
        # reactions reach its free component (rod/self_contact.py); obstacles' rows not yet
        if support.kind == "sliding" and scene.contact.obstacles:
            raise SceneError(
                f"structure.supports[{i}].kind: a sliding node holds some of its positions: "
                "obstacles' rows are written for nodes free in all or held in all (not yet "
                "for this support; self contact alone takes it)"
            )
    if scene.solver.nonlinear == "snes" or scene.solver.petsc:
        raise SceneError(
            "solver.nonlinear: contact's rows need the project's Newton loop, not SNES "
            "(no [solver.petsc] options)"
        )
    for end in ("start", "end"):
        if getattr(scene.supports, end) in ("roller", "sliding"):
            raise SceneError(
                f"supports.{end}: a {getattr(scene.supports, end)} end holds some of its "
                "positions: contact's rows are written for nodes free in all or held in all "
                "(not yet for a rod's end; self contact without obstacles takes a structure's "
                "sliding support)"
            )
    if scene.contact.kinetic > scene.contact.static_friction:
        raise SceneError(
            f"contact.kinetic_friction: must not exceed contact.static_friction "
            f"({scene.contact.static_friction}), got {scene.contact.kinetic}"
        )


def _check_structure_scene(scene: Scene) -> None:
    """What a structure does not support yet, refused by name: distributed loads that depend
    on s or are data (a structure has no single arc length), a section law of s, the printed
    end-load sign (its leaves' loads alone would take it)."""
    if scene.structure is None:
        return
    for name in ("force_density", "torque_density"):
        for i, e in enumerate(getattr(scene.loads, name)):
            if is_data(e) or e.depends_on("s"):
                raise SceneError(
                    f"loads.{name}[{i}]: on a structure a distributed load may depend on t "
                    "and constants only (no arc length s along a structure, no data yet)"
                )
    if scene.rod.section.expressions():
        raise SceneError(
            "rod.section: a section law of s on a structure is not supported yet (constants only)"
        )
    if scene.model.end_load_sign != "balance":
        # a leaf's load takes the scene's convention on ds, a chain's the balance sign on dS
        raise SceneError(
            'model.end_load_sign: a structure\'s node loads take the balance sign; "printed" '
            "would turn them at its leaves only"
        )


#: The keys of a general section law in [rod.section] (docs/sections.md), any shape.
LAW_KEYS = ("stiffness", "mass_per_length", "inertia")
#: The stations where a section law given by expressions of s is checked: 401 along the rod.
LAW_STATIONS = 401


def _check_section_law(scene: Scene) -> None:
    """A section law's expressions of s (and L, the parameters): names known, and at
    :data:`LAW_STATIONS` stations s ∈ [0, L] finite, K symmetric positive definite, μ and I
    positive; SceneError naming the key (and the station). Between stations a K that loses
    its definiteness is not seen: the law is a user's, smooth as a section is."""
    spec = scene.rod.section
    if scene.rod.rotary_inertia is not None and spec.inertia is not None:
        raise SceneError(
            "rod.section.inertia: give the inertias once, here or in rod.rotary_inertia"
        )
    entries = spec.expressions()
    if not entries:
        return
    names = dict(scene.expression_names())
    allowed = {*names, "s"}
    s = np.linspace(0.0, scene.rod.length, LAW_STATIONS)
    values = {}
    for key, expr in entries:
        parsed = Expression.parse(expr.source, allowed, key)
        value = np.broadcast_to(parsed.evaluate(**names, s=s), s.shape)
        bad = ~np.isfinite(value)
        if "stiffness" not in key:  # μ and I: positive
            bad |= value <= 0.0
        if bad.any():
            at = float(s[np.argmax(bad)])
            raise SceneError(
                f"{key}: must be finite (and > 0 for a mass) along the rod, "
                f"got {float(value[np.argmax(bad)])!r} at s = {at:.6g} m"
            )
        values[key] = value
    if spec.stiffness is None:
        return
    K = np.empty((LAW_STATIONS, 6, 6))
    for i, row in enumerate(spec.stiffness):
        for j, x in enumerate(row):
            K[:, i, j] = x if isinstance(x, float) else values[f"rod.section.stiffness[{i}][{j}]"]
    smallest = np.linalg.eigvalsh(K).min(axis=1)
    if (smallest <= 0.0).any():
        k = int(np.argmax(smallest <= 0.0))
        raise SceneError(
            f"rod.section.stiffness: not positive definite at s = {float(s[k]):.6g} m "
            f"(smallest eigenvalue {float(smallest[k]):.3g})"
        )


def _place_supports(supports: Supports, reference: ReferenceShape, length: float) -> Supports:
    """The supports on the rod at rest: its ``chord`` r0(ℓ) − r0(0) [m], and on a rod curved
    at rest a pinned end's hinge axis by default its reference binormal d0_2 there (Supports),
    SceneError naming supports.<end>_axis if that is not along e1, e2 or e3."""
    ends = np.array([0.0, length])
    r0 = reference.positions(ends)
    x, y, z = (float(c) for c in r0[1] - r0[0])
    axes: dict[str, Any] = {}
    if reference.curved:
        frames = reference.frames(ends)
        for i, end in enumerate(("start", "end")):
            if getattr(supports, end) != "pinned" or getattr(supports, f"{end}_axis") is not None:
                continue
            d2 = frames[i, 1]
            k = int(np.argmax(np.abs(d2)))
            if abs(abs(d2[k]) - 1.0) > 1e-12:
                raise SceneError(
                    f"supports.{end}_axis: required for a pinned end of this "
                    f"reference.shape = {reference.shape!r}: its binormal d0_2 there, "
                    f"{np.array2string(d2, precision=4)}, is not along e1, e2 or e3 (the "
                    f"default hinge axis); give one of them, e.g. [0, 1, 0]"
                )
            axes[f"{end}_axis"] = (
                float(np.round(d2[0])),
                float(np.round(d2[1])),
                float(np.round(d2[2])),
            )
    return replace(supports, chord=(x, y, z), **axes)


def _check_polyline(scene: Scene, reference: ReferenceShape) -> None:
    """A polyline's segments are not empty, normal to the binormal (d0_2 ⊥ d0_3), as long as
    the rod together, and its corners lie at nodes of the mesh (where its frame may jump);
    SceneError naming the key."""
    assert reference.binormal is not None, "a polyline requires it (scene/keys.py)"
    pts = np.asarray(reference.points, dtype=float)
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    ell = scene.rod.length
    for i, step in enumerate(steps):
        if not step > 1e-12 * ell:
            raise SceneError(
                f"reference.points[{i + 1}]: the same point as the one before; a "
                "segment must have a length"
            )
    b = np.asarray(reference.binormal) / np.linalg.norm(reference.binormal)
    cosines = np.abs(np.diff(pts, axis=0) @ b) / steps
    if cosines.max() > 1e-9:
        i = int(np.argmax(cosines > 1e-9))  # the first segment, not round-off's largest
        raise SceneError(
            f"reference.binormal: must be normal to every segment (d0_2 ⊥ d0_3), but its "
            f"cosine with segment {i + 1} (points[{i}] to points[{i + 1}]) is {cosines[i]:.3g}"
        )
    total = float(steps.sum())
    if abs(total - ell) > 1e-9 * ell:
        raise SceneError(
            f"reference.points: the polyline is {total:.10g} m long, rod.length = {fmt(ell)} m"
        )
    elements = scene.discretisation.elements
    at = np.cumsum(steps)[:-1] / ell * elements
    for i, node in enumerate(at):
        if abs(node - round(node)) > 1e-9 * max(1.0, node):
            raise SceneError(
                f"reference.points[{i + 1}]: the corner at s = {node * ell / elements:.6g} m is "
                f"not at a node of the mesh ({elements} elements of {ell / elements:.6g} m); "
                "choose discretisation.elements so that every corner is at a node"
            )


def _half_size(scene: Scene) -> float:
    """Half the section's largest extent [m]: a rod may not be bent tighter."""
    spec = scene.rod.section
    extents = [spec.a, spec.b, spec.diameter, spec.outer_diameter]
    return 0.5 * max([x for x in extents if x is not None] or [math.sqrt(spec.constants().area)])


#: How closely a curve's expressions must give an arc-length parametrisation and an
#: orthonormal frame (|r0'| = 1, |d0_1| = 1, d0_1 · r0' = 0), at 64 points an element. A speed
#: |r0'| = 1 + ε makes the rod's mass and stiffnesses per unit of s off by a relative ε, and
#: a frame ε from orthonormal its sections' axes by ε rad: 1e-6 is below the discretisation
#: errors the verification holds (2e-5 in of 63 in, 3e-7, for the bend) and still admits
#: constants written with 7 digits (cos(α) as 0.9800666).
CURVE_TOLERANCE = 1e-6


def _check_curve(scene: Scene, reference: ReferenceShape) -> None:
    """A curve's r0(s) and d0_1(s) are finite, s is their arc length (|r0'| = 1), d0_1 is a
    unit vector normal to the tangent d0_3 = r0', and the curve is no tighter than the section
    (|r0''| < 1/half size), at 64 points an element; SceneError naming the key and the place."""
    ell = scene.rod.length
    s = np.linspace(0.0, ell, 64 * scene.discretisation.elements + 1)
    with np.errstate(all="ignore"):
        r0, d1 = reference.positions(s), reference.curve_values(reference.director, s)
        t, bend = (reference.curve_values(reference.position, s, k) for k in (1, 2))
    for name, values in (("position", np.hstack([r0, t, bend])), ("director", d1)):
        bad = ~np.isfinite(values).all(axis=1)
        if bad.any():
            raise SceneError(
                f"reference.{name}: not a finite number at s = {s[np.argmax(bad)]:.6g} m"
            )
    speed, size, cosine = np.linalg.norm(t, axis=1), np.linalg.norm(d1, axis=1), (d1 * t).sum(1)
    checks = (
        ("position", speed - 1.0, "s must be its arc length, |dr0/ds| = 1", "|dr0/ds|", speed),
        ("director", size - 1.0, "d0_1 must be a unit vector", "|d0_1|", size),
        (
            "director",
            cosine,
            "d0_1 must be normal to the tangent d0_3 = dr0/ds",
            "their cosine",
            cosine,
        ),
    )
    # Each rule names the first place along the rod where it is broken: the place of a
    # maximum would be decided by round-off where the broken quantity is constant (a circle's
    # curvature), and differ between CPUs.
    for name, error, rule, quantity, shown in checks:
        broken = np.abs(error) > CURVE_TOLERANCE
        if broken.any():
            i = int(np.argmax(broken))
            raise SceneError(
                f"reference.{name}: {rule} (within {CURVE_TOLERANCE:g}); {quantity} is "
                f"{shown[i]:.6g} at s = {s[i]:.6g} m"
            )
    curvature, half = np.linalg.norm(bend, axis=1), _half_size(scene)
    broken = ~(curvature * half < 1.0)
    if broken.any():
        i = int(np.argmax(broken))
        raise SceneError(
            f"reference.position: its radius of curvature at s = {s[i]:.6g} m, "
            f"{1.0 / curvature[i]:.4g} m, must exceed half the section's size, {half:.4g} m"
        )


def _check_body_probe(scene: Scene) -> None:
    """probes.csv's body columns (output.probe_fields "body") are the centre of the body
    carried by the end the probe is at: SceneError without a [loads.body], on a structure
    (its bodies are at nodes: not probed yet), or with the body at the other end."""
    if "body" not in scene.output.probe_fields:
        return
    key = 'output.probe_fields: "body"'
    if scene.structure is not None:
        raise SceneError(f"{key}: a structure's bodies ([[structure.bodies]]) are not probed yet")
    body = scene.loads.body
    if body is None:
        raise SceneError(f"{key} is the centre of a [loads.body], and the scene has none")
    at = {1.0: "end", 0.0: "start"}.get(scene.probe_sigma)
    if body.end != at:
        where = f"the {at} (s = {'ℓ' if at == 'end' else 0})" if at else "mid-span"
        raise SceneError(
            f"{key} is the centre of the body at the probe's end, but the probe is at "
            f"{where} and the body at the {body.end}"
        )


def _check_point_load(scene: Scene) -> None:
    """loads.point.s lies inside the rod at a node of the mesh; SceneError naming it."""
    point, ell = scene.loads.point, scene.rod.length
    if point is None:
        return
    if not point.s < ell:
        raise SceneError(
            f"loads.point.s: must lie inside the rod, 0 < s < rod.length = {fmt(ell)} m (an end "
            f"load is [loads.end]), got {fmt(point.s)}"
        )
    elements = scene.discretisation.elements
    node = point.s / ell * elements
    if abs(node - round(node)) > 1e-9 * max(1.0, node):
        raise SceneError(
            f"loads.point.s: must be at a node of the mesh ({elements} elements of "
            f"{ell / elements:.6g} m), got {fmt(point.s)}"
        )


def _check_reference(scene: Scene, reference: ReferenceShape) -> None:
    """What a rod curved at rest does not support yet, refused by name: roller and sliding
    supports (a roller's or slide's free direction is the straight rod's tangent e3) and the
    printed torsion inertia (which divides a row that a curved rod's rows mix,
    forms/general_form.py). Pinned (a hinge, :func:`_place_supports`) and spherical ends
    hold angles that are rotations about e1, e2, e3 whatever the rest frame D0."""
    if reference.closed:
        _check_closed(scene, reference)
    if not reference.curved:
        return
    if reference.shape == "polyline":
        _check_polyline(scene, reference)
    elif reference.shape == "curve":
        _check_curve(scene, reference)
    else:
        assert reference.radius is not None, "an arc and a helix require it (scene/keys.py)"
        half = _half_size(scene)
        if not reference.radius > half:
            raise SceneError(
                f"reference.radius: must exceed half the section's size, {half:.4g} m (a rod "
                f"bent tighter than its own thickness is no rod), got {fmt(reference.radius)}"
            )
    for end in ("start", "end"):
        kind = getattr(scene.supports, end)
        if kind in ("roller", "sliding"):
            raise SceneError(
                f"supports.{end}: {kind!r} is not supported with reference.shape = "
                f"{reference.shape!r} yet (its free direction is the straight rod's e3); use "
                f"'clamped', 'pinned', 'spherical' or 'free'"
            )
    if scene.model.torsion_inertia != "polar":
        raise SceneError(
            f"model.torsion_inertia: {scene.model.torsion_inertia!r} (the paper's printed "
            f"erratum) is not defined for reference.shape = {reference.shape!r}; use 'polar'"
        )


def refuse_closed(scene: Scene, command: str) -> None:
    """SceneError for a closed rod (reference.closed) in a command other than ``modes``."""
    if scene.reference.closed:
        raise SceneError(
            f"reference.closed: a closed rod has modes only ({command} needs its unknowns "
            "joined at s = 0 and s = ℓ, which its solver does not have yet); use "
            "cosserat-fem modes"
        )


def refuse_contact(scene: Scene | None, command: str) -> None:
    """SceneError for a scene with [contact] in a command that does not impose it
    (docs/contact.md: static and run do; the linearisations about a state and the reduced
    models do not have its rows yet)."""
    if scene is not None and scene.contact is not None:
        raise SceneError(
            f"contact: {command} does not impose contact yet (static and run do); remove the "
            "[contact] table (--unset contact) to analyse the rod without its obstacles"
        )


def refuse_structure(scene: Scene | None, command: str) -> None:
    """SceneError for a structure (scene.structure) in a command that supports the single rod
    only (docs/structures.md: run, static, modes, continue, stability and validate take
    structures)."""
    if scene is not None and scene.structure is not None:
        raise SceneError(
            f"structure: {command} is not supported on a structure yet (run, static, modes, "
            "continue, stability, a periodic orbit, validate and sweeps of plain members "
            "are); see docs/structures.md"
        )


#: How far apart a closed rod's two ends may be at rest: [m] per m of rod, and in the frame.
CLOSURE_TOLERANCE = 1e-9


def _check_closed(scene: Scene, reference: ReferenceShape) -> None:
    """A closed rod (reference.closed) has no ends: both supports free, no end loads, and its
    reference curve must close, position and frame (a ring: an arc of length 2π R)."""
    for end in ("start", "end"):
        if getattr(scene.supports, end) != "free":
            raise SceneError(
                f"supports.{end}: a closed rod (reference.closed = true) has no ends to hold; "
                f"use 'free', got {getattr(scene.supports, end)!r}"
            )
        load = getattr(scene.loads, end)
        if load is not None and not all(e.is_zero for e in (*load.force, *load.torque)):
            raise SceneError(
                f"loads.{end}: a closed rod (reference.closed = true) has no end to load"
            )
    for name, form_load in scene.loads.form_loads():  # a load declared with its physics
        if getattr(form_load, "end", None) is not None:
            raise SceneError(
                f"loads.{name}.end: a closed rod (reference.closed = true) has no end to load"
            )
    ell = scene.rod.length
    ends = np.array([0.0, ell])
    r0, D0 = reference.positions(ends), reference.frames(ends)
    gap, turn = float(np.linalg.norm(r0[1] - r0[0])), float(np.abs(D0[1] - D0[0]).max())
    if gap > CLOSURE_TOLERANCE * ell or turn > CLOSURE_TOLERANCE:
        hint = ""
        if reference.shape == "arc":
            assert reference.radius is not None, "an arc requires it (scene/keys.py)"
            hint = (
                f" (an arc closes when rod.length = 2π reference.radius = "
                f"{2 * math.pi * reference.radius!r} m)"
            )
        raise SceneError(
            f"reference.closed: the rod's reference does not close: its ends are {gap:.3g} m "
            f"apart and their frames differ by {turn:.3g}{hint}"
        )


def load_scene(path: str | Path, overrides: Overrides = ()) -> Scene:
    """Read, override and validate a TOML scene file; collective under MPI: rank 0 reads
    it, every rank parses its bytes (schema.read_input), whose SHA-256 the scene keeps; its
    tables (loads given by data) are read relative to its folder, by rank 0 too."""
    raw = read_input(path, "scene file")
    tables = TableStore.collective(Path(path).parent)
    scene = scene_from_dict(
        parse_toml(raw, path), source=str(path), overrides=overrides, tables=tables
    )
    return replace(scene, source_sha256=hashlib.sha256(raw).hexdigest())
