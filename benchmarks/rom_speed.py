"""The reduced model's speed (issue 28's goals; docs/rom.md §8): full, Galerkin-reduced and
hyper-reduced (ECSW) runs of the same scene, the hyper-reduced with the integrator on full
vectors ("hyper-full") and on the reduced coordinates ("hyper-q"), interleaved (full,
Galerkin, hyper-full, hyper-q, full, ...), no error indicator,
medians of the solve loop without output (summary.json ``wall_time_s``), their ratios, and
where a reduced step's time goes (the solver's counters): per step, per residual (the sampled
elements' kernels and projection), per Newton iteration apart from the residual (the k×k LU
solve, the norms), per solve apart from its iterations (the guess's projection and the
state's reconstruction, O(n k)), and the time loop's own per step (the integrator's
arithmetic and Python, everything but the solves). Then the floor of a hyper-q step, part by
part, timed alone (``floor``): one stage solve in C, SDIRK's step Python and kernels without
its solves, the state check, the accept, the event calls, the loop's Python around them.

    .venv/bin/python benchmarks/rom_speed.py paper [--repeats 5] [--modes 12] [--tau 1e-2]
    .venv/bin/python benchmarks/rom_speed.py riser [--elements 10000] [--steps 20] [--tau 1e-2]
    .venv/bin/python benchmarks/rom_speed.py paper --indicator [--repeats 5]

``--indicator``: instead, the error indicator's cost (docs/rom.md §10, "Cost"): each reduced
run without and with the indicator (cosserat_fem/rom/indicator.py, its default settings)
interleaved, the indicator's own wall time (summary.json ``rom.indicator.wall_time_s``), its
set-up's (``setup_wall_time_s``: the first run of the process builds the modes, the others
find them cached) and the rest per sample, as shares of the solve loop without it (medians).

``paper``: scenes/cao_tucker_2008.toml (0.06 s, 2000 SDIRK3 steps), trained on its own full
run. ``riser``: the riser of benchmarks/long_rods.py, trained on a short full run of
``--steps`` steps, the reduced runs over the same steps (the cost of a step, not the error).
The machine is shared: compare within a pair, and read the per-step costs.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import cosserat_fem as cf
from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.rom import basis as rb
from cosserat_fem.rom import galerkin, hyper

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"


def loop_time(result) -> float:
    return float(result.summary["wall_time_s"]["solve_loop_without_output"])


def breakdown(result, steps: int) -> dict:
    """µs per step, per residual, per iteration beyond its residual, per solve beyond its
    iterations, and the loop's own per step (module docstring)."""
    nt = result.summary["newton"]
    loop = loop_time(result)
    solve, res, jac = nt["time_solve"], nt["time_residual"], nt.get("time_jacobian", 0.0)
    its, solves, residuals = nt["iterations"], nt["solves"], nt["residual_assemblies"]
    us = 1e6
    return {
        "step": loop / steps * us,
        "residual": res / residuals * us,
        "iteration_beyond_residual": (solve - res - jac) / max(its, 1) * us
        if nt.get("loop") == "hyper"
        else float("nan"),
        "solve": solve / max(solves, 1) * us,
        "loop_own_per_step": (loop - solve) / steps * us,
        "solves_per_step": solves / steps,
        "iterations_per_solve": its / max(solves, 1),
    }


def interleaved(scene, bases: dict, repeats: int, steps: int) -> dict:
    """{name: [results]} of full and reduced runs taken in turn."""
    runs: dict = {"full": [], **{name: [] for name in bases}}
    for _ in range(repeats):
        runs["full"].append(run_scene(scene, write_outputs=False, record=True))
        for name, (basis, use_hyper, coordinates) in bases.items():
            make = galerkin.solver_factory(basis, use_hyper, coordinates)
            runs[name].append(
                run_scene(scene, write_outputs=False, record=True, solver_factory=make)
            )
    return runs


