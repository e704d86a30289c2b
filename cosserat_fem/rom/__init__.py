"""Reduced models of the rod from POD modes (issue 28; docs/rom.md): the basis
(cosserat_fem/rom/basis.py, offline) and the Galerkin-reduced solve in the time loop
(cosserat_fem/rom/galerkin.py, online) and the commands' work (cosserat_fem/rom/runs.py:
``cosserat-fem rom build|run|validate``). From Python: ``cf.rom.train(scenes, tolerance)``,
``cf.rom.write_basis``/``read_basis``, ``cf.rom.build(scenes, out, tolerance=...)``,
``cf.rom.run(scene, basis, out)`` and ``cf.rom.validate(basis, scenes, out)``, imported on
first use (no DOLFINx at ``import cosserat_fem``)."""

from __future__ import annotations

#: The functions of the reduced model's API and the module each comes from.
_API = {
    "train": "basis",
    "write_basis": "basis",
    "read_basis": "basis",
    "Basis": "basis",
    "SnapshotCollector": "basis",
    "run": "runs",
    "build": "runs",
    "validate": "runs",
    "IndicatorSettings": "indicator",
}


def __getattr__(name: str):
    if name in _API:
        import importlib

        return getattr(importlib.import_module(f"cosserat_fem.rom.{_API[name]}"), name)
    raise AttributeError(f"module 'cosserat_fem.rom' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])
