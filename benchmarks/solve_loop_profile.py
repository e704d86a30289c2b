"""Where the time loop of a scene spends its time, per step, against its floor.

    PYTHONPATH=. .venv/bin/python benchmarks/solve_loop_profile.py [scene] [--set key=value]

Serial, no outputs (``write_outputs=False``, probe rows kept in memory). After a warm-up run
(JIT cache, first touch), two runs of the scene:

1. **Unprofiled** (perf_counter): summary.json's ``solve_loop_without_output`` and Newton's
   counters and timers (``time_solve`` = the nonlinear solves, ``time_residual`` = the
   residual evaluations in them); everything else in the loop is the integrator, the state
   checks, the loop and its observers.
2. **cProfile and PETSc's event log**, from the first step to the end of the loop (an
   observer starts and stops them): tottime by category. A C function's tottime excludes
   the Python it calls back (SNES calls the residual), and ``KSPSolve`` is taken out of
   SNES's ``solve`` by the event log. Functions that only serve their caller (numpy
   internals, PETSc vector methods, DOLFINx's Function and Constant properties, built-ins
   other than the kernels) are charged to their callers, in proportion. The profilers add a
   cost to every call, so these figures are larger than those of run 1: they give the shares.
3. **The floor**, measured at the end of run 1 with the run's own form, matrix factors and
   vectors: the run's number of residual assemblies made by ``dolfinx.cpp.fem.assemble_vector``
   with coefficients and constants packed once, then its number of ``KSP.solve`` calls alone
   (median of 3). Also the cost of one call of each part of a residual evaluation (median of
   7 x 4000 calls).

Speeds drift on a shared machine: compare figures within one invocation, and old against new
code only by interleaved runs.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import time
from collections import defaultdict

import numpy as np
from dolfinx import cpp
from dolfinx.fem.petsc import assemble_vector, set_bc
from petsc4py import PETSc

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.scene.build import load_scene
from cosserat_fem.timestepping.events import Observer

SCENE = "scenes/cao_tucker_2008.toml"
EVENTS = ("KSPSolve", "MatSolve", "SNESSolve", "SNESFunctionEval")

# Categories of profiled functions, first match wins: (category, test on (file, name)).
KERNEL = "residual: assembly kernel (C++)"
PACK = "residual: packing coefficients and constants (C++)"
BC = "residual: Dirichlet rows, set_bc (C++)"
WRAPPERS = "residual: DOLFINx's Python assembly wrappers (fem.petsc, fem.assemble)"
NEWTON = "Newton: newton.py Python (callbacks or loop) and its PETSc calls"
SNES = "Newton: SNES's own C work (solve minus KSPSolve)"
KSP = "Newton: KSP solve (triangular solves)"
INTEGRATOR = "integrator (its step: Python and the C kernels cf_sdirk_*)"
LOOP = "loop, state checks, observers"
ROWS = (KERNEL, PACK, BC, WRAPPERS, NEWTON, SNES, KSP, INTEGRATOR, LOOP)
_BUILTINS = {
    "dolfinx.cpp.fem.assemble_vector": KERNEL,
    "dolfinx.cpp.fem.pack_coefficients": PACK,
    "dolfinx.cpp.fem.pack_constants": PACK,
    "dolfinx.cpp.fem.set_bc": BC,
    "'solve' of 'petsc4py.PETSc.SNES'": SNES,
    "'solve' of 'petsc4py.PETSc.KSP'": KSP,
    "cf_sdirk_": INTEGRATOR,
}
_WRAPPER_FILES = ("/dolfinx/fem/petsc.py", "/dolfinx/fem/assemble.py", "functools.py")
_TRANSPARENT = ("numpy", "weakref.py", "<__array_function__", "abc.py", "/dolfinx/")


def category(func: tuple) -> str | None:
    """The category of a pstats key (file, line, name); None: charged to its callers."""
    filename, _, name = func
    for key, cat in _BUILTINS.items():
        if key in name:
            return cat
    if any(f in filename for f in _WRAPPER_FILES):  # functools: their singledispatch
        return WRAPPERS
    if filename == "~" or any(t in filename for t in _TRANSPARENT):
        return None
    if filename.endswith("newton.py"):
        return NEWTON
    if filename.endswith(("integrators.py", "adaptive.py")):
        return INTEGRATOR
    return LOOP


def by_category(stats: pstats.Stats) -> dict[str, float]:
    """tottime [s] summed by category; a transparent function's time goes to its callers in
    proportion to the time spent on their behalf (pstats' per-caller tottime)."""
    raw = stats.stats
    memo: dict[tuple, dict[str, float]] = {}

    def shares(func, depth=0) -> dict[str, float]:
        """Fractions of func's time by category (through transparent callers)."""
        cat = category(func)
        if cat is not None:
            return {cat: 1.0}
        if func in memo:
            return memo[func]
        callers = raw[func][4] if func in raw else {}
        total = sum(c[2] for c in callers.values())
        out: dict[str, float] = defaultdict(float)
        if depth > 8 or total <= 0.0:
            out[LOOP] = 1.0
        else:
            for caller, c in callers.items():
                for cat2, f in shares(caller, depth + 1).items():
                    out[cat2] += f * c[2] / total
        memo[func] = dict(out)
        return memo[func]

    totals: dict[str, float] = defaultdict(float)
    for func, (_, _, tottime, _, _) in raw.items():
        for cat, f in shares(func).items():
            totals[cat] += f * tottime
    return totals


class Profiling(Observer):
    """cProfile and PETSc's event log from the first step to the end of the loop."""

    def __init__(self):
        self.profile = cProfile.Profile()
        self.events: dict[str, float] = {}

    def started(self, loop) -> None:
        self.events = {e: -_event_time(e) for e in EVENTS}
        self.profile.enable()

    def ended(self, loop, failure) -> None:
        self.profile.disable()
        for e in EVENTS:
            self.events[e] += _event_time(e)


def _event_time(name: str) -> float:
    return PETSc.Log.Event(name).getPerfInfo()["time"]


def _ksp(solver) -> PETSc.KSP:
    ksp = getattr(solver, "ksp", None)
    # Also the SNES-based solver of before the lean loop (docs/decisions.md), for comparisons.
    return ksp if ksp is not None else solver.snes.getKSP()


def _per_call(function, calls: int = 4000, repeats: int = 7) -> float:
    """Median over ``repeats`` of the mean time [s] of one call of ``function``."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            function()
        times.append((time.perf_counter() - t0) / calls)
    return statistics.median(times)


class Floor(Observer):
    """At the end of the loop (before the solver is destroyed): the floor and the per-call
    costs of the residual's parts, with the run's form, factors and vectors."""

    def __init__(self):
        self.floor: dict[str, float] = {}
        self.per_call: dict[str, float] = {}

    def ended(self, loop, failure) -> None:
        solver, stats = loop.solver, loop.solver.stats
        form, ksp, b = solver.F_form, _ksp(solver), solver.b
        y, x = b.duplicate(), b.duplicate()
        loop.model.U.vector.copy(x)
        constants, coefficients = cpp.fem.pack_constants(form), cpp.fem.pack_coefficients(form)
        array = np.zeros(b.getLocalSize())
        n_res, n_it = stats.residual_assemblies, stats.iterations

        def assemble():
            cpp.fem.assemble_vector(array, form, constants, coefficients)

        times = {"assembly": [], "ksp": []}
        for _ in range(3):
            t0 = time.perf_counter()
            for _ in range(n_res):
                assemble()
            t1 = time.perf_counter()
            for _ in range(n_it):
                ksp.solve(b, y)
            t2 = time.perf_counter()
            times["assembly"].append(t1 - t0)
            times["ksp"].append(t2 - t1)
        self.floor = {k: statistics.median(v) for k, v in times.items()}

        def wrapper():
            with b.localForm() as local:
                local.set(0.0)
            assemble_vector(b, form)
            set_bc(b, solver.bcs, x, -1.0)

        owned, x_owned = np.zeros(b.getLocalSize()), x.array_r.copy()
        self.per_call = {
            "pack_coefficients (C++)": _per_call(lambda: cpp.fem.pack_coefficients(form)),
            "pack_constants (C++)": _per_call(lambda: cpp.fem.pack_constants(form)),
            "assemble_vector, prepacked (C++)": _per_call(assemble),
            "set_bc (C++)": _per_call(lambda: cpp.fem.set_bc(owned, solver.bcs, x_owned, -1.0)),
            "zero b + fem.petsc.assemble_vector + set_bc (DOLFINx API)": _per_call(wrapper),
            "KSP.solve": _per_call(lambda: ksp.solve(b, y)),
        }
        y.destroy()
        x.destroy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=SCENE)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    scene = load_scene(args.scene, ["output.xdmf=false", *args.set])
    run_scene(scene, write_outputs=False, record=True)  # warm-up: JIT cache, first touch

    floor = Floor()
    summary = run_scene(scene, write_outputs=False, record=True, observers=[floor]).summary
    PETSc.Log.begin()
    profiling = Profiling()
    profiled = run_scene(scene, write_outputs=False, record=True, observers=[profiling]).summary
    totals = by_category(pstats.Stats(profiling.profile))
    ksp_time = profiling.events["KSPSolve"] if totals.get(SNES) else totals.get(KSP, 0.0)
    if totals.get(SNES):  # SNES's tottime holds the KSP solves: the event log splits them out
        totals[SNES] -= ksp_time
        totals[KSP] = ksp_time

    steps, nt = summary["steps"], summary["newton"]
    wall = summary["wall_time_s"]
    us = 1e6 / steps
    print(
        f"{args.scene}: {steps} steps, {nt['solves']} solves, {nt['iterations']} Newton "
        f"iterations, {nt['residual_assemblies']} residual assemblies, "
        f"{nt['jacobian_assemblies']} Jacobian assemblies"
    )
    print("\n1. Unprofiled run (perf_counter), µs per step")
    loop = wall["solve_loop_without_output"]
    rows = [
        ("solve loop without output", loop),
        ("  Newton solves (time_solve)", nt["time_solve"]),
        ("    residual evaluations (time_residual)", nt["time_residual"]),
        ("    Jacobian assemblies (time_jacobian)", nt["time_jacobian"]),
        (
            "    the rest of the solves",
            nt["time_solve"] - nt["time_residual"] - nt["time_jacobian"],
        ),
        ("  outside the solves", loop - nt["time_solve"]),
    ]
    for name, seconds in rows:
        print(f"  {name:58s} {seconds * us:8.1f}")

    print("\n2. Profiled run (cProfile tottime + PETSc event log), µs per step")
    total = sum(totals.values())
    for name in ROWS:
        print(f"  {name:68s} {totals.get(name, 0.0) * us:8.1f}")
    print(f"  {'total profiled':68s} {total * us:8.1f}")
    print(
        f"  (its solve loop: {profiled['wall_time_s']['solve_loop_without_output'] * us:.1f}; "
        f"MatSolve {profiling.events['MatSolve'] * us:.1f} of KSPSolve "
        f"{profiling.events['KSPSolve'] * us:.1f})"
    )

    print("\n3. Floor (the run's counts), µs per step")
    fl = floor.floor
    print(
        f"  {nt['residual_assemblies']} x C++ assemble_vector, prepacked      "
        f"{fl['assembly'] * us:8.1f}"
    )
    print(f"  {nt['iterations']} x KSP.solve                                 {fl['ksp'] * us:8.1f}")
    print(
        f"  floor                                              "
        f"{(fl['assembly'] + fl['ksp']) * us:8.1f}"
    )
    print(
        f"  unprofiled solve loop / floor: {loop / (fl['assembly'] + fl['ksp']):.2f}; "
        f"Newton solves / floor: {nt['time_solve'] / (fl['assembly'] + fl['ksp']):.2f}"
    )
    print("\n   one call, µs (median of 7 x 4000 calls)")
    for name, seconds in floor.per_call.items():
        print(f"  {name:58s} {seconds * 1e6:8.2f}")


if __name__ == "__main__":
    main()
