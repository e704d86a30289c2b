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


def test_chains_of_contacts_are_taken_by_levels_and_a_cycle_is_refused_in_one_line():
    """(P.5)'s levels: a pair is at level 0 if nothing presses on its slave, else one more
    than the deepest pair whose partner cell holds the slave (the longest chain ending at
    it). Three stacked pairs (117 on 110's cell, 110 on 100's, 100 on a cell of nodes no
    pair presses with) are at levels 2, 1, 0 whatever their order, also where 117's
    closest point is at its cell's end away from 110 (weight 0 there: inside a P3 cell a
    weight vanishes where its derivative does not, and the Jacobian adds to that node).
    Pairs lying on each other in a cycle (possible on a structure only) are refused with
    their place, one line, a SolverError not retried."""
    from cosserat_fem.common.errors import SolverError
    from cosserat_fem.nls.pair_contact import Pairs
    from cosserat_fem.rod.model import build_model
    from cosserat_fem.rod.obstacles import contact_rows

    model = build_model(scene_from_dict(hairpin(0.0, 0.0245)), MPI.COMM_SELF)
    pairs = contact_rows(model).pairs

    def levels(slave, partner, weights):
        empty = np.zeros(len(slave))
        return pairs._levels(
            Pairs(
                np.array(slave),
                np.array(partner),
                empty,
                empty,
                np.array(weights),
                empty,
                empty,
                empty,
            )
        )

    even = [0.25, 0.25, 0.25, 0.25]
    stack = levels(
        [100, 117, 110], [[3, 4, 5, 6], [108, 109, 110, 111], [99, 100, 101, 102]], [even] * 3
    )
    assert stack.tolist() == [2, 0, 1]
    # 117's closest point at the end of its cell away from 110: a weight 0 still counts
    apart = levels(
        [100, 117, 110],
        [[3, 4, 5, 6], [108, 109, 110, 111], [99, 100, 101, 102]],
        [even, [1.0, 0.0, 0.0, 0.0], even],
    )
    assert apart.tolist() == [2, 0, 1]
    with pytest.raises(
        SolverError, match=r"^contact: parts of the rod lie on each other in a cycle"
    ) as e:
        levels([100, 110], [[108, 109, 110, 111], [99, 100, 101, 102]], [even, even])
    assert "\n" not in str(e.value) and "s = " in str(e.value) and not e.value.retry


# Three parts stacked (a chain of contacts, (P.5)): leg 1 from the clamp along e1, a corner
# up to leg 2 back over it, a short slanted corner up to leg 3 forward over leg 2; its end D3
# pressed down lands on leg 2, which presses on leg 1 under it. Lengths [m]; the corners at
# vertices of cells of 0.05 m; leg 3 rises SLANT along e1 so that D3 lies inside a cell.
ZL1, ZL2, ZL3, SLANT, ZR = 0.7, 0.6, 0.15, 0.008, 0.0245
STIFF_LEG3 = 100.0


def stack(P: float, rigid: float | None, tail: float = 0.0) -> dict:
    """The stacked rod loaded by P [N] down at D3, its leg 1 and first corner ``rigid`` times
    stiffer than leg 2, its second corner and leg 3 STIFF times; or (``rigid`` None) the rod
    from the first corner's top, clamped there, over the plane z = r that is leg 1's top.
    With a ``tail`` [m] the rod goes on from D3 straight up (as stiff as leg 3), loaded at its
    end instead: more rod after D3, so that a partition along s can put D3 on another rank
    than leg 2's nodes under it."""
    rise = math.sqrt(0.05**2 - SLANT**2)
    top = [[ZL1, 0, H], [ZL1 - ZL2, 0, H], [ZL1 - ZL2 + SLANT, 0, H + rise]]
    top.append([ZL1 - ZL2 + SLANT + ZL3, 0, H + rise])
    if tail:
        top.append([ZL1 - ZL2 + SLANT + ZL3, 0, H + rise + tail])
    data = hairpin(0.0, ZR)
    data["loads"] = {"end": {"force": [0, 0, -P]}}
    start = 0.0 if rigid is None else ZL1 + H  # s [m] at the first corner's top
    factor = f"(1 + {STIFF_LEG3 - 1!r}*heaviside(s - {start + ZL2!r}))"
    if rigid is None:
        data["reference"]["points"] = top
        data["contact"]["obstacles"] = [{"kind": "plane", "point": [0, 0, ZR], "normal": [0, 0, 1]}]
    else:
        data["reference"]["points"] = [[0, 0, 0], [ZL1, 0, 0]] + top
        factor += f"*(1 + {rigid!r}*heaviside({start!r} - s))"
    data["rod"]["length"] = start + ZL2 + 0.05 + ZL3 + tail
    area, inertia = math.pi * ZR**2, math.pi * ZR**4 / 4
    EI, EA, GA = E * inertia, E * area, KAPPA * E / (2 * (1 + NU)) * area
    diagonal = [GA, GA, EA, EI, EI, EI / (1 + NU)]
    data["rod"]["section"]["stiffness"] = [
        [f"{k!r}*{factor}" if i == j else 0 for j in range(6)] for i, k in enumerate(diagonal)
    ]
    data["discretisation"]["elements"] = round(data["rod"]["length"] / 0.05)
    # leg 2 lands on a rigid base along its length: in one step its nodes all touch at the
    # first iterate and are let go one an iteration (16 steps: 4 s instead of 12 s)
    data["static"]["load_steps"] = 16
    return data


