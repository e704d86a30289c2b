"""Chaos groundwork (issue 27 item 4): the Poincaré section (cosserat_fem/analysis/observers.py
``PoincareSection``, poincare.csv) and the largest Lyapunov exponent by Benettin's method
(cosserat_fem/analysis/lyapunov.py, ``cf.lyapunov``); the buckled beam's route to chaos
(scenes/buckled_beam.toml), its first period doubling located by continuation.

**The linear case.** The paper's rod (tests/test_response.py's setting: 4 cubic elements,
planar in x-z, a load 1 sin(πs/ℓ) sin Ωt N/m in x: tip amplitude ~3e-5 m, so the geometric
terms are (u/ℓ)² ~ 1e-9 of the motion) with Kelvin–Voigt damping τ_d: the damping operator is
τ_d × the stiffness operator (forms/general_form.py), so mode n decays at
σ_n = ζ_n ω_n = τ_d ω_n²/2 (ζ_n = τ_d ω_n/2) and the least damped is the first bending mode
(x, about d2), ω1 of the same discretisation (``cf.modes``). The difference of two
trajectories of a linear system obeys the unforced system: the largest exponent is −σ1 exactly,
whatever the forcing. The forcing period T = 2π/ω_d1 (ω_d1 = ω1 √(1 − ζ1²), at resonance) is
the damped period of mode 1, so that over one period the continuous flow maps mode 1's state to
e^{−σ1 T} times itself.

What the discrete run computes (SDIRK3, h = T/N): mode 1's state (a, da/dτ) is mapped over a
period by R(hJ)^N (R the method's stability function, J the mode's 2×2 matrix), which scales
it by |ρ|, ρ = R(λ1 h)^N, λ1 = −σ1 + iω_d1, and turns it by δ = arg ρ (its phase error per
period) in the coordinates (cos, sin) where the state is M (cos φ, sin φ), M = [[1, 0],
[−σ̂, −ω̂_d]] (hats: over ω0, the solver's rates being d/dτ). The norm of U restricted to mode
1 is ‖Φ‖ ‖M v(φ)‖ (p and q share the shape Φ). So after discard intervals (other modes gone:
σ2/σ1 = (ω2/ω1)² ≈ 39, and the overdamped ones decay at ≥ 1/τ_d, or by SDIRK3's
|R(∞)| = 0.73 a step, 2e-11 over 2 periods of 40 steps), the running estimate is

    λ_n = ln|R(λ1 h)|/h + [ln‖Mv(φ0 + nδ)‖ − ln‖Mv(φ0)‖] / (n T),

and the bracket is at most (κ² − 1)/(2κ) n|δ| (κ = cond M: the largest slope of
½ ln(s1² cos²φ + s2² sin²φ) in φ): the averaging's error is at most (κ² − 1)/(2κ) |δ|/T, its
discrete target ln|R(λ1 h)|/h, and the integrator's error ln|R(λ1 h)|/h + σ1 = O(h³)
(order 3). Newton stops at an update below stol ‖U‖: each step may leave up to
stol × RMS(U) in the difference, at most steps × stol RMS(U) / d0 in a stretch.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_command
from test_response import SET

import cosserat_fem as cf
from cosserat_fem.analysis.observers import PoincareSection
from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.poincare import POINCARE, read_poincare
from cosserat_fem.timestepping.integrators import _sdirk_tableau

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
OMEGA0 = 207.0236  # rad/s, the paper's reference frequency
ZETA1 = 0.05  # the first mode's damping ratio (about), ζ1 = τ_d ω1/2
TAU_D = 2 * ZETA1 / OMEGA0  # s
STOL = 1e-10
PERIODS, DISCARD = 12, 2
#: tests/test_response.py's linear rod with this file's damping and Newton tolerance.
BASE = {**SET, "damping.retardation_time": TAU_D, "solver.stol": STOL}


def sdirk_R(z: complex, order: int = 3) -> complex:
    """The SDIRK stability function R(z) = 1 + z bᵀ (I − zA)⁻¹ 1 of the project's tableau."""
    _, A, b = _sdirk_tableau(order)
    return 1 + z * b @ np.linalg.solve(np.eye(len(b)) - z * A, np.ones(len(b)))


