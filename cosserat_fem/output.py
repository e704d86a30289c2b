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

No output is written through a link (a symbolic link or a file with other names, as ``cp -as``,
``cp -al`` or ``rsync --link-dest`` make) into a file outside the folder
(cosserat_fem/safe_files.py): probes.csv is made as a new file, or, on a restart, continued as
the folder's own copy; every XDMF, HDF5 and checkpoint file is a new file or renamed over the
old name. No special file (a FIFO, a device) is opened.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import math
import mmap
import os
import re
import resource
import time
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import ufl
from dolfinx import fem, geometry, mesh
from mpi4py import MPI

from . import safe_files
from .charts import euler_angles, euler_matrix, quaternion_frame, quaternion_of_frame
from .errors import OutputError
from .forms.kinematics import directors
from .forms.resultants import resultants
from .io.probes import PROBE_FIELD_COLUMNS, probe_columns
from .parallel import agree
from .results import FRAME_NAME, xdmf_mesh_xml

if TYPE_CHECKING:
    from .model import RodModel


def probe_position(scene, s: float) -> list[float]:
    """r0(s) [m], the probe's point on the rod at rest (the scene's [reference]): the point
    whose displacement probes.csv's x, y, z are (summary.json ``probe_reference_position_m``)."""
    return [float(x) for x in scene.reference.positions([s])[0]]


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
        self.reference_frames: np.ndarray | None = None  # D0 at the points, rod curved at rest

    def __call__(self, angles: np.ndarray, chart_values, sigma=None) -> np.ndarray:
        """Fixed-basis angles (points, 3) of the chart angles ``angles`` at points whose
        chart quaternions ``chart_values()`` gives (points, 4), called only once the chart
        has moved; for a rod curved at rest, those of its directors D0 D A, with D0 the
        reference frame at the points σ = ``sigma()`` (cosserat_fem/resolved.py)."""
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
            return self.frame
        return euler_matrix(*angles.T)


class PointProbe:
    """Evaluates (x, y, z, θ, ψ, φ) in SI units [m, rad] at σ = ``sigma`` of a model's rod, on
    its owning rank (the components of p the model does not solve are 0), followed by the
    ``fields`` of ``output.probe_fields`` (:data:`~cosserat_fem.io.probes.PROBE_FIELD_COLUMNS`):
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
        out[3:6] = self.angles(out[None, 3:6], self._chart_value, lambda: [self.sigma])[0]
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
    reference = model.reference_form()
    res = None
    if {"strains", "forces"} & set(fields):
        res = resultants(U, model.rod, tau, chart, reference)
    ell = model.length
    exprs = {
        "displacement": lambda: ufl.as_vector([ell * U[0], ell * U[1], ell * U[2]]),
        "angles": lambda: _fixed_basis_angles(U, chart, reference),
        "strain_v": lambda: res.v,
        "curvature_u": lambda: res.u,
        "force_n": lambda: res.n,
        "torque_m": lambda: res.m,
        **{
            f"director_d{i + 1}": (lambda i=i: _director(U, chart, i, reference))
            for i in range(3)
        },
    }
    return [(name, exprs[name]()) for field in fields for name in FIELD_ARRAYS[field]]


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
    (cosserat_fem/charts.py euler_angles, not continued)."""
    if chart is None and reference is None:
        return ufl.as_vector([U[3], U[4], U[5]])
    D = _directors(U, chart, reference)
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
        the straight rod's (0, 0, s)."""
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
        self.geometry: np.ndarray | None = None
        self.topology: np.ndarray | None = None
        self._first = self._second = None
        if comm.rank == 0:
            flat = np.concatenate(ids_all)
            n = self.n_points
            seen = np.bincount(flat, minlength=n)
            if seen.min() < 1 or seen.max() > 2:
                raise RuntimeError("output points: every point must have one or two cells")
            at = np.zeros(n)
            at[flat] = np.concatenate(sigma_all)  # a vertex has the same σ in both its cells
            order = np.argsort(at, kind="stable")  # the ids in the order of σ
            number = np.empty(n, dtype=np.int64)
            number[order] = np.arange(n)
            rows = number[flat]  # the point of each gathered row
            if positions is None:
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
            rows = gathered
        if comm.rank != 0:
            return None
        return 0.5 * (rows[self._first] + rows[self._second])


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


