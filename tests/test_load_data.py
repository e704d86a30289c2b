"""Loads from data (cosserat_fem/scene/load_data.py, load_coefficients.py; docs/loads.md): tables of
t (and s) against values and Python callables in place of load expressions.

What is held, each against analysis:

* the interpolants converge at their orders (linear 2, cubic 4, PCHIP 3, previous 1) on
  smooth functions, and reproduce the polynomials they contain exactly;
* the paper's load sampled into a table of t and s at spacing h gives the expression's run
  up to the interpolation error: for linear interpolation in t the error's mean over each
  interval is −(h²/12) f'' = +(ωh)²/12 f for f ∝ sin ωt, so the table's load is the
  expression's times 1 − (ωh)²/12 plus a part of zero mean, and the response differs from the
  expression's by −(ωh)²/12 u to leading order (measured orders 2.01-2.04; held: the
  difference is that closed form within 5 % at h = T/16, and the order is 2 ± 0.1); for the
  cubic spline the error is O(h⁴) and its leading part has zero mean over each interval, so
  the response converges faster (measured orders 6.3 and 6.7; held: >= 4, the spline's);
* a constant table, a step table (sample and hold) and a constant grid give the closed-form
  static deflections of the Timoshenko cantilever (as tests/test_statics.py: 1e-8);
* a callable equal to an expression gives the same run to round-off;
* a callable that fails, and a table that changes under a restart or a resumed sweep, are
  refused in one line naming the key.

Malformed tables: tests/test_input_fuzz.py. Serial against mpirun: the test marked long here.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_command

import cosserat_fem as cf
from cosserat_fem.analysis.statics import solve_static
from cosserat_fem.common.errors import SceneError
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.reference import timoshenko as tb
from cosserat_fem.reference.rod_planes import bending_planes
from cosserat_fem.rod.model import rod_constants
from cosserat_fem.scene.build import load_scene
from cosserat_fem.scene.load_data import LoadTable, TableStore, parse_table

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
OMEGA = 8 * 207.0236  # rad/s, the paper's forcing frequency 8 ω0
PERIOD = 2 * math.pi / OMEGA  # s
STEP = 3e-5  # s, the scene's
#: Half a period of the paper's load: 63 steps.
END = round(0.5 * PERIOD / STEP) * STEP
#: A quick run of the paper's scene, Newton converged far below the differences measured
#: (they reach 1e-10 m; the update test at 1e-12 of ‖U‖ leaves ~1e-16 m).
QUICK = {"time.end": END, "output.xdmf": False, "output.checkpoint": False, "solver.stol": 1e-12}


def paper_load(t, s):
    """The paper's force density component [N/m] at t [s], s [m] (ℓ = 1 m)."""
    return 2e3 * np.sin(np.pi * s) * np.sin(OMEGA * t)


def write_grid(path: Path, h: float, end: float, points_s: int = 33) -> Path:
    """The paper's load sampled at spacing h in t (from 0 past ``end``) and at ``points_s``
    points in s over [0, 1] m: a grid table with columns t, s, q."""
    rows = ["t, s, q"]
    for i in range(int(math.ceil(end / h)) + 2):
        for s in np.linspace(0.0, 1.0, points_s):
            rows.append(f"{i * h!r}, {s!r}, {paper_load(i * h, s)!r}")
    path.write_text("\n".join(rows) + "\n")
    return path


def table(data: str, spec: dict | None = None) -> LoadTable:
    """A LoadTable of the CSV text ``data`` (column F unless ``spec`` says)."""
    file = parse_table(data.encode(), "mem.csv", "k")
    return LoadTable.build("k", file, {"column": "F", **(spec or {})}, "mem.csv")


def sampled(f, t: np.ndarray) -> str:
    return "t, F\n" + "".join(f"{a!r}, {f(a)!r}\n" for a in t)


def orders(errors: list[float]) -> np.ndarray:
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


