"""What a command will cost, estimated from the scene before any work: memory, wall time, disk.

Each estimate is a *lower bound* built from costs measured on the 2-core machine of
docs/reliability.md (a run costs at least this much), so that a scene is refused only when it
certainly cannot run within its limits: ``limits.memory`` (default: the memory available on
this machine, shared by the ranks on it), ``limits.wall_time`` (default a day) and the free
space of the output folder. A refusal is a :class:`SceneError` naming the key that makes the
cost (``discretisation.elements``, ``time.step``, ``static.load_steps``, ...); raising
``limits.*`` runs a very large case on purpose. The estimate is printed by ``validate``.

Costs (lower bounds, each below what was measured; docs/reliability.md):

* memory: 80 MB for the loaded stack (Python, DOLFINx, PETSc: 100 MB measured at 300 dofs),
  plus 600 bytes a dof (1.2 kB measured at 3.6e5 and 3.6e6 dofs: matrix, LU factors, vectors);
* time: a solve of a reused Jacobian costs at least 30 µs + 0.1 µs a dof (one residual
  assembly, 25 ns a dof measured, and two triangular solves), a full Newton iteration at
  least 100 µs + 1 µs a dof (Jacobian assembly and LU factorisation: 0.68 ms measured at 300
  dofs, 6 µs a dof at 3.6e6); at least one solve per step or load step;
* disk: a probe row is 170 bytes, 24 more for each column of output.probe_fields; an XDMF
  frame holds 8 bytes per value and point and at least 1.4 kB of HDF5 metadata per array,
  and the XML listing every frame is rewritten at each frame (so the frames cost time
  quadratic in their number: at least 100 bytes a frame and array written per frame, at
  2 GB/s).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from .errors import SceneError
from .results import PROBE_COLUMNS, probe_columns
from .scene import PLANAR, Scene

MEMORY_BASE = 80e6  # bytes
MEMORY_PER_DOF = 600.0  # bytes
REUSED_SOLVE_S = 30e-6  # s
REUSED_SOLVE_PER_DOF_S = 0.1e-6  # s
FULL_ITERATION_S = 100e-6  # s
FULL_ITERATION_PER_DOF_S = 1e-6  # s
PROBE_ROW_BYTES = 170
PROBE_COLUMN_BYTES = 24
H5_ARRAY_METADATA_BYTES = 1400
XML_BYTES_PER_FRAME_ARRAY = 100
WRITE_BYTES_PER_S = 2e9
#: Arrays written per output.fields entry (cosserat_fem/output.py FIELD_ARRAYS).
_ARRAYS_PER_FIELD = {"displacement": 1, "angles": 1, "strains": 2, "forces": 2, "directors": 3}


@dataclass(frozen=True)
class Estimate:
    """Lower bounds of a command's cost; ``driver`` names the key each one grows with."""

    memory: float  # bytes, all ranks together
    seconds: float
    disk: float  # bytes written to the output folder
    memory_driver: str
    time_driver: str
    disk_driver: str

    def describe(self) -> str:
        return (
            f"at least {_bytes(self.memory)} of memory, {_duration(self.seconds)} and "
            f"{_bytes(self.disk)} of disk"
        )


def _bytes(n: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} bytes"


def _duration(s: float) -> str:
    """``s`` seconds as text for a message: in s, h, days or years."""
    if s >= 86400 * 365:
        return f"{s / (86400 * 365):.3g} years"
    if s >= 86400:
        return f"{s / 86400:.3g} days"
    if s >= 3600:
        return f"{s / 3600:.3g} h"
    return f"{s:.3g} s"


def dofs(scene: Scene, modal: bool = False) -> float:
    """Unknowns the solver holds: 12 per Lagrange node, 6 for a planar scene, 6 for modes
    (a float: the count may exceed what any machine holds)."""
    disc = scene.discretisation
    nodes = float(disc.elements) * disc.degree + 1
    plane = scene.plane()
    per_node = 6 if modal else len(PLANAR[plane]) if plane is not None else 12
    return nodes * per_node


def _solve_seconds(n: float, full: bool) -> float:
    if full:
        return FULL_ITERATION_S + FULL_ITERATION_PER_DOF_S * n
    return REUSED_SOLVE_S + REUSED_SOLVE_PER_DOF_S * n


