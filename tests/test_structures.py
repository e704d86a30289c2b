"""Structures: straight rods joined rigidly at shared nodes (issue 29 item 1, docs/structures.md).

A structure's mesh is an interval mesh embedded in 3D whose vertices are the rest positions
r0/ℓ; a junction is one vertex shared by its members' cells, so they share p and q there (a
rigid joint), and d/dσ is the tangential derivative (forms/kinematics.py d_sigma). Checked here:
the one-member structure against the single rod (gdim 1), Lee's frame as three members against
its kinked polyline rod, a portal frame and a T against the linear frame (stiffness method with
exact Timoshenko members, derived here), serial against mpirun -n 2, and the bad input.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import shutil
import sys

import numpy as np
import pytest
from conftest import ROOT, run_command, subprocess_env
from virtual_display import run_pvpython

from cosserat_fem import api
from cosserat_fem.common.errors import SceneError
from cosserat_fem.scene.build import load_scene, read_toml, scene_from_dict

LEE = ROOT / "scenes" / "lee_frame.toml"
PORTAL = ROOT / "scenes" / "portal_frame.toml"
# Lee's section and material (EA = 4320, EI = 1440 in the plane, κ G A = 1384.6).
E, NU, AREA, I_PLANE, KAPPA = 720.0, 0.3, 6.0, 2.0, 5.0 / 6.0


def nodal(model) -> dict[tuple, np.ndarray]:
    """{rest position r0 [m] rounded to 1e-7: U's 12 values} at every Lagrange node of the
    model: a structure's r0 = ℓ times its mesh coordinates, a rod's its reference curve at
    s = ℓ σ."""
    n = model.V.dofmap.index_map.size_local
    coords = model.V.tabulate_dof_coordinates()[:n]
    if model.scene.structure is not None:
        r0 = coords * model.length
    else:
        r0 = model.scene.reference.positions(coords[:, 0] * model.length)
    U = model.layout.full_array(model.U.x.array)[:n]  # a planar rod's embedded in 12
    return {tuple(np.round(r, 7)): U[i] for i, r in enumerate(r0)}


def difference(a, b) -> float:
    """max |U_a − U_b| over the nodes of a (the same rest positions in b), over max |U_a|."""
    one, two = nodal(a), nodal(b)
    assert one.keys() == two.keys()
    diff = max(float(np.abs(one[k] - two[k]).max()) for k in one)
    return diff / max(float(np.abs(v).max()) for v in one.values())


def rod_and_structure(end_force, end_torque, elements=8, gravity=(0, 0, 0)):
    """The paper's rod along e3 (Lee's section, L = 120, clamped at s = 0, an end load,
    ``gravity``) and the same as a one-member structure from (0, 0, 0) to (0, 0, 120), as
    scenes (:func:`rod_and_structure_data`'s)."""
    return tuple(
        scene_from_dict(d) for d in rod_and_structure_data(end_force, end_torque, elements, gravity)
    )


def rod_and_structure_data(end_force, end_torque, elements=8, gravity=(0, 0, 0)):
    """The data of :func:`rod_and_structure`'s scenes."""
    base = read_toml(LEE)
    for key in ("reference", "supports", "loads"):
        base.pop(key)
    base["rod"]["length"] = 120.0
    base["discretisation"] = {"elements": elements, "degree": 3}
    base["time"] = {"end": 0.05, "step": 0.01}
    rod = {
        **base,
        "supports": {"start": "clamped", "end": "free"},
        "loads": {"end": {"force": end_force, "torque": end_torque}, "gravity": list(gravity)},
    }
    structure = {**base, "rod": {k: v for k, v in base["rod"].items() if k != "length"}}
    structure["discretisation"] = {"degree": 3}
    structure["loads"] = {"gravity": list(gravity)}
    structure["structure"] = {
        "nodes": [{"name": "A", "position": [0, 0, 0]}, {"name": "B", "position": [0, 0, 120]}],
        "members": [{"name": "m", "from": "A", "to": "B", "elements": elements}],
        "supports": [{"node": "A", "kind": "clamped"}],
        "loads": [{"node": "B", "force": end_force, "torque": end_torque}],
    }
    return rod, structure


def test_one_member_structure_is_the_single_rod():
    """A one-member structure along e3 (mesh in 3D, the rest frame D0 = I as a DG0 field, the
    tangential derivative) against the single rod (mesh in 1D, the paper's forms): an end load
    that bends it in both planes and twists it (tip rotation ~0.5 rad, P L²/EI = 1) and a
    gravity across and along it (ρ A g L = 0.072, a distributed load), statics
    in 4 load steps and 5 steps of a dynamic run after the load is applied suddenly. The two
    discretisations are the same (8 P3 cells, the same quadrature): the forms differ in their
    operations only (D0 D and t0 + p' with D0 = I, t0 = e3; grad f · t with t = e3), so the
    states agree to round-off amplified by Newton's tolerance: 1e-9 of max |U| (measured
    3.3e-13 statically, 6.8e-15 after the dynamic steps)."""
    rod, structure = rod_and_structure([0.1, 0.05, 0], [0, 0, 2.0], gravity=(0, 1e-4, -1e-4))
    rod = dataclasses.replace(rod, static=dataclasses.replace(rod.static, load_steps=4))
    structure = dataclasses.replace(
        structure, static=dataclasses.replace(structure.static, load_steps=4)
    )
    a, b = api.static(rod), api.static(structure)
    tip = a.probes[-1]
    assert abs(tip[5]) > 0.3  # ψ: a large rotation, not the linear range
    assert difference(a.model, b.model) < 1e-9
    np.testing.assert_allclose(b.probes[-1], tip, rtol=0, atol=1e-9 * np.abs(tip).max())
    c, d = api.run(rod), api.run(structure)
    assert difference(c.model, d.model) < 1e-9
    assert np.abs(c.model.U.x.array).max() > 1e-4  # it moved


def test_a_follower_node_load_is_the_rods_follower_end_load():
    """A follower force and torque at the leaf of the one-member structure along e3 (D0 = I,
    so the node's rest basis is the end's directors at rest) against the single rod's
    [loads.follower] at its end (components along d1, d2, d3): the same forms on the two
    meshes, within 1e-9 of max |U| as :func:`test_one_member_structure_is_the_single_rod`
    (a tip rotation > 0.3 rad: the load has turned with the end). And inside a chain: the
    same load at the middle node B of A - B - C (|AB| = 120, |BC| = 60, its interior facet
    dS, one side) leaves AB as the one member with the load at its leaf (BC unloaded, straight,
    carried along): within 1e-9 on AB's nodes."""
    force, torque = [0.1, 0.05, 0.02], [0, 0.5, 1.0]
    rod_data, structure = rod_and_structure_data([0, 0, 0], [0, 0, 0])
    rod_data["loads"] = {"follower": {"force": force, "torque": torque}}
    rod_data["static"] = {"load_steps": 4}
    data = copy.deepcopy(structure)
    data["structure"]["loads"] = [{"node": "B", "force": force, "torque": torque, "follower": True}]
    data["static"] = {"load_steps": 4}
    a, b = api.static(scene_from_dict(rod_data)), api.static(scene_from_dict(data))
    assert max(abs(a.probes[-1][4]), abs(a.probes[-1][5])) > 0.3  # turned
    assert difference(a.model, b.model) < 1e-9
    chain = copy.deepcopy(structure)
    chain["structure"]["nodes"].append({"name": "C", "position": [0, 0, 180]})
    chain["structure"]["members"].append({"name": "n", "from": "B", "to": "C", "elements": 4})
    chain["structure"]["loads"] = data["structure"]["loads"]
    chain["static"] = {"load_steps": 4}
    c = api.static(scene_from_dict(chain))
    one, two = nodal(b.model), nodal(c.model)

    def physical(values, ell):  # positions [m] (p = x/ℓ, ℓ the members' total) and angles
        return np.concatenate([values[:3] * ell, values[3:6]])

    gaps = [physical(one[k], 120.0) - physical(two[k], 180.0) for k in one]
    scale = max(float(np.abs(physical(v, 120.0)).max()) for v in one.values())
    assert max(float(np.abs(g).max()) for g in gaps) < 1e-9 * scale


def test_one_member_structure_moves_its_chart_as_the_rod():
    """The one-member structure and the single rod (all twelve unknowns: planar = "off") under
    a tip torque of 40 about e1 and a force across (θ at the tip 1.46 rad, past the chart's
    move at 0.9 rad, charts.RESET_THETA): both move their charts (the rod's nodes signed
    along σ, the structure's breadth-first along its mesh from another first node: the same
    frames, Q and −Q being one rotation), so their states in the moved charts agree to
    round-off: 1e-9 of max |U| (measured 5.9e-14)."""
    rod, structure = rod_and_structure([0, 0.02, 0], [40.0, 0, 0])
    rod = dataclasses.replace(
        rod,
        static=dataclasses.replace(rod.static, load_steps=8),
        discretisation=dataclasses.replace(rod.discretisation, planar="off"),
    )
    structure = dataclasses.replace(
        structure, static=dataclasses.replace(structure.static, load_steps=8)
    )
    a, b = api.static(rod), api.static(structure)
    assert a.model.chart_moved and b.model.chart_moved
    assert a.probes[-1][4] > 1.4
    assert difference(a.model, b.model) < 1e-9


def t_structure(elements: int, left: tuple[str, str] = ("E", "B")) -> dict:
    """A T's [structure] without loads: a column A-B of 120 clamped at A, arms B-C and (by
    ``left``) E-B of 60 along ±e1, ``elements`` cells each."""
    return {
        "nodes": [
            {"name": "A", "position": [0, 0, 0]},
            {"name": "B", "position": [0, 0, 120]},
            {"name": "C", "position": [60, 0, 120]},
            {"name": "E", "position": [-60, 0, 120]},
        ],
        "members": [
            {"name": "column", "from": "A", "to": "B", "elements": elements},
            {"name": "right", "from": "B", "to": "C", "elements": elements},
            {"name": "left", "from": left[0], "to": left[1], "elements": elements},
        ],
        "supports": [{"node": "A", "kind": "clamped"}],
    }


def chart_tree(reverse: bool):
    """A T (column A-B, arms B-C and E-B of 60, 4 P3 cells each, clamped at A) whose arms
    twist under torques ±30 about e1 at their tips and C pushed along e2 (θ at C 1.23 rad:
    the chart moves), the left arm given from B to E if ``reverse``; 8 load steps."""
    data = read_toml(PORTAL)
    data["static"]["load_steps"] = 8
    data["structure"] = t_structure(4, ("B", "E") if reverse else ("E", "B"))
    data["structure"]["loads"] = [
        {"node": "C", "torque": [30, 0, 0], "force": [0, 0.05, 0]},
        {"node": "E", "torque": [-30, 0, 0]},
    ]
    return scene_from_dict(data)


def test_a_member_given_the_other_way_round_is_the_same_structure():
    """The T of :func:`chart_tree` with its left arm given from E to B and from B to E: its
    cells then run the other way, with d0_1 and d0_3 negated (rod/structure.py), and the
    rotations are large enough that both move their charts (through the junction). The same
    structure: the nodes' positions agree to round-off, 1e-9 of the largest displacement
    (measured 3.5e-15), and so do the probe's rows (C)."""
    a, b = api.static(chart_tree(False)), api.static(chart_tree(True))
    assert a.model.chart_moved and b.model.chart_moved
    one, two = nodal(a.model), nodal(b.model)
    largest = max(float(np.abs(v[:3]).max()) for v in one.values())
    assert largest > 0.05
    assert max(float(np.abs(one[k][:3] - two[k][:3]).max()) for k in one) < 1e-9 * largest
    np.testing.assert_allclose(b.probes[-1], a.probes[-1], rtol=0, atol=1e-9)


def lee_as_structure(P: float, load_steps: int) -> tuple:
    """scenes/lee_frame.toml (a kinked polyline rod, 20 P3, hinges about e2) and the same as a
    structure of three members (the column 10 cells, the beam 2 + 8 cells split at the load
    point s = 144), both under P, as scenes."""
    overrides = [f"parameters.P={P}", f"static.load_steps={load_steps}"]
    rod = load_scene(LEE, overrides)
    data = read_toml(LEE)
    for key in ("reference", "supports", "loads"):
        data.pop(key)
    data["rod"].pop("length")
    data["discretisation"].pop("elements")
    data["parameters"]["P"] = P
    data["static"]["load_steps"] = load_steps
    data["structure"] = {
        "nodes": [
            {"name": "A", "position": [0, 0, 0]},
            {"name": "B", "position": [0, 0, 120]},
            {"name": "P", "position": [24, 0, 120]},
            {"name": "C", "position": [120, 0, 120]},
        ],
        "members": [
            {"name": "column", "from": "A", "to": "B", "elements": 10},
            {"name": "near", "from": "B", "to": "P", "elements": 2},
            {"name": "far", "from": "P", "to": "C", "elements": 8},
        ],
        "supports": [{"node": "A", "kind": "pinned"}, {"node": "C", "kind": "pinned"}],
        "loads": [{"node": "P", "force": [0, 0, "-P"]}],
    }
    return rod, scene_from_dict(data)


def test_lee_frame_as_a_structure_is_the_kinked_rod():
    """Lee's frame as three members with a rigid corner at B against scenes/lee_frame.toml's
    polyline rod: the same 20 P3 cells, the same frames on each (d0_2 = e2; d0_1 = e2 × d0_3,
    the polyline's b × t), the same hinges about e2 at the ends and the same point load, at
    P = 1.2 (65 % of the first limit load 1.854, 6 steps: ψ up to 0.48 rad), and 5 steps of a
    dynamic run with P applied suddenly. Only the arithmetic differs (the structure's D0 on
    the column is I; its derivative the tangential one): 1e-8 of max |U| (measured 2.0e-15
    statically, 1.0e-15 in the run)."""
    rod, structure = lee_as_structure(1.2, 6)
    a, b = api.static(rod), api.static(structure)
    assert np.abs(a.model.U.x.array.reshape(-1, 12)[:, 4]).max() > 0.3
    assert difference(a.model, b.model) < 1e-8
    short = [
        dataclasses.replace(x, time=dataclasses.replace(x.time, end=0.05)) for x in (rod, structure)
    ]
    c, d = api.run(short[0]), api.run(short[1])
    assert np.abs(c.model.U.x.array).max() > 0.1  # it moved
    assert difference(c.model, d.model) < 1e-8


def timoshenko_element(a, b, EA, EI, GA) -> np.ndarray:
    """The 6×6 stiffness of an exact Timoshenko member from the point ``a`` to ``b`` in the
    x-z plane, dofs (ux, uz, β) at a then b, β counter-clockwise in (x, z) (about −e2): axial
    EA/L, bending with shear (the end forces of w'' linear in the member, Φ = 12 EI/(GA L²))."""
    d = np.subtract(b, a)
    L = float(np.hypot(*d))
    c, s = d / L
    phi = 12 * EI / (GA * L * L)
    bend = (
        EI
        / (L**3 * (1 + phi))
        * np.array(
            [
                [12, 6 * L, -12, 6 * L],
                [6 * L, (4 + phi) * L * L, -6 * L, (2 - phi) * L * L],
                [-12, -6 * L, 12, -6 * L],
                [6 * L, (2 - phi) * L * L, -6 * L, (4 + phi) * L * L],
            ]
        )
    )
    k = np.zeros((6, 6))
    k[np.ix_([0, 3], [0, 3])] = EA / L * np.array([[1, -1], [-1, 1]])
    k[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])] = bend
    T = np.kron(np.eye(2), np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]))
    return T.T @ k @ T


