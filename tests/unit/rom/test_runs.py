"""Unit checks of cosserat_fem/rom/runs.py without a rod: the members an option chooses, the
indicator read from a reduced run's summary (absent: None, printed "n/a"), and the table."""

from __future__ import annotations

import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.rom.runs import Validation, indicator_of, parse_members, validation_lines

pytestmark = pytest.mark.unit


@pytest.mark.parametrize(
    ("text", "chosen"),
    [
        (None, list(range(30))),
        ("0,10,20", [0, 10, 20]),
        ("::10", [0, 10, 20]),
        ("5:12:3", [5, 8, 11]),
        ("29, 0, 29", [29, 0]),  # in the order given, once each
        ([3, 4], [3, 4]),
    ],
)
def test_members_chosen(text, chosen):
    assert parse_members(text, 30) == chosen


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("0,30", "--members: member 30 out of range (the sweep has members 0 to 29)"),
        ("-1", "--members: member -1 out of range"),
        ("a,b", "--members: member numbers '0,10,20' or a range"),
        ("::0", "--members: member numbers"),
        ("40:50", "--members: chooses no member"),
        ([True], "--members: member True out of range"),
    ],
)
def test_members_refused_in_one_line(text, fragment):
    with pytest.raises(SceneError) as refused:
        parse_members(text, 30)
    assert fragment in str(refused.value) and "\n" not in str(refused.value)


def test_random_members_are_distinct_sorted_and_repeatable():
    """random:N: N distinct members in range, sorted, the same at every call (seed 0), and
    every member when N is the count; N outside [1, count] refused."""
    drawn = parse_members("random:20", 200)
    assert len(set(drawn)) == 20 and drawn == sorted(drawn) and 0 <= drawn[0] <= drawn[-1] < 200
    assert parse_members("random:20", 200) == drawn
    assert parse_members("random:5", 5) == [0, 1, 2, 3, 4]
    for text in ("random:0", "random:6", "random:x"):
        with pytest.raises(SceneError, match="--members: random:N draws N of the sweep's 5"):
            parse_members(text, 5)


def test_indicator_read_where_present():
    """The contract of the reduced run's summary: rom.indicator.max (a float) and
    rom.outside_training (a list); anything else is "not reported" (None)."""
    summary = {"rom": {"indicator": {"max": 2.5e-3}, "outside_training": ["load amplitude"]}}
    assert indicator_of(summary) == (2.5e-3, ["load amplitude"])
    assert indicator_of({"rom": {"model": "reduced"}}) == (None, None)
    assert indicator_of({"rom": {"indicator": {"max": "big"}, "outside_training": "x"}}) == (
        None,
        None,
    )
    assert indicator_of({}) == (None, None)


def test_table_prints_n_a_without_an_indicator():
    rows = [
        {"target": "m00000", "modes": 10, "energy_left_out": 5.7e-9, "error": 2.107e-4,
         "indicator": None, "outside_training": None},
        {"target": "scene", "modes": 4, "energy_left_out": 1.4e-5, "error": 2.6e-2,
         "indicator": 0.031, "outside_training": []},
    ]  # fmt: skip
    lines = validation_lines(Validation(rows, None))
    assert len(lines) == 3 and lines[0].split()[:2] == ["target", "modes"]
    assert lines[1].split() == ["m00000", "10", "5.700e-09", "2.107e-04", "n/a", "n/a"]
    assert lines[2].split() == ["scene", "4", "1.400e-05", "2.600e-02", "3.100e-02", "none"]
