"""Every demo runs and its printed quantities are checked against values derived
independently: the paper's demo over its whole 0.06 s serially, and its first 0.006 s under
``mpirun -n 2`` against the serial run (scikit-fem's test_examples style).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import HUNG_AFTER, ROOT, parse_qoi, run_command

from cosserat_fem.reference.backbone import Duffing, clamped_modal_force
from cosserat_fem.reference.curved import BATHE_BOLOURCHI_SHOOTING

DEMO = str(ROOT / "demos" / "cao_tucker_2008.py")
FULL = 0.06  # s: the scene's whole run, 2000 steps (serial: ~1.3 s of solving)
END = 0.006  # s: the run under mpirun -n 2, 200 steps, compared with the first 200 serial ones


@pytest.fixture(scope="module")
def demo_runs(tmp_path_factory):
    """The demo as it is (0.06 s) on one rank, and its first 0.006 s on two (a step on two
    ranks is many MPI messages: 400 steps took ~400 s at load 9 on two cores)."""
    runs = {}
    for ranks, end in ((1, None), (2, END)):
        out = tmp_path_factory.mktemp(f"demo{ranks}")
        args = [DEMO, "--out", str(out), "--frames", "40"]
        args += [] if end is None else ["--end", str(end)]
        proc = run_command(args, ranks)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        runs[ranks] = (parse_qoi(proc.stdout), out)
    return runs


def test_demo_against_linear_timoshenko(demo_runs):
    """The whole default run (0 ≤ t ≤ 0.06 s, 8 cubic elements, SDIRK3 at Δt = 30 μs).

    x(ℓ,t), y(ℓ,t) against the closed-form linear Timoshenko response. Expected difference:
    the default discretisation's error against a fine run, 3.2e-4 (x) and 5.6e-4 (y)
    (docs/convergence.md, "The default settings": mostly the time step's phase error, which
    grows with the horizon), plus the geometric nonlinearity the linear reference leaves out,
    1.2e-4 and 1.6e-4 over 0.06 s (docs/convergence.md, "References"): at most 4.4e-4 and
    7.2e-4. Measured 2.1e-4 (x) and 4.3e-4 (y); required within 1e-3 (relative L2), and the
    maxima within 1e-3 (measured 5.6e-6 and 2.4e-4).
    """
    qoi, out = demo_runs[1]
    assert qoi["t_end_s"] == pytest.approx(FULL)
    assert qoi["rel_l2_error_x"] < 1e-3
    assert qoi["rel_l2_error_y"] < 1e-3
    assert qoi["max_abs_x_m"] == pytest.approx(qoi["timoshenko_max_abs_x_m"], rel=1e-3)
    assert qoi["max_abs_y_m"] == pytest.approx(qoi["timoshenko_max_abs_y_m"], rel=1e-3)
    # z(ℓ,t) and φ(ℓ,t) are purely nonlinear (second order in the deflection): they must follow
    # second-order perturbation theory (reference/second_order.py). Expected difference over
    # 0.06 s: the default discretisation's error against a fine run, 9.6e-4 (z) and 2.2e-3 (φ)
    # (docs/convergence.md: the 30 μs step's, through the axial and torsional modes), plus the
    # third-order terms the theory leaves out (8e-5 and 1.5e-4 over 0.02 s at tiny steps,
    # docs/convergence.md; growing with the horizon like the phase drift of x and y, to about
    # 2.5e-4 and 4.5e-4): at most ~1.2e-3 and ~2.7e-3. Measured 7.5e-4 (z) and 1.7e-3 (φ);
    # required within 1.5e-3 and 3e-3, the extremes within 1e-3 and 1.5e-3 (measured 1.4e-4,
    # 2.6e-4).
    assert qoi["rel_l2_error_z"] < 1.5e-3
    assert qoi["rel_l2_error_phi"] < 3e-3
    assert qoi["min_z_m"] == pytest.approx(qoi["second_order_min_z_m"], rel=1e-3)
    assert qoi["min_phi_rad"] == pytest.approx(qoi["second_order_min_phi_rad"], rel=1.5e-3)
    assert qoi["max_z_m"] < 1e-12  # the free end only ever moves inwards (foreshortening)
    for name in (
        "fig4_free_end.png",
        "fig5_x_surface.png",
        "fig6_y_surface.png",
        "solution.xdmf",
        "solution.frames/mesh.h5",
        "solution.frames/000000.h5",
        "probes.csv",
        "summary.json",
    ):
        assert (out / name).stat().st_size > 0, name


#: Fig. 4's panels by their y label: (probes.csv column, the reference's label, the relative
#: L2 bound of test_demo_against_linear_timoshenko and its docstring; None: no reference).
FIG4 = {
    "x(ℓ,t) [m]": (1, "linear Timoshenko", 1e-3),
    "y(ℓ,t) [m]": (2, "linear Timoshenko", 1e-3),
    "z(ℓ,t) [m]": (3, "second-order theory", 1.5e-3),
    "θ(ℓ,t) [rad]": (4, None, None),
    "ψ(ℓ,t) [rad]": (5, None, None),
    "φ(ℓ,t) [rad]": (6, "second-order theory", 3e-3),
}


def rel_l2(u: np.ndarray, ref: np.ndarray) -> float:
    return float(np.sqrt(np.mean((u - ref) ** 2) / np.mean(ref**2)))


def test_the_demos_figures_draw_the_run_and_the_analysis(demo_runs):
    """What the paper demo's figures draw, read back from them (fig4_free_end.npz: the lines
    of the figure object; fig5/fig6_*_surface.npz: the surfaces' data), not their pixels.

    * Fig. 4: each panel (found by its label) draws its probes.csv column against t exactly,
      and x, y, z, φ also their reference: the closed-form linear Timoshenko response, the
      second-order theory (cosserat_fem/reference), equal to a fresh evaluation to 1e-12 of
      its largest value, and within the run's bound of it (test_demo_against_linear_timoshenko).
    * Figs. 5 and 6: x(s, t) and y(s, t) at the 41 stations σ = j/40 and the sampled times
      (t = 0, then every 50 steps for --frames 40), against the closed-form linear Timoshenko
      field (the same modal superposition at every s) within 1e-3 relative L2 (the free end's
      bound, whose argument, the discretisation's phase error and the neglected nonlinearity,
      holds for every station; measured 2.1e-4 and 4.4e-4); the clamp's row 0 (to 1e-12 of the
      largest value: the cell's Lagrange basis at a node, tests/test_api.py) and the free end's
      row the probe's values at those times, to the same 1e-12."""
    from cosserat_fem.reference.rod_planes import sine_load_response, sine_load_tip_response
    from cosserat_fem.reference.second_order import RodData, second_order_tip_response
    from cosserat_fem.scene.build import load_scene

    _, out = demo_runs[1]
    scene = load_scene(ROOT / "scenes" / "cao_tucker_2008.toml")
    q0, omega = 2e3, 8.0 * scene.omega0
    probes = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    t = probes[:, 0]
    x_ref, y_ref = sine_load_tip_response(scene, t, q0=q0, omega=omega)
    z_ref, phi_ref = second_order_tip_response(
        RodData.from_scene(scene), q0, omega, t, torsion_inertia=scene.model.torsion_inertia
    )
    references = {1: x_ref, 2: y_ref, 3: z_ref, 6: phi_ref}
    fig4 = np.load(out / "fig4_free_end.npz")
    labels = {str(fig4[k]): k.split("/")[0] for k in fig4.files if k.endswith("/ylabel")}
    assert sorted(labels) == sorted(FIG4)
    for label, (column, reference, bound) in FIG4.items():
        axes = labels[label]
        np.testing.assert_array_equal(fig4[f"{axes}/line0"], [t, probes[:, column]])
        lines = [k for k in fig4.files if k.startswith(f"{axes}/line") and k.count("/") == 1]
        assert len(lines) == (1 if reference is None else 2), label
        if reference is not None:
            assert str(fig4[f"{axes}/line1/label"]) == reference
            drawn = fig4[f"{axes}/line1"]
            expected = references[column]
            np.testing.assert_array_equal(drawn[0], t)
            assert np.abs(drawn[1] - expected).max() <= 1e-12 * np.abs(expected).max(), label
            assert rel_l2(probes[:, column], drawn[1]) < bound, label
    every = 2000 // 40
    for name, column, plane in (("fig5_x_surface", 1, 0), ("fig6_y_surface", 2, 1)):
        surface = np.load(out / f"{name}.npz")
        s, times, value = surface["s"], surface["t"], surface["value"]
        np.testing.assert_allclose(s, np.linspace(0.0, scene.rod.length, 41), rtol=0, atol=1e-15)
        np.testing.assert_allclose(times, t[::every], rtol=0, atol=1e-15)  # t: 11 digits
        assert value.shape == (times.size, s.size)
        scale = np.abs(value).max()
        assert np.abs(value[:, 0]).max() <= 1e-12 * scale
        assert np.abs(value[:, -1] - probes[::every, column]).max() <= 1e-12 * scale
        field = sine_load_response(scene, times, q0=q0, omega=omega, s=s)[plane]
        assert rel_l2(value, field) < 1e-3, name


