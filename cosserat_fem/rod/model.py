"""From a scene to a discrete rod: mesh, space, boundary conditions and the residual.

The rod is the interval σ ∈ [0, 1] (σ = s/ℓ, eq. (47)) with ``elements`` cells and a
12-component Lagrange field U = (p, q) of the scene's degree (one ``VectorElement``, blocked
dofs, see docs/developers.md). A clamped end gets the Dirichlet condition p = q = 0 (55); a
free end gets the natural condition through the boundary form of
:func:`cosserat_fem.forms.general_form.residual_terms`. Loads are the scene's expressions
of s [m] and t [s], turned into UFL with s = ℓ σ and t = τ/ω0; loads given by data (tables,
callables) are Constants and quadrature Functions set from τ before each assembly
(cosserat_fem/rod/load_coefficients.py, :meth:`RodModel.sync_loads`); loads that are identically
zero are left out of the form.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import logging
import math
from dataclasses import dataclass, field

import basix
import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.fem.function import ElementMetaData
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem import forms
from cosserat_fem.common import jit
from cosserat_fem.common.errors import SceneError
from cosserat_fem.common.parallel import agree
from cosserat_fem.common.rotations import axis_rotation
from cosserat_fem.forms import follower, rigid_body
from cosserat_fem.forms import reference as reference_shapes
from cosserat_fem.forms.general_form import (
    DistributedLoads,
    EndLoadConvention,
    EndLoads,
    KelvinVoigtDamping,
    LoadContext,
    ViscousDamping,
    residual_terms,
)
from cosserat_fem.forms.groups import Groups, RodConstants, dimensionless_groups
from cosserat_fem.forms.kinematics import P_NAMES, quaternion_chart
from cosserat_fem.forms.reference import Reference
from cosserat_fem.forms.resultants import scaled_law
from cosserat_fem.forms.section import SectionLaw
from cosserat_fem.nls.constraints import Identification, Joint
from cosserat_fem.nls.contact import NodeContact
from cosserat_fem.nls.contacts import Contacts
from cosserat_fem.rod import charts
from cosserat_fem.rod.charts import change_chart, change_chart_rate, chart_of
from cosserat_fem.rod.load_coefficients import DataLoads
from cosserat_fem.rod.structure import (
    StructureMesh,
    cell_members,
    create_structure_mesh,
    member_frames,
    member_laws,
)
from cosserat_fem.scene.build import PLANAR, Scene
from cosserat_fem.scene.expressions import Expression, derivative
from cosserat_fem.scene.layout import FULL, Layout
from cosserat_fem.scene.load_data import is_data

START_TAG, END_TAG, POINT_TAG = 1, 2, 3
# The unknowns solved (the model's Layout): all twelve, or those of motion in one plane: x-z,
# (x, z, ψ) and their rates (y = θ = φ = 0 is an invariant set of (65) when no load, support or
# initial state leaves the plane: every y, θ, φ row of F vanishes there), or y-z, (y, z, θ) and
# their rates (x = ψ = φ = 0 likewise; θ carries the bending, so the chart limit |θ| < π/2
# applies); tests/test_planar.py; the components of each plane: scene.PLANAR.


def _drop_build_chatter(record: logging.LogRecord) -> bool:
    return record.name != "root" or record.levelno >= logging.WARNING


def quiet_jit_logging() -> None:
    """Keep the console clean during JIT compilation.

    FFCx installs a root handler (``logging.basicConfig``) and setuptools' distutils resets the
    root level to INFO on every C build, so each compiled form would print its compiler lines.
    A filter on the root handlers drops INFO records of the root logger only.
    """
    for handler in logging.getLogger().handlers:
        if _drop_build_chatter not in handler.filters:
            handler.addFilter(_drop_build_chatter)


def rod_constants(scene: Scene) -> RodConstants:
    """Physical constants of the scene's rod, with ω0 resolved (section 6 when 'auto')."""
    return scene.rod_constants()


@dataclass
class SupportMotion:
    """A prescribed support translation X(t) [m] (supports.``end``_motion), its rate X'(t)
    [m/s] and the Dirichlet Constants of the support's 12 (clamped) or 8 (pinned) components."""

    end: str
    position: tuple
    rate: tuple
    acceleration: tuple
    values: dict[int, fem.Constant]


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """Λ = exp(α n×) = I + sin α n× + (1 − cos α) n×² (Rodrigues): the right-handed rotation
    by ``angle`` α [rad] about the unit ``axis`` n."""
    return axis_rotation(np.asarray(axis, dtype=float), angle)


def prescribed_angle(motion, model: RodModel, t: float, factor: float | None):
    """(α, dα/dt, d²α/dt²) of a prescribed angle (``motion``'s ``angle``, ``rate``,
    ``acceleration`` Expressions, its ``key``) at time ``t`` [s]; ``factor`` λ (statics): α λ
    and zero rates. SceneError naming the key if one is not finite."""
    values = dict(model.scene.expression_names(), t=t)
    try:
        alpha, rate, acc = (
            e.evaluate(**values) for e in (motion.angle, motion.rate, motion.acceleration)
        )
    except ValueError:
        alpha = rate = acc = math.nan
    if factor is not None:
        alpha, rate, acc = alpha * factor, 0.0, 0.0
    if not all(math.isfinite(x) for x in (alpha, rate, acc)):
        raise SceneError(f"{motion.key}: {motion.angle.source!r} is not finite at t = {t:.6g} s")
    return alpha, rate, acc


