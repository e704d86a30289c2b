"""The choice of nonlinear solver: the project's Newton loop (cosserat_fem/nls/newton.py) or
PETSc's SNES (cosserat_fem/nls/snes.py), by the scene's ``solver.nonlinear`` and
``[solver.petsc]`` (docs/solvers.md). Its own module so that the Newton loop does not import
SNES, which is a subclass of it, and SNES is imported only when a scene chooses it."""

from __future__ import annotations

import ufl
from dolfinx import fem

from cosserat_fem.nls.constraints import Identification
from cosserat_fem.nls.contact import NodeContact
from cosserat_fem.nls.contacts import Contacts
from cosserat_fem.nls.newton import NewtonSettings, NewtonSolver


def make_solver(
    F: ufl.Form,
    U: fem.Function,
    bcs: list,
    settings: NewtonSettings,
    constraints: Identification | None = None,
    contact: NodeContact | Contacts | None = None,
) -> NewtonSolver:
    """The nonlinear solver of F(U) = 0 that ``settings`` choose: PETSc's SNES configured by
    ``settings.petsc`` (:class:`~cosserat_fem.nls.snes.SNESSolver`) for
    nonlinear = "snes", or "auto" with options; else :class:`NewtonSolver`. Both have the
    same interface, stop rule and Jacobian policies, and take the dofs ``constraints`` ties
    (cosserat_fem/nls/constraints.py); ``contact``'s rows (cosserat_fem/nls/contact.py) need
    the project's Newton loop."""
    if settings.nonlinear == "snes" or (settings.nonlinear == "auto" and settings.petsc):
        from cosserat_fem.nls.snes import SNESSolver

        if contact is not None:
            raise ValueError("contact's rows need the project's Newton loop, not SNES")

        return SNESSolver(F, U, bcs, settings, constraints=constraints)
    return NewtonSolver(F, U, bcs, settings, constraints=constraints, contact=contact)
