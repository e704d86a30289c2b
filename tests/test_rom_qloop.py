"""The hyper-reduced run with its integrator on the reduced coordinates (docs/rom.md §8;
cosserat_fem/rom/hyper.py ``ReducedCoordinates``, cosserat_fem/timestepping/integrators.py "The
space"): SDIRK's stage arithmetic on 2k-vectors and U lifted only where read, against the
hyper-reduced run whose integrator works on full vectors (the same ECSW basis, the same
residual and Jacobian), its restart, the integrators that refuse it, and the chart's
refusal."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import ROOT

import cosserat_fem as cf
from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.common.errors import SolverError
from cosserat_fem.rom import basis as rb
from cosserat_fem.rom import galerkin, hyper
from cosserat_fem.rom.indicator import ErrorIndicator

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
SHORT = {"time.end": 0.006}  # the paper's scene over a tenth of its span (200 steps)
EPS = np.finfo(float).eps


def _run(scene, basis, coordinates: bool, **keywords):
    make = galerkin.solver_factory(basis, True, coordinates)
    return run_scene(scene, write_outputs=False, record=True, solver_factory=make, **keywords)


def _free_end(result) -> np.ndarray:
    return result.probes[:, 1:4]


@pytest.fixture(scope="module")
def paper():
    """The short paper scene, its POD basis (ε ≤ 1e-10) with ECSW's sampling at τ = 1e-2
    (all 8 elements, docs/rom.md §9), and its full run."""
    scene = cf.load(PAPER, SHORT)
    basis, (full,) = rb.train([scene], tolerance=1e-10)
    return scene, hyper.ecsw([scene], basis, 1e-2), full


def test_paper_scene_in_reduced_coordinates_is_the_full_vector_run(paper):
    """(a) The paper's short span (200 SDIRK3 steps, 400 stage solves): the run in reduced
    coordinates equals the hyper-reduced run on full vectors to round-off. In exact arithmetic
    they are the same recursion: every state the full-vector integrator forms is
    U_ref + V y with the y this one forms (docs/rom.md §5, "Why the integrators are
    unchanged"), and its guess q₀ = Vᵀ W (U − U_ref) (here the W-projection: the sampled rows
    are all rows) gives that y back. In floating point they differ per solve by the
    projection's sums of n = 300 terms, at most γ_n = n ε = 6.7e-14 of the state (worst case),
    and the stable recursion (|R(z)| ≤ 1) adds 400 of them: the bound 400 n ε = 2.7e-11 of the
    free end's norm, asserted 1e-10 (measured 7e-15). The iterations are the same in number
    (decided by norms far from their thresholds), the solver says which state it kept, and
    the final U (lifted in full at the end) agrees to the same bound.

    The error indicator (docs/rom.md §10), which asks for the full state at its sampled steps
    only (loop.lift), estimates alike. E is linear in the defect R = F(U_red) that forces its
    modes (10.5); states δ apart (relative to the free end's norm) move R by J δU, which the
    transport turns into an error of the size of δU times its gain, so |ΔE| ≤ gain × δ. With
    the states' bound δ = 400 n ε = 2.7e-11 and the gain ≤ 10 (tests/test_rom_cli.py's
    restart, the same argument: measured 0.087 there), |ΔE| ≤ 2.7e-10 at every sample (E up
    to 0.48 at the first samples, near rest; measured 2.2e-14). The bound of before, 1e-7
    of E's largest value, was a guess at R's size; this one follows from the states'."""
    scene, sampled, full = paper
    indicators = [ErrorIndicator(), ErrorIndicator()]
    vectors = _run(scene, sampled, False, observers=[indicators[0]])
    coordinates = _run(scene, sampled, True, observers=[indicators[1]])
    assert coordinates.summary["newton"]["loop"] == "hyper"
    # the indicator's estimates alike: |ΔE| ≤ 10 × 400 n ε (docstring)
    values = [np.array(i.values) for i in indicators]
    assert values[0].size == 20 and np.all(values[0] > 0)
    n = sampled.V.shape[0]
    assert np.abs(values[1] - values[0]).max() <= 10 * 400 * n * EPS
    assert coordinates.summary["newton"]["iterations"] == vectors.summary["newton"]["iterations"]
    difference = rb.relative_l2(_free_end(coordinates), _free_end(vectors))
    assert difference <= 1e-10
    u, v = coordinates.model.U.x.array, vectors.model.U.x.array
    assert np.abs(u - v).max() <= 1e-10 * np.abs(v).max()
    # and it is the reduced model: the full run within §7's 10 √ε (measured 6.6e-6)
    assert rb.relative_l2(_free_end(coordinates), _free_end(full)) <= 10 * np.sqrt(
        sampled.energy_left_out()
    )


