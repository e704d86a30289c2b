"""Work-precision benchmark of the paper's cantilever: run time against error, and PyElastica.

    make bench     (or: .venv/bin/python benchmarks/work_precision.py [--quick])

Problem: scenes/cao_tucker_2008.toml over 0 ≤ t ≤ 0.06 s. Error: the relative L2 norm over
time (every 10 μs) of the free-end x(ℓ,t) and y(ℓ,t) against a reference; the benchmark error
of a run is the larger of the two, and the largest pointwise error (relative to max |ref|) is
reported as well.

Reference: 32 cubic elements, generalized-α with ρ∞ = 1, Richardson-extrapolated in time from
Δt = 2.5 μs and 1.25 μs (the method is second order). Its own error is bounded by the difference
to the extrapolation from 5 and 2.5 μs (time) plus the change from 24 to 32 elements (space), and
is checked to be at least 10x below the best point plotted.

Configurations (families): element degree 1-3 × elements, time step, integrator (BDF2;
generalized-α with ρ∞ = 0, 0.5, 0.8, 1), Jacobian policy (full, lagged, frozen). Wall time is
the solve loop (probes written every step, no XDMF), median of ``REPEATS`` runs in the same
process with a warm JIT cache; the JIT time of a cold cache is reported separately.

Peer: PyElastica (benchmarks/pyelastica/, its own venv made by its setup.sh) on the same scene
at several resolutions, each at about 90 % of its largest stable time step, numba compile time
excluded.

Outputs (benchmarks/results/, not committed except summary.*): work_precision.png,
scaling.png, work_precision.csv, summary.json and summary.md (time to reach 1e-2, 1e-3, 1e-4,
the ratios to PyElastica, and where the time of one step goes).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np

from cosserat_fem.scene import load_scene
from cosserat_fem.simulation import run

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
RESULTS = ROOT / "benchmarks" / "results"
ELASTICA = ROOT / "benchmarks" / "pyelastica"
REPEATS = 3
NO_FIELDS = ["output.xdmf=false"]


# ------------------------------------------------------------------------------ our runs
def run_ours(overrides: list[str], repeats: int = REPEATS) -> dict:
    """Median solve-loop time of ``repeats`` runs and the probes of the last one."""
    scene = load_scene(SCENE, NO_FIELDS + overrides)
    out = RESULTS / "runs" / "current"
    loops, summary = [], None
    for _ in range(repeats):
        summary = run(scene, out).summary
        loops.append(summary["wall_time_s"]["solve_loop"])
    probes = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    return {
        "overrides": overrides,
        "t": probes[:, 0],
        "x": probes[:, 1],
        "y": probes[:, 2],
        "wall_s": statistics.median(loops),
        "wall_runs_s": loops,
        "dofs": summary["dofs"],
        "steps": summary["steps"],
        "newton": summary["newton"],
    }


def on_grid(t: np.ndarray, u: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Values at the grid times (exact where the run's times contain the grid)."""
    return np.interp(grid, t, u)


def errors(run_: dict, ref: dict) -> dict:
    grid = ref["t"]
    out = {}
    for c in ("x", "y"):
        u = on_grid(run_["t"], run_[c], grid)
        diff = u - ref[c]
        out[f"l2_{c}"] = float(np.sqrt(np.mean(diff**2) / np.mean(ref[c] ** 2)))
        out[f"max_{c}"] = float(np.abs(diff).max() / np.abs(ref[c]).max())
    out["error"] = max(out["l2_x"], out["l2_y"])
    out["max_error"] = max(out["max_x"], out["max_y"])
    return out


