"""The stand-in for pkg_resources (cosserat_fem/common/pkg_resources_shim.py): UFL and FFCx import
with it and read the versions that importlib.metadata and the real pkg_resources give; any
other use of pkg_resources gets the real module. Each case runs in its own process, as the
stand-in is installed at ``import cosserat_fem``."""

from __future__ import annotations

import json

from conftest import run_command

VERSIONS = """
import json, sys
import cosserat_fem, ufl, ffcx
import importlib.metadata as md
stand_in = type(sys.modules["pkg_resources"]).__name__
versions = [ufl.__version__, ffcx.__version__]
expected = [md.version("fenics-ufl"), md.version("fenics-ffcx")]
import pkg_resources
real = [pkg_resources.working_set.by_key[k].version for k in ("fenics-ufl", "fenics-ffcx")]
print(json.dumps({"stand_in": stand_in, "versions": versions, "expected": expected,
                  "real": real, "after": type(sys.modules["pkg_resources"]).__name__}))
"""

UNKNOWN = """
import cosserat_fem, pkg_resources
try:
    pkg_resources.get_distribution("no-such-distribution-here")
except pkg_resources.DistributionNotFound as exc:
    print("DistributionNotFound")
"""

ALREADY = """
import sys, pkg_resources
real = sys.modules["pkg_resources"]
import cosserat_fem, ufl
print(sys.modules["pkg_resources"] is real)
"""


def _run(code: str) -> str:
    proc = run_command(["-c", code])
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout.strip()


def test_ufl_and_ffcx_import_with_the_stand_in_and_read_their_versions():
    """The stand-in serves the imports (the real module is not loaded by them), the versions
    equal importlib.metadata's and the real pkg_resources' (FFCx's cache keys contain its
    version); the first other use brings the real module in."""
    report = json.loads(_run(VERSIONS).splitlines()[-1])
    assert report["stand_in"] == "_StandIn"
    assert report["versions"] == report["expected"] == report["real"]
    assert report["after"] == "module"


def test_an_unknown_distribution_raises_the_real_exception():
    assert _run(UNKNOWN).splitlines()[-1] == "DistributionNotFound"


def test_a_real_pkg_resources_imported_before_is_kept():
    assert _run(ALREADY).splitlines()[-1] == "True"