class Linear:
    """The linear case at N = ``steps`` a period on ``elements`` cells (module docstring);
    :meth:`run` computes the exponent."""

    def __init__(self, steps: int = 40, elements: int = 4):
        base = {**BASE, "discretisation.elements": elements}
        self.omega1 = cf.modes(cf.load(PAPER, base), count=1)[0].omega
        self.sigma = TAU_D * self.omega1**2 / 2
        self.omega_d = self.omega1 * math.sqrt(1 - (TAU_D * self.omega1 / 2) ** 2)
        self.T = 2 * math.pi / self.omega_d
        self.h = self.T / steps
        self.steps = steps
        overrides = {"time.step": self.h, "time.end": PERIODS * self.T}
        self.scene = cf.load(PAPER, {**base, **overrides, "parameters.r": self.omega_d / OMEGA0})
        lam = complex(-self.sigma, self.omega_d)
        self.discrete = math.log(abs(sdirk_R(lam * self.h))) / self.h
        self.drift = abs(np.angle(sdirk_R(lam * self.h) ** steps))  # δ per period [rad]

    def run(self, observers=(), out=None) -> Linear:
        self.result = cf.lyapunov(
            self.scene, self.T, periods=PERIODS, discard=DISCARD, observers=observers, out=out
        )
        M = np.array([[1.0, 0.0], [-self.sigma / OMEGA0, -self.omega_d / OMEGA0]])
        kappa = np.linalg.cond(M)
        rms = self.result.poincare[:, -1].max()  # RMS of U along the reference
        newton = self.steps * STOL * rms / self.result.perturbation / self.T
        self.bound = (kappa**2 - 1) / (2 * kappa) * self.drift / self.T + newton
        return self


@pytest.fixture(scope="module")
def linear(tmp_path_factory):
    """The linear case at 40 steps a period, with a second section half a step off the
    output grid (interpolated), poincare.csv in a folder."""
    out = tmp_path_factory.mktemp("linear")
    case = Linear()
    phase = 2 * math.pi * 0.5 / case.steps + 1.0
    off_grid = PoincareSection(case.T, phase)
    case.run(observers=[off_grid], out=out)
    return case, off_grid, phase, out


def test_the_linear_exponent_is_minus_the_least_damped_modes_decay_rate(linear):
    """λ of the linear damped rod equals its discrete target ln|R(λ1 h)|/h within the
    averaging's bound (module docstring; measured 2.8e-4 1/s against a bound of 1.3e-3), and
    −ζ1 ω1 = −τ_d ω1²/2 within that bound plus the integrator's error |ln|R(λ1 h)|/h + σ1|
    (6.6e-2 1/s at 40 steps a period, 0.6 %). The running estimate is flat after the
    discarded intervals: each λ_n meets the same bound."""
    case, *_ = linear
    result = case.result
    assert result.exponent == result.running[-1]
    assert np.isnan(result.running[:DISCARD]).all()
    for estimate in result.running[DISCARD:]:
        assert abs(estimate - case.discrete) <= case.bound, (estimate, case.discrete, case.bound)
    integrator = abs(case.discrete + case.sigma)
    assert integrator <= 0.01 * case.sigma  # SDIRK3 at ω h = 2π/40: (ω h)³ ~ 4e-3
    assert abs(result.exponent + case.sigma) <= case.bound + integrator
    assert result.times == pytest.approx(np.arange(1, PERIODS + 1) * case.T, rel=1e-12)


