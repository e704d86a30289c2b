"""cosserat_fem/nls/constraints.py: dofs identified by rows of the assembled system.

A joint whose copy is tied to its master in all twelve components is a rigid joint: the Newton
iterates with the rows (C.1)-(C.2) must be those of the shared vertex (today's rigid joint), to
the round-off of the row operations; and the rows on a vector are the sums and differences
(C.1)-(C.2) themselves.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis.statics import static_solver
from cosserat_fem.nls.constraints import Identification
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import scene_from_dict

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from test_joints import frame_scene, gerber, pendulum  # noqa: E402


def solved(joint: bool, components: tuple[int, ...] | None = None):
    """The Gerber beam (tests/test_joints.py) at P = 1e-3 statically; with the joint's
    identified ``components`` replaced (all twelve: a rigid joint). w_D [length]."""
    scene = frame_scene(gerber(1e-3, joint=joint))
    model = build_model(scene, MPI.COMM_SELF, planar=False)
    if components is not None:
        ties = model.constraints
        assert ties is not None
        model.constraints = Identification(
            model.V,
            list(ties.master_blocks),
            list(ties.copy_blocks),
            [components] * len(ties.master_blocks),
            model.bcs,
        )
    solver = static_solver(scene, model)
    model.load_factor.value = 1.0
    solver.solve()
    return model, solver


def test_all_twelve_components_tied_are_the_shared_vertex():
    """Identification of the copy's twelve components: the state of the rigid joint (one
    shared vertex) within 1e-12 of its largest value (measured 1.5e-16: the row sums'
    round-off); the copy's values equal its master's to round-off (the constraint rows hold
    δ_c − δ_m = u_c − u_m, which the LU's solve meets to its round-off: 1e-14 of the
    largest value, not bit for bit, which another CPU's rounding would decide)."""
    shared, _ = solved(joint=False)
    tied, _ = solved(joint=True, components=tuple(range(12)))
    ties = tied.constraints
    u = tied.U.x.array
    assert np.abs(u[ties.copies] - u[ties.masters]).max() <= 1e-14 * np.abs(u).max()
    at = {}
    for model in (shared, tied):
        x = model.V.tabulate_dof_coordinates()
        values = model.U.x.array.reshape(-1, 12)
        at[id(model)] = {tuple(np.round(p, 9)): v for p, v in zip(x, values, strict=True)}
    scale = np.abs(shared.U.x.array).max()
    for point, value in at[id(shared)].items():
        assert np.abs(at[id(tied)][point] - value).max() <= 1e-12 * scale


def test_the_rows_on_a_vector_are_sums_and_differences():
    """apply_vector on a residual: each master's entry gains its copy's (C.1), each copy's is
    u_c − u_m (C.2); a master held by a support keeps its entry."""
    model, solver = solved(joint=True)
    ties = model.constraints
    rng = np.random.default_rng(1)
    b = rng.standard_normal(model.U.x.array.size)
    u = rng.standard_normal(b.size)
    want = b.copy()
    for c, m, added in zip(ties.copies, ties.masters, ties.added, strict=True):
        if added:
            want[m] += b[c]
        want[c] = u[c] - u[m]
    ties.apply_vector(b, u)
    assert np.array_equal(b, want)
    assert len(ties) == 6 and ties.added.all()  # x, y, z and their rates; B is not held


def test_the_compiled_residual_applies_the_linear_rows_only():
    """A serial solve of a structure with spherical joints assembles its residual in C
    (newton_loop.c cf_residual, the rows (C.1)-(C.2) included): the solver takes the C loop
    only after its first residual equalled DOLFINx's with Identification.apply_vector bit
    for bit (NewtonSolver._make_native). A hinge's rows (C.3)-(C.8) are numpy's only, one
    implementation: with a hinge the loop is Python's. (The double pendulum of
    tests/test_joints.py: no point load, whose interior facet integral keeps DOLFINx's
    assembly.)"""
    for kind, loop in (("spherical", "c"), ("hinge", "python")):
        scene = scene_from_dict(pendulum(1e-3, kind=kind))
        model = build_model(scene, MPI.COMM_SELF, planar=False)
        assert static_solver(scene, model).loop == loop, kind


def test_a_hinge_about_e3_in_one_chart_is_the_identification_of_theta_and_psi():
    """Joint (C.3)-(C.7) for a hinge about e3 whose copies share a chart (any chart, any
    angles with θ_a = θ_b, ψ_a = ψ_b): g = 0, G_b = −G_a on (θ, ψ), so the kinematic
    rows' C_K = diag(1, 1, 0) and N_K ∝ e3: the former identification, to round-off (1e-14).
    With φ_a = φ_b also C_R = diag(1, 1, 0) (the balance rows' combination, body turns over Î,
    equals the sum while the body frames agree) and differs once φ differs (by more than 1e-3
    at Δφ = 0.9)."""
    from cosserat_fem.nls.constraints import Joint
    from cosserat_fem.rod.charts import quaternion_frame

    rng = np.random.default_rng(3)
    Q = rng.standard_normal(4)
    frame = quaternion_frame(Q / np.linalg.norm(Q))
    joint = Joint(0, 1, np.array([0.0, 0.0, 2.0]), False)  # normalised
    joint.inertia = np.array([7.5e-5, 3.3e-5, 1.1e-4])
    theta, psi = 0.4, -1.3
    for phi_b, same in ((0.7, True), (1.6, False)):
        alpha = np.array([theta, psi, 0.7, theta, psi, phi_b])
        g = joint.constraint(alpha, 0.0, (frame, frame))
        _, _, _, _, (C_K, C_R), (N_K, _), G = joint.rows(
            alpha, np.zeros(6), np.zeros(3), np.zeros(3), (frame, frame)
        )
        assert np.abs(g).max() < 1e-14
        np.testing.assert_allclose(G[:, 3:5] @ np.linalg.inv(-G[:, :2]), np.eye(2), atol=1e-14)
        np.testing.assert_allclose(C_K, np.diag([1.0, 1.0, 0.0]), rtol=0, atol=1e-14)
        assert abs(N_K[0, 0]) + abs(N_K[0, 1]) < 1e-14 * abs(N_K[0, 2])
        off = np.abs(C_R - np.diag([1.0, 1.0, 0.0])).max()
        assert (off < 1e-13) if same else (off > 1e-3), (phi_b, off)


def test_a_joints_gradient_is_its_constraints_derivative():
    """Joint.gradient (complex steps) against central differences of Joint.constraint (step
    1e-6: truncation ~1e-12, round-off ~1e-10), for a hinge and a driven joint about a tilted
    axis in two different charts, at angles off the rest: within 1e-8."""
    from cosserat_fem.nls.constraints import Joint
    from cosserat_fem.rod.charts import quaternion_frame

    rng = np.random.default_rng(5)
    frames = tuple(quaternion_frame(q / np.linalg.norm(q)) for q in rng.standard_normal((2, 4)))
    alpha = rng.uniform(-0.8, 0.8, 6)
    for driven in (False, True):
        joint = Joint(0, 1, np.array([0.8, 0.0, 0.6]), driven)
        G = joint.gradient(alpha, 0.7, frames)
        eps = 1e-6
        for k in range(7):
            step = np.zeros(7)
            step[k] = eps
            up = joint.constraint(alpha + step[:6], 0.7 + step[6], frames)
            down = joint.constraint(alpha - step[:6], 0.7 - step[6], frames)
            np.testing.assert_allclose(G[:, k], (up - down) / (2 * eps), rtol=0, atol=1e-8)
