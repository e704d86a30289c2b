"""Unit tests of cosserat_fem/analysis/periodic.py: the classification of multipliers, the
refusals before any solve, and the period expression. The shooting itself and the monodromy
matrix: tests/test_periodic.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosserat_fem import api
from cosserat_fem.analysis.periodic import Shooting, classify
from cosserat_fem.common.errors import SceneError

CLAMPED = {
    "supports.end": "clamped",
    "loads.force_density": ["F*sin(pi*s/L)*sin(r*w1*t)", 0, 0],
    "parameters.F": 1.0,
    "parameters.w1": 1302.92,
    "parameters.r": 1.07,
    "output.xdmf": False,
    "output.checkpoint": False,
    "discretisation.elements": 2,
}


def _scene(**more):
    from conftest import ROOT

    return api.load(ROOT / "scenes" / "cao_tucker_2008.toml", {**CLAMPED, **more})


@pytest.mark.parametrize(
    ("multipliers", "kind"),
    [
        ([0.9, -0.5, 0.3 + 0.4j, 0.3 - 0.4j], "stable"),
        ([1.2, 0.9, 0.1], "fold"),  # a real multiplier beyond +1: the middle branch
        ([-1.1, 0.9], "period-doubling"),
        ([0.8 + 0.7j, 0.8 - 0.7j, 0.5], "torus"),  # |μ| = 1.063, a complex pair
        ([], "stable"),
    ],
)
def test_classify_names_how_stability_is_lost(multipliers, kind):
    """The largest |μ| decides: inside the unit circle stable, else by where it left it
    (+1 fold, −1 period doubling, a complex pair a torus)."""
    assert classify(np.array(multipliers, dtype=complex)) == kind


def test_a_multiplier_on_the_circle_is_not_yet_unstable():
    """|μ| = 1 − 1e-12 is within UNIT_CIRCLE (1e-9) of the circle: not called stable, because
    round-off cannot tell it from a crossing; 1 − 1e-6 is stable."""
    assert classify(np.array([1.0 - 1e-12])) == "fold"
    assert classify(np.array([1.0 - 1e-6])) == "stable"


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"time.integrator": "bdf2"}, "time.integrator"),
        ({"time.integrator": "generalized-alpha"}, "time.integrator"),
        ({"time.adaptive": True}, "time.adaptive"),
    ],
)
def test_a_multistep_or_adaptive_scene_is_refused_naming_the_key(overrides, key):
    """The period map's state is U alone only for a one-step method with fixed steps: the
    others are refused before anything is built, naming the key."""
    with pytest.raises(SceneError, match=key):
        Shooting(_scene(**overrides), "2*pi/(r*w1)")


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"steps_per_period": 0}, "steps_per_period"),
        ({"steps_per_period": 2.5}, "steps_per_period"),
        ({"settle": -1}, "settle"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"tolerance": 0.0}, "tolerance"),
    ],
)
def test_periodic_orbit_refuses_bad_arguments_naming_them(kwargs, name):
    with pytest.raises(SceneError, match=name):
        api.periodic_orbit(_scene(), "2*pi/(r*w1)", **kwargs)


def test_the_period_expression_and_a_guess_of_the_wrong_size():
    """The period expression in the scene's constants, 2π/(r w1) [s], and again at another
    value of the parameter r; a guess of the wrong size is refused naming ``guess``."""
    shooting = Shooting(_scene(), "2*pi/(r*w1)", steps_per_period=4, parameter="r")
    try:
        assert shooting.period == pytest.approx(2 * math.pi / (1.07 * 1302.92), rel=1e-15)
        shooting.set_parameter(1.1)
        assert shooting.period == pytest.approx(2 * math.pi / (1.1 * 1302.92), rel=1e-15)
        assert shooting.model.parameter_value("r") == 1.1
        with pytest.raises(SceneError, match="guess"):
            shooting.check_state(np.zeros(shooting.n_local + 1))
        with pytest.raises(SceneError, match="period"):
            Shooting(_scene(), "-1.0")
    finally:
        shooting.destroy()


def test_a_monodromy_too_large_for_memory_is_refused_naming_the_key():
    """600 cubic elements, planar: n = 6 × 1801 = 10806 dofs, whose dense columns (X, two
    stage rates, PETSc's two dense matrices, a copy: 6 n² doubles) need 5.2 GiB > 2 GiB."""
    with pytest.raises(SceneError, match=r"discretisation.elements: .* 5\.2 GiB"):
        Shooting(_scene(**{"discretisation.elements": 600}), "2*pi/(r*w1)")


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"end": 1.0}, "end"),
        ({"step": 0.02, "max_step": 0.01}, "step"),
        ({"step": -0.01}, "step"),
        ({"max_step": float("nan")}, "max_step"),
        ({"scale": 0.0}, "scale"),
        ({"settle": -1}, "settle"),
        ({"max_points": 1}, "max_points"),
        ({"start": "one"}, "start"),
    ],
)
def test_periodic_branch_refuses_bad_arguments_naming_them(kwargs, name):
    """Refused before anything is built, one line naming the argument."""
    arguments = {"start": 1.0, "end": 1.1, **kwargs}
    with pytest.raises(SceneError, match=f"^{name}: "):
        api.periodic_branch(_scene(), "2*pi/(r*w1)", "r", **arguments)


def test_the_determinant_is_the_product_of_the_multipliers_less_one():
    """Shooting.determinant from the LU of M − I: sign × exp(ln|det|) = Π(μ − 1) over the free
    dofs × (−1)^(held dofs) (M − I is −I there), on a 2-element rod at rest over 4 steps;
    the same matrix, so to round-off (1e-10 relative on ~50 factors)."""
    shooting = Shooting(_scene(), "2*pi/(r*w1)", steps_per_period=4, parameter="r")
    try:
        shooting.linearise(shooting.rest(), 1.07)
        sign, log_det = shooting.determinant()
        assert shooting.linearised is not None
        mu = shooting.multipliers(shooting.linearised)
        product = np.prod(mu - 1.0) * (-1.0) ** (shooting.n - mu.size)
    finally:
        shooting.destroy()
    assert abs(product.imag) <= 1e-10 * abs(product)
    assert sign * math.exp(log_det) == pytest.approx(product.real, rel=1e-10)
