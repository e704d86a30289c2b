"""The DOLFINx side of a run's outputs: what is sampled or computed on the mesh before it is
written by cosserat_fem/io/ (which imports no DOLFINx).

* :class:`PointProbe`: (x, y, z, θ, ψ, φ, ...) at the probe point, on the rank that owns it, for
  probes.csv (:class:`~cosserat_fem.io.probes.ProbeWriter`), so a step costs no communication;
  :func:`probe_sigma`, :func:`probe_position`: where the probe is.
* :class:`XdmfWriter`: the UFL of the output fields (displacement, angles, strains, forces,
  directors), evaluated at the output points (:class:`CentrelineOutput`) and gathered on rank
  0, which writes them (:class:`~cosserat_fem.io.xdmf.XdmfSeries`).
* :class:`LineSampler`: (x, y, z, θ, ψ, φ) at many points along the rod (the demos).

Quantities are in SI units: positions in m (x = ℓ p1, ...), angles in rad, time in s. A run
that stops early, or is killed (even with SIGKILL), leaves readable outputs up to the last step
written (tests/test_kill.py): probe rows reach the file before every XDMF frame, so probes.csv
always covers the last frame on disk (cosserat_fem/io/probes.py, io/xdmf.py).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import ufl
from dolfinx import fem, geometry, mesh
from mpi4py import MPI

from cosserat_fem.common.errors import OutputError
from cosserat_fem.common.parallel import agree
from cosserat_fem.forms.kinematics import directors
from cosserat_fem.forms.resultants import resultants
from cosserat_fem.io.probes import PROBE_FIELD_COLUMNS, probe_columns
from cosserat_fem.io.xdmf import FIELD_ARRAYS, XdmfSeries
from cosserat_fem.rod.charts import (
    euler_angles,
    euler_matrix,
    quaternion_frame,
    quaternion_of_frame,
)

if TYPE_CHECKING:
    from cosserat_fem.rod.model import RodModel


def probe_position(scene, s: float) -> list[float]:
    """r0(s) [m], the probe's point on the rod at rest (the scene's [reference]): the point
    whose displacement probes.csv's x, y, z are (summary.json ``probe_reference_position_m``);
    on a structure, its probe node's (resolved.Structure.probe_node), whatever s."""
    if scene.structure is not None:
        return [float(x) for x in scene.structure.positions()[scene.structure.probe_node()]]
    return [float(x) for x in scene.reference.positions([s])[0]]


def probe_sigma(scene) -> float:
    """The probe point σ of a scene (cosserat_fem/scene/resolved.py ``Scene.probe_sigma``)."""
    return scene.probe_sigma


class FixedBasisAngles:
    """The angles (θ, ψ, φ) that the samplers report: those of (18) measured from the fixed
    basis. With a chart that has moved (cosserat_fem/rod/charts.py) they are the angles of the
    rod's directors D A, continued from the previous call's (of the two triples and their
    turns of 2π, the one nearest: :func:`~cosserat_fem.rod.charts.euler_angles`), so that they
    stay continuous through the chart's resets; only where θ passes ±π/2 itself, where ψ and
    φ are not defined apart, may they jump. Before the first reset they are the unknowns'."""

    def __init__(self, model: RodModel):
        self.model = model
        self.last: np.ndarray | None = None  # the angles of the previous call
        self.frame: np.ndarray | None = None  # its directors D A (in a moved chart)
        self.reference_frames: np.ndarray | None = None  # D0 at the points, rod curved at rest

    def __call__(self, angles: np.ndarray, chart_values, sigma=None) -> np.ndarray:
        """Fixed-basis angles (points, 3) of the chart angles ``angles`` at points whose
        chart quaternions ``chart_values()`` gives (points, 4), called only once the chart
        has moved; for a rod curved at rest, those of its directors D0 D A, with D0 the
        reference frame at the points σ = ``sigma()`` (cosserat_fem/scene/resolved.py)."""
        model = self.model
        reference = model.scene.reference
        if (model.chart is None or not model.chart_moved) and not reference.curved:
            if model.chart is not None:
                self.last = angles.copy()
            return angles
        D = euler_matrix(*angles.T)
        if model.chart is not None and model.chart_moved:
            D = D @ quaternion_frame(chart_values())
        if reference.curved:
            if self.reference_frames is None:  # the sampler's points do not move
                self.reference_frames = reference.frames(model.length * np.asarray(sigma()))
            D = self.reference_frames @ D
        self.last = euler_angles(D, angles if self.last is None else self.last)
        self.frame = D
        return self.last

    def directors(self, angles: np.ndarray) -> np.ndarray:
        """The directors D (points, 3, 3) of the last call, whose angles it returned as
        ``angles``: D A as computed in a moved chart (not rebuilt from the angles, which lose
        digits near θ = ±π/2), else D(θ, ψ, φ) of (18)."""
        model = self.model
        if (model.chart is not None and model.chart_moved) or model.scene.reference.curved:
            assert self.frame is not None, "set by the last call (D A, D0 D A)"
            return self.frame
        return euler_matrix(*angles.T)


