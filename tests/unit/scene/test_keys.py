"""A scene key is declared once, on the resolved field it becomes (cosserat_fem/scene/keys.py), and
everything is built from it by name (issue 26 item 6).

* Every number key that a scene gives is found, by its own name, in the resolved field it
  declares: each is given a value of its own (distinct from every other key's and from its
  default), so that two keys swapped anywhere between the file and the resolved scene
  (``time.rtol`` and ``time.atol``, say) would fail. Exact equality: the value is copied.
* :func:`~cosserat_fem.scene.keys.build` fills a dataclass by name: the same table built into a
  dataclass with its fields in reverse order gives every field the same value.
* :func:`~cosserat_fem.scene.keys.to_table` (``Scene.to_dict``) writes every declared field from its
  declaration alone: a dataclass given new keyword fields (a number, a renamed key, an "auto"
  number left to be chosen, a sub-table, an absent optional table, a list of choices) has
  them in its table, and in the scene's ``to_dict`` where it is the scene's table, with no
  other edit; the table it writes, checked and built again, is the same dataclass. Every
  shipped scene's ``to_dict``, through JSON and read again, is the same scene (exact: the same
  values parsed again), and writes the same dict.
* Every shipped scene (scenes/*.toml) resolves to the scene that main 72e1e44 resolved, before
  the keys were declared on the resolved fields: tests/data/resolved_scenes.json is that
  resolution (``Scene.to_dict`` and the derived ω0, section constants, plane, absent terms and
  step count, written by 72e1e44's code); the comparison is of those plain values, exact (the
  same operations on the same inputs), a key added to a table since (``time.impact_steps``)
  at its schema default (``schema.default_of``: the behaviour before it).
* What each support holds is one table, HELD_BY_SUPPORT, from which Supports derives the held
  components (a hinge's from its axis) and the rigid-body modes (issue 27 item 2).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
from pathlib import Path

import numpy as np
import pytest

from cosserat_fem.scene.build import load_scene, scene_from_dict
from cosserat_fem.scene.keys import (
    HELD_BY_SUPPORT,
    POSITIVE,
    SUPPORTS,
    Choice,
    ChoiceList,
    Number,
    Table,
    build,
    check_table,
    declared_names,
    table,
    to_table,
)
from cosserat_fem.scene.keys import key as declare
from cosserat_fem.scene.resolved import Damping, Scene, Supports, Time
from cosserat_fem.scene.schema import SCHEMA, default_of, parse_toml

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[3]
BASE = ROOT / "tests" / "data" / "base_scene.toml"


def _numbers(table: Table, prefix: str = "") -> list[tuple[str, Number]]:
    """(dotted key, spec) of each plain number key: not "auto" (resolved by a rule), not
    required (the base scene's geometry and material, whose values couple), and not in
    tables the base scene leaves out or whose keys depend on a shape."""
    found = []
    for name, spec in table.fields.items():
        key = f"{prefix}.{name}" if prefix else name
        if isinstance(spec, Table):
            if not spec.optional and key not in ("rod", "rod.section", "reference"):
                found += _numbers(spec, key)
        elif isinstance(spec, Number) and not spec.auto and not spec.required:
            found.append((key, spec))
    return found


def _distinct_values(numbers: list[tuple[str, Number]]) -> dict[str, float]:
    """A value for each key in its range, different from its default and from every other
    key's: integers 2, 3, 4, ... in turn (the base scene's keys admit them: degree <= 5 is the
    fourth), reals 0.1 + index/1000 (scaled into a bounded range)."""
    values, integer = {}, 2
    for index, (key, spec) in enumerate(numbers):
        if spec.integer:
            integer += integer == spec.default
            values[key], integer = integer, integer + 1
            assert spec.interval.contains(values[key]), key
            continue
        lo = spec.interval.lo if spec.interval.lo is not None else 0.0
        value = 0.1 + index / 1000.0
        if spec.interval.hi is not None:
            value = lo + (spec.interval.hi - lo) * value
        values[key] = value
    assert len(set(values.values())) == len(values)
    return values


def _resolved(scene: Scene, key: str):
    """The resolved value of the dotted ``key``, walked by the declared names alone."""
    obj = scene
    for name in key.split("."):
        obj = getattr(obj, declared_names(type(obj))[name])
    return obj


def test_every_number_key_lands_in_its_own_field():
    """Each plain number key, given a value of its own, is that value in its resolved field."""
    data = parse_toml(BASE.read_bytes(), BASE)
    numbers = [(k, s) for k, s in _numbers(SCHEMA) if not k.startswith("time.")]
    assert len(numbers) >= 15  # solver, damping, static, discretisation, output, ...
    overrides = _distinct_values(numbers)
    overrides["output.xdmf_interval"] = 0.0  # a multiple of the step: its default, kept
    scene = scene_from_dict(data, overrides=overrides)
    for key, value in overrides.items():
        assert _resolved(scene, key) == value, key


def test_time_keys_land_in_their_own_fields():
    """time.* (rtol and atol, the swap the issue names), with values of their own."""
    data = parse_toml(BASE.read_bytes(), BASE)
    given = {
        "time.start": 0.0,
        "time.end": 0.002,
        "time.step": 1e-4,
        "time.rho_inf": 0.3,
        "time.max_halvings": 3,
        "time.rtol": 3e-5,
        "time.atol": 7e-11,
        "time.max_step": 2e-4,
        "time.integrator": "bdf2",
        "time.adaptive": True,
    }
    scene = scene_from_dict(data, overrides=given)
    for key, value in given.items():
        assert _resolved(scene, key) == value, key


def test_build_fills_by_name_whatever_the_order():
    """A dataclass with Time's fields in reverse order, built from the same table, holds the
    same value in every field."""
    raw = {
        "start": 0.0,
        "end": 1.0,
        "step": 0.1,
        "integrator": "bdf2",
        "rho_inf": 0.5,
        "max_halvings": 4,
        "adaptive": False,
        "rtol": 1e-4,
        "atol": 1e-10,
        "max_step": 0.0,
        "impact_steps": False,
    }
    fields = dataclasses.fields(Time)
    reverse = dataclasses.make_dataclass(
        "ReversedTime",
        [(f.name, f.type, dataclasses.field(metadata=f.metadata)) for f in reversed(fields)],
        frozen=True,
        kw_only=True,
    )
    straight, reversed_ = build(Time, raw), build(reverse, raw)
    assert [f.name for f in dataclasses.fields(reverse)][-2:] == ["end", "start"]
    for f in fields:
        assert getattr(straight, f.name) == getattr(reversed_, f.name) == raw[f.name]


def test_schema_is_declared_by_the_resolved_scene():
    """SCHEMA is the table the resolved Scene declares; every table's keys map to fields."""
    assert Table.of(Scene) == SCHEMA
    assert declared_names(type(load_scene(BASE).rod.material))["shear_modulus"] == (
        "shear_modulus_value"
    )