def estimate(scene: Scene, command: str, start: float | None = None, modes: int = 0) -> Estimate:
    """Lower bounds of the cost of ``command`` ("run", "static", "modes") on ``scene``;
    ``start`` [s]: a restart's checkpoint time (the steps left); ``modes``: --count."""
    n = dofs(scene, modal=command == "modes")
    memory = MEMORY_BASE + MEMORY_PER_DOF * n
    disk, disk_driver = 0.0, "output.directory"
    if command == "run":
        t = scene.time
        steps = (t.end - (t.start if start is None else start)) / t.step  # a float: may be vast
        full = scene.solver.jacobian == "full"
        seconds = steps * _solve_seconds(n, full)
        time_driver = "time.step" if 2 * _solve_seconds(0, full) > _solve_seconds(n, full) else (
            "discretisation.elements"
        )
        extra = len(probe_columns(scene.output.probe_fields)) - len(PROBE_COLUMNS)
        row = PROBE_ROW_BYTES + PROBE_COLUMN_BYTES * extra
        disk = (steps + 1) * row
        disk_driver = "time.step"
        if scene.output.xdmf:
            frames = math.floor(steps / float(scene.output.xdmf_every(t.step))) + 1.0
            arrays = sum(_ARRAYS_PER_FIELD[f] for f in scene.output.fields)
            points = float(scene.discretisation.elements) * scene.discretisation.degree + 1
            frame = arrays * (24 * points + H5_ARRAY_METADATA_BYTES)
            xml = XML_BYTES_PER_FRAME_ARRAY * arrays * frames**2 / 2.0
            disk += frames * frame
            seconds += xml / WRITE_BYTES_PER_S
            if frames * frame > (steps + 1) * row:
                disk_driver = "output.xdmf_interval"
            if xml / WRITE_BYTES_PER_S > seconds / 2:
                time_driver = "output.xdmf_interval"
    elif command == "static":
        seconds = float(scene.static.load_steps) * _solve_seconds(n, full=True)
        time_driver = "static.load_steps" if scene.static.load_steps > n else (
            "discretisation.elements"
        )
    else:
        seconds = _solve_seconds(n, full=True)
        memory += 2 * 8.0 * n * max(modes, 1)  # the Krylov basis: at least 2 count vectors
        time_driver = "--count"
    memory_driver = "--count" if command == "modes" and modes > n / 2 else "discretisation.elements"
    return Estimate(memory, seconds, disk, memory_driver, time_driver, disk_driver)


def available_memory() -> float:
    """Bytes of memory available on this machine now (MemAvailable), inf if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))
    except (OSError, ValueError):
        return math.inf


def free_disk(path: str | Path) -> float:
    """Bytes free for this user in the file system of ``path`` (its nearest existing
    parent), inf if unknown."""
    folder = Path(path).absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    try:
        info = os.statvfs(folder)
    except OSError:
        return math.inf
    return float(info.f_bavail * info.f_frsize)


def check(
    scene: Scene,
    command: str,
    out_dir: str | Path | None = None,
    ranks_on_node: int = 1,
    ranks: int = 1,
    start: float | None = None,
    modes: int = 0,
) -> Estimate:
    """SceneError if the estimate exceeds the scene's limits or this machine; else the
    estimate. Memory is compared per node: the ranks on this node share what is available."""
    e = estimate(scene, command, start, modes)
    limits = scene.limits
    per_node = e.memory / ranks * ranks_on_node
    if limits.memory is not None:
        allowed, source = limits.memory, f"limits.memory = {limits.memory:g} bytes"
    else:
        allowed = available_memory()
        source = f"the {_bytes(allowed)} available on this machine (limits.memory: auto)"
    if per_node > allowed:
        raise SceneError(
            f"{e.memory_driver}: the {command} needs {_bytes(per_node)} of memory at least "
            f"(estimated), more than {source}; set limits.memory to run it on purpose"
        )
    wall = limits.wall_time
    if e.seconds > wall:
        raise SceneError(
            f"{e.time_driver}: the {command} needs {_duration(e.seconds)} at least here "
            f"(estimated), more than limits.wall_time = {wall:g} s; raise limits.wall_time to "
            "run it on purpose"
        )
    if out_dir is not None and e.disk > 0.0:
        free = free_disk(out_dir)
        if e.disk > free:
            raise SceneError(
                f"{e.disk_driver}: the outputs need {_bytes(e.disk)} at least (estimated), "
                f"more than the {_bytes(free)} free in {str(out_dir)!r}"
            )
    return e
