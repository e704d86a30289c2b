"""Run outputs: free-end probes (CSV), an XDMF time series for ParaView, ``summary.json``.

Quantities are written in SI units: positions in m (x = ℓ p1, ...), angles in rad, time in
s. The probe row is written by the one rank that owns the probe point, so a step costs no
communication; rows are handed to the operating system every ``flush_every`` rows and at the
end, so a run that stops early, or is killed, keeps what it computed up to the last flush
(``fsync`` only at the end: what is flushed to the page cache survives a killed process).
"""

from __future__ import annotations

import json
import os
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


class ProbeWriter:
    """``probes.csv`` with the header t,x,y,z,theta,psi,phi, written by the probe's owner."""

    def __init__(self, path: Path, probe: PointProbe, flush_every: int = 200):
        self.probe = probe
        self.flush_every = flush_every
        self._pending = 0
        self._rows = np.empty((flush_every, len(PROBE_HEADER)))
        self._file = None
        if probe.is_owner:
            self._file = open(path, "w", encoding="utf-8")  # noqa: SIM115 - closed in close()
            self._file.write(",".join(PROBE_HEADER) + "\n")
            self._file.flush()

    def write(self, t: float) -> None:
        """Buffer the row of time t; every ``flush_every`` rows go to the file."""
        if self._file is None:
            return
        row = self._rows[self._pending]
        row[0] = t
        row[1:] = self.probe.values()
        self._pending += 1
        if self._pending >= self.flush_every:
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

    def close(self) -> None:
        if self._file is not None:
            self.flush(sync=True)
            self._file.close()
            self._file = None


class XdmfWriter:
    """XDMF/HDF5 time series: ``displacement`` (x, y, z) [m] and ``angles`` (θ, ψ, φ) [rad].

    Fields are interpolated into P1 (XDMF keeps vertex values only). The mesh coordinate is
    σ = s/ℓ along the first axis.
    """

    def __init__(self, path: Path, U: fem.Function, length: float, jit_params: dict | None = None):
        """``U`` holds (p1, ..., p6) in its first six components; ``write`` may be given another
        Function of the same space (e.g. one mode shape after another)."""
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
        self.file = io.XDMFFile(msh.comm, str(path), "w")
        self.file.write_mesh(msh)
        self.writes = 0

    def write(self, t: float, U: fem.Function | None = None) -> None:
        if U is not None and U is not self.U:
            self.U.x.array[:] = U.x.array
        self.displacement.interpolate(self._disp_expr)
        self.angles.interpolate(self._ang_expr)
        self.file.write_function(self.displacement, t)
        self.file.write_function(self.angles, t)
        self.writes += 1

    def close(self) -> None:
        self.file.close()


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
