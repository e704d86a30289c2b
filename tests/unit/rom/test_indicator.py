"""Unit checks of cosserat_fem/rom/indicator.py's algebra without a rod: the oscillator step
(10.6) against closed forms, the relative estimate (10.7) against its definition, the training
range of the reduced coordinates and the test of a
state outside it, and the settings' refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.rom.indicator import (
    ErrorIndicator,
    IndicatorSettings,
    coordinate_ranges,
    oscillator_step,
    outside_loads,
    outside_range,
    relative_estimate,
)

pytestmark = pytest.mark.unit


def test_oscillator_step_is_exact_for_linear_forcing():
    """(10.6) against closed forms of η̈ + λ η = a + b s. From rest under a constant a:
    η = a/λ (1 − cos ω s), η̇ = a/ω sin ω s; a free oscillation from η = 1: cos ω s,
    −ω sin ω s; a ramp b s from rest: η = b/λ (s − sin(ω s)/ω), η̇ = b/λ (1 − cos ω s). To
    1e-13 (round-off of the terms' size 1/λ); and 100 steps of s/100 with the forcing carried
    over give the one step to 1e-12 (the step is exact, so it composes)."""
    lam = np.array([0.5, 4.0, 900.0])
    w, s = np.sqrt(lam), 0.7
    zero, ones = np.zeros(3), np.ones(3)
    eta, rate = oscillator_step(zero, zero, lam, s, 2.0 * ones, zero)
    assert eta == pytest.approx(2.0 / lam * (1 - np.cos(w * s)), abs=1e-13)
    assert rate == pytest.approx(2.0 / w * np.sin(w * s), abs=1e-13)
    eta, rate = oscillator_step(ones, zero, lam, s, zero, zero)
    assert eta == pytest.approx(np.cos(w * s), abs=1e-13)
    assert rate == pytest.approx(-w * np.sin(w * s), abs=1e-12)
    eta, rate = oscillator_step(zero, zero, lam, s, zero, 3.0 * ones)
    assert eta == pytest.approx(3.0 / lam * (s - np.sin(w * s) / w), abs=1e-13)
    assert rate == pytest.approx(3.0 / lam * (1 - np.cos(w * s)), abs=1e-13)
    one = oscillator_step(ones, -ones, lam, s, 0.5 * ones, 3.0 * ones)
    eta, rate = ones, -ones
    for i in range(100):
        eta, rate = oscillator_step(
            eta, rate, lam, s / 100, (0.5 + 3.0 * i * s / 100) * ones, 3.0 * ones
        )
    assert eta == pytest.approx(one[0], abs=1e-12) and rate == pytest.approx(one[1], abs=1e-11)


def test_relative_estimate_is_the_ratio_of_the_l2_sums():
    """E = C (Σ |e_j|²)^{1/2} / (Σ |u_j|²)^{1/2} (10.7): |e| = (3, 4) and |u| = (6, 8) give
    C · 5/10 (a 3-4-5 triangle each); a state still at its reference gives 0, not a division
    by zero."""
    assert relative_estimate(3.0**2 + 4.0**2, 6.0**2 + 8.0**2, 1.2) == pytest.approx(0.6)
    assert relative_estimate(1.0, 0.0, 1.2) == 0.0


def test_coordinate_ranges_and_the_state_outside_them():
    """Two modes (coordinates a1, a2 of p, b1, b2 of its rate) over three snapshots: the range is
    each row's min and max, the largest norm the largest given. With margin 0.25 of the largest
    p-amplitude (2.0: slack 0.5) a1 = 2.4 is inside, 2.6 outside; a2 (amplitude 0.1) may go to
    0.6, since the slack is the largest mode's, not its own (a small mode's relative scatter is
    not a larger amplitude); the rate coordinates have their own slack (0.25 · 4 = 1). A basis
    truncated to one mode compares only a1 and b1 (its 2 of the provenance's 4 rows)."""
    coordinates = np.array(
        [
            [-2.0, 0.0, 2.0],  # a1
            [-0.1, 0.05, 0.1],  # a2
            [-4.0, 1.0, 4.0],  # b1
            [0.0, 0.2, 0.3],  # b2
        ]
    )
    ranges = coordinate_ranges(coordinates, np.array([1.0, 3.0, 2.0]))
    assert ranges["min"] == [-2.0, -0.1, -4.0, 0.0]
    assert ranges["max"] == [2.0, 0.1, 4.0, 0.3]
    assert ranges["largest_norm"] == 3.0
    assert outside_range(np.array([2.4, 0.59, 4.9, -0.9]), ranges, 2, 0.25) == []
    assert outside_range(np.array([2.6, 0.0, 0.0, 0.0]), ranges, 2, 0.25) == [0]
    assert outside_range(np.array([0.0, 0.61, 0.0, 1.31]), ranges, 2, 0.25) == [1, 3]
    assert outside_range(np.array([0.0, -5.1]), ranges, 1, 0.25) == [1]  # b1 of one mode


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("every", 0),
        ("every", 2.5),
        ("every", True),
        ("tolerance", 0.0),
        ("margin", -1.0),
        ("modes", 0),
        ("modes", 1.5),
    ],
)
def test_settings_refuse_bad_values_in_one_line(key, value):
    """A bad setting is a SceneError of one line naming it."""
    with pytest.raises(SceneError) as refused:
        IndicatorSettings(**{key: value})
    assert f"indicator.{key}" in str(refused.value) and "\n" not in str(refused.value)