def frame_linear(nodes, members, clamped, loads, EA, EI, GA):
    """The linear plane frame in the x-z plane (stiffness method, members
    :func:`timoshenko_element`): ``nodes`` {name: (x, z)}, ``members`` [(from, to)],
    ``clamped`` node names, ``loads`` {name: (Fx, Fz) or (Fx, Fz, M)}, M a moment
    counter-clockwise in (x, z). Returns {name: (ux, uz, β)}, β the rotation
    counter-clockwise in (x, z) (about −e2)."""
    free = [n for n in nodes if n not in clamped]
    index = {n: 3 * i for i, n in enumerate(free)}
    K = np.zeros((3 * len(free), 3 * len(free)))
    for a, b in members:
        kg = timoshenko_element(nodes[a], nodes[b], EA, EI, GA)
        dofs = [index[n] + i if n in index else -1 for n in (a, b) for i in range(3)]
        for i, di in enumerate(dofs):
            for j, dj in enumerate(dofs):
                if di >= 0 and dj >= 0:
                    K[di, dj] += kg[i, j]
    f = np.zeros(len(K))
    for n, load in loads.items():
        f[index[n] : index[n] + len(load)] = load
    u = np.linalg.solve(K, f)
    return {n: u[index[n] : index[n] + 3] for n in free}