def test_riser_in_reduced_coordinates_is_the_full_vector_run():
    """(b) The riser of benchmarks/long_rods.py at 200 elements (n = 7212, 3D, a chart),
    trained on 20 steps (k at ε ≤ 1e-8, ECSW on every other stage at τ = 1e-2: 17 of 200
    elements), 20 steps reduced both ways. Here the full-vector run reads its guess off the
    sampled rows S, q₀ = V_S⁺ (U − U_ref)_S (V_S's condition number κ ≤ 1e6,
    hyper.CONDITION_LIMIT), whose round-off is at most (κ + |S|) ε of the state per solve
    (κ ε from the rounded rows, γ_|S| = |S| ε from P's sums of |S| terms); 40 solves of a
    stable recursion: the bound 40 (κ + |S|) ε, with κ and |S| of the run (measured κ = 34,
    |S| ≈ 800: 7e-12; measured difference 4.7e-16, 17 elements kept). The state check ran on
    the bound (8.1) only: the riser's angles stay far from the chart's limit (``quiet``)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from long_rods import riser

    scene = riser(200, 20)
    basis, _ = rb.train([scene], tolerance=1e-8)
    sampled = hyper.ecsw([scene], basis, 1e-2, every=2)
    assert sampled.sample_cells.size < 40
    kept: dict = {}
    vectors = _run(scene, sampled, False)
    coordinates = _run(scene, sampled, True, observers=[_keeper(kept)])
    assert kept["quiet"] is True
    difference = rb.relative_l2(_free_end(coordinates), _free_end(vectors))
    assert difference <= 40 * (kept["kappa"] + kept["rows"]) * EPS
    assert coordinates.summary["newton"]["iterations"] == vectors.summary["newton"]["iterations"]


def _condition(solver) -> float:
    """κ(V_S) of the guess's rows (1: the W-projection, no rows)."""
    rows = solver._arrays["fit"]
    if rows.size == 0:
        return 1.0
    sigma = np.linalg.svd(solver.V[rows], compute_uv=False)
    return float(sigma[0] / sigma[-1])


def restart_bound(stol: float, steps: int, norm: float, scale: float) -> float:
    """The largest difference, relative to ``scale``, of the free end between a reduced run
    continued from a checkpoint and the straight run, ``steps`` SDIRK3 steps after the
    restart: each stage solve ends with its estimated error at most stol ‖U‖ (the chord
    Newton's stop, cosserat_fem/nls/newton.py: η ‖δU‖ ≤ stol ‖U‖, Hairer & Wanner IV.8), and
    the two runs iterate with different Jacobians (the continued one forms a fresh J_r, the
    straight one keeps its frozen one), so their stage values may differ by up to
    2 stol ‖U‖. A step passes its stages' errors ε_1, ε_2 to U_{n+1} as
    (b_1/γ) ε_1 + (b_2/γ) [(S − I)(a_21/γ) ε_1 + ε_2], S = (I − γhJ)⁻¹ of norm ≤ 1 for
    the damped rod: at most c = b_1/γ + 2 b_2 |a_21|/γ² + b_2/γ = 2.20 (SDIRK3's tableau,
    computed here) times the larger ε, and the stable recursion (|R(z)| ≤ 1) does not
    amplify the earlier steps': 2 c stol ‖U‖ steps, ‖U‖ the largest over the run (the
    free end's entries no larger than the vector's norm). The paper's short scene:
    ‖U‖ ≈ 0.062, the free end's motion 1.05e-3 m, 100 steps: 2.6e-3 of the motion; a
    restart from another state or time misses by the motion itself."""
    from cosserat_fem.timestepping.integrators import _sdirk_tableau

    gamma, A, b = _sdirk_tableau(3)
    c = b[0] / gamma + 2 * b[1] * abs(A[1, 0]) / gamma**2 + b[1] / gamma
    return 2 * c * stol * steps * norm / scale


def largest_norm(kept: list):
    """An observer that keeps the largest ‖U‖ (the full vector, Euclidean) at the outputs."""
    from cosserat_fem.timestepping.events import Observer

    class Largest(Observer):
        def output(self, loop, k, t) -> None:
            kept.append(float(np.linalg.norm(loop.model.U.x.array)))

    return Largest()


def _keeper(kept: dict):
    from cosserat_fem.timestepping.events import Observer

    class Keep(Observer):
        needs_full_state = False

        def ended(self, loop, failure) -> None:
            kept["quiet"] = getattr(loop._check, "quiet", None)
            kept["kappa"] = _condition(loop.solver)
            kept["rows"] = loop.solver._arrays["fit"].size
            kept["coordinates"] = loop.solver.reduced_coordinates

    return Keep()


