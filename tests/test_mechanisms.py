"""Rods that are not held still: a pendulum (pinned–free) and mechanisms in general.

A support holds what its kind says: a clamped end p and q, a pinned end (a fork) x, y, z and
φ, a spherical end (a ball joint) x, y, z (cosserat_fem/rod/model.py). Supports that leave the
rod a rigid-body motion (neither end clamped, and not a fork at one end with the position
held at the other) make a mechanism: its dynamics are well posed (the mass matrix is
regular), its statics are not (the stiffness is singular), and refuse it with one line; its
modes about the straight rod begin with its rigid-body modes, ω = 0.

The pendulum, scenes/pendulum.toml: the paper's bar made 100x stiffer, pinned at s = 0,
released from rest horizontal under gravity. The rigid physical pendulum released from the
horizontal swings with the period T = 4 √(I_O/(m g d)) K(sin(π/4)), I_O = ρAℓ³/3 + ρ c ℓ (the
section's rotary inertia c = c22 about e2, c11 about e1), d = ℓ/2, K by the arithmetic-
geometric mean. The rod's period, from the two times the free end passes below the pivot (at
T/4 and 3T/4, interpolated linearly where it moves fastest), differs from it by the time
integrator's phase error: generalized-α at Δt = 2 ms, measured 1.53e-5 of T, and 3.82e-6,
9.61e-7 at 1 ms and 0.5 ms (order 2.00; the ratio at 2 and 1 ms is held), so the rod's own
flexibility and stretch (its first flexible mode is ~2800x faster than the swing:
(1/2800)² ~ 1e-7) lie below 1e-7.
Required: within 2e-5 of T, in the x-z plane (about e2, ψ through π), the y-z plane (about
e1, θ through π) and 3D: about e2 on the fork (ψ needs no chart), about e1 on a spherical
joint (θ passes π/2: the chart moves; equal to the y-z plane's to 1e-8 s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT, run_command
from rod_energy import EnergyRecorder

from cosserat_fem.analysis.equilibria import compute_modes
from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.common.errors import SceneError
from cosserat_fem.rod.model import rod_constants
from cosserat_fem.scene.build import load_scene, scene_from_dict
from cosserat_fem.scene.schema import read_toml
from cosserat_fem.timestepping.events import Observer

PENDULUM = ROOT / "scenes" / "pendulum.toml"
ABOUT_E1 = ["loads.gravity=[0,-9.81,0]"]
IN_3D = "discretisation.planar='off'"


def rigid_period(scene, axis: str) -> float:
    """The module docstring's T [s] for a swing about ``axis`` ("e1" or "e2")."""
    rod = rod_constants(scene)
    sec, ell, g = rod.section, rod.length, 9.81
    c = sec.c22 if axis == "e2" else sec.c11
    inertia = rod.density * (sec.area * ell**3 / 3 + c * ell)
    moment = rod.density * sec.area * ell * g * ell / 2
    a, b = 1.0, math.sqrt(0.5)  # K(k) = π / (2 AGM(1, √(1 − k²))), k² = 1/2
    for _ in range(30):
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return 4 * math.sqrt(inertia / moment) * math.pi / (2 * a)


def period(rows: np.ndarray, length: float) -> float:
    """2 (t2 − t1), t1 and t2 the first two times the free end passes z = −ℓ (below the
    pivot), by linear interpolation between the output times."""
    t, h = rows[:, 0], length + rows[:, 3]
    i = np.flatnonzero(np.sign(h[:-1]) != np.sign(h[1:]))[:2]
    times = t[i] + (t[i + 1] - t[i]) * h[i] / (h[i] - h[i + 1])
    return 2.0 * (times[1] - times[0])


CASES = {
    "x-z": ([], "e2", "x-z", 0),
    "y-z": (ABOUT_E1, "e1", "y-z", 0),
    "3d fork about e2": ([IN_3D], "e2", None, 0),
    "3d spherical about e1": ([*ABOUT_E1, IN_3D, "supports.start='spherical'"], "e1", None, 6),
}


@pytest.fixture(scope="module")
def swings():
    out = {}
    for name, (extra, axis, plane, moves) in CASES.items():
        scene = load_scene(PENDULUM, ["output.xdmf=false", *extra])
        assert scene.plane() == plane
        result = run_scene(scene, write_outputs=False, record=True)
        assert result.summary["chart_resets"] == moves
        out[name] = (period(result.probes, scene.rod.length), rigid_period(scene, axis))
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_a_stiff_pendulum_swings_with_the_rigid_period(swings, name):
    T, rigid = swings[name]
    assert abs(T - rigid) <= 2e-5 * rigid, (T, rigid)