def assert_linear_frame(model, nodes: dict, linear: dict, names) -> None:
    """The in-plane displacements (x, z) of ``model``'s ``names`` within 1e-6 of the largest
    of :func:`frame_linear`'s ``linear`` there (``nodes`` {name: (x, z)} their rest places):
    the frames' tolerance (one P3 cell a member holds the linear fields exactly; the
    geometric nonlinearity and Newton's tolerance are left)."""
    U, ell = nodal(model), model.length
    for name in names:
        x, z = nodes[name]
        got = U[(float(x), 0.0, float(z))][[0, 2]] * ell
        want = linear[name][:2]
        assert np.abs(got - want).max() < 1e-6 * np.abs(want).max(), (name, got, want)


def stiffnesses() -> tuple[float, float, float]:
    G = E / (2 * (1 + NU))
    return E * AREA, E * I_PLANE, KAPPA * G * AREA


def with_elements(scene, n: int, degree: int):
    """``scene`` with ``n`` cells of ``degree`` on every member."""
    st = scene.structure
    members = tuple(dataclasses.replace(m, elements=n) for m in st.members)
    return dataclasses.replace(
        scene,
        structure=dataclasses.replace(st, members=members),
        discretisation=dataclasses.replace(
            scene.discretisation, elements=n * len(members), degree=degree
        ),
    )


@pytest.mark.long
def test_lee_frame_as_a_structure_continues_as_the_kinked_rod():
    """Pseudo-arclength continuation (cosserat_fem/nls/arclength.py) of Lee's frame, P = 10 λ,
    as the kinked rod (its load point s = 144 probed) and as the structure of three members
    (its probe node P, the loaded one; :func:`lee_as_structure`): the same discretisation
    (tests/test_structures.py, statics within 1e-8), so the same path: the first 13 points
    (up past the limit load, whose λ is located, and back): λ and the load point's position
    within 1e-8 of the largest value (measured ~1e-11: the continuation's corrector tolerance on the
    same equations), the limit load's λ within 1e-8 relative (the published limit load of
    this discretisation, 18.55, is tests/test_snap_through.py's). And the stability of the
    two at λ = 0.1: the same lowest eigenvalues of K φ = λ M φ within 1e-8 relative."""
    rod, structure = lee_as_structure(10.0, 1)
    options = {"max_points": 13, "switch": 0, "directions": (1,)}
    a = api.continuation(rod, 0.0, 1.0, probe=144.0, **options)
    b = api.continuation(structure, 0.0, 1.0, **options)
    # λ and the load point's position (the angles: the rod's of its directors, the
    # structure's of its node's rotation from the rest, tests/test_structures.py probes)
    one = np.array([[q.factor, *q.tip[:3]] for q in a.branches[0].points])
    two = np.array([[q.factor, *q.tip[:3]] for q in b.branches[0].points])
    assert one.shape == two.shape == (13, 4)
    np.testing.assert_allclose(two, one, rtol=0, atol=1e-8 * np.abs(one).max(axis=0).max())
    limits = [[q.factor for q in r.branches[0].special if q.kind == "limit"] for r in (a, b)]
    assert len(limits[0]) == len(limits[1]) == 1
    assert abs(limits[1][0] - limits[0][0]) <= 1e-8 * abs(limits[0][0])
    rod_at, structure_at = api.stability_at(rod, 0.1), api.stability_at(structure, 0.1)
    assert rod_at.status == structure_at.status == "stable"
    np.testing.assert_allclose(
        np.sort(np.real(structure_at.eigenvalues))[:4],
        np.sort(np.real(rod_at.eigenvalues))[:4],
        rtol=1e-8,
    )
    with pytest.raises(SceneError, match="^probe: a structure has no arclength s"):
        api.continuation(structure, 0.0, 1.0, probe=144.0, **options)


def test_a_one_member_structures_periodic_orbit_is_the_rods():
    """The periodic orbit (cosserat_fem/analysis/periodic.py: shooting over one forcing
    period, 60 SDIRK steps, one settled period) of the rod of :func:`rod_and_structure` (4
    P3 cells) under an end force F sin(ω t) along e1 at ω = 1.1 ω1, damped, and of the same
    as a one-member structure with the force at its leaf: the same equations on the two
    meshes, so the same amplitude (the probe's x, the tip's), within 1e-8 relative (the
    shooting's tolerance 1e-9; measured 2e-12), stable both; the structure solves all
    twelve components, so its Floquet multipliers hold the rod's (each within 1e-6 of one of
    the structure's: the in-plane motions are an invariant subspace) and more."""
    rod_data, structure_data = rod_and_structure_data([0, 0, 0], [0, 0, 0], elements=4)
    omega1 = api.modes(scene_from_dict(rod_data), 1)[0].omega
    for data in (rod_data, structure_data):
        data["parameters"] = {"w": 1.1 * omega1, "F": 1e-3}
        data["damping"] = {"translational": 1e-3}
        data["output"] = {"xdmf": False, "checkpoint": False}
    rod_data["loads"]["end"] = {"force": ["F*sin(w*t)", 0, 0], "torque": [0, 0, 0]}
    structure_data["structure"]["loads"] = [{"node": "B", "force": ["F*sin(w*t)", 0, 0]}]
    rod, structure = (
        api.periodic_orbit(scene_from_dict(d), "2*pi/w", steps_per_period=60, settle=1)
        for d in (rod_data, structure_data)
    )
    assert rod.amplitude > 1.0  # 1.79 (the tip's x over a length of 120)
    assert abs(structure.amplitude - rod.amplitude) <= 1e-8 * rod.amplitude
    assert rod.stability == structure.stability == "stable"
    for mu in rod.multipliers:
        assert np.abs(np.asarray(structure.multipliers) - mu).min() < 1e-6, mu