class PointProbe:
    """Evaluates (x, y, z, θ, ψ, φ) in SI units [m, rad] at σ = ``sigma`` of a model's rod, on
    its owning rank (the components of p the model does not solve are 0), followed by the
    ``fields`` of ``output.probe_fields`` (:data:`~cosserat_fem.io.probes.PROBE_FIELD_COLUMNS`):
    the quaternion of the directors (q0, q1, q2, q3), signed as the previous call's so that it
    is continuous in time, the directors d1, d2, d3 in the fixed basis, a body's position, and
    the contact's load [N/m], gap [m] and state at the probe (cosserat_fem/nls/contact.py).

    With a chart (cosserat_fem/rod/charts.py) the angles are those of (18) for the rod's own
    directors D A, measured from the fixed basis as without one, and continued from the
    previous call's (of the two triples and their turns of 2π, the one nearest:
    :func:`~cosserat_fem.rod.charts.euler_angles`), so that they stay continuous through a
    reset of the chart; only through θ = ±π/2 exactly, where ψ and φ are not defined apart,
    may ψ and φ jump."""

    def __init__(
        self,
        model: RodModel,
        sigma: float,
        U: fem.Function | None = None,
        fields: tuple[str, ...] = (),
    ):
        """``U``: the Function read (default ``model.U``), of the model's space and layout;
        ``fields``: output.probe_fields."""
        U = model.U if U is None else U
        unknown = set(fields) - set(PROBE_FIELD_COLUMNS)
        if unknown:
            raise ValueError(
                f"probe fields {sorted(unknown)} are none of {list(PROBE_FIELD_COLUMNS)}"
            )
        self.columns = probe_columns(tuple(fields))
        self._quaternion = "quaternion" in fields
        self._directors = "directors" in fields
        self._body = self._body_frame(model, sigma) if "body" in fields else None
        if "contact" in fields and model.contact is None:
            raise ValueError("the probe field contact needs a scene with [contact]")
        self._contact = model.contact.values if model.contact and "contact" in fields else None
        self._last_q: np.ndarray | None = None  # the quaternion of the previous call
        msh = U.function_space.mesh
        self.U = U
        self.angles = FixedBasisAngles(model)
        self.length = model.length
        self.sigma = sigma
        self.point = np.array([[sigma, 0.0, 0.0]])
        if model.scene.structure is not None:  # its probe node, r0/ℓ
            self.point = np.array([probe_position(model.scene, 0.0)]) / model.length
        tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
        candidates = geometry.compute_collisions(tree, self.point)
        cells = geometry.compute_colliding_cells(msh, candidates, self.point).links(0)
        n_owned = msh.topology.index_map(msh.topology.dim).size_local
        owned = [c for c in cells if c < n_owned]
        comm = msh.comm
        mine = comm.rank if owned else comm.size
        self.owner = comm.allreduce(mine, op=MPI.MIN)
        if self.owner == comm.size:
            raise RuntimeError(f"probe point σ = {sigma} lies outside the mesh")
        self.cell = owned[0] if (owned and comm.rank == self.owner) else None
        layout = model.layout
        self._bs = layout.size
        self._slots = np.arange(layout.p_count)
        self._p = np.array(layout.components[: layout.p_count], dtype=int)
        self._scale = layout.si_scale(model.length, model.omega0)[: layout.p_count]
        # Fast path: a probe on a node of the Lagrange space reads that node's values.
        self._node = None
        if self.cell is not None:
            n_local = U.function_space.dofmap.index_map.size_local
            coords = U.function_space.tabulate_dof_coordinates()[:n_local]
            hits = np.flatnonzero(np.abs(coords - self.point).max(axis=1) < 1e-12)
            if hits.size:
                self._node = int(hits[0])

    @property
    def is_owner(self) -> bool:
        return self.cell is not None

    def values(self) -> np.ndarray | None:
        """(x, y, z, θ, ψ, φ, ...) (``columns`` but t) on the owning rank, None elsewhere."""
        if self.cell is None:
            return None
        if self._node is not None:
            bs = self._bs
            block = self.U.x.array[bs * self._node : bs * (self._node + 1)]
        else:
            block = self.U.eval(self.point, np.array([self.cell], dtype=np.int32))
        out = np.zeros(len(self.columns) - 1)
        out[self._p] = block[self._slots] * self._scale
        out[3:6] = self.angles(out[None, 3:6], self._chart_value, lambda: [self.sigma])[0]
        if self._quaternion or self._directors or self._body is not None:
            D = self.angles.directors(out[None, 3:6])[0]
            at = 6
            if self._quaternion:
                q = quaternion_of_frame(D)
                if self._last_q is not None and q @ self._last_q < 0.0:
                    q = -q
                out[at : at + 4] = self._last_q = q
                at += 4
            if self._directors:
                out[at : at + 9] = D.ravel()
                at += 9
            if self._body is not None:  # u_C = u + (D − D0)ᵀ c (forms/rigid_body.py (B1))
                D0, c = self._body
                out[at : at + 3] = out[:3] + (D - D0).T @ c
                at += 3
        if self._contact is not None:  # load [N/m], gap [m], state at the probe
            if self._node is not None:
                out[-5:] = self._contact.x.array[6 * self._node : 6 * self._node + 5]
            else:
                point = np.array([self.cell], dtype=np.int32)
                out[-5:] = self._contact.eval(self.point, point)[:5]
        return out

    @staticmethod
    def _body_frame(model: RodModel, sigma: float) -> tuple[np.ndarray, np.ndarray]:
        """(D0, c): the rest directors at the probe point and the offset [m] of the body
        carried there (the scene's check puts the probe at the body's end)."""
        scene = model.scene
        body = scene.loads.body
        assert body is not None, "the scene's check: probe field body needs [loads.body]"
        reference = scene.reference
        D0 = reference.frames(np.array([model.length * sigma]))[0] if reference.curved else None
        return (np.eye(3) if D0 is None else D0), np.array(body.offset_vector(), dtype=float)

    def seed(self, row: np.ndarray) -> None:
        """Continue from a row (t, x, ..., φ, ...) of probes.csv: a restart's last row, so that
        its angles and quaternion continue from there as the uninterrupted run's do (class
        docstring)."""
        self.angles.last = np.asarray(row[4:7], dtype=float).reshape(1, 3)
        if self._quaternion:
            self._last_q = np.asarray(row[7:11], dtype=float)

    def _chart_value(self) -> np.ndarray:
        """The chart's quaternion at the probe point, (1, 4)."""
        chart = self.angles.model.chart
        assert chart is not None, "called for a model with a chart"
        if self._node is not None:
            return chart.x.array[None, 4 * self._node : 4 * self._node + 4]
        return chart.eval(self.point, np.array([self.cell], dtype=np.int32))


