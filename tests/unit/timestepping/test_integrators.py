"""Unit tests of the time integrators (cosserat_fem/timestepping/integrators.py) on small ODE
systems.

The problem: n scalar unknowns, one DG0 component each on a one-cell mesh of [0, 1]. The cell
has measure 1 and the DG0 basis function is 1 on it, so the assembled residual row i is
exactly U̇_i − f_i(U, τ): the integrators see a DOLFINx problem and the test sees an ODE
system y' = f(y, τ). Each integrator is driven through its own ``step``/``accept`` API with
the project's NewtonSolver (full Jacobian, default NewtonSettings, no boundary conditions), as
cosserat_fem/analysis/simulation.py drives it.

Amplification (linear y' = M y, M = diag(z_i/h) ⊕ an oscillator block): every solve is linear,
so one Newton iteration with an exact LU (M is block diagonal, the matrix is that of a direct
solve) leaves only round-off, and the integrator must reproduce each method's amplification
to a small multiple of the machine epsilon ε. The references are computed here with numpy from
the methods' defining equations (the literature, not the module's code):

* implicit midpoint (BDF2's first step, generalized-α with ρ∞ = 1): (I − hM/2) y1 =
  (I + hM/2) y0, scalar R(z) = (1 + z/2)/(1 − z/2);
* BDF2: U̇_{n+1} = Σ d_j y_j, with d_j the derivatives at t_{n+1} of the Lagrange basis of
  (t_{n−1}, t_n, t_{n+1}) (a Vandermonde solve, for any step ratio); at constant steps the
  recurrence (3/2 − z) y_{n+1} − 2 y_n + y_{n−1}/2 = 0, y_n = c1 r1^n + c2 r2^n with r1,2 the
  roots of (3/2 − z) r² − 2 r + 1/2 and c1,2 fitted to y0 and the midpoint y1;
* generalized-α (Jansen, Whiting & Hulbert 2000, first-order form), on (y, w = h ẏ):
  y1 = y0 + w0 + γ (w1 − w0) and w0 + αm (w1 − w0) = z (y0 + αf (y1 − y0)), i.e.
  [[1, −γ], [−z αf, αm]] (y1, w1) = [[1, 1 − γ], [z (1 − αf), αm − 1]] (y0, w0), so
  G(z) = L(z)⁻¹ R(z) with det G = (αm − 1 − z (1 − αf)(1 − γ))/(αm − z αf γ) and
  tr G = (2 αm − 1 + z (γ (1 − αf) + αf (1 − γ)))/(αm − z αf γ). As z → −∞,
  det G → (1 − αf)(1 − γ)/(αf γ) = ρ∞² and tr G → −(1 − αf)/αf − (1 − γ)/γ = −2 ρ∞
  (αf = γ = 1/(1 + ρ∞), so (1 − αf)/αf = (1 − γ)/γ = ρ∞): both eigenvalues tend to −ρ∞, the
  spectral radius at infinity is ρ∞;
* SDIRK: R(z) = 1 + z bᵀ (I − z A)⁻¹ 1 = P(z)/(1 − γ z)^s with P(z) = det(I − z (A − 1 bᵀ))
  (a rank-one update of I − z A, whose determinant is (1 − γz)^s): the coefficients of P are
  those of the characteristic polynomial of A − 1 bᵀ (numpy.poly), and R(∞) =
  det(A − 1 bᵀ)/γ^s. For the two-stage method this is 1 − bᵀ A⁻¹ 1 = 1 − (4γ − 1)/(2γ²) =
  1 − √3 = −0.7320508 (γ = (3 + √3)/6); for Crouzeix's three-stage method −0.6304149.

Order (a smooth solution, fixed steps): y' = 1 − y² (tanh τ), y' = cos(τ) y (exp(sin τ),
a time-dependent residual), y' = −2 (y − sin τ) + cos τ (sin τ + e^(−2τ), a forced one) and
y' = −y (e^(−τ)), all to τ = 1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import ufl
from conftest import jit_installed
from dolfinx import fem, mesh
from dolfinx.fem.petsc import assemble_matrix, assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.nls.newton import NewtonSettings, NewtonSolver
from cosserat_fem.timestepping.integrators import (
    BDF2,
    SDIRK,
    GeneralizedAlpha,
    Static,
    _sdirk_tableau,
    alpha_parameters,
    make_integrator,
)

pytestmark = pytest.mark.unit

EPS = np.finfo(float).eps
N = 8  # unknowns of the linear problem: 6 scalar modes and one oscillator block
DIAG_Z = (-1e8, -50.0, -2.0, -0.4, 0.3, 1e-3)  # z = λh (not −1/2: BDF2's double root)
OMEGA_H = 0.8  # ωh of the oscillator block: eigenvalues ±iω, z = ∓iωh
H = 0.5  # the step (τ units): M = diag(z)/h, so that h enters the forms


@pytest.fixture(scope="module", autouse=True)
def _quiet_safe_jit():
    with jit_installed():  # the project's crash-safe, quiet compiles (tests/conftest.py)
        yield


class OdeSystem:
    """n unknowns, one DG0 component each on a one-cell mesh, and residual factories."""

    def __init__(self, n: int):
        self.msh = mesh.create_unit_interval(MPI.COMM_SELF, 1)
        self.V = fem.VectorFunctionSpace(self.msh, ("DG", 0), dim=n)
        self.v = ufl.TestFunction(self.V)
        self.M = fem.Constant(self.msh, PETSc.ScalarType(np.zeros((n, n))))

    def linear(self, U, Udot, time):
        """y' = M y (M a Constant: one compiled form serves every test)."""
        return ufl.inner(Udot - ufl.dot(self.M, U), self.v) * ufl.dx

    def nonlinear(self, U, Udot, time):
        """The four ODEs of the order tests (module docstring)."""
        f = ufl.as_vector(
            [
                1.0 - U[0] ** 2,
                ufl.cos(time) * U[1],
                -2.0 * (U[2] - ufl.sin(time)) + ufl.cos(time),
                -U[3],
            ]
        )
        return ufl.inner(Udot - f, self.v) * ufl.dx


