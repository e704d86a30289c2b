"""Ranks that agree: an error found on one MPI rank is raised on every rank, never left to
hang the others in their next collective call.

* :func:`agree` is the rule inside the code: after a step that may fail on some ranks only
  (reading a rank's checkpoint file, writing probes.csv on the probe's owner), every rank
  passes what it found and all raise the first problem, of the same type.
* :func:`agree_or_abort` is the command line's last line of defence for an error that was not
  agreed on: a rank that leaves with an error waits a few seconds for the others to leave
  too; if they do not (they are blocked in a collective call), it aborts the MPI job instead
  of hanging it.
"""

from __future__ import annotations

import sys
import time

from mpi4py import MPI

from .errors import CosseratError

#: Seconds a failing rank waits for the others before it aborts the job.
ABORT_AFTER = 10.0


def agree(comm: MPI.Comm, problem: CosseratError | None) -> None:
    """Raise on every rank the first rank's ``problem`` (collective; in serial, just raise
    it). The problem's class must take its message as its one argument."""
    if comm.size == 1:
        if problem is not None:
            raise problem
        return
    found = [p for p in comm.allgather(problem and (type(problem), str(problem))) if p]
    if found:
        kind, message = found[0]
        raise kind(message)


def from_root(comm: MPI.Comm, value):
    """Rank 0's ``value`` on every rank (a decision every rank must take alike)."""
    return value if comm.size == 1 else comm.bcast(value, root=0)


def ranks_on_node(comm: MPI.Comm) -> int:
    """How many ranks of ``comm`` share this rank's node (and its memory); collective."""
    if comm.size == 1:
        return 1
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        return node.size
    finally:
        node.Free()


_AGREEMENT: MPI.Comm | None = None


def prepare_agreement(comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Make the private communicator :func:`agree_or_abort` uses (collective; at start-up)."""
    global _AGREEMENT
    if comm.size > 1 and _AGREEMENT is None:
        _AGREEMENT = comm.Dup()


def agree_or_abort(code: int, timeout: float = ABORT_AFTER) -> None:
    """On the way out with an error: wait until every rank is on its way out too (a
    non-blocking barrier on a private communicator), else abort the job with ``code`` after
    ``timeout`` seconds. Returns at once in serial."""
    comm = _AGREEMENT
    if comm is None:
        return
    request = comm.Ibarrier()
    deadline = time.monotonic() + timeout
    while not request.Test():
        if time.monotonic() > deadline:
            print(
                f"cosserat-fem: rank {comm.rank} stopped with an error the other ranks did not "
                "meet; aborting the MPI job",
                file=sys.stderr,
                flush=True,
            )
            MPI.COMM_WORLD.Abort(code)
        time.sleep(0.01)