@dataclass
class NodeRotation:
    """A structure node turned by a prescribed rotation Λ(t) = exp(α(t) n×) from the rest
    (StructureSupport.rotation, rotation_axis: ``key``, ``angle`` α(t) [rad], ``axis`` n), and
    the Dirichlet Constants of its angles (θ, ψ, φ) and their rates (components 3-5, 9-11).

    The angles are those of Λ in the node's chart A(Q) (charts.py): D(θ, ψ, φ) = Λᵀ Aᵀ, the
    triple nearest the node's current angles, so that a rotation through 2π passes the
    chart's limits as the rest of the structure does, by the chart's moves (the node is not a
    fork: all its angles are held). Their τ-rates are dα/dτ ∂a/∂α (and d²a/dτ² = (dα/dτ)²
    ∂²a/∂α² + d²α/dτ² ∂a/∂α), the α-derivatives by central differences of step :attr:`H`
    (truncation O(H²) ~ 1e-8; round-off ~ 1e-16/H = 1e-12 in the first, 1e-16/H² = 1e-8 in
    the second). The held angles themselves are exact."""

    key: str
    axis: tuple[float, float, float]
    angle: Expression
    rate: Expression
    acceleration: Expression
    blocks: np.ndarray  # the node's blocks of U on this rank (none where it is not)
    values: dict[int, fem.Constant]
    H = 1e-4

    def angles(self, model: RodModel, alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The node's angles at α in its chart, and their first and second α-derivatives
        (collective: the node's chart and angles come from the ranks that have it)."""
        Q, near = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3)
        local = None
        if self.blocks.size:
            block = int(self.blocks[0])
            full = model.layout.full_array(model.U.x.array)
            chart = None if model.chart is None else model.chart.x.array.reshape(-1, 4)[block]
            local = (chart, full[block, 3:6].copy())
        found = [x for x in model.msh.comm.allgather(local) if x is not None]
        if found:
            Q = Q if found[0][0] is None else found[0][0]
            near = found[0][1]
        frame = charts.quaternion_frame(Q)
        h = self.H
        a = [
            charts.euler_angles(rotation_matrix(self.axis, alpha + k * h).T @ frame.T, near)
            for k in (0, -1, 1)
        ]
        return a[0], (a[2] - a[1]) / (2.0 * h), (a[2] - 2.0 * a[0] + a[1]) / h**2

    def set(self, model: RodModel, t: float, rates: bool, factor: float | None) -> None:
        """The Constants at time ``t`` [s]: the angles and their τ-rates (``rates``: the
        τ-rates and τ-accelerations, for the initial-rate problem); ``factor`` λ (statics):
        α(t) λ, the rates zero. SceneError naming the key if α(t) is not finite."""
        alpha, rate, acc = prescribed_angle(self, model, t, factor)
        a, da, dda = self.angles(model, alpha)
        w = model.omega0
        dadtau = da * rate / w
        second = (dda * rate**2 + da * acc) / w**2
        p, q = (dadtau, second) if rates else (a, dadtau)
        for i in range(3):
            self.values[3 + i].value = p[i]
            self.values[9 + i].value = q[i]


@dataclass
class JointDrive:
    """A driven joint of a structure (StructureJoint kind "driven": ``key``, ``angle`` α(t)
    [rad] about its axis n0): its copy is its master turned by exp(α [n0×]), the constraint
    (C.3) of cosserat_fem/nls/constraints.py whose ``joint`` (None on a rank that does not own
    it) takes α and its τ-derivatives before each solve."""

    key: str
    angle: Expression
    rate: Expression
    acceleration: Expression
    joint: Joint | None

    def set(self, model: RodModel, t: float, rates: bool, factor: float | None) -> None:
        """α, dα/dτ, d²α/dτ² at time ``t`` [s] (``factor`` λ, statics: α(t) λ, the rates
        zero; ``rates`` changes nothing: the joint's rows take what they need), as
        NodeRotation.set. SceneError naming the key if α(t) is not finite."""
        alpha, rate, acc = prescribed_angle(self, model, t, factor)
        if self.joint is not None:
            w = model.omega0
            self.joint.drive[:] = (alpha, rate / w, acc / w**2)


def _what(component: int) -> str:
    """What a support's component holds: the position, or its rate."""
    return "its position" if component < 6 else "its rate"


@dataclass
class RodModel:
    """The discrete rod of a scene; ``residual`` is the factory the integrators call."""

    scene: Scene
    msh: mesh.Mesh
    V: fem.FunctionSpace
    U: fem.Function
    bcs: list
    dx: ufl.Measure
    ds: ufl.Measure
    rod: RodConstants
    groups: Groups
    convention: EndLoadConvention
    skipped: list[str]
    load_factor: fem.Constant
    #: Prescribed support motions (a rod's ends) and node rotations (a structure's).
    motions: list[SupportMotion | NodeRotation | JointDrive] = field(default_factory=list)
    layout: Layout = field(default_factory=Layout)  # the components of (p, q) U holds
    #: The quaternions Q(σ) of the frame the angles are measured from (forms/kinematics.py,
    #: "Charts"; cosserat_fem/rod/charts.py), or None: the fixed basis, the paper's chart.
    chart: fem.Function | None = None
    #: Whether the residual carries the chart (until the first reset a run solves the paper's
    #: forms, which cost less; outputs carry the chart whenever there is one).
    chart_active: bool = False
    #: Whether the chart has left the fixed basis (Q ≢ (1, 0, 0, 0)).
    chart_moved: bool = False
    #: U's blocks (local) at a pinned end, a fork or a hinge (:func:`is_fork`): its held
    #: angles mean rotations about the fixed basis only in the paper's chart, so the chart
    #: never moves there (a fork's θ = ±π/2 is the gimbal lock of the joint itself).
    fork_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))
    #: A polyline's reference frame D0, cellwise constant (made by :meth:`reference_form`).
    reference_frame: fem.Function | None = None
    #: The scene's [parameters] as Constants in the forms (made by :meth:`_symbols`).
    _parameters: dict | None = None
    #: The loads given by data in the forms (made by build_model).
    data: DataLoads | None = None
    #: A structure's mesh, nodes and node loads (cosserat_fem/rod/structure.py), or None.
    structure: StructureMesh | None = None
    #: The dofs its joints tie (cosserat_fem/nls/constraints.py), or None: no joints.
    constraints: Identification | None = None
    #: The contact rows (cosserat_fem/nls/contact.py; made by rod/obstacles.py contact_rows),
    #: whose ``values`` the outputs read; None: no contact.
    contact: NodeContact | Contacts | None = None

    @property
    def needs_chart(self) -> bool:
        """Whether the Euler-angle chart can be singular: θ and ψ both solved (checks.py)."""
        return self.layout.index(3) is not None and self.layout.index(4) is not None

    def use_chart(self, active: bool = True) -> None:
        """Give the model a chart, Q = (1, 0, 0, 0) (the fixed basis) to start with, if it has
        none; ``active``: the residuals built from now on carry it. The quaternions share U's
        Lagrange nodes (checked)."""
        if self.chart is None:
            degree = self.V.ufl_element().degree()
            space = fem.VectorFunctionSpace(self.msh, ("Lagrange", degree), dim=4)
            if not np.array_equal(
                space.tabulate_dof_coordinates(), self.V.tabulate_dof_coordinates()
            ):
                raise RuntimeError("the chart's quaternions do not share the nodes of U")
            self.chart = fem.Function(space, name="Q")
            self.chart.x.array.reshape(-1, 4)[:, 0] = 1.0
        self.chart_active = self.chart_active or active

    def chart_form(self):
        """The UFL chart of :attr:`chart` (None without one)."""
        return None if self.chart is None else quaternion_chart(self.chart)

    def reference_form(self) -> Reference | None:
        """The rest configuration of the scene's [reference] in UFL (forms/reference.py), or
        None for the straight rod, whose forms are the paper's (65) as written."""
        if self.scene.structure is not None:  # the members' frames (rod/structure.py)
            frame = self.reference_frame
            assert frame is not None, "_model's (member_frames)"
            return Reference(ufl.as_vector([frame[2, j] for j in range(3)]), frame, ufl.zero(3))
        shape = self.scene.reference
        if not shape.curved:
            return None
        sigma = ufl.SpatialCoordinate(self.msh)[0]
        if shape.shape == "arc":
            return reference_shapes.circular_arc(sigma, self.length, shape.radius)
        if shape.shape == "polyline":
            frame = self._polyline_frame()
            return Reference(ufl.as_vector([frame[2, j] for j in range(3)]), frame, ufl.zero(3))
        if shape.shape == "curve":
            assert shape.constants is not None, "a curve's (scene/build.py)"
            symbols = {"s": self.length * sigma, **shape.constants}

            def vector(expressions, order: int):
                """A curve's expressions, or their order-th derivative in s, in UFL."""
                for _ in range(order):
                    expressions = [derivative(e, "s") for e in expressions]
                return ufl.as_vector([e.to_ufl(symbols) for e in expressions])

            return reference_shapes.curve(
                vector(shape.position, 1),
                vector(shape.position, 2),
                vector(shape.director, 0),
                vector(shape.director, 1),
            )
        return reference_shapes.helix(sigma, self.length, shape.radius, shape.pitch_angle)

    def _polyline_frame(self) -> fem.Function:
        """A polyline's frame D0 as a cellwise-constant 3×3 field (made once): each cell holds
        the frame of the segment its midpoint lies on (corners are at nodes, checked), so
        any number of corners costs one coefficient, not a chain of conditionals."""
        if self.reference_frame is None:
            space = fem.TensorFunctionSpace(self.msh, ElementMetaData("DG", 0), shape=(3, 3))
            cells = self.msh.topology.index_map(1)
            count = cells.size_local + cells.num_ghosts
            vertices = self.msh.geometry.dofmap.array.reshape(-1, 2)[:count]
            middle = self.msh.geometry.x[vertices, 0].mean(axis=1) * self.length
            frames = self.scene.reference.frames(middle)  # (cells, 3, 3)
            dofs = space.dofmap.list.array.reshape(-1)[:count]
            frame = fem.Function(space, name="D0")
            frame.x.array.reshape(-1, 9)[dofs] = frames.reshape(-1, 9)
            self.reference_frame = frame
        return self.reference_frame

    def chart_maps(self, Q_new: np.ndarray):
        """(state_map, rate_map) of :meth:`Integrator.change_variables` from the current chart to
        the nodal quaternions ``Q_new``, for state arrays of U's layout; the nodes whose
        quaternion does not change keep their values bit for bit."""
        assert self.chart is not None, "use_chart made it"
        layout, Q_old = self.layout, self.chart.x.array.reshape(-1, 4).copy()
        pick = list(layout.components)
        moved = np.any(Q_new != Q_old, axis=1)
        Q_from, Q_to = Q_old[moved], Q_new[moved]

        def state_map(state: np.ndarray) -> np.ndarray:
            full = layout.full_array(state).copy()
            full[moved] = change_chart(full[moved], Q_from, Q_to)
            return full[:, pick].ravel()

        def rate_map(state: np.ndarray, rate: np.ndarray) -> np.ndarray:
            full, dfull = layout.full_array(state), layout.full_array(rate).copy()
            dfull[moved] = change_chart_rate(full[moved], dfull[moved], Q_from, Q_to)
            return dfull[:, pick].ravel()

        return state_map, rate_map

    def new_chart(self, state: np.ndarray | None = None) -> np.ndarray:
        """The nodal quaternions (nodes, 4) of the rod's own rotation in ``state`` (default U):
        the chart in which its angles are zero (cosserat_fem/rod/charts.py ``chart_of``), but at
        :attr:`fork_nodes`, which keep theirs. Signed for a continuous field along the rod
        (:meth:`_continuous_signs`). Collective. A joint's copy takes its own rotation as its
        chart, as every node: the joints' rows (C.3)-(C.8) of cosserat_fem/nls/constraints.py
        read each copy's chart."""
        state = self.U.x.array if state is None else state
        assert self.chart is not None, "use_chart made it"
        Q_old = self.chart.x.array.reshape(-1, 4)
        Q_new = chart_of(self.layout.full_array(state), Q_old)
        self._continuous_signs(Q_new)
        Q_new[self.fork_nodes] = Q_old[self.fork_nodes]
        return Q_new

    def _continuous_signs(self, Q: np.ndarray) -> None:
        """Flip the signs of ``Q`` (local nodes, in place) so that neighbouring nodes along the
        rod hold quaternions with a positive product, from the first node (σ = 0), which keeps
        the sign of its old quaternion. q and −q are the same rotation, but the frame between
        two nodes is the normalised interpolant, which passes through Q = 0 between q and a
        nearly opposite −q': signing each node like its old quaternion is not enough once a
        node has turned by more than π in its chart since the last move (ψ and φ are not
        bounded by the move's test), and such a move once made the interpolated frame turn
        over inside an element (measured: the flying spaghetti's energy jumped from 750 J to
        14000 J). Rank 0 sweeps the owned nodes of all ranks in the order of σ; on a structure
        along its mesh (:meth:`_graph_flips`)."""
        V, comm = self.V, self.msh.comm
        n = V.dofmap.index_map.size_local
        if self.structure is not None:
            mine = self._graph_flips(Q[:n])
            Q[:n][mine] *= -1.0
            self._ghost_signs(Q)
            return
        sigma = V.tabulate_dof_coordinates()[:n, 0]
        parts = comm.gather((sigma, Q[:n].copy()), root=0)
        flips = None
        if comm.rank == 0:
            sigmas = np.concatenate([p[0] for p in parts])
            values = np.concatenate([p[1] for p in parts])
            order = np.argsort(sigmas, kind="stable")
            flip_sorted = np.zeros(len(order), dtype=bool)
            for k in range(1, len(order)):
                previous = values[order[k - 1]] * (-1.0 if flip_sorted[k - 1] else 1.0)
                flip_sorted[k] = float(values[order[k]] @ previous) < 0.0
            flip = np.empty(len(order), dtype=bool)
            flip[order] = flip_sorted
            sizes = np.cumsum([0, *(len(p[0]) for p in parts)])
            flips = [flip[sizes[r] : sizes[r + 1]] for r in range(comm.size)]
        mine = comm.scatter(flips, root=0)
        Q[:n][mine] *= -1.0
        self._ghost_signs(Q)

    def _graph_flips(self, Q_owned: np.ndarray) -> np.ndarray:
        """Which owned nodes' quaternions to negate on a structure's mesh (collective): rank 0
        gathers the nodes and cells of all ranks and walks the mesh breadth-first from its
        first node (global 0, which keeps its sign), a node signed like the neighbour it is
        reached from (a node of the same cell: the frame between them is that cell's
        interpolant), so that every node has a positive product with that neighbour: the
        rod's rule along σ, on a tree or a closed frame (whose loop closes on a rotation
        field continuous from the rest, so its last edge agrees too). A joint's two copies are
        one more edge (their rotations apart, the sign across it is any: the walk reaches the
        members beyond it)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import breadth_first_order

        V, comm = self.V, self.msh.comm
        imap = V.dofmap.index_map
        n = imap.size_local
        glob = imap.local_to_global(np.arange(n + imap.num_ghosts, dtype=np.int32))
        owned_cells = self.msh.topology.index_map(self.msh.topology.dim).size_local
        cells = V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)[:owned_cells]
        if self.constraints is not None:  # a joint's copies: one more edge of the walk
            ties = self.constraints
            joined = glob[np.stack([ties.master_blocks, ties.copy_blocks], axis=1)]
        else:
            joined = np.zeros((0, 2), dtype=np.int64)
        parts = comm.gather((glob[:n], Q_owned.copy(), glob[cells], joined), root=0)
        flips = None
        if comm.rank == 0:
            total = imap.size_global
            values = np.empty((total, 4))
            for ids, q, _, _ in parts:
                values[ids] = q
            links = np.concatenate([c for _, _, c, _ in parts])
            k = links.shape[1]
            pairs = np.concatenate([j for _, _, _, j in parts])
            rows = np.concatenate([np.repeat(links, k, axis=1).ravel(), pairs[:, 0]])
            cols = np.concatenate([np.tile(links, (1, k)).ravel(), pairs[:, 1]])
            graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(total, total)).tocsr()
            order, parent = breadth_first_order(graph, 0, directed=False)
            sign = np.ones(total)
            for node in order[1:]:
                up = parent[node]
                sign[node] = sign[up] * (-1.0 if values[node] @ values[up] < 0.0 else 1.0)
            flips = [sign[ids] < 0.0 for ids, _, _, _ in parts]
        return comm.scatter(flips, root=0)

    def _ghost_signs(self, Q: np.ndarray) -> None:
        """The ghost nodes' quaternions take their owners' (after signing the owned ones)."""
        comm = self.msh.comm
        if comm.size > 1:  # the ghosts take their owners' signs
            assert self.chart is not None, "use_chart made it"
            work = fem.Function(self.chart.function_space)
            work.x.array[:] = Q.ravel()
            work.x.scatter_forward()
            Q[:] = work.x.array.reshape(-1, 4)

    def chart_margin(self, cos: np.ndarray) -> float:
        """The smallest |cos θ| (``cos``: cos θ at the owned nodes, checks.cos_theta) over the
        nodes whose chart may move (not :attr:`fork_nodes`); 1 if none. Local."""
        values = np.abs(cos)
        if self.fork_nodes.size:
            values = values.copy()
            values[self.fork_nodes[self.fork_nodes < values.size]] = 1.0
        return float(np.minimum.reduce(values)) if values.size else 1.0

    @functools.cached_property
    def _parallel_comm(self):
        """The mesh's communicator if it has several ranks, else None (Mesh.comm costs a few
        μs a call, and the chart's test runs every step)."""
        comm = self.msh.comm
        return comm if comm.size > 1 else None

    def chart_move_due(self, cos: np.ndarray) -> float | None:
        """The angle |θ| of the node nearest the chart's singularity if a move is due there,
        |cos θ| < cos charts.RESET_THETA (``cos`` as for :meth:`chart_margin`), else None
        (also without a chart). Collective."""
        if self.chart is None:
            return None
        smallest = self.chart_margin(cos)
        if self._parallel_comm is not None:
            smallest = self._parallel_comm.allreduce(smallest, op=MPI.MIN)
        if smallest >= math.cos(charts.RESET_THETA):
            return None
        return math.acos(min(smallest, 1.0))

    def set_chart(self, Q: np.ndarray) -> None:
        """The chart's nodal quaternions (nodes, 4); marks it moved."""
        assert self.chart is not None, "use_chart made it"
        self.chart.x.array[:] = np.asarray(Q).ravel()
        self.chart_moved = True

    def reset_chart(self, state: np.ndarray | None = None) -> np.ndarray:
        """Move the chart onto the rod's rotation at every node: U (or ``state``, an array of
        U's layout, changed in place) gets zero angles and their rates ŵ (charts.chart_of,
        change_chart); returns the state array. Collective."""
        state = self.U.x.array if state is None else state
        Q_new = self.new_chart(state)
        state[:] = self.chart_maps(Q_new)[0](state)
        self.set_chart(Q_new)
        return state

    @property
    def nodes(self) -> int:
        """Lagrange nodes of this rank (owned and ghost): blocks of U's array."""
        return self.U.x.array.size // self.layout.size

    @property
    def omega0(self) -> float:
        return self.rod.omega0

    def move_supports(self, tau: float, rates: bool = False) -> None:
        """Set the Dirichlet values of prescribed support motions at τ = ω0 t (47):
        p_i = X_i(t)/ℓ, q_i = dp_i/dτ = X_i'(t)/(ℓ ω0), i = x, y, z; with ``rates``, their
        τ-derivatives instead (q_i and X_i''(t)/(ℓ ω0²), for the initial-rate problem).
        SceneError naming the motion if a value is not finite (``log(t - 1)`` at t < 1)."""
        if not self.motions:
            return
        t = tau / self.omega0
        values = dict(self.scene.expression_names(), t=t)
        w, ell = self.omega0, self.length
        for m in self.motions:
            if isinstance(m, NodeRotation | JointDrive):
                m.set(self, t, rates, None)
                continue
            p, q = (m.rate, m.acceleration) if rates else (m.position, m.rate)
            scale = (1.0 / ell, 1.0 / (ell * w))
            scale = (scale[1], scale[1] / w) if rates else scale
            for i in (i for i in range(3) if i in m.values):
                for j, e, factor in ((i, p[i], scale[0]), (6 + i, q[i], scale[1])):
                    try:
                        value = e.evaluate(**values) * factor
                    except ValueError:
                        value = math.nan
                    if not math.isfinite(value):
                        raise SceneError(
                            f"supports.{m.end}_motion[{i}]: {_what(j)} {e.source!r} is not "
                            f"finite at t = {t:.6g} s"
                        )
                    m.values[j].value = value

    def load_entries(self) -> list[tuple[str, Expression]]:
        """(dotted key, component) of every load and support motion of the scene that is not
        a constant: an expression, or data (cosserat_fem/scene/load_data.py)."""
        return [(key, e) for key, e in self.scene.load_components() if not e.is_constant]

    def sync_loads(self, time_eval) -> None:
        """Set the data loads of the forms of the time Constant ``time_eval`` to their values
        at its τ (call it after setting τ, before assembling; collective if a callable is
        among them: cosserat_fem/rod/load_coefficients.py)."""
        if self.data is not None:
            self.data.sync(time_eval)

    def nonfinite_load(self, times: list[float]) -> str | None:
        """What is not finite among the loads and support motions at ``times`` [s], at the
        nodes and quadrature points of the rod: "key = "source" is nan at t = ..., s = ... m",
        or None (collective). A solve that fails asks this before it blames the step."""
        cells = self.msh.geometry.dofmap.array.reshape(-1, 2)
        x = self.msh.geometry.x[:, 0]
        degree = self.scene.discretisation.quadrature_degree
        xi, _ = basix.make_quadrature(basix.CellType.interval, degree)
        xi = np.concatenate([[0.0], xi[:, 0], [1.0]])
        s = self.length * (x[cells[:, :1]] + xi[None, :] * (x[cells[:, 1:]] - x[cells[:, :1]]))
        s = s.ravel()
        names = self.scene.expression_names()
        found = None
        for t in times:
            for key, e in self.load_entries():
                with np.errstate(all="ignore"):
                    values = e.evaluate(s=s, t=np.full_like(s, t), **names)
                bad = np.flatnonzero(~np.isfinite(values))
                if bad.size and found is None:
                    where = f", s = {s[bad[0]]:.4g} m" if e.depends_on("s") else ""
                    found = f"{key} = {e.source!r} is {values[bad[0]]} at t = {t:.6g} s{where}"
        found_all = [f for f in self.msh.comm.allgather(found) if f]
        return found_all[0] if found_all else None

    def turn_nodes(self, t: float, factor: float) -> None:
        """Statics: the prescribed node rotations at α(t) times the load factor ``factor``,
        written into U (their dofs only). Collective."""
        rotations = [m for m in self.motions if isinstance(m, NodeRotation | JointDrive)]
        for m in rotations:
            m.set(self, t, False, factor)
        if rotations:
            fem.set_bc(self.U.x.array, self.bcs)
            if self.constraints is not None:
                self.constraints.enforce(self.U.x.array)

    def support_dofs_to(self, state: np.ndarray, tau: float) -> None:
        """Write the moving supports' values at τ into a state array (their dofs only)."""
        if not self.motions:
            return
        self.move_supports(tau)
        fem.set_bc(state, self.bcs)
        if self.constraints is not None:  # driven joints' copies
            self.constraints.enforce(state)

    @property
    def length(self) -> float:
        return self.rod.length

    def global_dofs(self) -> int:
        imap = self.V.dofmap.index_map
        return imap.size_global * self.V.dofmap.index_map_bs

    def _symbols(self, time_eval) -> dict:
        """The values of the scene's expression names in UFL: L and ω0 as numbers, each of the
        [parameters] a DOLFINx Constant (so that scenes that differ in their parameters only,
        a sweep's members, share their compiled forms), s = ℓ σ [m] and t = τ/ω0 [s] with
        τ = ``time_eval`` (47)."""
        sigma = ufl.SpatialCoordinate(self.msh)[0]
        names = dict(self.scene.expression_names())
        if self._parameters is None:
            self._parameters = {
                name: fem.Constant(self.msh, PETSc.ScalarType(value))
                for name, value in self.scene.parameters.items()
            }
        names.update(self._parameters)
        names["s"] = self.length * sigma
        names["t"] = time_eval / self.omega0
        return names

    def set_parameter(self, name: str, value: float) -> None:
        """Give the scene parameter ``name`` the value ``value`` in the forms built (its
        Constant, :meth:`_symbols`): the same compiled forms, a new forcing (a shooting
        problem's continuation parameter, cosserat_fem/analysis/periodic.py)."""
        if self._parameters is None:
            raise RuntimeError("set_parameter before any form was built (no Constants yet)")
        self._parameters[name].value = value

    def parameter_value(self, name: str) -> float:
        """The value of the scene parameter ``name`` in the forms (:meth:`set_parameter`)."""
        if self._parameters is None:
            return float(self.scene.parameters[name])
        return float(self._parameters[name].value)

    def _vector(self, exprs, symbols, time_eval):
        """A load vector times the load factor λ (1 in dynamics; stepped in statics); its
        data components are coefficients of the time Constant ``time_eval``."""
        if exprs is None or all(e.is_zero for e in exprs):
            return None
        components = []
        for e in exprs:
            if is_data(e):
                assert self.data is not None, "build_model made the data loads"
                components.append(self.data.coefficient(e, time_eval))
            else:
                components.append(e.to_ufl(symbols))
        return self.load_factor * ufl.as_vector(components)

    def residual(self, U_eval, Udot_eval, time_eval, charted: bool | None = None) -> ufl.Form:
        """The weak residual (65) at (U_eval, Udot_eval) of U's layout, loads at τ = time_eval
        (a reduced U is embedded in the 12 components, tested by its own components only);
        angles measured in the chart if ``charted`` (default: :attr:`chart_active`)."""
        full = self.layout.full
        test = full(ufl.TestFunction(self.V))
        terms = self.residual_terms(full(U_eval), full(Udot_eval), time_eval, test, charted)
        return terms.total()

    def load_vectors(self, time_eval) -> tuple[DistributedLoads, tuple[EndLoads, ...]]:
        """The scene's loads at τ = time_eval as UFL vectors (absent ones are None)."""
        sym = self._symbols(time_eval)
        loads = self.scene.loads
        force = self._vector(loads.force_density, sym, time_eval)
        if loads.has_gravity:  # the weight μ g [N/m], a force density f of (36), fixed basis
            law = self.rod.law  # μ = a general law's mass_per_length (of s), else ρ A
            if law is not None and law.mass_per_length is not None:
                weight = law.mass_per_length
            else:
                weight = self.rod.density * self.rod.section.area
            gravity = self.load_factor * ufl.as_vector([weight * g for g in loads.gravity])
            force = gravity if force is None else force + gravity
        distributed = DistributedLoads(
            force=force,
            torque=self._vector(loads.torque_density, sym, time_eval),
        )
        ends = []
        for tag, end in ((START_TAG, loads.start), (END_TAG, loads.end)):
            if end is None:
                continue
            ends.append(
                EndLoads(
                    ds=self.ds(tag),
                    force=self._vector(end.force, sym, time_eval),
                    torque=self._vector(end.torque, sym, time_eval),
                )
            )
        if self.structure is not None:  # node loads: a leaf's ds, a chain's dS (checked)
            sub = self.ds.subdomain_data()
            dS = ufl.Measure("dS", domain=self.msh, subdomain_data=sub)
            for load, tag, interior in self.structure.loads:
                if load.follower:  # turning with the node: residual_terms
                    continue
                ends.append(
                    EndLoads(
                        ds=(dS if interior else self.ds)(tag),
                        force=self._vector(load.force, sym, time_eval),
                        torque=self._vector(load.torque, sym, time_eval),
                        interior=interior,
                    )
                )
        if loads.point is not None:  # at the node s (checked), on an interior facet
            dS = ufl.Measure("dS", domain=self.msh, subdomain_data=self.ds.subdomain_data())
            ends.append(
                EndLoads(
                    ds=dS(POINT_TAG),
                    force=self._vector(loads.point.force, sym, time_eval),
                    torque=self._vector(loads.point.torque, sym, time_eval),
                    interior=True,
                )
            )
        return distributed, tuple(ends)

    def residual_terms(self, U_eval, Udot_eval, time_eval, test=None, charted=None):
        """The terms of (65); ``test`` defaults to the test function of the 12-component space;
        ``charted`` as for :meth:`residual`."""
        charted = self.chart_active if charted is None else charted
        distributed, ends = self.load_vectors(time_eval)
        V = ufl.TestFunction(self.V) if test is None else test
        d = self.scene.damping
        viscous = ViscousDamping(d.translational, d.rotational, self.omega0) if d.viscous else None
        kelvin_voigt = (
            KelvinVoigtDamping(d.retardation_time, self.omega0) if d.kelvin_voigt else None
        )
        chart = self.chart_form() if charted else None
        terms = residual_terms(
            U_eval,
            Udot_eval,
            V,
            self.groups,
            self.dx,
            distributed,
            ends,
            self.convention,
            viscous,
            kelvin_voigt,
            chart,
            self.reference_form(),
            scaled_law(self.rod) if self.rod.law is not None else None,
        )
        form_loads = self.scene.loads.form_loads()
        bodies = self.structure.bodies if self.structure is not None else []
        followers = [
            (i, x)
            for i, x in enumerate(self.structure.loads if self.structure else [])
            if x[0].follower
        ]
        if form_loads or bodies or followers:  # the loads declared with their physics
            sym = self._symbols(time_eval)
            context = LoadContext(
                U=U_eval,
                V=V,
                groups=self.groups,
                convention=self.convention,
                chart=chart,
                reference=self.reference_form(),
                ds={"start": self.ds(START_TAG), "end": self.ds(END_TAG)},
                vector=lambda exprs: self._vector(exprs, sym, time_eval),
                Udot=Udot_eval,
                omega0=self.omega0,
                gravity=(
                    self.load_factor * ufl.as_vector(self.scene.loads.gravity)
                    if self.scene.loads.has_gravity
                    else None
                ),
            )
            for name, load in form_loads:
                physics = importlib.import_module(f"{forms.__name__}.{load.physics}")
                terms.extra[name] = physics.residual(load, context)
            # a structure's bodies at its nodes: a leaf's ds, a chain's dS; their inertia and
            # offset in the fixed basis at rest, so no member's frame D0 (forms/rigid_body.py)
            at_node = dataclasses.replace(context, reference=None)
            dS = ufl.Measure("dS", domain=self.msh, subdomain_data=self.ds.subdomain_data())
            for i, (body, tag, interior) in enumerate(bodies):
                measure = (dS if interior else self.ds)(tag)
                terms.extra[f"structure.bodies[{i}]"] = rigid_body.body_term(
                    body, at_node, measure, interior
                )
            for i, (node_load, tag, interior) in followers:  # Λ F, Λ M: the rest basis
                measure = (dS if interior else self.ds)(tag)
                force, torque = (context.vector(v) for v in (node_load.force, node_load.torque))
                terms.extra[f"structure.loads[{i}]"] = follower.turning(
                    force, torque, at_node, measure, interior
                )
        return terms

    def initial_state(self) -> np.ndarray:
        """U at time.start from the scene's [initial] fields (zero where none is given):
        p = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ), q = dp/dτ = (ẋ/(ℓ ω0), ..., θ̇/ω0, ...)."""
        U = fem.Function(self.V)
        given = self.scene.initial.fields()
        if given:
            values = dict(self.scene.expression_names())
            x = self.V.tabulate_dof_coordinates()[:, 0] * self.length  # s at the nodes
            state = np.zeros((len(x), 12))
            scale = {"displacement": 1.0 / self.length, "angles": 1.0}
            scale["velocity"] = 1.0 / (self.length * self.omega0)
            scale["angle_rates"] = 1.0 / self.omega0
            first = {"displacement": 0, "angles": 3, "velocity": 6, "angle_rates": 9}
            for name, vector in given.items():
                for i, e in enumerate(vector):
                    state[:, first[name] + i] = scale[name] * np.broadcast_to(
                        np.asarray(e.evaluate(s=x, **values), dtype=float), x.shape
                    )
            bad, problem = ~np.isfinite(state), None
            if bad.any():
                node, column = np.argwhere(bad)[0]
                name = next(n for n, c in first.items() if c <= column < c + 3)
                i = column - first[name]
                problem = SceneError(
                    f"initial.{name}[{i}]: {given[name][i].source!r} is not finite at "
                    f"s = {x[node]:.4g} m"
                )
            agree(self.msh.comm, problem)
            U.x.array[:] = state[:, list(self.layout.components)].reshape(-1)
        return U.x.array


