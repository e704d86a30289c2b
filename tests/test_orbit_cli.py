"""The command line of periodic orbits and chaos (issue 27 item 5): ``cosserat-fem orbits``
(one orbit, or a branch with its files, progress and restarts) and ``cosserat-fem lyapunov``
(cosserat_fem/analysis/orbit_runs.py), and ``cosserat-fem plot`` of their folders.

The orbit scene is tests/test_periodic.py's clamped–clamped rod (ℓ = 1 m) driven by
F sin(πs/ℓ) sin(r ω1 t) on 4 cells at N = 20 SDIRK3 steps a period: a thousandth of the
demo's load (linear, amplitude ~9 μm) from r = 1.03 to 1.07, four steps of ~0.3 s; the long
test traces the demo's load through its two folds (N = 40). The Lyapunov scene is
tests/test_chaos.py's linear rod.

**Tolerances.** The command and the API run the same algorithm (trace_orbits) from the
same rest state; what may differ is bounded by the engine's corrector tolerance 1e-9 in
the metric √(w ‖Δu‖² + Δp²) (``cf.periodic_branch``'s settings): |Δp| ≤ 1e-9, and, as w
makes the first orbit's weighted norm 4 a/ℓ (a its amplitude, ``scale`` = 4), a weighted
Δu of 1e-9 is a relative change of the orbit of 1e-9 / (4 a/ℓ) = 2.8e-5 at a = 9 μm; the
amplitude is compared to that. A restart rebuilds the engine's state from the saved last
points: the next step from the pseudo-arclength constraint ⟨t, x − x_prev⟩ = s, which the
corrector met to 1e-9 (orbit_runs.py ``_step``), so the continued points are the whole
branch's to the same bounds.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_command

import cosserat_fem as cf
from cosserat_fem import api

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
PERIOD = "2*pi/(r*w1)"
#: tests/test_periodic.py's scene at a thousandth of the demo's load, on 4 cells.
LINEAR = {
    "supports.end": "clamped",
    "output.checkpoint": False,
    "damping.translational": 170.74,
    "loads.force_density": ["F*sin(pi*s/L)*sin(r*w1*t)", 0, 0],
    "parameters.F": 5.9158,
    "parameters.w1": 1302.92,
    "parameters.r": 1.03,
    "discretisation.elements": 4,
}
#: LINEAR marched by 20 fixed steps a forcing period T = 2π/(1.03 ω1), over 3 periods.
MARCHED = {
    **LINEAR,
    "time.step": 2 * math.pi / (1.03 * 1302.92) / 20,
    "time.end": 3 * 2 * math.pi / (1.03 * 1302.92),
    "output.xdmf_interval": 0,
}
BRANCH = ["--period", PERIOD, "--parameter", "r", "--from", "1.03", "--to", "1.07"]
STEPS = ["--steps-per-period", "20", "--step", "0.01", "--max-step", "0.02"]
#: |Δp| and the amplitude's relative difference the corrector's tolerance allows (module
#: docstring).
DP, DA = 1e-9, 2.8e-5


def sets(overrides: dict) -> list[str]:
    return [a for k, v in overrides.items() for a in ("--set", f"{k}={json.dumps(v)}")]


def api_branch() -> tuple[tuple, dict]:
    """The arguments and options of the API's call for :data:`BRANCH` and :data:`STEPS`."""
    scene = cf.load(PAPER, LINEAR)
    return (scene, PERIOD, "r", 1.03, 1.07), {
        "steps_per_period": 20,
        "step": 0.01,
        "max_step": 0.02,
    }


def cli(*args: str):
    return run_command(["-m", "cosserat_fem.cli", *args])


@pytest.fixture(scope="module")
def whole_branch(tmp_path_factory) -> Path:
    """The folder of the uninterrupted ``orbits`` branch over :data:`BRANCH` with
    :data:`STEPS` of :data:`LINEAR`: the reference of the cut and restarted branches (one
    run for the module's tests, which only read it; a run of the command is ~1 s)."""
    whole = tmp_path_factory.mktemp("orbits") / "whole"
    proc = cli("orbits", str(PAPER), *sets(LINEAR), *BRANCH, *STEPS, "--out", str(whole))
    assert proc.returncode == 0, proc.stderr
    return whole


def rows(path) -> list[dict]:
    lines = path.read_text().splitlines()
    return [dict(zip(lines[0].split(","), ln.split(","), strict=True)) for ln in lines[1:]]


def refused(proc, message: str, out) -> None:
    """``proc`` refused as bad input: exit 2, one line on stderr holding ``message``, no
    traceback, and its --out folder ``out`` not made."""
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert message in line and "Traceback" not in proc.stderr
    assert not out.exists()


def same_rows(folder, reference) -> list[dict]:
    """orbit_branch.csv's rows in ``folder``, asserted to be those of ``reference`` to the
    module docstring's bounds (p within DP, the amplitude within DA relative, |μ| within
    1e-8: the monodromy of this linear case depends on p alone), the same kinds."""
    expected, got = rows(reference / "orbit_branch.csv"), rows(folder / "orbit_branch.csv")
    assert len(got) == len(expected)
    for a, b in zip(got, expected, strict=True):
        assert abs(float(a["parameter"]) - float(b["parameter"])) <= DP
        assert float(a["amplitude"]) == pytest.approx(float(b["amplitude"]), rel=DA)
        assert abs(float(a["mu_abs"]) - float(b["mu_abs"])) <= 1e-8
        assert a["point"] == b["point"]
    return got


