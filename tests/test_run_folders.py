"""Run folders that users copy, link, share and fill: nothing of theirs is lost or written
through (issue 25, items 4, 5, 6, 12, 14).

* A new ``run`` into a folder removes only the files the project wrote there (the checkpoint's
  and the frames' own names), never a user's file or a run nested inside, and refuses in one
  line, touching nothing, where a user's file stands where it must write (item 4).
* A folder has one writer: a second ``run``, ``static``, ``run --restart`` or ``sweep`` is
  refused in one line naming the holder (its run id, process, host), and the lock dies with
  its holder, SIGKILL included (item 5).
* No output is written through a symbolic or hard link: restarting a copy made with ``cp -as``
  or ``cp -al`` leaves the original byte for byte as it was and gives the restart of a plain
  copy, byte for byte; a new run replaces links, never follows them (item 6).
* A FIFO anywhere in a run's or a sweep's folder hangs nothing: ``run --restart``, a new run,
  ``sweep``, ``plot`` and ``pod`` end, refusing in one line or going on (item 12).
* sweep.json is written atomically: a write cut by the file size limit leaves none, and the
  sweep then starts normally (item 14).

Equality of bytes is the test for a restart (tests/test_restart.py says why: the restart is
bit for bit the uninterrupted run). Time limits here mean "hung": 60-120 s against a few
seconds measured.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import (
    HUNG_AFTER,
    PYTHON,
    ROOT,
    fails_if_hung,
    folder_tree,
    read_table,
    run_command,
    subprocess_env,
)

from cosserat_fem.cli import main

SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
SHORT = ["--set", "time.end=0.0006", "--set", "output.xdmf_interval=6e-5"]
RESTART = ["--set", "time.end=0.00081"]  # 27 steps of 30 us: 7 beyond the checkpoint
HUNG = HUNG_AFTER  # s: a command that takes longer has hung (each takes 1-8 s here)


def snapshot(folder: Path) -> dict[str, str]:
    return folder_tree(folder)


def cli(capsys, *args: str) -> tuple[int, list[str]]:
    """``cosserat-fem args`` in this process: the exit status and the stderr lines."""
    capsys.readouterr()
    status = main(list(args))
    return status, capsys.readouterr().err.strip().splitlines()


def one_line(status: int, err: list[str], *names: str) -> None:
    """A refusal: exit 2, one stderr line, no traceback, naming each of ``names``."""
    assert status == 2 and len(err) == 1, (status, err)
    assert "internal error" not in err[0] and "Traceback" not in err[0], err
    for name in names:
        assert name in err[0], (name, err)


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """A completed run of 20 steps: probes, 11 XDMF frames, checkpoints (the last at its
    end), made once."""
    folder = tmp_path_factory.mktemp("folders") / "base"
    assert main(["run", SCENE, "--out", str(folder), "--quiet", *SHORT]) == 0
    return folder


def copy_of(base: Path, folder: Path) -> Path:
    return Path(shutil.copytree(base, folder, symlinks=True))


# ------------------------------------------------------------------------ item 4: ownership
def test_a_new_run_removes_only_the_files_it_owns(base, tmp_path, capsys):
    """A new run (3 frames, no checkpoint) into the folder of an earlier one (11 frames, a
    checkpoint) that also holds a user's notes in checkpoint/ and solution.frames/ and a whole
    run nested in checkpoint/: the notes and the nested run are left byte for byte; of the
    earlier run's files none is left (its index, state files and frames 3-10 gone, frames 0-2
    and mesh.h5 the new run's); before, checkpoint/ and solution.frames/ went wholesale."""
    folder = copy_of(base, tmp_path / "run")
    (folder / "checkpoint" / "notes.txt").write_text("mine\n")
    (folder / "solution.frames" / "readme.txt").write_text("mine too\n")
    (folder / "solution.frames" / "extra").mkdir()
    nested = folder / "checkpoint" / "nested"
    assert main(["run", SCENE, "--out", str(nested), "--quiet", *SHORT]) == 0
    theirs = {
        k: v
        for k, v in snapshot(folder).items()
        if k.startswith(("checkpoint/n", "solution.frames/readme", "solution.frames/extra"))
    }
    status, err = cli(
        capsys,
        "run",
        SCENE,
        "--out",
        str(folder),
        "--quiet",
        "--set",
        "time.end=0.0006",
        "--set",
        "output.xdmf_interval=3e-4",
        "--set",
        "output.checkpoint=false",
    )
    assert status == 0, err
    after = snapshot(folder)
    assert {k: v for k, v in after.items() if k in theirs} == theirs
    assert sorted(p.name for p in (folder / "checkpoint").iterdir()) == ["nested", "notes.txt"]
    frames = sorted(p.name for p in (folder / "solution.frames").iterdir())
    assert frames == ["000000.h5", "000001.h5", "000002.h5", "extra", "mesh.h5", "readme.txt"]


