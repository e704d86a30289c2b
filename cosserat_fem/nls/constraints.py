"""Dofs tied to others by rows of the assembled system (docs/joints-design.md).

An :class:`Identification` ties pairs of dofs: the copy's value u_c equals its master's u_m
(a structure's joint, cosserat_fem/rod/structure.py, ties the copies of a node's vertex). The
unknowns keep both copies, and the Newton system J δ = F of the constrained problem is made
from the assembled one by row operations, for each pair (c, m):

    F_m ← F_m + F_c,       J_m,: ← J_m,: + J_c,:   (the copy's equation moved to its master)  (C.1)
    F_c ← u_c − u_m,       J_c,: ← e_cᵀ − e_mᵀ     (the constraint)                          (C.2)

With u = P u_r (P the 0/1 prolongation: the copy takes its master's value) (C.1) is Pᵀ F and
Pᵀ J on the masters' rows, and a solution of the square system (C.1)-(C.2) is the solution of
the reduced system Pᵀ J P δ_r = Pᵀ F (its copies equal to their masters). A master held by a
Dirichlet condition keeps its row u_m − g: the support takes the copy's equation as a part of
its reaction. The matrix keeps its 12×12 blocks, so PETSc's blocked LU runs as without the
pairs; the blocks the rows add, (master, the copy's neighbours) and (copy, master), are in its
sparsity from the start (:meth:`create_matrix`). Linear constraints need nothing of the time
integrators: every state they combine satisfies them.

**Hinges and driven joints** tie the rotations of a master a and its copy b nonlinearly (a
:class:`Joint`; their positions are pairs as above). With Λ = (D(θ, ψ, φ) A)ᵀ a node's rotation
in its own chart A (cosserat_fem/rod/charts.py; each copy keeps its own chart through the
chart's moves), α_a, α_b the two nodes' angles, n0 the joint's axis at rest, (t1, t2, n0)
orthonormal:

    hinge:  g = (t1, t2)ᵀ Λ_aᵀ Λ_b n0  (m = 2),   driven:  g = vee(skew(exp(α_d [n0×])ᵀ Λ_aᵀ Λ_b))
    (m = 3, α_d(τ) the drive),                                                          (C.3)

G_a, G_b, G_d = ∂g/∂(α_a, α_b, α_d) (by complex steps: exact). The copy's rows reach its
master's by the reaction moved across: with multipliers, f_a + G_aᵀ λ = 0 and f_b + G_bᵀ λ = 0
for the generalised forces f conjugate to the coordinates G is taken in, so λ = −(G_b
G_bᵀ)⁻¹ G_b f_b is eliminated; the copy keeps the rows of its free turn (N, spanning G_b's
null space). The two row groups are
conjugate to different virtual motions: the kinematic rows K (tested by the angles' v_p,
components 3-5, ∫ (ṗ − q)·v_p) to the angles α, the balance rows R (tested by v_q,
components 9-11) to the body turns c (Λ → Λ exp(c×), ŵ = Mm α̇) each divided by its row's
rotary inertia Î_j (forms/general_form.py: δϑ = Σ_j v_{9+j} λ_j/Î_j), so with H = G Mm⁻¹:

    C_K = −G_aᵀ (G_b G_bᵀ)⁻¹ G_b,   N_K = (G_b's rows' cross product) (a hinge; none if m = 3)
    C_R = −Î⁻¹ H_aᵀ (H_b H_bᵀ)⁻¹ H_b Î,   N_R = (Mm_b N_Kᵀ)ᵀ Î                              (C.4)
    K_a ← K_a + C_K K_b,   K_b ← (g, N_K K_b)                                               (C.5)
    R_a ← R_a + C_R R_b                                                                     (C.6)
    R_b ← (G_a q_a + G_b q_b + G_d dα_d/dτ, N_R R_b)   (the constraint's rate)             (C.7)

and their Jacobian rows exactly: C J_b,: and N J_b,:, G in the angles' (and the rates')
columns, and the derivatives of C K_b, N K_b, C R_b, N R_b and of (C.7)'s G q in the angles
with the copy's rows and q held (the reactions' derivatives, (C.8): central differences of
the exact G, :meth:`Joint.tangent`, at the last residual's reactions). This is the
null-space (Galerkin) reduction of both row groups onto the joint's constraint, the position
constraint in the kinematic rows and its rate in the balance rows, so the integrators see
an ODE again (no multiplier, no index). For a hinge about e3 whose copies share a chart,
(C.3) gives G_b = −G_a = S (e1, e2)ᵀ (S an invertible 2×2) at any angles with θ_a = θ_b,
ψ_a = ψ_b: C_K = diag(1, 1, 0), N_K ∝ e3 and (C.5),
(C.7) are (C.1)-(C.2) on θ, ψ and their rates, the former linear identification; C_R is
diag(1, 1, 0) too while the copies' φ agree, and differs once the hinge has turned: the
former identification's sum of the balance rows added moments in two body frames a hinge's
turn apart (invisible in a plane, where no moment crosses the axis; a driven joint about a
tilted axis showed it: an error of 7e-3 m that did not shrink with h, tests/test_joints.py).

A pair's two dofs, and a joint's two blocks, are owned by one rank (the structure's
partitioner); each rank lists its own.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from dolfinx import cpp, fem
from dolfinx.fem.petsc import assemble_matrix
from petsc4py import PETSc

from cosserat_fem.common.rotations import axis_rotation, cross_matrix
from cosserat_fem.rod.charts import angular_map, euler_angles, euler_matrix, quaternion_frame


# --- joints whose rotations are tied nonlinearly (hinge, driven) ----------------------------
def _rotation(angles, frame: np.ndarray) -> np.ndarray:
    """Λ = (D(θ, ψ, φ) A)ᵀ, the spatial rotation of a node whose angles (real or complex,
    (..., 3)) are measured in the chart whose frame is A (rows a_j; charts.py): d_i = Λ d0_i."""
    angles = np.asarray(angles)
    D = euler_matrix(angles[..., 0], angles[..., 1], angles[..., 2])
    return np.swapaxes(D @ frame, -1, -2)


@dataclass
class Joint:
    """The rotational tie of a hinge or a driven joint between the master block ``master`` and
    the copy block ``copy`` (local, owned) of a node (module docstring, (C.3)-(C.8)): about the
    unit axis ``axis`` n0 of the rest frame (fixed basis), ``driven`` by the angle α(τ) whose
    value and first two τ-derivatives :attr:`drive` holds (set before each solve:
    cosserat_fem/rod/model.py JointDrive). ``added``: the master's angle rows take the copy's
    (not held by a support)."""

    master: int
    copy: int
    axis: np.ndarray
    driven: bool
    added: bool = True
    #: α, dα/dτ, d²α/dτ² [rad, rad per unit τ, ...] of a driven joint
    drive: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: Î, the rotary inertias that divide the balance rows 9-11 (forms/general_form.py
    #: row_inertias; only their ratios matter)
    inertia: np.ndarray = field(default_factory=lambda: np.ones(3))
    #: the copy's rows (K_b, R_b), (α, q) and the rows' (C, N, G) of the joint at the last
    #: residual (the Jacobian's rows and reaction terms (C.8) are taken there)
    last: tuple | None = None

    def __post_init__(self) -> None:
        n = np.asarray(self.axis, dtype=float)
        self.axis = n / np.linalg.norm(n)
        other = np.eye(3)[int(np.argmin(np.abs(self.axis)))]
        t1 = np.cross(self.axis, other)
        t1 /= np.linalg.norm(t1)
        #: (t1, t2, n0) a right-handed orthonormal basis: the hinge's g uses t1, t2
        self.basis = np.stack([t1, np.cross(self.axis, t1)], axis=1)

    @property
    def count(self) -> int:
        """m: the constraints on the copy's rotation (2 a hinge, 3 a driven joint)."""
        return 3 if self.driven else 2

    def constraint(self, alpha, angle, frames: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """g(α_a, α_b, α_d) of (C.3) for the six angles ``alpha`` (master's, copy's; real or
        complex; (..., 6) for a batch) in the charts ``frames`` (A_a, A_b) and the drive
        angle ``angle`` (a number, or (...) with the batch): (..., m)."""
        alpha = np.asarray(alpha)
        La, Lb = _rotation(alpha[..., :3], frames[0]), _rotation(alpha[..., 3:], frames[1])
        M = np.swapaxes(La, -1, -2) @ Lb
        if not self.driven:
            return (M @ self.axis) @ self.basis
        E = np.swapaxes(axis_rotation(self.axis, angle), -1, -2) @ M
        return 0.5 * np.stack(
            [E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0], E[..., 1, 0] - E[..., 0, 1]],
            axis=-1,
        )

    def gradient(self, alpha, angle, frames) -> np.ndarray:
        """(G_a, G_b, G_d) = ∂g/∂(α_a, α_b, α_d) as one (..., m, 7) array for angles (..., 6),
        by complex steps (exact to round-off: no difference is taken), in one batch."""
        h = 1e-30
        steps = 1j * h * np.eye(7)
        a = np.asarray(alpha, dtype=complex)[..., None, :] + steps[:, :6]
        d = complex(angle) + steps[:, 6]
        return np.swapaxes(self.constraint(a, d, frames).imag, -1, -2) / h

    def rows(self, alpha, q, K_b, R_b, frames) -> tuple:
        """The joint's rows (C.4)-(C.7) at the angles ``alpha`` ((..., 6): a batch), their rates
        ``q`` (6), the copy's kinematic and balance rows ``K_b``, ``R_b`` (3 each): (C_K K_b,
        copy's K rows, C_R R_b, copy's R rows, (C_K, C_R), (N_K, N_R), G), N the (3 − m, 3)
        rows of the free turn."""
        T = lambda X: np.swapaxes(X, -1, -2)  # noqa: E731
        alpha = np.asarray(alpha)
        angle, rate = self.drive[0], self.drive[1]
        G = self.gradient(alpha, angle, frames)
        Ga, Gb, Gd = G[..., :3], G[..., 3:6], G[..., 6]
        C = -T(Ga) @ np.linalg.solve(Gb @ T(Gb), Gb)
        if self.count == 2:
            N = np.cross(Gb[..., 0, :], Gb[..., 1, :])[..., None, :]
        else:
            N = np.zeros((*alpha.shape[:-1], 0, 3))
        # the balance rows' virtual turns: body components c (Λ → Λ exp(c×)) over Î
        # (forms/general_form.py), ŵ = Mm α̇: H = G Mm⁻¹, C_R = −Î⁻¹ H_aᵀ (H_b H_bᵀ)⁻¹ H_b Î
        Ma = angular_map(alpha[..., 0], alpha[..., 2])
        Mb = angular_map(alpha[..., 3], alpha[..., 5])
        Ha, Hb = T(np.linalg.solve(T(Ma), T(Ga))), T(np.linalg.solve(T(Mb), T(Gb)))
        inertia = self.inertia
        C_R = -(T(Ha) @ np.linalg.solve(Hb @ T(Hb), Hb)) * inertia[None, :] / inertia[:, None]
        N_R = (N @ T(Mb)) * inertia
        g = self.constraint(alpha, angle, frames)
        K = np.concatenate([g, N @ K_b], axis=-1)
        R = np.concatenate([Ga @ q[:3] + Gb @ q[3:] + Gd * rate, N_R @ R_b], axis=-1)
        return C @ K_b, K, C_R @ R_b, R, (C, C_R), (N, N_R), G

    def rate_rows(self, alpha, q, frames) -> tuple[np.ndarray, np.ndarray]:
        """The right-hand sides of (C.5), (C.7) differentiated in τ, for the initial rates
        (U̇ solved, ṗ = q): G ṗ = −G_d α̇_d and G q̇ = −(dh/dτ at q̇ = 0), h = G q + G_d α̇_d,
        dh/dτ along (α̇, α̇_d) = (q, α̇_d) by a central difference of step 1e-6 rad, plus
        G_d α̈_d."""
        angle, rate, acceleration = self.drive
        eps = 1e-6

        def h(sign: float) -> np.ndarray:
            G = self.gradient(alpha + sign * eps * q, angle + sign * eps * rate, frames)
            return G[:, :6] @ q + G[:, 6] * rate

        G = self.gradient(alpha, angle, frames)
        return -G[:, 6] * rate, -((h(1.0) - h(-1.0)) / (2 * eps) + G[:, 6] * acceleration)

    def enforce(self, u: np.ndarray, bs: int, frames) -> None:
        """Put the copy's angles and rates in the local values ``u`` (blocks of ``bs``) on the
        joint: Λ_b turned by the smallest turn that takes Λ_b n0 to Λ_a n0 (a hinge), or
        Λ_b = Λ_a exp(α [n0×]) (driven), its angles the triple nearest its old ones; its rates
        moved by the least change that meets (C.7)."""
        a, b = self.master * bs, self.copy * bs
        La, Lb = _rotation(u[a + 3 : a + 6], frames[0]), _rotation(u[b + 3 : b + 6], frames[1])
        if self.driven:
            target = La @ axis_rotation(self.axis, self.drive[0])
        else:
            s, t = Lb @ self.axis, La @ self.axis
            v, c = np.cross(s, t), float(s @ t)
            target = (
                np.eye(3) + cross_matrix(v) + cross_matrix(v) @ cross_matrix(v) / (1.0 + c)
            ) @ Lb
        u[b + 3 : b + 6] = euler_angles(target.T @ frames[1].T, near=u[b + 3 : b + 6])
        alpha = np.concatenate([u[a + 3 : a + 6], u[b + 3 : b + 6]])
        q = np.concatenate([u[a + 9 : a + 12], u[b + 9 : b + 12]])
        G = self.gradient(alpha, self.drive[0], frames)
        Gb = G[:, 3:6]
        u[b + 9 : b + 12] -= Gb.T @ np.linalg.solve(
            Gb @ Gb.T, G[:, :6] @ q + G[:, 6] * self.drive[1]
        )

    def tangent(self, alpha, q, K_b, R_b, frames) -> tuple[np.ndarray, np.ndarray]:
        """∂/∂α of the rows (C.4)-(C.7) with the copy's rows and q held (the reactions'
        derivatives of (C.8)): ((6, 6) for the K rows, master's then copy's; the same for the
        R rows), by central differences of step 1e-6 rad of :meth:`rows` (whose G is exact:
        error O(1e-12) truncation + O(1e-10) round-off, relative)."""
        eps = 1e-6
        shifted = np.asarray(alpha)[None, :] + eps * np.concatenate([np.eye(6), -np.eye(6)])
        out = self.rows(shifted, q, K_b, R_b, frames)
        K = np.concatenate([out[0], out[1]], axis=-1)
        R = np.concatenate([out[2], out[3]], axis=-1)
        return (K[:6] - K[6:]).T / (2 * eps), (R[:6] - R[6:]).T / (2 * eps)


