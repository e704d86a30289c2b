"""Pinned (hinge) and spherical ends of rods curved or kinked at rest (issue 27 item 2), each
against a linear solution derived here, and Lee's frame (scenes/lee_frame.toml).

The loads are small (displacements 1e-8 to 1e-6 of the rod's size), so the geometrically exact
rod answers as the linear theory of the same rod: its complementary energy is exactly
∫ (M²/EI + N²/EA + Q²/κGA + T²/GJ)/2 ds, the laws m = J (u − u0), n = K (v − v0) having no
coupling, so Castigliano's theorem on that energy (axial and shear compliance included) and a
stiffness method with exact Timoshenko members are this rod's linear closed forms. What is
left is the discretisation error, measured under refinement in each test, and the geometric
nonlinearity, of the order of the displacement over the size (≤ 2e-6 here).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import ufl
from conftest import ROOT
from cosserat_fem.forms.kinematics import directors
from cosserat_fem.forms.resultants import resultants
from dolfinx import fem

from cosserat_fem import api
from cosserat_fem.cli import main
from cosserat_fem.common.errors import SceneError
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.scene.build import scene_from_dict

LEE = ROOT / "scenes" / "lee_frame.toml"
BEND = ROOT / "scenes" / "bathe_bolourchi_bend.toml"


def section(EA: float, GA: float, EI: tuple[float, float], GJ: float) -> dict:
    """[rod.section] and [rod.material] of a rod with these stiffnesses [N, N m²] (area 1)."""
    shear = GA / EA  # G with E = EA, κ = 1
    return {
        "section": {
            "shape": "constants",
            "area": 1.0,
            "c11": EI[0] / EA,
            "c22": EI[1] / EA,
            "c33": GJ / (shear * EA),
            "shear_coefficient": 1.0,
        },
        "material": {"density": 1.0, "young_modulus": EA, "shear_modulus": shear * EA},
    }


def displacement(model, s: float) -> np.ndarray:
    """(x, y, z) displacement [m] at arc length s (output/fields.py's probe; serial)."""
    values = PointProbe(model, s / model.length).values()
    assert values is not None, "serial: this rank owns every cell"
    return values[:3]


def horizontal_force(model) -> np.ndarray:
    """e1 · n [N], the contact force's fixed-basis e1 component (forms/resultants.py, from the
    strains relative to the rest state) at the Gauss points of each cell (degree-many: the
    points where the derivative of a Lagrange field is most accurate)."""
    U = model.layout.full(model.U)
    chart = model.chart_form() if model.chart_moved else None
    reference = model.reference_form()
    n = resultants(U, model.rod, 0.0, chart, reference).n
    frame = reference.frame * directors(ufl.as_vector([U[k] for k in range(6)]), chart)
    degree, E = model.scene.discretisation.degree, model.scene.discretisation.elements
    gauss = (np.polynomial.legendre.leggauss(degree)[0] + 1.0) / 2.0
    expr = fem.Expression((frame.T * n)[0], gauss[:, None])
    return expr.eval(np.arange(E, dtype=np.int32)).ravel()


# A semicircular two-hinged arch of radius R = 1 m: EI = 1 N m², EA = 1e3 N, κGA = 500 N, so
# that the axial and shear compliance (1/EA + 1/κGA against R²/EI) change H by 2e-3 and the
# crown deflection by 6.6e-2 of themselves: more than the tolerances below, which thus see them.
R_ARCH, EI_ARCH, EA_ARCH, GA_ARCH = 1.0, 1.0, 1e3, 5e2
P_ARCH = 1e-6  # N, at the crown: δ/R = 2e-8


def arch_scene(elements: int, end: str = "pinned", extra: tuple[str, ...] = ()):
    """The arch (reference.shape = "arc": from the origin along e3 to (2R, 0, 0), crown at
    (R, 0, R)), pinned at both ends (hinges about the default axis, the binormal e2), a
    force −P e3 at the crown; cubic elements."""
    return scene_from_dict(
        {
            "title": "two-hinged semicircular arch",
            "rod": {
                "length": math.pi * R_ARCH,
                **section(EA_ARCH, GA_ARCH, (EI_ARCH, EI_ARCH), EI_ARCH),
            },
            "reference": {"shape": "arc", "radius": R_ARCH},
            "supports": {"start": "pinned", "end": end},
            "loads": {"point": {"s": math.pi * R_ARCH / 2, "force": [0, 0, -P_ARCH]}},
            "discretisation": {"elements": elements, "degree": 3},
            "time": {"end": 1.0, "step": 0.1},  # static only: unused
        },
        overrides=list(extra),
    )


def arch_closed_form(P: float) -> tuple[float, float]:
    """(H [N], δ [m]): the thrust and the crown deflection of the two-hinged semicircle under
    a crown load P, by Castigliano with H the redundant.

    With φ from the crown (the right half, φ ∈ [0, π/2], support at φ = π/2), the section
    forces from the right support's reactions (P/2 up, H inwards):
    M = (P/2) R (1 − sin φ) − H R cos φ, N = −H cos φ − (P/2) sin φ,
    Q = −H sin φ + (P/2) cos φ. ∂U*/∂H = 0 over both halves, with ∫cos² = ∫sin² = π/4,
    ∫(1 − sin) cos = ∫ sin cos = 1/2 on [0, π/2]:

        H = (P/π) (R²/EI − 1/EA + 1/κGA) / (R²/EI + 1/EA + 1/κGA),

    P/π = 0.31831 P without the axial and shear terms (Timoshenko & Gere's two-hinged
    semicircle). δ = ∂U*/∂P at that H, with ∫(1 − sin)² = 3π/4 − 2:

        δ = 2R [ (R²/EI) (P (3π/4 − 2)/4 − H/4) + (H/4 + π P/16)/EA + (π P/16 − H/4)/κGA ],

    0.018928 P R³/EI in the bending-only limit."""
    c = R_ARCH**2 / EI_ARCH
    a, g = 1.0 / EA_ARCH, 1.0 / GA_ARCH
    H = P / math.pi * (c - a + g) / (c + a + g)
    pi = math.pi
    d = 2 * R_ARCH * (c * (P * (3 * pi / 4 - 2) / 4 - H / 4) + a * (H / 4 + pi * P / 16))
    return H, d + 2 * R_ARCH * g * (pi * P / 16 - H / 4)


def test_two_hinged_arch_thrust_and_crown_deflection():
    """The two-hinged semicircular arch (:func:`arch_scene`) against :func:`arch_closed_form`
    (H = 3.1768e-7 N, δ = 2.0279e-8 m for P = 1e-6 N). Cubic elements, 16 and 32: the crown
    deflection errs by 7.0e-5 and 1.2e-6 of itself (measured; 5.8e-8 with 64, each halving
    60x smaller), so 5e-6 at 32 elements and the 16-element error at least 10x larger
    (converged under refinement). H is the e1 component of the contact force, −H anywhere
    (no horizontal load): at the Gauss points of every cell it errs by at most 1.7e-4 of H
    with 32 elements (2.5e-3 with 16), its mean by 8e-6: bounds 5e-4 and 3e-5. The bending-only
    forms miss by 2.0e-3 (H) and 6.6e-2 (δ), so the axial and shear compliance are seen."""
    H, delta = arch_closed_form(P_ARCH)
    crown = {}
    for elements in (16, 32):
        result = api.static(arch_scene(elements))
        model = result.model
        crown[elements] = displacement(model, math.pi * R_ARCH / 2)
        np.testing.assert_allclose(crown[elements][2], result.probes[-1][3], rtol=1e-12)
    error = {e: abs(-crown[e][2] - delta) / delta for e in crown}
    assert error[32] < 5e-6 and error[16] > 10 * error[32], error
    assert abs(crown[32][0]) < 1e-6 * delta  # symmetric: the crown moves straight down
    force = -horizontal_force(model)  # the 32-element model
    assert np.abs(force - H).max() < 5e-4 * H
    assert abs(force.mean() - H) < 3e-5 * H
    bending_only = P_ARCH / math.pi
    assert abs(bending_only - H) > 50 * 3e-5 * H


def timoshenko_frame(
    nodes: np.ndarray,
    members: list[tuple[int, int]],
    EA: float,
    EI: float,
    GA: float,
    held: dict[int, tuple[int, ...]],
    loads: dict[int, tuple[float, float, float]],
) -> np.ndarray:
    """Linear plane frame by the stiffness method: ``nodes`` (n, 2) in the plane (x, z),
    dofs (u_x, u_z, rotation) a node; each member an exact Timoshenko element (exact for
    loads at the nodes): axial EA/ℓ [[1, −1], [−1, 1]], bending with Φ = 12 EI/(κGA ℓ²),

        EI/((1 + Φ) ℓ³) [[12, 6ℓ, −12, 6ℓ], [6ℓ, (4 + Φ) ℓ², −6ℓ, (2 − Φ) ℓ²],
                         [−12, −6ℓ, 12, −6ℓ], [6ℓ, (2 − Φ) ℓ², −6ℓ, (4 + Φ) ℓ²]]

    in (v1, θ1, v2, θ2) (Przemieniecki, Theory of Matrix Structural Analysis, 1968, eq. 5.116),
    turned into the plane; ``held``: node → its held dofs; ``loads``: node → (F_x, F_z, M).
    Returns the displacements (n, 3)."""
    n = len(nodes)
    K = np.zeros((3 * n, 3 * n))
    for i, j in members:
        d = nodes[j] - nodes[i]
        ell = float(np.hypot(*d))
        c, s = d / ell
        phi = 12 * EI / (GA * ell**2)
        b = EI / ((1 + phi) * ell**3)
        k = np.zeros((6, 6))  # local (u1, v1, θ1, u2, v2, θ2)
        k[np.ix_([0, 3], [0, 3])] = EA / ell * np.array([[1, -1], [-1, 1]])
        bend = b * np.array(
            [
                [12, 6 * ell, -12, 6 * ell],
                [6 * ell, (4 + phi) * ell**2, -6 * ell, (2 - phi) * ell**2],
                [-12, -6 * ell, 12, -6 * ell],
                [6 * ell, (2 - phi) * ell**2, -6 * ell, (4 + phi) * ell**2],
            ]
        )
        k[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])] = bend
        T1 = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
        T = np.kron(np.eye(2), T1)
        dofs = [3 * i, 3 * i + 1, 3 * i + 2, 3 * j, 3 * j + 1, 3 * j + 2]
        K[np.ix_(dofs, dofs)] += T.T @ k @ T
    F = np.zeros(3 * n)
    for node, load in loads.items():
        F[3 * node : 3 * node + 3] = load
    fixed = [3 * node + d for node, ds in held.items() for d in ds]
    free = np.setdiff1d(np.arange(3 * n), fixed)
    u = np.zeros(3 * n)
    u[free] = np.linalg.solve(K[np.ix_(free, free)], F[free])
    return u.reshape(n, 3)