def test_portal_frame_small_load_is_the_linear_frame():
    """scenes/portal_frame.toml (two columns clamped at the base, a beam joined rigidly, F at
    B along e1, F = 1e-6: sway 7.2e-5 of 120) against the linear frame (:func:`frame_linear`,
    EA = 4320, EI = 1440, κGA = 1384.6, computed here).

    P3 holds the linear Timoshenko frame's fields exactly (w cubic, θ quadratic in each member
    under end loads), so one cell a member gives its sway: the rest is the geometric
    nonlinearity, of the order of the rotations (3.6e-7) and of the Newton tolerance: within
    1e-6 relative (measured 3.2e-8), and ψ_B = −β_B (ψ turns about e2, β about −e2).
    The vertical displacement of B, 1.19e-8 (the columns' axial strain), also carries the
    columns' second-order shortening ~ u_B²/H = 4e-11: within 4 u_B²/H of the linear one.
    P2 converges: errors in the sway at 2, 4, 8 cells a member at an observed rate ≥ 1.8
    (measured 2.08 and 2.26; the cubic's interpolation error in P2, order h²)."""
    EA, EI, GA = stiffnesses()
    nodes = {"A": (0, 0), "B": (0, 120), "C": (120, 120), "D": (120, 0)}
    linear = frame_linear(
        nodes, [("A", "B"), ("B", "C"), ("D", "C")], {"A", "D"}, {"B": (1e-6, 0.0)}, EA, EI, GA
    )
    ux, uz, beta = linear["B"]
    scene = load_scene(PORTAL, ["parameters.F=1e-6"])
    row = api.static(with_elements(scene, 1, 3)).probes[-1]  # λ, x, y, z, θ, ψ, φ at B
    assert abs(row[1] - ux) < 1e-6 * ux
    assert abs(row[3] - uz) < 4 * ux**2 / 120
    assert abs(row[5] + beta) < 1e-6 * abs(beta)
    errors = [abs(api.static(with_elements(scene, n, 2)).probes[-1][1] - ux) for n in (2, 4, 8)]
    rates = [math.log2(errors[i] / errors[i + 1]) for i in range(2)]
    assert min(rates) > 1.8, (errors, rates)


