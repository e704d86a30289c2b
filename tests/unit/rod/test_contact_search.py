"""cosserat_fem/rod/contact_search.py: the rod-rod and self-contact search, closed forms.

* The P3 cell's nodes are DOLFINx 0.5.2's (GLL: (1 ∓ 1/√5)/2 inside), Λ_3 = 1.5 (the
  Lebesgue constant of 4 GLL points), and a curved P3 cell stays inside its grown box (S.1).
* Boxes: the grid's pairs are exactly the brute-force overlapping pairs (an exact test).
* Closest points against closed forms: crossing straight segments (the foot and the distance
  exactly: a straight P3 cell is linear in ξ, Newton's first step lands, round-off 1e-15 m),
  a parabola held exactly by P3 (ξ* = 1/√2, distance √3/2), the clamped ends.
* Two parallel rods at distance d: every (node, cell) pair's gap is √(d² + Δz²) − 2r, Δz the
  node's distance along the rods to the partner cell (0 inside it: d − 2r).
* A helix against itself: each node's gap to the neighbouring turn is D* − 2r, D* the helix's
  closest approach (a root of R² sin t + c² t = 0), within the P3 interpolation bound.
* Random curves: the candidates hold every cell pair that brute force finds within the margin,
  and their number a cell stays bounded as the curve grows (O(n)).
* The Verlet list: every pair whose gap closes after nodes moved < margin/(1 + Λ) is in it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial import cKDTree

from cosserat_fem.rod.contact_search import (
    VerletList,
    arc_lengths,
    candidate_pairs,
    cell_boxes,
    cell_pairs,
    closest_point_sensitivities,
    closest_points,
    least_gap_between_nodes,
    lebesgue_constant,
    reference_nodes,
    shape_functions,
)

pytestmark = pytest.mark.unit

XI3 = reference_nodes(3)


def line_cells(start, end, n: int, degree: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A straight rod from ``start`` to ``end`` in ``n`` P_k cells: (positions, dofs) with
    shared vertices (dofs: the vertices first, as DOLFINx numbers a cell)."""
    xi = reference_nodes(degree)
    t = (np.arange(n)[:, None] + xi[None, :]) / n  # (n, k+1) parameters
    dofs = np.empty((n, degree + 1), dtype=np.int64)
    dofs[:, 0], dofs[:, 1] = np.arange(n) * degree, np.arange(1, n + 1) * degree
    dofs[:, 2:] = dofs[:, :1] + np.arange(1, degree)
    positions = np.empty(((n * degree) + 1, 3))
    positions[dofs] = np.asarray(start) + t[..., None] * (np.asarray(end) - np.asarray(start))
    return positions, dofs


