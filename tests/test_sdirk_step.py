"""The one SDIRK step (cosserat_fem/timestepping/integrators.py ``SDIRK.step`` over the C kernels
``cf_sdirk_*`` of newton_loop.c), serial and under ``mpirun -n 2``.

Every run takes the step through Python's own dispatch, so a subclass's override runs on every
step attempt, serial and MPI alike (before issue 26 a serial run took a whole step in C and
silently ignored an override of ``step`` or of the predictor). The counts are exact: one
``step`` call per attempt, one ``predict`` call per stage of each attempt (SDIRK3: two stages).
A predictor that guesses U = Z_i (no extrapolation of the stage rates) starts each stage
from another point than the default's, so Newton's iterates, and the state it stops at (within
its tolerance), differ from the default run's: the override reaches the solves.

A state that breaks a support (``initial_state`` through the API: y = 1e-3 m everywhere, where
the rod's start is clamped, g = 0) is held by each stage's solve, not by the step: the Dirichlet
row of the residual is U_d − g and the Jacobian's row and column there are the identity's, so
the first update is δU_d = U_d and every stage value is U_d = 0 exactly (x − x = 0). Then
K_i,d = (0 − Z_i,d)/(γh) and U_{n+1,d} = U_n,d + h Σ b_i K_i,d = R(∞) U_n,d with SDIRK3's
R(∞) = 1 − bᵀA⁻¹1 = 1 − √3 (γ = (3 + √3)/6; |R(∞)| = 0.73): the clamp's y decays as
R(∞)^n, to the rounding of 20 steps of the C kernels' few elementwise operations (a few units
in the last place each: 1e-13 relative), (1e-3/ℓ) (1 − √3)^20. The other clamped unknowns start
at 0 and stay 0 (to the same rounding, in the comparison below). Serial, the C assembler and
DOLFINx's give the same bits (the same step, the same guesses, the same LU: the same
operations).

Serial and two ranks solve the stage systems with different LU packages (PETSc's own, MUMPS),
and whether MUMPS returns an identity row's δU_d = U_d to the last bit is its own affair (its
scaling of rows and columns, its pivoting), not ours: so the clamped row is compared within a
few units in the last place of its scale σ = 1e-3/ℓ (the largest value the row ever holds), not
bit for bit. The bound: a solve that returns δU_d = U_d (1 + ε), |ε| ≤ 4 u (u = 2^-53, a
scaling and its inverse), leaves a stage value −ε U_d instead of 0, which enters U_{n+1,d}
through h b_i K_i,d = −b_i Z_i,d/γ with Σ|b_i|/γ = 1.27 (SDIRK3): ≤ 5 u σ a step; each step's
error then decays by |R(∞)| = 0.73, so 20 steps sum to ≤ 5 u σ/(1 − 0.73) < 19 u σ; allowed 32
units in the last place of σ (np.spacing(σ), between u σ and 2 u σ: at most 7e-15 σ).
Elsewhere serial and two ranks agree to the Newton tolerance (tests/test_adaptive.py's bound).
"""

from __future__ import annotations

import json

import numpy as np
from conftest import ROOT, run_command

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"