def test_demo_serial_equals_mpi(demo_runs):
    """Identical free-end histories on 1 and 2 ranks (LU and MUMPS differ only by round-off):
    the two-rank run's 0.006 s against the first 200 steps of the serial one (a run's steps do
    not depend on its end time: a serial run to 0.006 s gives those rows bit for bit)."""
    (_, out1), (q2, out2) = demo_runs[1], demo_runs[2]
    p2 = np.loadtxt(out2 / "probes.csv", delimiter=",", skiprows=1)
    p1 = np.loadtxt(out1 / "probes.csv", delimiter=",", skiprows=1)[: len(p2)]
    assert q2["t_end_s"] == pytest.approx(END) and len(p2) == 201
    np.testing.assert_array_equal(p1[:, 0], p2[:, 0])
    for j in range(1, 7):
        scale = np.abs(p1[:, j]).max()
        assert np.abs(p1[:, j] - p2[:, j]).max() <= 1e-10 * scale, j
    extremes = {
        "max_abs_x_m": np.abs(p1[:, 1]).max(),
        "max_abs_y_m": np.abs(p1[:, 2]).max(),
        "min_z_m": p1[:, 3].min(),
        "min_phi_rad": p1[:, 6].min(),
        "max_phi_rad": p1[:, 6].max(),
    }
    for name, value in extremes.items():
        assert q2[name] == pytest.approx(value, rel=1e-10), name


