"""The command line: outputs of a run, bad input, numerical trouble."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from conftest import ROOT, run_command

SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
CLI = ["-m", "cosserat_fem.cli"]


def cli(*args: str, ranks: int = 1):
    return run_command([*CLI, *args], ranks)


def run_scene(out, *overrides: str, ranks: int = 1):
    """``cosserat-fem run`` on the paper's scene with ``--set`` overrides, at Δt = 10 μs (the
    step the times and row counts below are written for; a test's own overrides win)."""
    sets = [arg for item in ("time.step=1e-5", *overrides) for arg in ("--set", item)]
    return cli("run", SCENE, "--out", str(out), *sets, ranks=ranks)


def test_run_writes_probes_summary_and_xdmf(tmp_path):
    out = tmp_path / "run"
    proc = run_scene(out, "time.end=0.002", "output.xdmf_interval=5e-4")
    assert proc.returncode == 0, proc.stderr
    lines = (out / "probes.csv").read_text().splitlines()
    assert lines[0] == "t,x,y,z,theta,psi,phi"
    data = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    assert data.shape == (201, 7)  # the initial state and 200 steps
    assert np.allclose(data[:, 0], np.linspace(0.0, 0.002, 201), rtol=0, atol=1e-15)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["steps"] == 200 and summary["time_reached_s"] == pytest.approx(0.002)
    disc = summary["scene"]["discretisation"]
    assert summary["dofs"] == 12 * (disc["elements"] * disc["degree"] + 1)
    assert summary["newton"]["iterations"] >= 200
    assert summary["wall_time_s"]["solve_loop"] > 0
    assert summary["scene"]["time"]["end"] == 0.002
    tree = ET.parse(out / "solution.xdmf")
    steps = tree.getroot().findall(".//Grid[@GridType='Collection']/Grid")
    times = sorted({float(g.find("Time").get("Value")) for g in steps})
    assert times == pytest.approx([0.0, 5e-4, 1e-3, 1.5e-3, 2e-3])
    names = {a.get("Name") for a in tree.getroot().iter("Attribute")}
    # the paper's scene asks for output.fields = displacement and angles only
    assert names == {"displacement", "angles"}
    frames = sorted(p.name for p in (out / "solution.frames").iterdir())
    assert frames == ["000000.h5", "000001.h5", "000002.h5", "000003.h5", "000004.h5", "mesh.h5"]
    assert all((out / "solution.frames" / name).stat().st_size > 0 for name in frames)


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--set", "time.stepp=1e-5"], "time.stepp: unknown key"),
        (["--set", "rod.length=-1"], "rod.length:"),
        (["--set", "rod.material.poisson_ratio=nan"], "rod.material.poisson_ratio:"),
        (["--set", 'loads.force_density=[0, "sin(", 0]'], "loads.force_density[1]:"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, fragment):
    proc = cli("run", SCENE, "--out", str(tmp_path / "x"), *args)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and fragment in err[0], proc.stderr


def test_missing_scene_file(tmp_path):
    proc = cli("run", str(tmp_path / "nope.toml"))
    assert proc.returncode == 2 and "not found" in proc.stderr and "Traceback" not in proc.stderr


def test_unwritable_output_folder(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    proc = run_scene(blocker / "sub", "time.end=1e-4")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "output.directory" in proc.stderr


def test_newton_failure_is_reported_with_time_and_place(tmp_path):
    """One Newton iteration, unreachable tolerances and a 1 MN tip force (a strongly nonlinear
    first step, so that the error estimate of the one iterate is far above xatol): the first
    step fails, and with time.max_halvings = 0 it is not retried."""
    out = tmp_path / "fail"
    proc = run_scene(
        out,
        "loads.end.force=[1e6,0,0]",
        "time.max_halvings=0",
        "solver.max_iterations=1",
        "solver.rtol=1e-30",
        "solver.atol=1e-30",
        "solver.stol=1e-30",
        "time.end=1e-4",
    )
    assert proc.returncode == 3, proc.stderr
    assert "t = 1e-05 s" in proc.stderr and "s = " in proc.stderr and "Newton" in proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 0
    assert (out / "probes.csv").read_text().splitlines() == [
        "t,x,y,z,theta,psi,phi",
        ",".join(["0.0000000000e+00"] + ["0.0000000000000000e+00"] * 6),
    ]


def test_a_whip_in_3d_turns_through_the_euler_angle_singularity(tmp_path):
    """A tip torque 2e5 N m about e1 spins the free end through θ = π/2, where det Ma = cos θ
    vanishes, when the rod is solved in 3D: the chart moves onto the rod (3 times in 2 ms,
    cosserat_fem/rod/charts.py) and the run completes; probes.csv's angles, measured from the
    fixed basis and continued, pass π/2 and reach 3.2 rad (tests/test_rotations.py holds
    the motion against the y-z plane's)."""
    out = tmp_path / "chart"
    proc = run_scene(
        out,
        "loads.force_density=[0,0,0]",
        "loads.end.torque=[2e5,0,0]",
        "discretisation.planar='off'",
        "time.end=0.002",
        "output.xdmf=false",
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "summary.json").read_text())["chart_resets"] == 3
    data = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    assert 3.1 < data[:, 4].max() < 3.3 and np.isfinite(data).all()


