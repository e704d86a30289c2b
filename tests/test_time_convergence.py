"""Orders in time against the closed-form Timoshenko response.

The paper's cantilever with its load scaled down 10x (so that the geometric nonlinearity, which
scales with the load squared, falls to ~2e-6 relative) over 0 ≤ t ≤ 6 ms, 16 cubic elements.
The floor of the comparison (space and nonlinearity) is 6e-7: SDIRK4 at Δt = 10 μs measures
5.9e-7 and stops improving. Time errors at the steps used are 2.6e-5 to 1e-2, at least 40x that
floor, so the observed order log2(e(2Δt)/e(Δt)) measures the integrator alone (the floor moves
it by at most 0.04).

* BDF2 and generalized-α are second order: measured 1.995 (BDF2), 2.012 (ρ∞ = 0.8) and 1.992
  (ρ∞ = 0) at Δt = 40 → 20 μs; required 2 ± 0.03. What moves an observed order off 2 here:
  the floor, by at most 0.005 at these steps (6e-7 against errors of 1.3e-4 to 6e-4 at
  20 μs), and the higher terms of the time error, e = C Δt² (1 + O(Δt)), whose effect is
  largest at the coarsest pair and does not grow as Δt halves: 1.981, 2.012, 1.974 at
  80 → 40 μs (within 0.026), then within 0.012 at 40 → 20 μs, and 2.002, 2.022, 2.002 at
  20 → 10 μs, where the floor's share reaches 0.02 for generalized-α. A first-order error
  term as large as the second-order one at 20 μs would make it log2(6/2) = 1.58.
* SDIRK3 is third order: measured 2.91 at Δt = 80 → 40 μs. Its stages are only first-order
  accurate (stage order 1), and on the stiff semi-discrete rod (axial and shear modes with
  ω Δt ≫ 1, driven by the load) SDIRK methods lose order as Δt shrinks: 2.86 at 40 → 20 μs.
  SDIRK4 shows it more (3.12, then 2.70), which is why it is not tested here but by
  manufactured solutions on a stocky rod (tests/test_mms.py, 3.99). 3 ± 0.15 for SDIRK3.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.reference.rod_planes import sine_load_tip_response
from cosserat_fem.scene.build import load_scene

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
    run_scene(scene, out)
    data = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    t, x = data[:, 0], data[:, 1]
    x_ref, _ = sine_load_tip_response(scene, t, q0=2e2, omega=8 * scene.omega0)
    return float(np.sqrt(np.mean((x - x_ref) ** 2) / np.mean(x_ref**2)))


SECOND = ((4e-5, 2e-5), 2.0, 0.03)


@pytest.mark.parametrize(
    ("integrator", "steps_order_tolerance"),
    [
        (["time.integrator=bdf2"], SECOND),
        (["time.integrator=generalized-alpha", "time.rho_inf=0.8"], SECOND),
        (["time.integrator=generalized-alpha", "time.rho_inf=0.0"], SECOND),
        (["time.integrator=sdirk3"], ((8e-5, 4e-5), 3.0, 0.15)),
    ],
    ids=["bdf2", "galpha-0.8", "galpha-0.0", "sdirk3"],
)
def test_order_in_time(tmp_path, integrator, steps_order_tolerance):
    steps, expected, tolerance = steps_order_tolerance
    errors = [tip_error(tmp_path, integrator + [f"time.step={dt}"]) for dt in steps]
    order = math.log2(errors[0] / errors[1])
    assert 2e-5 < errors[1] < 1e-2, errors  # well above the spatial and nonlinear floors
    assert abs(order - expected) < tolerance, (errors, order)
