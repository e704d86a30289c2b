"""Contact on a structure (issue 30; docs/contact.md, "Contact on a structure"): members
pressed on one another and onto an obstacle, against the linear frame's closed forms.

**Two crossing cantilevers.** Member A runs along e1 from its clamp R1 = 0 through the
crossing point X = (a, 0, 0) to its free end (L, 0, 0); member B along e2 from its clamp
R2 = (a, −b, h) over X to its free end (a, L − b, h), h = 2r + δ0: their tubes of radius r
cross at a right angle δ0 apart. A third member, the link R1-R2, keeps the structure one
(both its ends clamped and nothing on it: it stays at rest). A force P down at B's tip
presses B onto A at X once B's deflection there reaches δ0. With the Timoshenko cantilever's
deflection at x under a unit force at ξ ≥ x,

    c(x, ξ) = x² (3ξ − x)/(6 EI) + x/(κGA),                                        (X.1)

B's node over X sinks by P c(b, L) − R c(b, b) and A's node at X by R c(a, a) (A's part
beyond X carries nothing), so B touches at P_c = δ0/c(b, L) and beyond it the contact carries

    R = (P c(b, L) − δ0) / (c(b, b) + c(a, a))                                      (X.2)

(their sections circles: no coupling of the two bending planes, no twist). The same with a
spherical joint at X whose copy is A's inner half's (A's outer half keeps the node) and A's
end pinned: a link with moment-free ends and no load between them carries no transverse
force in the linear theory, so (X.2) holds unchanged. The pair's partner cell is then the
inner half's last, which holds the copy: the cells carry the copy's master instead
(cosserat_fem/rod/obstacles.py), so the reaction reaches the master's balance rows, which
the joint's (C.1) made the node's whole (without that the copy, a node of its own at X, sits
on the outer half's centreline, and the scene is refused as starting through itself).

The linear frame is exact for the P3 elements when the loads sit at vertices (moments linear
along each cell; tests/test_self_contact.py measured the same), and X is a vertex of both
members, so the reaction's error is the geometric nonlinearity's, O(δ0/L) relative, as the
hairpin's (tests/test_self_contact.py); measured: 2.6e-5, 6.3e-6 and 6.7e-7 at δ0 = 1e-3,
1e-4 and 1e-5 m (L = 1 m; the last two in proportion). Bounds 1.5e-5 and 1.5e-6 at the last
two: about twice the measured and proportional to δ0 (a defect of the rows, a reaction or a
gap wrong by a fraction of itself, would not shrink with δ0). With the joint the pinned link
adds a term of its own: A's inner half, bent by w_A = R c(a, a), draws X in by
3 w_A²/(5a), which the link resists with N = EA 3 w_A²/(5a)/(L − a), whose vertical part
N w_A/(L − a) adds to R: 2.0e-3 of R at δ0 = 1e-3 m (measured 2.03e-3), (δ0)² smaller at
1e-4 m, 2.0e-5, plus the 6e-6 above (measured 2.7e-5): bound 5e-5.

**A portal frame on a plane.** A column clamped at its foot A = 0 rises to B = (0, 0, H), a
beam runs to C = (W, 0, H) (rigid corners), a column comes down to the foot D = (W, 0, 0),
whose tube rests on the plane z = −r (the gap 0 at rest, frictionless: a roller). A force P
down at the beam's middle M presses D onto the plane; by the unit-load method (a unit force
up at D: the right column's axial force 1, the beam's moment W − s and shear 1, the left
column's moment W and axial force 1),

    c_DD = W³/(3 EI) + W/κGA + W² H/EI + 2H/EA,
    c_DM = (x² W/2 − x³/6)/EI + x/κGA + x W H/EI + H/EA   (x = W/2),                (P.3)

and the plane pushes D up with R = P c_DM/c_DD (one redundant). Its error is the linear
theory's, O(w/L), w the deflections over the frame's size.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import script_serial_and_mpi
from mpi4py import MPI

from cosserat_fem.analysis.statics import static_path
from cosserat_fem.rod.contact_search import reference_nodes
from cosserat_fem.rod.self_contact import Members, SelfContactGeometry
from cosserat_fem.scene.build import scene_from_dict

L, A_AT, B_AT, R = 1.0, 0.5, 0.5, 0.01
E, NU, KAPPA = 2.0e9, 0.3, 0.9
AREA, INERTIA = math.pi * R**2, math.pi * R**4 / 4
EI, EA, GA = E * INERTIA, E * AREA, KAPPA * E / (2 * (1 + NU)) * AREA


def c(x: float, xi: float) -> float:
    """(X.1): a cantilever's deflection [m/N] at x under a unit force at ξ ≥ x."""
    return x**2 * (3 * xi - x) / (6 * EI) + x / GA


