"""cosserat_fem/rod/contact_search.py under ``mpirun -n 2``: the candidate pairs found from
allgathered boxes equal the serial ones.

A two-strand plectoneme-like curve (the design's worst case: every cell has partners on the
other strand, 400 P3 cells, tube radius 0.9 × half the strands' distance) is dealt to the
ranks at random (each cell's rank drawn from one seed, the same on every rank: no contiguity
assumed). Each rank finds its pairs (global ids i < j, i owned) with every rank's cells
(:func:`parallel_pairs`), then the least node-to-cell gap of each pair from the gathered
nodes. The union over ranks must be the serial set, each pair once (an exact integer
equality: the boxes are the same floating-point numbers however the cells are dealt), and the
gaps equal to 1e-13 m (the same arithmetic on the same numbers; batched differently, so not
asserted bit for bit). On one rank the script also checks :func:`parallel_pairs` against the
serial :func:`cell_pairs`.
"""

from __future__ import annotations

import pytest
from conftest import script_serial_and_mpi

_SCRIPT = """
import json
import numpy as np
from mpi4py import MPI
from cosserat_fem.rod.contact_search import (
    Cells, arc_lengths, cell_pairs, closest_points, parallel_pairs, reference_nodes)

comm = MPI.COMM_WORLD
n, radius, margin = 400, 0.9, 0.2
m = n // 2
t = (np.arange(n)[:, None] + reference_nodes(3)[None, :]) / n  # (n, 4) on [0, 1]
phase = 2 * np.pi * n / 32 * np.where(t <= 0.5, 2 * t, 2 - 2 * t)  # out on one strand, back
strand = np.where(t <= 0.5, 0.0, np.pi)
nodes = np.stack([np.cos(phase + strand), np.sin(phase + strand), 8 * phase], axis=-1)
lengths = arc_lengths(nodes)
arc = np.column_stack([np.cumsum(lengths) - lengths, np.cumsum(lengths)])
owner = np.random.default_rng(0).integers(comm.size, size=n)
mine = np.flatnonzero(owner == comm.rank)
owned = Cells(nodes[mine], np.full(len(mine), radius), arc[mine], np.zeros(len(mine), int), mine)
pairs, every = parallel_pairs(comm, owned, margin)
where = {int(g): k for k, g in enumerate(every.ids)}
i = np.array([where[a] for a in pairs[:, 0]], dtype=int)
j = np.array([where[b] for b in pairs[:, 1]], dtype=int)
gaps = []
for a, b in ((i, j), (j, i)):  # each cell's 4 nodes against the other cell
    near = closest_points(every.nodes[a].reshape(-1, 3), np.repeat(every.nodes[b], 4, axis=0),
                          radius, radius)
    gaps.append(near.gap.reshape(-1, 4).min(axis=1))
gap = np.minimum(*gaps) if len(pairs) else np.zeros(0)
found = comm.gather((pairs.tolist(), gap.tolist()), root=0)
check = None
if comm.size == 1:
    check = cell_pairs(nodes, radius, margin, arc).tolist() == pairs.tolist()
if comm.rank == 0:
    rows = sorted(zip(*(sum((f[q] for f in found), []) for q in range(2))))
    print(json.dumps({"pairs": [r[0] for r in rows], "gaps": [r[1] for r in rows],
                      "serial_function": check}))
"""


@pytest.mark.mpi
def test_parallel_pairs_equal_serial(tmp_path):
    """The module docstring's equalities; the set is not empty (≥ n/2 pairs: every cell of
    one strand meets the other strand) and no pair is found twice."""
    serial, parallel = script_serial_and_mpi(tmp_path / "pairs.py", _SCRIPT)
    assert serial["serial_function"] is True
    assert len(serial["pairs"]) >= 200
    assert len({tuple(p) for p in parallel["pairs"]}) == len(parallel["pairs"])
    assert parallel["pairs"] == serial["pairs"]
    gaps = [abs(a - b) for a, b in zip(serial["gaps"], parallel["gaps"], strict=True)]
    assert max(gaps) <= 1e-13
