"""Scenes, overrides and safe expressions (fast; no dolfinx)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import ufl

from cosserat_fem.common.errors import CosseratError, SceneError, SolverError
from cosserat_fem.scene.build import (
    auto_reference_frequency,
    load_scene,
    read_toml,
    scene_from_dict,
)
from cosserat_fem.scene.expressions import Expression, parse_vector

PAPER = Path(__file__).resolve().parents[1] / "scenes" / "cao_tucker_2008.toml"
PAPER_OMEGA0 = 207.0236
NAMES = {"s", "t", "L", "omega0"}


BASE = Path(__file__).resolve().parent / "data" / "base_scene.toml"


def paper_text() -> str:
    """The malformed cases edit a frozen copy of the paper scene (tests/data)."""
    return BASE.read_text(encoding="utf-8")


def write(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# ------------------------------------------------------------------------------ paper scene
def test_paper_scene_resolves() -> None:
    scene = load_scene(PAPER)
    E = 7.1e10
    assert scene.rod.length == 1.0
    assert (scene.rod.section.a, scene.rod.section.b) == (0.04, 0.06)
    assert scene.rod.section.shear_coefficient == 0.833
    assert scene.rod.material.shear_modulus == pytest.approx(E / (2 * 1.32), rel=1e-15)
    assert scene.rod.material.shear_modulus_value is None
    assert scene.model.reference_frequency == PAPER_OMEGA0
    assert scene.omega0 == PAPER_OMEGA0
    assert scene.expression_names() == {"L": 1.0, "omega0": PAPER_OMEGA0}
    assert scene.time.n_steps == round(0.06 / scene.time.step)
    assert scene.discretisation.quadrature_degree == 2 * scene.discretisation.degree
    assert scene.output.xdmf_every(scene.time.step) == round(
        scene.output.xdmf_interval / scene.time.step
    )
    assert scene.supports.start == "clamped" and scene.supports.end == "free"
    assert scene.loads.start is None and scene.loads.end is None
    assert scene.loads.force_density[2].is_zero
    assert all(e.is_zero for e in scene.loads.torque_density)
    assert scene.loads.force_density[0].depends_on("s")
    assert scene.source == str(PAPER)


def test_paper_load_value() -> None:
    scene = load_scene(PAPER)
    f1 = scene.loads.force_density[0]
    t = 0.3e-3
    expected = 2e3 * math.sin(math.pi * 0.5) * math.sin(8 * PAPER_OMEGA0 * t)
    assert f1.evaluate(s=0.5, t=t, **scene.expression_names()) == pytest.approx(expected)


def test_auto_reference_frequency_matches_paper() -> None:
    scene = load_scene(PAPER, ["model.reference_frequency=auto"])
    assert scene.model.reference_frequency is None
    assert auto_reference_frequency(scene.rod) == pytest.approx(PAPER_OMEGA0, rel=1e-6)
    assert scene.expression_names()["omega0"] == pytest.approx(PAPER_OMEGA0, rel=1e-6)


def test_round_trip_paper() -> None:
    scene = load_scene(PAPER)
    data = json.loads(json.dumps(scene.to_dict()))
    again = scene_from_dict(data)
    assert again == scene
    assert again.to_dict() == data


def test_round_trip_with_everything(tmp_path: Path) -> None:
    text = paper_text().replace("poisson_ratio = 0.32", "shear_modulus = 2.7e10")
    text += (
        '\n[parameters]\namp = 5.0\n\n[loads.end]\nforce = [0, "amp*ramp(t - 0.01)", 0]\n'
        'torque = ["1e2*heaviside(t-0.02)", 0, 0]\n'
    )
    path = write(tmp_path, text)
    scene = load_scene(
        path, ["model.reference_frequency=auto", "time.integrator=generalized-alpha"]
    )
    assert scene.parameters == {"amp": 5.0}
    assert scene.rod.material.shear_modulus == 2.7e10
    assert scene.loads.end is not None
    assert scene.loads.end.force[1].evaluate(t=0.03, amp=5.0) == pytest.approx(0.1)
    assert scene.expression_names()["amp"] == 5.0
    assert scene_from_dict(json.loads(json.dumps(scene.to_dict()))) == scene


def test_defaults_of_a_minimal_scene() -> None:
    data = {
        "rod": {
            "length": 2,
            "section": {"a": 0.01, "b": 0.02},
            "material": {"density": 1000, "young_modulus": 1e9, "shear_modulus": 4e8},
        },
        "time": {"end": 1, "step": 0.25},
    }
    scene = scene_from_dict(data)
    assert scene.rod.length == 2.0 and isinstance(scene.rod.length, float)
    assert scene.rod.section.shear_coefficient == pytest.approx(5 / 6)
    assert scene.model.reference_frequency is None
    assert scene.time.n_steps == 4
    assert (scene.discretisation.elements, scene.discretisation.degree) == (20, 2)
    # The defaults the README states: SDIRK3 and a frozen Jacobian.
    assert scene.time.integrator == "sdirk3" and scene.solver.jacobian == "frozen"
    assert scene.solver.max_iterations == 25
    assert scene.output.directory == "results" and scene.output.xdmf_every(0.25) == 1
    assert scene.to_dict()["model"]["reference_frequency"] == "auto"
    assert scene_from_dict(scene.to_dict()) == scene


# -------------------------------------------------------------------------------- overrides
def test_overrides() -> None:
    scene = load_scene(
        PAPER,
        [
            "time.step=1e-5",
            "discretisation.degree=3",
            'loads.force_density=[0,0,"1e3*t"]',
            "time.integrator=generalized-alpha",
            "title=a bare string title",
            "output.xdmf=false",
        ],
    )
    assert scene.time.step == 1e-5 and scene.time.n_steps == 6000
    assert scene.discretisation.degree == 3 and scene.discretisation.quadrature_degree == 6
    assert [e.source for e in scene.loads.force_density] == ["0", "0", "1e3*t"]
    assert scene.time.integrator == "generalized-alpha"
    assert scene.title == "a bare string title"
    assert scene.output.xdmf is False


def test_override_of_the_exclusive_material_pair() -> None:
    scene = load_scene(PAPER, ["rod.material.shear_modulus=2.5e10"])
    assert scene.rod.material.poisson_ratio is None
    assert scene.rod.material.shear_modulus == 2.5e10
    back = load_scene(
        PAPER, ["rod.material.shear_modulus=2.5e10", "rod.material.poisson_ratio=0.3"]
    )
    assert back.rod.material.shear_modulus_value is None


def test_override_creates_tables_and_parameters() -> None:
    scene = load_scene(
        PAPER, ["parameters.amp=3", 'loads.end.force=[0, 0, "amp*t"]', "rod.length=2"]
    )
    assert scene.parameters == {"amp": 3.0}
    assert scene.loads.end is not None and scene.loads.end.force[2].source == "amp*t"


def test_overrides_do_not_touch_the_input() -> None:
    data = load_scene(PAPER).to_dict()
    before = json.dumps(data, sort_keys=True)
    scene_from_dict(data, overrides=["time.step=1e-5", "rod.section.a=0.05"])
    assert json.dumps(data, sort_keys=True) == before


def test_unset_removes_a_key_or_a_table_in_order_with_set(capsys) -> None:
    """--set could not remove a key, so changing a section's shape meant editing the file
    (the rectangle's a, b and torsion_constant are not a circle's). ``--unset KEY``
    (cosserat_fem/scene/schema.py: Removal; UNSET in a mapping, the API's cf.UNSET) removes a key
    or a table, in order with --set; a key the schema does not have is refused with a
    did-you-mean, one the scene does not hold by name (nothing is removed silently)."""
    from cosserat_fem.cli import main
    from cosserat_fem.scene.schema import UNSET, Removal

    circle = [
        Removal("rod.section.a"),
        Removal("rod.section.b"),
        Removal("rod.section.torsion_constant"),
        "rod.section.shape=circle",
        "rod.section.diameter=0.05",
    ]
    scene = load_scene(PAPER, circle)
    assert scene.rod.section.shape == "circle" and scene.rod.section.diameter == 0.05
    as_map = {
        "rod.section.a": UNSET,
        "rod.section.b": UNSET,
        "rod.section.torsion_constant": UNSET,
        "rod.section.shape": "circle",
        "rod.section.diameter": 0.05,
    }
    assert load_scene(PAPER, as_map) == scene
    argv = [
        "validate",
        str(PAPER),
        "--unset",
        "rod.section.a",
        "--unset",
        "rod.section.b",
        "--unset",
        "rod.section.torsion_constant",
        "--set",
        "rod.section.shape=circle",
        "--set",
        "rod.section.diameter=0.05",
    ]
    capsys.readouterr()
    assert main(argv) == 0
    assert 'rod.section.shape = "circle"' in capsys.readouterr().out
    # In order: removed then set again is set; set then removed is removed (a default back).
    assert load_scene(PAPER, [Removal("rod.section.a"), "rod.section.a=0.05"]).rod.section.a == 0.05
    with pytest.raises(SceneError, match="^rod.section.a: required for shape 'rectangle'"):
        load_scene(PAPER, ["rod.section.a=0.05", Removal("rod.section.a")])
    assert load_scene(PAPER, [Removal("time.max_halvings")]).time.max_halvings == 6
    # A whole table.
    loaded = load_scene(PAPER, ["loads.end.force=[0, 0, 1]"])
    assert loaded.loads.end is not None
    assert load_scene(PAPER, ["loads.end.force=[0, 0, 1]", Removal("loads.end")]) == load_scene(
        PAPER
    )
    with pytest.raises(SceneError, match="^rod.section.diameter: not in the scene"):
        load_scene(PAPER, [Removal("rod.section.diameter")])
    with pytest.raises(SceneError, match="^rod.sectio: unknown key .*did you mean 'rod.section'"):
        load_scene(PAPER, {"rod.sectio": UNSET})
    with pytest.raises(SceneError, match="--unset rod.section.a removes it"):
        load_scene(PAPER, ["rod.section.shape=circle", "rod.section.diameter=0.05"])


def test_unset_works_in_a_sweeps_overrides(tmp_path) -> None:
    """``sweep FILE --unset KEY``: the command line's overrides of a sweep's base scene take
    removals too (every member's scene is a circle here)."""
    from cosserat_fem.scene.schema import Removal
    from cosserat_fem.studies.sweep_spec import load_sweep

    path = tmp_path / "sweep.toml"
    path.write_text(
        f'[sweep]\nscene = "{PAPER}"\n[sweep.vary]\n"rod.section.diameter" = [0.04, 0.05]\n',
        encoding="utf-8",
    )
    overrides = [
        Removal("rod.section.a"),
        Removal("rod.section.b"),
        Removal("rod.section.torsion_constant"),
        "rod.section.shape=circle",
    ]
    spec = load_sweep(path, overrides)
    diameters = [spec.scene(m).rod.section.diameter for m in spec.members]
    assert diameters == [0.04, 0.05]
    assert {spec.scene(m).rod.section.shape for m in spec.members} == {"circle"}


# ------------------------------------------------------------------------- malformed scenes
END_LOAD = '\n[loads.end]\nforce = [0, 0, "s*t"]\n'

# (id, [(old, new), ...] replacements in the paper file (old must occur once), overrides,
#  expected message prefix, expected substring)
MALFORMED = [
    ("unknown-top-level", [("[rod]\n", "[rods]\nx = 1\n\n[rod]\n")], [], "rods:", "'rod'"),
    (
        "unknown-nested",
        [("young_modulus = 7.1e10", "youngs_modulus = 7.1e10")],
        [],
        "rod.material.youngs_modulus:",
        "did you mean 'rod.material.young_modulus'",
    ),
    (
        "key-at-wrong-level",
        [("length = 1.0", "length = 1.0\ndensity = 1.0")],
        [],
        "rod.density:",
        "rod.material.density",
    ),
    ("missing-length", [("length = 1.0", "")], [], "rod.length:", "required"),
    ("negative-length", [("length = 1.0", "length = -1.0")], [], "rod.length:", "> 0"),
    (
        "zero-young",
        [("young_modulus = 7.1e10", "young_modulus = 0")],
        [],
        "rod.material.young_modulus:",
        "got 0",
    ),
    (
        "poisson-0.5",
        [("poisson_ratio = 0.32", "poisson_ratio = 0.5")],
        [],
        "rod.material.poisson_ratio:",
        "must lie in (-1, 0.5), got 0.5",
    ),
    (
        "poisson-minus-1",
        [("poisson_ratio = 0.32", "poisson_ratio = -1")],
        [],
        "rod.material.poisson_ratio:",
        "got -1",
    ),
    (
        "poisson-and-shear",
        [("poisson_ratio = 0.32", "poisson_ratio = 0.32\nshear_modulus = 2e10")],
        [],
        "rod.material:",
        "both",
    ),
    ("neither-poisson-nor-shear", [("poisson_ratio = 0.32", "")], [], "rod.material:", "neither"),
    (
        "nan-density",
        [("density = 2730.0", "density = nan")],
        [],
        "rod.material.density:",
        "got nan",
    ),
    (
        "inf-young",
        [("young_modulus = 7.1e10", "young_modulus = inf")],
        [],
        "rod.material.young_modulus:",
        "got inf",
    ),
    ("bool-for-number", [("a = 0.04", "a = true")], [], "rod.section.a:", "got true"),
    ("string-for-number", [("step = 2e-5", 'step = "2e-5"')], [], "time.step:", 'got "2e-5"'),
    (
        "float-for-int",
        [("elements = 20", "elements = 2.5")],
        [],
        "discretisation.elements:",
        "integer",
    ),
    ("degree-0", [("degree = 2", "degree = 0")], [], "discretisation.degree:", "[1, 5]"),
    ("degree-6", [("degree = 2", "degree = 6")], [], "discretisation.degree:", "got 6"),
    (
        "quadrature-0",
        [('quadrature_degree = "auto"', "quadrature_degree = 0")],
        [],
        "discretisation.quadrature_degree:",
        '"auto"',
    ),
    (
        "unknown-integrator",
        [('integrator = "bdf2"', 'integrator = "rk4"')],
        [],
        "time.integrator:",
        '"generalized-alpha"',
    ),
    (
        "choice-did-you-mean",
        [('jacobian = "full"', 'jacobian = "laged"')],
        [],
        "solver.jacobian:",
        'did you mean "lagged"',
    ),
    ("rho-inf-1.5", [("rho_inf = 0.5", "rho_inf = 1.5")], [], "time.rho_inf:", "[0, 1]"),
    ("end-before-start", [("start = 0.0", "start = 0.1")], [], "time.end:", "time.start"),
    ("step-larger-than-span", [("step = 2e-5", "step = 0.1")], [], "time.step:", "<="),
    ("step-not-dividing", [("step = 2e-5", "step = 7e-3")], [], "time.step:", "integer"),
    (
        "unparsable-expression",
        [
            (
                '"2e3*sin(pi*s/L)*sin(8*omega0*t)",\n    "2e3',
                '"2e3*sin(pi*s/L*sin(8*omega0*t)",\n    "2e3',
            )
        ],
        [],
        "loads.force_density[0]:",
        "syntax error",
    ),
    (
        "unknown-name",
        [('"2e3*sin(pi*s/L)*sin(8*omega0*t)",\n    0', '"2e3*sin(omega*t)",\n    0')],
        [],
        "loads.force_density[1]:",
        "did you mean 'omega0'",
    ),
    (
        "dangerous-expression",
        [
            (
                "torque_density = [0, 0, 0]",
                "torque_density = [0, \"__import__('os').system('true')\", 0]",
            )
        ],
        [],
        "loads.torque_density[1]:",
        "only calls of plain function names",
    ),
    (
        "vector-of-two",
        [("torque_density = [0, 0, 0]", "torque_density = [0, 0]")],
        [],
        "loads.torque_density:",
        "3",
    ),
    ("s-in-end-load", [("", END_LOAD)], [], "loads.end.force[2]:", "arc length s"),
    (
        "end-load-on-clamped-end",
        [("", "\n[loads.start]\nforce = [1, 0, 0]\n")],
        [],
        "loads.start:",
        'supports.start = "clamped"',
    ),
    (
        "motion-of-a-free-end",
        [('end = "free"', 'end = "free"\nend_motion = ["1e-3*t", 0, 0]')],
        [],
        "supports.end_motion:",
        "needs an end held in x, y and z",
    ),
    (
        "xdmf-interval-not-multiple",
        [("xdmf_interval = 2e-4", "xdmf_interval = 3e-5")],
        [],
        "output.xdmf_interval:",
        "multiple",
    ),
    ("int-for-bool", [("xdmf = true", "xdmf = 1")], [], "output.xdmf:", "true or false"),
    (
        "empty-directory",
        [('directory = "results/cao_tucker_2008"', 'directory = ""')],
        [],
        "output.directory:",
        "non-empty",
    ),
    ("reserved-parameter", [("", "\n[parameters]\nL = 2.0\n")], [], "parameters.L:", "reserved"),
    (
        "shear-coefficient-0",
        [("shear_coefficient = 0.833", "shear_coefficient = 0")],
        [],
        "rod.section.shear_coefficient:",
        "(0, 1]",
    ),
    ("bad-override-key", [], ["time.stepp=1e-5"], "time.stepp:", "did you mean 'time.step'"),
    ("override-of-a-table", [], ["rod=1"], "rod:", "table"),
    ("override-below-a-leaf", [], ["rod.length.x=1"], "rod.length.x:", "not a table"),
    ("override-bad-value", [], ["time.step=fast"], "time.step:", 'got "fast"'),
]


def _apply(text: str, replacements: list[tuple[str, str]]) -> str:
    for old, new in replacements:
        if old == "":
            text += new
            continue
        assert text.count(old) >= 1, old
        text = text.replace(old, new, 1)
    return text


@pytest.mark.parametrize(
    ("replacements", "overrides", "prefix", "fragment"),
    [pytest.param(*case[1:], id=case[0]) for case in MALFORMED],
)
def test_malformed_scene(
    tmp_path: Path,
    replacements: list[tuple[str, str]],
    overrides: list[str],
    prefix: str,
    fragment: str,
) -> None:
    path = write(tmp_path, _apply(paper_text(), replacements))
    with pytest.raises(SceneError) as info:
        load_scene(path, overrides)
    message = str(info.value)
    assert message.startswith(prefix), message
    assert fragment in message, message
    assert "\n" not in message


def test_number_of_malformed_cases() -> None:
    assert len({case[0] for case in MALFORMED}) == len(MALFORMED) >= 20


def test_malformed_toml_names_file_and_line(tmp_path: Path) -> None:
    path = write(tmp_path, "title = 'x'\n[rod\nlength = 1.0\n", name="broken.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert str(info.value).startswith(str(path))
    assert "line 2" in str(info.value)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match="not found"):
        read_toml(tmp_path / "nope.toml")


def test_override_without_equals_sign() -> None:
    with pytest.raises(SceneError, match="dotted.key=value"):
        load_scene(PAPER, ["time.step"])


# ------------------------------------------------------------------------------ expressions
SAMPLES = [
    "2e3*sin(pi*s/L)*sin(8*omega0*t)",
    "heaviside(s - 0.5)*ramp(t - 0.1) + min(s, t)*max(abs(s - 1), 0.25)",
    "sqrt(1 + s**2) - exp(-t)*cos(omega0*t) + log(2 + s) / tan(0.3 + t)",
    "asin(s/2) + acos(t/3) + atan(s*t) + sinh(s) - cosh(t) + tanh(s - t) + e**-s",
    "-(+s) ** 2 / L",
    "7",
]


@pytest.mark.parametrize("source", SAMPLES)
def test_numeric_and_ufl_agree(source: str) -> None:
    expr = Expression.parse(source, NAMES, "k")
    mesh = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.interval, 1))
    x = ufl.SpatialCoordinate(mesh)
    t_const = ufl.Constant(mesh)
    as_ufl = expr.to_ufl({"s": 2.0 * x[0], "t": t_const, "L": 2.0, "omega0": 3.0})
    for s, t in [(0.0, 0.0), (0.3, 0.2), (1.1, 0.7), (1.9, 0.05)]:
        numeric = expr.evaluate(s=s, t=t, L=2.0, omega0=3.0)
        value = as_ufl if isinstance(as_ufl, float) else as_ufl((s / 2.0,), {t_const: t})
        assert float(value) == pytest.approx(numeric, rel=1e-13, abs=1e-13)
        # constant symbols fold to a float
        folded = expr.to_ufl({"s": s, "t": t, "L": 2.0, "omega0": 3.0})
        assert isinstance(folded, float) and folded == pytest.approx(numeric, rel=1e-13)
        # a UFL-constant version evaluates the same
        constant = expr.to_ufl({"s": ufl.as_ufl(s), "t": ufl.as_ufl(t), "L": 2.0, "omega0": 3.0})
        assert float(constant) == pytest.approx(numeric, rel=1e-13, abs=1e-13)


