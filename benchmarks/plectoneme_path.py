# %% [markdown]
# # A clamped rod twisted past its buckling twist, without contact (issue 30)
#
# The rod of tests/test_greenhill.py (L = 1 m, circle d = 2 mm, E = 1e9 Pa, ν = 0.3; clamped
# at A, s = 0; at B, s = L, a sliding support that holds B's lateral position and rotation,
# free along the axis, turned about e3 by the twist Φ) under a dead tension T = 100 EI/L²
# at B along e3 (a node load), driven in Φ past its buckling twist Φ_c (the root of the
# clamped-clamped determinant, :func:`buckling_torque`: 27.2786 rad) onto the buckled
# branch, up to where the tube (radius r) first touches itself. No contact rows: past that
# the path goes on through itself. Without tension (T = 0, Greenhill's twist 11.6829 rad of
# tests/test_greenhill.py) the buckled branch falls in Φ for good while B slides in: the
# twisted rod collapses, and no plectoneme regime follows (docs/plectoneme.md).
#
# **The drive** (:class:`TwistPath`). Load stepping (cf.static) follows the path up to the
# fold only, and `cf.continuation` refuses prescribed turns (not linear in the load factor),
# so the arclength engine (cosserat_fem/nls/arclength.py) is given a paths.RodPath whose
# parameter is the turn, p = Φ/PHI_REF: the turned support's held angles g(p) are written
# into U with every state (as load stepping does), the Dirichlet rows are x − g(p), and R_p
# is a central difference. A round rod's buckled states are a circle of them (turned about
# the axis, the material frame turned back: a zero eigenvalue all along), so a lateral
# gravity g_x (ρ A g_x e1 [N/m], the scene's [loads] gravity) pins one of them: 1 m/s² from
# Φ = 0 over the fold (where it rounds off the subcritical bifurcation for the steps, 0.01
# to 0.02 in the engine's metric) until B has shortened by 5 cm; then the state is carried
# over to the same rod with 1e-2 m/s² (a second model on the same mesh, the chart with it),
# corrected at that Φ and continued on, Φ decreasing, until the gap is below −r.
#
# **Recorded at each point** (:class:`PathPoint`): Φ [rad]; the end torque M = e3 · m(0)
# [N m], the section torque at the clamp A (minus the clamp's reaction about the axis),
# and M(L) − M(0) (the two ends' e3 · m agree where no distributed moment acts about e3:
# with the imperfection's load they differ at O(g_x)); the reaction of B's support on the
# rod [N] (the raw residual's rows of the linear momentum balance at B, its axial part 0:
# B slides); B's axial shift Δz [m] (the end shortening, minus the tension's stretch
# T/EA); the largest lateral displacement; and the gaps of the centreline's cells that are
# at least π r apart in arc (cosserat_fem/rod/contact_search.py: cell_pairs with the self
# contact exclusion, closest_points): the least distance between the cells' curves minus 2r
# (the contact onset, gap = 0, located by the engine as a test function to 1e-9 in
# arclength), and the least node-to-cell gap, which is what node-to-segment rows will see.
#
#     .venv/bin/python benchmarks/plectoneme_path.py [elements ...]    # default 16 32

# %%
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np
import ufl
from cosserat_fem.forms.resultants import resultants
from dolfinx import fem
from mpi4py import MPI
from scipy.optimize import brentq, minimize_scalar

from cosserat_fem.analysis import paths
from cosserat_fem.nls import arclength
from cosserat_fem.output.fields import _directors
from cosserat_fem.rod.contact_search import (
    arc_lengths,
    cell_pairs,
    closest_points,
    shape_functions,
)
from cosserat_fem.scene.build import scene_from_dict

NU, DIAMETER, LENGTH = 0.3, 0.002, 1.0
EI = 1e9 * math.pi * DIAMETER**4 / 64  # [N m²]
TENSION = 100 * EI / LENGTH**2  # [N]: T L²/EI = 100
PHI_REF = 12.0  # the support's `rotation` [rad]: the twist is Φ = PHI_REF × the turn factor


