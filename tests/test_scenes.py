"""Every scene under scenes/ is valid and runs (scikit-fem's test_examples, for scenes).

Static scenes (those whose header comment says ``cosserat-fem static``) are solved with their
own settings, modal ones (``cosserat-fem modes``) give their first modes; dynamic ones run
their first 50 steps. Each must complete with finite probes that moved (or finite, positive
frequencies), so a scene broken by a change of the schema or the solver fails here.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem import api
from cosserat_fem.results import probe_columns
from cosserat_fem.scene import load_scene
from cosserat_fem.simulation import run
from cosserat_fem.statics import static_path

SCENES = sorted((ROOT / "scenes").glob("*.toml"))


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_scene_runs(tmp_path, path):
    scene = load_scene(path)
    if f"cosserat-fem modes scenes/{path.name}" in path.read_text():
        modes = api.modes(scene, count=8)
        assert all(np.isfinite(m.omega) for m in modes) and modes[-1].omega > 0.0
        return
    if f"cosserat-fem static scenes/{path.name}" in path.read_text():
        result = static_path(scene, tmp_path)
        assert result.summary["status"] == "completed"
        return
    end = scene.time.start + 50 * scene.time.step
    short = load_scene(path, [f"time.end={end!r}", "output.xdmf=false"])
    result = run(short, tmp_path)
    assert result.summary["status"] == "completed" and result.summary["steps"] == 50
    probes = np.loadtxt(tmp_path / "probes.csv", delimiter=",", skiprows=1)
    columns = probe_columns(short.output.probe_fields)
    assert probes.shape == (51, len(columns)) and np.isfinite(probes).all()
    assert np.abs(probes[-1, 1:4] - probes[0, 1:4]).max() > 0.0  # something moved
