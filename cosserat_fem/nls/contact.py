"""Unilateral contact with Coulomb friction at nodes, by rows of the Newton system
(docs/contact.md; the design and its measurements: docs/contact-design.md).

At a node k that may touch, with positions x = r0 + ℓ u_x (u_x its scaled position
unknowns), gap g(x) [m] (≥ 0 outside, :class:`~cosserat_fem.rod.obstacles.Surface`), unit
normal n = ∇g and tangent basis T (rows spanning n's orthogonal complement), let F be the
node's translational balance rows of the assembled residual (the rows tested by the rates'
test functions, in the scaling where a nodal force P [N] is g0 P/ℓ). F is the force the node
lacks: with a contact force R the balance is F − R = 0, so at a node in contact R = F, with

    f_N = n·F ≥ 0 (pressure),   f_T = T F (friction),   Δu = u_x − u_x,old (since the last
    accepted state),  trial t = P (F − c Δu), P = I − n nᵀ  (c > 0: the augmentation),
    λ_N = f_N − c g/ℓ (the augmented pressure).

The Alart–Curnier conditions, decided anew at each Newton iterate (a semi-smooth Newton =
the primal-dual active set method, Hintermüller, Ito & Kunisch 2002), replace the node's
balance rows [n; T] F by

    free  (f_N − c g/ℓ < 0):      the rows as assembled (R = 0);                      (K.1)
    stick (|t| < μ λ_N, or t = 0): g/ℓ = 0 and T Δu = 0 (exact: no penetration, no creep); (K.2)
    slip  (otherwise):            g/ℓ = 0 and T (P F − μ_k f_N t/|t|) = 0              (K.3)

with μ = μ_s, or μ_k for a node that slid in the last accepted state or at the last iterate
(a sliding node sticks again when the force it needs drops below the kinetic limit; a node
that starts to slide within a solve does not stick again by the static one). The contact
force is the replaced rows' residual: no multiplier unknowns, the matrix keeps its blocks
(every new entry lies in the node's own block row). The Jacobian rows are the generalized
derivative of (K.2)-(K.3), with the obstacle's curvature ∂n/∂u = ℓ ∇²g and the tangent
basis's turn with n. A solve is converged only when its active set stopped changing
(``hold``: the C stop rule's flag, cosserat_fem/nls/newton_loop.c ``cf_test``), and by the
update test only with ‖F‖ ≤ ‖F0‖ (``guard``: a rigid slide that no stuck node holds drifts
with shrinking relative updates, which is no answer).

The node's slip is its centreline's: the friction acts at the centreline (no moment about
it; docs/contact.md "Limits").
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.common.errors import SolverError
from cosserat_fem.common.rotations import cross_matrix

FREE, STICK, SLIP = 0, 1, 2
#: |g|/ℓ below which a node touches before the augmentation is known (the round-off of a
#: position placed on a surface is ~1e-16 ℓ)
TOUCHING = 1e-12
#: a force below this times the residual's largest entry is round-off (a zero pressure)
ROUNDOFF = 1e-12


def tangent_bases(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal rows T (len(n), m − 1, m) spanning each unit normal's complement in R^m
    (m = 2: n turned by a right angle; m = 3: t1 from the axis e that n is furthest from,
    a = e − (e·n) n, t1 = a/|a|, t2 = n × t1), and their derivatives ∂T_j/∂n
    (len(n), m − 1, m, m)."""
    count, m = n.shape
    if m == 2:
        turn = np.array([[0.0, -1.0], [1.0, 0.0]])
        return (n @ turn.T)[:, None, :], np.broadcast_to(turn, (count, 1, 2, 2)).copy()
    e = np.zeros_like(n)
    e[np.arange(count), np.argmin(np.abs(n), axis=1)] = 1.0
    en = np.sum(e * n, axis=1)
    a = e - en[:, None] * n
    size = np.linalg.norm(a, axis=1)
    t1 = a / size[:, None]
    t2 = np.cross(n, t1)
    eye = np.eye(3)
    da = -(n[:, :, None] * e[:, None, :] + en[:, None, None] * eye)
    dt1 = ((eye - t1[:, :, None] * t1[:, None, :]) @ da) / size[:, None, None]
    dt2 = -cross_matrix(t1) + cross_matrix(n) @ dt1
    return np.stack([t1, t2], axis=1), np.stack([dt1, dt2], axis=1)


