"""MPI jobs given hostile input or events, under mpirun -n 2: ranks that disagree about their
input, sweeps with fewer members (or chains) than groups, and an interrupt that reaches one
rank. In the style of tests/test_input_fuzz.py: variants of each, the same contract.

The contract (docs/reliability.md): every rank computes from the same input, or none does,
and no MPI job hangs.

* **Ranks that disagree.** Rank 0 reads a scene or sweep file and every rank parses its bytes
  (schema.read_input): ranks that would read different bytes under one name (a copy per node,
  a file edited while the job starts; here: a relative name in a folder of each rank's own)
  all compute rank 0's. Ranks given different command lines (a scene, --set or --out taken
  from an environment variable per rank) are refused: exit 2, one line naming the argument.
  Before: the ranks parsed their own files: different loads gave exit 0 and a blend of two
  runs, a different time.end a hang, two sweep files a table with rows of both.
* **Fewer members than groups.** A group that gets no member must not leave the others
  waiting: PETSc initialises collectively over the world communicator, so every rank
  imports DOLFINx before the groups split. Before: a sweep of one member on two ranks hung,
  and so did a sweep resumed with fewer members (or chains) left than groups.
* **An interrupt on one rank.** SIGINT on rank 1 alone is remembered and every rank of the
  run stops at its next step (exit 130, summary.json "interrupted"); what no run checks ends
  with the job aborted after parallel.ABORT_AFTER s. Before: that rank left (status 130)
  without the abort safeguard while the other waited in a collective call for ever.

A job that hangs is what these tests must catch: each mpirun gets ``HUNG`` seconds, 10x the
longest measured here under load (a run of 20 steps under mpirun -n 2: 11 s, at a load of 9
on two cores; 1.5 s unloaded; one-off, 2026-12-03); a test whose job ends later fails.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from conftest import (
    HUNG_AFTER,
    PYTHON,
    ROOT,
    read_table,
    run_command,
    said,
    stop_tree,
    subprocess_env,
)
from test_sweep import chain_sweep

from cosserat_fem import api
from cosserat_fem.io.probes import read_probe_table

pytestmark = pytest.mark.mpi

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
TEXT = PAPER.read_text(encoding="utf-8")
#: Seconds after which an mpirun job is taken as hung (module docstring).
HUNG = HUNG_AFTER
#: A command line run on every rank with "{rank}" in its arguments replaced by the rank's
#: number (as a shell wrapper would take a file per rank from an environment variable); the
#: first argument, if not "-", is a folder each rank works in (its own, by "{rank}").
LAUNCH = (
    "import os, resource, signal, sys\n"
    "from cosserat_fem.cli import main\n"
    "rank = os.environ['OMPI_COMM_WORLD_RANK']\n"
    "folder, *argv = [a.replace('{rank}', rank) for a in sys.argv[1:]]\n"
    "if folder != '-':\n"
    "    os.chdir(folder)\n"
    "if os.environ.get('FSIZE_RANK') == rank:  # ulimit -f 0 on this rank, MPI started\n"
    "    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
    "    resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))\n"
    "sys.exit(main(argv))\n"
)


def launch(argv: list[str], folder: str = "-", timeout: float = HUNG, env: dict | None = None):
    """``cosserat-fem argv`` under mpirun -n 2, "{rank}" in ``folder`` and ``argv`` per rank;
    ``env``: variables added (FSIZE_RANK: the rank whose files cannot grow)."""
    return run_command(["-c", LAUNCH, folder, *argv], ranks=2, timeout=timeout, env=env)


def scene_text(**changes: str) -> str:
    """The paper's scene with lines replaced: ``changes`` maps a line's start (unique in the
    file) to its new line."""
    lines = TEXT.splitlines(keepends=True)
    for start, line in changes.items():
        at = [i for i, text in enumerate(lines) if text.startswith(start)]
        assert len(at) == 1, start
        lines[at[0]] = line + "\n"
    return "".join(lines)


#: The paper's scene made short: 20 steps of 30 μs, no XDMF.
SHORT = {"end = 0.06": "end = 0.0006", "xdmf = true": "xdmf = false"}


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# ------------------------------------------------------------------ ranks given different input
def per_rank_files(folder: Path, name: str, texts: list[str]) -> None:
    """``folder/r<rank>/name`` with each rank's text."""
    for rank, text in enumerate(texts):
        (folder / f"r{rank}").mkdir(exist_ok=True)
        (folder / f"r{rank}" / name).write_text(text, encoding="utf-8")