def test_restart_in_reduced_coordinates(paper, tmp_path):
    """(c) 3 ms in reduced coordinates, checkpointed (the checkpoint holds full vectors: U,
    U_n and the predictor's rates lifted), continued to 6 ms (their coordinates read back
    by the W-projection, exact on the basis to round-off) against 6 ms at once: within
    :func:`restart_bound` of the largest |x, y, z| (the continued run forms a fresh J̃_r at
    its first solve where the straight run keeps its frozen one; 2 c stol ‖U‖ a step over
    the 100 steps after the restart, 2.6e-3 of the motion here; measured 9.9e-9)."""
    scene, sampled, _full = paper
    norms: list = []
    straight = _run(scene, sampled, True, observers=[largest_norm(norms)])
    half = tmp_path / "half"
    make = galerkin.solver_factory(sampled, True, True)
    first = run_scene(
        cf.load(PAPER, {"time.end": 0.003}), out_dir=half, solver_factory=make, record=True
    )
    assert first.time_reached == pytest.approx(0.003)
    again, checkpoint = cf.resume(half, {"time.end": 0.006})
    kept: dict = {}
    second = run_scene(
        again, restart=checkpoint, solver_factory=make, record=True, observers=[_keeper(kept)]
    )
    assert kept["coordinates"] is True
    joined = np.vstack([first.probes[:, 1:4], second.probes[:, 1:4]])
    scale = np.abs(_free_end(straight)).max()
    assert joined.shape == _free_end(straight).shape
    bound = restart_bound(scene.solver.stol, 100, max(norms), scale)
    assert np.abs(joined - _free_end(straight)).max() <= bound * scale


@pytest.mark.parametrize("integrator", ["bdf2", "generalized-alpha"])
def test_other_integrators_in_reduced_coordinates(paper, integrator):
    """(d) BDF2 (U_n, U_{n−1}) and generalized-α (U_n, and U̇_n as a rate) on the reduced
    coordinates, over 30 steps of the paper's scene with its SDIRK-trained basis: equal to
    their full-vector runs to the round-off bound of (a), 30 solves × n ε = 2e-12 (asserted
    1e-10; measured 7.0e-15 and 4.7e-15), the same Newton iterations (82 and 59); the
    solver says it kept the coordinates.
    Generalized-α's consistent U̇_0 is solved in full and read into its coordinates (a rate:
    V y, no reference). Adaptive steps (their error control reads U) keep the full-vector
    state and are that run: equal probes."""
    scene, sampled, _full = paper
    other = cf.load(PAPER, {"time.integrator": integrator, "time.end": 9e-4})
    kept: dict = {}
    coordinates = _run(other, sampled, True, observers=[_keeper(kept)])
    vectors = _run(other, sampled, False)
    assert kept["coordinates"] is True
    assert rb.relative_l2(_free_end(coordinates), _free_end(vectors)) <= 1e-10
    assert coordinates.summary["newton"]["iterations"] == vectors.summary["newton"]["iterations"]
    adaptive = cf.load(
        PAPER, {"time.integrator": integrator, "time.end": 3e-4, "time.adaptive": True}
    )
    asked = _run(adaptive, sampled, True, observers=[_keeper(kept)])
    assert kept["coordinates"] is False
    assert np.array_equal(asked.probes, _run(adaptive, sampled, False).probes)


def test_the_whip_in_3d_is_refused_at_the_chart_with_the_time():
    """(e) The whip (a sudden tip torque) in 3D, basis and ECSW trained on its first 0.4 ms:
    the run in reduced coordinates meets the chart's move (the bound (8.1) passes 0.9 rad,
    the exact θ rows are lifted and the move is due at t = 0.24 ms, as for the Galerkin run,
    tests/test_rom_indicator.py) and stops with one line naming the chart and the time."""
    whip = ROOT / "scenes" / "whip.toml"
    in_3d = {"discretisation.planar": "off", "output.xdmf": False}
    training = cf.load(whip, {**in_3d, "time.end": 4e-4})
    basis, _ = rb.train([training], tolerance=1e-10)
    sampled = hyper.ecsw([training], basis, 1e-2)
    kept: dict = {}
    with pytest.raises(SolverError) as refused:
        _run(cf.load(whip, in_3d), sampled, True, observers=[_keeper(kept)])
    assert kept["coordinates"] is True
    message = str(refused.value)
    assert "\n" not in message and "chart" in message and "at t = 0.00024 s" in message


def test_from_an_initial_state_on_the_basis(paper):
    """(f) A run that starts away from the reference (the state the full run reached at 6 ms,
    projected onto the basis: U_0 = U_ref + V y_0) over 30 steps: in reduced coordinates U_n
    starts at y_0 (not at the reference's 0) and the run equals the full-vector one to the
    round-off bound of (a), 60 solves × n ε = 4e-12, asserted 1e-10 (with U_n started at
    0 instead, as a first version did: 0.99); both leave y_0 (the
    probe's first output moves by more than 1e-6 of its size: the test sees a run that stood
    still or restarted from rest)."""
    scene, sampled, full = paper
    model = full.model
    u = model.U.x.array[: sampled.V.shape[0]]
    y0 = (u - sampled.reference) @ (sampled.weights[:, None] * sampled.V)
    start = model.layout.full_array(sampled.reference + sampled.V @ y0)
    short = cf.load(PAPER, {"time.end": 9e-4})
    vectors = _run(short, sampled, False, initial_state=start)
    coordinates = _run(short, sampled, True, initial_state=start)
    tip = _free_end(coordinates)
    assert np.abs(tip[1] - tip[0]).max() > 1e-6 * np.abs(tip[0]).max()
    assert rb.relative_l2(tip, _free_end(vectors)) <= 1e-10
