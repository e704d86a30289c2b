"""Shared helpers: running the CLI, demos and mpirun in subprocesses."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PYTHON = sys.executable  # the venv's interpreter (make test runs pytest from .venv)


def subprocess_env() -> dict[str, str]:
    env = dict(os.environ)
    # Open MPI refuses to run as root (containers, CI) unless told; 2 ranks on 2 cores.
    env.update(
        OMPI_ALLOW_RUN_AS_ROOT="1",
        OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
        OMPI_MCA_rmaps_base_oversubscribe="1",
    )
    return env


def said(stderr: str) -> list[str]:
    """The project's lines of ``stderr`` other than a sweep's progress (one line per member as
    it finishes, cosserat_fem/progress.py's SweepProgress): what a command reports, without
    the lines Open MPI adds when a rank exits non-zero."""
    return [
        line
        for line in stderr.splitlines()
        if line.startswith("cosserat-fem:") and not line.startswith("cosserat-fem: sweep member ")
    ]


def run_command(
    args: list[str], ranks: int = 1, timeout: float = 600, cwd: Path = ROOT, env: dict | None = None
):
    """Run ``args`` (a Python script and its arguments) serially or under mpirun; ``env``:
    variables added to the environment."""
    cmd = [PYTHON, *args]
    if ranks > 1:
        mpirun = shutil.which("mpirun")
        if mpirun is None:
            pytest.fail("mpirun not found: install openmpi-bin (make setup does)")
        cmd = [mpirun, "-n", str(ranks), *cmd]
    return subprocess.run(
        cmd,
        cwd=cwd,
        env={**subprocess_env(), **(env or {})},
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def parse_qoi(stdout: str) -> dict[str, float]:
    """The ``QOI name = value`` lines a demo prints."""
    values = {}
    for line in stdout.splitlines():
        if line.startswith("QOI "):
            name, value = line[4:].split("=")
            values[name.strip()] = float(value)
    return values


def python_steps(monkeypatch) -> None:
    """Time loops step with their integrator's Python step, whose solves are Python calls that
    a test can replace: not with cosserat_fem/native_sdirk.py, whose stages and solves are one
    C call (its failures, retries and rejections are those of the Python step, bit for bit:
    tests/test_native_newton.py)."""
    from cosserat_fem import loop

    monkeypatch.setattr(loop, "stepper", lambda integrator, *args: integrator)


def inject_newton_failures(monkeypatch, fails) -> None:
    """Make Newton solve number n (counting from 1 over all solvers) raise NewtonFailure when
    ``fails(n)`` is true (time loops take Python steps: :func:`python_steps`); undone by
    monkeypatch.undo() or at the end of the test."""
    from cosserat_fem.newton import NewtonFailure, NewtonSolver

    python_steps(monkeypatch)

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
    """cosserat_fem.jit.install() for a block (crash-safe, quiet compiles: other processes
    share the FFCx cache); the state before it is restored afterwards."""
    from cosserat_fem import jit

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
        proc = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)],
                           ranks)  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        tables[ranks] = [{k: v for k, v in r.items() if k != "wall_s"}
                         for r in read_table(out / "sweep.csv")]  # fmt: skip
    return tables


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