VARIANTS = {
    # a scene per rank (SCENE=$SCENE_$RANK): before, validate passed on both
    "scene": (["validate", "{tmp}/r{rank}/scene.toml"], "SCENE"),
    "set": (["validate", str(PAPER), "--set", "time.end=0.00{rank}6"], "--set"),
    "out": (["run", str(PAPER), "--out", "{tmp}/out{rank}", "--set", "time.end=0.0006"], "--out"),
    "sweep": (["sweep", "{tmp}/r{rank}/sweep.toml", "--out", "{tmp}/out"], "SWEEP"),
}


@pytest.mark.parametrize(
    "variant",
    ["scene", *(pytest.param(v, marks=pytest.mark.long) for v in VARIANTS if v != "scene")],
)
def test_ranks_given_different_command_lines_are_refused(tmp_path, variant):
    """A scene file, a --set, an --out or a sweep file that differs between the ranks: exit 2
    at once, one line naming the argument and both values; nothing is written (before: each
    rank read its own; with other loads a blend and exit 0, with another time.end a hang)."""
    longer = scene_text(**{**SHORT, "end = 0.06": "end = 0.0012"})
    per_rank_files(tmp_path, "scene.toml", [scene_text(**SHORT), longer])
    per_rank_files(
        tmp_path,
        "sweep.toml",
        [
            f'[sweep]\nscene = "{PAPER}"\n[sweep.vary]\n"time.step" = [{s}]\n'
            for s in ("1e-5", "2e-5")
        ],
    )
    argv, name = VARIANTS[variant]
    proc = launch([a.replace("{tmp}", str(tmp_path)) for a in argv])
    assert proc.returncode == 2, proc.stderr
    lines = said(proc.stderr)
    assert len(lines) == 1 and lines[0].startswith(
        f"cosserat-fem: error: {name}: the MPI ranks were given different command lines (rank 0: "
    )
    assert "rank 1: " in lines[0]
    assert not any(p.name.startswith("out") for p in tmp_path.iterdir())


@pytest.mark.long
@pytest.mark.parametrize(
    ("what", "rank1"),
    [
        ("time.end", {"end = 0.0006": "end = 0.0012"}),  # before: a hang
        ("loads", {'    "2e3*sin': '    "4e3*sin(pi*s/L)*sin(8*omega0*t)",'}),  # x: a blend
    ],
)
def test_ranks_that_would_read_different_scenes_all_run_rank_0s(tmp_path, what, rank1):
    """One name, other bytes on rank 1 (each rank in a folder of its own, as with a copy of the
    scene per node or a file edited as the job starts): both ranks run rank 0's scene. Its
    probes.csv is that of ``mpirun -n 2 run`` of rank 0's file byte for byte (the same ranks,
    partition and solver; tests/test_sweep.py: runs are deterministic), and summary.json
    names the SHA-256 of rank 0's file (before: another time.end hung the job, other loads
    gave exit 0 and a blend: rank 1's half of the rod loaded twice as much)."""
    texts = [scene_text(**SHORT), scene_text(**SHORT)]
    lines = texts[1].splitlines()
    for start, line in rank1.items():  # the first line that starts so (force_density's x)
        lines[next(i for i, t in enumerate(lines) if t.startswith(start))] = line
    texts[1] = "\n".join(lines) + "\n"
    assert texts[1] != texts[0]
    per_rank_files(tmp_path, "scene.toml", texts)
    proc = launch(
        ["run", "scene.toml", "--out", str(tmp_path / "out"), "--quiet"], str(tmp_path / "r{rank}")
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text(encoding="utf-8"))
    assert summary["scene_file_sha256"] == sha256(tmp_path / "r0" / "scene.toml")
    alone = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "run",
            str(tmp_path / "r0" / "scene.toml"),
            "--out",
            str(tmp_path / "alone"),
            "--quiet",
        ],
        2,
        timeout=HUNG,
    )
    assert alone.returncode == 0, alone.stderr
    assert (tmp_path / "out" / "probes.csv").read_bytes() == (
        tmp_path / "alone" / "probes.csv"
    ).read_bytes()


