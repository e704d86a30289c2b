"""Seeing the result: the XDMF output as ParaView reads it, and ``cosserat-fem plot/render``.

* A static cantilever (ℓ = 2 m, 4 cubic elements) under a small tip force P e1 and twisting
  torque T e3: the XDMF arrays against the closed forms of the linear regime, n(s) = P e1 and
  m(s) = (0, P (ℓ − s), T) in the director frame, everywhere along the rod. Cubic elements
  hold the exact linear solution (cubic deflection, quadratic rotation), so what is left is
  the rod's geometric nonlinearity, relative O(δ/ℓ, φ) ~ 1e-5 here: tolerance 1e-4 of P and
  P ℓ. A factor ℓ (û for u), a frame or component mix-up or a sign gives O(1).
* The mesh points lie on the reference centreline (0, 0, s), s ∈ [0, ℓ] [m], one point per
  Lagrange node (elements × degree + 1).
* The resultants of forms/resultants.py are the flux of the general form (63) unscaled:
  b = −((g0/ℓ) Dᵀ n, (g_i/ℓ) m_i) at a random large-rotation state, to round-off.
* A short dynamic run of the paper's scene, opened by ParaView's own reader (``xvfb-run -a
  pvpython tests/paraview_check.py``): the six point arrays and the time steps, the free-end
  values equal to probes.csv (1e-12: double precision, the XML marks Precision="8"),
  "Warp By Vector" = points + displacement, and a rendered PNG that is not blank.
* ``cosserat-fem plot`` and ``render`` on that run (and plot on the static one): the files, their
  pixel sizes, not blank; ``output.fields`` restricted to the displacement writes only it;
  a folder without outputs is bad input (exit 2, one line, no traceback).
* ``mpirun -n 2`` writes the same arrays as the serial run (a vertex on the partition
  boundary takes the mean of two cells owned by different ranks).

h5py cannot be loaded next to DOLFINx in one process, so the plot/render commands run in
subprocesses and this file reads the .h5 with tests/xdmf_files.py (the HDF5 C library).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import ufl
from conftest import ROOT, run_command, subprocess_env
from cosserat_fem.forms.general_form import flux
from cosserat_fem.forms.kinematics import rotation_matrix, split
from cosserat_fem.forms.resultants import resultants
from dolfinx import fem
from PIL import Image, ImageSequence
from xdmf_files import read_arrays

from cosserat_fem.model import build_model, rod_constants
from cosserat_fem.scene import load_scene
from cosserat_fem.statics import static_path

SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
ARRAYS = {"displacement", "angles", "strain_v", "curvature_u", "force_n", "torque_m"}
ALL_FIELDS = 'output.fields=["displacement", "angles", "strains", "forces"]'
P, T, LENGTH = 2.0, 2.0, 2.0  # N, N m, m: deflection 2.4e-4 m, twist 3.6e-4 rad
STATIC = [
    "loads.force_density=[0,0,0]",
    f"rod.length={LENGTH}",
    "discretisation.elements=8",
    "discretisation.degree=3",
    f"loads.end.force=[{P},0,0]",
    f"loads.end.torque=[0,0,{T}]",
    ALL_FIELDS,
]
DYNAMIC = ["time.end=0.0048", "output.xdmf_interval=2.4e-4", ALL_FIELDS]  # 160 steps, 21 frames


def cli(*args: str, ranks: int = 1) -> subprocess.CompletedProcess:
    return run_command(["-m", "cosserat_fem.cli", *args], ranks=ranks)


def non_blank(path: Path) -> tuple[float, float]:
    """(fraction of pixels that differ from the corner's background, std of the grey levels)."""
    pixels = np.asarray(Image.open(path).convert("RGB"), dtype=float)
    background = pixels[0, -1]
    drawn = np.abs(pixels - background).sum(axis=2) > 30
    return float(drawn.mean()), float(pixels.mean(axis=2).std())


@pytest.fixture(scope="module")
def static_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("static")
    static_path(load_scene(SCENE, STATIC), out)
    return out


@pytest.fixture(scope="module")
def dynamic_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("dynamic") / "run"
    sets = sum((["--set", s] for s in DYNAMIC), [])
    proc = cli("run", SCENE, "--out", str(out), "--quiet", *sets)
    assert proc.returncode == 0, proc.stderr
    return out


def directors(angles: np.ndarray) -> np.ndarray:
    """D = Dφ Dθ Dψ of eqs. (15)-(18) at each point, (N, 3, 3): row i is d_i in the fixed
    basis (the product of the elementary rotations, not forms/kinematics.py's (18))."""
    out = []
    for th, ps, ph in angles:
        c, s = np.cos, np.sin
        d_psi = np.array([[c(ps), 0, -s(ps)], [0, 1, 0], [s(ps), 0, c(ps)]])
        d_theta = np.array([[1, 0, 0], [0, c(th), s(th)], [0, -s(th), c(th)]])
        d_phi = np.array([[c(ph), s(ph), 0], [-s(ph), c(ph), 0], [0, 0, 1]])
        out.append(d_phi @ d_theta @ d_psi)
    return np.array(out)


def balance_errors(out: Path) -> tuple[float, float]:
    """Largest deviations from the exact (nonlinear) balance of a tip load: Dᵀn = P e1 and
    Dᵀm = T e3 + (r(ℓ) − r(s)) × P e1 along the rod, relative to P and P ℓ."""
    points, _, arrays = read_arrays(out / "solution.xdmf")
    D = directors(arrays["angles"][-1])
    n_fixed = np.einsum("kij,ki->kj", D, arrays["force_n"][-1])
    m_fixed = np.einsum("kij,ki->kj", D, arrays["torque_m"][-1])
    r = points + arrays["displacement"][-1]
    m_exact = np.array([0.0, 0.0, T]) + np.cross(r[-1] - r, [P, 0.0, 0.0])
    return np.abs(n_fixed - [P, 0, 0]).max() / P, np.abs(m_fixed - m_exact).max() / (P * LENGTH)


def test_tip_load_resultants_match_the_closed_form(static_run, tmp_path):
    points, times, arrays = read_arrays(static_run / "solution.xdmf")
    assert set(arrays) == ARRAYS
    s = points[:, 2]
    assert len(s) == 8 * 3 + 1  # a point per Lagrange node
    np.testing.assert_array_equal(points[:, :2], 0.0)  # on the axis: (0, 0, s) [m]
    np.testing.assert_allclose(s, np.linspace(0.0, LENGTH, 25), rtol=0, atol=1e-14)
    assert times[-1] == 1.0  # the full load
    n, m = arrays["force_n"][-1], arrays["torque_m"][-1]
    # Linear regime, director frame: n = P e1, m = (0, P (ℓ − s), T). What is left is the
    # rotation of the directors (ψ, φ ~ 4e-4 rad) and the discretisation error (below).
    np.testing.assert_allclose(n, np.tile([P, 0.0, 0.0], (25, 1)), rtol=0, atol=2e-3 * P)
    m_linear = np.column_stack([np.zeros(25), P * (LENGTH - s), np.full(25, T)])
    np.testing.assert_allclose(m, m_linear, rtol=0, atol=2e-3 * P * LENGTH)
    # Strains and curvatures of the same state: u2 = m2/(E c22), v3 − 1 = n3/(E A).
    rod = rod_constants(load_scene(SCENE, STATIC))
    c22, area = rod.section.c22, rod.section.area
    u2 = P * LENGTH / (rod.young_modulus * c22)
    assert arrays["curvature_u"][-1][0, 1] == pytest.approx(u2, rel=2e-3)
    np.testing.assert_allclose(
        arrays["strain_v"][-1][:, 2] - 1.0, n[:, 2] / (rod.young_modulus * area), atol=1e-15
    )
    # The exact balance of the tip load holds up to the discretisation error, which falls
    # like h^3 (the derivative of a cubic field): 8 elements against 4 (measured 7.5x).
    coarse = tmp_path / "coarse"
    static_path(load_scene(SCENE, [*STATIC, "discretisation.elements=4"]), coarse)
    (n_fine, m_fine), (n_coarse, m_coarse) = balance_errors(static_run), balance_errors(coarse)
    assert n_fine < 1e-3 and m_fine < 1e-5, (n_fine, m_fine)
    assert n_coarse / n_fine > 4.0 and m_coarse / m_fine > 4.0
    # The XDMF free-end values are the probe's, row by row (load steps).
    probes = np.loadtxt(static_run / "probes.csv", delimiter=",", skiprows=1, ndmin=2)
    np.testing.assert_allclose(probes[:, 0], times, rtol=0, atol=1e-15)
    np.testing.assert_allclose(arrays["displacement"][:, -1], probes[:, 1:4], rtol=0, atol=1e-15)
    np.testing.assert_allclose(arrays["angles"][:, -1], probes[:, 4:7], rtol=0, atol=1e-15)


def test_resultants_are_the_flux_of_the_general_form():
    """b = −((g0/ℓ) Dᵀ n, (g1/ℓ) m1, (g2/ℓ) m2, (g3/ℓ) m3) at a random state."""
    model = build_model(load_scene(SCENE, ["rod.length=2.0"]))  # loads in x, y: 12 unknowns
    U = model.U
    rng = np.random.default_rng(7)
    U.x.array[:] = 0.3 * rng.standard_normal(U.x.array.size)
    p, _ = split(U)
    dU = U.dx(0)
    dp = ufl.as_vector([dU[i] for i in range(6)])
    res, groups, ell = resultants(U, model.rod), model.groups, model.length
    D = rotation_matrix(p[3], p[4], p[5])
    n_fixed = D.T * res.n
    ours = ufl.as_vector(
        [-groups.g0 / ell * n_fixed[i] for i in range(3)]
        + [-g / ell * res.m[i] for i, g in enumerate((groups.g1, groups.g2, groups.g3))]
    )
    points = np.array([[0.1], [0.5], [0.9]])
    cells = np.arange(model.msh.topology.index_map(1).size_local, dtype=np.int32)
    a = fem.Expression(ours, points).eval(cells)
    b = fem.Expression(flux(p, dp, groups), points).eval(cells)
    assert np.abs(b).max() > 1.0  # a large-rotation state, not the trivial one
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())


