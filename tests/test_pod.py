"""POD (Karhunen–Loève modes, cosserat_fem/studies/karhunen_loeve.py): exact on constructed
snapshots, independent of the stations' spacing, and, for a linear free vibration, its leading modes
are the linear mode shapes with the energies the modal amplitudes give (issue 17, item 4).

The free vibration: the paper's cantilever (scenes/cao_tucker_2008.toml, loads off), started
at rest from p(s, 0) = ε (a1 φ1 + a2 φ2), φ1, φ2 its first two bending modes in the x-z plane
(cf.modes: ω1 = 206.78, ω2 = 1286.03 rad/s), ε = 1e-3, a1 = 1, a2 = 0.5, over T = two periods
of mode 1 (0.0608 s, 1216 steps of the midpoint rule: generalized-α with ρ∞ = 1). Linear theory
gives u(s, t) = Σ_i ε a_i cos(ω_i t) φ_i(s). Snapshots every 4 steps (305), at 97 stations.
"""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
import subprocess

import numpy as np
import pytest
from conftest import PYTHON, ROOT, file_size_limit, run_command, said, subprocess_env
from xdmf_files import read_arrays

import cosserat_fem as cf
from cosserat_fem.common.errors import SceneError
from cosserat_fem.studies.karhunen_loeve import Snapshots, pod, trapezoid_weights

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
#: Free vibration: no loads; the midpoint rule (energy-conserving: no numerical damping).
FREE = {
    "loads.force_density": [0, 0, 0],
    "output.xdmf": False,
    "output.checkpoint": False,
    "time.integrator": "generalized-alpha",
    "time.rho_inf": 1.0,
    "solver.stol": 1e-8,
}
EPS, A1, A2 = 1e-3, 1.0, 0.5
STATIONS = np.linspace(0.0, 1.0, 97)
STEPS = 1216
#: Snapshots every EVERY steps: 305 (their SVD costs T n² with n = 97 × 6).
EVERY = 4


def free_vibration():
    """(result, ω1, ω2, the two modes, Δt) of the run of the module docstring."""
    modes = cf.modes(cf.load(SCENE, FREE), count=4)
    first, second = [m for m in modes if m.kind == "bending-x"][:2]
    end = 2 * 2 * math.pi / first.omega
    dt = end / STEPS
    p = EPS * (A1 * first.shape.x.array.reshape(-1, 6) + A2 * second.shape.x.array.reshape(-1, 6))
    state = np.zeros((len(p), 12))
    state[:, :6] = p
    scene = cf.load(SCENE, {**FREE, "time.end": end, "time.step": dt})
    result = cf.run(scene, fields=STATIONS, initial_state=state.ravel(), field_every=EVERY)
    return result, first.omega, second.omega, (first, second), dt


def sample(shape, sigmas: np.ndarray, length: float) -> np.ndarray:
    """A mode's shape (a 6-component Function of p) at σ = ``sigmas`` in SI units (x, y, z
    [m] = ℓ p1..p3; angles [rad]), serial."""
    from dolfinx import geometry

    msh = shape.function_space.mesh
    points = np.zeros((len(sigmas), 3))
    points[:, 0] = sigmas
    tree = geometry.BoundingBoxTree(msh, 1)
    cells = geometry.compute_colliding_cells(msh, geometry.compute_collisions(tree, points), points)
    values = shape.eval(
        points, np.array([cells.links(i)[0] for i in range(len(points))], dtype=np.int32)
    )
    values[:, :3] *= length
    return values


@pytest.fixture(scope="module")
def vibration():
    result, w1, w2, modes, dt = free_vibration()
    length = result.model.scene.rod.length
    shapes = [sample(m.shape, STATIONS, length) for m in modes]
    return {"result": result, "omega": (w1, w2), "shapes": shapes, "dt": dt}


# --- constructed snapshots -----------------------------------------------------------------


