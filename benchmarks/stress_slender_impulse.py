"""Stress case 5 (a very slender rod, ℓ/a = 1000) and the impulse scene (adaptive steps).

Usage (from the repository root):

    .venv/bin/python benchmarks/stress_slender_impulse.py [--part slender|impulse|all] [--quick]

About 6-7 minutes on the 2-core machine (``--quick``: about 2). Tables go to stdout and to
``benchmarks/results/stress_slender_impulse.md``, the numbers to ``.json`` next to it.

**Part A, the slender rod.** A cantilever ℓ = 1 m, square 1 mm × 1 mm section (ℓ/a = 1000),
E = 7.1e10 Pa, ν = 0.32, κ = 0.833, under a tip force P along e1 with α = Pℓ²/(EI).

* Linear regime (α = 3e-5, tip deflection 1e-5 ℓ): the tip deflection against Timoshenko's
  closed form Pℓ³/(3EI) + Pℓ/(κGA) (the shear term is 7.9e-7 of the bending one here) for
  degree 1-3, full (2k) and reduced (2k − 2, 1 for k = 1) quadrature, 4-512 elements, with the
  ratios that the locking analysis of ``tests/test_stress_slender.py`` predicts:
  P1 full (1 − 1/(4N²))/(1 + μ), μ = κGAh²/(12EI); P1 reduced 1 − 1/(4N²);
  P2 full 1 − λ/((1 + λ) 4N²), λ = κGAh²/(60EI); P2 reduced and P3 exact (the solution is in
  the space). And a sine load f = q sin(πs/ℓ) against its closed form, where P3 is not exact.
* The second-order deviation (membrane locking: the axial constraint z' ≈ −ψ²/2 cannot be
  met by z' of degree k − 1) at α = 3e-4 and 3e-3.
* Newton: the iteration history of a small-load solve, iterations per load step of the
  elastica α = 10 for ℓ/a = 25 ... 1000, the condition number of the Jacobian, and a
  dynamic run (sudden tip force, SDIRK3, frozen Jacobian).
* Large deflection (α = 2, 10) against the exact extensible, shearable rod
  (``reissner_tip_load``), full and reduced quadrature, degree 1-4.

**Part B, the impulse scene** (``scenes/impulse.toml``): error of x(ℓ,t), y(ℓ,t) (relative L2
over t = 0, 1, ..., 60 ms, the larger of the two) against SDIRK3 at Δt = 1.25 μs (bounded by
its distance to Δt = 2.5 μs), against the number of steps and the solve-loop time (median of
``REPEATS`` runs, probes written, no XDMF), for fixed steps Δt = 1 ms/k and adaptive steps
(SDIRK3 and generalized-α ρ∞ = 0.8), and the cost ratio at equal error: for each adaptive run
the cheapest fixed run of the same integrator whose error is not larger. Also the step sizes the
controller takes, a pulse at t = 5 ms (after a quiet start), and a blow on the free end instead
of the distributed one ("tip hammer").
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_matrix

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.reference.elastica import reissner_tip_load
from cosserat_fem.reference.timoshenko import (
    TimoshenkoBeam,
    natural_frequencies,
    static_deflection_sine_load,
    tip_deflection_end_force,
)
from cosserat_fem.rod.model import build_model, rod_constants
from cosserat_fem.scene.build import load_scene, scene_from_dict
from cosserat_fem.timestepping import adaptive
from cosserat_fem.timestepping.events import Observer
from cosserat_fem.timestepping.integrators import make_integrator

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
IMPULSE = ROOT / "scenes" / "impulse.toml"
REPEATS = 3
GRID = 1e-3  # s, error grid of part B (every fixed step below divides it)

# ----------------------------------------------------------------------------- part A data
LENGTH, SIDE = 1.0, 1e-3
YOUNG, POISSON, KAPPA, DENSITY = 7.1e10, 0.32, 0.833, 2730.0
BEAM = TimoshenkoBeam.rectangular(LENGTH, SIDE, SIDE, YOUNG, POISSON, KAPPA, DENSITY)


class Report:
    """Markdown lines, printed as they come and written at the end."""

    def __init__(self):
        self.lines: list[str] = []
        self.data: dict = {}

    def __call__(self, text: str = "") -> None:
        print(text, flush=True)
        self.lines.append(text)

    def table(self, header: list[str], rows: list[list]) -> None:
        self("| " + " | ".join(header) + " |")
        self("|" + "---|" * len(header))
        for row in rows:
            self("| " + " | ".join(str(v) for v in row) + " |")
        self()


def rod_table(side: float) -> dict:
    """The slender rod's [rod] table: ℓ = LENGTH, a square section of the given side [m]."""
    return {
        "length": LENGTH,
        "section": {"a": side, "b": side, "shear_coefficient": KAPPA},
        "material": {"density": DENSITY, "young_modulus": YOUNG, "poisson_ratio": POISSON},
    }


