# %% [markdown]
# # The cost of the rod-rod search (docs/contact.md, "Rod-rod search (built, not wired)")
#
# The design's worst case, a two-strand plectoneme-like curve of n P3 cells whose strands
# nearly touch (every cell has partners on the other strand; 16 cells a turn on each strand,
# tube radius 0.9 of half the strands' distance, margin 0.2), searched for self contact:
# the candidate cell pairs (boxes, grid, the π r exclusion) and the Verlet list (each node
# of a pair's cell against the other cell: Newton's closest points, then g ≤ margin).
# Best of ``repeats`` runs, one process, numpy.
#
#     .venv/bin/python benchmarks/contact_search.py [repeats]

# %%
from __future__ import annotations

import sys
import time

import numpy as np

from cosserat_fem.rod.contact_search import VerletList, arc_lengths, cell_pairs, reference_nodes


def plectoneme(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, dofs, arc) of n P3 cells: out along one strand, back along the other."""
    t = (np.arange(n)[:, None] + reference_nodes(3)[None, :]) / n
    phase = 2 * np.pi * n / 32 * np.where(t <= 0.5, 2 * t, 2 - 2 * t)
    strand = np.where(t <= 0.5, 0.0, np.pi)
    nodes = np.stack([np.cos(phase + strand), np.sin(phase + strand), 8 * phase], axis=-1)
    dofs = np.empty((n, 4), dtype=np.int64)
    dofs[:, 0], dofs[:, 1] = 3 * np.arange(n), 3 * np.arange(1, n + 1)
    dofs[:, 2:] = dofs[:, :1] + np.arange(1, 3)
    positions = np.empty((3 * n + 1, 3))
    positions[dofs] = nodes
    lengths = arc_lengths(nodes)
    return positions, dofs, np.column_stack([np.cumsum(lengths) - lengths, np.cumsum(lengths)])


# %%
if __name__ == "__main__":
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    radius, margin = 0.9, 0.2
    for n in (1000, 10_000, 100_000):
        positions, dofs, arc = plectoneme(n)
        best_pairs = best_list = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            pairs = cell_pairs(positions[dofs], radius, margin, arc)
            t1 = time.perf_counter()
            listed = VerletList(positions, dofs, radius, margin, arc)
            t2 = time.perf_counter()
            best_pairs, best_list = min(best_pairs, t1 - t0), min(best_list, t2 - t1)
        print(
            f"{n:>7} cells: {len(pairs):>7} candidate pairs ({len(pairs) / n:.2f} a cell) in "
            f"{best_pairs * 1e3:8.1f} ms ({best_pairs / n * 1e6:.1f} µs a cell); Verlet list "
            f"{len(listed.pairs):>7} node-cell pairs in {best_list * 1e3:8.1f} ms "
            f"({best_list / n * 1e6:.1f} µs a cell, the pairs' search included)"
        )
