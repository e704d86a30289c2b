"""The cost estimate before a run (cosserat_fem/analysis/budget.py): the limits on memory it sees,
and its memory per dof measured against the peak memory of real runs (issue 25 items 16, 28).

The estimate is a lower bound, so that only what certainly cannot run is refused: a bound
that is too high refuses runs that fit, one ten times too low refuses nothing. The measured
tests below fail for a tenfold error either way."""

from __future__ import annotations

import json
import resource
import subprocess
from pathlib import Path

import pytest
from conftest import PYTHON, ROOT, run_command, said, subprocess_env

from cosserat_fem.analysis import budget
from cosserat_fem.common.errors import SceneError
from cosserat_fem.scene.build import load_scene

SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
PLANAR = 'loads.force_density=["2e3*sin(pi*s/L)*sin(8*omega0*t)", 0, 0]'  # x-z: 6 a node


def run_in_child(overrides: list[str], limit: int | None = None) -> dict:
    """``cosserat-fem run`` of the paper's scene with ``overrides`` in a process of its own
    (with RLIMIT_AS = ``limit`` bytes if given): its exit status, stderr, and its peak
    resident memory (VmHWM) and address space (VmPeak) in bytes."""
    script = (
        "import json, sys\n"
        "from cosserat_fem.cli import main\n"
        "status = main(sys.argv[1:])\n"
        "vm = {l.split(':')[0]: int(l.split()[1]) * 1024 for l in open('/proc/self/status')\n"
        "      if l.startswith(('VmHWM', 'VmPeak'))}\n"
        "print(json.dumps({'status': status, **vm}))\n"
    )
    sets = [arg for item in overrides for arg in ("--set", item)]

    def limited() -> None:
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_AS, (limit, resource.RLIM_INFINITY))

    proc = subprocess.run(
        [PYTHON, "-c", script, "run", SCENE, "--quiet", *sets],
        env=subprocess_env(),
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=limited,
    )
    lines = proc.stdout.strip().splitlines()
    result = json.loads(lines[-1]) if lines and lines[-1].startswith("{") else {}
    return {"returncode": proc.returncode, "stderr": proc.stderr, **result}


def short(tmp_path: Path, name: str, *extra: str) -> list[str]:
    """Two output steps of the paper's scene into tmp_path/name, no XDMF."""
    return [f"output.directory={tmp_path / name}", "time.end=0.00006", "output.xdmf=false", *extra]


# --- item 16: the limits "auto" sees -------------------------------------------------------


def test_a_process_address_space_limit_refuses_what_cannot_fit(tmp_path):
    """Item 16: ``limits.memory = "auto"`` compared the estimate with the machine's available
    memory alone; under ``ulimit -v`` (RLIMIT_AS, as batch systems set) a run beyond it was
    not refused and died inside PETSc or DOLFINx ("internal error: RuntimeError: PETSc
    error ..."). Now the room left under the limit (the limit less VmSize now) is compared
    with what the run adds: one line naming the key and the limit, exit 2, before any work.

    The limit is the address space of a small run of this machine (its VmPeak: the stack
    loaded, a few MB of model) plus 400 MB; 40000 cubic elements in 3D are 1.44e6 dofs, at
    least 500 bytes each (budget.MEMORY_PER_DOF): 720 MB, certainly beyond. The small run
    itself still runs under that limit (the check refuses only what cannot fit)."""
    small = run_in_child(short(tmp_path, "small", "discretisation.elements=8"))
    assert small["returncode"] == 0 and small["status"] == 0, small["stderr"]
    limit = small["VmPeak"] + 400 * 2**20
    again = run_in_child(short(tmp_path, "again", "discretisation.elements=8"), limit)
    assert again["status"] == 0, again["stderr"]
    big = run_in_child(short(tmp_path, "big", "discretisation.elements=40000"), limit)
    lines = big["stderr"].strip().splitlines()
    assert big.get("status") == 2 and len(lines) == 1, big
    assert lines[0].startswith("cosserat-fem: error: discretisation.elements: the run needs ")
    assert "address-space limit (ulimit -v)" in lines[0] and "internal error" not in lines[0]
    assert not (tmp_path / "big").exists()  # refused before anything was written


