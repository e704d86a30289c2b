"""A rod dropped on a plane: no penetration, and the energy balance (issue 30; docs/contact.md,
"The dropped rod's energy").

The rod of tests/test_contact.py (L = 1 m, d = 0.02 m, E = 1e7 Pa, ρ = 1000 kg/m³, 10 cubic
cells, μ = 0.5, weight w = 3.082 N/m along −e1) over the plane x = −r, dropped

* flat from 1 mm (E(0) = w L 1 mm = 3.082e-3 J): all nodes land together, a rigid motion;
* tilted and sliding: turned by α = atan 0.02 about e2 (unstrained: ψ = α with the turned
  positions), its low end s = 0 2 mm above the plane, its high end 22 mm, moving along e3
  at 0.3 m/s (E(0) = 0.05111 J): the low end lands first, the rod falls onto the plane node
  after node, bounces, and friction brakes its slide.

The balance, at every accepted step t_n,

    B(t_n) = E_kin + E_elastic + E_gravity + W_friction + W_impact + W_damping − E(0)    (B)

with E_kin, E_elastic of the state (tests/rod_energy.py's EnergyMonitor), E_gravity =
w Σ_k a_k x_k (a_k = ∫ φ_k ds the nodes' shares of the length: exact for the P3 positions),
W_friction and W_impact the contact's counters (summary.json's friction_work_J and
impact_loss_J: NodeContact.accept, (W.1)), and W_damping = −Σ_n h P_d(U_{n+½}) the work
of the Kelvin–Voigt forces at the step's midpoint state (the state where the midpoint rule
evaluates them; P_d of forms/energy.py). No B is taken from the run itself: E from the
states, the losses from the counters.

What is true (derivation in NodeContact.accept's docstring):

* the midpoint rule (generalized-α at ρ∞ = 1): M (v₁ − v₀)/h = f(x_m) + R with
  Δx = h (v₀ + v₁)/2 makes the kinetic energy's change the work (f + R)·Δx exactly, at
  an impact too, so B is the midpoint error of the elastic forces and the rotations only:
  O(h³) a step, O(h²) over the run; for the rigid flat drop it is 0 (round-off).
* BDF2 and generalized-α at ρ∞ = 0.5 change the kinetic energy at a velocity jump by
  O(Δvᵀ M Δv) more than any work of the force: B jumps at every impact by a fraction of
  the energy of the impact, and does not shrink with h (the impacts lower the order to 0).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI
from rod_energy import EnergyMonitor
from test_contact import RHO, W, rod_on_plane

from cosserat_fem import api
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import scene_from_dict
from cosserat_fem.timestepping.events import Observer

TILT = math.atan(0.02)
#: E(0) [J] of the flat drop: w L × 1 mm
FLAT_E0 = W * 1.0 * 1e-3


def drop(
    integrator: str,
    step: float,
    *,
    tilted: bool,
    end: float,
    rho_inf: float | None = None,
    retardation: float = 0.0,
) -> dict:
    """The scene of the module docstring, flat or tilted and sliding, with a Kelvin–Voigt
    ``retardation`` time τ_d [s] if non-zero."""
    data = rod_on_plane(10, mu=0.5)
    if tilted:
        data["initial"] = {
            "displacement": [f"0.002 + {math.sin(TILT)!r}*s", 0, f"{math.cos(TILT) - 1!r}*s"],
            "angles": [0, TILT, 0],
            "velocity": [0, 0, 0.3],
        }
    else:
        data["initial"] = {"displacement": ["0.001", 0, 0]}
    data["time"] = {"end": end, "step": step, "integrator": integrator}
    if rho_inf is not None:
        data["time"]["rho_inf"] = rho_inf
    if retardation:
        data["damping"] = {"retardation_time": retardation}
    return data


class Ledger(Observer):
    """At t = 0 and after every accepted step: t [s], the state U, the contact's counters
    W_friction, W_impact [J] and its force R [N] (nodes, 3)."""

    def __init__(self):
        self.t: list[float] = []
        self.U: list[np.ndarray] = []
        self.friction: list[float] = []
        self.impact: list[float] = []
        self.force: list[np.ndarray] = []
        self.contact = None

    def started(self, loop) -> None:
        self.contact = loop.solver.contact
        self._keep(loop)

    def step_accepted(self, loop) -> None:
        self._keep(loop)

    def _keep(self, loop) -> None:
        c = self.contact
        self.t.append(loop.state.t)
        self.U.append(loop.model.U.x.array.copy())
        self.friction.append(c.dissipated)
        self.impact.append(c.impact_loss)
        self.force.append(c.force.copy())


def run_drop(data: dict) -> dict:
    """Run ``data``; B(t_n) of (B) (array), E(0), the least gap [m] over the states, the
    summary's contact entries, and B with the trapezoid ½ (R_{n−1} + R_n)·Δx of consecutive
    forces in place of the counters (the quadrature (W.1) rejects)."""
    ledger = Ledger()
    result = api.run(scene_from_dict(data), observers=(ledger,))
    model, c = result.model, ledger.contact
    monitor = EnergyMonitor(model)
    damping = None
    if "damping" in data:  # P_d alone: the same rod without gravity (no load power)
        free = {**data, "loads": {**data["loads"], "gravity": [0, 0, 0]}}
        damping = EnergyMonitor(build_model(scene_from_dict(free), MPI.COMM_SELF))
    u = model.U.x.array
    final = u.copy()
    energy, gaps, lost, trapezoid = [], [], [0.0], [0.0]
    for n, U in enumerate(ledger.U):
        x = c.positions(U)
        u[:] = U
        energy.append(sum(monitor.energies()) + W * float(np.sum(c.shares * x[:, 0])))
        gaps.append(float(c.surface(x)[0].min()))
        if n:
            dx = x - c.positions(ledger.U[n - 1])
            trapezoid.append(
                trapezoid[-1] - np.sum(0.5 * (ledger.force[n - 1] + ledger.force[n]) * dx)
            )
            if damping is not None:
                damping.model.U.x.array[:] = 0.5 * (ledger.U[n - 1] + U)
                h = ledger.t[n] - ledger.t[n - 1]
                lost.append(lost[-1] - h * damping.power(ledger.t[n]))
            else:
                lost.append(0.0)
    u[:] = final
    E = np.array(energy)
    counters = np.array(ledger.friction) + np.array(ledger.impact)
    return {
        "B": E - E[0] + counters + np.array(lost),
        "B_trapezoid": E - E[0] + np.array(trapezoid) + np.array(lost),
        "E0": E[0],
        "t": np.array(ledger.t),
        "gap": min(gaps),
        "damping": lost[-1],
        "contact": result.summary["contact"],
    }


def order(coarse: float, fine: float) -> float:
    """The observed order of an error that fell from ``coarse`` to ``fine`` as h halved."""
    return math.log2(coarse / fine)


@pytest.mark.parametrize("step", [1e-3, 5e-4])
def test_a_flat_drop_balances_to_round_off_with_the_midpoint_rule(step):
    """Flat drop from 1 mm, generalized-α at ρ∞ = 1 (the implicit midpoint rule), 60 ms:
    a rigid motion (straight, E_elastic = 0), so (B) is an identity of the scheme: |B| ≤
    1e-12 E(0) at every step (round-off: measured 1.1e-15, 4.2e-16 E(0) at 1, 0.5 ms). The
    impact did something: the counters took ≥ 0.5 E(0) (measured 0.9998 E(0) at both steps:
    the rod comes nearly to rest), all of it W_impact (W_friction ≤ 1e-12 E(0): nothing
    slides; measured 1.4e-16). The trapezoid of consecutive forces instead of (W.1) misses
    by > 0.1 E(0) (measured 1.21 and 0.59 E(0)): the quadrature matters. No node goes
    through the plane: the gap row is linear in the positions on a plane, so Newton meets it
    to the linear solve's round-off (|x| ~ r = 0.01 m: bound 1e-15 m; measured −1.7e-18 m)."""
    out = run_drop(drop("generalized-alpha", step, tilted=False, end=0.06, rho_inf=1.0))
    E0 = out["E0"]
    assert E0 == pytest.approx(FLAT_E0, rel=1e-12)
    assert np.abs(out["B"]).max() <= 1e-12 * E0
    assert out["contact"]["impact_loss_J"] >= 0.5 * E0
    assert abs(out["contact"]["friction_work_J"]) <= 1e-12 * E0
    assert np.abs(out["B_trapezoid"]).max() > 0.1 * E0
    assert out["gap"] >= -1e-15