def slender_scene(
    degree: int,
    elements: int,
    quadrature="auto",
    force=(0.0, 0.0, 0.0),
    side: float = SIDE,
    load_steps: int = 1,
    force_density=(0, 0, 0),
):
    """The slender cantilever as a scene (statics; time keys only to satisfy the schema)."""
    return scene_from_dict(
        {
            "rod": rod_table(side),
            "loads": {"force_density": list(force_density), "end": {"force": list(force)}},
            "time": {"end": 1.0, "step": 1.0},
            "discretisation": {
                "elements": elements,
                "degree": degree,
                "quadrature_degree": quadrature,
            },
            "static": {"load_steps": load_steps},
            "solver": {"max_iterations": 30},
            "output": {"xdmf": False},
        }
    )


class NewtonLog(Observer):
    """Every Newton iteration's norms and SNES reason (the newton_iteration event)."""

    def __init__(self):
        self.rows: list[tuple] = []

    def newton_iteration(self, loop, it, norms, reason) -> None:
        self.rows.append((it, *norms, reason))


class AcceptedTimes(Observer):
    """The end times [s] of the accepted steps (the step_accepted event)."""

    def __init__(self):
        self.times: list[float] = []

    def step_accepted(self, loop) -> None:
        self.times.append(loop.state.t)


def tip_values(scene, observers=()) -> tuple[np.ndarray, list[int], int]:
    result = static_path(scene, write_outputs=False, observers=observers)
    tip = PointProbe(result.model, 1.0).values()
    return tip, result.iterations, result.bisections


def reduced(degree: int) -> int:
    """Reduced quadrature: k Gauss points, degree 2k − 2 (1 for k = 1: the schema needs ≥ 1)."""
    return max(1, 2 * degree - 2)


def predicted_ratio(degree: int, quadrature, n: int) -> float:
    """Tip deflection / (Pℓ³/(3EI) + Pℓ/(κGA)) of the linear Timoshenko FE (the analysis)."""
    h = LENGTH / n
    bending, shear = LENGTH**3 / (3 * BEAM.EI), LENGTH / BEAM.kGA
    full = quadrature == "auto"
    if degree == 1:
        mu = BEAM.kGA * h * h / (12 * BEAM.EI) if full else 0.0
        return (bending * (1 - 1 / (4 * n * n)) / (1 + mu) + shear) / (bending + shear)
    if degree == 2 and full:
        lam = BEAM.kGA * h * h / (60 * BEAM.EI)
        return (bending * (1 - lam / (1 + lam) / (4 * n * n)) + shear) / (bending + shear)
    return 1.0