NONLINEAR_Y0 = np.array([0.0, 1.0, 1.0, 1.0])


def nonlinear_exact(t: float) -> np.ndarray:
    return np.array(
        [math.tanh(t), math.exp(math.sin(t)), math.sin(t) + math.exp(-2 * t), math.exp(-t)]
    )


@pytest.fixture(scope="module")
def linear_system():
    return OdeSystem(N)


@pytest.fixture(scope="module")
def nonlinear_system():
    return OdeSystem(4)


def diagonal_plus_oscillator(zs, omega_h: float, h: float) -> np.ndarray:
    """M (τ units) with scalar modes z_i/h and the block [[0, ω], [−ω, 0]] (a' = ω b,
    b' = −ω a: a + i b is multiplied by e^(−iωτ), z = −iωh)."""
    M = np.zeros((N, N))
    M[range(len(zs)), range(len(zs))] = np.asarray(zs) / h
    w = omega_h / h
    M[N - 2, N - 1], M[N - 1, N - 2] = w, -w
    return M


class Run:
    """An integrator and its NewtonSolver on a fresh unknown U = y0."""

    def __init__(
        self,
        system: OdeSystem,
        factory,
        name: str,
        y0,
        rho_inf: float = 0.5,
        settings: NewtonSettings | None = None,
    ):
        self.U = fem.Function(system.V)
        self.U.x.array[:] = y0
        self.integrator = make_integrator(name, self.U, factory, 0.0, rho_inf=rho_inf)
        self.solver = NewtonSolver(
            self.integrator.residual_form(), self.U, [], settings or NewtonSettings()
        )

    def advance(self, steps) -> np.ndarray:
        """The states after each step (row k: after k steps; row 0: the start)."""
        states = [self.U.x.array.copy()]
        for h in steps:
            self.integrator.step(h, self.solver.solve)
            self.integrator.accept(h)
            states.append(self.U.x.array.copy())
        return np.array(states)

    def close(self):
        self.solver.destroy()


def window_scale(reference: np.ndarray, blocks=((N - 2, N),)) -> np.ndarray:
    """The magnitude against which row k (the state after k steps) is held: the largest
    |reference| in rows k − 2 .. k, entry-wise, with each block of ``blocks`` (the oscillator:
    a rotated component may pass near zero) taking its norm. A step's predictor is made of
    the states and rates of the last two steps, and its residual is evaluated there, so the
    round-off of a step is ε times their size, whatever the size of the new state (a stiff
    mode that falls by 1e-8 in a step is held to ε of the states before it)."""
    size = np.abs(reference).astype(float)
    for a, b in blocks:
        size[:, a:b] = np.linalg.norm(reference[:, a:b], axis=1, keepdims=True)
    return np.array([size[max(k - 2, 0) : k + 1].max(axis=0) for k in range(len(size))])


def relative_errors(measured: np.ndarray, reference: np.ndarray) -> np.ndarray:
    return np.abs(measured - reference) / window_scale(reference)


# ---------------------------------------------------------------------- references (numpy)
def sdirk_literature(order: int) -> tuple[float, np.ndarray, np.ndarray]:
    """(γ, A, b) transcribed from Hairer & Wanner II, section IV.6 (Nørsett's two-stage
    order 3; Crouzeix's three-stage order 4, 1975); checked by the order conditions below."""
    if order == 3:
        g = (3.0 + math.sqrt(3.0)) / 6.0
        return g, np.array([[g, 0.0], [1.0 - 2.0 * g, g]]), np.array([0.5, 0.5])
    g = 1.0 / math.sqrt(3.0) * math.cos(math.pi / 18.0) + 0.5
    d = 1.0 / (6.0 * (2.0 * g - 1.0) ** 2)
    A = np.array([[g, 0.0, 0.0], [0.5 - g, g, 0.0], [2.0 * g, 1.0 - 4.0 * g, g]])
    return g, A, np.array([d, 1.0 - 2.0 * d, d])


def sdirk_R(z, order: int):
    """P(z)/(1 − γz)^s with P(z) = det(I − z (A − 1bᵀ)) = Σ_k c_k z^k, c = numpy.poly."""
    g, A, b = sdirk_literature(order)
    s = len(b)
    c = np.poly(A - np.outer(np.ones(s), b))  # det(λI − B) = Σ c_k λ^(s−k)
    P = sum(c[k] * z**k for k in range(s + 1))  # z^s det(I/z − B) = det(I − zB)
    return P / (1.0 - g * z) ** s


def sdirk_R_infinity(order: int) -> float:
    g, A, b = sdirk_literature(order)
    return float(np.linalg.det(A - np.outer(np.ones(len(b)), b)) / g ** len(b))


def sdirk_matrix_step(hM: np.ndarray, order: int) -> np.ndarray:
    """The one-step map of the RK method on y' = M y: stage rates (I − A ⊗ hM) hK =
    (1 ⊗ hM) y0, y1 = y0 + (bᵀ ⊗ I) hK."""
    _, A, b = sdirk_literature(order)
    s, n = len(b), hM.shape[0]
    big = np.eye(s * n) - np.kron(A, hM)
    stages = np.linalg.solve(big, np.kron(np.ones((s, 1)), hM))
    return np.eye(n) + np.kron(b[None, :], np.eye(n)) @ stages