def test_snapshots_of_known_decomposition_are_recovered_to_round_off():
    """u(t_i) = ū + Σ_k a_k(t_i) φ_k with φ_k orthonormal in the weighted product (random
    shapes, uneven stations, weights ρA and ρI) and a_k zero-mean, orthogonal, with mean
    squares λ_k: the SVD gives exactly λ_k, ±φ_k, ±a_k and ū. Round-off of the SVD is
    ~1e-16 × the largest σ, so a λ_k down to 1e-4 of the first keeps ~1e-12 relative:
    allowed 1e-10 (energies, coefficients) and 1e-9 (shapes: their own gap to the next
    λ enters the SVD's vector error)."""
    rng = np.random.default_rng(17)
    s = np.sort(rng.uniform(0.0, 2.0, 40))
    rod = (5.0, 2e-3, 3e-3, 5e-3)
    w = np.array([rod[0]] * 3 + list(rod[1:]))
    scale = np.sqrt(trapezoid_weights(s)[:, None] * w[None, :])
    r, times = 5, np.linspace(0.0, 1.0, 60)
    q, _ = np.linalg.qr(rng.standard_normal((s.size * 6, r)))
    shapes = q.T.reshape(r, s.size, 6) / scale
    energies = np.array([3.0, 1.0, 0.2, 1e-2, 3e-4])
    c = rng.standard_normal((times.size, r))
    c -= c.mean(axis=0)
    c, _ = np.linalg.qr(c)
    coefficients = c * np.sqrt(times.size * energies)
    mean = rng.standard_normal((s.size, 6))
    values = mean + np.einsum("tk,knc->tnc", coefficients, shapes)
    found = pod(Snapshots(s, times, values, rod), modes=r, weighting="kinetic")
    np.testing.assert_allclose(found.energies, energies, rtol=1e-10)
    np.testing.assert_allclose(found.total, energies.sum(), rtol=1e-10)
    np.testing.assert_allclose(found.cumulative[-1], 1.0, rtol=1e-10)
    np.testing.assert_allclose(found.mean, mean, rtol=0, atol=1e-12)
    for k in range(r):
        sign = np.sign(found.inner(found.shapes[k], shapes[k]))
        np.testing.assert_allclose(
            found.shapes[k], sign * shapes[k], rtol=0, atol=1e-9 * np.abs(shapes[k]).max()
        )
        np.testing.assert_allclose(
            found.coefficients[:, k],
            sign * coefficients[:, k],
            rtol=0,
            atol=1e-10 * np.abs(coefficients[:, k]).max(),
        )
        np.testing.assert_allclose(found.inner(found.shapes[k], found.shapes[k]), 1.0, rtol=1e-12)
        flat = found.shapes[k].ravel()
        assert flat[np.argmax(np.abs(flat))] > 0  # the sign convention
    # the coefficients' mean squares are the energies; the displacement weighting of the
    # same snapshots drops the angles
    np.testing.assert_allclose((found.coefficients**2).mean(axis=0), energies, rtol=1e-10)
    assert pod(Snapshots(s, times, values, rod), modes=2).shapes.shape == (2, s.size, 3)


def test_modes_do_not_depend_on_the_spacing_of_the_stations():
    """x(s, t) = Σ_k A_k c_k(t) f_k(s), f_k = √(2/ℓ) sin((k − ½) π s/ℓ) (orthonormal in L²(0, ℓ)),
    c_1 = cos 2πt, c_2 = sin 6πt on a periodic grid (exactly orthogonal, zero mean): the
    energies are A_k²/2 and the shapes f_k. On 201 evenly spaced stations and on 201 graded
    ones (σ_j = (j/200)², spacing 0 to 0.01 ℓ) the trapezoidal product errs by at most
    h² ((k − ½)π/ℓ)²/3 relative (h the largest spacing; the trapezoid rule's error bound for
    f_k², whose second derivative is at most 4/ℓ ((k − ½)π/ℓ)²): 7.4e-4 for k = 2 on the
    graded stations, 1.9e-4 on the even ones. The plain Euclidean sum over the graded stations
    (no quadrature weights) weighs the clamped end's crowded stations and changes the energy
    ratio by more than 10 %."""
    length = 2.0
    times = np.arange(40) / 40
    amplitudes = np.array([1e-2, 4e-3])
    expected = amplitudes**2 / 2

    def snapshots(sigma):
        s = length * sigma
        f = np.array([np.sqrt(2 / length) * np.sin((k - 0.5) * np.pi * s / length) for k in (1, 2)])
        c = np.array([np.cos(2 * np.pi * times), np.sin(6 * np.pi * times)])
        values = np.zeros((times.size, s.size, 3))
        values[:, :, 0] = np.einsum("k,kt,kn->tn", amplitudes, c, f)
        return Snapshots(s, times, values), f

    for sigma in (np.linspace(0.0, 1.0, 201), np.linspace(0.0, 1.0, 201) ** 2):
        snaps, f = snapshots(sigma)
        found = pod(snaps, modes=2)
        h = np.diff(snaps.s).max()
        bound = h**2 * (1.5 * np.pi / length) ** 2 / 3
        np.testing.assert_allclose(found.energies, expected, rtol=bound)
        for k in range(2):
            shape = np.zeros_like(found.shapes[k])
            shape[:, 0] = f[k]
            mac = found.inner(found.shapes[k], shape) ** 2 / found.inner(shape, shape)
            assert 1 - mac < bound
    plain = np.linalg.svd(snaps.values[:, :, 0], compute_uv=False) ** 2
    assert abs(plain[1] / plain[0] / (expected[1] / expected[0]) - 1) > 0.1


