"""A riser (a heavy slender cable) hanging onto a frictionless seabed: the touchdown point and
the top tension against the elastic catenary (issue 30; docs/contact.md, "The riser's
touchdown"; the closed forms: cosserat_fem/reference/catenary.py (K.1)-(K.4)).

The cable: L = 6 m, circle d = 5 mm (or 10 mm), E = 1e7 Pa, ν = 0.3, ρ = 1000 kg/m³ (the
submerged weight w = ρ A g), straight at rest along e3 on the plane x = −r (gravity along −e1),
pinned at its anchor s = 0. Statics refuses a prescribed support motion (analysis/statics.py),
so the top s = L carries its tension instead: the dead force F = (V, 0, H), H = a w (a = 2 m)
and V = S0 w (S0 = 2.2 m, the suspended length; V < w L/2, else small loads would first lift
the whole rod about its anchor). Its static state has the top at some (h, X_top), so it is the
equilibrium of the cable held there, with the reaction F: the position-controlled closed form
(from_top_position) is checked with the measured top position as its input and the known |F|
as the tension it must give. Frictionless (μ = 0): the load path does not matter.

Bending: the boundary layer λ = sqrt(EI/H) = 28 mm at d = 5 mm (λ/S0 = 1.3e-2; the shear
layer sqrt(EI/κGA) = 2.1 mm). By (K.4) the touchdown point is at s* = L − S0 − λ, and the top
is moved by δX_top = 0.2226 λ² = 0.18 mm and δh = −0.0512 λ² = −41 µm from the cable's: this
problem is sensitive (the slack L − X_top is 0.29 m), and these O(λ²) moves shift the tension
the catenary gives for the measured top by 7.3e-4. The strain H/EA = 2e-3 is not negligible
either: the inextensible catenary for the same top gives a tension 7 % off (the 12 mm stretch
is a large part of the slack), and (K.3)'s stretch terms are 8e-4 of T_top; the elastic one is
used throughout.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from mpi4py import MPI

from cosserat_fem.analysis.statics import static_path
from cosserat_fem.reference.catenary import (
    bending_shift,
    from_top_force,
    from_top_position,
    top_tension,
)
from cosserat_fem.scene.build import scene_from_dict

L, RHO, E, G, NU = 6.0, 1000.0, 1e7, 9.81, 0.3
SPAN, HANGING = 2.0, 2.2  # a = H/w and S0 = V/w [m]
GLL3 = 0.5 - math.sqrt(5) / 10  # P3's GLL node in a cell of unit length (0, 0.276, 0.724, 1)


@functools.cache
def riser(diameter: float, elements: int) -> dict:
    """The cable of the module docstring solved by statics with contact, 10 load steps; its
    figures. Newton may take 200 iterations: the first step's solve starts from the rod lying
    flat, and its lift-off front moves a node or two an iteration to the small-load lifted
    length 2V/w = 4.4 m from the top, which does not depend on the load's size (so a smaller
    step does not help; 51 iterations at 40 cells, 94 at 80, then 2-14 a step)."""
    area, inertia = math.pi * diameter**2 / 4, math.pi * diameter**4 / 64
    w = RHO * area * G
    H, V = SPAN * w, HANGING * w
    data = {
        "rod": {
            "length": L,
            "section": {"shape": "circle", "diameter": diameter},
            "material": {"density": RHO, "young_modulus": E, "poisson_ratio": NU},
        },
        "supports": {"start": "pinned", "end": "free"},
        "loads": {"gravity": [-G, 0, 0], "end": {"force": [V, 0, H]}},
        "static": {"load_steps": 10},
        "solver": {"max_iterations": 200},
        "time": {"end": 1.0, "step": 1.0},
        "discretisation": {"elements": elements, "degree": 3},
        "contact": {
            "obstacles": [{"kind": "plane", "point": [-diameter / 2, 0, 0], "normal": [1, 0, 0]}],
            "static_friction": 0.0,
        },
    }
    result = static_path(scene_from_dict(data), comm=MPI.COMM_SELF, write_outputs=False)
    model = result.model
    layout, u = model.layout, model.U.x.array
    bs = layout.size
    s = model.V.tabulate_dof_coordinates()[: u.size // bs, 0] * L
    x = np.zeros((s.size, 3))
    x[:, 2] = s
    for k in range(3):
        slot = layout.index(k)
        if slot is not None:
            x[:, k] += u[slot::bs] * L
    order = np.argsort(s)
    s, x = s[order], x[order]
    EI, EA = E * inertia, E * area
    kappa_GA = 0.9 * E / (2 * (1 + NU)) * area  # κ ≈ 0.9: the shear layer's size only
    touching = x[:, 0] <= 1e-12
    last = int(np.flatnonzero(touching).max())
    return {
        "w": w,
        "EA": EA,
        "EI": EI,
        "H": H,
        "V": V,
        "lam": math.sqrt(EI / H),
        "shear_layer": math.sqrt(EI / kappa_GA),
        "x": x,
        "last": s[last],
        "spacing": (1 - 2 * GLL3) * L / elements,  # the largest gap between P3 nodes
        "iterations": result.iterations,
    }


def top_tension_held(c: dict, bending: bool = False) -> float:
    """T_top [N] of the elastic catenary held at the measured top, less (K.4)'s moves by the
    bending stiffness if ``bending``, over |F|, minus one."""
    dX, dh = bending_shift(c["w"], c["H"], c["V"], c["EI"]) if bending else (0.0, 0.0)
    held = from_top_position(c["w"], c["EA"], L, c["x"][-1, 0] - dh, c["x"][-1, 2] - dX)
    return held.T_top / math.hypot(c["H"], c["V"]) - 1


def touchdown_bound(c: dict) -> float:
    """The touchdown node's distance [m] from s* = L − S0 − λ: the contact holds the nodes only,
    so the front is resolved to a node spacing Δ; with the next order λ²/a and the shear layer
    sqrt(EI/κGA), over which the seabed's point reaction spreads."""
    return c["spacing"] + c["lam"] ** 2 / SPAN + c["shear_layer"]