def material() -> dict:
    return {
        "section": {"shape": "circle", "diameter": 2 * R, "shear_coefficient": KAPPA},
        "material": {"density": 1000.0, "young_modulus": E, "poisson_ratio": NU},
    }


def crossing(P: float, delta0: float, joint: bool = False) -> dict:
    """The crossing cantilevers of the module docstring (cells of 0.25 m: X a vertex of both);
    ``joint``: A's outer half on a spherical joint at X, pinned at its end."""
    h = 2 * R + delta0
    nodes = [
        {"name": "R1", "position": [0, 0, 0]},
        {"name": "X", "position": [A_AT, 0, 0]},
        {"name": "TA", "position": [L, 0, 0]},
        {"name": "R2", "position": [A_AT, -B_AT, h]},
        {"name": "TB", "position": [A_AT, L - B_AT, h]},
    ]
    members = [
        {"name": "A1", "from": "R1", "to": "X", "elements": 2},
        {"name": "A2", "from": "X", "to": "TA", "elements": 2},
        {"name": "link", "from": "R1", "to": "R2", "elements": 1},
        {"name": "B", "from": "R2", "to": "TB", "elements": 4},
    ]
    supports = [{"node": "R1", "kind": "clamped"}, {"node": "R2", "kind": "clamped"}]
    structure = {
        "nodes": nodes,
        "members": members,
        "supports": supports,
        "loads": [{"node": "TB", "force": [0, 0, -P]}],
    }
    if joint:
        structure["joints"] = [{"node": "X", "kind": "spherical", "members": ["A1"]}]
        supports.append({"node": "TA", "kind": "pinned"})
    return {
        "rod": material(),
        "structure": structure,
        "static": {"load_steps": 1},
        "time": {"end": 1.0, "step": 1.0},
        "discretisation": {"degree": 3},
        "contact": {"self_contact": True},
    }


def pressed(scene: dict, comm=MPI.COMM_SELF) -> tuple[float, dict]:
    """The pairs' contact force [N] (0 if none; summed over the ranks) and summary.json's
    contact entries."""
    result = static_path(scene_from_dict(scene), comm=comm, write_outputs=False)
    pairs = result.model.contact.pairs
    rows = pairs._rows
    force = float(rows["fN"].sum() * pairs.force_scale) if len(rows.get("local", ())) else 0.0
    return comm.allreduce(force), result.model.contact.summary()


@pytest.mark.parametrize(
    ("delta0", "bound", "joint"),
    [(1e-4, 1.5e-5, False), (1e-5, 1.5e-6, False), (1e-4, 5e-5, True)],
)
def test_crossing_cantilevers_carry_the_frames_reaction(delta0, bound, joint):
    """At P = 2 P_c one pair presses (B's node over X on A), its force is (X.2) within
    ``bound`` relative (module docstring: measured 6.3e-6, 6.7e-7 and, with the joint,
    2.7e-5), its gap 0 to 1e-12 δ0 (the row g = 0 solved to the Newton tolerance): no
    penetration; at P = P_c/2 nothing touches and the least gap is δ0 − P c(b, L) = δ0/2
    within 1e-5 relative (the same linear theory; measured 2.2e-8 at δ0 = 1e-4 m)."""
    closing = delta0 / c(B_AT, L)
    force, summary = pressed(crossing(2 * closing, delta0, joint))
    expected = (2 * closing * c(B_AT, L) - delta0) / (c(B_AT, B_AT) + c(A_AT, A_AT))
    assert summary["pairs_in_contact"] == 1
    assert abs(force / expected - 1) < bound
    assert abs(summary["least_pair_gap_m"]) < 1e-12 * delta0
    force, summary = pressed(crossing(0.5 * closing, delta0, joint))
    assert force == 0.0 and summary["pairs_in_contact"] == 0
    assert abs(summary["least_pair_gap_m"] / (0.5 * delta0) - 1) < 1e-5