def reference() -> tuple[dict, dict]:
    """Richardson-extrapolated fine solution and a measured bound on its error.

    Runs at Δt = 5, 2.5 and 1.25 μs (32 cubic elements, generalized-α ρ∞ = 1); the reference
    is R = (4 u(1.25) − u(2.5))/3. The same extrapolation from (5, 2.5) μs differs from R by
    about the error of that coarser extrapolation, an upper bound for the error of R in time;
    the space error is bounded by the difference of 24 and 32 elements at 1.25 μs.
    """
    fine = [
        "discretisation.degree=3",
        "time.integrator=generalized-alpha",
        "time.rho_inf=1.0",
        "solver.stol=1e-12",
    ]
    runs = {
        dt: run_ours(fine + ["discretisation.elements=32", f"time.step={dt}"], repeats=1)
        for dt in ("5e-6", "2.5e-6", "1.25e-6")
    }
    coarse = run_ours(fine + ["discretisation.elements=24", "time.step=1.25e-6"], repeats=1)
    grid = runs["5e-6"]["t"][::2]  # every 10 μs

    def sampled(r):
        return {"t": grid, "x": on_grid(r["t"], r["x"], grid), "y": on_grid(r["t"], r["y"], grid)}

    def richardson(a, b):
        return {"t": grid, **{c: (4.0 * b[c] - a[c]) / 3.0 for c in ("x", "y")}}

    s5, s25, s125 = (sampled(runs[k]) for k in ("5e-6", "2.5e-6", "1.25e-6"))
    ref, ref_coarse = richardson(s25, s125), richardson(s5, s25)
    estimate = {
        "time_bound": errors(ref_coarse, ref)["error"],
        "space_24_vs_32": errors(sampled(coarse), s125)["error"],
        "richardson_correction": errors(s125, ref)["error"],
        "wall_s": sum(r["wall_s"] for r in runs.values()) + coarse["wall_s"],
    }
    estimate["error_bound"] = estimate["time_bound"] + estimate["space_24_vs_32"]
    return ref, estimate


# ----------------------------------------------------------------------------- families
def families(quick: bool) -> dict[str, list[list[str]]]:
    steps = ("4e-5", "2e-5", "1e-5", "5e-6") if not quick else ("2e-5", "1e-5")
    galpha = ["time.integrator=generalized-alpha"]
    fams: dict[str, list[list[str]]] = {}
    for degree, elements in ((1, (64, 128)), (2, (16, 32)), (3, (8, 12, 16, 24))):
        for n in elements if not quick else elements[-1:]:
            key = f"P{degree}x{n} gen-α 0.8 frozen"
            fams[key] = [
                [
                    f"discretisation.degree={degree}",
                    f"discretisation.elements={n}",
                    *galpha,
                    "time.rho_inf=0.8",
                    f"time.step={dt}",
                ]
                for dt in steps
            ]
    for label, over in (
        ("BDF2", ["time.integrator=bdf2"]),
        ("gen-α 0", [*galpha, "time.rho_inf=0.0"]),
        ("gen-α 0.5", [*galpha, "time.rho_inf=0.5"]),
        ("gen-α 1", [*galpha, "time.rho_inf=1.0"]),
    ):
        fams[f"P3x16 {label} frozen"] = [
            ["discretisation.degree=3", "discretisation.elements=16", *over, f"time.step={dt}"]
            for dt in steps
        ]
    for policy in ("full", "lagged"):
        fams[f"P3x16 gen-α 0.8 {policy}"] = [
            [
                "discretisation.degree=3",
                "discretisation.elements=16",
                *galpha,
                "time.rho_inf=0.8",
                f"solver.jacobian={policy}",
                f"time.step={dt}",
            ]
            for dt in steps
        ]
    return fams


# ---------------------------------------------------------------------------- PyElastica
def _pyelastica_python() -> str | None:
    """Make PyElastica's own venv (benchmarks/pyelastica/setup.sh); its python, or None."""
    proc = subprocess.run(["bash", str(ELASTICA / "setup.sh")], capture_output=True, text=True)
    if proc.returncode != 0:
        print(f"PyElastica: set-up failed, peer skipped:\n{proc.stderr[-2000:]}")
        return None
    venv = Path(os.environ.get("PYELASTICA_VENV", RESULTS / "pyelastica-venv"))
    return str(venv / "bin" / "python")


def _stable_steps(python: str, elements: tuple[int, ...]) -> dict[int, float]:
    """Benchmark step per N: the largest 1e-5/k below 90 % of the measured stable step
    (bisection on short runs, benchmarks/pyelastica/stable_dt.py)."""
    table = ELASTICA / "results" / "stable_dt.json"
    known = {}
    if table.exists():
        known = {row["N"]: row["dt_bench"] for row in json.loads(table.read_text())["rows"]}
    missing = [n for n in elements if n not in known]
    if missing:
        subprocess.run(
            [
                python,
                str(ELASTICA / "stable_dt.py"),
                "--elements",
                *map(str, sorted(set(known) | set(missing))),
            ],
            check=True,
        )
        known = {row["N"]: row["dt_bench"] for row in json.loads(table.read_text())["rows"]}
    return {n: known[n] for n in elements}


