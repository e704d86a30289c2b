"""The Python API (cosserat_fem/api.py): the README's example runs, and its arrays are the
command line's numbers.

The arrays in memory and the files of the same run come from the same floating-point
operations, so they are compared exactly: probes.csv prints the values with 17 significant
digits (the value read back is the value written) and t with 11 (k Δt has at most 6 here,
so 1e-15 s).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_command

import cosserat_fem as cf
from cosserat_fem.cli import main
from cosserat_fem.common.errors import SceneError

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"


def readme_example() -> str:
    """The Python block after the marker ``<!-- python-api-example -->`` in README.md."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    found = re.search(r"<!-- python-api-example -->\s*```python\n(.*?)```", text, re.S)
    assert found, "README.md has no marked Python example"
    return found.group(1)


def test_the_readme_example_runs(capsys, tmp_path, monkeypatch):
    """At most 15 lines, run as written from another folder than the repository's (its
    scene paths were relative to the repository's folder, and failed anywhere else); it
    prints the free end, the field along the rod, the frequencies and the rolled-up tip, and
    no negative zero (the rolled-up tip's x printed "-0." where round-off leaves -1e-17)."""
    code = readme_example()
    assert len(code.strip().splitlines()) <= 15
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "free end at t = 0.0030 s" in out and "frequencies [Hz]" in out
    numbers = re.findall(r"-?\d+\.?\d*(?:e[+-]?\d+)?", out)
    assert not [n for n in numbers if n.startswith("-") and float(n) == 0.0], out
    the_readme_numbers_hold(out)


def printed(out: str, label: str) -> np.ndarray:
    """The numbers printed after ``label`` on its line of ``out``."""
    (line,) = [x for x in out.splitlines() if x.startswith(label)]
    number = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
    return np.array([float(v) for v in re.findall(number, line[len(label) :])])


def the_readme_numbers_hold(out: str) -> None:
    """What the README's example prints, against independent values.

    * The free end's x at t = 3 ms and x at σ = 0, ¼, ½, ¾, 1: the closed-form linear
      Timoshenko response from rest (exact modal superposition,
      cosserat_fem/reference/timoshenko.py), within 1e-3 of its largest |x| so far, the bound
      tests/test_demos.py derives for the whole 0.06 s (the discretisation's 3.2e-4 and the
      nonlinearity's 1.2e-4, both growing with the horizon), plus the printed rounding (five
      digits; 1e-7 m). Measured 3e-5. The clamp prints 0.
    * The four lowest frequencies: the Timoshenko frequency equation of each bending plane
      (reference/rod_planes.py), within 1e-3 (tests/test_modes.py's bound at the default
      mesh, from the h^6 estimate; measured ≤ 1.7e-5) plus the printed 0.005 Hz.
    * The rolled-up tip (x, z): the clamp's (0, −ℓ), within the scene's 1e-8 ℓ
      (tests/test_scenes.py) plus the printed 5e-10 m."""
    from cosserat_fem.reference.rod_planes import linear_spectrum, sine_load_response

    scene = cf.load(SCENE, {"time.end": 0.003})
    (t, x_tip) = printed(out, "free end at t = ")
    assert t == 0.003
    stations = np.linspace(0.0, 1.0, 5)
    times = np.linspace(0.0, t, 301)
    linear, _ = sine_load_response(scene, times, 2e3, 8 * scene.omega0, stations * scene.rod.length)
    largest = np.abs(linear).max()
    assert x_tip == pytest.approx(linear[-1, -1], abs=1e-3 * largest + 5e-5 * abs(x_tip))
    along = printed(out, "x along the rod [m]:")
    assert along.shape == (5,) and along[0] == 0.0
    np.testing.assert_allclose(along, linear[-1], rtol=0, atol=1e-3 * largest + 5e-8)
    hertz = printed(out, "frequencies [Hz]:")
    closed = np.array([w / (2 * np.pi) for w, _ in linear_spectrum(scene, 4)])
    assert (np.abs(hertz - closed) <= 1e-3 * closed + 0.005).all(), (hertz, closed)
    rolled = printed(out, "rolled-up tip (x, z) [m]:")
    np.testing.assert_allclose(rolled, [0.0, -1.0], rtol=0, atol=1e-8 + 5e-10)


