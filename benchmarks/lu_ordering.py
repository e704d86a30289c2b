"""PETSc's LU of the rod's Jacobian in two orderings: fill, factorisation and solve times.

    .venv/bin/python benchmarks/lu_ordering.py [--elements 8 100 1000 10000]

For each mesh (the paper's scene, cubic elements, its first steps), the Jacobian the run
assembled is factorised by PETSc's LU (serial BAIJ) with the nested-dissection ordering
(PETSc's default) and with the dofs' own order ("natural": DOLFINx numbers them along the rod);
printed: the factor's nonzeros, one factorisation [ms] and one solve [μs] (best of 5 batches),
twice in turn. docs/decisions.md, "LU ordering", quotes a run of it.
"""

from __future__ import annotations

import argparse
import time
import timeit

from petsc4py import PETSc

from cosserat_fem import api
from cosserat_fem.timestepping.events import Observer


class Measure(Observer):
    """At the end of the run, before the solver is freed: the orderings on its Jacobian."""

    def __init__(self, elements: int):
        self.elements = elements

    def ended(self, loop, failure) -> None:
        solver = loop.solver
        A = solver.A
        dofs, nonzeros = A.getSize()[0], A.getInfo()["nz_used"]
        print(f"{self.elements} elements, {dofs} dofs, {nonzeros:.0f} nonzeros")
        for ordering in ("nd", "natural") * 2:
            ksp = PETSc.KSP().create(A.comm)
            ksp.setType("preonly")
            pc = ksp.getPC()
            pc.setType("lu")
            pc.setFactorSolverType("petsc")
            pc.setFactorOrdering(ordering)
            ksp.setOperators(A)
            t0 = time.perf_counter()
            ksp.setUp()
            factor = time.perf_counter() - t0
            count = max(5, int(2e5 / A.getSize()[0]))
            best = (
                min(
                    timeit.repeat(
                        lambda ksp=ksp: ksp.solve(solver.b, solver.dx), number=count, repeat=5
                    )
                )
                / count
            )
            fill = pc.getFactorMatrix().getInfo()["nz_used"]
            print(
                f"  {ordering:8s} factor nonzeros {fill:.0f}, factorisation "
                f"{factor * 1e3:.2f} ms, solve {best * 1e6:.1f} us"
            )
            ksp.destroy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--elements", type=int, nargs="+", default=[8, 100, 1000, 10000])
    for elements in parser.parse_args().elements:
        scene = api.load(
            "scenes/cao_tucker_2008.toml",
            ["output.xdmf=false", "time.end=3e-4", f"discretisation.elements={elements}"],
        )
        api.run(scene, observers=[Measure(elements)], record=False)


if __name__ == "__main__":
    main()
