"""Issue 28's goal "a forcing-frequency sweep" (demos/rom_frequency_sweep.py): the paper's
cantilever swept over its first two resonances (scenes/sweeps/rom_forcing.toml, r = Ω/ω0
from 0.75 to 1.75, at least 200 members), the whole sweep with reduced members, training
included, against the same sweep with full members; the two sweeps interleaved (reduced,
full, reduced, ...), each into a fresh folder, and summarised by medians, because the
machine's speed drifts while other work shares it. Then ``cf.rom.validate`` on 20
members drawn at random (``random:20``, the seeded draw of ``cosserat-fem rom validate``):
each in full and reduced, the true relative L2 free-end error beside the indicator; the goal
asks for every indicated error ≤ 1e-2, confirmed by the true one.

    .venv/bin/python benchmarks/rom_sweep.py [--members 201] [--train 5] [--repeats 3]
        [--ecsw TAU]

Serial (one core) unless started under mpirun; prints Markdown tables.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

import cosserat_fem as cf
from cosserat_fem.studies.sweep_spec import RomSettings

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "scenes" / "sweeps" / "rom_forcing.toml"


def sweep_of(members: int, train: int):
    """The sweep file's spec with ``members`` values of r and ``train`` trained members spread
    evenly (the ends included)."""
    chosen = sorted({int(round(x)) for x in np.linspace(0, members - 1, train)})
    text = SWEEP.read_text(encoding="utf-8")
    text = text.replace("../cao_tucker_2008.toml", str(ROOT / "scenes" / "cao_tucker_2008.toml"))
    text = re.sub(r"num = \d+", f"num = {members}", text)
    text = re.sub(r"train = \[[^\]]*\]", f"train = {json.dumps(chosen)}", text)
    folder = Path(tempfile.mkdtemp()) if MPI.COMM_WORLD.rank == 0 else None
    path = Path(MPI.COMM_WORLD.bcast(str(folder), root=0)) / "sweep.toml"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text(text, encoding="utf-8")
    MPI.COMM_WORLD.Barrier()
    try:
        return cf.load_sweep(path)
    finally:
        MPI.COMM_WORLD.Barrier()
        if MPI.COMM_WORLD.rank == 0:
            shutil.rmtree(path.parent, ignore_errors=True)


def timed_sweep(spec, out: Path, indicators: list[float] | None = None) -> float:
    """Wall time [s] of the whole sweep into a fresh ``out`` (its training included); its
    members' indicators (sweep.csv's column) put in ``indicators`` if given."""
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        shutil.rmtree(out, ignore_errors=True)
    comm.Barrier()
    started = time.perf_counter()
    result = cf.sweep(spec, out)
    comm.Barrier()
    wall = time.perf_counter() - started
    failed = [row["member"] for row in result.rows if row["status"] != "completed"]
    if failed:
        raise SystemExit(f"rom_sweep: members {failed} did not complete in {out}")
    if indicators is not None:
        indicators[:] = [float(row["indicator"]) for row in result.rows]
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--members", type=int, default=201)
    parser.add_argument("--train", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--validate", type=int, default=20, help="members drawn at random")
    parser.add_argument(
        "--ecsw", type=float, default=None, metavar="TAU", help="hyper-reduced members (§9)"
    )
    parser.add_argument("--out", default=None, help="folder of the sweeps (default: a temporary)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    spec = sweep_of(args.members, args.train)
    if args.ecsw is not None:
        assert spec.rom is not None
        spec = replace(spec, rom=replace(spec.rom, ecsw=args.ecsw))
    full_spec = replace(spec, rom=RomSettings(model="full"))
    folder = Path(args.out) if args.out else Path(tempfile.gettempdir()) / "rom_sweep_bench"
    times: dict[str, list[float]] = {"reduced": [], "full": []}
    indicators: list[float] = []
    for _ in range(args.repeats):
        times["reduced"].append(timed_sweep(spec, folder / "reduced", indicators))
        times["full"].append(timed_sweep(full_spec, folder / "full"))
    basis = folder / "reduced" / "rom" / "basis.npz"
    provenance = json.loads(basis.with_suffix(".json").read_text())["provenance"]
    started = time.perf_counter()
    checked = cf.rom.validate(
        basis, sweep=spec, members=f"random:{args.validate}", out=folder / "validation"
    )
    validation_wall = time.perf_counter() - started
    if comm.rank != 0:
        return
    print(
        f"{platform.node()}, {os.cpu_count()} cores, {comm.size} rank(s), load average "
        f"{os.getloadavg()[0]:.1f}; {args.members} members, r = 0.75 ... 1.75, trained on "
        f"{len(spec.rom.train)} ({list(spec.rom.train)}); {provenance['modes']} modes, "
        f"ε = {provenance['energy_left_out']:.2e}"
    )
    print()
    print("| sweep | median [s] | per member [s] | all [s] |")
    print("|---|---|---|---|")
    medians = {name: statistics.median(values) for name, values in times.items()}
    for name, values in times.items():
        print(
            f"| {name}{' (training included)' if name == 'reduced' else ''} | "
            f"{medians[name]:.1f} | {medians[name] / args.members:.3f} | "
            f"{', '.join(f'{v:.1f}' for v in values)} |"
        )
    print(f"\nfull / reduced = {medians['full'] / medians['reduced']:.2f} (goal: ≥ 30)")
    print(
        f"indicator over all {len(indicators)} reduced members: {min(indicators):.2e} to "
        f"{max(indicators):.2e} ({'≤' if max(indicators) <= 1e-2 else '>'} 1e-2)\n"
    )
    print("| member | r | true error | indicator | indicator / error | outside training |")
    print("|---|---|---|---|---|---|")
    worst = 0.0
    for row in checked.rows:
        index = int(row["target"].lstrip("m"))
        r = spec.members[index].values["parameters.r"]
        indicator = row["indicator"]
        worst = max(worst, indicator, row["error"])
        flags = ", ".join(sorted({f["what"] for f in row["outside_training"] or []})) or "none"
        print(
            f"| {index} | {r:.3f} | {row['error']:.2e} | {indicator:.2e} | "
            f"{indicator / row['error']:.2f} | {flags} |"
        )
    print(
        f"\n{len(checked.rows)} members validated in {validation_wall:.1f} s: largest error or "
        f"indicator {worst:.2e} ({'≤' if worst <= 1e-2 else '>'} 1e-2)"
    )


if __name__ == "__main__":
    main()