def _field_expressions(
    U, model: RodModel, fields: tuple[str, ...]
) -> list[tuple[str, ufl.core.expr.Expr]]:
    """(array name, UFL 3-vector) of the requested fields of ``U`` (in the model's layout);
    see :class:`XdmfWriter`."""
    U = model.layout.full(U)  # a planar model's unknowns in the 12 components (zeros elsewhere)
    tau = model.scene.damping.retardation_time  # n, m with their Kelvin–Voigt parts
    chart = model.chart_form() if model.chart_moved else None
    reference = model.reference_form()
    res = None
    if {"strains", "forces"} & set(fields):
        res = resultants(U, model.rod, tau, chart, reference)
    ell = model.length

    def resultant(name: str) -> ufl.core.expr.Expr:
        assert res is not None, "made for the fields strains and forces"
        return getattr(res, name)

    exprs: dict[str, Callable[[], ufl.core.expr.Expr]] = {
        "displacement": lambda: ufl.as_vector([ell * U[0], ell * U[1], ell * U[2]]),
        # a structure's: those of the nodes' rotation Λ, as its probes (docs/structures.md)
        "angles": lambda: _fixed_basis_angles(
            U, chart, None if model.scene.structure is not None else reference
        ),
        "strain_v": lambda: resultant("v"),
        "curvature_u": lambda: resultant("u"),
        "force_n": lambda: resultant("n"),
        "torque_m": lambda: resultant("m"),
        **{f"director_d{i + 1}": partial(_director, U, chart, i, reference) for i in range(3)},
        "contact_load": lambda: _contact(model, (0, 1, 2)),
        "contact_gap": lambda: _contact(model, (3, 4, None)),
    }
    return [(name, exprs[name]()) for field in fields for name in FIELD_ARRAYS[field]]


