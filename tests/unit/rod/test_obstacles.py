"""cosserat_fem/rod/obstacles.py: the obstacles' signed distances and their derivatives.

Each distance against its closed form at chosen points (a plane's is linear, a sphere's and
a cylinder's the distance to the centre or the axis minus the radius), and ∇d, ∇²d against
central differences of d and ∇d (error O(ε²): 1e-8 relative at ε = 1e-5 m on a 1 m scale,
bound 1e-7). A surface of several obstacles takes, at each point, the nearest one.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.rod.obstacles import Obstacle, Surface

pytestmark = pytest.mark.unit

PLANE = Obstacle("plane", np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.6, 0.8]))
SPHERE = Obstacle("sphere", np.array([1.0, 2.0, 3.0]), None, 0.5)
CYLINDER = Obstacle("cylinder", np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), 0.3)


def test_distances_are_the_closed_forms():
    """Points at known distances: 0.64 and 1 above the plane (n·(x − a)), 1.5 outside the sphere
    (|x − c| − R = 2 − 0.5), on the cylinder's surface at any height (|e| = R), inside it."""
    x = np.array([[0.0, 0.0, -0.2], [5.0, 7.0, -1.0 - 5.0 * 0.75]])
    assert np.allclose(PLANE.distance(x)[0], [0.64, 0.6 * 7 - 0.8 * 3.75], atol=1e-15)
    assert PLANE.distance(np.array([[0.0, 0.6, -0.2]]))[0][0] == pytest.approx(1.0, abs=1e-15)
    assert SPHERE.distance(np.array([[1.0, 4.0, 3.0]]))[0][0] == pytest.approx(1.5, abs=1e-15)
    on = np.array([[1.3, 0.0, -4.0], [1.0, 0.3, 7.0], [1.1, 0.0, 0.0]])
    assert np.allclose(CYLINDER.distance(on)[0], [0.0, 0.0, -0.2], atol=1e-15)


@pytest.mark.parametrize("obstacle", [PLANE, SPHERE, CYLINDER], ids=["plane", "sphere", "cylinder"])
def test_gradient_and_hessian_are_the_derivatives(obstacle):
    """∇d and ∇²d against central differences at random points (module docstring); ∇d is
    a unit vector."""
    rng = np.random.default_rng(3)
    x = rng.normal(size=(6, 3)) * 2
    d, grad, hessian = obstacle.distance(x)
    assert np.allclose(np.linalg.norm(grad, axis=1), 1.0, atol=1e-14)
    eps = 1e-5
    for k in range(3):
        step = np.zeros(3)
        step[k] = eps
        dp, gp, _ = obstacle.distance(x + step)
        dm, gm, _ = obstacle.distance(x - step)
        assert np.abs((dp - dm) / (2 * eps) - grad[:, k]).max() < 1e-7
        assert np.abs((gp - gm) / (2 * eps) - hessian[:, :, k]).max() < 1e-7


def test_a_surface_takes_the_nearest_obstacle_less_the_radius():
    """Two planes facing each other (a channel |x| ≤ 1): each point's gap is its distance to
    the nearer wall minus the tube's radius 0.1, its normal that wall's."""
    walls = Surface(
        [
            Obstacle("plane", np.array([-1.0, 0, 0]), np.array([1.0, 0, 0])),
            Obstacle("plane", np.array([1.0, 0, 0]), np.array([-1.0, 0, 0])),
        ],
        0.1,
    )
    g, n, _ = walls(np.array([[-0.5, 0, 0], [0.7, 3, 0]]))
    assert np.allclose(g, [0.4, 0.2], atol=1e-15)
    assert np.array_equal(n[:, 0], [1.0, -1.0])


def test_a_point_at_a_centre_or_on_an_axis_has_a_normal():
    """At a sphere's centre or on a cylinder's axis ∇d is undefined; the distance is then −R
    (the deepest point) with a unit normal across the axis and no curvature, never an error
    (an MPI rank that raised there would leave the others waiting in a collective)."""
    for obstacle, at in ((SPHERE, SPHERE.point), (CYLINDER, CYLINDER.point + [0, 0, 3.0])):
        d, grad, hessian = obstacle.distance(np.array([at]))
        assert d[0] == -obstacle.radius
        assert np.linalg.norm(grad[0]) == pytest.approx(1.0, abs=1e-15)
        if obstacle is CYLINDER:
            assert abs(grad[0] @ CYLINDER.direction) < 1e-15
        assert not hessian.any()


def _surface(distance: str) -> Obstacle:
    """A "surface" obstacle of the signed ``distance`` (an expression of x, y, z)."""
    from cosserat_fem.scene.expressions import Expression
    from cosserat_fem.scene.resolved import Obstacle as Spec

    spec = Spec(kind="surface", distance=Expression.parse(distance, {"x", "y", "z"}, "d"))
    return Obstacle.of(spec)


def test_a_surface_given_by_its_distance_equals_the_closed_forms():
    """The sphere and the cylinder above written as distances of x, y, z give their d, ∇d and
    ∇²d (the expressions' symbolic derivatives) to round-off at random points; the inside of
    a tube, 0.3 − |e|, is the cylinder's with the signs turned, and on its axis (∇d not
    finite) a unit normal and no curvature, no error."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(6, 3)) * 2
    sphere = _surface("sqrt((x - 1)**2 + (y - 2)**2 + (z - 3)**2) - 0.5")
    cylinder = _surface("sqrt((x - 1)**2 + y**2) - 0.3")
    tube = _surface("0.3 - sqrt((x - 1)**2 + y**2)")
    for given, exact, sign in ((sphere, SPHERE, 1), (cylinder, CYLINDER, 1), (tube, CYLINDER, -1)):
        for a, b in zip(given.distance(x), exact.distance(x), strict=True):
            assert np.allclose(a, sign * b, rtol=0, atol=1e-13)
    d, n, hessian = tube.distance(np.array([[1.0, 0.0, 4.0]]))
    assert d[0] == pytest.approx(0.3) and np.linalg.norm(n[0]) == pytest.approx(1.0)
    assert np.all(hessian == 0.0)
    assert np.allclose(tube.gradient_size(x), 1.0, rtol=0, atol=1e-14)
    assert np.allclose(_surface("x**2").gradient_size(np.array([[2.0, 0, 0]])), 4.0)