def stacked_forces(
    P: float, rigid: float | None, comm=MPI.COMM_SELF, tail: float = 0.0
) -> tuple[dict, np.ndarray, tuple[int, list[int]]]:
    """{node's s from the first corner's top [m] (rounded to 1e-9): its contact force [N]} of
    D3 (the pair on leg 2) and of leg 2's nodes (pairs on leg 1, or on the plane), and the
    levels of the pressed pairs whose slave carries another pressed pair's reaction, over
    the ranks of ``comm``; the rank that owns the last pressed slave along s (D3) and those
    that own a carrying one."""
    result = static_path(scene_from_dict(stack(P, rigid, tail)), comm=comm, write_outputs=False)
    model = result.model
    x = model.V.tabulate_dof_coordinates()[:, 0] * model.length
    x -= 0.0 if rigid is None else ZL1 + H
    pairs = model.contact.pairs
    r = pairs._rows
    forces = {
        round(float(x[a]), 9): float(f) * pairs.force_scale
        for a, f in zip(r["local"], r["fN"], strict=True)
    }
    obstacles = model.contact.obstacles
    if obstacles is not None:
        on = np.flatnonzero(obstacles.state != 0)
        for a, f in zip(obstacles.blocks[on], obstacles._rows["fN"][on], strict=True):
            forces[round(float(x[a]), 9)] = float(f) * obstacles.force_scale
    forces = {k: v for part in comm.allgather(forces) for k, v in part.items()}
    carried = np.concatenate(comm.allgather(r["partner"][np.abs(r["weights"]) > 0.0]))
    carrying = np.isin(r["local"] + pairs.start, carried)
    levels = np.concatenate(comm.allgather(r["level"][carrying]))
    last = comm.allgather(float(x[r["local"]].max(initial=-np.inf)))
    carriers = [rank for rank, any_ in enumerate(comm.allgather(bool(carrying.any()))) if any_]
    return forces, levels, (int(np.argmax(last)), carriers)


def test_a_chain_of_contacts_passes_the_reaction_on_as_the_rod_on_a_plane():
    """Three parts stacked (the scene :func:`stack`), P = 800 N at D3: D3 presses on leg 2,
    whose nodes press on leg 1 there, one of them in D3's partner cell (a chain: it carries
    D3's reaction and presses, level 1). With leg 1 and its corner 1e7 times stiffer than leg
    2, leg 2 is clamped at the corner's top and lies over leg 1's top as over a plane: the
    same rod from there on the plane z = r (D3 on leg 2 by the pair rows, leg 2 on the plane
    by the obstacles' rows, which read the pair's reaction: no chain) must give the same
    forces. They differ by leg 1's compliance only, relative O(1/factor): measured at the
    factors 1e6 and 1e7 1.0e-6 and 1.0e-7 of the largest force at leg 2's nodes (tolerance
    10/factor = 1e-6), 2.4e-8 and 2.4e-9 at D3 (tolerance 1e-7). Rows that took the assembled
    F_a for F̃_a (all pairs in one level) give a leg-2 node −797 N, pulling: 0.19 of the
    largest off, and D3 7e-4."""
    chain, carrying, _ = stacked_forces(800.0, 1e7)
    plane, _, _ = stacked_forces(800.0, None)
    assert carrying.size and carrying.min() >= 1, carrying
    end = max(chain)
    assert abs(chain.pop(end) / plane.pop(max(plane)) - 1) < 1e-7
    assert chain.keys() == plane.keys() and len(chain) >= 2, (chain, plane)
    largest = max(plane.values())
    assert all(abs(chain[x] - plane[x]) < 1e-6 * largest for x in chain), (chain, plane)


_CHAIN_SCRIPT = """
import json, sys
sys.path.insert(0, {tests!r})
from mpi4py import MPI
from test_self_contact import stacked_forces
forces, carrying, (end, carriers) = stacked_forces(800.0, 1e7, MPI.COMM_WORLD, tail=1.0)
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps({{"forces": sorted(forces.items()), "carrying": carrying.tolist(),
                      "end": end, "carriers": carriers}}))
"""