@pytest.mark.parametrize(
    "make, name",
    [
        (lambda f: (f / "checkpoint").write_text("mine\n"), "checkpoint"),
        (lambda f: (f / "probes.csv").mkdir(), "probes.csv"),
        (lambda f: (f / "solution.frames" / "000001.h5").mkdir(), "000001.h5"),
        (lambda f: (f / "checkpoint" / "checkpoint.json").mkdir(), "checkpoint.json"),
    ],
    ids=[
        "a file named checkpoint",
        "a folder named probes.csv",
        "a folder among the frames",
        "a folder named checkpoint.json",
    ],
)
def test_a_users_file_where_the_run_writes_is_refused_touching_nothing(
    tmp_path, capsys, make, name
):
    """Something not the project's where the run must write: refused in one line naming it,
    exit 2, the folder as it was (before: a file named checkpoint was deleted)."""
    folder = tmp_path / "run"
    (folder / "solution.frames").mkdir(parents=True)
    (folder / "checkpoint").mkdir() if name == "checkpoint.json" else None
    make(folder)
    before = snapshot(folder)
    status, err = cli(capsys, "run", SCENE, "--out", str(folder), "--quiet", *SHORT)
    one_line(status, err, name)
    assert snapshot(folder) == before


# ----------------------------------------------------------------------------- item 5: lock
HOLD = """
import sys
from pathlib import Path
from cosserat_fem.io.folder_lock import FolderLock
lock = FolderLock.take(Path(sys.argv[1]), "run", "feedc0de")
print("held", flush=True)
sys.stdin.read()
"""


def holder(folder: Path) -> subprocess.Popen:
    """A process that holds ``folder``'s lock (run id feedc0de) until its stdin closes."""
    proc = subprocess.Popen(
        [PYTHON, "-c", HOLD, str(folder)],
        cwd=ROOT,
        env=subprocess_env(),
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline() == "held\n"
    return proc


def test_a_held_folder_is_refused_to_every_writer_naming_the_holder(base, tmp_path, capsys):
    """While another process holds a run folder, ``run``, ``static``, ``run --restart``,
    ``sweep``, ``modes`` (about either state) and ``stability`` into it are refused (exit 2,
    one line naming the holder's run id and process) and the folder is as it was; once the
    holder is killed with SIGKILL, the lock is gone with it and a restart goes on."""
    folder = copy_of(base, tmp_path / "run")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'[sweep]\nscene = "{SCENE}"\n[sweep.vary]\n"time.step" = [1e-5, 2e-5]\n')
    before = snapshot(folder)
    proc = holder(folder)
    try:
        for args in (
            ["run", SCENE, "--out", str(folder)],
            ["static", SCENE, "--out", str(folder)],
            ["run", "--restart", str(folder), *RESTART],
            ["sweep", str(sweep), "--out", str(folder)],
            ["modes", SCENE, "--out", str(folder)],
            ["modes", SCENE, "--about", "static", "--out", str(folder)],
            ["stability", SCENE, "--range", "0", "1", "--out", str(folder)],
        ):
            status, err = cli(capsys, *args, "--quiet")
            one_line(status, err, "feedc0de", f"process {proc.pid}", "in use")
        assert snapshot(folder) == {
            **before,
            ".cosserat-fem.lock": snapshot(folder)[".cosserat-fem.lock"],
        }
    finally:
        proc.kill()
        proc.wait()
    status, err = cli(capsys, "run", "--restart", str(folder), "--quiet", *RESTART)
    assert status == 0, err
    assert not (folder / ".cosserat-fem.lock").exists()  # removed by the writer at its end