class Identification:
    """The pairs (copy, master) of owned local dofs of ``V`` (scalar indices: block × bs +
    component) built from ``masters`` and ``copies`` (local dof blocks, owned), each pair of
    blocks tying its ``components``; ``bcs`` the Dirichlet conditions whose masters keep
    their rows (module docstring)."""

    def __init__(
        self,
        V: fem.FunctionSpace,
        masters: list[int],
        copies: list[int],
        components: list[tuple[int, ...]],
        bcs: list,
        joints: list[Joint] | None = None,
    ):
        self.bs = bs = V.dofmap.index_map_bs
        #: the rotational ties of hinges and driven joints, (C.3)-(C.8)
        self.joints: list[Joint] = list(joints or [])
        #: the nodal quaternions of the chart the angles are measured in (nodes, 4), or None
        #: (the fixed basis): set by the model that owns the chart
        self.chart: Callable[[], np.ndarray | None] = lambda: None
        #: the unknowns' local values a linear problem's joint rows (:meth:`apply_vector`
        #: with u None) are taken at: set by the model (its U)
        self.state: Callable[[], np.ndarray] = lambda: np.zeros(0)
        self.V = V
        self._extra: list[tuple[np.ndarray, np.ndarray]] = []  # made with the matrix
        self.master_blocks = np.asarray(masters, dtype=np.int32)
        self.copy_blocks = np.asarray(copies, dtype=np.int32)
        pairs = [
            (c * bs + k, m * bs + k)
            for m, c, ks in zip(masters, copies, components, strict=True)
            for k in ks
        ]
        self.copies = np.array([c for c, _ in pairs], dtype=np.int32)
        self.masters = np.array([m for _, m in pairs], dtype=np.int32)
        held = np.concatenate(
            [np.zeros(0, dtype=np.int32)]
            + [bc.dof_indices()[0][: bc.dof_indices()[1]] for bc in bcs]
        )
        #: the pairs whose master's row takes its copy's (C.1): its master not held
        self.added = ~np.isin(self.masters, held)
        offset = V.dofmap.index_map.local_range[0] * bs
        self._global_copies = (self.copies + offset).astype(PETSc.IntType)
        self._global_masters = (self.masters + offset).astype(PETSc.IntType)
        self._offset = offset
        for joint in self.joints:
            joint.added = not np.isin(joint.master * bs + 3, held)

    def __len__(self) -> int:
        return len(self.copies)

    def create_matrix(self, form: fem.FormMetaClass) -> PETSc.Mat:
        """A BAIJ matrix of the bilinear ``form`` whose sparsity also holds the blocks
        (master, each block of the copy's cells) and (copy, master) that (C.1)-(C.2) fill.
        Its nonzero pattern is kept when rows are zeroed."""
        pattern = fem.create_sparsity_pattern(form)
        dofmap = self.V.dofmap
        cells = dofmap.list.array.reshape(-1, dofmap.dof_layout.num_dofs)
        blocks = []
        for master, copy in zip(self.master_blocks, self.copy_blocks, strict=True):
            neighbours = np.unique(cells[(cells == copy).any(axis=1)]).astype(np.int32)
            pattern.insert(np.array([master], dtype=np.int32), neighbours)
            pattern.insert(np.array([copy], dtype=np.int32), np.array([master], dtype=np.int32))
            blocks.append((master, neighbours))
        pattern.assemble()
        self._extra = [
            (np.array([master], dtype=PETSc.IntType), neighbours.astype(PETSc.IntType))
            for master, neighbours in blocks
        ] + [
            (np.array([copy], dtype=PETSc.IntType), np.array([master], dtype=PETSc.IntType))
            for (master, _), copy in zip(blocks, self.copy_blocks, strict=True)
        ]
        A = cpp.la.petsc.create_matrix(self.V.mesh.comm, pattern, "baij")
        A.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        return A

    def assemble_matrix(
        self, A: PETSc.Mat, form: fem.FormMetaClass, bcs: list, tangent: bool = False
    ) -> PETSc.Mat:
        """``form`` assembled into ``A`` (made by :meth:`create_matrix`, zeroed) with the
        Dirichlet rows and columns of ``bcs`` and the rows (C.1)-(C.2), (C.4)-(C.7) (with
        (C.8) if ``tangent``: Newton's Jacobian); returns A."""
        # a singledispatch overload (mat, form, bcs) DOLFINx's annotations do not show
        assemble_matrix(A, form, bcs=bcs)  # type: ignore[misc, arg-type]
        self.reserve(A)
        A.assemble()
        self.apply_matrix(A, tangent)
        return A

    def reserve(self, A: PETSc.Mat) -> None:
        """Explicit zeros into the blocks (C.1)-(C.2) fill, after an assembly into ``A`` and
        before its final assembly, which drops the preallocated entries nothing was set in:
        the rows' values then need no new nonzero (a malloc each)."""
        A.assemble(PETSc.Mat.AssemblyType.FLUSH)  # between DOLFINx's inserts and these adds
        for rows, cols in self._extra:
            zeros = np.zeros(len(rows) * len(cols) * self.bs * self.bs)
            A.setValuesBlockedLocal(rows, cols, zeros, addv=PETSc.InsertMode.ADD_VALUES)

    def apply_matrix(self, A: PETSc.Mat, tangent: bool = False) -> None:
        """(C.1)-(C.2) and the joints' (C.4)-(C.7) on the assembled matrix ``A`` (collective:
        every rank calls it; after :meth:`reserve` and A's final assembly); ``tangent``: A is
        Newton's Jacobian, which takes the reactions' derivatives (C.8) too (not a linear
        problem's matrix, the initial rates')."""
        rows = [A.getRow(int(c)) for c in self._global_copies[self.added]]
        base = self.bs * np.array([j.copy for j in self.joints], dtype=int) + self._offset
        olds = [[A.getRow(int(b + k)) for k in (3, 4, 5, 9, 10, 11)] for b in base]
        for m, (cols, vals) in zip(self._global_masters[self.added], rows, strict=True):
            A.setValues([m], cols, vals, addv=PETSc.InsertMode.ADD_VALUES)
        later = [
            self._joint_rows(A, joint, old, tangent)
            for joint, old in zip(self.joints, olds, strict=True)
        ]
        A.assemble()
        joint_rows = [r for rows_of in later for r, _, _ in rows_of]
        A.zeroRows(np.concatenate([self._global_copies, np.array(joint_rows, PETSc.IntType)]), 1.0)
        for c, m in zip(self._global_copies, self._global_masters, strict=True):
            A.setValue(int(c), int(m), -1.0, addv=PETSc.InsertMode.INSERT_VALUES)
        for rows_of in later:
            for row, cols, vals in rows_of:
                A.setValues([row], cols, vals, addv=PETSc.InsertMode.INSERT_VALUES)
        A.assemble()

    def frames(self, joint: Joint) -> tuple[np.ndarray, np.ndarray]:
        """The chart frames (A_a, A_b) at the joint's master and copy."""
        Q = self.chart()
        if Q is None:
            return np.eye(3), np.eye(3)
        return quaternion_frame(Q[joint.master]), quaternion_frame(Q[joint.copy])

    def _angles(self, joint: Joint, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(α_a, α_b) and (q_a, q_b) of the joint in the local values ``u``."""
        a, b = joint.master * self.bs, joint.copy * self.bs
        alpha = np.concatenate([u[a + 3 : a + 6], u[b + 3 : b + 6]])
        return alpha, np.concatenate([u[a + 9 : a + 12], u[b + 9 : b + 12]])

    def _joint_rows(self, A: PETSc.Mat, joint: Joint, copy_rows: list, tangent: bool) -> list:
        """The master's rows (C.4), (C.6) added into ``A`` (with their (C.8) terms if
        ``tangent``) from the copy's assembled rows ``copy_rows`` (its K rows, then its R
        rows: (columns, values) each); returns the copy's rows (C.5), (C.7) as (row,
        columns, values) to insert once its old rows are zeroed (global indices)."""
        bs, off = self.bs, self._offset
        a, b = joint.master * bs + off, joint.copy * bs + off
        frames = self.frames(joint)
        if tangent and joint.last is not None:  # at the last residual's state
            K_b, R_b, alpha, q, Cs, Ns, G = joint.last
        else:  # a linear problem's matrix (no reactions), or no residual yet
            alpha, q = self._angles(joint, self.state())
            K_b = R_b = np.zeros(3)
            Cs, Ns, G = joint.rows(alpha, q, K_b, R_b, frames)[4:]
        DK, DR = joint.tangent(alpha, q, K_b, R_b, frames) if tangent else (None, None)
        angles = np.array([a + 3, a + 4, a + 5, b + 3, b + 4, b + 5], dtype=PETSc.IntType)
        rates = angles + 6
        m = joint.count
        out = []
        for first, D, C, N in ((3, DK, Cs[0], Ns[0]), (9, DR, Cs[1], Ns[1])):
            old = copy_rows[:3] if first == 3 else copy_rows[3:]
            cols = np.concatenate([c for c, _ in old]).astype(PETSc.IntType)

            def combined(weights, extra=None, extra_cols=angles, old=old, cols=cols):
                values = np.concatenate([w * v for w, (_, v) in zip(weights, old, strict=True)])
                every = cols if extra is None else np.concatenate([cols, extra_cols])
                values = values if extra is None else np.concatenate([values, extra])
                unique, where = np.unique(every, return_inverse=True)
                summed = np.zeros(unique.size)
                np.add.at(summed, where, values)
                return unique.astype(PETSc.IntType), summed

            if joint.added:
                for i in range(3):
                    row_cols, row_vals = combined(C[i], None if D is None else D[i])
                    A.setValues([a + first + i], row_cols, row_vals, PETSc.InsertMode.ADD_VALUES)
            for i in range(m):  # the constraint (C.5) or its rate (C.7)
                if first == 3:
                    out.append((b + first + i, angles, G[i, :6]))
                else:
                    extra = np.zeros(6) if D is None else D[3 + i]
                    out.append(
                        (
                            b + first + i,
                            np.concatenate([rates, angles]),
                            np.concatenate([G[i, :6], extra]),
                        )
                    )
            for i in range(3 - m):  # the free turn's balance, N R_b
                extra = None if D is None else D[3 + m + i]
                out.append((b + first + m + i, *combined(N[i], extra)))
        return out

    def apply_vector(self, b: np.ndarray, u: np.ndarray | None) -> None:
        """(C.1)-(C.2) on the owned values ``b`` of an assembled vector, u the unknowns' local
        values (None: a linear problem's right-hand side, the initial rates', whose copies
        are to be their masters, the joints' rows (C.5), (C.7) differentiated in τ at the
        model's state :attr:`state`)."""
        added = self.added
        np.add.at(b, self.masters[added], b[self.copies[added]])
        if u is None:
            b[self.copies] = 0.0
        else:
            b[self.copies] = u[self.copies] - u[self.masters]
        bs = self.bs
        for joint in self.joints:
            state = self.state() if u is None else u
            alpha, q = self._angles(joint, state)
            ia, ib = joint.master * bs, joint.copy * bs
            K_b, R_b = b[ib + 3 : ib + 6].copy(), b[ib + 9 : ib + 12].copy()
            frames = self.frames(joint)
            to_K, K, to_R, R, Cs, Ns, G = joint.rows(alpha, q, K_b, R_b, frames)
            m = joint.count
            if u is None:  # the initial rates: (C.5), (C.7) differentiated in τ
                K[:m], R[:m] = joint.rate_rows(alpha, q, frames)
            else:  # the reactions at u, for the Jacobian's (C.8)
                joint.last = (K_b, R_b, alpha, q, Cs, Ns, G)
            if joint.added:
                b[ia + 3 : ia + 6] += to_K
                b[ia + 9 : ia + 12] += to_R
            b[ib + 3 : ib + 6], b[ib + 9 : ib + 12] = K, R

    def enforce(self, u: np.ndarray) -> None:
        """u_c = u_m in the unknowns' local values ``u``, and each joint's copy put on its
        joint (:meth:`Joint.enforce`): a guess, or a state a method combined from its stages
        (which meets nonlinear or time-dependent constraints only to its order)."""
        u[self.copies] = u[self.masters]
        for joint in self.joints:
            joint.enforce(u, self.bs, self.frames(joint))
