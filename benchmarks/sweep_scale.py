"""A sweep of the paper's scene on 1 and 2 ranks: members per second and the sweep's overhead.

    .venv/bin/python benchmarks/sweep_scale.py [--members 100] [--ranks 1 2]

The sweep (written to a temporary folder): scenes/cao_tucker_2008.toml as shipped, 0.06 s each
(2000 SDIRK3 steps), no XDMF, ``keep = "probes"``, its load's forcing frequency varied from 6
to 10 ω0 over ``--members`` values (a [parameters] Constant: one compile for all). Each rank
count runs the whole sweep once, as ``mpirun -n N cosserat-fem sweep`` (groups of one rank),
after a warm-up member that fills the JIT cache. Printed per rank count: the wall time of the
process, members per second, the sum of the members' own wall times (the table's ``wall_s``)
and the overhead, wall − Σ wall_s / N: start-up, the split, the counter, the table.
docs/sweeps.md quotes one run.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SWEEP = """[sweep]
scene = "{scene}"
max_members = 100000
keep = "probes"
[sweep.set]
"output.xdmf" = false
"output.checkpoint" = false
"loads.force_density" = ["2e3*sin(pi*s/L)*sin(forcing*omega0*t)",
                         "2e3*sin(pi*s/L)*sin(forcing*omega0*t)", 0]
[sweep.vary]
"parameters.forcing" = {{ start = 6.0, stop = 10.0, num = {members} }}
"""


def sweep(path: Path, out: Path, ranks: int) -> float:
    """Wall time [s] of ``cosserat-fem sweep`` on ``ranks`` ranks."""
    command = [
        sys.executable,
        "-m",
        "cosserat_fem.cli",
        "sweep",
        str(path),
        "--out",
        str(out),
        "--quiet",
    ]
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), *command]
    env = {**os.environ, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}
    t0 = time.perf_counter()
    subprocess.run(command, cwd=ROOT, env=env, check=True)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--members", type=int, default=100)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="sweep-scale-"))
    try:
        scene = ROOT / "scenes" / "cao_tucker_2008.toml"
        warm = work / "warm.toml"
        warm.write_text(SWEEP.format(scene=scene, members=1), encoding="utf-8")
        sweep(warm, work / "warm", 1)
        path = work / "sweep.toml"
        path.write_text(SWEEP.format(scene=scene, members=args.members), encoding="utf-8")
        print("ranks, members, wall [s], members/s, sum of member walls [s], overhead [s]")
        for ranks in args.ranks:
            out = work / f"n{ranks}"
            wall = sweep(path, out, ranks)
            with open(out / "sweep.csv", newline="", encoding="utf-8") as stream:
                rows = list(csv.DictReader(stream))
            assert len(rows) == args.members and all(r["status"] == "completed" for r in rows)
            own = sum(float(r["wall_s"]) for r in rows)
            print(
                f"{ranks}, {len(rows)}, {wall:.1f}, {len(rows) / wall:.2f}, {own:.1f}, "
                f"{wall - own / ranks:.1f}"
            )
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
