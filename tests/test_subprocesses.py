"""The suite's own subprocess helpers (tests/conftest.py): MPI settings for a busy machine, and
a hang limit that ends every rank.

On a machine busy with other work (load 6-9 on two cores) the MPI tests took ten times their
quiet time: Open MPI binds each of two ranks to a core of its own and a waiting rank spins on
its core, so a rank could neither move off a busy core nor leave its core to the partner it
waits for. And a test past its limit raised subprocess's TimeoutExpired, which says nothing
of a hang, after killing mpirun alone (its ranks, in process groups of their own, ran on for
seconds until Open MPI's run-time noticed).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pytest
from conftest import run_command, running

pytestmark = pytest.mark.mpi

RANK_REPORT = """
import json, os, sys
from mpi4py import MPI
rank = MPI.COMM_WORLD.rank
with open(os.path.join(sys.argv[1], f"{rank}.json"), "w") as out:
    json.dump([rank, sorted(os.sched_getaffinity(0)),
               os.environ.get("OMPI_MCA_mpi_yield_when_idle")], out)
"""

HANGS = """
import os, sys, time
from mpi4py import MPI
comm = MPI.COMM_WORLD
open(os.path.join(sys.argv[1], f"{comm.rank}.pid"), "w").write(str(os.getpid()))
if comm.rank == 0:
    time.sleep(3600)  # rank 1 waits for it in a collective: a hang
comm.Barrier()
"""


def test_mpirun_ranks_are_not_bound_to_a_core_and_yield_when_they_wait(tmp_path: Path):
    """Under the tests' mpirun each rank may run on every CPU this process may use, and has
    Open MPI's yield-when-idle set (each rank writes a file: two ranks' lines on mpirun's
    stdout can come joined)."""
    proc = run_command(["-c", RANK_REPORT, str(tmp_path)], ranks=2)
    assert proc.returncode == 0, proc.stderr
    reports = [json.loads((tmp_path / f"{rank}.json").read_text()) for rank in (0, 1)]
    cpus = sorted(os.sched_getaffinity(0))
    assert reports == [[0, cpus, "1"], [1, cpus, "1"]]


def test_a_hung_mpi_job_fails_its_test_and_leaves_no_rank_running(tmp_path: Path):
    """An MPI job past its limit fails the test with "hung" in the message, and no rank is
    left running (each rank's pid checked in /proc, 10 s of grace: conftest.stop_tree sends
    every process of the job SIGTERM, then SIGKILL)."""
    script = tmp_path / "hangs.py"
    script.write_text(HANGS)
    with pytest.raises(pytest.fail.Exception, match="hung: .* had not ended after 3 s"):
        run_command([str(script), str(tmp_path)], ranks=2, timeout=3)
    pids = [int((tmp_path / f"{rank}.pid").read_text()) for rank in (0, 1)]
    deadline = time.monotonic() + 10
    while any(running(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(running(pid) for pid in pids), pids
