"""Sweeps (cosserat_fem/studies/sweep_spec.py, sweep.py): members run as the same scene alone would,
failures recorded, a restarted sweep skips finished members, malformed sweeps refused before
any member runs, and under mpirun -n 2 (two groups dealt by a one-sided counter) the same
table as in serial.

Equality is the test for the members' results: a member is its scene run by
cosserat_fem.analysis.simulation.run_scene on its group's communicator, exactly as ``cosserat-fem
run`` of that scene alone, so its probes.csv is the same file byte for byte, and its table row (the
probe's final and largest values, printed with repr) the same text in serial and under MPI.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from conftest import ROOT, read_table, run_command, sweep_serial_and_mpi

from cosserat_fem import api
from cosserat_fem.cli import main
from cosserat_fem.common.errors import SceneError
from cosserat_fem.studies.sweep_run import columns

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
SHORT = {"time.end": 0.0006, "output.xdmf": False}


def sweep_file(folder: Path, body: str, scene: Path = PAPER, **sweep) -> Path:
    """A sweep file of the paper's scene (or ``scene``), 0.6 ms without XDMF, ``sweep`` keys
    and ``body``."""
    head = [f'scene = "{scene}"', *(f"{k} = {json.dumps(v)}" for k, v in sweep.items())]
    fixed = [f'"{k}" = {json.dumps(v)}' for k, v in SHORT.items()]
    text = "[sweep]\n" + "\n".join(head) + "\n[sweep.set]\n" + "\n".join(fixed) + "\n" + body
    path = folder / "sweep.toml"
    path.write_text(text, encoding="utf-8")
    return path


STEPS = '[sweep.vary]\n"time.step" = [1e-5, 2e-5, 3e-5]\n'


def test_members_are_their_scenes_run_alone(tmp_path):
    spec = api.load_sweep(sweep_file(tmp_path, STEPS))
    result = api.sweep(spec, tmp_path / "out")
    assert result.ran == 3 and result.skipped == 0
    rows = read_table(tmp_path / "out" / "sweep.csv")
    assert [r["member"] for r in rows] == ["0", "1", "2"]
    assert [r["status"] for r in rows] == ["completed"] * 3
    assert [json.loads(r["time.step"]) for r in rows] == [1e-5, 2e-5, 3e-5]
    assert list(rows[0]) == columns(spec)
    for member, step in enumerate((1e-5, 2e-5, 3e-5)):
        alone = tmp_path / f"alone{member}"
        scene = api.load(PAPER, {**SHORT, "time.step": step})
        api.run(scene, alone)
        got = (tmp_path / "out" / "members" / f"m{member:05d}" / "probes.csv").read_bytes()
        assert got == (alone / "probes.csv").read_bytes()
        assert int(rows[member]["steps"]) == round(0.0006 / step)


def test_a_failed_member_is_recorded_and_the_sweep_goes_on(tmp_path):
    """A distributed load of 1e10 N/m with no halving allowed: Newton fails in the first step
    (status "failed", the one-line reason); the members before and after complete."""
    cases = (
        '[[sweep.case]]\n"time.step" = 3e-5\n'
        '[[sweep.case]]\n"loads.force_density" = ["1e10", 0, 0]\n"time.max_halvings" = 0\n'
        '[[sweep.case]]\n"time.step" = 2e-5\n'
    )
    result = api.sweep(api.load_sweep(sweep_file(tmp_path, cases)), tmp_path / "out")
    rows = read_table(result.table)
    assert [r["status"] for r in rows] == ["completed", "failed", "completed"]
    assert rows[1]["message"].startswith("SolverError: ") and "\n" not in rows[1]["message"]
    assert rows[0]["message"] == rows[2]["message"] == ""


def test_a_restarted_sweep_skips_the_finished_members(tmp_path):
    """A sweep killed after two members (its table part: their rows and a third cut by the
    kill) runs only the third again, into the same table."""
    spec = api.load_sweep(sweep_file(tmp_path, STEPS))
    out = tmp_path / "out"
    api.sweep(spec, out)
    part = out / "table" / "group-0.csv"
    lines = part.read_text(encoding="utf-8").splitlines(keepends=True)
    full = read_table(out / "sweep.csv")
    part.write_text("".join(lines[:3]) + lines[3][:40], encoding="utf-8")  # member 2 cut
    (out / "sweep.csv").unlink()
    result = api.sweep(spec, out)
    assert (result.ran, result.skipped) == (1, 2)
    again = read_table(out / "sweep.csv")
    assert [r["member"] for r in again] == ["0", "1", "2"]
    for old, new in zip(full, again, strict=True):
        assert {k: v for k, v in old.items() if k != "wall_s"} == {
            k: v for k, v in new.items() if k != "wall_s"
        }
    other = api.load_sweep(sweep_file(tmp_path, '[sweep.vary]\n"time.step" = [1e-5]\n'))
    with pytest.raises(SceneError, match="holds another sweep"):
        api.sweep(other, out)


@pytest.mark.parametrize(
    ("body", "sweep", "message"),
    [
        (
            '[sweep.vary]\n"tim.step" = [1e-5]\n',
            {},
            "sweep member 0 (tim.step = 1e-05): tim: unknown key",
        ),
        (
            '[sweep.vary]\n"time.step" = [-1e-5]\n',
            {},
            "sweep member 0 (time.step = -1e-05): time.step: must be > 0 [s], got -1e-05",
        ),
        (
            '[sweep.vary]\n"time.step" = []\n',
            {},
            'sweep.vary."time.step": must be a non-empty list',
        ),
        (
            '[sweep.vary]\n"time.step" = {start = 1e-5, stop = 2e-5, num = 0}\n',
            {},
            'sweep.vary."time.step".num: an empty range',
        ),
        (
            '[sweep.vary]\n"time.step" = {start = 1e-5, stop = 2e-5, num = 50}\n'
            '"solver.stol" = {start = 1e-8, stop = 1e-7, num = 50}\n',
            {"max_members": 1000},
            "sweep.max_members: the sweep has 2500 members, more than max_members = 1000",
        ),
        (
            '[sweep.vary]\n"time.step" = [1e-5, 2e-5]\n"solver.stol" = [1e-8]\n',
            {"combine": "zip"},
            "sweep.vary: combine = 'zip' needs lists of one length",
        ),
        (
            STEPS,
            {"max_members": 200000},
            "sweep.max_members: at most 100000 (every rank "
            "validates every member first), got 200000",
        ),
        (STEPS, {"keep": "all"}, "sweep.keep: must be one of 'run', 'probes', got \"all\""),
        (STEPS, {"group_size": 0}, "sweep.group_size: must be a positive integer, got 0"),
        (STEPS, {"colour": 1}, "sweep.colour: unknown key"),
        (
            STEPS + '[[sweep.case]]\n"time.step" = 1e-5\n',
            {},
            "sweep: give either [sweep.vary] or [[sweep.case]]",
        ),
    ],
)
def test_a_malformed_sweep_is_refused_before_any_member_runs(tmp_path, body, sweep, message):
    path = sweep_file(tmp_path, body, **sweep)
    proc = run_command(
        ["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(tmp_path / "out")]
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"cosserat-fem: error: {message}"), proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


# Long set (make test within 3 minutes): make test keeps the MPI fuzz's sweeps on two ranks.
@pytest.mark.long
@pytest.mark.mpi
def test_a_sweep_under_mpi_equals_the_serial_sweep(tmp_path):
    """mpirun -n 2: two groups of one rank take members from the counter; every member is
    run serially on its group, so the table is the serial table to the last digit (all but
    the wall times), and each group wrote its own part."""
    path = sweep_file(tmp_path, STEPS, keep="probes")
    tables = sweep_serial_and_mpi(path, tmp_path)
    assert tables[1] == tables[2]
    assert sorted(p.name for p in (tmp_path / "n2" / "table").iterdir()) == [
        "group-0.csv",
        "group-1.csv",
    ]
    kept = sorted(p.name for p in (tmp_path / "n2" / "members" / "m00000").iterdir())
    assert kept == ["probes.csv", "summary.json"]


def test_the_example_sweep_is_valid():
    """scenes/sweeps/paper_forcing.toml: five members, the forcing 6 ... 10 ω0 (a range)."""
    spec = api.load_sweep(ROOT / "scenes" / "sweeps" / "paper_forcing.toml")
    assert [m.values for m in spec.members] == [
        {"parameters.forcing": f} for f in (6.0, 7.0, 8.0, 9.0, 10.0)
    ]
    assert spec.keep == "probes" and spec.group_size == 1


@pytest.mark.long
def test_a_sweep_killed_with_sigkill_and_started_again_skips_what_finished(tmp_path):
    """The process killed (SIGKILL) once the first row is in the table; the sweep started
    again with the same --out runs only the members without a row, and its table equals an
    uninterrupted sweep's (all but the wall times). ~10 s."""
    import os
    import signal
    import subprocess
    import time

    from conftest import PYTHON, subprocess_env

    path = sweep_file(tmp_path, '[sweep.vary]\n"time.step" = [1e-5, 2e-5, 3e-5, 1.5e-5]\n')
    out = tmp_path / "killed"
    cmd = [PYTHON, "-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, env=subprocess_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    part, deadline = out / "table" / "group-0.csv", time.monotonic() + 120
    while not (part.exists() and part.read_bytes().count(b"\n") >= 2):
        assert proc.poll() is None, "the sweep ended before it was killed"
        assert time.monotonic() < deadline, "no row in 120 s"
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    rows_before = part.read_bytes().count(b"\n") - 1
    assert 1 <= rows_before < 4
    again = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)])
    assert again.returncode == 0, again.stderr
    assert f"ran {4 - rows_before}, skipped {rows_before} finished before" in again.stdout
    whole = run_command(
        ["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(tmp_path / "whole")]
    )
    assert whole.returncode == 0, whole.stderr
    strip = [{k: v for k, v in r.items() if k != "wall_s"} for r in read_table(out / "sweep.csv")]
    assert strip == [
        {k: v for k, v in r.items() if k != "wall_s"}
        for r in read_table(tmp_path / "whole" / "sweep.csv")
    ]


def test_members_that_differ_in_parameters_share_their_compiled_forms():
    """The [parameters] are Constants in the forms (RodModel._symbols): the residuals of two
    members of the example sweep (forcing 6 and 7 ω0) have one UFL signature, so FFCx
    compiles them once (the example's five members: 10 s → 3 s here); a load written with
    the number itself has another."""
    from dolfinx import fem
    from mpi4py import MPI

    from cosserat_fem.rod.model import build_model

    spec = api.load_sweep(ROOT / "scenes" / "sweeps" / "paper_forcing.toml")

    def signature(scene) -> str:
        model = build_model(scene, MPI.COMM_WORLD)
        time = fem.Constant(model.msh, 0.0)  # τ symbolic: a number 0 would fold the load away
        return model.residual(model.U, model.U, time).signature()

    first, second = (signature(spec.scene(m)) for m in spec.members[:2])
    assert first == second
    load = "2e3*sin(pi*s/L)*sin(7*omega0*t)"  # the second member's, with the number written
    written = api.load(PAPER, {**SHORT, "loads.force_density": [load, load, 0]})
    assert signature(written) != first


def test_plot_draws_a_sweep_from_its_table_or_its_parts(tmp_path):
    """``cosserat-fem plot DIR`` of a sweep's folder: sweep.png (1300 × 1040 px) against the
    varied key, from sweep.csv, or from the table parts while there is none (a killed sweep:
    its cut row dropped); a table without the sweep's columns is refused in one line."""
    import struct

    out = tmp_path / "out"
    api.sweep(api.load_sweep(sweep_file(tmp_path, STEPS)), out)
    (out / "sweep.csv").unlink()
    part = out / "table" / "group-0.csv"
    part.write_text(part.read_text(encoding="utf-8") + "3,compl", encoding="utf-8")
    proc = run_command(["-m", "cosserat_fem.cli", "plot", str(out)])
    assert proc.returncode == 0, proc.stderr
    png = (out / "sweep.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and struct.unpack(">II", png[16:24]) == (1300, 1040)
    part.write_text("member,status\n0,completed\n", encoding="utf-8")
    proc = run_command(["-m", "cosserat_fem.cli", "plot", str(out)])
    assert proc.returncode == 2
    assert proc.stderr.startswith("cosserat-fem: error: plot: ") and "no sweep's table" in (
        proc.stderr
    )
    assert proc.stderr.count("\n") == 1


@pytest.mark.long
@pytest.mark.mpi
def test_a_group_of_two_ranks_runs_a_member_as_mpirun_runs_it_alone(tmp_path):
    """group_size = 2 under mpirun -n 2: one group, each member on both ranks; its probes.csv
    is that of ``mpirun -n 2 cosserat-fem run`` of the member's scene, byte for byte (MUMPS
    there, as in the group; a serial run rounds otherwise)."""
    path = sweep_file(tmp_path, '[sweep.vary]\n"time.step" = [1e-5, 2e-5]\n', group_size=2)
    out = tmp_path / "out"
    proc = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)], 2)
    assert proc.returncode == 0, proc.stderr
    assert [p.name for p in (out / "table").iterdir()] == ["group-0.csv"]
    sets = [f"--set={k}={json.dumps(v)}" for k, v in {**SHORT, "time.step": 2e-5}.items()]
    alone = tmp_path / "alone"
    proc = run_command(["-m", "cosserat_fem.cli", "run", str(PAPER), "--out", str(alone), *sets], 2)
    assert proc.returncode == 0, proc.stderr
    member = out / "members" / "m00001" / "probes.csv"
    assert member.read_bytes() == (alone / "probes.csv").read_bytes()