def test_a_settled_response_has_a_period_one_section_and_its_spread_falls_as_the_transient(
    linear,
):
    """The Poincaré points x_j of the tip (j ≥ 2: mode 1 alone rings) are the steady
    response's one point x_∞ plus the transient, Re(c ρ^j), ρ = R(λ1 h)^N (module docstring):
    the three numbers (x_∞, c) fitted by least squares leave a residual of round-off and
    Newton's error (bounded by 1e-6 of the spread, measured 3e-9), so the section converges to
    one point (period 1) with a spread falling by |ρ| = e^{−σ_h T} a period. At phase 0 (on
    the output grid) and at a phase half a step off it (the cubic interpolation), x_∞ equals
    the closed-form linear steady state Im(P e^{iφ0}) (tests/modal_checks.py) within SDIRK3's
    error at resonance: the amplitude ∝ 1/σ (its relative error |σ_h − σ|/σ), the phase error
    δ a period detuning it by δ/(σT), and O((Ωh)³) off resonance: 1.3e-2 in all (measured
    6.5e-3, 3.4e-3). poincare.csv holds the rows."""
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from modal_checks import linear_steady_state

    case, off_grid, phase, out = linear
    reference = linear_steady_state(case.scene, case.omega_d)
    rho = sdirk_R(complex(-case.sigma, case.omega_d) * case.h) ** case.steps
    sigma_h = -case.discrete
    tolerance = (
        abs(sigma_h - case.sigma) / case.sigma
        + case.drift / (case.sigma * case.T)
        + (case.omega_d * case.h) ** 3
    )
    for rows, phi in ((case.result.poincare, 0.0), (off_grid.rows, phase)):
        assert rows is not None
        j, x = rows[DISCARD:, 0], rows[DISCARD:, 2]
        powers = rho**j
        A = np.column_stack([np.ones_like(j), powers.real, -powers.imag])
        coefficients, *_ = np.linalg.lstsq(A, x, rcond=None)
        spread = np.abs(np.diff(x)).max()
        assert np.abs(x - A @ coefficients).max() <= 1e-6 * spread
        closed = (reference[0] * np.exp(1j * phi)).imag
        assert abs(coefficients[0] / closed - 1) <= tolerance, (phi, coefficients[0], closed)
        ratios = np.abs(np.diff(x))[1:] / np.abs(np.diff(x))[:-1]
        assert np.median(ratios) == pytest.approx(abs(rho), rel=0.05)
    columns, rows = read_poincare(out / POINCARE)
    assert columns == case.result.columns and np.array_equal(rows, case.result.poincare)
    assert rows[:, 0].tolist() == list(range(PERIODS + 1))


def test_the_section_interpolates_cubics_exactly_between_outputs():
    """Between output times the section state is the cubic through the four output states
    around it (Lagrange): exact for a state that is a cubic in t (to round-off, 1e-12 of its
    size), and for a quartic its error falls 16-fold (2⁴, ±10 %: the next term is
    O(Δt⁵)) when the output interval is halved. Irregular output times (an adaptive run's
    are the grid, but the rule does not need it)."""
    rng = np.random.default_rng(1)

    def sections(signal, dt: float) -> tuple[np.ndarray, np.ndarray]:
        section = PoincareSection(0.37, phase=0.9)
        got: list[tuple[float, float]] = []
        section._sample = lambda t, state: got.append((t, float(state[0])))
        section.next = 0
        times = np.arange(0.0, 3.0, dt)
        times[1:-1] += rng.uniform(-0.2, 0.2, times.size - 2) * dt
        for t in times:
            section._push(float(t), np.array([signal(t)]))
        t, v = np.array(got).T
        return t, v - signal(t)

    cubic = lambda t: 1.0 + 2.0 * t - 3.0 * t**2 + 0.5 * t**3  # noqa: E731
    t, error = sections(cubic, 0.05)
    assert t.size == 8 and np.allclose(t, (np.arange(8) + 0.9 / (2 * np.pi)) * 0.37)
    assert np.abs(error).max() <= 1e-11  # round-off of values up to ~10
    quartic = lambda t: np.sin(3 * t)  # noqa: E731
    coarse = np.abs(sections(quartic, 0.02)[1]).max()
    fine = np.abs(sections(quartic, 0.01)[1]).max()
    assert 8 <= coarse / fine <= 32  # irregular times: the ratio of two maxima, 16 ± 2x


@pytest.mark.parametrize(
    "arguments, message",
    [
        ({"period": -1.0}, "^period: must be the forcing period"),
        ({"periods": 0}, "^periods: must be a whole number >= 1"),
        ({"periods": 3, "every": 2}, "^periods: 3 is not a whole number of intervals"),
        ({"discard": 4}, "^discard: 4 leaves none"),
        ({"period": 0.0333}, "^time.step: "),
        ({"perturbation": 0.5}, r"^perturbation: must lie in \(0, 1e-2\]"),
    ],
)
def test_bad_requests_are_refused_in_one_line_before_any_work(arguments, message):
    scene = cf.load(PAPER, {**BASE, "time.end": 0.01, "time.step": 1e-3})
    request = {"period": 0.01, "periods": 4, **arguments}
    period = request.pop("period")
    with pytest.raises(SceneError, match=message):
        cf.lyapunov(scene, period, **request)
    adaptive = cf.load(PAPER, {**BASE, "time.end": 0.01, "time.step": 1e-3, "time.adaptive": True})
    with pytest.raises(SceneError, match="^time.adaptive: "):
        cf.lyapunov(adaptive, 0.01, periods=4)