def test_arrays_equal_the_command_lines_files(tmp_path):
    """cf.run's probes equal the probes.csv that `cosserat-fem run` writes for the same
    scene, and its sampled field at σ = 1 equals the probes' x, y, z, θ, ψ, φ there: the
    probe reads the node's value, the sampler evaluates the cell's Lagrange basis there (1
    and 0 to a few ulp), so they agree to 1e-12 of the largest value; out= writes the same
    files as the command line."""
    overrides = {"time.end": 0.0015, "output.xdmf": False}
    result = cf.run(cf.load(SCENE, overrides), fields=[0.0, 0.5, 1.0], field_every=10)
    assert (
        main(
            [
                "run",
                str(SCENE),
                "--out",
                str(tmp_path / "cli"),
                "--quiet",
                "--set",
                "time.end=0.0015",
                "--set",
                "output.xdmf=false",
            ]
        )
        == 0
    )
    rows = np.loadtxt(tmp_path / "cli" / "probes.csv", delimiter=",", skiprows=1)
    assert result.probes.shape == rows.shape == (51, 7)
    assert np.array_equal(result.probes[:, 1:], rows[:, 1:])
    assert np.abs(result.probes[:, 0] - rows[:, 0]).max() <= 1e-15
    assert result.field_times.tolist() == pytest.approx(result.probes[::10, 0].tolist(), abs=0)
    tip = result.probes[::10, 1:]
    assert np.abs(result.field_values[:, 2, :] - tip).max() <= 1e-12 * np.abs(tip).max()
    clamped = np.abs(result.field_values[:, 0, :]).max()  # 0 at the node, a few ulp nearby
    assert clamped <= 1e-12 * np.abs(tip).max()
    cf.run(cf.load(SCENE, overrides), out=tmp_path / "api")
    assert (tmp_path / "api" / "probes.csv").read_bytes() == (
        tmp_path / "cli" / "probes.csv"
    ).read_bytes()


def test_the_public_run_has_the_command_lines_defaults(tmp_path):
    """cf.run (the one public run; cosserat_fem/analysis/simulation.py's run_scene is internal) with
    only a scene and a folder runs what `cosserat-fem run` runs: every key of summary.json is
    the same but the run's identity, its wall times and the Newton solver's timers (the
    scene, integrator, solver loop, LU package, steps and every Newton count: the same
    operations in the same order), and probes.csv is the same bytes."""
    assert (
        main(
            [
                "run",
                str(SCENE),
                "--out",
                str(tmp_path / "cli"),
                "--quiet",
                "--set",
                "time.end=0.0006",
            ]
        )
        == 0
    )
    result = cf.run(cf.load(SCENE, {"time.end": 0.0006}), tmp_path / "api")
    cli = json.loads((tmp_path / "cli" / "summary.json").read_text())
    api = json.loads((tmp_path / "api" / "summary.json").read_text())
    assert api == result.summary and api["kind"] == "run" and api["status"] == "completed"
    timers = {k for k in api["newton"] if k.startswith("time")}
    for summary in (cli, api):
        for key in ("run_id", "wall_time_s"):
            summary.pop(key)
        for key in timers:
            summary["newton"].pop(key)
    assert api == cli
    assert (tmp_path / "api" / "probes.csv").read_bytes() == (
        tmp_path / "cli" / "probes.csv"
    ).read_bytes()