def test_a_range_ends_at_its_stop_exactly(tmp_path):
    """{start = 1e-5, stop = 3e-5, num = 3}: 1e-5 + (2e-5 · 2)/2 would be 2.9999999999999997e-5
    in floating point; the last member's value is the stop as written."""
    spec = api.load_sweep(
        sweep_file(tmp_path, '[sweep.vary]\n"time.step" = {start = 1e-5, stop = 3e-5, num = 3}\n')
    )
    values = [m.values["time.step"] for m in spec.members]
    assert values[0] == 1e-5 and values[-1] == 3e-5
    assert values[1] == pytest.approx(2e-5, rel=1e-15)  # an inner value: to rounding


@pytest.mark.parametrize("ranks", [1, pytest.param(2, marks=[pytest.mark.mpi, pytest.mark.long])])
def test_a_sweep_tells_each_member_as_it_finishes(tmp_path, ranks):
    """Item 22: a sweep printed nothing until its last member ended. Now one line on stderr
    per member finished (in a pipe too: a sweep's lines are few), numbered in the order they
    finish across the groups (under mpirun -n 2, two groups share a one-sided counter, and
    each group's first rank prints its members' lines): the member, its status and wall time,
    k of the 3 done, the elapsed time and the time left at the rate so far (0 after the
    last). ``--quiet`` prints nothing; a sweep started again over finished members runs none
    and tells none."""
    import re

    path = sweep_file(tmp_path, STEPS, keep="probes")
    out = tmp_path / "out"
    sweep = ["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)]
    proc = run_command(sweep, ranks)
    assert proc.returncode == 0, proc.stderr
    # Found anywhere in stderr, not line by line: under mpirun two ranks print, and mpirun may
    # put one rank's line inside another's
    pattern = re.compile(
        r"cosserat-fem: sweep member (\d) completed in [0-9.e+-]+ s; (\d) of 3 "
        r"done, elapsed [0-9.:]+(?: s)?, ETA ([0-9.:]+?)(?: s|\n|$)"
    )
    found = [(None, m[1], m[2], None, m[3]) for m in pattern.finditer(proc.stderr)]
    assert len(found) == 3 and proc.stderr.count("cosserat-fem:") == 3, proc.stderr
    assert sorted(int(m[1]) for m in found) == [0, 1, 2]
    assert sorted(int(m[2]) for m in found) == [1, 2, 3]
    assert next(m[4] for m in found if m[2] == "3") == "0.0"
    again = run_command(sweep, ranks)
    assert again.returncode == 0 and "sweep member" not in again.stderr, again.stderr
    quiet = run_command([*sweep[:-1], str(tmp_path / "quiet"), "--quiet"], ranks)
    assert quiet.returncode == 0 and quiet.stderr == "" and quiet.stdout == "", quiet.stderr


# ------------------------------------------------------------------ issue 25 (items 9, 13, 19, 21)
def test_the_command_line_set_wins_over_the_sweep_set(tmp_path, capsys):
    """``sweep --set KEY=V`` is applied after ``[sweep.set]`` (before: first, so that a key the
    file also sets was silently ignored): time.end 0.0003 on the command line beats the
    file's 0.0006, and a member then takes 0.0003 / step steps. A bad key from the command
    line is named as such, not as ``sweep.set``."""
    path = sweep_file(tmp_path, STEPS)
    spec = api.load_sweep(path, ["time.end=0.0003"])
    assert [spec.scene(m).time.end for m in spec.members] == [0.0003] * 3
    spec = api.load_sweep(path, {"time.end": 0.0003})  # the API's mapping alike
    assert spec.scene(spec.members[0]).time.end == 0.0003
    with pytest.raises(SceneError, match=r"^tim: unknown key"):
        api.load_sweep(path, ["tim.end=1"])


@pytest.mark.parametrize(
    ("body", "sets", "message"),
    [
        (STEPS, ["time.step=1e-5"], "--set time.step: every member of the sweep sets it"),
        (STEPS + '"time.step" = 1e-5\n', [], None),  # appended to [sweep.vary]: a duplicate
        (
            '[[sweep.case]]\n"time.step" = 1e-5\n[[sweep.case]]\n"time.step" = 2e-5\n',
            [" time . step =1e-5"],
            "--set time.step: every member of the sweep sets it",
        ),
        (
            '[[sweep.case]]\n"time.step" = 1e-5\n[[sweep.case]]\n"solver.stol" = 1e-9\n',
            ["time.step=2e-5"],
            "",
        ),  # the second case takes it: allowed
    ],
)
def test_a_set_key_that_every_member_replaces_is_refused(tmp_path, body, sets, message):
    """A key given by ``--set`` that every member sets itself would never be used: refused
    naming it (a key some cases leave out is their value; ``[sweep.set]`` may give one, as
    scenes/sweeps/clamped_hysteresis.toml does)."""
    path = sweep_file(tmp_path, body)
    if message is None:  # TOML itself refuses a key given twice in one table
        with pytest.raises(SceneError, match="malformed TOML"):
            api.load_sweep(path, sets)
    elif message:
        with pytest.raises(SceneError, match=f"^{message}"):
            api.load_sweep(path, sets)
    else:
        spec = api.load_sweep(path, sets)
        assert [spec.scene(m).time.step for m in spec.members] == [1e-5, 2e-5]


def test_sweep_help_is_the_sweeps(capsys):
    """``sweep --help`` describes a sweep file and its --out and --set (before: run's text,
    "scene file (TOML)", "default: output.directory")."""
    from cosserat_fem.cli import main

    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    out = " ".join(capsys.readouterr().out.split())  # as argparse wraps it for any width
    assert "SWEEP sweep file (TOML)" in out and "scene file" not in out
    assert "results/<the sweep file's name>" in out and "after the sweep file's [sweep.set]" in out


def test_a_toml_date_among_a_sweep_values_is_refused_in_one_line(tmp_path):
    """A TOML date among a varied key's values: the member is refused naming the date as TOML
    writes it (before: TypeError, "Object of type date is not JSON serializable")."""
    path = sweep_file(tmp_path, '[sweep.vary]\n"time.step" = [1e-5, 1979-05-27]\n')
    with pytest.raises(
        SceneError,
        match=r"^sweep member 1 \(time\.step = 1979-05-27\): time\."
        r"step: must be a number",
    ):
        api.load_sweep(path)


def test_a_range_whose_span_overflows_has_finite_values(tmp_path):
    """{start = -1e308, stop = 1e308, num = 3}: stop − start overflows to inf, and start + inf·0
    was NaN; the values are the ends' weighted sums, exact here: -1e308, 0.5·(-1e308) +
    0.5·1e308 = 0 (halving is exact in binary), 1e308."""
    spec = api.load_sweep(
        sweep_file(
            tmp_path, '[sweep.vary]\n"parameters.a" = {start = -1e308, stop = 1e308, num = 3}\n'
        )
    )
    assert [m.values["parameters.a"] for m in spec.members] == [-1e308, 0.0, 1e308]


@pytest.mark.parametrize(
    ("body", "sweep", "message"),
    [
        (
            '[sweep.vary]\n"limits.wall_time" = [100.0, 1e-6]\n',
            {},
            r"sweep member 1 \(limits\.wall_time = 1e-06\): time\.step: the run needs .* more "
            r"than limits\.wall_time = 1e-06 s",
        ),
        (
            '[sweep.vary]\n"limits.memory" = [1e12, 1000.0]\n',
            {},
            r"sweep member 1 \(limits\.memory = 1000\.0\): discretisation\.elements: the run needs "
            r".* of memory .* more than limits\.memory = 1000 bytes",
        ),
        (
            '[sweep.vary]\n"time.step" = [1e-5]\n',
            {"scene": ROOT / "scenes" / "free_ring.toml"},
            r"sweep member 0 \(time\.step = 1e-05\): reference\.closed: a closed rod has modes "
            r"only",
        ),
    ],
)
def test_members_that_their_run_would_refuse_are_refused_with_the_sweep(
    tmp_path, body, sweep, message
):
    """A member over its limits (wall time, memory: budget.py's lower bounds) or of a closed
    rod is refused when the sweep is loaded, exit 2, no output folder (before: run one by one
    into "error" rows, and the sweep exited 0)."""
    path = sweep_file(tmp_path, body, **sweep)
    out = tmp_path / "out"
    proc = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)])
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1
    assert re.match(f"cosserat-fem: error: {message}", proc.stderr), proc.stderr
    assert not out.exists()


