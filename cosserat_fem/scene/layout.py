"""The layout of the unknowns: which components of U = (p, q) a model solves, in which order,
with their names and units.

The general form (65) has twelve unknowns at every node, p = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ) and its
rate q = dp/dτ (τ = ω0 t, (47)). A model may solve a subset: a planar scene solves the
in-plane ones (x, z, ψ or y, z, θ, and their rates; scene.PLANAR), a modal problem p alone.
The model owns its :class:`Layout` and hands it to everything that reads U (probes, XDMF
output, the step controller, the state checks): nothing infers the layout from U's size.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl

from cosserat_fem.forms.kinematics import P_NAMES

#: All twelve components of U = (p, q).
FULL = tuple(range(12))
#: Names of the twelve components: those of p, then their τ-rates.
NAMES = (*P_NAMES, *(f"d{n}/dtau" for n in P_NAMES))
#: The SI unit of each component once scaled (:meth:`Layout.si_scale`).
UNITS = ("m", "m", "m", "rad", "rad", "rad", "m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s")


@dataclass(frozen=True)
class Layout:
    """``components``: the full component (0-11) of each entry of U's blocks, p first."""

    components: tuple[int, ...] = FULL

    def __post_init__(self) -> None:
        comps = self.components
        if len(set(comps)) != len(comps) or not set(comps) <= set(FULL):
            raise ValueError(f"a layout holds distinct components of 0-11, got {comps}")
        if any(c >= 6 for c in comps[: self.p_count]) or any(c < 6 for c in comps[self.p_count :]):
            raise ValueError(f"a layout holds the components of p first, got {comps}")

    @property
    def size(self) -> int:
        """Entries a node's block holds."""
        return len(self.components)

    @property
    def reduced(self) -> bool:
        return self.components != FULL

    @property
    def p_count(self) -> int:
        """How many of the entries are components of p (they come first)."""
        return sum(c < 6 for c in self.components)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(NAMES[c] for c in self.components)

    @property
    def p_names(self) -> tuple[str, ...]:
        return self.names[: self.p_count]

    def index(self, component: int) -> int | None:
        """Position in a block of full component ``component`` (None if not solved)."""
        return self.components.index(component) if component in self.components else None

    def si_scale(self, length: float, omega0: float) -> np.ndarray:
        """Factors from each entry to SI units (:data:`UNITS`): ℓ for x, y, z, 1 for the
        angles, ℓ ω0 and ω0 for their rates."""
        full = np.array([length] * 3 + [1.0] * 3 + [length * omega0] * 3 + [omega0] * 3)
        return full[list(self.components)]

    def full(self, u) -> ufl.core.expr.Expr:
        """The twelve components of a UFL vector of this layout (zeros where not solved)."""
        if not self.reduced:
            return u
        return ufl.as_vector([u[self.index(i)] if i in self.components else 0.0 for i in FULL])

    def full_array(self, state: np.ndarray) -> np.ndarray:
        """(nodes, 12) values of a state array of this layout (zeros where not solved)."""
        blocks = np.asarray(state).reshape(-1, self.size)
        if not self.reduced:
            return blocks
        out = np.zeros((blocks.shape[0], 12))
        out[:, list(self.components)] = blocks
        return out

    def from_full(self, state: np.ndarray, nodes: int) -> np.ndarray:
        """A state array of this layout from one of all twelve components at each of
        ``nodes`` nodes (a reduced state cannot be told x-z from y-z by its size: embed it
        with :meth:`full_array` first)."""
        if np.size(state) != nodes * 12:
            raise ValueError(
                f"a state of {np.size(state)} values, expected 12 per node ({nodes * 12}); "
                "embed a reduced state with Layout.full_array first"
            )
        return np.asarray(state).reshape(nodes, 12)[:, list(self.components)].ravel()
