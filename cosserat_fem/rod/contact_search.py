"""Rod-rod and self contact: the geometric search (docs/contact.md, "Rod-rod search").

Built, not wired into the Newton rows yet (docs/contact-design.md, "Rod-rod and self contact").
A rod's centreline is a chain of P_k cells, x(ξ) = Σ_j N_j(ξ) x_j, ξ ∈ [0, 1], N_j the
element's own Lagrange basis (basix, as DOLFINx 0.5.2 builds "CG" k: the ``gll_warped``
lattice, which on an interval is the Gauss-Lobatto-Legendre points, P3: 0, 1, 0.2764, 0.7236
in the cell's dof order, the two vertices first). Each cell carries a circular tube of radius r.
A cell is given by its nodal positions, an array (cells, k+1, 3) [m] in that dof order.

* **Boxes** (:func:`cell_boxes`). A P_k cell bulges beyond its nodes' box: since Σ N_j = 1,
  x_c(ξ) − lo_c = Σ N_j (x_jc − lo_c) ≤ P(ξ) w_c with P = Σ_{N_j>0} N_j = (Λ(ξ) + 1)/2,
  Λ(ξ) = Σ |N_j(ξ)| the Lebesgue function, w_c the box's width along axis c. So the curve lies
  in the nodes' box grown by ((Λ_k − 1)/2) w_c along each axis c                          (S.1)
  (Λ_k = max Λ: 1, 1.25, 1.5, 1.64 for P1-P4 on these points; :func:`lebesgue_constant`
  bounds it from above). Grown further by r + margin/2, two cells' boxes overlap whenever
  their tubes come within ``margin`` of each other (the gap's points differ by ≤ r_a + r_b +
  margin along every axis).
* **Candidate pairs** (:func:`candidate_pairs`): the boxes hashed into a uniform grid of
  spacing s (the 90th percentile of the boxes' largest widths, ≥ 1/16 of the widest; a box
  meets ∏_c (⌊hi_c/s⌋ − ⌊lo_c/s⌋ + 1) grid cells, ≤ 8 for most, ≤ 17³ for the widest), pairs
  formed within each grid cell, each pair kept once (in the grid cell of its overlap's lower
  corner) when the boxes overlap. The cost is
  O(n) in the cells when the number of boxes a grid cell meets is bounded (tubes that do not
  interpenetrate pack at most O(s³/(r² h)) cells into a grid cell), plus a sort (n log n).
* **Self contact** (:func:`exclude_neighbours`): two cells of one rod closer than π r in arc
  length (between their nearer ends) are not a pair. The argument: a contact of the tube with
  itself is a chord x(s₂) − x(s₁) of length d = 2r normal to the centreline at both ends (a
  critical point of the distance). Take u its direction and f(s) = (x(s) − x(s₁))·u: f' =
  sin φ, φ the tangent's angle out of the plane normal to u, φ(s₁) = φ(s₂) = 0 and |φ'| ≤ κ.
  A tube of radius r folds over itself where κ > 1/r, so κ ≤ 1/r, and pointwise φ(s) ≤
  min((s − s₁)/r, (s₂ − s)/r, π/2) gives, with L = s₂ − s₁ ≤ π r,
      d = f(s₂) ≤ ∫ sin(min(...)) ds = 2r (1 − cos(L/(2r))) < 2r  when L < π r,        (S.2)
  equality only for a half circle of radius r. So no real contact lies within π r of arc.
  There the tube is its own neighbourhood (Schur's comparison, κ ≤ 1/r: a chord of arc
  L ≤ π r is ≥ 2r sin(L/(2r)), so the distance of a node to its own rod reaches 2r at π r at
  the earliest): the excluded band holds the spurious contacts (a node always lies on its
  own neighbours' tubes), and a kept pair with g ≤ 0 is the rod come back on itself (on a
  straight rod the nearest kept point is π r away: g ≥ (π − 2) r). Between
  cell midpoints this is the design's π r + h for equal cells h. It drops a real contact whose
  points are < π r + h_i + h_j apart in arc: by (S.2) with a bending radius ρ instead of r,
  2ρ (1 − cos(L/(2ρ))) ≥ 2r needs L ≥ 2ρ arccos(1 − r/ρ), so only a rod bent somewhere
  between the two points to a radius ρ with 2ρ arccos(1 − r/ρ) < π r + h_i + h_j (equal
  cells h = r/4, r, 10 r: ρ < 1.45 r, 3.12 r, 67 r, surface strains r/ρ > 69 %, 32 %, 1.5 %).
  Coarse cells (h ≫ r) therefore cost real contacts of tight loops: mesh them finer.
* **Closest points** (:func:`closest_points`): node x_a against a cell x_b(ξ): Newton on
  φ'(ξ) = −(x_a − x_b(ξ))·x_b'(ξ) = 0 (φ = |x_a − x_b|²/2, a polynomial of degree 2k: on a
  curved cell it may have two minima), from every local minimum of φ sampled at 4k + 1 points
  (not the nearest node alone: that misses the least minimum of 1.6 % of wiggly random cells),
  ξ clamped to [0, 1] (an end is the answer when φ decreases out of the cell), the
  Gauss-Newton curvature |x_b'|² where φ'' ≤ 0, steps halved while φ grows; the least of
  these and the two ends. Gap
  g = |x_a − x_b(ξ)| − r_a − r_b [m], normal n = (x_a − x_b(ξ))/|·| (from b to a), weights
  N_j(ξ) of b's nodes: what the rows need (the reaction on b's node j is N_j(ξ) n f_N).
* **Verlet list** (:class:`VerletList`): the (node, cell) pairs with g ≤ margin, stale when a
  node has moved more than margin/(1 + Λ_k) since (the design's margin/2 for P1): a pair
  outside the list had g > margin, and its gap drops by at most |Δx_a| + max_ξ |Σ N_j Δx_j|
  ≤ (1 + Λ_k) max |Δx|, so while no node has moved that far it stays > 0.
* **MPI** (:func:`gather_cells`, :func:`parallel_pairs`): each rank's owned cells (nodes, radii,
  arc intervals, global ids) allgathered (8 (3(k+1) + 4) bytes a cell: 1.3 MB at 10⁴ P3 cells);
  each rank pairs its owned cells with every cell, keeping (i, j) with global ids i < j, i
  owned: the union over ranks is the serial set, each pair once.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import basix
import numpy as np
from mpi4py import MPI

#: Closest points are computed in chunks of this many pairs (a working set that stays in the
#: cache: 42 µs a cell at 10⁵ cells, not 72-97 in one piece, before the sampled starts).
CHUNK = 1 << 15
#: Newton starts from each local minimum of the distance sampled at SAMPLES k + 1 points.
SAMPLES = 4


@cache
def _element(degree: int):
    return basix.create_element(
        basix.ElementFamily.P, basix.CellType.interval, degree, basix.LagrangeVariant.gll_warped
    )


def reference_nodes(degree: int) -> np.ndarray:
    """The P_k cell's nodes ξ_j ∈ [0, 1], in DOLFINx 0.5.2's dof order (vertices first)."""
    return _element(degree).points[:, 0].copy()


def shape_functions(degree: int, xi: np.ndarray, derivatives: int = 0) -> np.ndarray:
    """N_j and its ξ-derivatives at the points ``xi`` (m,): (derivatives + 1, m, k + 1)."""
    points = np.asarray(xi, dtype=float).reshape(-1, 1)
    if not len(points):  # basix 0.5.1 aborts the process on no points
        return np.zeros((derivatives + 1, 0, degree + 1))
    return _element(degree).tabulate(derivatives, points)[..., 0]


@cache
def lebesgue_constant(degree: int) -> float:
    """An upper bound of Λ_k = max_ξ Σ_j |N_j(ξ)| (S.1): its maximum on 20 001 points plus
    the Lipschitz bound max Σ |N_j'| times half their spacing (Λ's growth between them)."""
    xi = np.linspace(0.0, 1.0, 20001)
    table = shape_functions(degree, xi, 1)
    return float(
        np.abs(table[0]).sum(axis=1).max() + np.abs(table[1]).sum(axis=1).max() * 0.5 / 20000
    )


def _degree(nodes: np.ndarray) -> int:
    if nodes.ndim != 3 or nodes.shape[2] != 3 or nodes.shape[1] < 2:
        raise ValueError(f"cell nodes: an array (cells, k+1, 3), got shape {nodes.shape}")
    return nodes.shape[1] - 1


def cell_boxes(
    nodes: np.ndarray, radius: np.ndarray | float, margin: float
) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (lo, hi), each (cells, 3) [m], that hold each cell's tube grown by margin/2: the
    nodes' box grown by (S.1) and by r + margin/2."""
    lo, hi = nodes.min(axis=1), nodes.max(axis=1)
    grow = 0.5 * (lebesgue_constant(_degree(nodes)) - 1.0) * (hi - lo)
    grow += (np.broadcast_to(radius, (len(nodes),)) + 0.5 * margin)[:, None]
    return lo - grow, hi + grow