@pytest.mark.parametrize("retardation", [0.0, 2e-4], ids=["undamped", "kelvin-voigt"])
def test_a_tilted_sliding_drop_balances_at_order_two_with_the_midpoint_rule(retardation):
    """The tilted, sliding rod (module docstring), generalized-α at ρ∞ = 1, 60 ms (the low end
    lands at 20 ms, the rest of the rod after it, bouncing, while friction brakes the
    slide), at h = 250, 125, 62.5 μs: the largest |B| over the run falls at the midpoint
    rule's order 2 (NodeContact.accept: O(h³) a step, impacts included), asserted over the
    two halvings together (log2 of the fall over 2) ≥ 1.5 and |B| ≤ 3e-5 E(0)
    at 62.5 μs.

    Measured (largest |B| / E(0); pairwise orders; with 31.25 μs as a fourth step):
    undamped 1.5e-4, 5.6e-5, 1.1e-5, 4.4e-6 (1.46, 2.29, 1.37; over two halvings 1.87 and
    1.83); with Kelvin–Voigt damping τ_d = 0.2 ms 1.6e-5, 4.9e-6, 1.3e-6, 2.9e-7 (1.72,
    1.95, 2.12; 1.84, 2.04). Over 100 ms the undamped rod gave 3.05, 2.75, 1.63. The
    scatter about 2 is the paths': the midpoint rule's restitution at a node's impact
    depends on where in the step it lands (a rigid node: e = 1 − 2δ/(V h), δ its height at
    the step before), so each h takes another path, with another constant in front of h²;
    with the damping (ζ = τ_d ω/2 ≈ 1.2 for the shear–rotary modes at ω ≈ 1.2e4 rad/s that
    the impacts excite) the scatter is smaller (measured). The margin 0.5 below 2 covers
    the measured 1.37-2.29 of a single halving, halved by taking two together. The balance
    is not met trivially: friction took ≥ 0.1 E(0), the impacts ≥ 0.05 E(0), the damping ≥ 0.1 E(0)
    (measured at 62.5 μs: 0.22, 0.16, 0 undamped; 0.22, 0.093, 0.36 damped). No node goes
    through the plane (1e-15 m as in the flat drop; measured −1.7e-18 m). 3-7 s."""
    worst = []
    for step in (2.5e-4, 1.25e-4, 6.25e-5):
        data = drop(
            "generalized-alpha", step, tilted=True, end=0.06, rho_inf=1.0, retardation=retardation
        )
        out = run_drop(data)
        E0 = out["E0"]
        worst.append(np.abs(out["B"]).max() / E0)
        assert out["gap"] >= -1e-15
    assert E0 == pytest.approx(
        W * (0.002 + 0.5 * math.sin(TILT)) + 0.5 * RHO * math.pi * 1e-4 * 0.09
    )
    assert order(worst[0], worst[2]) / 2 >= 1.5, worst
    assert worst[-1] <= 3e-5, worst
    assert out["contact"]["friction_work_J"] >= 0.1 * E0
    assert out["contact"]["impact_loss_J"] >= 0.05 * E0
    if retardation:
        assert out["damping"] >= 0.1 * E0