def test_the_swing_through_the_chart_equals_the_plane(swings):
    assert abs(swings["3d spherical about e1"][0] - swings["y-z"][0]) <= 1e-8


def test_the_period_error_falls_as_the_step_squared(swings):
    """The x-z swing at Δt = 2 ms and 1 ms: the period's difference from the rigid one is
    generalized-α's phase error, second order, so halving Δt divides it by 4 (measured 4.005:
    1.53e-5 and 3.82e-6 of T). Allowed 4 ± 0.15: the rod's flexibility, below 1e-7 of T
    (module docstring), moves the ratio by at most 4 (1e-7/3.8e-6) ≈ 0.1, the scheme's
    next-order term by (ω Δt) ~ 7e-3 of it (ω = 2π/T)."""
    T2, rigid = swings["x-z"]
    scene = load_scene(PENDULUM, ["output.xdmf=false", "time.step=1e-3"])
    T1 = period(run_scene(scene, write_outputs=False, record=True).probes, scene.rod.length)
    ratio = (T2 - rigid) / (T1 - rigid)
    assert ratio == pytest.approx(4.0, abs=0.15), (T2, T1, rigid)


@pytest.mark.parametrize(
    "supports",
    [
        ("pinned", "free"),
        ("spherical", "spherical"),
        ("free", "free"),
        ("spherical", "free"),
        ("roller", "free"),
        ("roller", "roller"),
        ("sliding", "sliding"),
    ],
)
def test_statics_of_a_mechanism_are_refused(supports):
    scene = load_scene(
        PENDULUM, [f"supports.start='{supports[0]}'", f"supports.end='{supports[1]}'"]
    )
    assert scene.supports.mechanism
    with pytest.raises(SceneError, match="supports: a static equilibrium needs the rod held"):
        static_path(scene, write_outputs=False)
    with pytest.raises(SceneError, match="supports: modes about the static state"):
        compute_modes(scene, 4, about="static")


@pytest.mark.parametrize(
    "supports",
    [
        ("clamped", "free"),
        ("pinned", "pinned"),
        ("pinned", "spherical"),
        ("pinned", "roller"),
        ("spherical", "roller"),
        ("sliding", "pinned"),
        ("clamped", "roller"),
    ],
)
def test_held_rods_are_not_mechanisms(supports):
    scene = load_scene(
        PENDULUM, [f"supports.start='{supports[0]}'", f"supports.end='{supports[1]}'"]
    )
    assert not scene.supports.mechanism