#: Run in-process (serial) and under mpirun (two ranks); prints one JSON line on rank 0.
_SCRIPT = """
import json, sys
import numpy as np
from mpi4py import MPI
from cosserat_fem import api
from cosserat_fem.analysis import simulation
from cosserat_fem.timestepping.integrators import SDIRK

calls = {"step": 0, "predict": 0}


class Stepped(SDIRK):
    def step(self, h, solve):
        calls["step"] += 1
        return super().step(h, solve)


class Predicted(SDIRK):
    def predict(self, stage):
        calls["predict"] += 1
        self.U.x.array[:] = self.Z.x.array  # U = Z_i: no extrapolation of the rates


def run(kind, overrides, initial_state=None):
    real = simulation.make_integrator
    if kind is not None:
        simulation.make_integrator = lambda name, U, residual, time, rho_inf=0.5: kind(
            U, residual, time, order=int(name[-1]))
    try:
        return api.run(api.load(sys.argv[1], overrides), initial_state=initial_state)
    finally:
        simulation.make_integrator = real


def attempts(result):
    return result.summary["accepted_steps"] + result.summary["rejected_steps"]


world = MPI.COMM_WORLD
base = {"time.end": 20 * 3e-5, "output.xdmf": False}
answer = {}
default = run(None, base)
stepped = run(Stepped, base)
predicted = run(Predicted, base)
answer["attempts"] = [attempts(r) for r in (stepped, predicted)]
answer["calls"] = dict(calls)
answer["predicted_differs"] = bool(world.allreduce(
    int(not np.array_equal(predicted.model.U.x.array, default.model.U.x.array)), op=MPI.MAX))
answer["stepped_equals_default"] = bool(world.allreduce(
    int(np.array_equal(stepped.model.U.x.array, default.model.U.x.array)), op=MPI.MIN))
# A state that breaks the clamp at s = 0: a displacement y = 1e-3 m everywhere.
model = default.model
full = np.zeros((model.nodes, 12))
full[:, 1] = 1e-3 / model.length
broken = {}
for loop in (["solver.loop=auto"], ["solver.loop=python"]):
    result = run(None, {**base, "solver.loop": loop[0].split("=")[1]}, initial_state=full)
    U = result.model.U.x.array.reshape(-1, result.model.layout.size)
    s = result.model.V.tabulate_dof_coordinates()[:, 0]
    here = np.isclose(s, 0.0)
    row = U[here][0].copy() if here.any() else np.full(U.shape[1], -np.inf)
    clamped = np.empty_like(row)
    world.Allreduce(row, clamped, op=MPI.MAX)  # the values of a rank that holds s = 0
    broken[loop[0]] = {
        "status": result.summary["status"],
        "clamped": clamped.tolist(),
        "length": model.length,
        "probes": result.probes.tolist(),
    }
answer["broken"] = broken
if world.rank == 0:
    print(json.dumps(answer))
"""


def _answer(ranks: int) -> dict:
    proc = run_command(["-c", _SCRIPT, str(PAPER)], ranks=ranks)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _check_overrides(answer: dict) -> None:
    stepped, predicted = answer["attempts"]
    assert stepped == predicted == 20  # fixed steps, none rejected
    assert answer["calls"] == {"step": stepped, "predict": 2 * predicted}
    assert answer["predicted_differs"]  # another guess, other iterates
    assert answer["stepped_equals_default"]  # the override adds nothing to the arithmetic


def test_sdirk_overrides_are_called_on_every_step_serial_and_mpi():
    """The module docstring: a subclass's ``step`` once per attempt and its ``predict`` once
    per stage, serial and on two ranks; the clamp broken by the initial state decays as
    R(∞)^n, the same bits serial (both assemblers: the same operations), and MPI (MUMPS)
    within 32 units in the last place of its scale σ = 1e-3/ℓ (the docstring's bound: 19 u σ);
    the probes serial = MPI to the Newton tolerance (stol = 1e-7 of ‖U‖:
    tests/test_adaptive.py's 1e-8 of the peak)."""
    serial, mpi = _answer(1), _answer(2)
    for answer in (serial, mpi):
        _check_overrides(answer)
        for run in answer["broken"].values():
            assert run["status"] == "completed"
    serial_rows = [np.array(run["clamped"]) for run in serial["broken"].values()]
    mpi_rows = [np.array(run["clamped"]) for run in mpi["broken"].values()]
    assert np.array_equal(serial_rows[0], serial_rows[1])  # bitwise: the C and DOLFINx's assembly
    sigma = 1e-3 / serial["broken"]["solver.loop=auto"]["length"]
    ulps = 32 * np.spacing(sigma)  # PETSc's LU against MUMPS (docstring)
    for row in mpi_rows:
        assert np.abs(row - serial_rows[0]).max() <= ulps, row - serial_rows[0]
    expected = sigma * (1.0 - 3.0**0.5) ** 20
    for row in (serial_rows[0], *mpi_rows):
        assert abs(row[1] - expected) <= 1e-13 * abs(expected) + ulps
        assert np.abs(np.delete(row, 1)).max() <= ulps  # the others stay 0
    c, dolfinx = (
        np.array(serial["broken"][k]["probes"]) for k in ("solver.loop=auto", "solver.loop=python")
    )
    assert np.array_equal(c, dolfinx)
    two = np.array(mpi["broken"]["solver.loop=auto"]["probes"])
    assert two.shape == c.shape
    for j in range(1, c.shape[1]):
        assert np.abs(two[:, j] - c[:, j]).max() <= 1e-8 * np.abs(c[:, j]).max(), j