@pytest.mark.long
def test_a_second_run_into_a_running_ones_folder_is_refused(tmp_path):
    """Two real runs: while the first runs (30 000 steps), a second into its folder is refused
    in one line naming the first's process and run id, and the first goes on with its outputs
    (before: the second deleted its checkpoint and XDMF file); after the first is killed
    (SIGKILL), a new run into the folder goes ahead (no stale lock)."""
    folder = tmp_path / "run"
    first = subprocess.Popen(
        [
            PYTHON,
            "-m",
            "cosserat_fem.cli",
            "run",
            SCENE,
            "--out",
            str(folder),
            "--quiet",
            "--set",
            "time.end=0.9",
        ],
        cwd=ROOT,
        env=subprocess_env(),
    )
    try:
        deadline = time.monotonic() + HUNG
        summary = {}
        while summary.get("status") != "running" or not (folder / "probes.csv").exists():
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.2)
            try:
                summary = json.loads((folder / "summary.json").read_text())
            except (OSError, ValueError):
                summary = {}
        second = run_command(
            [
                "-m",
                "cosserat_fem.cli",
                "run",
                SCENE,
                "--out",
                str(folder),
                "--quiet",
                "--set",
                "time.end=0.0003",
            ],
            timeout=HUNG,
        )
        assert second.returncode == 2 and second.stderr.count("\n") == 1, second.stderr
        assert f"process {first.pid}" in second.stderr and summary["run_id"] in second.stderr
        assert first.poll() is None, "the first run was stopped"
        assert json.loads((folder / "summary.json").read_text())["run_id"] == summary["run_id"]
        assert (folder / "solution.xdmf").is_file()
    finally:
        first.kill()
        first.wait()
    third = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "run",
            SCENE,
            "--out",
            str(folder),
            "--quiet",
            "--set",
            "time.end=0.0003",
        ],
        timeout=HUNG,
    )
    assert third.returncode == 0, third.stderr


@pytest.mark.long
@pytest.mark.mpi
def test_a_held_folder_is_refused_under_mpi(tmp_path):
    """Under mpirun -n 2 the lock is rank 0's and every rank refuses alike: one line, exit 2,
    no hang (the job ends well within the limit)."""
    folder = tmp_path / "run"
    folder.mkdir()
    proc = holder(folder)
    try:
        done = run_command(
            ["-m", "cosserat_fem.cli", "run", SCENE, "--out", str(folder), "--quiet", *SHORT],
            ranks=2,
            timeout=HUNG,
        )
    finally:
        proc.kill()
        proc.wait()
    assert done.returncode == 2 and "feedc0de" in done.stderr, done.stderr
    assert sorted(p.name for p in folder.iterdir()) == [".cosserat-fem.lock"]


# ---------------------------------------------------------------------------- item 6: links
def linked_copy(original: Path, copy: Path, hard: bool) -> None:
    """``cp -al`` (``hard``) or ``cp -as`` of ``original``: folders made, every file a link."""
    for path in sorted(original.rglob("*")):
        target = copy / path.relative_to(original)
        if path.is_dir():
            target.mkdir(parents=True)
        elif hard:
            os.link(path, target)
        else:
            target.symlink_to(path.resolve())


@pytest.mark.parametrize("hard", [False, True], ids=["cp -as", "cp -al"])
def test_a_restart_of_a_linked_copy_leaves_the_original(base, tmp_path, capsys, hard):
    """A copy whose files are all links to the original's: its restart leaves every file of
    the original byte for byte (before: the original's probes.csv was cut and extended), and
    gives the probes, XDMF file and checkpoint index of the restart of a plain copy, byte for
    byte."""
    original, plain = copy_of(base, tmp_path / "original"), copy_of(base, tmp_path / "plain")
    copy = tmp_path / "copy"
    copy.mkdir()
    linked_copy(original, copy, hard)
    before = snapshot(original)
    assert cli(capsys, "run", "--restart", str(plain), "--quiet", *RESTART)[0] == 0
    status, err = cli(capsys, "run", "--restart", str(copy), "--quiet", *RESTART)
    assert status == 0, err
    assert snapshot(original) == before
    for name in ("probes.csv", "solution.xdmf"):
        assert (copy / name).read_bytes() == (plain / name).read_bytes(), name
        assert not (copy / name).is_symlink() and (copy / name).stat().st_nlink == 1


