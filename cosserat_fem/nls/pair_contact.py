"""Contact between a node and a partner cell of the same rod (or structure), with Coulomb
friction or without, by rows of the Newton system (docs/contact.md, "Self contact"; the
geometry: cosserat_fem/rod/contact_search.py, cosserat_fem/rod/self_contact.py).

A pair is a node a (the slave) and a partner cell of nodes j (the master) with its closest
point x_b(ξ) = Σ N_j(ξ) x_j, gap g = |x_a − x_b| − r_a − r_b [m] and unit normal n (from the
partner to the node). With F_a the node's translational balance rows of the assembled residual
(cosserat_fem/nls/contact.py: the force the node lacks, in the rows' scaling), f_N = n·F_a and
c the augmentation, an active pair (f_N − c g/ℓ ≥ 0) replaces the node's rows [n; T] F_a:
without friction by

    [g/ℓ; T F_a]    (the gap closed, the tangential balance kept)                      (P.1)

carrying the reaction to the partner's nodes, each free node's balance rows

    F_j ← F_j + N_j(ξ) n f_N                                                          (P.2)

(the joints' (C.1), cosserat_fem/nls/constraints.py, with weights: Σ N_j = 1, so the partner
takes what the node is pushed with); with friction (μ_s > 0) by the obstacles' (K.2)-(K.3)
with the relative slip Δ = Δx_a − Σ N_j(ξ) Δx_j of the two centreline points since the
accepted state,

    stick: [g/ℓ; T Δ],   slip: [g/ℓ; T (P F_a − μ_k f_N s)],  s the direction of the trial
    P (F_a − c Δ)                                                                       (P.3)

and the whole force then to the partner, F_j ← F_j + N_j(ξ) F_a                       (P.4).

The Jacobian is the derivative of (P.1)-(P.4), with the closest point's (S.3): the slave's
rows gain the partner's position columns and the partner's rows the slave's, entries the
assembled pattern lacks (PETSc allocates them at the first insertion and keeps them). A node
is the slave of the pair whose partner lies before it along the rod (single pass: the other
direction's pairs are dropped), except at a sliding node (below).

A node may be pressed and carry other pairs' reactions at once (a chain of contacts: a loop
turning into a ply, three parts of the rod stacked). Its force is then the assembled one plus
what is passed to it,

    F̃_a = F_a + Σ_q N_a(ξ_q) R_q    (R_q the force (P.2)/(P.4) of each pair q whose
    partner cell holds a)                                                              (P.5)

and F̃_a takes F_a's place in (P.1)-(P.4). The pairs are taken by levels: a pair's level is
0 if nothing presses on its slave, else one more than the largest level of the pairs pressing
on it; each level reads F̃ with the reactions of the levels before and passes its own on
(each level one assembly of PETSc's Vec, and of the matrix, whose rows then carry the
reactions' derivatives: the Jacobian stays exact). On one rod a partner's nodes lie before its
slave along the rod, or hold a sliding node (whose cells' nodes are no slaves:
rod/self_contact.py), so the levels exist; pairs that press on each other in a cycle
(possible on a structure) are refused with their place.

A node whose positions a support holds has no rows as a slave, and a reaction onto it goes to
the support in the components the support holds (a part of the rod may then pass through a
fully held node: the sampled check between nodes does not look at the nodes themselves). A
node held in part (a sliding support: held across its axis, free along it) keeps the free
component of the reactions (P.2)/(P.4) in its balance row along the axis; it is no slave,
nor is any node of its cells, which the other parts' nodes press on instead
(rod/self_contact.py): a slave row there would read its normal force from its one free
balance row, f_N = F_e/(n·e), which a lateral contact (n ⊥ e) leaves undetermined.

Under MPI every rank holds every node's position (an Allgatherv an iterate: 24 bytes a node)
and finds the same pairs; each rank writes the rows of the slaves it owns, and the reactions
reach their owners by PETSc's assembly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.common.errors import SolverError
from cosserat_fem.nls.contact import (
    FREE,
    ROUNDOFF,
    SLIP,
    STICK,
    pressed,
    slip_derivative,
    tangent_bases,
    tangential,
    trial_force,
)

#: how deep [in radii] the rod's parts may pass through each other between the nodes before
#: a step is rejected (the issue's bound for a capstan's penetration: 1 % of the radius)
BETWEEN_NODES = 1e-2
#: how far [in ℓ] an iterate may move a node from the last accepted state, the nodes' mean
#: motion taken out, before its solve is taken as diverged and its step retried smaller. Every
#: node of a connected rod or structure of length ℓ lies within ℓ (1 + ε) of the nodes' mean
#: at strains ε, so whatever the step (a free rod's flight, a support's motion, a rotation) no
#: node moves more than 2 ℓ (1 + ε) relative to the mean; a diverging full Newton grows its
#: iterates geometrically (0.03, 0.07, 0.5, 42, 8e5 m on the thin plectoneme), each costing
#: the search a rebuild; docs/decisions.md, "A diverging iterate stops at 3 ℓ"
DIVERGED = 3.0


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
    """The rows (P.1)-(P.4) of the module docstring on the space ``V`` of a rod whose owned
    nodes are at ``rest`` [m] (owned, 3), ``held`` (owned, m) which of their solved positions a
    support holds (a node with any held has no rows as a slave; the reactions reach its free
    components only), ``places`` their arc lengths s [m]; ``geometry`` maps every node's position
    (global order, (N, 3)) to the :class:`Pairs` of nodes at most a margin from a partner;
    the slots and ``solved`` as :class:`~cosserat_fem.nls.contact.NodeContact`'s; the
    friction ``static_friction`` μ_s (0: none) and ``kinetic_friction`` μ_k (default μ_s)."""

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
        static_friction: float = 0.0,
        kinetic_friction: float | None = None,
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
        held = np.asarray(held, dtype=bool).reshape(owned, len(self.solved))
        #: every node's held positions (N, m), and whether any is held (no rows as a slave)
        self.held_slots_all = np.vstack(self.comm.allgather(held))
        self.held_all = self.held_slots_all.any(axis=1)
        self.places_all = np.concatenate(self.comm.allgather(np.asarray(places, dtype=float)))
        self.owned = owned
        #: PETSc's Vec of the owned layout that carries the reactions (P.2) to their owners
        self._reactions = PETSc.Vec().createMPI((owned * bs, PETSc.DECIDE), comm=self.comm)
        self._reactions.setOption(PETSc.Vec.Option.IGNORE_NEGATIVE_INDICES, True)
        #: each owned node's augmentation c as a slave (None until a Jacobian is seen:
        #: :meth:`apply_matrix`)
        self.c: np.ndarray | None = None
        rest_all = np.concatenate(self.comm.allgather(np.asarray(rest, dtype=float)))
        #: the active pairs at the last iterate and at the last accepted state, (slave, first
        #: partner node) global, and the rows' data of the last iterate
        self.active = np.zeros((0, 3), dtype=np.int64)
        self.accepted = np.zeros((0, 3), dtype=np.int64)
        #: Coulomb friction between the parts (P.3)-(P.4), or none (μ_s = 0)
        self.mu_s = static_friction
        self.mu_k = static_friction if kinetic_friction is None else kinetic_friction
        self.friction = static_friction > 0.0
        count = len(self.held_all)
        #: each node's state as a slave (FREE, STICK, SLIP) at the last iterate and accepted
        self.node_state = np.zeros(count, dtype=np.int8)
        self.node_accepted = np.zeros(count, dtype=np.int8)
        #: every node's position at the last accepted state [m] (the friction's history)
        self.x_old = rest_all.copy()
        #: the work friction between the parts dissipated [J] over the accepted states, and
        #: the normal forces' (the impacts' loss), as NodeContact's
        self.dissipated = 0.0
        self.impact_loss = 0.0
        self._rows: dict = {}
        self.least_gap = np.inf
        self.most = 0
        self.started = False
        self.most_changes = 0
        self.flipped = np.zeros(0, dtype=np.int64)
        #: every node's position at the last iterate [m] (None before one)
        self._x: np.ndarray | None = None
        #: whether the next iterate is a solve's first, and whether it forces the accepted
        #: pairs (:meth:`first_iterate`)
        self.first = False
        self.force_first = True
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
        """The global row indices of the balance ``slots`` (one per solved position) of the
        global ``nodes``; −1 where a support holds that position (PETSc drops negative
        indices: the support takes those reactions)."""
        rows = nodes[..., None] * self.bs + slots
        return np.where(self.held_slots_all[nodes], -1, rows).astype(PETSc.IntType)

    # -- the rows -------------------------------------------------------------------------
    def first_iterate(self, first: bool, force: bool = True) -> None:
        """Whether the next iterate is a Newton solve's first (set before the solve, cleared
        after it): there a slave keeps the partner cell it was accepted with at a concave
        corner (rod/self_contact.py), and with ``force`` the slaves pressed at the accepted
        state press whatever their test, in the state they were accepted in
        (:meth:`_press`)."""
        self.first, self.force_first = first, force

    def apply_vector(self, b: np.ndarray, u: np.ndarray) -> bool:
        """Decide the pairs and their states at the iterate (u, F = ``b``, the owned values of
        the assembled residual) and write (P.1)-(P.2) into ``b`` ((P.3)-(P.4) with
        friction), level by level (P.5); whether the active set or a state changed on any
        rank since the last iterate (collective)."""
        first, self.first = self.first, False
        self._x = self.everywhere(u)
        step = self._x - self.x_old  # every rank: the same answer
        moved = np.linalg.norm(step - step.mean(axis=0), axis=1) if len(step) else step[:, 0]
        far = int(np.argmax(moved)) if len(moved) else 0
        if len(moved) and moved[far] > DIVERGED * self.ell:
            raise SolverError(
                f"self contact: an iterate moved the node at s = {self.places_all[far]:.4g} m "
                f"{moved[far]:.3g} m from the accepted state relative to the nodes' mean, more "
                f"than {DIVERGED:g} ℓ (a diverging solve)",
                where="contact",
                retry=True,
            )
        # the pressed pairs (slave, partner's first node) a slave keeps at a concave corner
        # (rod/self_contact.py), every rank's: each holds its own slaves' only
        pressing = (self.accepted if first else self.active)[:, :2]
        keep = np.concatenate(self.comm.allgather(pressing)).reshape(-1, 2)
        try:  # the same positions and pairs kept on every rank: the same answer, or error
            pairs = self.geometry(self._x, keep)
        except FloatingPointError as exc:  # a diverged iterate, a degenerate closest point
            raise SolverError(f"self contact: {exc}", where="contact", retry=True) from None
        mine = (pairs.slave >= self.start) & (pairs.slave < self.start + self.owned)
        mine &= ~self.held_all[pairs.slave]
        level = self._levels(pairs)  # the same on every rank
        zero = ROUNDOFF * self.comm.allreduce(float(np.abs(b).max(initial=0.0)), op=MPI.MAX)
        parts = []
        for at in range(max(1, int(level.max(initial=0)) + 1)):
            here = np.flatnonzero(mine & (level == at))
            part = self._press(pairs, here, b, zero, first and self.force_first)
            self._pass_on(part, b)  # collective: the reactions before the next level reads
            part["level"] = np.full(len(part["local"]), at)
            parts.append(part)
        self._rows = r = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
        self.least_gap = self.comm.allreduce(float(pairs.gap[mine].min(initial=np.inf)), op=MPI.MIN)
        slave = r["local"] + self.start
        active = np.column_stack([slave, r["partner"][:, 0], r["state"]]).astype(np.int64)
        active = active[np.argsort(slave, kind="stable")]
        # a pair pressed against its test (a solve's first iterate) holds the solve too
        changed = not np.array_equal(active, self.active) or bool(r["forced"].any())
        self.flipped = slave if changed else slave[:0]
        self.active = active
        self.node_state[:] = FREE
        self.node_state[slave] = r["state"]
        return bool(self.comm.allreduce(changed, op=MPI.LOR))

    def _levels(self, pairs: Pairs) -> np.ndarray:
        """Each pair's level (P.5): 0 if no candidate pair (a node within the search's margin
        of a cell) has its slave in its partner cell, else one more than the largest level of
        those pairs (the longest chain of candidates that ends at it). Every partner node
        counts, its weight N_j(ξ) 0 or not: inside a P_k cell (k ≥ 2) a weight vanishes where
        its derivative does not, and the pair's Jacobian then adds to that node's rows.
        ContactChain if the candidates form a cycle (possible on a structure only: on one rod
        a partner's nodes lie before its slave along the rod, or the partner is a sliding
        node's cell, which holds no slave). The same on every rank (every rank has all
        pairs)."""
        count = len(pairs.slave)
        level = np.zeros(count, dtype=np.int64)
        pressing = ~self.held_all[pairs.slave]
        index = np.full(len(self.held_all), -1, dtype=np.int64)
        index[pairs.slave[pressing]] = np.flatnonzero(pressing)
        source, j = np.nonzero(np.broadcast_to(pressing[:, None], pairs.partner.shape))
        target = index[pairs.partner[source, j]]
        source, target = source[target >= 0], target[target >= 0]
        order = np.argsort(target, kind="stable")  # the edges by target: one reduceat a round
        source, target = source[order], target[order]
        heads = (
            np.flatnonzero(np.r_[True, target[1:] != target[:-1]])
            if len(target)
            else np.zeros(0, dtype=np.int64)
        )
        targets = target[heads]
        for _ in range(count + 1):  # the longest paths: at most count rounds without a cycle
            longer = level.copy()
            if len(targets):
                deepest = np.maximum.reduceat(level[source] + 1, heads)
                longer[targets] = np.maximum(level[targets], deepest)
            grew = longer != level
            if not grew.any():
                return level
            level = longer
        where = self.places_all[pairs.slave[grew]]
        raise ContactChain(
            f"parts of the rod lie on each other in a cycle at s = {where.min():.4g} to "
            f"{where.max():.4g} m (within 2r: a chain of contacts that could close): not "
            "supported"
        )

    def _press(
        self, pairs: Pairs, here: np.ndarray, b: np.ndarray, zero: float, first: bool
    ) -> dict:
        """The rows' data of the pairs ``here`` (this rank's slaves of one level) that press:
        their force F̃_a = ``b`` at the slaves' balance rows (the reactions of the levels
        before included, (P.5)), the states and (P.1)/(P.3)'s rows, which are written into
        ``b``; ``force`` is what (P.2)/(P.4) pass to the partner. At a solve's ``first``
        iterate a slave pressed at the accepted state presses whatever its test: the
        predictor's gaps (second order in the step along a curved partner) times c decide
        the test there, and on the thin plectoneme's ply they opened most pairs at once
        (docs/decisions.md, "A solve starts from the accepted contact set")."""
        solved = self.solved
        local = pairs.slave[here] - self.start
        n = pairs.normal[here][:, solved]
        F = b[self.pq[local]]
        fN = np.sum(n * F, axis=1)
        gs = pairs.gap[here] / self.ell
        c = np.zeros(len(local)) if self.c is None else self.c[local]
        on = pressed(fN, gs, None if self.c is None else c, zero)
        forced = np.zeros(len(on), dtype=bool)
        if first:
            forced = ~on & np.isin(pairs.slave[here], self.accepted[:, 0])
            on |= forced
        c = c[on]
        which = here[on]
        slave, partner, weights = pairs.slave[which], pairs.partner[which], pairs.weights[which]
        n, F, fN, gs = n[on], F[on], fN[on], gs[on]
        T, dT = tangent_bases(n)
        state = np.full(len(slave), SLIP, dtype=np.int8)  # frictionless: free to slide
        # the relative slip of the two centreline points since the accepted state (scaled)
        moved = (self._x - self.x_old)[:, solved] / self.ell
        slips = moved[partner]  # (m, k+1, solved)
        du = moved[slave] - np.einsum("mj,mjd->md", weights, slips)
        w, _, size, s = trial_force(F, n, du, c[:, None])
        if self.friction:
            sliding = (self.node_accepted[slave] == SLIP) | (self.node_state[slave] == SLIP)
            mu = np.where(sliding, self.mu_k, self.mu_s)
            pressure = fN - c * gs
            state = np.where((size < mu * pressure) | (size == 0.0), STICK, SLIP).astype(np.int8)
            # a pair pressed against its test (a first iterate) keeps its accepted state: its
            # pressure is negative there, which would make it slip and then read μ_k
            state = np.where(forced[on], self.node_accepted[slave], state).astype(np.int8)
            # (P.3): stick holds the relative slip, slip gives μ_k f_N against it
            v = np.where(
                (state == STICK)[:, None], du, tangential(F - self.mu_k * fN[:, None] * s, n)
            )
            force = F  # the whole force the slave lacks goes to the partner (P.4)
        else:
            v = F  # (P.1): the tangential balance kept
            force = n * fN[:, None]
        b[self.pq[local[on]]] = np.column_stack([gs, np.einsum("kij,kj->ki", T, v)])
        return dict(
            local=local[on],
            partner=partner,
            state=state,
            n=n,
            T=T,
            dT=dT,
            F=F,
            fN=fN,
            v=v,
            w=w,
            s=s,
            size=size,
            du=du,
            slips=slips,
            gap=pairs.gap[which],
            weights=weights,
            force=force,
            forced=forced[on],
            d_gap=pairs.d_gap[which][:, :, solved],
            d_normal=pairs.d_normal[which][:, solved][:, :, :, solved],
            d_weights=pairs.d_weights[which][:, :, :, solved],
        )

    def _pass_on(self, part: dict, b: np.ndarray) -> None:
        """(P.2)/(P.4): the reactions N_j R of the pairs ``part`` added to the partner nodes'
        balance rows in ``b``, on whichever rank owns them (collective)."""
        reactions = self._reactions
        reactions.zeroEntries()
        values = part["weights"][:, :, None] * part["force"][:, None, :]
        reactions.setValues(
            self._global_rows(part["partner"], self.balance_slots).ravel(),
            values.ravel(),
            addv=PETSc.InsertMode.ADD_VALUES,
        )
        reactions.assemble()
        b += reactions.getArray(readonly=True)

    def apply_matrix(self, A: PETSc.Mat) -> None:
        """The Jacobian rows of (P.1)-(P.4) at the pairs and states :meth:`apply_vector`
        decided, in the assembled ``A`` (collective; after its final assembly); each node's
        augmentation c as a slave: the largest |A| on the diagonal of its balance rows against
        its positions (the node's own stiffness scale, whatever the rod's direction), read
        before the rows change A; a node where all are 0 takes the largest c of the rod (c = 0
        would press it whatever its gap). Why each node its own: docs/decisions.md, "Self
        contact: node-to-cell rows", its "Each slave's own augmentation c"."""
        start = self.start * self.bs
        c = np.array(
            [
                np.abs(np.diag(A.getValues(qs.tolist(), xs.tolist()))).max()
                for qs, xs in zip(self.pq + start, self.px + start, strict=True)
            ]
        ).reshape(-1)
        largest = self.comm.allreduce(float(c.max(initial=0.0)), op=MPI.MAX)
        c[c == 0.0] = largest
        r = self._rows
        if not r:  # no residual seen yet: no pairs to write
            self.c = c
            return
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        levels = self.comm.allreduce(int(r["level"].max(initial=-1)) + 1, op=MPI.MAX)
        for at in range(levels):  # (P.5): a level's rows read the reactions passed to them
            pairs = np.flatnonzero(r["level"] == at)
            J, every, geo_at = self._gather(A, pairs)
            new, add = self._derivatives(pairs, J, geo_at) if len(pairs) else (J, J)
            for i, p in enumerate(pairs):
                q = (self.pq[r["local"][p]] + start).astype(PETSc.IntType)
                A.setValues(q, every[i], new[i], addv=PETSc.InsertMode.INSERT_VALUES)
            A.assemble()
            for i, p in enumerate(pairs):
                rows = self._global_rows(r["partner"][p], self.balance_slots)
                for j, q in enumerate(rows):
                    if (q >= 0).any():  # PETSc skips a held position's row (−1)
                        A.setValues(q, every[i], add[i, j], addv=PETSc.InsertMode.ADD_VALUES)
            A.assemble()
        self.c = c

    def _gather(self, A: PETSc.Mat, pairs: np.ndarray) -> tuple[np.ndarray, ...]:
        """The ``pairs``' slave rows of ``A`` over the union of their columns and the K
        points' positions: J (P, m, E), the columns ``every`` (P, E; −1 pads a pair's shorter
        list: PETSc skips negative columns) and where the positions' columns lie in them,
        ``geo_at`` (P, K m)."""
        r = self._rows
        m, k1 = len(self.solved), r["partner"].shape[1]
        gathered, columns, geo = [], [], []
        for p in pairs:
            a = int(r["local"][p])
            rows = [A.getRow(int(row)) for row in self.pq[a] + self.start * self.bs]
            nodes = np.concatenate([[a + self.start], r["partner"][p]])
            geo_cols = (nodes[:, None] * self.bs + self.position_slots[None, :]).ravel()
            gathered.append(rows)
            columns.append(np.unique(np.concatenate([c for c, _ in rows] + [geo_cols])))
            geo.append(geo_cols)
        E = max((len(c) for c in columns), default=0)
        every = np.full((len(pairs), E), -1, dtype=PETSc.IntType)
        J = np.zeros((len(pairs), m, E))
        geo_at = np.zeros((len(pairs), (k1 + 1) * m), dtype=np.int64)
        for i, (rows, cols, geo_cols) in enumerate(zip(gathered, columns, geo, strict=True)):
            every[i, : len(cols)] = cols
            for row, (c_i, v_i) in enumerate(rows):
                J[i, row, np.searchsorted(cols, c_i)] = v_i
            geo_at[i] = np.searchsorted(cols, geo_cols)
        return J, every, geo_at

    def _derivatives(
        self, pairs: np.ndarray, J: np.ndarray, geo_at: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The ``pairs``' new slave rows (P, m, E) and the rows each partner node adds (P, k+1,
        m, E) over E columns: their rows ``J`` (P, m, E) of the assembled matrix with the
        reactions passed to them (P.5), the K points' positions at the columns ``geo_at`` (P,
        K m). Each quantity's derivative is a row block over the E columns: dF̃ = J, dn =
        ℓ ∂n/∂x, dN_j = ℓ ∂N_j/∂x, dΔ of the relative slip."""
        r = {key: value[pairs] for key, value in self._rows.items()}
        P, m, E = J.shape
        n, T, dT, F, fN = r["n"], r["T"], r["dT"], r["F"], r["fN"]
        weights, k1 = r["weights"], r["weights"].shape[1]

        def placed(block: np.ndarray) -> np.ndarray:
            """A block (P, rows, K m) over the positions' columns, spread over the E."""
            out = np.zeros((P, block.shape[1], E))
            np.put_along_axis(out, np.broadcast_to(geo_at[:, None, :], block.shape), block, 2)
            return out

        dF = J
        dn = placed(self.ell * r["d_normal"].reshape(P, m, -1))
        dw = placed(self.ell * r["d_weights"].reshape(P, k1, -1))  # (P, k+1, E)
        dfN = np.einsum("pa,pae->pe", n, dF) + np.einsum("pa,pae->pe", F, dn)
        eye = np.eye(m)
        new = np.zeros((P, m, E))
        new[:, :1] = placed(r["d_gap"].reshape(P, 1, -1))  # ∂(g/ℓ)/∂u
        if not self.friction:  # (P.1): T F; (P.2): N_j n f_N
            dv = dF
            force = n * fN[:, None]
            dforce = n[:, :, None] * dfN[:, None, :] + fN[:, None, None] * dn
        else:
            force, dforce = F, dF
            # dΔ = du_a − Σ N_j du_j − Σ Δu_j dN_j (positions' columns: a, then the partner)
            block = np.zeros((P, m, k1 + 1, m))
            block[:, :, 0] = eye
            block[:, :, 1:] = -weights[:, None, :, None] * eye[None, :, None, :]
            dDelta = placed(block.reshape(P, m, -1))
            dDelta -= np.einsum("pjd,pje->pde", r["slips"], dw)
            dv = dDelta.copy()  # stick: the slip held
            slip = r["state"] != STICK
            if slip.any():  # (P.3): v = P F − μ_k f_N s
                c = np.zeros(P) if self.c is None else self.c[r["local"]]
                dv[slip] = slip_derivative(
                    n[slip],
                    F[slip],
                    r["w"][slip],
                    r["s"][slip],
                    r["size"][slip],
                    dF[slip],
                    dn[slip],
                    dDelta[slip],
                    c[slip][:, None, None],
                    self.mu_k,
                )
        new[:, 1:] = np.einsum("pjm,pme->pje", T, dv)
        new[:, 1:] += np.einsum("pjab,pa,pbe->pje", dT, r["v"], dn)
        add = weights[:, :, None, None] * dforce[:, None] + force[:, None, :, None] * dw[:, :, None]
        return new, add

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
        r = self._rows
        x = self.everywhere(u)  # collective
        if not initial:
            # the step's contact work −R·Δ [J] (Δ the relative motion of the two centreline
            # points), split as NodeContact.accept's: its part along n the impacts' loss, the
            # rest friction's; on every rank (a rank without slaves adds zeros)
            work = np.zeros(2)
            if len(r.get("local", ())):
                moved = (x - self.x_old)[:, self.solved] / self.ell
                du = moved[r["local"] + self.start]
                du -= np.einsum("mj,mjd->md", r["weights"], moved[r["partner"]])
                R = r["force"]
                scale = self.force_scale * self.ell
                normal = -np.sum(np.sum(r["n"] * R, axis=1) * np.sum(r["n"] * du, axis=1))
                work[:] = normal * scale, (-np.sum(R * du) - normal) * scale
            normal, tangential_work = self.comm.allreduce(work)
            self.impact_loss += float(normal)
            self.dissipated += float(tangential_work)
        self.x_old = x
        self.accepted = self.active.copy()
        self.node_accepted = self.node_state.copy()
        self.most = max(self.most, self.count())
        out = self.values.x.array.reshape(-1, 6)
        out[: self.owned] = 0.0
        if len(r.get("local", ())):
            a = r["local"]
            force = np.zeros((len(a), 3))
            force[:, self.solved] = r["force"] * self.force_scale
            out[a, :3] = force / self.shares[a, None]
            out[a, 3] = r["gap"]
            out[a, 4] = r["state"]
        self.values.x.scatter_forward()

    def _moved(self) -> tuple[int, int]:
        """The slaves that came into contact and those that left it since the accepted state,
        over the ranks (collective)."""
        now, before = set(self.active[:, 0].tolist()), set(self.accepted[:, 0].tolist())
        total = self.comm.allreduce(np.array([len(now - before), len(before - now)]))
        return int(total[0]), int(total[1])

    def _changes(self) -> int:
        """The slaves that came into or out of contact since the accepted state (collective)."""
        return sum(self._moved())

    def transitions(self) -> tuple[int, int]:
        """The slaves that came into contact and those that left it in the step just solved,
        over the ranks; (0, 0) in the first step (collective): NodeContact.transitions'."""
        return self._moved() if self.started else (0, 0)

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
            "pair_friction_work_J": self.dissipated,
            "pair_impact_loss_J": self.impact_loss,
            "least_pair_gap_m": self.least_gap,
        }

    def state_dict(self) -> dict:
        return {
            "pairs.active": self.active.copy(),
            "pairs.accepted": self.accepted.copy(),
            "pairs.c": np.full(self.owned, np.nan) if self.c is None else self.c.copy(),
            "pairs.most": np.array(self.most),
            "pairs.most_changes": np.array(self.most_changes),
            "pairs.started": np.array(self.started),
            "pairs.node_state": self.node_state.copy(),
            "pairs.node_accepted": self.node_accepted.copy(),
            "pairs.x_old": self.x_old.copy(),
            "pairs.dissipated": np.array(self.dissipated),
            "pairs.impact_loss": np.array(self.impact_loss),
        }

    def load_state_dict(self, state: dict) -> None:
        self.active = np.asarray(state["pairs.active"], dtype=np.int64).reshape(-1, 3).copy()
        self.accepted = np.asarray(state["pairs.accepted"], dtype=np.int64).reshape(-1, 3).copy()
        self.node_state = np.asarray(state["pairs.node_state"], dtype=np.int8).copy()
        self.node_accepted = np.asarray(state["pairs.node_accepted"], dtype=np.int8).copy()
        self.x_old = np.asarray(state["pairs.x_old"], dtype=float).copy()
        self.dissipated = float(state["pairs.dissipated"])
        self.impact_loss = float(state["pairs.impact_loss"])
        c = np.broadcast_to(np.asarray(state["pairs.c"], dtype=float), (self.owned,))
        self.c = None if np.isnan(c).all() else c.copy()  # an old checkpoint: one c for all
        self.most = int(state["pairs.most"])
        self.most_changes = int(state["pairs.most_changes"])
        self.started = bool(state["pairs.started"])


class PartlyHeld(SolverError):
    """The cells of two sliding supports' nodes touching (rod/self_contact.py): one line,
    where = "contact", not retried (as ContactChain)."""

    def __init__(self, reason: str):
        super().__init__(reason, where="contact")


class ContactChain(SolverError):
    """A contact configuration the rows do not support (pairs pressing on each other in a
    cycle; a node pressed onto the rod and onto an obstacle at once): one line, where =
    "contact", not retried (docs/decisions.md, "Self contact: node-to-cell rows"); one met
    only at a passing iterate stops the run too (statics halves the load step on any
    SolverError)."""

    def __init__(self, reason: str):
        super().__init__(reason, where="contact")
