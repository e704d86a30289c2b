"""A rigid body carried by an end ([loads.body], forms/rigid_body.py; issue 29 item 2).

The references are the linear Timoshenko beam's, derived here independently of the code: the
rod of the paper's section 6 bending in the x-z plane about d2 (EI = E c22, κGA, ρA, ρ c22)
with a body of mass m, rotary inertia J about its centre (J22) and its centre at e along d3
from the tip. Stationarity of ∫ (ω² T − U) dt, T = ½ ∫ ρA ẇ² + ρI ψ̇² dx + ½ m ẇ_C² + ½ J ψ̇²,
w_C = w(L) + e ψ(L), U = ½ ∫ EI ψ'² + κGA (w' − ψ)² dx, gives for y = (w, ψ, M, V)
(M = EI ψ', V = κGA (w' − ψ))

    w' = ψ + V/κGA,  ψ' = M/EI,  M' = −V − ρI ω² ψ,  V' = −ρA ω² w,
    w = ψ = 0 at x = 0,   V = ω² m w_C,  M = ω² (m e w_C + J ψ) at x = L,

and in statics under gravity g across the rod (x), q = ρA g, P = m g, the tip deflection

    w(L) = q L⁴/(8 EI) + q L²/(2 κGA) + P L³/(3 EI) + P L/κGA + P e L²/(2 EI).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT
from scipy.linalg import expm
from scipy.optimize import brentq

import cosserat_fem as cf
from cosserat_fem.common.errors import SceneError
from cosserat_fem.timestepping.events import Observer

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
UNLOADED = {"loads.force_density": [0, 0, 0]}


def beam(scene):
    """(EI, κGA, ρA, ρI, L) of bending in x about d2 for ``scene``'s rod."""
    rod = scene.rod
    a, b = rod.section.a, rod.section.b
    area, c22 = a * b, b * a**3 / 12.0
    E, rho = rod.material.young_modulus, rod.material.density
    G = E / (2.0 * (1.0 + rod.material.poisson_ratio))
    return E * c22, rod.section.shear_coefficient * G * area, rho * area, rho * c22, rod.length


def tip_residual(omega, EI, kGA, rhoA, rhoI, L, m, J, e, at=None):
    """det of the free tip's conditions M(L) = V(L) = 0 over the two free starts (M(0),
    V(0)), the body at x = ``at`` (default the tip, L): y crosses it with the jumps
    V(a+) = V(a−) − ω² m w_C, M(a+) = M(a−) − ω² (m e w_C + J ψ) (the stationarity of the
    module docstring's functional with the body inside; at the tip, with nothing beyond,
    they are its tip conditions)."""
    w2 = omega * omega
    at = L if at is None else at
    A = np.array(
        [
            [0.0, 1.0, 0.0, 1.0 / kGA],
            [0.0, 0.0, 1.0 / EI, 0.0],
            [0.0, -rhoI * w2, 0.0, -1.0],
            [-rhoA * w2, 0.0, 0.0, 0.0],
        ]
    )
    jump = np.eye(4)
    jump[3, :2] = -w2 * m * np.array([1.0, e])  # V: −ω² m (w + e ψ)
    jump[2, :2] = -w2 * np.array([m * e, m * e * e + J])  # M: −ω² (m e w_C + J ψ)
    Y = expm(A * (L - at)) @ jump @ expm(A * at)[:, 2:]  # y(L) from y(0) = (0, 0, M0, V0)
    scale = np.abs(Y).max(axis=1)
    return np.linalg.det(Y[2:] / scale[2:, None])


def timoshenko_omegas(count, EI, kGA, rhoA, rhoI, L, m, J, e, at=None):
    """The ``count`` lowest ω [rad/s] of the beam with its body (at the tip, or at x =
    ``at``), by sign changes of :func:`tip_residual` on a fine grid, each refined by Brent's
    method to 1e-13."""
    args = (EI, kGA, rhoA, rhoI, L, m, J, e, at)
    grid = np.linspace(1.0, 4000.0, 8000)
    values = [tip_residual(w, *args) for w in grid]
    roots = []
    for w0, w1, f0, f1 in zip(grid, grid[1:], values, values[1:], strict=False):
        if np.sign(f0) != np.sign(f1):
            roots.append(brentq(tip_residual, w0, w1, args=args, xtol=1e-13, rtol=1e-15))
        if len(roots) == count:
            break
    return np.array(roots)