def test_bad_snapshots_are_refused_naming_the_argument():
    """modes outside [1, T], a non-finite value or time, stations out of order, an unknown
    weighting, the kinetic weighting without angles, snapshots that do not vary: SceneError
    naming what is wrong."""
    s, times = np.linspace(0, 1, 5), np.arange(4.0)
    values = np.ones((4, 5, 3))
    for modes in (0, 5, 1.5):
        with pytest.raises(SceneError, match=r"^modes \(--modes\): .*\[1, 4\]"):
            pod(Snapshots(s, times, values), modes=modes)
    bad = values.copy()
    bad[2, 1, 0] = np.nan
    with pytest.raises(SceneError, match=r"^snapshots: .*not finite \(at t = 2 s\)"):
        pod(Snapshots(s, times, bad))
    with pytest.raises(SceneError, match="^stations: "):
        pod(Snapshots(s[::-1], times, values))
    with pytest.raises(SceneError, match="^weighting: must be one of"):
        pod(Snapshots(s, times, values), weighting="mass")
    with pytest.raises(SceneError, match="^weighting: 'kinetic' needs the angles"):
        pod(Snapshots(s, times, values), weighting="kinetic")
    with pytest.raises(SceneError, match="^snapshots: times that are not finite$"):
        pod(Snapshots(s, np.array([0.0, np.nan, 2.0, 3.0]), values))
    with pytest.raises(SceneError, match="^snapshots: the fields do not vary"):
        pod(Snapshots(s, times, values))  # constant: nothing left once the mean is removed


def test_one_station_is_sampled_and_refused_by_pod_by_name():
    """cf.run(scene, fields=[0.5]) met an internal IndexError (DOLFINx's Function.eval gives a
    flat array for a single point), so cf.pod(result, [0.5]) never reached its SceneError
    "stations: need at least two". The one station's values are now those of the same
    station sampled with another (the same evaluation: equal), and pod refuses it by name."""
    scene = cf.load(SCENE, {"time.end": 0.0006, "output.xdmf": False})
    one = cf.run(scene, fields=[0.5])
    two = cf.run(scene, fields=[0.5, 1.0])
    assert one.field_values.shape == (21, 1, 6)
    assert np.array_equal(one.field_values[:, 0], two.field_values[:, 0])
    assert np.abs(one.field_values[-1, 0, :2]).max() > 0  # the rod moved there
    with pytest.raises(SceneError, match="^stations: need at least two"):
        cf.pod(one, [0.5])


#: Two stations: under mpirun -n 2 each rank holds one (a flat array from Function.eval).
ENDS_SCRIPT = """
import sys
import numpy as np
from mpi4py import MPI
import cosserat_fem as cf
result = cf.run(cf.load(sys.argv[1], {"time.end": 0.0006}), fields=[0.0, 1.0])
if MPI.COMM_WORLD.rank == 0:
    np.save(sys.argv[2], result.field_values)
"""