# ================================================================== interpolants (no DOLFINx)
@pytest.mark.parametrize(
    "kind, order", [("linear", 2), ("cubic", 4), ("pchip", 3), ("previous", 1)]
)
def test_interpolants_converge_at_their_orders(kind, order):
    """sup |f − I_h f| for f = exp(2t) on [0, 1] (f' and f'''' never vanish: no extremum,
    where PCHIP drops to order 2), h = 1/64 ... 1/512, on 20001 points: the interpolation
    error bounds (linear h²/8 f'', cubic O(h⁴), PCHIP O(h³), previous h f') give the orders;
    measured 2.00, 3.98-3.99, 2.98-2.99, 1.00. Held within 0.1."""
    tt = np.linspace(0.0, 1.0, 20001)
    errors = []
    for k in range(4):
        t = np.linspace(0.0, 1.0, 64 * 2**k + 1)
        interpolant = table(sampled(lambda a: math.exp(2 * a), t), {"interpolation": kind})
        errors.append(np.abs(interpolant.evaluate(t=tt) - np.exp(2 * tt)).max())
    assert orders(errors) == pytest.approx(order, abs=0.1)
    # One time at a stage (Horner on the piece) is the vectorised evaluation, to round-off.
    some = tt[::997]
    at_once = np.array([interpolant.value(x) for x in some])
    assert np.abs(at_once - interpolant.evaluate(t=some)).max() <= 1e-15 * math.exp(2)


def test_interpolants_reproduce_their_polynomials():
    """Exactly (to round-off): a linear table a line, a cubic spline (not-a-knot) a cubic,
    PCHIP a line (its slopes are estimates: exact for a line only), previous a step. A grid
    (t, s) interpolated linearly in t and cubically in s reproduces (1 + 2t)(s³ − s), also
    through a sampler's weights in s computed once."""
    t = np.linspace(0.0, 2.0, 9)
    tt = np.linspace(0.0, 2.0, 101)
    line = table(sampled(lambda a: 3 * a - 1, t))
    assert np.abs(line.evaluate(t=tt) - (3 * tt - 1)).max() < 1e-14
    cubic = table(sampled(lambda a: a**3 - 2 * a, t), {"interpolation": "cubic"})
    assert np.abs(cubic.evaluate(t=tt) - (tt**3 - 2 * tt)).max() < 1e-13
    pchip = table(sampled(lambda a: 3 * a - 1, t), {"interpolation": "pchip"})
    assert np.abs(pchip.evaluate(t=tt) - (3 * tt - 1)).max() < 1e-14
    step = table("t, F\n0, 1\n1, 5\n2, 7\n", {"interpolation": "previous"})
    assert [step.value(x) for x in (0.0, 0.5, 1.0, 1.999, 2.0)] == [1, 1, 5, 5, 7]
    rows = ["t, s, F"] + [
        f"{a}, {b}, {(1 + 2 * a) * (b**3 - b)!r}"
        for a in (0.0, 0.5, 1.0)
        for b in np.linspace(0, 1, 6)
    ]
    grid = table("\n".join(rows), {"s_interpolation": "cubic"})
    s = np.linspace(0.0, 1.0, 37)
    assert np.abs(grid.at(0.3, s) - 1.6 * (s**3 - s)).max() < 1e-14
    assert np.abs(grid.sampler(s)(0.3) - 1.6 * (s**3 - s)).max() < 1e-14  # weights once


def test_outside_the_table():
    """refuse: the end pieces continue (a stage just beyond the span); hold: the end rows'
    values, rate zero; zero: zero. The rate of a linear table is its slope."""
    data = "t, F\n0, 0\n1, 2\n"
    assert table(data).value(1.1) == pytest.approx(2.2)
    assert table(data).value(-0.1) == pytest.approx(-0.2)
    assert table(data, {"outside": "hold"}).value(1.5) == 2.0
    assert table(data, {"outside": "hold"}).value(-1.0) == 0.0
    assert table(data, {"outside": "zero"}).value(1.5) == 0.0
    assert table(data).derivative("t").value(0.5) == pytest.approx(2.0)
    assert table(data, {"outside": "hold"}).derivative("t").value(1.5) == 0.0


def test_a_store_reads_each_file_once(tmp_path, monkeypatch):
    """Two components of one file cost one read; a second store reads it again (a new
    cf.load sees an edited file)."""
    import cosserat_fem.scene.load_data as load_data

    path = tmp_path / "f.csv"
    path.write_text("t, A, B\n0, 1, 2\n1, 3, 4\n")
    reads = []
    real = load_data.read_bytes
    monkeypatch.setattr(
        load_data, "read_bytes", lambda p, k, c=None: reads.append(p) or real(p, k, c)
    )
    store = TableStore(tmp_path)
    assert store.read("f.csv", "a") is store.read(str(path), "b")
    TableStore(tmp_path).read("f.csv", "a")
    assert reads == [str(path), str(path)]


