# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # A frequency response with jumps: the clamped–clamped rod hardens
#
# The paper's aluminium rod (ℓ = 1 m, 40 mm × 60 mm) clamped at both ends is driven near its
# first bending frequency in x, ω1 = 1302.92 rad/s (`cosserat-fem modes`), by
#
# $$ f_x = F \sin(\pi s/\ell)\,\sin(r\,\omega_1 t), \qquad F = 5915.8\ \mathrm{N/m}, $$
#
# with viscous damping c = 170.74 N s/m² (ζ1 = c / (2ρAω1) = 0.01). Bending stretches the
# clamped axis; the axial force, N = EA/(2ℓ) ∫ w'² ds, stiffens the rod as the amplitude
# grows, and its first mode is a Duffing oscillator
#
# $$ \ddot q + 2\zeta\omega_1\dot q + \omega_1^2 q + \alpha q^3 = f \sin\Omega t,
#    \qquad \alpha = \frac{EA\,(\int\varphi'^2)^2}{2\ell\,\rho A\int\varphi^2}, $$
#
# q the mid-span displacement, f = 1000 m/s² the load's modal force. Its harmonic balance,
# a² [(ω1² + ¾αa² − Ω²)² + (2ζω1Ω)²] = f², has three roots over a band of frequencies above
# ω1: an upward sweep rides the upper branch and jumps down at its end, a downward one stays
# on the lower branch and jumps up where it ends (cosserat_fem/reference/backbone.py).
#
# The demo runs the sweep `scenes/sweeps/clamped_hysteresis.toml` (two chains of members, one
# upward and one downward; each member runs until its response is periodic and starts from
# the state its predecessor ended in, cosserat_fem/studies/response.py), draws both against the
# harmonic balance (`demos/output/frequency_response/harmonic_balance.png`; `cosserat-fem plot`
# of the folder draws its own `response.png` beside it) and prints the amplitudes
# as QOI lines, which the test suite checks against the harmonic balance and between a serial
# and an `mpirun -n 2` run (where each rank runs one chain).
#
# Run it with `python demos/frequency_response.py` (about 2 minutes serially, 1 on two ranks)
# or `mpirun -n 2 python demos/frequency_response.py` (on a busy machine with Open MPI's
# settings of the README's "Running a scene"); `--values 1.04 1.07 1.10` runs fewer
# frequencies.

# %%
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

# cosserat_fem first: a process that mpirun did not start then starts MPI in 0.08 s instead of
# 0.45 s (cosserat_fem/common/mpi_start.py).
import cosserat_fem  # noqa: F401

# isort: split
import numpy as np
from mpi4py import MPI

from cosserat_fem import api
from cosserat_fem.common.errors import CosseratError
from cosserat_fem.plot import drawn_lines
from cosserat_fem.reference.backbone import Duffing, clamped_modal_force

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "scenes" / "sweeps" / "clamped_hysteresis.toml"
comm = MPI.COMM_WORLD

parser = argparse.ArgumentParser(description="A frequency response with jumps")
parser.add_argument(
    "--out",
    default=str(ROOT / "demos" / "output" / "frequency_response"),
    help="output folder (the sweep's)",
)
parser.add_argument(
    "--values",
    type=float,
    nargs="+",
    default=None,
    metavar="R",
    help="forcing frequencies r = Ω/ω1 (default: the sweep file's 0.98 ... 1.14)",
)
args = parser.parse_args()

# %% [markdown]
# ## The sweep
#
# `cf.load_sweep` reads and validates the sweep (every member's scene) before anything runs;
# `cf.sweep` deals its two chains to the groups of ranks and writes `sweep.csv`, a row per
# member with its amplitudes (`amp_x`: half the peak-to-peak of x at mid-span [m] over the
# last two periods), whether it `settled` and from which member it `continued`.