@pytest.mark.long
def test_the_exponent_converges_in_the_time_step_at_the_integrators_order():
    """At N = 40, 80, 160 steps a period each estimate meets its discrete target within the
    averaging's bound (module docstring), and the error against −σ1 falls at SDIRK3's order 3:
    log2 of the ratio of successive errors within 3 ± 0.25 (the O(h⁴) term: measured 2.93
    from 40 to 80)."""
    errors = []
    for steps in (40, 80, 160):
        case = Linear(steps).run()
        assert abs(case.result.exponent - case.discrete) <= case.bound
        errors.append(abs(case.result.exponent + case.sigma))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 3) <= 0.25), (errors, orders)


@pytest.mark.long
def test_the_exponent_converges_in_the_mesh():
    """On 2, 4 and 8 cubic elements each estimate meets its own discretisation's target
    ln|R(λ1 h)|/h (ω1 of that mesh) within the averaging's bound, and the estimates converge:
    the change from 4 to 8 elements is at most a quarter of that from 2 to 8, plus both bounds
    (ω1's error falls as h^6 for cubic elements: 64-fold from 2 to 4; measured 7.2e-3 and
    1.1e-4 1/s against 8 elements)."""
    cases = [Linear(40, elements).run() for elements in (2, 4, 8)]
    for case in cases:
        assert abs(case.result.exponent - case.discrete) <= case.bound
    values = [c.result.exponent for c in cases]
    slack = cases[1].bound + cases[2].bound
    assert abs(values[1] - values[2]) <= abs(values[0] - values[2]) / 4 + slack, values


#: The linear case under mpirun: every rank's exponent and rank 0's section as JSON.
MPI_SCRIPT = """
import json, sys
sys.path.insert(0, sys.argv[1])
from mpi4py import MPI
from test_chaos import Linear
case = Linear().run()
exponents = MPI.COMM_WORLD.allgather(case.result.exponent)
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps({"exponents": exponents, "discrete": case.discrete, "bound": case.bound,
                      "section": case.result.poincare[:, 2].tolist()}))
"""


@pytest.mark.mpi
@pytest.mark.long
def test_the_exponent_under_mpirun_meets_the_same_bound(linear):
    """Under ``mpirun -n 2`` every rank returns the same exponent (one allreduce decides
    every distance), within the serial run's bound of the discrete rate; the perturbation's
    direction differs (each rank draws its own part), which the bound allows: after the
    discarded intervals only mode 1 is left. The reference trajectory is the serial one up to
    round-off in the assembly's order: its section equals the serial section within 1e-9 of
    its size (measured ~1e-15)."""
    import json

    case, *_ = linear
    proc = run_command(["-c", MPI_SCRIPT, str(Path(__file__).parent)], ranks=2)
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["exponents"][0] == got["exponents"][1]
    assert abs(got["exponents"][0] - case.discrete) <= case.bound
    serial = case.result.poincare[:, 2]
    size = np.abs(serial).max()
    assert np.abs(np.array(got["section"]) - serial).max() <= 1e-9 * size


#: scenes/buckled_beam.toml's beam (cosserat_fem/reference/buckled_beam.py's reduction).
BUCKLED = ROOT / "scenes" / "buckled_beam.toml"


def buckled_beam():
    """The BuckledBeam of scenes/buckled_beam.toml, and the scene's own constants checked
    against its mapping at the published δ = 0.3, ω = 1.2, γ = 0.28 (to round-off: the
    scene's numbers were printed from it with 17 digits)."""
    from cosserat_fem.reference.buckled_beam import BuckledBeam

    scene = cf.load(BUCKLED)
    section = scene.rod.section
    beam = BuckledBeam(
        scene.rod.length,
        scene.rod.material.young_modulus,
        scene.rod.material.density,
        section.a * section.b,
        section.b * section.a**3 / 12,
        2 * section.a**2 * math.pi**2 / (12 * scene.rod.length),
    )
    values = scene.parameters
    assert values["D"] == pytest.approx(beam.shortening, rel=1e-12)
    assert values["As"] == pytest.approx(beam.amplitude, rel=1e-12)
    assert values["f0"] == pytest.approx(beam.force(0.28), rel=1e-12)
    assert values["Om"] == pytest.approx(beam.frequency(1.2), rel=1e-12)
    assert scene.damping.translational == pytest.approx(beam.damping(0.3), rel=1e-12)
    return beam