def pyelastica_points(quick: bool, shifted: bool = False) -> list[dict]:
    """The peer at several resolutions; [] (with the reason printed) if it cannot run.

    ``shifted``: the clamp moved to s = 0 (``--shift-clamp``), not PyElastica's standard use:
    its clamp fixes the directors of the first element, i.e. acts at s = h/2, which makes the
    standard set-up first order in space (benchmarks/pyelastica/README.md).
    """
    python = _pyelastica_python()
    if python is None:
        return []
    elements = (20, 80) if quick else (10, 20, 40, 80, 160, 320, 640)
    steps = _stable_steps(python, elements)
    points = []
    for n in elements:
        dt = steps[n]
        out = RESULTS / "pyelastica" / f"n{n}{'_shifted' if shifted else ''}.csv"
        out.parent.mkdir(parents=True, exist_ok=True)
        walls = []
        repeats = 1 if (quick or n >= 640) else REPEATS
        for _ in range(repeats):
            cmd = [
                python,
                str(ELASTICA / "cantilever.py"),
                "--elements",
                str(n),
                "--dt",
                repr(dt),
                "--end",
                "0.06",
                "--out",
                str(out),
                "--warmup",
            ]
            proc = subprocess.run(
                cmd + (["--shift-clamp"] if shifted else []), capture_output=True, text=True
            )
            if proc.returncode != 0:
                print(f"PyElastica N={n} failed: {proc.stderr[-500:]}")
                break
            walls.append(json.loads(out.with_suffix(".json").read_text())["wall_s"])
        if not walls:
            continue
        data = np.loadtxt(out, delimiter=",", skiprows=1)
        points.append(
            {
                "elements": n,
                "dt": dt,
                "t": data[:, 0],
                "x": data[:, 1],
                "y": data[:, 2],
                "wall_s": statistics.median(walls),
                "wall_runs_s": walls,
            }
        )
    return points


# --------------------------------------------------------------------------------- report
def time_to_reach(points: list[tuple[float, float]], target: float) -> float | None:
    """Smallest wall time among points whose error is ≤ target."""
    ok = [w for e, w in points if e <= target]
    return min(ok) if ok else None


def harder_component(step: float = 1e-5) -> dict:
    """Which of x(ℓ,t), y(ℓ,t) is harder, derived from the exact linear modal solution.

    From rest, each bending plane responds with a forced part at Ω = 8 ω0 and free vibrations
    at its natural frequencies ω_k with tip amplitudes Q_k Ω W_k(ℓ)/(ω_k (ω_k² − Ω²)). A second
    order, non-dissipative integrator (generalized-α, ρ∞ = 1) shifts the phase of an oscillation
    at ω by (ω h)² ω t/12; the resulting error, summed over the modes in quadrature and divided
    by the root mean square of the response, predicts each component's relative L2 error.
    """
    from cosserat_fem.reference.rod_planes import bending_planes
    from cosserat_fem.reference.timoshenko import forced_response, mode_shapes

    scene = load_scene(SCENE)
    big_omega = 8.0 * scene.omega0
    t = np.arange(0.0, 0.06 + 1e-12, 1e-5)
    t_rms = float(np.sqrt(np.mean(t**2)))
    out = {}
    for name, beam in zip("xy", bending_planes(scene), strict=True):
        r = forced_response(beam, 2e3, big_omega, t, modes=20)
        w, q = np.asarray(r.omega), np.asarray(r.Q)
        tip = np.array([m.W(beam.length) for m in mode_shapes(beam, 20)])
        free = np.abs(q / (w**2 - big_omega**2) * (big_omega / w) * tip)
        forced = float(np.abs(q / (w**2 - big_omega**2) * tip).sum())
        phase = (w * step) ** 2 * w * t_rms / 12.0
        err = np.hypot(
            np.sqrt(np.sum((free * phase) ** 2) / 2.0),
            forced * (big_omega * step) ** 2 * big_omega * t_rms / 12.0 / np.sqrt(2),
        )
        rms = float(np.sqrt(np.mean(np.asarray(r.w) ** 2)))
        k = int(np.argmax(free * phase))
        out[name] = {
            "predicted_relative_error": float(err / rms),
            "dominant_mode_rad_s": float(w[k]),
            "dominant_free_amplitude_m": float(free[k]),
        }
    out["predicted_ratio_y_over_x"] = (
        out["y"]["predicted_relative_error"] / out["x"]["predicted_relative_error"]
    )
    return out