def support_conditions(
    V: fem.FunctionSpace, scene: Scene, ends: dict[str, np.ndarray], components: tuple[int, ...]
) -> tuple[list, dict[str, dict[int, fem.Constant]]]:
    """Dirichlet conditions of the scene's supports (55) on a space whose blocks hold the
    ``components`` of (p, q): all of them zero at a clamped end at rest; else, one by one, the
    held ones (Supports.held_components: clamped all; pinned x, y, z, φ, or a hinge's two
    angles across its axis, and their rates; spherical x, y, z and theirs; roller x, y, φ and
    theirs; sliding all but z and its rate) with a Constant value each (what a prescribed
    motion sets). ``ends``: the vertices of each end. Returns the conditions and, by end,
    {full component: its Constant}."""
    bcs: list = []
    held: dict[str, dict[int, fem.Constant]] = {}
    for name, ents in ends.items():
        kind, moving = getattr(scene.supports, name), scene.supports.motion(name) is not None
        held[name] = node_conditions(
            V, ents, kind, scene.supports.held_components(name), components, moving, bcs
        )
    return bcs, held


def node_conditions(
    V: fem.FunctionSpace,
    ents: np.ndarray,
    kind: str,
    held: tuple[int, ...],
    components: tuple[int, ...],
    moving: bool,
    bcs: list,
) -> dict[int, fem.Constant]:
    """Append to ``bcs`` the Dirichlet conditions of one support (:func:`support_conditions`)
    at the vertices ``ents``: all components zero if clamped and not ``moving``, else each of
    the ``held`` ones with a Constant value; returns {full component: its Constant}."""
    values: dict[int, fem.Constant] = {}
    if kind == "clamped" and not moving:
        dofs = fem.locate_dofs_topological(V, 0, ents)
        bcs.append(fem.dirichletbc(np.zeros(len(components), dtype=np.float64), dofs, V))
        return values
    if kind == "free":
        return values
    for i in (i for i in held if i in components):
        j = components.index(i)
        value = fem.Constant(V.mesh, PETSc.ScalarType(0.0))
        dofs = fem.locate_dofs_topological(V.sub(j), 0, ents)
        bcs.append(fem.dirichletbc(value, dofs, V.sub(j)))
        values[i] = value
    return values


