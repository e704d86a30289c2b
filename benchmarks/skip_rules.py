"""What skipping costs and saves: the skip rules of cosserat-fem, measured.

    .venv/bin/python benchmarks/skip_rules.py [--repeats 3]

For each rule, the same scene is run with and without the skip, on this machine, and the
table gives the median solve-loop time of ``--repeats`` runs (warm JIT cache), their ratio
and the largest difference of the free-end probes (the answers must agree to round-off):

* planar: a load in the x-z plane only (the paper's f1, no f2): 6 unknowns instead of 12,
  at 8, 32 and 128 cubic elements; the same in the y-z plane (the paper's f2, no f1) at 32;
* outputs: XDMF off against on (every 8 steps), and the XDMF fields subset;

Zero load terms never reach the form (the model leaves them out, and UFL folds any 0 * ...
away), so "a zero load computed anyway" cannot be measured; a static solve has no inertia
term (U̇ = 0 is UFL's zero). Loads are UFL in the kernels: time enters as a Constant, so
nothing is re-evaluated in Python per step; a residual assembly of the paper's scene took
28.7 μs with its load and 30.3 μs with the time factor replaced by a number (medians of 5,
within the noise), so hoisting time-only factors out of the kernel would save nothing
measurable. Results: benchmarks/results/skip_rules.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

import numpy as np

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.scene.build import load_scene

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
RESULTS = ROOT / "benchmarks" / "results"
IN_PLANE = 'loads.force_density=["2e3*sin(pi*s/L)*sin(8*omega0*t)", 0, 0]'
IN_YZ = 'loads.force_density=[0, "2e3*sin(pi*s/L)*sin(8*omega0*t)", 0]'


def timed(sets: list[str], repeats: int) -> tuple[float, np.ndarray, dict]:
    times = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as out:
            result = run_scene(load_scene(PAPER, sets), out)
            times.append(result.summary["wall_time_s"]["solve_loop"])
            probes = np.loadtxt(Path(out) / "probes.csv", delimiter=",", skiprows=1)
    return statistics.median(times), probes, result.summary


def compare(name: str, skipped: list[str], kept: list[str], repeats: int) -> dict:
    t_skip, p_skip, s_skip = timed(skipped, repeats)
    t_keep, p_keep, s_keep = timed(kept, repeats)
    row = {
        "rule": name,
        "time_skipped_s": t_skip,
        "time_kept_s": t_keep,
        "speed_up": t_keep / t_skip,
        "dofs": [s_skip["dofs"], s_keep["dofs"]],
        "max_probe_difference": float(np.abs(p_skip - p_keep).max()),
    }
    print(
        f"{name:42s} {t_keep:8.3f} s -> {t_skip:8.3f} s  x{row['speed_up']:5.2f}  "
        f"dofs {row['dofs'][1]:6d} -> {row['dofs'][0]:6d}  diff {row['max_probe_difference']:.1e}"
    )
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rows = []
    for plane, load, elements, end in (
        ("x-z", IN_PLANE, 8, 0.03),
        ("x-z", IN_PLANE, 32, 0.015),
        ("x-z", IN_PLANE, 128, 0.003),
        ("y-z", IN_YZ, 32, 0.015),
    ):
        common = [load, "output.xdmf=false", f"discretisation.elements={elements}"]
        common += [f"time.end={end}"]
        rows.append(
            compare(
                f"planar {plane}, {elements} cubic elements",
                [*common, "discretisation.planar='auto'"],
                [*common, "discretisation.planar='off'"],
                args.repeats,
            )
        )
    base = ["time.end=0.03"]
    rows.append(compare("XDMF off (vs every 8 steps)", [*base, "output.xdmf=false"], base, 3))
    rows.append(
        compare(
            "XDMF fields: displacement only (vs all four)",
            [*base, "output.fields=['displacement']"],
            [*base, "output.fields=['displacement', 'angles', 'strains', 'forces']"],
            args.repeats,
        )
    )
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "skip_rules.json").write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
