"""Unit tests of cosserat_fem/analysis/path_restart.py: a branch's end saved and loaded again
exactly, the record refused on other ranks. The restart itself (a continuation cut in two
equals the whole): tests/test_continuation.py::test_restart_equals_the_whole_branch."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from cosserat_fem.analysis.path_restart import (
    branch_end,
    load_branch,
    read_index,
    save_branch_state,
    write_index,
)
from cosserat_fem.common.errors import SceneError
from cosserat_fem.nls.arclength import Branch, ContinuationSettings, Point


def _point(p: float, seed: int) -> Point:
    rng = np.random.default_rng(seed)
    return Point(rng.random(5), p, rng.random(5), 0.1 * p, -1.0, 1.0 / 3.0, 4, "regular")


def test_branch_end_round_trip(tmp_path):
    """The last three points of a 5-point branch come back bit for bit (u, t_u in npz; λ,
    dλ/ds, ln|det| through JSON's repr), with first_index 2 = the points before them, the
    step, the rejected steps and the direction."""
    comm = MPI.COMM_SELF
    points = [_point(0.1 * k + 1.0 / 7.0, k) for k in range(5)]
    branch = Branch(points=points, direction=-1, steps_rejected=3, step=0.123456789)
    save_branch_state(tmp_path, 2, branch, comm)
    write_index(tmp_path, {"a": 1}, ContinuationSettings(), {2: branch_end(branch)}, comm)
    record = read_index(tmp_path, comm)
    loaded = load_branch(tmp_path, record, 2, comm)
    assert loaded.first_index == 2 and loaded.direction == -1
    assert loaded.step == branch.step and loaded.steps_rejected == 3
    for a, b in zip(points[2:], loaded.points, strict=True):
        assert np.array_equal(a.u, b.u) and np.array_equal(a.t_u, b.t_u)
        assert (a.p, a.t_p, a.det_sign, a.log_det, a.iterations) == (
            b.p,
            b.t_p,
            b.det_sign,
            b.log_det,
            b.iterations,
        )
    assert ContinuationSettings(**record["settings"]) == ContinuationSettings()
    with pytest.raises(SceneError, match="^--branch"):
        load_branch(tmp_path, record, 0, comm)


def test_other_ranks_refused(tmp_path):
    """A record written by 2 ranks is refused on 1, naming --restart (states are per rank)."""
    comm = MPI.COMM_SELF
    write_index(tmp_path, {}, ContinuationSettings(), {}, comm)
    path = tmp_path / "continuation" / "restart.json"
    path.write_text(path.read_text().replace('"ranks": 1', '"ranks": 2'))
    with pytest.raises(SceneError, match="^--restart: .* ran on 2 ranks"):
        read_index(tmp_path, comm)