BODY = {"loads.body.mass": 6.552, "loads.body.inertia": [0.02, 0.02, 0.02]}


@pytest.mark.parametrize("offset", [0.0, 0.1], ids=["centred", "offset along d3"])
def test_a_tip_body_lowers_the_cantilevers_frequencies_as_the_timoshenko_beam(offset):
    """The two lowest bending-x frequencies of the paper's cantilever carrying a body of its
    own mass (6.552 kg, μ = 1), J = 0.02 I kg m² (J22 acts), at e = 0 and 0.1 m along d3,
    against the Timoshenko beam's (module docstring): the modes' mass matrix takes the
    body's through UFL's derivative with respect to the rates. The references are exact
    roots (1e-13). The difference is the rod's discretisation, cubic cells, whose frequency
    error goes as h^(2k) = h^6: the second frequency's error falls by 2^6 = 64 (at least
    45: the observed order ≥ 5.5) from 8 to 16 cells and is below 2e-7 at 16 (measured
    6.6e-6, 1.2e-7 centred; 5.0e-6, 9.3e-8 offset), the first's below 1e-9 at 16 (2.3e-10,
    1.1e-10: the eigensolver's tolerance). Without the body the first frequency is 2.3
    times higher."""
    errors = []
    for cells in (8, 16):
        settings = {**UNLOADED, **BODY, "loads.body.offset": [0.0, 0.0, offset]}
        scene = cf.load(SCENE, {**settings, "discretisation.elements": cells})
        modes = [m for m in cf.modes(scene, count=6) if m.kind == "bending-x"][:2]
        reference = timoshenko_omegas(2, *beam(scene), 6.552, 0.02, offset)
        errors.append(np.abs(np.array([m.omega for m in modes]) / reference - 1.0))
    coarse, fine = errors
    assert fine[0] < 1e-9 and fine[1] < 2e-7, errors
    assert np.log2(coarse[1] / fine[1]) >= 5.5, errors


def test_a_tip_weight_bends_the_cantilever_as_the_closed_form():
    """Gravity g = 0.01 m/s² along x on the paper's cantilever with a tip body of 6.552 kg at
    e = 0.1 m along d3: the static tip deflection against the linear Timoshenko beam's
    (module docstring). Measured 2.1e-12 relative at 16 cubic cells: the element is exact at
    its nodes for these loads (the uniform weight, the tip force and moment), so what remains
    is the geometric nonlinearity, (w/L)² ~ 2e-12 (w = 1.5e-6 m), and Newton's last
    correction: 1e-9 bounds them. Without the body's weight, or its moment P e, the deflection
    is 75% or 10% smaller."""
    settings = {
        **UNLOADED,
        **BODY,
        "loads.body.offset": [0.0, 0.0, 0.1],
        "loads.gravity": [0.01, 0.0, 0.0],
        "discretisation.elements": 16,
    }
    scene = cf.load(SCENE, settings)
    result = cf.static(scene)
    x_tip = float(result.probes[-1, 1])  # (λ, x, y, z, θ, ψ, φ) at the probe, the free end
    EI, kGA, rhoA, _, L = beam(scene)
    q, P, e = rhoA * 0.01, 6.552 * 0.01, 0.1
    w = q * L**4 / (8 * EI) + q * L**2 / (2 * kGA) + P * L**3 / (3 * EI)
    w += P * L / kGA + P * e * L**2 / (2 * EI)
    assert x_tip == pytest.approx(w, rel=1e-9)


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        ({"loads.body.mass": 0.0}, r"^loads\.body\.mass: "),
        ({"loads.body.mass": 1.0, "loads.body.offset": [0, "x", 0]}, r"^loads\.body\.offset\[1\]"),
        (
            {"loads.body.mass": 1.0, "loads.body.inertia": [1.0, 1.0, 3.0]},
            r"^loads\.body\.inertia: not a rigid body's",
        ),
        (
            {
                "loads.body.mass": 1.0,
                "loads.body.inertia": [1.0, 1.0, 1.0],
                "loads.body.products": [0.0, 0.0, 2.0],
            },
            r"^loads\.body\.inertia: not positive definite",
        ),
        ({"loads.body.inertia": [1.0, 1.0, 1.0]}, r"^loads\.body\.mass"),
    ],
)
def test_a_bad_body_is_one_line_naming_the_key(sets, message):
    """Bad bodies: a SceneError naming the key (the command line prints it as one line)."""
    with pytest.raises(SceneError, match=message) as err:
        cf.load(SCENE, {**UNLOADED, **sets})
    assert "\n" not in str(err.value)