def report(runs: dict, steps: int, reference) -> None:
    full = statistics.median(loop_time(r) for r in runs["full"])
    print("| run | median solve loop [s] | all [s] | full / this | µs a step | error vs full |")
    print("|---|---|---|---|---|---|")
    for name, results in runs.items():
        times = [loop_time(r) for r in results]
        median = statistics.median(times)
        error = rb.relative_l2(results[0].probes[:, 1:4], reference)
        print(
            f"| {name} | {median:.4f} | {', '.join(f'{t:.3f}' for t in times)} | "
            f"{full / median:.2f} | {median / steps * 1e6:.1f} | {error:.2e} |"
        )
    print()
    print(
        "| run | µs a step | µs a residual | µs an iteration beyond its residual | "
        "µs a solve | loop's own µs a step | solves a step | iterations a solve |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, results in runs.items():
        parts = [breakdown(r, steps) for r in results]
        b = {key: statistics.median(p[key] for p in parts) for key in parts[0]}
        print(
            f"| {name} | {b['step']:.1f} | {b['residual']:.2f} | "
            f"{b['iteration_beyond_residual']:.2f} | {b['solve']:.1f} | "
            f"{b['loop_own_per_step']:.1f} | {b['solves_per_step']:.2f} | "
            f"{b['iterations_per_solve']:.2f} |"
        )


def _median_us(call, repeats: int = 2000) -> float:
    """The median µs of ``call()`` over ``repeats`` timed calls (after 50 untimed)."""
    for _ in range(50):
        call()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e6


def floor(scene, basis, steps: int) -> None:
    """Where a hyper-q step's time goes, each part timed alone on a run's loop after its
    steps (medians, inside the run's ``ended``, before its solver is destroyed): a stage
    solve at a converged state (C), SDIRK's step without its solves (its Python and the
    cf_sdirk kernels on 2k-vectors), the state check, the accept, one event call with no
    observer, and whole steps (attempt + accept, the loop's Python around them) with the C
    solves' share of them from the solver's clock."""
    from cosserat_fem.timestepping.events import Events, Observer
    from cosserat_fem.timestepping.loop import TimeLoop

    def measure(loop) -> dict:
        integrator, solver = loop.integrator, loop.solver
        h = scene.time.step * loop.omega0
        quiet = Events()
        rows = {
            "a stage solve at a converged state (one residual, no iteration)": _median_us(
                solver.solve
            ),
            "SDIRK's step without its solves (Python + cf_sdirk_stage)": _median_us(
                lambda: integrator.step(h, lambda: 0)
            ),
            "the state check (bound (8.1))": _median_us(lambda: loop._check(loop.state.t)),
            "SDIRK's accept (cf_sdirk_accept)": _median_us(lambda: integrator.accept(0.0)),
            "an event with no observer (Events.step_attempted)": _median_us(
                lambda: quiet.step_attempted(loop, 0.0)
            ),
        }
        again = TimeLoop(loop.model, integrator, solver, scene.time, quiet)

        def whole_step() -> None:
            t_new = again.state.t + scene.time.step
            failure = again.attempt(t_new)
            assert failure is None, failure
            again.accept(t_new)

        count = 500
        for _ in range(50):
            whole_step()
        clock = solver._state.time_solve
        t0 = time.perf_counter()
        for _ in range(count):
            whole_step()
        whole = (time.perf_counter() - t0) / count * 1e6
        in_c = (solver._state.time_solve - clock) / count * 1e6
        rows["a whole step (TimeLoop.attempt + accept), mean"] = whole
        rows["of which its stage solves (cf_solve, C)"] = in_c
        rows["of which Python (loop.py, SDIRK.step, the check, events)"] = whole - in_c
        return rows

    make = galerkin.solver_factory(basis, True, True)
    kept: dict = {}

    class Keep(Observer):
        needs_full_state = False

        def ended(self, loop, failure) -> None:
            kept["rows"] = measure(loop)

    run_scene(scene, write_outputs=False, solver_factory=make, observers=[Keep()])
    print("| part of a hyper-q step | µs |")
    print("|---|---|")
    for name, us in kept["rows"].items():
        print(f"| {name} | {us:.1f} |")


def indicator_cost(scene, bases: dict, repeats: int) -> None:
    """The indicator's share of the solve loop (module docstring, ``--indicator``)."""
    from cosserat_fem.rom.indicator import ErrorIndicator, IndicatorSettings

    rows: dict = {
        name: {"loop": [], "own": [], "setup": [], "samples": [], "every": []} for name in bases
    }
    for _ in range(repeats):
        for name, (basis, use_hyper, coordinates) in bases.items():
            make = galerkin.solver_factory(basis, use_hyper, coordinates)
            bare = run_scene(scene, write_outputs=False, record=True, solver_factory=make)
            watch = ErrorIndicator(IndicatorSettings())
            run_scene(
                scene, write_outputs=False, record=True, solver_factory=make, observers=[watch]
            )
            entry = watch.summary_entries()["rom"]["indicator"]
            r = rows[name]
            r["loop"].append(loop_time(bare))
            r["own"].append(entry["wall_time_s"])
            r["setup"].append(entry["setup_wall_time_s"])
            r["samples"].append(len(entry["times"]))
            r["every"].append(entry["every"])
    print(
        "| run | solve loop without [s] | indicator [s] | of which set-up [s] (each run) | "
        "samples | every | ms a sample | indicator / loop | without the set-up |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, r in rows.items():
        loop, own = statistics.median(r["loop"]), statistics.median(r["own"])
        setup = statistics.median(r["setup"])
        samples = statistics.median(r["samples"])
        per = (own - setup) / max(samples, 1) * 1e3
        print(
            f"| {name} | {loop:.4f} | {own:.4f} | {setup:.4f} "
            f"({', '.join(f'{t:.3f}' for t in r['setup'])}) | {samples:g} | "
            f"{statistics.median(r['every']):g} | {per:.2f} | {own / loop:.1%} | "
            f"{(own - setup) / loop:.1%} |"
        )


def trained(scene, args, tolerance: float, modes: int | None = None):
    """The basis of a full run of ``scene`` (its first ``modes``), its ECSW sampling, the
    full run; the training's times printed."""
    t0 = time.perf_counter()
    basis, (full,) = rb.train([scene], tolerance=tolerance)
    basis = basis.truncated(modes) if modes else basis
    t1 = time.perf_counter()
    sampled = hyper.ecsw([scene], basis, args.tau, every=args.every)
    print(
        f"{full.model.global_dofs()} dofs; training: full run + POD {t1 - t0:.2f} s, ECSW "
        f"{time.perf_counter() - t1:.2f} s; k = {basis.modes}, ECSW {sampled.provenance['ecsw']}"
    )
    return basis, sampled, full


def paper(args) -> None:
    scene = cf.load(PAPER)
    steps = round((scene.time.end - scene.time.start) / scene.time.step)
    basis, sampled, full = trained(scene, args, 1e-14, args.modes)
    bases = {
        "galerkin": (basis, False, False),
        "hyper-full": (sampled, True, False),
        "hyper-q": (sampled, True, True),
    }
    if args.indicator:
        return indicator_cost(scene, bases, args.repeats)
    report(interleaved(scene, bases, args.repeats, steps), steps, full.probes[:, 1:4])
    print()
    floor(scene, sampled, steps)


def riser(args) -> None:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from long_rods import riser as riser_scene

    scene = riser_scene(args.elements, args.steps)
    print(f"riser, {args.elements} elements, {args.steps} steps, POD ε ≤ {args.pod_tolerance:g}")
    basis, sampled, full = trained(scene, args, args.pod_tolerance)
    bases = {"hyper-full": (sampled, True, False), "hyper-q": (sampled, True, True)}
    if args.galerkin:
        bases["galerkin"] = (basis, False, False)
    if args.indicator:
        return indicator_cost(scene, bases, args.repeats)
    report(interleaved(scene, bases, args.repeats, args.steps), args.steps, full.probes[:, 1:4])
    print()
    floor(scene, sampled, args.steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=["paper", "riser"])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--modes", type=int, default=12)
    parser.add_argument("--tau", type=float, default=1e-2, help="ECSW's tolerance")
    parser.add_argument("--every", type=int, default=1, help="ECSW: every n-th stage solve")
    parser.add_argument("--elements", type=int, default=10000)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--pod-tolerance", type=float, default=1e-8)
    parser.add_argument("--galerkin", action="store_true", help="riser: the Galerkin run too")
    parser.add_argument(
        "--indicator", action="store_true", help="the error indicator's cost instead"
    )
    args = parser.parse_args()
    print(
        f"{time.strftime('%Y-%m-%d %H:%M')} {platform.node()} load {os.getloadavg()[0]:.1f}, serial"
    )
    (paper if args.case == "paper" else riser)(args)


if __name__ == "__main__":
    main()
