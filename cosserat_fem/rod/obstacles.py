"""Rigid obstacles and the rod's contact with them (docs/contact.md).

An obstacle is the outside of a surface with a signed distance d(x) [m] (positive outside):

* plane through a, unit normal n:  d = n·(x − a),  ∇d = n,  ∇²d = 0;
* sphere of radius R about c:      d = |x − c| − R,  ∇d = ê,  ∇²d = (I − ê êᵀ)/|x − c|;
* cylinder of radius R, unit axis a through c, e = (I − a aᵀ)(x − c):
                                   d = |e| − R,  ∇d = ê,  ∇²d = (I − a aᵀ − ê êᵀ)/|e|,

ê the unit vector along x − c or e. The rod's surface, a tube of radius r about its centreline,
keeps out of an obstacle when the gap g = d(x) − r of each centreline node x is ≥ 0 (exact for
a circular section whatever the rotation). Several obstacles: each node meets the one of the
smallest gap. :func:`contact_rows` makes the rows of the Newton system that impose it with
Coulomb friction (cosserat_fem/nls/contact.py) on a rod's model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.common.errors import SceneError
from cosserat_fem.common.parallel import agree
from cosserat_fem.nls.contact import TOUCHING, NodeContact
from cosserat_fem.nls.contacts import Contacts
from cosserat_fem.nls.pair_contact import PairContact, PartlyHeld
from cosserat_fem.rod.self_contact import Members, SelfContactGeometry
from cosserat_fem.rod.structure import cell_members
from cosserat_fem.scene.expressions import derivative


@dataclass(frozen=True)
class Obstacle:
    """A rigid obstacle (module docstring): ``kind`` plane | sphere | cylinder | surface,
    ``point`` a [m], ``direction`` its unit normal (plane) or axis (cylinder), ``radius`` R
    [m]; a surface's signed distance d and its first and second derivatives in x, y, z
    (``field``: d, ∇d (3), ∇²d (3, 3) as expressions) with the ``constants`` they use."""

    kind: str
    point: np.ndarray
    direction: np.ndarray | None = None
    radius: float = 0.0
    field: tuple | None = None
    constants: dict | None = None

    @classmethod
    def of(cls, spec, constants: dict | None = None) -> Obstacle:
        """From a scene's [[contact.obstacles]] entry (cosserat_fem/scene/resolved.py), the
        scene's ``constants`` (L, omega0, the parameters: Scene.expression_names())."""
        direction = spec.normal if spec.kind == "plane" else spec.axis
        field = None
        if spec.distance is not None:
            d = spec.distance
            gradient = [derivative(d, v) for v in "xyz"]
            field = (d, gradient, [[derivative(g, v) for v in "xyz"] for g in gradient])
        return cls(
            spec.kind,
            np.zeros(3) if spec.point is None else np.asarray(spec.point, dtype=float),
            None if direction is None else np.asarray(direction, dtype=float),
            0.0 if spec.radius is None else float(spec.radius),
            field,
            dict(constants or {}),
        )

    def _values(self, expressions, x: np.ndarray) -> np.ndarray:
        """The ``expressions`` (a list, nested or not) of a surface at the points ``x`` (n, 3):
        an array of the list's shape followed by (n,)."""
        at = {"x": x[:, 0], "y": x[:, 1], "z": x[:, 2], **(self.constants or {})}
        if isinstance(expressions, list):
            rows = [self._values(e, x) for e in expressions]
            return np.concatenate([r if r.ndim == 2 else r[None] for r in rows])
        return np.broadcast_to(np.asarray(expressions.evaluate(**at), dtype=float), (len(x),))

    def _surface(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A surface's (d, ∇d/|∇d|, ∇²d) at ``x`` (n, 3): the expressions evaluated (a
        signed distance has |∇d| = 1; :func:`_check_start` refuses one that has not)."""
        assert self.field is not None, "a surface has its distance"
        d, gradient, hessian = self.field
        g = self._values(gradient, x).T.copy()
        h = self._values(hessian, x).T.reshape(len(x), 3, 3).copy()
        size = np.linalg.norm(g, axis=1)
        # on a medial axis (∇d not finite or zero: the tube's axis of "R - sqrt(x**2 + y**2)")
        # any unit normal and no curvature, as at a sphere's centre: never an error on one rank
        singular = ~np.isfinite(size) | (size == 0.0) | ~np.isfinite(h).all(axis=(1, 2))
        g[singular], size[singular], h[singular] = [1.0, 0.0, 0.0], 1.0, 0.0
        return self._values(d, x), g / size[:, None], h

    def gradient_size(self, x: np.ndarray, medial: float | None = 1.0) -> np.ndarray:
        """|∇d| at ``x`` (n, 3): 1 for the plane, sphere and cylinder; a surface's as given,
        ``medial`` where it has none (0 or not finite: a medial axis; None: as it is)."""
        if self.field is None:
            return np.ones(len(x))
        size = np.linalg.norm(self._values(self.field[1], x), axis=0)
        if medial is None:
            return size
        return np.where(np.isfinite(size) & (size > 0.0), size, medial)

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(d, ∇d, ∇²d) at the points ``x`` (n, 3): (n,), (n, 3), (n, 3, 3). At a sphere's
        centre or on a cylinder's axis (d = −R, the deepest point, where ∇d is undefined) a
        unit normal across the axis and no curvature: a value on every rank, never an error
        (an MPI rank that raised here would leave the others waiting)."""
        if self.kind == "surface":
            return self._surface(x)
        rel = x - self.point
        eye = np.broadcast_to(np.eye(3), (len(x), 3, 3))
        if self.kind == "plane":
            assert self.direction is not None, "a plane has its normal"
            n = np.broadcast_to(self.direction, x.shape).copy()
            return rel @ self.direction, n, np.zeros((len(x), 3, 3))
        if self.kind == "cylinder":
            assert self.direction is not None, "a cylinder has its axis"
            a = self.direction
            rel = rel - np.outer(rel @ a, a)
            eye = eye - np.outer(a, a)
        norm = np.linalg.norm(rel, axis=1)
        centre = norm == 0.0  # on the centre or the axis: the deepest point, any normal will do
        if np.any(centre):
            across = np.array([1.0, 0.0, 0.0])
            if self.kind == "cylinder":  # a unit direction across the axis
                assert self.direction is not None
                a = self.direction
                across = np.eye(3)[np.argmin(np.abs(a))]
                across = (across - (across @ a) * a) / np.linalg.norm(across - (across @ a) * a)
            rel = rel.copy()
            rel[centre] = across
        n = rel / np.where(centre, 1.0, norm)[:, None]
        safe = np.where(centre, np.inf, norm)  # a centre point's curvature: none
        hessian = (eye - n[:, :, None] * n[:, None, :]) / safe[:, None, None]
        return norm - self.radius, n, hessian