@pytest.mark.long
@pytest.mark.mpi
def test_a_chain_of_contacts_under_mpirun_equals_serial(tmp_path):
    """The three parts stacked of the test above, with a tail of 1 m going on straight up
    from D3 and loaded at its end (:func:`stack`), under mpirun -n 2: the rod is dealt in two
    halves along s, so D3 lies on the second rank and the middle part's nodes under it,
    which carry D3's reaction and press on leg 1, on the first (asserted: a partition that
    moved would fail here, not pass untested): the reaction crosses the ranks from one level
    to the next by PETSc's assembly, in the residual and in the Jacobian. The same carrying
    nodes and levels, and forces equal to the serial ones to 1e-9 of the largest (the same
    Newton iterates; MUMPS against PETSc's LU: round-off 1e-12 of the rows times the
    condition of the iterations; measured 1.7e-12 to 6.5e-12 on 2 to 5 ranks without the
    tail)."""
    from pathlib import Path

    text = _CHAIN_SCRIPT.format(tests=str(Path(__file__).parent))
    serial, parallel = script_serial_and_mpi(tmp_path / "stack.py", text)
    assert parallel["end"] not in parallel["carriers"] and parallel["carriers"], parallel
    assert sorted(serial["carrying"]) == sorted(parallel["carrying"])
    assert serial["carrying"] and min(serial["carrying"]) >= 1
    one, two = dict(serial["forces"]), dict(parallel["forces"])
    assert one.keys() == two.keys()
    largest = max(one.values())
    assert all(abs(one[k] - two[k]) < 1e-9 * largest for k in one), (one, two)


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


@pytest.mark.parametrize("friction", [0.0, 0.5])
def test_a_solve_starts_from_the_accepted_contact_set(friction):
    """The hairpin's free leg turned down onto leg 1, 0.01 r through at its end D: the pairs
    of its last fifth press and are accepted. Moved back to 1e-4 r apart at D, the test opens
    them at an iterate, but not at a Newton solve's first (``first_iterate``): there the
    slaves pressed at the accepted state press whatever their test (the predictor's gaps
    decide it; on the thin plectoneme's ply it opened most pairs at once), in their accepted
    stick/slip state (with friction: not the slip their negative pressure would give, which
    makes the next iterate read μ_k), and such an iterate is not converged (the solve's
    hold); the iterate after is tested again. ``NewtonSolver.solve`` marks its first iterate
    and clears the mark after."""
    from cosserat_fem.analysis.statics import static_solver
    from cosserat_fem.nls.contact import FREE, STICK
    from cosserat_fem.rod.model import build_model

    r = 0.0245
    delta0, _ = closure(r)
    data = hairpin(0.0, r)
    data["contact"]["static_friction"] = friction
    scene = scene_from_dict(data)
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    contact, pairs = solver.contact, solver.contact.pairs
    bs, ell = model.layout.size, model.length
    s = model.V.tabulate_dof_coordinates()[:, 0] * ell
    z = model.layout.index(2)
    ramp = np.clip((s - L1 - H) / L2, 0.0, None)  # 0 at the corner, 1 at the free end

    def moved(depth: float) -> int:
        model.U.x.array[:] = 0.0
        model.U.x.array[z::bs] -= ramp * (delta0 + depth) / ell
        solver._residual()
        return pairs.count()

    through = moved(0.01 * r)  # the nodes of the leg's last fifth: (δ0 + 0.01 r) a/L2 > δ0
    assert through >= 2
    contact.accept(model.U.x.array)
    slaves = pairs.accepted[:, 0]
    stuck = pairs.node_accepted[slaves] == STICK  # frictionless: all SLIP (free to slide)
    assert stuck.any() == (friction > 0) and (pairs.node_accepted[slaves] != FREE).all()
    assert moved(-1e-4 * r) == 0
    contact.first_iterate(True)
    assert moved(-1e-4 * r) == through and pairs.least_gap > 0.0
    assert (pairs.node_state[slaves] == pairs.node_accepted[slaves]).all()
    contact.first_iterate(True)  # the same pairs as the iterate before, against their test:
    assert moved(-1e-4 * r) == through and solver._state.hold == 1  # not converged there
    assert moved(-1e-4 * r) == 0
    marks = []
    original = pairs.first_iterate
    pairs.first_iterate = lambda first, **kw: marks.append(first) or original(first, **kw)
    model.U.x.array[:] = 0.0
    contact.accept(model.U.x.array)  # at rest: nothing pressed, converged at once
    solver.solve()
    assert marks == [True, False] and not pairs.first


