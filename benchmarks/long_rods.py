"""Cost and memory of long rods against their size, serial and under mpirun -n 2 (issue 15).

    .venv/bin/python benchmarks/long_rods.py [--elements 1000 10000 ...] [--steps 20]
        [--configs serial-lu mpi-mumps mpi-gmres-bjacobi ...] [--repeats 3]

Scene: a 100 m steel riser, a tube of 0.1 m and 0.08 m diameters (ℓ/a = 1000), clamped at
the top (s = 0) and free at the bottom, in a current whose drag rises linearly over 1 s to
q = 1 N/m along e1 (scenes/cao_tucker_2008.toml with :data:`RISER_TABLES` and :data:`RISER`).
Cubic elements, SDIRK3 at Δt = 1 ms, frozen Jacobian, all twelve unknowns (no planar
reduction), no outputs: the cost of the solve loop alone. Each size runs in a fresh process
(``--child``), in each solver configuration of ``--configs`` (:data:`CONFIGS`: serial or
under mpirun -n 2, the Newton loop or SNES with PETSc options), ``--repeats`` rounds taken
in turn, and prints one JSON line: dofs, the set-up (mesh, forms, spaces), the first step,
the median of the later steps (an observer timing every step), Newton iterations, and the
peak resident memory of the busiest rank (``ru_maxrss``).

Printed, and written to benchmarks/results/long_rods.csv and long_rods.md: per size and
configuration (the median round), ms a step and µs a dof and Newton iteration (O(n) work is
a flat column), the first step, MB of peak memory and kB a dof (its slope), and the first
configuration's step over this one's (> 1: this one pays). Where the time goes is read from
the summary's counters (residual assembly, solves).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
RESULTS = ROOT / "benchmarks" / "results"
DEFAULT_ELEMENTS = (100, 300, 1000, 3000, 10000, 30000, 100000)
_SNES = ["solver.nonlinear=snes"]
_GMRES = [
    *_SNES,
    "solver.petsc.ksp_type=gmres",
    "solver.petsc.ksp_rtol=1e-12",
    "solver.petsc.sub_pc_type=lu",
]
#: ``--configs``: name -> (ranks, scene overrides). The project's Newton loop with PETSc's LU
#: (serial) or MUMPS (under MPI), SNES with its defaults (the same solves through PETSc's
#: SNES), and SNES with GMRES preconditioned by block Jacobi or additive Schwarz (overlap 1),
#: each block factorised by LU (a rank's part of a rod is one block: the preconditioned
#: operator is the identity but for the coupling at the partition's interfaces).
CONFIGS: dict[str, tuple[int, list[str]]] = {
    "serial-lu": (1, []),
    "serial-snes-lu": (1, _SNES),
    "mpi-mumps": (2, []),
    "mpi-snes-mumps": (2, _SNES),
    "mpi-gmres-bjacobi": (2, [*_GMRES, "solver.petsc.pc_type=bjacobi"]),
    "mpi-gmres-asm": (2, [*_GMRES, "solver.petsc.pc_type=asm", "solver.petsc.pc_asm_overlap=1"]),
    # Inexact Newton: each linear solve to 1e-6 of its residual only (fewer Krylov
    # iterations, perhaps more Newton iterations).
    "mpi-gmres-bjacobi-loose": (
        2,
        [*_GMRES, "solver.petsc.pc_type=bjacobi", "solver.petsc.ksp_rtol=1e-6"],
    ),
}
#: The riser: steel (E = 210 GPa, ρ = 7850 kg/m³, ν = 0.3), 100 m, tube 0.1/0.08 m.
RISER_TABLES = {
    "rod": {
        "length": 100.0,
        "section": {"shape": "tube", "outer_diameter": 0.1, "inner_diameter": 0.08},
        "material": {"density": 7850.0, "young_modulus": 2.1e11, "poisson_ratio": 0.3},
    },
}
RISER = [
    "title='Steel riser, 100 m, in a current'",
    "model.reference_frequency='auto'",
    "loads.force_density=['1.0*min(t/1.0, 1.0)', 0, 0]",
    "time.step=1e-3",
    "time.integrator='sdirk3'",
    "solver.jacobian='frozen'",
    "output.xdmf=false",
    "output.checkpoint=false",
    "discretisation.planar='off'",  # all 12 unknowns, as a rod in a 3D current needs
]


def riser(elements: int, steps: int, extra: list[str] = ()):
    """The riser's scene (module docstring) with ``elements`` cubic elements, ``steps`` steps,
    and the overrides ``extra``."""
    from cosserat_fem.scene.build import read_toml, scene_from_dict

    data = read_toml(SCENE)
    data.update(RISER_TABLES)
    overrides = [*RISER, f"discretisation.elements={elements}", f"time.end={steps * 1e-3!r}"]
    return scene_from_dict(data, source="long_rods.py", overrides=[*overrides, *extra])


def child(elements: int, steps: int, extra: list[str]) -> None:
    """One run of ``elements`` cubic elements for ``steps`` steps; prints a JSON line (rank 0)."""
    import resource

    from mpi4py import MPI

    from cosserat_fem.analysis.simulation import run_scene

    scene = riser(elements, steps, extra)
    stamps: list[float] = []
    stamp = lambda k, t, model: stamps.append(time.perf_counter())  # noqa: E731
    result = run_scene(scene, write_outputs=False, observers=[stamp])
    comm = MPI.COMM_WORLD
    peak_kb = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, op=MPI.MAX)
    if comm.rank == 0:
        s = result.summary
        step_s = [b - a for a, b in zip(stamps[1:], stamps[2:], strict=False)]
        newton = s["newton"]
        print(
            "RESULT "
            + json.dumps(
                {
                    "elements": elements,
                    "ranks": comm.size,
                    "dofs": s["dofs"],
                    "steps": s["steps"],
                    "setup_s": s["wall_time_s"]["setup"],
                    "first_step_s": stamps[1] - stamps[0],
                    "step_ms": 1e3 * statistics.median(step_s),
                    "iterations_per_step": newton["iterations"] / s["steps"],
                    "residual_s": newton["time_residual"],
                    "jacobian_s": newton["time_jacobian"],
                    "solve_s": newton["time_solve"],
                    "loop_s": s["wall_time_s"]["solve_loop_without_output"],
                    "peak_mb": peak_kb / 1024.0,
                }
            ),
            flush=True,
        )


def measure(elements: int, steps: int, ranks: int, extra: list[str]) -> dict:
    """A fresh process (mpirun -n ``ranks`` if > 1) running :func:`child`."""
    command = [sys.executable, __file__, "--child", str(elements), "--steps", str(steps)]
    command += [f"--set={x}" for x in extra]
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), *command]
    env = {**os.environ, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}
    proc = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, env=env, check=False)
    lines = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"{elements} elements on {ranks} ranks: {proc.stderr[-2000:]}")
    return json.loads(lines[-1].removeprefix("RESULT "))


def table(rows: list[dict]) -> str:
    """The markdown table of the module docstring; the last column is the first
    configuration's ms a step at that size over this row's (> 1: this one is faster)."""
    head = (
        "| elements | dofs | configuration | ranks | ms/step | µs/(dof·iteration) | "
        "iterations/step | first step [s] | peak [MB] | kB/dof | first/this |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    first: dict[int, dict] = {}
    lines = []
    for r in rows:
        per = 1e3 * r["step_ms"] / (r["dofs"] * max(r["iterations_per_step"], 1e-9))
        ratio = first.setdefault(r["elements"], r)["step_ms"] / r["step_ms"]
        lines.append(
            f"| {r['elements']} | {r['dofs']} | {r['config']} | {r['ranks']} | "
            f"{r['step_ms']:.3g} | {per:.3g} | {r['iterations_per_step']:.2f} | "
            f"{r['first_step_s']:.3g} | {r['peak_mb']:.0f} | "
            f"{1024 * r['peak_mb'] / r['dofs']:.3g} | {ratio:.2f} |"
        )
    return head + "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--elements", type=int, nargs="+", default=list(DEFAULT_ELEMENTS))
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument(
        "--configs",
        nargs="+",
        default=["serial-lu", "mpi-mumps"],
        choices=list(CONFIGS),
        help="solver configurations (CONFIGS), in turn",
    )
    parser.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="rounds of all configurations at each size; the median is kept",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scene override for every run, e.g. discretisation.degree=1",
    )
    args = parser.parse_args()
    if args.child is not None:
        child(args.child, args.steps, args.set)
        return
    rows = []
    for elements in args.elements:
        runs: dict[str, list[dict]] = {name: [] for name in args.configs}
        for _ in range(args.repeats):  # interleaved: the machine's speed drifts
            for name in args.configs:
                ranks, extra = CONFIGS[name]
                runs[name].append(
                    {"config": name, **measure(elements, args.steps, ranks, [*extra, *args.set])}
                )
                r = runs[name][-1]
                print(
                    f"{elements:7d} elements {r['dofs']:8d} dofs {name}: "
                    f"{r['step_ms']:.3g} ms/step, first {r['first_step_s']:.3g} s, "
                    f"{r['iterations_per_step']:.2f} it/step, {r['peak_mb']:.0f} MB",
                    flush=True,
                )
        for name in args.configs:
            ordered = sorted(runs[name], key=lambda r: r["step_ms"])
            rows.append(ordered[len(ordered) // 2])
    RESULTS.mkdir(parents=True, exist_ok=True)
    with open(RESULTS / "long_rods.csv", "w", encoding="utf-8") as stream:
        keys = list(rows[0])
        stream.write(",".join(keys) + "\n")
        for r in rows:
            stream.write(",".join(str(r[k]) for k in keys) + "\n")
    text = table(rows)
    (RESULTS / "long_rods.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
