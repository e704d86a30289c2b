"""Natural frequencies and mode shapes of a rod about a static state, by SLEPc.

The general form (65) is linearised about a state p0 at rest (the straight rod, or the static
equilibrium under the scene's loads at the start time). With U = (p, q), q = ṗ, the second block
of (65) reads Ma(p) p̈ + b(p, p')' − g(p, p', ṗ) = 0; its velocity terms (the products of (64)
and the gyroscopic terms) are quadratic in ṗ and vanish at rest, so the linearisation is

    M p̈ + K p = 0,   M = ∂F/∂p̈ |p0,   K = ∂F/∂p |p0,

with F the weak residual of the second block on a 6-component space (same mesh and degree as
the dynamics). K includes the load stiffness of state-dependent loads (torques in fixed
directions, (38) and (43); follower end loads, forms/follower.py, whose K is not
symmetric). Modes e^{iωt} φ solve the generalized eigenproblem

    K φ = λ M φ,   ω = ω0 √λ  [rad/s]   (λ in units of the time scale τ = ω0 t, (47)).

K and M are not symmetric in general (each row is a balance law divided by its own inertia,
(48)), so the problem is solved as a generalized non-Hermitian one with shift-and-invert about 0
(LU: PETSc in serial, MUMPS in parallel). Clamped dofs get 1 on K's diagonal and 0 on M's, which
sends their eigenvalues to infinity, away from the wanted ones.

Each mode is classified by where its kinetic energy lies: bending-x (x and ψ), bending-y
(y and θ), axial (z) or torsion (φ), with the physical weights ρ A ℓ² for the translations
p1..p3 and ρ c11, ρ c22, ρ I3 for θ, ψ, φ (I3 = c11 + c22, or c33 with torsion_inertia =
"printed": forms/groups.py).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.fem.petsc import assemble_matrix
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.analysis.observers import summary_start
from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import OutputError, SceneError, SolverError
from cosserat_fem.common.parallel import agree
from cosserat_fem.forms.general_form import row_inertias
from cosserat_fem.io.run_folder import write_summary
from cosserat_fem.nls.constraints import Identification
from cosserat_fem.output.fields import XdmfWriter
from cosserat_fem.rod.model import FULL, RodModel, structure_conditions, support_conditions
from cosserat_fem.scene.build import Scene, refuse_contact

KINDS = ("bending-x", "bending-y", "axial", "torsion")
# Which of p1..p6 = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ) belongs to which kind of motion.
_GROUPS = {"bending-x": (0, 4), "bending-y": (1, 3), "axial": (2,), "torsion": (5,)}


@dataclass
class Mode:
    """One natural mode: ω [rad/s], its kind, kinetic-energy fractions, shape (6 components),
    and the eigenvalue λ of K φ = λ M φ it comes from (dimensionless, ω = ω0 √λ).

    A λ that is negative (a state beyond a stability limit: the mode grows like e^{ω0 √−λ t})
    or complex (flutter, e.g. under follower-like loads) has no ω: ``omega`` is NaN and
    ``note`` says which, with the growth rate; round-off of the non-symmetric K, M (an
    imaginary part below 1e-8 |λ| + 1e-10 of the largest |λ| found, a negative λ below 1e-12 of
    it) is not taken for either."""

    omega: float
    kind: str
    fractions: dict[str, float]
    shape: fem.Function
    eigenvalue: complex = 0j
    note: str = ""

    @property
    def frequency_hz(self) -> float:
        return self.omega / (2.0 * np.pi)


def eigenvalue_kind(lam: complex, scale: float) -> str:
    """ "flutter" for a complex λ (|Im λ| > 1e-8 |λ| + 1e-10 ``scale``), "divergence" for a
    negative one (Re λ < −1e-12 ``scale``), "" otherwise (a mode that oscillates); ``scale``
    is the largest |λ| found. The round-off of the non-symmetric K, M is not taken for either
    (:class:`Mode`): relative to λ, and near λ = 0 relative to the scale, where a double
    eigenvalue (a round shaft's two planes of bending) splits into a pair ±i 1.8e-10 at a
    scale of 24 (measured, tests/test_greenhill.py: 7.5e-12 of the scale, under a tenth of
    the bound)."""
    if abs(lam.imag) > 1e-8 * abs(lam) + 1e-10 * scale:
        return "flutter"
    return "divergence" if lam.real < -1e-12 * scale else ""


def angular_frequency(lam: complex, omega0: float, scale: float) -> tuple[float, str]:
    """(ω [rad/s], note) of the eigenvalue λ (see :class:`Mode`); ``scale``: the largest |λ|
    found, for what counts as round-off."""
    kind = eigenvalue_kind(lam, scale)
    if kind == "flutter":
        return math.nan, f"complex eigenvalue {lam.real:.6g}{lam.imag:+.6g}i (flutter)"
    if kind == "divergence":
        rate = omega0 * math.sqrt(-lam.real)
        return math.nan, f"negative eigenvalue {lam.real:.6g}: unstable, grows at {rate:.6g} 1/s"
    return omega0 * math.sqrt(max(lam.real, 0.0)), ""


@dataclass
class ModalProblem:
    """Assembled K, M on the 6-component space of a model, and its base state p0; for a
    closed rod, ``joint``: the map S of :func:`join_ends` (a mode's shape is S φ)."""

    model: RodModel
    P: fem.FunctionSpace
    p0: fem.Function
    K: PETSc.Mat
    M: PETSc.Mat
    joint: PETSc.Mat | None = None

    def destroy(self) -> None:
        for matrix in (self.K, self.M, self.joint):
            if matrix is not None:
                matrix.destroy()


def modal_supports(model: RodModel, P: fem.FunctionSpace) -> list:
    """The supports on the 6-component space P of p (model.support_conditions: p = 0 at a
    clamped end; x, y, z, φ = 0 at a pinned one); a structure's at its nodes
    (model.structure_conditions)."""
    if model.structure is not None:
        return structure_conditions(P, model.scene, model.structure.vertices, FULL[:6])[0]
    ends = {
        name: mesh.locate_entities_boundary(model.msh, 0, lambda x, c=coord: np.isclose(x[0], c))
        for name, coord in (("start", 0.0), ("end", 1.0))
    }
    return support_conditions(P, model.scene, ends, FULL[:6])[0]


class ModalOperator:
    """K and M of ``model`` about states p0, with its loads at the time ``time`` [s] and its
    load factor (``model.load_factor``) as they are when :meth:`problem` is called. The forms
    are compiled, and the loads' time Constant registered, once: each :meth:`problem`
    assembles them anew about another p0 (a static path visits many)."""

    def __init__(self, model: RodModel, time: float):
        self.model = model
        element = ufl.VectorElement(
            "Lagrange", model.msh.ufl_cell(), model.scene.discretisation.degree, dim=6
        )
        self.P = P = fem.FunctionSpace(model.msh, element)
        self.p0 = fem.Function(P, name="p0")
        acc = fem.Function(P, name="p_ddot")
        v, dp = ufl.TestFunction(P), ufl.TrialFunction(P)
        zeros = [0.0] * 6
        U = ufl.as_vector([self.p0[i] for i in range(6)] + zeros)
        Udot = ufl.as_vector(zeros + [acc[i] for i in range(6)])
        V = ufl.as_vector(zeros + [v[i] for i in range(6)])
        self.time = fem.Constant(model.msh, PETSc.ScalarType(time * model.omega0))
        F = model.residual_terms(U, Udot, self.time, test=V).total()
        self.bcs = modal_supports(model, P)
        self.K_form = fem.form(ufl.derivative(F, self.p0, dp))
        self.M_form = fem.form(ufl.derivative(F, acc, dp))

    def problem(self, base: np.ndarray | None = None) -> ModalProblem:
        """K and M about p0 (``base``: a 12-component state array of ``model.V``; None = the
        straight rod). The 12- and 6-component spaces share their node numbering (same mesh
        and scalar element, blocked dofs), so p0 is the first six entries of each 12-block.
        The caller destroys the matrices (:meth:`ModalProblem.destroy`)."""
        self.p0.x.array[:] = 0.0 if base is None else base.reshape(-1, 12)[:, :6].ravel()
        self.model.sync_loads(self.time)
        K = assemble_matrix(self.K_form, bcs=self.bcs, diagonal=1.0)
        K.assemble()
        M = assemble_matrix(self.M_form, bcs=self.bcs, diagonal=0.0)
        M.assemble()
        problem = ModalProblem(model=self.model, P=self.P, p0=self.p0, K=K, M=M)
        if self.model.constraints is not None:  # a structure's joints
            return join_copies(problem, self.model.constraints)
        return join_ends(problem) if self.model.scene.reference.closed else problem


def assemble_modal_problem(model: RodModel, base: np.ndarray | None = None) -> ModalProblem:
    """K and M about p0 (:meth:`ModalOperator.problem`), the loads at time.start: the modes
    of a run's start. About a static state, :class:`~cosserat_fem.analysis.equilibria.
    Equilibria` keeps one :class:`ModalOperator` at static.time."""
    return ModalOperator(model, model.scene.time.start).problem(base)


def _end_dofs(P: fem.FunctionSpace, sigma: float) -> np.ndarray:
    """The global indices of the six dofs of p at the node at σ (on every rank)."""
    blocks = fem.locate_dofs_geometrical(P, lambda x: np.isclose(x[0], sigma))
    index_map = P.dofmap.index_map
    owned = blocks[blocks < index_map.size_local]
    mine = index_map.local_to_global(owned.astype(np.int32)) if owned.size else []
    found = [b for part in P.mesh.comm.allgather(list(mine)) for b in part]
    if len(found) != 1:
        raise RuntimeError(f"not one node at σ = {sigma}: {found}")
    return 6 * int(found[0]) + np.arange(6)


def join_ends(problem: ModalProblem) -> ModalProblem:
    """The eigenproblem of a closed rod (reference.closed): its unknowns p(ℓ) = p(0), the end
    node (σ = 1) a copy of the start node (σ = 0) (:func:`identify`). The weak form of the
    ring has test functions continuous across the joint too, so its rows are Sᵀ applied to the
    open rod's. The reference must close in position and frame (scene validation), so p =
    (displacement, Euler angles of R that carries D0) means the same at both ends."""
    start, end = _end_dofs(problem.P, 0.0), _end_dofs(problem.P, 1.0)
    return identify(problem, end, start, np.zeros(end.size, dtype=bool))


def join_copies(problem: ModalProblem, ties: Identification) -> ModalProblem:
    """The eigenproblem of a structure whose joints tie dofs (cosserat_fem/nls/constraints.py,
    ``ties`` on the model's 12-component space): the ties of p's components, on the
    6-component space (the same blocks), by :func:`identify`; a copy whose master a support
    holds is held."""
    P = problem.P
    offset = P.dofmap.index_map.local_range[0]
    block, k = np.divmod(ties.copies, ties.bs)
    master = ties.masters // ties.bs
    of_p = k < 6  # p's components: the first six of (p, q)
    copies = 6 * (block[of_p] + offset) + k[of_p]
    masters = 6 * (master[of_p] + offset) + k[of_p]
    combos = [row for joint in ties.joints for row in joint_rows(problem, ties, joint)]
    # K's and M's angle rows are moments over the rows' rotary inertias Î (forms/
    # general_form.py): times Î they are the virtual work of the angles (at the rest), which
    # Sᵀ combines across components for a hinge off the axes (the eigenproblem unchanged)
    if problem.model.msh.comm.allreduce(len(ties.joints), op=MPI.SUM):  # collective
        scale = problem.K.createVecLeft()
        blocks = scale.getArray().reshape(-1, 6)
        blocks[:, :3] = 1.0
        blocks[:, 3:] = row_inertias(problem.model.groups)
        problem.K.diagonalScale(L=scale)
        problem.M.diagonalScale(L=scale)
    return identify(problem, copies, masters, ~ties.added[of_p], combos)


def joint_rows(problem: ModalProblem, ties: Identification, joint) -> list:
    """A hinge's or a driven joint's copy angles as functions of its master's about p0:
    the constraint (C.3) of cosserat_fem/nls/constraints.py linearised, G_a δα_a + G_b δα_b =
    0, so δα_b = L δα_a + n β, L = −G_bᵀ (G_b G_bᵀ)⁻¹ G_a, n spanning G_b's null space (a
    hinge's free turn; none for a driven joint). β is the copy's angle k* with the largest
    |n_k|, which keeps its own column: the others are rows (row, columns, coefficients) of S
    over the master's angles (none if a support holds them) and that angle (global indices
    of the 6-component space). Exact about a base without reactions (the rest); about a
    loaded base the reactions' λ·∂²g term is not in K."""
    offset = problem.P.dofmap.index_map.local_range[0]
    p0 = problem.p0.x.array
    a, b = 6 * joint.master, 6 * joint.copy
    alpha = np.concatenate([p0[a + 3 : a + 6], p0[b + 3 : b + 6]])
    G = joint.gradient(alpha, joint.drive[0], ties.frames(joint))
    Ga, Gb = G[:, :3], G[:, 3:6]
    L = -Gb.T @ np.linalg.solve(Gb @ Gb.T, Ga)
    masters = 6 * (joint.master + offset) + 3 + np.arange(3)
    copies = 6 * (joint.copy + offset) + 3 + np.arange(3)
    keep = [] if joint.count == 3 else [int(np.argmax(np.abs(np.cross(Gb[0], Gb[1]))))]
    if keep:
        n = np.cross(Gb[0], Gb[1])
        k = keep[0]
        L = L - np.outer(n / n[k], L[k])
    rows = []
    for j in (j for j in range(3) if j not in keep):
        cols = list(masters) if joint.added else []
        coefs = list(L[j]) if joint.added else []
        if keep:
            cols.append(copies[keep[0]])
            coefs.append(n[j] / n[keep[0]])
        rows.append((int(copies[j]), np.array(cols), np.array(coefs)))
    return rows


def identify(
    problem: ModalProblem,
    copies: np.ndarray,
    masters: np.ndarray,
    held: np.ndarray,
    combos: list | None = None,
) -> ModalProblem:
    """The eigenproblem with the dofs ``copies`` (global indices) taking the values of their
    ``masters``, or zero where ``held`` (the master held by a support).

    S maps the reduced p onto p: S = I but for the copies' rows, whose 1 moves to their
    master's column (none where held), and the rows ``combos`` (row, columns, coefficients):
    a copy's value a combination of others (a hinge's linearised angles, :func:`joint_rows`).
    The copies' test functions are their masters' too, so
    K̃ = Sᵀ K S + D, M̃ = Sᵀ M S, where the copies' rows and columns are zero and D puts 1 on
    K̃'s diagonal there (their eigenvalues are infinite, as a clamped dof's: away from the
    wanted ones); a mode φ of (K̃, M̃) has the shape S φ. Each rank gives the copies it owns,
    or all (only the owned ones are used)."""
    K, M = problem.K, problem.M
    rows = K.getOwnershipRange()
    entries: list[tuple[list, list]] = [([r], [1.0]) for r in range(*rows)]
    mine = (copies >= rows[0]) & (copies < rows[1])
    for copy, master, is_held in zip(copies[mine], masters[mine], held[mine], strict=True):
        entries[copy - rows[0]] = ([], []) if is_held else ([master], [1.0])
    dependent = list(copies[mine])
    for row, cols, coefs in combos or []:
        if rows[0] <= row < rows[1]:
            entries[row - rows[0]] = (list(cols), list(coefs))
            dependent.append(row)
    widest = max((len(c) for c, _ in entries), default=1)
    S = PETSc.Mat().createAIJ((K.getSizes()[0], K.getSizes()[0]), nnz=(widest, widest), comm=K.comm)
    pointers = np.concatenate([[0], np.cumsum([len(c) for c, _ in entries])])
    columns = np.array([c for cs, _ in entries for c in cs], dtype=PETSc.IntType)
    values = np.array([v for _, vs in entries for v in vs], dtype=float)
    S.setValuesCSR(pointers.astype(PETSc.IntType), columns, values)
    S.assemble()
    K_joined, M_joined = K.PtAP(S), M.PtAP(S)
    K.destroy()  # the unjoined: replaced
    M.destroy()
    K_joined.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for row in dependent:
        K_joined.setValue(int(row), int(row), 1.0, addv=PETSc.InsertMode.ADD_VALUES)
    K_joined.assemble()
    return ModalProblem(problem.model, problem.P, problem.p0, K_joined, M_joined, joint=S)


def shift_invert(problem: ModalProblem, count: int, ncv: int, tol: float, lu_package: str):
    """SLEPc's solved EPS of K φ = λ M φ (``problem``'s K, M) for the ``count`` eigenvalues
    nearest the shift (``ncv`` the subspace, ``tol`` the tolerance, ``lu_package`` the LU of the
    shift-and-invert); the caller reads and destroys it."""
    from slepc4py import SLEPc

    eps = SLEPc.EPS().create(problem.model.msh.comm)
    eps.setOperators(problem.K, problem.M)
    eps.setProblemType(SLEPc.EPS.ProblemType.GNHEP)
    eps.setDimensions(nev=count, ncv=ncv)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    # A mechanism's K is singular (its rigid-body modes, λ = 0): shift-invert about λ = −1
    # (ω = i ω0: K + M is positive definite), which finds the same lowest modes.
    shift = -1.0 if problem.model.scene.mechanism else 0.0
    eps.setTarget(shift)
    eps.setTolerances(tol=tol, max_it=500)
    st = eps.getST()
    st.setType(SLEPc.ST.Type.SINVERT)
    st.setShift(shift)
    ksp = st.getKSP()
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType(lu_package)
    eps.solve()
    return eps


def solve_eigenproblem(problem: ModalProblem, count: int) -> list[Mode]:
    """The ``count`` lowest modes, sorted by frequency."""
    comm = problem.model.msh.comm
    package = "petsc" if comm.size == 1 else "mumps"
    eps = shift_invert(problem, count, max(2 * count + 10, 30), 1e-13, package)
    found = eps.getConverged()
    if found < count:
        eps.destroy()
        raise SolverError(
            f"SLEPc converged {found} of the {count} modes asked for",
            where="modes",
            suggestion="ask for fewer (--count) or refine the mesh (discretisation.elements)",
        )
    vr, vi = problem.K.createVecs()
    joined = vr.duplicate()
    pairs = []
    for i in range(found):
        lam = eps.getEigenpair(i, vr, vi)
        shape = fem.Function(problem.P, name="mode")
        if problem.joint is not None:
            problem.joint.mult(vr, joined)
            shape.vector.array[:] = joined.array
        else:
            shape.vector.array[:] = vr.array
        shape.x.scatter_forward()
        pairs.append((complex(lam), shape))
    pairs.sort(key=lambda pair: (pair[0].real, pair[0].imag))
    weights = _kinetic_weights(problem.model)
    scale = max((abs(lam) for lam, _ in pairs), default=1.0)
    rigid = problem.model.scene.rigid_body_modes()
    modes = []
    every = _energy_fractions([shape for _, shape in pairs[:count]], weights)
    for i, ((lam, shape), fractions) in enumerate(zip(pairs[:count], every, strict=True)):
        omega, note = angular_frequency(lam, problem.model.omega0, scale)
        if i < rigid:  # λ = 0 to the round-off of K's largest eigenvalues, of either sign
            omega, note = 0.0, f"rigid-body mode (λ = {lam.real:.2g}, round-off)"
        kind = max(fractions, key=fractions.__getitem__)
        modes.append(Mode(omega, kind, fractions, _normalised(shape), lam, note))
    eps.destroy()
    return modes


def _kinetic_weights(model: RodModel) -> np.ndarray:
    """ρ A ℓ² for p1..p3 (p = x/ℓ) and ρ c11, ρ c22, ρ I3 for θ, ψ, φ, per unit σ (I3: the
    torsion row's, forms/groups.py)."""
    rod = model.rod
    trans = rod.density * rod.section.area * rod.length**2
    return np.array([trans] * 3 + [rod.density * c for c in rod.rotary_inertias])


def _energy_fractions(shapes: list[fem.Function], weights: np.ndarray) -> list[dict[str, float]]:
    """The part of the kinetic energy Σ_i w_i ∫ φ_i² dσ of each mode in ``shapes`` in each
    kind of motion (KINDS), ``weights`` w from :func:`_kinetic_weights` (collective). The six
    forms ∫ u_i² dσ are built once, on a Function the shapes are copied into (the weights
    outside them: one compiled form whatever the rod)."""
    if not shapes:
        return []
    space = shapes[0].function_space
    comm, u = space.mesh.comm, fem.Function(space)
    forms = [fem.form(u[i] ** 2 * ufl.dx) for i in range(6)]
    every = []
    for shape in shapes:
        u.x.array[:] = shape.x.array
        local = np.array([fem.assemble_scalar(form) for form in forms])
        per_component = weights * comm.allreduce(local, op=MPI.SUM)
        total = per_component.sum()
        every.append(
            {kind: float(per_component[list(idx)].sum() / total) for kind, idx in _GROUPS.items()}
        )
    return every


def _normalised(shape: fem.Function) -> fem.Function:
    """Scale so that the largest |component| is 1 with a positive sign."""
    comm = shape.function_space.mesh.comm
    local = shape.x.array
    i = int(np.argmax(np.abs(local))) if local.size else 0
    mine = (abs(local[i]), local[i]) if local.size else (0.0, 1.0)
    _, value = max(comm.allgather(mine))
    shape.x.array[:] /= value
    return shape


def max_modes(scene: Scene) -> int:
    """How many modes the discretisation has: the free dofs of p, six per Lagrange node less
    those the supports hold (:meth:`~cosserat_fem.scene.resolved.Supports.held`: six at a
    clamped end, four at a fork or a hinge, three at a ball joint or a roller, five at a
    sliding end)."""
    disc = scene.discretisation
    if scene.structure is not None:  # its vertices: the nodes and each member's interior ones
        st = scene.structure
        vertices = len(st.nodes) + sum(m.elements - 1 for m in st.members)
        held = sum(len(sum(s.held(), ())) for s in st.supports)
        return 6 * (vertices + (disc.degree - 1) * disc.elements) - held
    nodes = disc.elements * disc.degree + 1 - scene.reference.closed  # a ring: ends joined
    held = sum(len(sum(scene.supports.held(end), ())) for end in ("start", "end"))
    return 6 * nodes - held


def check_count(scene: Scene, count) -> None:
    """SceneError naming --count unless it is a whole number in [1, :func:`max_modes`]; for a
    scene with [contact] (its modes would ignore the obstacles)."""
    refuse_contact(scene, "modes")
    if isinstance(count, bool) or not isinstance(count, int | np.integer):
        raise SceneError(f"count (--count): must be a whole number, got {count!r}")
    most = max_modes(scene)
    if not 1 <= count <= most:
        raise SceneError(
            f"--count: must lie in [1, {most}] (the modes of {scene.discretisation.elements} "
            f"elements of degree {scene.discretisation.degree}: six unknowns a node less the "
            f"held ones; more elements give more), got {count}"
        )


def write_modes(out: Path, model: RodModel, modes: list[Mode], about: str = "undeformed") -> None:
    """``modes.csv`` (rank 0), ``modes.xdmf`` (shapes as a series indexed by mode number) and
    ``modes.json``, the summary of the modal analysis (cosserat_fem/io/run_folder.py; not
    summary.json, which belongs to the run or static solve of the folder, if any)."""
    comm = model.msh.comm
    problem = None
    if comm.rank == 0:
        try:
            fd = safe_files.create(out / "modes.csv")  # never written through a link
            with os.fdopen(fd, "w", newline="", encoding="utf-8") as stream:
                writer = csv.writer(stream)
                writer.writerow(
                    ["mode", "omega_rad_s", "frequency_hz", "kind"]
                    + [f"fraction_{k.replace('-', '_')}" for k in KINDS]
                    + ["eigenvalue_re", "eigenvalue_im", "note"]
                )
                for i, mode in enumerate(modes, start=1):
                    lam = mode.eigenvalue
                    writer.writerow(
                        [i, f"{mode.omega:.12e}", f"{mode.frequency_hz:.12e}", mode.kind]
                        + [f"{mode.fractions[k]:.6f}" for k in KINDS]
                        + [f"{lam.real:.12e}", f"{lam.imag:.12e}", mode.note]
                    )
        except OSError as exc:
            problem = OutputError(
                f"output: cannot write {str(out / 'modes.csv')!r} ({exc.strerror or exc})"
            )
    agree(comm, problem)
    if modes:
        scratch = fem.Function(modes[0].shape.function_space, name="mode")
        # Displacement and angles only: strains and resultants of an eigenvector of
        # arbitrary amplitude would be nonlinear functions of that amplitude.
        xdmf = XdmfWriter(out / "modes.xdmf", model, ("displacement", "angles"), U=scratch)
        for i, mode in enumerate(modes, start=1):
            xdmf.write(float(i), mode.shape)
        xdmf.close()
    modes_found = [
        {
            "omega_rad_s": m.omega,
            "kind": m.kind,
            "eigenvalue": [m.eigenvalue.real, m.eigenvalue.imag],
            "note": m.note,
        }
        for m in modes
    ]
    summary = summary_start("modes", model.scene, comm, about=about, modes=modes_found)
    summary["status"] = "completed"
    write_summary(out / "modes.json", summary, comm)
