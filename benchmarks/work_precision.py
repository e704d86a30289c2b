"""Work-precision benchmark of the paper's cantilever: run time against error, and PyElastica.

    make bench     (or: .venv/bin/python benchmarks/work_precision.py [--quick])

Problem: scenes/cao_tucker_2008.toml over 0 ≤ t ≤ 0.06 s. Error: the relative L2 norm over
time (every 10 μs) of the free-end x(ℓ,t) and y(ℓ,t) against a reference; the benchmark error
of a run is the larger of the two, and the largest pointwise error (relative to max |ref|) is
reported as well. Which of the two is harder is derived from the exact linear modal solution
(:func:`harder_component`) and compared with what the runs show.

Reference: 40 cubic elements, SDIRK3 at Δt = 1.25 μs, Newton to stol = 1e-12. Its error is
bounded by (time) |u(2.5 μs) − u(1.25 μs)|/3, the error of the finer run for any method of
order ≥ 2 (SDIRK3 is third order), plus (space) |u(32 elements) − u(40 elements)| at 1.25 μs,
a bound for the 32-element run and so for the 40-element one; the bound must be at least 10x
below the best point plotted.

Configurations (families): element degree 1-3 × elements × time step × integrator (BDF2;
generalized-α with ρ∞ = 0, 0.5, 0.8, 1; SDIRK3 and SDIRK4) × Jacobian policy (full, lagged,
frozen), and adaptive steps (SDIRK3, generalized-α) at several tolerances. Wall time is the
solve loop (probes written every step, no XDMF), median of ``REPEATS`` runs in one process with
a warm JIT cache, taken in passes over all configurations (:func:`timed_rows`); the JIT time
of a cold cache is measured separately in a fresh process (:func:`jit_times`).

Peer: PyElastica (benchmarks/pyelastica/, its own venv made by its setup.sh) on the same scene
at several resolutions, each at about 90 % of its largest stable time step, numba compile time
excluded (measured separately).

Outputs (benchmarks/results/, not committed except summary.*): work_precision.png,
scaling.png, work_precision.csv, scaling.csv, summary.json and summary.md (time to reach 1e-2,
1e-3 and 1e-4, the ratios to PyElastica, the default scene, and where the time of one step
goes).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from petsc4py import PETSc

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.scene.build import load_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
RESULTS = ROOT / "benchmarks" / "results"
ELASTICA = ROOT / "benchmarks" / "pyelastica"
REPEATS = 3
DEFAULT_REPEATS = 5
NO_FIELDS = ["output.xdmf=false"]
TARGETS = (1e-2, 1e-3, 1e-4)


# ------------------------------------------------------------------------- resumable rows
class RowCache:
    """Finished rows, appended to ``rows.jsonl`` as they come: a benchmark that fails or is
    stopped keeps them, and ``--resume`` skips what is already there."""

    def __init__(self, path: Path, resume: bool):
        self.path = path
        self.rows: dict[str, dict] = {}
        if resume and path.exists():
            for line in path.read_text(encoding="utf-8").splitlines():
                row = json.loads(line)
                self.rows[row.pop("_key")] = row
        elif path.exists():
            path.unlink()

    def get(self, key: str) -> dict | None:
        return self.rows.get(key)

    def put(self, key: str, row: dict) -> dict:
        self.rows[key] = row
        with open(self.path, "a", encoding="utf-8") as stream:
            stream.write(json.dumps({"_key": key, **row}) + "\n")
        return row


# ------------------------------------------------------------------------------ our runs
def run_ours(overrides: list[str], repeats: int = REPEATS) -> dict:
    """Median solve-loop time of ``repeats`` runs and the probes of the last one."""
    scene = load_scene(SCENE, NO_FIELDS + overrides)
    out = RESULTS / "runs" / "current"
    loops, summary = [], None
    for _ in range(repeats):
        summary = run_scene(scene, out).summary
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


def probe_error(probes: np.ndarray) -> float | None:
    """The benchmark error of probe rows (t, x, y, ...) of the paper's scene against the stored
    reference (results/reference.npz, made by ``make bench``); None without it."""
    stored = RESULTS / "reference.npz"
    if not stored.exists():
        return None
    data = np.load(stored)
    ref = {c: data[c] for c in ("t", "x", "y")}
    return errors({"t": probes[:, 0], "x": probes[:, 1], "y": probes[:, 2]}, ref)["error"]


def reference(quick: bool, resume: bool) -> tuple[dict, dict]:
    """The fine solution and a measured bound on its error (module docstring); kept in
    reference.npz/.json, reused with ``--resume``."""
    stored, info = RESULTS / "reference.npz", RESULTS / "reference.json"
    if resume and stored.exists() and info.exists():
        data = np.load(stored)
        return {c: data[c] for c in ("t", "x", "y")}, json.loads(info.read_text())
    ref, estimate = _compute_reference(quick)
    np.savez(stored, **ref)
    info.write_text(json.dumps(estimate, indent=2), encoding="utf-8")
    return ref, estimate


def _compute_reference(quick: bool) -> tuple[dict, dict]:
    fine = ["discretisation.degree=3", "time.integrator=sdirk3", "solver.stol=1e-12"]
    n_fine, n_coarse = (24, 16) if quick else (40, 32)
    dt_fine, dt_coarse = ("2.5e-6", "5e-6") if quick else ("1.25e-6", "2.5e-6")
    finest = run_ours(fine + [f"discretisation.elements={n_fine}", f"time.step={dt_fine}"], 1)
    coarse_t = run_ours(fine + [f"discretisation.elements={n_fine}", f"time.step={dt_coarse}"], 1)
    coarse_s = run_ours(fine + [f"discretisation.elements={n_coarse}", f"time.step={dt_fine}"], 1)
    grid = np.round(np.arange(0.0, 0.06 + 1e-12, 1e-5), 12)

    def sampled(r):
        return {"t": grid, "x": on_grid(r["t"], r["x"], grid), "y": on_grid(r["t"], r["y"], grid)}

    ref = sampled(finest)
    estimate = {
        "configuration": f"P3 x {n_fine}, SDIRK3, dt = {dt_fine} s, stol = 1e-12",
        "time_bound": errors(sampled(coarse_t), ref)["error"] / 3.0,
        "time_difference": errors(sampled(coarse_t), ref)["error"],
        "space_bound": errors(sampled(coarse_s), ref)["error"],
        "wall_s": finest["wall_s"] + coarse_t["wall_s"] + coarse_s["wall_s"],
    }
    estimate["error_bound"] = estimate["time_bound"] + estimate["space_bound"]
    return ref, estimate


# ----------------------------------------------------------------------------- families
def _config(degree: int, elements: int, integrator: list[str], policy: str, dt: str) -> list:
    return [
        f"discretisation.degree={degree}",
        f"discretisation.elements={elements}",
        *integrator,
        f"solver.jacobian={policy}",
        f"time.step={dt}",
    ]


GEN_ALPHA_08 = ["time.integrator=generalized-alpha", "time.rho_inf=0.8"]
SDIRK3 = ["time.integrator=sdirk3"]
SDIRK4 = ["time.integrator=sdirk4"]


def families(quick: bool) -> dict[str, list[list[str]]]:
    """Configuration families: one curve each in the work-precision plot."""
    two_step = ("4e-5", "2e-5", "1e-5", "5e-6", "2.5e-6") if not quick else ("2e-5", "1e-5")
    rk = ("8e-5", "6e-5", "4e-5", "3e-5", "2e-5", "1e-5") if not quick else ("4e-5", "2e-5")
    fams: dict[str, list[list[str]]] = {}

    def add(label, degree, elements, integrator, steps, policy="frozen"):
        fams[label] = [_config(degree, elements, integrator, policy, dt) for dt in steps]

    # Space: degree and elements, generalized-α ρ∞ = 0.8 (the two-step default).
    space = ((1, (64, 128)), (2, (16, 32)), (3, (8, 12, 16, 24)))
    for degree, elements in space:
        for n in elements if not quick else elements[-1:]:
            steps = two_step if (degree, n) in ((3, 12), (3, 16)) else two_step[:4]
            add(f"P{degree}x{n} gen-α 0.8", degree, n, GEN_ALPHA_08, steps)
    # Time integrators on 16 cubic elements.
    for label, over in (
        ("BDF2", ["time.integrator=bdf2"]),
        ("gen-α 0", ["time.integrator=generalized-alpha", "time.rho_inf=0.0"]),
        ("gen-α 0.5", ["time.integrator=generalized-alpha", "time.rho_inf=0.5"]),
        ("gen-α 1", ["time.integrator=generalized-alpha", "time.rho_inf=1.0"]),
    ):
        add(f"P3x16 {label}", 3, 16, over, two_step[:4])
    for n in (8, 12, 16) if not quick else (12,):
        add(f"P3x{n} SDIRK3", 3, n, SDIRK3, rk)
    for n in (12, 16) if not quick else (16,):
        add(f"P3x{n} SDIRK4", 3, n, SDIRK4, rk)
    # Adaptive steps (time.step is then the first step and the output interval).
    tolerances = ("1e-3", "1e-4", "1e-5", "1e-6") if not quick else ("1e-4",)
    for label, integrator in (("SDIRK3", SDIRK3), ("gen-α 0.8", GEN_ALPHA_08)):
        fams[f"P3x16 {label} adaptive"] = [
            [
                "discretisation.degree=3",
                "discretisation.elements=16",
                *integrator,
                "solver.jacobian=frozen",
                "time.adaptive=true",
                "time.atol=1e-12",
                "time.step=1e-5",
                f"time.rtol={rtol}",
            ]
            for rtol in tolerances
        ]
    # Jacobian policies (frozen is the default of every family above).
    for policy in ("full", "lagged"):
        add(f"P3x16 gen-α 0.8 {policy} Jacobian", 3, 16, GEN_ALPHA_08, two_step[:4], policy)
        add(f"P3x12 SDIRK3 {policy} Jacobian", 3, 12, SDIRK3, rk[::2], policy)
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


def pyelastica_points(quick: bool, shifted: bool, cache: RowCache, label: str):
    """Yield (N, run, compile times) for the peer at several resolutions; nothing if it
    cannot run. Resolutions already in ``cache`` (key ``label|N``) yield (N, None, {}).

    ``shifted``: the clamp moved to s = 0 (``--shift-clamp``), not PyElastica's standard use:
    its clamp fixes the directors of the first element, i.e. acts at s = h/2, which makes the
    standard set-up first order in space (benchmarks/pyelastica/README.md).
    """
    elements = (20, 80) if quick else (10, 20, 40, 80, 160, 320, 640)
    todo = [n for n in elements if cache.get(f"{label}|{n}") is None]
    for n in elements:
        if n not in todo:
            yield n, None, {}
    if not todo:
        return
    python = _pyelastica_python()
    if python is None:
        return
    steps = _stable_steps(python, elements)
    for n in todo:
        dt = steps[n]
        out = RESULTS / "pyelastica" / f"n{n}{'_shifted' if shifted else ''}.csv"
        out.parent.mkdir(parents=True, exist_ok=True)
        walls, compile_s = [], []
        repeats = 1 if (quick or n >= 640) else REPEATS
        for _ in range(repeats):
            cmd = [python, str(ELASTICA / "cantilever.py"), "--elements", str(n)]
            cmd += ["--dt", repr(dt), "--end", "0.06", "--out", str(out), "--warmup"]
            proc = subprocess.run(
                cmd + (["--shift-clamp"] if shifted else []), capture_output=True, text=True
            )
            if proc.returncode != 0:
                print(f"PyElastica N={n} failed: {proc.stderr[-500:]}")
                break
            record = json.loads(out.with_suffix(".json").read_text())
            walls.append(record["wall_s"])
            compile_s.append(record["compile_s"])
        if not walls:
            continue
        data = np.loadtxt(out, delimiter=",", skiprows=1)
        point = {"dt": dt, "t": data[:, 0], "x": data[:, 1], "y": data[:, 2]}
        point.update(wall_s=statistics.median(walls), wall_runs_s=walls)
        yield n, point, {"warm_cache_compile_s_median": statistics.median(compile_s)}


# --------------------------------------------------------------------------------- extras
def jit_times() -> dict:
    """Set-up and JIT compile time of the default scene, cold cache and warm, fresh processes.

    A cold cache is an empty ``XDG_CACHE_HOME`` (where FFCx puts its compiled forms)."""
    out: dict = {}
    end = 4 * load_scene(SCENE).time.step  # four steps of the default scene
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as run_dir:
        for label in ("cold", "warm"):
            env = dict(os.environ, XDG_CACHE_HOME=cache)
            cmd = [sys.executable, "-m", "cosserat_fem.cli", "run", str(SCENE)]
            cmd += ["--set", f"time.end={end!r}", "--set", "output.xdmf=false", "--out", run_dir]
            t0 = time.perf_counter()
            subprocess.run(cmd, env=env, check=True, capture_output=True)
            process = time.perf_counter() - t0
            summary = json.loads((Path(run_dir) / "summary.json").read_text())
            out[label] = {
                "process_s": process,
                "setup_s": summary["wall_time_s"]["setup"],
                "jit_compile_s": summary["wall_time_s"]["jit_compile"],
            }
    return out


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


_EVENTS = ("KSPSolve", "MatSolve")
_FACTOR_EVENTS = ("MatLUFactorSym", "MatLUFactorNum")


def _event_times() -> dict[str, float]:
    return {e: PETSc.Log.Event(e).getPerfInfo()["time"] for e in _EVENTS + _FACTOR_EVENTS}


def step_breakdown(overrides: list[str] | None = None) -> dict:
    """Where the time of one step of the default scene goes (serial, warm cache).

    The Newton solver's timers (cosserat_fem/nls/newton.py: residual and Jacobian assemblies, the
    whole solves) and PETSc's event log (LU factorisation, symbolic + numeric, and triangular
    solves, MatSolve, inside KSPSolve); what is left of the solves is the Newton loop's own
    work (norms, vector updates, convergence tests). Outside the solves: the integrator's
    predictor and history update, the state check and the probe output, i.e. the time loop's
    Python.
    """
    PETSc.Log.begin()
    scene = load_scene(SCENE, NO_FIELDS + (overrides or []))
    run_scene(scene, RESULTS / "runs" / "breakdown")  # warm-up (JIT cache, first-touch)
    loops, parts, summaries = [], [], []
    for _ in range(DEFAULT_REPEATS):
        before = _event_times()
        summaries.append(run_scene(scene, RESULTS / "runs" / "breakdown").summary)
        after = _event_times()
        loops.append(summaries[-1]["wall_time_s"]["solve_loop"])
        parts.append({k: after[k] - before[k] for k in before})
    i = int(np.argsort(loops)[len(loops) // 2])  # the median run
    d, steps, nt = parts[i], summaries[i]["steps"], summaries[i]["newton"]
    factor = d["MatLUFactorSym"] + d["MatLUFactorNum"]
    ms = 1e3 / steps
    return {
        "solve_loop_s": loops[i],
        "residual_assembly_ms": ms * nt["time_residual"],
        "jacobian_assembly_ms": ms * nt["time_jacobian"],
        "lu_factorisation_ms": ms * factor,
        "triangular_solves_ms": ms * d["MatSolve"],
        "ksp_overhead_ms": ms * (d["KSPSolve"] - d["MatSolve"] - factor),
        "newton_loop_ms": ms
        * (nt["time_solve"] - nt["time_residual"] - nt["time_jacobian"] - d["KSPSolve"]),
        "time_loop_python_ms": ms * (loops[i] - nt["time_solve"]),
        "total_ms": ms * loops[i],
        "newton_iterations_per_step": nt["iterations"] / steps,
        "residual_assemblies_per_step": nt["residual_assemblies"] / steps,
        "jacobian_assemblies": nt["jacobian_assemblies"],
    }


def scaling(quick: bool) -> list[dict]:
    """Cost per time step against dofs, degrees 1-3, frozen and full Jacobian (300 steps of
    the paper's scene, generalized-α ρ∞ = 0.8, Δt = 10 μs)."""
    rows = []
    counts = (8, 32, 128) if quick else (8, 16, 32, 64, 128, 256)
    for degree in (1, 2, 3):
        for n in counts:
            for policy in ("frozen", "full"):
                over = _config(degree, n, GEN_ALPHA_08, policy, "1e-5") + ["time.end=0.003"]
                r = run_ours(over, repeats=1 if quick else REPEATS)
                rows.append(
                    {
                        "degree": degree,
                        "elements": n,
                        "policy": policy,
                        "dofs": r["dofs"],
                        "ms_per_step": 1e3 * r["wall_s"] / r["steps"],
                        "newton_iterations_per_step": r["newton"]["iterations"] / r["steps"],
                    }
                )
                print(f"  scaling P{degree}x{n} {policy}: {rows[-1]['ms_per_step']:.3f} ms/step")
    return rows


# --------------------------------------------------------------------------------- report
def time_to_reach(points: list[tuple[float, float]], target: float) -> float | None:
    """Smallest wall time among points whose error is ≤ target."""
    ok = [w for e, w in points if e <= target]
    return min(ok) if ok else None


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """(error, wall) points that no other point beats in both, by increasing wall time."""
    front, best = [], float("inf")
    for error, wall in sorted(points, key=lambda p: (p[1], p[0])):
        if error < best:
            front.append((error, wall))
            best = error
    return front


def best_config(rows: list[dict], target: float) -> dict | None:
    ok = [r for r in rows if r["code"] == "cosserat-fem" and r["error"] <= target]
    return min(ok, key=lambda r: r["wall_s"]) if ok else None


def _short(row: dict) -> str:
    """'family, Δt = ...' (or 'rtol = ...') for a row of ours."""
    rtol = [c for c in row["config"].split() if c.startswith("time.rtol=")]
    if rtol:
        return f"{row['family']}, rtol = {rtol[0].split('=')[1]}"
    step = [c for c in row["config"].split() if c.startswith("time.step=")]
    return f"{row['family']}, Δt = {step[0].split('=')[1]} s" if step else row["family"]


def write_csv(path: Path, rows: list[dict]) -> None:
    fields = list(dict.fromkeys(k for row in rows for k in row))
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)


