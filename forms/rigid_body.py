"""A rigid body carried by an end of the rod ([loads.body], declared by
cosserat_fem/scene/resolved.py RigidBody): its weight and its inertia act on the end.

The body is fixed to the end's section: its centre of mass C lies at the ``offset`` c from the
end's centroid and it turns with the end's directors. With c and the inertia tensor J_C about
C given in the components of the end's directors at rest (d0_i; d0_i = e_i for the straight
rod), and the end's position r, directors' matrix R (rows λ_j, forms/kinematics.py
:func:`directors`; D0 R on a rod curved at rest, forms/reference.py), angular velocity ω and
acceleration α, the body's centre and its acceleration are, in the fixed basis,

    r_C = r + c_s,   c_s = Rᵀ D0ᵀ c,                                             (B1)
    a_C = r̈ + α × c_s + ω × (ω × c_s),                                          (B2)

and the body exerts on the end the force and the moment about the end's centroid

    f^b = m (g − a_C),                                                          (B3)
    l^b = c_s × f^b − Rᵀ (J_λ ω̂̇ + ω̂ × J_λ ω̂),   J_λ = D0ᵀ J_C D0,              (B4)

(Newton and Euler for the body, J_λ ω̂ its angular momentum about C in the components of the
rows λ_j, ω̂ = Mm (θ̇, ψ̇, φ̇) (26), ω̂̇ = Mm (θ̈, ψ̈, φ̈) + Ṁm (θ̇, ψ̇, φ̇)). In the solver's
units r̈ = ℓ ω0² (q̇1, q̇2, q̇3), ω = ω0 Rᵀ ω̂, α = ω0² Rᵀ ω̂̇ (the rows λ_j turn with ω, so
d/dt (Rᵀ ω̂) = Rᵀ ω̂̇). f^b [N] and l^b [N m] then enter the end's data g_b exactly as an
end load in fixed directions (forms/general_form.py :func:`end_data`, the balance convention:
the body is new physics, not one of the paper's printed conventions). The term depends on q̇,
so the integrators' and the modes' mass matrices (UFL's derivative with respect to the rates)
carry the body's mass and inertia; in statics (q = q̇ = 0) only its weight remains, which the
load factor scales as the rod's own.

The body's energy (for tests of the balance, tests/rod_energy.py) is
T_B = ½ m |v_C|² + ½ ω̂ · J_λ ω̂ (v_C = ṙ + ω × c_s) and its weight's potential −m g · r_C.

Tests: tests/test_rigid_body.py (a cantilever's frequencies with a tip mass, its rotary
inertia and an offset against the Euler–Bernoulli frequency equation solved in the test; a
static tip weight against the end force it equals; the energy of a free swing).
"""

from __future__ import annotations

import ufl

from .general_form import EndLoadConvention, EndLoads, LoadContext, end_data
from .kinematics import angles, angular_map, angular_map_rate, directors, split, translations


def body_frame(J, c, context: LoadContext):
    """(J_λ, c_λ): the body's inertia [kg m²] and offset [m] in the components of the rows λ_j
    of R (J_λ = D0ᵀ J D0, c_λ = D0ᵀ c; unchanged on the straight rod)."""
    J, c = ufl.as_matrix(J), ufl.as_vector(c)
    if context.reference is None:
        return J, c
    D0 = context.reference.frame
    return D0.T * J * D0, D0.T * c


def end_force_and_moment(load, context: LoadContext):
    """(f^b [N], l^b [N m]) of (B3), (B4) in the fixed basis, UFL 3-vectors."""
    p, q = split(context.U)
    qdot = split(context.Udot)[1]
    ell, w0 = context.groups.length, context.omega0
    J, c = body_frame(load.inertia_tensor(), load.offset_vector(), context)
    R = directors(p, context.chart)
    mm = angular_map(p[3], p[5])
    w_hat = mm * angles(q)
    wdot_hat = mm * angles(qdot) + angular_map_rate(p[3], p[5], q[3], q[5]) * angles(q)
    c_s = R.T * c
    omega, alpha = w0 * (R.T * w_hat), w0 * w0 * (R.T * wdot_hat)
    a_C = ell * w0 * w0 * translations(qdot) + ufl.cross(alpha, c_s)
    a_C = a_C + ufl.cross(omega, ufl.cross(omega, c_s))
    force = -load.mass * a_C
    if context.gravity is not None:
        force = force + load.mass * context.gravity
    euler = w0 * w0 * (J * wdot_hat + ufl.cross(w_hat, J * w_hat))
    return force, ufl.cross(c_s, force) - R.T * euler


def residual(load, context: LoadContext) -> ufl.Form:
    """The term of a body at the rod's end ``load.end`` ([loads.body]): :func:`body_term`."""
    return body_term(load, context, context.ds[load.end])


def body_term(load, context: LoadContext, ds: ufl.Measure, interior: bool = False) -> ufl.Form:
    """The body's term of the weak residual, −g_b · v_q over the point measure ``ds`` with the
    f^b, l^b of (B3), (B4): an end's ds, or with ``interior`` a node's interior facet dS
    between two cells (a structure's chain), evaluated on one side (the fields are
    continuous there), as a point load is (forms/general_form.py ``EndLoads``)."""
    force, moment = end_force_and_moment(load, context)
    p, vq = split(context.U)[0], split(context.V)[1]
    end = EndLoads(ds=ds, force=force, torque=moment, interior=interior)
    data = end_data(p, context.groups, end, EndLoadConvention(), context.chart)
    term = -ufl.inner(data, vq)
    return (term("+") if interior else term) * ds


def kinetic_energy(load, context: LoadContext):
    """T_B = ½ m |v_C|² + ½ ω · J ω [J] at the body's end (module docstring), a UFL scalar to
    integrate over that end's ds."""
    p, q = split(context.U)
    ell, w0 = context.groups.length, context.omega0
    J, c = body_frame(load.inertia_tensor(), load.offset_vector(), context)
    R = directors(p, context.chart)
    w_hat = angular_map(p[3], p[5]) * angles(q)
    v_C = ell * w0 * translations(q) + w0 * ufl.cross(R.T * w_hat, R.T * c)
    return 0.5 * load.mass * ufl.dot(v_C, v_C) + 0.5 * w0 * w0 * ufl.dot(w_hat, J * w_hat)
