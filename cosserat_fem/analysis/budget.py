"""What a command will cost, estimated from the scene before any work: memory, wall time, disk.

Each estimate is a *lower bound* built from costs measured on the 2-core development machine
(a run costs at least this much), so that a scene is refused only when it
certainly cannot run within its limits: ``limits.memory`` (default "auto": every limit that
applies here, :func:`memory_limits`: the machine's available memory, the control group's
limit, the process's ``ulimit -v`` and ``-d``), ``limits.wall_time`` (default a day) and the
free space of the output folder. A refusal is a :class:`SceneError` naming the key that makes the
cost (``discretisation.elements``, ``time.step``, ``static.load_steps``, ...); raising
``limits.*`` runs a very large case on purpose. The estimate is printed by ``validate``.

Costs (lower bounds, each below what was measured; why: docs/decisions.md, "The budget's
lower bounds"; docs/reliability.md, D8 and 28):

* memory: 80 MB for the loaded stack (Python, DOLFINx, PETSc), plus 500 bytes a dof: the
  matrix, its LU factors and the vectors. tests/test_budget.py::test_the_memory_per_dof_is_measured
  holds the slope of the peak resident memory between 500 and 5000 bytes a dof (3D, degree 3)
  and ::test_the_memory_per_dof_bounds_the_cheapest_scene (long) at least 500 (planar, degree 1);
* time: a solve of a reused Jacobian costs at least 30 µs + 0.1 µs a dof (one residual
  assembly and two triangular solves), a full Newton iteration at least 100 µs + 1 µs a dof
  (Jacobian assembly and LU factorisation); at least one solve per step or load step;
* disk: a probe row is 170 bytes, 24 more for each column of output.probe_fields; an XDMF
  frame holds 8 bytes per value and point and at least 1.4 kB of HDF5 metadata per array,
  and at least 100 bytes a frame and array of XML (:func:`xml_bytes_written`), written at
  2 GB/s.
"""

from __future__ import annotations

import math
import os
import resource
from dataclasses import dataclass
from pathlib import Path

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.probes import PROBE_COLUMNS, probe_columns
from cosserat_fem.io.xdmf import FIELD_ARRAYS, XdmfSeries
from cosserat_fem.scene.build import PLANAR, Scene

MEMORY_BASE = 80e6  # bytes
MEMORY_PER_DOF = 500.0  # bytes
REUSED_SOLVE_S = 30e-6  # s
REUSED_SOLVE_PER_DOF_S = 0.1e-6  # s
FULL_ITERATION_S = 100e-6  # s
FULL_ITERATION_PER_DOF_S = 1e-6  # s
PROBE_ROW_BYTES = 170
PROBE_COLUMN_BYTES = 24
H5_ARRAY_METADATA_BYTES = 1400
XML_BYTES_PER_FRAME_ARRAY = 100
WRITE_BYTES_PER_S = 2e9


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