#: The swing of the energy and momentum tests: no loads, an off-axis body with products of
#: inertia, set moving in 3D; generalized-α with ρ∞ = 1 over 0.01 s.
SWING = {
    **UNLOADED,
    "loads.body.mass": 6.552,
    "loads.body.inertia": [0.03, 0.02, 0.025],
    "loads.body.products": [0.002, -0.001, 0.003],
    "loads.body.offset": [0.02, 0.01, 0.1],
    "initial.velocity": ["0.6*s/L", "0.4*s/L", 0],
    "initial.angle_rates": [0, 0, "30*s/L"],
    "output.xdmf": False,
    "time.integrator": "generalized-alpha",
    "time.rho_inf": 1.0,
    "solver.jacobian": "full",
    "time.end": 0.01,
    "solver.stol": 1e-8,
}


def swing_drifts(folder, recorder_type, drift, changes=None) -> list[float]:
    """``drift(recorder)`` of the :data:`SWING` (with ``changes``) run at Δt = 4e-5, 2e-5 s."""
    from cosserat_fem.analysis.simulation import run_scene

    drifts = []
    for dt in (4e-5, 2e-5):
        recorder = recorder_type()
        scene = cf.load(SCENE, {**SWING, **(changes or {}), "time.step": dt})
        run_scene(scene, folder, observers=(recorder,))
        drifts.append(drift(recorder))
    return drifts


def test_a_swinging_body_keeps_the_energy_at_the_integrators_order(tmp_path):
    """No loads, no damping: the paper's cantilever set swinging in 3D (velocity (0.6, 0.4,
    0) s/L m/s, a twist rate 30 s/L rad/s) with a body of 6.552 kg whose centre is off the
    axis, c = (0.02, 0.01, 0.1) m, and whose inertia has products, so that every term of
    (B2)-(B4) works (the centripetal ω × (ω × c), the angular acceleration's α × c, the
    gyroscopic ω̂ × J ω̂). E = T + V of the rod plus the body's T_B is conserved by the
    equations; generalized-α with ρ∞ = 1 (the midpoint rule's energy behaviour) keeps it to
    O(Δt²): the drift over 0.01 s falls by 4 (2^2, ±20%) when Δt halves (a wrong term
    drifts at O(1), alike at both steps). Measured: drifts 1.08e-7, 2.63e-8 (ratio 4.08).
    The centripetal term with the wrong sign drifts 4e-2; the gyroscopic term does no work
    (ω · (ω × J ω) = 0), which the next test checks instead."""
    from rod_energy import EnergyRecorder

    def drift(recorder) -> float:
        E = np.array(recorder.E)
        return np.abs(E - E[0]).max() / E[0]

    drifts = swing_drifts(tmp_path, EnergyRecorder, drift)
    assert 3.2 < drifts[0] / drifts[1] < 4.8, drifts