# ============================================================================= dynamic runs
@pytest.fixture(scope="module")
def expression_run():
    """The paper's scene with its expression load: probes (t, x, y, z, ...)."""
    return cf.run(cf.load(SCENE, QUICK)).probes


def grid_run(tmp_path: Path, h: float, kind: str) -> np.ndarray:
    """The paper's scene with its load as a grid table of spacing h (cubic in s on 33 points:
    an s-error of ~1e-6 of the load, 1e-10 m in the response, below the differences held)."""
    path = write_grid(tmp_path / f"grid-{kind}-{h:.6g}.csv", h, END)
    component = {
        "table": str(path),
        "column": "q",
        "interpolation": kind,
        "s_interpolation": "cubic",
    }
    scene = cf.load(SCENE, {**QUICK, "loads.force_density": [component, component, 0]})
    return cf.run(scene).probes


def test_a_linear_table_of_the_paper_load_converges_at_order_two(tmp_path, expression_run):
    """Module docstring: x and y of the probe differ from the expression's run by
    −(ωh)²/12 u to leading order; at h = T/16 the rest is 0.9 % of the difference (measured;
    held 5 %), and the difference falls by 4 as h halves (orders 2.01, 2.02 measured)."""
    reference = expression_run[:, 1:3]
    errors = []
    for k, h in enumerate((PERIOD / 8, PERIOD / 16, PERIOD / 32)):
        difference = grid_run(tmp_path, h, "linear")[:, 1:3] - reference
        errors.append(np.abs(difference).max())
        if k == 1:
            leading = -((OMEGA * h) ** 2) / 12 * reference
            assert np.abs(difference - leading).max() < 0.05 * errors[-1]
    assert orders(errors) == pytest.approx(2.0, abs=0.1)


def test_a_cubic_table_of_the_paper_load_converges_at_least_at_order_four(tmp_path, expression_run):
    """Module docstring: the spline's order 4 at least (measured 6.3 and 6.7 for the
    response); its difference at T/32 (measured 1.1e-10 m) far below the linear table's at
    the same spacing (5.8e-7 m)."""
    reference = expression_run[:, 1:3]
    errors = [
        np.abs(grid_run(tmp_path, h, "cubic")[:, 1:3] - reference).max()
        for h in (PERIOD / 8, PERIOD / 16, PERIOD / 32)
    ]
    assert np.all(orders(errors) >= 4.0)
    assert errors[-1] < 1e-3 * (OMEGA * PERIOD / 32) ** 2 / 12 * np.abs(reference).max()


@pytest.mark.parametrize("integrator", ["sdirk3", "generalized-alpha", "bdf2"])
def test_a_callable_gives_the_expression_run(integrator):
    """f(t, s) for the force density and f(t) for an end torque equal to the expressions:
    the same probes, and the same power of the loads (the energy monitor's own time
    Constant), to round-off (both evaluate the same libm functions at the same points and
    times: held at 1e-12 of the largest value). Each integrator evaluates its loads at other
    times (SDIRK's stages, generalized-α's τ_n + α_f h and its consistent initial rate,
    BDF2's midpoint start); the end torque's term depends on the angles, so it is in the
    Jacobian too."""
    from rod_energy import EnergyMonitor

    sets = {**QUICK, "time.integrator": integrator}
    runs = []
    for loads in (
        {"loads.end.torque": [0, 0, "5*sin(3000*t)"]},
        {
            "loads.force_density": [paper_load, paper_load, 0],
            "loads.end.torque": [0, 0, lambda t: 5 * math.sin(3000 * t)],
        },
    ):
        result = cf.run(cf.load(SCENE, {**sets, **loads}))
        monitor = EnergyMonitor(result.model)  # at the last state, the loads at other times
        runs.append((result.probes, np.array([monitor.power(t) for t in (0.0, 1e-3, END)])))
    (reference, power), (probes, callable_power) = runs
    assert np.abs(probes - reference).max() <= 1e-12 * np.abs(reference[:, 1:]).max()
    assert np.abs(callable_power - power).max() <= 1e-12 * np.abs(power).max()
    assert np.abs(reference[:, 6]).max() > 1e-9  # the end torque twisted the rod


