# %% [markdown]
# # Joints between members by dof identification: a prototype (docs/joints-design.md)
#
# Not wired into the package. A structure's joint today is one shared mesh vertex (rigid).
# Here the joint's vertex is duplicated (member 2 gets its own copy of node B) and the two
# copies' dofs are identified afterwards, u = P u_r with a sparse 0/1 prolongation P (n × m),
# three ways (:func:`solve`): J_r = Pᵀ J P by PETSc's MatPtAP ("ptap"); J assembled straight
# into the reduced matrix through a local-to-global map ("local map"); or the full BAIJ system
# kept, the slave's identified rows added to the master's and replaced by u_s − u_m = 0
# ("rows", the one docs/joints-design.md recommends).
#
# A spherical joint identifies the translations p1..3 and their rates q1..3 of the two copies;
# a rigid joint all twelve components (which must be today's shared vertex to round-off).
#
# The case: three collinear members along e1 in the x-z plane, A (clamped) - B - D - C
# (pinned, hinge axis e2), a = |AB| = 40, |BD| = |DC| = 30, c = |BC| = 60, a dead force P
# along −e3 at D; portal_frame.toml's section (EI = 1440 in the plane, κGA = 720/2.6·6·5/6).
# With a spherical joint at B the beam BC has moment-free ends, so it is statically
# determinate: B carries V = P (c − b)/c, the cantilever AB deflects at B by
#
#     w_B = V (a³/(3 EI) + a/(κGA)),                                                (J.1)
#
# and D (b = 30 from B) by
#
#     w_D = w_B (c − b)/c + P b² (c − b)²/(3 EI c) + P b (c − b)/(κGA c)              (J.2)
#
# (Timoshenko members; P3 holds their linear fields exactly, so one cell a member leaves only
# the geometric nonlinearity, relative O(P²): 3.6e-5 at P = 1e-3, measured).
#
#     .venv/bin/python benchmarks/joints_prototype.py [P3 cells a member for the timing]

# %%
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from dolfinx import cpp as _cpp
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

import cosserat_fem.rod.model as model_module
from cosserat_fem.analysis.statics import static_solver
from cosserat_fem.rod import structure as structure_module
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import read_toml, scene_from_dict

ROOT = Path(__file__).resolve().parents[1]

E, NU, AREA, I_PLANE, KAPPA = 720.0, 0.3, 6.0, 2.0, 5.0 / 6.0
EI, KGA = E * I_PLANE, KAPPA * E / (2 * (1 + NU)) * AREA
A_LEN, B_LEN, C_LEN = 40.0, 30.0, 60.0
LOAD = 1e-3


def scene(elements: int, load: float = LOAD):
    return scene_from_dict(
        {
            "title": "joint prototype",
            "rod": read_toml(ROOT / "scenes" / "portal_frame.toml")["rod"],  # E, NU, ... above
            "structure": {
                "nodes": [
                    {"name": "A", "position": [0, 0, 0]},
                    {"name": "B", "position": [A_LEN, 0, 0]},
                    {"name": "D", "position": [A_LEN + B_LEN, 0, 0]},
                    {"name": "C", "position": [A_LEN + C_LEN, 0, 0]},
                ],
                "members": [
                    {"name": "AB", "from": "A", "to": "B", "elements": elements},
                    {"name": "BD", "from": "B", "to": "D", "elements": elements},
                    {"name": "DC", "from": "D", "to": "C", "elements": elements},
                ],
                "supports": [
                    {"node": "A", "kind": "clamped"},
                    {"node": "C", "kind": "pinned", "axis": [0, 1, 0]},
                ],
                "loads": [{"node": "D", "force": [0, 0, -load]}],
            },
            "static": {"load_steps": 1},
            "time": {"end": 1.0, "step": 1.0},
            "discretisation": {"degree": 3},
        }
    )


# %% [markdown]
# The duplicated vertex: create_structure_mesh with member BD's first vertex a new point at
# B's place (the package refuses two nodes at one place; the prototype patches its mesh).

# %%
_original = structure_module.create_structure_mesh


def duplicated_mesh(structure, length, comm):
    """create_structure_mesh with member 1 (BD) starting from its own copy of node B: the
    function's call of dolfinx.mesh.create_mesh is given one more point, B's copy, and
    member 1's first cell starts from it (its vertices tagged as B's, both)."""
    real = mesh.create_mesh

    def create(comm, topology, x, domain):
        first = structure.members[0].elements  # member 1's first cell
        topology = topology.copy()
        joint, topology[first, 0] = topology[first, 0], len(x)
        return real(comm, topology, np.vstack([x, x[joint]]), domain)

    mesh.create_mesh = create
    try:
        return _original(structure, length, comm)
    finally:
        mesh.create_mesh = real


