# %% [markdown]
# # Node-to-plane contact with exact Coulomb stick: a prototype (docs/contact-design.md)
#
# Not wired into the package. A straight free-free rod along e3 lies on the rigid plane
# x = −r (its surface touches, so the gap of its axis node i is g_i = x_i: linear in p), under
# gravity along −e1; its end s = ℓ is pulled along the rod by T and lifted by V. The package's
# own static model (`build_model`, planar x-z: the unknowns (x, z, ψ) and their rates, a
# 6-block, `static_solver`: the residual F and its BAIJ Jacobian J) is solved by a
# semi-smooth Newton of the Alart-Curnier conditions written as **rows**: at a node in
# contact, the balance rows (tested by v_q, components 3 = x, 4 = z) are replaced,
#
#     normal (x):   active when f_N − c g > 0 (f_N = F_x, the contact force the row needs)
#                   row: g = x_i/ℓ = 0                      (exact: no penetration)
#     tangent (z):  f_T = F_z, trial t = f_T − c Δz_i (Δz_i: the slip since the last step)
#                   stick if |t| ≤ μ f_N:   row  Δz_i = 0   (exact: no creep)
#                   slip  otherwise:        row  f_T − μ f_N sign(t) = 0
#
# and left as they are at a node out of contact (f = 0). The forces are the rows' residuals:
# no multiplier unknowns, the matrix keeps its blocks (the new entries lie in the node's own
# diagonal block and in rows it already has). The active set is re-decided at every iterate
# (the primal-dual active set method = semi-smooth Newton, Hintermüller, Ito & Kunisch 2002).
#
# Closed forms checked (E A, E I, w = ρ A g per length; linear theory, small loads):
#
# * the end lifted by V: the lifted length a = 2V/w and the end's height h = 2V⁴/(3 w³ EI)
#   (moment about the lift-off point, where M = 0; the plane's point reaction V there; the
#   shear terms cancel: V a − w a²/2 = 0);                                          (P.1)
# * pulled by T < μ w L: a slip zone of length a = T/(μ w) at the pulled end, the rest
#   sticks (exactly still), the end slides u = T²/(2 EA μ w);                          (P.2)
# * T > μ w L: no equilibrium (the rod slides away): the static Newton must fail.      (P.3)
#
#     .venv/bin/python benchmarks/contact_prototype.py [P3 cells for the timing]

# %%
from __future__ import annotations

import sys
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.analysis.statics import static_solver
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import scene_from_dict

L, D, RHO, E, NU, G, KAPPA = 1.0, 0.02, 1000.0, 1e7, 0.3, 9.81, 0.9
AREA, INERTIA = np.pi * D**2 / 4, np.pi * D**4 / 64
W = RHO * AREA * G  # N/m
X, Z, PSI, QX, QZ = 0, 1, 2, 3, 4  # planar x-z block: x, z, ψ, then the rates' (balance) rows
BS = 6


def scene(elements: int, pull: float, lift: float, degree: int = 3):
    return scene_from_dict(
        {
            "title": "contact prototype",
            "rod": {
                "length": L,
                "section": {"shape": "circle", "diameter": D, "shear_coefficient": KAPPA},
                "material": {"density": RHO, "young_modulus": E, "poisson_ratio": NU},
            },
            "supports": {"start": "free", "end": "free"},
            "loads": {"gravity": [-G, 0, 0], "end": {"force": [lift, 0, pull]}},
            "static": {"load_steps": 1},
            "time": {"end": 1.0, "step": 1.0},
            "discretisation": {"elements": elements, "degree": degree},
        }
    )