MOUNT_V2 = "41 31 0:38 / /sys/fs/cgroup rw,relatime - cgroup2 cgroup2 rw\n"
MOUNT_V1 = (
    "31 23 0:28 / /sys/fs/cgroup rw - tmpfs tmpfs rw\n"
    "35 31 0:32 / /sys/fs/cgroup/memory rw,relatime - cgroup cgroup rw,memory\n"
)
V1 = "sys/fs/cgroup/memory/"
#: name: (the files of a fake root, the room expected, the limit file named).
CGROUPS = {
    "v2, a job's step": (
        {
            "proc/self/cgroup": "0::/job/step\n",
            "proc/self/mountinfo": MOUNT_V2,
            "sys/fs/cgroup/job/memory.max": "1000000000\n",
            "sys/fs/cgroup/job/memory.current": "300000000\n",
            "sys/fs/cgroup/job/memory.stat": "anon 200000000\nfile 100000000\n",
            "sys/fs/cgroup/job/step/memory.max": "max\n",
            "sys/fs/cgroup/job/step/memory.current": "250000000\n",
            "sys/fs/cgroup/job/step/memory.stat": "anon 200000000\nfile 50000000\n",
        },
        8e8,
        "/sys/fs/cgroup/job/memory.max",
    ),
    "v1, its parent's limit": (
        {
            "proc/self/cgroup": "9:name=systemd:/\n4:memory:/process_api/abc\n0::/\n",
            "proc/self/mountinfo": MOUNT_V1,
            V1 + "memory.limit_in_bytes": "9223372036854771712\n",
            V1 + "memory.usage_in_bytes": "900000000\n",
            V1 + "process_api/memory.limit_in_bytes": "500000000\n",
            V1 + "process_api/memory.usage_in_bytes": "200000000\n",
            V1 + "process_api/memory.stat": "cache 40000000\ntotal_cache 50000000\n",
            V1 + "process_api/abc/memory.limit_in_bytes": "9223372036854771712\n",
            V1 + "process_api/abc/memory.usage_in_bytes": "100000000\n",
        },
        3.5e8,
        V1 + "process_api/memory.limit_in_bytes",
    ),
    "v2, a namespace": (
        {
            "proc/self/cgroup": "0::/../elsewhere\n",
            "proc/self/mountinfo": MOUNT_V2.replace(" / /sys", " /container /sys"),
            "sys/fs/cgroup/memory.max": "400000000\n",
            "sys/fs/cgroup/memory.current": "100000000\n",
        },
        3e8,
        "/sys/fs/cgroup/memory.max",
    ),
    "v2, no limit": (
        {
            "proc/self/cgroup": "0::/a\n",
            "proc/self/mountinfo": MOUNT_V2,
            "sys/fs/cgroup/a/memory.max": "max\n",
            "sys/fs/cgroup/a/memory.current": "1\n",
        },
        None,
        None,
    ),
}


@pytest.mark.parametrize("case", CGROUPS)
def test_the_control_group_limit_is_read(tmp_path, case):
    """Item 16: the room under a control group's memory limit is the limit less the memory in
    use that the kernel cannot reclaim (the page cache is not counted), the tightest of the
    group's and its ancestors' limits. Fake /proc and /sys trees, each number chosen so that
    another reading gives another room:

    * v2, a job's step inside a job: the step has "max", the job 1e9 with 3e8 in use of which
      1e8 page cache: room 1e9 - 2e8 = 8e8, named by the job's memory.max;
    * v1 (this machine's layout): the leaf unlimited (2^63 less a page), its parent 5e8 with
      2e8 in use, 5e7 of it cache: room 3.5e8;
    * a cgroup namespace (the path is outside the mount's root): the mount point's own files;
    * no limit anywhere: None."""
    files, room, named = CGROUPS[case]
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    limit = budget.cgroup_limit(tmp_path)
    if room is None:
        assert limit is None
    else:
        assert limit.room == room and not limit.per_process and named.lstrip("/") in limit.text


def test_a_control_group_limit_refuses_what_cannot_fit(monkeypatch):
    """Item 16: the room under the control group's limit (200 MB here) against what the run
    adds to the memory in use: 500 bytes a dof (budget.MEMORY_PER_DOF), and the part of
    MEMORY_BASE (80 MB) not yet resident in each process on the node.

    * 10000 cubic elements in 3D, 360012 dofs: 180 MB, the base loaded: it fits;
    * 12000 elements, 432012 dofs: 216 MB: refused, naming the key and the limit;
    * 10000 elements on two ranks of this node, each with 30 MB resident: 2 x (90 + 50) MB:
      refused; on two nodes (one rank here): 140 MB, it fits;
    * ``limits.memory`` set by hand runs it on purpose."""
    text = "the 200 MB left under the memory limit of this process's control group (test)"
    monkeypatch.setattr(
        budget, "cgroup_limit", lambda root=None: budget.MemoryLimit(200e6, False, text)
    )
    resident = {"VmRSS": budget.MEMORY_BASE}
    monkeypatch.setattr(budget, "_status_bytes", lambda field, root: resident.get(field))
    ten, twelve = (load_scene(SCENE, [f"discretisation.elements={n}"]) for n in (10000, 12000))
    budget.check(ten, "run")
    with pytest.raises(SceneError) as info:
        budget.check(twelve, "run")
    message = str(info.value)
    assert message.startswith(
        "discretisation.elements: the run needs 216 MB more memory on "
        "this node at least (estimated), more than " + text
    )
    resident["VmRSS"] = 30e6
    with pytest.raises(SceneError, match="needs 280 MB more memory on this node"):
        budget.check(ten, "run", ranks_on_node=2, ranks=2)
    budget.check(ten, "run", ranks_on_node=1, ranks=2)
    budget.check(load_scene(SCENE, ["discretisation.elements=12000", "limits.memory=1e12"]), "run")


