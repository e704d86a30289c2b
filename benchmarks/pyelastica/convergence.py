#!/usr/bin/env python3
"""Spatial convergence of the PyElastica cantilever.

Tip displacement x(l, t), y(l, t) over 0 <= t <= --end (default 0.02 s) for
N = 10, 20, 40, 80, (160, 320, 640) at one small dt (default 1e-7 s, stable for
N <= 640 and with a time error ~1e-8 relative, negligible here).  Errors are
relative L2 over the 1e-5 s samples,
    e_N = ||u_N - u_ref|| / ||u_ref||,
against (a) the finest run, (b) the Richardson extrapolation of the two finest
runs for first order, 2 u_{2N} - u_N, and (c) the cosserat-fem reference
(``demos/output/probes.csv``) when given/found.  Observed orders are
log2(e_N / e_2N).

Writes results/convergence.json (and the per-N CSVs) next to this file.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import cantilever as C  # noqa: E402

DEFAULT_REF = os.path.join(HERE, "..", "..", "demos", "output", "probes.csv")


def rel_l2(u, ref):
    return float(np.linalg.norm(u - ref) / np.linalg.norm(ref))


def load_reference(path, times):
    """Reference tip history (cosserat-fem probes.csv: t,x,y,z,...) on `times`."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    t = data["t"]
    out = np.empty((len(times), 3))
    for k, c in enumerate("xyz"):
        out[:, k] = np.interp(times, t, data[c])
    if times[-1] > t[-1] + 1e-12:
        raise ValueError(f"reference {path} ends at {t[-1]} < {times[-1]}")
    return out


def orders(errs, ns):
    return [
        math.log2(errs[i] / errs[i + 1]) if errs[i + 1] > 0 else None for i in range(len(ns) - 1)
    ]


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--elements", type=int, nargs="+", default=[10, 20, 40, 80, 160, 320, 640])
    ap.add_argument("--dt", type=float, default=1e-7)
    ap.add_argument("--end", type=float, default=0.02)
    ap.add_argument("--reference", default=DEFAULT_REF)
    ap.add_argument(
        "--shift-clamp",
        action="store_true",
        help="non-standard variant (see cantilever.build): effective clamp moved to z=0",
    )
    ap.add_argument("--outdir", default=None)
    args = ap.parse_args(argv)
    if args.outdir is None:
        args.outdir = os.path.join(
            HERE, "results", "convergence_shifted" if args.shift_clamp else "convergence"
        )

    os.makedirs(args.outdir, exist_ok=True)
    C.simulate(10, args.dt, 20 * args.dt, record=False)  # JIT warm-up
    runs = {}
    for n in sorted(args.elements):
        s, steps, wall, ok = C.simulate(n, args.dt, args.end, shift_clamp=args.shift_clamp)
        if not ok:
            raise SystemExit(f"N={n} dt={args.dt} unstable")
        runs[n] = s
        np.savetxt(
            os.path.join(args.outdir, f"N{n}_dt{args.dt:.0e}.csv"),
            s,
            delimiter=",",
            header="t,x,y,z",
            comments="",
            fmt="%.16e",
        )
        print(
            f"N={n:4d} steps={steps} wall={wall:.2f}s  x(end)={s[-1, 1]:.6e} y(end)={s[-1, 2]:.6e}",
            flush=True,
        )
    ns = sorted(runs)
    times = runs[ns[0]][:, 0]
    finest = runs[ns[-1]][:, 1:3]
    p = 2 if args.shift_clamp else 1  # assumed order for the extrapolation
    rich = (2**p * runs[ns[-1]][:, 1:3] - runs[ns[-2]][:, 1:3]) / (2**p - 1)
    res = {
        "dt": args.dt,
        "end": args.end,
        "N": ns,
        "vs_finest": {},
        "vs_richardson": {},
        "vs_cosserat_fem": {},
    }
    refs = {"vs_finest": finest, "vs_richardson": rich}
    if args.reference and os.path.exists(args.reference):
        refs["vs_cosserat_fem"] = load_reference(args.reference, times)[:, 0:2]
        res["reference"] = os.path.abspath(args.reference)
    else:
        del res["vs_cosserat_fem"]
    for key, ref in refs.items():
        for k, c in enumerate("xy"):
            use = ns[:-1] if key == "vs_finest" else ns
            e = [rel_l2(runs[n][:, 1 + k], ref[:, k]) for n in use]
            res[key][c] = {"N": use, "rel_l2": e, "order": orders(e, use)}
    # Richardson vs cosserat-fem
    if "vs_cosserat_fem" in refs:
        res["richardson_vs_cosserat_fem"] = {
            c: rel_l2(rich[:, k], refs["vs_cosserat_fem"][:, k]) for k, c in enumerate("xy")
        }
    res["shift_clamp"] = bool(args.shift_clamp)
    with open(args.outdir.rstrip("/") + ".json", "w") as fh:
        json.dump(res, fh, indent=1)
    for key in refs:
        for c in "xy":
            r = res[key][c]
            print(
                f"{key:16s} {c}: "
                + "  ".join(f"N={n}:{e:.3e}" for n, e in zip(r["N"], r["rel_l2"], strict=True))
            )
            print(
                f"{'':16s}    orders: "
                + "  ".join("-" if o is None else f"{o:.2f}" for o in r["order"])
            )
    if "richardson_vs_cosserat_fem" in res:
        print(
            f"Richardson (order {p}, two finest) vs cosserat-fem:",
            res["richardson_vs_cosserat_fem"],
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