@pytest.mark.long
@pytest.mark.parametrize(
    "gamma, period, guess", [(0.20, 1, (0.57, 0.41)), (0.28, 2, (0.246, 0.237))]
)
def test_the_buckled_beam_starts_the_published_route_to_chaos(gamma, period, guess):
    """scenes/buckled_beam.toml at the published δ = 0.3, ω = 1.2 (Guckenheimer & Holmes
    1983, §2.2): at γ = 0.20 the section settles on one point, at γ = 0.28 on two (period 2,
    after the doubling at γ = 0.2656 of the one-mode reduction, ``period_doubling``). The rod's
    points (mid-span x / a_s, periods 25-40) equal the reduction's orbit (``duffing_orbit``)
    within the sum of what separates them, times 2: the geometrically exact terms
    (π a_s/ℓ)² = 3.3e-4, shear and rotary inertia (π r/ℓ)² = 8.2e-5, axial inertia
    (Ω/ω_axial)² = 1.2e-4, SDIRK3 at 100 steps a period (2π/100)³ = 2.5e-4 (7.8e-4 in all,
    carried to the orbit by 1/|1 − μ| ≤ 1.3 for the multipliers μ of these orbits, |μ| ≤
    0.46): 2e-3 of a_s (measured 3.3e-4, 4.2e-4 and 4.8e-4). Both attractors are periodic:
    their largest exponent is negative, and since their multipliers are a complex pair (whose
    product is e^{−δ n T}) it is −δ√k/2 = −c/(2ρA) = −21.8 1/s, up to the averaging's bias
    (module docstring): the perturbation turns in the pair's plane between directions of
    different norm, so over the 20 averaged periods the estimate is off by at most
    ln κ/(20 T), κ the condition number of the pair's real basis (Re v, Im v) of the
    reduction's monodromy in the rod's state units (x, dx/dτ' → a, ȧ/ω0: rates scaled by
    √k/ω0): 1.6 1/s at γ = 0.20 (κ = 3.1), 3.0 1/s at 0.28 (κ = 8.7, a pair near the real
    axis); measured 0.49 and 2.44 1/s. Plus the reduction's 2e-3 (above) of the rate."""
    from cosserat_fem.reference.buckled_beam import duffing_flow, duffing_orbit

    beam = buckled_beam()
    Om, periods = beam.frequency(1.2), 40
    T = 2 * math.pi / Om
    scene = cf.load(BUCKLED, {"time.end": periods * T, "parameters.f0": beam.force(gamma)})
    result = cf.lyapunov(scene, T, periods=periods, discard=20)
    x = result.poincare[25:, 2] / beam.amplitude
    point, multipliers = duffing_orbit(gamma, guess, period)
    assert np.abs(multipliers).max() <= 0.46
    orbit = [point[0]]
    if period == 2:
        orbit.append(duffing_flow(gamma, 0.3, 1.2, point, 1, 1e-12)[0][0])
    nearest = np.min(np.abs(x[:, None] - np.array(orbit)[None, :]), axis=1)
    assert nearest.max() <= 2e-3, (x, orbit)
    assert len({int(np.argmin(np.abs(v - np.array(orbit)))) for v in x}) == period
    assert result.exponent < 0
    monodromy = duffing_flow(gamma, 0.3, 1.2, point, period, 1e-12)[1]
    v = np.linalg.eig(monodromy)[1][:, 0]
    scale = np.diag([1.0, math.sqrt(beam.k) / scene.omega0])
    kappa = np.linalg.cond(scale @ np.column_stack([v.real, v.imag]))
    rate = 0.3 * math.sqrt(beam.k) / 2
    bound = math.log(kappa) / ((periods - 20) * T) + 2e-3 * rate
    assert abs(result.exponent + rate) <= bound, (result.exponent, rate, bound)