def _contact(model: RodModel, slots: tuple[int | None, ...]) -> ufl.core.expr.Expr:
    """The 3-vector of the contact's output values (cosserat_fem/nls/contact.py
    ``NodeContact.values``) in ``slots`` (None: 0): the load [N/m] (a node's force over its
    share of the length), or (gap [m], state, 0), interpolated between the nodes."""
    if model.contact is None:
        raise ValueError("the XDMF field contact needs a scene with [contact]")
    values = model.contact.values
    return ufl.as_vector([0.0 * values[0] if k is None else values[k] for k in slots])


def _directors(U, chart, reference) -> ufl.core.expr.Expr:
    """The directors' matrix of U: D of (18), D A in a chart, D0 D A for a rod curved at rest
    (forms/reference.py)."""
    D = directors(ufl.as_vector([U[k] for k in range(6)]), chart)
    return D if reference is None else reference.frame * D


def _director(U, chart, i: int, reference=None) -> ufl.core.expr.Expr:
    """The director d_(i+1) of U in the fixed basis (row i of :func:`_directors`)."""
    D = _directors(U, chart, reference)
    return ufl.as_vector([D[i, j] for j in range(3)])


def _fixed_basis_angles(U, chart, reference=None) -> ufl.core.expr.Expr:
    """(θ, ψ, φ) of U, or in a chart (one that has moved) or for a rod curved at rest those
    of (18) for its directors (:func:`_directors`), with |θ| ≤ π/2 and ψ, φ in (−π, π]
    (cosserat_fem/rod/charts.py euler_angles, not continued)."""
    if chart is None and reference is None:
        return ufl.as_vector([U[3], U[4], U[5]])
    D = _directors(U, chart, reference)
    return ufl.as_vector(
        [ufl.asin(-D[2, 1]), ufl.atan_2(D[2, 0], D[2, 2]), ufl.atan_2(D[0, 1], D[1, 1])]
    )