@pytest.mark.mpi
@pytest.mark.long
def test_a_rank_that_holds_one_station_samples_it(tmp_path):
    """Under ``mpirun -n 2`` the stations σ = 0 and 1 lie one on each rank: each rank's single
    point met the same IndexError. The gathered fields equal the serial run's to the solvers'
    round-off (MUMPS against PETSc's LU at every step: measured 9.8e-16 of the largest value;
    allowed 1e-12, a step's round-off times the Jacobian's condition over 20 steps)."""
    path = tmp_path / "fields.npy"
    proc = run_command(["-c", ENDS_SCRIPT, str(SCENE), str(path)], ranks=2)
    assert proc.returncode == 0, proc.stderr
    serial = cf.run(cf.load(SCENE, {"time.end": 0.0006}), fields=[0.0, 1.0]).field_values
    parallel = np.load(path)
    assert parallel.shape == serial.shape
    assert np.abs(parallel - serial).max() <= 1e-12 * np.abs(serial).max()


# --- the linear free vibration -------------------------------------------------------------


def window_terms(w1: float, w2: float, T: float) -> tuple[float, float]:
    """Bounds of the window's effects on the time correlations of c_i = cos ω_i t − mean over
    [0, T] (normalised by 1/2, the infinite window's ⟨c_i²⟩): the cross term
    |2⟨c1 c2⟩| ≤ 1/((ω2 − ω1) T) + 1/((ω2 + ω1) T) + 2/(ω1 T ω2 T) (the product of the means),
    and the self terms |2⟨c_i²⟩ − 1| ≤ 1/(2 ω_i T) + 2/(ω_i T)²."""
    cross = 1 / ((w2 - w1) * T) + 1 / ((w2 + w1) * T) + 2 / (w1 * T * w2 * T)
    selves = sum(1 / (2 * w * T) + 2 / (w * T) ** 2 for w in (w1, w2))
    return cross, selves


@pytest.mark.parametrize("weighting", ["displacement", "kinetic"])
def test_leading_pod_modes_of_a_free_vibration_are_its_linear_modes(vibration, weighting):
    """MAC_k = ⟨ψ_k, φ_k⟩² / (‖ψ_k‖² ‖φ_k‖²) of the POD modes ψ_k and the linear modes φ_k,
    in the POD's own product.

    With e_i = ε² a_i² ‖φ_i‖²/2 (e2/e1 = 0.021 here), c = ⟨φ1, φ2⟩/(‖φ1‖ ‖φ2‖) and the window's
    cross term γ (|2γ| ≤ 1/((ω2 − ω1)T) + ... = 0.0283, :func:`window_terms`), the correlation
    operator in the basis (φ̂1, its orthogonal complement in span{φ1, φ2}) has the off-diagonal
    e2 c + 2γ √(e1 e2), so the POD basis is turned by θ ≈ (e2 |c| + 2|γ| √(e1 e2))/(e1 − e2)
    from the linear modes: 1 − MAC1 ≤ θ² and 1 − MAC2 ≤ (|c| + θ)² (φ2 is itself |c| off the
    complement). c ≠ 0 because the linear modes are orthogonal in the mass product, not in
    the displacement product (Feeny & Kappagantu 1998): measured c = −7.6e-4 there (the rotary
    inertia ρ c22 of the angles is left out), 2.2e-4 in the kinetic product (its lumped
    quadrature against the finite elements' consistent mass). The time discretisation does
    not enter: the midpoint rule advances each linear mode on its own (with its own discrete
    frequency), so the snapshots stay in span{φ1, φ2}. Allowed twice the bound, for the
    perturbation's next terms (relative O(θ², e2/e1)). Measured: 1 − MAC = 2.4e-6 and 6.4e-7
    (displacement; bounds θ² = 1.8e-5, (|c| + θ)² = 2.5e-5), 2.5e-6 and 3.2e-6 (kinetic;
    bounds 1.8e-5 and 2.0e-5). The energy beyond the two modes is 2.4e-7 of the total: the
    nonlinear terms, relative (u/ℓ)² ~ 1e-6 (the tip moves ~1 mm); allowed 1e-5."""
    result, shapes = vibration["result"], vibration["shapes"]
    found = cf.pod(result, STATIONS, modes=4, weighting=weighting)
    components = 3 if weighting == "displacement" else 6
    phi = [shape[:, :components] for shape in shapes]
    norms = [found.inner(p, p) for p in phi]
    c = found.inner(phi[0], phi[1]) / math.sqrt(norms[0] * norms[1])
    e1, e2 = (EPS * A1) ** 2 * norms[0] / 2, (EPS * A2) ** 2 * norms[1] / 2
    cross, _ = window_terms(*vibration["omega"], result.field_times[-1])
    theta = (e2 * abs(c) + cross * math.sqrt(e1 * e2)) / (e1 - e2)
    mac = [found.inner(found.shapes[k], phi[k]) ** 2 / norms[k] for k in range(2)]
    assert 1 - mac[0] <= 2 * theta**2
    assert 1 - mac[1] <= 2 * (abs(c) + theta) ** 2
    assert found.cumulative[1] > 1 - 1e-5