def guided(a: float) -> float:
    """A cantilever's tip deflection [m/N] under a unit force there, the tip's turn held (a
    `sliding` support along the force): a³/(12 EI) + a/(κGA)."""
    return a**3 / (12 * EI) + a / GA


def sliding_crossing(P: float, delta0: float, reverse: bool) -> dict:
    """The crossing cantilevers with X on a `sliding` support along e3 (its x, y and turn
    held, z free); ``reverse``: B listed first, so that A's nodes would be the slaves on a
    structure's rule (the larger member index)."""
    scene = crossing(P, delta0)
    structure = scene["structure"]
    structure["supports"].append({"node": "X", "kind": "sliding", "axis": [0, 0, 1]})
    if reverse:
        structure["members"] = structure["members"][::-1]
    return scene


@pytest.mark.parametrize("reverse", [False, True])
def test_a_sliding_node_takes_its_free_part_of_the_reaction(reverse):
    """X on a `sliding` support along e3: A's inner half is a cantilever whose tip X moves
    down with its turn held, so under B's force R it sinks by R g(a) (:func:`guided`), and

        R = (P c(b, L) − δ0) / (c(b, b) + g(a))                                     (X.3)

    (A's outer half carries nothing). The pair's partner cell holds X: the reaction's z part
    must reach X's free balance row (its x, y parts the support); dropped there as at a fully
    held node, X would not move and R would be (P c(b, L) − δ0)/c(b, b), 25 % higher. With
    the members reversed, A's nodes at X would be the slaves by the structure's rule; the
    nodes of X's cells are no slaves (rod/self_contact.py), so B's node presses on A there
    too. P = 2 P_c, δ0 = 1e-4 m: the error is the geometric nonlinearity's, here second order
    (X's turn held, the first-order term of the crossing above vanishes): measured −7.66e-6,
    −7.79e-8, −7.79e-10 at δ0 = 1e-3, 1e-4, 1e-5 m, both orders alike to 3e-12. It is a sum
    of terms of either sign: one is A's inner half stretching as it bends between R1 and X
    (both held along e1), N = (3/5) EA w²/a², whose geometric stiffness (6/5) N/a stiffens X
    by 0.24 (w/r)² relative (A/I = 4/r²), w = R g(a) = 0.2 δ0, so R by +1.9e-7; the measured
    −7.8e-8 is what is left after the others. Bound 5e-7 at 1e-4 m (about 2.5× the largest
    term); a reaction part lost or doubled is O(1) (25 % for X's z part)."""
    delta0 = 1e-4
    closing = delta0 / c(B_AT, L)
    scene = sliding_crossing(2 * closing, delta0, reverse)
    result = static_path(scene_from_dict(scene), comm=MPI.COMM_SELF, write_outputs=False)
    pairs = result.model.contact.pairs
    rows = pairs._rows
    assert len(rows["local"]) == 1
    expected = (2 * closing * c(B_AT, L) - delta0) / (c(B_AT, B_AT) + guided(A_AT))
    force = float(rows["fN"][0] * pairs.force_scale)
    assert abs(force / expected - 1) < 5e-7, (force, expected)
    slave = rows["local"][0] + pairs.start
    x = pairs.everywhere(result.model.U.x.array)
    assert np.abs(x[slave, :2] - [A_AT, 0.0]).max() < 1e-6 and x[slave, 2] > R  # B's, over X
    assert np.isin(rows["partner"][0], np.flatnonzero(pairs.held_slots_all[:, 0])).any()