class Contact:
    """The rows of node-to-plane contact with Coulomb friction (module docstring) on the
    owned node blocks ``blocks`` of a planar x-z model; ``mu`` the friction coefficient, ``c``
    the Alart-Curnier augmentation (any positive number: it changes the path, not the
    solution; here of the order of J's diagonal); ``order``: the blocks in their order along
    the rod, for the chain predictor (None: the plain semi-smooth Newton)."""

    def __init__(self, blocks: np.ndarray, mu: float, c: float, order: np.ndarray | None = None):
        self.blocks, self.mu, self.c, self.order = blocks, mu, c, order
        self.z_old = None  # the tangential positions at the last converged step
        self.state = np.ones(blocks.size, dtype=np.int8)  # 0 free, 1 stick, 2 slip: resting

    def decide(self, u: np.ndarray, F: np.ndarray) -> np.ndarray:
        """The set of each node at the iterate (u, F(u)) (the semi-smooth Newton's choice)."""
        b = self.blocks
        gap, fN, fT = u[b * BS + X], F[b * BS + QX], F[b * BS + QZ]
        trial = fT - self.c * (u[b * BS + Z] - self.z_old)
        state = np.where(fN - self.c * gap > 0, 1, 0).astype(np.int8)
        state[(state == 1) & (np.abs(trial) >= self.mu * fN * (1 - 1e-9))] = 2
        self.sign = np.sign(trial)
        if self.order is not None:
            self._chain(state, trial, fN)
        return state

    def _chain(self, state: np.ndarray, trial: np.ndarray, fN: np.ndarray) -> None:
        """The chain predictor: a node that starts to slip carried, as a support, the excess
        |t| − μ f_N that its stuck neighbours along the rod will carry once it slips; walk
        away from it along the rod, each stuck neighbour taking its capacity μ f_N from the
        excess, and let slip those it exhausts (in the same direction). A prediction only:
        the next iterate's test corrects a node released wrongly."""
        order = self.order
        where = np.empty_like(order)
        where[order] = np.arange(order.size)
        for k in np.flatnonzero((self.state == 1) & (state == 2)):
            for step in (-1, 1):
                excess, j = abs(trial[k]) - self.mu * fN[k], where[k] + step
                while 0 <= j < order.size and excess > 0 and state[order[j]] == 1:
                    excess -= self.mu * fN[order[j]]
                    if excess > 0:
                        state[order[j]], self.sign[order[j]] = 2, self.sign[k]
                    j += step

    def apply(self, A: PETSc.Mat, F: np.ndarray, u: np.ndarray) -> None:
        """The rows of the active nodes in A (assembled) and F (module docstring)."""
        b, st = self.blocks, self.state
        on = b[st > 0]
        slip = b[st == 2]
        mus = self.mu * self.sign[st == 2]
        # slip rows J_T − μ s J_N (the planar tangent is one direction: s = ±1 is constant)
        rows = [(A.getRow(int(k * BS + QZ)), A.getRow(int(k * BS + QX))) for k in slip]
        A.zeroRows(np.concatenate([on * BS + QX, on * BS + QZ]).astype(PETSc.IntType), diag=0.0)
        for k, m, ((ct, vt), (cn, vn)) in zip(slip, mus, rows, strict=True):
            A.setValues([int(k * BS + QZ)], ct, vt, addv=True)
            A.setValues([int(k * BS + QZ)], cn, -m * vn, addv=True)
        stick = b[st == 1]
        for k in on:
            A.setValue(int(k * BS + QX), int(k * BS + X), 1.0, addv=True)
        for k in stick:
            A.setValue(int(k * BS + QZ), int(k * BS + Z), 1.0, addv=True)
        A.assemble()
        F[slip * BS + QZ] -= mus * F[slip * BS + QX]
        F[on * BS + QX] = u[on * BS + X]
        F[stick * BS + QZ] = u[stick * BS + Z] - self.z_old[st == 1]