def timed_rows(configs: list[tuple[str, list[str]]], cache: RowCache, ref: dict) -> list[dict]:
    """One row per (family, overrides): errors against ``ref`` and the median solve-loop time.

    The repeats are taken in passes over all configurations (pass 1 runs each once, pass 2
    again, ...), not back to back: this machine has slow spells of tens of seconds (the same
    run measured 0.9 s and 1.9 s minutes apart), which back-to-back repeats would put on one
    configuration's every run and the median could not remove. The default scene gets
    ``DEFAULT_REPEATS`` passes, the others ``REPEATS``; a row is cached after every pass."""
    keys = [f"{family}|{' '.join(over)}" for family, over in configs]
    wanted = [DEFAULT_REPEATS if family == "default scene" else REPEATS for family, _ in configs]
    for n in range(max(wanted)):
        for key, (family, over), repeats in zip(keys, configs, wanted, strict=True):
            row = cache.get(key)
            if n >= repeats or (row is not None and len(row["wall_runs_s"]) > n):
                continue
            r = run_ours(over, repeats=1)
            if row is None:
                nt = r["newton"]
                row = {
                    "code": "cosserat-fem",
                    "family": family,
                    "config": " ".join(over) if over else "(defaults)",
                    "dofs": r["dofs"],
                    "steps": r["steps"],
                    "wall_s": r["wall_s"],
                    "wall_runs_s": [],
                    "newton_iterations": nt["iterations"],
                    "residual_assemblies": nt["residual_assemblies"],
                    "jacobians": nt["jacobian_assemblies"],
                    **({"newton": nt} if family == "default scene" else {}),
                    **errors(r, ref),
                }
            row["wall_runs_s"] = [*row["wall_runs_s"], r["wall_s"]]
            row["wall_s"] = statistics.median(row["wall_runs_s"])
            cache.put(key, row)
            print(
                f"  pass {n + 1}  {family:32s} {(over or ['(defaults)'])[-1]:17s} "
                f"err {row['error']:.2e} wall {r['wall_s']:.2f} s (median {row['wall_s']:.2f})"
                f" it/step {row['newton_iterations'] / row['steps']:.2f}",
                flush=True,
            )
    return [cache.get(key) for key in keys]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer configurations, 1 repeat")
    parser.add_argument("--no-peer", action="store_true", help="skip PyElastica")
    parser.add_argument(
        "--resume", action="store_true", help="reuse the reference and the rows of a stopped run"
    )
    args = parser.parse_args()
    global REPEATS, DEFAULT_REPEATS
    if args.quick:
        REPEATS = DEFAULT_REPEATS = 1
    RESULTS.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()

    print("reference ...", flush=True)
    ref, ref_est = reference(args.quick, args.resume)
    print(
        f"  reference error bound {ref_est['error_bound']:.1e} (time {ref_est['time_bound']:.1e},"
        f" space {ref_est['space_bound']:.1e})",
        flush=True,
    )

    cache = RowCache(RESULTS / "rows.jsonl", args.resume)
    configs = [(f, over) for f, overs in families(args.quick).items() for over in overs]
    configs.append(("default scene", []))
    rows = timed_rows(configs, cache, ref)
    default_err = {k: rows[-1][k] for k in ("l2_x", "max_x", "l2_y", "max_y", "error", "max_error")}
    default = {"wall_s": rows[-1]["wall_s"], "wall_runs_s": rows[-1]["wall_runs_s"]}
    default.update(steps=rows[-1]["steps"], newton=rows[-1]["newton"])

    peers: dict[str, list[tuple[float, float]]] = {"standard": [], "shifted": []}
    peer_compile: dict[str, list[float]] = {}
    for shifted in (False, True):
        if args.no_peer:
            break
        label = "PyElastica, clamp shifted to s = 0" if shifted else "PyElastica"
        print(f"{label} ...", flush=True)
        for n, p, compile_info in pyelastica_points(args.quick, shifted, cache, label):
            row = cache.get(f"{label}|{n}")
            if row is None:
                row = cache.put(
                    f"{label}|{n}",
                    {
                        "code": "PyElastica",
                        "family": label,
                        "config": f"N={n} dt={p['dt']:.3g}",
                        "dofs": 6 * (n + 1),
                        "steps": round(0.06 / p["dt"]),
                        "wall_s": p["wall_s"],
                        "newton_iterations": 0,
                        "residual_assemblies": 0,
                        "jacobians": 0,
                        "compile_s": compile_info["warm_cache_compile_s_median"],
                        **errors(p, ref),
                    },
                )
            rows.append(row)
            peer_compile.setdefault("warm_cache_compile_s", []).append(row["compile_s"])
            peers["shifted" if shifted else "standard"].append((row["error"], row["wall_s"]))
            print(f"  {row['config']} err {row['error']:.2e} wall {row['wall_s']:.2f} s")
    write_csv(RESULTS / "work_precision.csv", rows)

    print("scaling ...", flush=True)
    scale_rows = scaling(args.quick)
    write_csv(RESULTS / "scaling.csv", scale_rows)
    print("step breakdown and JIT ...", flush=True)
    breakdown = step_breakdown()
    jit = jit_times()

    ours_all = [(r["error"], r["wall_s"]) for r in rows if r["code"] == "cosserat-fem"]
    peer = peers["standard"]
    targets = {}
    for target in TARGETS:
        mine, theirs = time_to_reach(ours_all, target), time_to_reach(peer, target)
        best = best_config(rows, target)
        targets[f"{target:g}"] = {
            "cosserat_fem_s": mine,
            "cosserat_fem_config": _short(best) if best else None,
            "pyelastica_s": theirs,
            "ratio": (theirs / mine) if (mine and theirs) else None,
        }
    equal_error = None
    if peer:
        best_peer = min(peer, key=lambda p: p[0])
        mine = time_to_reach(ours_all, best_peer[0])
        equal_error = {
            "pyelastica_error": best_peer[0],
            "pyelastica_s": best_peer[1],
            "cosserat_fem_s": mine,
            "ratio": best_peer[1] / mine if mine else None,
        }
    best_plotted = min(e for e, _ in ours_all + peer + peers["shifted"])
    summary = {
        "reference": ref_est,
        "best_point_plotted": best_plotted,
        "reference_10x_below_best": ref_est["error_bound"] * 10 <= best_plotted,
        "time_to_reach": targets,
        "equal_error_vs_pyelastica": equal_error,
        "pyelastica_shifted_clamp_time_to_reach": {
            f"{t:g}": time_to_reach(peers["shifted"], t) for t in TARGETS
        },
        "default_scene": {
            **default_err,
            "solve_loop_s": default["wall_s"],
            "runs_s": default["wall_runs_s"],
            "steps": default["steps"],
            "newton": default["newton"],
        },
        "step_breakdown": breakdown,
        "jit": jit,
        "pyelastica_compile": peer_compile,
        "harder_component": harder_component(),
        "repeats": REPEATS,
        "benchmark_wall_s": time.perf_counter() - started,
    }
    (RESULTS / "summary.json").write_text(json.dumps(summary, indent=2), encoding="utf-8")
    (RESULTS / "summary.md").write_text(summary_markdown(summary, rows), encoding="utf-8")
    plot(rows, peers, scale_rows)
    print((RESULTS / "summary.md").read_text())


