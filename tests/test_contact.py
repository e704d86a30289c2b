"""Contact with rigid obstacles and Coulomb friction (issue 30; docs/contact.md).

A free-free straight rod along e3 (L = 1 m, circle d = 0.02 m, E = 1e7 Pa, ρ = 1000 kg/m³,
weight w = ρ A g = 3.082 N/m) lies on the plane x = −r (its surface touches: the gap of node i
is its x), under gravity along −e1; its end s = L is pulled along the rod by T and lifted by V.
Closed forms (linear theory, small loads; derivations in docs/contact-design.md, "Closed
forms"):

* (P.1) lifted by V: the lifted length a = 2V/w, the end's height h = 2V⁴/(3 w³ EI)
  (Euler–Bernoulli: a point reaction V at the lift-off point where M = 0; the shear terms
  V a − w a²/2 vanish);
* (P.2) pulled by T < μ w L: the slip zone a = T/(μ w) at the pulled end, the rest exactly
  still, the end slides u = T²/(2 EA μ w) (the friction μ w per length uniform in the slip
  zone, the axial strain T(s)/EA integrated);
* (P.3) T > μ w L: no static equilibrium;
* (D.1) sliding along the plane with speed v0, every point alike: the kinetic friction μ w a
  length decelerates the rod rigidly (no internal force), so it stops after
  d = v0²/(2 μ_k g) at t = v0/(μ_k g), having given its kinetic energy ½ ρ A L v0² to
  friction; with μ_s ≥ μ_k it then stays (gravity has no tangential part).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI

from cosserat_fem import api
from cosserat_fem.analysis.statics import static_path, static_solver
from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import scene_from_dict

L, D, RHO, E, G = 1.0, 0.02, 1000.0, 1e7, 9.81
AREA, INERTIA = math.pi * D**2 / 4, math.pi * D**4 / 64
W = RHO * AREA * G  # N/m


def rod_on_plane(
    elements: int,
    pull: float = 0.0,
    lift: float = 0.0,
    mu: float = 0.5,
    nu: float = 0.3,
    planar: str = "auto",
    **contact,
) -> dict:
    """The scene of the module docstring."""
    return {
        "rod": {
            "length": L,
            "section": {"shape": "circle", "diameter": D, "shear_coefficient": 0.9},
            "material": {"density": RHO, "young_modulus": E, "poisson_ratio": nu},
        },
        "supports": {"start": "free", "end": "free"},
        "loads": {"gravity": [-G, 0, 0], "end": {"force": [lift, 0, pull]}},
        "static": {"load_steps": 1},
        "time": {"end": 1.0, "step": 1.0},
        "discretisation": {"elements": elements, "degree": 3, "planar": planar},
        "contact": {
            "obstacles": [{"kind": "plane", "point": [-D / 2, 0, 0], "normal": [1, 0, 0]}],
            "static_friction": mu,
            **contact,
        },
    }


def displacements(data: dict) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """σ of each node and its displacement [m] (nodes, 3) at the static state; the Newton
    iterations of each load step."""
    result = static_path(scene_from_dict(data), comm=MPI.COMM_SELF, write_outputs=False)
    model = result.model
    layout, u = model.layout, model.U.x.array
    bs = layout.size
    out = np.zeros((u.size // bs, 3))
    for k in range(3):
        slot = layout.index(k)
        if slot is not None:
            out[:, k] = u[slot::bs] * L
    return model.V.tabulate_dof_coordinates()[:, 0], out, result.iterations


def test_a_pulled_rod_slides_at_its_end_and_sticks_exactly_elsewhere():
    """(P.2) at T = 0.5 μ w L, μ = 0.5, 10 cubic cells: the slip zone ends at σ = 0.5, a node,
    where the exact displacement (quadratic in the slip zone, zero beyond) is a P3 function
    and the consistent nodal friction forces are the uniform friction's: the end's slide is
    T²/(2 EA μ w) to round-off (bound 1e-10 relative; measured 1e-15). The stuck nodes do
    not move at all: their rows are Δx_T = 0 (bound 1e-15 m, measured 0.0). The 3D model
    (planar off: two tangent directions, the slip row's 3D tangent) equals the x-z one to
    1e-12 of the slide."""
    mu = 0.5
    T = 0.5 * mu * W * L
    sigma, u, _ = displacements(rod_on_plane(10, pull=T, mu=mu))
    slide = T**2 / (2 * E * AREA * mu * W)
    assert abs(u[np.argmax(sigma), 2] / slide - 1) < 1e-10
    stuck = sigma < 1 - T / (mu * W * L) - 1e-9
    assert stuck.sum() >= 15
    assert np.abs(u[stuck]).max() <= 1e-15
    sigma3, u3, _ = displacements(rod_on_plane(10, pull=T, mu=mu, planar="off"))
    assert np.array_equal(sigma3, sigma)
    assert np.abs(u3 - u).max() <= 1e-12 * slide


def test_a_pull_beyond_the_friction_has_no_equilibrium():
    """(P.3): T = 1.1 μ w L exceeds what friction holds: no static state, a SolverError
    (the load steps halved to their limit) rather than a state."""
    with pytest.raises(SolverError, match="load"):
        displacements(rod_on_plane(4, pull=1.1 * 0.5 * W * L, mu=0.5))


def test_a_rod_lifted_at_its_end_leaves_the_plane_as_the_closed_form():
    """(P.1) at V = 0.05 w L, 20 cubic cells, the shear made stiff (ν = −0.99: κGA 130×
    larger, so the shear layer sqrt(EI/κGA) where the point reaction spreads is 7e-3 of the
    lifted length; with ν = 0.3 it is 8.5 % and h differs by 4 %: docs/contact-design.md):
    the end's height within 1e-4 of 2V⁴/(3 w³ EI) (measured −7.2e-6 on every mesh from 10 to
    80 cells: the geometric nonlinearity at this V). No node goes through the plane
    (x ≥ −1e-12 m: the gap row holds to round-off, measured 1e-18 m). The lifted nodes are
    those beyond L − 2V/w, to the node spacing; the Newton iterations at most 2 + 2 a lifted
    node."""
    V = 0.05 * W * L
    sigma, u, its = displacements(rod_on_plane(20, lift=V, nu=-0.99))
    h = 2 * V**4 / (3 * W**3 * E * INERTIA)
    assert abs(u[np.argmax(sigma), 0] / h - 1) < 1e-4
    assert u[:, 0].min() >= -1e-12
    lifted = sigma[u[:, 0] > 1e-12]
    assert abs(lifted.min() - (1 - 2 * V / (W * L))) <= 1.0 / 20
    # the lift-off front moves about a node an iteration (no predictor for it): a guard of
    # 2 + 2 a lifted node (7 nodes; measured 11)
    assert its[0] <= 2 + 2 * lifted.size


def jacobian_case(case: str) -> dict:
    """A scene whose nodes touch a curved obstacle at rest (gap 0 to round-off): in 3D an arc
    (ρ = 0.1 m) on a sphere about its centre; planar (x-z) the straight rod on a cylinder
    of radius 20 m whose axis e2 passes 20 m + r below its middle (gaps ≤ (s − L/2)²/2R =
    6e-3 m)."""
    if case == "3d":
        R, r = 0.1, D / 20
        rho = R + r
        data = rod_on_plane(3, mu=0.3, planar="off", kinetic_friction=0.2)
        data["rod"]["section"]["diameter"] = 2 * r
        data["reference"] = {"shape": "arc", "radius": rho}
        data["loads"] = {"start": {"force": [0, 0, -10]}, "end": {"force": [5, 3, 1]}}
        data["contact"]["obstacles"] = [{"kind": "sphere", "point": [rho, 0, 0], "radius": R}]
        return data
    if case == "surface":  # the 3D case's sphere given as a signed distance of x, y, z
        data = jacobian_case("3d")
        rho, R = data["reference"]["radius"], data["contact"]["obstacles"][0]["radius"]
        distance = f"sqrt((x - {rho!r})**2 + y**2 + z**2) - {R!r}"
        data["contact"]["obstacles"] = [{"kind": "surface", "distance": distance}]
        return data
    data = rod_on_plane(3, mu=0.3, kinetic_friction=0.2)
    data["contact"]["obstacles"] = [
        {"kind": "cylinder", "point": [-20 - D / 2, 0, 0.5], "axis": [0, 1, 0], "radius": 20}
    ]
    return data


@pytest.mark.parametrize("case", ["3d", "planar", "surface"])
@pytest.mark.parametrize("state", ["slip", "stick"])
def test_the_rows_jacobian_is_the_derivative_of_the_rows(case, state):
    """The Jacobian rows of the contact (K.2)-(K.3) against central differences of the
    residual with its rows, at a random state u about the rest (1e-3 scaled: nodes through
    the obstacle and off it): sliding nodes (c = 1e3, the friction's history at rest: the
    trial c Δu beyond the cone) or stuck ones (c = 1e6, the history at u: Δu = 0), in 3D on
    a sphere (the obstacle's curvature in both tangent directions, the tangent basis's turn)
    and in the x-z plane on a cylinder, and on the sphere given as a surface's signed
    distance (its gradient and Hessian by the expressions' derivatives). The differences'
    error is O(ε²): from ε = 1e-5 to 1e-6 it falls 100× (bound 30-300; measured 3D slip
    1.7e-5 → 1.7e-7, stick 7.7e-6 → 7.7e-8), unless it is the differences' round-off
    already (planar, the cylinder's curvature 1/20 m: 7e-11 and 2e-10 at 1e-5), and at 1e-6
    it is below 1e-5 of the rows (a missing term would leave an O(1) error). The states
    decided at u ± ε v are those at u (checked)."""
    data = jacobian_case(case)
    scene = scene_from_dict(data)
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    contact = solver.contact
    rng = np.random.default_rng(1)
    u0 = rng.normal(size=model.U.x.array.size) * 1e-3
    c = 1e3 if state == "slip" else 1e6  # an augmentation held fixed
    if state == "stick":
        contact.u_old = u0[contact.px].copy()

    def rows(u):
        model.U.x.array[:] = u
        contact.c = c
        solver._residual()
        return solver.b.array.copy(), contact.state.copy()

    _, states = rows(u0)
    wanted = 2 if state == "slip" else 1
    assert np.sum(states == wanted) >= 2 and np.sum(states == 0) >= 1, states
    contact.c = c
    solver._assemble_jacobian()
    v = rng.normal(size=u0.size)
    x, y = solver.A.createVecs()
    x.array[:] = v
    solver.A.mult(x, y)
    active = contact.pq[states != 0].ravel()
    errors = []
    for eps in (1e-5, 1e-6):
        (plus, s_plus), (minus, s_minus) = rows(u0 + eps * v), rows(u0 - eps * v)
        assert np.array_equal(s_plus, states) and np.array_equal(s_minus, states)
        fd = (plus - minus) / (2 * eps)
        errors.append(np.abs(fd - y.array)[active].max() / np.abs(y.array[active]).max())
    assert errors[1] < 1e-5, errors
    # O(ε²) unless the differences' error is their round-off already (ε = 1e-5: ~1e-11 / ε)
    assert errors[0] < 1e-8 or 30 < errors[0] / errors[1] < 300, errors


def test_a_surface_given_by_its_distance_is_the_obstacle_it_describes():
    """(P.1) and (P.2) at once (the rod lifted by V = 0.05 w L and pulled by 0.4 μ w L) on
    the plane x = −r given as kind "plane" and as kind "surface" with the distance x + r
    (evaluated through the expressions and their derivatives, which the rows' Jacobian test
    above checks on a sphere): the same static state to round-off (1e-12 of the
    displacements) and the same Newton iterations (within one)."""
    states = []
    for kind in ("plane", "surface"):
        data = rod_on_plane(10, lift=0.05 * W * L, pull=0.2 * W * L, nu=-0.99)
        if kind == "surface":
            data["contact"]["obstacles"] = [{"kind": "surface", "distance": f"x + {D / 2!r}"}]
        result = static_path(scene_from_dict(data), comm=MPI.COMM_SELF, write_outputs=False)
        states.append((result.model.U.x.array.copy(), result.iterations))
    (u_plane, it_plane), (u_surface, it_surface) = states
    # the same problem to round-off: the same iterations, or one more where a CPU rounds a
    # stop test's last digit the other way
    assert abs(sum(it_surface) - sum(it_plane)) <= 1
    assert np.abs(u_surface - u_plane).max() <= 1e-12 * np.abs(u_plane).max()


@pytest.mark.parametrize(
    ("distance", "message"),
    [
        ("x**2 + y**2 + z**2 - 1", "not a signed distance"),
        ("sqrt(x - 1)", "not finite at s"),
        ("0*x + 0.5", "its gradient is 0 at every node"),
    ],
)
def test_a_surface_that_is_not_a_signed_distance_is_refused(distance, message):
    """A function that vanishes on the surface but is no distance (|∇d| ≠ 1) would give
    wrong gaps, and one without a value at a node (a NaN gap is never in contact): refused
    at the start in one line naming the key and the place."""
    data = jacobian_case("surface")
    data["contact"]["obstacles"][0]["distance"] = distance
    with pytest.raises(SceneError, match=rf"^contact\.obstacles\[0\]\.distance: {message}"):
        static_path(scene_from_dict(data), comm=MPI.COMM_SELF, write_outputs=False)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"obstacles": [{"kind": "plane", "point": [0, 0, 0]}]},
            r"^contact\.obstacles\[0\]\.normal: a plane needs it",
        ),
        (
            {
                "obstacles": [
                    {"kind": "sphere", "point": [0, 0, 0], "radius": 1, "normal": [1, 0, 0]}
                ]
            },
            r"^contact\.obstacles\[0\]\.normal: a sphere takes no normal",
        ),
        (
            {"obstacles": [{"kind": "plane", "point": [0, 0, 0], "normal": [0, 0, 0]}]},
            r"^contact\.obstacles\[0\]\.normal: must not be the zero vector",
        ),
        ({"obstacles": []}, r"^contact\.obstacles: give one obstacle"),
        (
            {"obstacles": [{"kind": "surface", "point": [0, 0, 0], "distance": "z"}]},
            r"^contact\.obstacles\[0\]\.point: a surface takes no point",
        ),
        ({"obstacles": [{"kind": "surface"}]}, r"^contact\.obstacles\[0\]\.distance: a surface"),
        (
            {"obstacles": [{"kind": "surface", "distance": "z + w"}]},
            r"^contact\.obstacles\[0\]\.distance",
        ),
        (
            {"obstacles": [{"kind": "surface", "distance": 0.5}]},
            r"^contact\.obstacles\[0\]\.distance: must depend on the position",
        ),
        (
            {"obstacles": [{"kind": "plane", "normal": [1, 0, 0]}]},
            r"^contact\.obstacles\[0\]\.point",
        ),
        ({"obstacles": [{"kind": "cone", "point": [0, 0, 0]}]}, r"^contact\.obstacles\[0\]\.kind"),
        ({"kinetic_friction": 0.9}, r"^contact\.kinetic_friction: must not exceed"),
        ({"static_friction": -1}, r"^contact\.static_friction"),
    ],
)
def test_bad_contact_input_is_one_line_naming_the_key(change, message):
    """Each mistake is a SceneError whose one line starts with the key at fault."""
    data = rod_on_plane(4)
    data["contact"].update(change)
    with pytest.raises(SceneError, match=message) as info:
        scene_from_dict(data)
    assert "\n" not in str(info.value)


def test_a_rectangle_needs_the_contact_radius_given():
    """ "auto" takes a circle's or a tube's radius; a rectangle's surface is not a tube:
    contact.radius must be given (the circumscribed tube is the user's choice)."""
    data = rod_on_plane(4)
    data["rod"]["section"] = {"shape": "rectangle", "a": 0.01, "b": 0.02}
    with pytest.raises(SceneError, match=r"^contact\.radius: give the surface's radius"):
        scene_from_dict(data)
    data["contact"]["radius"] = 0.0112
    assert scene_from_dict(data).contact.radius == 0.0112


def sliding(integrator: str, step: float, mu_k: float = 0.5, mu_s: float = 0.5, end=0.3) -> dict:
    """(D.1): the rod on the plane, 10 cubic cells, with v0 = 1 m/s along e3."""
    data = rod_on_plane(10, mu=mu_s, kinetic_friction=mu_k)
    data["initial"] = {"velocity": [0, 0, 1.0]}
    data["time"] = {"end": end, "step": step, "integrator": integrator}
    return data


@pytest.mark.parametrize("integrator", ["bdf2", "generalized-alpha"])
def test_a_sliding_rod_stops_after_the_closed_form_distance(integrator):
    """(D.1) at μ = 0.5, h = 5 ms (N = 41 steps to the stop): the semi-discrete system is
    solved exactly by the uniform deceleration (the consistent mass times a uniform
    acceleration is the consistent load, and the nodal friction forces are μ times the
    consistent nodal weights), BDF2 and generalized-α integrate the quadratic trajectory
    exactly, and the error is the last step's, where the nodes stick instead of reversing:
    at most v h with v ≤ μ g h, relative 2/N² = 1.2e-3 (bound 2e-3; measured 3.1e-5 BDF2,
    8.3e-5 generalized-α). After the stop nothing moves (the stick rows: 1e-12 m over the
    last 50 ms); no node goes through the plane (1e-12 m). The friction's work in
    summary.json is the kinetic energy, to the same bound (measured 3e-5 BDF2, 4.5e-5
    generalized-α: whose initial acceleration holds the nodes on the plane and brakes them by
    friction; started in free fall and frictionless, its normal force oscillated about the
    weight, 3.85, 2.70, 3.27 N ..., and it slid 0.8 % too far)."""
    v0, mu = 1.0, 0.5
    result = api.run(scene_from_dict(sliding(integrator, 0.005)))
    t, x, z = result.probes[:, 0], result.probes[:, 1], result.probes[:, 3]
    d = v0**2 / (2 * mu * G)
    assert abs(z[-1] / d - 1) < 2e-3
    assert np.ptp(z[t >= 0.25]) <= 1e-12
    assert x.min() >= -1e-12
    kinetic = 0.5 * RHO * AREA * L * v0**2
    assert abs(result.summary["contact"]["friction_work_J"] / kinetic - 1) < 2e-3
    assert result.summary["contact"]["nodes_stick"] == 31


def test_kinetic_friction_slides_and_static_friction_holds():
    """μ_k = 0.3 < μ_s = 0.6: the slide is v0²/(2 μ_k g) (the kinetic coefficient governs
    it; bound as above, N = 68 steps: 4.3e-4, asserted 1e-3), and the rod then stays,
    held by the static one."""
    result = api.run(scene_from_dict(sliding("bdf2", 0.005, mu_k=0.3, mu_s=0.6, end=0.45)))
    t, z = result.probes[:, 0], result.probes[:, 3]
    assert abs(z[-1] / (1.0 / (2 * 0.3 * G)) - 1) < 1e-3
    assert np.ptp(z[t >= 0.4]) <= 1e-12


def test_a_sliding_run_restarts_bit_for_bit(tmp_path):
    """To 0.15 s in one go, and to 0.1 s then restarted from its checkpoint: the same states,
    bit for bit (the contact's set, its friction history and augmentation are in the
    checkpoint), while the rod still slides at 0.1 s. Released 1 mm above the plane, it lands
    at 14 ms: the counters (friction_work_J, impact_loss_J > 0) are restored too."""
    data = sliding("bdf2", 0.005, end=0.15)
    data["initial"]["displacement"] = ["0.001", 0, 0]
    data["output"] = {"checkpoint_interval": 0.05}
    whole = api.run(scene_from_dict(data), tmp_path / "whole")
    part = {**data, "time": {**data["time"], "end": 0.1}}
    api.run(scene_from_dict(part), tmp_path / "part")
    scene, checkpoint = api.resume(tmp_path / "part", ["time.end=0.15"])
    rest = api.run(scene, restart=checkpoint)
    assert np.array_equal(whole.model.U.x.array, rest.model.U.x.array)
    assert whole.summary["contact"] == rest.summary["contact"]
    assert whole.summary["contact"]["impact_loss_J"] > 0


def test_contact_is_refused_where_it_is_not_imposed():
    """SDIRK (its step is not its solved stage) and the linearisations (modes) refuse a
    scene with [contact] in one line naming the key."""
    data = sliding("sdirk3", 0.005)
    with pytest.raises(SceneError, match=r"^time\.integrator: contact needs"):
        api.run(scene_from_dict(data))
    with pytest.raises(SceneError, match=r"^contact: modes does not impose contact"):
        api.modes(scene_from_dict(rod_on_plane(4)))


def test_the_contact_forces_and_gaps_are_written(tmp_path):
    """output.fields and probe_fields "contact": at 50 ms, while every node slides, the XDMF's
    contact load [N/m] (each node's force over its share of the length) is the weight w a
    length along e1 and −μ w along the slide at every point (the consistent nodal forces of
    a uniform load are its density times the shares; bound 1e-9 relative), the gaps are 0
    (1e-12 m) and every state is 2 (slip: interpolated between the nodes, to round-off); the
    probe (the end s = L) the same."""
    from xdmf_files import read_arrays

    data = sliding("bdf2", 0.005, end=0.05)
    data["output"] = {"fields": ["displacement", "contact"], "probe_fields": ["contact"]}
    result = api.run(scene_from_dict(data), tmp_path)
    _, times, arrays = read_arrays(tmp_path / "solution.xdmf")
    force, gap = arrays["contact_load"][-1], arrays["contact_gap"][-1]
    assert times[-1] == pytest.approx(0.05)
    assert np.abs(force - [W, 0.0, -0.5 * W]).max() <= 1e-9 * W
    assert np.abs(gap[:, 0]).max() <= 1e-12 and np.abs(gap[:, 1] - 2.0).max() <= 1e-12
    row = result.probes[-1]
    assert row[7:12] == pytest.approx([W, 0.0, -0.5 * W, 0.0, 2.0], rel=1e-9, abs=1e-12)


DRUM, ROPE = 0.1, 0.002  # the capstan's drum radius and rope diameter [m]


def capstan(theta: float, mu: float, ratio: float, end: float = 0.1, T1: float = 1.0) -> dict:
    """A rope (d = 2 mm, E = 1e8 Pa, ρ = 1150 kg/m³, 16 cubic cells) wrapped by θ over a fixed
    drum of radius 0.1 m (axis e2): at rest an arc of the centreline radius ρ = R + r about
    the drum's axis, its ends pulled along their tangents by T1 (s = 0) and T2 = ratio T1
    (s = ρθ), both raised over 50 ms (a load applied at once overshoots and slides a rope
    that would hold), BDF2 at 1 ms."""
    rho = DRUM + ROPE / 2
    ramp = "min(1, t/0.05)"
    T2 = ratio * T1
    return {
        "rod": {
            "length": rho * theta,
            "section": {"shape": "circle", "diameter": ROPE},
            "material": {"density": 1150.0, "young_modulus": 1e8, "poisson_ratio": 0.3},
        },
        "reference": {"shape": "arc", "radius": rho},
        "supports": {"start": "free", "end": "free"},
        "loads": {
            "start": {"force": [0, 0, f"-{T1}*{ramp}"]},
            "end": {
                "force": [f"{T2 * math.sin(theta)}*{ramp}", 0, f"{T2 * math.cos(theta)}*{ramp}"]
            },
        },
        "time": {"end": end, "step": 1e-3, "integrator": "bdf2"},
        "discretisation": {"elements": 16, "degree": 3},
        "contact": {
            "obstacles": [
                {"kind": "cylinder", "point": [rho, 0, 0], "axis": [0, 1, 0], "radius": DRUM}
            ],
            "static_friction": mu,
        },
    }


def rope_ends(result) -> tuple[float, float]:
    """The displacements [m] of the rope's ends s = 0 and s = ℓ at the end of the run."""
    model = result.model
    u, bs = model.U.x.array, model.layout.size
    sigma = model.V.tabulate_dof_coordinates()[:, 0]
    disp = np.stack([u[model.layout.index(k) :: bs] for k in (0, 2)], axis=1) * model.length
    return (
        float(np.linalg.norm(disp[np.argmin(sigma)])),
        float(np.linalg.norm(disp[np.argmax(sigma)])),
    )


@pytest.mark.long
@pytest.mark.parametrize(
    ("mu", "theta"), [(0.1, math.pi / 2), (0.3, math.pi), (0.5, 1.5 * math.pi)]
)
def test_the_capstan_holds_below_its_critical_ratio_and_slides_above(mu, theta):
    """The capstan (Euler–Eytelwein): the rope holds while T2/T1 < e^{μθ} and slides beyond.
    The friction acts at the centreline (docs/contact.md, "Limits"), so the critical ratio
    is e^{μθ} exactly for the continuum (friction at the surface would give e^{μθR/(R+r)},
    0.5 % lower here). μ ∈ {0.1, 0.3, 0.5}, θ ∈ {π/2, π, 3π/2}, T2 = 2.5 N (EA = 314 N).
    At 0.99 e^{μθ} the rope holds: its low end s = 0 moves at most 1e-4 m over the run (the
    issue's bound; it is the elastic stretch of a short slip zone there: measured 5.8e-5,
    2.3e-6, 4.0e-5 m), nothing moves over the last 30 ms (1e-12 m: the stick rows), and no
    point between the nodes goes through the drum by more than 1 % of the rope's radius (the
    P3 curve's dip between nodes on the drum; measured 1.8e-4, 5.4e-5, 8.5e-6 r). At
    1.01 e^{μθ} it slides: the excess 1 % of T2 = 0.025 N on the rope's mass (1.2-1.7 g)
    accelerates it by ≥ 14 m/s², ≥ 0.16 m in the 0.15 s after the ramp if nothing else
    acted; asserted > 0.02 m by 0.2 s (measured 2.6, 0.07, 0.012 m at 0.1 s). So the
    critical ratio is e^{μθ} within 1 %. ~30-50 s each."""
    crit = math.exp(mu * theta)
    T1 = 2.5 / crit  # T2 2.5 N at most: the rope's strain T/EA ≤ 0.8 %
    stations = np.linspace(0.0, 1.0, 401)
    held = api.run(scene_from_dict(capstan(theta, mu, 0.99 * crit, T1=T1)), fields=stations)
    low, _ = rope_ends(held)
    assert low <= 1e-4
    t = held.probes[:, 0]
    assert np.ptp(held.probes[t >= 0.07, 1:4], axis=0).max() <= 1e-12
    rho = DRUM + ROPE / 2
    x = held.model.scene.reference.positions(stations * rho * theta) + held.field_values[-1][:, :3]
    gap = np.hypot(x[:, 0] - rho, x[:, 2]) - rho
    assert gap.min() >= -0.01 * ROPE / 2
    slid = api.run(scene_from_dict(capstan(theta, mu, 1.01 * crit, T1=T1, end=0.2)))
    assert rope_ends(slid)[0] > 0.02


def dropped(max_changes: int, end: float = 0.15) -> dict:
    """The rod of the module docstring released 2 mm above the plane at s = 0 and 22 mm at
    s = L (a tilt of 0.02), BDF2 at 5 ms: its low end lands first, then the rest of it."""
    data = rod_on_plane(10, mu=0.5, max_changes=max_changes)
    data["initial"] = {"displacement": ["0.002 + 0.02*s", 0, 0]}
    data["time"] = {"end": end, "step": 0.005, "integrator": "bdf2", "max_halvings": 8}
    return data


def test_a_step_that_changes_the_contact_set_too_much_is_halved(tmp_path):
    """contact.max_changes: the tilted rod landing brings 11 nodes into or out of contact in
    one 5 ms step without a cap (measured; > 5 asserted, so the cap has work to do); with
    max_changes = 5 the steps that would change more are rejected and halved, and no
    accepted step changes more than 5 (summary.json's most_changes_in_a_step), to 0.1 s:
    with the midpoint steps around its impacts (timestepping/loop.py, "Impacts") the rod
    bounces on, and at 0.143 s six nodes along it come or go at once, which no halving
    splits (measured; without them the run to 0.15 s passed). With 3, the
    changes at one place cannot be split below 2e-5 s (nodes of one cell landing together):
    the run stops with a one-line SolverError giving the time, the place (s) and the key,
    and keeps the outputs written before (probes.csv's rows up to the stop)."""
    free = api.run(scene_from_dict(dropped(0)))
    assert free.summary["contact"]["most_changes_in_a_step"] > 5
    capped = api.run(scene_from_dict(dropped(5, end=0.1)))
    assert capped.summary["contact"]["most_changes_in_a_step"] <= 5
    assert capped.summary["rejected_steps"] >= 1
    with pytest.raises(SolverError) as info:
        api.run(scene_from_dict(dropped(3)), tmp_path)
    message = str(info.value)
    assert "\n" not in message and "contact.max_changes = 3" in message
    assert " at t = " in message and message.startswith("s = ")
    rows = (tmp_path / "probes.csv").read_text().splitlines()
    assert len(rows) > 2  # the header, t = 0 and the steps before the stop


def test_a_solve_whose_contact_set_does_not_settle_says_where():
    """A Newton solve that ends while the contact set still changes (here forced: one
    iteration allowed, the sliding rod's 31 nodes all coming into contact at its first
    iterate) fails with the set's change in its one line: how many nodes and where."""
    data = sliding("bdf2", 0.005)
    data["time"]["max_halvings"] = 0
    data["solver"] = {"max_iterations": 1}
    with pytest.raises(
        SolverError, match=r"the contact set still changed at 31 nodes, s = 0 to 1 m"
    ):
        api.run(scene_from_dict(data))


def test_a_slip_front_across_the_rod_takes_few_newton_iterations():
    """The chain predictor (nls/contact.py ``_chain``): pulled by T = 0.9 μ w L (the slip zone
    0.9 of the rod) in one load step, the slip front crosses 0.9 of the nodes; without the
    predictor the active set moves one node an iteration (≥ 432 iterations at 160 cubic
    cells, 481 nodes: the solve fails at 25), with it the count does not grow with the mesh
    (measured 13, 10, 8 at 10, 40, 160 cells; bound 20). The answer is (P.2)'s at every mesh
    (1e-10: the slip front at a node, σ = 0.1)."""
    mu = 0.5
    T = 0.9 * mu * W * L
    for cells in (10, 40, 160):
        sigma, u, its = displacements(rod_on_plane(cells, pull=T, mu=mu))
        assert its[0] <= 20, cells
        assert abs(u[np.argmax(sigma), 2] / (T**2 / (2 * E * AREA * mu * W)) - 1) < 1e-10


def test_a_rod_pulled_beyond_static_friction_starts_to_slide_at_the_kinetic_one():
    """μ_s = 0.6 > μ_k = 0.3, the end pulled from rest by T = 1.2 μ_s w L (a step load): static
    friction cannot hold it, and once every node slides the friction is μ_k w L, so the
    centre of mass accelerates at a = (T − μ_k w L)/(ρ A L) whatever the axial waves (the
    momentum balance). Its position (the fields at 601 stations, trapezoid) fitted by a
    quadratic over 50-100 ms gives a to 1e-9 (BDF2 is exact on a quadratic; measured
    1e-14). Before the fix a node that started to slide met μ_k f_N, stuck again by μ_s,
    and alternated to the iteration limit (the review's finding)."""
    mu_s, mu_k = 0.6, 0.3
    T = 1.2 * mu_s * W * L
    data = rod_on_plane(10, pull=T, mu=mu_s, kinetic_friction=mu_k)
    data["time"] = {"end": 0.1, "step": 0.001, "integrator": "bdf2"}
    stations = np.linspace(0.0, 1.0, 601)
    result = api.run(scene_from_dict(data), fields=stations)
    t = result.field_times
    centre = np.trapz(result.field_values[:, :, 2], stations, axis=1)
    late = t >= 0.05
    acceleration = 2 * np.polyfit(t[late], centre[late], 2)[0]
    assert acceleration == pytest.approx((T - mu_k * W * L) / (RHO * AREA * L), rel=1e-9)
    assert result.summary["contact"]["nodes_slip"] == 31


def test_a_rod_starting_inside_an_obstacle_or_on_a_partly_held_end_is_refused():
    """A sphere overlapping the rod at rest: one line naming the obstacle, its depth and s,
    before any step. A sliding end (x, y held, z free): refused naming the support (contact
    rows are written for nodes free or held in all their positions)."""
    data = rod_on_plane(4)
    data["contact"]["obstacles"].append({"kind": "sphere", "point": [0.05, 0, 0.5], "radius": 0.1})
    with pytest.raises(
        SceneError,
        match=r"^contact\.obstacles\[1\]: the rod starts inside this sphere, 0\.06 m deep at "
        r"s = 0\.5 m",
    ):
        api.run(
            scene_from_dict({**data, "time": {"end": 0.01, "step": 0.005, "integrator": "bdf2"}})
        )
    data = rod_on_plane(4)
    data["supports"] = {"start": "clamped", "end": "sliding"}
    with pytest.raises(
        SceneError, match=r"^supports\.end: a sliding end holds some of its positions"
    ):
        scene_from_dict(data)


def test_the_first_output_has_the_initial_gaps():
    """At t = 0 the contact outputs carry the gap of the initial state (no force yet): the
    rod released 2 mm above the plane at s = 0 and 22 mm at s = L (the probe's end)."""
    data = dropped(0, end=0.01)
    data["output"] = {"probe_fields": ["contact"]}
    first = api.run(scene_from_dict(data)).probes[0]
    assert first[0] == 0.0
    assert first[10] == pytest.approx(0.022, abs=1e-15)  # contact_gap at s = L


def test_a_gap_without_a_value_during_a_solve_is_an_error_with_its_place():
    """A surface's distance defined only on part of space (x + r plus 0 × sqrt(x + 0.5):
    a plane's distance where x ≥ −0.5, none below): an iterate that puts a node below gets a
    NaN gap, which no row would hold (a NaN is never pressed). The residual raises a
    SolverError naming the node's s, on every rank (retried by a smaller step)."""
    from cosserat_fem.common.errors import SolverError

    data = rod_on_plane(3)
    data["contact"]["obstacles"] = [
        {"kind": "surface", "distance": f"x + {D / 2!r} + 0*sqrt(x + 0.5)"}
    ]
    scene = scene_from_dict(data)
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    solver._residual()  # finite at rest
    bs, x = model.layout.size, model.layout.index(0)
    sigma = model.V.tabulate_dof_coordinates()[:, 0]
    end = int(np.argmax(sigma))
    model.U.x.array[end * bs + x] = -1.0 / L  # the end node 1 m down: below x = −0.5
    with pytest.raises(
        SolverError, match=r"^contact: the obstacle's gap is not finite at s = 1 m"
    ) as e:
        solver._residual()
    assert e.value.retry