class _Hdf5:
    """HDF5 files made in memory by the HDF5 C library that DOLFINx has loaded, called through
    ctypes (h5py brings a library of its own, which cannot share a process with DOLFINx's).

    :meth:`image` builds a file with the core driver and no backing store and returns its
    bytes: the library never writes to disk, so a write that fails (disk full, ``ulimit -f``)
    is Python's OSError, never a failure inside HDF5. The files have superblock version 0 and
    contiguous datasets, as DOLFINx writes them: readable by every HDF5 since 1.8, and no
    "file open for writing" flag is ever set in them. HDF5's own error report on stderr is
    switched off during the calls (a failure raises RuntimeError)."""

    _lib = None

    def __init__(self):
        lib = self.library()
        hid = ctypes.c_int64
        self.lib = lib
        self.float64 = (hid.in_dll(lib, "H5T_IEEE_F64LE_g").value,
                        hid.in_dll(lib, "H5T_NATIVE_DOUBLE_g").value)  # fmt: skip
        self.int64 = (hid.in_dll(lib, "H5T_STD_I64LE_g").value,
                      hid.in_dll(lib, "H5T_NATIVE_INT64_g").value)  # fmt: skip
        self.fapl = lib.H5Pcreate(hid.in_dll(lib, "H5P_CLS_FILE_ACCESS_ID_g").value)
        self.lcpl = lib.H5Pcreate(hid.in_dll(lib, "H5P_CLS_LINK_CREATE_ID_g").value)
        self.dcpl = lib.H5Pcreate(hid.in_dll(lib, "H5P_CLS_DATASET_CREATE_ID_g").value)
        if (
            min(self.fapl, self.lcpl, self.dcpl) < 0
            or lib.H5Pset_fapl_core(self.fapl, 1 << 16, 0) < 0
            or lib.H5Pset_create_intermediate_group(self.lcpl, 1) < 0
            or lib.H5Pset_obj_track_times(self.dcpl, 0) < 0  # the same bytes for the same data
        ):
            raise RuntimeError("HDF5: cannot set up in-memory files")

    @classmethod
    def library(cls) -> ctypes.CDLL:
        """The HDF5 C library already in this process (DOLFINx's), with the prototypes used."""
        if cls._lib is not None:
            return cls._lib
        found = None
        pattern = re.compile(r"/libhdf5(?:_openmpi|_mpich|_serial)?\.so(?:\.[0-9]+)*$")
        try:
            with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
                for line in maps:
                    fields = line.split(maxsplit=5)
                    if len(fields) == 6 and pattern.search(fields[5].strip()):
                        found = fields[5].strip()
                        break
        except OSError:
            pass
        for name in ("hdf5_openmpi", "hdf5_mpich", "hdf5_serial", "hdf5"):
            found = found or ctypes.util.find_library(name)
        if not found:
            raise RuntimeError("the HDF5 C library (DOLFINx's) was not found")
        lib = ctypes.CDLL(found)
        hid, herr, size = ctypes.c_int64, ctypes.c_int, ctypes.c_size_t
        pointer, text = ctypes.c_void_p, ctypes.c_char_p
        for name, result, arguments in (
            ("H5open", herr, []),
            ("H5Fcreate", hid, [text, ctypes.c_uint, hid, hid]),
            ("H5Fopen", hid, [text, ctypes.c_uint, hid]),
            ("H5Fflush", herr, [hid, ctypes.c_int]),
            ("H5Fget_file_image", ctypes.c_ssize_t, [hid, pointer, size]),
            ("H5Fclose", herr, [hid]),
            ("H5Pcreate", hid, [hid]),
            ("H5Pset_fapl_core", herr, [hid, size, ctypes.c_uint]),
            ("H5Pset_create_intermediate_group", herr, [hid, ctypes.c_uint]),
            ("H5Pset_obj_track_times", herr, [hid, ctypes.c_uint]),
            ("H5Screate_simple", hid, [ctypes.c_int, pointer, pointer]),
            ("H5Sget_simple_extent_ndims", ctypes.c_int, [hid]),
            ("H5Sget_simple_extent_dims", ctypes.c_int, [hid, pointer, pointer]),
            ("H5Sclose", herr, [hid]),
            ("H5Dcreate2", hid, [hid, text, hid, hid, hid, hid, hid]),
            ("H5Dopen2", hid, [hid, text, hid]),
            ("H5Dget_space", hid, [hid]),
            ("H5Dwrite", herr, [hid, hid, hid, hid, hid, pointer]),
            ("H5Dread", herr, [hid, hid, hid, hid, hid, pointer]),
            ("H5Dget_offset", ctypes.c_uint64, [hid]),
            ("H5Dclose", herr, [hid]),
            ("H5Eget_auto2", herr, [hid, pointer, pointer]),
            ("H5Eset_auto2", herr, [hid, pointer, pointer]),
        ):
            function = getattr(lib, name)
            function.restype, function.argtypes = result, arguments
        if lib.H5open() < 0:
            raise RuntimeError(f"HDF5: cannot initialise {found}")
        cls._lib = lib
        return lib

    @contextlib.contextmanager
    def _quiet(self):
        """HDF5's printing of its error stack off (restored after)."""
        handler, data = ctypes.c_void_p(), ctypes.c_void_p()
        self.lib.H5Eget_auto2(0, ctypes.byref(handler), ctypes.byref(data))
        self.lib.H5Eset_auto2(0, None, None)
        try:
            yield
        finally:
            self.lib.H5Eset_auto2(0, handler, data)

    def image(self, datasets: list[tuple[str, np.ndarray]]) -> tuple[ctypes.Array, list[int]]:
        """The bytes of an HDF5 file holding the float64 or int64 ``datasets`` (name: a path
        from the root, its groups made as needed), and where each dataset's values begin in
        them; RuntimeError if HDF5 fails."""
        lib = self.lib
        with self._quiet():
            f = lib.H5Fcreate(b"cosserat-fem-image.h5", 2, 0, self.fapl)  # H5F_ACC_TRUNC
            if f < 0:
                raise RuntimeError("HDF5: cannot make an in-memory file")
            try:
                offsets = [self._dataset(f, name, values) for name, values in datasets]
                size = lib.H5Fget_file_image(f, None, 0) if lib.H5Fflush(f, 0) >= 0 else -1
                image = ctypes.create_string_buffer(max(size, 0))
                if size <= 0 or lib.H5Fget_file_image(f, image, size) != size:
                    raise RuntimeError("HDF5: cannot take the in-memory file's image")
            finally:
                lib.H5Fclose(f)
        return image, offsets

    def _dataset(self, f: int, name: str, values: np.ndarray) -> int:
        """Make and write a dataset in the open file f; where its values begin in the file."""
        lib = self.lib
        dims = (ctypes.c_uint64 * values.ndim)(*values.shape)
        stored, memory = self.float64 if values.dtype == np.float64 else self.int64
        if values.dtype not in (np.float64, np.int64) or not values.flags.c_contiguous:
            raise TypeError(f"HDF5 dataset {name}: C-ordered float64 or int64 values only")
        space = lib.H5Screate_simple(values.ndim, dims, None)
        dataset = lib.H5Dcreate2(f, name.encode(), stored, space, self.lcpl, self.dcpl, 0)
        lib.H5Sclose(space)
        if dataset < 0:
            raise RuntimeError(f"HDF5: cannot make the dataset {name}")
        try:
            if lib.H5Dwrite(dataset, memory, 0, 0, 0, values.ctypes.data) < 0:
                raise RuntimeError(f"HDF5: cannot write the dataset {name}")
            return lib.H5Dget_offset(dataset)
        finally:
            lib.H5Dclose(dataset)

    def read(self, path: Path, name: str) -> np.ndarray:
        """The dataset ``name`` of the HDF5 file ``path`` as float64; RuntimeError if it cannot
        be read."""
        lib = self.lib
        with self._quiet():
            f = lib.H5Fopen(str(path).encode(), 0, 0)  # H5F_ACC_RDONLY
            if f < 0:
                raise RuntimeError(f"HDF5: cannot open {str(path)!r}")
            try:
                dataset = lib.H5Dopen2(f, name.encode(), 0)
                if dataset < 0:
                    raise RuntimeError(f"HDF5: no dataset {name} in {str(path)!r}")
                try:
                    space = lib.H5Dget_space(dataset)
                    ndims = lib.H5Sget_simple_extent_ndims(space)
                    dims = (ctypes.c_uint64 * max(ndims, 1))()
                    lib.H5Sget_simple_extent_dims(space, dims, None)
                    lib.H5Sclose(space)
                    values = np.empty(tuple(dims[: max(ndims, 0)]), dtype=np.float64)
                    if ndims < 0 or lib.H5Dread(dataset, self.float64[1], 0, 0, 0,
                                                values.ctypes.data) < 0:  # fmt: skip
                        raise RuntimeError(f"HDF5: cannot read {name} of {str(path)!r}")
                finally:
                    lib.H5Dclose(dataset)
            finally:
                lib.H5Fclose(f)
        return values