class MomentumRecorder(Observer):
    """Observer: the angular momentum H [kg m²/s] about the origin of the rod and its body at
    every output time (a free-free rod without loads keeps it),

        H = ∫ (r × ρA ṙ + Rᵀ I ω̂ ω0) ds + m r_C × v_C + Rᵀ J ω̂ ω0 (at the body's end),

    with the rod's rotary inertias I = ρ (c11, c22, I3) along the directors (forms/energy.py),
    r = (ℓ p1, ℓ p2, s + ℓ p3) (the straight rod), the body's r_C, v_C of (B1), (B2)."""

    def __init__(self):
        self.H: list[np.ndarray] = []
        self.forms: list | None = None
        self.charted = False

    def output(self, loop, k: int, t: float) -> None:
        import ufl
        from cosserat_fem.forms.general_form import LoadContext
        from cosserat_fem.forms.kinematics import angular_velocity, directors, split
        from cosserat_fem.forms.rigid_body import body_frame
        from dolfinx import fem
        from mpi4py import MPI

        from cosserat_fem.rod.model import END_TAG

        model = loop.model
        if self.forms is None or model.chart_moved != self.charted:
            self.charted = model.chart_moved
            chart = model.chart_form() if model.chart_moved else None
            U, rod = model.layout.full(model.U), model.rod
            p, q = split(U)
            ell, w0 = rod.length, model.omega0
            s = ell * ufl.SpatialCoordinate(model.msh)[0]
            r = ufl.as_vector([ell * p[0], ell * p[1], s + ell * p[2]])
            r_dot = ell * w0 * ufl.as_vector([q[0], q[1], q[2]])
            R = directors(p, chart)
            w_hat = angular_velocity(p, q)
            inertia = ufl.as_vector(rod.rotary_inertias)
            own = rod.density * (
                rod.section.area * ufl.cross(r, r_dot)
                + w0 * R.T * ufl.as_vector([inertia[i] * w_hat[i] for i in range(3)])
            )
            body = model.scene.loads.body
            context = LoadContext(
                U=U, V=None, groups=model.groups, convention=None, chart=chart,
                reference=None, ds={}, vector=None, omega0=w0,
            )  # fmt: skip
            J, c = body_frame(body.inertia_tensor(), body.offset_vector(), context)
            c_s = R.T * c
            v_C = r_dot + w0 * ufl.cross(R.T * w_hat, c_s)
            carried = body.mass * ufl.cross(r + c_s, v_C) + w0 * R.T * (J * w_hat)
            self.forms = [
                fem.form(ell * own[i] * ufl.dx + carried[i] * model.ds(END_TAG)) for i in range(3)
            ]
        comm = model.msh.comm
        self.H.append(
            np.array([comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM) for f in self.forms])
        )


def test_a_flying_rod_and_its_body_keep_their_angular_momentum(tmp_path):
    """The paper's rod free at both ends, no loads, set tumbling (velocity (0.6, 0.4, 0) s/L
    m/s, a twist rate 30 s/L rad/s) with the off-axis body of products of inertia: the
    angular momentum H of rod and body (:class:`MomentumRecorder`) is conserved by the
    equations; generalized-α with ρ∞ = 1 keeps it to O(Δt²): the drift of H over 0.01 s,
    relative to |H|, falls by 4 (±20%) when Δt halves (a wrong term drifts at O(1)).
    This holds the gyroscopic ω̂ × J ω̂ of (B4), which does no work and so escapes the
    energy. Measured: drifts 1.16e-8, 2.93e-9 (ratio 3.97); with the gyroscopic term's sign
    flipped 3.8e-3 at both steps."""

    def drift(recorder) -> float:
        H = np.array(recorder.H)
        return np.linalg.norm(H - H[0], axis=1).max() / np.linalg.norm(H[0])

    drifts = swing_drifts(tmp_path, MomentumRecorder, drift, {"supports.start": "free"})
    assert 3.2 < drifts[0] / drifts[1] < 4.8, drifts