@pytest.mark.parametrize(
    "function, what",
    [
        (lambda t: 1 / (t - t), "raised ZeroDivisionError"),
        (lambda t: math.nan if t > 2e-4 else 0.0, "returned nan"),
        (lambda t: "x", "not a number"),
    ],
)
def test_a_callable_that_fails_is_refused_naming_the_key(function, what):
    """One line naming the component and the time; exit 2 (SceneError)."""
    scene = cf.load(SCENE, {**QUICK, "loads.end.force": [0, function, 0]})
    with pytest.raises(SceneError) as caught:
        cf.run(scene)
    message = str(caught.value)
    assert message.startswith("loads.end.force[1]: the callable ") and what in message
    assert "at t = " in message and "\n" not in message


def test_a_motion_from_a_table_follows_the_expression(tmp_path):
    """The base excitation's X sin(Ωt) as a cubic table at Ωh = 2π/64 and 2π/128: its rate
    and acceleration are the spline's derivatives. The initial velocity must equal the
    table's rate at t = 0 (the refusal says so, with the value: the spline's end slope,
    X Ω (1 + 1.6e-5) at 2π/64), so the rod starts with that. The rate enters the clamp's
    Dirichlet values and the start, and the spline's derivative converges at order 3 at least
    (h³/24 max|f⁗|, Hall and Meyer), so the tip's difference from the expression's run falls
    by 8 at least as h halves (measured 16: the not-a-knot end at t = 0 dominates, at order 4
    here; 1.0e-8 m, then 6.4e-10 m, of a 4.1e-4 m motion)."""
    scene = ROOT / "scenes" / "base_excitation.toml"
    quick = {"time.end": 4e-3, "output.xdmf": False, "output.checkpoint": False}
    reference = cf.run(cf.load(scene, quick)).probes[:, 1]
    X, Omega = 5e-4, 200.0
    differences = []
    for points in (64, 128):
        path = tmp_path / f"base{points}.csv"
        path.write_text(
            sampled(
                lambda a: X * math.sin(Omega * a), np.arange(0, 10e-3, 2 * math.pi / Omega / points)
            )
        )
        motion = [{"table": str(path), "column": "F", "interpolation": "cubic"}, 0, 0]
        sets = {**quick, "supports.start_motion": motion}
        with pytest.raises(SceneError, match=r"^initial\.velocity\[0\]: must equal the rate "):
            cf.load(scene, sets)
        rate = table(path.read_text(), {"interpolation": "cubic"}).derivative("t").value(0.0)
        probes = cf.run(cf.load(scene, {**sets, "initial.velocity": [rate, 0, 0]})).probes
        differences.append(np.abs(probes[:, 1] - reference).max())
    assert differences[0] < 1e-4 * np.abs(reference).max()
    assert differences[0] / differences[1] > 8.0


# ============================================================================ static, closed form
@pytest.fixture(scope="module")
def beams():
    scene = load_scene(SCENE)
    return (*bending_planes(scene), rod_constants(scene))


STATIC = [
    "loads.force_density=[0,0,0]",
    "discretisation.elements=4",
    "discretisation.degree=3",
    "solver.stol=1e-8",
    "time.end=0.002",
    "time.step=1e-3",
    "output.xdmf_interval=0",
]


def tip(overrides: list[str], directory: Path) -> np.ndarray:
    """(x, y, z, θ, ψ, φ) at s = ℓ of the static solve, tables relative to ``directory``."""
    scene_file = directory / "scene.toml"
    shutil.copy(SCENE, scene_file)
    model, _ = solve_static(load_scene(scene_file, STATIC + overrides))
    return PointProbe(model, 1.0).values()


def test_a_step_table_gives_the_static_closed_form(tmp_path, beams):
    """An end force from a sample-and-hold table at static.time between its rows is the row
    before's value, 0.5 N; and at a row, that row's 1 N: the Timoshenko tip deflections
    (1.5e-5 m at 1 N: the geometric nonlinearity (δ/ℓ)² ~ 2e-10 and Newton's tolerance under
    the 1e-8 of tests/test_statics.py)."""
    bx, _, _ = beams
    (tmp_path / "steps.csv").write_text("t, P\n0, 0\n1e-3, 0.5\n2e-3, 1\n")
    force = '[{table = "steps.csv", column = "P", interpolation = "previous"}, 0, 0]'
    for time, P in ((1.5e-3, 0.5), (2e-3, 1.0)):
        u = tip([f"loads.end.force={force}", f"static.time={time}"], tmp_path)
        assert u[0] == pytest.approx(tb.tip_deflection_end_force(bx, P), rel=1e-8)


