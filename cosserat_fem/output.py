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

import json
import os
import shutil
import time
import weakref
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem, geometry, io
from mpi4py import MPI

PROBE_HEADER = ("t", "x", "y", "z", "theta", "psi", "phi")
_ROW_FORMAT = "%.10e," + ",".join(["%.16e"] * (len(PROBE_HEADER) - 1)) + "\n"


class PointProbe:
    """Evaluates (x, y, z, θ, ψ, φ) in SI units at σ = ``sigma`` on its owning rank."""

    def __init__(self, U: fem.Function, sigma: float, length: float):
        msh = U.function_space.mesh
        self.U = U
        self.length = length
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
        self._scale = np.array([length, length, length, 1.0, 1.0, 1.0])
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
        """(x, y, z, θ, ψ, φ) on the owning rank, None elsewhere."""
        if self.cell is None:
            return None
        if self._node is not None:
            bs = self.U.function_space.dofmap.index_map_bs
            return self.U.x.array[bs * self._node : bs * self._node + 6] * self._scale
        u = self.U.eval(self.point, np.array([self.cell], dtype=np.int32))
        return u[:6] * self._scale


# The open probe writers of this process: XdmfWriter.write flushes them before each frame.
_PROBE_WRITERS: weakref.WeakSet[ProbeWriter] = weakref.WeakSet()


class ProbeWriter:
    """``probes.csv`` with the header t,x,y,z,theta,psi,phi, written by the probe's owner.

    Rows are buffered and handed to the operating system when ``flush_every`` rows are
    pending, when ``max_delay`` seconds (wall time) have passed since the last flush, and
    before every XDMF frame (:meth:`XdmfWriter.write` flushes every open ProbeWriter of its
    process). So a killed run loses at most the rows since the last XDMF frame (7 rows at
    the default scene's 8 steps a frame) or of the last ``max_delay`` s, and probes.csv
    always reaches the last frame of the XDMF file. Measured per row, default scene: the
    same ~12 us a row (full run) as flushing every 200 rows only; flushing every row cost
    ~23 us a row more on a busy ext4 file system (a write() can wait ~3 ms for a journal
    commit of another process), 3-5 % of a ~0.5 ms step.
    """

    def __init__(
        self,
        path: Path,
        probe: PointProbe,
        flush_every: int = 200,
        max_delay: float = 0.05,
        append: bool = False,
    ):
        """``append``: continue an existing file (a restart, which has cut it back)."""
        self.probe = probe
        self.flush_every = flush_every
        self.max_delay = max_delay
        self._pending = 0
        self._rows = np.empty((flush_every, len(PROBE_HEADER)))
        self._file = None
        self._deadline = 0.0
        if probe.is_owner:
            mode = "a" if append else "w"
            self._file = open(path, mode, encoding="utf-8")  # noqa: SIM115 - closed in close()
            if not append:
                self._file.write(",".join(PROBE_HEADER) + "\n")
            self.flush()
            _PROBE_WRITERS.add(self)

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
        if self._file is not None:
            if self._pending:
                # One formatting call for the whole block (about 10x cheaper than per value).
                block = tuple(self._rows[: self._pending].ravel())
                self._file.write((_ROW_FORMAT * self._pending) % block)
            self._file.flush()
            if sync:
                os.fsync(self._file.fileno())
            self._pending = 0
            self._deadline = time.monotonic() + self.max_delay

    def close(self) -> None:
        if self._file is not None:
            self.flush(sync=True)
            self._file.close()
            self._file = None
            _PROBE_WRITERS.discard(self)


