"""The follower end force and torque ([loads.follower], forms/follower.py): loads that turn with
the end's directors, checked against closed forms in statics (``solve_static``, Newton to
solver.rtol = 1e-10 of the residual).

**Roll-up.** A follower torque M about d2 at the free end of a straight cantilever: in the x-z
plane d2 = e2 throughout, so it is the fixed torque of scenes/rollup.toml, and the rod bends
into a circle of radius R = E c22 / M with no contact force (n = 0: no stretch, no shear), tip
at x = R (1 − cos(ℓ/R)), z = R sin(ℓ/R), ψ = ℓ/R. The only error is the discretisation's: the
angle ψ = M s/(E c22) is linear and exact in P2, the position its integral of (sin ψ, cos ψ),
the Lagrange interpolation of a smooth function, whose error falls as h^(degree+1) or faster.

**Beam-column.** A cantilever under a compressive force F along its axis and a small fixed
transverse force P at the tip. Linear theory (w(s) the deflection along e1, EI = E c22,
k² = F/EI): equilibrium of the part beyond s gives EI w'' + F w = F w_L + Q (ℓ − s), with Q the
tip's transverse force, w(0) = w'(0) = 0. A fixed force along −e3 has Q = P:

    w_L = (P/F) (tan(kℓ)/k − ℓ),                        (Timoshenko & Gere, beam-column)

which diverges at the Euler load kℓ = π/2. A follower force along −d3 turns with the tip's
tangent, so Q = P − F w'(ℓ); solving the same equation with this Q gives Q = P cos(kℓ) and

    w_L = (P/F) (sin(kℓ)/k − ℓ cos(kℓ)),

finite beyond the Euler load (the tangential follower force does not buckle the rod statically;
it loses stability by flutter only, Beck's load kℓ = 4.49). Both tend to P ℓ³/(3 EI) as F → 0.
The rod is slender (a = 4 mm, ℓ = 1 m) and P small (w_L ~ 1e-4 ℓ), so the neglected effects
are: the rod's shear and axial strain, relative E a²/(12 κ G ℓ²) ~ 4e-6 and F/(E A) ~ 5e-6;
the nonlinearity, relative (w_L/ℓ)² ~ 1e-8; the discretisation (P3, 10 elements, a solution
of wavenumber k ≤ 2/ℓ). Measured: 1.3e-5, 1.5e-5 and 0.9e-5 relative (follower and fixed at
kℓ = 1, follower at kℓ = 2), the size of the first two. The tolerance, 1e-4 relative, is 7x
above that and 10^4 below the difference between the follower and the fixed cases (a factor
1.85 at kℓ = 1).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosserat_fem.analysis.statics import solve_static
from cosserat_fem.common.errors import SceneError
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.scene.build import load_scene
from cosserat_fem.scene.schema import UNSET

ROLLUP = Path(__file__).resolve().parents[1] / "scenes" / "rollup.toml"


def tip(overrides: dict, fields: tuple[str, ...] = ()) -> tuple[np.ndarray, float]:
    """(x, y, z, θ, ψ, φ, then the probe ``fields``) at s = ℓ [m, rad] of the static solution,
    and E c22 [N m²]."""
    scene = load_scene(ROLLUP, {"loads.end": UNSET, **overrides})
    rod = scene.rod_constants()
    model, _ = solve_static(scene)
    return PointProbe(model, 1.0, fields=fields).values(), rod.young_modulus * rod.section.c22


@pytest.mark.parametrize(("elements", "tolerance"), [(8, 5e-7), (16, 3e-9)])
def test_follower_torque_rolls_a_cantilever_into_a_circle(elements, tolerance):
    """Half a turn (ℓ/R = π): tip at x = 2R, z = ℓ + (R sin π − ℓ) = 0, ψ = π, in P4. The
    discrete positions cannot be the circle exactly, so the discrete contact force is not
    zero and ψ carries its error too (measured, of ℓ and rad: x 8.4e-8 and 3.4e-10, ψ 2.0e-7
    and 8.2e-10 at 8 and 16 elements, the fixed torque's to the last digit). Each tolerance is
    6-9x its measured error; the 16-element one is 170x below the 8-element error, so a
    convergence slower than h^4.8 between the two meshes fails (P4: h^5 or faster expected).
    The planar x-z model solves no out-of-plane unknowns, so none are asserted."""
    ell = 1.0
    u, _ = tip(
        {
            "parameters.turns": 0.5,
            "loads.follower.torque": [0, "turns*2*pi*EI/L", 0],
            "discretisation.elements": elements,
            "discretisation.degree": 4,
            "static.load_steps": 8,
        }
    )
    R = ell / math.pi
    assert abs(u[4] - math.pi) < 2.5 * tolerance
    assert abs(u[0] - R * (1 - math.cos(ell / R))) < tolerance * ell
    assert abs(u[2] - (R * math.sin(ell / R) - ell)) < tolerance * ell


SLENDER = {
    "rod.section.a": 0.004,
    "rod.section.b": 0.006,
    "discretisation.elements": 10,
    "discretisation.degree": 3,
    "static.load_steps": 4,
}


def beam_column(k_ell: float, follower: bool) -> tuple[float, float]:
    """(w_L computed, w_L closed form) [m] at F = (kℓ)² EI/ℓ², P = 1e-4 F."""
    scene = load_scene(ROLLUP, {"loads.end": UNSET, **SLENDER})
    rod = scene.rod_constants()
    EI, ell = rod.young_modulus * rod.section.c22, rod.length
    F = k_ell**2 * EI / ell**2
    P, k = 1e-4 * F, k_ell / ell
    if follower:
        loads = {"loads.end.force": [P, 0, 0], "loads.follower.force": [0, 0, -F]}
        exact = P / F * (math.sin(k_ell) / k - ell * math.cos(k_ell))
    else:
        loads = {"loads.end.force": [P, 0, -F]}
        exact = P / F * (math.tan(k_ell) / k - ell)
    u, _ = tip({**SLENDER, **loads})
    return u[0], exact


@pytest.mark.parametrize("follower", [True, False], ids=["follower", "fixed"])
def test_follower_and_fixed_compression_below_euler(follower):
    """kℓ = 1: each case its closed form (module docstring); they differ by a factor 1.85."""
    got, exact = beam_column(1.0, follower)
    assert got == pytest.approx(exact, rel=1e-4)


def test_follower_compression_beyond_euler_stays_near_straight():
    """kℓ = 2, beyond the Euler load (π/2) where a fixed force has no stable state near the
    straight one: the follower case is the finite closed form 0.8708 P ℓ / F."""
    got, exact = beam_column(2.0, True)
    assert exact > 0
    assert got == pytest.approx(exact, rel=1e-4)


def test_follower_load_scene_checks():
    """Only a free end carries it (the message names the key); its plane is found as for a
    fixed load; the scene's dict holds it and reads back the same."""
    with pytest.raises(SceneError, match=r"^loads\.follower\.end: a follower load needs a free"):
        load_scene(ROLLUP, {"loads.follower.end": "start", "loads.follower.force": [1, 0, 0]})
    scene = load_scene(ROLLUP, {"loads.end": UNSET, "loads.follower.torque": [0, 2, 0]})
    assert scene.plane() == "x-z"
    assert (
        load_scene(ROLLUP, {"loads.end": UNSET, "loads.follower.torque": [2, 0, 0]}).plane()
        == "y-z"
    )
    assert (
        load_scene(ROLLUP, {"loads.end": UNSET, "loads.follower.torque": [0, 0, 2]}).plane() is None
    )
    from cosserat_fem.scene.build import scene_from_dict

    assert scene_from_dict(scene.to_dict()) == scene
    assert ("loads.follower.torque[1]", scene.loads.follower.torque[1]) in scene.load_components()


def test_a_follower_force_turns_with_a_rest_frame_that_is_not_the_identity():
    """A rod curved at rest has the directors D0 D (forms/follower.py): the straight rod of
    rollup.toml written as a curve r0 = (0, 0, s) with d0_1 = e2 (so d0_2 = −e1) is the same
    rod turned by 90° about its axis. A square section makes the turn invisible to the
    stiffness, so a follower force P along its d1 is the straight rod's follower force along
    d2 = e2: the same tip position, to the solver's tolerance (Newton to 1e-10 of the
    residual; 1e-8 of the deflection). Taking D's rows for the directors, as if D0 = I, puts
    the force along e1 instead: a tip moved along x, not y."""
    square = {
        "loads.end": UNSET,
        "rod.section.a": 0.005,
        "rod.section.b": 0.005,
        "discretisation.elements": 6,
        "static.load_steps": 2,
    }
    P = 0.05
    straight, _ = tip({**square, "loads.follower.force": [0, P, 0]})
    turned, _ = tip(
        {
            **square,
            "loads.follower.force": [P, 0, 0],
            "reference.shape": "curve",
            "reference.position": [0, 0, "s"],
            "reference.director": [0, 1, 0],
        }
    )
    assert straight[1] > 1e-3  # the tip moved along e2, a large deflection
    np.testing.assert_allclose(turned[:3], straight[:3], rtol=0, atol=1e-8 * straight[1])


@pytest.mark.long
def test_a_follower_force_and_torque_in_3d_are_the_fixed_loads_of_the_end_they_reach():
    """In the long set (4 s, two 3D form compilations; make test is at its 3 minutes).
    In 3D, with all three components of each: the follower loads' equilibrium is the one the
    fixed loads Dᵀ F and Dᵀ M (forms/follower.py) give, with D the directors that the tip
    reaches (from its angles, (18): charts.euler_matrix). The second solve starts from the
    straight rod, so equal tips say both solves found one equilibrium: to the Newton
    tolerance (1e-10 of the residual; 1e-7 of the tip's displacement allows the error of D
    taken from the first solve's angles). A torque that does not turn (M in place of Dᵀ M in
    forms/follower.py) fails it, while the other tests of this file pass (checked,
    2026-12-03)."""
    from cosserat_fem.rod.charts import euler_matrix

    common = {
        "loads.end": UNSET,
        "discretisation.planar": "off",
        "discretisation.elements": 4,
        "static.load_steps": 3,
    }
    F, M = np.array([0.4, -0.3, -0.2]), np.array([0.3, 0.5, -0.4])
    follower, EI = tip(
        {
            **common,
            "loads.follower.force": [f"{f!r}*EI/L**2" for f in F],
            "loads.follower.torque": [f"{m!r}*EI/L" for m in M],
        }
    )
    ell = 1.0
    D = euler_matrix(*follower[3:6])
    force, torque = D.T @ (F * EI / ell**2), D.T @ (M * EI / ell)
    fixed, _ = tip(
        {**common, "loads.end.force": force.tolist(), "loads.end.torque": torque.tolist()}
    )
    scale = np.abs(follower[:3]).max()
    assert scale > 0.1 * ell  # a large deflection
    np.testing.assert_allclose(fixed[:3], follower[:3], rtol=0, atol=1e-7 * scale)


@pytest.mark.long
def test_a_follower_torque_on_a_rod_curved_at_rest_is_the_fixed_torque_of_its_tip():
    """In the long set (1.3 s with its forms compiled, 9 s with two 3D forms of a curved rod
    to compile; make test is at its 3 minutes). A rod
    curved at rest, a quarter circle (reference.shape = "arc", R = 2ℓ/π: the tip's rest
    tangent d0_3 = e1, D0(ℓ) far from I), under a follower end torque with components M =
    (0.1, 0.2, 0.3) E c22/ℓ along the tip's directors d_k, the rows of D0 D (forms/follower.py:
    l^b = Dᵀ (D0ᵀ M)). Its equilibrium is the one the fixed torque l^b = Σ M_k d_k gives, with
    the directors d_k of the tip it reaches (the probe's, output.probe_fields = directors:
    D0 D at σ = ℓ): the two are the same discrete load at the discrete solution, since both
    read D at the end from the tip node's values, so the discretisation's error cancels and
    what is left is the Newton tolerance (1e-10 of the residual; measured 2e-16 of the tip's
    displacement; allowed 1e-7 of it, as the straight rod's 3D test). Dropping D0ᵀ (the
    components taken along D's rows, as if D0 = I) moves the tip by 1.4 times its
    displacement: checked, 2026-12-04, by removing it from forms/follower.py."""
    common = {
        "loads.end": UNSET,
        "reference.shape": "arc",
        "reference.radius": 2 / math.pi,
        "discretisation.elements": 4,
        "static.load_steps": 2,
    }
    M = np.array([0.1, 0.2, 0.3])
    follower, EI = tip(
        {**common, "loads.follower.torque": [f"{m!r}*EI/L" for m in M]}, fields=("directors",)
    )
    D = follower[6:15].reshape(3, 3)  # rows d1, d2, d3 at the tip, fixed basis
    fixed, _ = tip({**common, "loads.end.torque": (D.T @ (M * EI)).tolist()})
    scale = np.abs(follower[:3]).max()
    assert scale > 0.05  # a large deflection [m]: the tip turns far from its rest frame
    np.testing.assert_allclose(fixed[:3], follower[:3], rtol=0, atol=1e-7 * scale)