def test_a_new_run_never_writes_through_a_link(base, tmp_path, capsys):
    """A folder whose every output name is a link to a file or folder outside it (probes.csv,
    summary.json's scratch name as a hard link, the XDMF file, the frames and checkpoint
    folders, the lock file): a new run writes its own files in their place and leaves every
    file outside as it was (before: it wrote its probes into the file probes.csv led to)."""
    outside = copy_of(base, tmp_path / "outside")
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "probes.csv").symlink_to(outside / "probes.csv")
    os.link(outside / "summary.json", folder / "summary.json.tmp")
    (folder / "solution.xdmf").symlink_to(outside / "solution.xdmf")
    (folder / "solution.frames").symlink_to(outside / "solution.frames")
    (folder / "checkpoint").symlink_to(outside / "checkpoint")
    (folder / ".cosserat-fem.lock").symlink_to(outside / "summary.json")
    before = snapshot(outside)
    status, err = cli(capsys, "run", SCENE, "--out", str(folder), "--quiet", *SHORT)
    assert status == 0, err
    assert snapshot(outside) == before
    assert not any(p.is_symlink() for p in folder.rglob("*"))
    assert (folder / "probes.csv").read_bytes() == (base / "probes.csv").read_bytes()


@pytest.mark.parametrize("name", ["checkpoint", "solution.frames"])
def test_a_restart_whose_folders_are_links_is_refused(base, tmp_path, capsys, name):
    """A restart whose checkpoint or frames folder is a link to a folder elsewhere would write
    there: refused in one line naming it, touching nothing on either side."""
    outside = copy_of(base, tmp_path / "outside")
    folder = copy_of(base, tmp_path / "run")
    shutil.rmtree(folder / name)
    (folder / name).symlink_to(outside / name)
    before, there = snapshot(folder), snapshot(outside)
    status, err = cli(capsys, "run", "--restart", str(folder), "--quiet", *RESTART)
    one_line(status, err, name, "link")
    assert snapshot(folder) == before and snapshot(outside) == there


# ------------------------------------------------------------------- item 12: special files
def within(seconds: float, fn):
    """``fn()``, failing the test if it takes more than ``seconds`` (conftest.fails_if_hung)."""
    with fails_if_hung(seconds):
        return fn()


RUN_NAMES = [
    "checkpoint/checkpoint.json",
    "checkpoint/state1.rank0.npz",
    "summary.json",
    "probes.csv",
    "solution.xdmf",
    "solution.frames/mesh.h5",
    "solution.frames/000004.h5",
    "solution.frames/000011.h5",
    "summary.json.tmp",
    "solution.xdmf-partial",
    "checkpoint/checkpoint.json.tmp",
    "checkpoint/state0.rank0.npz.tmp",
    ".cosserat-fem.lock",
]


@pytest.mark.parametrize("name", RUN_NAMES)
def test_a_fifo_in_a_run_folder_hangs_no_restart(base, tmp_path, capsys, name):
    """A FIFO in place of (or beside) a file of a run's folder: ``run --restart`` ends (before:
    blocked for ever in open() for 8 of these names), either refusing in one line naming the
    FIFO with every file as it was, or continuing to the bytes of a clean restart."""
    clean = copy_of(base, tmp_path / "clean")
    assert main(["run", "--restart", str(clean), "--quiet", *RESTART]) == 0
    folder = copy_of(base, tmp_path / "run")
    (folder / name).unlink(missing_ok=True)
    os.mkfifo(folder / name)
    before = snapshot(folder)
    status, err = within(
        HUNG, lambda: cli(capsys, "run", "--restart", str(folder), "--quiet", *RESTART)
    )
    if status == 0:
        assert (folder / "probes.csv").read_bytes() == (clean / "probes.csv").read_bytes()
    else:
        one_line(status, err, Path(name).name)
        assert snapshot(folder) == before


def test_fifos_at_every_output_name_hang_no_new_run(tmp_path, capsys):
    """A folder with a FIFO at every name a run writes (and their scratch names): a new run
    replaces them and completes (before: blocked opening probes.csv)."""
    folder = tmp_path / "run"
    (folder / "checkpoint").mkdir(parents=True)
    (folder / "solution.frames").mkdir()
    for name in RUN_NAMES:
        os.mkfifo(folder / name)
    status, err = within(
        HUNG, lambda: cli(capsys, "run", SCENE, "--out", str(folder), "--quiet", *SHORT)
    )
    assert status == 0, err
    assert not [p for p in folder.rglob("*") if not (p.is_file() or p.is_dir())]