def midpoint_matrix_step(hM: np.ndarray) -> np.ndarray:
    eye = np.eye(hM.shape[0])
    return np.linalg.solve(eye - 0.5 * hM, eye + 0.5 * hM)


def bdf2_weights(t_prev: float, t_now: float, t_new: float) -> np.ndarray:
    """d_j with p'(t_new) = Σ d_j p(t_j) for every quadratic p (Vandermonde, shifted nodes)."""
    s = np.array([t_prev, t_now, t_new]) - t_new
    V = np.vander(s, 3, increasing=True).T  # V[k, j] = s_j^k
    return np.linalg.solve(V, np.array([0.0, 1.0, 0.0]))  # d/ds s^k at 0


def bdf2_reference(M: np.ndarray, y0: np.ndarray, steps) -> np.ndarray:
    """Midpoint start, then variable-step BDF2: (d2 I − M) y_{n+1} = −d0 y_{n−1} − d1 y_n."""
    times = np.concatenate([[0.0], np.cumsum(steps)])
    out = [y0, midpoint_matrix_step(steps[0] * M) @ y0]
    for n in range(1, len(steps)):
        d = bdf2_weights(times[n - 1], times[n], times[n + 1])
        rhs = -d[0] * out[n - 1] - d[1] * out[n]
        out.append(np.linalg.solve(d[2] * np.eye(len(y0)) - M, rhs))
    return np.array(out)


def alpha_G(z, rho_inf: float) -> np.ndarray:
    """Generalized-α's amplification matrix on (y, hẏ), G = L⁻¹ R (module docstring) with
    L⁻¹ = [[αm, γ], [z αf, 1]]/det L written out: each entry to a few ε of itself (a numerical
    solve would leave the O(1/z) entries of a stiff G only ε of the O(1) ones)."""
    am, af = 0.5 * (3.0 - rho_inf) / (1.0 + rho_inf), 1.0 / (1.0 + rho_inf)
    g = 0.5 + am - af
    det = am - z * af * g
    return (
        np.array(
            [
                [am + g * z * (1.0 - af), am * (1.0 - g) + g * (am - 1.0)],
                [z, z * af * (1.0 - g) + am - 1.0],
            ],
            dtype=complex,
        )
        / det
    )


def alpha_matrix_step(hM: np.ndarray, rho_inf: float) -> np.ndarray:
    """The same for y' = M y on (y, hẏ) of size 2n."""
    am, af = 0.5 * (3.0 - rho_inf) / (1.0 + rho_inf), 1.0 / (1.0 + rho_inf)
    g = 0.5 + am - af
    eye = np.eye(hM.shape[0])
    L = np.block([[eye, -g * eye], [-af * hM, am * eye]])
    R = np.block([[eye, (1.0 - g) * eye], [(1.0 - af) * hM, (am - 1.0) * eye]])
    return np.linalg.solve(L, R)


# ---------------------------------------------------------------------- the tableaux
@pytest.mark.parametrize("order", [3, 4])
def test_sdirk_tableau_order_conditions_and_stiff_limit(order):
    """The module's tableau is the literature's, satisfies the order conditions of its order
    (all trees up to order 4: 1, 1/2, 1/3, 1/6, 1/4, 1/8, 1/12, 1/24, sums of at most a few
    dozen products of O(1) numbers, so 20 ε), and has R(∞) = −0.73 and −0.63 as the
    module docstring states (rounded there to two digits), exactly 1 − √3 for order 3."""
    g, A, b = sdirk_literature(order)
    g_mod, A_mod, b_mod = _sdirk_tableau(order)
    np.testing.assert_allclose(
        [g_mod, *A_mod.ravel(), *b_mod], [g, *A.ravel(), *b], rtol=0, atol=4 * EPS
    )
    c = A.sum(axis=1)
    conditions = [(b.sum(), 1.0), (b @ c, 1 / 2), (b @ c**2, 1 / 3), (b @ A @ c, 1 / 6)]
    if order == 4:
        conditions += [
            (b @ c**3, 1 / 4),
            (b @ (c * (A @ c)), 1 / 8),
            (b @ A @ c**2, 1 / 12),
            (b @ A @ A @ c, 1 / 24),
        ]
    for value, exact in conditions:
        assert abs(value - exact) <= 20 * EPS
    # The order is not higher: the tall tree of order p + 1, bᵀ A^(p−1) c = 1/(p + 1)!, fails
    # (by −0.090 and 0.164; the bushy ones hold for order 3, whose c are Gauss's nodes).
    tall = b @ np.linalg.matrix_power(A, order - 1) @ c
    assert abs(tall - 1 / math.factorial(order + 1)) > 0.05
    r_inf = sdirk_R_infinity(order)
    assert abs(abs(r_inf) - {3: 0.73, 4: 0.63}[order]) < 0.005
    if order == 3:
        assert abs(r_inf - (1 - math.sqrt(3))) <= 8 * EPS
    else:
        assert abs(r_inf - -0.6304149) < 1e-7  # det(A − 1bᵀ)/γ³
    # The two forms of R agree (and A-stability on the imaginary axis: |R(iy)| ≤ 1).
    for z in (-1e8, -50.0, -2.0, -0.5, 0.3, 1e-3, -0.8j, 3j - 0.1):
        direct = 1 + z * b @ np.linalg.solve(np.eye(len(b)) - z * A, np.ones(len(b)))
        assert abs(sdirk_R(z, order) - direct) <= 64 * EPS * max(1.0, abs(direct))
    assert all(abs(sdirk_R(1j * y, order)) <= 1 + 4 * EPS for y in np.linspace(-50, 50, 101))