def portal_modes_linear(n: int, count: int = 4) -> np.ndarray:
    """The lowest ``count`` angular frequencies [rad/s] of the portal frame of
    scenes/portal_frame.toml as a linear plane frame: ``n`` exact Timoshenko elements a member
    (:func:`timoshenko_element`) and lumped masses, ρA h/2 in both translations and
    ρI h/2 in the rotation at each end of an element (ρ = 1), the bases clamped. Lumping
    errs by O(h²)."""
    EA, EI, GA = stiffnesses()
    index: dict[tuple, int] = {}
    elements = []
    for a, b in (((0, 0), (0, 120)), ((0, 120), (120, 120)), ((120, 0), (120, 120))):
        a, b = np.asarray(a, float), np.asarray(b, float)
        ids = [
            index.setdefault(tuple(np.round(a + (b - a) * j / n, 9)), len(index))
            for j in range(n + 1)
        ]
        elements += list(zip(ids[:-1], ids[1:], strict=True))
    points = {i: np.array(p) for p, i in index.items()}
    K, M = np.zeros((3 * len(index), 3 * len(index))), np.zeros(3 * len(index))
    for i, j in elements:
        L = float(np.linalg.norm(points[j] - points[i]))
        dofs = [3 * i, 3 * i + 1, 3 * i + 2, 3 * j, 3 * j + 1, 3 * j + 2]
        K[np.ix_(dofs, dofs)] += timoshenko_element(points[i], points[j], EA, EI, GA)
        for q in (i, j):
            M[3 * q : 3 * q + 2] += AREA * L / 2
            M[3 * q + 2] += I_PLANE * L / 2
    bases = {index[(0.0, 0.0)], index[(120.0, 0.0)]}
    keep = [d for d in range(len(M)) if d // 3 not in bases]
    Kf, m = K[np.ix_(keep, keep)], np.sqrt(M[keep])
    values = np.linalg.eigvalsh(Kf / m[:, None] / m[None, :])
    return np.sqrt(values[:count])


def test_portal_frame_modes_are_the_linear_frame_modes():
    """The first four in-plane natural frequencies of scenes/portal_frame.toml (8 P3 cells a
    member; in-plane: y, θ, φ of the shape zero) against the linear frame's
    (:func:`portal_modes_linear`, extrapolated from 64 and 128 elements a member by its h²
    lumping error: the extrapolation moves them by at most 1.1e-5 relative, so what it leaves,
    of higher order, is some 1e-6 at most). The Cosserat modes about the undeformed frame are
    those of the linear Timoshenko frame with rotary inertia ρ c22; what is left is their P3
    discretisation error at 8 cells (measured 4.4e-7, 1.6e-5, 3.7e-5, 5.1e-5; 4 cells gave
    3.6e-4 on the second): within 1e-4.
    The out-of-plane modes (bending about d0_1 and torsion) are in between; not checked."""
    fine, finer = portal_modes_linear(64), portal_modes_linear(128)
    linear = finer + (finer - fine) / 3
    modes = api.modes(with_elements(load_scene(PORTAL), 8, 3), count=8)
    in_plane = []
    for mode in modes:
        shape = mode.shape.x.array.reshape(-1, 6)
        if np.abs(shape[:, [1, 3, 5]]).max() < 1e-8 * np.abs(shape).max():
            in_plane.append(mode.omega)
    assert len(in_plane) >= 4
    np.testing.assert_allclose(in_plane[:4], linear, rtol=1e-4)


def test_t_tree_small_load_is_the_linear_frame(tmp_path):
    """A T (a column A-B clamped at A, arms B-C and B-E along ±e1 of 60: a junction of three
    members), a small downward force 1e-8 at the tip C and 2e-8 across at E, against the
    linear frame (:func:`frame_linear`): one P3 cell a member gives the Timoshenko frame's
    fields exactly, so what is left is the geometric nonlinearity, of the order of the
    rotations (1.5e-7 here; at 100 times the load the difference was 1.7e-5, 100 times
    larger, as it should), and Newton's tolerance: within 1e-6 relative at both tips; the
    probe follows the node structure.probe names (E). The XDMF file is one mesh of the 3
    members (4 nodes + 2 interior points a member: 10 points, 9 segments of 20 or 40), its
    first points the nodes' rest positions."""
    EA, EI, GA = stiffnesses()
    data = read_toml(PORTAL)
    data["structure"] = {
        **t_structure(1),
        "probe": "E",
        "loads": [
            {"node": "C", "force": [0, 0, -1e-8]},
            {"node": "E", "force": [2e-8, 0, 0]},
        ],
    }
    scene = scene_from_dict(data)
    nodes = {"A": (0, 0), "B": (0, 120), "C": (60, 120), "E": (-60, 120)}
    members = [("A", "B"), ("B", "C"), ("E", "B")]
    loads = {"C": (0.0, -1e-8), "E": (2e-8, 0.0)}
    linear = frame_linear(nodes, members, {"A"}, loads, EA, EI, GA)
    result = api.static(scene, tmp_path / "t")
    U = nodal(result.model)
    ell = result.model.length
    for name, (x, z) in (("C", (60, 120)), ("E", (-60, 120))):
        got = U[(float(x), 0.0, float(z))][[0, 2]] * ell
        want = linear[name][:2]
        assert np.abs(got - want).max() < 1e-6 * np.abs(want).max(), (name, got, want)
    # structure.probe = "E": probes.csv follows that node (x, z there, exactly U's)
    row = result.probes[-1]
    np.testing.assert_array_equal(row[[1, 3]], U[(-60.0, 0.0, 120.0)][[0, 2]] * ell)
    summary = json.loads((tmp_path / "t" / "summary.json").read_text())
    assert summary["probe_node"] == "E" and "probe_s_m" not in summary
    assert summary["probe_reference_position_m"] == [-60.0, 0.0, 120.0]
    # h5py cannot read in a process that has loaded DOLFINx (cosserat_fem/io/xdmf.py): another.
    # (read_xdmf orders the points of one rod by s: not a structure's; the mesh as written.)
    read = "import sys, json, h5py; f = h5py.File(sys.argv[1]); print(json.dumps(["
    read += "f['/Mesh/mesh/geometry'][()].tolist(), f['/Mesh/mesh/topology'][()].tolist()]))"
    done = run_command(["-c", read, str(tmp_path / "t" / "solution.frames" / "mesh.h5")])
    assert done.returncode == 0, done.stderr[-2000:]
    geometry, topology = map(np.array, json.loads(done.stdout.strip().splitlines()[-1]))
    assert topology.shape == (9, 2)
    segments = np.linalg.norm(geometry[topology[:, 1]] - geometry[topology[:, 0]], axis=1)
    np.testing.assert_allclose(np.sort(segments), [20] * 6 + [40] * 3, rtol=1e-12)
    assert geometry.shape == (10, 3)
    assert {tuple(np.round(p, 9)) for p in geometry[:4]} == {
        (0.0, 0.0, 0.0),
        (0.0, 0.0, 120.0),
        (60.0, 0.0, 120.0),
        (-60.0, 0.0, 120.0),
    }


def test_a_load_at_a_junction_of_three_members_is_the_linear_frames():
    """The T of :func:`t_structure` (one P3 cell a member) under forces at its junction B of
    three members, 1e-8 along e1 and 2e-8 along −e3, and a torque 1e-7 about e2 there: the
    node is split to a chain of two members and a copy tied in all twelve components
    (resolved.Structure.splits; the shared vertex to round-off, tests/unit/nls/
    test_constraints.py), whose interior facet carries the load. Against the linear frame
    (:func:`frame_linear`, the torque its moment at B): the geometric nonlinearity and
    Newton's tolerance are left, within 1e-6 relative at B and the tips (as
    :func:`test_t_tree_small_load_is_the_linear_frame`). A rigid body of mass m at B
    weighs as the force m g there: the same state within 1e-12 of its largest value."""
    EA, EI, GA = stiffnesses()
    data = read_toml(PORTAL)
    force = {"node": "B", "force": [1e-8, 0, -2e-8], "torque": [0, 1e-7, 0]}
    data["structure"] = {**t_structure(1), "loads": [force]}
    result = api.static(scene_from_dict(data))
    nodes = {"A": (0, 0), "B": (0, 120), "C": (60, 120), "E": (-60, 120)}
    members = [("A", "B"), ("B", "C"), ("E", "B")]
    # the torque about e2 is a moment −1e-7 counter-clockwise in (x, z)
    linear = frame_linear(nodes, members, {"A"}, {"B": (1e-8, -2e-8, -1e-7)}, EA, EI, GA)
    assert_linear_frame(result.model, nodes, linear, ("B", "C", "E"))
    assert len(result.model.constraints) == 12  # one rigid copy at B
    mass, g = 0.5, 1e-6  # a gravity small enough for the frame's linear range
    weighed = {**t_structure(1), "loads": [{"node": "B", "force": [0, 0, -mass * g]}]}
    carried = {**t_structure(1), "bodies": [{"node": "B", "mass": mass, "inertia": [1, 1, 1]}]}
    states = []
    for structure in (weighed, carried):
        data = read_toml(PORTAL)
        data["structure"] = structure
        data["loads"] = {"gravity": [0, 0, -g]}
        states.append(api.static(scene_from_dict(data)).model.U.x.array.copy())
    scale = np.abs(states[0]).max()
    assert scale > 0
    np.testing.assert_allclose(states[1], states[0], rtol=0, atol=1e-12 * scale)


def test_closed_square_frame_small_load_is_the_linear_frame():
    """A closed frame (four members of 120 in a loop A-B-C-D-A, the mesh a cycle; the member
    C-D against the loop's sense), clamped at A, forces 1e-8 along e1 and −e3 at C (a node
    of two members: the interior-facet measure), against the linear frame
    (:func:`frame_linear`): one P3 cell a member is exact for it, so within 1e-6 relative at
    B, C and D (the geometric nonlinearity, rotations ~1e-7, and Newton's tolerance). The
    closed loop is statically indeterminate: its sway needs the corners rigid."""
    EA, EI, GA = stiffnesses()
    data = read_toml(PORTAL)
    data["structure"] = {
        "nodes": [
            {"name": n, "position": [x, 0, z]}
            for n, (x, z) in {"A": (0, 0), "B": (0, 120), "C": (120, 120), "D": (120, 0)}.items()
        ],
        "members": [
            {"name": "ab", "from": "A", "to": "B", "elements": 1},
            {"name": "bc", "from": "B", "to": "C", "elements": 1},
            {"name": "cd", "from": "D", "to": "C", "elements": 1},
            {"name": "da", "from": "D", "to": "A", "elements": 1},
        ],
        "supports": [{"node": "A", "kind": "clamped"}],
        "loads": [{"node": "C", "force": [1e-8, 0, -1e-8]}],
    }
    nodes = {"A": (0, 0), "B": (0, 120), "C": (120, 120), "D": (120, 0)}
    members = [("A", "B"), ("B", "C"), ("D", "C"), ("D", "A")]
    linear = frame_linear(nodes, members, {"A"}, {"C": (1e-8, -1e-8)}, EA, EI, GA)
    result = api.static(scene_from_dict(data))
    assert_linear_frame(result.model, nodes, linear, ("B", "C", "D"))


MPI_SCRIPT = """
import json, sys
from mpi4py import MPI
from cosserat_fem import api
from cosserat_fem.scene.build import load_scene
sys.path.insert(0, "tests")
from test_structures import chart_tree
scene = load_scene(sys.argv[1], ["parameters.F=0.5", "static.load_steps=3", "time.end=5"])
static = api.static(scene).probes[-1]
run = api.run(scene).probes[-1]
tree = api.static(chart_tree(False))
moved = tree.model.chart_moved
if MPI.COMM_WORLD.rank == 0:
    rows = {"static": static, "run": run, "tree": tree.probes[-1]}
    print(json.dumps({"moved": moved, **{k: list(map(float, v)) for k, v in rows.items()}}))
"""


@pytest.mark.long
def test_portal_frame_serial_equals_mpi(tmp_path):
    """scenes/portal_frame.toml at F = 0.5 (a sway of 33.4, over a quarter of the height:
    rotations of 0.18 rad) statically in 3 steps, and 5 steps of a dynamic run (the force
    applied suddenly), and the T of :func:`chart_tree` (a junction of three members, its
    arms twisted past the chart's move) statically, in one process and under
    mpirun -n 2 (the mesh split between the ranks, the junctions' dofs shared): the probe's
    rows agree to 1e-8 of their largest value (the same equations, Newton to its tolerance
    from the same start: the assembly's order of sums differs, ~1e-14, amplified by the
    condition number and the tolerance; measured ~5e-16 relative)."""
    script = tmp_path / "portal_mpi.py"
    script.write_text(MPI_SCRIPT)
    answers = []
    for ranks in (1, 2):
        done = run_command([str(script), str(PORTAL)], ranks=ranks)
        assert done.returncode == 0, done.stderr[-2000:]
        answers.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert abs(answers[0]["static"][1]) > 5.0  # a large sway (33.4)
    assert abs(answers[0]["run"][1]) > 1e-3  # it moved (0.0143 after 5 s; period ~2000 s)
    assert answers[0]["moved"] and answers[1]["moved"]  # the T's charts moved
    assert abs(answers[0]["tree"][4]) > 1.0  # θ at C 1.23 rad
    for key in ("static", "run", "tree"):
        one, two = np.array(answers[0][key]), np.array(answers[1][key])
        np.testing.assert_allclose(two, one, rtol=0, atol=1e-8 * np.abs(one).max())


def test_portal_frame_restart_continues_bit_for_bit(tmp_path):
    """A dynamic run of scenes/portal_frame.toml (F = 0.5) to t = 6 in one go, and to t = 3
    then restarted from its checkpoint to 6: the same states, bit for bit (the restart reads
    U, its rate and the step's state back exactly; the structure's mesh is rebuilt the same
    from the scene)."""
    changes = ["parameters.F=0.5", "output.checkpoint_interval=3"]
    whole = api.run(load_scene(PORTAL, [*changes, "time.end=6"]), tmp_path / "whole")
    api.run(load_scene(PORTAL, [*changes, "time.end=3"]), tmp_path / "part")
    scene, checkpoint = api.resume(tmp_path / "part", ["time.end=6"])
    rest = api.run(scene, restart=checkpoint)
    assert abs(whole.probes[-1][1]) > 1e-3
    assert np.array_equal(whole.model.U.x.array, rest.model.U.x.array)


NODES = [
    {"name": "A", "position": [0, 0, 0]},
    {"name": "B", "position": [0, 0, 1]},
    {"name": "C", "position": [1, 0, 1]},
]


def structure_data(**changes) -> dict:
    """scenes/portal_frame.toml's data with an L of two members A-B-C, clamped at A, loaded at
    C, its [structure] changed by ``changes``."""
    data = read_toml(PORTAL)
    data["structure"] = {
        "nodes": NODES,
        "members": [
            {"name": "column", "from": "A", "to": "B", "elements": 2},
            {"name": "beam", "from": "B", "to": "C", "elements": 2},
        ],
        "supports": [{"node": "A", "kind": "clamped"}],
        "loads": [{"node": "C", "force": [1, 0, 0]}],
        **changes,
    }
    return data


def test_the_printed_end_load_sign_is_refused_on_a_structure():
    """model.end_load_sign = "printed" would turn the loads at a structure's leaves (ds, the
    scene's convention) but not inside its chains (dS, the balance sign): refused in one
    line (found by review)."""
    with pytest.raises(SceneError, match="^model.end_load_sign: a structure's node loads"):
        load_scene(PORTAL, ["model.end_load_sign=printed"])


def test_the_bad_inputs_base_is_a_valid_structure():
    """The L that each bad input changes (:func:`structure_data`) is itself accepted: its
    length 2 m the members' total, its elements 4."""
    scene = scene_from_dict(structure_data())
    assert scene.rod.length == 2.0 and scene.discretisation.elements == 4


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"nodes": [*NODES, {"name": "Z", "position": [5, 5, 5]}]},
            "structure.nodes[3]: node 'Z' is joined to no member",
        ),
        (
            {"members": [{"name": "m", "from": "A", "to": "A", "elements": 2}]},
            "structure.members[0].to: a member joins two different nodes",
        ),
        (
            {"members": [{"name": "m", "from": "A", "to": "Q", "elements": 2}]},
            "structure.members[0].to: unknown node 'Q'",
        ),
        (
            {
                "nodes": [*NODES, {"name": "Z", "position": [0, 0, 1]}],
                "members": [{"name": "m", "from": "B", "to": "Z", "elements": 2}],
            },
            "structure.nodes[3].position: the place of node 'B'",
        ),
        (
            {"supports": [{"node": "Q", "kind": "clamped"}]},
            "structure.supports[0].node: unknown node 'Q'",
        ),
        (
            {"supports": [{"node": "A", "kind": "hinge"}]},
            "structure.supports[0].kind: must be one of",
        ),
        (
            {"loads": [{"node": "Q", "force": [1, 0, 0]}]},
            "structure.loads[0].node: unknown node 'Q'",
        ),
    ],
)
def test_bad_structures_are_refused_in_one_line(changes, message):
    """Each bad [structure] is a SceneError whose one line starts with the key at fault."""
    with pytest.raises(SceneError) as info:
        scene_from_dict(structure_data(**changes))
    text = str(info.value)
    assert text.startswith(message), text
    assert "\n" not in text


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("reference", {"shape": "arc", "radius": 10.0}, "reference: a structure's members"),
        ("supports", {"start": "clamped"}, "supports: a structure is held at its nodes"),
        ("initial", {"displacement": [1, 0, 0]}, "initial: initial fields on a structure"),
        ("loads.body", {"mass": 1.0}, "loads.body: a rigid body at a structure's node"),
    ],
)
def test_single_rod_keys_are_refused_on_a_structure(key, value, message):
    """The keys of a single rod that a structure gives otherwise are refused by name."""
    data = read_toml(PORTAL)
    table, _, leaf = key.rpartition(".")
    (data.setdefault(table, {}) if table else data)[leaf] = value
    with pytest.raises(SceneError, match=f"^{message}"):
        scene_from_dict(data)


