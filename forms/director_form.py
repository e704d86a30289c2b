"""The balance laws (6) in vector/director form, written directly in UFL.

This is a second, independent construction of the residual of :mod:`.general_form`, used by
the tests to check that form term by term. It shares nothing with it but the unknown:

* the directors are the rows of the product Dφ Dθ Dψ of the elementary rotations (15)-(17)
  (not the multiplied-out (18));
* the curvature is u = ½ Σ d_i × ∂s d_i (3) and the angular velocity w = ½ Σ d_i × ∂t d_i (4),
  with ∂t d_i and ∂tt d_i by UFL's chain rule through the Euler angles (not (25)-(26), (64));
* the constitutive laws are the tensors (9)-(10): n = Σ K_ii (v·d_i − δ_i3) d_i,
  m = Σ J_ii (u·d_i) d_i, h = Σ I_ii (w·d_i) d_i with I33 = ρ (c11 + c22) (46), or the
  rotary inertias given apart from the section (``RodConstants.mass_inertias``); with a
  general section law (``RodConstants.law``, forms/section.py) n = Σ n_i d_i and
  m = Σ m_i d_i with (n_i, m_i) of forms/resultants.py ``section_law`` (the one place the law
  is written) on the strains v·d_i − v0_i, u·d_i − u0_i, its μ(σ) and I_ii(σ) in the inertia;
* the scaled stiffnesses come from the physical constants, not from the groups (48);
* in a chart of quaternions Q(σ), the directors are the rows of that product times the frame
  Aᵀ = (n0² − |n|²) I + 2 n nᵀ + 2 n0 [n]× of the normalised quaternion (n0, n) = Q/|Q|
  (Euler–Rodrigues; not kinematics.py's quaternion_frame, nor its frame curvature κ̂).

Units: length ℓ, time 1/ω0, force F* = ρ A ℓ² ω0². The weak form is the principle of virtual
work for (6),

    ∫ (r̈ − f)·δr + n·δr' + (∂t h − v × n − l)·δϑ + m·δϑ' dσ − Σ_free ends (f^b·δr + l^b·δϑ),

with δr = (v7, v8, v9) and δϑ = Σ_i v_{9+i} d_i / Î_i, which is (65) row by row.
"""

from __future__ import annotations

import ufl

from .general_form import retardation_times
from .groups import RodConstants
from .kinematics import split
from .resultants import section_law, stiffness_matrix


def _elementary_rotations(theta, psi, phi):
    """(15), (16), (17)."""
    c, s = ufl.cos, ufl.sin
    d_psi = ufl.as_matrix([[c(psi), 0.0, -s(psi)], [0.0, 1.0, 0.0], [s(psi), 0.0, c(psi)]])
    d_theta = ufl.as_matrix(
        [[1.0, 0.0, 0.0], [0.0, c(theta), s(theta)], [0.0, -s(theta), c(theta)]]
    )
    d_phi = ufl.as_matrix([[c(phi), s(phi), 0.0], [-s(phi), c(phi), 0.0], [0.0, 0.0, 1.0]])
    return d_phi * d_theta * d_psi