def test_a_constant_grid_gives_the_uniform_load_closed_form(tmp_path, beams):
    """A force density q = 10 N/m from a grid table (t, s) constant in both, at the
    quadrature points: the uniform-load deflections (degree 4 holds them exactly: 1e-8)."""
    bx, by, _ = beams
    rows = ["t, s, q"] + [f"{t}, {s}, 10" for t in (0, 1e-3, 2e-3) for s in (0, 0.5, 1)]
    (tmp_path / "q.csv").write_text("\n".join(rows) + "\n")
    q = '{table = "q.csv", column = "q"}'
    u = tip([f"loads.force_density=[{q}, {q}, 0]", "discretisation.degree=4"], tmp_path)
    assert u[0] == pytest.approx(tb.tip_deflection_uniform_load(bx, 10.0), rel=1e-8)
    assert u[1] == pytest.approx(tb.tip_deflection_uniform_load(by, 10.0), rel=1e-8)


# ================================================================= restarts, sweeps, callables
def cli(*args: str) -> tuple[int, str]:
    """The command line in this process: (exit status, stderr's last line)."""
    import contextlib
    import io

    from cosserat_fem.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = main(list(args))
    lines = err.getvalue().strip().splitlines()
    return status, lines[-1] if lines else ""


def test_a_restart_with_another_table_content_is_refused(tmp_path):
    """The checkpoint's scene holds the table's SHA-256: the same file restarts, an edited
    one is refused in one line naming the key, exit 2, before anything is touched."""
    shutil.copy(SCENE, tmp_path / "scene.toml")
    path = tmp_path / "tip.csv"
    path.write_text(sampled(lambda a: 100 * math.sin(3000 * a), np.linspace(0, 2e-3, 41)))
    force = '[0, {table = "tip.csv", column = "F", interpolation = "cubic"}, 0]'
    out = tmp_path / "run"
    status, _ = cli(
        "run",
        str(tmp_path / "scene.toml"),
        "--out",
        str(out),
        "--quiet",
        "--set",
        f"loads.end.force={force}",
        "--set",
        "time.end=6e-4",
        "--set",
        "output.xdmf=false",
    )
    assert status == 0
    summary = json.loads((out / "summary.json").read_text())
    held = summary["scene"]["loads"]["end"]["force"][1]
    assert held["table"] == str(path) and len(held["sha256"]) == 64
    probes = (out / "probes.csv").read_bytes()
    path.write_text(path.read_text() + "# edited\n")  # the same values, another content
    status, line = cli("run", "--restart", str(out), "--set", "time.end=1.2e-3", "--quiet")
    assert status == 2 and line.startswith("cosserat-fem: error: loads.end.force[1].sha256: ")
    assert (out / "probes.csv").read_bytes() == probes


def test_a_run_with_a_callable_load_cannot_be_restarted(tmp_path):
    """summary.json and the checkpoint name the callable; a restart is refused in one line,
    through cf.resume (the saved scene) and through cf.run with the callable given again
    (a checkpoint cannot say that it is the run's), before anything is touched."""
    from cosserat_fem.io.checkpoint import load_checkpoint

    scene = cf.load(
        SCENE,
        {
            **QUICK,
            "time.end": 6e-4,
            "output.checkpoint": True,
            "loads.end.force": [0, lambda t: 10.0, 0],
        },
    )
    cf.run(scene, tmp_path / "run")
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["scene"]["loads"]["end"]["force"][1]["callable"].endswith("<lambda>")
    probes = (tmp_path / "run" / "probes.csv").read_bytes()
    with pytest.raises(
        SceneError,
        match=r"^loads\.end\.force\[1\]: the load was the Python "
        r"callable .* cannot be restarted",
    ):
        cf.resume(tmp_path / "run", {"time.end": 1.2e-3})
    with pytest.raises(
        SceneError,
        match=r"^loads\.end\.force\[1\]: a run with a callable "
        r"load .* cannot be restarted",
    ):
        cf.run(scene, restart=load_checkpoint(tmp_path / "run"))
    assert (tmp_path / "run" / "probes.csv").read_bytes() == probes