def test_cli_refuses_a_bad_structure_in_one_line(tmp_path):
    """`cosserat-fem run` on a structure whose member names an unknown node: exit status
    non-zero, one line on stderr naming the key, no traceback."""
    bad = tmp_path / "bad.toml"
    bad.write_text(PORTAL.read_text().replace('from = "D", to = "C"', 'from = "D", to = "Q"'))
    done = run_command(["-m", "cosserat_fem.cli", "run", str(bad)])
    assert done.returncode != 0
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert "Traceback" not in done.stderr
    assert any("structure.members[2].to: unknown node 'Q'" in line for line in lines), lines


@pytest.mark.parametrize(
    ("command", "message"),
    [
        (
            ["continue", "--range", "0", "1", "--probe", "10"],
            "probe: a structure has no arclength s",
        ),
    ],
)
def test_commands_a_structure_cannot_do_are_refused_in_one_line(tmp_path, command, message):
    """`cosserat-fem continue --probe s` on scenes/portal_frame.toml (a structure has no
    arclength: its probe is a node): exit status 2 (a SceneError), one line naming the key,
    no traceback, no output folder."""
    out = tmp_path / "out"
    done = run_command(
        ["-m", "cosserat_fem.cli", command[0], str(PORTAL), *command[1:], "--out", str(out)]
    )
    assert done.returncode == 2
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], lines
    assert not out.exists()


@pytest.mark.parametrize("command", ["plot", "render", "pod"])
def test_a_structures_run_is_refused_by_the_single_rod_readers(tmp_path, command):
    """`plot`, `render` and `pod` read a single rod's outputs (points in the order of s): on a
    structure's run folder they exit 2 with one line saying so, no traceback, nothing
    written."""
    api.run(load_scene(PORTAL, ["time.end=2"]), tmp_path / "run")
    before = sorted(p.name for p in (tmp_path / "run").iterdir())
    done = run_command(["-m", "cosserat_fem.cli", command, str(tmp_path / "run")])
    assert done.returncode == 2, done.stderr[-2000:]
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "is the run of a structure" in lines[0], lines
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == before


