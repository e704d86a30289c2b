"""tests/unit mirrors the package (issue 26 item 7): every module of cosserat_fem has its unit
test file, tests/unit/<subpackage>/test_<module>.py (cosserat_fem/scene/keys.py:
tests/unit/scene/test_keys.py; a top-level module such as cosserat_fem/api.py:
tests/unit/test_api.py; cosserat_fem.forms, which lives in forms/: tests/unit/forms/), or is
named in :data:`INTEGRATION_ONLY` with the integration test files in tests/ that cover it.

So a new module without a unit test or a named integration test fails the suite, and so does
an entry left behind (its module gone, or given a unit test since: the entry goes), a file it
names that does not exist, and a unit test file that mirrors no module (a module renamed
without its test). The package is walked as files (no import: no DOLFINx, a few milliseconds);
its folders are pyproject.toml's ``[tool.setuptools.package-dir]``. Exact comparisons of names.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
UNIT = ROOT / "tests" / "unit"

#: The modules covered only by integration tests (tests/test_*.py), each with the files that
#: cover it. A unit test (tests/unit/<subpackage>/test_<module>.py) replaces its entry.
INTEGRATION_ONLY: dict[str, str] = {
    # interface
    "api": "tests/test_api.py",
    "cli": "tests/test_cli.py tests/test_ux.py",
    "plot": "tests/test_response.py tests/test_output_fuzz.py",
    "render": "tests/test_visualisation.py",
    # common
    "common.jit": "tests/test_jit_cache.py",
    "common.log": "tests/test_ux.py tests/test_step_rejection.py",
    "common.mpi_start": "tests/test_mpi_start.py",
    "common.parallel": "tests/test_newton_mpi.py tests/test_mpi_fuzz.py",
    "common.pkg_resources_shim": "tests/test_pkg_resources_shim.py",
    "common.safe_files": "tests/test_input_fuzz.py tests/test_budget.py",
    # contact's rows with the rod itself
    "nls.contacts": "tests/test_self_contact.py",
    "nls.pair_contact": "tests/test_self_contact.py",
    "rod.self_contact": "tests/test_self_contact.py",
    # io
    "io.checkpoint": "tests/test_restart.py tests/test_reliability.py",
    "io.folder_lock": "tests/test_run_folders.py",
    "io.line_mesh": "tests/test_structures.py",
    "common.rotations": "tests/unit/rod/test_charts.py tests/unit/io/test_beamdyn.py",
    "io.hdf5": "tests/test_xdmf_writer.py tests/test_pod.py",
    "io.output_files": "tests/test_visualisation.py tests/test_pod.py",
    "io.run_folder": "tests/test_run_folders.py tests/test_claims.py",
    "io.sweep_table": "tests/test_sweep.py",
    "io.xdmf": "tests/test_xdmf_writer.py tests/test_kill_window.py",
    # scene
    "scene.build": "tests/test_scene.py tests/test_scene_features.py",
    "scene.describe": "tests/test_input_fuzz.py tests/test_cli.py",
    "scene.load_data": "tests/test_load_data.py",
    "scene.resolved": "tests/test_scene.py tests/test_scene_features.py",
    # forms (cosserat_fem.forms, in forms/)
    "forms.conventions": "tests/test_forms.py",
    "forms.director_form": "tests/test_forms.py",
    "forms.energy": "tests/test_energy.py",
    "forms.follower": "tests/test_follower.py",
    "forms.semitangential": "tests/test_greenhill.py",
    "forms.rigid_body": "tests/test_rigid_body.py",
    "forms.general_form": "tests/test_forms.py",
    "forms.groups": "tests/test_forms.py",
    "forms.kinematics": "tests/test_forms.py",
    "forms.reference": "tests/test_forms.py tests/test_curved.py",
    "forms.resultants": "tests/test_planar.py tests/test_visualisation.py",
    "forms.section": "tests/test_forms.py tests/test_second_order_reference.py",
    # rod
    "rod.checks": "tests/test_rotations.py tests/test_step_rejection.py",
    "rod.load_coefficients": "tests/test_load_data.py",
    "rod.model": "tests/test_statics.py tests/test_planar.py tests/test_modes.py",
    # reference
    "reference.backbone": "tests/test_backbone.py",
    "reference.curved": "tests/test_curved.py tests/test_ring.py",
    "reference.elastica": "tests/test_elastica_reference.py",
    "reference.rod_planes": "tests/test_statics.py tests/test_modes.py",
    "reference.second_order": "tests/test_second_order_reference.py",
    "reference.timoshenko": "tests/test_elastica_reference.py tests/test_statics.py",
    "reference.torsion": "tests/test_second_order_reference.py",
    # nls
    "nls.native_newton": "tests/test_native_newton.py tests/test_newton_mpi.py",
    "nls.snes": "tests/test_snes.py",
    "nls.solvers": "tests/test_snes.py",
    # timestepping
    "timestepping.events": "tests/test_mechanisms.py tests/test_performance_guard.py",
    "timestepping.loop": "tests/test_restart.py tests/test_sdirk_step.py",
    # output
    "output.fields": "tests/test_visualisation.py tests/test_planar.py",
    "output.results": "tests/test_output_fuzz.py tests/test_rotations.py",
    # analysis
    "analysis.budget": "tests/test_budget.py",
    "analysis.equilibria": "tests/test_stability.py",
    "analysis.lyapunov": "tests/test_chaos.py",
    "analysis.modal": "tests/test_modes.py",
    "analysis.paths": "tests/test_continuation.py",
    "analysis.observers": "tests/test_restart.py tests/test_reliability.py",
    "analysis.progress": "tests/test_ux.py",
    "analysis.restart": "tests/test_restart.py",
    "analysis.simulation": "tests/test_api.py tests/test_restart.py",
    "analysis.statics": "tests/test_statics.py tests/test_large_deflection.py",
    # studies
    "studies.karhunen_loeve": "tests/test_pod.py",
    "studies.response": "tests/test_response.py",
    # rom
    "rom.galerkin": "tests/test_rom.py",
    "studies.sweep_run": "tests/test_sweep.py tests/test_response.py",
    "studies.sweep_spec": "tests/test_sweep.py tests/test_scene.py",
}

#: Unit test files that test no module of the package: the test tree's own checks, and the
#: measure of the structure in benchmarks/ (tests/unit/benchmarks/test_<name>.py mirrors
#: benchmarks/<name>.py).
NOT_A_MODULE = {"test_mirror.py"}


def package_folders() -> dict[str, Path]:
    """{dotted package: its folder}, from pyproject.toml's package-dir (``cosserat_fem.forms``
    lives in forms/)."""
    with (ROOT / "pyproject.toml").open("rb") as file:
        dirs = tomllib.load(file)["tool"]["setuptools"]["package-dir"]
    return {package: ROOT / folder for package, folder in dirs.items()}


def modules() -> set[str]:
    """Every module of the package, dotted below ``cosserat_fem`` ("scene.keys", "api"), not
    counting the packages' ``__init__``."""
    found = set()
    for package, folder in package_folders().items():
        prefix = package.split(".")[1:]
        for path in folder.rglob("*.py"):
            if path.name != "__init__.py":
                found.add(".".join([*prefix, *path.relative_to(folder).with_suffix("").parts]))
    return found