#: A member of 130 steps whose limits.wall_time, 0.01 s, is above its estimated lower bound
#: (130 steps of at least 55 μs: 7 ms, budget.py) but below what building its model alone
#: takes: it stops when the wall-time limit is first looked at, after 64 steps (t = 0.00064 s
#: and 0.00128 s), with a checkpoint.
WALL = {"time.end": 0.0013, "limits.wall_time": 0.01}


def test_members_that_stop_are_not_finished_and_continue(tmp_path):
    """Members stopped by limits.wall_time (a passing reason) leave the sweep unfinished: it
    raises StopError (exit 4) after writing their "stopped" rows, and keeps their
    checkpoints even with keep = "probes" (before: recorded as finished, exit 0, and their
    checkpoints deleted). Started again with limits.wall_time raised (not "another sweep":
    limits.* are not part of its identity), it continues each from its checkpoint (a
    restart, summary.json's restarts = 1) and its table equals an uninterrupted sweep's
    (checkpoint.py: a restart continues bit for bit), all but the wall times."""
    from cosserat_fem.common.errors import StopError

    vary = '[sweep.vary]\n"time.step" = [1e-5, 2e-5]\n'
    path = sweep_file(tmp_path, vary, keep="probes")
    out = tmp_path / "out"
    with pytest.raises(
        StopError,
        match=r"^sweep: 2 members stopped \(member 0: LimitReached: "
        r"limits\.wall_time: the run stopped at t = 0\.00064 s",
    ):
        api.sweep(api.load_sweep(path, WALL), out)
    rows = read_table(out / "sweep.csv")
    assert [r["status"] for r in rows] == ["stopped", "stopped"]
    assert "run --restart" not in rows[0]["message"]  # the sweep's own advice instead
    for member in ("m00000", "m00001"):
        assert (out / "members" / member / "checkpoint" / "checkpoint.json").is_file()
    raised = {**WALL, "limits.wall_time": 1000.0}
    result = api.sweep(api.load_sweep(path, raised), out)
    assert (result.ran, result.skipped) == (2, 0)
    for member in ("m00000", "m00001"):
        summary = json.loads((out / "members" / member / "summary.json").read_text())
        assert summary["restarts"] == 1 and summary["status"] == "completed"
        assert sorted(p.name for p in (out / "members" / member).iterdir()) == [
            "probes.csv",
            "summary.json",
        ]
    whole = api.sweep(api.load_sweep(path, raised), tmp_path / "whole")
    assert whole.ran == 2

    def strip(table):
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in read_table(table)]

    assert strip(out / "sweep.csv") == strip(tmp_path / "whole" / "sweep.csv")
    assert api.sweep(api.load_sweep(path, raised), out).ran == 0  # finished now
    # The table's parts hold each member's stopped row and its row run again; read without
    # sweep.csv (a sweep killed while it continued them), the later row replaces the stopped
    # one: plot gave "a row of member 0, twice" before the readers shared the rule.
    from cosserat_fem.io.sweep_table import read_sweep_rows

    (out / "sweep.csv").unlink()
    parts = [
        row for part in sorted((out / "table").glob("group-*.csv")) for row in read_table(part)
    ]
    assert sorted(r["status"] for r in parts) == ["completed"] * 2 + ["stopped"] * 2
    assert [r["status"] for r in read_sweep_rows(out)[1]] == ["completed", "completed"]
    assert main(["plot", str(out), "--quiet"]) == 0


