"""Shared helpers: running the CLI, demos and mpirun in subprocesses."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYTHON = sys.executable  # the venv's interpreter (make test runs pytest from .venv)
ROUNDOFF = Path(__file__).resolve().parent / "roundoff"

# ROUNDOFF_NOISE=N: another CPU's round-off (N ulps) in numpy's transcendentals, here and in
# every subprocess (tests/roundoff/roundoff_noise.py).
if os.environ.get("ROUNDOFF_NOISE", "") not in ("", "0"):
    sys.path.insert(0, str(ROUNDOFF))
    import roundoff_noise

    roundoff_noise.install()
    os.environ["PYTHONPATH"] = os.pathsep.join(
        [str(ROUNDOFF), *filter(None, [os.environ.get("PYTHONPATH")])]
    )


#: A subprocess limit that means "hung", not "slow" [s]: make test's subprocesses take at most
#: ~10 s on two idle cores, and ~400 s took the slowest (the paper's demo, 400 steps on two
#: ranks: a step is many MPI messages) at load 9 on two cores; an MPI job that waits for ever
#: in a collective never ends. Callers with a known longer run give their own limit.
HUNG_AFTER = 900.0


def subprocess_env() -> dict[str, str]:
    """The environment of the tests' subprocesses: os.environ and Open MPI's settings for a
    machine shared with other work (docs/developers.md, "MPI on a busy machine")."""
    env = dict(os.environ)
    env.update(
        # Open MPI refuses to run as root (containers, CI) unless told; 2 ranks on 2 cores.
        OMPI_ALLOW_RUN_AS_ROOT="1",
        OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
        OMPI_MCA_rmaps_base_oversubscribe="1",
        # A rank that waits for another yields its core instead of spinning on it, and no rank
        # is bound to a core (Open MPI binds each of two ranks to a core of its own): on a busy
        # machine (pytest's other worker, another mpirun, other users) a spinning rank took
        # the core its partner needed, and a bound rank could not move off a busy core (a
        # 400-step run on two ranks: 38-68 s wall against 7-20 s with both settings).
        OMPI_MCA_mpi_yield_when_idle="1",
        OMPI_MCA_hwloc_base_binding_policy="none",
    )
    return env


def said(stderr: str) -> list[str]:
    """The project's lines of ``stderr`` other than a sweep's progress (one line per member as
    it finishes, cosserat_fem/analysis/progress.py's SweepProgress): what a command reports, without
    the lines Open MPI adds when a rank exits non-zero."""
    return [
        line
        for line in stderr.splitlines()
        if line.startswith("cosserat-fem:") and not line.startswith("cosserat-fem: sweep member ")
    ]


def cpu_seconds() -> float:
    """CPU seconds used so far by this process and its waited-for children (a compiler run by
    cffi), user and system: a measure of work that other processes on the machine do not
    change, unlike wall time (a limit on it is "too much work", never "a busy machine")."""
    return sum(os.times()[:4])


def descendants(pid: int) -> list[int]:
    """The processes started by ``pid``, their children and so on (mpirun's ranks: Open MPI
    puts them in process groups of their own, so a signal to mpirun's group misses them)."""
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents.setdefault(int(stat.rsplit(")", 1)[1].split()[1]), []).append(int(entry.name))
    found, todo = [], [pid]
    while todo:
        kids = parents.get(todo.pop(), [])
        found += kids
        todo += kids
    return found


def running(pid: int) -> bool:
    """The process exists and is not a zombie (a zombie holds no files and runs nothing)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] not in ("Z", "X")


def stop_tree(proc: subprocess.Popen, grace: float = 10.0) -> None:
    """End ``proc`` and every process it started: SIGTERM (mpirun passes it on to its ranks),
    then SIGKILL to whatever is left after ``grace`` seconds."""
    victims = [*descendants(proc.pid), proc.pid]
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in victims:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, sig)
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=grace)
        victims = [pid for pid in victims if running(pid)]


def run_command(
    args: list[str],
    ranks: int = 1,
    timeout: float = HUNG_AFTER,
    cwd: Path = ROOT,
    env: dict | None = None,
) -> subprocess.CompletedProcess:
    """Run ``args`` (a Python script and its arguments) serially or under mpirun; ``env``:
    variables added to the environment. ``timeout`` [s] is a hang limit (:data:`HUNG_AFTER`):
    past it the command and every process it started are ended and the test fails, saying
    so."""
    cmd = [PYTHON, *args]
    if ranks > 1:
        mpirun = shutil.which("mpirun")
        if mpirun is None:
            pytest.fail("mpirun not found: install openmpi-bin (make setup does)")
        cmd = [mpirun, "-n", str(ranks), *cmd]
    proc = subprocess.Popen(
        cmd,
        cwd=cwd,
        env={**subprocess_env(), **(env or {})},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        stop_tree(proc)
        out, err = proc.communicate()
        pytest.fail(
            f"hung: {' '.join(cmd)} had not ended after {timeout:g} s (a hang limit; "
            f"its stderr ends: {err[-2000:]!r})"
        )
    except BaseException:  # Ctrl-C, a test's own failure: leave no rank running
        stop_tree(proc)
        raise
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


def parse_qoi(stdout: str) -> dict[str, float]:
    """The ``QOI name = value`` lines a demo prints."""
    values = {}
    for line in stdout.splitlines():
        if line.startswith("QOI "):
            name, value = line[4:].split("=")
            values[name.strip()] = float(value)
    return values


def inject_newton_failures(monkeypatch, fails) -> None:
    """Make Newton solve number n (counting from 1 over all solvers) raise NewtonFailure when
    ``fails(n)`` is true (every stage of every integrator calls NewtonSolver.solve: the
    users' path); undone by monkeypatch.undo() or at the end of the test."""
    from cosserat_fem.nls.newton import NewtonFailure, NewtonSolver

    real_solve = NewtonSolver.solve
    calls = {"n": 0}

    def solve(self):
        calls["n"] += 1
        if fails(calls["n"]):
            raise NewtonFailure("injected", 0)
        return real_solve(self)

    monkeypatch.setattr(NewtonSolver, "solve", solve)


@contextlib.contextmanager
def jit_installed():
    """cosserat_fem.common.jit.install() for a block (crash-safe, quiet compiles: other processes
    share the FFCx cache); the state before it is restored afterwards."""
    from cosserat_fem.common import jit

    before = jit.installed()
    jit.install()
    try:
        yield
    finally:
        if not before:
            jit.uninstall()


def read_table(path: Path) -> list[dict]:
    """The rows of a CSV table (a sweep's sweep.csv) as dicts of strings."""
    import csv

    with open(path, newline="", encoding="utf-8") as stream:
        return list(csv.DictReader(stream))


def sweep_serial_and_mpi(path: Path, folder: Path) -> dict[int, list[dict]]:
    """``cosserat-fem sweep path`` on one rank and under mpirun -n 2 (into folder/n1, n2): each
    table's rows without the wall times, which differ run to run."""
    tables = {}
    for ranks in (1, 2):
        out = folder / f"n{ranks}"
        proc = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)], ranks)
        assert proc.returncode == 0, proc.stderr
        tables[ranks] = [
            {k: v for k, v in r.items() if k != "wall_s"} for r in read_table(out / "sweep.csv")
        ]
    return tables