def test_fifos_among_pod_outputs_hang_no_pod(base, tmp_path):
    """FIFOs where ``pod`` writes (pod.csv, pod.xdmf's scratch name, a frame of pod.frames)
    and a link to a file outside in pod.xdmf: pod ends (before: blocked for ever opening
    pod.csv) with its files written as new files, the file outside as it was."""
    folder = copy_of(base, tmp_path / "run")
    (folder / "pod.frames").mkdir()
    for name in ("pod.csv", "pod.xdmf-partial", "pod.frames/000000.h5"):
        os.mkfifo(folder / name)
    outside = tmp_path / "outside.txt"
    outside.write_text("mine\n")
    (folder / "pod.png").symlink_to(outside)
    proc = run_command(["-m", "cosserat_fem.cli", "pod", str(folder)], timeout=HUNG)
    assert proc.returncode == 0, proc.stderr
    assert all(
        (folder / name).is_file() and not (folder / name).is_symlink()
        for name in ("pod.csv", "pod.xdmf", "pod.png", "pod.frames/000000.h5")
    )
    assert outside.read_text() == "mine\n"


def sweep_file(folder: Path) -> Path:
    """A sweep of two members of the paper's scene, 0.6 ms each without XDMF."""
    path = folder / "sweep.toml"
    path.write_text(
        f'[sweep]\nscene = "{SCENE}"\n[sweep.set]\n"time.end" = 0.0006\n'
        '"output.xdmf" = false\n[sweep.vary]\n"time.step" = [2e-5, 3e-5]\n'
    )
    return path


@pytest.fixture(scope="module")
def swept(tmp_path_factory) -> tuple[Path, Path]:
    """A finished sweep's folder and its sweep file."""
    root = tmp_path_factory.mktemp("swept")
    out = root / "out"
    assert main(["sweep", str(sweep_file(root)), "--out", str(out), "--quiet"]) == 0
    return out, root / "sweep.toml"


@pytest.mark.parametrize(
    "name",
    [
        "sweep.json",
        "table/group-0.csv",
        ".sweep.csv.tmp",
        "members/m00001/final_state.npz",
        ".cosserat-fem.lock",
    ],
)
def test_a_fifo_in_a_sweep_folder_hangs_neither_sweep_nor_plot(swept, tmp_path, capsys, name):
    """A FIFO in a sweep's folder: started again, the sweep ends (before: blocked reading
    sweep.json or a table part), refusing in one line naming it or finishing with every member
    done; ``plot`` of the folder ends too."""
    out = Path(shutil.copytree(swept[0], tmp_path / "out"))
    (out / name).unlink(missing_ok=True)
    os.mkfifo(out / name)
    status, err = within(
        HUNG, lambda: cli(capsys, "sweep", str(swept[1]), "--out", str(out), "--quiet")
    )
    if status != 0:
        one_line(status, err, Path(name).name)
    status, err = within(HUNG, lambda: cli(capsys, "plot", str(out)))  # a sweep: no h5py
    assert status == 0 or len(err) == 1, err


# ------------------------------------------------------------------ item 14: sweep.json
def test_a_sweep_json_cut_by_a_full_disk_does_not_block_the_folder(tmp_path):
    """A sweep started under a file size limit of 100 bytes (as a full disk: its 300-byte
    sweep.json cannot be written) stops in one line and leaves no sweep.json (before: one cut
    at 100 bytes); the sweep started again without the limit runs both members (before: every
    later sweep there was an internal error)."""
    out = tmp_path / "out"
    path = sweep_file(tmp_path)
    command = [PYTHON, "-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out), "--quiet"]

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (100, resource.RLIM_INFINITY))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    cut = subprocess.run(
        command,
        cwd=ROOT,
        env=subprocess_env(),
        capture_output=True,
        text=True,
        timeout=HUNG,
        preexec_fn=limit,
    )
    assert cut.returncode != 0 and cut.stderr.count("\n") == 1, cut.stderr
    assert "internal error" not in cut.stderr and not (out / "sweep.json").exists()
    again = run_command(
        ["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out), "--quiet"], timeout=HUNG
    )
    assert again.returncode == 0, again.stderr
    assert [row["status"] for row in read_table(out / "sweep.csv")] == ["completed"] * 2


def test_a_damaged_sweep_json_is_refused_in_one_line(swept, tmp_path, capsys):
    """A sweep.json that is not JSON (cut, edited) or not an object: the sweep is refused in one
    line naming it, exit 2 (before: an internal error, and under mpirun a 10 s wait and
    MPI_ABORT)."""
    for text in ('{"fingerprint": "ab', "[1, 2]"):
        out = Path(shutil.copytree(swept[0], tmp_path / f"out{len(text)}"))
        (out / "sweep.json").write_text(text)
        status, err = cli(capsys, "sweep", str(swept[1]), "--out", str(out), "--quiet")
        one_line(status, err, "sweep.json")


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