@pytest.mark.long
def test_the_reduction_follows_the_published_route():
    """The one-mode reduction (cosserat_fem/reference/buckled_beam.py) at δ = 0.3, ω = 1.2
    from (x, x') = (1, 0): its section's last 40 of 200 periods repeat with the published
    periods (γ = 0.20: 1, 0.28: 2, 0.29: 4, 0.37: 5, to 1e-6: the attractors' multipliers
    are ≤ 0.5 a period, so 160 periods leave 1e-40 of the start), and at γ = 0.50 with none
    up to 12 (chaos: no repeat closer than 1e-3). Its first period doubling, where the
    period-1 orbit's multiplier is −1, lies between the published period-1 and period-2
    values: γ = 0.26558 (Brent's method to 1e-8)."""
    from cosserat_fem.reference.buckled_beam import HOLMES_ROUTE, duffing_section, period_doubling

    def period_of(x: np.ndarray, tolerance: float) -> int:
        for n in range(1, 13):
            if np.abs(x[n:] - x[:-n]).max() <= tolerance:
                return n
        return 0

    for gamma, period in HOLMES_ROUTE.items():
        x = duffing_section(gamma, 200)[-40:, 0]
        assert period_of(x, 1e-6 if period else 1e-3) == period, gamma
    assert period_doubling() == pytest.approx(0.26558, abs=1e-5)


@pytest.mark.long
def test_the_buckled_beam_is_chaotic_at_the_published_forcing():
    """At γ = 0.50 (published: chaos) the rod's section does not repeat with any period up to
    12 within 1e-2 a_s (its points spread over both wells, |x| up to 1.4 a_s) and its largest
    exponent is positive: measured 18.6 1/s = 0.128 √k over periods 30-90, against the
    reduction's 0.106 √k (500 periods; 0.119 and 0.094 over their halves: a finite-time
    estimate of a chaotic exponent scatters by ~10 % at these lengths). The test holds the
    sign, and the size within a factor 2 of the reduction's."""
    beam = buckled_beam()
    Om, periods = beam.frequency(1.2), 90
    T = 2 * math.pi / Om
    scene = cf.load(BUCKLED, {"time.end": periods * T, "parameters.f0": beam.force(0.5)})
    result = cf.lyapunov(scene, T, periods=periods, discard=30)
    x = result.poincare[30:, 2] / beam.amplitude
    for n in range(1, 13):
        assert np.abs(x[n:] - x[:-n]).max() > 1e-2, n
    assert x.min() < 0 < x.max()  # both wells
    reduction = 0.106 * math.sqrt(beam.k)
    assert reduction / 2 <= result.exponent <= 2 * reduction, result.exponent


def sdirk_duffing_period(y, gamma: float, steps: int, delta: float = 0.3, omega: float = 1.2):
    """The reduction's state (x, x') one forcing period 2π/ω after y at τ = 0, by the
    project's SDIRK3 tableau at ``steps`` fixed steps (each stage solved by Newton to 1e-15):
    the discrete map that the rod's steps make of its first mode (a Runge–Kutta method
    commutes with the linear change of variables to the mode's amplitude and with the
    scaling of time, so the reduction under SDIRK3 is the rod's first mode under SDIRK3)."""
    g, A, b = _sdirk_tableau(3)
    c = A.sum(axis=1)
    h = 2 * math.pi / omega / steps
    y = np.array(y, dtype=float)
    for n in range(steps):
        rates: list[np.ndarray] = []
        for i in range(len(b)):
            Z = y + h * sum((A[i, j] * rates[j] for j in range(i)), np.zeros(2))
            force = gamma * math.cos(omega * (n + c[i]) * h)
            Y = Z.copy()
            for _ in range(50):
                x, v = Y
                F = Y - Z - h * g * np.array([v, -delta * v + x - x**3 + force])
                J = np.eye(2) - h * g * np.array([[0.0, 1.0], [1.0 - 3 * x * x, -delta]])
                d = np.linalg.solve(J, F)
                Y -= d
                if np.abs(d).max() <= 1e-15:
                    break
            rates.append((Y - Z) / (g * h))
        y = y + h * sum((bi * k for bi, k in zip(b, rates, strict=True)), np.zeros(2))
    return y


