# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # A cantilever under harmonic distributed load (Cao & Tucker 2008, section 6)
#
# This demo reproduces the numerical example of Cao & Tucker, *Nonlinear dynamics of elastic
# rods using the Cosserat theory: modelling and simulation*, IJSS 45 (2008) 460-477: a
# uniform aluminium cantilever, clamped at s = 0 and free at s = ℓ, driven from rest by the
# distributed transverse force
#
# $$ f_x = f_y = 2\,\sin(\pi s/\ell)\,\sin(8\omega_0 t)\ \mathrm{kN/m},
#    \qquad 0 \le t \le 0.06\ \mathrm{s}. $$
#
# It writes the paper's Figs. 4-6 (free-end histories of x, y, z, θ, ψ, φ; the surfaces
# x(s,t) and y(s,t)) as PNGs and the solution as XDMF for ParaView, and prints the quantities
# of interest, which the test suite checks against the closed-form linear Timoshenko response
# and between a serial and an `mpirun -n 2` run.
#
# Run it with `python demos/cao_tucker_2008.py` or `mpirun -n 2 python demos/...`;
# `--end 0.01` shortens the run, `--set key=value` overrides any scene value.

# %% [markdown]
# ## The model
#
# With p = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ), q = dp/dτ, σ = s/ℓ and τ = ω0 t (47), the rod obeys the
# general form (65),
#
# $$ \dot p = q, \qquad M_a(p)\,\dot q + b(p, p')' = g(p, p', q, t), $$
#
# with the mass matrix Ma (66), the flux b (63) (contact force and torque) and the source g
# (67) (gyroscopic, shear-coupling and load terms); see `forms/general_form.py` and
# `docs/errata.md` for the corrections made to the printed equations. At s = 0 the rod is
# clamped (p = q = 0); the free end s = ℓ carries no load. The section is a = 0.04 m (along
# d1) by b = 0.06 m (along d2), so bending in x (about d2, c22 = b a³/12) is the softer
# direction: its first frequency is ω0 = 207 rad/s, the y-direction's is 1.5 ω0. The forcing
# frequency 8 ω0 = 1656 rad/s lies between the first and second bending modes of both planes.
#
# | quantity | symbol | value |
# |---|---|---|
# | length | ℓ | 1 m |
# | section | a × b | 0.04 m × 0.06 m |
# | density | ρ | 2730 kg/m³ |
# | Young's modulus | E | 7.1e10 Pa |
# | Poisson's ratio | ν | 0.32 |
# | shear coefficient | κ | 0.833 |
# | reference frequency | ω0 | 207.0236 rad/s |

# %%
from __future__ import annotations

import argparse
import sys
from pathlib import Path

# cosserat_fem first: a process that mpirun did not start then starts MPI in 0.08 s instead of
# 0.45 s (cosserat_fem/common/mpi_start.py).
import cosserat_fem  # noqa: F401

# isort: split
import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis import progress
from cosserat_fem.api import run
from cosserat_fem.common.errors import CosseratError
from cosserat_fem.output.fields import LineSampler
from cosserat_fem.plot import drawn_lines
from cosserat_fem.reference.rod_planes import sine_load_tip_response
from cosserat_fem.reference.second_order import RodData, second_order_tip_response
from cosserat_fem.scene.build import load_scene

ROOT = Path(__file__).resolve().parents[1]
comm = MPI.COMM_WORLD

parser = argparse.ArgumentParser(description="Cao & Tucker (2008), section 6")
parser.add_argument("--end", type=float, default=None, help="end time [s] (default: scene)")
parser.add_argument("--out", default=str(ROOT / "demos" / "output"), help="output folder")
parser.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE")
parser.add_argument("--frames", type=int, default=300, help="time samples of the surfaces")
args = parser.parse_args()

overrides = list(args.overrides)
if args.end is not None:
    overrides.append(f"time.end={args.end}")
try:
    scene = load_scene(ROOT / "scenes" / "cao_tucker_2008.toml", overrides)
except CosseratError as exc:
    sys.exit(f"cao_tucker_2008: {exc}")
out = Path(args.out)

# %% [markdown]
# ## Solving
#
# The scene's default discretisation (8 cubic elements; the A-stable third-order SDIRK3 at
# Δt = 30 μs, two implicit stages a step that share one frozen Jacobian) is the fastest
# configuration of the work-precision benchmark (`benchmarks/README.md`) whose free-end error
# is within 1e-3 (5.6e-4); `docs/convergence.md` shows the convergence in space and time.
# An observer samples x(s,t) and y(s,t) on 41 stations for the surface plots.

