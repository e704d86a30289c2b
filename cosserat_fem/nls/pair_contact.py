"""Frictionless contact between a node and a partner cell, by rows of the Newton system
(docs/contact.md, "Self contact"; the geometry: cosserat_fem/rod/contact_search.py).

A pair is a node a (the slave) and a partner cell of nodes j (the master) with its closest
point x_b(ξ) = Σ N_j(ξ) x_j, gap g = |x_a − x_b| − r_a − r_b [m] and unit normal n (from the
partner to the node). With F_a the node's translational balance rows of the assembled residual
(cosserat_fem/nls/contact.py: the force the node lacks, in the rows' scaling), f_N = n·F_a and
c the augmentation, an active pair (f_N − c g/ℓ ≥ 0) replaces the node's rows [n; T] F_a by

    [g/ℓ; T F_a]    (the gap closed, the tangential balance kept: no friction)        (P.1)

and carries the reaction to the partner's nodes, each free node's balance rows

    F_j ← F_j + N_j(ξ) n f_N                                                          (P.2)

(the joints' (C.1), cosserat_fem/nls/constraints.py, with weights: Σ N_j = 1, so the partner
takes what the node is pushed with). The Jacobian is the derivative of (P.1)-(P.2), with the
closest point's (S.3): the slave's rows gain the partner's position columns and the partner's
rows the slave's, entries the assembled pattern lacks (PETSc allocates them at the first
insertion and keeps them). A node is the slave of the pair whose partner lies before it
along the rod (single pass: the other direction's pairs are dropped); a node that carries a
partner's reaction and is itself pressed (a chain of contacts) is refused with its place, and
so is a slave held by a support.

Under MPI every rank holds every node's position (an Allgatherv an iterate: 24 bytes a node)
and finds the same pairs; each rank writes the rows of the slaves it owns, and the reactions
(P.2) reach their owners by PETSc's assembly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.common.errors import SolverError
from cosserat_fem.nls.contact import ROUNDOFF, TOUCHING, tangent_bases

#: how deep [in radii] the rod's parts may pass through each other between the nodes before
#: a step is rejected (the issue's bound for a capstan's penetration: 1 % of the radius)
BETWEEN_NODES = 1e-2


@dataclass(frozen=True)
class Pairs:
    """What the geometry answers for the nodes' current positions: each pair's ``slave`` (global
    node), ``partner`` (k+1 global nodes, dof order), and of their closest points the gap [m],
    the unit normal, the weights N_j(ξ), and the derivatives of these with respect to the
    K = k + 2 points' positions (contact_search.Sensitivities: gap (m, K, 3), normal
    (m, 3, K, 3), weights (m, k+1, K, 3))."""

    slave: np.ndarray
    partner: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    weights: np.ndarray
    d_gap: np.ndarray
    d_normal: np.ndarray
    d_weights: np.ndarray


class PairContact:
    """The rows (P.1)-(P.2) of the module docstring on the space ``V`` of a rod whose owned
    nodes are at ``rest`` [m] (owned, 3), ``held`` those whose positions a support holds,
    ``places`` their arc lengths s [m]; ``geometry`` maps every node's position (global
    order, (N, 3)) to the :class:`Pairs` of nodes at most a margin from a partner; the slots
    and ``solved`` as :class:`~cosserat_fem.nls.contact.NodeContact`'s."""

    def __init__(
        self,
        V: fem.FunctionSpace,
        rest: np.ndarray,
        held: np.ndarray,
        geometry,
        *,
        length: float,
        force_scale: float,
        position_slots: list,
        balance_slots: list,
        solved: list[int],
        places: np.ndarray,
        shares: np.ndarray,
        partly: np.ndarray | None = None,
    ):
        self.comm = V.mesh.comm
        bs = V.dofmap.index_map_bs
        self.bs = bs
        imap = V.dofmap.index_map
        owned = imap.size_local
        self.start = imap.local_range[0]
        self.rest, self.geometry = rest, geometry
        self.ell, self.force_scale, self.solved = length, force_scale, list(solved)
        self.position_slots = np.asarray(position_slots, dtype=np.int64)
        self.balance_slots = np.asarray(balance_slots, dtype=np.int64)
        self.px = np.arange(owned)[:, None] * bs + self.position_slots[None, :]
        self.pq = np.arange(owned)[:, None] * bs + self.balance_slots[None, :]
        self.held_all = np.concatenate(self.comm.allgather(np.asarray(held, dtype=bool)))
        self.places_all = np.concatenate(self.comm.allgather(np.asarray(places, dtype=float)))
        #: the nodes some of whose positions a support holds (a sliding node): no pair may
        #: press on or with them (:meth:`_check_partly`)
        partly = np.zeros(len(held), dtype=bool) if partly is None else partly
        self.partly_all = np.concatenate(self.comm.allgather(np.asarray(partly, dtype=bool)))
        self.owned = owned
        #: PETSc's Vec of the owned layout that carries the reactions (P.2) to their owners
        self._reactions = PETSc.Vec().createMPI((owned * bs, PETSc.DECIDE), comm=self.comm)
        self._reactions.setOption(PETSc.Vec.Option.IGNORE_NEGATIVE_INDICES, True)
        #: the augmentation c (None until a Jacobian is seen), as NodeContact's
        self.c: float | None = None
        #: the active pairs at the last iterate and at the last accepted state, (slave, first
        #: partner node) global, and the rows' data of the last iterate
        self.active = np.zeros((0, 2), dtype=np.int64)
        self.accepted = np.zeros((0, 2), dtype=np.int64)
        self._rows: dict = {}
        self.least_gap = np.inf
        self.most = 0
        self.started = False
        self.most_changes = 0
        self.flipped = np.zeros(0, dtype=np.int64)
        #: every node's position at the last iterate [m] (None before one)
        self._x: np.ndarray | None = None
        self.shares = shares
        #: the outputs, as NodeContact's: each slave's contact load [N/m], its gap [m] and 1
        #: while pressed (other nodes: zeros)
        element = V.ufl_element()
        space = fem.VectorFunctionSpace(V.mesh, (element.family(), element.degree()), dim=6)
        self.values = fem.Function(space, name="contact")

    def __len__(self) -> int:
        return self.owned

    def everywhere(self, u: np.ndarray) -> np.ndarray:
        """Every node's position [m] (global order, (N, 3)) at the unknowns' local values ``u``
        (collective)."""
        x = self.rest.copy()
        x[:, self.solved] += self.ell * u[self.px]
        return np.concatenate(self.comm.allgather(x))

    def _global_rows(self, nodes: np.ndarray, slots: np.ndarray) -> np.ndarray:
        """The global row indices of the ``slots`` of the global ``nodes``; held nodes' −1
        (PETSc drops negative indices: a support takes those reactions)."""
        rows = nodes[..., None] * self.bs + slots
        return np.where(self.held_all[nodes][..., None], -1, rows).astype(PETSc.IntType)

    # -- the rows -------------------------------------------------------------------------
    def apply_vector(self, b: np.ndarray, u: np.ndarray) -> bool:
        """Decide the pairs at the iterate (u, F = ``b``, the owned values of the assembled
        residual) and write (P.1)-(P.2) into ``b``; whether the active set changed on any rank
        since the last iterate (collective)."""
        self._x = self.everywhere(u)
        pairs = self.geometry(self._x)
        mine = (pairs.slave >= self.start) & (pairs.slave < self.start + self.owned)
        mine &= ~self.held_all[pairs.slave]
        local = pairs.slave[mine] - self.start
        solved = self.solved
        n = pairs.normal[mine][:, solved]
        F = b[self.pq[local]]
        fN = np.sum(n * F, axis=1)
        gs = pairs.gap[mine] / self.ell
        zero = ROUNDOFF * self.comm.allreduce(float(np.abs(b).max(initial=0.0)), op=MPI.MAX)
        if self.c is None:
            on = (gs < -TOUCHING) | ((gs <= TOUCHING) & (fN >= -zero))
        else:
            on = fN - self.c * gs >= -zero
        slave, partner = pairs.slave[mine][on], pairs.partner[mine][on]
        self._check_chains(slave, partner)
        self._check_partly(pairs, partner)
        which = np.flatnonzero(mine)[on]
        T, dT = tangent_bases(n[on])
        self._rows = dict(
            local=local[on],
            partner=partner,
            n=n[on],
            T=T,
            dT=dT,
            F=F[on],
            fN=fN[on],
            gap=pairs.gap[which],
            weights=pairs.weights[which],
            d_gap=pairs.d_gap[which][:, :, solved],
            d_normal=pairs.d_normal[which][:, solved][:, :, :, solved],
            d_weights=pairs.d_weights[which][:, :, :, solved],
        )
        self.least_gap = self.comm.allreduce(float(pairs.gap[mine].min(initial=np.inf)), op=MPI.MIN)
        # (P.2): the reactions N_j n f_N to the partner's nodes, on whichever rank owns them
        reactions = self._reactions
        reactions.zeroEntries()
        values = pairs.weights[which][:, :, None] * (n[on] * fN[on, None])[:, None, :]
        reactions.setValues(
            self._global_rows(partner, self.balance_slots).ravel(),
            values.ravel(),
            addv=PETSc.InsertMode.ADD_VALUES,
        )
        reactions.assemble()
        b += reactions.getArray(readonly=True)
        # (P.1)
        rows = np.column_stack([gs[on], np.einsum("kij,kj->ki", T, F[on])])
        b[self.pq[local[on]]] = rows
        active = np.column_stack([slave, partner[:, 0]]) if len(slave) else self.active[:0]
        changed = not np.array_equal(active, self.active)
        self.flipped = slave if changed else slave[:0]
        self.active = active
        return bool(self.comm.allreduce(changed, op=MPI.LOR))

    def _check_chains(self, slave: np.ndarray, partner: np.ndarray) -> None:
        """ContactChain (every rank) if an active slave also carries a partner's reaction."""
        slaves = np.concatenate(self.comm.allgather(slave))
        carriers = np.concatenate(self.comm.allgather(partner.ravel()))
        both = np.intersect1d(slaves, carriers)
        if both.size:
            where = self.places_all[both]
            raise ContactChain(
                f"a node pressed onto the rod also carries another's contact (a chain of "
                f"contacts) at s = {where.min():.4g} to {where.max():.4g} m: not supported yet"
            )

    def _check_partly(self, pairs: Pairs, partner: np.ndarray) -> None:
        """PartlyHeld (every rank) if an active pair's partner cell (``partner``, this rank's)
        has a node some of whose positions a support holds, or such a node touches a cell as a
        slave: its free components would lose the reaction, or it would have no rows."""
        partly = self.partly_all
        bad = partner[partly[partner].any(axis=1)].ravel() if len(partner) else partner.ravel()
        slaves = pairs.slave[partly[pairs.slave] & (pairs.gap <= TOUCHING * self.ell)]
        nodes = np.concatenate(self.comm.allgather(np.concatenate([bad, slaves])))
        nodes = nodes[partly[nodes]]
        if nodes.size:
            where = self.places_all[nodes]
            raise PartlyHeld(
                f"a part of the rod touches at s = {where.min():.4g} to {where.max():.4g} m, "
                "a node held in some of its positions (a sliding support): not supported yet"
            )

    def apply_matrix(self, A: PETSc.Mat) -> None:
        """The Jacobian rows of (P.1)-(P.2) at the pairs :meth:`apply_vector` decided, in the
        assembled ``A`` (collective; after its final assembly); the augmentation c as
        NodeContact's (the largest diagonal position entry of an owned free node over the
        ranks)."""
        free = np.flatnonzero(~self.held_all[self.start : self.start + self.owned])
        local_c = max(
            (
                abs(A.getValue(int(q), int(x)))
                for q, x in zip(
                    self.pq[free[:1], 0] + self.start * self.bs,
                    self.px[free[:1], 0] + self.start * self.bs,
                    strict=True,
                )
            ),
            default=0.0,
        )
        r = self._rows
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        count = len(r.get("local", ()))
        rows_out, adds = [], []
        for p in range(count):
            a = int(r["local"][p])
            q = self.pq[a] + self.start * self.bs
            gathered = [A.getRow(int(row)) for row in q]
            cols = gathered[0][0]
            J = np.array([vals for _, vals in gathered])  # (m, ncols)
            nodes = np.concatenate([[a + self.start], r["partner"][p]])
            geo_cols = (nodes[:, None] * self.bs + self.position_slots[None, :]).ravel()
            every = np.union1d(cols, geo_cols).astype(PETSc.IntType)
            at, geo_at = np.searchsorted(every, cols), np.searchsorted(every, geo_cols)
            m = len(q)
            n, T, dT, F, fN = r["n"][p], r["T"][p], r["dT"][p], r["F"][p], r["fN"][p]
            dn = self.ell * r["d_normal"][p].reshape(m, -1)  # ∂n/∂u (m, K m)
            # (P.1): the gap row ∂(g/ℓ)/∂u; the tangential rows T J + (∂T/∂n F) ∂n/∂u
            new = np.zeros((m, len(every)))
            new[0, geo_at] = r["d_gap"][p].ravel()
            new[1:, at] = T @ J
            new[1:, geo_at] += np.einsum("jab,a->jb", dT, F) @ dn
            rows_out.append((q, every, new))
            # (P.2): the partner's rows gain N_j n nᵀ J and ∂(N_j n f_N)/∂u
            dfN = np.zeros(len(every))
            dfN[at] = n @ J
            dfN[geo_at] += F @ dn
            weights = r["weights"][p]
            dw = self.ell * r["d_weights"][p].reshape(len(weights), -1)
            for j, node in enumerate(r["partner"][p]):
                if self.held_all[node]:
                    continue
                add = weights[j] * np.outer(n, dfN)
                add[:, geo_at] += fN * np.outer(n, dw[j]) + weights[j] * fN * dn
                adds.append((node * self.bs + self.balance_slots, every, add))
        for q, every, new in rows_out:
            A.setValues(q.astype(PETSc.IntType), every, new, addv=PETSc.InsertMode.INSERT_VALUES)
        A.assemble()
        for q, every, add in adds:
            A.setValues(q.astype(PETSc.IntType), every, add, addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()
        self.c = self.comm.allreduce(float(local_c), op=MPI.MAX) or None

    def interpenetration(self) -> tuple[str, str] | None:
        """(where, reason) if the rod's parts pass through each other between the nodes by
        more than :data:`BETWEEN_NODES` r at the last iterate, else None. The rows hold the
        gap at the nodes: parts that cross between their nodes (at an angle, on cells longer
        than ~2r) meet where no row looks. The same answer on every rank (every rank has
        every position)."""
        if self._x is None:
            return None
        gap, a, b = self.geometry.between_nodes(self._x)
        if gap >= -BETWEEN_NODES * self.geometry.radius:
            return None
        return (
            f"s = {a:.4g} m against s = {b:.4g} m",
            f"the rod passes through itself between its nodes, {-gap:.3g} m deep (the "
            "contact rows hold at the nodes; parts crossing between them need cells of "
            "about 2r there)",
        )

    # -- the history ----------------------------------------------------------------------
    def accept(self, u: np.ndarray, initial: bool = False) -> None:
        """The solved state ``u`` is kept: the changes of the step are counted."""
        if not initial:
            if self.started:
                self.most_changes = max(self.most_changes, self._changes())
            self.started = True
        self.accepted = self.active.copy()
        self.most = max(self.most, self.count())
        out = self.values.x.array.reshape(-1, 6)
        out[: self.owned] = 0.0
        r = self._rows
        if len(r.get("local", ())):
            a = r["local"]
            force = np.zeros((len(a), 3))
            force[:, self.solved] = r["n"] * (r["fN"] * self.force_scale)[:, None]
            out[a, :3] = force / self.shares[a, None]
            out[a, 3] = r["gap"]
            out[a, 4] = 1.0
        self.values.x.scatter_forward()

    def _changes(self) -> int:
        """The slaves that came into or out of contact since the accepted state (collective)."""
        now, before = set(self.active[:, 0].tolist()), set(self.accepted[:, 0].tolist())
        return int(self.comm.allreduce(len(now ^ before)))

    def count(self) -> int:
        """The active pairs over the ranks."""
        return int(self.comm.allreduce(len(self.active)))

    def unsettled(self) -> str:
        """Where the pairs changed at the last iterate, for a solve that failed (collective)."""
        where = self.places_all[self.flipped] if len(self.flipped) else np.zeros(0)
        count = self.comm.allreduce(int(where.size))
        if not count:
            return ""
        low = self.comm.allreduce(float(where.min(initial=np.inf)), op=MPI.MIN)
        high = self.comm.allreduce(float(where.max(initial=-np.inf)), op=MPI.MAX)
        return f"the self-contact pairs still changed at s = {low:.4g} to {high:.4g} m"

    def summary(self) -> dict:
        """summary.json's "contact" entries of the pairs."""
        return {
            "pairs_in_contact": self.count(),
            "most_pairs_in_contact": self.most,
            "least_pair_gap_m": self.least_gap,
        }

    def state_dict(self) -> dict:
        return {
            "pairs.active": self.active.copy(),
            "pairs.accepted": self.accepted.copy(),
            "pairs.c": np.array(np.nan if self.c is None else self.c),
            "pairs.most": np.array(self.most),
            "pairs.most_changes": np.array(self.most_changes),
            "pairs.started": np.array(self.started),
        }

    def load_state_dict(self, state: dict) -> None:
        self.active = np.asarray(state["pairs.active"], dtype=np.int64).reshape(-1, 2).copy()
        self.accepted = np.asarray(state["pairs.accepted"], dtype=np.int64).reshape(-1, 2).copy()
        c = float(state["pairs.c"])
        self.c = None if np.isnan(c) else c
        self.most = int(state["pairs.most"])
        self.most_changes = int(state["pairs.most_changes"])
        self.started = bool(state["pairs.started"])


class PartlyHeld(SolverError):
    """A pair at a node a sliding support holds in part: one line, where = "contact"."""

    def __init__(self, reason: str):
        super().__init__(reason, where="contact")


class ContactChain(SolverError):
    """A contact configuration the pair rows do not support (a chain of contacts): one line,
    where = "contact" (not retried: a smaller step meets it again)."""

    def __init__(self, reason: str):
        super().__init__(reason, where="contact")
