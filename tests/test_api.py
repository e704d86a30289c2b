"""The Python API (cosserat_fem/api.py): the README's example runs, and its arrays are the
command line's numbers.

The arrays in memory and the files of the same run come from the same floating-point
operations, so they are compared exactly: probes.csv prints the values with 17 significant
digits (the value read back is the value written) and t with 11 (k Δt has at most 6 here,
so 1e-15 s).
"""

from __future__ import annotations

import os
import re

import numpy as np
import pytest
from conftest import ROOT, run_command

import cosserat_fem as cf
from cosserat_fem.cli import main
from cosserat_fem.errors import SceneError

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"


def readme_example() -> str:
    """The Python block after the marker ``<!-- python-api-example -->`` in README.md."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    found = re.search(r"<!-- python-api-example -->\s*```python\n(.*?)```", text, re.S)
    assert found, "README.md has no marked Python example"
    return found.group(1)


def test_the_readme_example_runs(capsys):
    """At most 15 lines, run as written from the repository's folder (its paths are
    relative to it); it prints the free end, the field along the rod, the frequencies and
    the rolled-up tip."""
    code = readme_example()
    assert len(code.strip().splitlines()) <= 15
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        exec(compile(code, "README.md", "exec"), {})
    finally:
        os.chdir(cwd)
    out = capsys.readouterr().out
    assert "free end at t = 0.0030 s" in out and "frequencies [Hz]" in out
    the_readme_numbers_hold(out)


def printed(out: str, label: str) -> np.ndarray:
    """The numbers printed after ``label`` on its line of ``out``."""
    (line,) = [x for x in out.splitlines() if x.startswith(label)]
    number = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
    return np.array([float(v) for v in re.findall(number, line[len(label):])])


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
    assert main(["run", str(SCENE), "--out", str(tmp_path / "cli"), "--quiet",
                 "--set", "time.end=0.0015", "--set", "output.xdmf=false"]) == 0  # fmt: skip
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
