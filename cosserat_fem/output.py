"""Run outputs: free-end probes (CSV), an XDMF time series for ParaView, ``summary.json``.

Quantities are written in SI units: positions in m (x = ℓ p1, ...), angles in rad, time in
s. The probe row is written by the one rank that owns the probe point, so a step costs no
communication.

A run that stops early, or is killed (even with SIGKILL), leaves readable outputs up to the
last step written (tests/test_kill.py): the XDMF/HDF5 pair is consistent between frames
(:class:`XdmfWriter`), and probe rows reach the file before every XDMF frame, so probes.csv
always covers the last frame on disk and loses at most the rows computed since
(:class:`ProbeWriter`). ``fsync`` only at the end: what reached the page cache survives a
killed process, though not a power cut.
"""

from __future__ import annotations

import hashlib
import os
import resource
import shutil
import time
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import ufl
from dolfinx import fem, geometry, io, mesh
from mpi4py import MPI

from .charts import euler_angles, euler_matrix, quaternion_frame, quaternion_of_frame
from .errors import OutputError
from .forms.kinematics import directors
from .forms.resultants import resultants
from .parallel import agree, from_root
from .results import PROBE_FIELD_COLUMNS, probe_columns

if TYPE_CHECKING:
    from .model import RodModel


def probe_sigma(scene) -> float:
    """The probe point σ of a scene: the free end at s = ℓ, else the free end at s = 0, else
    mid-span."""
    if scene.supports.end == "free":
        return 1.0
    if scene.supports.start == "free":
        return 0.0
    return 0.5


class FixedBasisAngles:
    """The angles (θ, ψ, φ) that the samplers report: those of (18) measured from the fixed
    basis. With a chart that has moved (cosserat_fem/charts.py) they are the angles of the
    rod's directors D A, continued from the previous call's (of the two triples and their
    turns of 2π, the one nearest: :func:`~cosserat_fem.charts.euler_angles`), so that they
    stay continuous through the chart's resets; only where θ passes ±π/2 itself, where ψ and
    φ are not defined apart, may they jump. Before the first reset they are the unknowns'."""

    def __init__(self, model: RodModel):
        self.model = model
        self.last: np.ndarray | None = None  # the angles of the previous call
        self.frame: np.ndarray | None = None  # its directors D A (in a moved chart)

    def __call__(self, angles: np.ndarray, chart_values) -> np.ndarray:
        """Fixed-basis angles (points, 3) of the chart angles ``angles`` at points whose
        chart quaternions ``chart_values()`` gives (points, 4), called only once the chart
        has moved."""
        model = self.model
        if model.chart is None or not model.chart_moved:
            if model.chart is not None:
                self.last = angles.copy()
            return angles
        D = euler_matrix(*angles.T) @ quaternion_frame(chart_values())
        self.last = euler_angles(D, angles if self.last is None else self.last)
        self.frame = D
        return self.last

    def directors(self, angles: np.ndarray) -> np.ndarray:
        """The directors D (points, 3, 3) of the last call, whose angles it returned as
        ``angles``: D A as computed in a moved chart (not rebuilt from the angles, which lose
        digits near θ = ±π/2), else D(θ, ψ, φ) of (18)."""
        model = self.model
        if model.chart is not None and model.chart_moved:
            return self.frame
        return euler_matrix(*angles.T)


