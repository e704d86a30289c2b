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
from conftest import ROOT

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