def step_breakdown() -> dict:
    """Where the time of one step of the default scene goes (serial, warm cache)."""
    scene = load_scene(SCENE, NO_FIELDS)
    summary = run(scene, RESULTS / "runs" / "breakdown").summary
    nt, steps = summary["newton"], summary["steps"]
    loop = summary["wall_time_s"]["solve_loop_without_output"]
    # One Jacobian assembly + LU factorisation, measured on the side.
    full = run(
        load_scene(SCENE, NO_FIELDS + ["solver.jacobian=full", "time.end=0.001"]),
        RESULTS / "runs" / "breakdown_full",
    ).summary["newton"]
    per_step = {
        "residual_assembly_ms": 1e3 * nt["time_residual"] / steps,
        "jacobian_assembly_ms": 1e3 * nt["time_jacobian"] / steps,
        "linear_solves_and_snes_ms": 1e3
        * (nt["time_solve"] - nt["time_residual"] - nt["time_jacobian"])
        / steps,
        "python_and_bookkeeping_ms": 1e3 * (loop - nt["time_solve"]) / steps,
        "total_ms": 1e3 * loop / steps,
        "newton_iterations_per_step": nt["iterations"] / steps,
        "jacobian_assemblies": nt["jacobian_assemblies"],
        "full_newton_ms_per_step": 1e3 * full["time_solve"] / full["solves"],
        "full_newton_jacobian_ms": 1e3 * full["time_jacobian"] / full["jacobian_assemblies"],
    }
    return per_step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer configurations, 1 repeat")
    args = parser.parse_args()
    global REPEATS
    if args.quick:
        REPEATS = 1
    RESULTS.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()

    print("reference ...", flush=True)
    ref, ref_est = reference()
    print(
        f"  reference error bound {ref_est['error_bound']:.1e} "
        f"(Richardson correction {ref_est['richardson_correction']:.1e}, "
        f"space 24 vs 32 {ref_est['space_24_vs_32']:.1e})",
        flush=True,
    )

    rows = []
    curves: dict[str, list[tuple[float, float]]] = {}
    for family, configs in families(args.quick).items():
        for over in configs:
            r = run_ours(over)
            e = errors(r, ref)
            row = {
                "code": "cosserat-fem",
                "family": family,
                "config": " ".join(over),
                "dofs": r["dofs"],
                "steps": r["steps"],
                "wall_s": r["wall_s"],
                "newton_iterations": r["newton"]["iterations"],
                "jacobians": r["newton"]["jacobian_assemblies"],
                **e,
            }
            rows.append(row)
            curves.setdefault(family, []).append((e["error"], r["wall_s"]))
            print(
                f"  {family:28s} {over[-1]:16s} err {e['error']:.2e} wall {r['wall_s']:.2f} s",
                flush=True,
            )
    default = run_ours([])
    default_err = errors(default, ref)
    rows.append(
        {
            "code": "cosserat-fem",
            "family": "default scene",
            "config": "(defaults)",
            "dofs": default["dofs"],
            "steps": default["steps"],
            "wall_s": default["wall_s"],
            "newton_iterations": default["newton"]["iterations"],
            "jacobians": default["newton"]["jacobian_assemblies"],
            **default_err,
        }
    )

    peer, peer_shifted = [], []
    for shifted, store in ((False, peer), (True, peer_shifted)):
        label = "PyElastica, clamp shifted to s = 0" if shifted else "PyElastica"
        print(f"{label} ...", flush=True)
        for p in pyelastica_points(args.quick, shifted):
            e = errors(p, ref)
            store.append((e["error"], p["wall_s"]))
            rows.append(
                {
                    "code": "PyElastica",
                    "family": label,
                    "config": f"N={p['elements']} dt={p['dt']:.3g}",
                    "dofs": 6 * (p["elements"] + 1),
                    "steps": round(0.06 / p["dt"]),
                    "wall_s": p["wall_s"],
                    "newton_iterations": 0,
                    "jacobians": 0,
                    **e,
                }
            )
            print(
                f"  N={p['elements']} dt={p['dt']:.2e} err {e['error']:.2e} "
                f"wall {p['wall_s']:.2f} s",
                flush=True,
            )

    with open(RESULTS / "work_precision.csv", "w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)

    ours_all = [(r["error"], r["wall_s"]) for r in rows if r["code"] == "cosserat-fem"]
    targets = {}
    for target in (1e-2, 1e-3, 1e-4):
        mine, theirs = time_to_reach(ours_all, target), time_to_reach(peer, target)
        targets[f"{target:g}"] = {
            "cosserat_fem_s": mine,
            "pyelastica_s": theirs,
            "ratio": (theirs / mine) if (mine and theirs) else None,
        }
    best_peer = min(peer, key=lambda p: p[0]) if peer else None
    equal_error = None
    if best_peer:
        mine = time_to_reach(ours_all, best_peer[0])
        equal_error = {
            "pyelastica_error": best_peer[0],
            "pyelastica_s": best_peer[1],
            "cosserat_fem_s": mine,
            "ratio": best_peer[1] / mine if mine else None,
        }
    breakdown = step_breakdown()
    best_plotted = min(e for e, _ in ours_all + peer)
    summary = {
        "reference": ref_est,
        "best_point_plotted": best_plotted,
        "reference_10x_below_best": ref_est["error_bound"] * 10 <= best_plotted,
        "time_to_reach": targets,
        "equal_error_vs_pyelastica": equal_error,
        "default_scene": {
            "error": default_err["error"],
            "l2_x": default_err["l2_x"],
            "l2_y": default_err["l2_y"],
            "max_error": default_err["max_error"],
            "solve_loop_s": default["wall_s"],
            "runs_s": default["wall_runs_s"],
        },
        "step_breakdown": breakdown,
        "harder_component": harder_component(),
        "repeats": REPEATS,
        "benchmark_wall_s": time.perf_counter() - started,
    }
    summary["pyelastica_shifted_clamp_time_to_reach"] = {
        f"{t:g}": time_to_reach(peer_shifted, t) for t in (1e-2, 1e-3, 1e-4)
    }
    (RESULTS / "summary.json").write_text(json.dumps(summary, indent=2), encoding="utf-8")
    plot(curves, peer, rows, peer_shifted)
    print(json.dumps(summary, indent=2))


def plot(curves, peer, rows, peer_shifted=()) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    for family, pts in curves.items():
        e, w = zip(*sorted(pts, key=lambda p: p[1]), strict=True)
        ax.loglog(w, e, "o-", ms=4, lw=1, label=family)
    if peer:
        e, w = zip(*sorted(peer, key=lambda p: p[1]), strict=True)
        ax.loglog(w, e, "ks--", ms=6, lw=1.5, label="PyElastica (standard clamp)")
    if peer_shifted:
        e, w = zip(*sorted(peer_shifted, key=lambda p: p[1]), strict=True)
        ax.loglog(w, e, "kD:", ms=5, lw=1.2, mfc="none", label="PyElastica, clamp at s = 0")
    default = [r for r in rows if r["family"] == "default scene"][0]
    ax.loglog([default["wall_s"]], [default["error"]], "r*", ms=14, label="default scene")
    ax.set_xlabel("wall time of the solve loop [s] (median)")
    ax.set_ylabel("relative L2 error of x(ℓ,t), y(ℓ,t) (max of the two)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("Cao & Tucker (2008) cantilever, 0 ≤ t ≤ 0.06 s")
    fig.tight_layout()
    fig.savefig(RESULTS / "work_precision.png", dpi=130)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for degree in (1, 2, 3):
        pts = sorted(
            (r["dofs"], r["wall_s"] / r["steps"] * 1e3)
            for r in rows
            if r["code"] == "cosserat-fem"
            and r["config"].startswith(f"discretisation.degree={degree}")
            and "frozen" in r["family"]
            and "time.step=1e-05" in r["config"]
        )
        if pts:
            d, c = zip(*pts, strict=True)
            ax.loglog(d, c, "o-", label=f"P{degree}, frozen Jacobian")
    ax.set_xlabel("dofs")
    ax.set_ylabel("ms per time step")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "scaling.png", dpi=130)
    plt.close(fig)


if __name__ == "__main__":
    main()
