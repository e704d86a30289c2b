"""Checkpoint/restart: a stopped run continues from its last checkpoint and gives the outputs
of an uninterrupted run, identically.

Every input of the remaining steps is restored (cosserat_fem/io/checkpoint.py): U, the
integrator's history, the Newton policy's state and the coefficients a reused Jacobian was
assembled from, the loop's position and, for adaptive steps, the step size, the error
estimate's past states and the field peaks. The same operations on the same numbers give the
same bits, so the tests ask for equality, not a tolerance: probes.csv byte for byte, the XDMF
frames value for value, and the same Newton iterations and Jacobians. Any state left out
shows: a Jacobian re-assembled at the restart state instead of the saved one moves the
modified-Newton iterates by about the Newton tolerance (1e-8 relative), a predictor without
its past rates costs iterations and changes the last bits, a lost step size changes the
adaptive step sequence.

The crash is an exception raised by an observer at step 130, after the checkpoints at steps
50 and 100 (checkpoint_interval = 50 steps): the run stops like a killed one (no final
checkpoint; the rows and frames of steps 101-130 are on disk and must be cut back; SIGKILL
itself is tests/test_kill.py). 200 steps of the paper's scene at Δt = 30 μs (BDF2 and
generalized-α at 15 μs).
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import ROOT, inject_newton_failures, run_command
from xdmf_files import read_xdmf

from cosserat_fem.analysis.restart import check_restart_scene, restart_overrides
from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.checkpoint import load_checkpoint
from cosserat_fem.scene.build import load_scene, scene_from_dict

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
CLI = ["-m", "cosserat_fem.cli"]
CRASH_STEP = 130

CONFIGS = {
    "sdirk3-frozen": ["time.step=3e-5"],
    "sdirk4-lagged": ["time.integrator=sdirk4", "solver.jacobian=lagged", "solver.lag=7"],
    "bdf2-full": ["time.integrator=bdf2", "time.step=1.5e-5", "solver.jacobian=full"],
    "generalized-alpha-frozen": ["time.integrator=generalized-alpha", "time.step=1.5e-5"],
    "sdirk3-adaptive": ["time.adaptive=true", "time.rtol=1e-5", "time.step=3e-5"],
    "generalized-alpha-adaptive": [
        "time.integrator=generalized-alpha",
        "time.adaptive=true",
        "time.rtol=1e-4",
        "solver.jacobian=lagged",
    ],
}


def scene_of(name: str, steps: int = 200):
    settings = CONFIGS[name]
    step = float(next((s.split("=")[1] for s in settings if s.startswith("time.step=")), 3e-5))
    return load_scene(
        SCENE,
        [
            *settings,
            f"time.end={steps * step!r}",
            f"output.checkpoint_interval={50 * step!r}",
            f"output.xdmf_interval={8 * step!r}",
        ],
    )


class Crash(RuntimeError):
    pass


def crash_at(step: int):
    def observer(k, t, model):
        if k == step:
            raise Crash(f"crash at step {k}")

    return observer


def outputs(out):
    summary = json.loads((out / "summary.json").read_text())
    return (out / "probes.csv").read_bytes(), read_xdmf(out / "solution.xdmf"), summary


@pytest.mark.parametrize("name", list(CONFIGS))
def test_restart_after_a_crash_gives_the_uninterrupted_run(tmp_path, name):
    scene = scene_of(name)
    run_scene(scene, tmp_path / "whole")
    probes, frames, summary = outputs(tmp_path / "whole")

    out = tmp_path / "crashed"
    with pytest.raises(Crash):
        run_scene(scene, out, observers=(crash_at(CRASH_STEP),))
    rows_on_disk = (out / "probes.csv").read_bytes().count(b"\n") - 1
    assert rows_on_disk == CRASH_STEP + 1  # the rows after the checkpoint are there to cut

    checkpoint = load_checkpoint(out)
    assert checkpoint.meta["generation"] == 2
    dt = scene.time.step
    if scene.time.adaptive:  # at the first accepted step from 100 Δt on
        assert 100 * dt * (1 - 1e-12) <= checkpoint.time < CRASH_STEP * dt
    else:
        assert checkpoint.time == pytest.approx(100 * dt, rel=1e-12)
    steps_done = int(checkpoint.time / dt * (1 + 1e-12))
    assert checkpoint.meta["outputs"]["probe_rows"] == steps_done + 1
    assert checkpoint.meta["outputs"]["xdmf_frames"] == steps_done // 8 + 1
    again = scene_from_dict(checkpoint.meta["scene"])
    assert again == scene
    result = run_scene(again, restart=checkpoint)
    assert result.summary["restarted_from_s"] == checkpoint.time
    assert result.summary["restarts"] == 1

    probes_r, frames_r, summary_r = outputs(out)
    assert probes_r == probes  # byte for byte
    for field in ("displacement", "angles"):
        times, values = frames[field]
        times_r, values_r = frames_r[field]
        assert len(times) == 26
        assert np.array_equal(times_r, times) and np.array_equal(values_r, values)
    assert np.abs(frames["displacement"][1]).max() > 1e-4  # the rod moved: a real comparison
    # The restarted run's counters continue the first run's: the same totals.
    for key in ("accepted_steps", "rejected_steps", "smallest_step_s", "largest_step_s"):
        assert summary_r[key] == summary[key], key
    for key in ("solves", "iterations", "jacobian_assemblies", "retries"):
        assert summary_r["newton"][key] == summary["newton"][key], key
    # One file a frame (cosserat_fem/io/xdmf.py): the restarted run's frames in new files.
    frames_dir = out / "solution.frames"
    expected = {"mesh.h5", *(f"{i:06d}.h5" for i in range(len(frames["displacement"][0])))}
    assert {p.name for p in frames_dir.iterdir()} == expected


def test_extending_a_completed_run(tmp_path):
    """A completed run keeps a checkpoint at its end: --set time.end=... continues it, as if it
    had been planned that long (fixed steps: the same steps)."""
    scene = scene_of("sdirk3-frozen")
    longer = scene_of("sdirk3-frozen", steps=300)
    run_scene(longer, tmp_path / "whole")
    run_scene(scene, tmp_path / "short")
    checkpoint = load_checkpoint(tmp_path / "short")
    assert checkpoint.time == pytest.approx(scene.time.end, rel=1e-12)
    more = scene_from_dict(checkpoint.meta["scene"], overrides=[f"time.end={longer.time.end!r}"])
    run_scene(more, restart=checkpoint)
    assert (tmp_path / "short/probes.csv").read_bytes() == (
        tmp_path / "whole/probes.csv"
    ).read_bytes()


def test_a_failed_run_continues_from_its_last_accepted_step(tmp_path, monkeypatch):
    """Every solve from step 50 on fails: the run stops after max_halvings = 3 halvings with a
    checkpoint of the last accepted state (t = 49 Δt) and the halving level it reached. The
    restart, with the trouble gone, takes step 50 in eighths and then goes on at Δt: its free
    end differs from an undisturbed run by the local error of that one step, ~1e-7 of the
    maxima (tests/test_step_rejection.py measured 2.4e-7 for three such steps); allowed 1e-5."""
    scene = load_scene(
        SCENE, ["time.end=0.006", "time.max_halvings=3", "output.checkpoint_interval=0"]
    )
    run_scene(scene, tmp_path / "whole")
    inject_newton_failures(monkeypatch, lambda n: n > 2 * 49)
    out = tmp_path / "failed"
    with pytest.raises(Exception, match="Newton did not converge"):
        run_scene(scene, out)
    monkeypatch.undo()
    checkpoint = load_checkpoint(out)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert checkpoint.time == summary["time_reached_s"] == pytest.approx(49 * 3e-5, rel=1e-12)
    assert checkpoint.parts["loop"]["level"] == 3
    result = run_scene(scene_from_dict(checkpoint.meta["scene"]), restart=checkpoint)
    assert result.summary["status"] == "completed"
    assert result.summary["smallest_step_s"] == pytest.approx(3e-5 / 8)
    whole = np.loadtxt(tmp_path / "whole/probes.csv", delimiter=",", skiprows=1)
    data = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    assert data.shape == whole.shape
    assert np.array_equal(data[:50], whole[:50])  # up to the failure: the same run
    for j in (1, 2):
        scale = np.abs(whole[:, j]).max()
        assert np.abs(data[:, j] - whole[:, j]).max() <= 1e-5 * scale


# Long set (make test within 3 minutes): make test keeps the serial restarts byte for byte.
@pytest.mark.long
@pytest.mark.mpi
def test_restart_under_mpi(tmp_path):
    """mpirun -n 2: the same bytes as an uninterrupted 2-rank run, through the command line;
    a 1-rank restart of the 2-rank checkpoint is refused with the reason (exit status 2). 40
    steps, a checkpoint every 10, a frame every 8: a run on two ranks of this small rod is a
    few MPI messages a step, slow on a busy machine (200 steps took 19-58 s at load 5-9)."""
    settings = ["time.end=0.0012", "output.checkpoint_interval=0.0003"]
    sets = [a for s in settings for a in ("--set", s)]
    whole, part = tmp_path / "whole", tmp_path / "part"
    run_command([*CLI, "run", str(SCENE), "--out", str(whole), *sets], ranks=2)
    run_command(
        [*CLI, "run", str(SCENE), "--out", str(part), *sets, "--set", "time.end=0.0006"], ranks=2
    )
    again = ["--set", "time.end=0.0012"]
    refused = run_command([*CLI, "run", "--restart", str(part), *again], ranks=1)
    assert refused.returncode == 2
    assert "written by 2 MPI ranks" in refused.stderr and "Traceback" not in refused.stderr
    done = run_command([*CLI, "run", "--restart", str(part), *again], ranks=2)
    assert done.returncode == 0, done.stderr
    assert (part / "probes.csv").read_bytes() == (whole / "probes.csv").read_bytes()
    assert read_xdmf(part / "solution.xdmf")["angles"][1].tolist() == (
        read_xdmf(whole / "solution.xdmf")["angles"][1].tolist()
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (["--set", "time.end=0.004"], "no checkpoint in"),
        (["--set", "discretisation.elements=4"], "--set discretisation.elements: cannot change"),
        (["--set", "time.step=1e-5"], "--set time.step: cannot change on --restart"),
    ],
)
def test_restart_bad_input(tmp_path, args, message):
    """One line naming the problem, exit status 2, no traceback."""
    empty = tmp_path / "empty"
    empty.mkdir()
    proc = run_command([*CLI, "run", "--restart", str(empty), *args])
    assert proc.returncode == 2
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_restart_of_a_completed_run_needs_a_later_end(tmp_path):
    run_scene(scene_of("sdirk3-frozen", steps=20), tmp_path)
    proc = run_command([*CLI, "run", "--restart", str(tmp_path)])
    assert proc.returncode == 2 and "time.end: the checkpoint is at t = 0.0006 s" in proc.stderr


def test_restart_overrides():
    restart_overrides(["time.end=1", "solver.jacobian=full", "output.checkpoint_interval=0"])
    for key in ("rod.length", "time.integrator", "output.xdmf", "solverx.y"):
        with pytest.raises(SceneError, match=f"--set {key}: cannot change on --restart"):
            restart_overrides([f"{key}=1"])


def test_a_checkpoint_from_before_a_key_existed_continues_at_its_default():
    """A checkpoint written before a scene key was added (here ``time.impact_steps``) ran as
    the key's default says: a restart at the default continues it, another value is refused
    naming the key (check_restart_scene)."""
    scene = scene_of("bdf2-full")
    held = json.loads(json.dumps(scene.to_dict()))
    del held["time"]["impact_steps"]
    checkpoint = SimpleNamespace(meta={"scene": held}, time=0.5 * scene.time.end)
    check_restart_scene(checkpoint, scene)
    changed = scene_from_dict(scene.to_dict(), overrides=["time.impact_steps=false"])
    with pytest.raises(SceneError, match="time.impact_steps: false where the checkpoint's run"):
        check_restart_scene(checkpoint, changed)