def _output_nodes(msh: mesh.Mesh, k: int) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """The output points of the owned cells of the solver mesh: the reference points j/k,
    j = 0..k (each cell split into k segments), as global ids (a vertex keeps its input
    index; the interior points of global cell g get n_vertices + (k − 1) g + j − 1) and their
    σ, arrays (owned cells, k + 1); the total number of points; and their mesh coordinates
    (owned cells, k + 1, 3) (a structure's r0/ℓ, cosserat_fem/rod/structure.py)."""
    comm = msh.comm
    imap = msh.topology.index_map(msh.topology.dim)
    n_owned = imap.size_local
    global_cells = np.arange(*imap.local_range, dtype=np.int64)
    nodes = msh.geometry.dofmap.array.reshape(-1, 2)[:n_owned]
    index = np.asarray(msh.geometry.input_global_indices, dtype=np.int64)
    n_vertices = comm.allreduce(int(index.max(initial=-1)) + 1, op=MPI.MAX)
    ids = np.empty((n_owned, k + 1), dtype=np.int64)
    ids[:, 0], ids[:, k] = index[nodes[:, 0]], index[nodes[:, 1]]
    ids[:, 1:k] = n_vertices + (k - 1) * global_cells[:, None] + np.arange(k - 1)[None, :]
    y0, y1 = msh.geometry.x[nodes[:, 0]], msh.geometry.x[nodes[:, 1]]
    xi = np.linspace(0.0, 1.0, k + 1)[None, :, None]
    coords = y0[:, None, :] + xi * (y1 - y0)[:, None, :]
    coords[:, 0], coords[:, k] = y0, y1  # exactly the vertices
    x0, x1 = y0[:, 0], y1[:, 0]
    sigma = x0[:, None] + np.linspace(0.0, 1.0, k + 1)[None, :] * (x1 - x0)[:, None]
    sigma[:, k] = x1  # exactly the vertex
    return ids, sigma, n_vertices + (k - 1) * imap.size_global, coords


