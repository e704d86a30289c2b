"""A rod's contact with itself: which node presses on which cell (docs/contact.md, "Self
contact"). The search is cosserat_fem/rod/contact_search.py's (a Verlet list of (node, cell)
pairs within a margin, rebuilt when a node has moved margin/(1 + Λ_k), self contact excluded
within π r of arc (S.2)); the rows are cosserat_fem/nls/pair_contact.py's.

Single pass: of the two directions of a contact (a node of one part of the rod on a cell of the
other, and back), the node that lies later along the rod is the slave and the cell the partner
(a node after the cell's last node in arc length). Each slave keeps its nearest partner cell.
"""

from __future__ import annotations

import numpy as np

from cosserat_fem.nls.pair_contact import Pairs
from cosserat_fem.rod.contact_search import (
    ClosestPoints,
    VerletList,
    closest_point_sensitivities,
    closest_points,
    least_gap_between_nodes,
)


class SelfContactGeometry:
    """The :class:`~cosserat_fem.nls.pair_contact.Pairs` of one rod whose cells are ``dofs``
    (cells, k+1) (global node indices, dof order), its nodes at arc lengths ``places`` (N,)
    [m] at rest, its surface a tube of ``radius`` r [m]; pairs within ``margin`` [m]."""

    def __init__(self, dofs: np.ndarray, places: np.ndarray, radius: float, margin: float):
        self.dofs, self.places = dofs, places
        self.radius, self.margin = radius, margin
        arc = places[dofs]
        self.arc = np.column_stack([arc.min(axis=1), arc.max(axis=1)])
        self.verlet: VerletList | None = None
        #: how many times the Verlet list was built
        self.builds = 0

    def __call__(self, x: np.ndarray) -> Pairs:
        """The single-pass pairs at the nodes' positions ``x`` (N, 3) [m]."""
        if self.verlet is None or self.verlet.stale(x):
            self.verlet = VerletList(x, self.dofs, self.radius, self.margin, self.arc)
            self.builds += 1
        node, cell = self.verlet.pairs.reshape(-1, 2).T
        later = self.places[node] > self.arc[cell, 1]
        node, cell = node[later], cell[later]
        cells = x[self.dofs[cell]]
        near = closest_points(x[node], cells, self.radius, self.radius)
        # each slave's nearest partner
        order = np.lexsort((near.gap, node))
        if len(order):
            order = order[np.concatenate([[True], node[order][1:] != node[order][:-1]])]
        node, cell, cells = node[order], cell[order], cells[order]
        near = ClosestPoints(
            *(getattr(near, f)[order] for f in ("xi", "point", "gap", "normal", "weights"))
        )
        d = closest_point_sensitivities(x[node], cells, near)
        return Pairs(
            node, self.dofs[cell], near.gap, near.normal, near.weights, d.gap, d.normal, d.weights
        )

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