def newton(model, contact: Contact | None, timings: dict, max_it: int = 200) -> tuple[int, int]:
    """Semi-smooth Newton (module docstring) to ‖F‖ ≤ 1e-10 ‖F_1‖ or ‖δ‖ ≤ 1e-12 ‖u‖ with an
    unchanged active set (the update test alone stalls at round-off: ‖u‖ is 1e-5 here);
    returns (iterations, active-set changes). RuntimeError if it does not converge."""
    solver = static_solver(model.scene, model)
    U, A, b = model.U, solver.A, solver.b
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)  # no new entries: proven
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    dx = b.duplicate()
    changes = 0
    for it in range(1, max_it + 1):
        t0 = time.perf_counter()
        solver._residual()
        solver._jacobian()
        t1 = time.perf_counter()
        same = True
        if contact is not None:
            u, F = U.x.array, b.array_w
            state = contact.decide(u, F)
            same = bool(np.array_equal(state, contact.state))
            changes += not same
            contact.state = state
            contact.apply(A, F, u)
        t2 = time.perf_counter()
        ksp.setOperators(A)
        ksp.solve(b, dx)
        t3 = time.perf_counter()
        timings.setdefault("assembly", []).append(t1 - t0)
        timings.setdefault("contact", []).append(t2 - t1)
        timings.setdefault("solve", []).append(t3 - t2)
        U.x.array[: dx.size] -= dx.array
        if not np.all(np.isfinite(dx.array)):
            break
        norm = b.norm()  # ‖F‖ at the iterate, with the contact rows
        norm0 = norm if it == 1 else norm0  # noqa: F821 (set at the first iteration)
        if same and (norm <= 1e-10 * norm0 or dx.norm() <= 1e-12 * U.vector.norm()):
            return it, changes
    raise RuntimeError(f"no convergence in {it} iterations (the active set changed {changes}x)")


def rod_on_plane(
    elements: int, pull: float, lift: float, mu: float, steps: int = 1, chain: bool = False
):
    """The model after the load (pull, lift) applied in ``steps`` equal increments (the
    friction's slip is measured from each converged step) and its Newton figures; ``chain``:
    with the chain predictor (:meth:`Contact._chain`)."""
    model = build_model(scene(elements, 0.0, 0.0), MPI.COMM_SELF)
    assert model.V.dofmap.index_map_bs == BS, "the planar x-z model"
    sigma = model.V.tabulate_dof_coordinates()[:, 0]
    blocks = np.arange(sigma.size)
    # c: of the order of the axial stiffness's diagonal, EA/(hℓ) in the scaled rows
    contact = Contact(blocks, mu, c=1e4, order=np.argsort(sigma) if chain else None)
    contact.z_old = model.U.x.array[blocks * BS + Z].copy()
    its, timings, changes = [], {}, 0
    for k in range(1, steps + 1):
        model.scene = scene(elements, pull * k / steps, lift * k / steps)
        model_k = build_model(model.scene, MPI.COMM_SELF)
        model_k.U.x.array[:] = model.U.x.array
        model = model_k
        n, c = newton(model, contact, timings)
        its.append(n)
        changes += c
        contact.z_old = model.U.x.array[blocks * BS + Z].copy()
    return model, sigma, contact, its, changes, timings


def no_contact_timing(elements: int) -> dict:
    """A cantilever of the same rod (start clamped, gravity): the iteration without contact."""
    sc = scene(elements, 0.0, 0.0)
    sc = scene_from_dict(
        {
            "title": "no contact",
            "rod": {
                "length": L,
                "section": {"shape": "circle", "diameter": D, "shear_coefficient": KAPPA},
                "material": {"density": RHO, "young_modulus": E * 1e3, "poisson_ratio": NU},
            },
            "supports": {"start": "clamped", "end": "free"},
            "loads": {"gravity": [-G, 0, 0]},
            "static": {"load_steps": 1},
            "time": {"end": 1.0, "step": 1.0},
            "discretisation": {"elements": elements, "degree": 3},
        }
    )
    model = build_model(sc, MPI.COMM_SELF)
    timings: dict = {}
    newton(model, None, timings)
    return timings


# %% [markdown]
# ## The rod-rod search: boxes in a uniform grid, O(n)
#
# Each segment (a cell of the deformed rod, a P_k curve) gets an axis-aligned box of its
# nodes, widened by the section's radius and a margin (a P_k curve may leave its nodes' hull by
# its interpolation error: the implementation widens by a bound of it). The boxes are hashed
# into a uniform grid of spacing the largest box's extent, so a box meets at most 8 grid cells
# (3D); pairs are the boxes sharing a grid cell whose boxes overlap, excluding neighbours
# along the rod (|i − j| ≤ ``skip``: adjacent cells always touch). Expected cost O(n) for
# boxes of bounded density (sorting the keys: O(n log n) with a small constant).


