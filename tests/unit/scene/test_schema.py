"""The names a scene may choose and the modules that implement them agree.

The schema (cosserat_fem/scene/schema.py) must stay light (``validate`` imports neither UFL nor
DOLFINx), so where the implementing module is heavy (the integrators, the Newton policies,
the XDMF fields) the schema spells the names out, and this test holds them equal to the
implementers' own registries; where it is light (forms/conventions.py, forms/section.py) the
schema imports the one list. Exact comparisons: names, not numbers.
"""

from __future__ import annotations

import pytest
from cosserat_fem.forms.conventions import END_LOAD_SCALINGS, END_LOAD_SIGNS, TORSION_INERTIAS
from cosserat_fem.forms.section import TORSION_CONSTANT_RULES

from cosserat_fem.io.xdmf import FIELD_ARRAYS
from cosserat_fem.nls.newton import JACOBIAN_POLICIES
from cosserat_fem.scene.schema import SCHEMA, XDMF_DEFAULT_FIELDS, XDMF_FIELDS
from cosserat_fem.timestepping.integrators import INTEGRATORS

pytestmark = pytest.mark.unit


def spec(key: str):
    table = SCHEMA
    for name in key.split("."):
        table = table.fields[name]
    return table


@pytest.mark.parametrize(
    ("key", "names"),
    [
        ("time.integrator", tuple(n for n in INTEGRATORS if n != "static")),
        ("solver.jacobian", JACOBIAN_POLICIES),
        ("output.fields", tuple(FIELD_ARRAYS)),
        ("model.torsion_inertia", TORSION_INERTIAS),
        ("model.end_load_sign", tuple(END_LOAD_SIGNS)),
        ("model.end_load_scaling", END_LOAD_SCALINGS),
        ("rod.section.torsion_constant", TORSION_CONSTANT_RULES),
    ],
)
def test_the_schema_offers_what_is_implemented(key, names):
    assert tuple(spec(key).choices) == tuple(names)


def test_the_xdmf_fields_default_to_all():
    assert spec("output.fields").default == XDMF_DEFAULT_FIELDS == XDMF_FIELDS[:4]