# %%
try:
    source = SWEEP
    if args.values is not None:  # the same sweep over other frequencies
        text = SWEEP.read_text(encoding="utf-8")
        start = text.index('"parameters.r" = { start')
        line = text[start : text.index("\n", start)]
        text = text.replace(line, f'"parameters.r" = {json.dumps(args.values)}')
        text = text.replace(
            'scene = "../cao_tucker_2008.toml"',
            f'scene = "{ROOT / "scenes" / "cao_tucker_2008.toml"}"',
        )
        folder = Path(tempfile.mkdtemp()) if comm.rank == 0 else None
        source = Path(comm.bcast(str(folder), root=0)) / "sweep.toml"
        if comm.rank == 0:
            source.write_text(text, encoding="utf-8")
        comm.Barrier()
    try:
        spec = api.load_sweep(source)  # read whole: the file is not needed after this
    finally:
        comm.Barrier()
        if source != SWEEP and comm.rank == 0:
            shutil.rmtree(source.parent, ignore_errors=True)
    out = Path(args.out)
    result = api.sweep(spec, out, progress=True)  # a line on stderr as each member ends
except CosseratError as exc:
    if comm.rank == 0:
        print(f"frequency_response: {exc}", file=sys.stderr)
    sys.exit(2)

# %% [markdown]
# ## The harmonic balance
#
# The Duffing coefficient α of the clamped rod's first mode (Euler–Bernoulli, the stretched
# axis), with the rod's own linear frequency ω1 and the modal force of the load.

# %%
base = spec.scene(spec.members[0])  # the rod, its damping and the load's parameters
w1, F, length = base.parameters["w1"], base.parameters["F"], base.rod.length  # rad/s, N/m, m
duffing = Duffing.of_clamped_scene(base, omega=w1)
rho_A = base.rod.material.density * base.rod.section.a * base.rod.section.b  # kg/m
s = np.linspace(0.0, length, 20001)
f = clamped_modal_force(F * np.sin(np.pi * s / length), s, length, rho_A)  # m/s²

# %% [markdown]
# ## The picture and the quantities of interest

# %%
if comm.rank == 0:
    rows = [r for r in result.rows if r["status"] == "completed"]
    if len(rows) != len(spec.members):
        print("frequency_response: not every member completed", file=sys.stderr)
        sys.exit(1)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5))
    r = np.linspace(0.96, 1.16, 401)
    for i in range(3):
        branch = [duffing.amplitudes(f, x * w1) for x in r]
        y = [
            v[i] if len(v) == 3 else (v[0] if i in (0, 2) and len(v) == 1 else np.nan)
            for v in branch
        ]
        ax.plot(
            r,
            1e3 * np.array(y),
            color="0.6",
            lw=1,
            ls="-" if i != 1 else ":",
            label="harmonic balance (one mode)" if i == 0 else None,
        )
    for direction, marker in (("up", "^-"), ("down", "v--")):
        chain = sorted(
            (float(row["parameters.r"]), float(row["amp_x"]))
            for row in rows
            if row["direction"] == direction
        )
        ax.plot(
            *np.array(chain).T * [[1], [1e3]],
            marker,
            ms=5,
            lw=1,
            label=f"cosserat-fem, sweep {direction}",
        )
    ax.set_xlabel("r = Ω / ω1")
    ax.set_ylabel("amplitude of x at mid-span [mm]")
    ax.set_title(f"Clamped–clamped rod: hardening, jumps and hysteresis (ζ1 = {duffing.zeta:.2g})")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "harmonic_balance.png", dpi=130)  # response.png is `plot`'s
    np.savez(out / "harmonic_balance.npz", **drawn_lines(fig))  # the lines as drawn, for a test
    print(f"-> {out / 'harmonic_balance.png'}")
    for row in rows:
        x = float(row["parameters.r"])
        key = f"{row['direction']}_{x:.2f}".replace(".", "p")
        print(f"QOI amp_{key}_m = {float(row['amp_x']):.12e}")
        roots = duffing.amplitudes(f, x * w1) or [np.nan]
        print(f"QOI duffing_low_{key}_m = {roots[0]:.12e}")
        print(f"QOI duffing_high_{key}_m = {roots[-1]:.12e}")
