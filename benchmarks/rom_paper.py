"""The reduced model of issue 28 on the paper's scene (docs/rom.md, "Measured error" and
"Time"): trained on its own full run (0.06 s, every output step a snapshot), the relative L2
free-end error of reduced runs of k modes against the full run, beside √ε(k), ε the energy
left out; then the solve loop's wall time (summary.json's ``solve_loop_without_output``) of
the full run and of reduced runs, interleaved (full, reduced, full, ...) and summarised by
medians, because the machine's speed drifts while other work shares it.

    .venv/bin/python benchmarks/rom_paper.py [--repeats 5] [--modes 4 8 12 16 20]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

import cosserat_fem as cf
from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.rom import basis as rb
from cosserat_fem.rom import galerkin

PAPER = Path(__file__).resolve().parents[1] / "scenes" / "cao_tucker_2008.toml"


def loop_time(result) -> float:
    return float(result.summary["wall_time_s"]["solve_loop_without_output"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--modes", type=int, nargs="+", default=[2, 4, 6, 8, 10, 12, 16, 20])
    args = parser.parse_args()
    scene = cf.load(PAPER)
    t0 = time.perf_counter()
    basis, (full,) = rb.train([scene], tolerance=1e-14)
    print(
        f"training: one full run + POD, {time.perf_counter() - t0:.2f} s wall; "
        f"{basis.provenance['snapshots']} snapshots, {basis.modes} modes at ε ≤ 1e-14"
    )
    reference = full.probes[:, 1:4]
    print("| k | ε(k) | √ε(k) | relative L2 free-end error | error/√ε | Newton its/solve |")
    print("|---|---|---|---|---|---|")
    for k in args.modes:
        if k > basis.modes:
            break
        reduced = galerkin.run(scene, basis.truncated(k))
        error = rb.relative_l2(reduced.probes[:, 1:4], reference)
        eps = basis.energy_left_out(k)
        newton = reduced.summary.get("newton", {})
        its = newton.get("iterations", 0) / max(newton.get("solves", 1), 1)
        print(
            f"| {k} | {eps:.2e} | {math.sqrt(eps):.2e} | {error:.2e} | "
            f"{error / math.sqrt(eps):.2f} | {its:.2f} |"
        )
    k_time = min(12, basis.modes)
    chosen = basis.truncated(k_time)
    times: dict[str, list[float]] = {"full": [], "reduced": []}
    for _ in range(args.repeats):
        times["full"].append(loop_time(run_scene(scene, write_outputs=False)))
        times["reduced"].append(loop_time(galerkin.run(scene, chosen)))
    med = {name: float(np.median(v)) for name, v in times.items()}
    print(f"\nsolve loop without output, median of {args.repeats} interleaved pairs, k = {k_time}:")
    for name, values in times.items():
        print(f"  {name}: {med[name]:.3f} s  (all: {', '.join(f'{v:.3f}' for v in values)})")
    print(f"  reduced / full = {med['reduced'] / med['full']:.2f}")
    print(
        f"  machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"load average {os.getloadavg()[0]:.2f}, serial"
    )


if __name__ == "__main__":
    main()