def test_alpha_parameters_and_stiff_limit():
    """αm, αf, γ of Jansen, Whiting & Hulbert (2000); γ = αf = 1/(1 + ρ∞) (module docstring
    algebra); the closed-form G(z) at z = −1e8 has det G = ρ∞² + O(1/|z|) and tr G = −2ρ∞ +
    O(1/|z|) (allowed 1e-6: the O(1/|z|) terms have O(1) coefficients, and round-off in G is
    O(ε) relative); its spectral radius is ρ∞ up to O(|z|^(−1/2)) (the limit is a Jordan
    block, −ρ∞ double with a non-zero off-diagonal: allowed 1e-3)."""
    for rho in (0.0, 0.25, 0.5, 0.8, 1.0):
        am, af, g = alpha_parameters(rho)
        assert am == pytest.approx(0.5 * (3 - rho) / (1 + rho), abs=4 * EPS)
        assert af == pytest.approx(1 / (1 + rho), abs=4 * EPS)
        assert g == pytest.approx(af, abs=4 * EPS)
        G = alpha_G(-1e8, rho)
        assert abs(np.linalg.det(G) - rho**2) < 1e-6
        assert abs(np.trace(G) + 2 * rho) < 1e-6
        assert abs(max(abs(np.linalg.eigvals(G))) - rho) < 1e-3
        # Resolved modes: the principal eigenvalue is e^z to second order, O(z³) at z = −1e-2
        # (measured 3.3e-7 at ρ∞ = 0 down to z³/12 = 8.3e-8 at ρ∞ = 1, the midpoint rule).
        z = -1e-2
        principal = min(np.linalg.eigvals(alpha_G(z, rho)), key=lambda m: abs(m - 1))
        assert abs(principal - math.exp(z)) < 1e-6
    with pytest.raises(ValueError):
        alpha_parameters(1.5)


# ---------------------------------------------------------------------- amplification
@pytest.mark.parametrize("order", [3, 4])
def test_sdirk_amplification(linear_system, order):
    """Three SDIRK steps on y' = M y: y_k = R(hM)^k y0, with the scalar modes against
    R(z)^k = (P(z)/(1 − γz)^s)^k and the oscillator against the Kronecker stage solve; the
    stiff mode z = −1e8 is R(∞) + O(1/|z|). Bound 32 ε relative: each stage is one division of
    a sum of O(1) terms (the stage values of the stiff mode are O(1/|z|) but exact to relative
    ε, their rates O(1)), a dozen roundings a step, three steps. Measured: at most 2.5 ε
    (SDIRK3) and 7.9 ε (SDIRK4); R(−1e8) − R(∞) = 2.8e-8 and 2.4e-8."""
    M = diagonal_plus_oscillator(DIAG_Z, OMEGA_H, H)
    linear_system.M.value = M
    y0 = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    run = Run(linear_system, linear_system.linear, f"sdirk{order}", y0)
    try:
        states = run.advance([H] * 3)
    finally:
        run.close()
    step = sdirk_matrix_step(H * M, order)
    kronecker = np.array([np.linalg.matrix_power(step, k) @ y0 for k in range(4)])
    reference = kronecker.copy()  # the scalar modes by the closed form R(z)^k
    reference[:, :6] = [[sdirk_R(z, order) ** k for z in DIAG_Z] for k in range(4)]
    assert relative_errors(kronecker, reference).max() <= 32 * EPS
    errors = relative_errors(states, reference)
    assert errors.max() <= 32 * EPS, errors.max(axis=0) / EPS
    # The oscillator: a + ib times R(−iωh) a step.
    R = sdirk_R(-1j * OMEGA_H, order)
    assert abs(states[1, 6] + 1j * states[1, 7] - R) <= 32 * EPS
    # The stiff limit: R(−1e8) = R(∞) + O(1e-8).
    assert abs(states[1, 0] - sdirk_R_infinity(order)) < 1e-7


@pytest.mark.parametrize(
    "steps", [[H] * 5, [H, 2 * H, 0.5 * H, 1.5 * H, 0.25 * H]], ids=["constant", "variable"]
)
def test_bdf2_amplification(linear_system, steps):
    """BDF2 after its midpoint start on y' = M y: step 1 is R(z) = (1 + z/2)/(1 − z/2); the
    later steps follow the variable-step BDF2 formula, whose weights are computed here from
    the quadratic Lagrange interpolant (ratios 2, 1/4, 3, 1/6 in the variable case); at
    constant steps the scalar modes are c1 r1^n + c2 r2^n with the recurrence's roots. The
    stiff mode: the midpoint start is A- but not L-stable, y1 = −1 + 4e-8, and BDF2 then damps
    by |r| = (3 − 2z)^(−1/2) = 7e-5 a step. Bound 32 ε relative: one linear solve a step with
    three terms on the right, errors carried through five steps (|r| ≤ 1 for the stable
    modes; the root formula itself rounds the powers r^n). Measured: at most 5.4 ε (variable
    steps), 4.0 ε (constant)."""
    M = diagonal_plus_oscillator(DIAG_Z, OMEGA_H, H)
    linear_system.M.value = M
    y0 = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    run = Run(linear_system, linear_system.linear, "bdf2", y0)
    try:
        states = run.advance(steps)
    finally:
        run.close()
    reference = bdf2_reference(M, y0, steps)
    errors = relative_errors(states, reference)
    assert errors.max() <= 32 * EPS, errors.max(axis=0) / EPS
    z = np.array(DIAG_Z) * steps[0] / H
    np.testing.assert_allclose(states[1, :6], (1 + z / 2) / (1 - z / 2), rtol=8 * EPS)
    if steps[1] == steps[0]:
        for i, zi in enumerate(DIAG_Z):
            r = np.roots([1.5 - zi, -2.0, 0.5])
            c = np.linalg.solve(np.array([[1.0, 1.0], r]), [1.0, states[1, i]])
            terms = np.array([c * r**n for n in range(len(steps) + 1)])
            closed = terms.sum(axis=1).real
            # The closed form rounds its terms c_j r_j^n, which cancel for the stiff mode
            # (|c_j| ≈ 1e4, |r_j| ≈ 7e-5): its own round-off is ε Σ_j |c_j r_j^n|.
            bound = 64 * EPS * (np.abs(terms).sum(axis=1) + window_scale(closed[:, None], ())[:, 0])
            assert np.all(np.abs(states[:, i] - closed) <= bound), (zi, states[:, i], closed)
        # L-stable: −2.5e-8, 5e-9, 2.3e-16 after the midpoint's −1 + 4e-8.
        assert abs(states[2, 0]) < 3e-8 and abs(states[4, 0]) < 1e-15