@pytest.mark.parametrize("source", SAMPLES)
def test_numpy_evaluation(source: str) -> None:
    expr = Expression.parse(source, NAMES, "k")
    s = np.linspace(0.0, 1.9, 7)
    values = expr.evaluate(s=s, t=0.2, L=2.0, omega0=3.0)
    assert isinstance(values, np.ndarray) and values.shape == s.shape
    expected = [expr.evaluate(s=float(x), t=0.2, L=2.0, omega0=3.0) for x in s]
    np.testing.assert_allclose(values, expected, rtol=1e-13, atol=1e-13)


def test_special_functions() -> None:
    def ev(text: str, **values: float) -> float:
        return Expression.parse(text, {"x", "y"}, "k").evaluate(**values)

    assert ev("heaviside(x)", x=0.0) == 1.0
    assert ev("heaviside(x)", x=-1e-300) == 0.0
    assert ev("ramp(x)", x=-2.0) == 0.0 and ev("ramp(x)", x=2.5) == 2.5
    assert ev("min(x, y)", x=1.0, y=-3.0) == -3.0
    assert ev("max(x, y)", x=1.0, y=-3.0) == 1.0
    assert ev("abs(x) + pi - e", x=-2.0) == pytest.approx(2 + math.pi - math.e)
    x = np.array([-1.0, 0.0, 2.0])
    np.testing.assert_array_equal(
        Expression.parse("heaviside(x)", {"x"}, "k").evaluate(x=x), [0, 1, 1]
    )
    np.testing.assert_array_equal(Expression.parse("ramp(x)", {"x"}, "k").evaluate(x=x), [0, 0, 2])


