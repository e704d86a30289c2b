# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # The capstan: a rope held by friction on a fixed drum
#
# A rope of 2 mm diameter lies half a turn (θ = π) over a fixed drum of radius R = 0.1 m
# (scenes/capstan.toml). Its ends are pulled along their tangents by T1 = 1 N and
# T2 = 2.4 N, both raised over 50 ms. Coulomb friction with μ = 0.3 between rope and drum
# holds the rope while
#
# $$ \frac{T_2}{T_1} < e^{\mu\theta} = e^{0.3\pi} = 2.566 $$
#
# (Euler–Eytelwein: on an element of the wrap the pressure p ds = T dφ, and at impending
# slip dT = μ p ds). The demo runs 0.1 s, prints the quantities of interest (the ends'
# displacements, the nodes in contact and sticking, the friction's work), which the test
# suite compares between a serial and an `mpirun -n 2` run, and writes solution.xdmf: open
# it in ParaView, "Warp By Vector" with `displacement`, and colour by `contact_load`
# (the drum's load on the rope [N/m]) or `contact_gap` (gap [m], state: 0 free, 1 stick,
# 2 slip).
#
# Run it with `python demos/capstan.py` or under `mpirun -n 2`; `--set key=value` overrides
# any scene value: `--set parameters.ratio=2.6` pulls beyond e^{μθ}, and the rope slides off.

# %% [markdown]
# ## The model
#
# The rope is the paper's rod (65), curved at rest: an arc of radius ρ = R + r = 0.101 m
# about the drum's axis e2 through (ρ, 0, 0), so that its surface (a tube of radius
# r = 1 mm about the centreline) touches the drum along the wrap with no bending moment.
# Contact holds at the nodes of the cubic elements (docs/contact.md): at a node whose gap
# g = |x − axis| − R − r closes and whose drum force would press, the node's balance rows
# are replaced by g = 0 and either no tangential motion since the last step (stick) or the
# tangential force μ times the normal one against the slip (slip), decided again at every
# Newton iterate (a semi-smooth Newton method). Stick is exact: a stuck node does not
# move at all.
#
# | quantity | symbol | value |
# |---|---|---|
# | rope diameter, area | d, A | 2 mm, 3.14e-6 m² |
# | Young's modulus, density | E, ρ | 1e8 Pa (EA = 314 N), 1150 kg/m³ |
# | drum radius, wrap | R, θ | 0.1 m, π |
# | friction coefficient | μ | 0.3 |
# | tensions | T1, T2 | 1 N, 2.4 N (raised over 50 ms) |
# | time step, end | Δt, T | 1 ms, 0.1 s (BDF2) |

# %%
from __future__ import annotations

import argparse
import math
from pathlib import Path

# cosserat_fem first: a process that mpirun did not start then starts MPI in 0.08 s instead of
# 0.45 s (cosserat_fem/common/mpi_start.py).
import cosserat_fem  # noqa: F401

# isort: split
import numpy as np
from mpi4py import MPI

from cosserat_fem import api
from cosserat_fem.common.errors import CosseratError

ROOT = Path(__file__).resolve().parents[1]
comm = MPI.COMM_WORLD

parser = argparse.ArgumentParser(description="The capstan: a rope held by friction on a drum")
parser.add_argument(
    "--out", default=str(ROOT / "demos" / "output" / "capstan"), help="output folder"
)
parser.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE")
args = parser.parse_args()

# %% [markdown]
# ## The run
#
# probes.csv follows the end s = ℓ (where T2 pulls), with the contact's load, gap and state
# there; solution.xdmf holds the rope every 5 ms.

# %%
try:
    scene = api.load(ROOT / "scenes" / "capstan.toml", args.overrides)
    result = api.run(scene, args.out)
except CosseratError as exc:
    raise SystemExit(f"cosserat-fem: {exc}") from None

# %% [markdown]
# ## Held or not
#
# The low-tension end s = 0 moves only by the rope's elastic stretch if the rope holds; it
# runs away if it slides. Displacements [m] at the end of the run, and the contact's
# counts from summary.json.

# %%
model = result.model
layout, u = model.layout, model.U.x.array
bs = layout.size
sigma = model.V.tabulate_dof_coordinates()[:, 0]
ends = {}
for name, where in (("low", 0.0), ("high", 1.0)):
    mine = np.flatnonzero(np.abs(sigma[: model.V.dofmap.index_map.size_local] - where) < 1e-12)
    value = 0.0
    if mine.size:
        k = mine[0]
        value = model.length * float(
            np.linalg.norm([u[k * bs + layout.index(i)] for i in range(3)])
        )
    ends[name] = comm.allreduce(value, op=MPI.MAX)
contact = result.summary["contact"]
if comm.rank == 0:
    mu, theta = scene.contact.static_friction, math.pi
    ratio = scene.parameters["ratio"]
    print(f"T2/T1 = {ratio:.4f} against e^(mu theta) = {math.exp(mu * theta):.4f}")
    print(f"low end moved {ends['low']:.3e} m, high end {ends['high']:.3e} m")
    print(
        f"nodes in contact {contact['nodes_contact']}, sticking {contact['nodes_stick']}, "
        f"sliding {contact['nodes_slip']}; friction's work {contact['friction_work_J']:.4e} J"
    )
    print("the rope", "holds" if ends["low"] < 1e-4 else "slides")
    print(f"ParaView: {Path(args.out) / 'solution.xdmf'}")
    print(f"QOI low_end_m = {ends['low']:.12e}")
    print(f"QOI high_end_m = {ends['high']:.12e}")
    print(f"QOI friction_work_J = {contact['friction_work_J']:.12e}")
    print(f"QOI nodes_stick = {contact['nodes_stick']:.12e}")
