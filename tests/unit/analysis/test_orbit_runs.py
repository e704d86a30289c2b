"""Unit tests of cosserat_fem/analysis/orbit_runs.py: the period from a number or an
expression of the scene's constants, its refusals, and the orbit branch's status line. The
commands' files, restarts and the Lyapunov run: tests/test_orbit_cli.py."""

from __future__ import annotations

import io
import math

import pytest

from cosserat_fem import api
from cosserat_fem.analysis.orbit_runs import OrbitProgress, period_value
from cosserat_fem.common.errors import SceneError

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def scene():
    from conftest import ROOT

    return api.load(
        ROOT / "scenes" / "cao_tucker_2008.toml",
        {"parameters.r": 1.25, "parameters.w1": 1302.92, "output.xdmf": False},
    )


def test_the_period_is_a_number_or_an_expression_of_the_constants(scene):
    """2π/(r w1) with r = 1.25, w1 = 1302.92 rad/s: 3.857904...e-3 s (to round-off); a
    number is taken as it is."""
    assert period_value(scene, "2*pi/(r*w1)") == pytest.approx(
        2 * math.pi / (1.25 * 1302.92), rel=1e-15
    )
    assert period_value(scene, 0.01) == 0.01


@pytest.mark.parametrize(
    "text, message",
    [
        ("-1", r"^--period: '-1' = -1.0 s; must be a positive time"),
        ("1/(r - r)", r"^--period: "),
        ("2*pi/nope", r"^--period"),
        (True, r"^--period: must be a time"),
        (math.inf, r"^--period: inf = inf s"),
    ],
)
def test_a_bad_period_is_one_line_naming_the_flag(scene, text, message):
    with pytest.raises(SceneError, match=message):
        period_value(scene, text)


def test_the_status_line_shows_the_orbit_and_its_share_of_max_points():
    """Enabled on a stream: the bar at points / max_points (3 of 12: 25.0 %), the orbit's
    count, parameter and amplitude."""
    stream = io.StringIO()
    bar = OrbitProgress(12, stream=stream, enabled=True)
    bar(3, 1.0625, 0.0123)
    text = stream.getvalue()
    assert " 25.0%" in text and "orbit 3, parameter 1.0625, amplitude 0.0123 m" in text
    silent = io.StringIO()
    OrbitProgress(12, stream=silent, enabled=False)(3, 1.0, 0.1)
    assert silent.getvalue() == ""


def test_a_load_that_does_not_repeat_after_the_period_is_refused(scene):
    """The paper's load sin(8 ω0 t) repeats after T = 2π/(8 ω0) and 3T, not after 1.01 T
    (its value then differs by ~2π × 0.01 of its size, far above the 1e-9 allowed); a
    trend t sin(8 ω0 t) never repeats. A scene without a load of t passes any period."""
    from cosserat_fem.analysis.orbit_runs import check_periodic

    period = 2 * math.pi / (8 * scene.omega0)
    check_periodic(scene, period)
    check_periodic(scene, 3 * period)
    with pytest.raises(SceneError, match=r"^loads\.force_density: .* not periodic with --period"):
        check_periodic(scene, 1.01 * period)
    from conftest import ROOT

    trend = api.load(
        ROOT / "scenes" / "cao_tucker_2008.toml",
        {"loads.force_density": ["t*sin(8*omega0*t)", 0, 0]},
    )
    with pytest.raises(SceneError, match="not periodic"):
        check_periodic(trend, period)
    still = api.load(ROOT / "scenes" / "cao_tucker_2008.toml", {"loads.force_density": [1, 0, 0]})
    check_periodic(still, 0.123)