@pytest.mark.parametrize("friction", [False, True])
def test_the_jacobian_at_a_sliding_nodes_cell_is_the_derivative_of_the_rows(friction):
    """tests/test_self_contact.py's ``jacobian_errors`` on the sliding crossing
    (:func:`sliding_crossing`, μ_s = 0.3, μ_k = 0.2 or frictionless): B moved 0.1 m back
    along e1, so that it crosses A inside X's cell (its weights all nonzero), and 5 mm down
    through it; A tilted there by a slope of 0.05 and its nodes moved unevenly along it, so
    that the normal and (with friction, sliding: the history at rest) the force have an x part
    at X, which X's support takes, and a z part, which X's free row gets. Out of the x-z
    plane (not ``planar``): B also moved 7 mm along its axis e2, so that the slip Δ and the
    trial force c Δ have a part across the plane, where the slip rows' c dΔ term shows (in
    the plane it is projected out); n stays near e3, away from a change of T's branch.
    Second order (``assert_second_order``)."""
    from test_self_contact import assert_second_order, jacobian_errors

    from cosserat_fem.rod.model import build_model
    from cosserat_fem.rod.obstacles import contact_rows

    data = sliding_crossing(0.0, 1e-4, reverse=False)
    if friction:
        data["contact"].update(static_friction=0.3, kinetic_friction=0.2)
    # the nodes' rest positions (serial: local order is global)
    model = build_model(scene_from_dict(data), MPI.COMM_SELF)
    x, y, z = contact_rows(model).pairs.everywhere(model.U.x.array).T
    on_b, on_a = z > R, (y == 0.0) & (z == 0.0)

    def displace(ux, uz, s, ell, uy):
        uy += np.where(on_b, 0.007 / ell, 0.0)
        ux -= np.where(on_b, 0.1 / ell, 0.0)
        uz -= np.where(on_b, 0.005 / ell, 0.0)
        uz += np.where(on_a, 0.05 * (x - 0.4) / ell, 0.0)
        ux += np.where(on_a, 0.003 * np.sin(40 * np.pi * x) / ell, 0.0)

    errors, active, _ = jacobian_errors(data, displace, planar=False)
    assert len(active) == 1 and active[0, 2] == 2, active  # one pair, sliding (or frictionless)
    assert_second_order(errors)


def test_a_joints_copy_is_neither_an_obstacle_node_nor_in_a_cell():
    """On the crossing with the joint at X and a plane far below: the joint's copy (its rows
    the joint's, (C.1)-(C.2)) is not among the obstacle's nodes, its master is, and no cell
    of the pairs' search holds the copy (its master's index instead). Serial: local blocks
    are global nodes."""
    scene = crossing(0.5 * 1e-4 / c(B_AT, L), 1e-4, joint=True)
    scene["contact"]["obstacles"] = [{"kind": "plane", "point": [0, 0, -1], "normal": [0, 0, 1]}]
    model = static_path(scene_from_dict(scene), comm=MPI.COMM_SELF, write_outputs=False).model
    (master,), (copy,), _, _ = model.structure.joint_blocks(model.V, model.scene.structure)
    assert copy not in model.contact.obstacles.blocks
    assert master in model.contact.obstacles.blocks
    cells = model.contact.pairs.geometry.dofs
    assert copy not in cells and master in cells


