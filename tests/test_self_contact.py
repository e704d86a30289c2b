"""A rod's contact with itself (issue 30; docs/contact.md, "Self contact"): a hairpin pressed
shut, against the linear frame's closed form.

The rod at rest is a polyline U in the x-z plane: leg 1 from the clamp (0, 0, 0) to (L1, 0, 0),
a rigid corner, a segment of length H up to (L1, 0, H), a corner, leg 2 back to the free end
D = (L1 − L2, 0, H) (L2 < L1: D lies over leg 1). Its tube of radius r leaves a gap
δ0 = H − 2r between the legs. A force P down at D closes the hairpin; once D touches leg 1 at
E below it, the contact carries R and D the net Q = P − R. By the unit-load method (a virtual
pair, 1 down at D and 1 up at E, whose moments vanish on leg 1 between the clamp and E), the
approach of D to E is Q C with

    C = (2 L2³/3 + H L2²)/EI + 2 L2/(κGA) + H/EA                                  (H.1)

(bending of both legs and of the segment under the arm L2, the legs' shear, the segment's
extension), so D touches at P_c = δ0/C and beyond it the contact carries R = P − δ0/C.

The linear frame is exact for the P3 elements here (moments linear along each straight
member: the displacements are cubic; measured: the same R at 39 and 78 cells to 1e-12), so
the reaction's error is the linear theory's, O(δ0/L): measured 4.6e-5 at δ0/L2 = 1.1e-3 and
5.6e-6 at 1.1e-4. The tolerances: 1e-4 and 1e-5 (twice the measured, and proportional to δ0:
a defect of the rows, a reaction or a gap wrong by a fraction of itself, would not shrink
with δ0).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import script_serial_and_mpi
from mpi4py import MPI

from cosserat_fem.analysis.statics import static_path
from cosserat_fem.scene.build import scene_from_dict

L1, H, L2 = 1.0, 0.05, 0.9
E, NU, KAPPA = 2.0e9, 0.3, 0.9


def closure(r: float) -> tuple[float, float]:
    """δ0 [m] and C [m/N] of (H.1) for a tube of radius ``r``."""
    area, inertia = math.pi * r**2, math.pi * r**4 / 4
    EI, EA, GA = E * inertia, E * area, KAPPA * E / (2 * (1 + NU)) * area
    C = (2 * L2**3 / 3 + H * L2**2) / EI + 2 * L2 / GA + H / EA
    return H - 2 * r, C


def hairpin(P: float, r: float, cells: int = 39) -> dict:
    """The scene of the module docstring (cells of 0.05 m: both corners at vertices)."""
    return {
        "rod": {
            "length": L1 + H + L2,
            "section": {"shape": "circle", "diameter": 2 * r, "shear_coefficient": KAPPA},
            "material": {"density": 1000.0, "young_modulus": E, "poisson_ratio": NU},
        },
        "reference": {
            "shape": "polyline",
            "points": [[0, 0, 0], [L1, 0, 0], [L1, 0, H], [L1 - L2, 0, H]],
            "binormal": [0, 1, 0],
        },
        "supports": {"start": "clamped", "end": "free"},
        "loads": {"end": {"force": [0, 0, -P]}},
        "static": {"load_steps": 1},
        "time": {"end": 1.0, "step": 1.0},
        "discretisation": {"elements": cells, "degree": 3},
        "contact": {"self_contact": True},
    }


def pressed(P: float, r: float) -> tuple[float, dict]:
    """The contact force [N] on D (0 if none) and summary.json's contact entries."""
    result = static_path(scene_from_dict(hairpin(P, r)), comm=MPI.COMM_SELF, write_outputs=False)
    pairs = result.model.contact.pairs
    rows = pairs._rows
    force = float(rows["fN"].sum() * pairs.force_scale) if len(rows.get("local", ())) else 0.0
    return force, result.model.contact.summary()


@pytest.mark.parametrize(("r", "bound"), [(0.0245, 1e-4), (0.02495, 1e-5)])
def test_a_hairpin_pressed_shut_carries_the_frames_reaction(r, bound):
    """At P = 2 P_c one pair presses (D on leg 1), its force is R = P − δ0/C within ``bound``
    relative (module docstring), its gap 0 to 1e-12 δ0 (the row g = 0 solved to the Newton
    tolerance); at P = P_c/2 nothing touches and the least gap is δ0 − P C to 1e-3 relative
    (the same linear theory)."""
    delta0, C = closure(r)
    force, summary = pressed(2 * delta0 / C, r)
    assert summary["pairs_in_contact"] == 1
    assert abs(force / (delta0 / C) - 1) < bound
    assert abs(summary["least_pair_gap_m"]) < 1e-12 * delta0
    force, summary = pressed(0.5 * delta0 / C, r)
    assert force == 0.0 and summary["pairs_in_contact"] == 0
    assert abs(summary["least_pair_gap_m"] / (0.5 * delta0) - 1) < 1e-3