def jacobian_errors(
    data: dict, displace, history=None, planar: bool = True
) -> tuple[dict, np.ndarray, np.ndarray]:
    """The Jacobian of the rows against central differences of the residual with its rows, on
    the scene ``data`` at a state ``displace(ux, uz, s, ℓ)`` sets (in place, on the scaled
    displacements along e1 and e3 at the nodes' arc lengths s [m]) plus a random 1e-7, the
    friction's history at ``history(ux, s, ℓ)`` of the state if given (else at rest), each
    node's c held at a random value in [1e6, 2e6] (so that a slave given another's shows).
    The differences move neither the supports' dofs nor, if ``planar``, the out-of-plane
    positions (n keeps n_y = 0 and the tangent basis its branch: T jumps where two of |n|'s
    components cross; in the plane the slip rows' c dΔ lies along s and is projected out,
    so the c term is checked by a mix-up of slaves, not by its size; ``planar`` false: the
    displacements along e2 random too, and ``displace`` gets them as a fifth argument, for
    a state whose normal stays away from such a crossing). Errors on the rows the pairs write (the
    slaves' tangential rows) and add to (the partners'), relative to their largest, at
    ε = 1e-6 and 1e-7; the active pairs and their levels (the pairs and states must not
    change within ±ε)."""
    from cosserat_fem.analysis.statics import static_solver
    from cosserat_fem.rod.model import build_model

    scene = scene_from_dict(data)
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    pairs = solver.contact.pairs
    bs, ell = model.layout.size, model.length
    s = model.V.tabulate_dof_coordinates()[:, 0] * ell
    x, y, z = (model.layout.index(k) for k in range(3))
    rng = np.random.default_rng(2)
    u0 = rng.normal(size=model.U.x.array.size) * 1e-7
    c = 1e6 * (1.0 + rng.random(pairs.owned))  # each slave's own (P.3): a mix-up shows
    if planar:
        displace(u0[x::bs], u0[z::bs], s, ell)
        u0[y::bs] = 0.0
    else:
        displace(u0[x::bs], u0[z::bs], s, ell, u0[y::bs])
    held = np.concatenate([bc.dof_indices()[0] for bc in model.bcs])
    u0[held] = 0.0

    def rows(u):
        model.U.x.array[:] = u
        pairs.c = c
        solver._residual()
        return solver.b.array.copy(), pairs.active.copy()

    if history is not None:
        past = u0.copy()
        history(past[x::bs], s, ell)
        past[held] = 0.0
        pairs.x_old = pairs.everywhere(past)
    _, active = rows(u0)
    solver._assemble_jacobian()
    v = rng.normal(size=u0.size)
    v[held] = 0.0
    if planar:
        v[y::bs] = 0.0
    xv, yv = solver.A.createVecs()
    xv.array[:] = v
    solver.A.mult(xv, yv)
    slaves = pairs.pq[active[:, 0] - pairs.start][:, 1:].ravel()
    partners = pairs.pq[np.unique(pairs._rows["partner"])].ravel()
    errors: dict = {"slaves": [], "partners": []}
    for eps in (1e-6, 1e-7):
        (plus, a_plus), (minus, a_minus) = rows(u0 + eps * v), rows(u0 - eps * v)
        assert np.array_equal(a_plus, active) and np.array_equal(a_minus, active)
        error = np.abs((plus - minus) / (2 * eps) - yv.array)
        for name, where in (("slaves", slaves), ("partners", partners)):
            errors[name].append(error[where].max() / np.abs(yv.array[where]).max())
    return errors, active, pairs._rows["level"]


def assert_second_order(errors: dict) -> None:
    """The errors of :func:`jacobian_errors` are O(ε²): from ε = 1e-6 to 1e-7 they fall
    30-300× (100 expected), unless below 1e-9 already, and are below 1e-6 at 1e-7, far below
    a missing term's O(1)."""
    for name, (coarse, fine) in errors.items():
        assert fine < 1e-6 and (coarse < 1e-9 or 30 < coarse / fine < 300), (name, errors)


@pytest.mark.parametrize("state", ["slip", "stick", "frictionless"])
def test_the_pair_rows_jacobian_is_the_derivative_of_the_rows(state):
    """:func:`jacobian_errors` on the hairpin with friction (μ_s = 0.3, μ_k = 0.2) or without:
    the free leg turned down through leg 1 by 1 cm at its end (about twenty slaves pressed,
    their partners' rows receiving) and moved along it by 7 mm (no slave over a vertex of leg
    1, where the nearest cell would switch), since the friction's history (slip: the trial
    force c Δ beyond the cone) or hardly (stick: the history at the state but for the
    partners 0.01 mm off along the leg, unevenly within their cells, so that Σ Δu_j dN_j
    counts); the partners move too, unevenly within their cells. Second order
    (:func:`assert_second_order`)."""
    r = 0.0245
    delta0, _ = closure(r)
    data = hairpin(0.0, r)
    if state != "frictionless":
        data["contact"].update(static_friction=0.3, kinetic_friction=0.2)

    def displace(ux, uz, s, ell):
        uz -= np.clip((s - L1 - H) / L2, 0.0, None) * (delta0 + 0.01) / ell
        ux += np.where(s > L1 + H, 0.007 / ell, 0.0)  # no slave above a partner's vertex
        # the partners move too, unevenly within their cells (else Σ Δu_j dN_j = 0)
        ux -= np.where(s < L1, 0.003 * np.sin(40 * np.pi * s) / ell, 0.0)

    def history(ux, s, ell):  # the partners 0.01 mm off, unevenly
        ux += np.where(s < L1, 1e-5 * np.sin(40 * np.pi * s) / ell, 0.0)

    errors, active, _ = jacobian_errors(data, displace, history if state == "stick" else None)
    assert len(active) >= 10 and set(active[:, 2]) == {2 if state != "stick" else 1}, active
    assert_second_order(errors)