def corner(alpha: float, r: float, h: float, cells: int = 12):
    """Two straight members of ``cells`` P3 cells of length ``h`` leaving J = 0 at the angle
    ``alpha`` (member 0 along e1 from J, member 1 towards J along the direction at alpha from
    e1, so that J is member 0's start and member 1's end): their SelfContactGeometry at rest
    and the positions."""
    xi = reference_nodes(3)
    t1 = np.array([np.cos(alpha), np.sin(alpha), 0.0])
    far = cells * h * t1
    points, dofs = [np.zeros(3)], []
    for m, (start, end) in enumerate(((np.zeros(3), cells * h * np.eye(3)[0]), (far, 0 * far))):
        previous = -1
        for k in range(cells):  # vertices shared along the member and at J (point 0)
            a, b = start + (end - start) * k / cells, start + (end - start) * (k + 1) / cells
            ends = []
            for v, x in ((k, a), (k + 1, b)):
                if (m, v) in ((0, 0), (1, cells)):
                    ends.append(0)
                elif v == k and k > 0:
                    ends.append(previous)
                else:
                    points.append(x)
                    ends.append(len(points) - 1)
            previous = ends[1]
            inner = []
            for q in xi[2:]:
                points.append(a + (b - a) * q)
                inner.append(len(points) - 1)
            dofs.append([*ends, *inner])
    dofs = np.array(dofs)
    x = np.array(points)
    direction = np.array([np.eye(3)[0], -t1])
    starts = np.array([np.zeros(3), far])
    members = Members(np.repeat([0, 1], cells), starts, direction, np.full(2, cells * h), x)
    return SelfContactGeometry(dofs, None, r, 2 * r, members), x


@pytest.mark.parametrize("degrees", [180.0, 120.0, 90.0, 45.0])
def test_no_pair_near_a_junction_starts_closer_than_pi_r(degrees):
    """(J.1) at a junction of two straight members at the angle α (cells r/2 long, so that
    the Verlet list, margin 2r, holds every pair within a gap of 2r): every listed pair's gap
    at rest is ≥ (π − 2) r (cosserat_fem/rod/self_contact.py: kept pairs start π r apart),
    to 1e-12 r, and nearly reached, within 2h (the exclusion is not wider than it needs: cell
    pairs are excluded by their nearer ends). Measured: least gaps 1.50, 1.46, 1.20, 1.29 r
    at 180°, 120°, 90°, 45°, against (π − 2) r = 1.14 r; the rod's π r alone (no 1/sin(α/2))
    gives 0.50 r at 90° and −0.58 r (overlapping tubes paired) at 45°. No node of member 0
    alone is a slave on member 1's cells (the larger index is the slave side)."""
    r, h = 0.01, 0.005
    alpha = math.radians(degrees)
    geometry, x = corner(alpha, r, h)
    pairs = geometry(x)
    gaps = geometry.verlet.closest.gap
    assert len(gaps) and gaps.min() >= (math.pi - 2) * r - 1e-12 * r
    reach = math.pi * r / math.sin(alpha / 2)
    least = reach * math.sin(alpha / 2) - 2 * r  # (π − 2) r at a + b = λ, a = b
    assert gaps.min() - least < h * 2
    member1 = np.unique(geometry.dofs[12:])
    on_member1 = np.isin(pairs.partner, member1).all(axis=1)
    assert np.isin(pairs.slave[on_member1], member1).all()


W, H = 1.0, 0.5


def portal(P: float) -> dict:
    """The portal frame on a plane of the module docstring (cells of 0.25 m: M a vertex)."""
    return {
        "rod": material(),
        "structure": {
            "nodes": [
                {"name": "A", "position": [0, 0, 0]},
                {"name": "B", "position": [0, 0, H]},
                {"name": "M", "position": [W / 2, 0, H]},
                {"name": "C", "position": [W, 0, H]},
                {"name": "D", "position": [W, 0, 0]},
            ],
            "members": [
                {"name": "left", "from": "A", "to": "B", "elements": 2},
                {"name": "beam1", "from": "B", "to": "M", "elements": 2},
                {"name": "beam2", "from": "M", "to": "C", "elements": 2},
                {"name": "right", "from": "D", "to": "C", "elements": 2},
            ],
            "supports": [{"node": "A", "kind": "clamped"}],
            "loads": [{"node": "M", "force": [0, 0, -P]}],
        },
        "static": {"load_steps": 1},
        "time": {"end": 1.0, "step": 1.0},
        "discretisation": {"degree": 3},
        "contact": {"obstacles": [{"kind": "plane", "point": [0, 0, -R], "normal": [0, 0, 1]}]},
    }