def _euler_rodrigues_frame(Q):
    """The frame matrix (row j = a_j) of the normalised quaternion Q/|Q| (module docstring)."""
    n = Q / ufl.sqrt(ufl.dot(Q, Q))
    v = ufl.as_vector([n[1], n[2], n[3]])
    cross = ufl.as_matrix([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    R = (n[0] ** 2 - ufl.dot(v, v)) * ufl.Identity(3) + 2.0 * ufl.outer(v, v) + 2.0 * n[0] * cross
    return R.T


def _rows(M):
    return [ufl.as_vector([M[i, j] for j in range(3)]) for i in range(3)]


def _axial(ds, dds):
    """½ Σ d_i × d_i^(•) for director lists ds and their derivatives dds, eqs. (3)-(4)."""
    return 0.5 * sum((ufl.cross(d, dd) for d, dd in zip(ds, dds, strict=True)), ufl.zero(3))


def director_residual_terms(
    U,
    Udot,
    V,
    rod: RodConstants,
    dx: ufl.Measure,
    force_density=None,
    torque_density=None,
    end_loads: tuple = (),
    viscous_damping: tuple[float, float] | None = None,
    retardation_time: float | tuple[float, ...] | None = None,
    chart_quaternion=None,
    reference=None,
) -> dict[str, ufl.Form]:
    """Residual of (6) in director form, split like :class:`.general_form.ResidualTerms`.

    force_density f [N/m], torque_density l [N m/m]: UFL 3-vectors in the fixed basis or None.
    end_loads: tuples (ds, f^b [N] or None, l^b [N m] or None).
    viscous_damping (c_t [N s/m²], c_r [N s]): the densities f_d = −c_t ∂t r and l_d = −c_r w,
    term ``damping``. retardation_time τ_d [s], or six μ_1..μ_6 [s] (strain order,
    docs/sections.md §1; τ_d is μ_i = τ_d): Kelvin–Voigt contact force and torque
    n_v = Σ μ_i K_ii ∂t(∂s r · d_i) d_i, m_v = Σ μ_{3+i} J_ii ∂t(u · d_i) d_i, or with a law
    row i of its K times μ_i (BeamDyn's diag(μ) K), term ``kelvin_voigt``, with
    ∂t(u · d_i) = ∂t u · d_i + u · ∂t d_i and ∂t u = ½ Σ (∂t d_i × ∂s d_i + d_i × ∂s ∂t d_i)
    from (3). chart_quaternion: a UFL 4-vector Q(σ), the angles measured from its frame
    (module docstring). reference: a forms.reference.Reference (t0, D0) of a rod curved at
    rest, for smooth t0 and D0: the directors are the rows of D0 times the rotation above
    (λ_j its rows), ∂s r = t0 + (p1', p2', p3'), and the strains are measured from those
    of the reference by (9)-(13):
    n = Σ K_ii (∂s r · d_i − t0 · d0_i) d_i, m = Σ J_ii (u · d_i − u0 · d0_i) d_i with
    u0 = ½ Σ d0_i × ∂s d0_i (3) (UFL's derivative of D0); the virtual rotation is
    δϑ = Σ_j v_{9+j} λ_j / Î_j (general_form.py, "A reference configuration").
    """
    sec = rod.section
    ell, rho, w0 = rod.length, rod.density, rod.omega0
    fstar = rho * sec.area * ell**2 * w0**2
    K = [sec.shear_coefficient * rod.shear_modulus * sec.area / fstar] * 2
    K.append(rod.young_modulus * sec.area / fstar)
    J = [
        rod.young_modulus * sec.c11 / (fstar * ell**2),
        rod.young_modulus * sec.c22 / (fstar * ell**2),
        rod.shear_modulus * sec.c33 / (fstar * ell**2),
    ]
    inertia = [i * w0**2 / fstar for i in rod.mass_inertias]
    # A general section law (forms/section.py): K/F* on the strains (v·d_i − v0_i, u·d_i − u0_i)
    # per unit σ (so the torque rows and the curvature columns carry 1/ℓ each), its μ and I
    # in the balance, the rod's inertias above still scaling the virtual rotation.
    law = rod.law
    if law is not None:
        stiff = stiffness_matrix(rod)
        K6 = [
            [stiff[a][b] / (fstar * ell ** ((a >= 3) + (b >= 3))) for b in range(6)]
            for a in range(6)
        ]
    mass = 1.0
    balance_inertia = inertia
    if law is not None and law.mass_per_length is not None:
        mass = law.mass_per_length / (rho * sec.area)
    if law is not None and law.inertia is not None:
        balance_inertia = [i * w0**2 / fstar for i in law.inertia]

    p, q = split(U)
    pdot, qdot = split(Udot)
    vp, vq = split(V)

    # Directors and their derivatives through the Euler angles (chain rule by UFL).
    ang = ufl.variable(ufl.as_vector([p[3], p[4], p[5]]))
    qa = ufl.as_vector([q[3], q[4], q[5]])
    qa_dot = ufl.as_vector([qdot[3], qdot[4], qdot[5]])
    D = _elementary_rotations(ang[0], ang[1], ang[2])
    if chart_quaternion is not None:
        D = D * _euler_rodrigues_frame(chart_quaternion)
    frame = _rows(D)  # λ_j, the frame of the virtual rotation
    if reference is not None:
        D = reference.frame * D
    i, j, k = ufl.indices(3)
    D_t = ufl.as_tensor(ufl.diff(D, ang)[i, j, k] * qa[k], (i, j))
    D_tt = ufl.as_tensor(ufl.diff(D, ang)[i, j, k] * qa_dot[k], (i, j)) + ufl.as_tensor(
        ufl.diff(D_t, ang)[i, j, k] * qa[k], (i, j)
    )
    d, d_t, d_tt = _rows(D), _rows(D_t), _rows(D_tt)
    d_s = [ufl.as_vector([di[m].dx(0) for m in range(3)]) for di in d]

    u = _axial(d, d_s)
    w = _axial(d, d_t)
    w_t = _axial(d, d_tt)
    r_s = ufl.as_vector([p[0].dx(0), p[1].dx(0), 1.0 + p[2].dx(0)])
    v0, u0 = [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]
    if reference is not None:
        t0 = reference.tangent
        r_s = t0 + ufl.as_vector([p[0].dx(0), p[1].dx(0), p[2].dx(0)])
        d0 = _rows(reference.frame)
        # grad of the whole matrix: a constant entry alone has no domain to differentiate in.
        a, b = ufl.indices(2)
        u_ref = _axial(d0, _rows(ufl.as_tensor(ufl.grad(reference.frame)[a, b, 0], (a, b))))
        v0 = [ufl.dot(t0, d0[a]) for a in range(3)]
        u0 = [ufl.dot(u_ref, d0[a]) for a in range(3)]

    if law is None:
        n = sum((K[a] * (ufl.dot(r_s, d[a]) - v0[a]) * d[a] for a in range(3)), ufl.zero(3))
        m = sum((J[a] * (ufl.dot(u, d[a]) - u0[a]) * d[a] for a in range(3)), ufl.zero(3))
    else:
        gamma = [ufl.dot(r_s, d[a]) - v0[a] for a in range(3)]
        kappa = [ufl.dot(u, d[a]) - u0[a] for a in range(3)]
        n_d, m_d = section_law(gamma, kappa, K6)
        n = sum((n_d[a] * d[a] for a in range(3)), ufl.zero(3))
        m = sum((m_d[a] * d[a] for a in range(3)), ufl.zero(3))
    h_t = sum(
        (
            balance_inertia[a]
            * ((ufl.dot(w_t, d[a]) + ufl.dot(w, d_t[a])) * d[a] + ufl.dot(w, d[a]) * d_t[a])
            for a in range(3)
        ),
        ufl.zero(3),
    )

    dr = ufl.as_vector([vq[0], vq[1], vq[2]])
    dth = sum((vq[3 + a] / inertia[a] * frame[a] for a in range(3)), ufl.zero(3))
    dr_s = ufl.as_vector([dr[a].dx(0) for a in range(3)])
    dth_s = ufl.as_vector([dth[a].dx(0) for a in range(3)])
    r_tt = ufl.as_vector([qdot[0], qdot[1], qdot[2]])

    terms: dict[str, ufl.Form] = {
        "kinematic": ufl.inner(pdot - q, vp) * dx,
        "inertia": (mass * ufl.dot(r_tt, dr) + ufl.dot(h_t, dth)) * dx,
        "elastic": (ufl.dot(n, dr_s) + ufl.dot(m, dth_s) - ufl.dot(ufl.cross(r_s, n), dth)) * dx,
    }
    if force_density is not None or torque_density is not None:
        load = 0
        if force_density is not None:
            load = load - ufl.dot(force_density * ell / fstar, dr)
        if torque_density is not None:
            load = load - ufl.dot(torque_density / fstar, dth)
        terms["distributed_load"] = load * dx
    end_form = None
    for ds, fb, lb in end_loads:
        if fb is None and lb is None:
            continue
        integrand = 0
        if fb is not None:
            integrand = integrand - ufl.dot(fb / fstar, dr)
        if lb is not None:
            integrand = integrand - ufl.dot(lb / (fstar * ell), dth)
        end_form = integrand * ds if end_form is None else end_form + integrand * ds
    if end_form is not None:
        terms["end_load"] = end_form
    if viscous_damping is not None:
        c_t, c_r = viscous_damping
        f_d = -c_t * ell * w0 * ufl.as_vector([q[0], q[1], q[2]])
        l_d = -c_r * w0 * w
        terms["damping"] = (-ufl.dot(f_d * ell / fstar, dr) - ufl.dot(l_d / fstar, dth)) * dx
    if retardation_time is not None:
        eta = [t * w0 for t in retardation_times(retardation_time)]
        r_st = ufl.as_vector([q[a].dx(0) for a in range(3)])
        d_st = [ufl.as_vector([dt[m].dx(0) for m in range(3)]) for dt in d_t]
        u_t = _axial(d_t, d_s) + _axial(d, d_st)
        v_rates = [ufl.dot(r_st, d[a]) + ufl.dot(r_s, d_t[a]) for a in range(3)]
        u_rates = [ufl.dot(u_t, d[a]) + ufl.dot(u, d_t[a]) for a in range(3)]
        if law is None:
            n_v = sum((eta[a] * K[a] * v_rates[a] * d[a] for a in range(3)), ufl.zero(3))
            m_v = sum((eta[3 + a] * J[a] * u_rates[a] * d[a] for a in range(3)), ufl.zero(3))
        else:
            nv_d, mv_d = section_law(v_rates, u_rates, K6)
            n_v = sum((eta[a] * nv_d[a] * d[a] for a in range(3)), ufl.zero(3))
            m_v = sum((eta[3 + a] * mv_d[a] * d[a] for a in range(3)), ufl.zero(3))
        terms["kelvin_voigt"] = (
            ufl.dot(n_v, dr_s) + ufl.dot(m_v, dth_s) - ufl.dot(ufl.cross(r_s, n_v), dth)
        ) * dx
    return terms