def xml_bytes_written(frames: float, arrays: int) -> float:
    """A lower bound of the bytes of XML that an XDMF series of ``frames`` frames of ``arrays``
    arrays writes (cosserat_fem/io/xdmf.py, :class:`~cosserat_fem.io.xdmf.XdmfSeries`): each
    frame once, S = ``XML_BYTES_PER_FRAME_ARRAY`` × arrays × frames in all, and the rewrites.
    A rewrite leaves at most ``XdmfSeries.SPARE[1]`` bytes of room for the frames after it, and
    a frame takes at least b = ``XML_BYTES_PER_FRAME_ARRAY`` × arrays of it, so past R = the
    larger of the two there is a rewrite at least every R bytes of frames, the k-th writing
    the k R bytes the XML then holds at least: R K (K + 1) / 2 more, K = ⌊S / R⌋ − 1. (Linear
    in the frames up to S = 2R, then quadratic with the small coefficient 1 / 2R; with no room
    at all, a rewrite at every frame: b F (F − 1) / 2 more.) Held by
    tests/test_budget.py::test_the_xml_bound_is_below_what_a_series_writes."""
    size = XML_BYTES_PER_FRAME_ARRAY * arrays * frames
    room = max(float(XdmfSeries.SPARE[1]), XML_BYTES_PER_FRAME_ARRAY * arrays)
    k = max(math.floor(size / room) - 1.0, 0.0)
    return size + room * k * (k + 1.0) / 2.0


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
        time_driver = (
            "time.step"
            if 2 * _solve_seconds(0, full) > _solve_seconds(n, full)
            else ("discretisation.elements")
        )
        extra = len(probe_columns(scene.output.probe_fields)) - len(PROBE_COLUMNS)
        row = PROBE_ROW_BYTES + PROBE_COLUMN_BYTES * extra
        disk = (steps + 1) * row
        disk_driver = "time.step"
        if scene.output.xdmf:
            frames = math.floor(steps / float(scene.output.xdmf_every(t.step))) + 1.0
            arrays = sum(len(FIELD_ARRAYS[f]) for f in scene.output.fields)
            points = float(scene.discretisation.elements) * scene.discretisation.degree + 1
            frame = arrays * (24 * points + H5_ARRAY_METADATA_BYTES)
            xml = xml_bytes_written(frames, arrays)
            disk += frames * frame
            seconds += xml / WRITE_BYTES_PER_S
            if frames * frame > (steps + 1) * row:
                disk_driver = "output.xdmf_interval"
            if xml / WRITE_BYTES_PER_S > seconds / 2:
                time_driver = "output.xdmf_interval"
    elif command == "static":
        seconds = float(scene.static.load_steps) * _solve_seconds(n, full=True)
        time_driver = (
            "static.load_steps" if scene.static.load_steps > n else ("discretisation.elements")
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


@dataclass(frozen=True)
class MemoryLimit:
    """Room left under one limit on memory: ``room`` bytes may still be allocated, by each
    process (``per_process``) or by all the ranks on this node together (``whole``: the
    room is for the whole estimate, not only for what the command adds to the memory in use
    now); ``text``, the room and the limit for a message ("the 2 GB left under ...")."""

    room: float
    per_process: bool
    text: str
    whole: bool = False


def _status_bytes(field: str, root: Path) -> float | None:
    """A ``Vm...`` field of /proc/self/status in bytes (None if unknown)."""
    try:
        for line in (root / "proc/self/status").read_text(encoding="ascii").splitlines():
            if line.startswith(field + ":"):
                return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


#: The process limits that bound memory: (resource, the /proc/self/status field it counts,
#: the shell's name for it).
_PROCESS_LIMITS = (
    ("RLIMIT_AS", "VmSize", "address-space limit (ulimit -v)"),
    ("RLIMIT_DATA", "VmData", "data limit (ulimit -d)"),
)


def process_limits(root: Path = Path("/")) -> list[MemoryLimit]:
    """The room under this process's soft resource limits on memory: RLIMIT_AS (all its
    mappings, VmSize: ``ulimit -v``, as batch systems set) and RLIMIT_DATA (its private
    writable mappings, VmData: ``ulimit -d``), each the limit minus what is in use now."""
    found = []
    for name, field, shell in _PROCESS_LIMITS:
        limit = resource.getrlimit(getattr(resource, name))[0]
        used = _status_bytes(field, root)
        if limit == resource.RLIM_INFINITY or used is None:
            continue
        room = limit - used
        found.append(
            MemoryLimit(
                room,
                True,
                f"the {_bytes(max(room, 0.0))} left under this "
                f"process's {shell} of {_bytes(limit)}, {_bytes(used)} in "
                "use",
            )
        )
    return found


def _cgroup_paths(root: Path) -> dict[int, str]:
    """{cgroup version: this process's cgroup path} from /proc/self/cgroup (v1: the memory
    controller's hierarchy)."""
    try:
        lines = (root / "proc/self/cgroup").read_text(encoding="utf-8").splitlines()
    except OSError:
        return {}
    paths = {}
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        if parts[0] == "0" and parts[1] == "":
            paths[2] = parts[2]
        elif "memory" in parts[1].split(","):
            paths[1] = parts[2]
    return paths


#: The files of a cgroup's limit and usage, by version.
_CGROUP_FILES = {
    2: ("memory.max", "memory.current"),
    1: ("memory.limit_in_bytes", "memory.usage_in_bytes"),
}


def _cgroup_folders(root: Path) -> list[tuple[Path, int]]:
    """(folder, version) of this process's memory cgroup and of each ancestor up to its
    hierarchy's mount point, innermost first (v2 if its memory controller is on, else v1; []
    if neither is mounted). A cgroup path outside the mount's root (a cgroup namespace, a
    container) is taken as the mount point itself."""
    paths = _cgroup_paths(root)
    try:
        mounts = (root / "proc/self/mountinfo").read_text(encoding="utf-8").splitlines()
    except OSError:
        return []
    for version in (2, 1):
        for mount in mounts if version in paths else ():
            head, _, rest = mount.partition(" - ")
            fields, tail = head.split(), rest.split()
            if len(fields) < 5 or len(tail) < 3:
                continue
            wanted = (
                tail[0] == "cgroup2"
                if version == 2
                else (tail[0] == "cgroup" and "memory" in tail[2].split(","))
            )
            if not wanted:
                continue
            mount_root, point = fields[3], root / fields[4].lstrip("/")
            inner = paths[version]
            relative = inner[len(mount_root) :] if inner.startswith(mount_root) else ""
            folder = point / relative.strip("/")
            limit_file = _CGROUP_FILES[version][0]
            if not (folder / limit_file).exists():
                folder = point
            chain = [folder]
            while chain[-1] != point and point in chain[-1].parents:
                chain.append(chain[-1].parent)
            chain = [f for f in chain if (f / limit_file).exists()]
            if chain:
                return [(f, version) for f in chain]
    return []


def _cgroup_value(folder: Path, name: str) -> float | None:
    """A number of a cgroup file ("max": inf), None if unreadable."""
    try:
        text = (folder / name).read_text(encoding="ascii").strip()
    except OSError:
        return None
    if text == "max":
        return math.inf
    try:
        return float(text)
    except ValueError:
        return None


def _cgroup_cache(folder: Path, version: int) -> float:
    """The page cache charged to the cgroup (``file`` in v2's memory.stat, ``total_cache``
    in v1's): the kernel reclaims it before it refuses memory, so it is not counted as used."""
    key = "file" if version == 2 else "total_cache"
    try:
        for line in (folder / "memory.stat").read_text(encoding="ascii").splitlines():
            name, _, value = line.partition(" ")
            if name == key:
                return float(value)
    except (OSError, ValueError):
        pass
    return 0.0


#: cgroup v1 writes "no limit" as the largest multiple of the page size below 2^63.
_CGROUP_UNLIMITED = 2.0**62


def cgroup_limit(root: Path = Path("/")) -> MemoryLimit | None:
    """The room under the memory limit of this process's control group: v2 ``memory.max``
    minus ``memory.current``, v1 ``memory.limit_in_bytes`` minus ``memory.usage_in_bytes``,
    the page cache not counted as used; the tightest of its own and its ancestors' (their
    limits hold too). Shared by every process in it, as the ranks of a batch job on one node
    are. None without a limit."""
    tightest = None
    for folder, version in _cgroup_folders(root):
        limit_name, usage_name = _CGROUP_FILES[version]
        limit, usage = _cgroup_value(folder, limit_name), _cgroup_value(folder, usage_name)
        if limit is None or usage is None or limit >= _CGROUP_UNLIMITED:
            continue
        used = max(0.0, usage - _cgroup_cache(folder, version))
        if tightest is None or limit - used < tightest.room:
            where = "/" + str(folder.relative_to(root)) if folder.is_relative_to(root) else folder
            room = limit - used
            tightest = MemoryLimit(
                room,
                False,
                f"the {_bytes(max(room, 0.0))} left under the "
                f"memory limit of this process's control group ({where}/"
                f"{limit_name}) of {_bytes(limit)}, {_bytes(used)} in use",
            )
    return tightest


def memory_limits(root: Path = Path("/")) -> list[MemoryLimit]:
    """Every limit on the memory a run may take here (``limits.memory = "auto"``), each as the
    room left under it: the memory available on the machine (for the whole estimate of the
    ranks on it), the control group's limit (shared by the ranks on the node) and this
    process's resource limits."""
    available = available_memory()
    found = [
        MemoryLimit(
            available, False, f"the {_bytes(available)} available on this machine", whole=True
        )
    ]
    group = cgroup_limit(root)
    if group is not None:
        found.append(group)
    return found + process_limits(root)


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
    comm=None,
) -> Estimate:
    """SceneError if the estimate exceeds the scene's limits or this machine; else the
    estimate. Memory is compared per node: the ranks on this node share what is available.
    With ``comm`` (collective): every rank raises the first rank's refusal, since what each
    rank sees (its process limits, the memory available when it looks) may differ."""
    if comm is None:
        return _check(scene, command, out_dir, ranks_on_node, ranks, start, modes)
    from cosserat_fem.common.parallel import agree

    problem = None
    try:
        e = _check(scene, command, out_dir, ranks_on_node, ranks, start, modes)
    except SceneError as exc:
        problem = exc
    agree(comm, problem)
    return e