class Surface:
    """The gap g = min over ``obstacles`` of d(x) − ``radius`` and its derivatives (module
    docstring): the geometry :class:`~cosserat_fem.nls.contact.NodeContact` asks for."""

    def __init__(self, obstacles: list[Obstacle], radius: float):
        self.obstacles, self.radius = obstacles, radius

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(g [m], ∇g, ∇²g [1/m]) at the points ``x`` (n, 3), each point's nearest obstacle."""
        best = [o.distance(x) for o in self.obstacles]
        which = np.argmin(np.stack([d for d, _, _ in best]), axis=0)
        pick = np.arange(len(x))
        d = np.stack([d for d, _, _ in best])[which, pick]
        n = np.stack([n for _, n, _ in best])[which, pick]
        hessian = np.stack([h for _, _, h in best])[which, pick]
        return d - self.radius, n, hessian


#: how far a surface's |∇d| may be from 1 at the nodes (its distance is then a distance to
#: this relative accuracy: the gap and the rows' derivative n are as exact)
UNIT_GRADIENT = 1e-6


def _check_start(
    contact: NodeContact, spec, u: np.ndarray, comm, obstacles: list[Obstacle]
) -> None:
    """SceneError (on every rank) naming the obstacle if a node starts inside one, beyond the
    round-off of a position placed on its surface (1e-12 ℓ): its depth and s; or if a
    surface's distance is not a signed distance at a node (|∇d| − 1 beyond 1e-6)."""
    x = contact.positions(u)
    problem = None
    for i, (obstacle, spec_i) in enumerate(zip(obstacles, spec.obstacles, strict=True)):
        g = obstacle.distance(x)[0] - float(spec.radius)
        size = obstacle.gradient_size(x)
        # a gradient exactly 0 at every node of every rank: the distance does not vary ("0*x
        # + 0.5"; a medial axis gives 0/0, not 0: a string centred in a borehole is fine)
        flat = bool((obstacle.gradient_size(x, None) == 0.0).all()) if len(x) else True
        if comm.allreduce(flat, op=MPI.LAND) and problem is None:
            problem = SceneError(
                f"contact.obstacles[{i}].distance: its gradient is 0 at every node (a "
                "distance must vary with the position)"
            )
        if problem is None and not np.isfinite(g).all():
            j = int(np.flatnonzero(~np.isfinite(g))[0])
            problem = SceneError(
                f"contact.obstacles[{i}].distance: not finite at s = {contact.places[j]:.4g} m "
                f"(the rod's node at {np.array2string(x[j], precision=4)} m)"
            )
        if problem is None and (np.abs(size - 1.0) > UNIT_GRADIENT).any():
            j = int(np.argmax(np.abs(size - 1.0)))
            problem = SceneError(
                f"contact.obstacles[{i}].distance: not a signed distance, |grad d| = "
                f"{size[j]:.6g} at s = {contact.places[j]:.4g} m (it must be 1: the distance "
                "to the surface, not any function that vanishes on it)"
            )
        if (g < -TOUCHING * contact.ell).any() and problem is None:
            j = int(np.argmin(g))
            problem = SceneError(
                f"contact.obstacles[{i}]: the rod starts inside this {spec_i.kind}, "
                f"{-g[j]:.3g} m deep at s = {contact.places[j]:.4g} m (its surface of radius "
                f"{float(spec.radius):.3g} m included); move the obstacle or the rod"
            )
    agree(comm, problem)