def test_a_resumed_sweep_with_another_table_is_refused(tmp_path):
    """The sweep's fingerprint holds every table's SHA-256: the same sweep resumes (nothing
    to run), an edited table makes it another sweep, refused in one line."""
    shutil.copy(SCENE, tmp_path / "scene.toml")
    path = tmp_path / "tip.csv"
    path.write_text("t, F\n0, 0\n1e-3, 10\n")
    (tmp_path / "sweep.toml").write_text(
        '[sweep]\nscene = "scene.toml"\n[sweep.set]\n"time.end" = 3e-4\n"output.xdmf" = false\n'
        '"loads.end.force" = [0, {table = "tip.csv", column = "F"}, 0]\n'
        '[sweep.vary]\n"damping.translational" = [0.0, 1.0]\n'
    )
    out = tmp_path / "out"
    assert cli("sweep", str(tmp_path / "sweep.toml"), "--out", str(out), "--quiet")[0] == 0
    assert cli("sweep", str(tmp_path / "sweep.toml"), "--out", str(out), "--quiet")[0] == 0
    path.write_text("t, F\n0, 0\n1e-3, 20\n")
    status, line = cli("sweep", str(tmp_path / "sweep.toml"), "--out", str(out), "--quiet")
    assert status == 2 and "holds another sweep" in line


@pytest.mark.long
def test_serial_equals_mpirun_with_table_and_callable_loads(tmp_path):
    """A grid table for the force density, a table for an end force and a callable end
    torque: the probes under mpirun -n 2 equal the serial ones to the round-off of the
    distributed LU (MUMPS against PETSc's LU; held at 1e-10 of the largest value, as the
    other serial-against-MPI tests)."""
    write_grid(tmp_path / "grid.csv", PERIOD / 16, END)
    (tmp_path / "tip.csv").write_text(
        sampled(lambda a: 50 * math.sin(3000 * a), np.linspace(0, 4e-3, 81))
    )
    script = tmp_path / "run.py"
    script.write_text(f"""
import math, sys, numpy as np
import cosserat_fem as cf
from mpi4py import MPI
grid = {{"table": "{tmp_path / "grid.csv"}", "column": "q", "interpolation": "cubic"}}
tip = {{"table": "{tmp_path / "tip.csv"}", "column": "F", "interpolation": "pchip"}}
scene = cf.load("{SCENE}", {{**{QUICK!r}, "loads.force_density": [grid, grid, 0],
                 "loads.end.force": [0, tip, 0],
                 "loads.end.torque": [0, 0, lambda t: 5 * math.sin(2000 * t)]}})
probes = cf.run(scene).probes
if MPI.COMM_WORLD.rank == 0:
    np.save(sys.argv[1], probes)
""")
    results = []
    for ranks in (1, 2):
        target = tmp_path / f"probes{ranks}.npy"
        done = run_command([str(script), str(target)], ranks=ranks, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        results.append(np.load(target))
    scale = np.abs(results[0][:, 1:]).max()
    assert np.abs(results[0] - results[1]).max() <= 1e-10 * scale


@pytest.mark.long
def test_callables_that_differ_between_ranks_are_refused_on_every_rank(tmp_path):
    """Under mpirun -n 2: a load of t whose callable gives each rank another value, and one
    that raises on rank 1 only, are refused with the same one line on both ranks (agreed, no
    hang: the job ends within its time limit). Each rank writes its lines to a file of its own
    (mpirun joins the ranks' stdout, and may put one rank's line inside another's)."""
    script = tmp_path / "ranks.py"
    script.write_text(f"""
import cosserat_fem as cf
from cosserat_fem.common.errors import SceneError
from mpi4py import MPI
rank = MPI.COMM_WORLD.rank
report = open(f"{tmp_path}/rank{{rank}}.txt", "w")
def raising(t):
    if rank == 1:
        raise ValueError("rank 1's data")
    return 1.0
for f in (lambda t: float(rank), raising):
    scene = cf.load("{SCENE}", {{**{QUICK!r}, "loads.end.force": [0, f, 0]}})
    try:
        cf.run(scene)
    except SceneError as exc:
        print(f"rank {{rank}}: {{exc}}", file=report, flush=True)
""")
    done = run_command([str(script)], ranks=2, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = sorted(
        line for rank in (0, 1) for line in (tmp_path / f"rank{rank}.txt").read_text().splitlines()
    )
    differ = "loads.end.force[1]: the callable gave 0.0 on rank 0 and 1.0 on rank 1"
    assert [line.split(": ", 1)[1].startswith(differ) for line in lines].count(True) == 2, lines
    assert len(lines) == 4, lines
    raised = "loads.end.force[1]: the callable __main__.raising(t) raised ValueError: rank 1's"
    assert [line.split(": ", 1)[1].startswith(raised) for line in lines].count(True) == 2, lines