def test_linear_modes_are_orthogonal_in_the_mass_product_only(vibration):
    """The cosine c of the two linear modes: in the kinetic (mass) product it is the
    trapezoid rule's error against the finite elements' consistent mass, about h² β2²/12 =
    2.0e-4 (h = 1/96 the stations' spacing, β2 = 4.694 the second mode's wavenumber ×ℓ):
    allowed twice that, measured 2.2e-4. In the displacement product the rotary inertia is
    left out: M-orthogonality ρA⟨x1, x2⟩ + ρ c22 ⟨ψ1, ψ2⟩ = 0 makes its c the rotary term
    −(c22/A) ⟨ψ1, ψ2⟩/(‖x1‖ ‖x2‖), measured −7.6e-4: equal to within the same quadrature
    error."""
    result, shapes = vibration["result"], vibration["shapes"]
    cosines = {}
    for weighting in ("displacement", "kinetic"):
        found = cf.pod(result, STATIONS, modes=1, weighting=weighting)
        phi = [shape[:, : len(found.components)] for shape in shapes]
        cosines[weighting] = found.inner(phi[0], phi[1]) / math.sqrt(
            found.inner(phi[0], phi[0]) * found.inner(phi[1], phi[1])
        )
    kinetic = found.weights
    h, beta2 = STATIONS[1] - STATIONS[0], 4.694
    allowed = 2 * h**2 * beta2**2 / 12
    assert abs(cosines["kinetic"]) <= allowed
    q = found.quadrature
    x1, x2 = shapes[0][:, 0], shapes[1][:, 0]
    rotary = (
        -(kinetic[4] / kinetic[0])
        * np.sum(q * shapes[0][:, 4] * shapes[1][:, 4])
        / (math.sqrt(np.sum(q * x1**2) * np.sum(q * x2**2)))
    )
    assert abs(cosines["displacement"] - rotary) <= allowed