class _FrameImages:
    """The bytes of the frame files of a series: the datasets ``/Function/<array>/<key>``,
    each (points, 3), made by HDF5 (:class:`_Hdf5`) for the first key of each length and then
    by copying an image of that length with the key and the values put in their places (about
    0.01 instead of 0.2 ms). The copy is used only if, for that first frame, it gives the very
    bytes HDF5 made (superblock 0 and the object formats of HDF5 1.8 carry no checksums, and
    time stamps are off, so the bytes depend on the names and values alone); otherwise HDF5
    makes every frame's file."""

    def __init__(self, h5: _Hdf5, arrays: list[str]):
        self.h5, self.arrays = h5, arrays
        self._templates: dict[int, tuple[bytes, list[int], list[int]] | None] = {}

    def _datasets(self, key: str, values: np.ndarray) -> list[tuple[str, np.ndarray]]:
        return [
            (f"/Function/{name}/{key}", np.ascontiguousarray(values[:, 3 * i : 3 * i + 3]))
            for i, name in enumerate(self.arrays)
        ]

    def __call__(self, key: str, values: np.ndarray):
        """The bytes (bytes-like) of the file of ``values`` (points, 3 per array) at ``key``."""
        if len(key) not in self._templates:
            image = self.h5.image(self._datasets(key, values))[0]
            self._templates[len(key)] = self._template(key, values, bytes(image))
            return image
        template = self._templates[len(key)]
        if template is None:
            return self.h5.image(self._datasets(key, values))[0]
        return self._copy(template, key, values)

    def _copy(self, template, key: str, values: np.ndarray) -> bytearray:
        base, keys, data = template
        image = bytearray(base)
        name = key.encode()
        for at in keys:
            image[at : at + len(name)] = name
        n = len(values)
        for i, at in enumerate(data):
            into = np.frombuffer(image, dtype="<f8", count=3 * n, offset=at).reshape(n, 3)
            into[:] = values[:, 3 * i : 3 * i + 3]
        return image

    def _template(self, key: str, values: np.ndarray, made: bytes):
        """(image, where the key is, where the values are) for keys of len(key), from images
        of the keys "aa..." and "bb..." (the key: the bytes where they differ); None unless
        the copy for ``key`` and ``values`` is ``made``, HDF5's image of them."""
        length, zero = len(key), np.zeros_like(values)
        a, data = self.h5.image(self._datasets("a" * length, zero))
        b = bytes(self.h5.image(self._datasets("b" * length, zero))[0])
        a = bytes(a)
        if not len(a) == len(b) == len(made):
            return None
        differ = np.flatnonzero(np.frombuffer(a, np.uint8) != np.frombuffer(b, np.uint8))
        keys = [int(at) for at in differ[::length]] if differ.size else []
        if len(differ) != length * len(self.arrays) or any(
            a[at : at + length] != b"a" * length for at in keys
        ):
            return None
        template = (a, keys, [int(at) for at in data])
        return template if self._copy(template, key, values) == made else None


