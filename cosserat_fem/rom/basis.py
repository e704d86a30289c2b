"""The reduced basis of a rod's unknown vector, from snapshots of runs (issue 28, offline part).

Snapshots u_i = U(t_i) − U_ref, i = 1..T, of the FE coefficient vector U (the model's
12-component field (p, q), or the components of one plane, blocked dofs; the vector the time
loop's Newton solve iterates on) are collected by :class:`SnapshotCollector`, an observer of the
time loop's outputs (cosserat_fem/timestepping/events.py), from one run or several. The
reference U_ref is the rest state (the run's initial state, the same for every run), so the
Dirichlet dofs, zero in every u_i, are zero in every mode and the reduced state
U_ref + V q holds them exactly.

**Inner product.** ⟨u, v⟩_W = uᵀ W v, W = diag(m_j w_c): m_j = ∫ φ_j dσ the lumped (row-sum)
L² mass of dof j's node along σ ∈ [0, 1], and w_c the kinetic weight of its component
(cosserat_fem/analysis/modal.py: ρAℓ² for p1..p3 = x/ℓ, ρc11, ρc22, ρI3 for θ, ψ, φ; the
same for the rates q = ṗ). It is the mass inner product of the linearised rod, lumped: its
norm of q is twice the kinetic energy (per ω0²), so that every component enters in the
units of energy rather than in the mixed units of U (metres over ℓ, radians), and for a free
vibration the POD modes are the normal modes (Feeny & Kappagantu 1998; docs/pod.md's
"kinetic" weighting). Lumped so that W is diagonal: √W scales rows and the POD is one SVD.

**POD.** A = √W [u_1 … u_T] = Φ Σ Ξᵀ (:func:`~cosserat_fem.studies.karhunen_loeve.snapshot_svd`,
the one SVD of both POD's), the modes v_k = W^{-1/2} φ_k, W-orthonormal (Vᵀ W V = I), the
energies λ_k = σ_k² (no 1/T, no mean removed: the reduced state is U_ref + V q, not a mean
plus modes), and the number of modes the fewest whose energy left out,
ε(k) = Σ_{i>k} λ_i / Σ_i λ_i, is at most the tolerance (docs/rom.md eq. (3)).

Under MPI the rows are distributed as U's (each rank its owned dofs); inner products are
summed over the ranks. The file (:func:`write_basis`, :func:`read_basis`): an .npz of the
global arrays (V, U_ref, W's diagonal, the energies) and a .json beside it of their
provenance (the scene's text and hash, the runs, snapshot times, energies, the tolerance) and
of the discretisation the rows belong to; a basis of another mesh or space is refused in one
line (SceneError) naming the file and what differs.

**A basis per chart.** Where the angles' chart may move (3D), the basis made by
:func:`pod_basis` keeps its snapshots and the chart each was recorded in (in memory, not in the
file); :func:`in_chart` maps them into another chart and PODs them again (docs/rom.md §9).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import OutputError, SceneError
from cosserat_fem.common.parallel import agree
from cosserat_fem.rom.indicator import basis_modes, coordinate_ranges, load_values
from cosserat_fem.studies.karhunen_loeve import modes_for_tolerance, snapshot_svd
from cosserat_fem.timestepping.events import Observer

#: The format's name and version in the .json.
FORMAT = "cosserat-fem reduced basis 1"


@dataclass
class Basis:
    """A reduced basis: ``V`` (n_owned, 2k) this rank's rows of the W-orthonormal modes
    (v_j = (φ_j, 0) for p, then v_{k+j} = (0, φ_j) for its rate q: docs/rom.md (4)),
    ``reference`` (n_owned,) U_ref, ``weights`` (n_owned,) W's diagonal, ``energies`` (T,)
    every POD energy λ_i (squares of the singular values), ``space``: the discretisation the
    rows belong to (:func:`space_of`), ``provenance``: what it was trained on (json)."""

    V: np.ndarray
    reference: np.ndarray
    weights: np.ndarray
    energies: np.ndarray
    space: dict
    provenance: dict = field(default_factory=dict)
    #: The residual rows' test weights D (n_owned,): the kinetic weight of each row's component
    #: (the rows are balance laws divided by their inertia, (48); Vᵀ D F is the Galerkin
    #: projection of the symmetric weak form: docs/rom.md (5)). None: D = I.
    tests: np.ndarray | None = None
    #: ECSW's sampled elements (cosserat_fem/rom/hyper.py): this rank's local cell indices,
    #: their weights ξ_e > 0 and their midpoints' σ (the cells' names in the file); None: no
    #: hyper-reduction (a Galerkin run assembles every element).
    sample_cells: np.ndarray | None = None
    sample_weights: np.ndarray | None = None
    sample_sigma: np.ndarray | None = None
    #: The error indicator's modes (cosserat_fem/rom/indicator.py, (10.5)): their λ (N,) and
    #: shapes on this rank's owned rows (n_owned, N; zero on q's rows), and in the provenance's
    #: "error_modes" the rod they belong to; None: solved when a run needs them.
    error_lambda: np.ndarray | None = None
    error_modes: np.ndarray | None = None
    #: The training snapshots u_i = U(t_i) − U_ref (n_owned, T), and the nodal quaternions of
    #: the chart each was recorded in (T entries, each (nodes·4,) or None: the fixed basis), for
    #: a basis per chart (:func:`in_chart`, docs/rom.md §9); None: not kept (a basis file's, or
    #: one trained without a chart: in a plane, where the angles' chart never moves).
    snapshots: np.ndarray | None = None
    snapshot_charts: list | None = None

    @cached_property
    def digest(self) -> str:
        """The SHA-256 of what a run on the basis computes with, this rank's rows: V's and
        U_ref's bytes (float64, C order, with their shapes), the supports the modes hold
        (space["supports"] as canonical JSON) and ECSW's sampled cells and weights if any;
        computed once (the arrays are not changed after the basis is made: truncated and
        hyper.ecsw make new ones). The identity of a basis given in memory, as the file's
        SHA-256 is of a file (runs.basis_identity)."""
        h = hashlib.sha256()
        arrays = [self.V, self.reference, self.sample_cells, self.sample_weights]
        for name, array in zip(("V", "U_ref", "cells", "weights"), arrays, strict=True):
            if array is None:
                continue
            a = np.ascontiguousarray(array, dtype=np.int64 if name == "cells" else np.float64)
            h.update(f"{name}{a.shape}".encode())
            h.update(a.tobytes())
        supports = json.dumps(self.space.get("supports"), sort_keys=True, default=str)
        h.update(b"supports" + supports.encode())
        return h.hexdigest()

    @property
    def sampled(self) -> bool:
        """Whether the basis carries ECSW's elements and weights."""
        return self.sample_cells is not None

    @property
    def modes(self) -> int:
        """k, the configuration modes: V has 2k columns, (φ_j, 0) then (0, φ_j)."""
        return self.V.shape[1] // 2

    def energy_left_out(self, k: int | None = None) -> float:
        """ε(k) = Σ_{i>k} λ_i / Σ_i λ_i (docs/rom.md eq. (3)), k = the basis's modes."""
        k = self.modes if k is None else k
        total = float(self.energies.sum())
        return float(self.energies[k:].sum() / total) if total > 0 else 0.0

    def truncated(self, k: int) -> Basis:
        """The first k modes (their energy left out in the provenance); the sampling of a
        hyper-reduction, fitted for all the modes, is dropped."""
        if not 1 <= k <= self.modes:
            raise SceneError(f"modes: must be in [1, {self.modes}], got {k!r}")
        provenance = {**self.provenance, "modes": k, "energy_left_out": self.energy_left_out(k)}
        provenance.pop("ecsw", None)
        K = self.modes
        V = np.hstack([self.V[:, :k], self.V[:, K : K + k]])
        return self.with_modes(V, self.energies, provenance)

    def with_modes(self, V: np.ndarray, energies: np.ndarray, provenance: dict) -> Basis:
        """This basis with the modes ``V``, the POD's ``energies`` and ``provenance``, the rest
        kept but a hyper-reduction's sampling (fitted to the modes of before)."""
        return replace(
            self,
            V=V,
            energies=energies,
            provenance=provenance,
            sample_cells=None,
            sample_weights=None,
            sample_sigma=None,
        )