@pytest.mark.parametrize("friction", [False, True])
def test_the_jacobian_of_a_chain_is_the_derivative_of_its_rows(friction):
    """:func:`jacobian_errors` on the three parts stacked (:func:`stack`, all of leg 2's
    stiffness but leg 3's, μ_s = 0.3, μ_k = 0.2 or frictionless): leg 2 and what follows
    pushed 5 mm through leg 1 and moved 7 mm along it (no node over a vertex of leg 1: the
    same cells), leg 3 another 5 mm through leg 2, so that leg 3's nodes press on leg 2
    (level 0) and leg 2's under them on leg 1 carrying their reactions (level 1: a chain,
    (P.5)), with friction leg 2's sliding on leg 1 (7 mm since the history at rest) and leg
    3's sticking on leg 2. A level's rows then differ with the positions of the level
    before's pairs through the reactions passed on; those columns reach the rows by the
    matrix's assembly between levels. Second order (:func:`assert_second_order`)."""
    data = stack(0.0, 0.0)
    if friction:
        data["contact"].update(static_friction=0.3, kinetic_friction=0.2)
    start, rise = ZL1 + H, math.sqrt(0.05**2 - SLANT**2)

    def displace(ux, uz, s, ell):
        uz -= np.where(s > start, (H - 2 * ZR + 0.005) / ell, 0.0)
        uz -= np.where(s >= start + ZL2 + 0.05, (rise - 2 * ZR + 0.005) / ell, 0.0)
        ux += np.where(s > start, 0.007 / ell, 0.0)

    errors, active, levels = jacobian_errors(data, displace)
    assert (levels == 1).sum() >= 3 and (levels == 0).sum() >= 3, levels
    assert levels.max() == 1
    if friction:
        assert set(active[:, 2]) == {1, 2}, active
    assert_second_order(errors)


