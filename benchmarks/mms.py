"""Method of manufactured solutions for the full nonlinear dynamic system (65).

A smooth p_ex(σ, τ) with p_ex(0, τ) = 0 (clamped at σ = 0) is chosen; with
U_ex = (p_ex, ∂τ p_ex) and U̇_ex = (∂τ p_ex, ∂ττ p_ex), written in UFL as functions of the
spatial coordinate and a time Constant, the discrete problem is

    F(U_h, U̇_h, τ; V) − F(U_ex(τ), U̇_ex(τ), τ; V) = 0   for all V,

with the rod's own residual F (:meth:`RodModel.residual`, free end at σ = 1, no loads). The
exact solution satisfies it for every V, interior and free-end terms alike, so the scheme is
consistent and the error U_h − U_ex is the discretisation error alone. The source term is
evaluated at the integrator's evaluation time, like any load.

Two families are provided. ``linear_in_time``, p = S(σ)(1 + ω τ), is reproduced exactly by
every integrator here (the implicit-midpoint start of BDF2, BDF2 and generalized-α are exact
for linear functions of τ; a quadratic is not, because the midpoint average differs from the
midpoint value by h² p̈/8), so its error is spatial; the acceleration vanishes but the velocity
q does not, so the gyroscopic and velocity-product terms of (64) take part. ``harmonic``,
p = S(σ) sin(ω τ + c), exercises the full inertia and gives the temporal orders on a fine mesh.
Every component moves, with angles of a few tenths of a radian, so the nonlinear kinematics
and the free-end flux take part. ``tumbling`` is ``harmonic`` plus a rod rolled up about e1
and unrolled again, unstretched (:func:`_rolling`), so that θ passes π/2 along the free
part of the rod and reaches 3.3 rad at its end, where the paper's chart is singular:
the solver's chart moves onto the rod (cosserat_fem/rod/charts.py), and the error is measured
in the chart-free motion, positions and directors (:attr:`MmsResult.error_motion`). The
source F(U_ex, U̇_ex) is that of the paper's chart: its rows are the force and moment
balances, in the fixed basis and the director basis, which do not depend on the chart the
unknowns are measured in (its kinematic rows vanish for the exact solution in any chart).
The rod should be stocky (e.g. a 0.3 m x 0.4 m section for
ℓ = 1 m): the manufactured strains are not small, and the stiffness ratio EA ℓ²/(EI) of a
slender rod would make coarse meshes lock and Newton's method start far from the solution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import ufl
from cosserat_fem.forms.kinematics import directors, translations
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.nls.newton import NewtonSettings
from cosserat_fem.nls.solvers import make_solver
from cosserat_fem.rod.model import RodModel, build_model
from cosserat_fem.scene.build import Scene
from cosserat_fem.timestepping.integrators import GeneralizedAlpha, make_integrator
from cosserat_fem.timestepping.loop import watch_chart

# Amplitudes: x/ℓ, y/ℓ, z/ℓ of a few per cent, angles of a few tenths of a radian.
AMPLITUDES = (0.04, -0.03, 0.01, 0.25, -0.3, 0.2)
WAVENUMBERS = (1.3, 1.7, 1.1, 1.9, 1.5, 2.1)
FREQUENCIES = (1.0, 1.3, 0.7, 1.6, 1.1, 1.9)
PHASES = (0.3, 1.1, 0.5, 0.9, 0.2, 0.7)
#: (A, ω, c) of the rolling part of the ``tumbling`` family (:func:`_rolling`).
ROLLING = (1.5, 1.6, -0.9)


@dataclass
class ExactSolution:
    """U_ex(σ, τ) and U̇_ex(σ, τ) as UFL expressions of a time Constant."""

    U: ufl.core.expr.Expr
    Udot: ufl.core.expr.Expr


def exact_solution(model: RodModel, tau, family: str) -> ExactSolution:
    """U_ex = (p_ex, ∂τ p_ex) and U̇_ex = (∂τ p_ex, ∂ττ p_ex) of ``family`` ("linear_in_time",
    "harmonic" or "tumbling", module docstring) at τ = ``tau`` (a UFL Constant or expression);
    ValueError for another family."""
    sigma = ufl.SpatialCoordinate(model.msh)[0]
    p, pt, ptt = [], [], []
    for a, k, w, c in zip(AMPLITUDES, WAVENUMBERS, FREQUENCIES, PHASES, strict=True):
        shape = a * ufl.sin(k * sigma)  # zero at the clamp σ = 0
        if family == "linear_in_time":
            T, Tt, Ttt = 1.0 + w * tau, w, 0.0
        elif family in ("harmonic", "tumbling"):
            T, Tt, Ttt = (
                ufl.sin(w * tau + c),
                w * ufl.cos(w * tau + c),
                -(w**2) * ufl.sin(w * tau + c),
            )
        else:
            raise ValueError(f"unknown family {family!r}")
        p.append(shape * T)
        pt.append(shape * Tt)
        ptt.append(shape * Ttt)
    if family == "tumbling":
        for i, (f, ft, ftt) in enumerate(_rolling(sigma, tau)):
            p[i], pt[i], ptt[i] = p[i] + f, pt[i] + ft, ptt[i] + ftt
    return ExactSolution(U=ufl.as_vector(p + pt), Udot=ufl.as_vector(pt + ptt))


def _rolling(sigma, tau) -> list[tuple]:
    """(f, ∂τ f, ∂ττ f) of each component of p for the rolling part of ``tumbling``: the rod
    bent about e1 into an arc of curvature κ(τ) = A (1.2 + sin(ω τ + c)), unstretched and
    unsheared (r' = d3 = (0, −sin θ, cos θ) with θ = κ σ), so y = (cos κσ − 1)/κ and
    z = sin(κσ)/κ − σ. κ stays ≥ 0.2 A (no 0/0); with A = 1.5, ω = 1.6, c = −0.9, θ(ℓ) = κ
    rises from 0.63 through π/2 to 3.3 rad and back to 2.9 over τ ∈ [0, 2]."""
    A, w, c = ROLLING
    kappa = ufl.variable(A * (1.2 + ufl.sin(w * tau + c)))
    k_t = A * w * ufl.cos(w * tau + c)
    k_tt = -A * w**2 * ufl.sin(w * tau + c)
    parts = [
        0.0 * sigma,
        (ufl.cos(kappa * sigma) - 1.0) / kappa,
        ufl.sin(kappa * sigma) / kappa - sigma,
        kappa * sigma,
        0.0 * sigma,
        0.0 * sigma,
    ]
    out = []
    for f in parts:
        f_k = ufl.diff(f, kappa)
        out.append((f, f_k * k_t, ufl.diff(f_k, kappa) * k_t**2 + f_k * k_tt))
    return out


def _interpolate(V: fem.FunctionSpace, expr) -> np.ndarray:
    f = fem.Function(V)
    f.interpolate(fem.Expression(expr, V.element.interpolation_points()))
    return f.x.array.copy()


@dataclass
class MmsResult:
    error_p: float  # relative L2 error of p at the final time (in the solver's chart)
    steps: int
    dofs: int
    #: Relative L2 error of the motion at the final time: positions and directors, chart-free,
    #: (∫ |r_h − r|² + |D_h − D|² dσ / ∫ |r|² + |D − I|² dσ)^½ (r in units of ℓ).
    error_motion: float = float("nan")
    chart_resets: int = 0


def run_mms(
    scene: Scene, family: str, tau_end: float, steps: int, comm: MPI.Comm = MPI.COMM_WORLD
) -> MmsResult:
    """Integrate the manufactured problem to τ_end in ``steps`` steps with the scene's
    integrator, element and solver; return the L2 error of p against p_ex(τ_end)."""
    model = build_model(scene, comm, planar=False)  # the manufactured fields use all twelve
    model.use_chart(active=False)  # it moves if θ nears ±π/2 (the tumbling family)
    tau0 = fem.Constant(model.msh, PETSc.ScalarType(0.0))
    exact0 = exact_solution(model, tau0, family)
    model.U.x.array[:] = _interpolate(model.V, exact0.U)

    def residual(U_eval, Udot_eval, time_eval):
        exact = exact_solution(model, time_eval, family)
        return model.residual(U_eval, Udot_eval, time_eval) - model.residual(
            exact.U, exact.Udot, time_eval, charted=False
        )

    tspan = scene.time
    integrator = make_integrator(tspan.integrator, model.U, residual, 0.0, rho_inf=tspan.rho_inf)
    if isinstance(integrator, GeneralizedAlpha):
        integrator.set_initial_rate(_interpolate(model.V, exact0.Udot))
    # The order measured is the integrator's, not the stop rule's: full Newton.
    settings = replace(NewtonSettings.of(scene.solver), jacobian="full")
    solver = make_solver(integrator.residual_form(), model.U, model.bcs, settings)
    h = tau_end / steps
    resets = int(watch_chart(model, integrator, solver) is not None)  # θ(ℓ, 0) may be large
    for _ in range(steps):
        integrator.step(h, solver.solve)
        integrator.accept(h)
        resets += watch_chart(model, integrator, solver) is not None
    solver.destroy()
    tau_end_const = fem.Constant(model.msh, PETSc.ScalarType(integrator.time))
    p_ex = ufl.as_vector([exact_solution(model, tau_end_const, family).U[i] for i in range(6)])
    p_h = ufl.as_vector([model.U[i] for i in range(6)])
    dx = ufl.Measure("dx", domain=model.msh, metadata={"quadrature_degree": 12})

    def integral(expr) -> float:
        return comm.allreduce(fem.assemble_scalar(fem.form(expr * dx)))

    err = integral(ufl.inner(p_h - p_ex, p_h - p_ex))
    ref = integral(ufl.inner(p_ex, p_ex))
    r_h, r_ex = translations(p_h), translations(p_ex)
    D_h = directors(p_h, model.chart_form() if model.chart_active else None)
    D_ex = directors(p_ex)
    motion = integral(ufl.inner(r_h - r_ex, r_h - r_ex) + ufl.inner(D_h - D_ex, D_h - D_ex))
    size = integral(
        ufl.inner(r_ex, r_ex) + ufl.inner(D_ex - ufl.Identity(3), D_ex - ufl.Identity(3))
    )
    return MmsResult(
        error_p=math.sqrt(err / ref),
        steps=steps,
        dofs=model.global_dofs(),
        error_motion=math.sqrt(motion / size),
        chart_resets=resets,
    )
