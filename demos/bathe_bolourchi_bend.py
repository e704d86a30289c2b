# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # A cantilever curved at rest: Bathe & Bolourchi's 45° bend
#
# The classical test of beams curved at rest (Bathe & Bolourchi 1979; Simo & Vu-Quoc 1986):
# a cantilever whose axis is a circular arc of radius R = 100 in over 45°, with a
# 1 in × 1 in section, bent and twisted out of its plane by a dead tip force of 600 lbf.
# The tip moves by about 63 in, the size of the rod itself. This demo loads it in ten steps,
# prints the tip displacement at each (the quantities of interest, which the test suite
# compares between a serial and an `mpirun -n 2` run and against an independent solution),
# and draws the rod along the load path.
#
# Run it with `python demos/bathe_bolourchi_bend.py` or under `mpirun -n 2`;
# `--set key=value` overrides any scene value.

# %% [markdown]
# ## The model
#
# The rod at rest is the arc r0(s) with the reference directors d0_i(s): d0_3 = r0' the
# tangent, d0_2 = e2 normal to the arc's plane ([reference] shape = "arc",
# `forms/reference.py`). The unknowns measure the motion from it: p1..p3 = (r − r0)/ℓ, and the
# Euler angles of the rotation R = D(θ, ψ, φ) that carries the reference directors to the
# current ones, whose matrix is D0 R. The strains of the constitutive laws (10)-(13) are
# measured from the rest state,
#
# $$ v - v_0 = D_0 (R\,r' - t_0), \qquad \hat u - \hat u_0 = D_0\,\kappa_R, $$
#
# with κ_R = Mm (θ', ψ', φ') the curvature of R (25): both vanish at rest, whatever the
# curve, so the rod at rest is an exact equilibrium. The balance laws (6) are the paper's, the
# moment rows written in the frame of R (`forms/general_form.py`, "A reference
# configuration"). Statics: the general form (65) without its rates, the load raised in steps.
#
# | quantity | symbol | value |
# |---|---|---|
# | radius, angle | R, α | 100 in = 2.54 m, 45° |
# | length | ℓ = R α | 78.54 in = 1.995 m |
# | section | a × b | 1 in × 1 in |
# | Young's modulus, Poisson's ratio | E, ν | 1e7 psi = 6.895e10 Pa, 0 |
# | shear and torsion stiffness | GA, GJ | E A/2, G (I2 + I3) |
# | tip force | P | 600 lbf = 2669 N along e2 |

# %%
from __future__ import annotations

import argparse
from pathlib import Path

# cosserat_fem first: a process that mpirun did not start then starts MPI in 0.08 s instead of
# 0.45 s (cosserat_fem/common/mpi_start.py).
import cosserat_fem  # noqa: F401

# isort: split
import numpy as np
from mpi4py import MPI

from cosserat_fem import api
from cosserat_fem.analysis import progress
from cosserat_fem.common.errors import CosseratError
from cosserat_fem.output.fields import LineSampler
from cosserat_fem.plot import drawn_lines
from cosserat_fem.timestepping.events import Observer

ROOT = Path(__file__).resolve().parents[1]
INCH = 0.0254  # m
comm = MPI.COMM_WORLD

parser = argparse.ArgumentParser(description="Bathe & Bolourchi's 45-degree bend")
parser.add_argument("--out", default=str(ROOT / "demos" / "output"), help="output folder")
parser.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE")
args = parser.parse_args()

# %% [markdown]
# ## The load path
#
# An observer samples the centreline, r0(s) + (x, y, z), at 41 points after every load step.

# %%


class Shapes(Observer):
    """The deformed centreline [m] after each accepted load step."""

    def __init__(self):
        self.shapes: list[np.ndarray] = []
        self.sampler: LineSampler | None = None

    def started(self, loop) -> None:
        self.sampler = LineSampler(loop.model, np.linspace(0.0, 1.0, 41))
        self.output(loop, 0, 0.0)

    def output(self, loop, k: int, t: float) -> None:
        values = self.sampler.sample()
        if values is not None:
            s = loop.model.length * self.sampler.sigmas
            self.shapes.append(loop.model.scene.reference.positions(s) + values[:, :3])


# The load factor reached, on a terminal (rank 0), as the load steps go.
bar = progress.StatusLine(enabled=None if comm.rank == 0 else False)
try:
    scene = api.load(ROOT / "scenes" / "bathe_bolourchi_bend.toml", args.overrides)
    shapes = Shapes()
    result = api.static(
        scene,
        observers=[
            shapes,
            lambda k, load_factor, model: bar.show(load_factor, f"load factor {load_factor:.3g}"),
        ],
    )
except CosseratError as exc:
    raise SystemExit(f"cosserat-fem: {exc}") from None
finally:
    bar.close()

# %% [markdown]
# ## The tip
#
# Towards the arc's centre (Δn, along e1), out of its plane (Δz, along e2) and along the
# clamp's tangent (Δt, along e3), in inches. The converged values are (−13.60452, 53.47486,
# −23.56024) in (docs/verification.md, section 6); Bathe & Bolourchi published
# (−13.4, 53.4, −23.5).

# %%
if comm.rank == 0:
    for row in result.probes[1:]:
        load = 600.0 * row[0]
        print(
            f"P = {load:5.0f} lbf: tip (dn, dz, dt) = "
            + ", ".join(f"{x / INCH:9.5f}" for x in row[1:4])
            + " in"
        )
    tip = result.probes[-1][1:4] / INCH
    for name, value in zip(("tip_dn_in", "tip_dz_in", "tip_dt_in"), tip, strict=True):
        print(f"QOI {name} = {value:.12e}")
    print(f"QOI load_steps = {len(result.probes) - 1:.12e}")

# %% [markdown]
# ## The picture
#
# The rod at rest (grey) and after each load step, seen from above the arc's plane and from
# along the clamp's tangent; `bathe_bolourchi_bend.npz` beside it holds the lines as drawn
# (`cosserat_fem.plot.drawn_lines`).

# %%
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, front) = plt.subplots(1, 2, figsize=(10, 4.5))
    colours = plt.cm.viridis(np.linspace(0.0, 1.0, len(shapes.shapes)))
    for k, (shape, colour) in enumerate(zip(shapes.shapes, colours, strict=True)):
        style = dict(color="0.6", lw=2) if k == 0 else dict(color=colour, lw=1.2)
        top.plot(shape[:, 2] / INCH, shape[:, 0] / INCH, **style)
        front.plot(shape[:, 0] / INCH, shape[:, 1] / INCH, **style)
    top.set(
        xlabel="e3 (along the clamp) [in]",
        ylabel="e1 (towards the centre) [in]",
        title="seen from e2",
        aspect="equal",
    )
    front.set(xlabel="e1 [in]", ylabel="e2 (the load) [in]", title="seen from e3", aspect="equal")
    fig.suptitle("Bathe & Bolourchi's 45° bend, 0 to 600 lbf in 10 steps")
    fig.tight_layout()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "bathe_bolourchi_bend.png", dpi=120)
    np.savez(out / "bathe_bolourchi_bend.npz", **drawn_lines(fig))
    print(f"wrote {out / 'bathe_bolourchi_bend.png'}")