def is_fork(scene: Scene, end: str) -> bool:
    """Whether the support at ``end`` holds some of the angles but not all (a fork, a hinge,
    a roller): their values mean a rotation about the fixed basis in the paper's chart only,
    so the chart never moves there (:attr:`RodModel.fork_nodes`)."""
    return 0 < len(scene.supports.held(end)[1]) < 3


def _ufl_law(rod: RodConstants, scene: Scene, msh: mesh.Mesh) -> RodConstants:
    """The rod with its section law's expressions of s (rod.section.stiffness, mass_per_length,
    inertia; docs/sections.md) as UFL expressions of s = ℓ σ (L and the parameters numbers)."""
    law = rod.law
    if law is None or not scene.rod.section.expressions():
        return rod
    symbols = dict(scene.expression_names())
    symbols["s"] = rod.length * ufl.SpatialCoordinate(msh)[0]

    def convert(x):
        return x if x is None or isinstance(x, float) else x.to_ufl(symbols)

    inertia = None if law.inertia is None else tuple(convert(x) for x in law.inertia)
    stiffness = tuple(tuple(convert(x) for x in row) for row in law.stiffness)
    return dataclasses.replace(
        rod, law=SectionLaw(stiffness, convert(law.mass_per_length), inertia)
    )


def build_model(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, planar: bool = True) -> RodModel:
    """The discrete rod; ``planar``: solve only the in-plane unknowns when the scene stays in
    the x-z or the y-z plane (:meth:`Scene.plane`, and discretisation.planar = "auto")."""
    quiet_jit_logging()
    jit.install()  # crash-safe, quiet compiles (cosserat_fem/common/jit.py)
    disc = scene.discretisation
    if scene.structure is not None:
        return _build_structure_model(scene, comm)
    msh = mesh.create_interval(comm, disc.elements, [0.0, 1.0])
    cell = msh.ufl_cell()
    plane = scene.plane() if planar else None
    components = PLANAR[plane] if plane is not None else FULL
    element = ufl.VectorElement("Lagrange", cell, disc.degree, dim=len(components))
    V = fem.FunctionSpace(msh, element)

    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    start = mesh.locate_entities_boundary(msh, 0, lambda x: np.isclose(x[0], 0.0))
    end = mesh.locate_entities_boundary(msh, 0, lambda x: np.isclose(x[0], 1.0))
    point = np.zeros(0, dtype=np.int32)
    if scene.loads.point is not None:
        sigma = scene.loads.point.s / scene.rod.length
        point = mesh.locate_entities(msh, 0, lambda x: np.isclose(x[0], sigma))
    facets = np.concatenate([start, end, point]).astype(np.int32)
    values = np.concatenate(
        [np.full(len(start), START_TAG), np.full(len(end), END_TAG), np.full(len(point), POINT_TAG)]
    )
    order = np.argsort(facets)
    tags = mesh.meshtags(msh, 0, facets[order], values[order].astype(np.int32))

    bcs, held = support_conditions(V, scene, {"start": start, "end": end}, components)
    # The ends holding some angles but not all (a fork, a hinge, a roller): the chart stays.
    forks = [ents for name, ents in (("start", start), ("end", end)) if is_fork(scene, name)]
    fork_nodes = np.concatenate(
        [np.zeros(0, dtype=np.int32)] + [fem.locate_dofs_topological(V, 0, e) for e in forks]
    ).astype(np.int32)
    motions: list[SupportMotion | NodeRotation | JointDrive] = []
    for name in ("start", "end"):
        motion = scene.supports.motion(name)
        if motion is not None:
            rates = tuple(derivative(e, "t") for e in motion)
            accelerations = tuple(derivative(e, "t") for e in rates)
            motions.append(SupportMotion(name, motion, rates, accelerations, held[name]))

    skipped = scene.absent_terms()
    if plane is not None:
        dropped = ", ".join(P_NAMES[i] for i in range(6) if i not in components)
        skipped += [f"out-of-plane unknowns {dropped}"]
    model = _model(scene, V, bcs, tags, components, skipped, fork_nodes)
    model.motions = motions
    return model