def test_a_member_whose_folder_cannot_be_made_stops_and_runs_later(tmp_path):
    """members/ taken by a file: no member's folder can be made, a passing reason (a full
    disk, a permission): each member "stopped", the sweep StopError (exit 4; before:
    "error" rows recorded as finished, exit 0, and "ran 0" once the cause was gone). With
    the file gone, the sweep runs them all."""
    from cosserat_fem.common.errors import StopError

    path = sweep_file(tmp_path, '[sweep.vary]\n"time.step" = [1e-5, 2e-5]\n')
    out = tmp_path / "out"
    out.mkdir()
    (out / "members").write_text("in the way", encoding="utf-8")
    with pytest.raises(StopError, match="^sweep: 2 members stopped"):
        api.sweep(api.load_sweep(path), out)
    rows = read_table(out / "sweep.csv")
    assert [r["status"] for r in rows] == ["stopped", "stopped"]
    assert rows[0]["message"].startswith("OutputError: sweep: cannot make ")
    (out / "members").unlink()
    result = api.sweep(api.load_sweep(path), out)
    assert (result.ran, result.skipped) == (2, 0)
    assert [r["status"] for r in read_table(out / "sweep.csv")] == ["completed", "completed"]


def chain_sweep(folder: Path, max_periods: int) -> Path:
    """A frequency response of the paper's scene (no XDMF), one chain of two members (r = 1,
    1.1, continued), 16 steps a period, at most ``max_periods`` periods."""
    path = folder / "chain.toml"
    path.write_text(
        f'[sweep]\nscene = "{PAPER}"\nkeep = "probes"\n[sweep.set]\n'
        '"output.xdmf" = false\n[sweep.vary]\n"parameters.r" = [1.0, 1.1]\n'
        '[sweep.response]\nperiod = "2*pi/(8*r*omega0)"\n'
        'continuation = "parameters.r"\nsteps_per_period = 16\n'
        f"max_periods = {max_periods}\n",
        encoding="utf-8",
    )
    return path