def lee_linear(P: float, EA: float, EI: float, GA: float, L: float = 120.0) -> np.ndarray:
    """Lee's frame in the x-z plane, linear (:func:`timoshenko_frame`): the column from the
    hinge at the origin up e3 to the corner (0, L), the beam along e1 to the hinge at (L, L),
    a force −P e3 at 24 = L/5 from the corner. The (u_x, u_z) of the corner and of the load
    point, (2, 2)."""
    nodes = np.array([[0.0, 0.0], [0.0, L], [L / 5, L], [L, L]])
    members = [(0, 1), (1, 2), (2, 3)]
    u = timoshenko_frame(nodes, members, EA, EI, GA, {0: (0, 1), 3: (0, 1)}, {2: (0, -P, 0)})
    return u[1:3, :2]


def lee_model_displacements(scene) -> np.ndarray:
    """The static solution's (x, z) displacement at the corner (s = 120) and under the load
    (s = 144)."""
    model = api.static(scene).model
    return np.array([displacement(model, s)[[0, 2]] for s in (120.0, 144.0)])


def test_lee_frame_small_load_matches_the_linear_frame():
    """scenes/lee_frame.toml under P = 1e-6 (its published limit load is 1.8e7 times that):
    the displacements (x, z) of the corner and of the load point against :func:`lee_linear`
    with the scene's EA = 4320, EI = 1440, κGA = (5/6) G A. The column is in compression and
    shortens (the corner's z, 4e-3 of the largest displacement, is EA's alone), and the corner
    sways by the beam's shortening H L/EA. The members are straight, so cubic Lagrange
    elements hold the linear Timoshenko solution exactly (20 and 40 elements agree to 1e-15);
    what is left is the geometric nonlinearity, second order in P: the beam's deflection w
    shortens it by ∫ w'²/2, comparable to H L/EA at P = 1e-3. Measured against the linear
    solution, relative to each component, at P = 1e-3, 1e-4, 1e-5, 1e-6: the sway 0.85,
    8.5e-2, 8.5e-3, 8.5e-4 (∝ P), the others at most 0.57, ..., 5.7e-4; relative to the
    largest displacement (6.1e-6 m at P = 1e-6) 2.8e-7. Bounds at P = 1e-6: 2e-3 of each
    component, 1e-6 of the largest. The same frame clamped at both ends deflects a third less
    under the load (measured 0.67 of it)."""
    P = 1e-6
    scene = api.load(LEE, [f"parameters.P={P}", "static.load_steps=1"])
    material, sec = scene.rod.material, scene.rod.section
    EA, EI = material.young_modulus * sec.area, material.young_modulus * sec.c22
    GA = sec.shear_coefficient * material.shear_modulus * sec.area
    expected = lee_linear(P, EA, EI, GA)
    got = lee_model_displacements(scene)
    scale = np.abs(expected).max()
    assert abs(expected[0, 1]) > 1e-3 * scale  # the column's shortening P_col/EA · L is there
    np.testing.assert_allclose(got, expected, rtol=2e-3, atol=0)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6 * scale)
    clamped = api.load(LEE, [f"parameters.P={P}", "supports.start=clamped", "supports.end=clamped"])
    assert np.abs(lee_model_displacements(clamped) - expected).max() > 0.1 * scale