def _model(scene: Scene, V, bcs, tags, components, skipped, fork_nodes) -> RodModel:
    """The RodModel on the space V with its conditions and vertex tags (build_model)."""
    # FFCx 0.5 reads the quadrature degree from the measure's metadata only; a
    # form_compiler_params={"quadrature_degree": q} is silently ignored.
    msh, q = V.mesh, scene.discretisation.quadrature_degree
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": q})
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    rod = _ufl_law(rod_constants(scene), scene, msh)
    frame = None
    if scene.structure is not None:  # the members' sections and frames, DG0 fields of one
        cells = cell_members(scene.structure, rod.length, msh)  # cell assignment (structure.py)
        rod = member_laws(rod, scene.structure, msh, assignment=cells)
        frame = member_frames(scene.structure, rod.length, msh, assignment=cells)
    return RodModel(
        scene=scene,
        msh=msh,
        V=V,
        U=fem.Function(V, name="U"),
        bcs=bcs,
        dx=dx,
        ds=ds,
        rod=rod,
        reference_frame=frame,
        groups=dimensionless_groups(rod),
        convention=EndLoadConvention(scene.model.end_load_sign, scene.model.end_load_scaling),
        skipped=skipped,
        load_factor=fem.Constant(msh, PETSc.ScalarType(1.0)),
        layout=Layout(components),
        fork_nodes=fork_nodes,
        data=DataLoads(msh, q, scene.rod.length, scene.omega0),
    )