def _check(
    scene: Scene,
    command: str,
    out_dir,
    ranks_on_node: int,
    ranks: int,
    start: float | None,
    modes: int,
) -> Estimate:
    """:func:`check` on this rank alone."""
    e = estimate(scene, command, start, modes)
    limits = scene.limits
    per_node = e.memory / ranks * ranks_on_node
    if limits.memory is not None:
        if per_node > limits.memory:
            raise SceneError(
                f"{e.memory_driver}: the {command} needs {_bytes(per_node)} of memory at least "
                f"(estimated), more than limits.memory = {limits.memory:g} bytes; set "
                "limits.memory to run it on purpose"
            )
    else:
        _check_memory(e, command, ranks_on_node, ranks)
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


def _check_memory(e: Estimate, command: str, ranks_on_node: int, ranks: int) -> None:
    """SceneError if the estimate exceeds a limit of :func:`memory_limits`. The machine's
    available memory is compared with the whole estimate of the node's ranks (as before any
    work); the room under a limit that counts what is in use now (the control group's, the
    process's) with what the command adds to it: the per-dof part of the estimate, and the
    part of MEMORY_BASE this process has not loaded yet (its resident memory short of it)."""
    per_node = e.memory / ranks * ranks_on_node
    resident = _status_bytes("VmRSS", Path("/")) or 0.0
    added = (e.memory - MEMORY_BASE) / ranks + max(0.0, MEMORY_BASE - resident)
    for limit in memory_limits():
        if limit.whole:
            need, what = per_node, f"{_bytes(per_node)} of memory"
        elif limit.per_process:
            need, what = added, f"{_bytes(added)} more memory in each process"
        else:
            need = added * ranks_on_node
            what = f"{_bytes(need)} more memory on this node"
        if need > limit.room:
            raise SceneError(
                f"{e.memory_driver}: the {command} needs {what} at least (estimated), more "
                f"than {limit.text} (limits.memory: auto); set limits.memory to run it on "
                "purpose"
            )