def test_probes_csv_follows_the_bodys_centre(tmp_path):
    """output.probe_fields = ["directors", "body"]: each row's body columns are the centre's
    displacement u + (D − I)ᵀ c of (B1) from the same row's displacement and directors
    (the straight rod: D0 = I), to round-off of the 3×3 product (1e-15 of the largest
    displacement and |c|), over a swing of the off-axis body in 3D that turns the end by
    ~0.05 rad (so that (D − I)ᵀ c is not small: above 1e-3 m, measured 4.7e-3 m)."""
    from cosserat_fem.io.probes import read_probe_table

    settings = {
        **UNLOADED,
        "loads.body.mass": 6.552,
        "loads.body.inertia": [0.03, 0.02, 0.025],
        "loads.body.offset": [0.02, 0.01, 0.1],
        "initial.velocity": ["6*s/L", "4*s/L", 0],
        "initial.angle_rates": [0, 0, "30*s/L"],
        "output.probe_fields": ["directors", "body"],
        "output.xdmf": False,
        "time.end": 0.0045,
    }
    cf.run(cf.load(SCENE, settings), tmp_path / "run")
    columns, rows = read_probe_table(tmp_path / "run" / "probes.csv")
    col = {name: i for i, name in enumerate(columns)}
    c = np.array([0.02, 0.01, 0.1])
    turn = []
    for row in rows:
        D = np.array([[row[col[f"d{j}_{x}"]] for x in "xyz"] for j in (1, 2, 3)])
        u = np.array([row[col[x]] for x in "xyz"])
        expected = u + (D - np.eye(3)).T @ c
        got = np.array([row[col[f"body_{x}"]] for x in "xyz"])
        scale = max(np.abs(u).max(), np.linalg.norm(c))
        assert np.abs(got - expected).max() <= 1e-15 * scale * 4
        turn.append(np.linalg.norm((D - np.eye(3)).T @ c))
    assert max(turn) > 1e-3, max(turn)


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        ({}, r'^output\.probe_fields: "body" is the centre of a \[loads\.body\], and the scene'),
        ({"loads.body.mass": 1.0, "loads.body.end": "start"}, r"and the body at the start$"),
    ],
)
def test_body_probe_columns_need_a_body_at_the_probe(sets, message):
    """The body columns without a body, or with the body at the clamped start while the probe
    is at the free end: one line naming output.probe_fields."""
    with pytest.raises(SceneError, match=message):
        cf.load(SCENE, {**UNLOADED, "output.probe_fields": ["body"], **sets})


#: The swing with its body in 3D, 40 steps, on every rank; rank 0 saves the probes to argv[2].
MPI_SCRIPT = """
import sys
import math

import numpy as np
from mpi4py import MPI
import cosserat_fem as cf
sys.path.insert(0, sys.argv[1])
from test_rigid_body import SCENE, SWING
scene = cf.load(SCENE, {**SWING, "time.step": 2.5e-5, "time.end": 0.001,
                        "output.probe_fields": ["body"]})
result = cf.run(scene)
if MPI.COMM_WORLD.rank == 0:
    np.save(sys.argv[2], result.probes)
"""


@pytest.mark.mpi
@pytest.mark.long
def test_a_body_under_mpirun_equals_serial(tmp_path):
    """The body's end on one rank's facet: ``mpirun -n 2`` gives the serial probes (the
    body's centre included) to the solver's tolerance: Newton stops at an update below
    stol ‖U‖ (1e-8 here), the partitions' sums differ at round-off, so each step's
    state may differ by stol ‖U‖; over 40 steps 40 stol of the largest value bounds it
    (measured 7.9e-16: the same iterations on both).
    ~10 s (two processes compile)."""
    from conftest import run_command

    probes = {}
    for ranks in (1, 2):
        out = tmp_path / f"n{ranks}.npy"
        proc = run_command(["-c", MPI_SCRIPT, str(ROOT / "tests"), str(out)], ranks)
        assert proc.returncode == 0, proc.stderr[-3000:]
        probes[ranks] = np.load(out)
    assert probes[1].shape == probes[2].shape
    scale = np.abs(probes[1][:, 1:]).max()
    assert np.abs(probes[1] - probes[2]).max() <= 40 * 1e-8 * scale


# ------------------------------------------------------------------- bodies at a structure's nodes
def paper_structure(nodes, members, body: dict) -> dict:
    """The paper's rod's section and material as a [structure] of ``nodes`` (name: position
    [m]) and ``members`` (name, from, to, elements), clamped at its first node, no loads, a
    [[structure.bodies]] entry ``body``."""
    from cosserat_fem.scene.schema import read_toml

    data = read_toml(SCENE)
    for name in ("supports", "loads", "reference"):
        data.pop(name, None)
    data["rod"].pop("length", None)
    data["discretisation"] = {"degree": 3}
    first = next(iter(nodes))
    data["structure"] = {
        "nodes": [{"name": n, "position": list(x)} for n, x in nodes.items()],
        "members": [{"name": n, "from": a, "to": b, "elements": k} for n, a, b, k in members],
        "supports": [{"node": first, "kind": "clamped"}],
        "bodies": [body],
    }
    return data