def _time_text(t: float) -> str:
    """A frame's time as the XML gives it (as DOLFINx's XDMFFile did: 17 significant digits);
    with "_" for "." it names the frame's datasets."""
    return f"{t:.17g}"


def _free_bytes(folder: Path) -> int:
    """The bytes free (to this user) in the file system of ``folder``."""
    info = os.statvfs(folder)
    return info.f_bavail * info.f_frsize


def _blocks(size: int) -> int:
    """``size`` bytes rounded up to whole blocks of 4 KiB (what a file of that size takes)."""
    return -(-size // 4096) * 4096


#: ``data`` (bytes-like) into a new file ``path`` (whatever had the name is replaced: never
#: written through a link; cosserat_fem/safe_files.py).
_write_file = safe_files.write_new


class XdmfWriter:
    """XDMF/HDF5 time series of the rod as a curve in 3D, for ParaView.

    The mesh is the reference centreline in physical coordinates: the straight rod along e3,
    points (0, 0, s) [m], s = ℓ σ (the reference axis of forms/kinematics.py, r' = (p1', p2',
    1 + p3')), or the curve r0(s) of the scene's [reference] (cosserat_fem/resolved.py), cells
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
    ================  ==============  ============================================  =======

    v, u, n, m are those of forms/resultants.py (reference state v = (0, 0, 1), u = n = m = 0;
    n(s), m(s) act on [0, s] from (s, ℓ], so at a free end they are the applied end load). A
    cell of degree k is drawn as k equal segments (one point per Lagrange node); at a vertex
    the strains and resultants, which jump between cells, take the mean of the two cells'.
    One temporal collection ``rod`` whose frames each carry the mesh, the time and all the
    arrays in double precision, so that ParaView shows one dataset. The points are numbered
    along the rod (σ from 0 to 1); under MPI rank 0 gathers the values and writes every file,
    for the same state the very files of a serial run.

    Files: the XML ``<name>.xdmf`` and the folder ``<name>.frames/`` of HDF5 files: the mesh
    in ``mesh.h5`` (``/Mesh/mesh/geometry``, ``/Mesh/mesh/topology``), frame i (from 0,
    restarts included) in ``<i, 6 digits>.h5`` (``/Function/<array>/<t>``, t as in the XML's
    Time with "_" for "."), e.g. ``solution.frames/000012.h5``; the XML names them relative
    to its own folder. After ``</Xdmf>`` the XML ends with a processing instruction
    ``<?cosserat-fem-spare ...?>`` of blanks: room for the frames to come.

    Kill-safe: after a kill at any moment (SIGKILL included), ``<name>.xdmf`` is well-formed
    and names exactly the frames written before, each in a complete HDF5 file that is never
    opened for writing again (the file of a frame killed in flight, which it does not name, is
    replaced by the next write of that frame or deleted by a restart). A frame is (1) written
    into a new HDF5 file (its bytes made in memory, :class:`_Hdf5`) and (2) added to the XML
    in place: the frame and new closing tags are written into the spare room, still inside
    the processing instruction (the document is unchanged), then one write of blanks, which
    lies within one memory page (Linux does not split such a write on a kill), turns the old
    closing tags and the instruction's opening into whitespace. When the room is used up, the
    XML is written anew, with room as large as the file was (16 KiB to 4 MiB; less under a
    file size limit), under a working name and renamed onto ``<name>.xdmf``. A frame is
    written only if its file and the XML fit in the file system and under ``ulimit -f``, else
    an OutputError (the frames before kept). Why this layout and what it costs:
    docs/decisions.md, "XDMF frames".
    """

    #: The least and the most spare room [bytes] after ``</Xdmf>`` when the XML is rewritten.
    SPARE = (16 << 10, 4 << 20)

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
        them, later frame files deleted: cosserat_fem/checkpoint.py), in its mesh's order of
        the points; the new frames go into new frame files from index ``frames`` on.
        Otherwise the XML and the frames folder of an earlier series are removed first.
        ``run_id``: the identity of the run, written into the XML (checked by a restart,
        cosserat_fem/checkpoint.py)."""
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
        self._expr = None
        self._compile()
        self.path = Path(path)
        suffix = self.path.suffix or ".xdmf"
        # A rewritten XML is written under this name, then renamed onto self.path.
        self._work = self.path.with_name(self.path.stem + suffix + "-partial")
        self.folder = frames_folder(self.path)
        self._doc: _XdmfDocument | None = None  # rank 0 only
        self._h5: _Hdf5 | None = None  # rank 0 only
        self._images: _FrameImages | None = None  # rank 0 only
        self._to_file: np.ndarray | None = None  # a resumed file's order of the points
        self._free = (0, -math.inf)  # free bytes of the file system, and until when to trust
        self.writes = 0 if resume is None else resume[1]
        problem = None
        if self._comm.rank == 0:
            try:
                self._h5 = _Hdf5()
                self._images = _FrameImages(self._h5, self.arrays)
                if resume is not None:
                    self._resume()
                else:
                    self._start(run_id)
            except OutputError as exc:
                problem = exc
            except (OSError, RuntimeError, ValueError, ET.ParseError) as exc:
                problem = OutputError(
                    f"output: cannot write the XDMF file {str(self.path)!r} "
                    f"({getattr(exc, 'strerror', None) or exc})"
                )
        agree(self._comm, problem)

    @property
    def h5(self) -> Path:
        """The HDF5 file the next frame goes into."""
        return self.folder / frame_file(self.writes)

    def _start(self, run_id: str | None) -> None:
        """A new series (rank 0): the XML and the frames of an earlier one removed (the XML
        first; in the frames folder only the files it writes, :data:`FRAME_NAME`: a user's
        files or folders there stay), ``mesh.h5`` written, the XML without frames published."""
        safe_files.remove_name(self.path)
        safe_files.remove_own_files(self.folder, FRAME_NAME)
        self.folder.mkdir(exist_ok=True)
        self._doc = _XdmfDocument(self.path, self._work, self._write_mesh(), run_id)
        self._rewrite(None, "the XDMF file")

    def _write_mesh(self) -> str:
        """``mesh.h5`` written (rank 0; OutputError if it may not fit); the Topology and
        Geometry that name it."""
        line = self.line
        image = self._h5.image(
            [("/Mesh/mesh/geometry", line.geometry), ("/Mesh/mesh/topology", line.topology)]
        )[0]
        self._check_room(len(image), 0, "the XDMF mesh", self.folder / MESH_FILE)
        _write_file(self.folder / MESH_FILE, image)
        return xdmf_mesh_xml(self.folder.name + "/" + MESH_FILE, len(line.geometry),
                         len(line.topology))  # fmt: skip

    def _resume(self) -> None:
        """Continue the published XML (rank 0): its frames and mesh kept, the values of the
        new frames put in the order of that mesh's points; the XML published anew (the same
        document, with spare room)."""
        text = safe_files.read_text(self.path)
        self._doc = _XdmfDocument.parse(self.path, self._work, text)
        self.folder.mkdir(exist_ok=True)  # outputs of the single-file layout
        if self._doc.mesh is None:  # no frame yet: the mesh as a new series writes it
            self._doc.mesh = self._write_mesh()
        else:
            self._to_file = self._file_order()
        self._rewrite(None, "the XDMF file")

    def _file_order(self) -> np.ndarray | None:
        """The output point (numbered in the order of σ) at each point of the resumed file's
        mesh (None if they are the same): earlier writers numbered the points as DOLFINx's
        output mesh did (under MPI not in the order of σ)."""
        item = ET.fromstring(f"<m>{self._doc.mesh}</m>").find("Geometry/DataItem")
        name, _, dataset = (item.text or "").strip().partition(":")
        os.close(safe_files.open_regular(self.path.parent / name))  # HDF5 would wait on a FIFO
        x = self._h5.read(self.path.parent / name, dataset)
        mine = self.line.geometry
        if x.shape == mine.shape:
            if np.array_equal(x, mine):
                return None
            order = np.argsort(x[:, 2], kind="stable")  # the file's points in the order of σ
            if np.allclose(x[order], mine, rtol=0.0, atol=1e-12 * max(mine[-1, 2], 1.0)):
                at = np.empty_like(order)
                at[order] = np.arange(len(order))
                return at
        raise OutputError(
            f"output: cannot continue {str(self.path)!r}: its mesh ({name}) is not this "
            "rod's output mesh"
        )

    def _check_room(self, file_bytes: int, xml_bytes: int, what: str, where: Path) -> None:
        """OutputError unless a new file of ``file_bytes`` and an XML of ``xml_bytes`` (0: not
        rewritten) fit under ``ulimit -f`` and in the file system (the limits are kept for
        :meth:`_rewrite`)."""
        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        limit = math.inf if limit == resource.RLIM_INFINITY else limit
        need = _blocks(file_bytes) + _blocks(xml_bytes) + (64 << 10)
        now = time.monotonic()
        # The free space is asked for again after a second, or when less than 1 GiB more than
        # needed is left; in between it is counted down (statvfs cost ~10-30 us a frame).
        if now > self._free[1] or self._free[0] < need + (1 << 30):
            self._free = (_free_bytes(self.folder), now + 1.0)
        free = self._free[0]
        self._limits = (limit, free)
        problem = None
        if max(file_bytes, xml_bytes) > limit:
            problem = f"the file size limit (ulimit -f) of {limit} bytes would be reached"
        elif need > free:
            problem = f"no space left on the device ({free} bytes free)"
        if problem:
            raise OutputError(
                f"output: {what} was not written to {str(where)!r}: {problem}; the frames "
                "before are kept"
            )
        self._free = (free - need + (64 << 10), self._free[1])

    def _rewrite(self, frame: bytes | None, what: str, written: int = 0) -> None:
        """The XML published anew with ``frame`` added (rank 0), with spare room (class
        docstring) as far as the limits allow; ``written``: bytes written since the limits
        were taken."""
        size = self._doc.rewrite_size(frame)
        if frame is None:
            self._check_room(0, size, what, self.path)
        limit, free = self._limits
        free -= _blocks(written) + _blocks(size) + (64 << 10)
        low, high = self.SPARE
        spare = min(max(size, low), high, limit - size, free)
        self._doc.rewrite(frame, int(max(spare, 0)))

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
            self._expr.eval(self.line.cells, self._values)
            values = self.line.point_values(self._values)
            problem = None
            if self._comm.rank == 0:
                try:
                    self._write_frame(t, values)
                except OutputError as exc:
                    problem = exc
                except (OSError, RuntimeError) as exc:
                    problem = OutputError(
                        f"output: cannot write the XDMF frame at t = {t:.6g} to "
                        f"{str(self.folder)!r} ({getattr(exc, 'strerror', None) or exc}); the "
                        "frames before are kept"
                    )
            agree(self._comm, problem)
        self.writes += 1

    def _write_frame(self, t: float, values: np.ndarray) -> None:
        """Rank 0: the frame's HDF5 file, then the frame added to the XML (class docstring)."""
        if self._to_file is not None:
            values = values[self._to_file]
        value = _time_text(t)
        key = value.replace(".", "_")
        image = self._images(key, values)
        h5 = self.h5
        frame = self._doc.frame(value, f"{self.folder.name}/{h5.name}", key, self.arrays,
                                len(values))  # fmt: skip
        rewrite = not self._doc.fits(frame)
        what = f"the XDMF frame at t = {t:.6g}"
        self._check_room(len(image), self._doc.rewrite_size(frame) if rewrite else 0, what, h5)
        _write_file(h5, image)
        if rewrite:
            self._rewrite(frame, what, len(image))
        else:
            self._doc.append(frame)

    def close(self) -> None:
        """Close the XML (rank 0); the files are complete after every frame."""
        if self._doc is not None:
            self._doc.close()