def joint_blocks(model, elements: int) -> tuple[int, int]:
    """The dof blocks of B's two copies: (member AB's, member BD's)."""
    msh = model.msh
    c2v = msh.topology.connectivity(1, 0)
    original = np.asarray(msh.topology.original_cell_index)
    dofmap = model.V.dofmap
    blocks = {}
    for v in model.structure.vertices["B"]:
        cells = msh.topology.connectivity(0, 1).links(v)
        assert len(cells) == 1, "a duplicated joint: one cell a copy"
        member = int(original[cells[0]]) // elements
        local = list(c2v.links(cells[0])).index(v)
        blocks[member] = int(dofmap.cell_dofs(cells[0])[local])
    return blocks[0], blocks[1]


# %% [markdown]
# P: every full dof is a reduced one except BD's copy of the identified components, which
# takes AB's copy's reduced index.


# %%
def prolongation(
    n: int, bs: int, slave: int, master: int, components
) -> tuple[PETSc.Mat, np.ndarray]:
    target = np.full(n, -1, dtype=np.int64)
    dropped = {slave * bs + c for c in components}
    keep = np.array([i for i in range(n) if i not in dropped])
    target[keep] = np.arange(keep.size)
    for c in components:
        target[slave * bs + c] = target[master * bs + c]
    m = keep.size
    P = PETSc.Mat().createAIJ([n, m], nnz=1, comm=MPI.COMM_SELF)
    for i in range(n):
        P.setValue(i, int(target[i]), 1.0)
    P.assemble()
    return P, target


def solve(model, joint, timings: dict, method: str = "shared") -> int:
    """Newton on the structure with the joint ``joint`` = (P, target, slave rows, master rows)
    (None: today's shared vertex); F and J assembled by the package's static solver (its
    residual with the Dirichlet rows, its BAIJ Jacobian). ``method``:

    * "ptap": J_r = Pᵀ J P (MatPtAP of J converted to AIJ), F_r = Pᵀ F, u ← u − P δ_r;
    * "local map": J assembled straight into the reduced AIJ matrix, whose local-to-global
      map sends full dof i to reduced dof target[i] (DOLFINx's unrolled assembly calls
      MatSetValuesLocal, which sums through the map: Pᵀ J P); F_r = Pᵀ F a bincount;
    * "rows": the full BAIJ system kept, with row operations: each identified slave row is
      added to its master's, then replaced by the constraint u_slave − u_master = 0 (the
      (slave, master) blocks added to the sparsity once); PETSc's blocked LU as today.

    Returns the iterations (the update test ‖δ‖ ≤ 1e-12 ‖u‖, tighter than the package's)."""
    solver = static_solver(model.scene, model)
    U, A, b = model.U, solver.A, solver.b
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    if method in ("ptap", "local map"):
        # the statics' 12×12 blocks have zero diagonal entries: PETSc's scalar LU of an AIJ
        # meets a zero pivot where its BAIJ LU inverts whole blocks; MUMPS pivots
        ksp.getPC().setFactorSolverType("mumps")
    if joint is not None:
        P, target, slaves, masters = joint
    if method == "local map":
        solver._jacobian()
        Ar = A.convert("aij").PtAP(P)  # once: the reduced sparsity
        lgmap = PETSc.LGMap().create(target.astype(PETSc.IntType), bsize=1, comm=MPI.COMM_SELF)
        Ar.setLGMap(lgmap, lgmap)
        br = P.createVecRight()
        m = br.size
    if method == "rows":
        # The first row operations add the (master, slave's neighbours) and (slave, master)
        # blocks to the sparsity, a few mallocs once. The matrix must hold J's pattern by then:
        # PETSc's first final assembly drops preallocated entries nothing was set in, so
        # inserting into the unfilled matrix and assembling made the next DOLFINx assembly
        # malloc every entry (measured: 240 s at 216 024 dofs against 0.05 s). Building the
        # matrix from a sparsity pattern with the blocks inserted is the clean way (the
        # design's item 4); here J is assembled once first.
        t0 = time.perf_counter()
        solver._jacobian()
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        timings["setup"] = [time.perf_counter() - t0]
    for it in range(1, 20):
        t0 = time.perf_counter()
        solver._residual()
        if method != "local map":
            solver._jacobian()
        t1 = time.perf_counter()
        if method == "shared":
            Ar, br = A, b
        elif method == "local map":
            form = solver.J_form
            Ar.zeroEntries()
            _cpp.fem.petsc.assemble_matrix(
                Ar,
                form,
                _cpp.fem.pack_constants(form),
                _cpp.fem.pack_coefficients(form),
                model.bcs,
                True,
            )
            Ar.assemblyBegin(PETSc.Mat.AssemblyType.FLUSH)
            Ar.assemblyEnd(PETSc.Mat.AssemblyType.FLUSH)
            _cpp.fem.petsc.insert_diagonal(Ar, model.V._cpp_object, model.bcs, 1.0)
            Ar.assemble()
            br.array[:] = np.bincount(target, weights=b.array, minlength=m)
        elif method == "ptap":
            # PETSc 3.18 has no PtAP of a BAIJ with an AIJ: A is converted first (timed too)
            Ar = A.convert("aij").PtAP(P)
            br = P.createVecRight()
            P.multTranspose(b, br)
        else:
            rows = [A.getRow(int(i)) for i in slaves]
            for j, (cols, vals) in zip(masters, rows, strict=True):
                A.setValues([j], cols, vals, addv=True)
            A.assemble()
            A.zeroRows(list(slaves), diag=1.0)
            A.setValues(list(slaves), list(masters), -np.eye(len(slaves)), addv=False)
            A.assemble()
            array = b.array_w
            array[masters] += array[slaves]
            array[slaves] = U.x.array[slaves] - U.x.array[masters]
            Ar, br = A, b
        t2 = time.perf_counter()
        timings.setdefault("assembly", []).append(t1 - t0)
        timings.setdefault("reduction", []).append(t2 - t1)
        dx = br.duplicate()
        ksp.setOperators(Ar)
        t3 = time.perf_counter()
        ksp.solve(br, dx)
        timings.setdefault("solve", []).append(time.perf_counter() - t3)
        if method in ("shared", "rows"):
            U.x.array[: dx.size] -= dx.array
        else:
            U.x.array[: target.size] -= dx.array[target]
        if dx.norm() <= 1e-12 * U.vector.norm():
            return it
    raise RuntimeError("no convergence")


