"""Ranks that agree: an error found on one MPI rank is raised on every rank, never left to
hang the others in their next collective call.

* :func:`agree` is the rule inside the code: after a step that may fail on some ranks only
  (reading a rank's checkpoint file, writing probes.csv on the probe's owner), every rank
  passes what it found and all raise the first problem, of the same type.
* :func:`agree_or_abort` is the command line's last line of defence for an error that was not
  agreed on: a rank that leaves with an error waits a few seconds for the others to leave
  too; if they do not (they are blocked in a collective call), it aborts the MPI job instead
  of hanging it.
* :func:`interrupt` and :func:`check_interrupt` stop every rank at one point for an
  interrupt (SIGINT) that may reach one rank and not the others: the signal is remembered,
  and a run's ranks find out together at their next step, where they stop alike (exit
  status 130). An interrupt that no run checks (a compile, a factorisation, a rank waiting
  for another) aborts the job after a few seconds (:func:`abort_later`), unless every rank
  left by then (:func:`cancel_abort`).
* :func:`install_exit_watchdog` is the Python API's counterpart of :func:`agree_or_abort`: a
  script under mpirun whose rank leaves with an uncaught exception ends the job within
  :data:`ABORT_AFTER` s instead of hanging it.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from typing import TypeVar

from mpi4py import MPI

T = TypeVar("T")

#: Seconds a failing rank waits for the others before it aborts the job.
ABORT_AFTER = 10.0


def agree(comm: MPI.Comm, problem: Exception | None) -> None:
    """Raise on every rank the first rank's ``problem`` (collective; in serial, just raise
    it). The problem's class must take its message as its one argument."""
    agree_and_gather(comm, problem, None)


def agree_and_gather(comm: MPI.Comm, problem: Exception | None, value: T) -> list[T]:
    """:func:`agree` on ``problem``, then every rank's ``value`` in the order of the ranks, in
    one collective (one ``allgather``)."""
    if comm.size == 1:
        if problem is not None:
            raise problem
        return [value]
    gathered = comm.allgather((problem and (type(problem), str(problem)), value))
    found = [p for p, _ in gathered if p]
    if found:
        kind, message = found[0]
        raise kind(message)
    return [v for _, v in gathered]


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


_WATCHDOG: threading.Timer | None = None
#: Whether this process was interrupted (SIGINT) under mpirun (:func:`interrupt`).
_INTERRUPTED = False


def interrupt() -> bool:
    """A SIGINT handler's part under mpirun: remember the interrupt, for every rank to stop
    at the same point of its run (:func:`check_interrupt`), and abort the job if it has not
    ended within :data:`ABORT_AFTER` s (work that does not check, a rank that waits for
    another: :func:`abort_later`). False (nothing done) outside an MPI job of several
    ranks, where the handler raises KeyboardInterrupt at once."""
    global _INTERRUPTED
    if not MPI.Is_initialized() or MPI.Is_finalized() or MPI.COMM_WORLD.size == 1:
        return False
    _INTERRUPTED = True
    abort_later(130)
    return True


def check_interrupt(comm: MPI.Comm, every: int = 1) -> int:
    """KeyboardInterrupt on every rank of ``comm`` if any was interrupted (:func:`interrupt`);
    else rank 0's ``every`` (when to look next, the same on every rank). Collective: one
    allreduce, so the ranks of a run stop at the same step."""
    if comm.size == 1:
        if _INTERRUPTED:
            raise KeyboardInterrupt
        return every
    # max of (interrupted, every): an interrupt anywhere wins, else rank 0's every (others 0)
    interrupted, every = comm.allreduce((_INTERRUPTED, every if comm.rank == 0 else 0), op=MPI.MAX)
    if interrupted:
        raise KeyboardInterrupt
    return every


def abort_later(code: int, timeout: float = ABORT_AFTER) -> None:
    """Abort the MPI job with ``code`` in ``timeout`` seconds, from a thread of its own (so
    that it also fires while this rank is blocked in a collective call), unless
    :func:`cancel_abort` comes first; once per process, nothing in serial or before MPI is
    initialised. Safe in a signal handler."""
    global _WATCHDOG
    if _WATCHDOG is not None or not MPI.Is_initialized() or MPI.Is_finalized():
        return
    if MPI.COMM_WORLD.size == 1:
        return

    def abort() -> None:
        print(
            f"cosserat-fem: rank {MPI.COMM_WORLD.rank} was interrupted and the ranks did not "
            f"all stop within {timeout:g} s; aborting the MPI job",
            file=sys.stderr,
            flush=True,
        )
        MPI.COMM_WORLD.Abort(code)

    _WATCHDOG = threading.Timer(timeout, abort)
    _WATCHDOG.daemon = True
    _WATCHDOG.start()


def cancel_abort() -> None:
    """The abort :func:`abort_later` scheduled, cancelled (every rank has stopped)."""
    global _WATCHDOG
    if _WATCHDOG is not None:
        _WATCHDOG.cancel()
        _WATCHDOG = None


#: Whether :func:`install_exit_watchdog` hooked this process.
_HOOKED = False


def install_exit_watchdog(timeout: float = ABORT_AFTER) -> bool:
    """Under mpirun (more than one rank, main thread): make an uncaught exception end the job
    within ``timeout`` s even when the other ranks are blocked in a collective call; True if
    installed (once per process).

    A rank that leaves a script with an exception calls MPI_Finalize at exit, which (Open MPI
    4.1) waits for every rank: the others, blocked in their next collective call, never come,
    and the job hangs. Nothing of Python runs by then (its threads are gone, faulthandler's
    watchdog is cancelled), so the excepthook, after printing the traceback, arms the one
    timer that outlives the interpreter: ``alarm(timeout)`` with SIGALRM's default action,
    which kills the process. If every rank leaves in time (all met the same error) the
    process exits first and the alarm never fires; else mpirun sees the rank killed by
    signal 14 and ends the job. The command line has its own, :func:`agree_or_abort`.

    Not covered: ``sys.exit`` (SystemExit) on one rank alone, which reaches no excepthook
    and whose status an exit hook cannot read (arming the alarm at every exit would kill a
    rank that legitimately waits in MPI_Finalize for a slower one); run such a script as
    ``mpirun -n N python -m mpi4py script.py``, whose runner aborts the job on a non-zero
    SystemExit."""
    global _HOOKED
    if (
        _HOOKED
        or MPI.COMM_WORLD.size == 1
        or threading.current_thread() is not threading.main_thread()
    ):
        return False
    before = sys.excepthook

    def hook(kind, value, traceback) -> None:
        before(kind, value, traceback)
        sys.stderr.flush()
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.alarm(max(1, round(timeout)))

    sys.excepthook = hook
    _HOOKED = True
    return True
