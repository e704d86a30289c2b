"""A stand-in for ``pkg_resources`` that answers ``get_distribution(name).version`` only.

UFL 2022.2 and FFCx 0.5 read their versions at import with
``pkg_resources.get_distribution(name).version``, and importing setuptools' ``pkg_resources``
scans every installed distribution: about 0.07 s of a whole run's 1.2 s here (one-off,
2026-12-02, ``python -c "import ufl"`` 0.22 s against 0.15 s, medians of 5; docs/decisions.md,
"Start-up"). :func:`install` puts this module's stand-in into ``sys.modules`` unless the real
one is imported already. The stand-in answers ``get_distribution`` from
``importlib.metadata`` (the same version strings, so FFCx's cache keys do not change); for
any other attribute, or a distribution ``importlib.metadata`` does not know, it imports the
real ``pkg_resources``, which replaces it in ``sys.modules``, and answers from that: code that
uses more of ``pkg_resources`` gets the real module.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import sys
import types


class _Distribution:
    """What the stand-in's get_distribution returns: a project name and its version."""

    def __init__(self, project_name: str, version: str):
        self.project_name = project_name
        self.version = version


class _StandIn(types.ModuleType):
    """``pkg_resources`` with get_distribution(name).version from importlib.metadata."""

    def get_distribution(self, name: str):
        try:
            return _Distribution(name, importlib.metadata.version(name))
        except (importlib.metadata.PackageNotFoundError, ValueError):
            return real().get_distribution(name)

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(real(), name)


def real() -> types.ModuleType:
    """The real pkg_resources, imported on first use (it then replaces the stand-in)."""
    if isinstance(sys.modules.get("pkg_resources"), _StandIn):
        del sys.modules["pkg_resources"]
    return importlib.import_module("pkg_resources")


def install() -> bool:
    """Put the stand-in into sys.modules unless pkg_resources is imported; True if it did."""
    if "pkg_resources" in sys.modules:
        return False
    sys.modules["pkg_resources"] = _StandIn("pkg_resources", __doc__)
    return True