@pytest.mark.parametrize("rho_inf", [0.0, 0.5, 1.0])
def test_generalized_alpha_amplification(linear_system, rho_inf):
    """Generalized-α on y' = M y from arbitrary (y0, ẏ0) (the map holds for any rate): each
    scalar z appears twice, started from (y, hẏ) = (1, 0) and (0, 1), so the columns of the
    measured G(z) are read off U and h·U̇_n; three steps give G(z)^k. The measured G at
    z = −1e8 has det G = ρ∞² and tr G = −2ρ∞ to O(1/|z|) + round-off (1e-6), so |R(∞)| = ρ∞;
    with ρ∞ = 1 the scheme is the implicit midpoint rule, y1 = (1 + z/2)/(1 − z/2) y0 for
    any ẏ0. Bound 32 ε relative to the magnitude of each column: the update of ẏ divides a
    difference of O(1) terms by γ (≥ 1/2), so its round-off is a few ε of the largest term.
    Measured: at most 1.0, 5.5 and 3.0 ε (ρ∞ = 0, 0.5, 1), the oscillator 1.5 ε; det G − ρ∞²
    and tr G + 2ρ∞ at most 4e-8 (O(1/|z|)); the spectral radius of the measured G is ρ∞ to
    8e-9 for ρ∞ = 0.5 and 1, and 7e-5 = |z|^(−1/2)/√2 for ρ∞ = 0 (the Jordan block)."""
    zs = (-1e8, -1e8, -2.0, -2.0, 0.3, 0.3)
    M = diagonal_plus_oscillator(zs, OMEGA_H, H)
    linear_system.M.value = M
    y0 = np.array([1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0])
    w0 = np.array([0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.3, -0.2])  # h ẏ0
    run = Run(linear_system, linear_system.linear, "generalized-alpha", y0, rho_inf=rho_inf)
    try:
        integrator = run.integrator
        assert isinstance(integrator, GeneralizedAlpha)
        integrator.set_initial_rate(w0 / H)
        measured = [np.concatenate([y0, w0])]
        for _ in range(3):
            integrator.step(H, run.solver.solve)
            integrator.accept(H)
            measured.append(np.concatenate([run.U.x.array, H * integrator.Udot_n.x.array]))
    finally:
        run.close()
    measured = np.array(measured)
    step = alpha_matrix_step(H * M, rho_inf)
    reference = np.array([np.linalg.matrix_power(step, k) @ measured[0] for k in range(4)])
    for k in range(1, 4):
        for pair, z in zip(range(0, 6, 2), zs[::2], strict=True):
            powers = [np.linalg.matrix_power(alpha_G(z, rho_inf), j).real for j in range(k + 1)]
            Gk = powers[k]
            got = np.array(
                [
                    [measured[k, pair], measured[k, pair + 1]],
                    [measured[k, N + pair], measured[k, N + pair + 1]],
                ]
            )
            # Each column is a state (y, hẏ), held to its size over the last three steps: the
            # predictor extrapolates the rates of two steps (window_scale), and G's entry
            # G21 → −(1 + ρ∞)² at z → −∞ carries an error of y into hẏ one step later.
            scale = np.max([np.abs(P).max(axis=0) for P in powers[-4:]], axis=0)
            assert (np.abs(got - Gk) / scale).max() <= 32 * EPS, (k, z, got, Gk)
    # The oscillator against the 2n x 2n map, scaled by the block's size.
    osc = [N - 2, N - 1, 2 * N - 2, 2 * N - 1]
    err = np.abs(measured[:, osc] - reference[:, osc]).max() / np.abs(reference[:, osc]).max()
    assert err <= 32 * EPS, err / EPS
    G = np.array([[measured[1, 0], measured[1, 1]], [measured[1, N], measured[1, N + 1]]])
    assert abs(np.linalg.det(G) - rho_inf**2) < 1e-6
    assert abs(np.trace(G) + 2 * rho_inf) < 1e-6
    assert abs(max(abs(np.linalg.eigvals(G))) - rho_inf) < 1e-3
    if rho_inf == 1.0:
        z = np.array(zs)
        np.testing.assert_allclose(
            measured[1, :6], y0[:6] * (1 + z / 2) / (1 - z / 2), rtol=0, atol=16 * EPS
        )