# %% [markdown]
# The runs: rigid today (shared vertex), rigid by identification, spherical by
# identification (three ways), against (J.2).


# %%
def run(
    kind: str, elements: int, timings: dict, method: str = "ptap", load: float = LOAD
) -> tuple[float, object]:
    """w_D [length] of a ``kind`` joint at B ("shared": today's vertex; "rigid",
    "spherical": the duplicated vertex identified by ``method``), and (model, iterations)."""
    sc = scene(elements, load)
    if kind == "shared":
        model = build_model(sc, MPI.COMM_SELF, planar=False)
        joint, method = None, "shared"
    else:
        model_module.create_structure_mesh = duplicated_mesh
        try:
            model = build_model(sc, MPI.COMM_SELF, planar=False)
        finally:
            model_module.create_structure_mesh = _original
        master, slave = joint_blocks(model, elements)
        components = np.array(range(12) if kind == "rigid" else (0, 1, 2, 6, 7, 8))
        bs = model.V.dofmap.index_map_bs
        P, target = prolongation(model.U.x.array.size, bs, slave, master, components)
        joint = (P, target, slave * bs + components, master * bs + components)
    its = solve(model, joint, timings, method)
    d = model.structure.vertices["D"]
    block = fem.locate_dofs_topological(model.V, 0, d)[0]
    w = -model.U.x.array[12 * block + 2] * sc.rod.length
    return w, (model, its)


def closed_form(load: float) -> float:
    """w_D of (J.1), (J.2) [length units of the scene]."""
    b, c = B_LEN, C_LEN
    w_B = load * (c - b) / c * (A_LEN**3 / (3 * EI) + A_LEN / KGA)
    return (
        w_B * (c - b) / c
        + load * b**2 * (c - b) ** 2 / (3 * EI * c)
        + load * b * (c - b) / (KGA * c)
    )


if __name__ == "__main__":
    METHODS = ("ptap", "local map", "rows")
    w_D = closed_form(LOAD)
    shared, _ = run("shared", 1, {})
    print(f"today's shared vertex (rigid)  w_D = {shared:.12e}")
    for method in METHODS:
        rigid, _ = run("rigid", 1, {}, method)
        print(
            f"rigid by {method:9s}: relative to the shared vertex "
            f"{abs(rigid - shared) / shared:.1e}"
        )
    print(f"closed form (J.2), spherical joint: w_D = {w_D:.12e}")
    for method in METHODS:
        w, (_, its) = run("spherical", 1, {}, method)
        print(
            f"spherical by {method:9s}: w_D = {w:.12e}, relative {abs(w - w_D) / w_D:.2e}, "
            f"{its} Newton iterations"
        )
    w, _ = run("spherical", 1, {}, "rows")
    w_small, _ = run("spherical", 1, {}, "rows", load=LOAD / 10)
    error, small = abs(w - w_D), abs(w_small - closed_form(LOAD / 10))
    print(
        f"the geometric nonlinearity: the errors at P and P/10 in the ratio {error / small:.0f} "
        "(O(P³): the linear response exact)"
    )
    elements = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    print(f"timing: {elements} P3 cells a member (medians over the Newton iterations)")
    for kind, method in (("shared", "shared"),) + tuple(("spherical", m) for m in METHODS):
        timings: dict = {}
        w, (model, its) = run(kind, elements, timings, method)
        n = model.U.x.array.size
        assembly, reduction, lu = (
            np.median(timings[k]) for k in ("assembly", "reduction", "solve")
        )
        print(
            f"{method:10s} {n} dofs: F, J and the joint {(assembly + reduction) * 1e3:.1f} ms an "
            f"iteration (the joint's part {reduction * 1e3:.1f} ms), LU {lu * 1e3:.1f} ms"
        )
