"""A structure's mesh: straight members joined rigidly at shared nodes (docs/structures.md).

The mesh is one interval mesh embedded in 3D (geometric dimension 3) whose vertices are the
rest positions r0/ℓ (ℓ = rod.length, the members' total length): the structure's nodes first,
in the scene's order, then each member's interior vertices, ``elements`` equal cells from its
``from`` node to its ``to`` node. A junction is one vertex that several members' cells share,
so they share its unknowns p = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ), q = dp/dτ: the angles parametrise the
spatial rotation Λ that turns every member's rest directors, d_i = Λ d0_i (forms/reference.py),
so the members' directors there keep their rest angles to one another: a rigid joint.

A joint other than rigid ([[structure.joints]], docs/structures.md) gives the members it names
their own copy of the node's vertex, a point appended after the members' interior vertices
(one copy a joint); the members it does not name keep the node's vertex (the *master*). The
copies' dofs are tied afterwards, by rows of the assembled system
(cosserat_fem/nls/constraints.py): a spherical joint identifies the translations and their
rates. Under MPI a joint's cells are all owned by one rank (:func:`_partitioner`), so that
both copies' dofs are its own.

On this mesh σ is the arc length over ℓ along each cell, d/dσ the tangential derivative
(forms/kinematics.py :func:`~cosserat_fem.forms.kinematics.d_sigma`), and the rest frame D0 a
cellwise-constant 3×3 field (:func:`member_frames`): each cell holds its member's frame
(resolved.StructureMember.frame), d0_1 and d0_3 negated where the cell runs against the member
(t = J[:, 0]/|J[:, 0]| is the cell's own direction), so that d0_3 = t on every cell and the
rest strains vanish (forms/reference.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import cpp, fem, mesh
from dolfinx.fem.function import ElementMetaData
from mpi4py import MPI

from cosserat_fem.common.parallel import agree
from cosserat_fem.forms.groups import RodConstants
from cosserat_fem.forms.resultants import stiffness_matrix
from cosserat_fem.forms.section import SectionLaw
from cosserat_fem.scene.resolved import JOINT_COMPONENTS, NodeBody, NodeLoad, Structure

#: The vertex tags of the structure's nodes: node i of the scene gets NODE_TAG + i.
NODE_TAG = 10


@dataclass
class StructureMesh:
    """The mesh of a structure, its nodes' vertices (local, by node name; at a joint the
    master's), their tags (a vertex MeshTags: :data:`NODE_TAG` + the node's index) and the
    node loads with their tag and whether the node is inside a chain of two members (an
    interior facet: dS)."""

    msh: mesh.Mesh
    vertices: dict[str, np.ndarray]
    tags: mesh.MeshTagsMetaClass
    loads: list[tuple[NodeLoad, int, bool]]
    #: the rigid bodies at nodes, with their tag and whether the node is a chain's (dS)
    bodies: list[tuple[NodeBody, int, bool]]
    #: per joint of structure.all_joints(): the local vertices (local or ghost; none on a
    #: rank without the joint's cells) of its master and of its copy
    joints: list[tuple[np.ndarray, np.ndarray]] = dataclasses.field(default_factory=list)

    def joint_blocks(
        self, V: fem.FunctionSpace, structure: Structure
    ) -> tuple[list[int], list[int], list[tuple[int, ...]], list[int]]:
        """The dof blocks of V tied by the joints that this rank owns, (masters, copies,
        components, joints): per joint one (master block, copy block), local indices, the
        components of U = (p, q) it identifies (resolved.JOINT_COMPONENTS of its kind) and
        its index in structure.all_joints(). A joint's two blocks are one rank's
        (:func:`_partitioner`); a RuntimeError on every rank if not. Collective."""
        owned = V.dofmap.index_map.size_local
        masters, copies, components, which = [], [], [], []
        problem = None
        for j, (joint, (master, copy)) in enumerate(
            zip(structure.all_joints(), self.joints, strict=True)
        ):
            pair = [fem.locate_dofs_topological(V, 0, v) for v in (master, copy)]
            mine = [len(b) > 0 and int(b[0]) < owned for b in pair]
            if mine[0] != mine[1] and problem is None:  # _partitioner's to prevent
                problem = RuntimeError(f"joint at {joint.node!r}: its copies on two ranks")
            if mine[0] and mine[1]:
                masters.append(int(pair[0][0]))
                copies.append(int(pair[1][0]))
                components.append(JOINT_COMPONENTS[joint.kind])
                which.append(j)
        agree(V.mesh.comm, problem)
        return masters, copies, components, which


def create_structure_mesh(structure: Structure, length: float, comm: MPI.Comm) -> StructureMesh:
    """The mesh of ``structure`` (module docstring), ℓ = ``length`` [m]; collective (rank 0
    gives the cells and points, DOLFINx distributes them)."""
    r0 = structure.positions()
    names = [n.name for n in structure.nodes]
    points = [r0[n] for n in names]
    cells = []
    for m in structure.members:
        a, b = r0[m.start], r0[m.end]
        chain = [names.index(m.start)]
        for j in range(1, m.elements):
            chain.append(len(points))
            points.append(a + (b - a) * j / m.elements)
        chain.append(names.index(m.end))
        cells += [[chain[j], chain[j + 1]] for j in range(m.elements)]
    first = np.cumsum([0] + [m.elements for m in structure.members])
    joint_points = []
    joints = structure.all_joints()
    for joint in joints:  # the named members' cells at the node: the copy
        joint_points.append(len(points))
        points.append(r0[joint.node])
        node = names.index(joint.node)
        for name in joint.members:
            i = [m.name for m in structure.members].index(name)
            for c in range(first[i], first[i + 1]):
                cells[c] = [len(points) - 1 if v == node else v for v in cells[c]]
    x = np.asarray(points, dtype=float) / length
    topology = np.asarray(cells, dtype=np.int64)
    if comm.rank != 0:
        x, topology = np.zeros((0, 3)), np.zeros((0, 2), dtype=np.int64)
    cell = ufl.Cell("interval", geometric_dimension=3)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", cell, 1, dim=3))
    if joints:
        groups = [[names.index(j.node), p] for j, p in zip(joints, joint_points, strict=True)]
        msh = mesh.create_mesh(comm, topology, x, domain, partitioner=_partitioner(groups))
    else:
        msh = mesh.create_mesh(comm, topology, x, domain)
    msh.topology.create_connectivity(0, 1)
    original = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)
    scale = max(1.0, float(np.abs(np.asarray(points)).max()) / length)
    vertices, at_node = {}, {}
    for name in names:
        at = r0[name] / length
        found = mesh.locate_entities(
            msh,
            0,
            lambda y, at=at: np.linalg.norm(y - at[:, None], axis=0) < 1e-10 * scale,
        )
        at_node[name] = (found, _input_vertex(msh, found, original))  # all copies there
        vertices[name] = found[~np.isin(at_node[name][1], joint_points)]
    copies = []
    for joint, point in zip(joints, joint_points, strict=True):
        found, points_of = at_node[joint.node]
        copies.append((vertices[joint.node], found[points_of == point]))
    entities = np.concatenate(list(vertices.values())).astype(np.int32)
    values = np.concatenate(
        [np.full(len(vertices[n]), NODE_TAG + i, dtype=np.int32) for i, n in enumerate(names)]
    )
    order = np.argsort(entities)
    tags = mesh.meshtags(msh, 0, entities[order], values[order])
    # a node of two members, or of more split to two (Structure.splits): an interior facet
    loads, bodies = (
        [(x, NODE_TAG + names.index(x.node), structure.degree(x.node) >= 2) for x in items]
        for items in (structure.loads, structure.bodies)
    )
    return StructureMesh(msh, vertices, tags, loads, bodies, copies)  # type: ignore[arg-type]


def _input_vertex(msh: mesh.Mesh, vertices: np.ndarray, original: np.ndarray) -> np.ndarray:
    """The input point (index in create_mesh's x) of each of the local ``vertices``: through
    a cell's geometry dofs (``original``: the geometry nodes' input indices; P1 geometry, so
    a cell's vertices are its geometry nodes, in the same order)."""
    c2v = msh.topology.connectivity(1, 0)
    v2c = msh.topology.connectivity(0, 1)
    nodes = msh.geometry.dofmap
    found = np.empty(len(vertices), dtype=np.int64)
    for k, v in enumerate(vertices):
        c = v2c.links(v)[0]
        local = list(c2v.links(c)).index(v)
        found[k] = original[nodes.links(c)[local]]
    return found


def _partitioner(groups: list[list[int]]):
    """DOLFINx's default cell partition with every cell that touches a joint (``groups``:
    per joint the input points of its master and its copy) owned by one rank, that of the
    joint's first such cell (joints that share a cell: one rank for all their cells), and
    the ghosts made again as DOLFINx makes them for a shared-facet mesh of intervals: a cell
    is a ghost on each other rank that owns a cell sharing a vertex with it. Rank 0 holds
    every input cell (create_structure_mesh)."""
    default = cpp.mesh.create_cell_partitioner()

    def partition(comm, nparts, tdim, cells, ghost_mode):
        parts = default(comm, nparts, tdim, cells, ghost_mode)
        count = cells.num_nodes
        if count == 0:
            return parts
        owner = np.array([parts.links(i)[0] for i in range(count)], dtype=np.int32)
        topology = cells.array.reshape(count, -1)
        merged: list[set[int]] = []  # the joints' cells, joints sharing a cell in one set
        for group in groups:
            touching = set(np.flatnonzero(np.isin(topology, group).any(axis=1)).tolist())
            for other in [m for m in merged if m & touching]:
                touching |= other
                merged.remove(other)
            merged.append(touching)
        for touching in merged:
            cells_of = np.array(sorted(touching))
            owner[cells_of] = owner[cells_of[0]]
        by_vertex: dict[int, set[int]] = {}
        for c, vertices in enumerate(topology):
            for v in vertices:
                by_vertex.setdefault(int(v), set()).add(int(owner[c]))
        data, offsets = [], [0]
        for c, vertices in enumerate(topology):
            ranks = set().union(*(by_vertex[int(v)] for v in vertices)) - {int(owner[c])}
            data += [int(owner[c]), *sorted(ranks)]
            offsets.append(len(data))
        return cpp.graph.AdjacencyList_int32(
            np.asarray(data, dtype=np.int32), np.asarray(offsets, dtype=np.int32)
        )

    return partition


def cell_members(
    structure: Structure, length: float, msh: mesh.Mesh
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each local and ghost cell: the index of the member it belongs to (by the cell's
    index in the input, :func:`create_structure_mesh` making each member's ``elements`` cells
    in the members' order: exact even for two members between the same nodes), whether its
    vertices run against that member, and the members' unit tangents (members, 3). A model's
    build computes it once and gives it to :func:`member_laws` and :func:`member_frames`
    (rod/model.py)."""
    cells = msh.topology.index_map(1)
    count = cells.size_local + cells.num_ghosts
    vertices = msh.geometry.dofmap.array.reshape(-1, 2)[:count]
    x0, x1 = msh.geometry.x[vertices[:, 0]] * length, msh.geometry.x[vertices[:, 1]] * length
    r0 = structure.positions()
    starts = np.array([r0[m.start] for m in structure.members])
    chords = np.array([r0[m.end] for m in structure.members]) - starts
    tangents = chords / np.linalg.norm(chords, axis=1)[:, None]
    first = np.cumsum([0] + [m.elements for m in structure.members])
    original = np.asarray(msh.topology.original_cell_index, dtype=np.int64)[:count]
    member = np.searchsorted(first, original, side="right") - 1
    against = ((x1 - x0) * tangents[member]).sum(1) < 0.0
    return member, against, tangents


def member_frames(
    structure: Structure,
    length: float,
    msh: mesh.Mesh,
    assignment: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> fem.Function:
    """D0 on each cell (module docstring) as a DG0 3×3 Function ``D0``: the member a cell
    belongs to is :func:`cell_members`'s (``assignment``, its result; None: computed here); its
    frame with d0_1, d0_3 negated where the cell's vertices run against the member, so that
    d0_3 is the cell's own tangent."""
    space = fem.TensorFunctionSpace(msh, ElementMetaData("DG", 0), shape=(3, 3))
    member, against, tangents = (
        cell_members(structure, length, msh) if assignment is None else assignment
    )
    frames = np.stack([m.frame(t) for m, t in zip(structure.members, tangents, strict=True)])
    D0 = frames[member].copy()
    D0[against, 0] *= -1.0
    D0[against, 2] *= -1.0
    dofs = space.dofmap.list.array.reshape(-1)[: len(member)]
    frame = fem.Function(space, name="D0")
    frame.x.array.reshape(-1, 9)[dofs] = D0.reshape(-1, 9)
    return frame


def member_laws(
    rod: RodConstants,
    structure: Structure,
    msh: mesh.Mesh,
    assignment: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> RodConstants:
    """The rod with the members' own section laws (structure.members[i].section,
    resolved.MemberSection) as one :class:`SectionLaw` of cellwise-constant entries: each
    entry of K, μ and (I11, I22, I33) that differs between members a DG0 Function holding its
    member's value on each cell, an entry equal on all members that number (so zero entries
    add no term, forms/resultants.section_law). A member without a section takes the scene's
    law (rod.section.stiffness, mass_per_length, inertia), else the shape's diagonal (13), ρA
    and rotary inertias. The rod unchanged when no member has a section. The directors'
    components are the member's (d0_1, d0_2, d0_3). A cell running against its member has
    d0_1, d0_3 negated and s reversed (:func:`member_frames`), which negates the d2 components
    of the strains (Γ2, κ2) and of the resultants: its K is F K F, F = diag(1, −1, 1, 1, −1,
    1) (K itself for a diagonal law). (The mesh builds every cell along its member, so no
    cell runs against it today; the rule keeps the law right if one does.)
    ``assignment``: :func:`cell_members`'s result (None: computed here)."""
    if all(m.section is None for m in structure.members):
        return rod
    K0 = np.array(stiffness_matrix(rod), dtype=float)
    law = rod.law
    mu0 = law.mass_per_length if law is not None and law.mass_per_length is not None else None
    mu0 = rod.density * rod.section.area if mu0 is None else mu0
    given = law.inertia if law is not None and law.inertia is not None else rod.mass_inertias
    values = []  # per member: the 6×6 K, μ, I as one vector of 6*6 + 1 + 3
    for m in structure.members:
        s = m.section
        K = K0 if s is None else np.array(s.stiffness, dtype=float)
        mu = mu0 if s is None or s.mass_per_length is None else s.mass_per_length
        inertia = given if s is None or s.inertia is None else s.inertia
        values.append(np.concatenate([K.reshape(-1), [mu], np.asarray(inertia, dtype=float)]))
    table = np.array(values)
    member, against, _ = (
        cell_members(structure, rod.length, msh) if assignment is None else assignment
    )
    # On a cell run against its member (d0_1, d0_3 and s reversed) the d2 components of the
    # strains and resultants change sign: the law there is F K F, F = diag(1, −1, 1, 1, −1, 1)
    # (the same K for a diagonal law).
    flips = np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
    cells = table[member]
    cells[against, :36] *= np.outer(flips, flips).reshape(-1)
    space = fem.FunctionSpace(msh, ("DG", 0))
    dofs = space.dofmap.list.array.reshape(-1)[: len(member)]

    def entry(j: int):
        column = table[:, j]  # constant over the members and their cells' turns: a number
        if np.all(column == column[0]) and np.all(cells[:, j] == column[0]):
            return float(column[0])
        field = fem.Function(space)
        field.x.array[dofs] = cells[:, j]
        return field

    stiffness = tuple(tuple(entry(6 * i + j) for j in range(6)) for i in range(6))
    inertia = (entry(37), entry(38), entry(39))
    return dataclasses.replace(rod, law=SectionLaw(stiffness, entry(36), inertia))