def test_a_branch_stops_at_its_wall_time_and_restarts_to_the_whole_branch(tmp_path, whole_branch):
    """About 3 s (a process per part: here 3 parts). limits.wall_time = 2 ms: above the
    budget's lower bound of the one period the command checks up front (budget.py: 0.76 ms
    for 20 steps of this 4-element rod), far below what the branch costs by the same bound
    (its 17 monodromies each time-march a period at least: 13 ms, and the shooting's set-up
    comes on top), so no machine traces it within the limit. Each part ends at the first
    point after its limit (exit 4, the reason on stderr and in summary.json beginning with
    orbit_runs.WALL_TIME_STOP) with its rows written, and ``orbits --restart`` continues it
    (each part given the limit again) until the branch reaches its range's end (exit 0)
    with the uninterrupted branch's rows (:func:`same_rows`)."""
    from cosserat_fem.analysis.orbit_runs import WALL_TIME_STOP

    whole, cut = whole_branch, tmp_path / "cut"
    base = ["orbits", str(PAPER), *BRANCH, *STEPS]
    limited = sets({**LINEAR, "limits.wall_time": 2e-3})
    proc = cli(*base, *limited, "--out", str(cut))
    parts = 1
    while proc.returncode == 4:
        summary = json.loads((cut / "summary.json").read_text())
        assert summary["reason"].startswith(WALL_TIME_STOP), summary["reason"]
        assert WALL_TIME_STOP in proc.stderr
        assert 1 <= len(rows(cut / "orbit_branch.csv")) < len(rows(whole / "orbit_branch.csv"))
        assert parts <= len(rows(whole / "orbit_branch.csv"))  # a point at least a part
        proc = cli("orbits", "--restart", str(cut), "--max-points", "300")
        parts += 1
    assert proc.returncode == 0, proc.stderr
    assert parts >= 2  # it did stop
    same_rows(cut, whole)