def contact_rows(model) -> NodeContact | Contacts | None:
    """The contact rows of a rod's ``model`` (cosserat_fem/rod/model.py) whose scene has a
    [contact] table, else None: every owned node whose positions no support holds, at its
    rest position r0(s) (the scene's [reference]), the positions x = r0 + ℓ u, the balance
    rows' forces in N times g0/ℓ (forms/general_form.py: a nodal force P enters its row as
    g0 P/ℓ), their shares of the length ℓ ∫ φ_k dσ; with ``self_contact`` the rod's pairs
    too (cosserat_fem/rod/self_contact.py, :class:`~cosserat_fem.nls.contacts.Contacts`).
    Kept as ``model.contact``, whose ``values`` the outputs read."""
    spec = model.scene.contact
    if spec is None:
        return None
    layout, V = model.layout, model.V
    bs = layout.size
    owned = V.dofmap.index_map.size_local
    held = np.zeros(owned * bs, dtype=bool)
    for bc in model.bcs:
        dofs, _ = bc.dof_indices()
        held[dofs[dofs < owned * bs]] = True
    positions = [layout.index(k) for k in range(3)]
    solved = [k for k in range(3) if positions[k] is not None]
    held_position = held.reshape(owned, bs)[:, [positions[k] for k in solved]]
    held_nodes = held_position.any(axis=1)
    ell = model.length
    rest, places, copies = _rest(model)
    # each node's share of the length, ℓ ∫ φ_k dσ [m]: a nodal force over it is a load per length
    scalar = fem.FunctionSpace(model.msh, ("Lagrange", V.ufl_element().degree()))
    shares = assemble_vector(fem.form(ufl.TestFunction(scalar) * model.dx))
    shares.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    shares = ell * shares.array[:owned]
    common = dict(
        length=ell,
        force_scale=ell / model.groups.g0,
        position_slots=[positions[k] for k in solved],
        balance_slots=[layout.index(6 + k) for k in solved],
        solved=solved,
    )
    obstacles = None
    if spec.obstacles:
        constants = model.scene.expression_names()
        shapes = [Obstacle.of(o, constants) for o in spec.obstacles]
        free = np.flatnonzero(~held_nodes & ~copies).astype(np.int32)
        obstacles = NodeContact(
            V,
            free,
            rest[free],
            Surface(shapes, float(spec.radius)),
            shares=shares[free],
            static_friction=spec.static_friction,
            kinetic_friction=spec.kinetic,
            places=places[free],
            max_changes=spec.max_changes,
            **common,
        )
        _check_start(obstacles, spec, model.U.x.array, V.mesh.comm, shapes)
    model.contact = obstacles
    if spec.self_contact:
        partly = held_nodes & ~held_position.all(axis=1)  # a sliding node's
        pairs = PairContact(
            V,
            rest,
            held_position,
            _self_geometry(model, places, rest, float(spec.radius), partly),
            places=places,
            shares=shares,
            static_friction=spec.static_friction,
            kinetic_friction=spec.kinetic,
            **common,
        )
        _check_self_start(pairs, model.U.x.array)
        model.contact = Contacts(obstacles, pairs)
    return model.contact


def _check_self_start(pairs: PairContact, u: np.ndarray) -> None:
    """SceneError (on every rank: each finds the same pairs) if a slave starts through its
    partner's surface, beyond round-off (1e-12 ℓ): on a structure, members whose tubes
    overlap where the exclusion at their junctions (rod/self_contact.py (J.1)) leaves them
    paired, e.g. across a member shorter than the exclusion; or two sliding supports' cells
    touching (the geometry's PartlyHeld, a scene's fault here)."""
    x = pairs.everywhere(u)
    try:
        found = pairs.geometry(x)
    except PartlyHeld as exc:
        raise SceneError(f"contact.self_contact: at the start, {exc.reason}") from None
    if not len(found.gap) or found.gap.min() >= -TOUCHING * pairs.ell:
        return
    j = int(np.argmin(found.gap))
    where = ", ".join(f"{v:.4g}" for v in x[found.slave[j]])
    raise SceneError(
        f"contact.self_contact: the surface starts through itself, {-found.gap[j]:.3g} m deep "
        f"at the node at ({where}) m (contact.radius {pairs.geometry.radius:.3g} m); move "
        "the members apart or give a smaller radius"
    )


