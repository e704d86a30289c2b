"""Unit tests of a structure's mesh and rest frames, cosserat_fem/rod/structure.py.

A Y of three members meeting at one node (a junction of three cells), one member given
against its node order: the mesh must have the nodes and interior vertices the members ask
for (one shared junction vertex), the P3 space the dofs of a tree (3 per cell + 1 per vertex),
and on every cell d0_3 must be the cell's own tangent (its vertices' order, what
forms/kinematics.py d_sigma differentiates along) with D0 orthonormal and right-handed, d0_2
the member's whatever the cell's direction: exact in floating point up to 1e-15.
"""

from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI

from cosserat_fem.rod.structure import NODE_TAG, create_structure_mesh, member_frames
from cosserat_fem.scene.resolved import (
    Structure,
    StructureMember,
    StructureNode,
)

pytestmark = pytest.mark.unit


def y_structure() -> Structure:
    """A trunk along e3 and two branches in the x-z plane, the left one from its tip."""
    nodes = (
        StructureNode(name="root", position=(0.0, 0.0, 0.0)),
        StructureNode(name="fork", position=(0.0, 0.0, 2.0)),
        StructureNode(name="right", position=(1.0, 0.0, 3.0)),
        StructureNode(name="left", position=(-1.0, 0.0, 3.0)),
    )
    members = (
        StructureMember(name="trunk", start="root", end="fork", elements=3),
        StructureMember(name="b1", start="fork", end="right", elements=2),
        StructureMember(name="b2", start="left", end="fork", elements=2),
    )
    return Structure(nodes=nodes, members=members)


def test_a_y_is_one_tree_mesh_with_its_nodes_tagged():
    structure = y_structure()
    length = float(structure.lengths().sum())
    made = create_structure_mesh(structure, length, MPI.COMM_SELF)
    msh = made.msh
    assert msh.geometry.dim == 3
    assert msh.topology.index_map(1).size_local == 7
    assert msh.topology.index_map(0).size_local == 4 + 2 + 1 + 1
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 3), dim=2)
    assert V.dofmap.index_map.size_local == 8 + 2 * 7  # vertices + 2 interior nodes a cell
    for i, node in enumerate(structure.nodes):
        (vertex,) = made.vertices[node.name]
        assert made.tags.find(NODE_TAG + i).tolist() == [vertex]
        connected = msh.topology.connectivity(0, 1).links(vertex)
        assert len(connected) == structure.degree(node.name)


def test_each_cell_frame_has_the_cell_tangent_as_d3():
    structure = y_structure()
    length = float(structure.lengths().sum())
    msh = create_structure_mesh(structure, length, MPI.COMM_SELF).msh
    frame = member_frames(structure, length, msh)
    D0 = frame.x.array.reshape(-1, 3, 3)
    dofs = frame.function_space.dofmap.list.array
    nodes = msh.geometry.dofmap.array.reshape(-1, 2)
    x = msh.geometry.x
    for cell in range(msh.topology.index_map(1).size_local):
        D = D0[dofs[cell]]
        t = x[nodes[cell, 1]] - x[nodes[cell, 0]]
        np.testing.assert_allclose(D[2], t / np.linalg.norm(t), atol=1e-15)
        np.testing.assert_allclose(D @ D.T, np.eye(3), atol=1e-15)
        assert abs(np.linalg.det(D) - 1.0) < 1e-15
        np.testing.assert_allclose(np.abs(D[1]), [0.0, 1.0, 0.0], atol=1e-15)  # e2 x d0_3 rule
