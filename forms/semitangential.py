"""A semitangential end torque: a conservative torque ([loads.semitangential], declared by
cosserat_fem/scene/resolved.py SemitangentialEndTorque).

A torque kept in a fixed direction (a "dead" or axial torque, [loads.end].torque) is not
conservative in 3D: its virtual work M · δω (δω the end's virtual rotation, a spin) is not the
variation of a function of the end's rotation, so its load stiffness is not symmetric and the
two equal bending planes of a round shaft become a complex pair under the smallest torque
(docs/equilibrium-stability.md). Ziegler's semitangential torque (H. Ziegler, Principles of
Structural Stability, 1968; J. H. Argyris et al., Comput. Methods Appl. Mech. Eng. 17/18
(1979) 1, "semitangential moments"; the definition as it is commonly quoted, the sources were
not at hand) is a conservative one: when the end turns by a small rotation vector θ its vector
turns by half of it, M = M0 + ½ θ × M0, and it has the potential −M0 · θ to second order
(δθ = δω − ½ θ × δω + O(θ²) makes M0 · δθ = (M0 + ½ θ × M0) · δω).

Here it is the torque of the potential

    V(R) = −|M0| τ(R),    τ = 2 atan2(q · e, q0),    e = M0/|M0|,

with R the end's rotation from its rest state (rest directors to current ones), (q0, q) its
unit quaternion and τ the twist angle about e of R's swing–twist decomposition (τ = θ · e +
O(|θ|³) for R = exp(θ×): the semitangential torque). The torque it exerts, M with
M · δω = |M0| δτ for a spatial spin δω (δq0 = −½ δω · q, δq = ½ (q0 δω + δω × q)), is

    M = |M0|² (Q0² M0 + Q0 Qv × M0 + (Qv · M0) Qv) / (Q0² |M0|² + (Qv · M0)²),

with any multiple (Q0, Qv) of the quaternion (the expression is homogeneous of degree 0 in
it), so no square root or inverse trigonometric function enters. Two multiples are used, each
where it is the larger (Shepperd's choice): 4 q0 (q0, q) = (1 + tr R, s), s = (R32 − R23,
R13 − R31, R21 − R12), which vanishes at a rotation by π, and 4 (q · M0) (q0, q) =
(M0 · s, (R + Rᵀ) M0 − (tr R − 1) M0), which vanishes where the twist about M0 is zero; the
first is taken where 4 q0² = 1 + tr R ≥ 4 (q · e)² = 2 e · R e − tr R + 1 (a shaft twisted
through π, as Greenhill's cantilever is at its critical torque, needs the second). M = M0
when R turns about e (a twisted, straight shaft keeps its axial torque), and M = M0 +
½ θ × M0 + O(|θ|²) for small θ. R is the transpose of the directors' matrix
(forms/kinematics.py :func:`directors`, rows d_i, in a chart D A): on a rod curved at rest the
directors are D0 D (forms/follower.py), the rest ones D0, and R = (D0 D)ᵀ D0 = Dᵀ again. M is
then the fixed end torque l^b of the general form's end data (forms/general_form.py
:func:`end_data`: the moment rows take d_i · M). Its Jacobian is UFL's derivative of this form,
exact; the torque is conservative (its work is the variation of V), so a round shaft's bending
frequencies stay real until one crosses zero.

Singular only where q0 = q · e = 0: a rotation by π about an axis normal to M0 (and M0 = 0,
which is taken as no torque).

Tests: tests/test_greenhill.py (Greenhill's shaft under an axial force and this torque against
the critical combination derived there; the torque of a twisted shaft stays axial).
"""

from __future__ import annotations

import ufl

from .general_form import EndLoads, LoadContext, end_data
from .kinematics import directors, split


def semitangential_torque(R, M0) -> ufl.core.expr.Expr:
    """The torque M [N m] (fixed basis) of the potential −|M0| τ(R) at the end rotation ``R``
    (3×3, the rest directors to the current ones), ``M0`` the torque at rest (module
    docstring); 0 where M0 = 0."""
    trace = ufl.tr(R)
    s = ufl.as_vector([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    m2 = ufl.dot(M0, M0)
    # 4 q0 (q0, q) where q0² ≥ (q · e)², else 4 (q · M0) (q0, q) (module docstring)
    first = ufl.ge((1.0 + trace) * m2, 2.0 * ufl.dot(M0, R * M0) - (trace - 1.0) * m2)
    Q0 = ufl.conditional(first, 1.0 + trace, ufl.dot(M0, s))
    Qv = ufl.conditional(first, s, (R + R.T) * M0 - (trace - 1.0) * M0)
    along = ufl.dot(Qv, M0)
    denominator = Q0**2 * m2 + along**2
    safe = ufl.conditional(ufl.gt(denominator, 0.0), denominator, 1.0)
    return m2 * (Q0**2 * M0 + Q0 * ufl.cross(Qv, M0) + along * Qv) / safe


def residual(load, context: LoadContext) -> ufl.Form | None:
    """The semitangential torque's term of the weak residual, −g_b · v_q at its end (None if
    zero); ``load`` has ``end`` ("start" or "end") and ``torque`` (its components at rest in
    the fixed basis e1, e2, e3, expressions of t)."""
    torque = context.vector(load.torque)
    if torque is None:
        return None
    p, vq = split(context.U)[0], split(context.V)[1]
    R = directors(p, context.chart).T
    fixed = EndLoads(ds=context.ds[load.end], torque=semitangential_torque(R, torque))
    data = end_data(p, context.groups, fixed, context.convention, context.chart)
    return -ufl.inner(data, vq) * fixed.ds
