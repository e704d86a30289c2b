"""cosserat-fem: the Cosserat rod of Cao & Tucker (2008) in FEniCSx/DOLFINx.

The physics (pure UFL) lives in :mod:`cosserat_fem.forms` (the top-level ``forms/`` folder);
this package is the machinery, in subpackages by layer, bottom first: ``common`` (errors, MPI
agreement, safe files, JIT), ``io`` (file formats), ``scene``, ``rod`` (the discrete rod),
``reference`` (closed forms), ``nls`` (Newton, SNES), ``timestepping``, ``output``,
``analysis`` (run, static, modes, stability), ``studies`` (sweeps, responses, POD);
docs/developers.md maps them. The Python API, ``cosserat_fem.load``, ``run``, ``resume``,
``static``, ``modes``, ``stability``, ``stability_at``, ``continuation``, ``periodic_orbit``,
``periodic_branch``,
``lyapunov``, ``load_sweep``, ``sweep`` and ``pod``, is :mod:`cosserat_fem.api`; the reduced
model's, ``cosserat_fem.rom.train``, ``run``, ..., is :mod:`cosserat_fem.rom` (docs/rom.md).
"""

from cosserat_fem.common import pkg_resources_shim
from cosserat_fem.common.mpi_start import start_mpi

__version__ = "0.1.0"

# Before anything else imports mpi4py: a process started without mpirun starts MPI in 0.08 s
# instead of 0.45 s (cosserat_fem/common/mpi_start.py).
QUICK_MPI_START = start_mpi()
# UFL and FFCx ask pkg_resources for their versions only: a stand-in saves importing it.
pkg_resources_shim.install()

#: The Python API (cosserat_fem/api.py), imported on first use: ``import cosserat_fem`` stays
#: light (the command line's plot and validate need no DOLFINx).
_API = (
    "load",
    "run",
    "resume",
    "static",
    "modes",
    "stability",
    "stability_at",
    "continuation",
    "periodic_orbit",
    "periodic_branch",
    "orbits",
    "lyapunov",
    "lyapunov_run",
    "load_sweep",
    "sweep",
    "pod",
    "UNSET",
)


def _watchdog() -> None:
    """A script's uncaught exception under mpirun ends the job instead of hanging it
    (cosserat_fem/common/parallel.py :func:`install_exit_watchdog`)."""
    from cosserat_fem.common.parallel import install_exit_watchdog

    install_exit_watchdog()


def __getattr__(name: str):
    if name in _API:
        _watchdog()
        from cosserat_fem import api

        return getattr(api, name)
    if name == "rom":  # the reduced model's functions (cosserat_fem/rom/, docs/rom.md)
        _watchdog()
        import importlib

        return importlib.import_module("cosserat_fem.rom")
    raise AttributeError(f"module 'cosserat_fem' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])