def test_a_structure_left_a_mechanism_has_no_static_state():
    """Static equilibrium of the portal frame without supports (six rigid-body motions,
    Structure.rigid_body_modes) or pinned at A only about e2 (one: the turn about e2 at A) is
    refused by name; clamped at A it has none."""
    for supports, rigid in (([], 6), ([{"node": "A", "kind": "pinned"}], 1)):
        data = read_toml(PORTAL)
        data["structure"]["supports"] = supports
        scene = scene_from_dict(data)
        assert scene.rigid_body_modes() == rigid
        with pytest.raises(SceneError, match="^structure.supports: a static equilibrium needs"):
            api.static(scene)
    data = read_toml(PORTAL)
    data["structure"]["supports"] = [{"node": "A", "kind": "clamped"}]
    assert scene_from_dict(data).rigid_body_modes() == 0


@pytest.mark.long
@pytest.mark.skipif(
    shutil.which("pvpython") is None or shutil.which("Xvfb") is None,
    reason="ParaView (pvpython) or Xvfb not installed",
)
def test_paraview_opens_the_portal_frame_as_one_object(tmp_path):
    """scenes/portal_frame.toml at F = 0.5 (a sway of 33.4) solved statically in 3 steps,
    its solution.xdmf opened with ParaView's own XDMF reader (tests/paraview_check.py): one
    dataset of 37 points (13 vertices, 2 more points in each of the 12 P3 cells), the nodes at
    their rest positions, the displacement of B (0, 0, 120) the probe's to 1e-12 (the same
    values, written and read in double precision), "Warp By Vector" the rest positions plus
    the displacement, and a picture that is not blank."""
    result = api.static(
        load_scene(PORTAL, ["parameters.F=0.5", "static.load_steps=3"]), tmp_path / "run"
    )
    png, report = tmp_path / "paraview.png", tmp_path / "paraview.json"
    script = str(ROOT / "tests" / "paraview_check.py")
    args = [script, str(tmp_path / "run" / "solution.xdmf"), str(png), str(report)]
    proc = run_pvpython(args, subprocess_env())
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    seen = json.loads(report.read_text())
    points = np.array(seen["points"])
    assert points.shape == (37, 3)
    rest = {tuple(np.round(p, 9)): i for i, p in enumerate(points)}
    for node in ((0, 0, 0), (0, 0, 120), (120, 0, 120), (120, 0, 0)):
        assert tuple(float(x) for x in node) in rest
    last = seen["frames"][repr(seen["times"][-1])]
    b = rest[(0.0, 0.0, 120.0)]
    row = result.probes[-1]
    np.testing.assert_allclose(last["displacement"][b], row[1:4], rtol=0, atol=1e-12)
    warped = np.array(seen["warped_points"])
    np.testing.assert_allclose(warped, points + np.array(last["displacement"]), atol=1e-12)
    assert png.stat().st_size > 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))


@pytest.mark.parametrize("suffix", [".vtk", ".msh"])
def test_a_structure_read_from_a_file_of_line_cells_is_the_scenes(tmp_path, suffix):
    """The portal frame's geometry written as a file of line cells (meshio: legacy VTK and
    Gmsh 2.2), points A, B, C, D and lines A–B, B–C, D–C, read by ``[structure] file`` with
    ``elements = 4`` (cosserat_fem/io/line_mesh.py: nodes n0..n3, members c0..c2): the same
    nodes, members, order and orientation as scenes/portal_frame.toml, so the same mesh and
    forms; its static sway equals the scene's to round-off (1e-12 of it). Its supports and
    load name the file's nodes (n0, n3; n1)."""
    import meshio

    from cosserat_fem.scene.build import load_scene

    portal = read_toml(PORTAL)
    positions = [n["position"] for n in portal["structure"]["nodes"]]
    path = tmp_path / f"portal{suffix}"
    lines = np.array([[0, 1], [1, 2], [3, 2]])
    extra = {"file_format": "gmsh22", "binary": False} if suffix == ".msh" else {}
    meshio.write_points_cells(path, np.array(positions, float), [("line", lines)], **extra)
    text = PORTAL.read_text()
    start = text.index("[structure]")
    end = text.index("\n[", start + 1)
    table = (
        f'[structure]\nfile = "{path.name}"\nelements = 4\n'
        'supports = [{ node = "n0", kind = "clamped" }, { node = "n3", kind = "clamped" }]\n'
        'loads = [{ node = "n1", force = ["F", 0, 0] }]\n'
    )
    scene_file = tmp_path / "portal_file.toml"
    scene_file.write_text(text[:start] + table + text[end:])
    from_file = load_scene(scene_file)
    assert [n.name for n in from_file.structure.nodes] == ["n0", "n1", "n2", "n3"]
    assert [(m.start, m.end) for m in from_file.structure.members] == [
        ("n0", "n1"), ("n1", "n2"), ("n3", "n2")
    ]  # fmt: skip
    ours, theirs = api.static(from_file).probes[-1], api.static(load_scene(PORTAL)).probes[-1]
    assert np.abs(ours - theirs).max() <= 1e-12 * np.abs(theirs).max()


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('file = "missing.vtk"', r"^structure\.file: .*missing\.vtk.*: no such file"),
        ('file = "bad.vtk"', r"^structure\.file: meshio cannot read"),
        ('file = "points.vtk"', r"^structure\.file: .*has no line cells"),
        ('file = "portal.vtk"\nelements = 0', r"^structure\.elements: a whole number"),
        ('file = "portal.vtk"\nnodes = []', r"^structure\.nodes: the structure's geometry"),
        ("elements = 2", r"^structure\.elements: the elements of each line cell"),
        ('file = "twice.vtk"', r"line cells 0 and 2 join the same points 0 and 1"),
        ('file = "curved.vtk"', r"has curved line cells \(line3\)"),
    ],
)
def test_a_bad_structure_file_is_one_line(tmp_path, table, message):
    """A missing, unreadable or lineless file, bad elements, a file beside nodes, a cell
    given twice (as Gmsh's MSH2 writes a cell of two physical groups: it would double that
    member) and a curved line: one line naming the key (the command line's exit 2)."""
    import meshio

    from cosserat_fem.scene.build import load_scene

    meshio.write_points_cells(
        tmp_path / "portal.vtk", np.eye(3), [("line", np.array([[0, 1], [1, 2]]))]
    )
    meshio.write_points_cells(tmp_path / "points.vtk", np.eye(3), [("vertex", np.array([[0]]))])
    twice = np.array([[0, 1], [1, 2], [1, 0]])
    meshio.write_points_cells(tmp_path / "twice.vtk", np.eye(3), [("line", twice)])
    meshio.write_points_cells(
        tmp_path / "curved.vtk", np.eye(3), [("line3", np.array([[0, 2, 1]]))]
    )
    (tmp_path / "bad.vtk").write_text("not a mesh\n")
    text = PORTAL.read_text()
    start = text.index("[structure]")
    end = text.index("\n[", start + 1)
    scene_file = tmp_path / "bad.toml"
    scene_file.write_text(text[:start] + "[structure]\n" + table + "\n" + text[end:])
    with pytest.raises(SceneError, match=message) as info:
        load_scene(scene_file)
    assert "\n" not in str(info.value)