def test_expression_properties() -> None:
    assert Expression.parse(0, NAMES, "k").is_zero
    assert Expression.parse("0", NAMES, "k").is_zero
    assert Expression.parse("0.0", NAMES, "k").is_zero
    assert not Expression.parse("0*s", NAMES, "k").is_zero
    assert not Expression.parse(1e-300, NAMES, "k").is_zero
    expr = Expression.parse("2*s + sin(t) + pi", NAMES, "k")
    assert expr.names == frozenset({"s", "t", "pi"})
    assert expr.depends_on("s") and not expr.depends_on("L") and not expr.depends_on("sin")
    assert Expression.parse(3, NAMES, "k").source == "3"
    assert Expression.parse(2e3, NAMES, "k").source == "2000.0"
    assert Expression("s*t") == Expression.parse(" s*t ", NAMES, "k")
    assert Expression.parse(" s*t ", NAMES, "k").source == "s*t"
    with pytest.raises(ValueError, match="no value given for t"):
        expr.evaluate(s=1.0)
    with pytest.raises(ValueError, match="cannot evaluate"):
        Expression.parse("log(s)", NAMES, "k").evaluate(s=-1.0)


@pytest.mark.parametrize(
    ("source", "fragment"),
    [
        ("__import__('os')", "unknown function '__import__'"),
        ("().__class__", "attribute access"),
        ("a.b", "attribute access"),
        ("x[0]", "indexing"),
        ("lambda: 1", "lambda"),
        ("[s for s in (1,)]", "comprehensions"),
        ("s < 1", "comparisons"),
        ("s if t else 1", "'if ... else'"),
        ("'text'", "only numbers"),
        ("sin(x=s)", "keyword"),
        ("min(s)", "2 arguments"),
        ("sin", "without arguments"),
        ("s % 2", "only + - * / **"),
        ("~s", "only unary"),
        ("sinn(s)", "did you mean 'sin'"),
        ("omega*t", "did you mean 'omega0'"),
        ("1e999*s", "not finite"),
        ("1/0 + s", "cannot be evaluated"),
        ("(-8)**(1/3)", "cannot be evaluated"),
        ("9**9**9", "cannot be evaluated"),
        ("2*(s+1", "syntax error"),
        ("", "empty"),
        ("-" * 300 + "s", "nested deeper"),  # a flat sum is not nesting (test_expression_fuzz)
    ],
)
def test_rejected_expressions(source: str, fragment: str) -> None:
    with pytest.raises(SceneError) as info:
        Expression.parse(source, NAMES, "loads.force_density[0]")
    assert str(info.value).startswith("loads.force_density[0]: ")
    assert fragment in str(info.value)


