"""Second order in time for BDF2 and generalized-α, against the closed-form Timoshenko response.

The paper's cantilever with its load scaled down 10x (so that the geometric nonlinearity, which
scales with the load squared, falls to ~2e-6 relative) over 0 ≤ t ≤ 6 ms, 16 cubic elements
(spatial error < 1e-5, benchmarks/convergence.py). Time errors at the steps used are 1e-4 to
1e-2, so the observed order log2(e(2Δt)/e(Δt)) measures the integrator alone. Both methods
are second order; measured orders are 1.99-2.02 for these steps, so we require 2 ± 0.1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem.reference.rod_planes import sine_load_tip_response
from cosserat_fem.scene import load_scene
from cosserat_fem.simulation import run

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
LOAD = "2e2*sin(pi*s/L)*sin(8*omega0*t)"
COMMON = [
    f'loads.force_density=["{LOAD}","{LOAD}",0]',
    "time.end=0.006",
    "output.xdmf=false",
    "discretisation.elements=16",
]


def tip_error(tmp_path, overrides: list[str]) -> float:
    scene = load_scene(SCENE, COMMON + overrides)
    out = tmp_path / "_".join(o.split("=")[-1] for o in overrides)
    run(scene, out)
    data = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    t, x = data[:, 0], data[:, 1]
    x_ref, _ = sine_load_tip_response(scene, t, q0=2e2, omega=8 * scene.omega0)
    return float(np.sqrt(np.mean((x - x_ref) ** 2) / np.mean(x_ref**2)))


@pytest.mark.parametrize(
    "integrator",
    [
        ["time.integrator=bdf2"],
        ["time.integrator=generalized-alpha", "time.rho_inf=0.8"],
        ["time.integrator=generalized-alpha", "time.rho_inf=0.0"],
    ],
    ids=["bdf2", "galpha-0.8", "galpha-0.0"],
)
def test_second_order_in_time(tmp_path, integrator):
    errors = [tip_error(tmp_path, integrator + [f"time.step={dt}"]) for dt in (4e-5, 2e-5)]
    order = math.log2(errors[0] / errors[1])
    assert 1e-4 < errors[1] < 1e-2, errors  # well above the spatial and nonlinear floors
    assert abs(order - 2.0) < 0.1, (errors, order)
