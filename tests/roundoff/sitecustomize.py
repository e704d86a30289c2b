"""Installs tests/roundoff/roundoff_noise.py in a subprocess of a ``ROUNDOFF_NOISE=1`` test run
(tests/conftest.py puts this folder on ``PYTHONPATH``), then runs the system's sitecustomize,
which this one shadows."""

import importlib.util
import sys
from pathlib import Path

import roundoff_noise

if roundoff_noise.requested():
    roundoff_noise.install()

for _folder in sys.path:
    _path = Path(_folder or ".") / "sitecustomize.py"
    if _path.is_file() and _path.resolve() != Path(__file__).resolve():
        _spec = importlib.util.spec_from_file_location("_system_sitecustomize", _path)
        if _spec and _spec.loader:
            _spec.loader.exec_module(importlib.util.module_from_spec(_spec))
        break
