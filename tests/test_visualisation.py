"""Seeing the result: the XDMF output as ParaView reads it, and ``cosserat-fem plot/render``.

* A static cantilever (ℓ = 2 m, 4 cubic elements) under a small tip force P e1 and twisting
  torque T e3: the XDMF arrays against the closed forms of the linear regime, n(s) = P e1 and
  m(s) = (0, P (ℓ − s), T) in the director frame, everywhere along the rod, within the bound
  that the exact (nonlinear) balance leaves them: the directors turn by the Euler angles
  (3.7e-4 rad here), the deflection (2.3e-4 m) is a moment arm, and the balance itself holds
  to the elements' error of n, a derivative of the cubic field times the stiff κGA (4.9e-4 P,
  falling as h^3). The bound, computed from the file, is 1.2e-3 of P and 6.5e-4 of P ℓ
  (measured 4.9e-4 and 8.8e-5); a factor ℓ (û for u), a frame or component mix-up or a sign
  gives O(1).
* The mesh points lie on the reference centreline (0, 0, s), s ∈ [0, ℓ] [m], one point per
  Lagrange node (elements × degree + 1).
* The resultants of forms/resultants.py are the flux of the general form (63) unscaled:
  b = −((g0/ℓ) Dᵀ n, (g_i/ℓ) m_i) at a random large-rotation state, to round-off.
* A short dynamic run of the paper's scene, opened by ParaView's own reader (``pvpython
  tests/paraview_check.py`` on an Xvfb display of its own, tests/virtual_display.py): the six
  point arrays and the time steps, the free-end values equal to probes.csv (1e-12: double
  precision, the XML marks Precision="8"), "Warp By Vector" = points + displacement, and a
  rendered PNG that is not blank.
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
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import ufl
from conftest import PYTHON, ROOT, file_size_limit, run_command, subprocess_env
from cosserat_fem.forms.general_form import flux
from cosserat_fem.forms.kinematics import rotation_matrix, split
from cosserat_fem.forms.resultants import resultants
from dolfinx import fem
from PIL import Image, ImageSequence
from virtual_display import run_pvpython
from xdmf_files import read_arrays

from cosserat_fem.analysis.statics import static_path
from cosserat_fem.rod.model import build_model, rod_constants
from cosserat_fem.scene.build import load_scene

SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
ARRAYS = {"displacement", "angles", "strain_v", "curvature_u", "force_n", "torque_m"}
ALL_FIELDS = 'output.fields=["displacement", "angles", "strains", "forces"]'
P, T, LENGTH = 2.0, 2.0, 2.0  # N, N m, m: deflection 2.3e-4 m, twist 2.0e-4 rad
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
    # Linear regime, director frame: n = P e1, m = (0, P (ℓ − s), T), to what the exact
    # balance (balance_errors: Dᵀn = P e1, Dᵀm = T e3 + (r(ℓ) − r(s)) × P e1) leaves. The
    # directors turn by at most α = max(|θ| + |ψ| + |φ|), which moves n and m by α |n| and
    # α |m|; the deflection u is a moment arm, (u(ℓ) − u(s)) × P e1, at most 2 max|u| P; the
    # balance holds to ε_n P and ε_m P ℓ in each component, √3 times that for a vector.
    alpha = np.abs(arrays["angles"][-1]).sum(axis=1).max()
    arm = 2 * np.linalg.norm(arrays["displacement"][-1], axis=1).max() * P
    eps_n, eps_m = balance_errors(static_run)
    bound_n = alpha * P + math.sqrt(3) * eps_n * P
    bound_m = alpha * math.hypot(P * LENGTH, T) + arm + math.sqrt(3) * eps_m * P * LENGTH
    assert bound_n < 2e-3 * P and bound_m < 1e-3 * P * LENGTH  # small: a real comparison
    np.testing.assert_allclose(n, np.tile([P, 0.0, 0.0], (25, 1)), rtol=0, atol=bound_n)
    m_linear = np.column_stack([np.zeros(25), P * (LENGTH - s), np.full(25, T)])
    np.testing.assert_allclose(m, m_linear, rtol=0, atol=bound_m)
    # Strains and curvatures of the same state: u2 = m2/(E c22), v3 − 1 = n3/(E A). At the
    # clamp the directors do not turn: m2 is P ℓ to the moment arm and ε_m.
    rod = rod_constants(load_scene(SCENE, STATIC))
    c22, area = rod.section.c22, rod.section.area
    u2 = P * LENGTH / (rod.young_modulus * c22)
    clamp = (arm + math.sqrt(3) * eps_m * P * LENGTH) / (P * LENGTH)
    assert arrays["curvature_u"][-1][0, 1] == pytest.approx(u2, rel=clamp)
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
@pytest.mark.skipif(
    shutil.which("pvpython") is None or shutil.which("Xvfb") is None,
    reason="ParaView (pvpython) or Xvfb not installed",
)
def test_paraview_reads_the_rod(dynamic_run, tmp_path):
    png, report = tmp_path / "paraview.png", tmp_path / "paraview.json"
    script = str(ROOT / "tests" / "paraview_check.py")
    args = [script, str(dynamic_run / "solution.xdmf"), str(png), str(report), "100"]
    proc = run_pvpython(args, subprocess_env())
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


def limited(limit: int, *args: str) -> subprocess.CompletedProcess:
    """``cosserat-fem ARGS`` in a child under a file size limit of ``limit`` bytes."""
    return subprocess.run(
        [PYTHON, "-m", "cosserat_fem.cli", *args],
        env=subprocess_env(),
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=file_size_limit(limit),
    )


def full_disk_outcome(proc, out: Path, failing: str, whole: Path, command: str) -> None:
    """Exit 4, one line naming ``failing``, and every file left in ``out`` whole (the bytes
    of the same command without the limit)."""
    assert proc.returncode == 4, proc.stderr
    assert proc.stderr.splitlines() == [
        f"cosserat-fem: error: {command}: cannot write {str(out / failing)!r} (File too large)"
    ]
    for path in out.iterdir():
        assert path.read_bytes() == (whole / path.name).read_bytes(), path


def test_plot_on_a_full_disk_stops_with_exit_4(tmp_path):
    """Item 17's sibling: ``plot`` on a full disk (a file size limit: EFBIG as ENOSPC) was
    "bad input" (exit 2) with matplotlib's cut PNG left behind. Now each figure is made in
    memory and written whole: exit 4 and one line naming the figure, no cut file. A limit of
    16 kB stops at the first figure, free_end.png (1300 x 1040 pixels: ~100 kB)."""
    run = tmp_path / "run"
    sets = [*DYNAMIC, "time.end=0.00048"]
    proc = cli("run", SCENE, "--out", str(run), "--quiet", *sum((["--set", s] for s in sets), []))
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "plots"
    full_disk_outcome(
        limited(16 * 2**10, "plot", str(run), "--out", str(out)),
        out,
        "free_end.png",
        tmp_path,
        "plot",
    )
    assert not list(out.iterdir())


@pytest.mark.long
def test_render_on_a_full_disk_stops_with_exit_4(dynamic_run, tmp_path):
    """Item 17: ``render`` on a full disk gave an internal OSError (a picture) or imageio's
    traceback and exit 2 (the animation), leaving cut files. Now each picture and the GIF are
    made in memory and written whole: exit 4 and one line naming the file. Limits from the
    sizes of an unlimited render: one byte short of the smallest picture stops at the first
    one, rod_peak.png; the largest picture plus one byte stops at the larger GIF."""
    whole = tmp_path / "whole"
    args = ["--frames", "6", "--quiet"]
    proc = cli("render", str(dynamic_run), "--out", str(whole), *args)
    assert proc.returncode == 0, proc.stderr
    sizes = {p.name: p.stat().st_size for p in whole.iterdir()}
    pictures = [size for name, size in sizes.items() if name.endswith(".png")]
    assert sizes["rod.gif"] > max(pictures)
    for limit, failing in (
        (sizes["rod_peak.png"] - 1, "rod_peak.png"),
        (max(pictures) + 1, "rod.gif"),
    ):
        out = tmp_path / failing
        proc = limited(limit, "render", str(dynamic_run), "--out", str(out), *args)
        full_disk_outcome(proc, out, failing, whole, "render")
        assert not (out / failing).exists()


@pytest.mark.long
def test_render_tells_its_progress(dynamic_run, tmp_path):
    """Item 22: render (27-40 s) printed nothing until it ended. render_run calls
    ``progress(done, total, what)`` after each of its 3 pictures and each animation frame
    (the command line draws it as a status line on a terminal): here 3 + 3 frames, done
    counting 1 to 6 of 6, each naming what was made."""
    script = (
        "import sys\nfrom cosserat_fem.render import render_run\n"
        "render_run(sys.argv[1], sys.argv[2], max_frames=3,\n"
        "           progress=lambda d, t, w: print(f'{d}|{t}|{w}', flush=True))\n"
    )
    proc = run_command(["-c", script, str(dynamic_run), str(tmp_path / "render")])
    assert proc.returncode == 0, proc.stderr
    calls = [line.split("|") for line in proc.stdout.splitlines()]
    assert [(int(d), int(t)) for d, t, _ in calls] == [(d, 6) for d in range(1, 7)]
    assert [w for _, _, w in calls] == [
        "rod_peak.png",
        "rod_last.png",
        "rod_frames.png",
        *(f"rod.gif, frame {i} of 3" for i in (1, 2, 3)),
    ]


@pytest.mark.parametrize("command", ["plot", "render"])
def test_a_folder_without_outputs_is_bad_input(tmp_path, command):
    proc = cli(command, str(tmp_path))
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "holds no run outputs" in proc.stderr
    proc = cli(command, str(tmp_path / "missing"))
    assert proc.returncode == 2 and "is not a folder" in proc.stderr, proc.stderr


@pytest.mark.long
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