BEND_DEMO = str(ROOT / "demos" / "bathe_bolourchi_bend.py")


@pytest.mark.long
def test_bend_demo_serial_and_mpi_against_the_shooting_solution(tmp_path):
    """In the long set (7 s; make test keeps the paper's demo serial and under mpirun, and
    tests/test_curved.py the bend's tip against the shooting solution).
    demos/bathe_bolourchi_bend.py on one and two ranks: the tip displacement [in] at 600 lbf
    within 2e-5 in of the shooting solution (the scene's discretisation error, as
    tests/test_curved.py argues), the two runs equal to 1e-9 of it (PETSc's LU against
    MUMPS's, round-off over 11 nonlinear load steps; measured: equal to the 13 printed
    digits), and the picture written, drawing (its lines read back, bathe_bolourchi_bend.npz)
    in both views a curve at rest and one a load step, each from the clamp at the origin:
    the first the arc at rest, R = 100 in about (R, 0, 0) in the e1-e3 plane (to 1e-9 in),
    the last ending at the arc's end moved by the printed tip displacement (to 1e-9 in, the
    printed digits)."""
    names = ("tip_dn_in", "tip_dz_in", "tip_dt_in")
    shooting = dict(zip(names, BATHE_BOLOURCHI_SHOOTING[600], strict=True))
    runs = []
    for ranks in (1, 2):
        out = tmp_path / f"bend{ranks}"
        proc = run_command([BEND_DEMO, "--out", str(out)], ranks)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        runs.append(parse_qoi(proc.stdout))
        assert (out / "bathe_bolourchi_bend.png").stat().st_size > 10_000
        bend_figure_draws_the_path(np.load(out / "bathe_bolourchi_bend.npz"), runs[-1])
    for name, value in shooting.items():
        assert runs[0][name] == pytest.approx(value, abs=2e-5), name
        assert runs[1][name] == pytest.approx(runs[0][name], rel=1e-9), name
    assert runs[1]["load_steps"] == runs[0]["load_steps"]


def bend_figure_draws_the_path(figure, qoi: dict[str, float]) -> None:
    """The bend demo's figure (test_bend_demo_serial_and_mpi_against_the_shooting_solution):
    axes 0 seen from e2 (e3, e1), axes 1 from e3 (e1, e2), in inches."""
    radius = 100.0  # in
    steps = int(qoi["load_steps"])
    end = radius * np.array([1 - np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4)])  # the arc's end
    tip = end + [qoi["tip_dn_in"], qoi["tip_dz_in"], qoi["tip_dt_in"]]
    views = ((0, (2, 0)), (1, (0, 1)))  # (axes, the components drawn as x and y)
    for axes, (horizontal, vertical) in views:
        lines = [figure[f"axes{axes}/line{j}"] for j in range(steps + 1)]
        assert f"axes{axes}/line{steps + 1}" not in figure.files
        for line in lines:
            assert line.shape == (2, 41) and np.abs(line[:, 0]).max() <= 1e-12
        rest = np.zeros((3, 41))
        rest[horizontal], rest[vertical] = lines[0]
        if axes == 0:  # the arc: (x − R)² + z² = R²
            assert np.abs(np.hypot(rest[0] - radius, rest[2]) - radius).max() <= 1e-9
        else:
            assert np.abs(rest[1]).max() <= 1e-12  # in its plane
        last = lines[-1][:, -1]
        np.testing.assert_allclose(last, [tip[horizontal], tip[vertical]], rtol=0, atol=1e-9)


FREQUENCY_RESPONSE = str(ROOT / "demos" / "frequency_response.py")
#: The sweep's frequencies in the long tests: from 1.04, below the lower fold (single-valued:
#: both chains meet), to 1.12, above the upper one, in the sweep file's steps of 0.01, so that
#: the upward chain jumps down (at 1.11) and the downward one up (at 1.04) as in the full sweep.
BAND = [f"{1.04 + 0.01 * k:.2f}" for k in range(9)]
#: The QOI lines of the branch of periodic orbits (the others are the sweep's).
BRANCH_KEYS = ("branch_", "fold_", "unstable_")


#: The branch the runs on one rank and on two compare: from the lower branch at r = 1.06 (the
#: orbit shot from rest) down through the lower fold and back up the middle branch to 1.06
#: (7 steps, 71 monodromies: 55 s serially, 5.5 min on two ranks at load 3 and 13 min at
#: load 6, where the whole branch's 230 had not ended after 17 min).
SHORT = ["1.06", "1.03"]


@pytest.fixture(scope="module")
def response_runs(tmp_path_factory):
    """demos/frequency_response.py: (QOI, folder) of three runs. "serial": the sweep over
    :data:`BAND` (two chains of nine) and the branch of periodic orbits over its default
    0.98 ... 1.14 (about 1 min for the sweep and 70 s for the branch, 42 steps and 230
    monodromies, on an idle core); "mpirun": the same sweep (a chain a rank) and the
    :data:`SHORT` branch on two ranks (the shooting shared in space); "short": one member a
    chain and the :data:`SHORT` branch, serially. The hang limit is twice the usual: on two
    ranks a shooting period is many MPI messages, and a busy machine makes each wait long
    (the SHORT branch on two ranks: 13 min at load 6 on two cores)."""
    runs = {}
    for name, ranks, values, branch in (
        ("serial", 1, BAND, []),
        ("mpirun", 2, BAND, ["--branch", *SHORT]),
        ("short", 1, ["1.06"], ["--branch", *SHORT]),
    ):
        out = tmp_path_factory.mktemp(name)
        args = [FREQUENCY_RESPONSE, "--values", *values, *branch, "--out", str(out)]
        proc = run_command(args, ranks, timeout=2 * HUNG_AFTER)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        runs[name] = (parse_qoi(proc.stdout), out)
    return runs


