"""PETSc's SNES as the nonlinear solver (cosserat_fem/nls/snes.py) against the project's Newton
loop.

With its default options (``newtonls``, the ``basic`` line search, ``preonly`` + LU) SNES does
the loop's operations: the same residual and Jacobian assembly, the same KSP, the update
W = X − Y (VecWAXPY with −1, x − y exactly as the loop's VecAXPY with −1 rounds it) and the
three norms in one reduction, and the project's stop rule is its convergence test. So its
iterates are the loop's (the C loop's, which are the Python loop's bit for bit:
tests/test_native_newton.py), up to a different order of the vector operations, which the
tolerance admits: a few roundings of the state, 4 ε max|U| per Newton iteration, summed over
the run's iterations (Newton's map contracts a perturbation of an iterate instead of growing
it, and the steps carry it on without growth: the runs are short and stable). The Newton
counters (solves, iterations, assemblies, retries) and the loop's (rejections, the smallest
step) must be equal: a stop decided differently would show there. Measured: equal bit for
bit, serially and under ``mpirun -n 2`` (MUMPS).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT, run_command

from cosserat_fem import api
from cosserat_fem.common.errors import SceneError

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
QUIET = ["output.xdmf=false", "output.checkpoint=false"]
EPS = np.finfo(float).eps

CASES = {
    # SDIRK3, a frozen Jacobian: the default path (SDIRK.step, cf_solve per stage)
    "paper": 60 * 3e-5,
    # full Newton (a Jacobian each iteration), BDF2
    "full-bdf2": ("6e-4", "solver.jacobian=full", "time.integrator=bdf2", "time.step=1e-5"),
    "lagged-adaptive": ("1.2e-3", "solver.jacobian=lagged", "solver.lag=3", "time.adaptive=true"),
    # Divergences (DIVERGED_MAX_IT): retried with a fresh Jacobian, then steps rejected and
    # halved, as the loop does
    "rejections": ("1e-3", "solver.max_iterations=1", "time.step=1e-4"),
}
NEWTON_COUNTERS = (
    "solves",
    "iterations",
    "residual_assemblies",
    "jacobian_assemblies",
    "retries",
    "max_iterations_in_a_solve",
)
LOOP_COUNTERS = ("steps", "accepted_steps", "rejected_steps", "smallest_step_s")


def _overrides(case: str) -> list[str]:
    spec = CASES[case]
    end, *extra = spec if isinstance(spec, tuple) else (repr(spec),)
    return [f"time.end={end}", *QUIET, *extra]


def _same_iterates(newton, snes, iterations: int) -> None:
    """The module docstring's test: the counters equal, the states within the round-off
    allowed for ``iterations`` Newton iterations."""
    for key in NEWTON_COUNTERS:
        assert snes.summary["newton"][key] == newton.summary["newton"][key], key
    for key in LOOP_COUNTERS:
        assert snes.summary[key] == newton.summary[key], key
    U, scale = newton.model.U.x.array, np.abs(newton.model.U.x.array).max()
    tolerance = 4 * EPS * scale * iterations
    assert np.abs(snes.model.U.x.array - U).max() <= tolerance
    assert np.abs(snes.probes - newton.probes).max() <= tolerance


@pytest.mark.parametrize("case", list(CASES))
def test_snes_with_its_defaults_takes_the_newton_loops_iterates(case):
    overrides = _overrides(case)
    newton = api.run(api.load(PAPER, overrides))
    snes = api.run(api.load(PAPER, [*overrides, "solver.nonlinear=snes"]))
    assert (newton.summary["newton"]["loop"], snes.summary["newton"]["loop"]) == ("c", "snes")
    _same_iterates(newton, snes, newton.summary["newton"]["iterations"])
    if case == "rejections":
        assert newton.summary["rejected_steps"] > 0 and newton.summary["newton"]["retries"] > 0


def test_static_load_steps_with_snes():
    """cosserat-fem static (full Newton, 20 load steps of the elastica at P ℓ²/EI = 10) with
    SNES: the same load factors, Newton iterations a step and state (module docstring)."""
    scene = ROOT / "scenes" / "tip_load_elastica.toml"
    newton = api.static(api.load(scene, ["output.xdmf=false"]))
    snes = api.static(api.load(scene, ["output.xdmf=false", "solver.nonlinear=snes"]))
    assert snes.load_factors == newton.load_factors
    assert snes.iterations == newton.iterations
    U = newton.model.U.x.array
    tolerance = 4 * EPS * np.abs(U).max() * sum(newton.iterations)
    assert np.abs(snes.model.U.x.array - U).max() <= tolerance


_MPI_SCRIPT = """
import json, sys
import numpy as np
from mpi4py import MPI
from cosserat_fem import api
overrides, world = json.loads(sys.argv[1]), MPI.COMM_WORLD
runs = [api.run(api.load(sys.argv[2], overrides + extra))
        for extra in ([], ["solver.nonlinear=snes"])]
newton, snes = runs
U = newton.model.U.x.array
gap = world.allreduce(np.abs(snes.model.U.x.array - U).max(initial=0.0), op=MPI.MAX)
scale = world.allreduce(np.abs(U).max(initial=0.0), op=MPI.MAX)
if world.rank == 0:
    print(json.dumps({"gap": gap, "scale": scale,
                      "probe_gap": float(np.abs(snes.probes - newton.probes).max()),
                      "newton": newton.summary["newton"], "snes": snes.summary["newton"],
                      "loop": [[r.summary[k] for k in ("steps", "rejected_steps")] for r in runs]}))
