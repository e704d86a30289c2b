"""Unit tests of benchmarks/structure.py, the measure of issue 26 (import cycles, upward imports,
the walk): its import resolution and its cycle finder on constructed cases whose answers are
known by hand, so that the figures it reports before and after a restructuring mean what its
docstring says."""

from __future__ import annotations

import ast
import importlib.util
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

_PATH = Path(__file__).resolve().parents[3] / "benchmarks" / "structure.py"
_SPEC = importlib.util.spec_from_file_location("structure", _PATH)
structure = importlib.util.module_from_spec(_SPEC)
sys.modules["structure"] = structure
_SPEC.loader.exec_module(structure)


@pytest.mark.parametrize(
    ("current", "is_package", "statement", "expected"),
    [
        ("cli", False, "from .api import run", ["api", "api.run"]),
        ("cli", False, "from . import scene", ["scene"]),
        ("io.probes", False, "from ..errors import SceneError", ["errors", "errors.SceneError"]),
        ("io.probes", False, "from .xdmf import write", ["io.xdmf", "io.xdmf.write"]),
        ("io", True, "from .probes import write", ["io.probes", "io.probes.write"]),
        ("cli", False, "import cosserat_fem.rod.model", ["rod.model"]),
        ("cli", False, "from cosserat_fem.forms import kinematics", ["forms", "forms.kinematics"]),
        ("cli", False, "import numpy as np", []),
    ],
)
def test_an_import_names_the_modules_it_loads(current, is_package, statement, expected):
    node = ast.parse(statement).body[0]
    assert structure._resolve(current, is_package, node) == expected


def test_cycles_are_the_strongly_connected_sets():
    """a -> b -> c -> a is one cycle, d -> e -> d another; f -> a and c -> g join none."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "g"}, "d": {"e"}, "e": {"d"}, "f": {"a"}}
    assert sorted(structure.cycles(graph)) == [["a", "b", "c"], ["d", "e"]]
    assert structure.cycles({"a": {"b"}, "b": set()}) == []


def test_a_deferred_import_is_told_from_a_module_level_one(tmp_path):
    """An import inside a function is deferred; one under ``if TYPE_CHECKING`` is not counted."""
    path = tmp_path / "m.py"
    path.write_text(
        "from typing import TYPE_CHECKING\nfrom .a import x\nif TYPE_CHECKING:\n"
        "    from .b import y\ndef f():\n    from .c import z\n",
        encoding="utf-8",
    )
    found = {"m": path, "a": path, "b": path, "c": path}
    assert structure._imports_of("m", path, found) == {"module": {"a"}, "deferred": {"c"}}


def test_every_module_is_in_a_layer():
    """A new module must be placed in structure.LAYERS, or upward imports go unseen."""
    unplaced = [m for m in structure.modules() if structure.layer_of(m) is None]
    assert unplaced == []
