"""Unit tests of cosserat_fem/common/errors.py: every error is one line, SolverError's message
is composed as documented (``[where] at t = ... s: reason (suggestion: ...)``), the classes
give the command line's exit statuses by their hierarchy (2 SceneError, 3 SolverError, 4
StopError), ``show_value`` writes a value as TOML would, ``out_folder`` refuses what is not a
folder naming the option.

Exact comparisons of strings: the messages are built from the inputs by string operations
only (``.6g`` of a float is correctly rounded, so the same on every machine).
"""

from __future__ import annotations

import datetime
import math

import pytest

from cosserat_fem.common.errors import (
    CosseratError,
    LimitReached,
    OutputError,
    SceneError,
    SolverError,
    StopError,
    out_folder,
    show_value,
)

pytestmark = pytest.mark.unit


@pytest.mark.parametrize("cls", [CosseratError, SceneError, StopError, OutputError, LimitReached])
def test_a_message_is_one_line(cls):
    error = cls("rod.length:\n  must be\tpositive,\r\n got -1 ")
    assert str(error) == error.message == "rod.length: must be positive, got -1"
    assert error.args == (error.message,)


def test_the_hierarchy_gives_the_exit_statuses():
    """cli.py maps the exit status by class: a StopError's subclasses exit 4 like it."""
    for cls in (SceneError, SolverError, StopError):
        assert issubclass(cls, CosseratError)
    for cls in (OutputError, LimitReached):
        assert issubclass(cls, StopError)
    assert not issubclass(SceneError, StopError) and not issubclass(SolverError, StopError)


def test_solver_error_composes_its_line():
    error = SolverError(
        "Newton did not converge\nin 25 iterations",
        time=1 / 3,
        where="newton",
        suggestion="reduce\n time.step",
        retry=True,
    )
    assert str(error) == (
        "newton at t = 0.333333 s: Newton did not converge in 25 iterations "
        "(suggestion: reduce time.step)"
    )
    assert (error.time, error.where, error.retry) == (1 / 3, "newton", True)
    assert error.reason == "Newton did not converge in 25 iterations"
    assert error.suggestion == "reduce time.step"


@pytest.mark.parametrize(
    ("kwargs", "line"),
    [
        ({}, "singular Jacobian"),
        ({"time": 0.0}, "at t = 0 s: singular Jacobian"),  # t = 0 is a time, not "unknown"
        ({"where": "linear solver"}, "linear solver: singular Jacobian"),
        ({"suggestion": ""}, "singular Jacobian"),
        ({"time": 2.5e-7}, "at t = 2.5e-07 s: singular Jacobian"),
    ],
)
def test_solver_error_leaves_out_what_is_unknown(kwargs, line):
    error = SolverError("singular Jacobian", **kwargs)
    assert str(error) == line
    assert error.retry is False


@pytest.mark.parametrize(
    ("value", "shown"),
    [
        (True, "true"),
        (False, "false"),
        ('say "hi" \\ there', '"say \\"hi\\" \\\\ there"'),
        (0.1, "0.1"),
        (7, "7"),
        (math.nan, "nan"),
        (-math.inf, "-inf"),
        ([1, 2.5, "x", [True]], '[1, 2.5, "x", [true]]'),
        ({"a": 1, "b": "c"}, '{a = 1, b = "c"}'),
        (datetime.date(2026, 12, 3), "2026-12-03"),
        (datetime.time(4, 5, 6), "04:05:06"),
        ("two\nlines", '"two lines"'),  # one line, whatever the value holds
        (None, "None"),
    ],
)
def test_show_value_writes_toml(value, shown):
    assert show_value(value) == shown


def test_show_value_shortens_to_120_characters():
    """117 characters of the rendering and "...": the rendering of 200 x's is a quote and
    116 x's, then the dots."""
    text = show_value("x" * 200)
    assert text == '"' + "x" * 116 + "..."
    assert len(text) == 120
    assert show_value("x" * 118) == '"' + "x" * 118 + '"'  # 120 characters: kept whole


def test_out_folder(tmp_path):
    assert out_folder(None) is None
    assert out_folder(str(tmp_path / "new")) == tmp_path / "new"  # need not exist yet
    assert out_folder(tmp_path) == tmp_path
    with pytest.raises(SceneError) as raised:
        out_folder("")
    assert str(raised.value) == "out (--out): must name a folder, got ''"
    (tmp_path / "file").write_text("")
    with pytest.raises(SceneError) as raised:
        out_folder(tmp_path / "file", option="out")
    assert str(raised.value) == f"out: {str(tmp_path / 'file')!r} is not a folder"
    with pytest.raises(SceneError, match=r"^out \(--out\): must name a folder, got 3$"):
        out_folder(3)