def test_two_members_between_the_same_nodes_keep_their_own_cells():
    """The portal frame with a second member from C to D beside the right column (a double
    column: a closed loop of two members): each member's cells are its own (by their input
    index, rod/structure.py ``cell_members``), 4 each, none run against its member. Before,
    cells went to the member nearest their midpoint, and the second of two members between
    the same nodes got none of them (3 cells flagged against), so its d1 and section were
    silently the first's (review of 2026-12-04)."""
    from cosserat_fem.rod.model import build_model
    from cosserat_fem.rod.structure import cell_members

    data = read_toml(PORTAL)
    data["structure"]["members"].append({"name": "right2", "from": "C", "to": "D", "elements": 4})
    scene = scene_from_dict(data)
    model = build_model(scene)
    member, against, _ = cell_members(scene.structure, model.length, model.msh)
    assert np.bincount(member, minlength=4).tolist() == [4, 4, 4, 4]
    assert not against.any()


def test_the_xdmf_angles_of_a_structure_are_its_nodes_rotation(tmp_path):
    """The portal frame's solution.xdmf ``angles`` at rest (t = 0) are zero at every point,
    the corners included, as probes.csv's: the Euler angles of the nodes' rotation Λ, not
    of the members' directors D0 Λ (the beam's would be (0, π/2, 0) and a corner the mean of
    two members', (0, π/4, 0): the review of 2026-12-04). To 1e-12 rad."""
    from xdmf_files import read_arrays  # tests/xdmf_files.py

    scene = api.load(PORTAL, {"time.end": 2.0, "output.fields": ["displacement", "angles"]})
    api.run(scene, tmp_path / "run")
    _, times, arrays = read_arrays(tmp_path / "run" / "solution.xdmf")
    assert times[0] == 0.0 and np.abs(arrays["angles"][0]).max() <= 1e-12


def test_a_sweep_of_a_structure_runs_its_members_and_refuses_what_it_cannot(tmp_path):
    """A sweep over the portal frame's lateral force F ∈ {1e-3, 2e-3} (plain members, no
    response): each member's row is its scene's run alone (final x of the probe B, equal to
    the solvers' tolerance 1e-9 relative: the same run), and F being in the linear range
    (sway 6e-4 of the height), the two sways are in the ratio of the forces, 2, to the
    geometric nonlinearity (sway/H)² ~ 4e-8: 1e-6. A [sweep.rom] on a structure: one line."""
    body = (
        f'[sweep]\nscene = "{PORTAL}"\nkeep = "probes"\n'
        '[sweep.set]\n"output.xdmf" = false\n"time.end" = 20.0\n'
        '[sweep.vary]\n"parameters.F" = [1e-3, 2e-3]\n'
    )
    path = tmp_path / "sweep.toml"
    path.write_text(body)
    result = api.sweep(api.load_sweep(path), tmp_path / "out")
    finals = [float(row["final_x"]) for row in result.rows]
    alone = api.run(load_scene(PORTAL, ["output.xdmf=false", "time.end=20.0"]))
    assert finals[0] == pytest.approx(float(alone.probes[-1, 1]), rel=1e-9)
    assert finals[1] / finals[0] == pytest.approx(2.0, rel=1e-6)
    path.write_text(body + '[sweep.rom]\nmodel = "reduced"\ntrain = [0]\ntolerance = 1e-6\n')
    with pytest.raises(SceneError, match=r"^sweep\.rom: not supported on a structure yet"):
        api.load_sweep(path)


def ring_polygon(count: int) -> dict:
    """scenes/free_ring.toml's ring (R = 1 m) as a closed polygon of ``count`` straight
    members, one cubic element each, rigidly joined at its vertices, free."""
    base = read_toml(ROOT / "scenes" / "free_ring.toml")
    data = {k: v for k, v in base.items() if k not in ("reference", "supports")}
    data["rod"] = {k: v for k, v in base["rod"].items() if k != "length"}
    data["discretisation"] = {"degree": 3}
    angles = 2.0 * math.pi * np.arange(count) / count
    data["structure"] = {
        "nodes": [
            {"name": f"p{i}", "position": [math.cos(a), 0.0, math.sin(a)]}
            for i, a in enumerate(angles)
        ],
        "members": [
            {"name": f"m{i}", "from": f"p{i}", "to": f"p{(i + 1) % count}", "elements": 1}
            for i in range(count)
        ],
    }
    return data


def test_a_closed_polygon_of_members_converges_to_the_ring():
    """A ring in dynamics through structures: the free ring (scenes/free_ring.toml, the closed
    rod's modes) as a closed polygon of 16 and 32 straight members with rigid corners. A
    polygon's rest curvature is lumped at its corners, which keep their angles: its six
    rigid-body modes are zero (below 1e-3 of the first flexible one) and its six lowest
    flexible frequencies (the in- and out-of-plane n = 2, 3 pairs) converge to the curved
    ring's at second order, the chord-versus-arc error of the polygon, (π/N)² ~ 4e-2 at N =
    16 times a factor of order 1 (measured 1.8e-2 and 4.5e-3: ratio 4.0; 64 members: 1.1e-3).
    Asserted: the ratio in [3.6, 4.4] (order 2 ± 0.15) and 1e-2 at N = 32."""
    ring = api.load(ROOT / "scenes" / "free_ring.toml")
    reference = np.array([m.omega for m in api.modes(ring, count=12)])[6:12]
    errors = []
    for count in (16, 32):
        omega = np.array([m.omega for m in api.modes(scene_from_dict(ring_polygon(count)), 12)])
        assert np.abs(omega[:6]).max() <= 1e-3 * omega[6]
        errors.append(np.abs(omega[6:12] / reference - 1.0))
    ratio = errors[0] / errors[1]
    assert np.all((3.6 <= ratio) & (ratio <= 4.4)), errors
    assert errors[1].max() < 1e-2, errors


def test_a_sweep_reads_its_structures_file_once(tmp_path):
    """A sweep over a structure whose geometry is a file of line cells: the file is read when
    the sweep is validated and its nodes are the members' (a member never reads it again),
    so a file changed afterwards changes no member and the sweep's fingerprint holds the
    geometry (the second review of 2026-12-04: it was read again by each member)."""
    import meshio

    portal = read_toml(PORTAL)
    positions = np.array([n["position"] for n in portal["structure"]["nodes"]], float)
    lines = np.array([[0, 1], [1, 2], [3, 2]])
    meshio.write_points_cells(tmp_path / "portal.vtk", positions, [("line", lines)])
    text = PORTAL.read_text()
    start, end = text.index("[structure]"), text.index("\n[", text.index("[structure]") + 1)
    table = (
        '[structure]\nfile = "portal.vtk"\nelements = 4\n'
        'supports = [{ node = "n0", kind = "clamped" }, { node = "n3", kind = "clamped" }]\n'
        'loads = [{ node = "n1", force = ["F", 0, 0] }]\n'
    )
    (tmp_path / "portal.toml").write_text(text[:start] + table + text[end:])
    (tmp_path / "sweep.toml").write_text(
        '[sweep]\nscene = "portal.toml"\n[sweep.vary]\n"parameters.F" = [1e-3, 2e-3]\n'
    )
    spec = api.load_sweep(tmp_path / "sweep.toml")
    moved = positions.copy()
    moved[1, 2] = 150.0
    meshio.write_points_cells(tmp_path / "portal.vtk", moved, [("line", lines)])
    scene = spec.scene(spec.members[0])
    assert [list(n.position) for n in scene.structure.nodes][1] == [0.0, 0.0, 120.0]