def test_the_orbits_command_gives_the_api_s_branch_with_its_files(tmp_path):
    """``orbits`` over r in [1.03, 1.07] against ``cf.periodic_branch`` with the same
    settings: as many points, each p within DP and amplitude within DA relative (module
    docstring), the same stability and kind, |μ| within 1e-8 (at this load the monodromy
    depends on p alone, the stretching terms (a/ℓ)² ~ 1e-10: |dμ/dp| Δp ≪ 1e-8);
    summary.json's reason, steps and monodromies the API's (integers of the same
    algorithm); orbit_branch.xdmf opens (tests/xdmf_files.py) with one frame per point,
    times 0, 1, ..., and the orbits' mid-span states differing from frame to frame; the
    command line's last line names the reason; ``plot`` draws orbit_branch.png."""
    from xdmf_files import read_arrays

    out = tmp_path / "cli"
    proc = cli("orbits", str(PAPER), *sets(LINEAR), *BRANCH, *STEPS, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "p reached 1.07" in proc.stdout
    arguments, options = api_branch()
    branch = api.periodic_branch(*arguments, **options)
    got = rows(out / "orbit_branch.csv")
    assert (
        len(got) == len(branch.points) + len(branch.special) >= 4
    )  # the start, two steps, the point at the bound
    for row, q in zip(got, branch.points, strict=False):
        assert abs(float(row["parameter"]) - q.parameter) <= DP
        assert float(row["amplitude"]) == pytest.approx(q.amplitude, rel=DA)
        assert abs(float(row["mu_abs"]) - abs(q.multipliers[0])) <= 1e-8
        assert (row["stability"], row["point"]) == (q.stability, q.kind)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == branch.reason == "p reached 1.07"
    assert (summary["steps"], summary["monodromies"]) == (branch.steps, branch.monodromies)
    assert summary["folds"] == [] and summary["points"] == len(branch.points)
    _, times, arrays = read_arrays(out / "orbit_branch.xdmf")
    assert list(times) == list(range(len(branch.points)))
    middle = arrays["displacement"][:, arrays["displacement"].shape[1] // 2, 0]
    assert np.all(np.isfinite(middle)) and np.all(np.abs(np.diff(middle)) > 0.0)
    plot = cli("plot", str(out))
    assert plot.returncode == 0, plot.stderr
    assert (out / "orbit_branch.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_restarted_branch_reaches_the_whole_branch_s_points(tmp_path, whole_branch):
    """A branch stopped at --max-points 2 (the start and one step: the step not yet at
    max_step, so the restart must rebuild the grown one) and restarted with --max-points 300
    has the rows of the uninterrupted branch (p within DP, amplitude within DA relative:
    module docstring; the kinds the same), orbit_branch.xdmf one frame per row, times 0, 1,
    ..., across the restart (also when, as after a kill between a frame and the restart
    record that counts it, the XML holds a frame more than the record: the restart cuts it
    back, and frame i is in its file i; before, the extra frame stayed, its file written
    over), and summary.json the same steps and monodromies in all (the
    restarted part's added to the first's) and restarts = 1. A restart of a branch that
    reached its range's end is refused in one line (exit 2), and so is ``continue
    --restart`` of the folder (no static continuation's record there), and, before, a
    restart of the cut branch without --max-points or with --max-points 2 (no point to add;
    before this was checked it ran, changed nothing but summary.json's restarts, exit 0)."""
    from xdmf_files import read_arrays, read_xdmf

    whole, cut = whole_branch, tmp_path / "cut"
    base = ["orbits", str(PAPER), *sets(LINEAR), *BRANCH, *STEPS]
    first = cli(*base, "--max-points", "2", "--out", str(cut))
    assert first.returncode == 0, first.stderr
    assert "the branch ended: 2 points (max_points)" in first.stderr
    assert len(rows(cut / "orbit_branch.csv")) == 2
    table = (cut / "orbit_branch.csv").read_bytes()
    for more in ([], ["--max-points", "2"]):  # no point to add: refused, the files kept
        idle = cli("orbits", "--restart", str(cut), *more)
        assert idle.returncode == 2 and len(idle.stderr.strip().splitlines()) == 1
        assert "--max-points: the orbit branch in " in idle.stderr and "has 2 points" in idle.stderr
        assert (cut / "orbit_branch.csv").read_bytes() == table
    # a kill after a third frame was written and before the record counted it: the XML and
    # frame file of a branch cut at 3 points (its first two frames are these two's)
    three = tmp_path / "three"
    assert cli(*base, "--max-points", "3", "--out", str(three)).returncode == 0
    shutil.copy(three / "orbit_branch.xdmf", cut / "orbit_branch.xdmf")
    frame = Path("orbit_branch.frames") / "000002.h5"
    shutil.copy(three / frame, cut / frame)
    assert len(read_xdmf(cut / "orbit_branch.xdmf")["displacement"][0]) == 3
    again = cli("orbits", "--restart", str(cut), "--max-points", "300")
    assert again.returncode == 0, again.stderr
    got = same_rows(cut, whole)
    _, times, _ = read_arrays(cut / "orbit_branch.xdmf")
    assert list(times) == list(range(len(got)))
    times, values = read_xdmf(cut / "orbit_branch.xdmf")["displacement"]  # frame i in file i
    assert list(times) == list(range(len(got)))
    s_whole = json.loads((whole / "summary.json").read_text())
    s_cut = json.loads((cut / "summary.json").read_text())
    for key in ("steps", "monodromies", "points", "reason"):
        assert s_cut[key] == s_whole[key], key
    assert s_cut["restarts"] == 1
    other = cli("continue", "--restart", str(cut))  # not a static continuation's folder
    assert other.returncode == 2 and "holds no continuation to restart" in other.stderr
    done = cli("orbits", "--restart", str(cut))
    assert done.returncode == 2 and "--restart:" in done.stderr and "already ended" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_the_branch_file_s_bytes_are_written_once_each(tmp_path, monkeypatch):
    """orbit_branch.csv of :func:`api_branch`'s branch, cut at max_points 2 and restarted to
    its end through ``cf.orbits``: the bytes written to it (every replace_on_root and
    append_on_root of orbit_runs.py counted) are the file's size after each part, its rows
    appended (before: the file rewritten whole after each point, Σ of its sizes: 1642
    bytes for the 605 of the whole branch's 4 rows, quadratic in the rows); a restart writes
    its kept rows once (cut to its record) and appends the rest. Its rows are the
    uninterrupted branch's (:func:`same_rows`)."""
    from cosserat_fem.analysis import orbit_runs

    written: list[int] = []
    for name in ("replace_on_root", "append_on_root"):
        original = getattr(orbit_runs, name, None)
        if original is None:
            continue

        def spy(path, data, *args, original=original, **kwargs):
            if Path(path).name == "orbit_branch.csv":
                written.append(len(data))
            return original(path, data, *args, **kwargs)

        monkeypatch.setattr(orbit_runs, name, spy)
    (scene, *rest), options = api_branch()
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    cf.orbits(scene, *rest, out=whole, **options)
    assert sum(written) == (whole / "orbit_branch.csv").stat().st_size
    written.clear()
    cf.orbits(scene, *rest, out=cut, max_points=2, **options)
    assert sum(written) == (cut / "orbit_branch.csv").stat().st_size
    assert len(rows(cut / "orbit_branch.csv")) == 2
    written.clear()
    cf.orbits(None, restart=cut, max_points=300)
    assert sum(written) == (cut / "orbit_branch.csv").stat().st_size
    same_rows(cut, whole)


def test_the_progress_is_told_each_orbit(tmp_path):
    """``cf.orbits``' progress(points, p, amplitude) is called once per point of the branch,
    in order (as it grows: the start and each accepted point; at its end the step beyond
    the range and the engine's point at its end, which the engine adds together), with the
    count of points so far and that point's p and amplitude."""
    calls = []
    arguments, options = api_branch()
    branch, summary = api.orbits(
        *arguments, **options, out=tmp_path, progress=lambda *a: calls.append(a)
    )
    assert [c[0] for c in calls] == list(range(1, len(branch.points) + 1))
    for (_, p, a), q in zip(calls, branch.points, strict=True):
        assert (p, a) == (q.parameter, q.amplitude)
    assert summary["points"] == len(branch.points)


def test_one_orbit_and_its_multipliers(tmp_path):
    """``orbits SCENE --period EXPR`` without a range: the orbit of ``cf.periodic_orbit``
    (the same shooting; Newton stops at an update below 1e-9 (1 + ‖U‖), ‖U‖ ~ 1e-5 in the
    solver's units at this amplitude, so the orbits may differ by 1e-9 in U, 1e-4 of the
    orbit: the amplitude within 1e-4 relative) and its multipliers in summary.json (|μ| of
    the first within 1e-9: a linear orbit's monodromy does not depend on the orbit)."""
    scene = cf.load(PAPER, {**LINEAR, "parameters.r": 1.07})
    orbit = api.periodic_orbit(scene, PERIOD, steps_per_period=20)
    proc = cli(
        "orbits",
        str(PAPER),
        *sets({**LINEAR, "parameters.r": 1.07}),
        "--period",
        PERIOD,
        "--steps-per-period",
        "20",
        "--out",
        str(tmp_path),
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["amplitude"] == pytest.approx(orbit.amplitude, rel=1e-4)
    assert summary["stability"] == orbit.stability == "stable"
    assert abs(math.hypot(*summary["multipliers"][0]) - abs(orbit.multipliers[0])) <= 1e-9
    assert "|mu|" in proc.stdout and proc.stderr == ""


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--parameter", "r", "--from", "1", "--to", "1.1"], "period (--period): give"),
        ([*BRANCH[:6], "--to", "1.03"], "end (--to): must differ from start (--from)"),
        (
            ["--period", PERIOD, "--parameter", "nope", "--from", "1", "--to", "1.1"],
            "(--parameter): 'nope' is not one of the scene's parameters",
        ),
        (["--period", PERIOD, "--from", "1"], "orbits --parameter: give"),
        (
            ["--period", "-1", "--parameter", "r", "--from", "1", "--to", "1.1"],
            "(--period): '-1' = -1.0 s; must be a positive time",
        ),
        ([*BRANCH, "--set", 'time.integrator="bdf2"'], "time.integrator: periodic orbits"),
        ([*BRANCH, "--step", "0.5"], "step (--step): must not exceed max_step"),
        (
            ["--period", "2.02*pi/(r*w1)", "--parameter", "r", "--from", "1", "--to", "1.1"],
            "loads.force_density: 'F*sin(pi*s/L)*sin(r*w1*t)' is not periodic with --period",
        ),
        (["--period", "2.02*pi/(r*w1)"], "is not periodic with --period"),
        (
            [*BRANCH, "--steps-per-period", "0"],
            "steps_per_period (--steps-per-period): must be a whole number >= 1, got 0",
        ),
        (["--period", PERIOD, "--settle", "-1"], "settle (--settle): must be a whole number"),
        ([*BRANCH, "--max-points", "1000000"], "max_points (--max-points): must lie in [2, 1"),
        (  # 1e9 steps a period: hours by the budget's lower bound, over limits.wall_time
            [*BRANCH, "--steps-per-period", "1000000000", "--set", "limits.wall_time=2"],
            "--settle, --steps-per-period: time.step: the run needs",
        ),
        (["--period", PERIOD, "--settle", "1000000000"], "--settle, --steps-per-period: "),
        (["--period", PERIOD, "--steps-per-period", "0"], "(--steps-per-period): must be"),
        (  # 2000 cubic cells: 36006 unknowns, 58 GiB of dense columns (periodic.py's bound 2)
            [*BRANCH, "--set", "discretisation.elements=2000"],
            "discretisation.elements: the monodromy matrix of 36006 dofs needs 58.0 GiB",
        ),
    ],
)
def test_bad_orbit_requests_are_one_line(tmp_path, arguments, message):
    """Each bad request: exit 2, one line on stderr naming the flag or key, no traceback,
    and no --out folder made (the request is checked before it). A shooting beyond the
    scene's limits.wall_time by budget.py's lower bound of its settle + 1 periods is one
    (before, it ran until killed: orbits has no stop at the wall time)."""
    out = tmp_path / "out"
    refused(cli("orbits", str(PAPER), *sets(LINEAR), *arguments, "--out", str(out)), message, out)


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--periods", "0"], "periods: must be a whole number >= 1, got 0"),
        (["--periods", "3", "--discard", "3"], "discard: 3 leaves none of the 3 intervals"),
        (["--periods", "3", "--every", "0"], "every: must be a whole number >= 1, got 0"),
        (["--periods", "3", "--every", "2"], "periods: 3 is not a whole number of intervals"),
    ],
)
def test_bad_lyapunov_requests_make_no_folder(tmp_path, arguments, message):
    """lyapunov's counts are checked before its --out folder is made: exit 2, one line
    naming the flag's key, and no folder."""
    out = tmp_path / "out"
    proc = cli(
        "lyapunov", str(PAPER), *sets(LINEAR), "--period", PERIOD, *arguments, "--out", str(out)
    )
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert message in line and not out.exists()