@pytest.mark.parametrize(
    ("integrator", "rho_inf"), [("bdf2", None), ("generalized-alpha", 0.5)], ids=["bdf2", "alpha"]
)
def test_bdf2_and_dissipative_alpha_change_the_energy_at_impacts_beyond_the_counters(
    integrator, rho_inf
):
    """Flat drop from 1 mm, 60 ms, BDF2 and generalized-α at ρ∞ = 0.5 (its default), at
    h = 1, 0.5, 0.25 ms. Before the landing (t < 13 ms; it lands at √(2 · 1 mm/g) = 14.3 ms)
    the fall is a quadratic in t, which BDF2 (and its midpoint start) integrates exactly:
    |B| ≤ 1e-12 E(0) (measured 2.0e-15, 2.7e-15, 2.8e-15); generalized-α's first-order
    form updates the positions with its rates' γ-weights, an O(h²) error even there:
    |B| ≤ 3.5e-4 E(0) (h/1 ms)² (measured 3.270e-4 (h/1 ms)² at all three steps). At the
    impact the velocity jumps within a step and these schemes' kinetic energy changes by
    O(Δvᵀ M Δv) more than the work of any force (module docstring): the largest |B| is a
    fraction of E(0) that does not fall with h. Measured: BDF2 0.23, 0.76, 0.92 E(0),
    generalized-α 0.56, 0.22, 1.70 E(0) (it rebounds above its start at 0.25 ms:
    E(60 ms) = 1.65 E(0)); asserted > 0.1 E(0) at every h. So impact_loss_J is the energy
    the contact forces took, not what the run lost, with these integrators (for BDF2 it
    exceeds E(0): 1.23, 1.72, 1.44 E(0)). Should impacts become exact (a velocity row,
    docs/contact.md), this test fails and is to be rewritten as the midpoint's. No node goes
    through the plane (1e-15 m; measured −1.7e-18 m at worst). 1-2 s."""
    for step in (1e-3, 5e-4, 2.5e-4):
        out = run_drop(drop(integrator, step, tilted=False, end=0.06, rho_inf=rho_inf))
        E0, B = out["E0"], out["B"]
        bound = 1e-12 if integrator == "bdf2" else 3.5e-4 * (step / 1e-3) ** 2
        assert np.abs(B[out["t"] < 0.013]).max() <= bound * E0, step
        assert np.abs(B).max() > 0.1 * E0, step
        assert out["gap"] >= -1e-15