# --- item 28: the memory per dof, measured -------------------------------------------------


def memory_slope(tmp_path: Path, sizes: tuple[int, int], *extra: str) -> tuple[float, float]:
    """(bytes a dof, bytes at no dof): the line through the peak resident memory (VmHWM) of
    runs of ``sizes`` elements (two output steps: the Jacobian, its LU factors and every
    vector made), each in a process of its own."""
    points = []
    for elements in sizes:
        overrides = short(tmp_path, f"e{elements}", f"discretisation.elements={elements}", *extra)
        result = run_in_child(overrides)
        assert result.get("status") == 0, result["stderr"]
        summary = json.loads((tmp_path / f"e{elements}" / "summary.json").read_text())
        points.append((summary["dofs"], result["VmHWM"]))
    (n0, m0), (n1, m1) = points
    slope = (m1 - m0) / (n1 - n0)
    return slope, m0 - slope * n0


def test_the_memory_per_dof_is_measured(tmp_path):
    """Item 28: budget.MEMORY_PER_DOF (500 bytes) and MEMORY_BASE (80 MB) are lower bounds
    of what a run takes, and not loose by a factor ten: the slope of the peak resident memory
    between 18012 and 90012 dofs (cubic elements in 3D: 60 nonzeros a row in the Jacobian,
    108 in its LU factors, the most per dof of the shipped element choices) lies between
    MEMORY_PER_DOF and ten times it, and so does its intercept with MEMORY_BASE.

    Measured here: 1650 bytes a dof, an intercept of ~95 MB. The margins (3.3 and 3 both
    ways) are far above the noise of a peak RSS (a few MB on the 119 MB between the sizes);
    a bound ten times too low (50 bytes: 500 < 1650) or too high (5000 > 1650) fails."""
    slope, base = memory_slope(tmp_path, (500, 2500))
    assert budget.MEMORY_PER_DOF <= slope <= 10 * budget.MEMORY_PER_DOF, slope
    assert budget.MEMORY_BASE <= base <= 10 * budget.MEMORY_BASE, base


@pytest.mark.long
def test_the_memory_per_dof_bounds_the_cheapest_scene(tmp_path):
    """Item 28, the lower bound where it is tightest: a planar scene of linear elements has
    the fewest nonzeros a row (18 in the Jacobian and in its factors), and its slope of the
    peak resident memory between 7.2e4 and 2.9e5 dofs (620 bytes a dof measured here) must
    still be at least budget.MEMORY_PER_DOF (500): else a scene that fits is refused."""
    slope, _ = memory_slope(tmp_path, (12000, 48000), "discretisation.degree=1", PLANAR)
    assert slope >= budget.MEMORY_PER_DOF, slope