@pytest.mark.long
@pytest.mark.skipif(shutil.which("pvpython") is None, reason="ParaView (pvpython) not installed")
def test_paraview_reads_the_rod(dynamic_run, tmp_path):
    png, report = tmp_path / "paraview.png", tmp_path / "paraview.json"
    script = str(ROOT / "tests" / "paraview_check.py")
    proc = subprocess.run(
        # -n: where -a starts looking for a free display; two xvfb-run -a started at once
        # (other jobs on the machine) can pick the same one and lose the X connection.
        ["xvfb-run", "-a", "-n", str(100 + os.getpid() % 800), "pvpython", script,
         str(dynamic_run / "solution.xdmf"), str(png), str(report), "100"],
        capture_output=True, text=True, timeout=300, env=subprocess_env(),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    seen = json.loads(report.read_text())
    assert set(seen["point_arrays"]) == ARRAYS
    np.testing.assert_allclose(seen["times"], np.arange(21) * 2.4e-4, rtol=0, atol=1e-15)
    points = np.array(seen["points"])
    assert points.shape == (8 * 3 + 1, 3)
    np.testing.assert_array_equal(points[:, :2], 0.0)
    tip = int(np.argmax(points[:, 2]))
    assert points[tip, 2] == 1.0
    probes = np.loadtxt(dynamic_run / "probes.csv", delimiter=",", skiprows=1)
    rows = {round(t / 3e-5): row for t, row in zip(probes[:, 0], probes[:, 1:], strict=True)}
    for t in seen["times"]:
        frame = seen["frames"][repr(t)]
        row = rows[round(t / 3e-5)]
        np.testing.assert_allclose(frame["displacement"][tip], row[:3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(frame["angles"][tip], row[3:], rtol=0, atol=1e-12)
    last = seen["frames"][repr(seen["times"][-1])]
    assert np.abs(last["displacement"]).max() > 1e-5  # the rod has moved
    warped = np.array(seen["warped_points"])
    np.testing.assert_allclose(warped, points + np.array(last["displacement"]), atol=1e-15)
    drawn, contrast = non_blank(png)
    assert Image.open(png).size == (800, 600)
    assert 0.01 < drawn < 0.6 and contrast > 5.0, (drawn, contrast)


@pytest.mark.long
def test_plot_and_render_a_run(dynamic_run, static_run, tmp_path):
    proc = cli("plot", str(dynamic_run), "--out", str(tmp_path / "plots"))
    assert proc.returncode == 0, proc.stderr
    sizes = {"free_end.png": (1300, 1040), "x_surface.png": (910, 650), "y_surface.png": (910, 650)}
    for name, size in sizes.items():
        path = tmp_path / "plots" / name
        assert Image.open(path).size == size, name
        drawn, contrast = non_blank(path)
        assert 0.02 < drawn < 0.7 and contrast > 5.0, (name, drawn, contrast)
    proc = cli("plot", str(static_run), "--quiet")  # into the run folder; t is the load factor
    assert proc.returncode == 0 and proc.stdout == "", proc.stderr
    assert all(Image.open(static_run / name).size == size for name, size in sizes.items())

    proc = cli("render", str(dynamic_run), "--out", str(tmp_path / "render"), "--frames", "6")
    assert proc.returncode == 0, proc.stderr
    drawn = {}
    for name in ("rod_peak.png", "rod_last.png", "rod_frames.png"):
        path = tmp_path / "render" / name
        assert Image.open(path).size == (1024, 768), name
        drawn[name], contrast = non_blank(path)
        assert 0.02 < drawn[name] < 0.6 and contrast > 5.0, (name, drawn[name], contrast)
    # The earlier frames of rod_frames.png are translucent tubes beside the last one: it covers
    # more of the picture than rod_last.png (measured 1.65x on the paper's scene; with depth
    # peeling, which Mesa's off-screen renderer cannot do with translucency, it was 0.97x).
    assert drawn["rod_frames.png"] > 1.2 * drawn["rod_last.png"], drawn
    gif = Image.open(tmp_path / "render" / "rod.gif")
    frames = [np.asarray(f.convert("L"), dtype=float) for f in ImageSequence.Iterator(gif)]
    assert len(frames) == 6 and frames[0].shape == (768, 1024)
    assert np.abs(frames[-1] - frames[0]).mean() > 0.1  # the rod moves between frames


def displacement_only(out: Path) -> Path:
    """A short run into ``out`` with output.fields = ["displacement"] (3 frames)."""
    sets = [*DYNAMIC, "time.end=0.00048", 'output.fields=["displacement"]']
    proc = cli("run", SCENE, "--out", str(out), "--quiet", *sum((["--set", s] for s in sets), []))
    assert proc.returncode == 0, proc.stderr
    return out


def test_fields_not_asked_for_are_not_written(tmp_path):
    _, times, arrays = read_arrays(displacement_only(tmp_path / "run") / "solution.xdmf")
    assert set(arrays) == {"displacement"} and len(times) == 3


@pytest.mark.long  # off-screen rendering: ~20 s of a busy machine's two cores
def test_render_colours_by_the_displacement_when_it_is_the_only_field(tmp_path):
    proc = cli("render", str(displacement_only(tmp_path / "run")), "--frames", "2", "--quiet")
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("command", ["plot", "render"])
def test_a_folder_without_outputs_is_bad_input(tmp_path, command):
    proc = cli(command, str(tmp_path))
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "holds no run outputs" in proc.stderr
    proc = cli(command, str(tmp_path / "missing"))
    assert proc.returncode == 2 and "is not a folder" in proc.stderr, proc.stderr


@pytest.mark.mpi
def test_mpirun_writes_the_serial_arrays(dynamic_run, tmp_path):
    out = tmp_path / "mpi"
    sets = sum((["--set", s] for s in DYNAMIC), [])
    proc = cli("run", SCENE, "--out", str(out), "--quiet", *sets, ranks=2)
    assert proc.returncode == 0, proc.stderr
    p1, t1, serial = read_arrays(dynamic_run / "solution.xdmf")
    p2, t2, parallel = read_arrays(out / "solution.xdmf")
    np.testing.assert_array_equal(p1, p2)
    np.testing.assert_array_equal(t1, t2)
    for name, values in serial.items():
        scale = np.abs(values).max()
        np.testing.assert_allclose(parallel[name], values, rtol=0, atol=1e-8 * scale, err_msg=name)