def curve_cells(curve, t0: float, t1: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The P3 cells interpolating ``curve`` (t ↦ (m, 3)) on [t0, t1]: (positions, dofs)."""
    positions, dofs = line_cells([t0, 0, 0], [t1, 0, 0], n)
    return curve(positions[:, 0]), dofs


def test_p3_nodes_and_lebesgue_constant():
    """GLL nodes (1 ∓ 1/√5)/2 to 1e-15; the bound of Λ_3 within 1e-3 above 1.5 (its sampling
    term is 18.2 × 2.5e-5 = 4.5e-4); a random curved P3 cell inside its box grown by (S.1),
    sampled at 2001 points (r = margin = 0)."""
    assert np.allclose(XI3, [0, 1, (1 - 5**-0.5) / 2, (1 + 5**-0.5) / 2], atol=1e-15, rtol=0)
    assert 1.5 <= lebesgue_constant(3) <= 1.501
    rng = np.random.default_rng(1)
    nodes = rng.normal(size=(200, 4, 3))
    lo, hi = cell_boxes(nodes, 0.0, 0.0)
    n = shape_functions(3, np.linspace(0, 1, 2001))[0]
    x = np.einsum("qj,cjd->cqd", n, nodes)
    assert np.all(x >= lo[:, None] - 1e-15) and np.all(x <= hi[:, None] + 1e-15)
    # Without the growth some cells leave their nodes' box: (S.1) is needed.
    assert np.any(x > nodes.max(axis=1)[:, None] + 1e-3)


@pytest.mark.parametrize("second", [False, True], ids=["one set", "two sets"])
def test_grid_pairs_are_the_overlapping_boxes(second):
    """500 random boxes (widths up to 1 in a 10-cube, some long: widths up to 4), their pairs
    from the grid equal the brute-force overlaps (all pairs tested): an exact set equality."""
    rng = np.random.default_rng(2)
    lo = rng.uniform(0, 10, (500, 3))
    hi = lo + rng.uniform(0, 1, (500, 3)) * np.where(rng.random((500, 1)) < 0.05, 4.0, 1.0)
    if second:
        lo_b = rng.uniform(0, 10, (300, 3))
        hi_b = lo_b + rng.uniform(0, 1, (300, 3))
        found = candidate_pairs(lo, hi, lo_b, hi_b)
        i, j = (a.ravel() for a in np.meshgrid(np.arange(500), np.arange(300), indexing="ij"))
    else:
        lo_b, hi_b = lo, hi
        found = candidate_pairs(lo, hi)
        i, j = np.triu_indices(500, 1)
    brute = np.column_stack([i, j])[np.all((lo[i] <= hi_b[j]) & (lo_b[j] <= hi[i]), axis=1)]
    assert len(brute) > 50
    assert np.array_equal(found, brute)


def test_crossing_segments():
    """Cell A along e1 (x ∈ [−1, 1]), cell B along e2 at height d = 0.3 (y ∈ [−1, 1]): A's node
    at x = a has its foot at (0, 0, d), ξ = 1/2, distance √(a² + d²), normal (a, 0, −d)/D,
    weights N_j(1/2), gap D − r_a − r_b; B moved to y ∈ [0.5, 2]: the foot is B's end ξ = 0,
    distance √(a² + 0.25 + d²). Round-off: 1e-15 m on unit lengths (bound 1e-14)."""
    d, ra, rb = 0.3, 0.05, 0.02
    a_pos, a_dofs = line_cells([-1, 0, 0], [1, 0, 0], 1)
    x = a_pos[a_dofs[0]]
    for y0, y1 in ((-1.0, 1.0), (0.5, 2.0)):
        b_pos, b_dofs = line_cells([0, y0, d], [0, y1, d], 1)
        cell = np.broadcast_to(b_pos[b_dofs[0]], (4, 4, 3))
        near = closest_points(x, cell, ra, rb)
        foot = max(y0, 0.0)
        dist = np.sqrt(x[:, 0] ** 2 + foot**2 + d**2)
        assert np.allclose(near.xi, (foot - y0) / (y1 - y0), atol=1e-14, rtol=0)
        assert np.allclose(near.point, [[0, foot, d]] * 4, atol=1e-14, rtol=0)
        assert np.allclose(near.gap, dist - ra - rb, atol=1e-14, rtol=0)
        expected = np.column_stack([x[:, 0], -foot + 0 * x[:, 0], -d + 0 * x[:, 0]])
        assert np.allclose(near.normal, expected / dist[:, None], atol=1e-14, rtol=0)
        assert np.allclose(near.weights, shape_functions(3, near.xi)[0], atol=0, rtol=0)
        assert np.allclose(near.weights.sum(axis=1), 1.0, atol=1e-14)


def test_curved_cell_and_its_ends():
    """The parabola y = x², x = ξ ∈ [0, 1], is a P3 cell exactly (nodes on it). From (0, 1):
    the foot at ξ* = 1/√2 (d/dx of x² + (x² − 1)² = 0), distance √3/2; from (−1, −1) the foot
    is the end ξ = 0 (distance √2); from (3, 1) the end ξ = 1 (distance 2). Newton stops at
    |Δξ| ≤ 1e-14 (quadratic: the error below): ξ to 1e-12, distances to 1e-13."""
    cell = np.column_stack([XI3, XI3**2, 0 * XI3])[None].repeat(3, axis=0)
    x = np.array([[0.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [3.0, 1.0, 0.0]])
    near = closest_points(x, cell)
    assert np.allclose(near.xi, [2**-0.5, 0.0, 1.0], atol=1e-12, rtol=0)
    assert np.allclose(near.gap, [3**0.5 / 2, 2**0.5, 2.0], atol=1e-13, rtol=0)
    assert np.allclose(near.point[0], [2**-0.5, 0.5, 0.0], atol=1e-12, rtol=0)


def test_parallel_rods():
    """Rod A on the z axis (z ∈ [0, 2], 7 cells), rod B at x = d = 0.25 (z ∈ [−0.3, 2.4], 9
    cells), r = 0.1, margin 0.1: each listed (node, cell) pair of A against B or B against A has
    gap √(d² + Δz²) − 2r, Δz = the node's distance to the cell's z-range (straight P3 cells:
    exact up to round-off, 1e-15; bound 1e-13); every node facing the other rod (z ∈ [0, 2])
    has a partner at gap d − 2r = 0.05, the others' least gap is larger;
    no pair within one rod (a straight rod's cells > π r apart are ≥ π r > 2r + margin apart)."""
    d, r, margin = 0.25, 0.1, 0.1
    pa, da = line_cells([0, 0, 0], [0, 0, 2], 7)
    pb, db = line_cells([d, 0, -0.3], [d, 0, 2.4], 9)
    positions = np.vstack([pa, pb])
    dofs = np.vstack([da, db + len(pa)])
    rod = np.repeat([0, 1], [7, 9])
    lengths = arc_lengths(positions[dofs])
    arc = np.column_stack([np.cumsum(lengths) - lengths, np.cumsum(lengths)])
    arc[7:] -= arc[7, 0]  # each rod's arc from its start
    listed = VerletList(positions, dofs, r, margin, arc, rod)
    node, cell = listed.pairs.T
    assert np.all((node < len(pa)) != (cell < 7)), "pairs across the rods only"
    z = positions[node, 2]
    zs = positions[dofs[cell]][:, :, 2]
    dz = np.maximum(np.maximum(zs.min(axis=1) - z, z - zs.max(axis=1)), 0.0)
    assert listed.closest is not None
    assert np.allclose(listed.closest.gap, np.sqrt(d**2 + dz**2) - 2 * r, atol=1e-13, rtol=0)
    assert np.all(listed.closest.gap <= margin)
    best = np.full(len(positions), np.inf)
    np.minimum.at(best, node, listed.closest.gap)
    inside = (positions[:, 2] >= -1e-12) & (positions[:, 2] <= 2 + 1e-12)  # facing the other rod
    assert np.allclose(best[inside], d - 2 * r, atol=1e-13, rtol=0)
    assert np.all(best[~inside] > d - 2 * r)
    side = np.where(node < len(pa), 1.0, -1.0)
    assert np.allclose(listed.closest.normal[dz == 0], (-side[dz == 0, None]) * [1, 0, 0])


def helix(radius: float, pitch: float):
    c = pitch / (2 * np.pi)
    return lambda t: np.column_stack([radius * np.cos(t), radius * np.sin(t), c * t])


def test_helix_against_itself():
    """A helix R = 1, pitch p = 0.5 (c = p/2π), 6 turns of 16 P3 cells each, tube r = 0.24,
    margin 0.05. D(t)² = 2R²(1 − cos t) + c²t² is the distance from a point to the one a turn
    of parameter t on; its minimum D* near t = 2π (R² sin t + c² t = 0, brentq) is every
    node's distance to each neighbouring turn (a screw symmetry). Independent check of D*:
    the minimum of D on 200 001 samples of [π, 3π] is above D* by ≤ M δ²/8, M = (R² + c²)/D*
    bounding D'' near the minimum, δ = 2π/200 000: 4e-10. The P3 cells interpolate the helix
    with an error ≤ √2 R max|∏(t − t_j)|/4! = √2 R Δ⁴ w/24 (Δ = 2π/16 the cell's parameter
    length, w = max over [0, 1] of |∏(ξ − ξ_j)|, the z component exact): 1.8e-5 m (measured
    1.1e-7: the error is mostly along the curve, the bound takes all of it). So each
    node's least gap is D* − 2r within that bound; no pair closer than π r in arc."""
    R, p, r, margin, per_turn, turns = 1.0, 0.5, 0.24, 0.05, 16, 6
    c = p / (2 * np.pi)
    t_star = brentq(lambda t: R**2 * np.sin(t) + c**2 * t, 1.5 * np.pi, 2 * np.pi, xtol=1e-15)
    d_star = math.sqrt(2 * R**2 * (1 - math.cos(t_star)) + (c * t_star) ** 2)
    t = np.linspace(np.pi, 3 * np.pi, 200001)
    sampled = np.sqrt(2 * R**2 * (1 - np.cos(t)) + (c * t) ** 2).min()
    assert 0 <= sampled - d_star <= (R**2 + c**2) / d_star * (2 * np.pi / 200000) ** 2 / 8 + 1e-15
    xi = np.linspace(0, 1, 10001)
    w = np.abs(np.prod(xi[:, None] - XI3[None, :], axis=1)).max() * 1.001
    bound = math.sqrt(2) * R * (2 * np.pi / per_turn) ** 4 * w / 24
    n = per_turn * turns
    positions, dofs = curve_cells(helix(R, p), 0.0, 2 * np.pi * turns, n)
    s = np.linspace(0.0, 2 * np.pi * turns * math.hypot(R, c), n + 1)  # exact arc length
    arc = np.column_stack([s[:-1], s[1:]])
    listed = VerletList(positions, dofs, r, margin, arc)
    assert listed.closest is not None
    best = np.full(len(positions), np.inf)
    np.minimum.at(best, listed.pairs[:, 0], listed.closest.gap)
    error = np.abs(best - (d_star - 2 * r))
    assert error.max() <= bound + 1e-12, (error.max(), bound)
    # Partners are a turn away (arc between the node and its foot near one turn, ≥ π r).
    node, cell = listed.pairs.T
    s_node = np.empty(len(positions))
    s_node[dofs] = s[:-1, None] + XI3[None, :] * (s[1] - s[0])
    s_foot = s[cell] + listed.closest.xi * (s[1] - s[0])
    assert np.all(np.abs(s_node[node] - s_foot) >= np.pi * r)


def random_curve(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A persistent random walk of n P3 cells (step h = 1) reflected in a cube of volume 20 n
    (a density that does not grow with n), interior nodes off the chord by ≤ 0.2:
    (positions, dofs, arc)."""
    rng = np.random.default_rng(seed)
    side = (20.0 * n) ** (1 / 3)
    v = np.empty((n + 1, 3))
    v[0] = side / 2
    direction = rng.normal(size=3)
    for i in range(n):
        direction = direction / np.linalg.norm(direction) + 0.6 * rng.normal(size=3)
        step = direction / np.linalg.norm(direction)
        nxt = v[i] + step
        out = (nxt < 0) | (nxt > side)
        direction[out] *= -1
        v[i + 1] = np.where(out, v[i] - step, nxt)
    positions, dofs = line_cells([0, 0, 0], [1, 0, 0], n)
    positions[dofs[:, 0]], positions[dofs[:, 1]] = v[:-1], v[1:]
    for j, x in enumerate(XI3[2:]):
        positions[dofs[:, 2 + j]] = (1 - x) * v[:-1] + x * v[1:] + rng.uniform(-0.2, 0.2, (n, 3))
    lengths = arc_lengths(positions[dofs])
    arc = np.column_stack([np.cumsum(lengths) - lengths, np.cumsum(lengths)])
    return positions, dofs, arc


def sampled_pairs(nodes, radius, margin, arc):
    """Every cell pair (i < j, not excluded in arc) whose curves sampled at 17 points each come
    within 2r + margin (sampled distances ≥ the true ones, so each pair found is truly within
    the margin): all pairs of samples within that distance, found exactly by a k-d tree
    (scipy's, independent of the grid)."""
    x = np.einsum("qj,cjd->cqd", shape_functions(3, np.linspace(0, 1, 17))[0], nodes)
    close = cKDTree(x.reshape(-1, 3)).query_pairs(2 * radius + margin, output_type="ndarray")
    pairs = np.unique(np.sort(close // 17, axis=1), axis=0)
    pairs = pairs[pairs[:, 0] < pairs[:, 1]]
    apart = np.maximum(arc[pairs[:, 1], 0] - arc[pairs[:, 0], 1], 0.0)
    return pairs[apart >= np.pi * radius]


def test_candidates_hold_every_near_pair_and_grow_linearly():
    """Random curves of 200 and 2000 cells, r = 0.15, margin 0.1: every sampled pair
    (:func:`sampled_pairs`) is a candidate, and the candidates a cell differ by < 2× between
    the sizes (a set growing as n² would give 10×; the curve's density is fixed)."""
    r, margin = 0.15, 0.1
    per_cell = []
    for n in (200, 2000):
        positions, dofs, arc = random_curve(n, seed=n)
        nodes = positions[dofs]
        found = cell_pairs(nodes, r, margin, arc)
        brute = sampled_pairs(nodes, r, margin, arc)
        assert len(brute) > n // 20, len(brute)
        have = set(map(tuple, found.tolist()))
        missing = [p for p in map(tuple, brute.tolist()) if p not in have]
        assert not missing, missing[:5]
        per_cell.append(len(found) / n)
    assert max(per_cell) < 2 * min(per_cell), per_cell


def test_verlet_list_holds_every_closing_pair():
    """A random curve of 150 cells, r = 0.15, margin 0.2, listed; its nodes then moved by
    random vectors of length 0.99 margin/(1 + Λ_3): the list is not stale, and every (node,
    cell) pair not excluded in arc whose gap is ≤ 0 now (all node-cell pairs, brute force) is in
    it; some of them had a positive gap at the build (the test is not empty). A node moved by
    1.01 × that makes it stale."""
    r, margin = 0.15, 0.2
    positions, dofs, arc = random_curve(150, seed=5)
    listed = VerletList(positions, dofs, r, margin, arc)
    rng = np.random.default_rng(6)
    step = rng.normal(size=positions.shape)
    step *= 0.99 * margin / (1 + lebesgue_constant(3)) / np.linalg.norm(step, axis=1)[:, None]
    moved = positions + step
    assert not listed.stale(moved)
    node_cell = np.zeros((len(positions), len(dofs)), dtype=bool)
    node_cell[dofs, np.arange(len(dofs))[:, None]] = True
    own = np.array([np.flatnonzero(row) for row in node_cell], dtype=object)
    node, cell = (a.ravel() for a in np.meshgrid(np.arange(len(positions)), np.arange(len(dofs))))
    mine = np.array([o[0] for o in own])[node]
    apart = np.maximum(np.maximum(arc[cell, 0] - arc[mine, 1], arc[mine, 0] - arc[cell, 1]), 0)
    far = apart >= np.pi * r + 1.0  # 1.0 ≥ the node's cell: far in arc from either of its cells
    node, cell = node[far], cell[far]
    now = closest_points(moved[node], moved[dofs[cell]], r, r).gap
    before = closest_points(positions[node], positions[dofs[cell]], r, r).gap
    closing = now <= 0
    have = set(map(tuple, listed.pairs.tolist()))
    assert all((a, b) in have for a, b in zip(node[closing], cell[closing], strict=True))
    assert np.sum(closing & (before > 0)) > 0
    jump = positions.copy()
    jump[7, 0] += 1.01 * margin / (1 + lebesgue_constant(3))
    assert listed.stale(jump)


def hairpin(s: np.ndarray, rho: float, leg: float) -> np.ndarray:
    """A hairpin by arc length s: down the leg x = −ρ (z from ``leg`` to 0), a half circle of
    radius ρ below the origin, up the leg x = +ρ."""
    bend = np.clip((s - leg) / rho, 0.0, np.pi)  # the angle turned
    x = -rho * np.cos(bend)
    z = np.where(s < leg, leg - s, 0.0) - rho * np.sin(bend) + np.maximum(s - leg - np.pi * rho, 0)
    return np.column_stack([x, 0 * s, z])


def test_self_exclusion_keeps_the_hairpins_legs():
    """A hairpin of bending radius ρ = 1.5 r (r = 0.1, legs 0.6, 67 P3 cells ≈ r/4 long), margin
    1.2 r: the legs face each other at 2ρ, so every leg node above z = 0.4 (farther than 2ρ from
    the bend; its partners straight cells: exact) has a least gap 2ρ − 2r = r (round-off, bound
    1e-13); lower leg nodes meet their own bend beyond π r of arc (gap 0.086, real); no kept
    pair has a
    negative gap (the bend's points ≥ π r apart in arc subtend ≥ π/1.5 rad: chord ≥ 2ρ sin(π/3)
    = 2.6 r, gap ≥ 0.6 r; P3 interpolates the bend to ~1e-6 r); without the exclusion nodes
    meet their own neighbours' tubes (negative gaps)."""
    r, rho, leg, margin = 0.1, 0.15, 0.6, 0.12
    total = 2 * leg + np.pi * rho
    n = 67
    positions, dofs = curve_cells(lambda s: hairpin(s, rho, leg), 0.0, total, n)
    s = np.linspace(0.0, total, n + 1)
    arc = np.column_stack([s[:-1], s[1:]])
    listed = VerletList(positions, dofs, r, margin, arc)
    assert listed.closest is not None
    assert listed.closest.gap.min() >= 0.5 * r
    best = np.full(len(positions), np.inf)
    np.minimum.at(best, listed.pairs[:, 0], listed.closest.gap)
    high = positions[:, 2] >= 0.4
    assert np.allclose(best[high], 2 * rho - 2 * r, atol=1e-13, rtol=0)
    spurious = VerletList(positions, dofs, r, margin, arc=None)
    assert spurious.closest is not None and spurious.closest.gap.min() < -r


def test_closest_points_find_the_least_of_several_minima():
    """2000 random curved P3 cells (nodes off the unit chord by N(0, 0.15²): wiggly, φ often
    with two minima) against random nodes: the gap equals the least distance over 2001
    samples of the cell from above to within the samples' error, max|x_b'| δ/2 (δ = 1/2000:
    the distance is Lipschitz in ξ), and from below to 1e-14 (a sample is a point of the cell).
    Newton from the nearest node alone missed the least minimum for 1.6 % of 20 000 such
    pairs (by up to 0.39); from every sampled local minimum, none."""
    rng = np.random.default_rng(0)
    m = 2000
    cells = np.column_stack([XI3, 0 * XI3, 0 * XI3])[None] + rng.normal(scale=0.15, size=(m, 4, 3))
    x = rng.normal(scale=0.7, size=(m, 3)) + [0.5, 0, 0]
    near = closest_points(x, cells)
    table = shape_functions(3, np.linspace(0, 1, 2001), 1)
    sampled = np.linalg.norm(np.einsum("qj,mjd->mqd", table[0], cells) - x[:, None], axis=2)
    speed = np.linalg.norm(np.einsum("qj,mjd->mqd", table[1], cells), axis=2).max(axis=1)
    excess = sampled.min(axis=1) - near.gap
    assert np.all(excess >= -1e-14)
    assert np.all(excess <= 1.1 * speed / 2000 / 2)


def test_closest_point_sensitivities_are_the_derivatives():
    """(S.3)'s derivatives of the gap, the normal and the partner's weights against central
    differences of :func:`closest_points` re-solved at moved points, on wiggly P3 cells (an
    interior foot) and with the foot clamped at an end (ξ held). Central differences err by
    O(ε²) times the third derivatives (O(1) here, the cells of size 1) plus the solve's
    round-off 1e-14/ε: at ε = 1e-5 both are ~1e-9 — the bound 1e-7 is above them and far
    below a missing term (the ξ terms are O(1): dropping dξ changes ∂n by > 0.1)."""
    rng = np.random.default_rng(7)
    m = 6
    cells = np.column_stack([XI3, np.zeros(4), np.zeros(4)])[None].repeat(m, axis=0)
    cells = cells + 0.15 * rng.standard_normal(cells.shape)
    x = np.column_stack([rng.uniform(0.3, 0.7, m), 0.4 + 0.2 * rng.random(m), rng.random(m)])
    x[-1] = [-0.8, 0.1, 0.0]  # beyond the cell's start: the foot is the end ξ = 0
    near = closest_points(x, cells)
    assert 0.0 < near.xi[:-1].min() and near.xi[:-1].max() < 1.0 and near.xi[-1] == 0.0
    exact = closest_point_sensitivities(x, cells, near)
    eps = 1e-5
    for i in range(5):  # the node, then the cell's four nodes
        for q in range(3):
            moved = []
            for sign in (1.0, -1.0):
                xs, cs = x.copy(), cells.copy()
                if i == 0:
                    xs[:, q] += sign * eps
                else:
                    cs[:, i - 1, q] += sign * eps
                moved.append(closest_points(xs, cs))
            up, down = moved
            assert np.abs((up.gap - down.gap) / (2 * eps) - exact.gap[:, i, q]).max() < 1e-7
            dn = (up.normal - down.normal) / (2 * eps)
            assert np.abs(dn - exact.normal[:, :, i, q]).max() < 1e-7
            dw = (up.weights - down.weights) / (2 * eps)
            assert np.abs(dw - exact.weights[:, :, i, q]).max() < 1e-7


def test_the_gap_between_nodes_finds_crossing_cells():
    """Two straight P3 cells of length 1 crossing at a right angle at their middles, their
    axes d = 0.05 apart, tubes of r = 0.03: they pass through each other by 2r − d = 0.01,
    yet every node is ≥ √(d² + (0.5 − 0.2764)²) − 2r = 0.169 from the other cell. Sampled at
    ξ = q/8, the middles ξ = 1/2 are among the points: the least gap is d − 2r exactly (to
    round-off), found on the pair, which node-to-cell gaps miss."""
    xi = reference_nodes(3)
    a = np.column_stack([xi - 0.5, 0 * xi, 0 * xi])
    b = np.column_stack([0 * xi, xi - 0.5, 0 * xi + 0.05])
    positions, dofs = np.vstack([a, b]), np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    gap, i, j = least_gap_between_nodes(positions, dofs, np.array([[0, 1]]), 0.03)
    assert gap == pytest.approx(-0.01, abs=1e-14) and {i, j} == {0, 1}
    nodes = closest_points(positions[[0, 1, 2, 3]], np.repeat(b[None], 4, 0), 0.03, 0.03)
    assert nodes.gap.min() > 0.16
    assert least_gap_between_nodes(positions, dofs, np.zeros((0, 2), int), 0.03)[0] == np.inf