# %%
def candidate_pairs(lo: np.ndarray, hi: np.ndarray, skip: int = 1) -> np.ndarray:
    """The pairs (i, j), i < j − skip, of boxes [lo_i, hi_i] (n × 3) that overlap."""
    n = lo.shape[0]
    cell = float((hi - lo).max())
    first = np.floor(lo / cell).astype(np.int64)
    entries, owners = [], []
    for corner in np.ndindex(2, 2, 2):  # the ≤ 8 grid cells a box can meet
        c = np.minimum(first + np.array(corner), np.floor(hi / cell).astype(np.int64))
        entries.append(c)
        owners.append(np.arange(n))
    c, who = np.vstack(entries), np.concatenate(owners)
    key = (c[:, 0] * 73856093) ^ (c[:, 1] * 19349663) ^ (c[:, 2] * 83492791)  # spatial hash
    key, unique_rows = np.unique(np.column_stack([key, who]), axis=0).T  # a box once a cell
    order = np.argsort(key, kind="stable")
    key, who = key[order], unique_rows[order]
    pairs = []
    for d in range(1, n):
        same = key[d:] == key[:-d]
        if not same.any():
            break
        a, b = who[:-d][same], who[d:][same]
        pairs.append(np.column_stack([np.minimum(a, b), np.maximum(a, b)]))
    if not pairs:
        return np.zeros((0, 2), dtype=np.int64)
    p = np.unique(np.vstack(pairs), axis=0)
    p = p[p[:, 1] - p[:, 0] > skip]
    overlap = np.all((lo[p[:, 0]] <= hi[p[:, 1]]) & (lo[p[:, 1]] <= hi[p[:, 0]]), axis=1)
    return p[overlap]


