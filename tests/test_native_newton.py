"""The C residual assembler (cosserat_fem/nls/native_newton.py, newton_loop.c ``cf_residual``)
against DOLFINx's, under the same Newton loop.

Every solve runs the one loop (newton_loop.c ``cf_solve``: the policy, the iterations, the stop
rule); ``solver.loop = "python"`` gives it DOLFINx's assembly as its residual callback, the
default the C assembler. The C assembler does DOLFINx's operations in the same order: the FFCx
kernels over the same cells with the same packed coefficients, DOLFINx's summation order and
set_bc's arithmetic for the Dirichlet rows. So equality is the test, bit for bit, of every probe
row and every Newton counter, not agreement to a tolerance: a difference in the last bit would
show that an operation differs, and grow through the run. The scenes cover what the C assembler
must carry: solves that converge at their guess (an arc at rest: no Jacobian is ever
assembled), cell integrals alone (the paper's scene), end loads (exterior facet integrals: the
whip, the roll-up, the flying spaghetti's free ends), Dirichlet values that move (base
excitation), a fork support, a form that changes in the run (the whip in 3D moves its chart: a
new form, a new assembler), adaptive steps, full Newton (the Jacobian callback each iteration)
and the three other integrators. A point load's interior facet integral keeps DOLFINx's
assembly, as does a parallel run (tests/test_scene_features.py runs those under MPI).

Every run takes the one SDIRK step (cosserat_fem/timestepping/integrators.py ``SDIRK.step``: its C
kernels around a ``NewtonSolver.solve`` per stage), so the cases differ in the assembler only,
among them SDIRK4, a lagged Jacobian, adaptive steps, a form that changes, solves that fail
(retried with a fresh Jacobian, then steps rejected and halved), and loads given by data (a grid
table, a table of t, a callable torque whose term the Jacobian holds), whose values at each stage
time the C assembler must read from the packed constants and the quadrature Functions.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem import api
from cosserat_fem.nls import native_newton

IN_3D = "discretisation.planar=off"

CASES = {
    "paper": ("cao_tucker_2008", 60, []),
    "paper-bdf2": ("cao_tucker_2008", 60, ["time.integrator=bdf2", "time.step=1e-5"]),
    "paper-sdirk4-full": (
        "cao_tucker_2008",
        30,
        ["time.integrator=sdirk4", "solver.jacobian=full"],
    ),
    "paper-adaptive": ("cao_tucker_2008", 60, ["time.adaptive=true"]),
    "paper-sdirk4": ("cao_tucker_2008", 60, ["time.integrator=sdirk4"]),
    "paper-lagged": ("cao_tucker_2008", 60, ["solver.jacobian=lagged", "solver.lag=3"]),
    # Solves that fail: retried with a fresh Jacobian, then steps rejected and halved.
    "paper-rejections": ("cao_tucker_2008", 10, ["solver.max_iterations=1", "time.step=1e-4"]),
    "whip-3d-chart": ("whip", 200, [IN_3D]),
    "rollup-alpha": ("rollup", 60, []),
    "base-excitation": ("base_excitation", 40, []),
    "pendulum-fork": ("pendulum", 20, []),
    "flying-spaghetti": ("flying_spaghetti", 20, []),
    "arc-at-rest": ("bathe_bolourchi_bend", 10, ["loads.end.force=[0,0,0]"]),
}


def _run(name: str, steps: int, extra: list[str], loop: str):
    path = ROOT / "scenes" / f"{name}.toml"
    scene = api.load(path)
    end = scene.time.start + steps * scene.time.step
    overrides = [f"time.end={end!r}", "output.xdmf=false", f"solver.loop={loop}", *extra]
    return api.run(api.load(path, overrides), record=True)


@pytest.mark.parametrize("case", list(CASES))
def test_the_c_loop_gives_the_python_loops_iterates_bit_for_bit(case):
    name, steps, extra = CASES[case]
    python = _run(name, steps, extra, "python")
    native = _run(name, steps, extra, "auto")
    assert python.summary["newton"]["loop"] == "python"
    assert native.summary["newton"]["loop"] == "c"
    assert python.summary["status"] == native.summary["status"] == "completed"
    assert np.array_equal(python.probes, native.probes)
    for key in (
        "solves",
        "iterations",
        "residual_assemblies",
        "jacobian_assemblies",
        "retries",
        "max_iterations_in_a_solve",
    ):
        assert python.summary["newton"][key] == native.summary["newton"][key], key
    if case == "whip-3d-chart":
        assert native.summary["chart_resets"] >= 1  # the form changed in the run
    if case == "paper-rejections":
        assert native.summary["rejected_steps"] > 0 and native.summary["newton"]["retries"] > 0


def _data_loads(folder) -> dict:
    """Loads given by data (cosserat_fem/scene/load_data.py) for the paper's scene: its force
    density as a grid table (linear in t, cubic in s), an end force as a cubic table of t and
    an end torque as a callable."""
    import math

    omega = 8 * 207.0236
    rows = ["t, s, q"] + [
        f"{i * 1e-4!r}, {s!r}, {2e3 * math.sin(math.pi * s) * math.sin(omega * i * 1e-4)!r}"
        for i in range(40)
        for s in np.linspace(0.0, 1.0, 9)
    ]
    (folder / "grid.csv").write_text("\n".join(rows) + "\n")
    tip = ["t, F"] + [f"{i * 1e-4!r}, {20 * math.sin(3000 * i * 1e-4)!r}" for i in range(40)]
    (folder / "tip.csv").write_text("\n".join(tip) + "\n")
    grid = {"table": str(folder / "grid.csv"), "column": "q", "s_interpolation": "cubic"}
    force = {"table": str(folder / "tip.csv"), "column": "F", "interpolation": "cubic"}
    return {
        "loads.force_density": [grid, grid, 0],
        "loads.end.force": [0, force, 0],
        "loads.end.torque": [0, 0, lambda t: 5.0 * math.sin(2000.0 * t)],
    }


@pytest.mark.parametrize("extra", [[], ["time.integrator=sdirk4"], ["time.adaptive=true"]])
def test_loads_from_data_under_the_c_assembler_bit_for_bit(tmp_path, extra):
    """A grid table, a table of t and a callable (issue 25 E24), set at each stage time before
    its solve (loop._solve): the C assembler reads their values as DOLFINx's does, so the same
    bits and counters (SDIRK4's stages outside the step included)."""
    sets = {"time.end": 60 * 3e-5, "output.xdmf": False, **_data_loads(tmp_path)}
    path = ROOT / "scenes" / "cao_tucker_2008.toml"
    for word in extra:
        key, _, value = word.partition("=")
        sets[key] = value if value != "true" else True
    python = api.run(api.load(path, {**sets, "solver.loop": "python"}))
    native = api.run(api.load(path, {**sets, "solver.loop": "auto"}))
    assert native.summary["newton"]["loop"] == "c" and python.summary["status"] == "completed"
    assert np.array_equal(python.probes, native.probes)
    for key in ("solves", "iterations", "residual_assemblies", "jacobian_assemblies"):
        assert python.summary["newton"][key] == native.summary["newton"][key], key


def test_a_point_load_keeps_the_python_loop():
    """An interior facet integral (``[loads.point]``) is not in the C loop: the run says so."""
    result = _run("simo_vuquoc_right_angle", 4, [], "auto")
    assert result.summary["newton"]["loop"] == "python"


def test_a_failed_compile_is_one_clear_error(tmp_path, monkeypatch):
    """A C source that does not compile (here: a syntax error; on a machine, missing PETSc
    headers) is reported as NotApplicable, and the process does not try to compile again (a
    second call fails at once, with the same reason); a run, whose Newton solves are C's
    (cf_solve), then stops with a CosseratError that says so (one line, no traceback at the
    command line), as FFCx's forms need a compiler too."""
    from cosserat_fem.common.errors import CosseratError

    broken = tmp_path / "newton_loop.c"
    broken.write_text(native_newton.SOURCE.read_text() + "\nthis is not C;\n")
    monkeypatch.setattr(native_newton, "SOURCE", broken)
    monkeypatch.setattr(native_newton, "_MODULE", None)
    monkeypatch.setattr(native_newton, "_FAILED", None)  # restored after: later tests build
    monkeypatch.setattr(native_newton, "_cache_dir", lambda: tmp_path / "cache")
    with pytest.raises(native_newton.NotApplicable, match="did not compile"):
        native_newton.compiled()
    broken.unlink()  # a second attempt would now fail otherwise (no source): it must not try
    with pytest.raises(native_newton.NotApplicable, match="did not compile"):
        native_newton.compiled()
    with pytest.raises(CosseratError, match="newton_loop.c.*did not compile"):
        _run("cao_tucker_2008", 2, [], "auto")


def test_a_damaged_library_is_compiled_again(tmp_path, monkeypatch, caplog):
    """Item 15: the C loop's library, cached as FFCx's forms are, was loaded whenever it
    existed: cut short (a partial copy of the cache), the run died of SIGBUS at its first
    residual. Now it is checked first (cosserat_fem/common/jit.py ``load_checked``; here a cache
    from before digests were recorded, so by its ELF structure), compiled again with one
    warning naming it, and whole afterwards (its digest recorded)."""
    import shutil

    from conftest import damage_library

    from cosserat_fem.common import jit

    shared = native_newton.library_path()  # read (when whole), never written
    monkeypatch.setattr(native_newton, "_MODULE", None)
    monkeypatch.setattr(native_newton, "_cache_dir", lambda: tmp_path)
    library = native_newton.library_path()
    if shared.exists() and jit.library_damage(shared) is None:
        shutil.copyfile(shared, library)  # saves a compile
    else:
        native_newton.compiled()
    damage_library(library, "cut, no record")
    monkeypatch.setattr(native_newton, "_MODULE", None)  # a new process, as far as the cache goes
    with caplog.at_level("WARNING", logger="cosserat_fem.common.jit"):
        module = native_newton.compiled()
    warned = [r.getMessage() for r in caplog.records if r.name == "cosserat_fem.common.jit"]
    assert len(warned) == 1 and str(library) in warned[0] and "compiling it again" in warned[0]
    assert jit.library_damage(library) is None
    assert library.with_name(library.name + jit.DIGEST_SUFFIX).exists()
    assert module.lib.cf_residual is not None