def test_a_body_at_a_structures_leaf_is_the_rods_body_at_its_end():
    """The paper's rod as a one-member structure (mesh in 3D) with a body at its leaf B, and
    the single rod with [loads.body] at its end: the same discretisation and, for the member
    along e3 (d0_i = e_i), the same components of the body; the structure's body is a
    NodeBody on the leaf's ds with D0 = I, the rod's a RigidBody through its reference-free
    forms. The six lowest frequencies agree to the eigensolver's tolerance (1e-9 relative,
    as tests/test_modes.py), measured 1e-12."""
    from cosserat_fem.scene.build import scene_from_dict

    body = {
        "mass": 6.552,
        "inertia": [0.03, 0.02, 0.025],
        "products": [0.002, -0.001, 0.003],
        "offset": [0.02, 0.01, 0.1],
    }
    rod = cf.load(SCENE, {**UNLOADED, **{f"loads.body.{k}": v for k, v in body.items()}})
    data = paper_structure(
        {"A": (0, 0, 0), "B": (0, 0, 1)}, [("m", "A", "B", 8)], {"node": "B", **body}
    )
    structure = scene_from_dict(data)
    one = np.array([m.omega for m in cf.modes(rod, count=6)])
    two = np.array([m.omega for m in cf.modes(structure, count=6)])
    np.testing.assert_allclose(two, one, rtol=1e-9)


def test_a_body_inside_a_chain_lowers_the_frequencies_as_the_timoshenko_beam():
    """The paper's cantilever as a chain of two members, A–B–C along e3 with B at 0.4 m,
    carrying at B (a node inside the chain: the interior facet dS) a body of 6.552 kg, J =
    0.02 I kg m², its centre 0.05 m along e3 from B: the two lowest bending-x frequencies
    against the Timoshenko beam with the body inside (:func:`tip_residual`'s jumps at x =
    0.4 m), converging as h^6 (cubic cells) as the tip body's: from 4 + 6 to 8 + 12 cells
    (h = 0.1 m to 0.05 m) each error falls by at least 2^5.5 = 45 and the finer's are below
    2e-9 and 5e-8 (measured 6.7e-8 → 1.2e-9 and 9.4e-7 → 1.7e-8: orders 5.8, 5.8)."""
    from cosserat_fem.scene.build import scene_from_dict

    body = {"node": "B", "mass": 6.552, "inertia": [0.02] * 3, "offset": [0, 0, 0.05]}
    errors = []
    for k in (1, 2):
        nodes = {"A": (0, 0, 0), "B": (0, 0, 0.4), "C": (0, 0, 1)}
        members = [("AB", "A", "B", 4 * k), ("BC", "B", "C", 6 * k)]
        scene = scene_from_dict(paper_structure(nodes, members, body))
        modes = [m for m in cf.modes(scene, count=6) if m.kind == "bending-x"][:2]
        reference = timoshenko_omegas(2, *beam(cf.load(SCENE)), 6.552, 0.02, 0.05, at=0.4)
        errors.append(np.abs(np.array([m.omega for m in modes]) / reference - 1.0))
    coarse, fine = errors
    assert fine[0] < 2e-9 and fine[1] < 5e-8, errors
    assert np.all(np.log2(coarse / fine) >= 5.5), errors


def test_a_weight_inside_a_chain_bends_it_as_the_closed_form():
    """The chain A–B–C of the test above in statics under g = 0.01 m/s² along e1, the body
    (6.552 kg, centre 0.05 m along e3 from B at a = 0.4 m): the tip's deflection against the
    linear Timoshenko cantilever's under its weight q = ρA g, the body's weight P = m g at a
    and its moment P e there,

        w(L) = q L⁴/8EI + q L²/2κGA + P a³/3EI + P a/κGA + P e a²/2EI
               + (P a²/2EI + P e a/EI) (L − a),

    which the cubic elements give at their nodes (as the tip body's test): 1e-9, as there
    (measured 2.7e-13)."""
    from cosserat_fem.scene.build import scene_from_dict

    body = {"node": "B", "mass": 6.552, "offset": [0, 0, 0.05]}
    nodes = {"A": (0, 0, 0), "B": (0, 0, 0.4), "C": (0, 0, 1)}
    data = paper_structure(nodes, [("AB", "A", "B", 4), ("BC", "B", "C", 6)], body)
    data["loads"] = {"gravity": [0.01, 0.0, 0.0]}
    data["structure"]["probe"] = "C"
    tip = float(cf.static(scene_from_dict(data)).probes[-1, 1])
    EI, kGA, rhoA, _, L = beam(cf.load(SCENE))
    q, P, e, a = rhoA * 0.01, 6.552 * 0.01, 0.05, 0.4
    w = q * L**4 / (8 * EI) + q * L**2 / (2 * kGA) + P * a**3 / (3 * EI) + P * a / kGA
    w += P * e * a**2 / (2 * EI) + (P * a**2 / (2 * EI) + P * e * a / EI) * (L - a)
    assert tip == pytest.approx(w, rel=1e-9)