@pytest.mark.long
def test_the_frequency_response_demo_jumps_where_the_harmonic_balance_says(response_runs):
    """The sweep of demos/frequency_response.py over r = 1.04 ... 1.12 (:data:`BAND`), on one
    rank and on two (a chain each): the same QOI lines of the sweep to the last digit (each
    chain runs serially on its rank), and the amplitudes of the harmonic balance of the
    one-mode Duffing model (cosserat_fem/reference/backbone.py).

    At r = 1.04 the response is single-valued and both chains agree; from 1.05 to 1.10 the
    upward chain stays on the upper branch and the downward one on the lower: two states of
    the same rod under the same load; at 1.11 and 1.12 both are on the lower. Tolerances from
    the full sweep (docs/verification.md, section 7): the upper branch measured 1.3-1.6 %
    above the harmonic balance here (the 40 mm section lowers the hardening coefficient by
    2 %, tests/test_backbone.py, which raises a ∝ 1/√α by 1 %; the next order in a² adds up
    to ~1.4 %): within 3 %; the lower branch 0.2-0.9 % below (most at 1.05, where it begins
    and is steepest): within 2 %. Where both chains hold the one state (1.04, 1.11, 1.12) they
    agree within 4e-4: each member stops with at most 1.6e-4 of its transient left (the sweep
    file's tolerance 1e-5 / (1 − exp(−2πζ))), from different sides (measured 1.5e-6, 2.5e-5
    at 1.11, where the upward chain has just jumped, and 3.9e-6).

    The figure (its lines read back, harmonic_balance.npz) draws those: the two chains'
    amplitudes [mm] at their r, and the harmonic balance's lowest and highest roots (the QOI
    lines' values, to their 12 printed digits) at those r on its curves."""
    qoi = {}
    for ranks, name in ((1, "serial"), (2, "mpirun")):
        values, out = response_runs[name]
        qoi[ranks] = {k: v for k, v in values.items() if not k.startswith(BRANCH_KEYS)}
        assert (out / "harmonic_balance.png").is_file()
        response_figure_draws_the_sweep(np.load(out / "harmonic_balance.npz"), qoi[ranks], BAND)
    # plot of the demo's folder draws its response.png beside the demo's figure, which it
    # overwrote when both were response.png (issue 25 E23)
    figure = (out / "harmonic_balance.png").read_bytes()
    proc = run_command(["-m", "cosserat_fem.cli", "plot", str(out)])
    assert proc.returncode == 0, proc.stderr
    assert (out / "harmonic_balance.png").read_bytes() == figure
    assert (out / "response.png").is_file()
    assert qoi[1] == qoi[2] and len(qoi[1]) == 6 * len(BAND)
    q = qoi[1]
    for r in ("1p04", "1p11", "1p12"):
        assert q[f"amp_up_{r}_m"] == pytest.approx(q[f"amp_down_{r}_m"], rel=4e-4), r
    assert q["amp_up_1p04_m"] == pytest.approx(q["duffing_high_up_1p04_m"], rel=0.03)
    for r in ("1p11", "1p12"):
        assert q[f"amp_up_{r}_m"] == pytest.approx(q[f"duffing_low_up_{r}_m"], rel=0.02)
    for r in ("1p05", "1p06", "1p07", "1p08", "1p09", "1p10"):
        up, down = q[f"amp_up_{r}_m"], q[f"amp_down_{r}_m"]
        assert up == pytest.approx(q[f"duffing_high_up_{r}_m"], rel=0.03), r
        assert down == pytest.approx(q[f"duffing_low_down_{r}_m"], rel=0.02), r
        assert up > 2.5 * down