def test_settings_refuse_infinity():
    with pytest.raises(SceneError, match="indicator.tolerance"):
        IndicatorSettings(tolerance=math.inf)


def test_the_largest_estimate_leaves_out_the_first_samples():
    """E's maximum (``rom.indicator.max``, the tolerance's test) leaves out the first quarter
    of the samples and always the first of several: a run of 3 samples whose first is the
    ratio of two near-zero norms (1.0) reports the largest of the others (before: 1.0, and a
    warning for every member of a short sweep); one sample is kept."""
    indicator = ErrorIndicator()
    indicator.values = [1.0, 1.4e-3, 4.1e-4]
    assert indicator.largest == 1.4e-3
    indicator.values = [1.0, 2e-3, 3e-3, 1e-3, 5e-4, 4e-4, 3e-4, 2e-4]
    assert indicator.largest == 3e-3  # the first two (a quarter) left out
    indicator.values = [7e-3]
    assert indicator.largest == 7e-3
    indicator.values = []
    assert indicator.largest == 0.0


def test_the_loads_outside_the_trained_ranges():
    """outside_loads against its rule: values trained on [1e3, 2e3] admit [750, 2250]
    (a quarter of the width 1e3 beyond each end, margin 0.25), one trained value admits
    itself only, another form (an expression the training had not) is outside, and a
    parameter the training had not is named."""
    form = '["#*sin(#*omega0*t)"]'
    trained = [{"form": form, "values": {"parameters.a": a, "n#2": 8.0}} for a in (1e3, 2e3)]

    def why(a, n=8.0, shape=form, extra=None):
        values = {"parameters.a": a, "n#2": n, **(extra or {})}
        return outside_loads({"form": shape, "values": values}, trained, 0.25)

    assert why(1e3) is None and why(1.5e3) is None and why(2249.0) is None
    assert why(751.0) is None
    assert "parameters.a = 2251 outside the trained range [1000, 2000]" in why(2251.0)
    assert "parameters.a = 749" in why(749.0)
    assert "n#2 = 8.001 outside the trained range [8, 8]" in why(1.5e3, n=8.001)
    assert "another expression" in why(1.5e3, shape='["#*cos(#*omega0*t)"]')
    assert "parameters.b = 1 was not a parameter" in why(1.5e3, extra={"parameters.b": 1.0})
