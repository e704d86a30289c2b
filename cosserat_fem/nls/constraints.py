"""Dofs identified with others, by rows of the assembled system (docs/joints-design.md).

An :class:`Identification` ties pairs of dofs: the copy's value u_c equals its master's u_m
(a structure's joint, cosserat_fem/rod/structure.py, ties the copies of a node's vertex). The
unknowns keep both copies, and the Newton system J δ = F of the constrained problem is made
from the assembled one by row operations, for each pair (c, m):

    F_m ← F_m + F_c,       J_m,: ← J_m,: + J_c,:   (the copy's equation moved to its master)  (C.1)
    F_c ← u_c − u_m − o_c,  J_c,: ← e_cᵀ − e_mᵀ     (the constraint)                          (C.2)

with o_c the pair's offset (:attr:`Identification.offset`; zero but where a joint drives its
copy, set before each solve: cosserat_fem/rod/model.py JointDrive).

With u = P u_r (P the 0/1 prolongation: the copy takes its master's value) (C.1) is Pᵀ F and
Pᵀ J on the masters' rows, and a solution of the square system (C.1)-(C.2) is the solution of
the reduced system Pᵀ J P δ_r = Pᵀ F (its copies equal to their masters). A master held by a
Dirichlet condition keeps its row u_m − g: the support takes the copy's equation as a part of
its reaction. The matrix keeps its 12×12 blocks, so PETSc's blocked LU runs as without the
pairs; the blocks the rows add, (master, the copy's neighbours) and (copy, master), are in its
sparsity from the start (:meth:`create_matrix`). Linear constraints need nothing of the time
integrators: every state they combine satisfies them.

A pair's two dofs are owned by one rank (the structure's partitioner); each rank lists its own.
"""

from __future__ import annotations

import numpy as np
from dolfinx import cpp, fem
from dolfinx.fem.petsc import assemble_matrix
from petsc4py import PETSc


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
    ):
        self.bs = bs = V.dofmap.index_map_bs
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
        #: o_c of (C.2), per pair: u_c = u_m + o_c
        self.offset = np.zeros(len(pairs))
        offset = V.dofmap.index_map.local_range[0] * bs
        self._global_copies = (self.copies + offset).astype(PETSc.IntType)
        self._global_masters = (self.masters + offset).astype(PETSc.IntType)

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

    def assemble_matrix(self, A: PETSc.Mat, form: fem.FormMetaClass, bcs: list) -> PETSc.Mat:
        """``form`` assembled into ``A`` (made by :meth:`create_matrix`, zeroed) with the
        Dirichlet rows and columns of ``bcs`` and the rows (C.1)-(C.2); returns A."""
        # a singledispatch overload (mat, form, bcs) DOLFINx's annotations do not show
        assemble_matrix(A, form, bcs=bcs)  # type: ignore[misc, arg-type]
        self.reserve(A)
        A.assemble()
        self.apply_matrix(A)
        return A

    def reserve(self, A: PETSc.Mat) -> None:
        """Explicit zeros into the blocks (C.1)-(C.2) fill, after an assembly into ``A`` and
        before its final assembly, which drops the preallocated entries nothing was set in:
        the rows' values then need no new nonzero (a malloc each)."""
        A.assemble(PETSc.Mat.AssemblyType.FLUSH)  # between DOLFINx's inserts and these adds
        for rows, cols in self._extra:
            zeros = np.zeros(len(rows) * len(cols) * self.bs * self.bs)
            A.setValuesBlockedLocal(rows, cols, zeros, addv=PETSc.InsertMode.ADD_VALUES)

    def apply_matrix(self, A: PETSc.Mat) -> None:
        """(C.1)-(C.2) on the assembled matrix ``A`` (collective: every rank calls it; after
        :meth:`reserve` and A's final assembly)."""
        rows = [A.getRow(int(c)) for c in self._global_copies[self.added]]
        for m, (cols, vals) in zip(self._global_masters[self.added], rows, strict=True):
            A.setValues([m], cols, vals, addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()
        A.zeroRows(self._global_copies, diag=1.0)
        for c, m in zip(self._global_copies, self._global_masters, strict=True):
            A.setValue(int(c), int(m), -1.0, addv=PETSc.InsertMode.INSERT_VALUES)
        A.assemble()

    def apply_vector(self, b: np.ndarray, u: np.ndarray | None) -> None:
        """(C.1)-(C.2) on the owned values ``b`` of an assembled vector, u the unknowns' local
        values (None: the constraint rows o_c, a linear problem's right-hand side whose
        copies are to be their masters plus the offsets)."""
        added = self.added
        np.add.at(b, self.masters[added], b[self.copies[added]])
        if u is None:
            b[self.copies] = self.offset
        else:
            b[self.copies] = u[self.copies] - u[self.masters] - self.offset

    def enforce(self, u: np.ndarray) -> None:
        """u_c = u_m + o_c in the unknowns' local values ``u`` (a guess, or a state a method
        combined from its stages, which meets time-dependent offsets only to its order)."""
        u[self.copies] = u[self.masters] + self.offset