# %%
stations = np.linspace(0.0, 1.0, 41)
every = max(1, scene.time.n_steps // args.frames)
frames_t: list[float] = []
frames: list[np.ndarray] = []
sampler: LineSampler | None = None


def sample_fields(step: int, t: float, model) -> None:
    global sampler
    if sampler is None:
        sampler = LineSampler(model, stations)
        values = sampler.sample()  # the initial state (at rest)
        if comm.rank == 0:
            frames_t.append(scene.time.start)
            frames.append(values * 0.0)
    if step % every == 0:
        values = sampler.sample()
        if comm.rank == 0:
            frames_t.append(t)
            frames.append(values)


# The progress bar (on a terminal, rank 0): time reached, steps and the time left.
bar = progress.ProgressBar(
    scene.time.start, scene.time.end, enabled=None if comm.rank == 0 else False
)
try:
    result = run(scene, out, observers=(sample_fields,), progress=bar)
except CosseratError as exc:
    sys.exit(f"cao_tucker_2008: {exc}")
finally:
    bar.close()

# %% [markdown]
# ## Quantities of interest and an independent check
#
# The response is small (tip deflections ~1e-3 ℓ), so the nonlinear rod must follow linear
# Timoshenko theory up to relative O(1e-5) (its geometric nonlinearity, measured in the
# convergence study). The closed-form reference is an exact modal superposition of the
# Timoshenko cantilever (shear and rotary inertia included) in each bending plane
# (`cosserat_fem/reference/timoshenko.py` and `rod_planes.py`).
#
# The axial displacement z and the twist φ are purely nonlinear: they are second order in the
# deflection, driven by products of the bending fields (foreshortening, shear coupling, and the
# torque E (c22 − c11) u1 u2 of bending in both planes at once). Second-order perturbation
# theory gives them as forced axial and torsional wave equations whose sources are products of
# the linear Timoshenko fields, solved exactly (`cosserat_fem/reference/second_order.py`); the
# rod must agree with it up to the next order, relative O(1e-4) for this load.

# %%
if comm.rank == 0:
    probes = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    t, x, y, z, theta, psi, phi = probes.T
    x_ref, y_ref = sine_load_tip_response(scene, t, q0=2e3, omega=8.0 * scene.omega0)
    z_ref, phi_ref = second_order_tip_response(
        RodData.from_scene(scene),
        2e3,
        8.0 * scene.omega0,
        t,
        torsion_inertia=scene.model.torsion_inertia,
    )

    def rel_l2(u, ref):
        return float(np.sqrt(np.mean((u - ref) ** 2) / np.mean(ref**2)))

    qoi = {
        "t_end_s": float(t[-1]),
        "max_abs_x_m": float(np.abs(x).max()),
        "max_abs_y_m": float(np.abs(y).max()),
        "min_z_m": float(z.min()),
        "max_z_m": float(z.max()),
        "min_phi_rad": float(phi.min()),
        "max_phi_rad": float(phi.max()),
        "timoshenko_max_abs_x_m": float(np.abs(x_ref).max()),
        "timoshenko_max_abs_y_m": float(np.abs(y_ref).max()),
        "rel_l2_error_x": rel_l2(x, x_ref),
        "rel_l2_error_y": rel_l2(y, y_ref),
        "second_order_min_z_m": float(z_ref.min()),
        "second_order_min_phi_rad": float(phi_ref.min()),
        "second_order_max_phi_rad": float(phi_ref.max()),
        "rel_l2_error_z": rel_l2(z, z_ref),
        "rel_l2_error_phi": rel_l2(phi, phi_ref),
        "solve_loop_s": result.summary["wall_time_s"]["solve_loop"],
    }
    for name, value in qoi.items():
        print(f"QOI {name} = {value:.12e}")

# %% [markdown]
# ## Figures 4, 5 and 6 of the paper
#
# Each PNG has the data it draws beside it, for a test or another plot: `fig4_free_end.npz`
# holds the lines of Fig. 4 as read back from the figure (`cosserat_fem.plot.drawn_lines`),
# `fig5_x_surface.npz` and `fig6_y_surface.npz` the surfaces' stations `s` [m], times `t` [s]
# and values [m] (times × stations).

# %%
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 2, figsize=(10, 8), sharex=True)
    panels = [
        (x, "x(ℓ,t) [m]"),
        (theta, "θ(ℓ,t) [rad]"),
        (y, "y(ℓ,t) [m]"),
        (psi, "ψ(ℓ,t) [rad]"),
        (z, "z(ℓ,t) [m]"),
        (phi, "φ(ℓ,t) [rad]"),
    ]
    for ax, (u, label) in zip(axes.flat, panels, strict=True):
        ax.plot(t, u, lw=0.8)
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
        ax.grid(alpha=0.3)
    axes[0, 0].plot(t, x_ref, "--", lw=0.6, label="linear Timoshenko")
    axes[1, 0].plot(t, y_ref, "--", lw=0.6, label="linear Timoshenko")
    axes[2, 0].plot(t, z_ref, "--", lw=0.6, label="second-order theory")
    axes[2, 1].plot(t, phi_ref, "--", lw=0.6, label="second-order theory")
    axes[2, 0].legend(loc="lower left", fontsize=7)
    axes[0, 0].legend(loc="upper left", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.suptitle("Free-end response (Cao & Tucker 2008, Fig. 4)")
    fig.tight_layout()
    fig.savefig(out / "fig4_free_end.png", dpi=130)
    np.savez(out / "fig4_free_end.npz", **drawn_lines(fig))
    plt.close(fig)

    T, S = np.meshgrid(np.array(frames_t), stations * scene.rod.length)
    F = np.array(frames)  # (frames, stations, 6)
    for number, column, name in ((5, 0, "x"), (6, 1, "y")):
        fig = plt.figure(figsize=(7, 5))
        ax = fig.add_subplot(projection="3d")
        ax.plot_surface(
            S,
            T,
            F[:, :, column].T,
            cmap="viridis",
            linewidth=0,
            antialiased=False,
            rcount=S.shape[0],
            ccount=S.shape[1],
        )
        ax.view_init(elev=30, azim=-60)
        ax.set_xlabel("s [m]")
        ax.set_ylabel("t [s]")
        ax.set_zlabel(f"{name}(s,t) [m]")
        ax.set_title(f"{name}(s,t) (Cao & Tucker 2008, Fig. {number})")
        fig.tight_layout()
        fig.savefig(out / f"fig{number}_{name}_surface.png", dpi=130)
        plt.close(fig)
        np.savez(out / f"fig{number}_{name}_surface.npz", s=S[:, 0], t=T[0], value=F[:, :, column])
    print(f"figures, probes.csv, solution.xdmf and summary.json written to {out}")