def greenhill_twist() -> float:
    """Φ_c = 2 x1 (1 + ν) [rad], tan x1 = x1 (tests/test_greenhill.py, shear dropped:
    1 + O((r/L)²))."""
    x1 = brentq(lambda x: math.tan(x) - x, math.pi + 1e-9, 1.5 * math.pi - 1e-9)
    return 2 * x1 * (1 + NU)


def buckling_torque(tension: float, bending: float = EI, length: float = LENGTH) -> float:
    """M_c [N m], the least torque at which the straight rod clamped at both ends (lateral
    position and slope held) under the tension T = ``tension`` [N] has an adjacent
    equilibrium: w = u + i v obeys EI w⁗ − i M w‴ − T w″ = 0 (Greenhill's equation of
    tests/test_greenhill.py with the tension's term), w = c0 + c1 s + c2 e^{i k1 s} +
    c3 e^{i k2 s}, EI k² − M k + T = 0. w = w' = 0 at s = 0 eliminates c0, c1; at s = L, with
    a_j = k_j L/2, σ = (a1 + a2)/2 = M L/(4 EI), δ = (a1 − a2)/2, the 2 × 2 determinant is,
    up to the factor (2i)² (2/L) e^{2iσ},

        D(M) = e^{iσ} sin a1 sin a2 (a2 − a1) + a1 a2 (e^{iδ} sin a1 − e^{−iδ} sin a2),

    and e^{−iσ} D is real (its imaginary part is round-off). Its first zero above
    M = 2 √(EI T) (where k1 = k2 and D vanishes trivially), by Brent from the first sign
    change on a grid of 4000 up to 3 √(EI T) + 10 EI/L. T > 0: at T = 0, k2 = 0 repeats c0
    and D vanishes identically (the solution has an s² term instead: tan x = x,
    :func:`greenhill_twist`), and as T → 0 the root tends to its M_c L/EI = 2 x1 = 8.98682.
    Shear and extension are dropped (O((r/L)²) = 1e-6 here). No closed form: a root of D."""
    EI_, L, T = bending, length, tension

    def real_part(M: float) -> float:
        root = math.sqrt(max(M * M - 4 * EI_ * T, 0.0))
        a1, a2 = (M + root) * L / (4 * EI_), (M - root) * L / (4 * EI_)
        sigma, delta = 0.5 * (a1 + a2), 0.5 * (a1 - a2)
        s1, s2 = math.sin(a1), math.sin(a2)
        D = np.exp(1j * sigma) * s1 * s2 * (a2 - a1) + a1 * a2 * (
            np.exp(1j * delta) * s1 - np.exp(-1j * delta) * s2
        )
        return float((D * np.exp(-1j * sigma)).real)

    low = 2 * math.sqrt(EI_ * T) * (1 + 1e-9) + 1e-9 * EI_ / L
    grid = np.linspace(low, 3 * math.sqrt(EI_ * T) + 10 * EI_ / L, 4000)
    values = [real_part(M) for M in grid]
    i = next(i for i in range(len(grid) - 1) if values[i] * values[i + 1] < 0)
    return float(brentq(real_part, grid[i], grid[i + 1], xtol=1e-14 * grid[i]))


def scene(elements: int, degree: int = 3, gravity: float = 0.0, tension: float = 0.0):
    """The twisted rod of the module docstring on ``elements`` P_degree cells, a lateral
    gravity ``gravity`` [m/s²] along e1 as its imperfection (scaled by the load factor)."""
    return scene_from_dict(
        {
            "title": "a clamped rod twisted past Greenhill's twist (plectoneme path)",
            "rod": {
                "section": {"shape": "circle", "diameter": DIAMETER},
                "material": {"density": 1000.0, "young_modulus": 1e9, "poisson_ratio": NU},
            },
            "structure": {
                "nodes": [
                    {"name": "A", "position": [0, 0, 0]},
                    {"name": "B", "position": [0, 0, LENGTH]},
                ],
                "members": [{"name": "AB", "from": "A", "to": "B", "elements": elements}],
                "loads": [{"node": "B", "force": [0.0, 0.0, tension]}],
                "supports": [
                    {"node": "A", "kind": "clamped"},
                    {
                        "node": "B",
                        "kind": "sliding",
                        "axis": [0, 0, 1],
                        "rotation": PHI_REF,
                        "rotation_axis": [0, 0, 1],
                    },
                ],
            },
            "loads": {"gravity": [gravity, 0.0, 0.0]},
            "static": {"load_steps": 1},
            "time": {"end": 1.0, "step": 1.0},
            "discretisation": {"degree": degree},
        }
    )