def test_a_chain_stops_at_its_stopped_member_and_continues_from_it(tmp_path):
    """A continued frequency response whose first member stops (limits.wall_time: 0.01 s,
    above the estimated 7 ms of its longest run of 128 steps, below what building it
    takes): the chain stops there, its second member is not run from rest (StopError:
    "1 member stopped ... and 1 not run after them"). Started again with the limit raised,
    the first runs from its start (a forced member's measurement is not in a checkpoint) and
    the second continues its final state: the table is the uninterrupted sweep's (all but
    the wall times)."""
    from cosserat_fem.common.errors import StopError

    path = chain_sweep(tmp_path, max_periods=8)
    out = tmp_path / "out"
    with pytest.raises(
        StopError,
        match=r"^sweep: 1 member stopped \(member 0: LimitReached: .*"
        r"\) and 1 not run after them; start the sweep again",
    ):
        api.sweep(api.load_sweep(path, ["limits.wall_time=0.01"]), out)
    assert [r["status"] for r in read_table(out / "sweep.csv")] == ["stopped"]
    result = api.sweep(api.load_sweep(path, ["limits.wall_time=1000"]), out)
    assert (result.ran, result.skipped) == (2, 0)
    api.sweep(api.load_sweep(path), tmp_path / "whole")

    def strip(table):
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in read_table(table)]

    assert strip(out / "sweep.csv") == strip(tmp_path / "whole" / "sweep.csv")
    assert [r["previous"] for r in read_table(out / "sweep.csv")] == ["", "0"]