def candidate_pairs(
    lo: np.ndarray, hi: np.ndarray, lo_b: np.ndarray | None = None, hi_b: np.ndarray | None = None
) -> np.ndarray:
    """The pairs of overlapping boxes, (m, 2) sorted: of one set, (i, j) with i < j; of two,
    (i, j) with i in the first and j in the second. Grid hashing (module docstring)."""
    boxes = [b for b in (lo, hi, lo_b, hi_b) if b is not None]
    if not all(np.isfinite(b).all() for b in boxes):  # a diverged state: no pair is lost silently
        raise FloatingPointError("contact search: a cell's box is not finite")
    side, offset = np.zeros(len(lo), dtype=np.int64), 0
    two = lo_b is not None and hi_b is not None
    if lo_b is not None and hi_b is not None:
        side = np.repeat([0, 1], [len(lo), len(lo_b)])
        offset = len(lo)
        lo, hi = np.vstack([lo, lo_b]), np.vstack([hi, hi_b])
    n = len(lo)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    widths = (hi - lo).max(axis=1)
    # A box meets ≤ 8 grid cells if it is no wider than the spacing, the widest ≤ 17³.
    spacing = max(float(np.quantile(widths, 0.9)), float(widths.max()) / 16)
    spacing = spacing if spacing > 0.0 else 1.0
    first = np.floor(lo / spacing).astype(np.int64)
    counts = np.floor(hi / spacing).astype(np.int64) - first + 1
    total = counts.prod(axis=1)
    who = np.repeat(np.arange(n), total)
    k = np.arange(len(who)) - np.repeat(np.cumsum(total) - total, total)
    c = counts[who]
    grid = first[who] + np.column_stack(
        [k % c[:, 0], (k // c[:, 0]) % c[:, 1], k // (c[:, 0] * c[:, 1])]
    )
    order = np.lexsort(grid.T[::-1])
    grid, who = grid[order], who[order]
    bucket = np.concatenate([[0], np.cumsum(np.any(grid[1:] != grid[:-1], axis=1))])
    found = []
    for d in range(1, len(who)):
        same = np.flatnonzero(bucket[d:] == bucket[:-d])
        if not len(same):
            break
        a, b = who[same], who[same + d]
        if two:
            keep = side[a] != side[b]
            same, a, b = same[keep], a[keep], b[keep]
        overlap = np.all((lo[a] <= hi[b]) & (lo[b] <= hi[a]), axis=1)
        corner = np.floor(np.maximum(lo[a], lo[b]) / spacing).astype(np.int64)
        once = overlap & np.all(corner == grid[same], axis=1)
        found.append(np.column_stack([np.minimum(a, b), np.maximum(a, b)])[once])
    pairs = np.vstack(found) if found else np.zeros((0, 2), dtype=np.int64)
    if two:
        pairs[:, 1] -= offset
    return pairs[np.lexsort(pairs.T[::-1])]


def _too_near(arc_i, arc_j, r_i, r_j) -> np.ndarray:
    """Whether cells of one rod with arc intervals ``arc_i``, ``arc_j`` (m, 2) are closer than
    π max(r_i, r_j) between their nearer ends (S.2)."""
    apart = np.maximum(np.maximum(arc_j[:, 0] - arc_i[:, 1], arc_i[:, 0] - arc_j[:, 1]), 0.0)
    return apart < np.pi * np.maximum(r_i, r_j)


def exclude_neighbours(
    pairs: np.ndarray, arc: np.ndarray, radius: np.ndarray | float
) -> np.ndarray:
    """The ``pairs`` of one rod's cells whose arc distance (between their nearer ends; ``arc``
    (cells, 2) each cell's [s₀, s₁] along the rod [m], current arc length) is ≥ π max(r_i,
    r_j): the self-contact exclusion (S.2)."""
    r = np.broadcast_to(radius, (len(arc),))
    i, j = pairs[:, 0], pairs[:, 1]
    return pairs[~_too_near(arc[i], arc[j], r[i], r[j])]


def arc_lengths(nodes: np.ndarray) -> np.ndarray:
    """Each cell's length ∫ |x'(ξ)| dξ [m] (Gauss-Legendre, 2k + 2 points: exact for a
    straight cell, O(h^{4k+4}) otherwise); the cumulative sum along a rod gives ``arc``."""
    k = _degree(nodes)
    points, weights = np.polynomial.legendre.leggauss(2 * k + 2)
    dn = shape_functions(k, 0.5 * (points + 1.0), 1)[1]
    return np.linalg.norm(np.einsum("qj,cjd->cqd", dn, nodes), axis=2) @ (0.5 * weights)


def _phi(degree: int, xi: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """φ = |x_b(ξ)|²/2 at each pair's ``xi``, the cells relative to their nodes."""
    xb = np.einsum("mj,mjd->md", shape_functions(degree, xi)[0], cells)
    return 0.5 * np.einsum("md,md->m", xb, xb)


@dataclass(frozen=True)
class ClosestPoints:
    """Node-to-cell closest points (module docstring), each (m,) or (m, ·)."""

    xi: np.ndarray  # the partner cell's ξ ∈ [0, 1]
    point: np.ndarray  # x_b(ξ) [m]
    gap: np.ndarray  # |x_a − x_b(ξ)| − r_a − r_b [m]
    normal: np.ndarray  # (x_a − x_b(ξ))/|·|, from the partner to the node
    weights: np.ndarray  # N_j(ξ) of the partner's k + 1 nodes (dof order)


def _newton(cells: np.ndarray, xi: np.ndarray, tolerance: float, max_iterations: int) -> np.ndarray:
    """Safeguarded Newton for φ'(ξ) = 0 from ``xi`` (:func:`closest_points`), the cells
    relative to their nodes (x_a = 0)."""
    k = cells.shape[1] - 1
    xi = xi.copy()
    active = np.ones(len(xi), dtype=bool)
    sizes = np.sqrt(np.einsum("mjd,mjd->mj", cells, cells))
    for _ in range(max_iterations):
        if not active.any():
            break
        idx = np.flatnonzero(active)
        table = shape_functions(k, xi[idx], 2)
        xb, t, tt = (np.einsum("mj,mjd->md", table[q], cells[idx]) for q in range(3))
        slope = np.einsum("md,md->m", xb, t)  # φ' = −(x_a − x_b)·x_b', x_a = 0
        speed = np.einsum("md,md->m", t, t)
        curvature = speed + np.einsum("md,md->m", xb, tt)
        step = -slope / np.where(curvature > 0.0, curvature, speed)
        # Halve the step while φ grows (a safeguard where φ is not convex on the cell).
        phi = 0.5 * np.einsum("md,md->m", xb, xb)
        new = np.clip(xi[idx] + step, 0.0, 1.0)
        for _ in range(60):
            grows = _phi(k, new, cells[idx]) > phi * (1.0 + 1e-14)
            if not grows.any():
                break
            step = np.where(grows, 0.5 * step, step)
            new = np.clip(xi[idx] + step, 0.0, 1.0)
        # Converged: the update below the tolerance, or the slope at its round-off level.
        spread = np.einsum("mj,mj->m", np.abs(table[1]), sizes[idx])
        reach = np.einsum("mj,mj->m", np.abs(table[0]), sizes[idx])
        noise = 8 * np.finfo(float).eps * (np.sqrt(2 * phi) * spread + np.sqrt(speed) * reach)
        active[idx] = (np.abs(new - xi[idx]) > tolerance) & (np.abs(slope) > noise)
        xi[idx] = new
    if active.any():
        raise FloatingPointError(f"closest points: {active.sum()} not converged")
    return xi


def closest_points(
    x: np.ndarray,
    cells: np.ndarray,
    radius_a: np.ndarray | float = 0.0,
    radius_b: np.ndarray | float = 0.0,
    tolerance: float = 1e-14,
    max_iterations: int = 50,
) -> ClosestPoints:
    """The closest point to each node ``x`` (m, 3) on its partner cell ``cells`` (m, k+1, 3).

    φ(ξ) = |x_a − x_b(ξ)|²/2 is a polynomial of degree 2k and may have several minima on a
    curved cell: φ is sampled at 4k + 1 points, and Newton on (x_a − x_b(ξ))·x_b'(ξ) = 0
    (module docstring) starts from every local minimum of the samples (one on a mildly
    curved cell), stops at |Δξ| ≤ ``tolerance`` or at the slope's round-off, 8 ε (|x_a − x_b|
    Σ|N_j'||x_j| + |x_b'| Σ|N_j||x_j|) (x_j relative to x_a); the least of these and the two
    ends is the answer. A basin narrower than the samples' spacing 1/(4k) may be missed."""
    k = _degree(cells)
    m = len(x)
    # Relative to the node (the round-off then scales with the cell, not with |x|).
    origin, cells = x, cells - x[:, None, :]
    starts = np.linspace(0.0, 1.0, SAMPLES * k + 1)
    sampled = shape_functions(k, starts)[0] @ cells  # (m, q, 3): matmul, 3x einsum's speed
    d2 = np.pad(
        np.einsum("mqd,mqd->mq", sampled, sampled), ((0, 0), (1, 1)), constant_values=np.inf
    )
    pair, q = np.nonzero((d2[:, 1:-1] <= d2[:, :-2]) & (d2[:, 1:-1] <= d2[:, 2:]))
    found = np.concatenate(
        [
            _newton(cells[pair], starts[q], tolerance, max_iterations),
            np.zeros(m),
            np.ones(m),
        ]
    )
    pair = np.concatenate([pair, np.arange(m), np.arange(m)])
    phi = _phi(k, found, cells[pair])
    first = np.lexsort((phi, pair))
    first = first[np.concatenate([[True], pair[first][1:] != pair[first][:-1]])] if m else first
    xi = found[first]
    weights = shape_functions(k, xi)[0]
    rel = -np.einsum("mj,mjd->md", weights, cells)  # x_a − x_b
    norm = np.linalg.norm(rel, axis=1)
    if np.any(norm == 0.0):
        raise FloatingPointError("a node on its partner's centreline: its normal is undefined")
    gap = norm - np.broadcast_to(radius_a, (m,)) - np.broadcast_to(radius_b, (m,))
    return ClosestPoints(xi, origin - rel, gap, rel / norm[:, None], weights)


@dataclass(frozen=True)
class Sensitivities:
    """The derivatives of node-to-cell closest points with respect to the positions of the
    K = k + 2 points X = (x_a, x_0, ..., x_k) (the node, then the cell's nodes in dof order):
    ``gap`` (m, K, 3), ``normal`` (m, 3, K, 3) (∂n_p/∂X_iq), ``weights`` (m, k+1, K, 3)."""

    gap: np.ndarray
    normal: np.ndarray
    weights: np.ndarray


def closest_point_sensitivities(
    x: np.ndarray, cells: np.ndarray, closest: ClosestPoints
) -> Sensitivities:
    """The derivatives of :func:`closest_points`' answer at the nodes ``x`` (m, 3) and cells
    ``cells`` (m, k+1, 3). With d = x_a − x_b(ξ), ρ = |d|, n = d/ρ, t = x_b'(ξ), x_b'' = t₂,
    an interior closest point keeps h = d·t = 0, so

        (|t|² − d·t₂) dξ = t·(dx_a − Σ N_j dx_j) + d·Σ N_j' dx_j,                       (S.3)
        dg = n·(dx_a − Σ N_j dx_j),   dn = (I − n nᵀ)(dx_a − Σ N_j dx_j − t dξ)/ρ,
        dN_j = N_j' dξ;

    at an end of the cell (ξ = 0 or 1, where h ≠ 0 in general) dξ = 0 and dg gains −(n·t) dξ
    = 0 all the same. (S.3)'s coefficient is > 0 at a strict interior minimum; where it is not
    (a node at a centre of curvature of the cell) ξ is held (dξ = 0)."""
    k = _degree(cells)
    m = len(x)
    table = shape_functions(k, closest.xi, 2)
    N, dN, ddN = table[0], table[1], table[2]
    t = np.einsum("mj,mjd->md", dN, cells)
    t2 = np.einsum("mj,mjd->md", ddN, cells)
    d = x - np.einsum("mj,mjd->md", N, cells)
    rho = np.linalg.norm(d, axis=1)
    n = d / rho[:, None]
    # the weights of the K points in dx_a − Σ N_j dx_j and in Σ N_j' dx_j
    w = np.concatenate([np.ones((m, 1)), -N], axis=1)  # (m, K)
    wd = np.concatenate([np.zeros((m, 1)), dN], axis=1)
    coefficient = np.einsum("md,md->m", t, t) - np.einsum("md,md->m", d, t2)
    interior = (closest.xi > 0.0) & (closest.xi < 1.0) & (coefficient > 0.0)
    scale = np.where(interior, 1.0 / np.where(coefficient > 0.0, coefficient, 1.0), 0.0)
    # dξ/dX_iq = (w_i t_q + wd_i d_q)/coefficient (m, K, 3)
    dxi = (w[:, :, None] * t[:, None, :] + wd[:, :, None] * d[:, None, :]) * scale[:, None, None]
    gap = w[:, :, None] * n[:, None, :]
    P = np.eye(3) - n[:, :, None] * n[:, None, :]
    # dn_p/dX_iq = (P_pq w_i − (P t)_p dξ/dX_iq)/ρ
    Pt = np.einsum("mpq,mq->mp", P, t)
    normal = (
        P[:, :, None, :] * w[:, None, :, None] - Pt[:, :, None, None] * dxi[:, None, :, :]
    ) / rho[:, None, None, None]
    weights = dN[:, :, None, None] * dxi[:, None, :, :]
    return Sensitivities(gap, normal, weights)


def cell_pairs(
    nodes: np.ndarray,
    radius: np.ndarray | float,
    margin: float,
    arc: np.ndarray | None = None,
    rod: np.ndarray | None = None,
) -> np.ndarray:
    """The candidate pairs (i, j), i < j, of the cells ``nodes`` (cells, k+1, 3) of one or
    several rods (``rod``: each cell's rod, default one rod) whose tubes may come within
    ``margin``; pairs of one rod's cells closer than π r in arc (``arc``,
    :func:`exclude_neighbours`) left out. ``arc`` None: no exclusion (then the cells should be
    of distinct rods)."""
    lo, hi = cell_boxes(nodes, radius, margin)
    pairs = candidate_pairs(lo, hi)
    if arc is None:
        return pairs
    rod = np.zeros(len(nodes), dtype=np.int64) if rod is None else np.asarray(rod)
    same = rod[pairs[:, 0]] == rod[pairs[:, 1]]
    kept = exclude_neighbours(pairs[same], arc, radius)
    pairs = np.vstack([pairs[~same], kept])
    return pairs[np.lexsort(pairs.T[::-1])]


class VerletList:
    """The (node, cell) pairs within a gap of ``margin`` (module docstring) of rods given by
    their nodes' ``positions`` (nodes, 3) [m] and cells ``dofs`` (cells, k+1) (node indices,
    dof order), a radius a cell, ``arc`` and ``rod`` as :func:`cell_pairs`'; ``keep`` (None:
    all) maps :func:`cell_pairs`' cell pairs to those kept (a structure's joints,
    cosserat_fem/rod/self_contact.py), before any closest point.

    ``pairs`` (m, 2): node, partner cell; ``closest`` their :class:`ClosestPoints` at the build.
    """

    def __init__(
        self,
        positions: np.ndarray,
        dofs: np.ndarray,
        radius: np.ndarray | float,
        margin: float,
        arc: np.ndarray | None = None,
        rod: np.ndarray | None = None,
        keep=None,
    ):
        self.margin, self.dofs = margin, dofs
        self.radius = np.broadcast_to(np.asarray(radius, dtype=float), (len(dofs),)).copy()
        self.reference = positions.copy()
        self.threshold = margin / (1.0 + lebesgue_constant(dofs.shape[1] - 1))
        nodes = positions[dofs]
        cells = cell_pairs(nodes, self.radius, margin, arc, rod)
        cells = cells if keep is None else keep(cells)
        #: the candidate cell pairs (i, j), i < j, of the build
        self.cell_pairs = cells
        k1 = dofs.shape[1]
        # (node, partner cell, the node's own cell): each node of a pair's cell against the other.
        rows = np.vstack(
            [
                np.column_stack([dofs[mine].ravel(), np.repeat(other, k1), np.repeat(mine, k1)])
                for mine, other in ((cells[:, 0], cells[:, 1]), (cells[:, 1], cells[:, 0]))
            ]
        )
        # A node shared by two cells meets a partner once, with the larger of its cells' radii.
        r_node = np.zeros(len(positions))
        np.maximum.at(r_node, rows[:, 0], self.radius[rows[:, 2]])
        key = np.unique(rows[:, 0] * len(dofs) + rows[:, 1])
        node, partner = key // len(dofs), key % len(dofs)
        found = []
        for part in np.array_split(np.arange(len(node)), max(1, len(node) // CHUNK)):
            a, b = node[part], partner[part]
            near = closest_points(positions[a], nodes[b], r_node[a], self.radius[b])
            keep = near.gap <= margin
            found.append((np.column_stack([a, b])[keep], near, keep))
        self.pairs = np.vstack([f[0] for f in found])
        self.closest = ClosestPoints(
            *(
                np.concatenate([getattr(f[1], name)[f[2]] for f in found])
                for name in ("xi", "point", "gap", "normal", "weights")
            )
        )

    def stale(self, positions: np.ndarray) -> bool:
        """Whether a node has moved more than margin/(1 + Λ_k) since the build: then a pair
        outside the list may have closed its gap (module docstring), rebuild."""
        return bool(np.linalg.norm(positions - self.reference, axis=1).max() > self.threshold)


def least_gap_between_nodes(
    positions: np.ndarray, dofs: np.ndarray, pairs: np.ndarray, radius: float
) -> tuple[float, int, int]:
    """The least gap [m] between the tubes of the cell ``pairs`` (m, 2) of a rod whose nodes
    are at ``positions`` (N, 3) [m] and cells ``dofs`` (cells, k+1), sampled at 2k + 1 points
    inside each cell (ξ = q/(2k + 2)) against the other cell's closest point, both ways; and
    the cells of the least (−1, −1 if no pair). Node-to-cell rows hold the gap at the nodes:
    where two parts of a rod cross between their nodes this finds how far they pass through
    each other (to the sampling, h/(2k + 2) along each cell)."""
    if not len(pairs):
        return np.inf, -1, -1
    k = dofs.shape[1] - 1
    xi = np.arange(1, 2 * k + 2) / (2 * k + 2)
    table = shape_functions(k, xi)[0]  # (q, k+1)
    best, where = np.inf, (-1, -1)
    for mine, other in ((pairs[:, 0], pairs[:, 1]), (pairs[:, 1], pairs[:, 0])):
        points = (table @ positions[dofs[mine]]).reshape(-1, 3)
        partner = np.repeat(positions[dofs[other]], len(xi), axis=0)
        gap = closest_points(points, partner, radius, radius).gap.reshape(len(mine), -1).min(1)
        i = int(np.argmin(gap))
        if gap[i] < best:
            best, where = float(gap[i]), (int(mine[i]), int(other[i]))
    return best, *where


@dataclass(frozen=True)
class Cells:
    """A rank's cells: ``nodes`` (n, k+1, 3) [m], ``radius`` (n,) [m], ``arc`` (n, 2) [m],
    ``rod`` (n,) and global ``ids`` (n,), integers."""

    nodes: np.ndarray
    radius: np.ndarray
    arc: np.ndarray
    rod: np.ndarray
    ids: np.ndarray


def gather_cells(comm: MPI.Comm, owned: Cells) -> Cells:
    """Every rank's owned cells on every rank (Allgatherv, rank order)."""
    n, k1 = owned.nodes.shape[:2]
    packed = np.column_stack(
        [owned.nodes.reshape(n, -1), owned.radius, owned.arc, owned.rod, owned.ids]
    ).astype(np.float64)
    width = packed.shape[1]
    counts = np.array(comm.allgather(n * width))
    every = np.empty((counts.sum() // width, width))
    comm.Allgatherv(
        np.ascontiguousarray(packed), [every, counts, np.cumsum(counts) - counts, MPI.DOUBLE]
    )
    return Cells(
        every[:, : 3 * k1].reshape(-1, k1, 3),
        every[:, 3 * k1],
        every[:, 3 * k1 + 1 : 3 * k1 + 3],
        every[:, 3 * k1 + 3].astype(np.int64),
        every[:, 3 * k1 + 4].astype(np.int64),
    )


def parallel_pairs(comm: MPI.Comm, owned: Cells, margin: float) -> tuple[np.ndarray, Cells]:
    """This rank's candidate pairs (global ids (i, j), i < j, i owned here) with every rank's
    cells, self contact excluded within π r (:func:`cell_pairs`); and the gathered cells."""
    every = gather_cells(comm, owned)
    lo, hi = cell_boxes(owned.nodes, owned.radius, margin)
    lo_b, hi_b = cell_boxes(every.nodes, every.radius, margin)
    pairs = candidate_pairs(lo, hi, lo_b, hi_b)
    i, j = owned.ids[pairs[:, 0]], every.ids[pairs[:, 1]]
    pairs = pairs[i < j]
    a, b = pairs[:, 0], pairs[:, 1]
    near = (owned.rod[a] == every.rod[b]) & _too_near(
        owned.arc[a], every.arc[b], owned.radius[a], every.radius[b]
    )
    ids = np.column_stack([owned.ids[a], every.ids[b]])[~near]
    return ids[np.lexsort(ids.T[::-1])], every