@pytest.mark.parametrize(
    ("name", "rho_inf"), [("bdf2", 0.5), ("generalized-alpha", 0.5), ("generalized-alpha", 0.0)]
)
def test_one_step_requests_take_midpoint_steps_then_the_method_restarts(
    linear_system, name, rho_inf
):
    """Integrator.use_one_step (module docstring, "One-step steps around a jump") on y' = M y:
    after two steps of the method, three steps at ``use_one_step(True)`` are the implicit
    midpoint rule's, y_{k+1} = (I − hM/2)⁻¹ (I + hM/2) y_k, whatever the history (BDF2's
    U_{n−1}, generalized-α's rate); then ``use_one_step(False)`` and ``restart``: BDF2 goes on
    by its formula from the last two midpoint states, generalized-α from the consistent rate
    h ẏ = h M y (restart's solve) by its own map on (y, hẏ). Bound 32 ε of each component's
    largest size over the steps compared, as the amplification tests (one linear solve a
    step; the mode z = −2 falls to 0 at the midpoint's first step, so not the window of
    relative_errors), and for generalized-α's first midpoint step to 32 ε of its predictor's
    size, 2 |h U̇_n| (the method's last rate: 1e8 for the stiff mode, whose answer is the
    predictor plus a correction of its size; later midpoint steps predict from their own
    rates (U_{n+1} − U_n)/h), and its steps after the restart to 32 ε of 2 |h ẏ| (its own
    predictor, as in its amplification test); the rate 4 ε of h M y (one solve of the
    identity). Measured: midpoint steps 3.6, 0.88, 1.1 ε (BDF2, ρ∞ = 0.5, 0); after the
    restart 3.0, 0.80, 1.1 ε. Only these are ``multistep``: ρ∞ = 1 is the midpoint rule
    already."""

    def held(measured: np.ndarray, reference: np.ndarray, predicted=0.0) -> float:
        size = np.maximum(np.abs(reference).max(axis=0), predicted)
        return float((np.abs(measured - reference) / np.where(size > 0, size, 1.0)).max())

    M = diagonal_plus_oscillator(DIAG_Z, OMEGA_H, H)
    linear_system.M.value = M
    y0 = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    run = Run(linear_system, linear_system.linear, name, y0, rho_inf=rho_inf)
    try:
        integrator = run.integrator
        assert integrator.multistep
        integrator.start(_Unsupported(), "petsc")
        own = run.advance([H, H])
        # the first midpoint step's predictor U_n + h U̇_n + ½ h (U̇_n − U̇_{n−1}) (BDF2: U_n)
        rates = [np.abs(H * integrator.Udot_n.x.array)] if name != "bdf2" else []
        predicted = 2 * np.max([np.zeros(N), *rates], axis=0)
        integrator.use_one_step(True)
        run.solver.request_jacobian()  # the residual's coefficients changed (as the loop does)
        midpoint = run.advance([H, H, H])
        integrator.use_one_step(False)
        integrator.restart(_Unsupported(), "petsc")
        run.solver.request_jacobian()
        rate = H * integrator.Udot_n.x.array.copy() if name != "bdf2" else None
        after = run.advance([H, H])
    finally:
        run.close()
    step = midpoint_matrix_step(H * M)
    reference = [own[-1]]
    for _ in range(3):
        reference.append(step @ reference[-1])
    assert held(midpoint, np.array(reference), predicted) <= 32 * EPS
    y = midpoint[-1]
    if name == "bdf2":
        d = bdf2_weights(0.0, H, 2 * H)
        ahead = [midpoint[-2], y]
        for _ in range(2):
            rhs = -d[0] * ahead[-2] - d[1] * ahead[-1]
            ahead.append(np.linalg.solve(d[2] * np.eye(N) - M, rhs))
        expected = np.array(ahead[1:])
        predicted = np.zeros(N)
    else:
        consistent = H * M @ y
        assert np.all(np.abs(rate - consistent) <= 4 * EPS * np.abs(consistent)), rate
        alpha = alpha_matrix_step(H * M, rho_inf)
        pairs = [np.concatenate([y, H * M @ y])]
        for _ in range(2):
            pairs.append(alpha @ pairs[-1])
        expected = np.array(pairs)[:, :N]
        predicted = 2 * np.abs(np.array(pairs)[:, N:]).max(axis=0)
    assert held(after, expected, predicted) <= 32 * EPS
    midpoint_rule = make_integrator("generalized-alpha", run.U, linear_system.linear, 0.0, 1.0)
    assert not midpoint_rule.multistep


# ---------------------------------------------------------------------- order
ORDERS = {"bdf2": 2, "generalized-alpha": 2, "sdirk3": 3, "sdirk4": 4}


def consistent_rate(integrator: GeneralizedAlpha) -> np.ndarray:
    """U̇_0 by the integrator's own linear problem (F is affine in U̇), solved densely."""
    a, L, W = integrator.initial_rate_problem()
    A = assemble_matrix(fem.form(a))
    A.assemble()
    b = assemble_vector(fem.form(L))
    n = b.getSize()
    rate = np.linalg.solve(A.getValues(range(n), range(n)), b.array)
    A.destroy()
    b.destroy()
    return rate


def global_errors(system, name: str, steps: int) -> np.ndarray:
    """|y_N − y(1)| for each of the four ODEs after ``steps`` equal steps to τ = 1."""
    run = Run(system, system.nonlinear, name, NONLINEAR_Y0)
    try:
        if name == "generalized-alpha":
            rate = consistent_rate(run.integrator)
            y = NONLINEAR_Y0
            exact_rate = [1 - y[0] ** 2, y[1], -2.0 * y[2] + 1.0, -y[3]]
            np.testing.assert_allclose(rate, exact_rate, rtol=0, atol=4 * EPS)
            run.integrator.set_initial_rate(rate)
        final = run.advance([1.0 / steps] * steps)[-1]
    finally:
        run.close()
    assert run.integrator.time == pytest.approx(1.0, abs=1e-14)
    return np.abs(final - nonlinear_exact(1.0))


# Step counts to τ = 1 (h = 1/N): the asymptotic range of each method on these ODEs.
STEPS = {
    "bdf2": (40, 80, 160),
    "generalized-alpha": (20, 40, 80),
    "sdirk3": (40, 80, 160),
    "sdirk4": (40, 80, 160),
}


