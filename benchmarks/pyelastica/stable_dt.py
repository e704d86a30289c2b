#!/usr/bin/env python3
"""Largest stable PositionVerlet time step of the PyElastica cantilever.

For each N, bisect dt on a short undamped run of the benchmark problem
(default 10 ms from rest, the real load); a run is unstable if the tip
displacement becomes non-finite or exceeds 1 m (checked every 1e-5 s).

Alongside, the linear prediction dt_lin = 2 / omega_max is printed, with
omega_max from the generalized eigenproblem K v = omega^2 M v of PyElastica's
discretisation linearised about the straight rod (staggered grid: positions on
nodes with lumped masses rho A h, rotations on elements with inertia rho I h,
shear on elements, bending/twist on interior nodes; node 0 and element 0
clamped), for the four decoupled families: axial, bending+shear in e1 (E I2),
bending+shear in e2 (E I1) and torsion.  Two closed-form estimates are also
given: the axial CFL limit h / c_E with c_E = sqrt(E / rho) and the
rotary-inertia/shear limit  2 / sqrt(12 k G / (rho a^2) + 4 E / (rho h^2)).

Writes ``results/stable_dt.json`` next to this file (or --out).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy.linalg import eigh

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cantilever as C  # noqa: E402


def linear_omega_max(n: int) -> dict:
    h = C.LENGTH / n
    rho, A = C.DENSITY, C.AREA
    out = {}
    # axial: u_1..u_n, springs EA/h
    K = np.zeros((n, n))
    M = np.full(n, rho * A * h)
    M[-1] *= 0.5
    k = C.YOUNG * A / h
    for e in range(n):  # element e joins nodes e, e+1 ; node 0 fixed
        idx = [e - 1, e]
        loc = np.array([[k, -k], [-k, k]])
        for a in range(2):
            for b in range(2):
                if idx[a] >= 0 and idx[b] >= 0:
                    K[idx[a], idx[b]] += loc[a, b]
    out["axial"] = math.sqrt(eigh(K, np.diag(M), eigvals_only=True).max())

    def bending(EI, rhoI):
        # dofs: w_1..w_n (n), theta_1..theta_{n-1} (n-1)
        nd = n + n - 1
        K = np.zeros((nd, nd))
        M = np.zeros(nd)
        M[:n] = rho * A * h
        M[n - 1] *= 0.5
        M[n:] = rhoI * h
        ks = C.KAPPA_SHEAR * C.SHEAR_MOD * A * h  # gamma_e = (w_{e+1}-w_e)/h - theta_e

        def wi(i):  # node index -> dof or -1
            return i - 1 if i >= 1 else -1

        def ti(e):  # element index -> dof or -1
            return n + e - 1 if e >= 1 else -1

        for e in range(n):
            idx = [wi(e), wi(e + 1), ti(e)]
            g = np.array([-1.0 / h, 1.0 / h, -1.0])
            loc = ks * np.outer(g, g)
            for a in range(3):
                for b in range(3):
                    if idx[a] >= 0 and idx[b] >= 0:
                        K[idx[a], idx[b]] += loc[a, b]
        for j in range(1, n):  # interior node j: kappa = (theta_j - theta_{j-1})/h
            idx = [ti(j - 1), ti(j)]
            g = np.array([-1.0 / h, 1.0 / h])
            loc = EI * h * np.outer(g, g)
            for a in range(2):
                for b in range(2):
                    if idx[a] >= 0 and idx[b] >= 0:
                        K[idx[a], idx[b]] += loc[a, b]
        return math.sqrt(eigh(K, np.diag(M), eigvals_only=True).max())

    out["bend_e1"] = bending(C.YOUNG * C.I2, rho * C.I2)
    out["bend_e2"] = bending(C.YOUNG * C.I1, rho * C.I1)
    # torsion: theta_1..theta_{n-1}, springs GJ/h between elements
    m = n - 1
    K = np.zeros((m, m))
    kt = C.SHEAR_MOD * C.J_TORSION / h
    for j in range(1, n):
        idx = [j - 2, j - 1]
        loc = np.array([[kt, -kt], [-kt, kt]])
        for a in range(2):
            for b in range(2):
                if idx[a] >= 0 and idx[b] >= 0:
                    K[idx[a], idx[b]] += loc[a, b]
    Mt = np.full(m, rho * (C.I1 + C.I2) * h)
    out["torsion"] = math.sqrt(eigh(K, np.diag(Mt), eigvals_only=True).max())
    return out


def is_stable(n, dt, run):
    _, _, _, ok = C.simulate(n, dt, run, record=False)
    return ok


def bisect(n, run, guess, rtol=0.005):
    lo, hi = 0.5 * guess, 1.5 * guess
    while not is_stable(n, lo, run):
        hi, lo = lo, lo / 2
    while is_stable(n, hi, run):
        lo, hi = hi, hi * 2
    while hi / lo - 1 > rtol:
        mid = math.sqrt(lo * hi)
        if is_stable(n, mid, run):
            lo = mid
        else:
            hi = mid
    return lo, hi


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--elements", type=int, nargs="+", default=[10, 20, 40, 80, 160])
    ap.add_argument("--run", type=float, default=0.01, help="length of the test run (s)")
    ap.add_argument("--safety", type=float, default=0.9)
    ap.add_argument(
        "--out",
        default=os.path.join(
            os.path.dirname(os.path.abspath(__file__)), "results", "stable_dt.json"
        ),
    )
    args = ap.parse_args(argv)

    C.simulate(10, 1e-6, 2e-5, record=False)  # JIT warm-up
    c_e = math.sqrt(C.YOUNG / C.DENSITY)
    c_s = math.sqrt(C.KAPPA_SHEAR * C.SHEAR_MOD / C.DENSITY)
    rows = []
    hdr = (
        "N",
        "dt_stable",
        "dt_unstable",
        "dt_lin",
        "h/c_E",
        "dt_rot",
        "C=dt*c_E/h",
        "dt_bench",
        "k=1e-5/dt_b",
        "secs",
    )
    print(("{:>5} " + "{:>12} " * (len(hdr) - 1)).format(*hdr))
    for n in args.elements:
        t0 = time.perf_counter()
        h = C.LENGTH / n
        om = linear_omega_max(n)
        dt_lin = 2.0 / max(om.values())
        dt_axial = h / c_e
        dt_rot = 2.0 / math.sqrt(
            12 * C.KAPPA_SHEAR * C.SHEAR_MOD / (C.DENSITY * C.A_THICK**2)
            + 4 * C.YOUNG / (C.DENSITY * h * h)
        )
        lo, hi = bisect(n, args.run, dt_lin)
        # benchmark step: <= safety * dt_stable and dividing the 1e-5 s output interval
        k = math.ceil(C.SAMPLE_DT / (args.safety * lo) - 1e-9)
        dt_b = C.SAMPLE_DT / k
        secs = time.perf_counter() - t0
        row = dict(
            N=n,
            h=h,
            dt_stable=lo,
            dt_unstable=hi,
            dt_linear=dt_lin,
            omega_max=om,
            dt_axial_cfl=dt_axial,
            dt_rot_shear_estimate=dt_rot,
            C_axial=lo * c_e / h,
            C_shear=lo * c_s / h,
            dt_bench=dt_b,
            k=k,
            test_run_s=args.run,
            search_s=secs,
        )
        rows.append(row)
        print(
            f"{n:>5} {lo:12.4e} {hi:12.4e} {dt_lin:12.4e} {dt_axial:12.4e} {dt_rot:12.4e} "
            f"{lo * c_e / h:12.4f} {dt_b:12.4e} {k:12d} {secs:12.1f}",
            flush=True,
        )
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump(dict(c_E=c_e, c_shear=c_s, safety=args.safety, rows=rows), fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
