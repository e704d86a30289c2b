"""Loads given by data (tables, callables: cosserat_fem/scene/load_data.py) in a model's forms.

An expression becomes UFL of the time Constant τ of the form that holds it (t = τ/ω0), so
UFL evaluates it wherever the form is assembled. Data cannot: a load of t only is a DOLFINx
``Constant``, one of t and s a ``Function`` of the quadrature space of the model's measure
(its values at the very quadrature points at which an expression would be evaluated, so the
only difference from the expression is the table's interpolation error). Their values are
set from the current value of that time Constant by :meth:`DataLoads.sync`, which whoever
assembles the form calls after setting τ: the time loop before each Newton solve (every
stage of every step: cosserat_fem/timestepping/loop.py), the static solve, the consistent initial
rate, the energy monitor and the modal problems. A time Constant's loads are evaluated once per
value of τ (a Newton retry at the same stage evaluates nothing again).

The values set here do not depend on the state U (a follower load's turn with the end's
directors is its form's, forms/follower.py, and UFL differentiates it), so the Jacobian is the
expression's with the value in place of the expression: UFL differentiates the same form, a
force's term vanishing and a torque's keeping its dependence on the angles through the
rotation's kinematics; whoever assembles a Jacobian needs the coefficients set too.

Under MPI every rank evaluates the same tables alike (the same bytes, read on rank 0); a
callable is called on every rank with the same t, its failures agreed on every rank, and a
load of t only must give every rank the same value (compared, one collective per τ).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import basix
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from cosserat_fem.common.errors import SceneError
from cosserat_fem.common.parallel import agree_and_gather
from cosserat_fem.scene.load_data import LoadCallable


@dataclass
class _Bound:
    """The coefficients of one time Constant: (component, Constant or Function, t ↦ its
    values) triples and the τ they were last set for."""

    time: fem.Constant
    entries: list = field(default_factory=list)
    tau: float | None = None


class DataLoads:
    """The data loads of a model's forms (module docstring): ``msh`` the rod's mesh on
    σ ∈ [0, 1], ``degree`` its measure's quadrature degree, ``length`` ℓ [m], ``omega0``
    [rad/s]."""

    def __init__(self, msh, degree: int, length: float, omega0: float):
        self.msh, self.degree, self.length, self.omega0 = msh, degree, length, omega0
        #: The data loads of each time Constant's forms, by the Constant's id (empty: none).
        self.bound: dict[int, _Bound] = {}
        self._space: fem.FunctionSpace | None = None
        self._s: np.ndarray | None = None

    def coefficient(self, component, time: fem.Constant):
        """The Constant (a load of t) or quadrature Function (of t and s) that stands for
        ``component`` in forms whose time Constant is ``time`` (one per pair: a form built
        again, e.g. after a chart move, holds the same one)."""
        if not isinstance(time, fem.Constant):
            raise TypeError("a data load needs a form whose time is a DOLFINx Constant")
        bound = self.bound.setdefault(id(time), _Bound(time))
        for known, coefficient, _ in bound.entries:
            if known is component:
                return coefficient
        if component.depends_on("s"):
            # FFCx makes the name a C identifier: loads.force_density[0] → loads_force_density_0
            name = re.sub(r"\W+", "_", component.key).strip("_")
            coefficient = fem.Function(self._quadrature_space(), name=name)
            values = component.sampler(self._s)  # t ↦ its values at the points
        else:
            coefficient = fem.Constant(self.msh, PETSc.ScalarType(0.0))
            values = component.value
        bound.entries.append((component, coefficient, values))
        bound.tau = None
        return coefficient

    def _quadrature_space(self) -> fem.FunctionSpace:
        """The scalar quadrature space of the measure's degree (the points of
        ``basix.make_quadrature``, which FFCx uses too) and s [m] at its dofs, local and
        ghost cells."""
        if self._space is None:
            element = ufl.FiniteElement(
                "Quadrature", self.msh.ufl_cell(), self.degree, quad_scheme="default"
            )
            space = fem.FunctionSpace(self.msh, element)
            xi = basix.make_quadrature(basix.CellType.interval, self.degree)[0][:, 0]
            cells = self.msh.geometry.dofmap.array.reshape(-1, 2)
            x = self.msh.geometry.x[:, 0]
            dofs = space.dofmap.list.array.reshape(cells.shape[0], -1)
            s = np.empty(space.dofmap.index_map.size_local + space.dofmap.index_map.num_ghosts)
            a, b = x[cells[:, 0]], x[cells[:, 1]]
            s[dofs] = self.length * (a[:, None] + xi[None, :] * (b - a)[:, None])
            self._space, self._s = space, s
        return self._space

    def sync(self, time: fem.Constant) -> None:
        """Set the data loads of the forms of ``time`` to their values at t = τ/ω0, τ the
        Constant's value now (collective when a callable is among them: its failures are
        agreed and a load of t only compared between ranks). SceneError naming the load."""
        bound = self.bound.get(id(time))
        if bound is None:
            return
        tau = float(time.value)
        if tau == bound.tau:
            return
        t = tau / self.omega0
        problem, shared = None, []
        for component, coefficient, values in bound.entries:
            try:
                if isinstance(coefficient, fem.Constant):
                    coefficient.value = values(t)
                    if isinstance(component, LoadCallable):
                        shared.append((component.key, float(coefficient.value)))
                else:
                    coefficient.x.array[:] = values(t)
            except SceneError as exc:
                problem = problem or exc
        comm = self.msh.comm
        if comm.size > 1 and any(isinstance(c, LoadCallable) for c, _, _ in bound.entries):
            _same_on_every_rank(agree_and_gather(comm, problem, shared), t)
        elif problem is not None:
            raise problem
        bound.tau = tau


def _same_on_every_rank(gathered: list[list[tuple[str, float]]], t: float) -> None:
    """SceneError on every rank if a callable load of t gave the ranks (``gathered``: each
    rank's (key, value) list) different values."""
    for rank, theirs in enumerate(gathered[1:], 1):
        for (key, mine), (_, other) in zip(gathered[0], theirs, strict=True):
            if mine != other:
                raise SceneError(
                    f"{key}: the callable gave {mine!r} on rank 0 and {other!r} on "
                    f"rank {rank} at t = {t:.10g} s; a load must be the same on "
                    "every rank"
                )