class XdmfWriter:
    """XDMF/HDF5 time series: ``displacement`` (x, y, z) [m] and ``angles`` (θ, ψ, φ) [rad].

    Fields are interpolated into P1 (XDMF keeps vertex values only). The mesh coordinate is
    σ = s/ℓ along the first axis.

    Kill-safe: a killed run (SIGKILL included) leaves ``<name>.xdmf`` listing exactly the
    frames written so far and ``<name>.h5`` holding them, readable by ParaView. An HDF5 file
    that is open for writing is not consistent on disk (DOLFINx 0.5.2 keeps it open until
    ``close()`` and has no flush: a killed run left an .h5 that did not open at all), and
    DOLFINx rewrites the whole XML file in place for every function written (a kill during
    that rewrite left an empty .xdmf, 14 kills in 60). So each frame:

    1. reopens the file in append mode ("a") under a working name ``<name>.xdmf-partial``
       (a hard link to the published XML, unlinked as soon as DOLFINx has read it, so that
       DOLFINx's rewrites go to a new file and never touch the published one; the same stem
       keeps the HDF5 file ``<name>.h5`` and the references in the XML unchanged),
    2. writes both functions and closes the file (HDF5 metadata and superblock on disk),
    3. publishes the XML by an atomic rename onto ``<name>.xdmf``.

    While a frame is being written the .h5 on disk is the closed file of the previous frame
    plus new, not yet referenced blocks at its end; the only window in which a kill can
    damage it is HDF5's own close (~0.1 ms a frame, in which metadata is written). A
    ``<name>.xdmf-partial`` left by a kill is a scratch file: ignore or delete it.

    Cost, default scene (8 cubic elements, 251 frames, serial, ext4; median of 7 runs): 1.54
    instead of 1.43 ms a frame, +0.11 ms or 3 % of the ~4 ms of solving between frames
    (reopen, link, rename ~0.6 ms, mostly repaid because DOLFINx's first XML rewrite of a
    frame now creates a new file instead of truncating one that is being written back; with
    a busy disk the old writer waited for that writeback twice a frame and this one was the
    faster, 3.9 against 7.8 ms). The .h5 grows by ~1.4 kB a frame of metadata that a reopened
    file does not reuse (656 kB instead of 314 kB). The XML loses its ``<!DOCTYPE>`` line on
    the first reopen (pugixml drops it when reading); ParaView does not need it.
    """

    def __init__(
        self,
        path: Path,
        U: fem.Function,
        length: float,
        jit_params: dict | None = None,
        resume: tuple[int, int] | None = None,
    ):
        """``U`` holds (p1, ..., p6) in its first six components; ``write`` may be given another
        Function of the same space (e.g. one mode shape after another). ``resume = (n,
        frames)``: continue the existing file, which holds ``frames`` frames, as restart n;
        its new frames go into ``<stem>-restart<n>.h5``."""
        msh = U.function_space.mesh
        self.U = U
        P1 = fem.VectorFunctionSpace(msh, ("Lagrange", 1), dim=3)
        self.displacement = fem.Function(P1, name="displacement")
        self.angles = fem.Function(P1, name="angles")
        pts = P1.element.interpolation_points()
        jp = jit_params or {}
        self._disp_expr = fem.Expression(
            ufl.as_vector([length * U[0], length * U[1], length * U[2]]), pts, jit_params=jp
        )
        self._ang_expr = fem.Expression(ufl.as_vector([U[3], U[4], U[5]]), pts, jit_params=jp)
        self.path = Path(path)
        # Same stem, other extension: DOLFINx derives the HDF5 name "<stem>.h5" from it.
        suffix = self.path.suffix or ".xdmf"
        self._work = self.path.with_suffix(suffix + "-partial")
        self._comm = msh.comm
        self.file: io.XDMFFile | None = None
        if resume is not None:
            restart, self.writes = resume
            stem = f"{self.path.stem}-restart{restart}"
            self._work = self.path.with_name(stem + suffix + "-partial")
            return
        self.file = io.XDMFFile(self._comm, str(self._work), "w")
        try:
            self.file.write_mesh(msh)
        finally:
            self._close_file()
        self._publish()
        self.writes = 0

    def write(self, t: float, U: fem.Function | None = None) -> None:
        if U is not None and U is not self.U:
            self.U.x.array[:] = U.x.array
        for probes in list(_PROBE_WRITERS):  # probes.csv reaches every frame on disk
            probes.flush()
        self.displacement.interpolate(self._disp_expr)
        self.angles.interpolate(self._ang_expr)
        self._reopen()
        try:
            self.file.write_function(self.displacement, t)
            self.file.write_function(self.angles, t)
        finally:
            self._close_file()
        self._publish()
        self.writes += 1

    def close(self) -> None:
        """Nothing stays open between frames; kept for the writer interface."""
        self._close_file()

    def _reopen(self) -> None:
        """Open the file in append mode under the working name, which is then unlinked."""
        comm = self._comm
        if comm.rank == 0:
            self._work.unlink(missing_ok=True)  # a frame that raised left it
            try:
                os.link(self.path, self._work)
            except OSError:  # no hard links on this file system
                shutil.copyfile(self.path, self._work)
        if comm.size > 1:
            comm.barrier()  # every rank reads the XML in the constructor
        self.file = io.XDMFFile(comm, str(self._work), "a")
        if comm.size > 1:
            comm.barrier()
        if comm.rank == 0:
            self._work.unlink()

    def _close_file(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None

    def _publish(self) -> None:
        # Rank 0 alone writes the XML (in write_function/write_mesh) and renames it, once
        # every rank has returned from closing the HDF5 file: parallel HDF5 spreads the
        # metadata writes over the ranks, and rank 0 may leave H5Fclose before rank 1 has
        # written its share (a kill then left an XML naming a dataset the .h5 did not hold).
        if self._comm.size > 1:
            self._comm.barrier()
        if self._comm.rank == 0:
            os.replace(self._work, self.path)


def write_json(path: Path, data: dict, comm: MPI.Comm) -> None:
    if comm.rank == 0:
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n", encoding="utf-8")
        tmp.replace(path)


class LineSampler:
    """Samples (x, y, z, θ, ψ, φ) in SI units at many σ points; results gathered on rank 0."""

    def __init__(self, U: fem.Function, sigmas: np.ndarray, length: float):
        msh = U.function_space.mesh
        self.U = U
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
        self._mine = np.flatnonzero(owner == comm.rank)
        self._points = pts[self._mine]
        self._cells = cells[self._mine]
        self._scale = np.array([length] * 3 + [1.0] * 3)
        self.comm = comm

    def sample(self) -> np.ndarray | None:
        """Array (len(sigmas), 6) on rank 0, None elsewhere."""
        local = np.zeros((len(self.sigmas), 6))
        if len(self._mine):
            local[self._mine] = self.U.eval(self._points, self._cells)[:, :6] * self._scale
        total = np.zeros_like(local) if self.comm.rank == 0 else None
        self.comm.Reduce(local, total, op=MPI.SUM, root=0)
        return total