@pytest.mark.parametrize("name", list(ORDERS))
def test_order_of_convergence(nonlinear_system, name):
    """Observed orders log2(e_h/e_{h/2}) on the four ODEs (module docstring), from three step
    sizes: on the finer pair within ±0.1 of 2, 2, 3, 4, and in the asymptotic range, where
    e = C h^p (1 + D h + ...) makes the deviation from p about D h/(2 ln 2), halving with h:
    the finer pair's deviation at most 0.7 of the coarser one's (+0.01 for noise). Measured
    (the ODEs in the order above): BDF2 1.989, 1.981, 2.002, 1.996 (coarser pair 1.978, 1.962,
    2.005, 1.993); generalized-α 1.999, 1.993, 2.004, 1.998; SDIRK3 2.987, 3.010, 2.980,
    2.990; SDIRK4 3.972, 4.064, 3.952, 3.976 (coarser 3.945, 4.124, 3.906, 3.952: the
    cos(τ)y equation has C5/C4 ≈ 7, so 40 → 80 steps is not yet asymptotic to 0.1).
    Round-off does not interfere: every error is above 50 N ε max|y| (the worst-case
    accumulation of a rounding per step; the smallest error, SDIRK4's 8.9e-12 at N = 160, is
    110x that, so round-off moves an order by < 0.03, realistically by √N ε: 0.001), and full
    Newton stops at ‖δU‖ ≤ 1e-8 ‖U‖ with a remaining error ~‖δU‖² ≈ 1e-16 a step."""
    p = ORDERS[name]
    steps = STEPS[name]
    errors = np.array([global_errors(nonlinear_system, name, n) for n in steps])
    orders = np.log2(errors[:-1] / errors[1:])
    round_off = steps[-1] * EPS * np.abs(nonlinear_exact(1.0)).max()
    assert errors.min() > 50 * round_off, errors
    deviation = np.abs(orders - p)
    assert np.all(deviation[-1] <= 0.1), (errors, orders)
    assert np.all(deviation[-1] <= 0.7 * deviation[-2] + 0.01), (errors, orders)


def test_static_uses_zero_rate_and_the_end_time(nonlinear_system):
    """Static solves f(U, τ + h) = 0 (U̇ = 0): 1 − U0² = 0 from 0.5 gives 1, cos(τ)U1 = 0
    gives 0, the forced equation U2 = sin τ + cos τ/2 at τ = 0.7, U3 = 0. Newton converges
    quadratically to ~ε (full Jacobian, ‖δU‖ ≤ 1e-8 ‖U‖ stops it with an error ~1e-16)."""
    run = Run(
        nonlinear_system, nonlinear_system.nonlinear, "static", np.array([0.5, 1.0, 1.0, 1.0])
    )
    try:
        integrator = run.integrator
        assert isinstance(integrator, Static)
        integrator.time = 0.3
        integrator.step(0.4, run.solver.solve)
        assert integrator.unknown_time == pytest.approx(0.7, abs=1e-15)
        assert float(integrator.time_eval.value) == pytest.approx(0.7, abs=1e-15)
        integrator.accept(0.4)
        t = 0.7
        np.testing.assert_allclose(
            run.U.x.array, [1.0, 0.0, math.sin(t) + math.cos(t) / 2, 0.0], rtol=0, atol=1e-14
        )
    finally:
        run.close()


class _Unsupported:
    """What Integrator.start asks of a system, for ODEs: no supports, no data loads; records
    the times at which the supports were asked to move."""

    bcs: list = []

    def __init__(self):
        self.moves: list[tuple[float, bool]] = []

    def move_supports(self, tau: float, rates: bool = False) -> None:
        self.moves.append((tau, rates))

    def sync_loads(self, time_eval) -> None:
        pass


@pytest.mark.parametrize("name", ["bdf2", "sdirk3", "sdirk4", "static", "generalized-alpha"])
def test_start_sets_up_only_what_the_integrator_needs(nonlinear_system, name):
    """Integrator.start: generalized-α solves F(U_0, U̇_0, 0) = 0 for U̇_0, here y' = f(y) at
    y0 = (0, 1, 1, 1): U̇_0 = (1 − 0², cos 0 · 1, −2(1 − 0) + 1, −1) = (1, 1, −1, −1), by one LU
    solve of a diagonal 4×4 system with unit entries (exact up to ε of each entry: 4ε), the
    supports moved to their rates and back; every other integrator leaves its state as it was
    (bit for bit: start does no arithmetic on it) and asks nothing of the system."""
    run = Run(nonlinear_system, nonlinear_system.nonlinear, name, NONLINEAR_Y0)
    try:
        before = (run.integrator.state_dict(), run.U.x.array.copy())
        system = _Unsupported()
        run.integrator.start(system, "petsc")
        if name == "generalized-alpha":
            np.testing.assert_allclose(
                run.integrator.Udot_n.x.array, [1.0, 1.0, -1.0, -1.0], rtol=0, atol=4 * EPS
            )
            assert system.moves == [(0.0, True), (0.0, False)]
        else:
            assert system.moves == []
            after = run.integrator.state_dict()
            assert after.keys() == before[0].keys()
            for key, value in before[0].items():
                np.testing.assert_array_equal(after[key], value)
        np.testing.assert_array_equal(run.U.x.array, before[1])
    finally:
        run.close()


def test_factory_names():
    """make_integrator maps the scene's names to the classes (and rejects others)."""
    system = OdeSystem(1)
    U = fem.Function(system.V)
    classes = {
        "bdf2": BDF2,
        "generalized-alpha": GeneralizedAlpha,
        "sdirk3": SDIRK,
        "sdirk4": SDIRK,
        "static": Static,
    }
    for name, cls in classes.items():
        assert isinstance(make_integrator(name, U, system.linear, 0.0), cls)
    with pytest.raises(ValueError):
        make_integrator("euler", U, system.linear, 0.0)