def supports_of(scene) -> object:
    """The scene's [supports] as the basis file keeps them (canonical JSON values): what
    space_of compares, and what a run's scene is checked against before it starts."""
    return json.loads(json.dumps(scene.to_dict().get("supports"), sort_keys=True, default=str))


def space_of(model) -> dict:
    """What a basis's rows must match: the scene's elements and degree, the components U
    holds (the layout), the global number of dofs and the supports (the rows every mode holds
    at zero)."""
    return {
        "elements": int(model.msh.topology.index_map(1).size_global),
        "degree": int(model.V.ufl_element().degree()),
        "components": [int(c) for c in model.layout.components],
        "dofs": int(model.global_dofs()),
        "supports": supports_of(model.scene),  # the Dirichlet rows U_ref + V q holds
    }


def owned(model) -> int:
    """How many of U's local values this rank owns (its rows of a basis)."""
    imap = model.V.dofmap.index_map
    return imap.size_local * model.V.dofmap.index_map_bs


def kinetic_rows(model, n: int) -> np.ndarray:
    """The kinetic weight w_c of each of n owned rows' component (p's and its rate's alike)."""
    from cosserat_fem.analysis.modal import _kinetic_weights

    kinetic = _kinetic_weights(model)
    w = np.array([float(kinetic[c % 6]) for c in model.layout.components])
    return np.tile(w, n // len(w))


def mass_weights(model) -> np.ndarray:
    """W's diagonal on this rank's owned dofs (module docstring): the row sums of the L² mass
    along σ times each component's kinetic weight, the same for p and its rate."""
    import ufl
    from dolfinx import fem

    from cosserat_fem.analysis.modal import _kinetic_weights

    kinetic = _kinetic_weights(model)
    w = [float(kinetic[c % 6]) for c in model.layout.components]
    v = ufl.TestFunction(model.V)
    form = fem.form(ufl.inner(ufl.as_vector(w), v) * ufl.dx(domain=model.msh))
    vector = fem.petsc.assemble_vector(form)
    vector.ghostUpdate(addv=_add(), mode=_reverse())
    weights = vector.array.copy()
    vector.destroy()
    return weights


def _add():
    from petsc4py import PETSc

    return PETSc.InsertMode.ADD


def _reverse():
    from petsc4py import PETSc

    return PETSc.ScatterMode.REVERSE


def state_rows(layout, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows of p and of its rate q among n owned rows of U (blocks of the layout's size,
    p's entries first), paired: q's row i is the rate of p's row i (entry c + 6 of c)."""
    comps, count = layout.components, layout.p_count
    if [c + 6 for c in comps[:count]] != list(comps[count:]):
        raise SceneError(f"layout: the rates do not pair with the components of p ({comps})")
    entry = np.arange(n) % layout.size
    return np.flatnonzero(entry < count), np.flatnonzero(entry >= count)


class SnapshotCollector(Observer):
    """Collects U − U_ref (this rank's owned values) and the chart's nodal quaternions (None
    without one) at the output steps k with k % ``every`` == 0 of one run or several (give the
    same collector to each run: :func:`collect`). U_ref is the state when the first run
    started (its ``started`` event). ``runs``: a label per run (for the provenance)."""

    def __init__(self, every: int = 1):
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise SceneError(f"every: must be a whole number >= 1, got {every!r}")
        self.every = every
        self.columns: list[np.ndarray] = []
        self.charts: list[np.ndarray | None] = []  # the chart of each column (None: fixed)
        self.times: list[float] = []
        self.reference: np.ndarray | None = None
        self.model = None
        self.runs = 0

    def started(self, loop) -> None:
        n = owned(loop.model)
        state = loop.model.U.x.array[:n]
        if self.reference is None:
            self.reference, self.model = state.copy(), loop.model
        elif self.reference.shape != state.shape or not np.array_equal(self.reference, state):
            raise SceneError(
                "snapshots: every run of a basis starts from the same rest state (its reference)"
            )
        self.runs += 1

    def output(self, loop, k: int, t: float) -> None:
        if k % self.every == 0:
            assert self.reference is not None, "started comes first"
            n = self.reference.size
            self.columns.append(loop.model.U.x.array[:n] - self.reference)
            chart = loop.model.chart
            self.charts.append(None if chart is None else chart.x.array.copy())
            self.times.append(t)


def pod_basis(model, collector: SnapshotCollector, tolerance: float, provenance: dict) -> Basis:
    """The POD basis of the collected snapshots (module docstring), with the fewest modes whose
    energy left out is at most ``tolerance`` (collective under MPI)."""
    if not (isinstance(tolerance, float | int) and 0.0 <= tolerance < 1.0):
        raise SceneError(f"tolerance: must be a number in [0, 1), got {tolerance!r}")
    if not collector.columns:
        raise SceneError("snapshots: none collected (no output step of the runs)")
    comm = model.msh.comm
    weights = mass_weights(model)
    snapshots = np.column_stack(collector.columns)
    V, energies, k = pod_modes(model.layout, weights, snapshots, comm, tolerance=tolerance)
    assert collector.reference is not None
    tests = kinetic_rows(model, len(weights))
    coordinates = comm.allreduce((weights[:, None] * V).T @ snapshots)
    norms = np.sqrt(comm.allreduce(np.einsum("ij,i,ij->j", snapshots, weights, snapshots)))
    provenance = {
        **provenance,
        "tolerance": float(tolerance),
        "modes": k,
        "energy_left_out": float(energies[k:].sum() / energies.sum()),
        "snapshots": len(collector.columns),
        "snapshot_times_s": [float(t) for t in collector.times],
        "inner_product": "lumped L2 mass along s times the kinetic weights (docs/rom.md)",
        # the training's range of c = Vᵀ W u_i (cosserat_fem/rom/indicator.py)
        "coordinates": coordinate_ranges(coordinates, norms),
    }
    lam, shapes, entry = basis_modes(model, len(weights))  # the indicator's, once a basis
    provenance["error_modes"] = entry
    charted = any(chart is not None for chart in collector.charts)
    return Basis(
        V,
        collector.reference.copy(),
        weights,
        energies,
        space_of(model),
        provenance,
        tests,
        error_lambda=lam,
        error_modes=shapes,
        # kept where a chart may move (a basis per chart, :func:`in_chart`), not in the plane
        snapshots=snapshots if charted else None,
        snapshot_charts=list(collector.charts) if charted else None,
    )


def pod_modes(layout, weights, snapshots, comm, tolerance=None, modes=None):
    """(V, energies, k): the W-orthonormal POD modes of the snapshots' p rows (n_owned, T),
    the fewest k whose energy left out is at most ``tolerance`` (docs/rom.md (3)), or the first
    ``modes``; V (n_owned, 2k) holds them on p's rows, then on its rate's (docs/rom.md (4)),
    each signed with its entry of largest magnitude positive. Collective."""
    p_rows, q_rows = state_rows(layout, len(weights))
    root = np.sqrt(weights[p_rows])
    Phi, sigma, _ = snapshot_svd(snapshots[p_rows] * root[:, None], comm)
    energies = sigma**2
    if not (energies.size and energies[0] > 0.0):
        raise SceneError("snapshots: the state never left its reference: no modes to find")
    k = modes_for_tolerance(energies, tolerance) if modes is None else min(modes, energies.size)
    shapes = np.divide(
        Phi[:, :k], root[:, None], out=np.zeros((len(root), k)), where=root[:, None] > 0
    )
    for j in range(k):  # the sign: each mode's entry of largest magnitude positive
        column = shapes[:, j]
        i = int(np.argmax(np.abs(column))) if column.size else 0
        local = (float(abs(column[i])), float(column[i])) if column.size else (-1.0, 0.0)
        if max(comm.allgather(local))[1] < 0:
            shapes[:, j] *= -1.0
    V = np.zeros((len(weights), 2 * k))
    V[p_rows, :k] = shapes
    V[q_rows, k:] = shapes
    return V, energies, k


def in_chart(basis: Basis, model) -> tuple[Basis, float]:
    """The basis per chart (docs/rom.md §9): the training snapshots, each mapped from the chart
    it was recorded in to the model's chart now (charts.change_chart at the nodes whose
    quaternion differs: the same directors and angular velocity, the angles and their rates
    measured from the new frame), POD'd again to the same k; returns it and the new POD's
    energy left out at k. Serial (the map needs every node of a snapshot). A SolverError
    with the reason where it cannot: a basis without its snapshots (a basis file's)."""
    from cosserat_fem.rod.charts import change_chart
    from cosserat_fem.rom.galerkin import chart_refusal

    if basis.snapshots is None or basis.snapshot_charts is None:
        raise chart_refusal(
            "the basis carries no training snapshots to re-express in the new chart (a basis "
            "file's; a basis per chart needs them: cf.rom.basis.train, or rom build and run in "
            "one process)"
        )
    if model.msh.comm.size > 1:
        raise chart_refusal(
            "a basis per chart is re-made serially only (the chart's map needs every node of "
            "a snapshot)"
        )
    layout = model.layout
    Q_new = model.chart.x.array.reshape(-1, 4)
    identity = np.zeros_like(Q_new)
    identity[:, 0] = 1.0
    pick, T, nodes = list(layout.components), len(basis.snapshot_charts), len(Q_new)
    Q_old = np.stack([identity if Q is None else Q.reshape(-1, 4) for Q in basis.snapshot_charts])
    states = basis.reference[:, None] + basis.snapshots  # (n, T): every node of each (serial)
    full = np.stack([layout.full_array(states[:, i]) for i in range(T)]).reshape(T * nodes, 12)
    Q_to = np.broadcast_to(Q_new, (T, nodes, 4)).reshape(T * nodes, 4)
    Q_from = Q_old.reshape(T * nodes, 4)
    moved = np.any(Q_to != Q_from, axis=1)
    full = full.copy()
    full[moved] = change_chart(full[moved], Q_from[moved], Q_to[moved])
    mapped = full.reshape(T, nodes, 12)[:, :, pick].reshape(T, -1).T - basis.reference[:, None]
    V, energies, k = pod_modes(layout, basis.weights, mapped, model.msh.comm, modes=basis.modes)
    coordinates = (basis.weights[:, None] * V).T @ mapped
    norms = np.sqrt(np.einsum("ij,i,ij->j", mapped, basis.weights, mapped))
    left = float(energies[k:].sum() / energies.sum())
    provenance = {
        **basis.provenance,
        "energy_left_out": left,
        "coordinates": coordinate_ranges(coordinates, norms),
    }
    return basis.with_modes(V, energies, provenance), left


def inner(basis_or_weights, u: np.ndarray, v: np.ndarray, comm) -> np.ndarray:
    """uᵀ W v summed over the ranks (u, v: this rank's owned rows; vectors or matrices)."""
    weights = basis_or_weights.weights if isinstance(basis_or_weights, Basis) else basis_or_weights
    local = np.asarray(u).T @ (weights[:, None] * np.asarray(v).reshape(len(weights), -1))
    return comm.allreduce(local) if comm.size > 1 else local


# --- the file -------------------------------------------------------------------------------


def basis_paths(path: str | Path) -> tuple[Path, Path]:
    """(FILE.npz, FILE.json) of a basis named FILE, FILE.npz or FILE.json: the suffixes
    appended, never replaced (a name with a dot, paper.v1, is its own basis)."""
    path = Path(path)
    stem = path.with_suffix("") if path.suffix in (".npz", ".json") else path
    return Path(f"{stem}.npz"), Path(f"{stem}.json")


def _node_order(model) -> tuple[np.ndarray, np.ndarray]:
    """For each owned row, its place in a numbering of U that does not depend on the ranks:
    (node position σ along the rod, entry of the block), so that a basis written from n ranks
    is read on m (the dof numbering is the partition's)."""
    bs = model.V.dofmap.index_map_bs
    imap = model.V.dofmap.index_map
    sigma = model.V.tabulate_dof_coordinates()[: imap.size_local, 0]
    return np.repeat(sigma, bs), np.tile(np.arange(bs), imap.size_local)


def write_basis(basis: Basis, model, path: str | Path) -> tuple[Path, Path]:
    """The basis as path.npz (V, reference, weights, energies, and where the basis has them
    ECSW's sampling and the error indicator's modes: global arrays in the order of
    the nodes' σ and the block's entries, which no partition decides) and path.json (the
    format, the space, the provenance); written by rank 0 (collective). Returns both paths."""
    comm = model.msh.comm
    sigma, entry = _node_order(model)
    tests = basis.tests if basis.tests is not None else np.ones_like(basis.weights)
    modes = basis.error_modes if basis.error_modes is not None else np.zeros((len(tests), 0))
    parts = comm.gather(
        (sigma, entry, basis.V, basis.reference, basis.weights, tests, modes), root=0
    )
    npz, meta = basis_paths(path)
    problem = None
    if comm.rank == 0:
        assert parts is not None
        s = np.concatenate([p[0] for p in parts])
        e = np.concatenate([p[1] for p in parts])
        order = np.lexsort((e, s))
        V = np.vstack([p[2] for p in parts])[order]
        reference = np.concatenate([p[3] for p in parts])[order]
        weights = np.concatenate([p[4] for p in parts])[order]
        tests = np.concatenate([p[5] for p in parts])[order]
        sampling = {}
        if basis.sample_sigma is not None and basis.sample_weights is not None:
            sampling = {"sample_sigma": basis.sample_sigma, "sample_weights": basis.sample_weights}
        if basis.error_modes is not None and basis.error_lambda is not None:
            sampling["error_modes"] = np.vstack([p[6] for p in parts])[order]
            sampling["error_lambda"] = basis.error_lambda
        data = io.BytesIO()
        np.savez(
            data,
            V=V,
            reference=reference,
            weights=weights,
            tests=tests,
            energies=basis.energies,
            **sampling,
        )
        document = {
            "format": FORMAT,
            "space": basis.space,
            "provenance": basis.provenance,
            "npz_sha256": hashlib.sha256(data.getvalue()).hexdigest(),  # the pair's link
        }
        try:  # each file replaced whole (never opened in place: a FIFO there blocks no one)
            npz.parent.mkdir(parents=True, exist_ok=True)
            safe_files.replace(npz, data.getvalue())
            safe_files.replace(meta, (json.dumps(document, indent=1) + "\n").encode())
        except OSError as exc:
            problem = OutputError(f"basis {str(npz)!r}: cannot be written ({exc})")
    agree(comm, problem)  # every rank raises alike: none waits for rank 0
    return npz, meta


def read_basis(path: str | Path, model) -> Basis:
    """The basis of :func:`write_basis` for ``model``, each rank its owned rows; a SceneError of
    one line naming the file if it is missing, not a basis, or of another mesh or space
    (elements, degree, components, dofs) than the model's (collective)."""
    npz, meta = basis_paths(path)
    try:
        document = json.loads(safe_files.read_text(meta))
        content = safe_files.read_regular(npz)
        arrays = np.load(io.BytesIO(content))
        data = {name: arrays[name] for name in ("V", "reference", "weights", "tests", "energies")}
        optional = ("sample_sigma", "sample_weights", "error_modes", "error_lambda")
        for name in optional:  # a basis without sampling or modes (an older file): absent
            data[name] = arrays[name] if name in arrays.files else None
    except (OSError, ValueError, KeyError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else type(exc).__name__
        raise SceneError(f"basis {str(npz)!r}: cannot be read ({why})") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise SceneError(f"basis {str(meta)!r}: not a reduced basis ({FORMAT!r})")
    link = document.get("npz_sha256")  # absent in files written before it was kept
    if link is not None and link != hashlib.sha256(content).hexdigest():
        raise SceneError(
            f"basis {str(npz)!r}: not the .npz its .json was written with (the pair was cut "
            "apart or mixed; rebuild the basis)"
        )
    expected, found = space_of(model), document.get("space", {})
    if not isinstance(found, dict):
        found = {}
    # a key the file lacks (supports, before they were kept) is not compared
    differ = [k for k in expected if k in found and found[k] != expected[k]]
    differ += [k for k in ("elements", "degree", "components", "dofs") if k not in found]
    if differ:
        name = differ[0]
        raise SceneError(
            f"basis {str(npz)!r}: made for {name} = {found.get(name)!r}, the scene has "
            f"{expected[name]!r} (rebuild the basis for this scene)"
        )
    sigma, entry = _node_order(model)
    # rank-independent order → this rank's rows: the place of (σ, entry) in the sorted order
    everything = np.vstack(model.msh.comm.allgather(np.column_stack([sigma, entry])))
    order = np.lexsort((everything[:, 1], everything[:, 0]))
    place = np.empty(len(order), dtype=int)
    place[order] = np.arange(len(order))
    start = sum(model.msh.comm.allgather(len(sigma))[: model.msh.comm.rank])
    rows = place[start : start + len(sigma)]
    cells = None
    if data["sample_sigma"] is not None:
        cells = _cells_at(model, data["sample_sigma"], npz)
    return Basis(
        V=data["V"][rows],
        reference=data["reference"][rows],
        weights=data["weights"][rows],
        energies=data["energies"],
        space=expected,
        provenance=document.get("provenance", {}),
        tests=data["tests"][rows],
        sample_cells=cells,
        sample_weights=data["sample_weights"],
        sample_sigma=data["sample_sigma"],
        error_lambda=data["error_lambda"],
        error_modes=None if data["error_modes"] is None else data["error_modes"][rows],
    )


def _cells_at(model, sigma: np.ndarray, npz: Path) -> np.ndarray:
    """The local cells whose midpoints are at ``sigma`` (a sampled basis is read serially:
    cosserat_fem/rom/hyper.py); a SceneError naming the file if one is not a cell's."""
    from cosserat_fem.rom.hyper import cell_midpoints

    if model.msh.comm.size > 1:
        raise SceneError(
            f"basis {str(npz)!r}: hyper-reduced (sampled elements), which runs serially only"
        )
    mids = cell_midpoints(model)
    order = np.argsort(mids)
    place = np.clip(np.searchsorted(mids[order], sigma), 0, len(mids) - 1)
    near = np.clip(place - 1, 0, len(mids) - 1)
    pick = np.where(
        np.abs(mids[order][place] - sigma) <= np.abs(mids[order][near] - sigma), place, near
    )
    cells = order[pick]
    if not np.allclose(mids[cells], sigma, rtol=0, atol=1e-12):
        raise SceneError(f"basis {str(npz)!r}: its sampled elements are not this mesh's cells")
    return cells.astype(np.int32)


def scene_provenance(scene) -> dict:
    """The scene's hash and text for a basis's provenance (the file the scene came from)."""
    text = None
    source = getattr(scene, "source", None)
    if source is not None and Path(str(source)).is_file():
        text = Path(str(source)).read_text()
    return {"scene_sha256": getattr(scene, "source_sha256", None), "scene_text": text}


def relative_l2(reduced: np.ndarray, full: np.ndarray) -> float:
    """‖a − b‖₂ / ‖b‖₂ over all rows and columns (a free end's trajectory)."""
    return math.sqrt(float(np.sum((reduced - full) ** 2)) / float(np.sum(full**2)))


def train(scenes, tolerance: float, every: int = 1, record: bool = True):
    """Run each scene in full (no files) with one :class:`SnapshotCollector` and return the POD
    basis of all their snapshots (:func:`pod_basis`) and the runs' results. The scenes share
    the discretisation and the rest state (a sweep's members). Collective."""
    from cosserat_fem.analysis.simulation import run_scene

    scenes = list(scenes)
    collector = SnapshotCollector(every)
    results = [
        run_scene(scene, write_outputs=False, observers=[collector], record=record)
        for scene in scenes
    ]
    provenance = {
        **scene_provenance(scenes[0]),
        "runs": [
            {
                "scene_sha256": getattr(s, "source_sha256", None),
                "title": getattr(s, "title", None),
                "time_s": [s.time.start, s.time.end],
                "step_s": s.time.step,
                "loads": s.to_dict().get("loads"),
                "load_values": load_values(s),
            }
            for s in scenes
        ],
        "every": every,
    }
    return pod_basis(results[0].model, collector, tolerance, provenance), results