def _s(value: float | None) -> str:
    return "not reached" if value is None else f"{value:.3g} s"


def summary_markdown(summary: dict, rows: list[dict]) -> str:
    """The tables of benchmarks/README.md, regenerated."""
    lines = ["| error ≤ | cosserat-fem | its configuration | PyElastica | ratio |"]
    lines.append("|---|---|---|---|---|")
    for target, row in summary["time_to_reach"].items():
        ratio = f"{row['ratio']:.0f}x" if row["ratio"] else "–"
        lines.append(
            f"| {target} | {_s(row['cosserat_fem_s'])} | {row['cosserat_fem_config'] or '–'} "
            f"| {_s(row['pyelastica_s'])} | {ratio} |"
        )
    eq = summary["equal_error_vs_pyelastica"]
    if eq:
        lines += [
            "",
            f"At PyElastica's best affordable error ({eq['pyelastica_error']:.2e}, "
            f"{eq['pyelastica_s']:.3g} s): cosserat-fem {_s(eq['cosserat_fem_s'])}, "
            f"ratio {eq['ratio']:.0f}x.",
        ]
    d = summary["default_scene"]
    lines += [
        "",
        f"Default scene: error {d['error']:.2e} (x {d['l2_x']:.2e}, y {d['l2_y']:.2e}; "
        f"max {d['max_error']:.2e}), solve loop {d['solve_loop_s']:.3g} s (median of "
        f"{len(d['runs_s'])}: {', '.join(f'{v:.3g}' for v in d['runs_s'])}).",
        "",
        "| one step of the default scene | ms |",
        "|---|---|",
    ]
    b = summary["step_breakdown"]
    for key in (
        "residual_assembly_ms",
        "jacobian_assembly_ms",
        "lu_factorisation_ms",
        "triangular_solves_ms",
        "ksp_overhead_ms",
        "newton_loop_ms",
        "time_loop_python_ms",
        "total_ms",
    ):
        lines.append(f"| {key.removesuffix('_ms').replace('_', ' ')} | {b[key]:.4f} |")
    r = summary["reference"]
    lines += [
        "",
        f"Reference: {r['configuration']}; error bound {r['error_bound']:.1e} (time "
        f"{r['time_bound']:.1e}, space {r['space_bound']:.1e}); best point plotted "
        f"{summary['best_point_plotted']:.1e}.",
    ]
    j = summary["jit"]
    lines.append(
        f"JIT: cold cache {j['cold']['jit_compile_s']:.2f} s compile "
        f"({j['cold']['process_s']:.1f} s process), warm {j['warm']['jit_compile_s']:.3f} s "
        f"({j['warm']['process_s']:.1f} s process)."
    )
    return "\n".join(lines) + "\n"