def part_slender(report: Report, quick: bool) -> None:
    report("## A. Stress case 5: a slender cantilever, ℓ/a = 1000")
    report()
    shear_share = (LENGTH / BEAM.kGA) / (LENGTH**3 / (3 * BEAM.EI))
    report(
        f"EI = {BEAM.EI:.4e} N m², κGA = {BEAM.kGA:.4e} N, κGAℓ²/EI = "
        f"{BEAM.kGA * LENGTH**2 / BEAM.EI:.3e}; shear term / bending term of the tip "
        f"deflection = {shear_share:.3e}"
    )
    report()
    data = report.data.setdefault("slender", {})

    # -- linear tip load -------------------------------------------------------------------
    alpha = 3e-5
    P = alpha * BEAM.EI / LENGTH**2
    exact = tip_deflection_end_force(BEAM, P)
    nonlinear = -4.0 / 35.0 * alpha**2  # elastica: w/ℓ = α/3 − 4α³/105
    report(f"### Tip force, α = Pℓ²/(EI) = {alpha:g} (geometric nonlinearity {nonlinear:.1e})")
    report()
    counts = (4, 8, 16, 32, 64, 128, 256) if quick else (4, 8, 16, 32, 64, 128, 256, 512)
    rows, table = [], {}
    for degree in (1, 2, 3):
        for quadrature in ("auto", reduced(degree)):
            previous = None
            for n in counts:
                tip, its, _ = tip_values(slender_scene(degree, n, quadrature, (P, 0, 0)))
                ratio = tip[0] / exact
                pred = predicted_ratio(degree, quadrature, n)
                err = abs(ratio - 1.0)
                rate = math.log2(previous / err) if previous and err > 1e-9 else None
                previous = err
                label = "full (2k)" if quadrature == "auto" else f"reduced ({quadrature})"
                table[f"P{degree} {label} {n}"] = {"ratio": ratio, "predicted": pred, "its": its}
                rows.append(
                    [
                        f"P{degree}",
                        label,
                        n,
                        f"{ratio:.10f}",
                        f"{pred:.10f}",
                        f"{ratio / pred - 1:+.1e}",
                        "" if rate is None else f"{rate:.2f}",
                        its[0],
                    ]
                )
    report.table(
        [
            "degree",
            "quadrature",
            "N",
            "tip / closed form",
            "analysis",
            "measured/analysis − 1",
            "rate",
            "Newton its",
        ],
        rows,
    )
    data["tip_force"] = table

    # -- sine load -------------------------------------------------------------------------
    q = 3e-4 * BEAM.EI / LENGTH**3
    exact_sine = static_deflection_sine_load(BEAM, q, LENGTH)[0]
    report("### Sine load q sin(πs/ℓ), qℓ³/(EI) = 3e-4 (P3 is not exact here)")
    report()
    rows = []
    for degree in (1, 2, 3):
        for quadrature in ("auto", reduced(degree)) if degree > 1 else (1,):
            previous = None
            for n in (4, 8, 16, 32, 64):
                scene = slender_scene(
                    degree, n, quadrature, force_density=(f"{q!r}*sin(pi*s/L)", 0, 0)
                )
                tip, _, _ = tip_values(scene)
                err = tip[0] / exact_sine - 1.0
                rate = math.log2(abs(previous / err)) if previous else None
                previous = err
                rows.append(
                    [
                        f"P{degree}",
                        "full (2k)" if quadrature == "auto" else f"reduced ({quadrature})",
                        n,
                        f"{err:+.3e}",
                        "" if rate is None else f"{rate:.2f}",
                    ]
                )
    report.table(["degree", "quadrature", "N", "tip / closed form − 1", "rate"], rows)

    # -- second-order deviation ------------------------------------------------------------
    report("### The deviation beyond linear theory and the elastica's −(4/35)α² (full quadrature)")
    report()
    rows = []
    for degree in (2, 3):
        for a in (3e-5, 3e-4, 3e-3):
            P2 = a * BEAM.EI / LENGTH**2
            lin = tip_deflection_end_force(BEAM, P2)
            for n in (4, 8, 16):
                tip, _, _ = tip_values(slender_scene(degree, n, "auto", (P2, 0, 0)))
                dev = tip[0] / lin / predicted_ratio(degree, "auto", n) - 1 + 4 / 35 * a**2
                rows.append([f"P{degree}", f"{a:g}", n, f"{dev:+.2e}", f"{dev / a**2:+.3e}"])
    report.table(["degree", "α", "N", "deviation", "deviation / α²"], rows)

    # -- Newton ----------------------------------------------------------------------------
    report("### Newton at ℓ/a = 1000")
    report()
    newton_log = NewtonLog()
    log = newton_log.rows
    # The Newton iterations, observed through the newton_iteration event.
    for degree, n in ((2, 16), (3, 8)):
        log.clear()
        tip_values(slender_scene(degree, n, "auto", (P, 0, 0)), (newton_log,))
        report(f"Small load (α = {alpha:g}), P{degree} × {n}, full Newton from the straight rod:")
        report()
        report.table(
            ["iteration", "‖U‖", "‖δU‖/‖U‖", "‖F‖", "SNES reason"],
            [
                [it, f"{x:.3e}", f"{(y / x if x else 0):.1e}", f"{f:.2e}", r]
                for it, x, y, f, r in log
            ],
        )
    rows = []
    sides = (4e-2, 1e-3) if quick else (4e-2, 4e-3, 2e-3, 1e-3)
    for side in sides:
        EI = YOUNG * side**4 / 12
        for steps in (20, 40, 80):
            log.clear()
            scene = slender_scene(4, 16, "auto", (10.0 * EI, 0, 0), side, steps)
            _, its, bisections = tip_values(scene, (newton_log,))
            relative = sum(1 for row in log if row[-1] == 3)
            rows.append(
                [
                    f"{LENGTH / side:.0f}",
                    steps,
                    sum(its),
                    max(its),
                    bisections,
                    relative,
                ]
            )
    report("Elastica α = 10, P4 × 16, full Newton, secant predictor:")
    report()
    report.table(
        [
            "ℓ/a",
            "load steps",
            "Newton its",
            "most in a step",
            "bisections",
            "solves ended by ‖F‖ ≤ rtol ‖F0‖",
        ],
        rows,
    )

    rows = []
    for side in (4e-2, 1e-3):
        for degree, n in ((3, 8), (2, 16), (1, 64)):
            model = build_model(slender_scene(degree, n, "auto", side=side))
            integrator = make_integrator("static", model.U, model.residual, 0.0)
            form = integrator.residual_form()
            J = fem.form(ufl.derivative(form, model.U, ufl.TrialFunction(model.V)))
            A = assemble_matrix(J, bcs=model.bcs)
            A.assemble()
            dense = A.convert("dense").getDenseArray().copy()  # a view until copied
            A.destroy()
            scale = 1.0 / np.sqrt(np.abs(dense).max(axis=1))
            rows.append(
                [
                    f"{LENGTH / side:.0f}",
                    f"P{degree} × {n}",
                    f"{np.linalg.cond(dense):.2e}",
                    f"{np.linalg.cond(scale[:, None] * dense * scale[None, :]):.2e}",
                ]
            )
    report("Condition number of the static Jacobian at the straight rod (2-norm, dense):")
    report()
    report.table(["ℓ/a", "mesh", "cond(J)", "cond(D J D), D = diag(max row)^-½"], rows)

    rows = []
    for side, P_dyn, dt, integrator in (
        (1e-3, 1e-5, 1e-3, "sdirk3"),
        (1e-3, 1e-5, 1e-4, "sdirk3"),
        (1e-3, 1e-5, 1e-3, "generalized-alpha"),
        (4e-2, 10.0, 3e-5, "sdirk3"),
    ):
        beam = TimoshenkoBeam.rectangular(LENGTH, side, side, YOUNG, POISSON, KAPPA, DENSITY)
        omega1 = natural_frequencies(beam, 1)[0]
        end = round(math.pi / omega1 / dt) * dt  # half a first period
        scene = scene_from_dict(
            {
                "rod": rod_table(side),
                "loads": {"end": {"force": [P_dyn, 0, 0]}},
                "time": {"end": end, "step": dt, "integrator": integrator, "rho_inf": 0.8},
                "discretisation": {"elements": 8, "degree": 3},
                "solver": {"jacobian": "frozen"},
                "output": {"xdmf": False},
            }
        )
        summary = run_scene(scene, RESULTS / "slender_dynamic").summary
        stats = summary["newton"]
        rows.append(
            [
                f"{LENGTH / side:.0f}",
                integrator,
                f"{dt:g}",
                summary["accepted_steps"],
                f"{stats['iterations'] / summary['accepted_steps']:.2f}",
                stats["jacobian_assemblies"],
                stats["retries"],
                stats["max_iterations_in_a_solve"],
            ]
        )
    report("Dynamics: a sudden tip force (δ_static = 1.7e-3 ℓ), half a first period, P3 × 8:")
    report()
    report.table(
        ["ℓ/a", "integrator", "Δt [s]", "steps", "Newton its/step", "Jacobians", "retries", "max"],
        rows,
    )

    # -- large deflection ------------------------------------------------------------------
    report("### Large deflection at ℓ/a = 1000 against the exact rod (reissner_tip_load)")
    report()
    rows = []
    for alpha_big in (2.0, 10.0):
        P_big = alpha_big * BEAM.EI / LENGTH**2
        scene0 = slender_scene(2, 4, force=(P_big, 0, 0))
        rod = rod_constants(scene0)
        s = rod.section
        exact_rod = reissner_tip_load(
            LENGTH, YOUNG * s.area, KAPPA * rod.shear_modulus * s.area, YOUNG * s.c22, P_big
        )
        for degree in (1, 2, 3, 4):
            for quadrature in ("auto", reduced(degree)) if degree > 1 else (1,):
                for n in (8, 16, 32) if quick else (8, 16, 32, 64):
                    scene = slender_scene(degree, n, quadrature, (P_big, 0, 0), load_steps=20)
                    tip, its, bisections = tip_values(scene)
                    rows.append(
                        [
                            f"{alpha_big:g}",
                            f"P{degree}",
                            "full (2k)" if quadrature == "auto" else f"reduced ({quadrature})",
                            n,
                            f"{(tip[0] - exact_rod.tip_x) / LENGTH:+.2e}",
                            f"{(LENGTH + tip[2] - exact_rod.tip_z) / LENGTH:+.2e}",
                            f"{sum(its)}/{len(its)}",
                            max(its),
                            bisections,
                        ]
                    )
    report.table(
        [
            "α",
            "degree",
            "quadrature",
            "N",
            "Δx(ℓ)/ℓ",
            "Δz(ℓ)/ℓ",
            "Newton its / steps",
            "most",
            "bisections",
        ],
        rows,
    )