@pytest.mark.parametrize(
    "scene, overrides, message",
    [
        (ROOT / "scenes" / "free_ring.toml", {}, "reference.closed: a closed rod has modes"),
        (  # 20 steps a period, 3 periods: above 1 µs by the budget's lower bound (budget.py)
            PAPER,
            {**MARCHED, "limits.wall_time": 1e-6},
            "time.step: the run needs",
        ),
    ],
)
def test_a_refused_lyapunov_run_makes_no_folder(tmp_path, scene, overrides, message):
    """A closed ring, and a run beyond the scene's limits.wall_time by budget.py's lower
    bound, are refused before the --out folder is made: exit 2, one line naming the key, no
    folder (before: both were refused after it was made, the budget's with a lock file and
    an empty folder left behind)."""
    out = tmp_path / "out"
    period = ["--period", PERIOD] if scene == PAPER else ["--period", "0.1"]
    proc = cli(
        "lyapunov", str(scene), *sets(overrides), *period, "--periods", "3", "--out", str(out)
    )
    refused(proc, message, out)


@pytest.mark.parametrize(
    "command",
    [
        ["continue", str(ROOT / "scenes" / "rollup.toml")],
        ["orbits", str(PAPER), *sets(LINEAR), *BRANCH, *STEPS],
        ["lyapunov", str(PAPER), *sets(MARCHED), "--period", PERIOD, "--periods", "1"],
    ],
    ids=["continue", "orbits", "lyapunov"],
)
def test_a_held_folder_is_refused_naming_the_option_given(tmp_path, command):
    """Each command into a folder another writer holds (its lock taken here): exit 2, one
    line naming the option that named the folder: ``--out`` when it was given (before:
    output.directory, which the user had not set), output.directory when the folder is the
    scene's default (``--set output.directory`` gave it; the command's own folder beneath),
    and the holder's lock and folder left as they were."""
    from cosserat_fem.io.folder_lock import LOCK, FolderLock

    folder = tmp_path / "held"
    default = {"continue": "continuation", "orbits": "orbits", "lyapunov": "lyapunov"}
    own = tmp_path / "scene_out" / default[command[0]]
    for path in (folder, own):
        path.mkdir(parents=True)
    locks = [FolderLock.take(folder, "run"), FolderLock.take(own, "run")]
    try:
        proc = cli(*command, "--out", str(folder))
        assert proc.returncode == 2, proc.stderr
        (line,) = proc.stderr.strip().splitlines()
        assert line.startswith(f"cosserat-fem: error: --out: {str(folder)!r} is in use by")
        scene_out = json.dumps(str(tmp_path / "scene_out"))
        proc = cli(*command, "--set", f"output.directory={scene_out}")
        assert proc.returncode == 2, proc.stderr
        (line,) = proc.stderr.strip().splitlines()
        assert line.startswith(f"cosserat-fem: error: output.directory: {str(own)!r} is in use")
        assert sorted(p.name for p in folder.iterdir()) == [LOCK]
    finally:
        for lock in locks:
            lock.release()