def test_run_static_and_modes_write_one_summary(tmp_path):
    """One summary (cosserat_fem/analysis/observers.py: summary_start, RunSummary): summary.json of
    a run and of a static solve and modes.json carry the same identity (version, scene file
    and its SHA-256, ranks, Python, the scene) with the same values, and each its kind; run
    and static the same discretisation keys and values, the same Newton counters and the
    same wall-time parts; static writes no checkpoint, the run does. Static's Newton
    iterations in all are the sum of its load steps' (the same solves counted twice), and its
    wall times add up: setup + solve loop ≤ total (three differences of one clock's readings,
    taken in that order; 1e-9 s of rounding)."""
    scene = cf.load(SCENE, {"time.end": 0.0003, "static.time": 0.002, "static.load_steps": 2})
    cf.run(scene, tmp_path / "run")
    cf.static(scene, tmp_path / "static")
    cf.modes(scene, 2, out=tmp_path / "modes")
    names = ("run/summary.json", "static/summary.json", "modes/modes.json")
    run, static, modes = (json.loads((tmp_path / name).read_text()) for name in names)
    assert (run["kind"], static["kind"], modes["kind"]) == ("run", "static", "modes")
    same = (
        "status",
        "cosserat_fem",
        "scene_file",
        "scene_file_sha256",
        "mpi_ranks",
        "python",
        "scene",
    )
    for key in same:
        assert run[key] == static[key] == modes[key], key
    for key in (
        "dofs",
        "elements",
        "degree",
        "quadrature_degree",
        "omega0_rad_s",
        "skipped_terms",
        "solved_unknowns",
        "groups",
        "probe_s_m",
        "probe_reference_position_m",
        "lu_package",
    ):
        assert run[key] == static[key], key
    assert static["checkpoints_written"] == 0 < run["checkpoints_written"]
    assert run["newton"].keys() == static["newton"].keys()
    assert run["wall_time_s"].keys() == static["wall_time_s"].keys()
    assert static["newton"]["iterations"] == sum(static["newton_iterations"]) > 0
    wall = static["wall_time_s"]
    assert wall["setup"] + wall["solve_loop"] <= wall["total"] + 1e-9


def test_overrides_as_a_mapping_or_as_strings():
    """A mapping of dotted keys and values is the same scene as the command line's
    strings; a bad one is a SceneError naming the key."""
    by_map = cf.load(SCENE, {"time.step": 1e-5, "loads.end.force": [0, 0, "1e3*t"]})
    by_text = cf.load(SCENE, ["time.step=1e-5", 'loads.end.force=[0, 0, "1e3*t"]'])
    assert by_map == by_text
    with pytest.raises(SceneError, match="time.stepp: unknown key"):
        cf.load(SCENE, {"time.stepp": 1})
    assert cf.load(cf.load(SCENE).to_dict(), {"time.end": 0.006}).time.end == 0.006


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"field_every": 0}, "field_every"),
        ({"field_every": 1.5}, "field_every"),
        ({"fields": [0.5, 1.2]}, "fields"),
        ({"fields": [float("nan")]}, "fields"),
        ({"fields": []}, "fields"),
        ({"fields": "abc"}, "fields"),
    ],
)
def test_bad_sampling_arguments_are_refused_before_any_work(kwargs, key):
    """A field_every of 0 would divide by zero at the first output, a station off the rod
    would fail only after the set-up: both refused at once, naming the argument."""
    with pytest.raises(SceneError, match=f"^{key}: "):
        cf.run(cf.load(SCENE, {"time.end": 0.0003}), **kwargs)