# ============================================================================= part B
def probes(scene, out: Path) -> tuple[np.ndarray, dict]:
    summary = run_scene(scene, out).summary
    return np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1), summary


def on_grid(data: np.ndarray) -> np.ndarray:
    k = np.round(data[:, 0] / GRID)
    return data[np.abs(data[:, 0] - k * GRID) < 1e-9 * GRID]


def errors(data: np.ndarray, ref: np.ndarray) -> list[float]:
    """Relative L2 errors of x, y, z, φ on the grid."""
    d, r = on_grid(data), on_grid(ref)
    assert d.shape == r.shape, (d.shape, r.shape)
    return [
        float(np.sqrt(np.mean((d[:, j] - r[:, j]) ** 2) / np.mean(r[:, j] ** 2)))
        for j in (1, 2, 3, 6)
    ]


def timed(scene, out: Path, repeats: int) -> tuple[np.ndarray, dict, float, float]:
    """Probes, summary and the median solve-loop times (with and without output)."""
    loops, bare = [], []
    for _ in range(repeats):
        data, summary = probes(scene, out)
        loops.append(summary["wall_time_s"]["solve_loop"])
        bare.append(summary["wall_time_s"]["solve_loop_without_output"])
    return data, summary, statistics.median(loops), statistics.median(bare)