@pytest.mark.mpi
@pytest.mark.parametrize("command", ["run", pytest.param("sweep", marks=pytest.mark.long)])
def test_a_limit_on_one_rank_refuses_on_every_rank(tmp_path, command):
    """Item 16's sibling: each rank sees its own process limits (and reads the available
    memory at its own moment), so one rank could refuse while the others began the run and
    waited for it in a collective call: 10 s, then MPI_ABORT. The refusal is now agreed
    (budget.check(comm=...)): under mpirun -n 2 with rank 1 alone under an address-space
    limit (its VmSize with the stack loaded + 300 MB), 40000 cubic elements in 3D (at least
    720 MB, 360 MB a rank) are refused on both ranks at once: exit 2, one line, from rank 0,
    naming rank 1's limit, and no folder made. A sweep of one such member (two groups of one
    rank: each checks the member against its own limits when the sweep is loaded) alike,
    naming the member."""

    script = (
        "import resource, sys\n"
        "from mpi4py import MPI\n"
        "import cosserat_fem.analysis.simulation\n"
        "from cosserat_fem.cli import main\n"
        "if MPI.COMM_WORLD.rank == 1:\n"
        "    vm = [int(l.split()[1]) * 1024 for l in open('/proc/self/status')\n"
        "          if l.startswith('VmSize')][0]\n"
        "    resource.setrlimit(resource.RLIMIT_AS, (vm + 300 * 2**20, resource.RLIM_INFINITY))\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    out = tmp_path / "big"
    args = [
        "run",
        SCENE,
        "--out",
        str(out),
        "--set",
        "discretisation.elements=40000",
        "--set",
        "time.end=0.00006",
    ]
    if command == "sweep":
        sweep = tmp_path / "sweep.toml"
        sweep.write_text(
            f"[sweep]\nscene = {json.dumps(SCENE)}\n[sweep.set]\n"
            '"discretisation.elements" = 40000\n"time.end" = 0.00006\n'
            '[sweep.vary]\n"parameters.forcing" = [8.0]\n'
        )
        args = ["sweep", str(sweep), "--out", str(out)]
    proc = run_command(["-c", script, *args], ranks=2)
    ours = said(proc.stderr)
    assert proc.returncode == 2 and len(ours) == 1, proc.stderr  # and mpirun's notice
    member = "sweep member 0 (parameters.forcing = 8.0): " if command == "sweep" else ""
    assert ours[0].startswith(
        f"cosserat-fem: error: {member}discretisation.elements: the run needs "
    ), ours[0]
    assert "address-space limit (ulimit -v)" in ours[0] and "MPI_ABORT" not in proc.stderr
    assert not out.exists()


def _xml_bytes_of_a_series(folder: Path, frames: int, names: list[str], monkeypatch) -> int:
    """The bytes an XdmfSeries of ``frames`` frames of the arrays ``names`` on 5 points writes
    to its XML (appends and rewrites: safe_files.write_all on the XML's descriptor)."""
    import os

    import numpy as np

    from cosserat_fem.common import safe_files
    from cosserat_fem.io.xdmf import XdmfSeries

    written = 0
    real = safe_files.write_all

    def counting(fd: int, data: bytes, offset: int) -> None:
        nonlocal written
        if os.readlink(f"/proc/self/fd/{fd}").endswith((".xdmf", ".xdmf-partial")):
            written += len(data)
        real(fd, data, offset)

    points = 5
    geometry = np.zeros((points, 3))
    geometry[:, 2] = np.linspace(0.0, 1.0, points)
    topology = np.column_stack([np.arange(points - 1), np.arange(1, points)]).astype(np.int64)
    with monkeypatch.context() as patch:
        patch.setattr(safe_files, "write_all", counting)
        series = XdmfSeries(folder / "rod.xdmf", names, geometry, topology)
        for frame in range(frames):
            series.write(frame * 1e-4, np.full((points, 3 * len(names)), float(frame)))
        series.close()
    return written


def test_the_xml_bound_is_below_what_a_series_writes(tmp_path, monkeypatch):
    """budget.xml_bytes_written is a lower bound of the XML bytes an XDMF series writes.
    Its closed form at two points: linear, 100 bytes a frame and array, up to twice the room
    R after a rewrite; then R K (K + 1) / 2 more. With R cut to 4 KiB, 300 frames of six
    arrays pass through many rewrites (the regime where the bound is quadratic): the bytes
    written are at least the bound (measured 29 MB against 3.9 MB: a frame's XML is more than
    100 bytes an array, and each rewrite writes all of them). With the shipped R = 4 MiB the
    same series writes less than the bound of the earlier writer, which rewrote the whole XML
    at every frame (100 × 6 × 300² / 2 = 27 MB; measured 2.7 MB, the bound 0.18 MB): that
    bound refused runs that fit (limits.wall_time), this one stays below what is written."""
    from cosserat_fem.io.xdmf import XdmfSeries

    names = ["displacement", "angles", "strain_v", "curvature_u", "force_n", "torque_m"]
    room = 4 << 10
    monkeypatch.setattr(XdmfSeries, "SPARE", (1 << 10, room))
    assert budget.xml_bytes_written(10, 6) == 6000.0  # below 2 R: no rewrite counted
    s = 100.0 * 6 * 300
    k = s // room - 1
    assert budget.xml_bytes_written(300, 6) == s + room * k * (k + 1) / 2
    # No room at all (tests/test_kill_window.py's "rewrite" case): a rewrite at every frame.
    monkeypatch.setattr(XdmfSeries, "SPARE", (0, 0))
    assert budget.xml_bytes_written(300, 6) == s + 600.0 * 300 * 299 / 2  # b F (F - 1) / 2
    monkeypatch.setattr(XdmfSeries, "SPARE", (1 << 10, room))
    (tmp_path / "small").mkdir()
    written = _xml_bytes_of_a_series(tmp_path / "small", 300, names, monkeypatch)
    assert written >= budget.xml_bytes_written(300, 6), written
    monkeypatch.undo()
    (tmp_path / "shipped").mkdir()
    written = _xml_bytes_of_a_series(tmp_path / "shipped", 300, names, monkeypatch)
    assert budget.xml_bytes_written(300, 6) <= written < 100.0 * 6 * 300**2 / 2, written