def _build_structure_model(scene: Scene, comm: MPI.Comm) -> RodModel:
    """The discrete structure (cosserat_fem/rod/structure.py): its mesh in 3D, all twelve
    components, the supports at its nodes (node_conditions; a pinned node a hinge, whose
    held angles keep the chart, like a fork), its node loads (RodModel.load_vectors)."""
    structure = scene.structure
    assert structure is not None, "build_model's branch"
    made = create_structure_mesh(structure, scene.rod.length, comm)
    element = ufl.VectorElement(
        "Lagrange", made.msh.ufl_cell(), scene.discretisation.degree, dim=len(FULL)
    )
    V = fem.FunctionSpace(made.msh, element)
    bcs, forks, rotations = structure_conditions(V, scene, made.vertices, FULL)
    model = _model(scene, V, bcs, made.tags, FULL, scene.absent_terms(), forks)
    model.structure = made
    model.motions = list(rotations)
    all_joints = structure.all_joints()
    if all_joints:  # the copies of the joints' nodes, tied (rod/structure.py)
        masters, copies, components, which = made.joint_blocks(V, structure)
        turning = {
            j: Joint(m, c, np.asarray(all_joints[j].axis), all_joints[j].kind == "driven")
            for m, c, j in zip(masters, copies, which, strict=True)
            if all_joints[j].kind in ("hinge", "driven")
        }
        for tie in turning.values():  # the balance rows' divisors (forms/general_form.py)
            tie.inertia = np.array(forms.general_form.row_inertias(model.groups))
        ties = Identification(V, masters, copies, components, bcs, list(turning.values()))
        ties.chart = lambda: None if model.chart is None else model.chart.x.array.reshape(-1, 4)
        ties.state = lambda: model.U.x.array
        model.constraints = ties
        # a rigid copy (a loaded junction's split) keeps its chart with its master's: a fork's
        kinds = [all_joints[j].kind for j in which]
        rigid = np.array([k == "rigid" for k in kinds], dtype=bool)
        held = rigid & np.isin(masters, model.fork_nodes)
        model.fork_nodes = np.concatenate(
            [model.fork_nodes, np.asarray(copies, dtype=np.int32)[held]]
        ).astype(np.int32)
        for j, joint in enumerate(structure.joints):
            if joint.kind != "driven":
                continue
            assert joint.angle is not None, "a driven joint's angle (scene/build.py)"
            rate = derivative(joint.angle, "t")
            model.motions.append(
                JointDrive(
                    f"structure.joints[{j}].angle",
                    joint.angle,
                    rate,
                    derivative(rate, "t"),
                    turning.get(j),
                )
            )
    return model