@dataclass
class PathPoint:
    """One state of the path (module docstring, "Recorded at each point")."""

    phi: float  # the twist Φ [rad]
    imperfection: float  # the lateral gravity g_x [m/s²]
    torque: float  # M = e3 · m(0) [N m]
    spread: float  # e3 · m(L) − M [N m]
    force: np.ndarray  # the reaction of B's support on the rod [N], fixed basis
    reaction_a: np.ndarray  # that of the clamp A [N]
    shift: float  # B's axial displacement [m]
    gap: float  # the least distance of the cells' curves ≥ π r apart in arc, − 2r [m]
    node_gap: float  # the least node-to-cell gap of those cells [m]
    radius: float  # the tube's r [m]
    lateral: float  # the largest lateral displacement [m]


class TwistPath(paths.RodPath):
    """R(U, p) = 0 of the rod of :func:`scene` (``gravity`` g_x [m/s²], ``tension`` [N]) with
    the twist Φ = PHI_REF p as the parameter p: the problem of the continuation engine
    (cosserat_fem/nls/arclength.py). Serial (MPI.COMM_SELF).

    paths.RodPath with three changes: the load factor stays 1 (RodPath sets it to p: the
    loads are the scene's throughout); the turned support's angles are written into U at
    g(p) with every state (RodModel.turn_nodes, as load stepping does; g taken nearest the
    state's own held angles, so continuous through Φ = π and across chart moves), so the
    interior rows see them; and the Dirichlet rows are x − g(p) of the path's state x (the
    engine's u carries the held angles). The Jacobian's Dirichlet rows and columns are the
    identity's (no lifting): the tangent's interior rows then need R_p's interior part, the
    change of the interior rows with the held values, and its Dirichlet rows get −g'(p):
    R_p is the central difference of R in p, step 1e-6 (g is smooth in p: the truncation
    error O(1e-12) is below the corrector's 1e-10).

    Private parts used: paths.check_path_scene is bypassed while RodPath is built (it
    refuses the turn), and the solver's ``_assemble`` gives the raw residual (reactions)."""

    H = 1e-6

    def __init__(self, elements: int, degree: int = 3, gravity: float = 1e-2, tension: float = 0.0):
        checked = paths.check_path_scene
        paths.check_path_scene = lambda scene, command="continue": None  # the turn: R_p here
        try:
            super().__init__(scene(elements, degree, gravity, tension), MPI.COMM_SELF)
        finally:
            paths.check_path_scene = checked
        model = self.model
        self.gravity = gravity
        self.radius = 0.5 * DIAMETER
        V = model.V
        self.bs = model.layout.size
        self.rest = V.tabulate_dof_coordinates() * model.length  # r0 [m] of each node
        cells = V.mesh.topology.index_map(1).size_local
        dofs = np.array([V.dofmap.cell_dofs(c) for c in range(cells)], dtype=np.int64)
        self.order = np.argsort(self.rest[dofs[:, 0], 2]).astype(np.int32)  # along the rod
        self.dofs = dofs[self.order]
        self._expression = None
        self.ends = (int(np.argmin(self.rest[:, 2])), int(np.argmax(self.rest[:, 2])))  # A, B
        held = [bc.dof_indices()[0] for bc in model.bcs]
        self.held = np.unique(np.concatenate(held))
        self.held = self.held[self.held < self.owned]

    def set_state(self, u: np.ndarray, p: float, chart: object = None) -> None:
        super().set_state(u, p, chart)
        self.model.load_factor.value = 1.0
        self.model.turn_nodes(self.scene.static.time, p)  # U's held angles: g(p)

    def residual(self, u: np.ndarray, p: float) -> np.ndarray:
        values = super().residual(u, p)  # the Dirichlet rows: g(p) − g(p) = 0
        held = self.model.U.x.array[self.held]
        values[self.held] = u[self.held] - held
        return values

    def dparameter(self, u: np.ndarray, p: float) -> np.ndarray:
        h = self.H
        derivative = (self.residual(u, p + h) - self.residual(u, p - h)) / (2 * h)
        self.set_state(u, p)
        return derivative

    # -- what is recorded -----------------------------------------------------------------
    def positions(self) -> np.ndarray:
        """The nodes' positions r0 + ℓ u [m] (nodes, 3)."""
        U = self.model.U.x.array.reshape(-1, self.bs)
        return self.rest + self.model.length * U[:, :3]

    def _resultants(self):
        """The fem.Expression of (x, m) in the fixed basis [m, N m] at both ends of a cell
        (reference points 0 and 1)."""
        if self._expression is None:
            model = self.model
            U = model.layout.full(model.U)
            chart = model.chart_form()
            reference = model.reference_form()
            res = resultants(U, model.rod, 0.0, chart, reference)
            D = _directors(U, chart, reference)  # rows: the directors in the fixed basis
            m = ufl.as_vector([sum(res.m[i] * D[i, j] for i in range(3)) for j in range(3)])
            X = ufl.SpatialCoordinate(model.msh)
            x = ufl.as_vector([model.length * (X[j] + U[j]) for j in range(3)])
            values = ufl.as_vector([*(x[j] for j in range(3)), *m])
            self._expression = (fem.Expression(values, np.array([[0.0], [1.0]])),)
        return self._expression[0]

    def point(self, at: arclength.Point) -> PathPoint:
        """The :class:`PathPoint` of the engine's point ``at``."""
        self.set_state(at.u, at.p, at.chart)
        values = self._resultants().eval(self.order).reshape(len(self.order), 2, 6)
        x, m = values[..., :3], values[..., 3:6]
        s = self.rest[self.dofs[[0, -1]], 2]  # the first and last cells' nodes' s
        torque_a = m[0, 0 if s[0, 0] < s[0, 1] else 1, 2]  # e3 · m at s = 0
        b = 0 if s[1, 0] > s[1, 1] else 1
        torque_b = m[-1, b, 2]
        positions = self.positions()
        gaps = self.gaps(positions)
        raw = np.zeros(self.model.U.x.array.size)
        self.solver._assemble(raw, dirichlet=False)  # the held dofs' rows: the reactions
        raw = raw.reshape(-1, self.bs)
        layout, scale = self.model.layout, self.model.length / self.model.groups.g0
        slots = [layout.index(6 + k) for k in range(3)]
        reactions = [raw[node, slots] * scale for node in self.ends]
        return PathPoint(
            phi=PHI_REF * at.p,
            imperfection=self.gravity,
            torque=float(torque_a),
            spread=float(torque_b - torque_a),
            force=reactions[1],
            reaction_a=reactions[0],
            shift=float(x[-1, b, 2] - LENGTH),
            gap=gaps[1],
            node_gap=gaps[0],
            radius=self.radius,
            lateral=float(np.hypot(*(positions - self.rest)[:, :2].T).max()),
        )

    def least_gap(self, positions: np.ndarray, margin: float = 0.05 * LENGTH) -> float:
        """The least gap |x(s₁) − x(s₂)| − 2r [m] between the centreline's cells ≥ π r apart
        in arc (contact_search's exclusion; ``margin`` if no pair of cells comes within it):
        :meth:`gaps`' second."""
        return self.gaps(positions, margin)[1]

    def gaps(self, positions: np.ndarray, margin: float = 0.05 * LENGTH) -> tuple[float, float]:
        """(node gap, centreline gap) [m] of the candidate pairs of cells ≥ π r apart in arc
        (cell_pairs with contact_search's exclusion): the least node-to-cell gap, what the
        node-to-segment rows will see; and the least distance between the two cells'
        curves, − 2r: each pair's 8k + 1 points of one cell against the other cell
        (closest_points), both ways, the least refined by a bounded scalar search in ξ
        between its neighbouring samples (two crossing strands meet between nodes: the node
        gap does not see them). ``margin`` for both if no pair comes within it."""
        nodes = positions[self.dofs]
        lengths = arc_lengths(nodes)
        arc = np.column_stack([np.cumsum(lengths) - lengths, np.cumsum(lengths)])
        pairs = cell_pairs(nodes, self.radius, margin, arc)
        if not len(pairs):
            return margin, margin
        k = self.dofs.shape[1] - 1
        xi = np.linspace(0.0, 1.0, 8 * k + 1)
        N = shape_functions(k, xi)[0]
        r = self.radius
        node_gap = curve_gap = margin
        best = None
        for mine, other in ((pairs[:, 0], pairs[:, 1]), (pairs[:, 1], pairs[:, 0])):
            near = closest_points(
                nodes[mine].reshape(-1, 3), np.repeat(nodes[other], k + 1, axis=0), r, r
            )
            node_gap = min(node_gap, float(near.gap.min()))
            points = np.einsum("qj,mjd->mqd", N, nodes[mine]).reshape(-1, 3)
            near = closest_points(points, np.repeat(nodes[other], len(xi), axis=0), r, r)
            at = int(np.argmin(near.gap))
            if near.gap[at] < curve_gap:
                curve_gap = float(near.gap[at])
                best = (mine[at // len(xi)], other[at // len(xi)], xi[at % len(xi)])
        if best is not None:
            i, j, x0 = best
            h = 1.0 / (8 * k)

            def distance(x: float) -> float:
                point = (shape_functions(k, np.array([x]))[0] @ nodes[i])[0]
                return float(closest_points(point[None], nodes[j][None], r, r).gap[0])

            found = minimize_scalar(
                distance,
                bounds=(max(0.0, x0 - h), min(1.0, x0 + h)),
                method="bounded",
                options={"xatol": 1e-10},
            )
            curve_gap = min(curve_gap, float(found.fun))
        return node_gap, curve_gap


@dataclass
class Path:
    """A traced path: its points (both stages), the fold Φ_max [rad] of the first stage, the
    contact onset Φ [rad] located on the second (None if not reached), why each stage ended,
    the points of each stage and the run time [s]."""

    points: list[PathPoint]
    fold: float
    onset: float | None
    onset_point: PathPoint | None
    reasons: tuple[str, str]
    counts: tuple[int, int]
    seconds: float
    #: the nodes' positions [m] (nodes, 3) and the cells' nodes (cells, k + 1), along the
    #: rod, at the contact onset (None if not reached)
    centreline: tuple[np.ndarray, np.ndarray] | None = None


def trace(
    elements: int,
    tension: float = TENSION,
    imperfections: tuple[float, float] = (1.0, 1e-2),
    past_fold: float = 0.05 * LENGTH,
    max_points: int = 3000,
    report=None,
    second_stage: bool = True,
) -> Path:
    """The path of the module docstring on ``elements`` P3 cells under the dead tension
    ``tension`` [N]: from the straight rod (Φ = 0) with the lateral gravity
    ``imperfections[0]`` [m/s²] by pseudo-arclength continuation in p = Φ/PHI_REF (steps
    0.01-0.02 in the engine's metric) over the fold to where B has shortened by ``past_fold``
    [m]; then the same state with the gravity ``imperfections[1]`` (a new model on the same
    mesh: the state and chart carried over, Newton at fixed Φ) continued on, Φ decreasing,
    until the gap is below −r, or Φ < 0, the contact onset (gap = 0) located on the way (the
    engine's test function, to 1e-9 in arclength). ``report(point)`` after each point;
    ``second_stage`` False: the first stage alone (its fold)."""
    t0 = time.perf_counter()
    points: list[PathPoint] = []
    first = TwistPath(elements, gravity=imperfections[0], tension=tension)

    def keep(path: TwistPath, at: arclength.Point) -> PathPoint:
        points.append(path.point(at))
        if report is not None:
            report(points[-1])
        return points[-1]

    def past(at: arclength.Point) -> str | None:
        return "past the fold" if keep(first, at).shift < -past_fold else None

    settings = arclength.ContinuationSettings(step=0.01, max_step=0.02, max_points=max_points)
    engine = arclength.Continuation(first, settings, past)
    start = engine.start_point(np.zeros(first.owned), 0.0)
    keep(first, start)
    one = engine.trace(start)
    folds = [q.p * PHI_REF for q in one.special if q.kind == "limit"]
    fold = folds[0] if folds else math.nan  # located to 1e-9 in arclength
    count = len(points)
    last = one.points[-1]
    if not second_stage:
        return Path(
            points, fold, None, None, (one.reason, ""), (count, 0), time.perf_counter() - t0
        )

    second = TwistPath(elements, gravity=imperfections[1], tension=tension)
    model = second.model
    assert model.chart is not None and isinstance(last.chart, np.ndarray)
    model.chart.x.array[:] = last.chart
    model.chart_moved = first.model.chart_moved
    second.chart = model.chart.x.array.copy()

    def contact(at: arclength.Point) -> str | None:
        return "past contact" if keep(second, at).gap < -second.radius else None

    def gap(at: arclength.Point) -> float:
        second.set_state(at.u, at.p, at.chart)
        return second.least_gap(second.positions())

    settings = arclength.ContinuationSettings(
        step=0.01, max_step=0.02, max_points=max_points, p_min=0.0, max_iterations=30
    )
    engine = arclength.Continuation(second, settings, contact, {"contact": gap})
    start = engine.start_point(last.u, last.p, direction=-1)
    keep(second, start)
    two = engine.trace(start)
    touch = [q for q in two.special if q.kind == "contact"]
    at = second.point(touch[0]) if touch else None
    centreline = (second.positions(), second.dofs) if touch else None
    return Path(
        points,
        fold,
        at.phi if at is not None else None,
        at,
        (one.reason, two.reason),
        (count, len(points) - count),
        time.perf_counter() - t0,
        centreline,
    )


def row(p: PathPoint) -> str:
    """One line of the table."""
    f = p.force
    return (
        f"{p.phi:9.4f} {p.torque * 1e3:9.5f} {p.spread * 1e3:+8.1e} "
        f"{math.hypot(f[0], f[1]) * 1e3:8.4f} {p.shift * 1e3:+9.3f} {p.lateral * 1e3:8.3f} "
        f"{p.gap / p.radius:+8.3f} {p.node_gap / p.radius:+8.3f}  {p.imperfection:g}"
    )


HEADER = "  Φ [rad] M [mN m] M(L)−M(0) |F⊥B| [mN] Δz_B [mm] max|w| [mm]  g/r  node g/r  g_x [m/s²]"


def table(path: Path, rows: int = 24) -> list[str]:
    """About ``rows`` lines of the path, evenly in the points' order, with the last point
    before the fold, the first past it, and the located contact onset in their place."""
    points = path.points
    stride = max(1, len(points) // rows)
    top = int(np.argmax([q.phi for q in points[: path.counts[0]]]))
    keep = sorted({*range(0, len(points), stride), top, top + 1, len(points) - 1})
    lines = [row(points[i]) for i in keep if i < len(points)]
    if path.onset_point is not None:
        where = next(
            (k for k, i in enumerate(keep) if i >= path.counts[0] and points[i].gap <= 0.0),
            len(lines),
        )
        lines.insert(where, row(path.onset_point) + "  <- contact onset")
    return lines


# %%
if __name__ == "__main__":
    meshes = [int(a) for a in sys.argv[1:]] or [16, 32]
    phi_c = buckling_torque(TENSION) * LENGTH / (EI / (1 + NU))
    print(
        f"T = {TENSION:.6g} N (T L²/EI = 100), M_c = {buckling_torque(TENSION):.6g} N m, "
        f"Φ_c = {phi_c:.5f} rad (linear analysis); GJ/L = {EI / (1 + NU) / LENGTH:.6e} N m"
    )
    for cells in meshes:
        path = trace(cells)
        print(f"\n{cells} P3 cells\n{HEADER}")
        print("\n".join(table(path)))
        print(
            f"{path.counts} points (two stages), {path.seconds:.1f} s; ended: {path.reasons}; "
            f"fold Φ_max = {path.fold:.5f} rad, contact onset Φ = {path.onset:.6f} rad"
            if path.onset is not None
            else f"{path.counts} points, {path.seconds:.1f} s; ended: {path.reasons}"
        )
