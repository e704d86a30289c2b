#!/usr/bin/env python3
"""Work-precision runs of the PyElastica cantilever (full 0 <= t <= 0.06 s).

For each N, run ``cantilever.py --warmup`` in a fresh process (so numba's
compile/cache-load time is measured separately from the integration loop) at
  * ``dt90``: 0.9 x the largest stable dt from results/stable_dt.json (tip
    output by cubic Hermite interpolation onto the 1e-5 s grid), and
  * ``dtdiv``: the largest 1e-5/k <= 0.9 x stable dt (exact output samples),
and compare x(l,t), y(l,t) with the cosserat-fem reference (relative L2 over
the 1e-5 s samples).  Writes results/benchmark.json and prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from convergence import DEFAULT_REF, load_reference, rel_l2  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--elements", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320, 640])
    ap.add_argument("--end", type=float, default=0.06)
    ap.add_argument("--stable", default=os.path.join(HERE, "results", "stable_dt.json"))
    ap.add_argument("--safety", type=float, default=0.9)
    ap.add_argument("--modes", nargs="+", default=["dt90", "dtdiv"], choices=["dt90", "dtdiv"])
    ap.add_argument("--shift-clamp", action="store_true")
    ap.add_argument("--reference", default=DEFAULT_REF)
    ap.add_argument("--outdir", default=None)
    args = ap.parse_args(argv)
    tag = "bench_shifted" if args.shift_clamp else "bench"
    outdir = args.outdir or os.path.join(HERE, "results", tag)
    os.makedirs(outdir, exist_ok=True)

    if not os.path.exists(args.stable):
        subprocess.run(
            [sys.executable, os.path.join(HERE, "stable_dt.py"), "--out", args.stable]
            + ["--elements", *map(str, args.elements)],
            check=True,
        )
    with open(args.stable) as fh:
        stable = {r["N"]: r for r in json.load(fh)["rows"]}

    ref = None
    if args.reference and os.path.exists(args.reference):
        ref = load_reference(args.reference, np.arange(round(args.end / 1e-5) + 1) * 1e-5)

    rows = []
    for n in args.elements:
        if n not in stable:
            raise SystemExit(f"no stable dt for N={n} in {args.stable}; rerun stable_dt.py")
        dts = {}
        d90 = args.safety * stable[n]["dt_stable"]
        dts["dt90"] = float(f"{d90:.4e}")
        k = int(np.ceil(1e-5 / d90 - 1e-9))
        dts["dtdiv"] = 1e-5 / k
        for mode in args.modes:
            dt = dts[mode]
            csv = os.path.join(outdir, f"N{n}_{mode}.csv")
            cmd = [sys.executable, os.path.join(HERE, "cantilever.py"), "--warmup"]
            cmd += ["--elements", str(n), "--dt", repr(dt), "--end", repr(args.end)]
            cmd += ["--out", csv]
            if args.shift_clamp:
                cmd.append("--shift-clamp")
            proc = subprocess.run(cmd, capture_output=True, text=True)
            rec = json.loads(proc.stdout.strip().splitlines()[-1])
            rec["mode"] = mode
            rec["dt_over_dt_stable"] = dt / stable[n]["dt_stable"]
            if ref is not None and rec["stable"]:
                s = np.loadtxt(csv, delimiter=",", skiprows=1)
                rec["rel_l2_x"] = rel_l2(s[:, 1], ref[:, 0])
                rec["rel_l2_y"] = rel_l2(s[:, 2], ref[:, 1])
                rec["rel_l2_z"] = rel_l2(s[:, 3], ref[:, 2])
            rows.append(rec)
            print(
                f"N={n:4d} {mode:5s} dt={dt:.4e} ({rec['dt_over_dt_stable']:.2f} dt_s) "
                f"steps={rec['steps']:7d} wall={rec['wall_s']:7.2f}s "
                f"compile={rec['compile_s']:.2f}s "
                f"stable={rec['stable']} max|x|={rec.get('max_abs_x', float('nan')):.5e} "
                f"max|y|={rec.get('max_abs_y', float('nan')):.5e} "
                f"z=[{rec.get('min_z', float('nan')):.3e},{rec.get('max_z', float('nan')):.1e}] "
                f"L2x={rec.get('rel_l2_x', float('nan')):.3e} "
                f"L2y={rec.get('rel_l2_y', float('nan')):.3e}",
                flush=True,
            )
    with open(outdir.rstrip("/") + ".json", "w") as fh:
        json.dump({"shift_clamp": args.shift_clamp, "end": args.end, "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
