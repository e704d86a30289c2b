"""``cosserat-fem validate``: a scene resolved, with units, and what a run of it will solve."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cosserat_fem.forms.kinematics import P_NAMES
from cosserat_fem.scene.build import PLANAR, Scene
from cosserat_fem.scene.load_data import is_data
from cosserat_fem.scene.schema import SCHEMA, Parameters, Table


def _unit(spec: Any) -> str:
    unit = getattr(spec, "unit", "")
    return f" [{unit}]" if unit else ""


def _show(value: Any) -> str:
    """``value`` as a scene file writes it: strings quoted, booleans in lower case, floats to 10
    digits, lists in brackets."""
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    if isinstance(value, dict):  # a load component given by a table: its inline table
        return "{" + ", ".join(f"{k} = {_show(v)}" for k, v in value.items()) + "}"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, bool):
        return str(value).lower()
    return f"{value:.10g}" if isinstance(value, float) else str(value)


def _lines(data: dict, table: Table, prefix: str) -> list[str]:
    """Lines ``  key = value [unit]`` of ``data`` (a part of :meth:`Scene.to_dict`) with the
    units of ``table``; keys dotted after ``prefix``, nested tables flattened."""
    out = []
    for name, value in data.items():
        spec = table.fields.get(name)
        key = f"{prefix}.{name}" if prefix else name
        if isinstance(spec, Table) and isinstance(value, dict):
            out += _lines(value, spec, key)
        elif isinstance(spec, Parameters) and isinstance(value, dict):
            out += [f"  {key}.{k} = {_show(v)}" for k, v in value.items()]
        else:
            out.append(f"  {key} = {_show(value)}{_unit(spec)}")
    return out


def describe_scene(scene: Scene) -> str:
    """The resolved scene (every key, defaults filled in, with units) and derived numbers."""
    section = scene.rod.section.constants()
    mat = scene.rod.material
    plane = scene.plane()
    unknowns = "all 12 of p and q"
    if plane is not None:
        solved = ", ".join(P_NAMES[i] for i in PLANAR[plane] if i < 6)
        unknowns = f"{solved} and their rates (planar in {plane})"
    nodes = scene.discretisation.elements * scene.discretisation.degree + 1
    if scene.structure is not None:  # a vertex per node, elements − 1 inside each member
        st = scene.structure
        nodes += len(st.nodes) - 1 - len(st.members)
    absent = scene.absent_terms()
    lines = [f"cosserat-fem: {scene.source}: valid", f"  title = {_show(scene.title)}"]
    data = scene.to_dict()
    data.pop("title")
    lines += _lines(data, SCHEMA, "")
    lines += [
        "derived:",
        f"  section: A = {section.area:.6g} m^2, c11 = {section.c11:.6g} m^4, "
        f"c22 = {section.c22:.6g} m^4, c33 = {section.c33:.6g} m^4, "
        f"kappa = {section.shear_coefficient:.6g}",
        f"  material: G = {mat.shear_modulus:.6g} Pa",
        f"  omega0 = {scene.omega0:.10g} rad/s (tau = omega0 t)",
        f"  time: {scene.time.n_steps} steps of {scene.time.step:.6g} s"
        + (" (adaptive: first step and output interval)" if scene.time.adaptive else ""),
        f"  unknowns: {unknowns}; {nodes * (6 if plane else 12)} dofs",
        _reference_line(scene),
        f"  not in the form (zero): {', '.join(absent) or 'nothing'}",
        *_data_lines(scene),
    ]
    return "\n".join(lines)


def _data_lines(scene: Scene) -> list[str]:
    """A line for each load component given by data (cosserat_fem/scene/load_data.py): what it is,
    with the unit of its load."""
    lines = []
    for key, component in scene.load_components():
        if is_data(component):
            spec: Any = SCHEMA
            for name in key.partition("[")[0].split("."):
                spec = spec.fields[name]
            lines.append(f"  {key}{_unit(spec)}: {component.describe()}")
    return ["load data:", *lines] if lines else []


def _reference_line(scene: Scene) -> str:
    """The rod at rest: its shape, length, end points and the total turning of its tangent."""
    ref, ell = scene.reference, scene.rod.length
    if scene.structure is not None:
        st = scene.structure
        return (
            f"  structure: {len(st.nodes)} nodes, {len(st.members)} straight members joined "
            f"rigidly, length {ell:.6g} m in all (docs/structures.md)"
        )
    ends = ref.positions(np.array([0.0, ell]))
    turning = ref.turning(ell)
    start, end = (", ".join(f"{x:.6g}" for x in point) for point in ends)
    closed = ", closed: its ends joined (modes only)" if ref.closed else ""
    return (
        f"  reference: {ref.shape}, length {ell:.6g} m, from ({start}) to ({end}) m, "
        f"total turning {turning:.6g} rad ({math.degrees(turning):.6g} deg){closed}"
    )
