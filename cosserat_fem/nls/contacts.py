"""The rows of a rod's contacts together: with obstacles (cosserat_fem/nls/contact.py) and
with itself (cosserat_fem/nls/pair_contact.py), with the interface the solvers, the time
loop and the outputs use of either.

The pairs' rows go first: their reactions (P.2) reach the partner's balance rows before an
obstacle's rows (K.1)-(K.3) read a node's balance as the force it lacks, so a node pressed by
the rod onto an obstacle carries both. A node that is pressed onto the rod and onto an
obstacle at once is refused (the two would replace the same rows).
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from cosserat_fem.nls.contact import FREE, NodeContact
from cosserat_fem.nls.pair_contact import ContactChain, PairContact


class Contacts:
    """``obstacles`` (or None) and ``pairs``, as one :class:`NodeContact`-like object."""

    def __init__(self, obstacles: NodeContact | None, pairs: PairContact):
        self.obstacles, self.pairs = obstacles, pairs
        self.comm = pairs.comm
        #: the outputs: the pairs' contact field, or with obstacles a field of both (the
        #: loads added, the obstacles' gap, the larger state) made at each accepted state
        self.values = pairs.values
        if obstacles is not None:
            self.values = pairs.values.copy()
            self.values.name = "contact"

    def __len__(self) -> int:
        return len(self.pairs)

    def first_iterate(self, first: bool) -> None:
        """The pairs' :meth:`PairContact.first_iterate`, forcing the accepted pairs without
        obstacles only: a slave the pairs press at a solve's first iterate whatever their
        test, which an obstacle also presses, would stop the run (the ContactChain below)
        where its test lets it go."""
        self.pairs.first_iterate(first, force=self.obstacles is None)

    def apply_vector(self, b: np.ndarray, u: np.ndarray) -> bool:
        changed = self.pairs.apply_vector(b, u)
        if self.obstacles is None:
            return changed
        changed = self.obstacles.apply_vector(b, u) or changed
        both = np.intersect1d(
            self.pairs.active[:, 0] - self.pairs.start,
            self.obstacles.blocks[self.obstacles.state != FREE],
        )
        if self.comm.allreduce(int(both.size)):
            raise ContactChain(
                "a node is pressed onto the rod and onto an obstacle at once: not supported yet"
            )
        return changed

    def apply_matrix(self, A: PETSc.Mat) -> None:
        self.pairs.apply_matrix(A)
        if self.obstacles is not None:
            self.obstacles.apply_matrix(A)

    def accept(self, u: np.ndarray, initial: bool = False) -> None:
        self.pairs.accept(u, initial)
        if self.obstacles is None:
            return
        self.obstacles.accept(u, initial)
        out = self.values.x.array.reshape(-1, 6)
        obstacle = self.obstacles.values.x.array.reshape(-1, 6)
        pair = self.pairs.values.x.array.reshape(-1, 6)
        out[:] = obstacle
        out[:, :3] += pair[:, :3]
        out[:, 4] = np.maximum(obstacle[:, 4], pair[:, 4])

    def step_changes(self) -> tuple[str, str] | None:
        """The rod passing through itself between nodes (a step is rejected, halved and at
        last stopped with the place), else the obstacles' changes beyond max_changes."""
        trouble = self.pairs.interpenetration()
        if trouble is not None or self.obstacles is None:
            return trouble
        return self.obstacles.step_changes()

    def interpenetration(self) -> tuple[str, str] | None:
        """The pairs' :meth:`PairContact.interpenetration` (a load step's check)."""
        return self.pairs.interpenetration()

    def transitions(self) -> tuple[int, int]:
        """The nodes that came into and left contact in the step just solved, the obstacles'
        and the pairs' together (the time loop's midpoint steps around an impact)."""
        came, left = self.pairs.transitions()
        if self.obstacles is not None:
            more = self.obstacles.transitions()
            came, left = came + more[0], left + more[1]
        return came, left

    def unsettled(self) -> str:
        parts = [self.pairs.unsettled()]
        if self.obstacles is not None:
            parts.append(self.obstacles.unsettled())
        return "; ".join(p for p in parts if p)

    def summary(self) -> dict:
        own = {} if self.obstacles is None else self.obstacles.summary()
        return {**own, **self.pairs.summary()}

    def touching(self, u: np.ndarray) -> np.ndarray:
        """The nodes resting on an obstacle (the initial rate's; the pairs hold none)."""
        if self.obstacles is None:
            return np.zeros(0, dtype=np.int64)
        return self.obstacles.touching(u)

    def holds_rates(self) -> bool:
        """No pair pressed (collective): a consistent initial rate holds only the nodes
        resting on obstacles; a slave pressed on the rod would accelerate into it (the
        integrator then keeps its own rate: GeneralizedAlpha.restart)."""
        return self.pairs.count() == 0

    def hold_rates(self, A, b, nodes, u) -> None:
        if self.obstacles is not None:
            self.obstacles.hold_rates(A, b, nodes, u)

    def normal_reactions(self, r, nodes, u) -> np.ndarray:
        if self.obstacles is None:
            return np.zeros(0)
        return self.obstacles.normal_reactions(r, nodes, u)

    def state_dict(self) -> dict:
        own = {} if self.obstacles is None else self.obstacles.state_dict()
        return {**own, **self.pairs.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.pairs.load_state_dict(state)
        if self.obstacles is not None:
            self.obstacles.load_state_dict(state)