@pytest.mark.long
def test_the_frequency_response_demo_folds_where_the_sweeps_jump(response_runs):
    """The demo's branch of periodic orbits (shooting, N = 100 SDIRK3 steps a period, r from
    0.98 to 1.14), serially, against the harmonic balance and against its own sweep.

    Asserted, with tests/test_periodic.py's reasoning for the whole S-curve (the same branch):
    - two folds, none rejected; a multiplier at +1 at each: the real multiplier nearest 1
      within 1e-4 of it (the fold located to 1e-6 in arclength, μ moving at |dμ/ds| ≲ 20:
      |μ − 1| ≲ 2e-5, and 5 times that for μ(s)'s curvature; measured 2e-6 and 2e-10), and it
      is the largest: the largest |μ| within 1e-4 of 1 too (the other multipliers, the
      damped modes', ≈ exp(−2πζ/r) = 0.94);
    - the folds against the harmonic balance's (test_periodic.harmonic_balance_folds, r =
      1.04377 and 1.11419): the fold lies at r² − 1 = ¾ α a²/ω² on the backbone, so the
      one-mode reduction's 3 % in amplitude is 6 % in r² − 1: within 0.06 (r_hb² − 1) in
      r² (measured: the lower fold 1.04328, −1.1 %; the upper 1.11005, −3.8 %); their
      amplitudes within 3 % (measured +0.9 %, 9.78 mm, and −0.04 %, 26.40 mm);
    - the sweep's jumps (the demo's own, :data:`BAND`): the upward chain's last member on the
      upper branch lies below the upper fold and its first after the jump at most one sweep
      step (0.01) before it; the downward chain's likewise at the lower fold (a sweep can
      leave a branch only where it ends or before: its basin shrinks to nothing at the fold;
      measured: the upper fold 1.11005 between the jump's members 1.10 and 1.11, the lower
      1.04328 between 1.05 and 1.04);
    - the middle branch: its orbits lie between the folds in r and in amplitude, each unstable
      by a real multiplier > 1 (the largest |μ| measured 1.017-1.137)."""
    from test_periodic import F_DEMO, RHO_A, W1, clamped, harmonic_balance_folds

    q, out = response_runs["serial"]
    assert q["branch_folds"] == 2 and q["branch_rejected"] == 0
    assert q["branch_steps"] >= 10 and q["branch_monodromies"] >= q["branch_steps"]
    for name in ("upper", "lower"):
        assert abs(q[f"fold_{name}_mu_nearest_one"] - 1.0) <= 1e-4, name
        assert abs(q[f"fold_{name}_mu_abs_max"] - 1.0) <= 1e-4, name
    duffing = Duffing.of_clamped_scene(clamped(F_DEMO, 1.0), omega=W1)
    s = np.linspace(0.0, 1.0, 20001)
    f = clamped_modal_force(F_DEMO * np.sin(np.pi * s), s, 1.0, RHO_A)
    (hb_low, a_low), (hb_up, a_up) = harmonic_balance_folds(f, duffing)
    for name, r_hb, a_hb in (("lower", hb_low, a_low), ("upper", hb_up, a_up)):
        assert abs(q[f"fold_{name}_r"] ** 2 - r_hb**2) <= 0.06 * (r_hb**2 - 1.0), name
        assert q[f"fold_{name}_amp_m"] == pytest.approx(a_hb, rel=0.03), name
    r = [float(v) for v in BAND]
    up = [q[f"amp_up_{v.replace('.', 'p')}_m"] for v in BAND]
    down = [q[f"amp_down_{v.replace('.', 'p')}_m"] for v in BAND]
    (j,) = [k for k in range(1, len(r)) if up[k] < 0.5 * up[k - 1]]  # upward: upper at r[j-1]
    assert r[j - 1] < q["fold_upper_r"] < r[j] + 0.01
    (k,) = [
        k for k in range(len(r) - 1) if down[k] > 2.0 * down[k + 1]
    ]  # downward: lower at r[k+1]
    assert r[k] - 0.01 < q["fold_lower_r"] < r[k + 1]
    assert q["unstable_points"] >= 5
    assert q["fold_lower_r"] < q["unstable_r_min"] <= q["unstable_r_max"] < q["fold_upper_r"]
    assert q["fold_lower_amp_m"] < q["unstable_amp_min_m"]
    assert q["unstable_amp_max_m"] < q["fold_upper_amp_m"]
    assert q["unstable_mu_abs_min"] > 1.0
    branch_figure_draws_the_orbits(np.load(out / "harmonic_balance.npz"), q)


def branch_figure_draws_the_orbits(figure, q: dict[str, float]) -> None:
    """harmonic_balance.png's lines after the sweep's: the branch's stretches, stable (solid)
    and unstable (dashed), and the folds: the folds' line at the QOI lines' folds (to their 12
    printed digits); one unstable stretch, from the upper fold to the lower (the order traced)
    with every point between them in r, and two stable stretches."""
    count = sum(1 for key in figure if key.endswith("/label"))
    assert count == 9  # the harmonic balance's 3, the sweep's 2, stretches 3, the folds
    lines = [figure[f"axes0/line{j}"] for j in range(count)]
    labels = [str(figure[f"axes0/line{j}/label"]) for j in range(count)]
    folds = lines[labels.index("fold: a multiplier at +1")]
    expected = [
        [q["fold_upper_r"], q["fold_lower_r"]],
        [1e3 * q["fold_upper_amp_m"], 1e3 * q["fold_lower_amp_m"]],
    ]
    np.testing.assert_allclose(folds, expected, rtol=1e-11)
    assert labels[5] == "periodic orbits, stable" and labels[7].startswith("_")  # unlabelled
    assert labels[6] == "periodic orbits, unstable"
    middle = lines[6]
    np.testing.assert_allclose(middle[:, [0, -1]], expected, rtol=1e-11)
    assert np.all((middle[0, 1:-1] > q["fold_lower_r"]) & (middle[0, 1:-1] < q["fold_upper_r"]))