def sdirk_period_doubling(steps: int, low: float = 0.25, high: float = 0.28) -> float:
    """The first period doubling of the reduction under SDIRK3 at ``steps`` a period: γ where
    the discrete map's period-1 orbit in the right well (Newton, followed from γ = low) has a
    multiplier −1 (its monodromy by central differences of 1e-6: error 1e-12), by Brent's
    method to 1e-9 (as ``period_doubling`` for the flow)."""
    from scipy.optimize import brentq, fsolve

    state = {"y": np.array([0.43, 0.34])}

    def crossing(gamma: float) -> float:
        y = fsolve(lambda y: sdirk_duffing_period(y, gamma, steps) - y, state["y"], xtol=1e-13)
        state["y"] = y
        e = 1e-6
        M = np.column_stack(
            [
                sdirk_duffing_period(y + e * d, gamma, steps)
                - sdirk_duffing_period(y - e * d, gamma, steps)
                for d in np.eye(2)
            ]
        ) / (2 * e)
        mu = np.linalg.eigvals(M)
        return float(np.min(mu.real)) + 1.0 if np.isreal(mu).all() else 1.0

    return brentq(crossing, low, high, xtol=1e-9)


@pytest.mark.long
def test_the_buckled_beam_s_first_period_doubling_by_continuation(tmp_path):
    """The route to chaos by its first step: cf.periodic_branch continues the period-1 orbit
    in the right well of scenes/buckled_beam.toml (its 8 cubic elements, SDIRK3 at 100 steps
    a period) in the forcing amplitude γ (the load g F1 sin(πs/ℓ) cos Ωt, F1 = ρA a_s k the
    load of γ = 1, p = g) from γ = 0.20 to 0.28, and locates where a real multiplier crosses
    −1 (cosserat_fem/analysis/periodic.py: det(M + I) changes sign) to 1e-6 in arclength.

    The reference: the one-mode reduction's doubling γ* = 0.2655818 (``period_doubling``,
    shooting with its monodromy, DOP853 at rtol 1e-12, Brent to 1e-8), and the same
    reduction under the rod's SDIRK3 steps (:func:`sdirk_period_doubling`), γ*_h = 0.2656452:
    the time step's share Δ_h = γ*_h − γ* = 6.3e-5 (8.0e-6 at 200 steps: order 3).

    The bound on what else separates the rod from the reduction. In the reduction's
    coefficients m ä + c ȧ − k a + β a³ = f cos Ωt, δ = c/√(mk), ω = Ω √(m/k) and γ =
    f √β / k^{3/2}; the rod moves m, k and β by the relative amounts (each a term the reduction
    drops, docs/chaos.md): the geometrically exact terms (π x_max a_s/ℓ)² = 6.0e-4 (x_max =
    1.35, the reduction's orbit's largest x at γ*), shear and the section's rotary inertia
    (π r/ℓ)² (1 + E/(κG)) = 3.4e-4 (r² = a²/12, κ = 5/6), axial inertia (Ω/ω_axial)² =
    1.2e-4 (ω_axial = π √(E/ρ)/ℓ): ε = 1.06e-3; each coefficient by at most 2ε (a relative
    change of the critical shortening enters k = ω_b² (D/D_cr − 1) times D/(D − D_cr) = 2).
    So |d ln δ|, |d ln ω| ≤ 2ε and |d ln γ| ≤ 4ε, and to first order the doubling moves by at
    most

        B = (2 |∂γ*/∂ln δ| + 2 |∂γ*/∂ln ω| + 4 γ*) ε = (0.33 + 0.98 + 1.06) ε = 2.5e-3,

    the sensitivities by central differences of ``period_doubling`` (relative steps 1e-3,
    0.163 and 0.490). Asserted: |γ_rod − γ*_h| ≤ B (measured 1.9e-5: the bound is the sum of
    the worst signs of every term, 130 times the measured) and |γ_rod − γ*| ≤ B + Δ_h
    (measured 8.2e-5); a real multiplier at −1 within 1e-4 at the located point (it moves by
    |dμ/dγ| ≤ 50 there, asserted from the next point, times the 1e-6 locate tolerance,
    doubled; measured 8e-11, the slope 24.6); the mode's other multiplier there is
    −e^{−δ 2π/ω} = −0.2079 (Liouville: the pair's product is the damping's e^{−δT}) within
    1e-3 (the rotational dofs' share of the kinetic energy, undamped: (π r/ℓ)² = 8e-5, and
    Δ_h; measured 8.9e-5); the orbits before the doubling are stable, those after it
    unstable by a real multiplier < −1 ("period-doubling"); the branch has no other special
    point (no fold, no torus: the complex pair meets on the negative real axis before
    splitting, which the bialternate test does not take for a torus); orbit_branch.csv has
    the point's row.
    Measured: γ_rod = 0.2656641 (f0 = 17.680 N/m), 6 continuation steps, 54 monodromies,
    90-100 s serial on 2 shared cores (2026-12-04, load 4-7)."""
    from scipy.integrate import solve_ivp

    from cosserat_fem.analysis.periodic import Shooting
    from cosserat_fem.reference.buckled_beam import duffing_orbit, period_doubling

    beam = buckled_beam()
    scene = cf.load(
        BUCKLED,
        {
            "parameters.g": 0.20,
            "parameters.F1": beam.force(1.0),
            "loads.force_density": ["g*F1*sin(pi*s/L)*cos(Om*t)", 0, 0],
            "output.xdmf": False,
            "output.checkpoint": False,
        },
    )
    period = 2 * math.pi / beam.frequency(1.2)
    shooting = Shooting(scene, period, steps_per_period=100, parameter="g")
    guess = shooting.model.U.x.array[: shooting.n_local].copy()  # the scene's buckled shape
    shooting.destroy()
    branch = cf.periodic_branch(
        scene,
        period,
        "g",
        0.20,
        0.28,
        guess=guess,
        settle=10,
        steps_per_period=100,
        step=0.01,
        max_step=0.02,
        out=tmp_path,
    )
    assert branch.reason == "p reached 0.28" and branch.rejected == 0
    assert [q.kind for q in branch.special] == ["period-doubling"]
    (doubling,) = branch.period_doublings
    rod = doubling.parameter

    exact = period_doubling()
    discrete = sdirk_period_doubling(100)
    h_share = discrete - exact
    assert 0.0 < h_share <= 1e-4  # measured 6.3e-5; (2π/100)³ = 2.5e-4 of γ* is its order
    sensitivity = [
        (
            period_doubling(**{name: value * (1 + 1e-3)})
            - period_doubling(**{name: value * (1 - 1e-3)})
        )
        / 2e-3
        for name, value in (("delta", 0.3), ("omega", 1.2))
    ]
    point, _ = duffing_orbit(exact, (0.43, 0.34))
    T = 2 * math.pi / 1.2
    flow = solve_ivp(
        lambda t, y: [y[1], -0.3 * y[1] + y[0] - y[0] ** 3 + exact * math.cos(1.2 * t)],
        (0.0, T),
        point,
        method="DOP853",
        rtol=1e-10,
        atol=1e-12,
        dense_output=True,
    )
    x_max = np.abs(flow.sol(np.linspace(0.0, T, 2001))[0]).max()
    material = scene.rod.material
    a, length = scene.rod.section.a, scene.rod.length
    shear = 2 * (1 + material.poisson_ratio) / (5 / 6)  # E/(κG)
    axial = math.pi * math.sqrt(material.young_modulus / material.density) / length
    eps = (
        (math.pi * x_max * beam.amplitude / length) ** 2
        + (math.pi / length) ** 2 * a**2 / 12 * (1 + shear)
        + (beam.frequency(1.2) / axial) ** 2
    )
    bound = (2 * abs(sensitivity[0]) + 2 * abs(sensitivity[1]) + 4 * exact) * eps
    report = dict(rod=rod, exact=exact, discrete=discrete, bound=bound, eps=eps, s=sensitivity)
    assert abs(rod - discrete) <= bound, report
    assert abs(rod - exact) <= bound + h_share, report

    mu = doubling.multipliers
    real = mu[np.abs(mu.imag) <= 1e-12 * np.abs(mu)].real
    after = next(q for q in branch.points if q.parameter > rod)
    slope = abs(after.multipliers[0].real + 1.0) / (after.parameter - rod)
    assert slope <= 50.0, slope
    assert np.abs(real + 1.0).min() <= 1e-4, mu[:4]
    assert np.abs(real + math.exp(-0.3 * T)).min() <= 1e-3, mu
    for q in branch.points:
        assert q.stability == ("stable" if q.parameter < rod else "period-doubling"), q.parameter
        if q.parameter > rod:
            assert q.multipliers[0].imag == 0.0 and q.multipliers[0].real < -1.0
    lines = (tmp_path / "orbit_branch.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    (row,) = [r for r in rows if r[-1] == "period-doubling"]
    assert float(row[1]) == rod and abs(float(row[4]) + 1.0) <= 1e-4