@pytest.mark.parametrize("value", [True, None, [1], math.nan, math.inf])
def test_rejected_expression_values(value: object) -> None:
    with pytest.raises(SceneError, match=r"^k: "):
        Expression.parse(value, NAMES, "k")


def test_parse_vector() -> None:
    x, y, z = parse_vector([1, "s", "2*t"], NAMES, "loads.force_density")
    assert (x.source, y.source, z.source) == ("1", "s", "2*t")
    with pytest.raises(SceneError, match=r"^loads.force_density: must be a list of 3"):
        parse_vector([1, 2], NAMES, "loads.force_density")
    with pytest.raises(SceneError, match=r"^loads.force_density\[2\]: unknown name"):
        parse_vector([1, 2, "q"], NAMES, "loads.force_density")


def test_errors_are_one_line() -> None:
    error = SolverError(
        "Newton did not converge\nin 25 iterations",
        time=0.0123,
        where="newton",
        suggestion="reduce time.step",
    )
    assert isinstance(error, CosseratError)
    assert str(error) == (
        "newton at t = 0.0123 s: Newton did not converge in 25 iterations "
        "(suggestion: reduce time.step)"
    )
    assert (error.time, error.where, error.suggestion) == (0.0123, "newton", "reduce time.step")
    assert str(SolverError("singular Jacobian")) == "singular Jacobian"
    assert str(SceneError("a.b: bad\nthing")) == "a.b: bad thing"