def plot(rows: list[dict], peers: dict, scale_rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 6.5))
    curves: dict[str, list[tuple[float, float]]] = {}
    for r in rows:
        if r["code"] == "cosserat-fem" and r["family"] != "default scene":
            curves.setdefault(r["family"], []).append((r["error"], r["wall_s"]))
    cmap = plt.get_cmap("tab20")
    for i, (family, pts) in enumerate(curves.items()):
        e, w = zip(*sorted(pts, key=lambda p: p[1]), strict=True)
        style = "s-" if "SDIRK" in family else ("^--" if "Jacobian" in family else "o-")
        if "adaptive" in family:
            style = "v-."
        ax.loglog(w, e, style, ms=3.5, lw=1, color=cmap(i % 20), label=family)
    for key, style, label in (
        ("standard", "ks--", "PyElastica (its standard clamp)"),
        ("shifted", "kD:", "PyElastica, clamp moved to s = 0"),
    ):
        if peers.get(key):
            e, w = zip(*sorted(peers[key], key=lambda p: p[1]), strict=True)
            ax.loglog(
                w, e, style, ms=6, lw=1.5, mfc="none" if key == "shifted" else "k", label=label
            )
    front = pareto_front([(r["error"], r["wall_s"]) for r in rows if r["code"] == "cosserat-fem"])
    e, w = zip(*front, strict=True)
    ax.loglog(w, e, "-", color="red", lw=3, alpha=0.35, label="cosserat-fem, best of all")
    default = [r for r in rows if r["family"] == "default scene"][0]
    ax.loglog([default["wall_s"]], [default["error"]], "r*", ms=16, label="default scene")
    for target in TARGETS:
        ax.axhline(target, color="0.6", lw=0.6, ls=":")
    ax.set_xlabel("wall time of the solve loop [s] (median)")
    ax.set_ylabel("relative L2 error of x(ℓ,t), y(ℓ,t) (the larger)")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=6.5, ncol=2, loc="lower left")
    ax.set_title("Cao & Tucker (2008) cantilever, 0 ≤ t ≤ 0.06 s: work against precision")
    fig.tight_layout()
    fig.savefig(RESULTS / "work_precision.png", dpi=130)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.5, 4.8))
    for degree, color in zip((1, 2, 3), ("C0", "C1", "C2"), strict=True):
        for policy, style in (("frozen", "o-"), ("full", "s--")):
            pts = sorted(
                (r["dofs"], r["ms_per_step"])
                for r in scale_rows
                if r["degree"] == degree and r["policy"] == policy
            )
            if pts:
                d, c = zip(*pts, strict=True)
                ax.loglog(d, c, style, color=color, label=f"P{degree}, {policy} Jacobian")
    ax.set_xlabel("dofs (12 per node)")
    ax.set_ylabel("ms per time step (median)")
    ax.set_title("Cost of a generalized-α step, serial")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "scaling.png", dpi=130)
    plt.close(fig)


if __name__ == "__main__":
    main()
