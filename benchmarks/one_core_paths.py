"""The paper's scene's solve loop on each of today's code paths, for docs/design-one-core.md.

(Written before step 1 of its plan: since then every Newton solve is ``cf_solve``, and the
third path below is ``cf_solve`` with an observer callback per iteration, not a Python loop.)

    PYTHONPATH=. .venv/bin/python benchmarks/one_core_paths.py [--rounds 5] [--set key=value]

Serial, no outputs. Four paths, one run each per round, interleaved (the machine's load
drifts), after one warm-up run of each:

* ``c-step``: today's default, the whole SDIRK step in C (native_sdirk.py, ``cf_sdirk_step``);
* ``py-step+c-newton``: the Python SDIRK step (integrators.SDIRK.step) around Newton's whole
  solve in C (``cf_solve``): the time loop's stepper replaced by the integrator;
* ``py-step+py-newton+c-kernels``: the Python step and the Python Newton loop (its stop rule
  and policy) calling the C residual and the C iteration body (``cf_residual``,
  ``cf_iterate``): the shape of a "Python composes, C computes" core; made by a no-op
  iteration hook, which NewtonSolver._run honours by iterating in Python;
* ``all-python``: ``solver.loop = "python"`` (DOLFINx's assembly, the path every MPI run takes).

Prints, per path, the medians over the rounds of the solve loop (summary's
``solve_loop_without_output``), of Newton's ``time_solve`` and of the time outside the solves,
in µs a step, the ratio of each path's loop to ``c-step`` (median of the per-round ratios),
and the Python-visible calls a step (sys.setprofile "call" and "c_call" events over steps
10-110 of a separate run). With ``--profile PATH``, instead: cProfile of one run of 200 steps
on that path (after a warm-up), the 20 functions of largest own time, µs and calls a step.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import sys

from cosserat_fem.events import Observer
from cosserat_fem.scene import load_scene
from cosserat_fem.simulation import run_scene

SCENE = "scenes/cao_tucker_2008.toml"
PATHS = ("c-step", "py-step+c-newton", "py-step+py-newton+c-kernels", "all-python")


class Path(Observer):
    """Puts the time loop on one of :data:`PATHS` when it starts; optionally counts the
    Python-visible calls of steps 10 to 110."""

    def __init__(self, name: str, count: bool = False):
        self.name, self.count_calls = name, count
        self.finished = self.calls = 0

    def started(self, loop) -> None:
        if self.name in ("py-step+c-newton", "py-step+py-newton+c-kernels"):
            loop.stepper = loop.integrator
        if self.name == "py-step+py-newton+c-kernels":
            loop.solver.iteration_hook = lambda it, norms, reason: None

    def _count(self, frame, event, arg) -> None:
        if event in ("call", "c_call"):
            self.calls += 1

    def step_finished(self, loop) -> None:
        if not self.count_calls:
            return
        self.finished += 1
        if self.finished == 10:
            self.calls = 0
            sys.setprofile(self._count)
        elif self.finished == 110:
            sys.setprofile(None)


class Profiled(Path):
    """:class:`Path` with cProfile from the loop's start to its end."""

    def started(self, loop) -> None:
        super().started(loop)
        self.profile = cProfile.Profile()
        self.profile.enable()

    def ended(self, loop, failure) -> None:
        self.profile.disable()


def profile(name: str, extra: list[str]) -> None:
    """The own time and calls a step of the 20 costliest functions of ``name``'s path."""
    scene = _scene(name, ["time.end=0.006", *extra])
    run_scene(scene, write_outputs=False, observers=[Path(name)])  # warm-up
    observer = Profiled(name)
    steps = run_scene(scene, write_outputs=False, observers=[observer]).summary["steps"]
    stats = pstats.Stats(observer.profile).stats
    total = sum(v[2] for v in stats.values())
    calls = sum(v[1] for v in stats.values())
    print(
        f"{name}: {steps} steps, profiled {total / steps * 1e6:.1f} µs and {calls / steps:.1f} "
        "calls a step"
    )
    for (file, line, function), (_, n, own, _, _) in sorted(
        stats.items(), key=lambda kv: -kv[1][2]
    )[:20]:
        print(
            f"  {own / steps * 1e6:7.1f} µs {n / steps:6.1f}/step  "
            f"{file.split('/')[-1]}:{line} {function}"
        )


def _scene(name: str, extra: list[str]):
    loop = "python" if name == "all-python" else "auto"
    return load_scene(SCENE, ["output.xdmf=false", f"solver.loop={loop}", *extra])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--profile", choices=PATHS)
    args = parser.parse_args()
    if args.profile:
        profile(args.profile, args.set)
        return
    scenes = {name: _scene(name, args.set) for name in PATHS}
    figures: dict[str, list[tuple[float, float, float]]] = {name: [] for name in PATHS}
    calls = {}
    for name in PATHS:  # warm-up, and the call count
        counter = Path(name, count=True)
        try:
            run_scene(scenes[name], write_outputs=False, record=True, observers=[counter])
        finally:
            sys.setprofile(None)
        calls[name] = counter.calls / 100
    steps = 0
    for _ in range(args.rounds):
        for name in PATHS:
            summary = run_scene(
                scenes[name], write_outputs=False, record=True, observers=[Path(name)]
            ).summary
            steps = summary["steps"]
            loop = summary["wall_time_s"]["solve_loop_without_output"]
            solve = summary["newton"]["time_solve"]
            figures[name].append((loop, solve, loop - solve))
    us = 1e6 / steps
    print(
        f"{SCENE} {' '.join(args.set)}: {steps} steps, {args.rounds} interleaved rounds; "
        "µs a step, medians"
    )
    print(
        f"  {'path':30s} {'loop':>7s} {'solves':>7s} {'outside':>8s} {'ratio':>6s} "
        f"{'calls/step':>10s}"
    )
    for name in PATHS:
        rows = figures[name]
        med = [statistics.median(r[i] for r in rows) * us for i in range(3)]
        ratio = statistics.median(r[0] / c[0] for r, c in zip(rows, figures["c-step"], strict=True))
        print(
            f"  {name:30s} {med[0]:7.1f} {med[1]:7.1f} {med[2]:8.1f} {ratio:6.2f} "
            f"{calls[name]:10.0f}"
        )


if __name__ == "__main__":
    main()