def test_a_structures_bodies_are_not_probed_yet():
    """output.probe_fields "body" on a structure with a body at a node: one line saying so
    (before: a message about the single rod's s = ℓ)."""
    from cosserat_fem.scene.build import scene_from_dict

    data = paper_structure(
        {"A": (0, 0, 0), "B": (0, 0, 1)}, [("m", "A", "B", 4)], {"node": "B", "mass": 1.0}
    )
    data["output"] = {**data.get("output", {}), "probe_fields": ["body"]}
    with pytest.raises(SceneError, match=r"a structure's bodies \(\[\[structure\.bodies\]\]\)"):
        scene_from_dict(data)


def test_a_body_on_a_rod_with_a_turned_rest_frame_takes_its_components_in_it():
    """The paper's cantilever with a square section (b = a = 0.04 m: any frame about e3 is
    principal) given as a "curve" whose rest directors are turned by 0.5 rad about e3
    (d0_1 = (cos 0.5, −sin 0.5, 0)), carrying a body whose offset c and inertia J (with
    products) are given in those d0 components; against the straight rod (d0_i = e_i)
    carrying the same body given in the fixed basis, D0ᵀ c and D0ᵀ J D0 (forms/rigid_body.py
    (B1): c_s = Rᵀ D0ᵀ c, J_λ = D0ᵀ J D0). The same physical rod and body: the static tip
    under gravity across (c's moment) and the six lowest frequencies (J) agree to round-off
    and the solvers' tolerances, 1e-9 relative (measured by the review: 3e-17 on the tip).
    With D0 c instead of D0ᵀ c the tip moved by 1.3e-8 m (the review of 2026-12-04)."""
    turn = 0.5
    d1 = np.array([math.cos(turn), -math.sin(turn), 0.0])
    D0 = np.array([d1, np.cross([0.0, 0.0, 1.0], d1), [0.0, 0.0, 1.0]])
    c = np.array([0.03, -0.05, 0.1])
    J = np.array([[0.02, 0.003, 0.001], [0.003, 0.03, 0.002], [0.001, 0.002, 0.025]])

    def body(c, J) -> dict:
        return {
            "loads.body.offset": [float(x) for x in c],
            "loads.body.inertia": [float(J[i, i]) for i in range(3)],
            "loads.body.products": [float(J[1, 2]), float(J[0, 2]), float(J[0, 1])],
        }

    base = {
        **UNLOADED,
        "loads.body.mass": 6.552,
        "rod.section.b": 0.04,
        "discretisation.elements": 6,
        "loads.gravity": [2.0, 0.0, 0.0],
    }
    turned = {
        "reference.shape": "curve",
        "reference.position": [0.0, 0.0, "s"],
        "reference.director": [float(d1[0]), float(d1[1]), 0.0],
    }
    a = cf.load(SCENE, {**base, **turned, **body(c, J)})
    b = cf.load(SCENE, {**base, **body(D0.T @ c, D0.T @ J @ D0)})
    tip_a, tip_b = cf.static(a).probes[-1, 1:4], cf.static(b).probes[-1, 1:4]
    assert np.abs(tip_a - tip_b).max() <= 1e-9 * np.abs(tip_b).max()
    omega_a = np.array([m.omega for m in cf.modes(a, count=6)])
    omega_b = np.array([m.omega for m in cf.modes(b, count=6)])
    np.testing.assert_allclose(omega_a, omega_b, rtol=1e-9)
