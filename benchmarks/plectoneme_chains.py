# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---
# %% [markdown]
# # A prototype of chains of contacts, for the plectoneme (one-off; docs/plectoneme.md)
#
# The self-contact rows (cosserat_fem/nls/pair_contact.py) refuse a node that is pressed onto
# the rod and also carries another node's contact. This prototype, serial and on one member
# only, passes the reactions on in order instead: the pairs are taken by their slave's arc
# length, last first; a slave's force is its assembled rows plus the reactions already
# passed to it, F̃_a = F_a + Σ_q N_a^q n_q f_N^q, so that its f_N = n·F̃_a and its rows
# [g/ℓ; T F̃_a] (P.1) see the pairs that press on it, and its own reaction (P.2) goes on to
# its partner's nodes. A partner's nodes lie before the slave along the rod, so the order is
# a topological one. The Jacobian follows the same order, each slave's rows taken with the
# derivatives of the reactions passed to it. It patches ``PairContact`` in this process
# only (:func:`allow_chains`), for measuring what the rows would give:
#
#     .venv/bin/python benchmarks/plectoneme_chains.py [cells ...]     # default 64
# %%
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.nls.contact import ROUNDOFF, TOUCHING, tangent_bases
from cosserat_fem.nls.pair_contact import PairContact

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _apply_vector(self: PairContact, b: np.ndarray, u: np.ndarray) -> bool:
    """(P.1)-(P.2) with the reactions passed on in order (module docstring); serial."""
    assert self.comm.size == 1, "the prototype is serial"
    self._x = self.everywhere(u)
    pairs = self.geometry(self._x)
    keep = np.flatnonzero(~self.held_all[pairs.slave])
    keep = keep[np.argsort(-self.places_all[pairs.slave[keep]], kind="stable")]
    solved = self.solved
    zero = ROUNDOFF * float(np.abs(b).max(initial=0.0))
    chosen, forces, normals_fN = [], [], []
    for k in keep:
        a = int(pairs.slave[k])
        n = pairs.normal[k][solved]
        F = b[self.pq[a]].copy()  # with the reactions passed to a so far
        fN = float(n @ F)
        g = pairs.gap[k] / self.ell
        if self.c is None:
            on = g < -TOUCHING or (g <= TOUCHING and fN >= -zero)
        else:
            on = fN - self.c * g >= -zero
        if not on:
            continue
        for j, node in enumerate(pairs.partner[k]):
            if not self.held_all[node]:
                b[self.pq[node]] += pairs.weights[k][j] * n * fN
        chosen.append(k)
        forces.append(F)
        normals_fN.append(fN)
    self._check_partly(pairs, pairs.partner[chosen] if chosen else pairs.partner[:0])
    which = np.array(chosen, dtype=np.int64)
    local = pairs.slave[which] - self.start
    n = pairs.normal[which][:, solved]
    T, dT = tangent_bases(n) if len(which) else (np.zeros((0, 2, 3)), np.zeros((0, 2, 3, 3)))
    F = np.array(forces).reshape(-1, len(solved))
    fN = np.array(normals_fN)
    self._rows = dict(
        local=local,
        partner=pairs.partner[which],
        n=n,
        T=T,
        dT=dT,
        F=F,
        fN=fN,
        gap=pairs.gap[which],
        weights=pairs.weights[which],
        d_gap=pairs.d_gap[which][:, :, solved],
        d_normal=pairs.d_normal[which][:, solved][:, :, :, solved],
        d_weights=pairs.d_weights[which][:, :, :, solved],
    )
    mine = ~self.held_all[pairs.slave]
    self.least_gap = float(pairs.gap[mine].min(initial=np.inf))
    for p in range(len(which)):
        b[self.pq[local[p]]] = np.concatenate([[pairs.gap[which[p]] / self.ell], T[p] @ F[p]])
    slave = pairs.slave[which]
    active = np.column_stack([slave, pairs.partner[which][:, 0]]) if len(slave) else self.active[:0]
    changed = not np.array_equal(active, self.active)
    self.flipped = slave if changed else slave[:0]
    self.active = active
    return changed


def _apply_matrix(self: PairContact, A: PETSc.Mat) -> None:
    """The Jacobian of :func:`_apply_vector`'s rows, in its order; serial."""
    free = np.flatnonzero(~self.held_all)
    local_c = abs(A.getValue(int(self.pq[free[0], 0]), int(self.px[free[0], 0])))
    r = self._rows
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    passed: dict[int, list] = {}  # node → [(cols, rows)] of the reactions' derivatives
    replaced, slaves = [], set(int(a) for a in r["local"])
    for p in range(len(r["local"])):
        a = int(r["local"][p])
        q = self.pq[a]
        gathered = [A.getRow(int(row)) for row in q]
        parts = [(gathered[0][0], np.array([vals for _, vals in gathered]))]
        parts += passed.pop(a, [])
        nodes = np.concatenate([[a], r["partner"][p]])
        geo_cols = (nodes[:, None] * self.bs + self.position_slots[None, :]).ravel()
        every = np.union1d(np.concatenate([c for c, _ in parts]), geo_cols).astype(PETSc.IntType)
        m = len(q)
        J = np.zeros((m, len(every)))
        for cols, rows in parts:
            np.add.at(J, (slice(None), np.searchsorted(every, cols)), rows)
        geo_at = np.searchsorted(every, geo_cols)
        n, T, dT, F, fN = r["n"][p], r["T"][p], r["dT"][p], r["F"][p], r["fN"][p]
        dn = self.ell * r["d_normal"][p].reshape(m, -1)
        new = np.zeros((m, len(every)))
        new[0, geo_at] = r["d_gap"][p].ravel()
        new[1:] = T @ J
        new[1:, geo_at] += np.einsum("jab,a->jb", dT, F) @ dn
        replaced.append((q, every, new))
        dfN = n @ J
        dfN[geo_at] += F @ dn
        weights = r["weights"][p]
        dw = self.ell * r["d_weights"][p].reshape(len(weights), -1)
        for j, node in enumerate(r["partner"][p]):
            if self.held_all[node]:
                continue
            add = weights[j] * np.outer(n, dfN)
            add[:, geo_at] += fN * np.outer(n, dw[j]) + weights[j] * fN * dn
            passed.setdefault(int(node), []).append((every, add))
    for q, every, new in replaced:
        A.setValues(q.astype(PETSc.IntType), every, new, addv=PETSc.InsertMode.INSERT_VALUES)
    A.assemble()
    for node, parts in passed.items():
        assert node not in slaves, "a slave's passed reactions are in its rows"
        for every, add in parts:
            rows = (node * self.bs + self.balance_slots).astype(PETSc.IntType)
            A.setValues(rows, every, add, addv=PETSc.InsertMode.ADD_VALUES)
    A.assemble()
    self.c = float(local_c) or None


def allow_chains() -> None:
    """Patch :class:`PairContact` in this process with the prototype (module docstring)."""
    PairContact.apply_vector = _apply_vector  # type: ignore[method-assign]
    PairContact.apply_matrix = _apply_matrix  # type: ignore[method-assign]


# %%
if __name__ == "__main__" and MPI.COMM_WORLD.size == 1:
    from plectoneme_run import report, run

    allow_chains()
    for cells in [int(a) for a in sys.argv[1:]] or [64]:
        report(cells, *run(cells))