@pytest.mark.parametrize(
    ("call", "key"),
    [
        (lambda s, out: cf.modes(s, about="sideways"), "about"),
        (lambda s, out: cf.modes(s, count="3"), "count"),
        (lambda s, out: cf.modes(s, count=2.5), "count"),
        (lambda s, out: cf.run(s, out, progress=3), "progress"),
        (lambda s, out: cf.run(s, out, observers=[3]), "observers"),
        (lambda s, out: cf.static(s, out, observers=["x"]), "observers"),
        (lambda s, out: cf.sweep(None, out), "spec"),
        (lambda s, out: cf.load(3), "source"),
        (lambda s, out: cf.run(s, ""), "out"),
        (lambda s, out: cf.modes(s, 2, out=SCENE), "out"),
        (lambda s, out: cf.lyapunov(s, 1e-4, periods=2, out=out, foo=1), "foo"),
        (lambda s, out: cf.lyapunov_run(s, 1e-4, periods=2, out=out, evry=2), "evry"),
    ],
)
def test_bad_api_arguments_are_refused_by_name(tmp_path, call, key):
    """The API's arguments are refused as the command line's are, by name and before any
    work: a ValueError (about), TypeErrors (count, a load's source, a sweep that is not one)
    and failures at the first output time, after the run's folder was claimed (progress and
    observers that are not functions) were not; out="" wrote into the current folder; a
    misspelt option of lyapunov was a TypeError."""
    scene = cf.load(SCENE, {"time.end": 0.0003})
    with pytest.raises(SceneError, match=f"^{key}[ :]"):
        call(scene, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_bad_initial_state_is_refused_by_name(tmp_path):
    """A NaN in cf.run(initial_state=...) went into the first step and came back as "the
    residual is not finite ... check the magnitude of the loads" after six halvings; an
    array of the wrong size or not of numbers as an internal ValueError. Each is now a
    SceneError naming initial_state (the NaN's node and component), before the run starts.
    A state of the right size and finite values runs (the straight rod at rest: zeros)."""
    scene = cf.load(SCENE, {"time.end": 0.0003})
    nodes = cf.run(scene).model.nodes
    nan = np.zeros(12 * nodes)
    nan[12 * 3 + 4] = np.nan
    cases = [
        (nan, r"value 40 \(node 3, component 4 of 12\) is not finite"),
        (np.full(12 * nodes, np.inf), "value 0 .* is not finite"),
        ("x", "must be an array of numbers"),
        ([[1, 2], [3]], "must be an array"),
        (np.zeros(7), "7 values, expected 12 a node"),
        (np.zeros(12), "12 values"),
    ]
    for state, reason in cases:
        with pytest.raises(SceneError, match=f"^initial_state: {reason}"):
            cf.run(scene, tmp_path / "out", initial_state=state)
    assert cf.run(scene, initial_state=np.zeros(12 * nodes)).summary["status"] == "completed"


def test_every_api_name_stays_a_function_once_the_machinery_is_imported():
    """The package's API names (cosserat_fem.__init__._API) are the functions of api.py even
    after every module of the package has been imported: a submodule named like an API
    function (the sweep runner was ``cosserat_fem.sweep``) replaces the name on the package
    at its import, so a notebook's second ``cf.sweep(...)`` met a module."""
    import importlib
    import pkgutil

    from cosserat_fem import api

    for info in pkgutil.iter_modules(cf.__path__):
        importlib.import_module(f"cosserat_fem.{info.name}")
    for name in cf._API:
        assert getattr(cf, name) is getattr(api, name), name


#: cf.run, cf.static, cf.modes and cf.pod on every rank; each rank saves its arrays (to the
#: folder argv[1], as rank<r>.npz); the serial run of the same script saves rank0.npz.
ARRAYS_SCRIPT = """
import sys
from pathlib import Path
import numpy as np
from mpi4py import MPI
import cosserat_fem as cf
root, out = Path(sys.argv[1]), Path(sys.argv[2])
scene = cf.load(root / "scenes" / "cao_tucker_2008.toml", {"time.end": 0.0015})
stations = np.linspace(0.0, 1.0, 13)
result = cf.run(scene, fields=stations, field_every=5)
rolled = cf.static(cf.load(root / "scenes" / "rollup.toml"))
modes = cf.modes(scene, count=6)
pod = cf.pod(result, stations, modes=3, weighting="kinetic")
np.savez(out / f"rank{MPI.COMM_WORLD.rank}.npz", probes=result.probes,
         field_times=result.field_times, field_values=result.field_values,
         static_probes=rolled.probes, load_factors=np.array(rolled.load_factors),
         omega=np.array([m.omega for m in modes]),
         fractions=np.array([list(m.fractions.values()) for m in modes]),
         kinds=np.array([m.kind for m in modes]), pod_energies=pod.energies,
         pod_shapes=pod.shapes, pod_coefficients=pod.coefficients, pod_mean=pod.mean)
"""


@pytest.mark.mpi
@pytest.mark.long
def test_the_arrays_are_the_same_on_every_rank_and_the_serial_runs(tmp_path):
    """The README's promise for the API's arrays under ``mpirun -n 2``: every rank gets the
    same arrays, bit for bit (each is gathered, or reduced, or computed from gathered data
    alike on every rank), from cf.run (probes, sampled fields), cf.static (probes, load
    factors), cf.modes (ω, energy fractions, kinds) and cf.pod (energies, shapes,
    coefficients, mean). Against the serial run of the same script: the solvers' round-off
    (MUMPS against PETSc's LU), which tests/test_demos.py and tests/test_pod.py bound by 1e-10
    of each array's largest value for a run and its POD (measured ~1e-14); ω to the
    eigensolver's tolerance, 1e-9 relative as tests/test_modes.py. ~15 s (two processes
    compile and run four solves)."""
    for ranks, folder in ((2, tmp_path / "mpi"), (1, tmp_path / "serial")):
        folder.mkdir()
        proc = run_command(["-c", ARRAYS_SCRIPT, str(ROOT), str(folder)], ranks)
        assert proc.returncode == 0, proc.stderr[-3000:]
    ranks = [np.load(tmp_path / "mpi" / f"rank{r}.npz") for r in (0, 1)]
    serial = np.load(tmp_path / "serial" / "rank0.npz")
    assert sorted(ranks[0].files) == sorted(ranks[1].files) == sorted(serial.files)
    for name in serial.files:
        assert np.array_equal(ranks[0][name], ranks[1][name]), name
        got, expected = ranks[0][name], serial[name]
        assert got.shape == expected.shape, name
        if name == "kinds":
            assert got.tolist() == expected.tolist()
        elif name == "omega":
            np.testing.assert_allclose(got, expected, rtol=1e-9, atol=0)
        else:
            scale = np.abs(expected).max()
            assert np.abs(got - expected).max() <= 1e-10 * scale, name


# ------------------------------------------------------------------------------ restarts
RESTART_SETTINGS = {"time.end": 0.0015, "output.xdmf_interval": 3e-4}
TRIPLE = "6e3*sin(pi*s/L)*sin(8*omega0*t)"  # three times the paper's load


@pytest.fixture(scope="module")
def completed(tmp_path_factory):
    """A completed run of 50 steps (t = 1.5 ms) whose checkpoint is at its end."""
    folder = tmp_path_factory.mktemp("restart") / "run"
    cf.run(cf.load(SCENE, RESTART_SETTINGS), folder)
    return folder


def _copy(folder, tmp_path):
    import shutil

    return Path(shutil.copytree(folder, tmp_path / "copy"))


def _digests(folder) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        (
            {"rod.material.young_modulus": 3.55e10, "loads.force_density": [TRIPLE, TRIPLE, 0]},
            "rod.material.young_modulus",
        ),  # the splice: E halved, 3x the load
        ({"loads.force_density": [TRIPLE, 0, 0]}, "loads.force_density"),
        ({"discretisation.elements": 9}, "discretisation.elements"),
        ({"time.step": 1.5e-5}, "time.step"),
        ({"title": "another"}, "title"),
        ({"loads.end.force": [0, 0, 1]}, "loads.end"),
        ({"output.xdmf": False}, "output.xdmf"),
    ],
)
def test_a_restart_refuses_a_scene_that_is_not_the_checkpoints(completed, tmp_path, overrides, key):
    """cf.run(scene, restart=checkpoint) continued the checkpoint's state with any scene: E
    halved and three times the load gave a splice of two problems and a normal exit. Now a
    scene that differs from the checkpoint's run in a key a restart may not change is a
    SceneError naming that key, and the folder is as it was."""
    folder = _copy(completed, tmp_path)
    before = _digests(folder)
    scene, checkpoint = cf.resume(folder, {"time.end": 0.0018})
    other = cf.load(SCENE, {**RESTART_SETTINGS, "time.end": 0.0018, **overrides})
    with pytest.raises(SceneError, match=f"^{re.escape(key)}[.:]"):
        cf.run(other, restart=checkpoint)
    assert _digests(folder) == before


