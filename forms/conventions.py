"""The conventions where the paper's equations are inconsistent (docs/errata.md), by name:
the one list of each, for the equations (forms/general_form.py, forms/groups.py) and the
scene's schema (cosserat_fem/scene/schema.py). Pure Python, so that reading a scene needs no UFL.

* ``TORSION_INERTIAS``: the rotary inertia of the torsion row (erratum 1, forms/groups.py):
  "polar", I3 = c11 + c22 (46), or "printed", I3 = c33 as in (54);
* ``END_LOAD_SIGNS``: the sign of the free-end data g_b (erratum 2): "balance", n(ℓ) = f^b
  (section 5), or "printed", eqs. (41), (44)-(45), (56)-(61); by name, the factor on g_b;
* ``END_LOAD_SCALINGS``: the scaling of g_b (erratum 3): "balance", (g0/ℓ, g_i/ℓ), or
  "printed", eq. (62).

The first of each is the default.
"""

TORSION_INERTIAS = ("polar", "printed")
END_LOAD_SIGNS = {"balance": 1.0, "printed": -1.0}
END_LOAD_SCALINGS = ("balance", "printed")