# A right-angle frame for the spherical end: legs a = 1 (along e3 from the clamp) and b = 0.8
# (along e1), EI = E c11 = 1 (the out-of-plane bending of both legs), GJ = 0.7, κGA = 200,
# EA = 1e3; a force P e2 out of the plane at the corner.
A_LEG, B_LEG, EI_OUT, GJ, GA_FRAME = 1.0, 0.8, 1.0, 0.7, 200.0
P_OUT = 1e-6


def out_of_plane_corner(P: float) -> float:
    """The corner's y displacement [m] of the frame above, clamped at the start and held by a
    ball joint (spherical) at the end, by Castigliano with the end's reaction R e2 the
    redundant (out of the plane only: in-plane there is no load). The frame as a cantilever:
    a unit force e2 at the end moves the end by

        f_RR = (a³ + b³)/(3 EI) + (a + b)/κGA + b² a/GJ

    (both legs bent about their d0_1, both sheared, the first twisted by the moment b about
    e3 its lever gives), a unit force at the corner moves corner and end alike by
    f_RP = a³/(3 EI) + a/κGA (the corner's rotation about e1 does not move the end, which lies
    along e1 from it). The ball joint takes no torque, so R = −P f_RP/f_RR and the corner moves
    by P f_RP (1 − f_RP/f_RR)."""
    f_rp = A_LEG**3 / (3 * EI_OUT) + A_LEG / GA_FRAME
    f_rr = (A_LEG**3 + B_LEG**3) / (3 * EI_OUT) + (A_LEG + B_LEG) / GA_FRAME
    f_rr += B_LEG**2 * A_LEG / GJ
    return P * f_rp * (1 - f_rp / f_rr)