"""


# Long set (make test within 3 minutes): make test keeps the serial cases.
@pytest.mark.long
@pytest.mark.parametrize("case", ["paper", "rejections"])
def test_snes_takes_the_newton_loops_iterates_under_mpi(case):
    """The module docstring's test on two ranks (MUMPS; the loop in Python there): the
    paper's scene with a frozen Jacobian; (long set) steps rejected after divergences."""
    proc = run_command(["-c", _MPI_SCRIPT, json.dumps(_overrides(case)), str(PAPER)], ranks=2)
    assert proc.returncode == 0, proc.stderr[-3000:]
    found = json.loads(proc.stdout.strip().splitlines()[-1])
    newton, snes = found["newton"], found["snes"]
    assert (newton["loop"], snes["loop"]) == ("python", "snes")
    for key in NEWTON_COUNTERS:
        assert snes[key] == newton[key], key
    assert found["loop"][0] == found["loop"][1]
    tolerance = 4 * EPS * found["scale"] * newton["iterations"]
    assert found["gap"] <= tolerance and found["probe_gap"] <= tolerance, found


def test_a_snes_divergence_is_a_rejected_step_then_one_line_with_time_and_place(tmp_path):
    """A trust region too small to move (snes_type = newtontr, snes_tr_delta0 = 1e-12) ends
    every solve with DIVERGED_TR_DELTA: the step is rejected and halved (time.max_halvings =
    1), then the run stops with exit status 3 and one line naming the time (the half step,
    5e-5 s), the place and SNES's reason."""
    proc = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "run",
            str(PAPER),
            "--out",
            str(tmp_path),
            "--set",
            "time.step=1e-4",
            "--set",
            "time.max_halvings=1",
            *[a for o in QUIET for a in ("--set", o)],
            "--petsc",
            "snes_type=newtontr",
            "--petsc",
            "snes_tr_delta0=1e-12",
        ]
    )
    assert proc.returncode == 3, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert "at t = 5e-05 s" in lines[0] and "DIVERGED_TR_DELTA" in lines[0], lines[0]
    assert "s = " in lines[0] and "rejected 1 times" in lines[0], lines[0]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] != "completed" and summary["newton"]["loop"] == "snes"


@pytest.mark.parametrize(
    ("option", "expected"),
    [
        ("snes_linesearch_typo=bt", "solver.petsc.snes_linesearch_typo: PETSc did not use"),
        # an option of a type not chosen (the trust region's, for newtonls)
        pytest.param(
            "snes_tr_delta0=0.1",
            "solver.petsc.snes_tr_delta0: PETSc did not use",
            marks=pytest.mark.long,
        ),
        (
            "snes_type=newtonlx",
            "solver.petsc.snes_type: PETSc refused 'newtonlx': Unable to find "
            "requested SNES type newtonlx",
        ),
        pytest.param(
            "snes_rtol=abc", "solver.petsc.snes_rtol: PETSc refused 'abc'", marks=pytest.mark.long
        ),
    ],
    ids=["unknown", "other-type", "bad-type", "bad-number"],
)
def test_a_petsc_option_that_is_wrong_is_one_line_naming_the_key(tmp_path, option, expected):
    """Exit status 2 and one line on stderr that starts with the dotted key."""
    proc = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "run",
            str(PAPER),
            "--out",
            str(tmp_path),
            "--set",
            "time.end=3e-5",
            *[a for o in QUIET for a in ("--set", o)],
            "--petsc",
            option,
        ]
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], lines


@pytest.mark.parametrize(
    ("overrides", "expected"),
    [
        (["solver.petsc.snes_rtol=[1]"], "solver.petsc.snes_rtol: a PETSc option's value must be"),
        (["solver.petsc.-snes_monitor="], "solver.petsc.-snes_monitor: a PETSc option's name"),
        (["solver.petsc.cosserat_snes_monitor="], "without its prefix"),
        (
            ["solver.nonlinear=newton", "solver.petsc.snes_monitor="],
            "solver.petsc.snes_monitor: PETSc options configure SNES, but solver.nonlinear = "
            '"newton"',
        ),
    ],
    ids=["value", "dash", "prefix", "newton"],
)
def test_a_malformed_petsc_option_is_refused_when_the_scene_is_read(overrides, expected):
    with pytest.raises(SceneError, match="^solver\\.petsc") as caught:
        api.load(PAPER, overrides)
    assert expected in str(caught.value)


def test_petsc_options_reach_snes_and_leave_petsc_after():
    """[solver.petsc] values become SNES's: snes_rtol overrides solver.rtol in the stop rule,
    snes_type chooses the method; after the solver is gone the options database holds none of
    them (another solver built later must not see them)."""
    from petsc4py import PETSc

    from cosserat_fem.nls.newton import NewtonSettings
    from cosserat_fem.nls.solvers import make_solver
    from cosserat_fem.rod.model import build_model
    from cosserat_fem.scene.schema import PETSC_PREFIX
    from cosserat_fem.timestepping.integrators import make_integrator

    scene = api.load(PAPER, ["solver.petsc.snes_rtol=1e-3", "solver.petsc.snes_type=newtontr"])
    model = build_model(scene)
    form = make_integrator("static", model.U, model.residual, 0.0).residual_form()
    solver = make_solver(form, model.U, model.bcs, NewtonSettings.of(scene.solver))
    try:
        assert solver.loop == "snes" and solver.snes.getType() == "newtontr"
        assert solver.settings.rtol == 1e-3 and solver.settings.stol == scene.solver.stol
    finally:
        solver.destroy()
    database = PETSc.Options()
    assert not any(database.hasName(PETSC_PREFIX + name) for name in ("snes_rtol", "snes_type"))
