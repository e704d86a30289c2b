"""A follower end force and torque: loads that turn with the end's directors ([loads.follower],
declared by cosserat_fem/scene/resolved.py FollowerEndLoad).

Given by their components along the directors d_k of the loaded end, F = (F1, F2, F3) [N] and
M = (M1, M2, M3) [N m], they are, in the fixed basis,

    f^b = Σ_k F_k d_k = Dᵀ F,        l^b = Σ_k M_k d_k = Dᵀ M,

with D the directors' matrix (rows d_k, forms/kinematics.py :func:`directors`, in the
chart), evaluated at the end. They then enter the free-end data g_b of the general form exactly
as the fixed end loads of (42) do (forms/general_form.py :func:`end_data`, with its sign and
scaling convention): the force rows take f^b = Dᵀ F, which turns with the end, and the moment
rows take l^b_i = d_i · l^b = M_i, the torque's director components, which are constant. The
term depends on the state through D only; its Jacobian is UFL's derivative of this form, exact
(not symmetric: a follower force is not conservative).

On a rod curved at rest (forms/reference.py) the directors' matrix is D0 D: d_i = Σ_j D0_ij λ_j,
λ_j the rows of D (those the moment rows are written in) and D0 the rest frame at the end. So
f^b = Dᵀ (D0ᵀ F) and l^b = Dᵀ (D0ᵀ M): the given components are turned by D0ᵀ first, and the
moment rows take (D0ᵀ M)_j = λ_j · l^b.

Tests: tests/test_follower.py (a follower torque rolls a cantilever into the circle of radius
E c22 / M; a tangential follower force against a fixed one, the beam-column closed forms; on a
rod curved at rest, a follower torque against the fixed torque of the tip's directors, which
fails without D0ᵀ).
"""

from __future__ import annotations

import ufl

from .general_form import EndLoadConvention, EndLoads, LoadContext, end_data
from .kinematics import directors, split


def residual(load, context: LoadContext) -> ufl.Form | None:
    """The follower load's term of the weak residual, −g_b · v_q at its end (None if zero);
    ``load`` has ``end`` ("start" or "end") and ``force``, ``torque`` (director components,
    expressions of t)."""
    force, torque = context.vector(load.force), context.vector(load.torque)
    if force is None and torque is None:
        return None
    if context.reference is not None:  # components along D0 D's rows: along D's, D0ᵀ F
        frame = context.reference.frame
        force = frame.T * force if force is not None else None
        torque = frame.T * torque if torque is not None else None
    return turning(force, torque, context, context.ds[load.end])


def turning(force, torque, context: LoadContext, ds: ufl.Measure, interior: bool = False):
    """The term −g_b · v_q of a force F and a torque M (UFL 3-vectors or None) given by their
    components along the rows λ_k of D (the directors' of a straight rod; at a structure's
    node the fixed basis at rest, turned by the node's rotation Λ = Dᵀ), on the measure ``ds``
    of an end or, ``interior``, the interior facet of a node (evaluated on its '+' side, the
    sign and scaling as a point load's: forms/general_form.py residual_terms)."""
    p, vq = split(context.U)[0], split(context.V)[1]
    D = directors(p, context.chart)
    fixed = EndLoads(
        ds=ds,
        force=D.T * force if force is not None else None,
        torque=D.T * torque if torque is not None else None,
        interior=interior,
    )
    if interior:
        convention = EndLoadConvention(scaling=context.convention.scaling)
        data = end_data(p, context.groups, fixed, convention, context.chart)
        return (-ufl.inner(data, vq))("+") * ds
    data = end_data(p, context.groups, fixed, context.convention, context.chart)
    return -ufl.inner(data, vq) * ds