@pytest.mark.long
def test_the_frequency_response_demo_branch_serial_equals_mpirun(response_runs):
    """The demo's :data:`SHORT` branch of periodic orbits (r from 1.06 down the lower branch,
    through the lower fold and up the unstable middle branch to 1.06) on one rank and on two
    (the shooting parallel in space: PETSc's LU serially, MUMPS under mpirun, other orders of
    the reductions): the same branch, up to how precisely each run solves it, not the bits.

    - The counts (steps, rejected steps, monodromies, folds, unstable points) equal: the step
      control decides on Newton's iteration counts, which round-off (1e-13 relative) changes
      only if an update lands within it of the tolerance.
    - A fold is located to 1e-6 in arclength s (the engine's locate_tolerance), so the two
      runs' folds lie within 2e-6 in s of each other: within 2e-6 in r (|dr/ds| ≤ 1); in
      amplitude within 5e-7 m (the metric weighs the first mode's amplitude a as 4 a/ℓ,
      ``scale`` 4, ℓ = 1 m: ℓ/4 × 2e-6); its multipliers within 4e-5 (|dμ/ds| ≲ 20,
      tests/test_periodic.py). The same bound holds the short branch's fold against the
      whole branch's lower fold (the serial run): the same fold, located from other points.
    - The middle branch's points are corrected points, converged to 1e-9 in the metric
      (‖δx‖; the error then of order ‖δx‖²), each from a prediction off the previous point,
      so the two runs' differences may add up over the steps: r within 2e-9 × steps of each
      other, the amplitude within ℓ/4 of that [m], the largest |μ| within 20 times it.

    Measured (orbit_branch.csv of both runs, full precision): the points' r within 2.6e-12,
    amplitudes 5.8e-13 m, largest |μ| 1.4e-11; the fold's r the same to the last bit, its
    amplitude 1.6e-15 m; the short branch's fold against the whole branch's lower fold: r
    the same to the 12 printed digits, the amplitude 5.5e-12 m."""
    one, two = (
        {k: v for k, v in response_runs[n][0].items() if k.startswith(BRANCH_KEYS)}
        for n in ("short", "mpirun")
    )
    assert one.keys() == two.keys() and len(one) == 5 + 4 + 6
    assert one["branch_folds"] == 1 and one["unstable_points"] >= 2
    corrected = 2e-9 * one["branch_steps"]
    for key, value in one.items():
        fold = key.startswith("fold_")
        if key.startswith("branch_") or key == "unstable_points":
            tolerance = 0.0
        elif key.endswith("_r") or key.startswith("unstable_r_"):
            tolerance = 2e-6 if fold else corrected
        elif key.endswith("_m"):
            tolerance = 5e-7 if fold else corrected / 4
        else:  # multipliers
            tolerance = 4e-5 if fold else 20 * corrected
        assert abs(two[key] - value) <= tolerance, (key, value, two[key])
    whole = response_runs["serial"][0]
    assert abs(one["fold_0_r"] - whole["fold_lower_r"]) <= 2e-6
    assert abs(one["fold_0_amp_m"] - whole["fold_lower_amp_m"]) <= 5e-7
    assert abs(one["fold_0_mu_nearest_one"] - whole["fold_lower_mu_nearest_one"]) <= 4e-5


def response_figure_draws_the_sweep(figure, qoi: dict[str, float], values: list[str]) -> None:
    """harmonic_balance.png's lines (one axes): the harmonic balance's three branches (lines
    0-2, on a grid of r), then the upward and the downward chain (lines 3 and 4), amplitudes in
    mm."""
    labels = [str(figure[f"axes0/line{j}/label"]) for j in range(5)]
    assert labels[0] == "harmonic balance (one mode)"
    assert labels[3:] == ["cosserat-fem, sweep up", "cosserat-fem, sweep down"]
    r = [float(v) for v in values]
    keys = [v.replace(".", "p") for v in values]
    for j, direction in ((3, "up"), (4, "down")):
        chain = figure[f"axes0/line{j}"]
        np.testing.assert_allclose(chain[0], r, rtol=1e-15)
        amplitudes = [1e3 * qoi[f"amp_{direction}_{k}_m"] for k in keys]
        np.testing.assert_allclose(chain[1], amplitudes, rtol=1e-11)
        for x, k in zip(r, keys, strict=True):
            for branch, root in ((0, "low"), (2, "high")):
                curve = figure[f"axes0/line{branch}"]
                i = int(np.argmin(np.abs(curve[0] - x)))
                assert abs(curve[0, i] - x) < 1e-12
                expected = 1e3 * qoi[f"duffing_{root}_{direction}_{k}_m"]
                assert curve[1, i] == pytest.approx(expected, rel=1e-6), (direction, x, root)


ROM_SWEEP = str(ROOT / "demos" / "rom_frequency_sweep.py")
#: The demo's small variant: r = 0.75, 0.875, ..., 1.75, trained on the five members at
#: r = 0.75, 1, 1.25, 1.5, 1.75 (the default's training set), the four between untrained.
ROM_MEMBERS = 9
#: The rod's first bending frequencies over ω0 (`cosserat-fem modes scenes/cao_tucker_2008.toml`:
#: 206.78 and 309.67 rad/s, ω0 = 207.0236 rad/s): x's and y's first resonances.
ROM_RESONANCES = {"x": 206.779767 / 207.0236, "y": 309.671795 / 207.0236}
#: The reduced members' error over √ε (ε the basis's energy left out, docs/rom.md (3)), the
#: bound: measured on this sweep 26-33 at ε = 7.0e-13, 7.1e-11 and 2.5e-9 (the error falls as
#: √ε over four decades: the constant is the model's). docs/rom.md §7's 1.4-7 on the paper's
#: scene is larger here because ε is a fraction of the five training runs' energy together,
#: which the resonant members dominate (a member's own left-out fraction is larger by the
#: ratio of the total to its energy, 2-10 here), and the amplitudes are 8 cm, not 2 mm.
ROM_ERROR_OVER_SQRT_EPS = 50.0