@pytest.mark.long
@pytest.mark.parametrize("which", ["sweep file", "base scene"])
def test_ranks_that_would_read_different_sweeps_all_run_rank_0s(tmp_path, which):
    """The sweep file, or its base scene (named relative to it), differs on rank 1 under one
    name: the table holds rank 0's sweep only, its members' values and their runs of rank
    0's base scene (before: rows from two sweeps, members run on scenes that differ by rank)."""
    steps = {
        "sweep file": (["1e-5", "2e-5"], ["3e-5", "1.5e-5"]),
        "base scene": (["1e-5", "2e-5"], ["1e-5", "2e-5"]),
    }[which]
    sweeps = [
        f'[sweep]\nscene = "scene.toml"\nkeep = "probes"\n[sweep.vary]\n'
        f'"time.step" = [{", ".join(s)}]\n'
        for s in steps
    ]
    ends = ["end = 0.0006", "end = 0.0012" if which == "base scene" else "end = 0.0006"]
    per_rank_files(tmp_path, "sweep.toml", sweeps)
    per_rank_files(tmp_path, "scene.toml", [scene_text(**{**SHORT, "end = 0.06": e}) for e in ends])
    proc = launch(
        ["sweep", "sweep.toml", "--out", str(tmp_path / "out"), "--quiet"],
        str(tmp_path / "r{rank}"),
    )
    assert proc.returncode == 0, proc.stderr
    rows = read_table(tmp_path / "out" / "sweep.csv")
    assert [json.loads(r["time.step"]) for r in rows] == [1e-5, 2e-5]
    assert [int(r["steps"]) for r in rows] == [60, 30]  # 0.6 ms: rank 0's time.end
    digest = sha256(tmp_path / "r0" / "scene.toml")
    for member in ("m00000", "m00001"):
        summary = json.loads((tmp_path / "out" / "members" / member / "summary.json").read_text())
        assert summary["scene_file_sha256"] == digest


# ------------------------------------------------------------ fewer members than groups
def sweep_file(folder: Path, values: str, **sweep) -> Path:
    """A sweep of the paper's scene (0.6 ms, no XDMF) over time.step ``values``."""
    head = "".join(f"{k} = {json.dumps(v)}\n" for k, v in sweep.items())
    path = folder / "sweep.toml"
    path.write_text(
        f'[sweep]\nscene = "{PAPER}"\n{head}[sweep.set]\n"time.end" = 0.0006\n'
        f'"output.xdmf" = false\n[sweep.vary]\n"time.step" = [{values}]\n',
        encoding="utf-8",
    )
    return path


def sweep_under_mpi(path: Path, out: Path):
    proc = run_command(
        ["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)], 2, timeout=HUNG
    )
    assert proc.returncode == 0, proc.stderr
    return proc


def strip(table: Path) -> list[dict]:
    """A table's rows without the wall times, which differ run to run."""
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in read_table(table)]