#: A sweep whose table parts are found damaged at its end, on world rank 0 alone (which reads
#: them to write sweep.csv): its first reading (the sweep's start) is the real one.
DAMAGED_AT_THE_END = """
import sys
from cosserat_fem.studies import sweep_run
from cosserat_fem.cli import main
from cosserat_fem.common.errors import SceneError
real, calls = sweep_run._finished, []
def finished(out):
    calls.append(out)
    if len(calls) > 1:
        raise SceneError("table/group-1.csv: line 3: damaged while the sweep ran (a test)")
    return real(out)
sweep_run._finished = finished
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.mpi
def test_a_table_damaged_at_the_sweeps_end_is_every_ranks_error(tmp_path):
    """World rank 0 reads the table parts alone at the sweep's end to write sweep.csv; a part
    it could not read (damaged meanwhile) raised there alone, and the other rank waited in its
    next collective call until the 10 s abort (MPI_ABORT, no one-line error). Now rank 0's
    finding is agreed: exit 2 on both ranks, one line naming the part."""
    path = sweep_file(tmp_path, '[sweep.vary]\n"time.step" = [1e-5, 2e-5]\n')
    proc = run_command(
        ["-c", DAMAGED_AT_THE_END, "sweep", str(path), "--out", str(tmp_path / "out")], 2
    )
    ours = [line for line in proc.stderr.splitlines() if line.startswith("cosserat-fem: error")]
    assert proc.returncode == 2, proc.stderr
    assert ours == [
        "cosserat-fem: error: table/group-1.csv: line 3: damaged while the sweep ran (a test)"
    ], proc.stderr
    assert "aborting the MPI job" not in proc.stderr and "MPI_ABORT" not in proc.stderr


def test_changes_make_the_same_sweep_over_other_values():
    """``cf.load_sweep(..., changes=...)`` (the demos' --values): the sweep file's [sweep.vary]
    replaced by other values gives exactly the members a file with those values would, the
    rest of the file kept (its [sweep.set], its response); [sweep.rom] merged key by key; what
    comes out is checked as a file's table (a bad change: one line naming the key)."""
    path = ROOT / "scenes" / "sweeps" / "clamped_hysteresis.toml"
    spec = api.load_sweep(path, changes={"vary": {"parameters.r": [1.0, 1.05]}})
    whole = api.load_sweep(path)
    assert [m.values["parameters.r"] for m in spec.members[:2]] == [1.0, 1.05]
    assert spec.response == whole.response and spec.base == whole.base
    rom = ROOT / "scenes" / "sweeps" / "rom_forcing.toml"
    changed = api.load_sweep(rom, changes={"rom": {"train": [0, 2]}})
    assert (
        changed.rom.train == (0, 2) and changed.rom.tolerance == api.load_sweep(rom).rom.tolerance
    )
    varied = {"parameters.r": api.UNSET, "parameters.F": [5000.0, 6000.0]}
    other = api.load_sweep(path, changes={"vary": varied, "response": api.UNSET})
    # UNSET removes a key: F varied instead of r, and no frequency response
    assert other.varied == ("parameters.F",) and len(other.members) == 2
    with pytest.raises(SceneError, match=r"^sweep\.scene: required, the base scene file"):
        api.load_sweep(path, changes={"scene": {"x": 1}})
