"""The paper's scene's free-end error and Newton iterations against the Newton tolerance.

    .venv/bin/python benchmarks/newton_tolerance.py [--stol 1e-8 3e-8 1e-7 3e-7 1e-6]

Runs scenes/cao_tucker_2008.toml (no XDMF) with each ``solver.stol`` and prints the Newton
iterations, the solve loop's time and the benchmark's error against results/reference.npz
(made by ``make bench``; benchmarks/work_precision.py ``errors``). docs/decisions.md, "The
paper's scene's Newton tolerance", quotes one run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stol", nargs="+", default=["1e-8", "3e-8", "1e-7", "3e-7", "1e-6"])
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from work_precision import probe_error

    from cosserat_fem import api

    if not (ROOT / "benchmarks" / "results" / "reference.npz").exists():
        sys.exit("benchmarks/results/reference.npz is missing: make bench makes it")
    print("stol, Newton iterations, solve loop [s], free-end error")
    for stol in args.stol:
        scene = api.load(
            ROOT / "scenes" / "cao_tucker_2008.toml", ["output.xdmf=false", f"solver.stol={stol}"]
        )
        result = api.run(scene, record=True)
        error = probe_error(result.probes)
        loop = result.summary["wall_time_s"]["solve_loop_without_output"]
        print(f"{stol}, {result.summary['newton']['iterations']}, {loop:.3f}, {error:.4e}")


if __name__ == "__main__":
    main()