def test_a_sweep_of_one_member_on_two_groups(tmp_path):
    """One member, two groups of one rank: the group without a member waits for the other
    and the sweep ends (before: it hung for ever); the row is the member's serial run's, to
    the last digit (tests/test_sweep.py: a group of one rank runs serially)."""
    path = sweep_file(tmp_path, "2e-5")
    proc = sweep_under_mpi(path, tmp_path / "n2")
    assert "ran 1, skipped 0" in proc.stdout
    api.sweep(api.load_sweep(path), tmp_path / "n1")
    assert strip(tmp_path / "n2" / "sweep.csv") == strip(tmp_path / "n1" / "sweep.csv")


@pytest.mark.long
@pytest.mark.parametrize("left", [0, 1])
def test_a_sweep_resumed_with_fewer_members_left_than_groups(tmp_path, left):
    """A sweep of three members whose table has rows for 3 - ``left`` (a sweep killed after
    them; the last rows removed from the serial run's part): resumed under mpirun -n 2 with
    fewer members left than groups, it runs what is left and its table is the uninterrupted
    sweep's (before: with one member left, a hang)."""
    path = sweep_file(tmp_path, "1e-5, 2e-5, 3e-5")
    out = tmp_path / "out"
    api.sweep(api.load_sweep(path), out)
    whole = strip(out / "sweep.csv")
    part = out / "table" / "group-0.csv"
    lines = part.read_text(encoding="utf-8").splitlines(keepends=True)
    part.write_text("".join(lines[: len(lines) - left]), encoding="utf-8")
    (out / "sweep.csv").unlink()
    proc = sweep_under_mpi(path, out)
    assert f"ran {left}, skipped {3 - left}" in proc.stdout
    assert strip(out / "sweep.csv") == whole


@pytest.mark.long
def test_a_frequency_response_of_one_chain_on_two_groups(tmp_path):
    """A forced response of one chain of two members (continuation) on two groups, run
    again with its second member left: one chain for two groups both times, and the table
    is the serial sweep's (before: a hang)."""
    path = chain_sweep(tmp_path, max_periods=4)
    api.sweep(api.load_sweep(path), tmp_path / "n1")
    out = tmp_path / "n2"
    sweep_under_mpi(path, out)
    assert strip(out / "sweep.csv") == strip(tmp_path / "n1" / "sweep.csv")
    for part in (out / "table").glob("group-*.csv"):  # the second member's row removed
        part.write_text(
            "".join(
                line
                for line in part.read_text().splitlines(keepends=True)
                if not line.startswith("1,")
            ),
            encoding="utf-8",
        )
    (out / "sweep.csv").unlink()
    assert "ran 1, skipped 1" in sweep_under_mpi(path, out).stdout
    assert strip(out / "sweep.csv") == strip(tmp_path / "n1" / "sweep.csv")


@pytest.mark.long
def test_a_group_that_cannot_write_its_table_part_ends_the_sweep_on_every_rank(tmp_path):
    """Rank 1 (group 1) cannot write a byte (``ulimit -f 0`` on its node): its group stops at
    its table part with OutputError; the other group runs every member, then every rank
    raises that error: exit 4, its one line, no abort (before: group 1's rank left, the
    other waited in a collective call until the abort safeguard took the job down 10 s
    later, and the error was never printed: only rank 0 prints, and rank 0 had none)."""
    path = sweep_file(tmp_path, "1e-5, 2e-5, 3e-5")
    out = tmp_path / "out"
    proc = launch(["sweep", str(path), "--out", str(out)], env={"FSIZE_RANK": "1"})
    assert proc.returncode == 4, proc.stderr
    assert said(proc.stderr) == [
        f"cosserat-fem: error: sweep: cannot write "
        f"{str(out / 'table' / 'group-1.csv')!r} ([Errno 27] File too "
        "large)"
    ]
    rows = read_table(out / "table" / "group-0.csv")
    assert sorted(r["member"] for r in rows) == ["0", "1", "2"]