SCENES = sorted((ROOT / "scenes").glob("*.toml"))
RESOLVED_BEFORE = ROOT / "tests" / "data" / "resolved_scenes.json"
#: The shipped scenes 72e1e44 resolved (those added since have no "before").
SCENES_BEFORE = [ROOT / "scenes" / name for name in sorted(json.loads(RESOLVED_BEFORE.read_text()))]


def _added(now: dict, before: dict, prefix: str = "") -> list[str]:
    """The dotted leaf keys of the tables in ``now`` that ``before`` has but not these."""
    added = []
    for name, value in now.items():
        key = f"{prefix}.{name}" if prefix else name
        if name not in before:
            if prefix:  # a leaf of a table 72e1e44 had (a whole new table is compared)
                added.append(key)
        elif isinstance(value, dict) and isinstance(before[name], dict):
            added += _added(value, before[name], key)
    return added


@pytest.mark.parametrize("path", SCENES_BEFORE, ids=lambda p: p.name)
def test_shipped_scenes_resolve_as_before(path):
    """Each shipped scene resolves to what 72e1e44 resolved (module docstring)."""
    before = json.loads(RESOLVED_BEFORE.read_text())
    scene = load_scene(path)
    now = scene.to_dict()
    now["_derived"] = {
        "omega0": scene.omega0,
        "rod_constants": repr(scene.rod_constants()),
        "plane": scene.plane(),
        "absent": scene.absent_terms(),
        "n_steps": scene.time.n_steps,
    }
    now = json.loads(json.dumps(now, sort_keys=True, default=repr))
    expected = before[path.name]
    # keys added since 72e1e44 resolve at their defaults (the scene as before)
    for key in _added(now, expected):
        table, name = key.rsplit(".", 1)
        value = functools.reduce(dict.get, table.split("."), now).pop(name)
        assert value == default_of(key), key
    # The derived constants (ω0 through a square root, c33 through a tanh series,
    # forms/section.py) may differ in their last bits on another libm: numbers within 1e-14
    # relative, the rest of their text exactly. The scene's own values are compared exactly.
    derived, derived_before = now.pop("_derived"), expected.pop("_derived")
    assert now == expected
    number = re.compile(r"-?\d+\.\d*(?:e[-+]?\d+)?|-?\d+e[-+]?\d+")
    for name, value in derived_before.items():
        mine, theirs = str(derived[name]), str(value)
        assert number.sub("#", mine) == number.sub("#", theirs), name
        np.testing.assert_allclose(
            [float(x) for x in number.findall(mine)],
            [float(x) for x in number.findall(theirs)],
            rtol=1e-14,
            atol=0,
            err_msg=name,
        )


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.name)
def test_shipped_scenes_round_trip(path):
    """to_dict, through JSON (what summary.json and a checkpoint hold), read again is the same
    scene, and writes the same dict."""
    scene = load_scene(path)
    data = json.loads(json.dumps(scene.to_dict()))
    again = scene_from_dict(data)
    assert again == scene
    assert again.to_dict() == data


