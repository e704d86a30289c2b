"""Unit tests of cosserat_fem/analysis/branch_outputs.py: branches.json's rows, the file written
whole by rank 0, the observer's progress calls. The XDMF of a branch and the files of a
continuation cut short: tests/test_continuation.py."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from cosserat_fem.analysis.branch_outputs import (
    BranchOutputs,
    replace_on_root,
    write_branch_reasons,
)
from cosserat_fem.common.errors import OutputError
from cosserat_fem.nls.arclength import Branch, Point


def _result():
    limit = SimpleNamespace(kind="limit", factor=0.75, note="approximate (bracket 0.1 wide)")
    bifurcation = SimpleNamespace(kind="bifurcation", factor=0.5, note="")
    b0 = SimpleNamespace(
        origin="primary",
        reason="p reached 1",
        points=[0] * 5,
        steps=4,
        rejected=1,
        special=[bifurcation, limit],
    )
    b1 = SimpleNamespace(
        origin="switched at load factor 0.5",
        reason="step below min_step",
        points=[0] * 2,
        steps=1,
        rejected=7,
        special=[],
    )
    return SimpleNamespace(branches=[b0, b1])


def test_reasons_file(tmp_path):
    """One entry per branch in order, with its origin, reason and counts; "xdmf" the branch's
    file, or null when the scene writes none; "approximate" the special points with a note
    (a locating that failed), the others not."""
    write_branch_reasons(tmp_path / "branches.json", _result())
    rows = json.loads((tmp_path / "branches.json").read_text())
    assert rows[0]["approximate"] == ["limit at load factor 0.75: approximate (bracket 0.1 wide)"]
    assert rows[1]["approximate"] == []
    assert [r["branch"] for r in rows] == [0, 1]
    assert rows[1]["reason"] == "step below min_step" and rows[1]["rejected"] == 7
    assert rows[0]["points"] == 5 and rows[0]["xdmf"] == "branch_0.xdmf"
    write_branch_reasons(tmp_path / "branches.json", _result(), xdmf=False)
    assert json.loads((tmp_path / "branches.json").read_text())[0]["xdmf"] is None


def test_replace_on_root_names_the_path(tmp_path):
    """A file that cannot be written: an OutputError naming it (not an OSError)."""
    with pytest.raises(OutputError, match="nowhere"):
        replace_on_root(tmp_path / "nowhere" / "x.csv", b"a\n")


def test_observer_counts_points():
    """progress(branches finished, points on the branch, λ): the first point is the branch's
    start (1), each accepted point adds one; a branch's end (no folder: nothing written)
    resets the count and adds a branch."""
    calls = []
    observer = BranchOutputs(None, lambda *a: calls.append(a))
    u = np.zeros(2)
    point = Point(u, 0.25, u, 1.0, 1.0, 0.0, 2, "regular")
    observer.point(point)
    observer.point(point)
    observer.branch(None, Branch(points=[point]))
    observer.point(point)
    assert calls == [(0, 2, 0.25), (0, 3, 0.25), (1, 2, 0.25)]