# ---------------------------------------------------------------------- the solve callback
@pytest.mark.parametrize("name", list(ORDERS))
def test_times_seen_by_the_solves(linear_system, name):
    """Each solve evaluates the residual at the documented time: BDF2's midpoint start at
    τ + h/2, then τ + h; generalized-α at τ + αf h (ρ∞ = 0.5: αf = 2/3); SDIRK stage i at
    τ + c_i h, c = A1 — for SDIRK4 c = (γ, 1/2, 1 − γ) = (1.0686, 0.5, −0.0686): its first
    stage lies beyond the step and its last before it (at a negative time in the first step
    from τ = 0). ``unknown_time`` is the same time except for the implicit-midpoint step
    (τ + h, the time of the unknown U) and generalized-α (τ + h)."""
    linear_system.M.value = -np.eye(N)
    run = Run(linear_system, linear_system.linear, name, np.ones(N))
    seen = []

    def solve():
        seen.append((float(run.integrator.time_eval.value), run.integrator.unknown_time))
        return run.solver.solve()

    try:
        for _ in range(2):
            run.integrator.step(0.25, solve)
            run.integrator.accept(0.25)
    finally:
        run.close()
    if name == "bdf2":
        expected = [(0.125, 0.25), (0.5, 0.5)]
    elif name == "generalized-alpha":
        expected = [(0.25 * 2 / 3, 0.25), (0.25 + 0.25 * 2 / 3, 0.5)]
    else:
        _, A, _ = sdirk_literature(int(name[-1]))
        expected = [(tau + c * 0.25,) * 2 for tau in (0.0, 0.25) for c in A.sum(axis=1)]
    np.testing.assert_allclose(seen, expected, rtol=0, atol=4 * EPS)


@pytest.mark.parametrize("name", list(ORDERS))
def test_rejected_step_leaves_no_trace(linear_system, name):
    """step(h') then reject() puts U back to the last accepted state, and the history is only
    changed by accept(): a run with a rejected attempt in the middle is bit for bit the run
    without it."""
    M = diagonal_plus_oscillator(DIAG_Z, OMEGA_H, H)
    linear_system.M.value = M
    y0 = np.linspace(1.0, 2.0, N)
    results = []
    for attempt in (False, True):
        run = Run(linear_system, linear_system.linear, name, y0)
        try:
            run.advance([H, 0.5 * H])
            if attempt:
                run.integrator.step(2 * H, run.solver.solve)
                run.integrator.reject()
                np.testing.assert_array_equal(run.U.x.array, run.integrator.last_accepted())
            results.append(run.advance([0.75 * H, H]))
        finally:
            run.close()
    np.testing.assert_array_equal(results[0], results[1])


def test_sdirk4_step_whose_stage_time_repeats_a_stored_one(linear_system):
    """SDIRK4 on y' = −y: a step of 1, then one of h2 = (γ − 1)/γ, whose first stage time
    τ_1 + γ h2 = γ equals (in floating point) the stored first stage time of step 1, γ · 1.
    The step is an ordinary linear solve: y2 = R(−1) R(−h2) to round-off is expected. The
    stage-rate predictor used to divide by zero there (the repeated time as two nodes): a NaN
    guess and a Newton failure at iteration 0 on a well-posed step, which an adaptive run
    (after rejections, or on its last step) could meet; the older rate of a repeated time is
    now left out of the extrapolation."""
    g, _, _ = sdirk_literature(4)
    h2 = (g - 1.0) / g
    assert 1.0 + g * h2 == g  # the coincidence, exact in floating point
    linear_system.M.value = -np.eye(N)
    run = Run(linear_system, linear_system.linear, "sdirk4", np.ones(N))
    try:
        states = run.advance([1.0, h2])
    finally:
        run.close()
    expected = sdirk_R(-1.0, 4) * sdirk_R(-h2, 4)
    np.testing.assert_allclose(states[-1], expected, rtol=32 * EPS)


@pytest.mark.parametrize("order", [3, 4])
@pytest.mark.parametrize("steps", [1, 2, 5])
def test_sdirk_loads_a_checkpoint_of_the_degree_s_predictor(linear_system, order, steps):
    """A checkpoint written when the predictor kept s + 1 stage rates in a ring (slot = count
    mod s + 1) continues bit for bit as one of today's ring of s: its newest s rates are
    taken, in their order. The older ring is rebuilt here from the run's own rates (the oldest
    slot filled with NaN, which must not reach the state) after 1, 2 and 5 steps, i.e. before,
    at and after the rings wrap."""
    M = diagonal_plus_oscillator(DIAG_Z, OMEGA_H, H)
    linear_system.M.value = M
    y0 = np.linspace(1.0, 2.0, N)
    name = f"sdirk{order}"
    plan = [H, 0.5 * H, 0.75 * H, H, 0.6 * H][:steps]
    results = []
    for old_format in (False, True):
        run = Run(linear_system, linear_system.linear, name, y0)
        try:
            run.advance(plan)
            state = run.integrator.state_dict()
            if old_format:
                size, stored = len(state["rate_times"]), int(state["stored"])
                rates = np.full((size + 1, N), np.nan)
                times = np.full(size + 1, np.nan)
                for count in range(max(stored - size, 0), stored):
                    rates[count % (size + 1)] = state["rates"][count % size]
                    times[count % (size + 1)] = state["rate_times"][count % size]
                state = {**state, "rates": rates, "rate_times": times}
            fresh = Run(linear_system, linear_system.linear, name, y0)
            try:
                fresh.U.x.array[:] = run.U.x.array
                fresh.integrator.load_state_dict(state)
                results.append(fresh.advance([0.8 * H, H, H]))
            finally:
                fresh.close()
        finally:
            run.close()
    assert np.isfinite(results[1]).all()
    np.testing.assert_array_equal(results[0], results[1])