def test_a_restart_refuses_another_folder_and_an_initial_state(completed, tmp_path):
    """out= was silently ignored on a restart (the run went on in the checkpoint's folder) and
    so was initial_state: both are refused by name, and so are a restart that is not a
    checkpoint and a scene whose time.end does not pass the checkpoint; out= naming the
    checkpoint's folder is that folder, and the run goes on there (to 1.8 ms: 60 steps)."""
    folder = _copy(completed, tmp_path)
    before = _digests(folder)
    scene, checkpoint = cf.resume(folder, {"time.end": 0.0018})
    with pytest.raises(SceneError, match="^out: the run continues in its checkpoint's folder"):
        cf.run(scene, tmp_path / "elsewhere", restart=checkpoint)
    assert not (tmp_path / "elsewhere").exists()
    with pytest.raises(SceneError, match="^initial_state: cannot be given with restart"):
        cf.run(scene, restart=checkpoint, initial_state=np.zeros(1))
    with pytest.raises(SceneError, match="^restart: must be the checkpoint of cf.resume"):
        cf.run(scene, restart=str(folder))
    for end in (0.0012, 0.0015):  # at or before the checkpoint: nothing to continue
        earlier = cf.load(SCENE, {**RESTART_SETTINGS, "time.end": end})
        with pytest.raises(SceneError, match="^time.end: the checkpoint is at t = 0.0015 s"):
            cf.run(earlier, restart=checkpoint)
    assert _digests(folder) == before
    result = cf.run(scene, folder / ".", restart=checkpoint)
    assert result.summary["status"] == "completed" and result.steps == 60