def test_the_matrix_pattern_stays_bounded_as_the_pairs_move_along_the_rod():
    """The pairs' entries stay in the matrix's pattern once inserted; a solver renews its
    matrix when they have grown past twice what a fresh matrix's first contact rows needed
    (NewtonSolver._renew_pattern). The hairpin's free leg pushed 5 mm through leg 1 and slid
    along it in 16 states 5 cm apart (its ~50 slaves' partners a cell further each time):
    the contact entries never exceed that bound plus one state's need (without renewals they
    would grow by a state's need each time: 16 times), the matrix is renewed at least three
    times, and at the last state the renewed matrix gives the same J v as a fresh solver's
    (1e-12 of its largest: the same entries, summed in another order at most)."""
    from cosserat_fem.analysis.statics import static_solver
    from cosserat_fem.rod.model import build_model

    r = 0.0245
    delta0, _ = closure(r)

    scene = scene_from_dict(hairpin(0.0, r))
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    bs, ell = model.layout.size, model.length
    s = model.V.tabulate_dof_coordinates()[:, 0] * ell
    x, z = model.layout.index(0), model.layout.index(2)
    held = np.concatenate([bc.dof_indices()[0] for bc in model.bcs])

    def state(shift: float) -> np.ndarray:
        u = np.zeros(model.U.x.array.size)
        leg = s > L1 + H
        u[z::bs] -= np.where(leg, (delta0 + 0.005) / ell, 0.0)
        u[x::bs] += np.where(leg, shift / ell, 0.0)
        u[held] = 0.0
        return u

    def jacobian(solver, u) -> None:
        solver.U.x.array[:] = u
        solver.contact.pairs.c = np.full(solver.contact.pairs.owned, 1e6)
        solver._residual()
        solver._assemble_jacobian()

    needs = []
    for shift in 0.007 + 0.05 * np.arange(16):
        jacobian(solver, state(shift))
        p = solver._pattern
        needs.append(p["need"])
        assert len(solver.contact.pairs.active) >= 40
        assert p["extra"] <= max(2 * p["need"], p["base"] // 10) + max(needs), (shift, p)
    assert solver._pattern["renewals"] >= 3
    assert solver.ksp.getOperators()[0].handle == solver.A.handle  # the KSP solves with it
    model.U.x.array[:] = 0.0  # a solver starts from a state not through itself
    fresh = static_solver(scene, model)
    jacobian(fresh, state(shift))
    v = np.random.default_rng(1).normal(size=model.U.x.array.size)
    products = []
    for one in (solver, fresh):
        xv, yv = one.A.createVecs()
        xv.array[:] = v
        one.A.mult(xv, yv)
        products.append(yv.array.copy())
    assert np.abs(products[0] - products[1]).max() < 1e-12 * np.abs(products[1]).max()


# Friction between the parts: the hairpin whose long leg and corner are 1e6 times stiffer than
# its free leg (a section varying along s), so that the free leg is a cantilever of length L2
# clamped at the corner and its end D presses on a rigid leg. EI, EA, κGA of the free leg:
STIFF = (100.0, 1.0e4, 1.0e6)  # N m², N, N


def rigid_hairpin(Px: float, Pz: float, r: float, mu: float) -> dict:
    """The hairpin above with friction μ between its parts, the free end loaded by (Px, 0,
    −Pz) (Px along e1, back towards the corner: along the free leg), in four load steps."""
    EI, EA, GA = STIFF
    factor = f"(1 + 1e6*heaviside({L1 + H!r} - s))"  # the long leg and the corner
    diagonal = [GA, GA, EA, EI, EI, EI / 1.3]
    data = hairpin(0.0, r)
    data["rod"]["section"]["stiffness"] = [
        [f"{k!r}*{factor}" if i == j else 0 for j in range(6)] for i, k in enumerate(diagonal)
    ]
    data["loads"] = {"end": {"force": [Px, 0, -Pz]}}
    data["static"] = {"load_steps": 4}
    data["contact"].update(static_friction=mu)
    return data


@pytest.mark.parametrize("slides", [False, True])
def test_friction_between_the_parts_sticks_and_slides_as_the_closed_form(slides):
    """The free leg, a cantilever (c2 = L2³/3EI + L2/κGA), is pressed on the rigid leg by Pz =
    2 δ0/c2 (contact from the load factor λ_c = 1/2 on: R = Pz − δ0/c2) and pulled along it by
    Px. Proportional loading: after contact the pair must carry (λ − λ_c) Px against at most
    μ (λ − λ_c) Pz, so it sticks for all λ if Px < μ Pz, and slides from the contact on if
    Px > μ Pz. Stick: the end moves along the leg only before the contact, u = λ_c Px L2/EA
    + 3δ0²/(5 L2) (the bent cantilever's end comes back by ∫ w'²/2: 1.2 % of u here), and the
    pair carries T = (1 − λ_c) Px < μ R. Slide: |P F| = μ f_N (to the Newton tolerance),
    T = μ R and u = (Px − μ R) L2/EA + 3δ0²/(5 L2). Tolerances 1e-3: the linear theory's
    O(δ0/L2) = 1e-4 (δ0 = 1e-4 m), the beam-column coupling Px L2²/EI ≈ 1e-4, the legs' 1e-6
    compliance (measured: R 2e-5 and 7.6e-5, T 4e-5 and 7.6e-5, slip u 2.3e-4); the stuck u
    3e-3, as it is set by where the contact starts, λ_c, whose O(δ0/L2) error it takes
    relative to λ_c (measured 7.9e-4). A stick that crept or a slip force wrong by μ would
    miss by O(1).

    The work friction dissipated (summary.json's pair_friction_work_J) is counted a load
    step at a time as the step's T times its slip: over the steps λ = 3/4 and 1 (the 4 load
    steps; sliding from λ_c = 1/2), with R_k = (λ_k − λ_c) Pz and the slip Δu_k = (Px/4 −
    μ ΔR_k) L2/EA, W = Σ μ R_k Δu_k = (3/32) μ² Pz² L2/EA (Px = 1.5 μ Pz). Tolerance 1e-3
    as above (measured 1.7e-4; 2.2e-5 at δ0 = 1e-5: the linear theory's O(δ0/L2)); the
    integral ∫ μ R du instead of the steps' sum, (1/16) μ² Pz² L2/EA, would miss by a third."""
    EI, EA, GA = STIFF
    r, mu = 0.02495, 0.3
    delta0 = H - 2 * r
    c2 = L2**3 / (3 * EI) + L2 / GA
    Pz = 2 * delta0 / c2
    Px = (1.5 if slides else 0.5) * mu * Pz
    result = static_path(
        scene_from_dict(rigid_hairpin(Px, Pz, r, mu)), comm=MPI.COMM_SELF, write_outputs=False
    )
    model = result.model
    pairs = model.contact.pairs
    rows = pairs._rows
    assert len(rows["local"]) == 1 and rows["state"][0] == (2 if slides else 1)
    force = rows["F"][0] * pairs.force_scale  # the whole force on the end (its x, z parts)
    # the push up, and the force along e1 (against Px: the pair holds the end back)
    normal, along = force[pairs.solved.index(2)], -force[pairs.solved.index(0)]
    R = Pz - delta0 / c2
    shortening = 3 * delta0**2 / (5 * L2)  # the bent leg's end comes back by ∫ w'²/2
    bs = model.layout.size
    end = np.argmax(model.V.tabulate_dof_coordinates()[:, 0])
    u = model.U.x.array[end * bs + model.layout.index(0)] * model.length
    assert abs(normal / R - 1) < 1e-3
    if slides:  # the rows' |P F| = μ_k f_N to the Newton tolerance, along e1 to the tilt
        n, F = rows["n"][0], rows["F"][0]
        tangential = F - (n @ F) * n
        assert abs(np.linalg.norm(tangential) / (mu * (n @ F)) - 1) < 1e-9
        assert abs(along / (mu * R) - 1) < 1e-3
        assert abs(u / ((Px - mu * R) * L2 / EA + shortening) - 1) < 1e-3
        work = model.contact.summary()["pair_friction_work_J"]
        assert abs(work / (3 / 32 * mu**2 * Pz**2 * L2 / EA) - 1) < 1e-3
    else:
        assert abs(along / (0.5 * Px) - 1) < 1e-3 and along < mu * R
        assert abs(u / (0.5 * Px * L2 / EA + shortening) - 1) < 3e-3


def test_a_hairpin_shut_in_time_lands_by_midpoint_steps_and_stays_shut():
    """The hairpin (δ0 = 1e-3 m) loaded at once by P = 3 P_c at its free end, in time (BDF2,
    h = 2 ms, 0.2 s; Kelvin-Voigt τ = 5 ms so that it settles): its end swings onto leg 1
    within the first half period. The landing step is
    redone by the midpoint rule (summary.json impact_steps_redone ≥ 1: the pairs report their
    landings as the obstacles do), the pair is shut at the end, and no node went through
    (least gap ≥ −1e-12 δ0: the row holds g = 0 at the node)."""
    from cosserat_fem import api

    r = 0.0245
    delta0, C = closure(r)
    data = hairpin(3 * delta0 / C, r)
    data["time"] = {"end": 0.2, "step": 0.002, "integrator": "bdf2"}
    data["damping"] = {"retardation_time": 0.005}
    data["output"] = {"xdmf": False}
    result = api.run(scene_from_dict(data))
    assert result.summary["impact_steps_redone"] >= 1
    contact = result.summary["contact"]
    assert contact["pairs_in_contact"] == 1
    assert contact["least_pair_gap_m"] >= -1e-12 * delta0


def test_the_contact_field_carries_the_pairs_with_obstacles_too():
    """With an obstacle besides (a plane far below), the outputs' contact field is both rows'
    (Contacts.values): at the pressed end the pair's load R over the node's share of the
    length, along +e3 (frictionless: state 2, sliding), to the Newton tolerance; nothing where
    the obstacle touches nothing."""
    r = 0.0245
    delta0, C = closure(r)
    data = hairpin(2 * delta0 / C, r)
    data["contact"]["obstacles"] = [{"kind": "plane", "point": [0, 0, -1], "normal": [0, 0, 1]}]
    result = static_path(scene_from_dict(data), comm=MPI.COMM_SELF, write_outputs=False)
    contact = result.model.contact
    values = contact.values.x.array.reshape(-1, 6)
    pairs = contact.pairs
    end = pairs._rows["local"][0]
    R = pairs._rows["fN"][0] * pairs.force_scale
    assert values[end, 2] == pytest.approx(R / pairs.shares[end], rel=1e-9)
    assert values[end, 4] == 2.0
    others = np.delete(np.arange(len(values)), end)
    assert np.all(values[others, :3] == 0.0) and np.all(values[others, 4] == 0.0)


_FRICTION_SCRIPT = """
import json, sys
sys.path.insert(0, {tests!r})
from mpi4py import MPI
from test_self_contact import rigid_hairpin, STIFF, H, L2
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.scene.build import scene_from_dict
EI, EA, GA = STIFF
r, mu = 0.02495, 0.3
delta0 = H - 2 * r
Pz = 2 * delta0 / (L2**3 / (3 * EI) + L2 / GA)
result = static_path(scene_from_dict(rigid_hairpin(1.5 * mu * Pz, Pz, r, mu)),
                     comm=MPI.COMM_WORLD, write_outputs=False)
summary = result.model.contact.summary()
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(summary))
"""


@pytest.mark.long
@pytest.mark.mpi
def test_friction_between_the_parts_under_mpirun_equals_serial(tmp_path):
    """The sliding case of the friction test under mpirun -n 2: the end and its partner on
    different ranks, every rank in the counters' sums (a rank without a slave once skipped
    them and mpirun hung). The friction's work equals serial to 1e-9 relative (MUMPS
    against PETSc's LU: round-off; measured 1.3e-11). The impacts' part to 1e-6 of itself:
    it is the landing step's R times the gap the end still closes in it (the contact starts
    a little after λ_c = 1/2: some 6e-9 m, O(δ0²/L2)), 1.2e-10 J, 2 % of the friction's;
    so small a gap is set where the Newton iterations stop, by their tolerance rather than
    by round-off (measured 2.9e-8 apart)."""
    from pathlib import Path

    text = _FRICTION_SCRIPT.format(tests=str(Path(__file__).parent))
    serial, parallel = script_serial_and_mpi(tmp_path / "friction.py", text)
    assert serial["pairs_in_contact"] == parallel["pairs_in_contact"] == 1
    for key, bound in (("pair_friction_work_J", 1e-9), ("pair_impact_loss_J", 1e-6)):
        assert serial[key] > 0 and abs(parallel[key] / serial[key] - 1) < bound, key


def test_generalized_alpha_keeps_its_rate_after_a_landing_on_the_rod(monkeypatch):
    """Generalized-α (ρ∞ = 0.5) restarts after the midpoint steps of a landing by solving a
    consistent rate, which holds the nodes resting on obstacles but not a slave pressed on
    the rod: that rate would accelerate the pressed end into its partner (measured: its
    vertical acceleration turned from −0.054 to +2.69 at the restart). With a pair pressed
    (Contacts.holds_rates False) the restart keeps the midpoint steps' rate: the rates before
    and after each restart are the same numbers, and the hairpin stays shut."""
    from cosserat_fem import api
    from cosserat_fem.timestepping.integrators import GeneralizedAlpha

    seen = []
    restart = GeneralizedAlpha.restart

    def recording(self, problem, lu_package):
        before = self._arrays[2].copy()
        restart(self, problem, lu_package)
        seen.append((problem.contact.holds_rates(), before, self._arrays[2].copy()))

    monkeypatch.setattr(GeneralizedAlpha, "restart", recording)
    r = 0.0245
    delta0, C = closure(r)
    data = hairpin(3 * delta0 / C, r)
    data["time"] = {"end": 0.08, "step": 0.002, "integrator": "generalized-alpha", "rho_inf": 0.5}
    data["damping"] = {"retardation_time": 0.005}
    data["output"] = {"xdmf": False}
    result = api.run(scene_from_dict(data))
    assert result.summary["contact"]["pairs_in_contact"] == 1
    pressed = [(before, after) for holds, before, after in seen if not holds]
    assert pressed and all(np.array_equal(b, a) for b, a in pressed)


def test_a_geometry_that_fails_is_a_retried_error_not_a_traceback():
    """A non-finite iterate (a NaN position: every gap would be NaN, never pressed, the
    contact silently lost) is a SolverError where = contact naming s, retried by a smaller
    step, the same on every rank (every rank searches the same gathered positions); so is a
    closest point that does not converge (contact_search's FloatingPointError)."""
    from cosserat_fem.analysis.statics import static_solver
    from cosserat_fem.common.errors import SolverError
    from cosserat_fem.rod.model import build_model

    scene = scene_from_dict(hairpin(0.0, 0.0245))
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    model.U.x.array[model.layout.index(2)] = np.nan  # a diverged iterate
    with pytest.raises(SolverError, match=r"^contact: self contact: ") as e:
        solver._residual()
    assert e.value.retry


def test_an_iterate_that_moves_a_node_3_lengths_is_a_retried_error():
    """A diverging solve's iterate (positions growing geometrically, each rebuilding the
    search) stops as soon as a node lies more than 3 ℓ from the accepted state relative to the
    nodes' mean motion: a retried SolverError naming the node's s and the distance; just below
    3 ℓ the residual is taken, and so is the whole rod moved 10 ℓ (a free rod's flight: no
    node moves more than 2 ℓ (1 + ε) relative to the mean, pair_contact.DIVERGED)."""
    from cosserat_fem.analysis.statics import static_solver
    from cosserat_fem.common.errors import SolverError
    from cosserat_fem.nls.pair_contact import DIVERGED
    from cosserat_fem.rod.model import build_model

    scene = scene_from_dict(hairpin(0.0, 0.0245))
    model = build_model(scene, MPI.COMM_SELF)
    solver = static_solver(scene, model)
    ell, y = model.length, model.layout.index(1)
    end = int(np.argmax(model.V.tabulate_dof_coordinates()[:, 0]))  # s = ℓ: D
    u, bs = model.U.x.array, model.layout.size
    count = len(u) // bs
    mean = 1.0 / count  # the mean of one node's shift over the count nodes
    u[end * bs + y] = 0.99 * DIVERGED / (1 - mean)  # scaled by ℓ: just within (across)
    solver._residual()
    u[y::bs] += 10.0  # the whole rod 10 ℓ across besides: a flight, no divergence
    solver._residual()
    u[y::bs] -= 10.0
    u[end * bs + y] = 1.01 * DIVERGED / (1 - mean)
    moved = r"^contact: self contact: an iterate moved the node at s = 1\.95 m"
    with pytest.raises(SolverError, match=moved) as e:
        solver._residual()
    assert e.value.retry and f"{1.01 * DIVERGED * ell:.3g} m" in str(e.value)
    assert "\n" not in str(e.value)
