"""Rotations of any size in dynamics: the chart of the angles moves onto the rod when θ nears
the singularity (cosserat_fem/rod/charts.py, docs/decisions.md "Charts"), and nothing else notices.

The motion: the paper's cantilever whipped by a sudden tip torque of 2e5 N m about e1, Δt =
10 μs, 2 ms. The free end turns through θ = π/2 at ~0.4 ms and reaches 3.2 rad; in 3D the chart
moves three times. About e1 the motion stays in the y-z plane, where the solved block of Ma is
1 and no chart is needed (cosserat_fem/rod/checks.py): the planar solve is the reference of the
3D one. They differ only by the frame's interpolation between the nodes, which a move of the
chart changes (O(h^(k+1)) of the rotation field's derivatives, cubic elements here), so the
difference must converge under refinement, and fast: measured 2.3e-5 rad (8 elements) and
3.3e-7 rad (16), order 6.1. Required: order ≥ 5 and ≤ 1e-6 rad at 16 elements.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import ROOT, run_command
from test_restart import Crash, crash_at

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.io.checkpoint import load_checkpoint
from cosserat_fem.scene.build import load_scene, scene_from_dict
from cosserat_fem.scene.schema import read_toml

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
CLI = ["-m", "cosserat_fem.cli"]
WHIP_SCENE = ROOT / "scenes" / "whip.toml"  # stol = 1e-8, argued from below
WHIP = ["output.xdmf=false"]
IN_3D = "discretisation.planar='off'"


def whip(extra: list[str]):
    return load_scene(WHIP_SCENE, [*WHIP, *extra])


@pytest.fixture(scope="module")
def whip_runs():
    """{(elements, plane): (probe rows, summary)} of the whip, in the y-z plane and in 3D."""
    runs = {}
    for elements in (8, 16):
        for planar in ("auto", IN_3D):
            extra = [f"discretisation.elements={elements}"]
            extra += [] if planar == "auto" else [planar]
            result = run_scene(whip(extra), write_outputs=False, record=True)
            runs[elements, "3d" if planar == IN_3D else "y-z"] = (result.probes, result.summary)
    return runs


def test_the_whip_in_3d_passes_the_singularity_and_equals_the_plane(whip_runs):
    """Module docstring: the same motion in 3D (charted) and in y-z (no chart)."""
    gaps = {}
    for elements in (8, 16):
        rows_3d, summary_3d = whip_runs[elements, "3d"]
        rows_yz, summary_yz = whip_runs[elements, "y-z"]
        assert summary_3d["status"] == "completed" and summary_3d["chart_resets"] == 3
        assert summary_yz["chart_resets"] == 0
        assert np.abs(rows_yz[:, 4]).max() > 3.0  # θ(ℓ) passes π/2 and goes on to ~3.2
        # x, ψ, φ stay zero in 3D too (to round-off of the frame products).
        assert np.abs(rows_3d[:, [1, 5, 6]]).max() < 1e-12
        gaps[elements] = np.abs(rows_3d[:, 2:5] - rows_yz[:, 2:5]).max()
    order = math.log2(gaps[8] / gaps[16])
    assert order >= 5.0, gaps
    assert gaps[16] <= 1e-6, gaps


RESTART_CONFIGS = {
    "sdirk3-frozen": [],
    "bdf2-full": ["time.integrator=bdf2", "solver.jacobian=full"],
    "generalized-alpha-frozen": ["time.integrator=generalized-alpha"],
    "sdirk3-adaptive": ["time.adaptive=true", "time.rtol=1e-5"],
}


@pytest.mark.parametrize("name", list(RESTART_CONFIGS))
def test_restart_across_moves_of_the_chart_gives_the_uninterrupted_run(tmp_path, name):
    """The chart (its quaternions, whether the residual carries it, whether it moved) is part
    of the checkpoint, and a move maps the integrator's history (tests/test_restart.py says
    why equality is the test). The chart moves at steps 24, 90 and 169 (fixed steps); the
    run crashes at step 180, after the checkpoint at step 100, and the restart must give the
    uninterrupted run's probes byte for byte, and the same counters; probes.csv holds the
    quaternion too, whose sign a restart continues from the last row as it does the angles."""
    extra = ["output.checkpoint_interval=1e-3", "output.probe_fields=['quaternion']"]
    scene = whip([IN_3D, *RESTART_CONFIGS[name], *extra])
    run_scene(scene, tmp_path / "whole")
    out = tmp_path / "crashed"
    with pytest.raises(Crash):
        run_scene(scene, out, observers=(crash_at(180),))
    checkpoint = load_checkpoint(out)
    assert 1e-3 * (1 - 1e-9) <= checkpoint.time < 1.8e-3
    assert checkpoint.parts["chart"]["moved"] == 1.0
    assert checkpoint.parts["loop"]["chart_resets"] == 2
    result = run_scene(scene_from_dict(checkpoint.meta["scene"]), restart=checkpoint)
    whole = json.loads((tmp_path / "whole/summary.json").read_text())
    assert whole["chart_resets"] == result.summary["chart_resets"] == 3
    assert (out / "probes.csv").read_bytes() == (tmp_path / "whole/probes.csv").read_bytes()
    for key in ("solves", "iterations", "jacobian_assemblies"):
        assert result.summary["newton"][key] == whole["newton"][key], key


@pytest.mark.long
@pytest.mark.mpi
def test_the_whip_under_mpi_equals_the_serial_run(tmp_path):
    """mpirun -n 2 against the serial run: the chart moves at the same steps (the decision is
    one reduction of the largest |θ|) and the free end agrees to the Newton tolerance (MUMPS
    and PETSc's LU round differently; the iterates stop within stol = 1e-8 of ‖U‖ of the
    solution, which the steps carry: allowed 1e-7 of the motion, ~1 m and ~3 rad). The first
    1 ms, 100 steps and two moves of the chart: on two ranks each step is many MPI messages,
    and the whole 2 ms took ~400 s at load 9 on two cores."""
    sets = [a for s in [*WHIP, IN_3D, "time.end=0.001"] for a in ("--set", s)]
    outs = {}
    for ranks in (1, 2):
        out = tmp_path / f"n{ranks}"
        proc = run_command([*CLI, "run", str(WHIP_SCENE), "--out", str(out), *sets], ranks=ranks)
        assert proc.returncode == 0, proc.stderr
        outs[ranks] = (
            np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1),
            json.loads((out / "summary.json").read_text()),
        )
    assert outs[1][1]["chart_resets"] == outs[2][1]["chart_resets"] == 2
    assert np.abs(outs[1][0] - outs[2][0]).max() <= 1e-7


def test_adaptive_steps_through_the_singularity():
    """Adaptive steps (rtol = 1e-6) through three moves of the chart. A smooth torque,
    4e5 sin²(πt/4 ms) N m (the sudden one excites axial and shear waves that 10 μs steps do not
    resolve: 0.07 rad against 2.5 μs): θ(ℓ) reaches 3.5 rad. The error estimate compares the
    new state with the history mapped into the new chart, so the moves cost the controller
    nothing: rejected steps within 1.5x those of the same adaptive run in the y-z plane
    (measured 34 and 28), and the free end within 1e-4 of fixed 2.5 μs steps (measured
    2.2e-5; their own error is 1e-6, from 7e-5 at 10 μs and order 3; the y-z adaptive run is
    2.9e-5 from the 3D one, so the chart adds nothing beyond the controller's error)."""
    smooth = ['loads.end.torque=["4e5*sin(pi*t/0.004)**2",0,0]']
    adaptive = ["time.adaptive=true", "time.rtol=1e-6"]
    results = {
        name: run_scene(whip([*smooth, *extra]), write_outputs=False, record=True)
        for name, extra in {
            "adaptive": [IN_3D, *adaptive],
            "adaptive y-z": adaptive,
            "fixed 2.5 us": [IN_3D, "time.step=2.5e-6"],
        }.items()
    }
    summary = results["adaptive"].summary
    assert summary["status"] == "completed" and summary["chart_resets"] == 3
    assert summary["rejected_steps"] <= 1.5 * results["adaptive y-z"].summary["rejected_steps"]
    fine = results["fixed 2.5 us"].probes[::4]
    assert np.abs(results["adaptive"].probes[:, 4]).max() > 3.0
    assert np.abs(results["adaptive"].probes[:, 2:5] - fine[:, 2:5]).max() <= 1e-4


def test_the_same_motion_in_the_two_planes():
    """A circular section (diameter 0.05 m) and a sudden end moment of 1.2e5 N m, about e2 in
    one run (the x-z plane, carried by ψ) and about e1 in the other (y-z, θ): the tip turns to
    3.06 rad in 2 ms. The section's symmetry makes the motions mirror images, x = −y and
    ψ = θ, z alike; the two planes solve the same equations with their components in
    another order, which rounds the same way here: equal to the bit (measured 0), allowed
    1e-12 of the motion. With the rod solved in 3D about e1 the chart moves, and the run
    agrees with the planes to the frame's interpolation error (≤ 1e-4 rad at 8 cubic
    elements: the whip's 2.3e-5, test above)."""
    raw = read_toml(SCENE)
    raw["rod"]["section"] = {"shape": "circle", "diameter": 0.05, "shear_coefficient": 0.9}
    common = ["time.step=1e-5", "time.end=0.002", "loads.force_density=[0,0,0]"]
    common += ["output.xdmf=false"]
    rows = {}
    for name, extra in {
        "x-z": ["loads.end.torque=[0,1.2e5,0]"],
        "y-z": ["loads.end.torque=[1.2e5,0,0]"],
        "3d": ["loads.end.torque=[1.2e5,0,0]", IN_3D],
    }.items():
        scene = scene_from_dict(raw, overrides=[*common, *extra])
        assert scene.plane() == (None if name == "3d" else name)
        rows[name] = run_scene(scene, write_outputs=False, record=True).probes
    xz, yz, full = rows["x-z"], rows["y-z"], rows["3d"]
    assert 3.0 < np.abs(xz[:, 5]).max() < 3.1
    mirrored = np.stack([-yz[:, 2], yz[:, 3], yz[:, 4]], axis=1)
    assert np.abs(xz[:, [1, 3, 5]] - mirrored).max() <= 1e-12 * 3.06
    assert np.abs(full[:, 2:5] - yz[:, 2:5]).max() <= 1e-4


def test_the_chart_stays_at_a_fork():
    """A pinned end is a fork: it holds x, y, z and φ, and φ = 0 keeps d1 ⊥ e2 only in the
    paper's chart (D(θ, ψ, 0) has d1 = (cos ψ, 0, −sin ψ)); in a moved chart it would hold
    d1 ⊥ a2 instead, another joint. So a move leaves the chart, and the state, of the pinned
    ends' nodes as they were, bit for bit, and moves every other node; and a fork's own θ
    does not call for a move (it is the joint's gimbal lock, not the chart's)."""
    from cosserat_fem.rod.checks import cos_theta
    from cosserat_fem.rod.model import build_model

    scene = load_scene(
        ROOT / "scenes" / "simply_supported_tube.toml", ["discretisation.planar='off'"]
    )
    model = build_model(scene)
    model.use_chart(active=False)
    assert model.fork_nodes.size == 2
    rng = np.random.default_rng(5)
    state = model.U.x.array.reshape(-1, 12)
    state[:] = 0.3 * rng.standard_normal(state.shape)
    state[model.fork_nodes, 3] = 1.2  # |cos θ| = 0.36 at the forks only
    assert model.chart_margin(cos_theta(model, model.U.x.array)) == pytest.approx(
        np.abs(np.cos(state[:, 3])).min(
            where=~np.isin(np.arange(len(state)), model.fork_nodes), initial=1.0
        )
    )
    before = state.copy()
    model.reset_chart()
    Q = model.chart.x.array.reshape(-1, 4)
    others = np.setdiff1d(np.arange(len(state)), model.fork_nodes)
    assert np.array_equal(state[model.fork_nodes], before[model.fork_nodes])
    assert np.array_equal(Q[model.fork_nodes], np.tile([1.0, 0, 0, 0], (2, 1)))
    assert np.abs(state[others, 3:6]).max() < 1e-14 and np.abs(Q[others, 1:]).max() > 0.1


def test_outputs_need_no_decoding_of_charts(tmp_path):
    """Through three moves of the chart (the whip in 3D, XDMF every 0.1 ms): the XDMF file's
    ``director_d1..3`` (output.fields "directors") are the rod's directors in the fixed
    basis, orthonormal; its ``angles`` give the same directors through (18) (the triple with
    |θ| ≤ π/2 once the chart has moved), and so do probes.csv's angles, continued from row to
    row; and so do probes.csv's quaternion and directors (output.probe_fields), the quaternion
    of unit length and continuous from row to row: between two rows it changes by
    2 sin(α/4) ≤ α/2, α the angle of the rotation between them, which is at most the sum of
    the changes of the three angles (18) (a turn of the sign would jump by ~2); at the free
    end all agree to round-off (1e-12)."""
    from xdmf_files import read_arrays

    from cosserat_fem.io.probes import PROBE_FIELD_COLUMNS
    from cosserat_fem.output.results import open_run
    from cosserat_fem.rod.charts import euler_matrix, quaternion_frame

    out = tmp_path / "whip"
    fields = "output.fields=['displacement', 'angles', 'directors']"
    probe_fields = "output.probe_fields=['directors', 'quaternion']"  # either order
    scene = whip([IN_3D, "output.xdmf=true", "output.xdmf_interval=1e-4", fields, probe_fields])
    result = run_scene(scene, out, record=True)
    assert result.summary["chart_resets"] == 3
    _, times, arrays = read_arrays(out / "solution.xdmf")
    assert len(times) == 21
    table = open_run(out, "test")
    q_columns, d_columns = PROBE_FIELD_COLUMNS["quaternion"], PROBE_FIELD_COLUMNS["directors"]
    assert table.probe_columns[7:] == (*q_columns, *d_columns)
    assert np.array_equal(table.probes[:, 1:], result.probes[:, 1:])  # %.16e: exact
    q = table.probes[:, 7:11]
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() < 1e-14
    turn = np.abs(np.diff(table.probes[:, 4:7], axis=0)).sum(axis=1)
    assert (np.linalg.norm(np.diff(q, axis=0), axis=1) <= 0.5 * turn + 1e-12).all()
    assert q[:, 0].min() < -0.02  # the end turned past π: a sign of q0 >= 0 would jump
    probes = table.probes[::10]
    D = np.stack([arrays[f"director_d{i}"][:, -1] for i in (1, 2, 3)], axis=1)  # (T, 3, 3)
    assert np.abs(D @ np.swapaxes(D, 1, 2) - np.eye(3)).max() < 1e-12
    assert np.abs(euler_matrix(*arrays["angles"][:, -1].T) - D).max() < 1e-12
    assert np.abs(euler_matrix(*probes[:, 4:7].T) - D).max() < 1e-12
    assert np.abs(probes[:, 11:20].reshape(-1, 3, 3) - D).max() < 1e-12
    assert np.abs(quaternion_frame(probes[:, 7:11]) - D).max() < 1e-12
    assert probes[:, 4].max() > 3.0  # continued past π/2; the XDMF triple is not
    assert np.abs(arrays["angles"][:, -1, 0]).max() <= math.pi / 2


def test_a_move_keeps_the_frame_continuous_past_half_a_turn():
    """A node may turn by more than π in its chart between moves (the move's test watches θ,
    not ψ or φ), and then the quaternion signed like its old one is nearly opposite to its
    neighbour's, and the frame interpolated between them passes through Q = 0 (this once
    made the flying spaghetti's energy jump from 750 J to 14000 J). Here ψ grows along the
    rod from 0 to 4 rad (past π, in the paper's chart), θ = 0.95 calls for a move: the new
    quaternions of neighbouring nodes must have positive products, and the strain energy of
    the state must be the same after the move as before, to the frame's interpolation error
    (measured ~1e-9 of it; a frame turned over between two nodes changes it by O(1))."""
    from rod_energy import EnergyMonitor

    from cosserat_fem.rod.model import build_model

    scene = load_scene(SCENE, [IN_3D, "loads.force_density=[0,0,0]"])
    model = build_model(scene)
    model.use_chart(active=False)
    sigma = model.V.tabulate_dof_coordinates()[:, 0]
    state = model.U.x.array.reshape(-1, 12)
    state[:, 4] = 4.0 * sigma**2  # ψ: from 0 to 4 rad, smooth
    state[:, 3] = 0.95 * sigma  # θ
    monitor = EnergyMonitor(model)
    before = monitor.energies()[1]
    model.reset_chart()
    after = monitor.energies()[1]
    Q = model.chart.x.array.reshape(-1, 4)[np.argsort(sigma)]
    assert (np.einsum("ij,ij->i", Q[1:], Q[:-1]) > 0.0).all()
    assert abs(after - before) <= 1e-6 * before, (before, after)


def test_a_restart_continues_the_sign_of_the_probe_quaternion():
    """q and −q are the same rotation: probes.csv's quaternion takes the sign nearest the
    previous row's, and a restart seeds that from the last row (PointProbe.seed), as the
    uninterrupted run would continue it. A rod turned by θ = 3 rad about e1 at its end: the
    quaternion is ±(cos 1.5, −sin 1.5, 0, 0); a fresh probe gives q0 ≥ 0, one seeded with the
    other sign (and its angles) keeps that sign, and both give the rod's directors (18)."""
    from cosserat_fem.output.fields import PointProbe
    from cosserat_fem.rod.charts import euler_matrix, quaternion_frame
    from cosserat_fem.rod.model import build_model

    model = build_model(load_scene(SCENE, [IN_3D]))
    sigma = model.V.tabulate_dof_coordinates()[:, 0]
    model.U.x.array.reshape(-1, 12)[:, 3] = 3.0 * sigma
    fresh = PointProbe(model, 1.0, fields=("quaternion",)).values()
    assert fresh[6] == pytest.approx(math.cos(1.5), abs=1e-15)
    seeded = PointProbe(model, 1.0, fields=("quaternion",))
    seeded.seed(np.concatenate([[0.0], fresh[:6], -fresh[6:10]]))
    again = seeded.values()
    assert np.array_equal(again[6:10], -fresh[6:10])
    D = euler_matrix(3.0, 0.0, 0.0)
    assert np.abs(quaternion_frame(again[6:10]) - D).max() < 1e-15
