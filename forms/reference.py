"""The rod at rest: a reference curve r0(s) and a reference frame d0_i(s), in UFL.

The paper's rod is straight at rest: r0 = s e3 and d0_i = e_i, so that v = (0, 0, 1) and
u = 0 there. A :class:`Reference` gives any other rest configuration by

* its **tangent** t0 = dr0/ds (a unit vector for an arc-length parameter; fixed basis), and
* its **frame** D0, row i the reference director d0_i in the fixed basis (orthonormal,
  right-handed; d0_1, d0_2 along the principal axes of the section).

The unknowns measure the motion from it (forms/general_form.py, "A reference configuration"):
p1..p3 = (r − r0)/ℓ, and the angles (θ, ψ, φ) the rotation Λ that turns the reference
directors into the current ones, d_i = Λ d0_i, parametrised by (18) in space (Λᵀ = D(θ, ψ, φ),
times a chart's frame A, forms/kinematics.py). So the directors' matrix is D0 D A, and the
strains of (10)-(13) measured from the rest state are

    v − v0 = D0 (R r' − t0),   û − û0 = D0 κ_R,   R = D A,

with κ_R = Mm (θ', ψ', φ') + D κ̂ the curvature of R (forms/kinematics.py :func:`curvature`),
r' = t0 + (p1', p2', p3'). They vanish at rest (p = 0, R = I) for any t0 and D0, smooth or
not: the rest residual is zero by construction, D0' is never formed, and a frame that jumps at
a node (a corner) needs nothing else. (From D0 D A = Λᵀ-rotated rows: (D0 R)' (D0 R)ᵀ =
D0' D0ᵀ + D0 (R' Rᵀ) D0ᵀ, whose axial vector is û0 + D0 κ_R for a rotation D0.)

The shapes here are functions of σ = s/ℓ (a UFL scalar, e.g. the mesh's SpatialCoordinate),
each in a placement of its own (its docstring); :func:`placed` turns one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import ufl


@dataclass(frozen=True)
class Reference:
    """The rest configuration (module docstring): ``tangent`` t0(σ) = dr0/ds (UFL 3-vector,
    fixed basis, dimensionless) and ``frame`` D0(σ) (UFL 3×3, row i = d0_i); ``curvature``:
    its curvature u0 [1/m] in the reference directors' components where known in closed form
    (for outputs of the total curvature u = u0 + D0 κ_R/ℓ; the equations never need it)."""

    tangent: ufl.core.expr.Expr
    frame: ufl.core.expr.Expr
    curvature: ufl.core.expr.Expr | None = None


def straight() -> Reference:
    """The paper's rod: t0 = e3, D0 = I, u0 = 0."""
    return Reference(ufl.as_vector([0.0, 0.0, 1.0]), ufl.Identity(3), ufl.zero(3))


def circular_arc(sigma, length: float, radius: float) -> Reference:
    """A circular arc of ``radius`` [m] in the e1-e3 plane, from the origin along e3 and bending
    towards +e1: r0 = (R (1 − cos(s/R)), 0, R sin(s/R)), d0_3 = t0, d0_2 = e2, d0_1 = d0_2 × d0_3.
    Its curvature û0 = (0, ℓ/R, 0): bent about d0_2 (the ψ direction)."""
    a = length * sigma / radius
    c, s = ufl.cos(a), ufl.sin(a)
    tangent = ufl.as_vector([s, 0.0, c])
    frame = ufl.as_matrix([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
    return Reference(tangent, frame, ufl.as_vector([0.0, 1.0 / radius, 0.0]))


def helix(sigma, length: float, radius: float, pitch_angle: float) -> Reference:
    """A helix of coil ``radius`` R [m] and ``pitch_angle`` α [rad] (between the tangent and
    the plane normal to the axis) about the axis x = −R, y = 0 along e3, from the origin:
    r0 = (R (cos ks − 1), R sin ks, s sin α), k = cos α / R, in the Frenet frame: d0_3 = t0,
    d0_1 = the principal normal (towards the axis), d0_2 = the binormal. Its curvature
    û0 = ℓ (0, cos²α/R, sin α cos α/R) (bending about the binormal, twist)."""
    k = math.cos(pitch_angle) / radius
    ca, sa = math.cos(pitch_angle), math.sin(pitch_angle)
    a = k * length * sigma
    c, s = ufl.cos(a), ufl.sin(a)
    tangent = ufl.as_vector([-s * ca, c * ca, sa])
    normal = ufl.as_vector([-c, -s, 0.0])
    binormal = ufl.as_vector([s * sa, -c * sa, ca])
    frame = ufl.as_matrix(
        [
            [normal[j] for j in range(3)],
            [binormal[j] for j in range(3)],
            [tangent[j] for j in range(3)],
        ]
    )
    curvature = ufl.as_vector([0.0, ca * ca / radius, sa * ca / radius])
    return Reference(tangent, frame, curvature)


def curve(tangent, tangent_rate, director, director_rate) -> Reference:
    """A curve given by its unit tangent t0 = d0_3 and a unit director d0_1 ⊥ t0 (UFL
    3-vectors, fixed basis) and their derivatives in s [1/m]: D0 has the rows d0_1,
    d0_2 = d0_3 × d0_1, d0_3, and the curvature in the reference directors' components is
    u0_1 = d0_2'·d0_3, u0_2 = d0_3'·d0_1, u0_3 = d0_1'·d0_2: the components (5) of u0 in the
    frame's own derivative, d0_i' = u0 × d0_i (2)."""
    d1, d3 = director, tangent
    d2 = ufl.cross(d3, d1)
    d2_rate = ufl.cross(tangent_rate, d1) + ufl.cross(d3, director_rate)
    frame = ufl.as_matrix([[d[j] for j in range(3)] for d in (d1, d2, d3)])
    curvature = ufl.as_vector(
        [ufl.dot(d2_rate, d3), ufl.dot(tangent_rate, d1), ufl.dot(director_rate, d2)]
    )
    return Reference(tangent, frame, curvature)


def placed(reference: Reference, rotation) -> Reference:
    """The reference turned by the fixed rotation ``rotation`` (3×3 nested sequence or UFL
    matrix, R x in column form): t0 → R t0, d0_i → R d0_i (D0 → D0 Rᵀ)."""
    R = ufl.as_matrix(rotation) if not isinstance(rotation, ufl.core.expr.Expr) else rotation
    return Reference(R * reference.tangent, reference.frame * R.T, reference.curvature)