def test_roller_and_sliding_ends_take_only_their_free_loads() -> None:
    """A roller (x, y, φ held) and a sliding clamp (x, y and the angles held) leave z free:
    an end force along e3 acts there, one across e3 or a torque about a held axis is
    refused naming the key; neither may carry a prescribed motion (z is not held)."""
    roller = ["supports.end=roller", "loads.force_density=[0,0,0]"]
    scene = load_scene(PAPER, [*roller, "loads.end.force=[0,0,-3]", "loads.end.torque=[1,0,0]"])
    assert scene.loads.end.force[2].source == "-3" and not scene.supports.mechanism
    bad = [
        ([*roller, "loads.end.force=[1,0,0]"], r"loads.end.force: a roller end holds x and y"),
        ([*roller, "loads.end.torque=[0,0,1]"], r"loads.end.torque\[2\]: a roller end holds"),
        (
            ["supports.end=sliding", "loads.force_density=[0,0,0]", "loads.end.torque=[1,0,0]"],
            r"loads.end.torque\[0\]: a sliding end holds its angle θ \(about e1\)",
        ),
        (
            ["supports.end=sliding", "supports.end_motion=[0,0,'sin(t)']"],
            r"supports.end_motion: a prescribed motion needs an end held in x, y and z",
        ),
    ]
    for overrides, message in bad:
        with pytest.raises(SceneError, match=message):
            load_scene(PAPER, overrides)


def test_a_pinned_end_takes_no_torque_about_e3() -> None:
    """A pinned (fork) end holds its twist φ: a torque about e3 there would be taken by the
    support silently, so it is refused; torques about e1 and e2 are the end's load."""
    pinned = ["supports.end=pinned", "loads.force_density=[0,0,0]"]
    assert load_scene(PAPER, [*pinned, "loads.end.torque=[1,2,0]"]).loads.end.torque[1].source
    with pytest.raises(SceneError, match=r"loads.end.torque\[2\]: a pinned end holds its angle φ"):
        load_scene(PAPER, [*pinned, "loads.end.torque=[0,0,5]"])