def test_errors_under_mpi_are_reported_once(tmp_path):
    proc = run_scene(tmp_path / "x", "rod.length=0", ranks=2)
    assert proc.returncode == 2
    assert proc.stderr.count("cosserat-fem: error: rod.length:") == 1, proc.stderr


SWEEP = str(ROOT / "scenes" / "sweeps" / "paper_forcing.toml")
#: Every command that writes, with the arguments that make it write (a RUN_DIR's command's
#: --out is checked before the folder is read: the folder given need hold nothing).
WRITERS = {
    "run": [SCENE, "--set", "time.end=0.0003"],
    "static": [SCENE],
    "modes": [SCENE, "--count", "2"],
    "validate": [SCENE],
    "sweep": [SWEEP],
    "plot": ["."],
    "render": ["."],
    "pod": ["."],
}


@pytest.mark.parametrize("command", list(WRITERS))
@pytest.mark.parametrize("out", ["", SCENE])
def test_an_empty_or_file_out_is_refused_by_name(tmp_path, monkeypatch, capsys, command, out):
    """``--out ''`` was taken as no --out: run, static and modes wrote into the scene's
    output.directory, sweep into results/<name>, plot and render into the current folder, pod
    into the run's. Given as an existing file, the error named output.directory. Each
    command now refuses both in one line naming --out (exit 2), and nothing is written (the
    current folder, where every default lies here, stays empty)."""
    from cosserat_fem.cli import main

    monkeypatch.chdir(tmp_path)
    status = main([command, *WRITERS[command], "--out", out, "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, err
    assert "--out" in err[0] and ("must name a folder" in err[0] or "is not a folder" in err[0])
    assert list(tmp_path.iterdir()) == []


def test_static_and_modes_without_out_leave_a_runs_folder_alone(tmp_path, monkeypatch, capsys):
    """Without --out a run, a static solve and the modes of one scene all went into its
    output.directory: the static solve claimed the folder (the run's checkpoint removed, its
    probes.csv and summary.json replaced) and the modes' files lay among the run's. Now
    static and modes write into static/ and modes/ beneath it: the run's files are as it
    left them and it continues from its checkpoint."""
    from cosserat_fem.cli import main

    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "results" / "cao_tucker_2008"  # the scene's output.directory
    assert main(["run", SCENE, "--set", "time.end=0.0003", "--quiet"]) == 0
    before = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    assert main(["modes", SCENE, "--count", "2", "--quiet"]) == 0
    assert main(["static", SCENE, "--quiet"]) == 0
    assert {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()} == before
    assert (folder / "modes" / "modes.csv").is_file()
    assert (folder / "static" / "probes.csv").is_file()
    capsys.readouterr()
    assert main(["run", "--restart", str(folder), "--set", "time.end=0.0006", "--quiet"]) == 0


def _sweep_file(folder) -> str:
    """A sweep of two members of 10 steps of the paper's scene."""
    path = folder / "tiny.toml"
    path.write_text(
        f'[sweep]\nscene = "{SCENE}"\n[sweep.set]\n"time.end" = 0.0003\n'
        '"output.xdmf" = false\n[sweep.vary]\n"time.max_halvings" = [5, 6]\n',
        encoding="utf-8",
    )
    return str(path)


#: The commands that print on stdout (``--quiet`` aside), as run with the test's folder.
PRINTERS = {
    "help": lambda tmp: ["--help"],
    "validate": lambda tmp: ["validate", SCENE],
    "modes": lambda tmp: ["modes", SCENE, "--count", "2", "--out", str(tmp / "modes")],
    "run": lambda tmp: [
        "run",
        SCENE,
        "--set",
        "time.end=0.0003",
        "--set",
        "output.xdmf_interval=6e-5",
        "--out",
        str(tmp / "run"),
    ],
    "run --verbose": lambda tmp: [
        "run",
        SCENE,
        "--set",
        "time.end=0.0003",
        "--verbose",
        "--out",
        str(tmp / "verbose"),
    ],
    "static": lambda tmp: ["static", SCENE, "--out", str(tmp / "static")],
    "sweep": lambda tmp: ["sweep", _sweep_file(tmp), "--out", str(tmp / "sweep")],
    "pod": lambda tmp: ["pod", str(tmp / "run"), "--out", str(tmp / "pod")],
    "plot": lambda tmp: ["plot", str(tmp / "run"), "--out", str(tmp / "plot")],
}
#: Run in the normal set: a command of Python alone and one that starts PETSc (its own
#: SIGPIPE handler dumped "Caught signal number 13 Broken Pipe" and exited 59).
QUICK = ("help", "validate", "modes")


def _closed_early(args: list[str], stream: str = "stdout") -> tuple[int, str]:
    """Run the command line with a ``stream`` (stdout or stderr) whose reader is gone before
    the command starts; its status and what it wrote on the other stream."""
    import subprocess

    from conftest import PYTHON, subprocess_env

    proc = subprocess.Popen(
        [PYTHON, *CLI, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=ROOT,
        env=subprocess_env(),
    )
    closed, other = (proc.stdout, proc.stderr) if stream == "stdout" else (proc.stderr, proc.stdout)
    closed.close()  # the reader has gone (as `| head -0` would)
    text = other.read().decode()
    return proc.wait(timeout=600), text


@pytest.mark.parametrize(
    "command",
    [c if c in QUICK else pytest.param(c, marks=pytest.mark.long) for c in PRINTERS],
)
def test_a_closed_stdout_ends_the_command_quietly(tmp_path, command):
    """``cosserat-fem modes ... | head -2`` gave PETSc's "Broken Pipe" dump and exit 59;
    validate (no PETSc) "internal error: BrokenPipeError", exit 1. Every command that prints
    now ends quietly with status 0 when its stdout's reader has gone (the files are written
    by then: only the report is cut), nothing on stderr; a verbose run whose stderr's reader
    has gone (its checkpoint lines; PETSc's dump and exit 59 too) ends 0 as well (a sweep's
    progress lines on stderr are its own). A real
    pipe, closed before the command prints; the limit of 600 s means hung (each takes a few
    seconds)."""
    if command in ("pod", "plot"):  # a run to read
        assert _closed_early(PRINTERS["run"](tmp_path))[0] == 0
    stream = "stderr" if command == "run --verbose" else "stdout"
    status, text = _closed_early(PRINTERS[command](tmp_path), stream)
    # a sweep tells each member as it finishes on stderr (its progress, not an error)
    said = [line for line in text.splitlines() if not line.startswith("cosserat-fem: sweep member")]
    assert status == 0 and (stream == "stderr" or not said), text
    if command == "run":
        assert json.loads((tmp_path / "run" / "summary.json").read_text())["status"] == "completed"


def test_static_with_probe_fields_prints_the_probe(tmp_path, monkeypatch, capsys):
    """`static` with output.probe_fields printed the six probe values by zipping them against
    every probe column (strict): an internal error, exit 1, after the outputs were written.
    Now it prints the six and exits 0; probes.csv keeps the fields' columns too."""
    from cosserat_fem.cli import main

    monkeypatch.chdir(tmp_path)
    status = main(
        ["static", SCENE, "--set", 'output.probe_fields=["directors"]', "--out", "static"]
    )
    out = capsys.readouterr()
    assert status == 0, out.err
    assert "probe: " in out.out + out.err
    header = (tmp_path / "static" / "probes.csv").read_text().splitlines()[0]
    assert "d3" in header or "director" in header, header