class CentrelineOutput:
    """The output points of a rod and the map to them from values at the points of the
    solver's owned cells: each solver cell split into ``k`` equal segments (one point per
    Lagrange node of degree k), the points numbered along the rod (in the order of σ).

    Rank 0 holds ``geometry``, the points on the reference centreline [m] (n_points, 3),
    (0, 0, ℓ σ) for the straight rod, and ``topology``, the segments as pairs of point
    numbers (sorted); both are
    None on the other ranks. A point's value is the mean of its cells' values (a vertex inside
    the rod has two cells, the other points one; the mean of one value is that value, bitwise,
    and of two the same in either order). Rank 0 gathers the values of all cells and averages
    them per point (in serial there is no communication). Nothing depends on the mesh's
    partition: under MPI the points, segments and values (of the same state) are a serial
    run's, bit for bit."""

    def __init__(self, msh: mesh.Mesh, length: float, k: int, positions=None):
        """``positions(s)``: the reference centreline r0 [m] at arc lengths s (n, 3); default
        the straight rod's (0, 0, s). On a structure's mesh (geometric dimension 3,
        cosserat_fem/rod/structure.py) the points are ℓ times the mesh's, numbered by their
        ids (its nodes first), and a junction's value the mean of two of its cells'."""
        comm = self.comm = msh.comm
        self.k = k
        self.cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
        ids, sigma, self.n_points, coords = _output_nodes(msh, k)
        embedded = msh.geometry.dim == 3
        if embedded:  # the structure's points are numbered by their ids, not sorted by σ
            sigma = ids.astype(float)
        self.counts = [ids.size] if comm.size == 1 else comm.allgather(ids.size)
        if comm.size > 1:
            ids_all = comm.gather(ids.ravel(), root=0)
            sigma_all = comm.gather(sigma.ravel(), root=0)
            coords_all = comm.gather(coords.reshape(-1, 3), root=0)
        else:
            ids_all, sigma_all = [ids.ravel()], [sigma.ravel()]
            coords_all = [coords.reshape(-1, 3)]
        self.geometry: np.ndarray | None = None
        self.topology: np.ndarray | None = None
        self._first = self._second = None
        if comm.rank == 0:
            flat = np.concatenate(ids_all)
            n = self.n_points
            seen = np.bincount(flat, minlength=n)
            if seen.min() < 1 or (seen.max() > 2 and not embedded):
                raise RuntimeError("output points: every point must have one or two cells")
            at = np.zeros(n)
            at[flat] = np.concatenate(sigma_all)  # a vertex has the same σ in both its cells
            order = np.argsort(at, kind="stable")  # the ids in the order of σ
            number = np.empty(n, dtype=np.int64)
            number[order] = np.arange(n)
            rows = number[flat]  # the point of each gathered row
            if embedded:
                self.geometry = np.zeros((n, 3))
                self.geometry[flat] = length * np.concatenate(coords_all)
            elif positions is None:
                self.geometry = np.zeros((n, 3))
                self.geometry[:, 2] = length * at[order]
            else:
                self.geometry = np.asarray(positions(length * at[order]), dtype=float)
            per_cell = rows.reshape(-1, k + 1)
            pairs = np.column_stack([per_cell[:, :k].ravel(), per_cell[:, 1:].ravel()])
            pairs.sort(axis=1)
            self.topology = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
            # Rows (k + 1) c + j of the gathered values (point j of gathered cell c) per point.
            by_point = np.argsort(rows, kind="stable")
            count = seen[order]
            start = np.concatenate([[0], np.cumsum(count)[:-1]])
            self._first, self._second = by_point[start], by_point[start + count - 1]

    def point_values(self, values: np.ndarray) -> np.ndarray | None:
        """(n_points, m) at the output points on rank 0, None elsewhere, from ``values`` (owned
        cells, (k + 1) m): the values at the k + 1 points of each owned solver cell,
        point-major. Collective."""
        m = values.shape[1] // (self.k + 1)
        rows = values.reshape(-1, m)
        comm = self.comm
        if comm.size > 1:
            gathered = np.empty((sum(self.counts), m)) if comm.rank == 0 else None
            sizes = [c * m for c in self.counts]
            comm.Gatherv(np.ascontiguousarray(rows), (gathered, sizes), root=0)
            if gathered is None:  # not rank 0
                return None
            rows = gathered
        if comm.rank != 0:
            return None
        return 0.5 * (rows[self._first] + rows[self._second])