def step_profile(scene) -> np.ndarray:
    """Accepted step end times of an adaptive run (the step_accepted event)."""
    accepted = AcceptedTimes()
    run_scene(scene, write_outputs=False, observers=(accepted,))
    return np.array(accepted.times)


def adaptive_overhead(report: Report, ref: np.ndarray, repeats: int) -> None:
    """Where the time of an adaptive run goes, against the fixed step of the same accuracy:
    the dense output (StateHistory.polynomial, timed by a wrapper: the error estimate of each
    step and the interpolation of each output), and an output grid 2.5x coarser
    (time.step = 25 μs = T/4: the first p + 1 = 4 steps, taken without an estimate, then
    cover the pulse)."""
    out = RESULTS / "impulse_run"
    spent = [0.0]
    original = adaptive.StateHistory.polynomial

    def polynomial(self, t, points):
        t0 = time.perf_counter()
        value = original(self, t, points)
        spent[0] += time.perf_counter() - t0
        return value

    runs = {
        "fixed Δt = 50 μs": ["time.adaptive=false", "time.step=5e-05"],
        "adaptive rtol = 1e-3, time.step = 10 μs": [],
        "adaptive rtol = 1e-3, time.step = 25 μs": ["time.step=2.5e-05"],
    }
    scenes = {
        label: load_scene(IMPULSE, ["output.xdmf=false", *over]) for label, over in runs.items()
    }
    loops: dict[str, list[float]] = {label: [] for label in runs}
    dense: dict[str, list[float]] = {label: [] for label in runs}
    last: dict[str, tuple] = {}
    count = max(repeats, 5)
    adaptive.StateHistory.polynomial = polynomial
    try:
        for _ in range(count):  # interleaved, so that machine drift hits all alike
            for label, scene in scenes.items():
                spent[0] = 0.0
                last[label] = probes(scene, out)
                loops[label].append(last[label][1]["wall_time_s"]["solve_loop"])
                dense[label].append(spent[0])
    finally:
        adaptive.StateHistory.polynomial = original
    rows = []
    for label in runs:
        data, summary = last[label]
        stats = summary["newton"]
        rows.append(
            [
                label,
                summary["accepted_steps"] + summary["rejected_steps"],
                summary["steps"],
                f"{max(errors(data, ref)[:2]):.2e}",
                f"{statistics.median(loops[label]):.3f}",
                f"{statistics.median(dense[label]):.3f}",
                f"{stats['time_solve']:.3f}",
                stats["iterations"],
                stats["jacobian_assemblies"],
            ]
        )
    report.data.setdefault("impulse", {})["overhead"] = {
        label: {"loops": loops[label], "dense": dense[label]} for label in runs
    }
    report(f"Where the time goes (SDIRK3, medians of {count} interleaved runs):")
    report()
    report.table(
        [
            "run",
            "steps (with rejected)",
            "outputs",
            "error x, y",
            "solve loop [s]",
            "dense output and estimates [s]",
            "SNES [s]",
            "Newton its",
            "Jacobians",
        ],
        rows,
    )


