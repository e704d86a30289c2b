"""Periodic orbits by shooting and their Floquet multipliers (cosserat_fem/analysis/periodic.py),
on the clamped–clamped rod of demos/frequency_response.py: the paper's aluminium rod (ℓ = 1 m,
40 mm × 60 mm) driven in x by F sin(πs/ℓ) sin(r ω1 t), ω1 = 1302.92 rad/s, with viscous
damping c = 170.74 N s/m² (ζ1 = c/(2ρAω1) = 0.01).

The references: for a small load, the multipliers of a linear damped mode and the scheme's
amplification factor over the period (closed forms); at the demo's load, the three roots of the
one-mode Duffing harmonic balance (cosserat_fem/reference/backbone.py) inside the band where
the response is multivalued, with the tolerances the demo's test derives for its time-marched
branches (tests/test_demos.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT, parse_qoi, run_command

from cosserat_fem import api
from cosserat_fem.analysis.periodic import Shooting
from cosserat_fem.reference.backbone import Duffing, clamped_modal_force, clamped_mode

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
W1 = 1302.92  # rad/s, the first bending frequency in x (cosserat-fem modes)
F_DEMO = 5915.8  # N/m: the first mode's modal force 1000 m/s²
C = 170.74  # N s/m²
RHO_A = 2730.0 * 0.04 * 0.06  # kg/m
PERIOD = "2*pi/(r*w1)"


def clamped(F: float, r: float):
    """The demo's scene (scenes/sweeps/clamped_hysteresis.toml's settings) at load F [N/m]
    and frequency ratio r."""
    return api.load(
        PAPER,
        {
            "supports.end": "clamped",
            "output.xdmf": False,
            "output.checkpoint": False,
            "damping.translational": C,
            "loads.force_density": ["F*sin(pi*s/L)*sin(r*w1*t)", 0, 0],
            "parameters.F": F,
            "parameters.w1": W1,
            "parameters.r": r,
        },
    )


def amplification(shooting: Shooting, z: complex) -> complex:
    """R(z) = 1 + z bᵀ (I − zA)⁻¹ 1 of the scene's SDIRK tableau: y' = λy, one step of
    h gives y R(λh)."""
    A, b = shooting.integrator.A, shooting.integrator.b
    return 1.0 + z * (b @ np.linalg.solve(np.eye(len(b)) - z * A, np.ones(len(b))))


def test_the_multipliers_of_a_linear_damped_response():
    """A thousandth of the demo's load (mid-span amplitude 4 μm: the stretching terms are
    (a/ℓ)² ~ 1e-11 of the linear ones) at r = 1.07, N = 100 SDIRK3 steps a period.

    The first bending mode, ω = ω1 of `cf.modes` on the same mesh, damped by c: its modal
    mass has the translational ρA ∫φ² and the rotary ρI ∫φ'² (I/A = a²/12), of which only the
    first is damped, so ζ = c/(2ρAω) (1 − ε), ε = (a²/12) ∫φ'²/∫φ² = 1.64e-3 (Euler–Bernoulli
    shape). The flow's multipliers are exp(λT), λ = ω(−ζ ± i√(1 − ζ²)); the discrete map's
    are R(λh)^N, R the scheme's amplification factor (:func:`amplification`), which differ
    from them by 1.0e-4 here (the integrator's error over the period).

    Asserted: the orbit's pair nearest R(λh)^N lies within 1e-5 of it, ten times closer than
    the integrator's own error, so the monodromy matrix is the discrete map's (measured
    3.8e-6: the ε correction, 9e-5 in |μ|, known to ~5 % from the Euler–Bernoulli shape,
    and ω's eigen-solve); and within |R^N − exp(λT)| + 1e-5 of the flow's. Also the
    amplitude against the linear one-mode response f/√((ω² − Ω²)² + (2ζωΩ)²), f = 1 m/s²:
    within 1 % (the other modes' quasi-static share at mid-span, measured −0.24 %)."""
    scene = clamped(F_DEMO / 1000, 1.07)
    omega = api.modes(scene, count=1)[0].omega
    shooting = Shooting(scene, PERIOD, steps_per_period=100)
    try:
        orbit = shooting.find(shooting.rest())
        T, N = shooting.period, shooting.steps
    finally:
        shooting.destroy()
    s = np.linspace(0.0, 1.0, 20001)
    phi, dphi = clamped_mode(s, 1.0)
    eps = (0.04**2 / 12) * np.trapz(dphi**2, s) / np.trapz(phi**2, s)
    assert eps == pytest.approx(1.64e-3, rel=0.01)
    zeta = C / (2 * RHO_A * omega) * (1 - eps)
    lam = omega * complex(-zeta, math.sqrt(1 - zeta**2))
    scheme, exact = amplification(shooting, lam * T / N) ** N, np.exp(lam * T)
    integrator_error = abs(scheme - exact)
    assert 5e-5 < integrator_error < 2e-4  # the scheme's error that the test must resolve
    mu = orbit.multipliers
    nearest = mu[np.argmin(np.abs(mu - scheme))]
    assert abs(nearest - scheme) <= 1e-5
    assert abs(nearest - exact) <= integrator_error + 1e-5
    assert np.conj(nearest) == pytest.approx(mu[np.argmin(np.abs(mu - np.conj(scheme)))])
    assert orbit.stability == "stable" and orbit.iterations <= 3  # linear: one step, one check
    Omega = 1.07 * W1
    linear = 1.0 / math.hypot(omega**2 - Omega**2, 2 * C / (2 * RHO_A) * Omega)
    assert orbit.amplitude == pytest.approx(linear, rel=0.01)


def harmonic_balance_guesses(shooting: Shooting, scene, r: float):
    """The three roots a of the one-mode harmonic balance at Ω = r ω1 and their guesses: q =
    a sin(Ωt − ϑ), tan ϑ = 2ζωΩ a / ((ω² + ¾αa² − Ω²) a), at t = 0 (q = −a sin ϑ, q̇ = aΩ cos ϑ)
    in the first mode's shape (Shooting.modal_state)."""
    duffing = Duffing.of_clamped_scene(scene, omega=W1)
    s = np.linspace(0.0, 1.0, 20001)
    f = clamped_modal_force(F_DEMO * np.sin(np.pi * s), s, 1.0, RHO_A)
    Omega = r * W1
    roots = duffing.amplitudes(f, Omega)
    guesses = []
    for a in roots:
        stiffness = duffing.omega**2 + 0.75 * duffing.alpha * a * a - Omega**2
        theta = math.atan2(2 * duffing.zeta * duffing.omega * Omega * a, stiffness * a)
        guesses.append(
            shooting.modal_state(
                lambda x: clamped_mode(x, 1.0)[0],
                lambda x: clamped_mode(x, 1.0)[1],
                -a * math.sin(theta),
                a * Omega * math.cos(theta),
            )
        )
    return roots, guesses


@pytest.mark.long
def test_three_orbits_inside_the_multivalued_band():
    """At r = 1.07 (inside the band 1.05-1.11 where the demo's sweeps part), N = 300 steps a
    period as the demo's sweep: shooting from each root of the harmonic balance finds three
    distinct orbits. Their mid-span amplitudes match the roots within the one-mode reduction's
    error, as tests/test_demos.py derives it for the time-marched branches: the upper branch
    within 3 % (α 2 % low for the 40 mm section raises a by 1 %, the next order in a² adds
    up to ~1.4 %; measured +1.5 %), the lower within 2 % (measured −0.35 %); the middle root,
    at the same large amplitude as the upper, within 3 % (measured +2.0 %). The upper and lower
    orbits are stable (every |μ| < 1: the damped modes' |μ| ≈ exp(−cT/(2ρA)) = 0.943); the
    middle one is not, with a real multiplier above 1 (measured 1.14): it lies between the
    two folds, where a multiplier crosses +1.

    The stable two are the states the demo's sweep settles in by time marching
    (docs/verification.md, section 7, r = 1.07: up 21.972 mm, down 4.179 mm, printed to
    four digits, each settled to 1.6e-4 of its motion): within 5e-4 (measured 2e-5, 5e-5)."""
    r = 1.07
    scene = clamped(F_DEMO, r)
    shooting = Shooting(scene, PERIOD, steps_per_period=300)
    try:
        roots, guesses = harmonic_balance_guesses(shooting, scene, r)
        assert len(roots) == 3
        orbits = [shooting.find(g) for g in guesses]
    finally:
        shooting.destroy()
    low, middle, high = orbits
    assert low.amplitude == pytest.approx(roots[0], rel=0.02)
    assert middle.amplitude == pytest.approx(roots[1], rel=0.03)
    assert high.amplitude == pytest.approx(roots[2], rel=0.03)
    assert high.amplitude == pytest.approx(21.972e-3, rel=5e-4)
    assert low.amplitude == pytest.approx(4.179e-3, rel=5e-4)
    assert low.amplitude < 0.5 * middle.amplitude < middle.amplitude < high.amplitude
    for orbit in (low, high):
        assert orbit.stable and np.abs(orbit.multipliers).max() < 1.0
        assert orbit.residual < 1e-9
    assert middle.stability == "fold"
    largest = middle.multipliers[0]
    assert abs(largest.imag) == 0.0 and largest.real > 1.0
    assert np.sum(np.abs(middle.multipliers) > 1.0) == 1  # one unstable direction


MPI_ORBIT = """
import sys
import cosserat_fem as cf
from cosserat_fem.analysis import periodic
from mpi4py import MPI
if sys.argv[1:] == ["petsc"]:  # the variational stages by MUMPS, not gathered
    periodic.GATHERED_DOFS = 0
gathers = []
csr = periodic._csr
periodic._csr = lambda A: gathers.append(1) or csr(A)
scene = cf.load({paper!r}, {{"supports.end": "clamped", "damping.translational": 170.74,
    "loads.force_density": ["F*sin(pi*s/L)*sin(r*w1*t)", 0, 0], "parameters.F": 5915.8,
    "parameters.w1": 1302.92, "parameters.r": 1.07, "output.xdmf": False,
    "output.checkpoint": False}})
orbit = cf.periodic_orbit(scene, "2*pi/(r*w1)", steps_per_period=100, settle=2)
if MPI.COMM_WORLD.rank == 0:
    print(f"QOI amplitude = {{orbit.amplitude!r}}")
    print(f"QOI stable = {{float(orbit.stable)!r}}")
    print(f"QOI gathered = {{float(bool(gathers))!r}}")
    for k, m in enumerate(orbit.multipliers[:6]):
        print(f"QOI mu{{k}}_re = {{m.real!r}}")
        print(f"QOI mu{{k}}_im = {{m.imag!r}}")
"""


@pytest.mark.long
def test_periodic_orbit_serial_equals_mpirun():
    """cf.periodic_orbit (two settled periods from rest, then shooting; N = 100) on one rank
    and on two, there with the variational stages gathered on every rank (periodic.py,
    "MPI": this 8-element rod's 150 unknowns are below GATHERED_DOFS) and by MUMPS: the same
    orbit's amplitude and six largest multipliers. The operations differ in the LU (PETSc's
    own serially, SuperLU gathered, MUMPS) and the order of the reductions: round-off,
    amplified by the Newton solves' tolerance (stol 1e-11), not by the result; within 1e-9
    relative (measured 1e-13)."""
    code = MPI_ORBIT.format(paper=str(PAPER))
    qoi = {}
    for ranks, variant in ((1, []), (2, []), (2, ["petsc"])):
        proc = run_command(["-c", code, *variant], ranks)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        qoi[ranks, tuple(variant)] = parse_qoi(proc.stdout)
    serial = qoi[1, ()]
    assert serial["stable"] == 1.0 and len(serial) == 15
    assert serial["gathered"] == 0.0 == qoi[2, ("petsc",)]["gathered"]
    assert qoi[2, ()]["gathered"] == 1.0
    for parallel in (qoi[2, ()], qoi[2, ("petsc",)]):
        assert parallel.keys() == serial.keys()
        for key, value in serial.items():
            if key != "gathered":
                assert parallel[key] == pytest.approx(value, rel=1e-9, abs=1e-12), key


@pytest.mark.long
def test_the_continuation_protocol_gives_the_orbit_s_tangent():
    """The protocol a pseudo-arclength engine calls (Shooting: residual, linearise, solve,
    dparameter, dot): along the lower orbit of the demo's load at r = 1.07 (N = 100), the
    tangent du/dr = −(M − I)⁻¹ ∂R/∂r from one ``linearise`` and one ``solve`` of
    ``dparameter`` equals the central difference of the orbits found at r ± 1e-4.

    Tolerance: the central difference's error is O(δ²) (measured 3.5e-4 at δ = 1e-3, 3.8e-6
    at 1e-4: the factor 100 of δ²), dparameter's forward difference of relative step 1e-6
    adds ~1e-6, the orbits' Newton tolerance 1e-12/(2δ) ~ 5e-9: within 2e-5 of the largest
    entry. The residual at the orbit is below the Newton tolerance, and ``dot`` is the
    Euclidean product (serial)."""
    shooting = Shooting(clamped(F_DEMO, 1.07), PERIOD, steps_per_period=100, parameter="r")
    try:
        orbit = shooting.find(shooting.settle(shooting.rest(), 2), tolerance=1e-12)
        u, r, delta = orbit.state, 1.07, 1e-4
        assert np.abs(shooting.residual(u, r)).max() < 1e-10
        shooting.linearise(u, r)
        tangent = shooting.solve(-shooting.dparameter(u, r))
        assert shooting.model.parameter_value("r") == r  # dparameter leaves p as it was
        ends = []
        for p in (r + delta, r - delta):
            shooting.set_parameter(p)
            ends.append(shooting.find(u, tolerance=1e-12).state)
    finally:
        shooting.destroy()
    central = (ends[0] - ends[1]) / (2 * delta)
    assert np.abs(central - tangent).max() <= 2e-5 * np.abs(central).max()
    assert shooting.dot(central, tangent) == pytest.approx(float(central @ tangent))


def test_a_linear_branch_follows_the_closed_form(tmp_path):
    """cf.periodic_branch at a thousandth of the demo's load (linear: the stretching terms are
    (a/ℓ)² ~ 1e-10 of the linear ones), r from 1.03 to 1.07 on the resonance's flank, N = 50
    SDIRK3 steps a period. Not across the peak: there a ∝ 1/ζ, and the scheme's numerical
    damping, O((ωh)⁴) a step (|R^N| − |exp(λT)| = 1e-4 at N = 100, the test above: 0.16 % of
    the physical ζωT = 0.063), is 16 times that at N = 50, 2.5 % of ζ; on the flank the
    damping term (2ζr)²/(r² − 1)² ≤ 0.1 of |H|⁻², so it moves |H| by < 0.15 %.

    Asserted: every orbit's amplitude equals the linear one-mode response
    |H(r)| f = f/√((ω² − Ω²)² + (2ζωΩ)²), f = 1 m/s², ζ = c/(2ρAω) (1 − ε) (the rotary
    inertia's share ε = 1.64e-3, test above), within 1 % (the other modes' quasi-static share
    at mid-span, −0.24 % at 1.07 in the test above; the scheme's 1e-4); each is stable and no
    special point is found (det(M − I) = Π(μ − 1) keeps its sign: every |μ| < 1); the
    branch reaches r = 1.07 exactly (the engine's last point at the bound); determinant()
    is the product of (μ − 1) over the free dofs and of −1 over the held ones (the same LU:
    1e-9 relative, the eigen-solve's round-off on 1e2 factors); and orbit_branch.csv has the
    header ORBIT_COLUMNS and one row per point."""
    from cosserat_fem.analysis.periodic import ORBIT_COLUMNS, Shooting

    scene = clamped(F_DEMO / 1000, 1.03)
    omega = api.modes(scene, count=1)[0].omega
    branch = api.periodic_branch(
        scene,
        PERIOD,
        "r",
        1.03,
        1.07,
        steps_per_period=50,
        step=0.01,
        max_step=0.02,
        out=tmp_path,
    )
    zeta = C / (2 * RHO_A * omega) * (1 - 1.64e-3)
    rs = [q.parameter for q in branch.points]
    assert rs[0] == 1.03 and rs[-1] == pytest.approx(1.07, abs=1e-9)
    inner = rs[:-1]  # the last point is the engine's at the bound, after the step beyond it
    assert all(b > a for a, b in zip(inner, inner[1:], strict=False)) and len(rs) >= 4
    assert not branch.special and branch.reason == "p reached 1.07"
    for q in branch.points:
        Omega = q.parameter * W1
        linear = 1.0 / math.hypot(omega**2 - Omega**2, 2 * zeta * omega * Omega)
        assert q.amplitude == pytest.approx(linear, rel=0.01), q.parameter
        assert q.stability == "stable"
    lines = (tmp_path / "orbit_branch.csv").read_text().splitlines()
    assert lines[0].split(",") == list(ORBIT_COLUMNS) and len(lines) == len(rs) + 1
    shooting = Shooting(scene, PERIOD, steps_per_period=50, parameter="r")
    try:
        shooting.linearise(branch.points[-1].state, 1.07)
        sign, log_det = shooting.determinant()
        assert shooting.linearised is not None
        mu = shooting.multipliers(shooting.linearised)
        held = shooting.n - mu.size
    finally:
        shooting.destroy()
    product = np.prod(mu - 1.0) * (-1.0) ** held
    assert abs(product.imag) <= 1e-12 * abs(product)
    assert sign * math.exp(log_det) == pytest.approx(product.real, rel=1e-9)


def harmonic_balance_folds(f: float, duffing: Duffing) -> list[tuple[float, float]]:
    """The two folds (r, amplitude [m]) of the one-mode harmonic balance under f sin(r ω1 t):
    where its count of roots changes, by bisection in r (60 halvings of [1.0, 1.07] and
    [1.07, 1.2]: to 1e-16), the amplitude the double root's."""
    folds = []
    for a, b in ((1.0, 1.07), (1.2, 1.07)):
        count = len(duffing.amplitudes(f, a * W1))
        for _ in range(60):
            middle = 0.5 * (a + b)
            if len(duffing.amplitudes(f, middle * W1)) == count:
                a = middle
            else:
                b = middle
        roots = duffing.amplitudes(f, b * W1)
        double = min(zip(roots, roots[1:], strict=False), key=lambda p: p[1] - p[0])
        folds.append((0.5 * (a + b), 0.5 * sum(double)))
    return folds


@pytest.mark.long
def test_the_whole_s_curve_with_its_folds():
    """cf.periodic_branch of the demo's forced orbit (its load, N = 100 SDIRK3 steps a period)
    from r = 0.98 to 1.14: the lower-frequency single branch rising to the upper branch, the
    fold where it ends, the unstable middle branch back to the second fold, the lower branch
    out to 1.14.

    Asserted:
    - the shape: r grows, falls, grows again, with exactly two folds located (limit points)
      and no other special point; the points between them (the middle branch) are unstable
      with one real multiplier > 1 ("fold"), all others stable (every |μ| < 1);
    - a real multiplier crosses +1 at each fold: the two points that bracket it (where dr/ds
      changes sign) have det(M − I) = Π(μ − 1) of opposite signs, which a complex pair
      (|μ − 1|² > 0) cannot give; and at the located fold a real multiplier is at +1 within
      1e-4: it is located to 1e-6 in arclength (locate_tolerance), and μ moves by at most
      0.1 a step (asserted, the largest |μ| between consecutive points; measured 0.08) over
      steps of at least 0.005 (the first step: none rejected, so none shorter), so
      |dμ/ds| ≲ 20 and |μ − 1| ≲ 2e-5; 1e-4 leaves 5 for μ(s)'s curvature over the step
      (measured 2e-6 and 0);
    - the folds against the harmonic balance's (:func:`harmonic_balance_folds`, r = 1.0438
      and 1.1142): its fold lies at r² − 1 = ¾ α a²/ω² on the backbone (a the fold's
      amplitude, set by the damping), so the one-mode reduction's 3 % in amplitude
      (tests/test_demos.py, the upper branch measured +1.6 %) is 6 % in r² − 1: within
      0.06 (r_hb² − 1) in r² (measured −3.8 % and −1.1 %); the fold amplitudes within 3 %
      (measured −0.03 %, +0.9 %);
    - the folds against the demo's sweeps (docs/verification.md, section 7): the upward one
      holds the upper branch at 1.10 and jumps by 1.11, the downward one holds the lower at
      1.05 and jumps by 1.04. A sweep can leave a branch only where it ends or before (its
      basin shrinks to nothing at the fold), so the folds lie at r > 1.10 and r < 1.05;
      and, the jump being at most one sweep step of 0.01 early, r < 1.12 and r > 1.03
      (measured 1.1100, 1.0433)."""
    scene = clamped(F_DEMO, 0.98)
    branch = api.periodic_branch(
        scene, PERIOD, "r", 0.98, 1.14, settle=3, steps_per_period=100, step=0.005
    )
    assert branch.reason == "p reached 1.14" and branch.rejected == 0
    assert [q.kind for q in branch.special] == ["limit", "limit"]
    upper_fold, lower_fold = branch.folds
    assert upper_fold.parameter > lower_fold.parameter
    points = branch.points
    r = np.array([q.parameter for q in points])
    turns = np.flatnonzero(np.diff(np.sign(np.diff(r[:-1]))))  # the last point: at the bound
    assert len(turns) == 2
    for q in points:
        between = lower_fold.amplitude < q.amplitude < upper_fold.amplitude and (
            lower_fold.parameter < q.parameter < upper_fold.parameter
        )
        on_middle = q.stability == "fold"
        if on_middle:
            assert between
            assert np.sum(np.abs(q.multipliers) > 1.0) == 1
            assert q.multipliers[0].imag == 0.0 and q.multipliers[0].real > 1.0
        else:
            assert q.stability == "stable"
    kinds = [q.stability for q in points]
    first, last = kinds.index("fold"), len(kinds) - 1 - kinds[::-1].index("fold")
    assert set(kinds[first : last + 1]) == {"fold"}  # one unstable stretch, the middle
    largest = np.array([abs(q.multipliers[0]) for q in points])
    assert np.abs(np.diff(largest)).max() <= 0.1  # the premise of the bound below
    for fold in branch.folds:
        k = min(
            (k for k in range(1, len(points)) if points[k - 1].det_sign != points[k].det_sign),
            key=lambda k: abs(points[k].parameter - fold.parameter),
        )
        assert (points[k - 1].dparameter > 0) != (points[k].dparameter > 0)
        assert abs(nearest_real_to_one(fold.multipliers) - 1.0) <= 1e-4
    duffing = Duffing.of_clamped_scene(scene, omega=W1)
    s = np.linspace(0.0, 1.0, 20001)
    f = clamped_modal_force(F_DEMO * np.sin(np.pi * s), s, 1.0, RHO_A)
    (hb_low, a_low), (hb_up, a_up) = harmonic_balance_folds(f, duffing)
    for fold, r_hb, a_hb in ((lower_fold, hb_low, a_low), (upper_fold, hb_up, a_up)):
        assert abs(fold.parameter**2 - r_hb**2) <= 0.06 * (r_hb**2 - 1.0)
        assert fold.amplitude == pytest.approx(a_hb, rel=0.03)
    assert 1.10 < upper_fold.parameter < 1.12
    assert 1.03 < lower_fold.parameter < 1.05


def nearest_real_to_one(multipliers: np.ndarray) -> float:
    """The real multiplier nearest +1."""
    real = [m.real for m in multipliers if m.imag == 0.0]
    return min(real, key=lambda m: abs(m - 1.0))
