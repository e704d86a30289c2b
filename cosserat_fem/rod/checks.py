"""State checks after a step or a load increment: a finite state, a regular Euler-angle chart.

det Ma = cos θ (66): the chart of the Euler angles (18) is singular at θ = ±π/2. After each
step U must be finite, |cos θ| ≥ :data:`CHART_COS_MIN` at every node, and cos θ must not have
changed sign since the last accepted state (a step that jumped over the singularity, which no
continuous motion passes). Trouble is a :class:`~cosserat_fem.common.errors.SolverError` naming the
time and the place along the rod.

The chart is singular only where θ and ψ are both solved for. In the planes (layout.py) the
angular block of Ma that is solved is Mm's entry for the one angle: 1 for ψ in x-z
(θ = φ = 0) and for θ in y-z (ψ = φ = 0), so a planar rod turns through any angle in either
plane (tests/test_large_deflection.py, the roll-up about e1 and e2).
"""

from __future__ import annotations

import math
from typing import NoReturn

import numpy as np
from mpi4py import MPI

from cosserat_fem.common.errors import SolverError
from cosserat_fem.rod.model import RodModel

CHART_COS_MIN = 1e-2
_min, _sum = np.minimum.reduce, np.add.reduce


def worst_place(model: RodModel, values: np.ndarray) -> tuple[float, float]:
    """(s [m], value) of the largest |value| over the rod; values: local per-block array."""
    imap = model.V.dofmap.index_map
    n = imap.size_local
    coords = model.V.tabulate_dof_coordinates()[:n, 0]
    local = np.abs(values[:n]) if n else np.zeros(1)
    i = int(np.argmax(local)) if n else 0
    mine = (float(local[i]) if n else -1.0, float(coords[i]) * model.length if n else 0.0)
    return max(model.msh.comm.allgather(mine))[::-1]


def first_place(model: RodModel, broken: np.ndarray) -> float:
    """s [m] of the first node along the rod (smallest s) where ``broken`` (local per-block
    booleans) is true, inf if none is (collective). A failed check names this place, not that
    of the largest value: where the checked quantity is constant along the rod (θ of a rigid
    rotation) round-off decides the largest, differently on another CPU or partition."""
    n = model.V.dofmap.index_map.size_local
    coords = model.V.tabulate_dof_coordinates()[:n, 0]
    hits = coords[np.asarray(broken[:n], dtype=bool)]
    mine = float(hits.min()) * model.length if hits.size else math.inf
    return model.msh.comm.allreduce(mine, op=MPI.MIN)


CHART_SUGGESTION = (
    "d3 is nearly parallel to e2, which the Euler angles (18) cannot represent; orient the rod "
    "so that large bending is about e2 (carried by ψ, which the chart allows without bound)"
)


def cos_theta(model: RodModel, state: np.ndarray) -> np.ndarray:
    """cos θ at the owned nodes of a state array (det Ma = cos θ, (66)); 1 where the solved
    block of Ma does not depend on θ (θ or ψ not solved for: module docstring)."""
    n = model.V.dofmap.index_map.size_local
    theta = model.layout.index(3)
    if theta is None or model.layout.index(4) is None:
        return np.ones(n)
    return np.cos(state.reshape(-1, model.layout.size)[:n, theta])


class StateCheck:
    """:func:`check_state` and :func:`cos_theta` of one model's U, with its views and sizes
    kept: a time step's check is then a few NumPy calls instead of a dozen lookups of DOLFINx
    properties (docs/decisions.md, "The compiled inner loop")."""

    def __init__(self, model: RodModel):
        self.model = model
        n = model.V.dofmap.index_map.size_local
        size = model.layout.size
        u = model.U.x.array
        self._owned = u[: n * size]
        theta = model.layout.index(3)
        planar = theta is None or model.layout.index(4) is None
        self._theta = None if planar else u.reshape(-1, size)[:n, theta]
        self._ones = np.ones(n)
        self._comm = model.msh.comm if model.msh.comm.size > 1 else None

    def cos_theta(self) -> np.ndarray:
        """cos θ at the owned nodes of U (:func:`cos_theta`; not to be changed in place)."""
        return self._ones if self._theta is None else np.cos(self._theta)

    def __call__(
        self, t: float | None, where_prefix: str = "", before: np.ndarray | None = None
    ) -> np.ndarray:
        """:func:`check_state` of U."""
        cos_now = self.cos_theta()
        # One number and (in parallel) one reduction per step: the smallest |cos θ|; −0.5 if
        # θ crossed ±π/2, −1 if any owned value is not finite (a NaN or inf makes the sum so).
        # The ufuncs' reduce: what ndarray.min and .sum call, without their Python layer.
        value = 1.0
        if cos_now.size:
            value = float(_min(np.abs(cos_now)))
            if before is not None and float(_min(before * cos_now)) <= 0.0:
                value = -0.5
            if not math.isfinite(value + float(_sum(self._owned))):
                value = -1.0
        if self._comm is not None:
            value = self._comm.allreduce(value, op=MPI.MIN)
        if value >= CHART_COS_MIN:
            return cos_now
        _report(self.model, t, where_prefix, before, cos_now, value)


def check_state(
    model: RodModel, t: float | None, where_prefix: str = "", before: np.ndarray | None = None
) -> np.ndarray:
    """Stop with a SolverError if U is not finite, if the Euler-angle chart is (nearly)
    singular, |cos θ| < ``CHART_COS_MIN``, or, given cos θ of the previous accepted state
    (``before``, from :func:`cos_theta` or an earlier call), if θ crossed ±π/2 at some node
    since then (cos θ changed sign: a step jumped over the singularity, through which no
    continuous motion passes, det Ma = cos θ (66)). Returns cos θ of U at the owned nodes.
    A loop that checks every step keeps a :class:`StateCheck` instead."""
    return StateCheck(model)(t, where_prefix, before)


def _report(model, t, where_prefix: str, before, cos_now: np.ndarray, value: float) -> NoReturn:
    """Raise the SolverError of a failed check (``value``: −1 not finite, −0.5 a crossing of
    ±π/2, else the smallest |cos θ|), with the place along the rod (collective)."""
    prefix = f"{where_prefix}{', ' if where_prefix else ''}"
    if value == -1.0:
        blocks = model.U.x.array.reshape(-1, model.layout.size)
        s = first_place(model, ~np.isfinite(blocks).all(axis=1))
        raise SolverError(
            time=t,
            where=f"{prefix}s = {s:.4g} m",
            reason="the solution became non-finite (NaN/inf)",
            suggestion="reduce time.step or check the loads",
            retry=True,
        )
    if value == -0.5:
        s = first_place(model, before * cos_now <= 0.0)
        raise SolverError(
            time=t,
            where=f"{prefix}s = {s:.4g} m",
            reason="Euler-angle chart singular: θ crossed ±π/2 within the step "
            "(det Ma = cos θ changed sign)",
            suggestion=CHART_SUGGESTION,
            retry=True,
        )
    cos_all = np.cos(model.layout.full_array(model.U.x.array)[:, 3])
    s = first_place(model, np.abs(cos_all) < CHART_COS_MIN)
    raise SolverError(
        time=t,
        where=f"{prefix}s = {s:.4g} m",
        reason=(
            f"Euler-angle chart singular: |cos θ| = {value:.2e} "
            "(θ near ±π/2, where det Ma = cos θ vanishes)"
        ),
        suggestion=CHART_SUGGESTION,
    )