def mirror(module: str) -> Path:
    """The unit test file of ``module`` ("scene.keys" → tests/unit/scene/test_keys.py)."""
    *folders, name = module.split(".")
    return UNIT.joinpath(*folders, f"test_{name}.py")


def test_the_walk_finds_the_package():
    """The walk sees the layers (a wrong folder would find nothing and pass everything)."""
    found = modules()
    for module in ("api", "scene.keys", "forms.kinematics", "nls.newton", "io.probes"):
        assert module in found
    assert not any(name.endswith("__init__") for name in found)


def test_every_module_has_a_unit_test_or_named_integration_tests():
    missing = sorted(m for m in modules() if not mirror(m).exists() and m not in INTEGRATION_ONLY)
    assert not missing, (
        "modules with neither a unit test (tests/unit/<subpackage>/test_<module>.py) nor an "
        f"entry in tests/unit/test_mirror.py INTEGRATION_ONLY: {missing}"
    )


def test_the_list_names_existing_modules_without_unit_tests_and_existing_files():
    found = modules()
    assert not sorted(set(INTEGRATION_ONLY) - found), "entries for modules that do not exist"
    tested = sorted(m for m in INTEGRATION_ONLY if mirror(m).exists())
    assert not tested, f"modules with a unit test now: remove their entries {tested}"
    for module, files in INTEGRATION_ONLY.items():
        assert files.split(), module
        absent = [name for name in files.split() if not (ROOT / name).is_file()]
        assert not absent, f"{module}: no such test file {absent}"


def test_every_unit_test_file_mirrors_a_module():
    """Each tests/unit file mirrors a module (or, under benchmarks/, a file of benchmarks/):
    a renamed module takes its test's name along. Each folder is a package (``__init__.py``),
    so that a unit test may share its basename with an integration test in tests/."""
    found = modules()
    for path in UNIT.rglob("test_*.py"):
        relative = path.relative_to(UNIT)
        assert (path.parent / "__init__.py").is_file(), f"{relative.parent}: no __init__.py"
        if relative.parts[0] == "benchmarks":
            assert (ROOT / "benchmarks" / path.name.removeprefix("test_")).is_file(), relative
        elif relative.name not in NOT_A_MODULE:
            module = ".".join([*relative.parent.parts, relative.stem.removeprefix("test_")])
            assert module in found, f"tests/unit/{relative} mirrors no module ({module})"
