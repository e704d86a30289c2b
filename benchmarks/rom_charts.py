# %% [markdown]
# # A basis per chart: the whip's reduced run through its chart moves (issue 28, docs/rom.md §9)
#
# The whip (scenes/whip.toml) in 3D: its Euler angles' chart moves when |θ| nears π/2. A
# Galerkin run follows each move (cosserat_fem/rom/galerkin.py ``follow_chart``): the training
# snapshots are mapped into the new chart and POD'd again to the same k, the state projected.
# For each training span and run span: the relative L2 free-end error against the full run
# (docs/rom.md §7), the indicator's E, and at each move the projection error of the lifted
# state (relative, W-norm), the new POD's energy left out and the move's wall time.
#
#     python3 benchmarks/rom_charts.py [--train 4e-4] [--span 2e-3] [--tolerance 1e-10]

# %%
from __future__ import annotations

import argparse
import time
from pathlib import Path

import cosserat_fem as cf
from cosserat_fem.rom import basis as rb
from cosserat_fem.rom import galerkin
from cosserat_fem.rom.indicator import IndicatorSettings
from cosserat_fem.timestepping.events import Observer

WHIP = Path(__file__).resolve().parents[1] / "scenes" / "whip.toml"
IN_3D = {"discretisation.planar": "off", "output.xdmf": False}


class Keeper(Observer):
    """Keeps the run's solver (its ``chart_moves``)."""

    solver = None

    def started(self, loop) -> None:
        self.solver = loop.solver


def measure(
    train: float, span: float, tolerance: float, modes: int | None = None, planar: bool = False
) -> dict:
    """Train on the whip's first ``train`` s (3D; ``planar``: in its plane, no chart), run it
    reduced and in full over ``span`` s."""
    setting = {"output.xdmf": False} if planar else IN_3D
    basis, _ = rb.train([cf.load(WHIP, {**setting, "time.end": train})], tolerance=tolerance)
    if modes is not None:
        basis = basis.truncated(modes)
    scene = cf.load(WHIP, {**setting, "time.end": span})
    keeper = Keeper()
    t0 = time.perf_counter()
    reduced = galerkin.run(scene, basis, indicator=IndicatorSettings(), observers=[keeper])
    wall = time.perf_counter() - t0
    full = cf.run(scene)
    error = rb.relative_l2(reduced.probes[:, 1:4], full.probes[:, 1:4])
    indicator = reduced.summary["rom"]["indicator"]
    return {
        "train": train,
        "span": span,
        "k": basis.modes,
        "error": error,
        "E": indicator["final"],
        "E_max": indicator["max"],
        "exceeded": indicator["exceeded"],
        "flags": [(x["what"], x["time"]) for x in reduced.summary["rom"]["outside_training"]],
        "moves": keeper.solver.chart_moves,
        "full_moves": full.summary.get("chart_resets"),
        "wall_s": wall,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--train", type=float, nargs="+", default=[4e-4])
    parser.add_argument("--span", type=float, nargs="+", default=[4e-4, 2e-3])
    parser.add_argument("--tolerance", type=float, default=1e-10)
    parser.add_argument("--modes", type=int, default=None)
    parser.add_argument("--planar", action="store_true", help="the whip in its plane (no chart)")
    args = parser.parse_args()
    for train in args.train:
        for span in args.span:
            r = measure(train, span, args.tolerance, args.modes, args.planar)
            print(
                f"train {r['train']:.1e} s, span {r['span']:.1e} s, k = {r['k']}: error "
                f"{r['error']:.3e}, E {r['E']:.3e} (max {r['E_max']:.3e}, exceeded "
                f"{r['exceeded']}), E/error {r['E'] / r['error']:.2f}, flags {r['flags']}, "
                f"wall {r['wall_s']:.2f} s, full run's moves {r['full_moves']}"
            )
            for m in r["moves"]:
                print(
                    f"  move at t = {m['time_s']:.3e} s: projection error "
                    f"{m['projection_error']:.3e} (accepted {m['projection_error_accepted']:.3e})"
                    f", energy left out {m['energy_left_out']:.2e}, {1e3 * m['wall_time_s']:.1f} ms"
                )


if __name__ == "__main__":
    main()