def tangential(v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """P v = v − (n·v) n of each row (the part in the tangent plane of the unit normal n)."""
    return v - np.sum(n * v, axis=1)[:, None] * n


def pressed(
    fN: np.ndarray, gs: np.ndarray, c: float | np.ndarray | None, zero: float
) -> np.ndarray:
    """Whether each node is in contact (K.1): its augmented pressure f_N − c g/ℓ ≥ 0 (``gs``
    = g/ℓ; a force of ``zero`` is round-off), or before any Jacobian (c None) through the
    obstacle, or touching to round-off and pressed (a touching node not pulled away stays:
    f_N = 0 at a touching node holds it)."""
    if c is None:
        return (gs < -TOUCHING) | ((gs <= TOUCHING) & (fN >= -zero))
    return fN - c * gs >= -zero


def augmentation(A: PETSc.Mat, rows: np.ndarray, cols: np.ndarray, comm) -> float | None:
    """The augmentation c of (K.1)-(K.3): the largest |A| at the owned (row, column) pairs
    given, the contact nodes' first balance row against their first position (the stiffness
    scale of the rows), over the ranks, so the same c serially and under MPI; None if all
    are 0 (collective)."""
    local = max(
        (abs(A.getValue(int(r), int(c))) for r, c in zip(rows, cols, strict=True)), default=0.0
    )
    return comm.allreduce(float(local), op=MPI.MAX) or None


def trial_force(
    F: np.ndarray, n: np.ndarray, du: np.ndarray, c: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The Coulomb trial of (K.2)-(K.3) for each row of forces ``F`` the nodes lack, unit
    normals ``n`` and slips ``du`` since the accepted state: w = F − c Δu (c one for all, or
    a column of each node's), t = P w, |t| and its direction s (0 where t = 0)."""
    w = F - c * du
    trial = tangential(w, n)
    size = np.linalg.norm(trial, axis=1)
    s = np.divide(trial, size[:, None], out=np.zeros_like(trial), where=size[:, None] > 0)
    return w, trial, size, s


def slip_derivative(
    n: np.ndarray,
    F: np.ndarray,
    w: np.ndarray,
    s: np.ndarray,
    size: np.ndarray,
    dF: np.ndarray,
    dn: np.ndarray,
    dslip: np.ndarray,
    c: float | np.ndarray,
    mu_k: float,
) -> np.ndarray:
    """The derivative (K, m, E) of the slip rows' v = P F − μ_k f_N s (K.3), s = t/|t|,
    t = P(F − c Δ), at K nodes (or contact points) with ``n``, ``F``, ``w``, ``s``, ``size``
    of :func:`trial_force`, given the derivatives over E columns of F, n and the slip Δ
    (each (K, m, E)), c one for all or (K, 1, 1): with P = I − n nᵀ, f_N = n·F,

        d(P F) = P dF − f_N dn − n (F·dn),   df_N = n·dF + F·dn,
        dt = P (dF − c dΔ) − (n·w) dn − n (w·dn),   ds = (I − s sᵀ) dt/|t|,
        dv = d(P F) − μ_k (s df_N + f_N ds)."""
    m = n.shape[1]
    eye = np.eye(m)
    fN = np.sum(n * F, axis=1)
    P = eye - n[:, :, None] * n[:, None, :]
    F_dn = np.einsum("ka,kac->kc", F, dn)
    dPF = P @ dF - fN[:, None, None] * dn - n[:, :, None] * F_dn[:, None, :]
    dfN = np.einsum("ka,kac->kc", n, dF) + F_dn
    nw = np.sum(n * w, axis=1)
    w_dn = np.einsum("ka,kac->kc", w, dn)
    dt = P @ (dF - c * dslip) - nw[:, None, None] * dn - n[:, :, None] * w_dn[:, None, :]
    safe = np.where(size > 0, size, 1.0)
    ds = (eye - s[:, :, None] * s[:, None, :]) @ dt / safe[:, None, None]
    ds[size == 0] = 0.0  # frictionless: no direction
    return dPF - mu_k * (s[:, :, None] * dfN[:, None, :] + fN[:, None, None] * ds)


class NodeContact:
    """The rows (K.1)-(K.3) of the module docstring at the owned node ``blocks`` of ``V``,
    their rest positions ``rest`` [m] (len(blocks), 3), ``surface`` x ↦ (g, ∇g, ∇²g),
    ``length`` ℓ [m], ``force_scale`` the newtons of a unit of a balance row (ℓ/g0),
    ``shares`` each node's share of the length ℓ ∫ φ_k dσ [m], the slots
    in a block of the solved positions and of their balance rows, ``solved`` the fixed-basis
    components they are (0, 1, 2 or a plane's two), the friction coefficients; ``places`` each
    node's arc length s [m] (for messages); ``max_changes`` the most nodes that may come into
    or out of contact in an accepted step (0: any number; :meth:`step_changes`)."""

    def __init__(
        self,
        V: fem.FunctionSpace,
        blocks: np.ndarray,
        rest: np.ndarray,
        surface,
        *,
        length: float,
        force_scale: float,
        shares: np.ndarray,
        position_slots: list,
        balance_slots: list,
        solved: list[int],
        static_friction: float,
        kinetic_friction: float,
        places: np.ndarray | None = None,
        max_changes: int = 0,
    ):
        bs = V.dofmap.index_map_bs
        self.comm = V.mesh.comm
        self.blocks, self.rest, self.surface = blocks, rest, surface
        self.ell, self.force_scale, self.solved = length, force_scale, list(solved)
        self.shares = shares
        self.mu_s, self.mu_k = static_friction, kinetic_friction
        self.places = np.zeros(len(blocks)) if places is None else np.asarray(places, float)
        self.max_changes = max_changes
        self._order = np.argsort(self.places, kind="stable")  # the nodes along the rod
        #: the nodes whose state changed at the last iterate (local indices)
        self.flipped = np.zeros(0, dtype=np.int64)
        #: whether a state was accepted after the initial one (the first step's contacts
        #: are not changes)
        self.started = False
        #: the most nodes that came into or out of contact in an accepted step
        self.most_changes = 0
        self.px = blocks[:, None] * bs + np.asarray(position_slots, dtype=np.int32)[None, :]
        self.pq = blocks[:, None] * bs + np.asarray(balance_slots, dtype=np.int32)[None, :]
        start = V.dofmap.index_map.local_range[0] * bs
        self._gx = (self.px + start).astype(PETSc.IntType)
        self._gq = (self.pq + start).astype(PETSc.IntType)
        count = len(blocks)
        #: each node's state at the last iterate and at the last accepted state (FREE, ...)
        self.state = np.zeros(count, dtype=np.int8)
        self.accepted = np.zeros(count, dtype=np.int8)
        #: the scaled positions at the last accepted state (the friction's history)
        self.u_old = np.zeros(self.px.shape)
        #: the augmentation c of the module docstring (None until a Jacobian is seen)
        self.c: float | None = None
        #: the contact force [N] on each node (fixed basis) and its gap [m], at the last iterate
        self.force = np.zeros((count, 3))
        self.gap = np.zeros(count)
        #: the work friction dissipated [J] over the accepted states (:meth:`accept`)
        self.dissipated = 0.0
        #: the energy the normal contact forces took [J] over the accepted states (:meth:`accept`)
        self.impact_loss = 0.0
        #: the most nodes in contact in an accepted state
        self.most = 0
        self._rows: dict = {}
        #: the outputs at the nodes of a Lagrange space like V's, 6 a node: the contact load
        #: [N/m] (the node's force over its share of the length, fixed basis), the gap [m],
        #: the state (0 free, 1 stick, 2 slip); filled by :meth:`accept` (nodes that cannot
        #: touch: zeros)
        element = V.ufl_element()
        space = fem.VectorFunctionSpace(V.mesh, (element.family(), element.degree()), dim=6)
        self.values = fem.Function(space, name="contact")

    def __len__(self) -> int:
        return len(self.blocks)

    def positions(self, u: np.ndarray) -> np.ndarray:
        """The nodes' positions x = r0 + ℓ u_x [m] (len, 3) at the unknowns' local values ``u``
        (the components a planar model does not solve stay at rest)."""
        x = self.rest.copy()
        x[:, self.solved] += self.ell * u[self.px]
        return x

    # -- the rows -------------------------------------------------------------------------
    def apply_vector(self, b: np.ndarray, u: np.ndarray) -> bool:
        """Decide each node's state at the iterate (u, F = ``b``: the owned values of the
        assembled residual, Dirichlet rows set) and replace its rows in ``b``; whether the
        set changed on any rank since the last iterate (collective)."""
        m = self.px.shape[1]
        g, normal, hessian = self.surface(self.positions(u))
        self._finite(g)
        n = normal[:, self.solved]
        curvature = hessian[:, self.solved][:, :, self.solved] * self.ell
        F = b[self.pq]
        fN = np.sum(n * F, axis=1)
        gs = g / self.ell
        c = self.c
        # a pressure of the forces' round-off counts as none (a touching, unloaded node stays)
        zero = ROUNDOFF * self.comm.allreduce(float(np.abs(b).max(initial=0.0)), op=MPI.MAX)
        active = pressed(fN, gs, c, zero)
        du = u[self.px] - self.u_old
        w, _, size, s = trial_force(F, n, du, 0.0 if c is None else c)
        # μ_k for a node sliding at the last accepted state or at the last iterate: a node
        # that starts to slide meets μ_k f_N and must not stick again by μ_s at once (with
        # μ_k < μ_s the onset would alternate stick and slip to the iteration limit)
        sliding = (self.accepted == SLIP) | (self.state == SLIP)
        mu = np.where(sliding, self.mu_k, self.mu_s)
        pressure = fN - (0.0 if c is None else c) * gs  # the augmented f_N: > 0 if active
        # at the cone's edge a node slides on (docs/contact-design.md), but a node neither
        # pressed nor pulled sticks (else a free rope's nodes would all be frictionless)
        holds = (size < mu * pressure) | (size == 0.0)
        state = np.where(active, np.where(holds, STICK, SLIP), FREE)
        state = state.astype(np.int8)
        self._chain(state, s, size - mu * pressure, mu * pressure)
        self.flipped = np.flatnonzero(state != self.state)
        changed = bool(self.flipped.size)
        self.state = state
        T, dT = tangent_bases(n)
        friction = F - self.mu_k * fN[:, None] * s
        # the tangential rows are T v: v = Δu (stick), P F − μ_k f_N s (slip)
        v = np.where((state == STICK)[:, None], du, tangential(friction, n))
        self._rows = dict(n=n, T=T, dT=dT, F=F, fN=fN, w=w, s=s, size=size, D=curvature, v=v)
        self.force.fill(0.0)
        self.force[:, self.solved] = np.where(active[:, None], F * self.force_scale, 0.0)
        self.gap = g
        # (K.2)-(K.3)
        on = state != FREE
        rows = np.zeros((len(state), m))
        rows[:, 0] = gs
        rows[:, 1:] = np.einsum("kij,kj->ki", T, v)
        b[self.pq[on]] = rows[on]
        return bool(self.comm.allreduce(changed, op=MPI.LOR))

    def _finite(self, g: np.ndarray) -> None:
        """SolverError on every rank if a node's gap is not finite (a surface's distance
        evaluated where it has none), with the least s [m] among such nodes (collective)."""
        bad = self.places[~np.isfinite(g)]
        where = self.comm.allreduce(float(bad.min(initial=np.inf)), op=MPI.MIN)
        if np.isfinite(where):
            raise SolverError(
                f"the obstacle's gap is not finite at s = {where:.4g} m (a surface's distance "
                "that has no value there)",
                where="contact",
                retry=True,
            )

    def _chain(
        self, state: np.ndarray, s: np.ndarray, excess: np.ndarray, capacity: np.ndarray
    ) -> None:
        """The chain predictor (docs/contact-design.md): a node that starts to slide (stuck at
        the last iterate) carried, as a support, the ``excess`` |t| − μ λ_N that its stuck
        neighbours along the rod will carry once it slides. Walking away from it, each stuck
        neighbour takes its ``capacity`` μ λ_N from the excess and is let slide (in the
        node's direction s) while the excess lasts. A prediction only: the next iterate's
        test sticks a node let go wrongly. Without it a slip front moves one node an
        iteration (the prototype: 80 iterations for a front over 60 nodes, 2 with it). Along
        this rank's nodes only: a front crossing ranks walks on at the next iterate."""
        started = np.flatnonzero((self.state == STICK) & (state == SLIP))
        if not started.size:
            return
        order = self._order
        where = np.empty_like(order)
        where[order] = np.arange(order.size)
        for k in started:
            for step in (-1, 1):
                left, j = excess[k], where[k] + step
                while 0 <= j < order.size and left > 0 and state[order[j]] == STICK:
                    left -= capacity[order[j]]
                    if left > 0:
                        state[order[j]], s[order[j]] = SLIP, s[k]
                    j += step

    def apply_matrix(self, A: PETSc.Mat) -> None:
        """The Jacobian rows of the states :meth:`apply_vector` decided, in the assembled
        ``A`` (collective; after its final assembly): each active node's balance rows
        overwritten on their own columns; the augmentation c taken from A's first
        position block (the largest over the ranks: the same c serially and under MPI)."""
        augmented = augmentation(A, self._gq[:, 0], self._gx[:, 0], self.comm)  # before inserts
        on = np.flatnonzero(self.state != FREE)
        gathered = [[A.getRow(int(q)) for q in self._gq[k]] for k in on]  # before any insert
        groups: dict[int, list[int]] = {}  # the nodes by their rows' length, done together
        for i, rows in enumerate(gathered):
            groups.setdefault(len(rows[0][0]), []).append(i)
        for members in groups.values():
            nodes = on[members]
            cols = np.array([gathered[i][0][0] for i in members])  # (K, ncols)
            J = np.array([[vals for _, vals in gathered[i]] for i in members])  # (K, m, ncols)
            at = np.array(
                [np.searchsorted(c, g) for c, g in zip(cols, self._gx[nodes], strict=True)]
            )
            assert np.array_equal(np.take_along_axis(cols, at, 1), self._gx[nodes]), "own block"
            new = self._jacobian_rows(nodes, J, at)
            for k, c, values in zip(nodes, cols, new, strict=True):
                A.setValues(self._gq[k], c, values, addv=PETSc.InsertMode.INSERT_VALUES)
        A.assemble()
        self.c = augmented

    def _jacobian_rows(self, nodes: np.ndarray, J: np.ndarray, at: np.ndarray) -> np.ndarray:
        """The new rows (K, m, ncols) of the active ``nodes`` whose assembled balance rows are
        ``J`` (K, m, ncols), their positions at the columns ``at`` (K, m): the derivatives of
        (K.2)-(K.3) (module docstring), all nodes at once."""
        r = {key: value[nodes] for key, value in self._rows.items()}
        K, m, _ = J.shape
        n, T, D, F = r["n"], r["T"], r["D"], r["F"]
        eye = np.eye(m)

        def positions(k: np.ndarray, lines: np.ndarray) -> tuple:
            """The index of the rows ``lines`` of the nodes ``k`` at their positions' columns."""
            return k[:, None, None], lines[None, :, None], at[k][:, None, :]

        every, tangent = np.arange(K), np.arange(1, m)
        new = np.zeros_like(J)
        new[positions(every, np.arange(1))] = n[:, None, :]  # the gap row: ∂(g/ℓ)/∂u = n
        # d(T v) = T dv + (∂T/∂n · v) ∂n/∂u, ∂n/∂u = D at the node's positions
        new[positions(every, tangent)] += np.einsum("kjab,ka,kbc->kjc", r["dT"], r["v"], D)
        stick = self.state[nodes] == STICK
        new[positions(np.flatnonzero(stick), tangent)] += T[stick]  # dv = dΔu
        slip = np.flatnonzero(~stick)
        if slip.size:  # (K.3): dv = d(P F − μ f_N s), n and Δu moving with the node's positions
            local = np.arange(slip.size)
            own = local[:, None, None], np.arange(m)[None, :, None], at[slip][:, None, :]
            dn = np.zeros_like(J[slip])
            dn[own] = D[slip]
            dslip = np.zeros_like(J[slip])
            dslip[own] = eye
            c = 0.0 if self.c is None else self.c
            dv = slip_derivative(
                n[slip], F[slip], r["w"][slip], r["s"][slip], r["size"][slip], J[slip], dn,
                dslip, c, self.mu_k,
            )  # fmt: skip
            new[slip, 1:, :] += T[slip] @ dv
        return new

    # -- a consistent initial rate (generalized-α) ---------------------------------------
    def touching(self, u: np.ndarray) -> np.ndarray:
        """The nodes (local indices) on an obstacle at the state ``u`` (|g| ≤ TOUCHING ℓ)."""
        g, _, _ = self.surface(self.positions(u))
        return np.flatnonzero(np.abs(g) <= TOUCHING * self.ell)

    def holds_rates(self) -> bool:
        """Whether :meth:`hold_rates` can make a consistent initial rate (always, for
        obstacles)."""
        return True

    def hold_rates(self, A: PETSc.Mat, b: np.ndarray, nodes: np.ndarray, u: np.ndarray) -> None:
        """In the linear system A U̇ = b of a consistent initial rate (rows tested as F's, so
        a node's balance rows A U̇ − b are the force R it lacks), the ``nodes``' balance rows
        [n; T] turned to: n·q̇ = 0 (a node resting on an obstacle does not accelerate into
        it), and T q̇ = 0 where the node does not slide (stuck), T R = −μ_k (n·R) T v̂ where
        it slides with the tangential velocity v (kinetic friction against it: linear in U̇)
        (collective; A assembled; ``b`` its owned values)."""
        _, normal, _ = self.surface(self.positions(u))
        n = normal[:, self.solved]
        T, _ = tangent_bases(n)
        v = tangential(u[self.pq], n)  # the nodes' tangential velocities
        speed = np.linalg.norm(v, axis=1)
        sliding = speed > TOUCHING * np.abs(u[self.pq]).max(initial=0.0) + 1e-300
        drag = np.zeros((len(speed), T.shape[1]))  # μ_k T v̂ of the sliding nodes
        drag[sliding] = self.mu_k * np.einsum(
            "kij,kj->ki", T[sliding], v[sliding] / speed[sliding, None]
        )
        gathered = [[A.getRow(int(q)) for q in self._gq[k]] for k in nodes]
        for k, rows in zip(nodes, gathered, strict=True):
            cols = rows[0][0]
            J = np.array([vals for _, vals in rows])
            at = np.searchsorted(cols, self._gq[k])  # the rates of q at their columns
            new = np.zeros_like(J)
            new[0, at] = n[k]
            if sliding[k]:
                new[1:] = T[k] @ J + np.outer(drag[k], n[k] @ J)
            else:
                new[1:, at] = T[k]
            A.setValues(self._gq[k], cols, new, addv=PETSc.InsertMode.INSERT_VALUES)
        A.assemble()
        rows = b[self.pq[nodes]]
        b[self.pq[nodes, 0]] = 0.0
        along = np.einsum("kij,kj->ki", T[nodes], rows)
        along += drag[nodes] * np.sum(n[nodes] * rows, axis=1)[:, None]
        b[self.pq[nodes, 1:]] = np.where(sliding[nodes, None], along, 0.0)

    def normal_reactions(self, r: np.ndarray, nodes: np.ndarray, u: np.ndarray) -> np.ndarray:
        """n·r at the ``nodes``' balance rows of ``r`` (owned values of A U̇ − b of the system
        without :meth:`hold_rates`): the obstacle's push (> 0) or pull (< 0) that holds them."""
        _, normal, _ = self.surface(self.positions(u))
        n = normal[nodes][:, self.solved]
        return np.sum(n * r[self.pq[nodes]], axis=1)

    # -- the history ----------------------------------------------------------------------
    def accept(self, u: np.ndarray, initial: bool = False) -> None:
        """The solved state ``u`` is kept (a load step, a time step; ``initial``: the state a
        solve starts from): the friction's history moves to it, and the work of the contact
        forces over the step is added to the counters, split along the normal n at ``u``:

            W = Σ_k R_k · Δx_k,   Δx_k = ℓ (u_x − u_x,old) at node k,                     (W.1)
            :attr:`impact_loss` += −Σ_k (n·R_k)(n·Δx_k),
            :attr:`dissipated` += −Σ_k (R_k − (n·R_k) n)·Δx_k      (friction, ≥ 0 a sliding
            node; 0 at a stuck one, whose row T Δu = 0 holds),

        with R_k the force of the step's solve (the replaced rows' residual at its last
        iterate: at the step's end for BDF2, at generalized-α's α_f point, 0 at a free node)
        and Δx over the whole step: one force a step, not a trapezoid of two steps' forces.
        Why: the midpoint rule (generalized-α at ρ∞ = 1) solves M (v₁ − v₀)/h = f(x_m) + R
        with Δx = h (v₀ + v₁)/2, so ½ v₁ᵀM v₁ − ½ v₀ᵀM v₀ = (f(x_m) + R)·Δx exactly, at an
        impact too (v jumps within the step; the impulse's work is R h at the mean velocity,
        Kelvin's theorem), and E(t) + W_friction + W_impact + W_damping − E(0) is the midpoint
        error of the elastic forces and the rotations, O(h³) a step (the positions are
        Lipschitz across impacts): O(h²) in all (tests/test_contact_energy.py). A trapezoid
        of consecutive forces would credit the landing step with half its impulse's work:
        an O(1) error an impact. For BDF2 and generalized-α at ρ∞ < 1 no quadrature of R
        closes the balance at an impact: their kinetic energy at a velocity jump Δv changes
        by O(Δvᵀ M Δv) more than any work of the force (their numerical dissipation, or
        gain, of the jump), which no counter holds (docs/contact.md, "The dropped rod's
        energy"). On a plane n·Δx = Δg: the normal work is −R_N g_old at the step a node
        lands (g = 0 at both ends after it)."""
        if initial:  # no iterate yet: the gaps of the state, no force, no step's work
            self.gap = self.surface(self.positions(u))[0]
        else:
            if self.started:
                self.most_changes = max(self.most_changes, self._changes()[0])
            self.started = True
            dx = np.zeros((len(self), 3))
            dx[:, self.solved] = self.ell * (u[self.px] - self.u_old)
            n = self.surface(self.positions(u))[1]
            normal = np.sum(n * self.force, axis=1) * np.sum(n * dx, axis=1)
            work = np.array([np.sum(normal), np.sum(self.force * dx)])  # (W.1): normal, whole
            normal_work, whole = self.comm.allreduce(work)
            self.impact_loss -= float(normal_work)
            self.dissipated -= float(whole - normal_work)
        self.u_old = u[self.px].copy()
        self.accepted = self.state.copy()
        self.most = max(self.most, self.counts()["contact"])
        out = self.values.x.array.reshape(-1, 6)
        out[self.blocks, :3] = self.force / self.shares[:, None]
        out[self.blocks, 3] = self.gap
        out[self.blocks, 4] = self.state
        self.values.x.scatter_forward()

    def _changes(self) -> tuple[int, float, float]:
        """The nodes that came into or out of contact since the accepted state, over the ranks,
        and the least and largest s [m] among them (collective)."""
        moved = (self.state != FREE) != (self.accepted != FREE)
        places = self.places[moved]
        count = self.comm.allreduce(int(moved.sum()))
        low = self.comm.allreduce(float(places.min(initial=np.inf)), op=MPI.MIN)
        high = self.comm.allreduce(float(places.max(initial=-np.inf)), op=MPI.MAX)
        return count, low, high

    def step_changes(self) -> tuple[str, str] | None:
        """(where, reason) if more than ``max_changes`` nodes came into or out of contact in
        the step just solved (not the first step: its contacts are the initial ones), else
        None (collective). A smaller step splits such changes when they are successive (an
        impact front), not when they are simultaneous (a flat rod landing flat)."""
        if not self.max_changes or not self.started:
            return None
        count, low, high = self._changes()
        if count <= self.max_changes:
            return None
        return (
            f"s = {low:.4g} to {high:.4g} m",
            f"{count} nodes came into or out of contact in one step, more than "
            f"contact.max_changes = {self.max_changes}",
        )

    def transitions(self) -> tuple[int, int]:
        """The nodes that came into contact and those that left it in the step just solved
        (since the accepted state), over the ranks; (0, 0) in the first step, whose contacts
        are the initial ones (collective). The time loop takes midpoint steps around an
        impact by them (cosserat_fem/timestepping/loop.py, "Impacts")."""
        if not self.started:
            return 0, 0
        came = np.sum((self.state != FREE) & (self.accepted == FREE))
        left = np.sum((self.state == FREE) & (self.accepted != FREE))
        total = self.comm.allreduce(np.array([came, left], dtype=np.int64))
        return int(total[0]), int(total[1])

    def unsettled(self) -> str:
        """Where the set changed at the last iterate, for a solve that failed (collective):
        "" if it did not change."""
        places = self.places[self.flipped]
        count = self.comm.allreduce(int(places.size))
        if not count:
            return ""
        low = self.comm.allreduce(float(places.min(initial=np.inf)), op=MPI.MIN)
        high = self.comm.allreduce(float(places.max(initial=-np.inf)), op=MPI.MAX)
        return f"the contact set still changed at {count} nodes, s = {low:.4g} to {high:.4g} m"

    def counts(self) -> dict[str, int]:
        """The nodes in contact, sticking and sliding, over the ranks."""
        local = np.array(
            [np.sum(self.state != FREE), np.sum(self.state == STICK), np.sum(self.state == SLIP)]
        )
        total = self.comm.allreduce(local)
        return {"contact": int(total[0]), "stick": int(total[1]), "slip": int(total[2])}

    def summary(self) -> dict:
        """summary.json's "contact": the nodes in contact, sticking and sliding at the last
        iterate, the most in contact in an accepted state, the friction's work
        ``friction_work_J`` and the impacts' energy loss ``impact_loss_J`` [J] (the normal
        forces' work, negated; :meth:`accept`: −(their sum) is the contact's whole work)."""
        return {
            **{f"nodes_{k}": v for k, v in self.counts().items()},
            "most_nodes_in_contact": self.most,
            "most_changes_in_a_step": self.most_changes,
            "friction_work_J": self.dissipated,
            "impact_loss_J": self.impact_loss,
        }

    def state_dict(self) -> dict:
        return {
            "contact.state": self.state.copy(),
            "contact.accepted": self.accepted.copy(),
            "contact.u_old": self.u_old.copy(),
            "contact.c": np.array(np.nan if self.c is None else self.c),
            "contact.dissipated": np.array(self.dissipated),
            "contact.impact_loss": np.array(self.impact_loss),
            "contact.most": np.array(self.most),
            "contact.most_changes": np.array(self.most_changes),
            "contact.started": np.array(self.started),
        }

    def load_state_dict(self, state: dict) -> None:
        self.state = np.asarray(state["contact.state"], dtype=np.int8).copy()
        self.accepted = np.asarray(state["contact.accepted"], dtype=np.int8).copy()
        self.u_old = np.asarray(state["contact.u_old"], dtype=float).copy()
        c = float(state["contact.c"])
        self.c = None if np.isnan(c) else c
        self.dissipated = float(state["contact.dissipated"])
        # a checkpoint from before the impacts' counter (2026-12-05): none counted yet
        self.impact_loss = float(state.get("contact.impact_loss", 0.0))
        self.most = int(state["contact.most"])
        self.most_changes = int(state["contact.most_changes"])
        self.started = bool(state["contact.started"])
