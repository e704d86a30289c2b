"""Reference quantities of the modes and the linear response of a rod, for tests and
benchmarks/verify.py: the in-plane share of a mode's energy, the linear steady state under
harmonic loads by a dense solve."""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_matrix, assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.analysis.modal import Mode, modal_supports
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import Scene


def in_plane_share(mode: Mode) -> float:
    """The share of a mode's kinetic energy in motions of the e1-e3 plane (x, z and ψ:
    bending-x and axial): 1 for a mode in that plane, 0 for one out of it (y, θ, φ). The plane
    of an arc (reference.shape = "arc") and of a ring."""
    return mode.fractions["bending-x"] + mode.fractions["axial"]


def linear_steady_state(scene: Scene, omega: float, sigma: float = 1.0) -> np.ndarray:
    """The steady state at σ = ``sigma`` of the straight rod at rest, linearised, under the
    scene's loads taken as g(s) sin ωt: complex amplitudes P (6,) of (x, y, z [m], θ, ψ, φ
    [rad]), the motion being Im(P e^{iωt}) (|P| the amplitude, arg P the phase against the
    load). With Ω = ω/ω0 and derivatives in τ = ω0 t (47), the second block of (65)
    linearised about rest, M p̈ + C ṗ + K p = f̂ sin Ωτ, gives

        (K + iΩ C − Ω² M) P = f̂,   K = ∂F/∂p, C = ∂F/∂q, M = ∂F/∂q̇,

    f̂ = −F at rest when sin Ωτ = 1: every mode's response ψ_nᵀ f̂ φ_n / (λ_n − Ω² + iΩ c_n)
    summed (for Kelvin–Voigt damping C = τ_d ω0 K, c_n = τ_d ω0 λ_n: the modal steady state
    with ζ_n = τ_d ω_n / 2). Dense, on one rank (every rank computes it); the reference of
    tests/test_response.py. ValueError if the loads are not g(s) sin ωt (f̂ at half a period
    later must be −f̂)."""
    model = build_model(scene, MPI.COMM_SELF, planar=False)
    element = ufl.VectorElement(
        "Lagrange", model.msh.ufl_cell(), scene.discretisation.degree, dim=6
    )
    P = fem.FunctionSpace(model.msh, element)
    p, q, a = (fem.Function(P) for _ in range(3))
    zeros = [0.0] * 6
    U = ufl.as_vector([p[i] for i in range(6)] + [q[i] for i in range(6)])
    Udot = ufl.as_vector(zeros + [a[i] for i in range(6)])
    V = ufl.as_vector(zeros + [ufl.TestFunction(P)[i] for i in range(6)])
    tau = fem.Constant(model.msh, PETSc.ScalarType(0.0))
    F = model.residual_terms(U, Udot, tau, test=V).total()
    bcs = modal_supports(model, P)
    dp = ufl.TrialFunction(P)

    def dense(of: fem.Function, diagonal: float) -> np.ndarray:
        matrix = assemble_matrix(fem.form(ufl.derivative(F, of, dp)), bcs=bcs, diagonal=diagonal)
        matrix.assemble()
        return matrix.convert("dense").getDenseArray().copy()

    K, C, M = dense(p, 1.0), dense(q, 0.0), dense(a, 0.0)
    fixed = np.concatenate([bc.dof_indices()[0] for bc in bcs]).astype(int)
    residual = fem.form(F)
    big = 2.0 * np.pi / omega

    def load(t: float) -> np.ndarray:
        tau.value = t * model.omega0
        model.sync_loads(tau)
        f = -assemble_vector(residual).array.copy()
        f[fixed] = 0.0
        return f

    f = load(0.25 * big)
    # The residual at rest is zero to round-off (~1e-7 of f̂ for 1 N/m on the paper's rod);
    # g(s) sin ωt vanishes at t = 0 and is −f̂ half a period after T/4.
    scale = 1e-6 * np.abs(f).max()
    if not (
        scale > 0
        and np.abs(load(0.75 * big) + f).max() <= scale
        and np.abs(load(0.0)).max() <= scale
    ):
        raise ValueError("linear_steady_state: the loads are not of the form g(s) sin(omega t)")
    w = omega / model.omega0
    amplitude = np.linalg.solve(K + 1j * w * C - w**2 * M, f)
    node = fem.locate_dofs_geometrical(P, lambda x: np.isclose(x[0], sigma))[0]
    scale = np.array([model.length] * 3 + [1.0] * 3)
    return amplitude.reshape(-1, 6)[node] * scale