def test_a_damaged_restart_folder_is_refused_in_one_line(tmp_path):
    """A branch cut at --max-points 2, then in three copies: its restart arrays missing,
    its restart arrays not a NumPy file, orbit_branch.csv missing, orbit_branch.csv cut to
    its first row (the record names 2). Each ``orbits --restart``: exit 2, one line naming
    --restart and the file, and the copy's orbit_branch.csv as it was (no row lost)."""
    import shutil

    cut = tmp_path / "cut"
    base = ["orbits", str(PAPER), *sets(LINEAR), *BRANCH, *STEPS, "--max-points", "2"]
    assert cli(*base, "--out", str(cut)).returncode == 0
    table = (cut / "orbit_branch.csv").read_text()
    arrays = "continuation/branch0.rank0.npz"
    damages = {
        "no_arrays": (arrays, None, "branch0.rank0.npz' cannot be read"),
        "bad_arrays": (arrays, "junk\n", "branch0.rank0.npz' cannot be read"),
        "no_table": ("orbit_branch.csv", None, "orbit_branch.csv' was not found"),
        "cut_table": (
            "orbit_branch.csv",
            table.splitlines()[0] + "\n" + table.splitlines()[1] + "\n",
            "holds 1 rows, fewer than the 2 of the saved branch",
        ),
    }
    for name, (path, text, message) in damages.items():
        folder = tmp_path / name
        shutil.copytree(cut, folder)
        (folder / path).unlink()
        if text is not None:
            (folder / path).write_text(text)
        before = (
            (folder / "orbit_branch.csv").read_bytes()
            if path != "orbit_branch.csv" or text
            else None
        )
        proc = cli("orbits", "--restart", str(folder), "--max-points", "300")
        assert proc.returncode == 2, (name, proc.stderr)
        (line,) = proc.stderr.strip().splitlines()
        assert "--restart: " in line and message in line, (name, line)
        if before is not None:
            assert (folder / "orbit_branch.csv").read_bytes() == before, name


def test_a_branch_whose_first_orbit_is_not_found_says_why(tmp_path):
    """solver.max_iterations = 1: the stage solves of the first period fail (Newton cannot
    converge in one iteration from rest), so there is no first orbit: exit 3, one line on
    stderr, and summary.json with no point and that line's reason; orbit_branch.csv holds
    its header alone and there is no restart data."""
    proc = cli(
        "orbits",
        str(PAPER),
        *sets({**LINEAR, "solver.max_iterations": 1}),
        *BRANCH,
        *STEPS,
        "--out",
        str(tmp_path),
    )
    assert proc.returncode == 3, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["points"] == 0 and summary["reason"] in line and "Newton" in line
    assert rows(tmp_path / "orbit_branch.csv") == []
    assert not (tmp_path / "continuation" / "orbits.json").exists()


def test_a_missing_period_and_a_folder_without_a_branch_are_one_line(tmp_path):
    """lyapunov without --period, or with a period that is not its forcing's (the paper's
    load sin(8 ω0 t) against 0.01 s), and orbits --restart of a folder that holds no
    branch: exit 2, one line naming the flag or the load's key."""
    proc = cli("lyapunov", str(PAPER), "--periods", "2", "--out", str(tmp_path / "l"))
    assert proc.returncode == 2 and "lyapunov --period: give" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    proc = cli("lyapunov", str(PAPER), "--period", "0.01", "--periods", "2")
    assert proc.returncode == 2 and "loads.force_density: " in proc.stderr
    assert " not periodic with --period T = 0.01 s" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    (tmp_path / "empty").mkdir()
    proc = cli("orbits", "--restart", str(tmp_path / "empty"))
    assert proc.returncode == 2 and "--restart:" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