def structure_conditions(
    V: fem.FunctionSpace, scene: Scene, vertices: dict[str, np.ndarray], components
) -> tuple[list, np.ndarray, list]:
    """The Dirichlet conditions of a structure's supports (node_conditions at each support's
    node, ``vertices`` by node name) on a space of the ``components`` of (p, q), the blocks
    of the nodes that hold some angles but not all (a hinge: the chart stays there), and the
    prescribed rotations (:class:`NodeRotation`; their Constants zero, the rest, until set)."""
    assert scene.structure is not None, "a structure's scene"
    bcs: list = []
    forks = [np.zeros(0, dtype=np.int32)]
    rotations = []
    for i, support in enumerate(scene.structure.supports):
        ents = vertices[support.node]
        held = support.held_components()
        turned = support.rotation is not None
        values = node_conditions(V, ents, support.kind, held, components, turned, bcs)
        if 0 < len(support.held()[1]) < 3:
            forks.append(fem.locate_dofs_topological(V, 0, ents))
        if turned and support.rotation_axis is not None and support.rotation is not None:
            rate = derivative(support.rotation, "t")
            rotations.append(
                NodeRotation(
                    f"structure.supports[{i}].rotation",
                    support.rotation_axis,
                    support.rotation,
                    rate,
                    derivative(rate, "t"),
                    fem.locate_dofs_topological(V, 0, ents),
                    values,
                )
            )
    return bcs, np.concatenate(forks).astype(np.int32), rotations
