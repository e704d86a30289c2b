"""The cost of one Floquet analysis (the monodromy matrix of one forcing period) against one
period of time marching, on the clamped rod of demos/frequency_response.py.

    .venv/bin/python benchmarks/floquet_cost.py [--steps 300] [--repeats 7]

The rod of scenes/sweeps/clamped_hysteresis.toml at r = 1.07 (8 cubic elements, planar: 150
dofs, 138 free), SDIRK3 with ``--steps`` steps a period, from its settled lower orbit (two
periods marched from rest; the cost hardly depends on the state). In turn, ``--repeats``
times: one period of the period map (cosserat_fem/analysis/periodic.py, the run's steps and
Newton solves), one period with the variational equations (the monodromy matrix). Printed:
the medians [s] and their ratio, and the ratio n + 1 periods (the finite-difference
monodromy) would cost. docs/decisions.md, "The monodromy matrix", quotes a run of it.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from cosserat_fem import api
from cosserat_fem.analysis.periodic import Shooting

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="steps a period")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved repeats")
    args = parser.parse_args()
    scene = api.load(
        ROOT / "scenes" / "cao_tucker_2008.toml",
        {
            "supports.end": "clamped",
            "output.xdmf": False,
            "output.checkpoint": False,
            "damping.translational": 170.74,
            "loads.force_density": ["F*sin(pi*s/L)*sin(r*w1*t)", 0, 0],
            "parameters.F": 5915.8,
            "parameters.w1": 1302.92,
            "parameters.r": 1.07,
        },
    )
    shooting = Shooting(scene, "2*pi/(r*w1)", steps_per_period=args.steps)
    u = shooting.settle(shooting.rest(), 2)
    shooting.advance(u, tangent=True)  # warm: first assemblies, factor set-up
    marching, floquet = [], []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        shooting.advance(u)
        t1 = time.perf_counter()
        shooting.advance(u, tangent=True)
        t2 = time.perf_counter()
        marching.append(t1 - t0)
        floquet.append(t2 - t1)
    shooting.destroy()
    a, b = statistics.median(marching), statistics.median(floquet)
    free = shooting.free.size
    print(f"dofs {shooting.n} (free {free}), {args.steps} steps a period, {args.repeats} repeats")
    print(f"one period of time marching: {a:.4f} s (median)")
    print(f"one monodromy matrix:        {b:.4f} s (median), {b / a:.1f} periods")
    print(f"finite differences would be: {free + 1} periods")


if __name__ == "__main__":
    main()