class TestLyapunov:
    """tests/test_chaos.py's linear rod (4 cells, Kelvin–Voigt ζ1 = 0.05) forced at its
    damped period T = 2π/ω_d1 by N = 40 steps a period, 6 periods, 2 discarded."""

    PERIODS, DISCARD, STEPS = 6, 2, 40

    def test_the_command_s_exponent_is_the_api_s(self, case):
        """summary.json's exponent and lyapunov.csv's running estimate equal ``cf.lyapunov``'s
        within the solver's noise: Newton stops at an update below stol ‖U‖, so a stretch
        may carry steps × stol × RMS(U) / d0 (tests/test_chaos.py), over the averaged time;
        the section's rows the API's within steps × periods × stol of each column's largest
        value (each step's Newton may leave stol relative). The exponent is
        negative (a damped linear rod) and ``plot`` draws lyapunov.png."""
        from test_chaos import STOL

        proc, out, result, _, T = case
        assert proc.returncode == 0, proc.stderr
        summary = json.loads((out / "summary.json").read_text())
        rms = result.poincare[:, -1].max()
        noise = self.STEPS * STOL * rms / result.perturbation / T
        assert result.exponent < 0
        assert abs(summary["exponent"] - result.exponent) <= noise
        table = rows(out / "lyapunov.csv")
        assert len(table) == result.times.size == self.PERIODS
        for row, t, lam in zip(table, result.times, result.running, strict=True):
            assert float(row["time"]) == pytest.approx(t, rel=1e-12)
            if math.isnan(lam):
                assert row["running_exponent"] == ""
            else:
                assert abs(float(row["running_exponent"]) - lam) <= noise * self.PERIODS
        from cosserat_fem.io.poincare import read_poincare

        _, section = read_poincare(out / "poincare.csv")
        scale = np.abs(result.poincare).max(axis=0) * self.STEPS * self.PERIODS * STOL
        assert np.all(np.abs(section - result.poincare) <= scale)
        plot = cli("plot", str(out))
        assert plot.returncode == 0, plot.stderr
        assert (out / "lyapunov.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    def test_the_scene_s_limits_refuse_or_stop_it(self, case, tmp_path):
        """limits.wall_time of 1 ms, below the budget's lower bound of the run's time
        (cosserat_fem/analysis/budget.py: 0.009 s for its 240 steps): refused before any work,
        exit 2, one line naming time.step, no folder. Of 20 ms, above that bound but far below
        the run's (its set-up alone takes longer): stopped at the first look at the clock (64
        steps of the reference trajectory), exit 4, one line naming limits.wall_time (not
        advising run --restart, which a Lyapunov run does not have), and what it computed
        kept (before: the stretches were lost): the 64 // 40 = 1 interval done in
        lyapunov.csv, its stretch the uninterrupted run's first (the same trajectories from
        the same perturbation) within the solver's noise (as in the test above: steps ×
        stol × RMS(U) / d0), its running exponent s_1 / T (discard 0, lyapunov.py), and
        summary.json "stopped", the reason, 1 interval and that exponent; ``plot`` draws it."""
        from test_chaos import STOL

        _, _, result, overrides, T = case
        common = ["--period", repr(T), "--periods", str(self.PERIODS)]
        refused = cli(
            "lyapunov",
            str(PAPER),
            *sets({**overrides, "limits.wall_time": 1e-3}),
            *common,
            "--out",
            str(tmp_path / "refused"),
        )
        assert refused.returncode == 2 and "time.step: the run needs" in refused.stderr
        assert len(refused.stderr.strip().splitlines()) == 1
        assert not (tmp_path / "refused").exists()
        stopped = tmp_path / "stopped"
        proc = cli(
            "lyapunov",
            str(PAPER),
            *sets({**overrides, "limits.wall_time": 0.02}),
            *common,
            "--out",
            str(stopped),
        )
        assert proc.returncode == 4, proc.stderr
        assert "limits.wall_time" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
        assert "run --restart" not in proc.stderr and "has no restart" in proc.stderr
        summary = json.loads((stopped / "summary.json").read_text())
        assert summary["status"] == "stopped" and "limits.wall_time" in summary["reason"]
        (row,) = rows(stopped / "lyapunov.csv")
        noise = self.STEPS * STOL * result.poincare[:, -1].max() / result.perturbation
        assert abs(float(row["stretch"]) - result.stretches[0]) <= noise
        assert float(row["running_exponent"]) == pytest.approx(float(row["stretch"]) / T, 1e-14)
        assert summary["intervals"] == 1 and summary["discard"] == 0
        assert summary["exponent"] == float(row["running_exponent"])
        plot = cli("plot", str(stopped))
        assert plot.returncode == 0, plot.stderr
        assert (stopped / "lyapunov.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    def test_an_interrupted_run_keeps_its_intervals(self, case, tmp_path):
        """A KeyboardInterrupt (Ctrl-C, or SIGTERM by cli.py) at the reference's 100th step,
        within the third interval of 40 steps: raised, and the 2 intervals done kept (before:
        lost): lyapunov.csv's 2 stretches the uninterrupted run's within the solver's noise,
        summary.json "stopped", "interrupted", 2 intervals, its exponent their mean over T
        (discard 0) to round-off."""
        from test_chaos import STOL

        from cosserat_fem.timestepping.events import Observer

        _, _, result, overrides, T = case

        class Interrupt(Observer):
            steps = 0

            def step_finished(self, loop) -> None:
                self.steps += 1
                if self.steps == 100:
                    raise KeyboardInterrupt

        out = tmp_path / "interrupted"
        scene = cf.load(PAPER, overrides)
        with pytest.raises(KeyboardInterrupt):
            cf.lyapunov_run(scene, T, periods=self.PERIODS, out=out, observers=[Interrupt()])
        table = rows(out / "lyapunov.csv")
        assert len(table) == 2
        noise = self.STEPS * STOL * result.poincare[:, -1].max() / result.perturbation
        stretches = [float(r["stretch"]) for r in table]
        assert np.all(np.abs(np.array(stretches) - result.stretches[:2]) <= noise)
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "stopped" and "interrupted" in summary["reason"]
        assert summary["intervals"] == 2
        assert summary["exponent"] == pytest.approx(sum(stretches) / (2 * T), rel=1e-14)

    def test_a_run_killed_by_sigterm_keeps_its_intervals(self, case, tmp_path):
        """``lyapunov`` of 20000 periods (about a minute here) ended by SIGTERM (the process
        ends where it is: no handler, and Open MPI's mpirun sends it to every rank) once
        lyapunov.csv has 3 rows: the rows of the intervals done are there, fewer than the
        run's (appended as each ends; before, the file was written at the end only, so
        none), the first two stretches the uninterrupted
        run's within the solver's noise (steps × stol × RMS(U) / d0, as above) and each
        running exponent Σ s_j / (n T) (discard 0) to round-off. poincare.csv keeps its rows
        too (appended as each period's section is sampled; before, written at the end only,
        so lost): at least the 3 periods of the intervals done, each row's period and time
        the uninterrupted run's and its state RMS within the solver's noise (steps × stol ×
        RMS(U) per period, 3 periods)."""
        import signal
        import subprocess
        import time

        from conftest import PYTHON, stop_tree, subprocess_env
        from test_chaos import STOL

        _, _, result, overrides, T = case
        out = tmp_path / "killed"
        command = ["-m", "cosserat_fem.cli", "lyapunov", str(PAPER), *sets(overrides)]
        command += ["--period", repr(T), "--periods", "20000", "--out", str(out)]
        killed = subprocess.Popen([PYTHON, *command], cwd=ROOT, env=subprocess_env())
        try:
            deadline = time.monotonic() + 120
            table: list[dict] = []
            while len(table) < 3 and killed.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
                if (out / "lyapunov.csv").exists():
                    table = rows(out / "lyapunov.csv")
            assert killed.poll() is None, "the run ended before it could be killed"
            killed.send_signal(signal.SIGTERM)
            assert killed.wait(timeout=60) == -signal.SIGTERM
        finally:
            stop_tree(killed)
        table = rows(out / "lyapunov.csv")
        assert 3 <= len(table) < 20000
        stretches = np.array([float(r["stretch"]) for r in table])
        noise = self.STEPS * STOL * result.poincare[:, -1].max() / result.perturbation
        assert np.all(np.abs(stretches[:2] - result.stretches[:2]) <= noise)
        running = np.cumsum(stretches) / (np.arange(1, stretches.size + 1) * T)
        got = np.array([float(r["running_exponent"]) for r in table])
        assert np.allclose(got, running, rtol=1e-12, atol=0)
        from cosserat_fem.io.poincare import read_poincare

        _, section = read_poincare(out / "poincare.csv")
        assert len(section) >= 3
        expected = result.poincare[:3]
        np.testing.assert_array_equal(section[:3, 0], expected[:, 0])
        np.testing.assert_allclose(section[:3, 1], expected[:, 1], rtol=1e-14, atol=0)
        rms_noise = 3 * self.STEPS * STOL * expected[:, -1].max()
        assert np.all(np.abs(section[:3, -1] - expected[:, -1]) <= rms_noise)

    def test_a_failed_run_says_why_in_summary_json(self, case, tmp_path):
        """solver.max_iterations = 1: the first step's Newton fails (exit 3, one line with the
        time and place); summary.json says "failed" with that line's reason (before: none
        written), and ``plot`` of the folder says lyapunov.csv was not written and why."""
        _, _, _, overrides, T = case
        out = tmp_path / "failed"
        proc = cli(
            "lyapunov",
            str(PAPER),
            *sets({**overrides, "solver.max_iterations": 1}),
            *["--period", repr(T), "--periods", str(self.PERIODS), "--out", str(out)],
        )
        assert proc.returncode == 3, proc.stderr
        (line,) = proc.stderr.strip().splitlines()
        assert "Newton did not converge" in line and " at t = " in line
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "failed" and summary["reason"] in line
        plot = cli("plot", str(out))
        assert plot.returncode == 2 and "the Lyapunov run failed (" in plot.stderr


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """The command's and the API's run of :class:`TestLyapunov`'s case."""
    from test_chaos import BASE, OMEGA0

    omega1 = cf.modes(cf.load(PAPER, BASE), count=1)[0].omega
    tau = BASE["damping.retardation_time"]
    omega_d = omega1 * math.sqrt(1 - (tau * omega1 / 2) ** 2)
    T = 2 * math.pi / omega_d
    overrides = {
        **BASE,
        "time.step": T / TestLyapunov.STEPS,
        "time.end": TestLyapunov.PERIODS * T,
        "parameters.r": omega_d / OMEGA0,
    }
    out = tmp_path_factory.mktemp("lyapunov")
    args = [
        "lyapunov",
        str(PAPER),
        *sets(overrides),
        "--period",
        repr(T),
        "--periods",
        str(TestLyapunov.PERIODS),
        "--discard",
        str(TestLyapunov.DISCARD),
        "--out",
        str(out),
    ]
    proc = cli(*args)
    result = cf.lyapunov(
        cf.load(PAPER, overrides), T, periods=TestLyapunov.PERIODS, discard=TestLyapunov.DISCARD
    )
    return proc, out, result, overrides, T


@pytest.mark.long
def test_the_s_curve_by_the_command_line_cut_or_killed_and_restarted(tmp_path):
    """The demo's load (F = 5915.8 N/m) on 4 cells at N = 40, r from 0.98 to 1.14 after 3
    settled periods: the command traces the S-curve through its two folds (r ≈ 1.044 and
    1.105, amplitudes 9.8 and 25.6 mm on this coarse rod), its middle points unstable
    ("fold": a real μ > 1).

    Cut at --max-points 20 (past the first fold) and restarted, it reaches the same folds:
    p within 1e-6 (located to 1e-6 in arclength, |dp/ds| ≤ 1), the same points and end.
    Killed (SIGKILL) once 5 orbits are written, wherever that falls, and restarted, its
    points are the whole branch's: p within DP and the amplitude within 1e-9 m (the
    corrector's 1e-9 in the metric is (ℓ/scale) 1e-9 = 2.5e-10 m of amplitude when one mode
    dominates: a = (ℓ/scale) √w ‖u‖ by the choice of w; a factor 4 for the others), the
    special points located after the kill among the whole branch's (those before it are
    lost: module docstring of orbit_runs.py). plot marks the folds."""
    import os
    import signal
    import subprocess
    import time

    from conftest import PYTHON, subprocess_env

    demo = {**LINEAR, "parameters.F": 5915.8, "parameters.r": 0.98}
    base = [
        "orbits",
        str(PAPER),
        *sets(demo),
        "--period",
        PERIOD,
        "--parameter",
        "r",
        "--from",
        "0.98",
        "--to",
        "1.14",
        "--steps-per-period",
        "40",
        "--settle",
        "3",
    ]
    whole, cut, killed = tmp_path / "whole", tmp_path / "cut", tmp_path / "killed"
    assert cli(*base, "--out", str(whole)).returncode == 0
    summary = json.loads((whole / "summary.json").read_text())
    folds = sorted(f["parameter"] for f in summary["folds"])
    assert len(folds) == 2 and 1.03 < folds[0] < 1.06 and 1.09 < folds[1] < 1.12
    table = rows(whole / "orbit_branch.csv")
    middle = [r for r in table if r["point"] == "regular" and r["stability"] != "stable"]
    assert middle and all(r["stability"] == "fold" for r in middle)
    assert cli(*base, "--max-points", "20", "--out", str(cut)).returncode == 0
    assert len(json.loads((cut / "summary.json").read_text())["folds"]) == 1
    again = cli("orbits", "--restart", str(cut), "--max-points", "300")
    assert again.returncode == 0, again.stderr
    restarted = json.loads((cut / "summary.json").read_text())
    assert restarted["points"] == summary["points"] and restarted["reason"] == summary["reason"]
    got = sorted(f["parameter"] for f in restarted["folds"])
    assert np.allclose(got, folds, rtol=0, atol=1e-6)
    assert cli("plot", str(cut)).returncode == 0

    proc = subprocess.Popen(
        [PYTHON, "-m", "cosserat_fem.cli", *base, "--out", str(killed)],
        cwd=ROOT,
        env=subprocess_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    record = killed / "continuation" / "orbits.json"
    try:
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                if json.loads(record.read_text())["rows"] >= 5:
                    break
            except (OSError, ValueError):
                pass
            time.sleep(0.05)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    again = cli("orbits", "--restart", str(killed), "--max-points", "300")
    assert again.returncode == 0, again.stderr
    expected = [r for r in table if r["point"] in ("start", "regular", "end")]
    after = rows(killed / "orbit_branch.csv")
    points = [r for r in after if r["point"] in ("start", "regular", "end")]
    assert len(points) == len(expected)
    for a, b in zip(points, expected, strict=True):
        assert abs(float(a["parameter"]) - float(b["parameter"])) <= DP
        assert abs(float(a["amplitude"]) - float(b["amplitude"])) <= 1e-9
    for special in (r for r in after if r not in points):
        assert any(abs(float(special["parameter"]) - f) <= 1e-6 for f in folds)


@pytest.mark.long
def test_the_branch_under_mpirun_with_a_restart_is_the_serial_one(tmp_path):
    """``mpirun -n 2 cosserat-fem orbits`` cut at --max-points 3 and restarted under mpirun:
    the serial branch's rows (p within DP, the amplitude within DA relative, |μ| within 1e-8:
    the partition changes the LU's round-off only, far inside the corrector's tolerance)
    and one XDMF frame per row across the restart. A restart on another number of ranks is
    refused in one line naming --restart (its states are per rank)."""
    from xdmf_files import read_arrays

    base = ["-m", "cosserat_fem.cli", "orbits", str(PAPER), *sets(LINEAR), *BRANCH, *STEPS]
    serial, parallel = tmp_path / "serial", tmp_path / "parallel"
    assert run_command([*base, "--out", str(serial)]).returncode == 0
    first = run_command([*base, "--max-points", "3", "--out", str(parallel)], ranks=2)
    assert first.returncode == 0, first.stderr
    wrong = cli("orbits", "--restart", str(parallel), "--max-points", "300")
    assert wrong.returncode == 2 and "on 1 ranks (it ran on 2" in wrong.stderr
    restart = ["-m", "cosserat_fem.cli", "orbits", "--restart", str(parallel)]
    again = run_command([*restart, "--max-points", "300"], ranks=2)
    assert again.returncode == 0, again.stderr
    got = same_rows(parallel, serial)
    _, times, _ = read_arrays(parallel / "orbit_branch.xdmf")
    assert list(times) == list(range(len(got)))
