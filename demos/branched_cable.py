# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # A branched cable swinging under gravity
#
# A structure of three rods (docs/structures.md): a nylon cord of 2 mm diameter hangs from a
# clamp at the top and forks at J into two branches of different lengths, the right one
# leaving the x-z plane. Released from rest with its members straight, it falls under its
# own weight and swings in 3D. The demo runs it for 0.6 s, prints the quantities of interest
# (the right leaf's displacement at the end and its lowest point, which the test suite
# compares between a serial and an `mpirun -n 2` run), and writes solution.xdmf, which
# ParaView opens as one object: the three members on one mesh, "Warp By Vector" with the
# displacement to see it move.
#
# Run it with `python demos/branched_cable.py` or under `mpirun -n 2`; `--set key=value`
# overrides any scene value (scenes/branched_cable.toml).

# %% [markdown]
# ## The model
#
# Each member is the paper's rod (65), straight at rest along its own tangent t0 with its own
# rest frame D0 (rows d0_1, d0_2, d0_3 = t0); the unknowns are the displacement (r − r0)/ℓ and
# the Euler angles of the *spatial* rotation Λ that carries the rest directors to the current
# ones, d_i = Λ d0_i (forms/reference.py), so the strains
#
# $$ v - v_0 = D_0 (R\,r' - t_0), \qquad \hat u - \hat u_0 = D_0\,\kappa_R $$
#
# vanish at rest on every member. The members are one interval mesh embedded in 3D whose
# vertices are the rest positions; at J three cells share a vertex, so they share its
# displacement and its Λ: their relative rotation stays the rest one, which is a rigid joint.
# The σ-derivative on that mesh is the tangential one, f' = ∇f · t (forms/kinematics.py
# `d_sigma`). Gravity adds the weight ρ A g to the force density of every member; Kelvin–Voigt
# damping with τ_d = 1 ms damps mode n by ζ_n = τ_d ω_n / 2.
#
# | quantity | symbol | value |
# |---|---|---|
# | diameter, area | d, A | 2 mm, 3.14e-6 m² |
# | Young's modulus, Poisson's ratio, density | E, ν, ρ | 2 GPa, 0.4, 1150 kg/m³ |
# | bending stiffness, weight | E I, ρ A g | 1.57e-3 N m², 0.0355 N/m |
# | trunk top–J, left J–L, right J–R | | 0.3 m, 0.3 m (30° below e1), 0.335 m (level, towards e2) |
# | time step, end | Δt, T | 2 ms, 0.6 s (SDIRK3) |

# %%
from __future__ import annotations

import argparse
from pathlib import Path

# cosserat_fem first: a process that mpirun did not start then starts MPI in 0.08 s instead of
# 0.45 s (cosserat_fem/common/mpi_start.py).
import cosserat_fem  # noqa: F401

# isort: split
from mpi4py import MPI

from cosserat_fem import api
from cosserat_fem.common.errors import CosseratError

ROOT = Path(__file__).resolve().parents[1]
comm = MPI.COMM_WORLD

parser = argparse.ArgumentParser(description="A branched cable swinging under gravity")
parser.add_argument(
    "--out", default=str(ROOT / "demos" / "output" / "branched_cable"), help="output folder"
)
parser.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE")
args = parser.parse_args()

# %% [markdown]
# ## The run
#
# probes.csv follows the right leaf R (`structure.probe`); solution.xdmf holds the whole
# structure every 20 ms.

# %%
try:
    scene = api.load(ROOT / "scenes" / "branched_cable.toml", args.overrides)
    result = api.run(scene, args.out)
except CosseratError as exc:
    raise SystemExit(f"cosserat-fem: {exc}") from None

# %% [markdown]
# ## The right leaf
#
# Its displacement [m] at the end of the run and the lowest it went (z along e3, up).

# %%
if comm.rank == 0:
    t, x, y, z = (result.probes[:, i] for i in range(4))
    lowest = int(z.argmin())
    print(f"R at t = {t[-1]:.3f} s: displacement ({x[-1]:.5f}, {y[-1]:.5f}, {z[-1]:.5f}) m")
    print(f"R lowest at t = {t[lowest]:.3f} s: {z[lowest]:.5f} m")
    print(f"ParaView: {Path(args.out) / 'solution.xdmf'}")
    for name, value in (("R_x_m", x[-1]), ("R_y_m", y[-1]), ("R_z_m", z[-1])):
        print(f"QOI {name} = {value:.12e}")
    print(f"QOI R_lowest_z_m = {z[lowest]:.12e}")
