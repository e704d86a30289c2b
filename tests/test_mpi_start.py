"""A process that no launcher started starts Open MPI without its daemon and network
transports (cosserat_fem/common/mpi_start.py), and hands none of those settings to the processes it
starts; under mpirun nothing is changed."""

from __future__ import annotations

import json

import pytest
from conftest import run_command

PROBE = """
import json, os
import cosserat_fem
from mpi4py import MPI
pid = os.getpid()
children = open(f"/proc/{pid}/task/{pid}/children").read().split()
report = {
    "quick": cosserat_fem.QUICK_MPI_START,
    "size": MPI.COMM_WORLD.size,
    "children": len(children),
    "left": {k: v for k, v in os.environ.items() if k.startswith("OMPI_MCA_p") or
             k.startswith("OMPI_MCA_btl") or k.startswith("OMPI_MCA_ess")},
}
reports = MPI.COMM_WORLD.gather(report)
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(reports))
"""


def probe(ranks: int = 1, env: dict | None = None) -> list[dict]:
    proc = run_command(["-c", PROBE], ranks, env=env)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_a_singleton_starts_without_a_daemon():
    """Open MPI 4.1 forks orted for a singleton unless told it is isolated: with the quick
    start the process has no child, and the settings are gone from its environment again."""
    [report] = probe()
    assert report == {"quick": True, "size": 1, "children": 0, "left": {}}


def test_a_setting_of_the_user_is_kept():
    [report] = probe(env={"OMPI_MCA_pml": "ob1"})
    assert report["quick"] and report["left"] == {"OMPI_MCA_pml": "ob1"}


@pytest.mark.mpi
def test_mpirun_keeps_its_own_settings():
    reports = probe(2)
    assert [r["quick"] for r in reports] == [False, False]
    assert [r["size"] for r in reports] == [2, 2]