def test_the_riser_touches_down_and_pulls_its_top_as_the_elastic_catenary():
    """d = 5 mm (λ = 28.2 mm), 40 cubic cells (nodes up to Δ = 0.447 · 0.15 m = 67 mm apart):

    (a) the touchdown point, the last node in contact s_c, is within Δ + λ²/a + sqrt(EI/κGA)
    = 70 mm of s* = L − S0 − λ (measured s_c − s* = −22 mm), hence within λ more of the
    catenary's L − S0 for the measured top (bound 98 mm, measured −49 mm);
    (b) the top tension: the elastic catenary held at the measured top gives |F| within 1e-3
    (measured 6.4e-4: the bending's O(λ²) moves of the top (K.4) make 7.3e-4 of it); held
    there less (K.4)'s moves, within 3e-4 (measured −8.8e-5: the O(λ³) remainder, −1.2e-4 at
    λ = 56 mm where the mesh no longer matters and 8× less here, and the discretisation's
    error of the height: the contact at the nodes, |h − δh − h_cable| ≤ 3.4e-5 m over 40-160
    cells, ~9e-5 of T_top through the closed form); and (K.3) at the measured height gives
    |F| within 1e-4 (measured −2.5e-5: the top's axial force N_t = |F| (1 − (κ_t λ_t)²/2),
    −1.4e-5, and the discretisation's; the stretch's terms of (K.3), 8e-4, would not pass);
    (c) no node below the seabed (x ≥ −1e-12 m; measured −2e-19 m: the gap rows hold to
    round-off)."""
    c = riser(0.005, 40)
    w, EA, H, V, lam = c["w"], c["EA"], c["H"], c["V"], c["lam"]
    h, X_top = c["x"][-1, 0], c["x"][-1, 2]
    held = from_top_position(w, EA, L, h, X_top)
    # (a)
    assert abs(c["last"] - (L - HANGING - lam)) <= touchdown_bound(c), c["last"]
    assert abs(c["last"] - held.touchdown_s) <= lam + touchdown_bound(c), held.touchdown_s
    # (b)
    assert abs(top_tension_held(c)) < 1e-3, top_tension_held(c)
    assert abs(top_tension_held(c, bending=True)) < 3e-4, top_tension_held(c, bending=True)
    assert abs(top_tension(w, EA, H, h) / math.hypot(H, V) - 1) < 1e-4
    # (c)
    assert c["x"][:, 0].min() >= -1e-12


def test_the_top_moves_by_the_bending_shift_of_order_lambda_squared():
    """With d = 10 mm and 5 mm (λ = 56.4 and 28.2 mm; a, S0 and the strain H/EA the same, so
    the cable is the same), 40 cubic cells: the top's horizontal distance minus the elastic
    catenary's for the force F (from_top_force) is (K.4)'s δX_top = 0.2226 λ² (0.71 and
    0.18 mm) to O(λ³): its relative error O(λ/a) (bound 2λ/a: 5.6 % and 2.8 %; measured
    −2.8 % and −0.8 %), falling with λ. The discretisation's part is below 1 % of it (40
    against 80 cells: 1.7596e-4 against 1.7478e-4 m at d = 5 mm)."""
    errors = []
    for d in (0.01, 0.005):
        c = riser(d, 40)
        cable = from_top_force(c["w"], c["EA"], L, c["H"], c["V"])
        shift = bending_shift(c["w"], c["H"], c["V"], c["EI"])[0]
        error = (c["x"][-1, 2] - cable.X_top) / shift - 1
        assert abs(error) <= 2 * c["lam"] / SPAN, (d, error)
        errors.append(abs(error))
    assert errors[1] < errors[0]


@pytest.mark.long
def test_the_riser_converges_under_refinement():
    """d = 5 mm at 40, 80 and 160 cubic cells: the touchdown node within its bound Δ + λ²/a +
    sqrt(EI/κGA) of s* on each mesh, the bound halving with Δ (70, 36, 19 mm; measured −22,
    −1.0, +5.4 mm); the top tension of the catenary held at the measured top less (K.4)'s
    moves within 3e-4 of |F| on each (test above; measured −8.8e-5, 4.4e-5, −2.6e-6), and at
    160 cells below a quarter of its error at 40 (the discretisation's part falls, though not
    monotonically: where the nodes fall about the touchdown point decides the contact's
    error)."""
    errors = []
    for n in (40, 80, 160):
        c = riser(0.005, n)
        assert abs(c["last"] - (L - HANGING - c["lam"])) <= touchdown_bound(c), (n, c["last"])
        errors.append(abs(top_tension_held(c, bending=True)))
        assert errors[-1] < 3e-4, (n, errors)
    assert errors[2] < errors[0] / 4, errors
