"""A quick start of Open MPI for a process that no launcher started (a "singleton").

``from mpi4py import MPI`` initialises MPI. Started by ``mpirun`` or ``srun``, Open MPI takes
its settings from the launcher. Started alone (``cosserat-fem run``, ``python script.py``,
every subprocess of the test suite), Open MPI 4.1 forks a daemon (orted) and initialises
its network transports for a process that can only talk to itself: 0.45 s of the start-up
here, against 0.08 s with the settings below (one-off, Open MPI 4.1.4, medians
of 3: docs/decisions.md, "A singleton's MPI start").

:func:`start_mpi` starts MPI (``from mpi4py import MPI``) with, where neither a launcher's
variables nor the user's own say otherwise, ``OMPI_MCA_ess_singleton_isolated=1`` (no
daemon: such a process cannot spawn others, which nothing here does),
``OMPI_MCA_pml=ob1`` and ``OMPI_MCA_btl=self,vader`` (in-process and shared-memory
transports only), then takes them out of the environment again, so that the processes this
one starts (an ``mpirun`` of a test or a study) inherit none of them. Other MPI libraries
ignore these names.
"""

from __future__ import annotations

import os
import sys

#: Variables a launcher sets (Open MPI's mpirun, PMIx and PMI-2 launchers such as srun,
#: MPICH's Hydra): with any of them present the process is not a singleton.
LAUNCHER_VARIABLES = (
    "OMPI_COMM_WORLD_SIZE",
    "PMIX_RANK",
    "PMI_RANK",
    "PMI_SIZE",
    "SLURM_PROCID",
    "MPI_LOCALNRANKS",
)
#: Open MPI's settings for a singleton (module docstring).
SINGLETON_SETTINGS = {
    "OMPI_MCA_ess_singleton_isolated": "1",
    "OMPI_MCA_pml": "ob1",
    "OMPI_MCA_btl": "self,vader",
}


def start_mpi(environ: dict | None = None) -> bool:
    """Start MPI with :data:`SINGLETON_SETTINGS` in ``environ`` (``os.environ`` by default) if
    no launcher started this process and MPI has not started yet, keeping any setting the
    user made, and remove the settings added afterwards; True if it did."""
    env = os.environ if environ is None else environ
    if "mpi4py.MPI" in sys.modules or any(name in env for name in LAUNCHER_VARIABLES):
        return False
    added = {name: value for name, value in SINGLETON_SETTINGS.items() if name not in env}
    env.update(added)
    try:
        from mpi4py import MPI  # noqa: F401  (MPI_Init reads the settings now)
    finally:
        for name in added:
            env.pop(name, None)
    return True
