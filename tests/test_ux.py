"""What the command line shows: progress bar, logging levels, the end summary, validate."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from conftest import ROOT, run_command

from cosserat_fem.analysis.progress import ProgressBar

CLI = ["-m", "cosserat_fem.cli"]
SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
SHORT = ["--set", "time.end=0.003", "--set", "output.xdmf=false"]


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_on_a_terminal_only(monkeypatch):
    """The bar on a terminal, silent in a pipe. Its ETA is the rate measured from its first
    update on (item 22): a run whose set-up and first step (the JIT compile falls in it) took
    100 s of a 1 s-a-percent run showed, after 2 %, 101 s x 98/2 = 1:22:29 left; the rate
    since the first update gives 1 s a percent, 98 s. The first update has no rate yet: "?"."""
    now = [0.0]
    monkeypatch.setattr("cosserat_fem.analysis.progress.time.monotonic", lambda: now[0])
    term = FakeTerminal()
    bar = ProgressBar(0.0, 2.0, stream=term)
    for clock, t, steps in ((100.0, 0.02, 10), (101.0, 0.04, 20), (102.0, 2.0, 1000)):
        now[0] = clock
        bar(t, steps, 4 * steps)
    bar.close()
    frames = term.getvalue().split("\r")
    assert "  1.0%" in frames[1] and "10 steps" in frames[1] and "4.00 it/step" in frames[1]
    assert "elapsed 1:40  ETA ?" in frames[1]
    assert "  2.0%" in frames[2] and "ETA 1:38" in frames[2]
    assert "100.0%" in frames[3] and "ETA  0.0 s" in frames[3]
    assert frames[-1] == ""  # the line is cleared at the end
    pipe = io.StringIO()  # not a terminal: silent
    quiet = ProgressBar(0.0, 2.0, stream=pipe)
    quiet(1.0, 5, 5)
    quiet.close()
    assert pipe.getvalue() == ""


def test_continuation_status_line(monkeypatch):
    """A continuation's line (issue 27 item 5): the points over max_points as the fraction
    (50 of 200: 25.0 %), the branches done, the point and its load factor; silent off a
    terminal."""
    from cosserat_fem.analysis.progress import ContinuationProgress

    now = [0.0]
    monkeypatch.setattr("cosserat_fem.analysis.progress.time.monotonic", lambda: now[0])
    term = FakeTerminal()
    bar = ContinuationProgress(200, stream=term)
    bar(1, 50, 0.75)
    bar.close()
    frames = term.getvalue().split("\r")
    assert " 25.0%" in frames[1] and "1 branches done, point 50, load factor 0.75" in frames[1]
    pipe = io.StringIO()
    quiet = ContinuationProgress(200, stream=pipe)
    quiet(0, 2, 0.1)
    assert pipe.getvalue() == ""


@pytest.mark.parametrize("ranks", [1, pytest.param(2, marks=[pytest.mark.mpi, pytest.mark.long])])
def test_run_prints_one_summary(tmp_path, ranks):
    proc = run_command([*CLI, "run", SCENE, "--out", str(tmp_path), *SHORT], ranks)
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr  # no progress bar in a pipe
    lines = proc.stdout.strip().splitlines()
    assert lines[0].startswith("cosserat-fem: completed: t = 0.003 s in 100 output steps")
    assert sum(line.startswith("cosserat-fem:") for line in lines) == 1  # rank 0 only
    assert any(line.strip().startswith("Newton:") for line in lines)
    assert f"{ranks} MPI rank(s)" in proc.stdout


def test_quiet_and_verbose(tmp_path):
    quiet = run_command([*CLI, "run", SCENE, "--out", str(tmp_path / "q"), *SHORT, "--quiet"])
    assert quiet.returncode == 0 and quiet.stdout == "" and quiet.stderr == ""
    verbose = run_command([*CLI, "run", SCENE, "--out", str(tmp_path / "v"), *SHORT, "--verbose"])
    assert verbose.returncode == 0
    # checkpoints every 0.3 ms ("auto": a tenth of the run), logged at --verbose
    assert verbose.stderr.count("cosserat-fem: checkpoint ") == 10


def test_validate_prints_the_resolved_scene_with_units():
    proc = run_command([*CLI, "validate", SCENE, "--set", "time.step=1e-5"])
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "rod.material.young_modulus = 7.1e+10 [Pa]" in out
    assert "time.step = 1e-05 [s]" in out and "6000 steps of 1e-05 s" in out
    assert "omega0 = 207.0236 rad/s" in out and "300 dofs" in out
    assert "discretisation.quadrature_degree = 6" in out  # "auto" resolved
    bad = run_command([*CLI, "validate", SCENE, "--set", "time.stepp=1"])
    assert bad.returncode == 2 and "did you mean 'time.step'" in bad.stderr
    assert "Traceback" not in bad.stderr


def test_help_lists_the_commands():
    proc = run_command([*CLI, "--help"])
    assert proc.returncode == 0
    for command in ("run", "static", "modes", "validate"):
        assert command in proc.stdout


@pytest.mark.parametrize("document", ["README.md", "docs", "scenes"])
def test_the_documented_commands_write_into_folders_of_their_own(document):
    """The README's serial and ``mpirun`` sweeps shared one --out, so the second skipped every
    member ("ran 0"), and so did the two in scenes/sweeps/paper_forcing.toml's comment; the
    README's run without --out and its modes of the same scene shared the scene's
    output.directory. Every command of a document (the README, each of docs/*.md, each
    scene file's comments) that writes (run, static, modes, sweep; the same command twice is
    one) now has a folder of its own, as the command line resolves it (cosserat_fem/cli.py:
    --out, or the command's default)."""
    import re
    import shlex

    from cosserat_fem import api
    from cosserat_fem.cli import _out, _parser

    root = ROOT / document
    paths = [root] if root.is_file() else sorted([*root.rglob("*.md"), *root.rglob("*.toml")])
    found = 0
    for path in paths:
        text = path.read_text(encoding="utf-8")
        lines = re.findall(r"^#? {4,}(.*cosserat-fem (?:run|static|modes|sweep) .*)$", text, re.M)
        folders: dict[str, str] = {}
        for line in sorted(set(lines)):
            words = shlex.split(re.sub(r"\[(--[^]]*)\]", r"\1", line), comments=True)
            start = next(i for i, w in enumerate(words) if w.endswith("cosserat-fem")) + 1
            args = _parser().parse_args(words[start:])
            if getattr(args, "restart", None):
                continue  # continues the folder of its run
            scene = None if args.command == "sweep" else api.load(ROOT / args.scene, args.overrides)
            folder = str(Path(_out(args, scene)))
            assert folder not in folders, (str(path), line, folders.get(folder))
            folders[folder] = line
        found += len(folders)
    assert found >= {"README.md": 10, "docs": 1, "scenes": 2}[document]