def script_serial_and_mpi(script: Path, text: str) -> list[dict]:
    """The Python ``text`` written to ``script`` and run on one rank and under mpirun -n 2:
    the JSON object each run prints on its last line (rank 0's), serial first."""
    import json

    script.write_text(text)
    answers = []
    for ranks in (1, 2):
        done = run_command([str(script)], ranks=ranks)
        assert done.returncode == 0, done.stderr[-2000:]
        answers.append(json.loads(done.stdout.strip().splitlines()[-1]))
    return answers


def damage_library(library: Path, how: str) -> None:
    """Damage a compiled library as a partial copy of the cache or a disk error would.

    "cut": the first half only (a copy interrupted; loaded, SIGBUS at its first call);
    "cut, no record": the same in a cache written before digests were recorded;
    "missing": the library gone, .c.cached still there (ModuleNotFoundError);
    "altered": 64 bytes in the middle changed (a disk error: found by the digest alone);
    "zeroed tail, no record": its last 4 KiB zeros (the section headers), no digest.
    The damaged bytes go to a new file put in the library's place: this process may have the
    library mapped, and a file cut in place would cut its mapping too (SIGBUS here)."""
    data = bytearray(library.read_bytes())
    if how.endswith("no record"):
        library.with_name(library.name + ".sha256").unlink(missing_ok=True)
    if how == "missing":
        library.unlink()
        return
    if how.startswith("cut"):
        data = data[: len(data) // 2]
    elif how == "altered":
        middle = len(data) // 2
        data[middle : middle + 64] = bytes(b ^ 0x5A for b in data[middle : middle + 64])
    elif how.startswith("zeroed tail"):
        data[-4096:] = bytes(4096)
    damaged = library.with_name("damaged")
    damaged.write_bytes(bytes(data))
    damaged.replace(library)


def file_size_limit(limit: int):
    """A child's RLIMIT_FSIZE (``ulimit -f``): a write past ``limit`` bytes fails with EFBIG,
    as on a full disk (SIGXFSZ ignored, as the command line does)."""
    import resource
    import signal

    def preexec() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    return preexec


def folder_tree(folder: Path, skip: tuple[str, ...] = ()) -> dict[str, str]:
    """Every name under ``folder`` (links not followed, names in ``skip`` left out): a file's
    SHA-256, a link's target, else "folder" or "special" (a FIFO, a socket, a device)."""
    import hashlib

    found = {}
    for path in sorted(folder.rglob("*")):
        if path.name in skip:
            continue
        name = str(path.relative_to(folder))
        if path.is_symlink():
            found[name] = "link -> " + os.readlink(path)
        elif path.is_dir():
            found[name] = "folder"
        elif path.is_file():
            found[name] = hashlib.sha256(path.read_bytes()).hexdigest()
        else:
            found[name] = "special"
    return found


class Hung(BaseException):
    """Raised by :func:`fails_if_hung`'s alarm: a BaseException, which no ``except
    Exception`` or ``except OSError`` of the code under test takes for a failed read."""


@contextlib.contextmanager
def fails_if_hung(seconds: float, what: str = ""):
    """Fail the test if the block takes more than ``seconds`` (a blocking open of a FIFO, a
    read that never ends, are interrupted by SIGALRM)."""
    import signal

    def alarm(signum, frame):
        raise Hung

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(max(1, int(seconds)))
    try:
        yield
    except Hung:
        pytest.fail(f"hung for {seconds} s {what}".strip())
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