def test_pod_energies_of_a_free_vibration_are_the_modal_amplitudes(vibration):
    """The energy ratio λ2/λ1 against the analytic e2/e1 = a2² ‖φ2‖² / (a1² ‖φ1‖²), within the
    window's terms (:func:`window_terms`: self terms 0.059, cross term 0.0283 entering the
    eigenvalues squared), c² and the sampling of the window at its N + 1 = 305 snapshots (the
    sum's end points, 2/N): bound 0.067, measured −5.2e-3 (T is a whole number of periods of
    mode 1, so its self term, 0.040 of the bound, vanishes: the bound is loose for it).

    Then against the exact two-mode prediction: the POD of Σ_i ε a_i (cos ω̃_i t − mean) φ_i
    at the run's output times with the midpoint rule's discrete frequencies
    ω̃ = (2/Δt) arctan(ω Δt/2) (it is exact for each linear mode: a rotation by ω̃ Δt a step):
    what is left is the nonlinearity, relative (u/ℓ)² ~ 1e-6 in the frequencies and the
    shapes, its phase accumulating over ω2 T = 78 rad: at most ~1e-4, and Newton's stop
    (stol 1e-8). Measured 7.2e-7 and 9.5e-6; allowed 1e-4. With the exact ω instead of ω̃ the
    energies err by the midpoint rule's phase error, (ω Δt)²/12 = 8.9e-6 and 3.4e-4 here
    (measured 9.3e-6, 3.3e-4)."""
    result, shapes = vibration["result"], vibration["shapes"]
    found = cf.pod(result, STATIONS, modes=2)
    phi = [shape[:, :3] for shape in shapes]
    norms = [found.inner(p, p) for p in phi]
    c = found.inner(phi[0], phi[1]) / math.sqrt(norms[0] * norms[1])
    w1, w2 = vibration["omega"]
    t = result.field_times
    cross, selves = window_terms(w1, w2, t[-1])
    analytic = A2**2 * norms[1] / (A1**2 * norms[0])
    bound = selves + cross**2 + c**2 + 2 / (t.size - 1)
    assert abs(found.energies[1] / found.energies[0] / analytic - 1) <= bound
    dt = vibration["dt"]
    discrete = [2 / dt * math.atan(w * dt / 2) for w in (w1, w2)]
    c = np.array([EPS * a * np.cos(w * t) for a, w in zip((A1, A2), discrete, strict=True)])
    values = np.einsum("kt,knc->tnc", c, np.array(phi))
    predicted = pod(Snapshots(found.s, t, values), modes=2)
    np.testing.assert_allclose(found.energies, predicted.energies, rtol=1e-4)
    # Other stations of the same number are not the ones the run sampled: refused.
    with pytest.raises(SceneError, match="^stations: not those the result was sampled at"):
        cf.pod(result, STATIONS**2, modes=2)


#: A free vibration from an initial velocity (no modes needed), 100 steps: for mpirun.
KICKED = {
    **FREE,
    "initial.velocity": ["0.3*s*s/(L*L)", "-0.2*s/L", 0],
    "time.end": 0.003,
    "time.step": 3e-5,
}
MPI_SCRIPT = """
import json, sys
import numpy as np
from mpi4py import MPI
import cosserat_fem as cf
scene = cf.load(sys.argv[1], json.loads(sys.argv[2]))
stations = np.linspace(0.0, 1.0, 97)
found = cf.pod(cf.run(scene, fields=stations), stations, modes=4, weighting="kinetic")
if MPI.COMM_WORLD.rank == 0:
    print("ENERGIES", json.dumps(found.energies.tolist()))
"""


# Long set (make test within 3 minutes): make test keeps the serial POD.
@pytest.mark.long
@pytest.mark.mpi
def test_pod_under_mpirun_equals_the_serial_one():
    """A free vibration from an initial velocity in x and y (100 steps), its POD under
    ``mpirun -n 2`` (each rank runs cf.pod on the gathered fields): the four leading energies
    equal the serial run's to the solvers' round-off (MUMPS against PETSc's LU at every step:
    measured 1.7e-14 relative at most, 1e-15 of the largest); allowed 1e-10 relative each (a
    step's round-off, ~1e-16 × the Jacobian's condition, over 100 steps)."""
    proc = run_command(["-c", MPI_SCRIPT, str(SCENE), json.dumps(KICKED)], ranks=2)
    assert proc.returncode == 0, proc.stderr
    line = [x for x in proc.stdout.splitlines() if x.startswith("ENERGIES")][0]
    parallel = np.array(json.loads(line.split(" ", 1)[1]))
    stations = np.linspace(0.0, 1.0, 97)
    result = cf.run(cf.load(SCENE, KICKED), fields=stations)
    serial = cf.pod(result, stations, modes=4, weighting="kinetic").energies
    np.testing.assert_allclose(parallel, serial, rtol=1e-10)


# --- a run's folder: the command line and the files ----------------------------------------


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    """The paper's scene for 0.006 s with its XDMF frames (every 2.4e-4 s: 26), and the same
    fields in memory at the XDMF points (σ = j/24: 8 cubic elements)."""
    out = tmp_path_factory.mktemp("pod") / "run"
    scene = cf.load(SCENE, {"time.end": 0.006, "output.checkpoint": False})
    nodes = np.linspace(0.0, 1.0, 25)
    result = cf.run(scene, out, fields=nodes, field_every=8)
    return out, result, nodes