def plectoneme_boxes(n: int, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Boxes of n segments of a two-strand plectoneme-like curve: a double helix of pitch
    8 radius whose strands touch (the self-contact's worst case: every segment has partners)."""
    m, total = n // 2, 2 * np.pi * n / 32  # 16 segments a turn, on either strand
    phase = np.concatenate([np.linspace(0.0, total, m + 1), np.linspace(total, 0.0, n - m)])
    strand = np.where(np.arange(n + 1) <= m, 0.0, np.pi)  # the loop: one segment across
    x = np.column_stack(
        [radius * np.cos(phase + strand), radius * np.sin(phase + strand), 8 * radius * phase]
    )
    lo = np.minimum(x[:-1], x[1:]) - radius
    hi = np.maximum(x[:-1], x[1:]) + radius
    return lo, hi


# %% [markdown]
# ## Greenhill's clamped rod (docs/contact-design.md, the plectoneme check)
#
# Linearised about the straight rod under a torque M (no tension), w = u + iv obeys
# EI w'''' − iM w''' = 0: w = c0 + c1 s + c2 s² + c3 exp(iαs/L), α = ML/EI; clamped ends
# (w = w' = 0 at s = 0, L) make a 4×4 determinant whose first zero is α_c.


# %%
def greenhill_clamped() -> float:
    """α_c = M_c L/EI of a rod clamped at both ends under a torque (Love's 8.99)."""
    from scipy.optimize import minimize_scalar

    def det(a: float) -> float:
        e = np.exp(1j * a)
        m = np.array([[1, 0, 0, 1], [0, 1, 0, 1j * a], [1, 1, 1, e], [0, 1, 2, 1j * a * e]])
        return abs(np.linalg.det(m))

    return float(minimize_scalar(det, bracket=(8.5, 9.0, 9.5), tol=1e-12).x)


# %%
if __name__ == "__main__":
    EA, EI = E * AREA, E * INERTIA
    N_TOTAL = W * L
    print(f"rod: L = {L} m, d = {D} m, EA = {EA:.4g} N, EI = {EI:.4g} N m², w = {W:.4g} N/m")

    # (P.1): the end lifted by V, friction holding the rod along its axis
    V = 0.05 * W * L
    a_exact, h_exact = 2 * V / W, 2 * V**4 / (3 * W**3 * EI)
    # the closed form is Euler-Bernoulli's (a point reaction V at the lift-off); a Timoshenko
    # rod spreads it over sqrt(EI/κGA) (0.85 r here): ν = −0.99 makes G 130x stiffer
    for nu in (0.3, -0.99):
        NU = nu
        for elements in (10, 20, 40, 80):
            model, sigma, contact, its, changes, _ = rod_on_plane(elements, 0.0, V, mu=0.5)
            x = model.U.x.array[contact.blocks * BS + X] * L
            end = int(np.argmax(sigma))
            touching = contact.state > 0
            a = L * (1 - sigma[touching].max())  # from the last node on the plane
            print(
                f"lift V = {V:.4g} N, ν = {nu}, {elements} P3 cells: h = {x[end]:.6e} m "
                f"(relative to (P.1) {(x[end] - h_exact) / h_exact:+.1e}), lifted {a:.4f} m "
                f"(2V/w = {a_exact:.4f}, cell {L / elements:.4f}), penetration "
                f"{max(0.0, -x.min()):.1e} m, max |x| on the plane "
                f"{np.abs(x[touching]).max():.1e} m, Newton {its[0]} iterations, "
                f"{changes} active-set changes"
            )
    NU = 0.3

    # (P.2), (P.3): the pull
    mu = 0.3
    for ratio, elements, steps, chain in (
        (0.5, 10, 1, False),
        (0.5, 40, 1, False),
        (0.5, 40, 4, False),
        (0.9, 40, 1, False),
        (0.5, 40, 1, True),
        (0.5, 40, 4, True),
        (0.9, 40, 1, True),
        (0.9, 160, 1, True),
        (1.1, 10, 1, False),
    ):
        T = ratio * mu * N_TOTAL
        try:
            model, sigma, contact, its, changes, _ = rod_on_plane(
                elements, T, 0.0, mu, steps, chain
            )
        except RuntimeError as exc:
            print(f"pull T = {ratio} μN: {exc}: no static equilibrium, (P.3)")
            continue
        u = model.U.x.array
        z = u[contact.blocks * BS + Z] * L  # U holds the displacement from the rest
        end = int(np.argmax(sigma))
        slip_zone = L * (1 - sigma[contact.state == 2].min())
        stuck = contact.state == 1
        print(
            f"pull T = {ratio} μN, {elements} P3 cells, {steps} steps"
            f"{', chain predictor' if chain else ''}: end slide {z[end]:.6e} m "
            f"(T²/(2EAμw) = {T**2 / (2 * EA * mu * W):.6e}), slip zone {slip_zone:.4f} m "
            f"(T/(μw) = {T / (mu * W):.4f}), max |slide| where it sticks "
            f"{np.abs(z[stuck]).max():.1e} m, Newton {its} iterations a step, {changes} "
            "active-set changes"
        )

    for n in (1000, 10000, 100000):
        lo, hi = plectoneme_boxes(n, 0.01)
        t0 = time.perf_counter()
        pairs = candidate_pairs(lo, hi, skip=2)
        dt = time.perf_counter() - t0
        print(
            f"search: {n} segments, {len(pairs)} candidate pairs, {dt * 1e3:.1f} ms "
            f"({dt / n * 1e9:.0f} ns a segment)"
        )

    alpha = greenhill_clamped()
    print(f"Greenhill, clamped ends: M_c L/EI = {alpha:.6f} = {alpha / np.pi:.6f} π")

    elements = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    base = no_contact_timing(elements)
    model = build_model(scene(elements, 0.5 * mu * N_TOTAL, 0.0), MPI.COMM_SELF)
    n_blocks = model.V.tabulate_dof_coordinates().shape[0]
    contact = Contact(np.arange(n_blocks), mu, c=1e4)
    contact.z_old = np.zeros(n_blocks)
    timings: dict = {}
    try:
        its = newton(model, contact, timings, max_it=10)[0]
    except RuntimeError:
        its = 10  # the iterations' cost is what is timed here
    med = {k: 1e3 * np.median(v) for k, v in timings.items()}
    med0 = {k: 1e3 * np.median(v) for k, v in base.items()}
    print(
        f"timing, {elements} P3 cells ({6 * (3 * elements + 1)} dofs), medians: no contact "
        f"F+J {med0['assembly']:.1f} ms, LU {med0['solve']:.1f} ms; contact F+J "
        f"{med['assembly']:.1f} ms, rows {med['contact']:.1f} ms, LU {med['solve']:.1f} ms "
        f"({its} iterations)"
    )