_SCRIPT = """
import json, sys
sys.path.insert(0, {tests!r})
from mpi4py import MPI
from test_self_contact import hairpin, closure
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.scene.build import scene_from_dict
delta0, C = closure(0.0245)
result = static_path(scene_from_dict(hairpin(2 * delta0 / C, 0.0245)), comm=MPI.COMM_WORLD,
                     write_outputs=False)
pairs = result.model.contact.pairs
rows = pairs._rows
local = float(rows["fN"].sum() * pairs.force_scale) if len(rows.get("local", ())) else 0.0
force = MPI.COMM_WORLD.allreduce(local)
tip = result.model.contact.summary()
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps({{"force": force, "pairs": tip["pairs_in_contact"]}}))
"""


@pytest.mark.long
@pytest.mark.mpi
def test_the_hairpin_under_mpirun_equals_serial(tmp_path):
    """Under mpirun -n 2 the tip D and its partner E lie on different ranks (the rod is dealt
    in two halves along s): the reaction reaches E's owner by PETSc's assembly. The force
    equals the serial one to 1e-9 relative (the same Newton iterates; MUMPS against PETSc's
    LU: round-off 1e-12 of the rows times the condition of the iterations)."""
    from pathlib import Path

    text = _SCRIPT.format(tests=str(Path(__file__).parent))
    serial, parallel = script_serial_and_mpi(tmp_path / "hairpin.py", text)
    assert serial["pairs"] == parallel["pairs"] == 1
    assert abs(parallel["force"] / serial["force"] - 1) < 1e-9


def test_a_chain_of_contacts_is_refused_in_one_line():
    """A node pressed onto the rod that also carries another node's contact is refused with
    its place, as a SolverError (one line, exit 3 at the command line): the rows would need
    the reactions ordered (docs/decisions.md, "Self contact")."""
    from cosserat_fem.common.errors import SolverError
    from cosserat_fem.rod.model import build_model
    from cosserat_fem.rod.obstacles import contact_rows

    model = build_model(scene_from_dict(hairpin(0.0, 0.0245)), MPI.COMM_SELF)
    pairs = contact_rows(model).pairs
    slave = np.array([100])
    with pytest.raises(SolverError, match=r"^contact: a node pressed onto the rod also") as e:
        pairs._check_chains(slave, np.array([[3, 100, 101, 102]]))
    assert "\n" not in str(e.value) and "s = " in str(e.value)
    pairs._check_chains(slave, np.array([[3, 4, 5, 6]]))  # no chain: nothing raised


def test_the_rod_through_itself_between_nodes_is_found_with_its_place():
    """The hairpin's free leg turned down about its corner until its end is 2.5r through leg 1
    (a displacement linear along the leg: exact in P3, through at its nodes and between
    them): the pairs' check names both places along the rod and the depth, and a time step
    or a load step with it is rejected (Contacts.step_changes, the statics' check). Through
    by 0.005 r at the end (within the bound 1e-2 r) it passes."""
    from cosserat_fem.analysis.statics import static_solver
    from cosserat_fem.rod.model import build_model

    r = 0.0245
    delta0, _ = closure(r)
    scene = scene_from_dict(hairpin(0.0, r))
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    contact = solver.contact
    bs, ell = model.layout.size, model.length
    s = model.V.tabulate_dof_coordinates()[:, 0] * ell
    z = model.layout.index(2)
    ramp = np.clip((s - L1 - H) / L2, 0.0, None)  # 0 at the corner, 1 at the free end
    assert contact.step_changes() is None  # before any iterate
    for depth, found in ((2.5 * r, True), (0.005 * r, False)):
        model.U.x.array[:] = 0.0
        model.U.x.array[z::bs] -= ramp * (delta0 + depth) / ell
        solver._residual()
        trouble = contact.step_changes()
        assert (trouble is not None) is found, trouble
    model.U.x.array[z::bs] -= ramp * 2.5 * r / ell
    solver._residual()
    where, reason = contact.step_changes()
    assert where.startswith("s = ") and "passes through itself between its nodes" in reason