def _rest(model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The owned nodes' rest positions [m] (owned, 3), their places s [m] (a rod's arc length;
    on a structure the members laid end to end in the scene's order, as ℓ is their total
    length: member m's node at arc a from its ``from`` node at s = a + the lengths of the
    members before m, a junction's node on its member of the largest index; the order in
    which NodeContact's slip fronts walk from node to node, and the s of the messages) and
    whether each is a joint's copy
    (rod/structure.py: its rows are the joint's, its equation its master's; no contact of its
    own). A structure's mesh has its vertices at r0/ℓ, so its dofs' coordinates times ℓ."""
    V, ell = model.V, model.length
    owned = V.dofmap.index_map.size_local
    coordinates = V.tabulate_dof_coordinates()[:owned]
    structure = model.scene.structure
    if structure is None:
        sigma = coordinates[:, 0]
        rest = np.asarray(model.scene.reference.positions(ell * sigma), dtype=float)
        return rest.reshape(-1, 3), ell * sigma, np.zeros(owned, dtype=bool)
    rest = ell * coordinates
    starts, tangents, lengths = _member_lines(structure)
    member, _, _ = cell_members(structure, ell, model.msh)
    top = np.full(owned, -1, dtype=np.int64)
    for c, m in enumerate(member):
        dofs = V.dofmap.cell_dofs(c)
        dofs = dofs[dofs < owned]
        top[dofs] = np.maximum(top[dofs], m)
    before = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    places = before[top] + np.einsum("nd,nd->n", rest - starts[top], tangents[top])
    copies = np.zeros(owned, dtype=bool)
    if structure.all_joints():
        copies[model.structure.joint_blocks(V, structure)[1]] = True
    return rest, places, copies


def _member_lines(structure) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The members' rest starts [m] (M, 3), unit tangents (M, 3) and lengths [m] (M,)."""
    r0 = structure.positions()
    starts = np.array([r0[m.start] for m in structure.members])
    chords = np.array([r0[m.end] for m in structure.members]) - starts
    lengths = np.linalg.norm(chords, axis=1)
    return starts, chords / lengths[:, None], lengths


def _self_geometry(
    model, places: np.ndarray, rest: np.ndarray, radius: float, partly: np.ndarray
) -> SelfContactGeometry:
    """The rod's cells as global node indices (every rank's, gathered) and its nodes' arc
    lengths, for the self-contact search; the Verlet margin 2r (rebuilt when a node has moved
    2r/(1 + Λ_k)). On a structure its members (self_contact.Members) instead of the arc
    lengths, and each joint's copy replaced in the cells by its master: the copy's position
    is its master's (the joint's rows), and a reaction (P.2) on its cells then reaches the
    master's balance rows, which (C.1) (nls/constraints.py, applied before the contact's rows
    in nls/newton.py) made the node's whole balance. ``partly`` (owned): the nodes a support
    holds in part (a sliding node: no slave, nor its cells' nodes)."""
    V = model.V
    comm = V.mesh.comm
    partly = np.concatenate(comm.allgather(np.asarray(partly, dtype=bool)))
    imap = V.dofmap.index_map
    cells = model.msh.topology.index_map(model.msh.topology.dim).size_local
    local = np.array([V.dofmap.cell_dofs(c) for c in range(cells)], dtype=np.int32)
    dofs = imap.local_to_global(local.ravel()).reshape(local.shape)
    every = np.vstack(comm.allgather(dofs)).astype(np.int64)
    structure = model.scene.structure
    if structure is None:
        return SelfContactGeometry(
            every, np.concatenate(comm.allgather(places)), radius, 2.0 * radius, partly=partly
        )
    master = np.arange(imap.size_global, dtype=np.int64)
    if structure.all_joints():  # each copy's master, global indices, every rank's
        masters, copies, _, _ = model.structure.joint_blocks(V, structure)
        mine = np.column_stack([copies, masters]).astype(np.int64) + imap.local_range[0]
        ties = np.vstack(comm.allgather(mine.reshape(-1, 2)))
        master[ties[:, 0]] = ties[:, 1]
    member = cell_members(structure, model.length, model.msh)[0][:cells]
    starts, tangents, lengths = _member_lines(structure)
    members = Members(
        np.concatenate(comm.allgather(member)),
        starts,
        tangents,
        lengths,
        np.vstack(comm.allgather(rest)),
    )
    return SelfContactGeometry(master[every], None, radius, 2.0 * radius, members, partly)