@dataclasses.dataclass(frozen=True, kw_only=True)
class _Inner:
    level: int = declare(Number(default=1, integer=True))


@dataclasses.dataclass(frozen=True, kw_only=True)
class _Extended(Damping):
    """Damping with keys of every kind the writer distinguishes added, and a derived field."""

    stiffness: float = declare(Number(default=2.0, unit="N/m"))
    mode: str = declare(Choice(choices=("a", "b"), default="a"))
    given_as: float | None = declare(Number(interval=POSITIVE), name="spelled", default=None)
    frequency: float | None = declare(Number(default="auto", auto=True), default=None)
    inner: _Inner = table(_Inner)
    absent: _Inner | None = table(_Inner, optional=True, default=None)
    kinds: tuple[str, ...] = declare(ChoiceList(choices=("x", "y"), default=()))
    derived: float = 0.0  # declares no key: not written


def test_new_keyword_fields_are_written_without_other_edits():
    """Fields declared on a dataclass appear in its table and in the scene's to_dict, each as
    its spec writes it; None leaves a key out ("auto" for an auto number); the table, checked
    and built again (with the reader's resolutions: the sub-table, "auto"), is the instance."""
    extended = _Extended(
        translational=1.5,
        rotational=0.0,
        retardation_time=0.0,
        stiffness=3.0,
        mode="b",
        given_as=7.0,
        inner=_Inner(level=4),
        kinds=("y",),
        derived=9.0,
    )
    written = {
        "translational": 1.5,
        "rotational": 0.0,
        "retardation_time": 0.0,
        "stiffness": 3.0,
        "mode": "b",
        "spelled": 7.0,
        "frequency": "auto",
        "inner": {"level": 4},
        "kinds": ["y"],
    }
    assert to_table(extended) == written
    scene = load_scene(BASE)
    data = dataclasses.replace(scene, damping=extended).to_dict()
    assert data == {**scene.to_dict(), "damping": written}

    raw = check_table("damping", written, Table.of(_Extended))
    rebuilt = build(_Extended, raw, inner=build(_Inner, raw["inner"]), frequency=None, derived=9.0)
    assert rebuilt == extended


#: The rigid-body modes of each pair of supports on the straight rod (a free rod 6; a fork the
#: two turns about it; a ball joint 3; two ball joints the turn about the line through them; a
#: roller the two turns and the slide along e3; a sliding end, or two rollers, the slide): the
#: table cosserat_fem/analysis/modal.py keeps by hand, and 0 for every pair not listed.
RIGID_BODY_MODES = {
    ("free", "free"): 6,
    ("free", "pinned"): 2,
    ("free", "spherical"): 3,
    ("spherical", "spherical"): 1,
    ("free", "roller"): 3,
    ("free", "sliding"): 1,
    ("roller", "roller"): 1,
    ("roller", "sliding"): 1,
    ("sliding", "sliding"): 1,
}


def test_supports_derive_from_held_by_support():
    """Supports.held is HELD_BY_SUPPORT but for a hinge, which holds the two angles across its
    axis; held_components adds the rates (6 later); the rigid-body modes, 6 less the rank of
    the held components of a small rigid motion, are the straight rod's table above for all
    36 pairs, and on a semicircle (chord 2R e1) two ball joints leave the turn about the chord,
    which a hinge about e1 leaves too and one about e2 or e3 holds."""
    for start in SUPPORTS:
        for end in SUPPORTS:
            supports = Supports(start=start, end=end)
            assert supports.held("start") == HELD_BY_SUPPORT[start]
            expected = RIGID_BODY_MODES.get(tuple(sorted((start, end))), 0)
            assert supports.rigid_body_modes() == expected, (start, end)
            assert supports.mechanism == (expected > 0)
    hinge = Supports(start="pinned", end="free", start_axis=(0.0, -2.0, 0.0))
    assert hinge.held("start") == ((0, 1, 2), (0, 2))
    assert hinge.held_components("start") == (0, 1, 2, 3, 5, 6, 7, 8, 9, 11)
    assert Supports(start="pinned", end="free").held_components("start") == (
        0,
        1,
        2,
        5,
        6,
        7,
        8,
        11,
    )
    arch = {"chord": (2.0, 0.0, 0.0)}
    assert Supports(start="spherical", end="spherical", **arch).rigid_body_modes() == 1
    for axis, modes in (((1.0, 0.0, 0.0), 1), ((0.0, 1.0, 0.0), 0), ((0.0, 0.0, 1.0), 0)):
        pair = Supports(start="pinned", end="spherical", start_axis=axis, **arch)
        assert pair.rigid_body_modes() == modes, axis
    hinges = {"start_axis": (0.0, 1.0, 0.0), "end_axis": (0.0, 1.0, 0.0)}
    assert Supports(start="pinned", end="pinned", **hinges, **arch).rigid_body_modes() == 0
