"""Convergence of the paper's cantilever (scenes/cao_tucker_2008.toml) in space and time.

Usage (from the repository root, after ``make setup``):

    .venv/bin/python benchmarks/convergence.py [--end 0.06] [--quick]

Each configuration overrides the scene (elements, degree, time step, integrator, Jacobian
policy) and is compared against two references:

* x(ℓ,t), y(ℓ,t): the closed-form *linear* Timoshenko response (exact modal superposition,
  :mod:`cosserat_fem.reference.timoshenko`), which the nonlinear rod must approach up to its
  geometric nonlinearity, measured at 1.6e-5 (x) and 2.5e-5 (y) relative for the paper's load
  (a 10x smaller load reduces it to the time-discretisation level: the nonlinear effect);
* z(ℓ,t), φ(ℓ,t) (purely nonlinear responses): the finest configuration of the study.

Errors are relative L2 norms over the probe times, ‖u_h − u_ref‖ / ‖u_ref‖. Results go to
``benchmarks/results/convergence.json`` and a Markdown table on stdout.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.reference.rod_planes import sine_load_tip_response
from cosserat_fem.scene.build import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
RESULTS = ROOT / "benchmarks" / "results"


def rel_l2(u: np.ndarray, ref: np.ndarray) -> float:
    return float(np.sqrt(np.mean((u - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


def run_config(overrides: list[str], out: Path) -> tuple[np.ndarray, dict]:
    scene = load_scene(SCENE, overrides)
    result = run_scene(scene, out)
    probes = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    return probes, result.summary


CONFIGS = {
    # name: overrides (the time step is appended per row)
    "P2 x 20": ["discretisation.degree=2", "discretisation.elements=20"],
    "P2 x 40": ["discretisation.degree=2", "discretisation.elements=40"],
    "P3 x 16": ["discretisation.degree=3", "discretisation.elements=16"],
    "P3 x 24": ["discretisation.degree=3", "discretisation.elements=24"],
    "P3 x 40": ["discretisation.degree=3", "discretisation.elements=40"],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--end", type=float, default=0.06, help="end time [s]")
    parser.add_argument("--quick", action="store_true", help="fewer configurations")
    args = parser.parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    common = [f"time.end={args.end}", "output.xdmf=false"]

    rows = []
    # Space: fixed small step (generalized-α, ρ∞ = 1: time error ~2e-6 at 2.5e-6 s).
    fine_time = ["time.integrator=generalized-alpha", "time.rho_inf=1.0", "time.step=2.5e-6"]
    space = ["P2 x 20", "P3 x 16", "P3 x 24"] if args.quick else list(CONFIGS)
    # Time: P3 x 24 with several steps and integrators.
    time_rows = []
    for integ in (
        ["time.integrator=bdf2"],
        ["time.integrator=generalized-alpha", "time.rho_inf=1.0"],
        ["time.integrator=generalized-alpha", "time.rho_inf=0.8"],
    ):
        for dt in (2e-5, 1e-5) if args.quick else (4e-5, 2e-5, 1e-5, 5e-6):
            time_rows.append((integ, dt))

    def record(label, overrides):
        t0 = time.perf_counter()
        probes, summary = run_config(common + overrides, RESULTS / "run")
        wall = time.perf_counter() - t0
        t = probes[:, 0]
        scene = load_scene(SCENE, common)
        xr, yr = sine_load_tip_response(scene, t, q0=2e3, omega=8.0 * scene.omega0)
        row = {
            "label": label,
            "overrides": overrides,
            "times": t,
            "probes": probes,
            "err_x": rel_l2(probes[:, 1], xr),
            "err_y": rel_l2(probes[:, 2], yr),
            "max_x": float(np.abs(probes[:, 1]).max()),
            "max_y": float(np.abs(probes[:, 2]).max()),
            "solve_loop_s": summary["wall_time_s"]["solve_loop"],
            "wall_s": wall,
            "newton_iterations": summary["newton"]["iterations"],
            "dofs": summary["dofs"],
        }
        rows.append(row)
        print(
            f"  {label:45s} err_x {row['err_x']:.2e} err_y {row['err_y']:.2e} "
            f"loop {row['solve_loop_s']:.2f} s",
            flush=True,
        )
        return row

    print("space (generalized-alpha, rho_inf = 1, dt = 2.5e-6 s):")
    for name in space:
        record(f"space {name}", CONFIGS[name] + fine_time)
    record("default scene settings", [])
    print("time (P3 x 24):")
    for integ, dt in time_rows:
        record(
            f"time {' '.join(integ)} dt={dt:g}", CONFIGS["P3 x 24"] + integ + [f"time.step={dt}"]
        )

    finest = max((r for r in rows if r["label"].startswith("space")), key=lambda r: r["dofs"])
    for r in rows:
        for j, name in ((3, "z"), (6, "phi")):
            if len(r["times"]) == len(finest["times"]):
                ref = finest["probes"][:, j]
                r[f"err_{name}"] = rel_l2(r["probes"][:, j], ref)
            else:
                step = round(
                    (r["times"][1] - r["times"][0]) / (finest["times"][1] - finest["times"][0])
                )
                ref = finest["probes"][::step, j]
                r[f"err_{name}"] = (
                    rel_l2(r["probes"][:, j], ref) if len(ref) == len(r["times"]) else None
                )

    print(
        "\n| configuration | dofs | err x | err y | err z | err phi | solve loop [s] | Newton its |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        ez = "-" if r.get("err_z") is None else f"{r['err_z']:.1e}"
        ep = "-" if r.get("err_phi") is None else f"{r['err_phi']:.1e}"
        print(
            f"| {r['label']} | {r['dofs']} | {r['err_x']:.1e} | {r['err_y']:.1e} | {ez} | {ep} | "
            f"{r['solve_loop_s']:.2f} | {r['newton_iterations']} |"
        )
    clean = [{k: v for k, v in r.items() if k not in ("times", "probes")} for r in rows]
    (RESULTS / "convergence.json").write_text(json.dumps(clean, indent=2))
    print(f"\nfinest (reference for z, phi): {finest['label']}")


if __name__ == "__main__":
    main()
