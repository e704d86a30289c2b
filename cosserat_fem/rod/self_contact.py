"""A rod's contact with itself: which node presses on which cell (docs/contact.md, "Self
contact"). The search is cosserat_fem/rod/contact_search.py's (a Verlet list of (node, cell)
pairs within a margin, rebuilt when a node has moved margin/(1 + Λ_k), self contact excluded
within π r of arc (S.2)); the rows are cosserat_fem/nls/pair_contact.py's.

Single pass: of the two directions of a contact (a node of one part of the rod on a cell of the
other, and back), the node that lies later along the rod is the slave and the cell the partner
(a node after the cell's last node in arc length). Each slave keeps its nearest partner cell,
except at a concave corner (below).

**A concave corner.** Where two cells of the partner meet at a kink that opens towards the
slave, the slave's closest points on both lie inside them, their gaps within round-off of
each other (1e-9 to 2e-7 r measured on the thin plectoneme), and a Newton update that closes
the gap to one cell's tangent puts the node nearer the other: the nearest cell alternates at
every iterate and the solve never settles (a step shrunk to 1e-11 s stalled on it; docs/
decisions.md, "A slave keeps its partner cell at a concave corner"). So a slave keeps the
partner it pressed (``keep``: at the last iterate, or at the accepted state at a solve's
first) while that cell's closest point is interior and its gap within :data:`CORNER` r of
the nearest; the other cell is then penetrated by at most that, a thousandth of the sampled
check's 1e-2 r between the nodes. A slave that presses none takes, of the interior
candidates within the band of its nearest, the one first along the rod (arc length, not the
cells' numbering: the same choice serially and under MPI, whatever the round-off), and the
nearest if none is interior. A
clamped closest point (a node past a cell's end) is never kept nor preferred: past a
vertex of straight cells it would tilt the normal by up to √(2 CORNER). A cell is known by
its first node; at a structure's joint two members' cells may share it (both kept, the
nearer wins), and "along the rod" is along each member's own arc: deterministic either way.

A node held in part by a support (a ``sliding`` node: its lateral positions held, free along
an axis) cannot close a gap across its held directions, so it is no slave, and neither is
any other node of the cells that hold it (their *held cells*): a node elsewhere is the slave
of a pair whose cell is a held cell, whichever direction the rule above gives. The reaction
then reaches the held cell's nodes, the sliding node's free component included
(nls/pair_contact.py). No node of a held cell being a slave, a pair onto a held cell is the
end of every chain of contacts (nls/pair_contact.py (P.5)): the levels stay acyclic. Two
held cells that touch each other have no pair: refused in one line (PartlyHeld).

On a structure (:class:`Members`; docs/contact.md, "Contact on a structure") each member is a
rod of its own with its arc a from its ``from`` node at rest:

* a member against itself: as a rod's, π r of its arc excluded (S.2), the node later along it
  the slave;
* two members p, q that meet at a junction J, at the angle α between their directions leaving
  J at rest: the cell pairs whose nearer ends lie a and b from J along them with

      a + b < λ = π r / sin(α/2)                                                      (J.1)

  excluded. At rest the members are straight: |a t_p − b t_q|² = a² + b² − 2ab cos α, whose
  least on a + b = λ is λ sin(α/2) (at a = b; homogeneous in (a, b), so λ sin(α/2) is the
  least for a + b ≥ λ too). So every kept pair starts π r apart, a gap ≥ (π − 2) r as the
  straight rod's nearest kept pair ((S.2)), and a member's node at J, which lies on the other
  member's centreline, is never paired with that member's cells at J. α = π (members in line)
  gives the rod's π r; α → 0 excludes everything near J (members folded onto each other);
* two members: the node whose member has the larger index is the slave (at a junction a node
  takes the largest index of its members), the same serially and under MPI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosserat_fem.nls.pair_contact import Pairs, PartlyHeld
from cosserat_fem.rod.contact_search import (
    ClosestPoints,
    VerletList,
    closest_point_sensitivities,
    closest_points,
    least_gap_between_nodes,
)

#: the band [in r] within which a slave keeps its partner cell at a concave corner (module
#: docstring)
CORNER = 1e-5


@dataclass(frozen=True)
class Members:
    """A structure's members, for its pairs (module docstring): each cell's ``member``
    (cells,), the members' rest ``starts`` (M, 3) [m] and unit ``tangents`` (M, 3), every
    node's ``rest`` position (N, 3) [m] (a joint's copies given their master's index in the
    cells: cosserat_fem/rod/obstacles.py) and the members' ``lengths`` (M,) [m]."""

    member: np.ndarray
    starts: np.ndarray
    tangents: np.ndarray
    lengths: np.ndarray
    rest: np.ndarray

    def along(self, nodes: np.ndarray, members: np.ndarray) -> np.ndarray:
        """The arc [m] of the ``nodes`` along the ``members`` (at rest, from each ``from``)."""
        rel = self.rest[nodes] - self.starts[members]
        return np.einsum("...d,...d->...", rel, self.tangents[members])