def test_pod_of_a_run_folder_writes_csv_xdmf_and_png(run_folder, tmp_path):
    """``cosserat-fem pod RUN_DIR --modes 3 --out DIR`` in a process that never imports
    DOLFINx (the start-up rule of plot and validate): pod.csv's energies equal those of the
    fields the run kept in memory at the same points and times (the XDMF holds the same
    doubles: allowed 1e-12 relative); pod.xdmf, read as ParaView reads it (HDF5's C library),
    holds one frame a mode (Time = 1, 2, 3) with √λ_k φ_k on the run's 25 points; pod.png is
    a PNG. ``cf.pod(folder)`` in this process (which has DOLFINx: the folder is read by a
    child process, pod.xdmf written with DOLFINx's HDF5) gives the same."""
    folder, result, nodes = run_folder
    out = tmp_path / "pod"
    code = (
        "import sys; from cosserat_fem.cli import main; code = main(sys.argv[1:]); "
        "print('DOLFINX', 'dolfinx' in sys.modules); sys.exit(code)"
    )
    proc = run_command(["-c", code, "pod", str(folder), "--modes", "3", "--out", str(out)])
    assert proc.returncode == 0, proc.stderr
    assert "DOLFINX False" in proc.stdout
    assert "-> " in proc.stdout and "pod.csv" in proc.stdout
    with open(out / "pod.csv", newline="") as stream:
        rows = list(csv.reader(stream))
    assert rows[0] == ["mode", "energy_m^3", "fraction", "cumulative"]
    energies = np.array([float(r[1]) for r in rows[1:]])
    memory = cf.pod(result, nodes, modes=3)
    assert len(memory.times) == 26
    np.testing.assert_allclose(energies, memory.energies, rtol=1e-12)
    np.testing.assert_allclose([float(r[3]) for r in rows[1:]], memory.cumulative, rtol=1e-12)
    points, times, arrays = read_arrays(out / "pod.xdmf")
    np.testing.assert_array_equal(times, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(points[:, 2], nodes * 1.0, rtol=0, atol=1e-15)
    rms = np.sqrt(memory.energies)[:, None, None] * memory.shapes
    np.testing.assert_allclose(arrays["displacement"], rms, rtol=0, atol=1e-12 * np.abs(rms).max())
    assert (out / "pod.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    here = cf.pod(folder, modes=3, out=tmp_path / "here")
    np.testing.assert_allclose(here.energies, energies, rtol=1e-12)
    assert [p.name for p in here.files] == ["pod.csv", "pod.xdmf", "pod.png"]
    np.testing.assert_allclose(
        read_arrays(tmp_path / "here" / "pod.xdmf")[2]["displacement"],
        arrays["displacement"],
        rtol=0,
        atol=1e-15,
    )


def test_pod_command_refuses_bad_input_in_one_line(run_folder, tmp_path, capsys):
    """No such folder, a folder without XDMF frames, K < 1 or more than the frames, a frame
    holding a non-finite value: exit 2 and one line naming the argument or the file, no
    traceback. The kinetic weighting of the run (its angles and summary.json's rod) works."""
    from cosserat_fem.cli import main
    from cosserat_fem.io.hdf5 import Hdf5

    folder = run_folder[0]
    empty = tmp_path / "probes-only"
    empty.mkdir()
    shutil.copy(folder / "probes.csv", empty / "probes.csv")
    damaged = tmp_path / "damaged"
    shutil.copytree(folder, damaged)
    frame = damaged / "solution.frames" / "000003.h5"
    h5 = Hdf5()
    names = ["displacement", "angles"]
    xml = (damaged / "solution.xdmf").read_text()
    key = re.search(r"solution\.frames/000003\.h5:/Function/displacement/([^<]+)<", xml)[1]
    values = [h5.read(frame, f"/Function/{n}/{key}") for n in names]
    values[0][4, 1] = np.inf
    frame.write_bytes(
        bytes(
            h5.image([(f"/Function/{n}/{key}", v) for n, v in zip(names, values, strict=True)])[0]
        )
    )
    cases = [
        ([str(tmp_path / "none")], "is not a folder"),
        ([str(empty)], "holds no solution.xdmf"),
        ([str(folder), "--modes", "0"], r"modes \(--modes\): must be a whole number in \[1, 26\]"),
        ([str(folder), "--modes", "27"], r"modes \(--modes\): .* got 27"),
        ([str(damaged)], "000003.h5.*not finite"),
    ]
    for i, (arguments, message) in enumerate(cases):
        if i < 2:  # refused before anything is read: in this process
            capsys.readouterr()
            assert main(["pod", *arguments, "--out", str(tmp_path / "out")]) == 2
            stderr = capsys.readouterr().err
        else:
            proc = run_command(
                ["-m", "cosserat_fem.cli", "pod", *arguments, "--out", str(tmp_path / "out")]
            )
            assert proc.returncode == 2, (arguments, proc.stderr)
            stderr = proc.stderr
        lines = stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in stderr, stderr
        assert lines[0].startswith("cosserat-fem: error: ")
        assert re.search(message, lines[0]), lines[0]
    assert (
        main(
            ["pod", str(folder), "--weighting", "kinetic", "--quiet", "--out", str(tmp_path / "k")]
        )
        == 0
    )
    with pytest.raises(SceneError, match="^stations: a run folder"):
        cf.pod(folder, STATIONS)


#: ``cosserat-fem ARGS`` in a child, with DOLFINx loaded first (its HDF5 library then makes
#: the .h5 files) or not (h5py makes them).
POD_CHILD = (
    "import sys\nif sys.argv[1] == 'dolfinx':\n    import dolfinx\n"
    "from cosserat_fem.cli import main\nsys.exit(main(sys.argv[2:]))\n"
)


def pod_child(library: str, folder, out, limit: int | None = None) -> subprocess.CompletedProcess:
    # Open MPI's start-up writes files of over 3 MB (shared memory, PMIx's data store): one
    # process needs neither (btl=self, gds=hash), as in tests/test_reliability.py's D2.
    env = subprocess_env() | {"OMPI_MCA_btl": "self", "PMIX_MCA_gds": "hash"}
    return subprocess.run(
        [PYTHON, "-c", POD_CHILD, library, "pod", str(folder), "--out", str(out), "--quiet"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=None if limit is None else file_size_limit(limit),
    )


@pytest.mark.parametrize("library", ["h5py", pytest.param("dolfinx", marks=pytest.mark.long)])
def test_pod_on_a_full_disk_stops_with_exit_4_and_no_cut_file(run_folder, tmp_path, library):
    """Item 17: ``pod`` on a full disk (here a file size limit: the write fails with EFBIG
    as with ENOSPC). h5py writing its file to the disk met the failure inside HDF5, whose
    clean-up at exit was a segmentation fault (exit 139), or exit 2 ("bad input") with
    HDF5's error stack as the message; a failed pod.png or pod.csv was exit 2. Now every file
    is made in memory and written whole: one line naming the file, exit 4 (an output that
    cannot be written, as for a run), and every file left is whole (the bytes of pod's files
    without the limit: the outputs are deterministic) and nothing half-written or hidden.

    Limits: 1 kB lets pod.csv (~0.6 kB) through and stops at pod.frames/mesh.h5 (~2 kB);
    32 kB lets the frames and pod.xdmf (< 10 kB) through and stops at pod.png (~130 kB)."""
    folder = run_folder[0]
    whole = tmp_path / "whole"
    proc = pod_child(library, folder, whole)
    assert proc.returncode == 0, proc.stderr
    for limit, failing in ((2**10, "pod.frames/mesh.h5"), (32 * 2**10, "pod.png")):
        out = tmp_path / f"limit{limit}"
        proc = pod_child(library, folder, out, limit)
        assert proc.returncode == 4, proc.stderr
        ours = said(proc.stderr)
        assert (
            ours
            == [  # besides, under a 1 kB limit, Open MPI's "Forwarding signal 25"
                f"cosserat-fem: error: pod: cannot write {str(out / failing)!r} (File too large)"
            ]
            and "Traceback" not in proc.stderr
        ), proc.stderr
        left = [p for p in out.rglob("*") if p.is_file()]
        assert left and not (out / failing).exists()
        for path in left:
            assert path.read_bytes() == (whole / path.relative_to(out)).read_bytes(), path