class PointProbe:
    """Evaluates (x, y, z, θ, ψ, φ) in SI units [m, rad] at σ = ``sigma`` of a model's rod, on
    its owning rank (the components of p the model does not solve are 0), followed by the
    ``fields`` of ``output.probe_fields`` (:data:`~cosserat_fem.results.PROBE_FIELD_COLUMNS`):
    the quaternion of the directors (q0, q1, q2, q3), signed as the previous call's so that it
    is continuous in time, and the directors d1, d2, d3 in the fixed basis.

    With a chart (cosserat_fem/charts.py) the angles are those of (18) for the rod's own
    directors D A, measured from the fixed basis as without one, and continued from the
    previous call's (of the two triples and their turns of 2π, the one nearest:
    :func:`~cosserat_fem.charts.euler_angles`), so that they stay continuous through a
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
        self._last_q: np.ndarray | None = None  # the quaternion of the previous call
        msh = U.function_space.mesh
        self.U = U
        self.angles = FixedBasisAngles(model)
        self.length = model.length
        self.sigma = sigma
        self.point = np.array([[sigma, 0.0, 0.0]])
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
            coords = U.function_space.tabulate_dof_coordinates()[:n_local, 0]
            hits = np.flatnonzero(np.abs(coords - sigma) < 1e-12)
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
        out[3:6] = self.angles(out[None, 3:6], self._chart_value)[0]
        if self._quaternion or self._directors:
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
        return out

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
        if self._node is not None:
            return chart.x.array[None, 4 * self._node : 4 * self._node + 4]
        return chart.eval(self.point, np.array([self.cell], dtype=np.int32))


def last_probe_row(path: Path) -> np.ndarray:
    """The last whole row of probes.csv (a restart's, already cut back to its checkpoint),
    as numbers."""
    with open(path, "rb") as stream:
        stream.seek(0, os.SEEK_END)
        size = stream.tell()
        stream.seek(max(0, size - 4096))
        lines = stream.read().decode("utf-8").splitlines()
    return np.array([float(v) for v in lines[-1].split(",")])


class ProbeWriter:
    """``probes.csv`` with the header t,x,y,z,theta,psi,phi (and the columns of the probe's
    ``output.probe_fields``), written by the probe's owner.

    Rows are buffered and handed to the operating system when ``flush_every`` rows are pending,
    when ``max_delay`` seconds (wall time) have passed since the last flush, and before every
    XDMF frame (the run flushes its probes before it writes a frame, cosserat_fem/simulation.py
    and statics.py). So a killed run loses at most the rows since the last XDMF frame (7 rows at
    the default scene's 8 steps a frame) or of the last ``max_delay`` s, and probes.csv always
    reaches the last frame of the XDMF file. Measured per row, default scene: the same ~12 us a
    row (full run) as flushing every 200 rows only; flushing every row cost ~23 us a row more on
    a busy ext4 file system (a write() can wait ~3 ms for a journal commit of another process),
    3-5 % of a ~0.5 ms step.

    The SHA-256 of the bytes written (:meth:`digest`) goes into each checkpoint, so that a
    restart can prove that probes.csv is the checkpointed run's (cosserat_fem/checkpoint.py).
    A write that fails (disk full, file size limit) raises :class:`OutputError` at once in
    serial; under MPI the owner keeps it and every rank raises it at :meth:`check`.
    """

    def __init__(
        self,
        path: Path,
        probe: PointProbe,
        flush_every: int = 200,
        max_delay: float = 0.05,
        resume: bool = False,
    ):
        """``resume``: continue the existing file (a restart, which has cut it back)."""
        self.path = Path(path)
        self.probe = probe
        self.comm = probe.U.function_space.mesh.comm
        self.flush_every = flush_every
        self.max_delay = max_delay
        self.error: OutputError | None = None
        self._pending = 0
        self._rows = np.empty((flush_every, len(probe.columns)))
        self._format = "%.10e," + ",".join(["%.16e"] * (len(probe.columns) - 1)) + "\n"
        self._file = None
        self._deadline = 0.0
        self._sha = hashlib.sha256()
        if probe.is_owner:
            try:
                if resume:
                    self._sha.update(self.path.read_bytes())
                self._file = open(path, "a" if resume else "w", encoding="utf-8")  # noqa: SIM115
            except OSError as exc:
                self._fail(exc)
            if not resume:
                self._write(",".join(probe.columns) + "\n")
            self.flush()
        self.check()

    def _fail(self, exc: OSError) -> None:
        """Keep the OutputError of a failed write and write no more; raised at once in serial, at
        :meth:`check` under MPI."""
        self.error = OutputError(
            f"output: cannot write {str(self.path)!r} ({exc.strerror or exc}); the rows "
            "before are kept"
        )
        self._file = None
        if self.comm.size == 1:
            raise self.error

    def _write(self, text: str) -> None:
        """``text`` to the file (flushed) and into the SHA-256; a failure goes to :meth:`_fail`."""
        if self._file is None:
            return
        try:
            self._file.write(text)
            self._file.flush()
        except OSError as exc:
            self._fail(exc)
            return
        self._sha.update(text.encode("utf-8"))

    def check(self) -> None:
        """Raise, on every rank, an error the owner met (collective under MPI)."""
        agree(self.comm, self.error)

    def write(self, t: float) -> None:
        """Buffer the row of time t; see the class docstring for when rows go to the file."""
        if self._file is None:
            return
        row = self._rows[self._pending]
        row[0] = t
        row[1:] = self.probe.values()
        self._pending += 1
        if self._pending >= self.flush_every or time.monotonic() >= self._deadline:
            self.flush()

    def flush(self, sync: bool = False) -> None:
        """Hand the pending rows to the operating system; ``sync``: fsync too (at the end)."""
        if self._file is not None:
            if self._pending:
                # One formatting call for the whole block (about 10x cheaper than per value).
                block = tuple(self._rows[: self._pending].ravel())
                self._pending = 0
                self._write((self._format * (len(block) // len(self.probe.columns))) % block)
            if sync and self._file is not None:
                try:
                    os.fsync(self._file.fileno())
                except OSError as exc:
                    self._fail(exc)
            self._deadline = time.monotonic() + self.max_delay

    def digest(self) -> str | None:
        """SHA-256 of what probes.csv holds (rows pending are written first); None off the
        owner."""
        if not self.probe.is_owner:
            return None
        self.flush()
        return self._sha.hexdigest()

    def close(self) -> None:
        """Flush, fsync and close the owner's file; a failure is handled as by :meth:`_fail`."""
        if self._file is not None:
            self.flush(sync=True)
            if self._file is not None:
                self._file.close()
            self._file = None


#: The point arrays of each ``output.fields`` entry, in the order they are written.
FIELD_ARRAYS: dict[str, tuple[str, ...]] = {
    "displacement": ("displacement",),
    "angles": ("angles",),
    "strains": ("strain_v", "curvature_u"),
    "forces": ("force_n", "torque_m"),
    "directors": ("director_d1", "director_d2", "director_d3"),
}


def _field_expressions(U, model: RodModel, fields: tuple[str, ...]) -> list[tuple[str, object]]:
    """(array name, UFL 3-vector) of the requested fields of ``U`` (in the model's layout);
    see :class:`XdmfWriter`."""
    U = model.layout.full(U)  # a planar model's unknowns in the 12 components (zeros elsewhere)
    tau = model.scene.damping.retardation_time  # n, m with their Kelvin–Voigt parts
    chart = model.chart_form() if model.chart_moved else None
    res = resultants(U, model.rod, tau, chart) if {"strains", "forces"} & set(fields) else None
    ell = model.length
    exprs = {
        "displacement": lambda: ufl.as_vector([ell * U[0], ell * U[1], ell * U[2]]),
        "angles": lambda: _fixed_basis_angles(U, chart),
        "strain_v": lambda: res.v,
        "curvature_u": lambda: res.u,
        "force_n": lambda: res.n,
        "torque_m": lambda: res.m,
        **{f"director_d{i + 1}": (lambda i=i: _director(U, chart, i)) for i in range(3)},
    }
    return [(name, exprs[name]()) for field in fields for name in FIELD_ARRAYS[field]]


def _director(U, chart, i: int) -> ufl.core.expr.Expr:
    """The director d_(i+1) of U in the fixed basis (row i of D, or of D A in a chart)."""
    D = directors(ufl.as_vector([U[k] for k in range(6)]), chart)
    return ufl.as_vector([D[i, j] for j in range(3)])


def _fixed_basis_angles(U, chart) -> ufl.core.expr.Expr:
    """(θ, ψ, φ) of U, or in a chart (one that has moved) those of (18) for the directors D A,
    with |θ| ≤ π/2 and ψ, φ in (−π, π] (cosserat_fem/charts.py euler_angles, not continued)."""
    if chart is None:
        return ufl.as_vector([U[3], U[4], U[5]])
    D = directors(ufl.as_vector([U[i] for i in range(6)]), chart)
    return ufl.as_vector(
        [ufl.asin(-D[2, 1]), ufl.atan_2(D[2, 0], D[2, 2]), ufl.atan_2(D[0, 1], D[1, 1])]
    )


def _output_nodes(msh: mesh.Mesh, k: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The output points of the owned cells of the solver mesh: the reference points j/k,
    j = 0..k (each cell split into k segments), as global ids (a vertex keeps its input
    index; the interior points of global cell g get n_vertices + (k − 1) g + j − 1) and their
    σ, arrays (owned cells, k + 1); and the total number of points."""
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
    x0, x1 = msh.geometry.x[nodes[:, 0], 0], msh.geometry.x[nodes[:, 1], 0]
    sigma = x0[:, None] + np.linspace(0.0, 1.0, k + 1)[None, :] * (x1 - x0)[:, None]
    sigma[:, k] = x1  # exactly the vertex
    return ids, sigma, n_vertices + (k - 1) * imap.size_global


class CentrelineOutput:
    """The output mesh, the reference centreline (0, 0, ℓ σ) [m] in 3D with each solver
    cell split into ``k`` equal segments (named "mesh"), and the map from values at the
    output points of the solver's owned cells to the P1 dofs of that mesh.

    A point's value is the mean of its cells' values (a vertex inside the rod has two cells,
    the other points one; the mean of one value is that value, bitwise). Rank 0 gathers the
    values of all cells, averages them per point and broadcasts the (small) result; every
    rank then takes the points of its part of the output mesh, which DOLFINx partitions on
    its own. In serial there is no communication."""

    def __init__(self, msh: mesh.Mesh, length: float, k: int):
        comm = self.comm = msh.comm
        self.k = k
        self.cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local,
                               dtype=np.int32)  # fmt: skip
        ids, sigma, self.n_points = _output_nodes(msh, k)
        self.counts = [ids.size] if comm.size == 1 else comm.allgather(ids.size)
        if comm.size > 1:
            ids_all = comm.gather(ids.ravel(), root=0)
            sigma_all = comm.gather(sigma.ravel(), root=0)
        else:
            ids_all, sigma_all = [ids.ravel()], [sigma.ravel()]
        x3 = np.zeros((0, 3))
        segments = np.zeros((0, 2), dtype=np.int64)
        self._first = self._second = None
        if comm.rank == 0:
            flat = np.concatenate(ids_all)
            x3 = np.zeros((self.n_points, 3))
            x3[flat, 2] = length * np.concatenate(sigma_all)
            per_cell = flat.reshape(-1, k + 1)
            segments = np.column_stack([per_cell[:, :k].ravel(), per_cell[:, 1:].ravel()])
            # Rows (k + 1) c + j of the gathered values (point j of gathered cell c) per id.
            order = np.argsort(flat, kind="stable")
            seen = np.bincount(flat, minlength=self.n_points)
            if seen.min() < 1 or seen.max() > 2:
                raise RuntimeError("output points: every point must have one or two cells")
            start = np.concatenate([[0], np.cumsum(seen)[:-1]])
            self._first, self._second = order[start], order[start + seen - 1]
        cell = ufl.Cell("interval", geometric_dimension=3)
        domain = ufl.Mesh(ufl.VectorElement("Lagrange", cell, 1, dim=3))
        self.mesh = mesh.create_mesh(comm, segments, x3, domain, ghost_mode=mesh.GhostMode.none)
        self.mesh.name = "mesh"
        self.space = fem.VectorFunctionSpace(self.mesh, ("Lagrange", 1), dim=3)
        # The id of every local dof (owned and ghost) of the P1 space on the output mesh.
        imap = self.space.dofmap.index_map
        self.dof_ids = np.empty(imap.size_local + imap.num_ghosts, dtype=np.int64)
        line_index = np.asarray(self.mesh.geometry.input_global_indices, dtype=np.int64)
        line_nodes = self.mesh.geometry.dofmap.array.reshape(-1, 2)
        self.dof_ids[self.space.dofmap.list.array.reshape(-1, 2)] = line_index[line_nodes]

    def point_values(self, values: np.ndarray) -> np.ndarray:
        """(points of the output mesh's local dofs, m) from ``values`` (owned cells,
        (k + 1) m): the values at the k + 1 points of each owned solver cell, point-major."""
        m = values.shape[1] // (self.k + 1)
        rows = values.reshape(-1, m)
        comm = self.comm
        if comm.size > 1:
            gathered = np.empty((sum(self.counts), m)) if comm.rank == 0 else None
            sizes = [c * m for c in self.counts]
            comm.Gatherv(np.ascontiguousarray(rows), (gathered, sizes), root=0)
            rows = gathered
        full = np.empty((self.n_points, m))
        if comm.rank == 0:
            full[:] = 0.5 * (rows[self._first] + rows[self._second])
        if comm.size > 1:
            comm.Bcast(full, root=0)
        return full[self.dof_ids]


#: The folder of an XDMF file's HDF5 files: ``<stem>.frames`` beside ``<stem>.xdmf``.
FRAMES_SUFFIX = ".frames"
#: The HDF5 file of the mesh in that folder (written once, when the series starts).
MESH_FILE = "mesh.h5"
#: Digits of a frame file's name: frame i (from 0) is ``<stem>.frames/<i, zero padded>.h5``.
FRAME_DIGITS = 6


def frames_folder(xdmf: Path) -> Path:
    """The folder of the HDF5 files of the XDMF file ``xdmf`` (see :class:`XdmfWriter`)."""
    xdmf = Path(xdmf)
    return xdmf.with_name(xdmf.stem + FRAMES_SUFFIX)


def frame_file(index: int) -> str:
    """The name, in :func:`frames_folder`, of the HDF5 file of frame ``index`` (from 0)."""
    return f"{index:0{FRAME_DIGITS}d}.h5"


class XdmfWriter:
    """XDMF/HDF5 time series of the rod as a curve in 3D, for ParaView.

    The mesh is the reference centreline in physical coordinates: the straight rod along e3,
    points (0, 0, s) [m], s = ℓ σ (the reference axis of forms/kinematics.py, r' = (p1', p2',
    1 + p3')), cells the solver's. So ParaView's "Warp By Vector" with ``displacement`` draws
    the deformed rod r(s) = (x, y, s + z). Point arrays (3-vectors), chosen by ``fields``
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
    ================  ==============  ============================================  =======

    v, u, n, m are those of forms/resultants.py (reference state v = (0, 0, 1), u = n = m = 0;
    n(s), m(s) act on [0, s] from (s, ℓ], so at a free end they are the applied end load). A
    cell of degree k is drawn as k equal segments (one point per Lagrange node); at a vertex
    the strains and resultants, which jump between cells, take the mean of the two cells'.
    One temporal collection ``rod`` whose frames each carry the mesh, the time and all the
    arrays in double precision, so that ParaView shows one dataset.

    Files: the XML ``<name>.xdmf`` and the folder ``<name>.frames/`` of HDF5 files: the mesh
    in ``mesh.h5``, frame i (from 0, restarts included) in ``<i, 6 digits>.h5``, e.g.
    ``solution.frames/000012.h5``; the XML names them relative to its own folder.

    Kill-safe: a killed run (SIGKILL included, at any moment) leaves ``<name>.xdmf`` listing
    exactly the frames written so far, each in a closed HDF5 file that is never opened for
    writing again. Each frame is written by DOLFINx into its own new file (with a scratch XML
    ``<name>.frames/<i>.xdmf-partial``) and closed, and only then is the published XML
    replaced atomically; a kill can damage only the frame in flight, which the XML does not
    name yet. A frame is written only if twice its size fits in the file system and under
    ``ulimit -f`` (an HDF5 write that fails half-way crashed the library), else an
    OutputError. Why this layout and what it costs: docs/decisions.md, "XDMF frames".
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
        them, later frame files deleted: cosserat_fem/checkpoint.py); the new frames go into
        new frame files from index ``frames`` on. Otherwise the XML and the frames folder of
        an earlier series are removed first. ``run_id``: the identity of the run, written into
        the XML (checked by a restart, cosserat_fem/checkpoint.py)."""
        msh = model.msh
        self.U = model.U if U is None else U
        self.fields = tuple(model.scene.output.fields if fields is None else fields)
        unknown = [f for f in self.fields if f not in FIELD_ARRAYS]
        if unknown:
            raise ValueError(f"unknown XDMF fields {unknown}; expected some of {FIELD_ARRAYS}")
        self._comm = msh.comm
        # A cell of degree k is drawn as k segments: the output points are the Lagrange
        # nodes for equispaced ones (P1 XDMF keeps values at mesh points only).
        k = max(1, self.U.function_space.ufl_element().degree())
        self.line = CentrelineOutput(msh, model.length, k)
        self.mesh = self.line.mesh
        P1 = self.line.space
        self.functions = [
            fem.Function(P1, name=name) for field in self.fields for name in FIELD_ARRAYS[field]
        ]
        self.model, self._jit_params, self._k = model, jit_params or {}, k
        self._expr = None
        self._compile()
        self.path = Path(path)
        suffix = self.path.suffix or ".xdmf"
        # The published XML is written under this name, then renamed onto self.path.
        self._work = self.path.with_name(self.path.stem + suffix + "-partial")
        self.folder = frames_folder(self.path)
        self.file: io.XDMFFile | None = None
        self._scratch: Path | None = None  # DOLFINx's XML of the file being written
        self._doc: _XdmfDocument | None = None  # rank 0 only
        # Bytes of a frame file (measured after each frame; at first the data alone).
        self._frame_bytes = len(self.functions) * (24 * self.line.n_points + 1400)
        prefix = self.folder.name + "/"
        if resume is not None:
            self.writes = resume[1]
            if self._comm.rank == 0:
                self._doc = _XdmfDocument(self.path.read_text(encoding="utf-8"), prefix)
                self.folder.mkdir(exist_ok=True)  # outputs of the single-file layout
            return
        self.writes = 0
        self._guard(self._write_mesh)
        if self._comm.rank == 0:
            self._doc = _XdmfDocument(self._scratch.read_text(encoding="utf-8"), prefix, run_id)
            self._scratch.unlink()
        self._guard(lambda: self._publish(None))

    @property
    def h5(self) -> Path:
        """The HDF5 file the next frame goes into."""
        return self.folder / frame_file(self.writes)

    def _write_mesh(self) -> None:
        """A new series: the XML and frames folder of an earlier one removed (the XML first),
        then DOLFINx's XML and .h5 of the output mesh, ``mesh.h5`` (collective)."""
        comm = self._comm
        self._scratch = (self.folder / MESH_FILE).with_suffix(".xdmf-partial")
        if comm.rank == 0:
            self.path.unlink(missing_ok=True)
            if self.folder.is_dir() and not self.folder.is_symlink():
                shutil.rmtree(self.folder)
            else:
                self.folder.unlink(missing_ok=True)
            self.folder.mkdir()
        if comm.size > 1:
            comm.barrier()
        self.file = io.XDMFFile(comm, str(self._scratch), "w")
        try:
            self.file.write_mesh(self.mesh)
        finally:
            self._close_file()
        if comm.size > 1:
            comm.barrier()

    def _guard(self, action, t: float | None = None) -> None:
        """Run ``action`` (collective); a failed write becomes an OutputError on every rank,
        and the published XML and the frames before stay as they were."""
        problem = None
        try:
            action()
        except (OSError, RuntimeError) as exc:
            self._close_file()
            when = f" at t = {t:.6g}" if t is not None else ""
            problem = OutputError(
                f"output: cannot write the XDMF frame{when} to {str(self.folder)!r} "
                f"({getattr(exc, 'strerror', None) or exc}); the frames before are kept"
            )
        agree(self._comm, problem)

    def _room_problem(self) -> str | None:
        """Why the next frame may not fit (rank 0): the HDF5 library cannot recover from a
        write that fails half-way (it crashed, and left an .h5 that no longer opened), so a
        frame is written only if twice its size, and the new XML, fit under the file size
        limit (ulimit -f; the XML is the largest file) and in the free space of the file
        system."""
        need = 2 * self._frame_bytes + 65536
        xml = self._doc.nbytes if self._doc is not None else 0
        try:
            limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
            if limit != resource.RLIM_INFINITY and xml + need > limit:
                return f"the file size limit (ulimit -f) of {limit} bytes would be reached"
            info = os.statvfs(self.folder)
            free = info.f_bavail * info.f_frsize
            if need + xml > free:
                return f"no space left on the device ({free} bytes free)"
        except OSError as exc:
            return str(exc.strerror or exc)
        return None

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
        OutputError if it may not fit (:meth:`_room_problem`) or is not written, the frames
        before kept. Collective."""
        if U is not None and U is not self.U:
            self.U.x.array[:] = U.x.array
        if self.functions:
            problem = from_root(self._comm, self._room_problem() if self._comm.rank == 0 else None)
            if problem:
                raise OutputError(
                    f"output: the XDMF frame at t = {t:.6g} was not written to "
                    f"{str(self.h5)!r}: {problem}; the frames before are kept"
                )
            if self._charted != self.model.chart_moved:
                self._compile()
            self._expr.eval(self.line.cells, self._values)
            mean = self.line.point_values(self._values)
            for k, function in enumerate(self.functions):
                function.x.array[:] = mean[:, 3 * k : 3 * k + 3].ravel()
            h5 = self.h5
            self._guard(lambda: self._write_frame(t), t)
            self._guard(lambda: self._publish(self._scratch), t)
            if self._comm.rank == 0:
                self._frame_bytes = max(self._frame_bytes, h5.stat().st_size)
        self.writes += 1

    def _write_frame(self, t: float) -> None:
        """DOLFINx's write of every array at t into the new file :attr:`h5`, with a scratch XML
        of this frame alone beside it."""
        self._reopen()
        try:
            last = len(self.functions) - 1
            for i, function in enumerate(self.functions):
                self.file.write_function(function, t)
                if i < last and self._comm.rank == 0:
                    # DOLFINx rewrites the whole scratch XML for every function: a new
                    # file each time, not one truncated and rewritten (ext4 then
                    # allocates its blocks at once, and frees them again with a discard:
                    # ~1.7 ms, against 0.05 ms for a new file that is unlinked).
                    self._scratch.unlink()
        finally:
            self._close_file()

    def close(self) -> None:
        """Nothing stays open between frames; kept for the writer interface."""
        self._close_file()

    def _reopen(self) -> None:
        """Open, in append mode, the scratch XML ``<i>.xdmf-partial`` of frame i, which holds
        the mesh only (DOLFINx refers to it), so that DOLFINx creates the new HDF5 file
        ``<i>.h5`` and its XML rewrites stay small and never touch the published file."""
        comm = self._comm
        self._scratch = self.h5.with_suffix(".xdmf-partial")
        if comm.rank == 0:
            # A frame killed or failed before its publication may have left both; neither is
            # named by the published XML.
            self.h5.unlink(missing_ok=True)
            self._scratch.unlink(missing_ok=True)
            self._scratch.write_text(self._doc.template(), encoding="utf-8")
        if comm.size > 1:
            comm.barrier()  # every rank reads the XML in the constructor
        self.file = io.XDMFFile(comm, str(self._scratch), "a")
        if comm.size > 1:
            comm.barrier()
        if comm.rank == 0:
            self._scratch.unlink()  # DOLFINx's first rewrite makes a new file (see write)

    def _close_file(self) -> None:
        if self.file is not None:
            file, self.file = self.file, None
            file.close()

    def _publish(self, scratch: Path | None) -> None:
        """Add the frame of DOLFINx's ``scratch`` XML (None: no frame) to the document and
        replace the published XML with it atomically (rank 0); if that fails the document
        drops the frame again."""
        # Rank 0 alone writes the XML (DOLFINx's scratch one in write_function/write_mesh,
        # then the published one) and renames it, once every rank has returned from closing
        # the HDF5 file: parallel HDF5 spreads the metadata writes over the ranks, and rank 0
        # may leave H5Fclose before rank 1 has written its share (a kill then left an XML
        # naming a dataset the .h5 did not hold).
        if self._comm.size > 1:
            self._comm.barrier()
        if self._comm.rank == 0:
            if scratch is not None:
                frame = scratch.read_text(encoding="utf-8")
                scratch.unlink()
                self._doc.add_frame(frame)
            try:
                self._work.unlink(missing_ok=True)  # a new file (see _write_frame)
                self._work.write_text(self._doc.text(), encoding="utf-8")
                os.replace(self._work, self.path)
            except OSError:
                if scratch is not None:
                    self._doc.drop_last()  # not published: the document stays the file's
                self._work.unlink(missing_ok=True)
                raise


_XDMF_HEAD = (
    '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
    '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
)
#: The one temporal collection of the published XML (and the name of each of its frames).
XDMF_GRID = "rod"
#: The name of the Information element of the Domain that holds the run's identity.
RUN_ID = "run_id"


def xdmf_run_id(root: ET.Element) -> str | None:
    """The run identity written into an XDMF file by :class:`XdmfWriter` (None if none)."""
    domain = root.find("Domain")
    item = None if domain is None else domain.find(f"Information[@Name='{RUN_ID}']")
    return None if item is None else item.get("Value")


def _element_text(element: ET.Element, level: int) -> str:
    """``element`` as indented XML text at depth ``level``; float DataItems marked
    ``Precision="8"`` (they are float64 in the .h5; unmarked, ParaView reads float32)."""
    for item in element.iter("DataItem"):
        if item.get("NumberType", "Float") == "Float" and "Precision" not in item.attrib:
            item.set("Precision", "8")
    ET.indent(element, space="  ", level=level)
    element.tail = None
    return "  " * level + ET.tostring(element, encoding="unicode") + "\n"


class _XdmfDocument:
    """The published XDMF XML, held by rank 0 as text: one temporal collection ``rod`` whose
    frames each hold the mesh (Topology, Geometry), the Time and every array of that time,
    so that ParaView shows one dataset carrying all the arrays (DOLFINx writes one collection
    per function, which ParaView shows as separate blocks: "Warp By Vector" with
    ``displacement`` would then move only the displacement block).

    Each frame's attributes are taken from the scratch XML that DOLFINx wrote for that frame
    alone (constant size), so a frame costs one write of the published file however many
    arrays it holds, instead of one DOLFINx rewrite per array of a file that grows with
    every frame (measured: 9 instead of 2 ms a frame for six arrays at 251 frames)."""

    def __init__(self, xml: str, prefix: str = "", run_id: str | None = None):
        """From DOLFINx's XML after ``write_mesh`` (grid "mesh") and the run's identity, or
        from a published file (which holds its run's). ``prefix``: the folder of the HDF5
        files relative to the published XML, put before the file names of DOLFINx's XML (which
        lies in that folder)."""
        root = ET.fromstring(xml)
        self.prefix = prefix
        self.run_id = run_id if run_id is not None else xdmf_run_id(root)
        domain = root.find("Domain")
        mesh = domain.find("Grid[@Name='mesh']")
        if mesh is None:
            collection = domain.find(f"Grid[@Name='{XDMF_GRID}']")
            mesh = collection.find("Grid")
        else:
            for item in mesh.iter("DataItem"):
                item.text = prefix + item.text.strip()
        parts = [mesh.find("Topology"), mesh.find("Geometry")]
        self.mesh = "".join(_element_text(e, 4) for e in parts)
        self.frames: list[str] = []
        collection = domain.find(f"Grid[@Name='{XDMF_GRID}']")
        if collection is not None:
            self.frames = [_element_text(g, 3) for g in collection.findall("Grid")]
        self.nbytes = sum(map(len, self.frames)) + 1024  # about len(text())

    def template(self) -> str:
        """The mesh alone, as DOLFINx writes it: the scratch file DOLFINx appends a frame to."""
        return (
            _XDMF_HEAD
            + '  <Domain>\n    <Grid Name="mesh" GridType="Uniform">\n'
            + self.mesh
            + "    </Grid>\n  </Domain>\n</Xdmf>\n"
        )

    def add_frame(self, xml: str) -> None:
        """Append the frame of ``xml``, DOLFINx's scratch file of one frame (one grid per
        function, each with the same Time and one Attribute; file names without the prefix)."""
        domain = ET.fromstring(xml).find("Domain")
        grids = [c.find("Grid") for c in domain.findall("Grid[@GridType='Collection']")]
        if not grids:
            return
        prefix = self.prefix
        parts = [f'      <Grid Name="{XDMF_GRID}" GridType="Uniform">\n', self.mesh]
        parts.append(f"        <Time Value={quoteattr(grids[0].find('Time').get('Value'))} />\n")
        for grid in grids:  # formatted directly: ElementTree's serializer cost ~0.1 ms each
            a = grid.find("Attribute")
            item = a.find("DataItem")
            precision = item.get("Precision", "8")
            parts.append(
                f"        <Attribute Name={quoteattr(a.get('Name'))} AttributeType="
                f"{quoteattr(a.get('AttributeType'))} Center={quoteattr(a.get('Center'))}>\n"
                f"          <DataItem Dimensions={quoteattr(item.get('Dimensions'))} "
                f'Format="HDF" Precision="{precision}">{escape(prefix + item.text.strip())}'
                "</DataItem>\n"
                "        </Attribute>\n"
            )
        parts.append("      </Grid>\n")
        self.frames.append("".join(parts))
        self.nbytes += len(self.frames[-1])

    def drop_last(self) -> None:
        """Forget the last frame added (it could not be published)."""
        self.nbytes -= len(self.frames.pop())

    def text(self) -> str:
        """The published XML: the run's identity and the collection ``rod`` of every frame."""
        identity = ""
        if self.run_id is not None:
            value = quoteattr(self.run_id)
            identity = f"    <Information Name={quoteattr(RUN_ID)} Value={value} />\n"
        return "".join(
            [
                _XDMF_HEAD,
                "  <Domain>\n",
                identity,
                f'    <Grid Name="{XDMF_GRID}" GridType="Collection" CollectionType="Temporal">\n',
                *self.frames,
                "    </Grid>\n  </Domain>\n</Xdmf>\n",
            ]
        )


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
            values = self.U.eval(self._points, self._cells)
            local[np.ix_(self._mine, self._p)] = values[:, : len(self._p)] * self._scale
            local[self._mine, 3:6] = self.angles(
                local[self._mine, 3:6],
                lambda: self.angles.model.chart.eval(self._points, self._cells),
            )
        total = np.zeros_like(local) if self.comm.rank == 0 else None
        self.comm.Reduce(local, total, op=MPI.SUM, root=0)
        return total