def test_static_of_a_pendulum_from_the_command_line(tmp_path):
    """One line naming the key, exit status 2, nothing written."""
    proc = run_command(
        ["-m", "cosserat_fem.cli", "static", str(PENDULUM), "--out", str(tmp_path / "s")]
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("cosserat-fem: error: supports: a static equilibrium needs")
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not (tmp_path / "s").exists()


def test_a_free_flying_rod_takes_the_impulse_of_its_load():
    """Free–free: the paper's rod in 3D, no support, a force (1e4, 2e4, 0) N at the end
    s = ℓ for the first 2 ms (exactly 100 steps of 20 μs; the load's step falls between
    steps). The total linear momentum P = ∫ ρA ∂t r ds is a linear function of the state, and
    the force rows of (65) sum to dP/dt = the applied force (the internal forces cancel: the
    test function 1 has no derivative), which every Runge–Kutta method integrates exactly for
    a force constant over each step: P = (20, 40, 0) N s from 2 ms on, to round-off (allowed
    1e-9 of it, the Newton solves' tolerance 1e-8 of ‖U‖ on a state whose momentum is one
    part of it), while the rod turns (its free end by 0.19 rad in 6 ms)."""
    from dolfinx import fem

    class Momentum(Observer):
        def __init__(self):
            self.values: list = []
            self.forms: list | None = None  # compiled once: they read model.U as it changes

        def output(self, loop, k, t):
            model = loop.model
            rod = model.rod
            scale = rod.density * rod.section.area * rod.length * rod.length * model.omega0
            if self.forms is None:
                U = model.layout.full(model.U)
                self.forms = [fem.form(U[6 + i] * model.dx) for i in range(3)]
            P = [fem.assemble_scalar(form) for form in self.forms]
            self.values.append((t, *(scale * np.array(P))))

    recorder = Momentum()
    scene = load_scene(
        ROOT / "scenes" / "cao_tucker_2008.toml",
        [
            "supports.start='free'",
            "loads.force_density=[0,0,0]",
            'loads.end.force=["1e4*heaviside(0.002-t)", "2e4*heaviside(0.002-t)", 0]',
            "time.step=2e-5",
            "time.end=0.006",
            "output.xdmf=false",
        ],
    )
    assert scene.supports.mechanism and scene.plane() is None
    result = run_scene(scene, write_outputs=False, record=True, observers=[recorder])
    values = np.array(recorder.values)
    after = values[values[:, 0] >= 0.002 - 1e-12][:, 1:]
    assert np.abs(after - [20.0, 40.0, 0.0]).max() <= 1e-9 * 40.0
    assert np.abs(result.probes[:, 4:7]).max() > 0.1


def free_rod(diameter: float, elements: int):
    """The paper's scene with a circular section, both ends free, no load."""
    raw = read_toml(ROOT / "scenes" / "cao_tucker_2008.toml")
    raw["rod"]["section"] = {"shape": "circle", "diameter": diameter}
    return scene_from_dict(
        raw,
        overrides=[
            "supports.start='free'",
            "loads.force_density=[0,0,0]",
            f"discretisation.elements={elements}",
        ],
    )


def test_modes_of_a_free_rod_bending():
    """Free–free, a slender circular rod (ℓ/d = 1000), 32 cubic elements: six rigid-body modes
    (ω = 0: their eigenvalues are round-off, |λ| ~ 1e-9 against 0.02 for the first flexible
    one), then the bending pairs (one in each plane, equal for the circle) at
    ω = (βℓ)² √(EI/(ρAℓ⁴)) with βℓ = 4.7300407, 7.8532046, 10.9956078 (cos βℓ cosh βℓ = 1).
    Measured βℓ: 4.7300352, 7.853184, 10.995577: the rod's shear and rotary inertia lower
    them by ~(βℓ)² (d/ℓ)² (1 + E/κG)/16 ~ 3e-6 of βℓ, the elements' error is below that
    (1.5e-5 at 16 elements for the third); required within 1e-4, the table's last digit."""
    scene = free_rod(0.001, 32)
    _, modes = compute_modes(scene, 12)
    assert [m.omega for m in modes[:6]] == [0.0] * 6
    assert all(m.note.startswith("rigid-body mode") for m in modes[:6])
    rod = rod_constants(scene)
    sec = rod.section
    scale = math.sqrt(rod.young_modulus * sec.c11 / (rod.density * sec.area * rod.length**4))
    beta = [math.sqrt(m.omega / scale) for m in modes[6:]]
    for k, expected in enumerate((4.7300407, 7.8532046, 10.9956078)):
        pair = beta[2 * k : 2 * k + 2]
        assert {modes[6 + 2 * k].kind, modes[7 + 2 * k].kind} == {"bending-x", "bending-y"}
        assert max(abs(b - expected) for b in pair) <= 1e-4, (pair, expected)


def test_modes_of_a_free_rod_axial_and_torsional():
    """Free–free, a stocky circular rod (d = 0.1 m), 16 cubic elements: the axial modes at
    nπ/ℓ √(E/ρ) and the torsional ones at nπ/ℓ √(G/ρ) (a circle: c33 = c11 + c22, so the
    polar rotary inertia is ρ c33), n = 1, 2, the model's exact values; measured within
    1e-8; required 1e-6."""
    scene = free_rod(0.1, 16)
    _, modes = compute_modes(scene, 24)
    rod = rod_constants(scene)
    for kind, modulus in (("axial", rod.young_modulus), ("torsion", rod.shear_modulus)):
        found = [m.omega for m in modes if m.kind == kind and m.omega > 0.0][:2]
        for n, omega in enumerate(found, start=1):
            exact = n * math.pi / rod.length * math.sqrt(modulus / rod.density)
            assert abs(omega - exact) <= 1e-6 * exact, (kind, n, omega, exact)
        assert len(found) == 2


@pytest.mark.parametrize(
    ("supports", "rigid"),
    [
        (("pinned", "free"), 2),
        (("spherical", "free"), 3),
        (("spherical", "spherical"), 1),
        (("roller", "free"), 3),
        (("sliding", "roller"), 1),
    ],
)
def test_rigid_body_modes_of_each_mechanism(supports, rigid):
    """The pendulum's rod: a fork leaves the two rotations about it (it holds the twist), a
    ball joint three, two ball joints the twist about the line through them, a roller at a
    free end its fork's two and the slide along e3, a sliding clamp with a roller the slide
    along e3 (modal.RIGID_BODY_MODES). Those modes
    come first with ω = 0, and the next is a flexible one, ~1e4 rad/s (the round-off of
    the zero ones is |λ| ≲ 1e-9, against λ ~ 20 for it)."""
    scene = load_scene(
        PENDULUM, [f"supports.start='{supports[0]}'", f"supports.end='{supports[1]}'"]
    )
    _, modes = compute_modes(scene, rigid + 1)
    assert [m.omega for m in modes[:rigid]] == [0.0] * rigid
    assert abs(modes[rigid].eigenvalue) > 1.0 and modes[rigid].omega > 1e3


class _CentreOfMass(Observer):
    """Observer: the centre of mass [m] of a uniform rod at every output time, (t, x, y, z):
    (0, 0, ℓ/2) + ℓ ∫ (p1, p2, p3) dσ."""

    def __init__(self):
        self.rows: list = []
        self._forms = None

    def output(self, loop, k, t):
        from dolfinx import fem

        model = loop.model
        if self._forms is None:
            U = model.layout.full(model.U)
            self._forms = [fem.form(U[i] * model.dx) for i in range(3)]
        ell = model.rod.length
        mean = [ell * fem.assemble_scalar(f) for f in self._forms]
        self.rows.append((t, mean[0], mean[1], ell / 2 + mean[2]))


@pytest.mark.long
def test_the_flying_spaghetti():
    """scenes/flying_spaghetti.toml (Simo & Vu-Quoc 1988, in space): a free rod pushed and
    twisted at one end by a triangle pulse of 5 s, then flying and tumbling (the chart moves
    5 times by 7 s, 8 by 10 s), SDIRK3, 10 cubic elements.

    * The centre of mass is exact: the force rows sum to m ẍ_c = F(t), F piecewise linear in t
      with its kinks on step boundaries, so x_c is a cubic of t on each piece, which an
      order-3 method integrates exactly: x_c = 3 + (2/15) t³ up to 2.5 s, 5 t − 9.5 from 5 s
      (momentum 50 N s), y_c = 0, z_c = 4 (measured within 1e-13 m; allowed 1e-10, the
      Newton tolerance on states of ~10 m).
    * The energy after the pulse (E = 724.42 J: 724.4231 at 10 elements, 724.4281 at 20)
      leaks at SDIRK3's rate: from 5 s to 7 s it falls by 4.9e-2 J at Δt = 0.02 s, 7.1e-3 J at
      0.01 s (order 2.78; 1.2e-3 at 0.005 s, order 2.60, as the energy that each move of the
      chart changes by its interpolation error, ~3e-4 J over the five moves, shows). Required:
      order above 2.5 and a leak below 2e-5 E at 0.01 s.
    (With rotary inertias of 10 about every axis, as some codes give them, and 2 cubic
    elements as one of them uses, E = 875.9 J: that code's plot shows about 877.)"""
    rows = {}
    for dt in (0.02, 0.01):
        energy, centre = EnergyRecorder(), _CentreOfMass()
        scene = load_scene(
            ROOT / "scenes" / "flying_spaghetti.toml",
            ["time.end=7", f"time.step={dt}", "output.xdmf=false"],
        )
        result = run_scene(scene, write_outputs=False, observers=[energy, centre])
        assert result.summary["chart_resets"] == 5
        C = np.array(centre.rows)
        pulse, free = C[:, 0] <= 2.5 + 1e-9, C[:, 0] >= 5.0 - 1e-9
        assert np.abs(C[pulse, 1] - (3 + 2 / 15 * C[pulse, 0] ** 3)).max() <= 1e-10
        assert np.abs(C[free, 1] - (5 * C[free, 0] - 9.5)).max() <= 1e-10
        assert np.abs(C[:, 2]).max() <= 1e-10 and np.abs(C[:, 3] - 4.0).max() <= 1e-10
        E = np.array(energy.E)[free]
        rows[dt] = (E[0], E[0] - E[-1])
    assert rows[0.01][0] == pytest.approx(724.42, abs=0.01)
    order = math.log2(rows[0.02][1] / rows[0.01][1])
    assert order > 2.5, rows
    assert 0.0 < rows[0.01][1] <= 2e-5 * rows[0.01][0], rows