def foot(P: float) -> tuple[int, float, float]:
    """The nodes on the plane, the plane's force on D [N] (its z component; 0 if none) and
    the least gap of the free nodes [m]."""
    result = static_path(scene_from_dict(portal(P)), comm=MPI.COMM_SELF, write_outputs=False)
    contact = result.model.contact
    touching = contact.state != 0
    force = float(contact.force[touching, 2].sum())
    return contact.summary()["nodes_contact"], force, float(contact.gap.min())


CDD = W**3 / (3 * EI) + W / GA + W**2 * H / EI + 2 * H / EA
CDM = (W**2 / 8 - W**3 / 48) / EI + W / (2 * GA) + W**2 * H / (2 * EI) + H / EA


@pytest.mark.parametrize(("w", "bound"), [(1e-4, 2e-5), (1e-5, 2e-6)])
def test_a_portal_frame_resting_on_a_plane_carries_the_frames_reaction(w, bound):
    """Under P (chosen so that the deflections are ~``w`` L) one node, D, rests on the plane;
    the plane's reaction is R = P c_DM/c_DD (P.3) within ``bound`` relative (the linear
    theory's O(w/L): measured 7.9e-6 and 7.1e-7, bounds about 2.5 times that and
    proportional to w), its gap 0 to 1e-12 m (no penetration). P reversed lifts D off the
    plane, by −P c_DM within ``bound`` relative (measured 7.7e-6 and 7.7e-7) and nothing
    touches."""
    P = w / (W**3 / (3 * EI))
    count, force, gap = foot(P)
    assert count == 1
    assert abs(force / (P * CDM / CDD) - 1) < bound
    assert abs(gap) < 1e-12
    count, force, gap = foot(-P)
    assert count == 0 and force == 0.0
    assert abs(gap / (P * CDM) - 1) < bound


_SCRIPT = """
import json, sys
sys.path.insert(0, {tests!r})
from mpi4py import MPI
from test_structure_contact import B_AT, L, W, EI, c, crossing, portal, pressed
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.scene.build import scene_from_dict
comm = MPI.COMM_WORLD
out = {{}}
for joint in (False, True):
    force, summary = pressed(crossing(2e-4 / c(B_AT, L), 1e-4, joint), comm)
    out[f"crossing {{joint}}"] = [force, summary["pairs_in_contact"]]
result = static_path(scene_from_dict(portal(1e-4 / (W**3 / (3 * EI)))), comm=comm,
                     write_outputs=False)
contact = result.model.contact
out["portal"] = [comm.allreduce(float(contact.force[contact.state != 0, 2].sum())),
                 contact.summary()["nodes_contact"]]
if comm.rank == 0:
    print(json.dumps(out))
"""


@pytest.mark.long
@pytest.mark.mpi
def test_structure_contact_under_mpirun_equals_serial(tmp_path):
    """Under mpirun -n 2 the crossing cantilevers (rigid and with the joint at X) and the
    portal frame are dealt to two ranks (the joint's cells on one, pairs and reactions
    between ranks through the gathered positions and PETSc's assembly): the contact forces
    equal the serial ones to 1e-9 relative (the same Newton iterates; MUMPS against PETSc's
    LU: round-off 1e-12 of the rows times the iterations' condition), the same contacts."""
    from pathlib import Path

    text = _SCRIPT.format(tests=str(Path(__file__).parent))
    serial, parallel = script_serial_and_mpi(tmp_path / "structure_contact.py", text)
    assert serial.keys() == parallel.keys()
    for key, (force, count) in serial.items():
        assert count == parallel[key][1] == 1, key
        assert abs(parallel[key][0] / force - 1) < 1e-9, key