def test_a_restart_may_unset_what_it_may_set(completed):
    """--unset on a restart (the command line's Removal, the API's UNSET): a key a restart may
    change returns to its default (limits.wall_time: a day); any other is refused as --set's
    are, naming --unset."""
    from cosserat_fem.scene.schema import Removal

    scene, _ = cf.resume(completed, [Removal("limits.wall_time"), "time.end=0.0018"])
    assert scene.limits.wall_time == 86400.0
    with pytest.raises(SceneError, match="^--unset rod.length: cannot change on --restart"):
        cf.resume(completed, [Removal("rod.length")])
    with pytest.raises(SceneError, match="^--unset rod.length: cannot change on --restart"):
        cf.resume(completed, {"rod.length": cf.UNSET})


@pytest.mark.parametrize("end", [0.001, 0.00101, 0.0015, 0.00151, 0.00155])
def test_a_restart_end_before_or_at_the_checkpoint_suggests_later_ends(completed, end):
    """time.end at or before the checkpoint (1.5 ms) was answered with "e.g. time.end =
    0.00099 or 0.00102", two ends before it; an end just after it that is not a whole
    number of steps (30 μs) with 0.0015, the checkpoint itself. Every end a refusal names
    is now later than the checkpoint: before it, the checkpoint's own message; after it, the
    whole numbers of steps around it that pass it."""
    with pytest.raises(SceneError, match="^time.end: ") as caught:
        cf.resume(completed, {"time.end": end})
    text = str(caught.value)
    if end <= 0.0015:
        assert "the checkpoint is at t = 0.0015 s; give a later end" in text
    suggested = [float(v) for v in re.findall(r"time\.end = ([0-9.e-]+)", text)]
    assert all(v > 0.0015 for v in suggested), text


# ------------------------------------------------------------------------------ a rank's error
ONE_RANK_FAILS = """
import sys
from mpi4py import MPI
import cosserat_fem as cf
scene = cf.load(sys.argv[1])
if MPI.COMM_WORLD.rank == 1:
    raise RuntimeError("rank 1 stops here")
cf.static(scene)  # collective: rank 0 waits in it for rank 1, which never comes
"""


@pytest.mark.mpi
@pytest.mark.long
def test_an_uncaught_error_on_one_rank_ends_the_job():
    """A script under ``mpirun -n 2`` whose rank 1 raises while rank 0 is in a collective call
    (cf.static builds the mesh) must end, not hang: before the API's exit watchdog
    (cosserat_fem/common/parallel.py ``install_exit_watchdog``) rank 1 waited in MPI_Finalize
    and rank 0 in the mesh's collectives until the test's hang limit. It ends within the
    watchdog's ABORT_AFTER = 10 s after the error (plus two start-ups, ~5 s here; the hang
    limit here is 300 s: two start-ups on a busy machine), non-zero, with rank 1's
    traceback. ~15 s."""
    proc = run_command(["-c", ONE_RANK_FAILS, str(SCENE)], ranks=2, timeout=300)
    assert proc.returncode != 0
    assert "RuntimeError: rank 1 stops here" in proc.stderr