def right_angle_frame(end: str, elements: int, extra: tuple[str, ...] = ()):
    """The frame of :func:`out_of_plane_corner` (a polyline, corner at s = a), its end
    ``end``; in-plane bending stiffness E c22 = 3 (not used by the load)."""
    return scene_from_dict(
        {
            "title": "right-angle frame, out-of-plane corner load",
            "rod": {"length": A_LEG + B_LEG, **section(1e3, GA_FRAME, (EI_OUT, 3.0), GJ)},
            "reference": {
                "shape": "polyline",
                "points": [[0, 0, 0], [0, 0, A_LEG], [B_LEG, 0, A_LEG]],
            },
            "supports": {"start": "clamped", "end": end},
            "loads": {"point": {"s": A_LEG, "force": [0, P_OUT, 0]}},
            "discretisation": {"elements": elements, "degree": 3},
            "time": {"end": 1.0, "step": 0.1},  # static only: unused
        },
        overrides=list(extra),
    )


def test_spherical_end_of_a_kinked_frame_out_of_plane():
    """The right-angle frame clamped at the start, a ball joint (spherical) at the end, a
    force P e2 out of its plane at the corner: the corner's y displacement against
    :func:`out_of_plane_corner`, 1.6e-7 m for P = 1e-6 N. Its legs are straight: cubic
    elements hold the linear solution (cubic bending displacements, linear twist) exactly, with
    9 elements (the corner node at s = 1: 5 on the first leg, 4 on the second); the response
    is odd in P (the frame's mirror image in its plane), so the nonlinearity enters at
    (δ/ℓ)² ≈ 3e-14 of it: measured 1.5e-13, bound 1e-8 (the solver's tolerance). A hinge
    about e2 at the end instead (the default pinned end: the turns about e1 and e3 held)
    moves the corner by 0.32 of that: the end's three free angles are seen. The end's
    position stays where it was."""
    expected = out_of_plane_corner(P_OUT)
    model = api.static(right_angle_frame("spherical", 9)).model
    corner = displacement(model, A_LEG)
    assert abs(corner[1] - expected) < 1e-8 * expected, (corner, expected)
    assert np.abs(displacement(model, A_LEG + B_LEG)).max() < 1e-12 * expected
    hinged = api.static(right_angle_frame("pinned", 9)).model
    assert displacement(hinged, A_LEG)[1] < 0.5 * expected


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (
            ["supports.start_axis=[0,0,0]"],
            "supports.start_axis: a hinge axis must not be zero, got [0, 0, 0]",
        ),
        (
            ["supports.end_axis=[1,1,0]"],
            "supports.end_axis: a hinge axis must lie along e1, e2 or e3",
        ),
        (
            ["supports.end=clamped", "supports.end_axis=[0,1,0]"],
            'supports.end_axis: only a pinned end has a hinge axis, but supports.end = "clamped"',
        ),
        (["supports.start_axis=[0,'a',0]"], "supports.start_axis[1]: must be a finite number"),
        (
            ["reference.shape=helix", "reference.pitch_angle=0.3", "supports.start=pinned"],
            "supports.start_axis: required for a pinned end of this reference.shape = 'helix'",
        ),
        (["supports.end=roller"], "supports.end: 'roller' is not supported with reference"),
        (
            ["loads.end.torque=[1,0,0]", "supports.end=pinned"],
            "loads.end.torque[0]: a pinned end holds its angle θ (about e1)",
        ),
    ],
)
def test_bad_supports_are_one_line_naming_the_key(overrides, message, capsys):
    """Bad hinge axes and supports the curved rod still refuses (on Lee's frame; the helix on
    the 45° bend, an arc): SceneError naming the key, and from the command line one line,
    exit 2 (no traceback)."""
    source = BEND if "reference.shape=helix" in overrides else LEE
    with pytest.raises(SceneError) as info:
        api.load(source, overrides)
    assert str(info.value).startswith(message), str(info.value)
    sets = [x for o in overrides for x in ("--set", o)]
    status = main(["validate", str(source), *sets])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and message in err[0], err