def _impulse_row(kind: str, label: str, s: dict, e, loop: float, bare: float) -> list:
    """A row of the impulse table: kind, setting, accepted and rejected steps, errors, times,
    Jacobians (``s``: a run's summary; ``e``: its errors)."""
    return [
        kind,
        label,
        s["accepted_steps"],
        s["rejected_steps"] if kind == "adaptive" else 0,
        f"{max(e[:2]):.2e}",
        f"{e[2]:.1e}",
        f"{e[3]:.1e}",
        f"{loop:.3f}",
        f"{bare:.3f}",
        s["newton"]["jacobian_assemblies"],
    ]


def part_impulse(report: Report, quick: bool) -> None:
    report("## B. Where adaptive steps pay off: scenes/impulse.toml")
    report()
    data = report.data.setdefault("impulse", {})
    repeats = 1 if quick else REPEATS
    no_fields = ["output.xdmf=false"]
    fixed = ["time.adaptive=false"]
    out = RESULTS / "impulse_run"
    scene_probe = load_scene(IMPULSE)
    duration = scene_probe.parameters["duration"]

    t0 = time.perf_counter()
    ref, _ = probes(
        load_scene(IMPULSE, no_fields + fixed + ["time.step=1.25e-6", "solver.stol=1e-12"]), out
    )
    ref2, _ = probes(
        load_scene(IMPULSE, no_fields + fixed + ["time.step=2.5e-6", "solver.stol=1e-12"]), out
    )
    bound = errors(ref2, ref)
    report(
        f"Reference: SDIRK3 at 1.25 μs; its distance to 2.5 μs (a bound of its own error for any "
        f"order ≥ 1): x {bound[0]:.1e}, y {bound[1]:.1e} ({time.perf_counter() - t0:.0f} s for "
        f"both). Error grid: every {GRID * 1e3:g} ms. Peaks: x {np.abs(ref[:, 1]).max():.3e} m, "
        f"y {np.abs(ref[:, 2]).max():.3e} m, z {np.abs(ref[:, 3]).max():.2e} m, φ "
        f"{np.abs(ref[:, 6]).max():.2e} rad."
    )
    report()
    data["reference_bound"] = bound

    ks = (
        (10, 15, 20, 25, 50, 100)
        if quick
        else (10, 12, 14, 15, 16, 18, 20, 22, 25, 28, 35, 50, 100)
    )
    curves: dict[str, dict[str, list]] = {}
    for integrator in ("sdirk3", "generalized-alpha"):
        label = "SDIRK3" if integrator == "sdirk3" else "generalized-α ρ∞ = 0.8"
        base = no_fields + [f"time.integrator={integrator}", "time.rho_inf=0.8"]
        rows, fixed_runs, adaptive_runs = [], [], []
        for k in ks:
            dt = GRID / k
            d, s, loop, bare = timed(
                load_scene(IMPULSE, base + fixed + [f"time.step={dt!r}"]), out, repeats
            )
            e = errors(d, ref)
            fixed_runs.append(
                {
                    "dt": dt,
                    "steps": s["accepted_steps"],
                    "error": max(e[:2]),
                    "loop": loop,
                    "bare": bare,
                }
            )
            rows.append(
                _impulse_row(
                    "fixed",
                    f"Δt = {dt * 1e6:.2f} μs (T/Δt = {duration / dt:.2f})",
                    s,
                    e,
                    loop,
                    bare,
                )
            )
        starts = ("1e-5", "1e-6") if integrator == "generalized-alpha" else ("1e-5",)
        rtols = (1e-3, 1e-4) if quick else (3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5)
        for first in starts:
            for rtol in rtols:
                if integrator == "generalized-alpha" and first == "1e-6" and rtol < 1e-4:
                    continue  # 60000 outputs of dense output a run: slow, and nothing new
                over = base + ["time.adaptive=true", f"time.step={first}", f"time.rtol={rtol:g}"]
                d, s, loop, bare = timed(load_scene(IMPULSE, over), out, repeats)
                e = errors(d, ref)
                adaptive_runs.append(
                    {
                        "rtol": rtol,
                        "first": first,
                        "steps": s["accepted_steps"],
                        "rejected": s["rejected_steps"],
                        "error": max(e[:2]),
                        "loop": loop,
                        "bare": bare,
                    }
                )
                rows.append(
                    _impulse_row(
                        "adaptive", f"rtol = {rtol:g}, time.step = {first}", s, e, loop, bare
                    )
                )
        report(f"### {label}")
        report()
        report.table(
            [
                "steps",
                "setting",
                "accepted",
                "rejected",
                "error x, y",
                "error z",
                "error φ",
                "solve loop [s]",
                "without output [s]",
                "Jacobians",
            ],
            rows,
        )
        rows = []
        for a in adaptive_runs:
            good = [f for f in fixed_runs if f["error"] <= a["error"]]
            if not good:
                rows.append(
                    [f"{a['rtol']:g} ({a['first']})", f"{a['error']:.2e}", "none", "", "", ""]
                )
                continue
            cheapest = min(good, key=lambda f: f["steps"])
            fastest = min(good, key=lambda f: f["loop"])
            rows.append(
                [
                    f"{a['rtol']:g} ({a['first']})",
                    f"{a['error']:.2e}",
                    f"{cheapest['dt'] * 1e6:.2f} μs: {cheapest['steps']} steps, "
                    f"{cheapest['error']:.1e}",
                    f"{cheapest['steps'] / (a['steps'] + a['rejected']):.2f}",
                    f"{fastest['loop'] / a['loop']:.2f}",
                    f"{fastest['bare'] / a['bare']:.2f}",
                ]
            )
        report(
            f"Cost at equal error ({label}): the fixed run with the fewest steps, and the "
            "fastest one, among those at least as accurate as the adaptive run"
        )
        report()
        report.table(
            [
                "adaptive rtol (time.step)",
                "its error",
                "cheapest fixed step as accurate",
                "steps fixed / adaptive (accepted + rejected)",
                "time fixed / adaptive",
                "same, without output",
            ],
            rows,
        )
        curves[integrator] = {"fixed": fixed_runs, "adaptive": adaptive_runs}
    data["curves"] = curves

    # -- where the steps and the time go -----------------------------------------------------
    adaptive_overhead(report, ref, repeats)
    times = step_profile(load_scene(IMPULSE, no_fields))
    h = np.diff(np.r_[0.0, times])
    rows = []
    edges = [0.0, duration, 1e-3, 5e-3, 0.02, 0.04, 0.06]
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        m = (times > lo + 1e-15) & (times <= hi + 1e-15)
        rows.append(
            [
                f"({lo * 1e3:g}, {hi * 1e3:g}] ms",
                int(m.sum()),
                f"{h[m].min() * 1e6:.2f}",
                f"{np.median(h[m]) * 1e6:.1f}",
                f"{h[m].max() * 1e6:.1f}",
            ]
        )
    report("Accepted steps of the scene as shipped (SDIRK3, rtol = 1e-3):")
    report()
    report.table(["window", "steps", "smallest [μs]", "median [μs]", "largest [μs]"], rows)

    # -- a pulse after a quiet start -------------------------------------------------------
    delayed = (
        "q0*(s/L)**2*(6 - 4*s/L + (s/L)**2)/3*sin(pi*(t - 0.005)/duration)**2"
        "*heaviside(t - 0.005)*heaviside(0.005 + duration - t)"
    )
    rows = []
    for extra in ([], [f"time.max_step={duration / 2!r}"]):
        over = no_fields + [f'loads.force_density=["{delayed}", "{delayed}", 0]'] + extra
        d, s = probes(load_scene(IMPULSE, over), out)
        rows.append(
            [
                "max_step = T/2" if extra else "no max_step",
                s["accepted_steps"],
                f"{np.abs(d[:, 1]).max():.3e}",
            ]
        )
    report("The same pulse at t = 5 ms (after a quiet start), adaptive SDIRK3, rtol = 1e-3:")
    report()
    report.table(["setting", "accepted steps", "max |x(ℓ)| [m] (3.0e-3 expected)"], rows)

    # -- the tip hammer --------------------------------------------------------------------
    if quick:
        return
    hammer = [
        "loads.force_density=[0, 0, 0]",
        'loads.end.force=["3.2e4*sin(pi*t/duration)**2*heaviside(duration - t)", '
        '"3.2e4*sin(pi*t/duration)**2*heaviside(duration - t)", 0]',
    ]
    ref_h, _ = probes(
        load_scene(
            IMPULSE, no_fields + hammer + fixed + ["time.step=1.25e-6", "solver.stol=1e-12"]
        ),
        out,
    )
    ref_h2, s2 = probes(
        load_scene(IMPULSE, no_fields + hammer + fixed + ["time.step=2.5e-6", "solver.stol=1e-12"]),
        out,
    )
    rows = [
        [
            "fixed",
            "2.5 μs (the reference's neighbour)",
            s2["accepted_steps"],
            0,
            f"{max(errors(ref_h2, ref_h)[:2]):.2e}",
        ]
    ]
    for dt in (1e-5, 2e-5, 5e-5):
        d, s = probes(load_scene(IMPULSE, no_fields + hammer + fixed + [f"time.step={dt!r}"]), out)
        rows.append(
            [
                "fixed",
                f"{dt * 1e6:g} μs",
                s["accepted_steps"],
                0,
                f"{max(errors(d, ref_h)[:2]):.2e}",
            ]
        )
    for rtol in (1e-3, 1e-4):
        d, s = probes(load_scene(IMPULSE, no_fields + hammer + [f"time.rtol={rtol:g}"]), out)
        rows.append(
            [
                "adaptive",
                f"rtol = {rtol:g}",
                s["accepted_steps"],
                s["rejected_steps"],
                f"{max(errors(d, ref_h)[:2]):.2e}",
            ]
        )
    report(
        "Tip hammer: the same impulse (1.6 N s in e1 and e2) as an end force "
        f"3.2e4 N sin²(πt/T); peak x {np.abs(ref_h[:, 1]).max():.2e} m (SDIRK3):"
    )
    report()
    report.table(["steps", "setting", "accepted", "rejected", "error x, y"], rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("slender", "impulse", "all"), default="all")
    parser.add_argument("--quick", action="store_true", help="fewer configurations, 1 repeat")
    args = parser.parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    report = Report()
    t0 = time.perf_counter()
    if args.part in ("slender", "all"):
        part_slender(report, args.quick)
    if args.part in ("impulse", "all"):
        part_impulse(report, args.quick)
    report(f"(total {time.perf_counter() - t0:.0f} s)")
    (RESULTS / "stress_slender_impulse.md").write_text("\n".join(report.lines) + "\n")
    (RESULTS / "stress_slender_impulse.json").write_text(json.dumps(report.data, indent=2))


if __name__ == "__main__":
    main()