class SelfContactGeometry:
    """The :class:`~cosserat_fem.nls.pair_contact.Pairs` of one rod whose cells are ``dofs``
    (cells, k+1) (global node indices, dof order), its nodes at arc lengths ``places`` (N,)
    [m] at rest, its surface a tube of ``radius`` r [m]; pairs within ``margin`` [m]. A
    structure gives its ``members`` instead of ``places`` (module docstring); ``partly`` (N,)
    marks the nodes a support holds in part (module docstring: their cells' nodes no slaves)."""

    def __init__(
        self,
        dofs: np.ndarray,
        places: np.ndarray | None,
        radius: float,
        margin: float,
        members: Members | None = None,
        partly: np.ndarray | None = None,
    ):
        self.dofs, self.places = dofs, places
        #: the cells holding a node held in part, and their nodes (no slaves)
        count = int(dofs.max(initial=-1)) + 1 if partly is None else len(partly)
        partly = np.zeros(count, dtype=bool) if partly is None else np.asarray(partly, bool)
        self.held_cells = partly[dofs].any(axis=1)
        self.never_slaves = np.zeros(count, dtype=bool)
        self.never_slaves[dofs[self.held_cells].ravel()] = True
        self.radius, self.margin, self.members = radius, margin, members
        self.rod = None if members is None else members.member
        if members is None:
            assert places is not None, "a rod's arc lengths"
            arc = places[dofs]
        else:
            arc = members.along(dofs, members.member[:, None])
            self._junctions(members)
        self.arc = np.column_stack([arc.min(axis=1), arc.max(axis=1)])
        self.verlet: VerletList | None = None
        #: how many times the Verlet list was built
        self.builds = 0

    def _junctions(self, members: Members) -> None:
        """Each node's (node, member) memberships and the largest member it is a node of; per
        two members meeting at a junction J: (p, q, J's arc along p and q, λ of (J.1))."""
        count = len(members.starts)
        k1 = self.dofs.shape[1]
        keys = np.unique(self.dofs.ravel() * count + np.repeat(members.member, k1))
        self.memberships = keys
        node, member = keys // count, keys % count
        self.top = np.full(len(members.rest), -1, dtype=np.int64)
        np.maximum.at(self.top, node, member)
        self.joints = []
        shared, first = np.unique(node, return_index=True)
        many = np.flatnonzero(np.diff(np.append(first, len(node))) > 1)
        for J in shared[many]:
            at = member[node == J]
            arcs = members.along(np.full(len(at), J), at)
            # the directions leaving J: along the member from its start, against it from its end
            out = members.tangents[at] * np.where(arcs < 0.5 * members.lengths[at], 1, -1)[:, None]
            for i in range(len(at)):
                for j in range(i + 1, len(at)):
                    half = np.sqrt(max(0.0, 0.5 * (1.0 - float(out[i] @ out[j]))))
                    reach = np.pi * self.radius / half if half > 0.0 else np.inf
                    self.joints.append((at[i], at[j], arcs[i], arcs[j], reach))

    def _keep(self, pairs: np.ndarray) -> np.ndarray:
        """The cell ``pairs`` (m, 2) not excluded at a junction by (J.1)."""
        member = self.members.member if self.members is not None else None
        if member is None or not len(pairs):
            return pairs
        near = np.zeros(len(pairs), dtype=bool)
        for p, q, ap, aq, reach in self.joints:
            for i, j, a_i, a_j in ((0, 1, ap, aq), (1, 0, aq, ap)):
                ci, cj = pairs[:, i], pairs[:, j]
                here = (member[ci] == p) & (member[cj] == q)
                a = self._from(ci, a_i)
                b = self._from(cj, a_j)
                near |= here & (a + b < reach)
        return pairs[~near]

    def _from(self, cells: np.ndarray, at: float) -> np.ndarray:
        """The arc [m] from the point ``at`` of the cells' member to their nearer end."""
        return np.maximum(np.maximum(self.arc[cells, 0] - at, at - self.arc[cells, 1]), 0.0)

    def _slaves(self, node: np.ndarray, cell: np.ndarray) -> np.ndarray:
        """Whether each (node, cell) pair's node is the slave (module docstring)."""
        if self.members is None:
            assert self.places is not None
            later = self.places[node] > self.arc[cell, 1]
        else:
            member = self.members.member[cell]
            count = len(self.members.starts)
            inside = np.isin(node * count + member, self.memberships)
            along = self.members.along(node, member) > self.arc[cell, 1]
            later = np.where(inside, along, self.top[node] > member)
        return ~self.never_slaves[node] & (later | self.held_cells[cell])

    def _check_held_cells(self, x: np.ndarray, node: np.ndarray, cell: np.ndarray) -> None:
        """PartlyHeld (on every rank: the same positions ``x``) if a node of a held cell
        touches another held cell: neither is a slave (module docstring), so nothing would
        keep them apart. A node's own cells do not count (the Verlet list may pair a
        junction's node with them: never a slave there either)."""
        if not self.held_cells.any():  # no sliding node: nothing to check at each iterate
            return
        both = self.never_slaves[node] & self.held_cells[cell]
        both &= ~(self.dofs[cell] == node[:, None]).any(axis=1)
        if not both.any():
            return
        node, cell = node[both], cell[both]
        near = closest_points(x[node], x[self.dofs[cell]], self.radius, self.radius)
        touching = near.gap <= 0.0
        if touching.any():
            where = x[node[touching][0]]
            raise PartlyHeld(
                "the cells of two supports that hold their nodes in part (sliding) touch at "
                f"({', '.join(f'{v:.4g}' for v in where)}) m: no pair keeps them apart (not "
                "supported)"
            )

    def __call__(self, x: np.ndarray, keep: np.ndarray | None = None) -> Pairs:
        """The single-pass pairs at the nodes' positions ``x`` (N, 3) [m], each slave with
        its nearest partner cell or, at a concave corner, the one of ``keep`` (pairs (slave,
        partner cell's first node), global: the module docstring); FloatingPointError if a
        position is not finite (a NaN would make every gap NaN, never pressed)."""
        if not np.isfinite(x).all():
            node = int(np.flatnonzero(~np.isfinite(x).all(axis=1))[0])
            where = f"s = {self.places[node]:.4g} m" if self.places is not None else f"node {node}"
            raise FloatingPointError(f"a node's position is not finite ({where})")
        if self.verlet is None or self.verlet.stale(x):
            self.verlet = VerletList(
                x, self.dofs, self.radius, self.margin, self.arc, self.rod, self._keep
            )
            self.builds += 1
        node, cell = self.verlet.pairs.reshape(-1, 2).T
        self._check_held_cells(x, node, cell)
        later = self._slaves(node, cell)
        node, cell = node[later], cell[later]
        cells = x[self.dofs[cell]]
        near = closest_points(x[node], cells, self.radius, self.radius)
        order = self._partners(len(x), node, cell, near, keep)
        node, cell, cells = node[order], cell[order], cells[order]
        near = ClosestPoints(
            *(getattr(near, f)[order] for f in ("xi", "point", "gap", "normal", "weights"))
        )
        d = closest_point_sensitivities(x[node], cells, near)
        return Pairs(
            node, self.dofs[cell], near.gap, near.normal, near.weights, d.gap, d.normal, d.weights
        )

    def _partners(
        self,
        count: int,
        node: np.ndarray,
        cell: np.ndarray,
        near: ClosestPoints,
        keep: np.ndarray | None,
    ) -> np.ndarray:
        """The index of each slave's partner among the candidates (``node``, ``cell``) of the
        ``count`` nodes with
        their closest points ``near``, one a slave in the order of the slaves: the kept cell
        of ``keep`` if its closest point is interior and its gap within CORNER r of the
        slave's nearest, else the interior candidate first along the rod within that band,
        else the nearest (module docstring, "A concave corner")."""
        if not len(node):
            return np.zeros(0, dtype=np.int64)
        by_node = np.argsort(node, kind="stable")
        heads = np.flatnonzero(np.r_[True, node[by_node][1:] != node[by_node][:-1]])
        least = np.minimum.reduceat(near.gap[by_node], heads)
        nearest = np.empty(len(node))
        nearest[by_node] = np.repeat(least, np.diff(np.r_[heads, len(node)]))
        corner = (near.gap <= nearest + CORNER * self.radius) & (near.xi > 0.0) & (near.xi < 1.0)
        kept = np.zeros(len(node), dtype=bool)
        if keep is not None and len(keep):
            first = np.full(count, -1, dtype=np.int64)
            first[keep[:, 0]] = keep[:, 1]
            kept = corner & (first[node] == self.dofs[cell, 0])
        rank = np.where(kept, 0, np.where(corner, 1, 2))
        along = np.where(rank == 1, self.arc[cell, 0], 0.0)
        order = np.lexsort((self.arc[cell, 0], near.gap, along, rank, node))
        return order[np.r_[True, node[order][1:] != node[order][:-1]]]

    def between_nodes(self, x: np.ndarray) -> tuple[float, float, float]:
        """The least gap [m] between the rod's parts sampled between the nodes (the rows hold
        it at the nodes only: contact_search.least_gap_between_nodes) at the positions ``x``
        of the last Verlet list's cell pairs, and the arc lengths s [m] of the two cells'
        middles (inf, nan, nan without pairs)."""
        if self.verlet is None:
            return np.inf, np.nan, np.nan
        gap, i, j = least_gap_between_nodes(x, self.dofs, self.verlet.cell_pairs, self.radius)
        if i < 0:
            return gap, np.nan, np.nan
        return gap, float(self.arc[i].mean()), float(self.arc[j].mean())
