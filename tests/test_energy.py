"""Energy: conservation in free vibration, and the work of the loads.

E = T + V of the rod and the power of its loads are UFL functionals (forms/energy.py).

* Free vibration: the paper's rod, released from rest in the static state under a large tip
  force (3e4, 2e4, 0) N (E = 6238 J, tip at (0.37, 0.12) ℓ), with generalized-α at ρ∞ = 1
  (no numerical dissipation). The largest energy drift over 10 ms shrinks at the method's order
  2 (measured 1.14e-5, 2.86e-6, 7.14e-7 for Δt = 40, 20, 10 μs); required within 0.1 of 2. At
  5 μs the Newton tolerance (stol = 1e-8) starts to show, so the study stops at 10 μs.
* Forced: the paper's load from rest; the change of energy equals the work of the loads,
  W = ∫ P dt (trapezoidal rule on the steps), up to a mismatch that shrinks at order 2
  (measured 1.44e-4, 3.59e-5, 8.98e-6 of max E); required within 0.1 of 2 and below 2e-4.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT
from rod_energy import EnergyMonitor, EnergyRecorder

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.analysis.statics import solve_static
from cosserat_fem.scene.build import load_scene

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
COMMON = [
    "output.xdmf=false",
    "time.integrator=generalized-alpha",
    "time.rho_inf=1.0",
    "solver.jacobian=full",
    "time.end=0.01",
    "solver.stol=1e-8",  # the tolerance the docstring argues from
]


def test_free_vibration_conserves_energy_at_order_two(tmp_path):
    unloaded = ["loads.force_density=[0,0,0]", "solver.stol=1e-8"]
    static, _ = solve_static(
        load_scene(SCENE, unloaded + ["loads.end.force=[3e4,2e4,0]", "static.load_steps=4"])
    )
    E0 = sum(EnergyMonitor(static).energies())
    drifts = []
    for dt in (4e-5, 2e-5, 1e-5):
        rec = EnergyRecorder()
        run_scene(
            load_scene(SCENE, unloaded + COMMON + [f"time.step={dt}"]),
            tmp_path,
            observers=(rec,),
            initial_state=static.U.x.array.copy(),
        )
        drifts.append(np.abs(np.array(rec.E) - E0).max() / E0)
    assert drifts[-1] < 1e-6
    for coarse, fine in zip(drifts[:-1], drifts[1:], strict=True):
        assert abs(math.log2(coarse / fine) - 2.0) < 0.1, drifts


def test_energy_change_equals_work_of_the_loads(tmp_path):
    mismatches = []
    for dt in (2e-5, 1e-5):
        rec = EnergyRecorder()
        run_scene(load_scene(SCENE, COMMON + [f"time.step={dt}"]), tmp_path, observers=(rec,))
        E = np.array([0.0, *rec.E])  # at rest at t = 0
        P = np.array([0.0, *rec.P])  # the load vanishes at t = 0
        W = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * dt)])
        mismatches.append(np.abs(E - W).max() / E.max())
    assert mismatches[-1] < 2e-4
    assert abs(math.log2(mismatches[0] / mismatches[1]) - 2.0) < 0.1, mismatches


# Long set (make test within 3 minutes): make test keeps the free vibration's conservation.
@pytest.mark.long
@pytest.mark.parametrize(
    "factors", [(1.0,) * 6, (1.5, 0.5, 0.5, 0.5, 1.5, 0.7)], ids=["one time", "six times"]
)
def test_damped_energy_loss_equals_the_dissipated_power(tmp_path, factors):
    """The large-amplitude release above (tip at (0.37, 0.12) ℓ, ψ = 0.58, θ = −0.18 rad), with
    viscous damping c_t (ζ1 = c_t/(2 ρ A ω1) = 1 %) and Kelvin–Voigt damping τ_d (ζ1 = τ_d ω1/2
    = 1 %): the energy lost equals the integral of the damping power P_d (forms/energy.py),
    E(t) − E0 = ∫ P_d dt. At this amplitude the Kelvin–Voigt rate v̇ = D q'_r + v × ŵ is not
    the linear one, so P_d is the nonlinear dissipation; a rate that were not the exact time
    derivative of the strain would not balance at all (without v × ŵ the "damping" feeds the
    rod: mismatch 40 E0, measured). With generalized-α at ρ∞ = 1 and the trapezoidal rule for
    ∫ P_d dt both errors are O(Δt²): measured 1.84e-4 and 4.77e-5 of E0 at Δt = 20 and 10 μs
    (order 1.95), required order 2 within 0.1 as above; the energy lost is 12 % of E0 (> 2 %)
    so that the balance is not met trivially. With six retardation times μ_i = τ_d × factors
    (per strain component, diag(μ) K ε̇; 1.5 for the x plane's shear 1 and bending 2, 0.5 for
    the y plane's and extension, 0.7 for torsion): the same balance, P_d = −ε̇ · diag(μ) K ε̇,
    which a μ_i applied to another component in the residual than in P_d would break;
    measured 1.91e-4 and 4.81e-5 (order 1.99), 13 % lost. (With μ3, μ6 = 2 and 3 τ_d the
    stiff axial and torsion modes are damped hard and 20 μs is not yet asymptotic: order 1.88,
    then 1.97 from 10 to 5 μs.)"""
    omega1 = 206.78
    area = 0.04 * 0.06
    damping = [
        f"damping.translational={2 * 0.01 * 2730.0 * area * omega1!r}",
        f"damping.retardation_time={[2 * 0.01 / omega1 * f for f in factors]!r}",
    ]
    unloaded = ["loads.force_density=[0,0,0]", "solver.stol=1e-8"]
    static, _ = solve_static(
        load_scene(SCENE, unloaded + ["loads.end.force=[3e4,2e4,0]", "static.load_steps=4"])
    )
    E0 = sum(EnergyMonitor(static).energies())
    mismatches, lost = [], None
    for dt in (2e-5, 1e-5):
        rec = EnergyRecorder()
        run_scene(
            load_scene(SCENE, unloaded + damping + COMMON + [f"time.step={dt}"]),
            tmp_path,
            observers=(rec,),
            initial_state=static.U.x.array.copy(),
        )
        E = np.array([E0, *rec.E])
        P = np.array([0.0, *rec.P])  # released from rest: no dissipation at t = 0
        W = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * dt)])
        mismatches.append(np.abs(E - E0 - W).max() / E0)
        lost = (E0 - E[-1]) / E0
    assert lost > 0.02
    assert abs(math.log2(mismatches[0] / mismatches[1]) - 2.0) < 0.1, mismatches