class XdmfWriter:
    """XDMF/HDF5 time series of the rod as a curve in 3D, for ParaView.

    The mesh is the reference centreline in physical coordinates: the straight rod along e3,
    points (0, 0, s) [m], s = ℓ σ (the reference axis of forms/kinematics.py, r' = (p1', p2',
    1 + p3')), or the curve r0(s) of the scene's [reference] (cosserat_fem/scene/resolved.py), cells
    the solver's. So ParaView's "Warp By Vector" with ``displacement`` draws the deformed rod
    r(s) = r0(s) + (x, y, z). For a rod curved at rest the angles are those of its directors
    D0 D A, and the strains and forces are measured from the reference (forms/resultants.py).
    Point arrays (3-vectors), chosen by ``fields``
    (the scene's ``output.fields``; a field not asked for is neither computed nor written):

    ================  ==============  ============================================  =======
    field             array           value                                         unit
    ================  ==============  ============================================  =======
    ``displacement``  displacement    (x, y, z) = ℓ (p1, p2, p3), fixed basis e_i   m
    ``angles``        angles          (θ, ψ, φ) = (p4, p5, p6)                      rad
    ``strains``       strain_v        v_i = d_i · ∂r/∂s (29), director basis        1
    ``strains``       curvature_u     u_i = d_i · u (25), director basis            1/m
    ``forces``        force_n         contact force n_i = d_i · n (9)-(10)          N
    ``forces``        torque_m        contact torque m_i = d_i · m (13)             N m
    ``directors``     director_d1..3  the directors d_i, fixed basis e_j (18)       1
    ``contact``       contact_load    the obstacles' load on the rod, fixed basis   N/m
    ``contact``       contact_gap     (gap, state: 0 free 1 stick 2 slip, 0)        m, 1
    ================  ==============  ============================================  =======

    v, u, n, m are those of forms/resultants.py (reference state v = (0, 0, 1), u = n = m = 0;
    n(s), m(s) act on [0, s] from (s, ℓ], so at a free end they are the applied end load). A
    cell of degree k is drawn as k equal segments (one point per Lagrange node); at a vertex
    the strains and resultants, which jump between cells, take the mean of the two cells'.
    One temporal collection ``rod`` whose frames each carry the mesh, the time and all the
    arrays in double precision, so that ParaView shows one dataset. The points are numbered
    along the rod (σ from 0 to 1); under MPI rank 0 gathers the values and writes every file,
    for the same state the very files of a serial run.

    The files (their layout, how a frame is added so that a kill leaves them readable): the
    rank-0 :class:`~cosserat_fem.io.xdmf.XdmfSeries` (cosserat_fem/io/xdmf.py).
    """

    def __init__(
        self,
        path: Path,
        model: RodModel,
        fields: tuple[str, ...] | None = None,
        U: fem.Function | None = None,
        jit_params: dict | None = None,
        resume: tuple[int, int] | None = None,
        run_id: str | None = None,
    ):
        """``model``: the discrete rod (mesh, constants); ``fields``: a subset of
        :data:`FIELD_ARRAYS` (default the scene's ``output.fields``); ``U``: the Function
        written (default ``model.U``), holding (p, q); ``write`` may be given another Function
        of the same space (e.g. one mode shape after another). ``resume = (n, frames)``:
        continue, as restart n, the existing XML, which holds ``frames`` frames (cut back to
        them, later frame files deleted: cosserat_fem/io/checkpoint.py), in its mesh's order of
        the points (:class:`~cosserat_fem.io.xdmf.XdmfSeries`). ``run_id``: the identity of
        the run, written into the XML (checked by a restart, cosserat_fem/io/checkpoint.py)."""
        msh = model.msh
        self.U = model.U if U is None else U
        self.fields = tuple(model.scene.output.fields if fields is None else fields)
        unknown = [f for f in self.fields if f not in FIELD_ARRAYS]
        if unknown:
            raise ValueError(f"unknown XDMF fields {unknown}; expected some of {FIELD_ARRAYS}")
        self._comm = msh.comm
        # A cell of degree k is drawn as k segments: the output points are the Lagrange
        # nodes for equispaced ones.
        k = max(1, self.U.function_space.ufl_element().degree())
        self.line = CentrelineOutput(msh, model.length, k, model.scene.reference.positions)
        self.arrays = [name for field in self.fields for name in FIELD_ARRAYS[field]]
        self.model, self._jit_params, self._k = model, jit_params or {}, k
        self._expr: fem.Expression | None = None
        self._compile()
        self.path = Path(path)
        self.files: XdmfSeries | None = None  # rank 0 only
        self.writes = 0 if resume is None else resume[1]
        problem = None
        if self._comm.rank == 0:
            assert self.line.geometry is not None and self.line.topology is not None  # rank 0's
            try:
                self.files = XdmfSeries(
                    self.path,
                    self.arrays,
                    self.line.geometry,
                    self.line.topology,
                    None if resume is None else resume[1],
                    run_id,
                )
            except OutputError as exc:
                problem = exc
        agree(self._comm, problem)

    def _compile(self) -> None:
        """The expression of every array at the output points; with a chart that has moved,
        the charted one (angles of the directors from the fixed basis; until then the
        unknowns' angles, which the paper's chart measures from it)."""
        self._charted = self.model.chart_moved
        parts = _field_expressions(self.U, self.model, self.fields)  # embeds a planar U once
        components = [expr[i] for _, expr in parts for i in range(3)]
        if components:
            points = np.linspace(0.0, 1.0, self._k + 1)[:, None]  # reference points j/k
            self._expr = fem.Expression(
                ufl.as_vector(components), points, jit_params=self._jit_params
            )
            self._values = np.empty((len(self.line.cells), (self._k + 1) * len(components)))

    def write(self, t: float, U: fem.Function | None = None) -> None:
        """A frame at t [s] (a load factor, a mode number) of U, or of ``U`` copied into it;
        OutputError if it may not fit or is not written, the frames before kept. Collective."""
        if U is not None and U is not self.U:
            self.U.x.array[:] = U.x.array
        if self.arrays:
            if self._charted != self.model.chart_moved:
                self._compile()
            assert self._expr is not None, "made by _compile for the arrays"
            self._expr.eval(self.line.cells, self._values)
            values = self.line.point_values(self._values)
            problem = None
            if self.files is not None:
                assert values is not None, "rank 0's, which has the files"
                try:
                    self.files.write(t, values)
                except OutputError as exc:
                    problem = exc
            agree(self._comm, problem)
        self.writes += 1

    def close(self) -> None:
        """Close the XML (rank 0); the files are complete after every frame."""
        if self.files is not None:
            self.files.close()