# ------------------------------------------------------------------ an interrupt on one rank
def ranks_of(mpirun: subprocess.Popen, count: int, deadline: float) -> dict[int, int]:
    """{rank: pid} of mpirun's children (Open MPI starts local ranks as its children)."""
    found: dict[int, int] = {}
    while len(found) < count:
        assert time.monotonic() < deadline, f"ranks not found: {found}"
        for entry in Path("/proc").iterdir():
            try:
                stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
                if entry.name.isdigit() and int(stat[1]) == mpirun.pid:
                    environ = (entry / "environ").read_bytes().split(b"\0")
                    rank = [v for v in environ if v.startswith(b"OMPI_COMM_WORLD_RANK=")]
                    if rank:
                        found[int(rank[0].split(b"=")[1])] = int(entry.name)
            except (OSError, IndexError, ValueError):
                continue
        time.sleep(0.05)
    return found


def interrupted(tmp_path: Path, argv: list[str], ready, ranks: tuple[int, ...]):
    """Start ``cosserat-fem argv`` under mpirun -n 2, wait until ``ready()``, send SIGINT to
    ``ranks``; (the job's exit status, its stderr)."""
    cmd = ["mpirun", "-n", "2", PYTHON, "-m", "cosserat_fem.cli", *argv]
    job = subprocess.Popen(
        cmd,
        cwd=ROOT,
        env=subprocess_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + HUNG
        pids = ranks_of(job, 2, deadline)
        while not ready():
            assert job.poll() is None, job.stderr.read()
            assert time.monotonic() < deadline, "the job never got going"
            time.sleep(0.05)
        for rank in ranks:
            os.kill(pids[rank], signal.SIGINT)
        _, err = job.communicate(timeout=HUNG)
        return job.returncode, err
    finally:
        if job.poll() is None:  # hung: end mpirun and every rank
            stop_tree(job)
            job.communicate()


def probe_rows(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except OSError:
        return 0


@pytest.mark.long
@pytest.mark.parametrize("ranks", [(1,), (0, 1)], ids=["rank 1", "both ranks"])
def test_an_interrupt_on_one_rank_ends_the_run_on_every_rank(tmp_path, ranks):
    """SIGINT to rank 1 alone (``kill -INT``), or to both (as srun forwards it): every rank
    stops at the same step, exit 130, summary.json "interrupted", probes.csv whole lines
    up to it, not aborted (before: rank 1 left, rank 0 waited for ever)."""
    out = tmp_path / "out"
    argv = [
        "run",
        str(PAPER),
        "--out",
        str(out),
        "--quiet",
        "--set",
        "time.end=0.3",
        "--set",
        "output.xdmf=false",
    ]
    status, err = interrupted(tmp_path, argv, lambda: probe_rows(out / "probes.csv") > 20, ranks)
    assert status == 130 and "MPI_ABORT" not in err, err
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["status"] == "interrupted"
    assert len(read_probe_table(out / "probes.csv")[1]) >= 20  # the rows seen before the signal


@pytest.mark.long
def test_an_interrupt_on_one_rank_of_a_sweep_ends_the_job(tmp_path):
    """A sweep on two groups of one rank, SIGINT to rank 1 while members run: rank 1's group
    stops, the other goes on with its member; the job is aborted (ABORT_AFTER s of wall time
    after the interrupt at the latest on an idle machine; the test's limit is a hang limit),
    the rows written are kept, and the sweep started again finishes the table as
    an uninterrupted sweep's (before: rank 1 left, rank 0 waited for ever)."""
    path = sweep_file(tmp_path, "1e-5, 2e-5, 3e-5, 1.5e-5, 6e-6, 5e-6, 4e-6, 1.2e-5")
    out = tmp_path / "out"
    parts = out / "table"

    def started() -> bool:
        return sum(probe_rows(p) for p in parts.glob("group-*.csv")) >= 4  # headers + 2 rows

    status, err = interrupted(tmp_path, ["sweep", str(path), "--out", str(out)], started, (1,))
    assert status != 0, err
    sweep_under_mpi(path, out)
    api.sweep(api.load_sweep(path), tmp_path / "whole")
    assert strip(out / "sweep.csv") == strip(tmp_path / "whole" / "sweep.csv")