@pytest.fixture(scope="module")
def rom_sweep_runs(tmp_path_factory):
    """demos/rom_frequency_sweep.py with ``--members 9`` serially and under ``mpirun -n 2``:
    QOI of each. Serially 10 s at load 2.5; on two ranks the training runs are on both ranks,
    and a step of 8 elements on two ranks is many MPI messages (the members run a rank each):
    the 5-member variant took 16.5 s at load 2.5; both runs of this one 85 s at load 2, 8 min
    at load 7."""
    runs = {}
    for ranks in (1, 2):
        out = tmp_path_factory.mktemp(f"rom_sweep{ranks}")
        args = [ROM_SWEEP, "--members", str(ROM_MEMBERS), "--out", str(out)]
        proc = run_command(args, ranks)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        runs[ranks] = parse_qoi(proc.stdout)
    return runs


@pytest.mark.long
def test_rom_sweep_demo_reduced_members_within_the_energy_left_out(rom_sweep_runs):
    """The reduced members against the full ones, serially (the long set: the demo's small
    variant takes 10 s).

    * The basis: 5 trained members, ε ≤ the tolerance 1e-8 (measured 6 modes, ε = 2.5e-9).
    * Every member, the four untrained ones between the trained included: the relative L2
      error of the free end's history (docs/rom.md §7's measure) and the amplitudes' largest
      difference over the member's amplitude within 50 √ε (:data:`ROM_ERROR_OVER_SQRT_EPS`;
      |max|a| − max|b|| ≤ max|a − b|, of the history's order). Measured: history errors
      4.1e-4 to 1.7e-3 (at most 33 √ε, √ε = 5.0e-5), amplitude differences 1.7e-4 to
      6.3e-4 (at most 13 √ε). Why √ε: a Galerkin solution's error is its stability
      constant C_s times the best approximation's, and the part of a trained member's
      snapshots outside the basis has at most ε of the five runs' energy E_tot, √(ε E_tot/E_m)
      relative to its own: error ≤ C_s √(E_tot/E_m) √ε. Neither factor is known
      independently here (C_s 1.4-7 on the paper's scene, §7, but the amplitudes here are
      8 cm, not 1 mm; E_tot/E_m 2-10; the untrained members interpolate), so the constant is
      measured: 26-33 at ε = 7.0e-13, 7.1e-11 and 2.5e-9, the same over four decades of ε,
      which is what √ε predicts; 50 is 1.5 times the largest. It fails for a basis without
      the rows' test weights (constant 3e3-1e4, §7) or a member off the basis.
    * The indicator (docs/rom.md §10) of every member, all in the training's range: not
      below the true error over 3 (the issue's factor on the unsafe side; measured E / error
      0.59-1.62). Its upper side, at most the tolerance 1e-2 and 3 times the error:
      :func:`test_rom_sweep_demo_indicator_within_three_times_the_error`.
    * The full members' amplitudes peak where the modes say: x's at the member nearest x's
      first frequency (r = 1, the mode at 0.9988), y's at the one nearest y's (r = 1.5, at
      1.4958); the members 0.125 apart, the peak's half-width over 0.12 s (≈ 2π/(ω0 T) =
      0.25) spans two of them, so only the largest is asserted.
    """
    qoi = rom_sweep_runs[1]
    assert qoi["members"] == ROM_MEMBERS and qoi["trained"] == 5
    eps = qoi["energy_left_out"]
    assert 0 < eps <= qoi["tolerance"] == 1e-8
    bound = ROM_ERROR_OVER_SQRT_EPS * np.sqrt(eps)
    keys = [f"m{m:05d}" for m in range(ROM_MEMBERS)]
    for key in keys:
        assert qoi[f"{key}_history_error"] <= bound, (key, qoi[f"{key}_history_error"], bound)
        assert qoi[f"{key}_amp_error"] <= bound, (key, qoi[f"{key}_amp_error"], bound)
        assert qoi[f"{key}_indicator"] >= qoi[f"{key}_history_error"] / 3, key
    assert sum(qoi[f"{key}_trained"] for key in keys) == 5
    r = np.array([qoi[f"{key}_r"] for key in keys])
    np.testing.assert_allclose(r, np.linspace(0.75, 1.75, ROM_MEMBERS), rtol=1e-15)
    for plane, resonance in ROM_RESONANCES.items():
        amplitudes = [qoi[f"{key}_amp_{plane}_full_m"] for key in keys]
        assert int(np.argmax(amplitudes)) == int(np.argmin(np.abs(r - resonance))), plane


@pytest.mark.long
def test_rom_sweep_demo_indicator_within_three_times_the_error(rom_sweep_runs):
    """The issue's goal for a sweep's members: each indicated error at most the tolerance
    1e-2 and at most 3 times the true error (docs/rom.md §10; the lower side, E ≥ error/3, in
    :func:`test_rom_sweep_demo_reduced_members_within_the_energy_left_out`). Measured
    (2026-12-04): E 5.0e-4 to 1.2e-3, E / error 0.59-1.62 over the 9 members; 0.59 and 1.23
    at r = 1 and 1.125, where the coupling (10.8) held constant between the samples made the
    transport grow (E / error 13.5 and 15.7 before; linear between them since, (10.10)): the
    margin to 3 is 1.85x, to 1e-2 8.5x."""
    qoi = rom_sweep_runs[1]
    for m in range(ROM_MEMBERS):
        key = f"m{m:05d}"
        E, error = qoi[f"{key}_indicator"], qoi[f"{key}_history_error"]
        assert E <= 1e-2 and E <= 3 * error, (key, E, error)