class LineSampler:
    """Samples (x, y, z, θ, ψ, φ) in SI units at many σ points of a model's rod; results
    gathered on rank 0 (the components of p the model does not solve are 0)."""

    def __init__(self, model: RodModel, sigmas: np.ndarray, U: fem.Function | None = None):
        """``U``: the Function read (default ``model.U``), of the model's space and layout."""
        U = model.U if U is None else U
        msh = U.function_space.mesh
        self.U = U
        self.angles = FixedBasisAngles(model)
        self.sigmas = np.asarray(sigmas, dtype=float)
        pts = np.zeros((len(self.sigmas), 3))
        pts[:, 0] = self.sigmas
        tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
        colliding = geometry.compute_colliding_cells(
            msh, geometry.compute_collisions(tree, pts), pts
        )
        n_owned = msh.topology.index_map(msh.topology.dim).size_local
        comm = msh.comm
        claim = np.full(len(pts), comm.size, dtype=np.int32)
        cells = np.zeros(len(pts), dtype=np.int32)
        for i in range(len(pts)):
            owned = [c for c in colliding.links(i) if c < n_owned]
            if owned:
                claim[i], cells[i] = comm.rank, owned[0]
        owner = np.empty_like(claim)
        comm.Allreduce(claim, owner, op=MPI.MIN)
        if (owner == comm.size).any():
            outside = self.sigmas[owner == comm.size][0]
            raise ValueError(f"sampling point σ = {outside} lies outside the mesh [0, 1]")
        self._mine = np.flatnonzero(owner == comm.rank)
        self._points = pts[self._mine]
        self._cells = cells[self._mine]
        layout = model.layout
        self._p = np.array(layout.components[: layout.p_count], dtype=int)
        self._scale = layout.si_scale(model.length, model.omega0)[: layout.p_count]
        self.comm = comm

    def sample(self) -> np.ndarray | None:
        """Array (len(sigmas), 6) on rank 0, None elsewhere."""
        local = np.zeros((len(self.sigmas), 6))
        if len(self._mine):
            # (points, values): Function.eval returns a flat array for a single point
            values = self.U.eval(self._points, self._cells).reshape(len(self._mine), -1)
            local[np.ix_(self._mine, self._p)] = values[:, : len(self._p)] * self._scale

            def chart_values() -> np.ndarray:
                chart = self.angles.model.chart
                assert chart is not None, "called for a model with a chart"
                return chart.eval(self._points, self._cells).reshape(len(self._mine), 4)

            local[self._mine, 3:6] = self.angles(
                local[self._mine, 3:6], chart_values, lambda: self._points[:, 0]
            )
        total = np.zeros_like(local) if self.comm.rank == 0 else None
        self.comm.Reduce(local, total, op=MPI.SUM, root=0)
        return total