_XDMF_HEAD = (
    '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
    '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
)
#: The one temporal collection of the published XML (and the name of each of its frames).
XDMF_GRID = "rod"
#: The name of the Information element of the Domain that holds the run's identity.
RUN_ID = "run_id"
#: The end of the document, and the opening of the processing instruction of spare room after
#: it (closed by ``?>`` at the end of the file): the blanks a frame is added with replace them.
_XDMF_TAIL = b"    </Grid>\n  </Domain>\n</Xdmf>\n"
_SPARE_OPEN = b"<?cosserat-fem-spare"
_SPARE_CLOSE = b"?>\n"
_SWITCH = len(_XDMF_TAIL) + len(_SPARE_OPEN)
_PAGE = max(mmap.PAGESIZE, 4096)


def _pad(offset: int) -> int:
    """Blanks to put at ``offset`` so that the _SWITCH bytes after them lie in one page."""
    within = offset % _PAGE
    return 0 if within + _SWITCH <= _PAGE else _PAGE - within


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
    """The published XDMF XML, held by rank 0, and its file: one temporal collection ``rod``
    whose frames each hold the mesh (Topology, Geometry), the Time and every array of that
    time, so that ParaView shows one dataset carrying all the arrays (DOLFINx writes one
    collection per function, which ParaView shows as separate blocks: "Warp By Vector" with
    ``displacement`` would then move only the displacement block). How a frame is added
    (:meth:`append`, :meth:`rewrite`): :class:`XdmfWriter`."""

    def __init__(self, path: Path, work: Path, mesh: str | None, run_id: str | None,
                 frames: list[bytes] | None = None):  # fmt: skip
        """``mesh``: the Topology and Geometry of every frame; ``work``: the working name of a
        rewrite; ``frames``: those of a published file."""
        self.path, self.work = path, work
        self.mesh, self.run_id = mesh, run_id
        self.frames: list[bytes] = frames or []
        self._frame_bytes = sum(map(len, self.frames))
        self._fd: int | None = None  # the published file, open for the appends
        self._tail = self._end = 0  # where its closing tags and its "?>" begin

    @classmethod
    def parse(cls, path: Path, work: Path, xml: str) -> _XdmfDocument:
        """The document of a published file (of any earlier writer): its run's identity, its
        frames, and the mesh of the first (else of the grid "mesh", else none)."""
        root = ET.fromstring(xml)
        domain = root.find("Domain")
        collection = domain.find(f"Grid[@Name='{XDMF_GRID}']")
        grids = [] if collection is None else collection.findall("Grid")
        mesh = grids[0] if grids else domain.find("Grid[@Name='mesh']")
        parts = [] if mesh is None else [mesh.find("Topology"), mesh.find("Geometry")]
        text = "".join(_element_text(e, 4) for e in parts if e is not None) or None
        frames = [_element_text(g, 3).encode() for g in grids]
        return cls(path, work, text, xdmf_run_id(root), frames)

    def frame(self, value: str, file: str, key: str, arrays: list[str], points: int) -> bytes:
        """The text of a frame at the time ``value`` whose ``arrays`` are the datasets
        ``/Function/<array>/<key>`` of the HDF5 file ``file`` (relative to the XML)."""
        parts = [f'      <Grid Name="{XDMF_GRID}" GridType="Uniform">\n', self.mesh,
                 f"        <Time Value={quoteattr(value)} />\n"]  # fmt: skip
        where = escape(file)
        for name in arrays:
            parts.append(
                f'        <Attribute Name="{name}" AttributeType="Vector" Center="Node">\n'
                f'          <DataItem Dimensions="{points} 3" Format="HDF" Precision="8">'
                f"{where}:/Function/{name}/{escape(key)}</DataItem>\n"
                "        </Attribute>\n"
            )
        parts.append("      </Grid>\n")
        return "".join(parts).encode()

    def _head(self) -> bytes:
        identity = ""
        if self.run_id is not None:
            value = quoteattr(self.run_id)
            identity = f"    <Information Name={quoteattr(RUN_ID)} Value={value} />\n"
        return (
            f"{_XDMF_HEAD}  <Domain>\n{identity}"
            f'    <Grid Name="{XDMF_GRID}" GridType="Collection" CollectionType="Temporal">\n'
        ).encode()

    def rewrite_size(self, frame: bytes | None) -> int:
        """The bytes of a rewrite with ``frame`` added, without spare room (at most)."""
        extra = 0 if frame is None else len(frame)
        head = len(self._head()) + self._frame_bytes + extra
        return head + _SWITCH + _SWITCH + len(_SPARE_CLOSE)

    def rewrite(self, frame: bytes | None, spare: int) -> None:
        """Publish the document, with ``frame`` added, and ``spare`` blanks of room after it:
        written under the working name, then renamed onto the published file (atomic)."""
        frames = self.frames if frame is None else [*self.frames, frame]
        text = self._head() + b"".join(frames)
        text += b" " * _pad(len(text))
        data = b"".join([text, _XDMF_TAIL, _SPARE_OPEN, b" " * spare, _SPARE_CLOSE])
        self.work.unlink(missing_ok=True)  # a new file (truncating one costs a discard)
        fd = safe_files.create(self.work)
        try:
            safe_files.write_all(fd, data, 0)
            os.replace(self.work, self.path)
        except BaseException:
            os.close(fd)
            self.work.unlink(missing_ok=True)
            raise
        self.close()
        self._fd, self._tail, self._end = fd, len(text), len(data) - len(_SPARE_CLOSE)
        if frame is not None:
            self.frames.append(frame)
            self._frame_bytes += len(frame)

    def _new_tail(self, frame: bytes) -> int:
        """Where the closing tags begin once ``frame`` is appended."""
        tail = self._tail + _SWITCH + 1 + len(frame)
        return tail + _pad(tail)

    def fits(self, frame: bytes) -> bool:
        """Whether ``frame`` can be appended in the spare room."""
        return self._fd is not None and self._new_tail(frame) + _SWITCH <= self._end

    def append(self, frame: bytes) -> None:
        """Add ``frame`` in place (it :meth:`fits`): (1) the frame, blanks, the closing tags
        and the opening of the spare's processing instruction written into the spare, which
        lies inside that instruction (the document is unchanged, whatever part of this is
        written); (2) the old closing tags and opening, in one page, made blanks."""
        start = self._tail + _SWITCH
        tail = self._new_tail(frame)
        staged = b"".join(
            [b" ", frame, b" " * (tail - start - 1 - len(frame)), _XDMF_TAIL, _SPARE_OPEN]
        )
        safe_files.write_all(self._fd, staged, start)
        safe_files.write_all(self._fd, b" " * _SWITCH, self._tail)
        self._tail = tail
        self.frames.append(frame)
        self._frame_bytes += len(frame)

    def close(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)


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
            local[self._mine, 3:6] = self.angles(
                local[self._mine, 3:6],
                lambda: self.angles.model.chart.eval(self._points, self._cells).reshape(
                    len(self._mine), 4),
                lambda: self._points[:, 0],
            )
        total = np.zeros_like(local) if self.comm.rank == 0 else None
        self.comm.Reduce(local, total, op=MPI.SUM, root=0)
        return total