@pytest.mark.long
def test_rom_sweep_demo_serial_equals_mpirun(rom_sweep_runs):
    """The demo's QOI on one rank and on two (the long set: 10 s and 30-40 s). Each member
    runs on one rank in both (group_size 1: the same serial arithmetic), and so do the
    training's full runs (on the first group of ranks, docs/rom.md §11), so the basis is the
    serial one; the bounds below are those of a training on both ranks (MUMPS for LU, the
    POD's tall-skinny QR over the ranks' rows), which the sweep does with group_size 2.

    * Amplitudes [m], both models: within 1e-11 relative (measured: full ones equal, reduced
      ones 2e-13 apart: the basis's round-off carried over 1200 steps).
    * The history and amplitude errors, differences of two amplitudes' scale: within 1e-11
      absolute (measured 1.6e-13).
    * The indicator, a residual about 1e-3 of the state's size: round-off δ of the state is
      δ/1e-3 of it, within 1e-8 relative (measured 1.9e-10).
    * ε, a ratio of the left-out singular values' squares (≈ √ε σ₁ each, so round-off δσ₁ is
      δ/√ε of ε, 2e-12): within 1e-10 relative (measured 1.2e-12); the modes equal.
    The wall times differ and are not compared."""
    one, two = rom_sweep_runs[1], rom_sweep_runs[2]
    assert one["modes"] == two["modes"] and one["members"] == two["members"] == ROM_MEMBERS
    assert two["energy_left_out"] == pytest.approx(one["energy_left_out"], rel=1e-10)
    for m in range(ROM_MEMBERS):
        key = f"m{m:05d}"
        assert two[f"{key}_r"] == one[f"{key}_r"]
        for plane in "xy":
            for model in ("full", "reduced"):
                name = f"{key}_amp_{plane}_{model}_m"
                assert two[name] == pytest.approx(one[name], rel=1e-11), name
        for name in ("amp_error", "history_error"):
            assert abs(two[f"{key}_{name}"] - one[f"{key}_{name}"]) <= 1e-11, (key, name)
        assert two[f"{key}_indicator"] == pytest.approx(one[f"{key}_indicator"], rel=1e-8), key


CABLE_DEMO = str(ROOT / "demos" / "branched_cable.py")


def demo_serial_and_mpi(demo: str, out: Path) -> list[dict]:
    """The quantities of interest ``demo`` prints on one rank and under mpirun -n 2 (its
    folders ``out``1 and ``out``2), each run with its solution.xdmf and probes.csv written."""
    runs = []
    for ranks in (1, 2):
        folder = out.with_name(f"{out.name}{ranks}")
        proc = run_command([demo, "--out", str(folder)], ranks)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        runs.append(parse_qoi(proc.stdout))
        assert (folder / "solution.xdmf").stat().st_size > 0 and (folder / "probes.csv").exists()
    return runs


@pytest.mark.mpi
@pytest.mark.long
def test_the_branched_cable_demo_serial_equals_mpirun(tmp_path):
    """demos/branched_cable.py (a structure of three members with a junction of three, 300
    steps of SDIRK3 under gravity) on one and two ranks: the right leaf's displacement at the
    end and its lowest point equal to 1e-9 of the largest (PETSc's LU against MUMPS's, the
    junction's cells split between the ranks: round-off through 300 nonlinear steps whose
    Newton iterations stop at stol = 1e-8 of ‖U‖ on both alike; measured: the 13 printed
    digits equal), a real swing (R falls by more than 0.1 m, 30% of its branch), and
    solution.xdmf written beside probes.csv for ParaView. ~10 s."""
    runs = demo_serial_and_mpi(CABLE_DEMO, tmp_path / "cable")
    scale = max(abs(v) for v in runs[0].values())
    for name, value in runs[0].items():
        assert abs(runs[1][name] - value) <= 1e-9 * scale, name
    assert runs[0]["R_lowest_z_m"] < -0.1


CAPSTAN_DEMO = str(ROOT / "demos" / "capstan.py")


@pytest.mark.mpi
@pytest.mark.long
def test_the_capstan_demo_serial_equals_mpirun(tmp_path):
    """demos/capstan.py (a rope half a turn over a drum, T2/T1 = 2.4 < e^{0.3π} = 2.566,
    100 steps of BDF2 with contact and friction) on one and two ranks: each quantity of
    interest equal to 1e-8 of itself (PETSc's LU against MUMPS's: round-off through full
    Newton solves that end quadratically, the contact's states decided alike; measured
    7e-12), the rope held (its low end moved less than 1e-4 m: the elastic stretch,
    measured 4.9e-5 m; every one of the 49 nodes sticking at the end) and solution.xdmf
    written for ParaView. ~30 s."""
    runs = demo_serial_and_mpi(CAPSTAN_DEMO, tmp_path / "capstan")
    for name, value in runs[0].items():
        assert abs(runs[1][name] - value) <= 1e-8 * abs(value), name
    assert runs[0]["low_end_m"] < 1e-4
    assert runs[0]["nodes_stick"] == 49