def test_lee_frame_scene_loads_with_its_hinges():
    """scenes/lee_frame.toml: hinges about e2 at both ends (the default, the polyline's
    binormal), holding θ and φ (the turns about e1 and e3); not a mechanism; the load at 24
    from the corner."""
    scene = api.load(LEE)
    assert scene.supports.held("start") == ((0, 1, 2), (0, 2))
    assert scene.supports.held("end") == ((0, 1, 2), (0, 2))
    assert scene.supports.rigid_body_modes() == 0
    assert scene.loads.point is not None and scene.loads.point.s == 144.0


def test_a_hinged_frame_with_a_free_end_has_one_rigid_body_mode():
    """Lee's frame hinged at its start (about e2) and free at its end swings about the hinge:
    one rigid-body mode (λ = 0), and the next is flexible (λ > 0, not reported as rigid).
    The count comes from the supports' one table (Supports.rigid_body_modes, from what the
    hinge holds); before, modal.py's own table counted a "pinned" end as a fork (two
    rotations free) and reported the first flexible mode as a second rigid one, ω = 0.
    max_modes: six a node less the five dofs the hinge holds (x, y, z, θ, φ)."""
    scene = api.load(LEE, {"supports.end": "free", "loads.point": api.UNSET})
    assert scene.supports.rigid_body_modes() == 1
    modes = api.modes(scene, 3)
    assert modes[0].omega == 0.0 and "rigid-body" in modes[0].note
    assert modes[1].omega > 0.0 and modes[1].note == "" and modes[1].eigenvalue.real > 0
    from cosserat_fem.analysis.modal import max_modes

    nodes = scene.discretisation.elements * scene.discretisation.degree + 1
    assert max_modes(scene) == 6 * nodes - 5
