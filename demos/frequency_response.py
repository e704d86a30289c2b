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
# the state its predecessor ended in, cosserat_fem/studies/response.py). A sweep by time
# marching sees the stable states only; the demo then traces the whole S-shaped response,
# its unstable middle branch included, as a branch of periodic orbits by shooting and
# pseudo-arclength continuation (`cf.periodic_branch`), with each orbit's Floquet
# multipliers: the folds where the middle branch meets the other two are where the sweeps
# jump. It draws the sweep's members, the branch and the harmonic balance on one figure
# (`demos/output/frequency_response/harmonic_balance.png`; `cosserat-fem plot` of the folder
# draws its own `response.png` beside it) and prints the amplitudes, the folds and their
# multipliers as QOI lines, which the test suite checks against the harmonic balance and
# between a serial and an `mpirun -n 2` run (where each rank runs one chain of the sweep,
# and the shooting is shared in space: each rank its rows).
#
# Run it with `python demos/frequency_response.py` (about 3 minutes serially on an idle core:
# 2 for the sweep, 70 s for the branch of 42 steps and 230 monodromies) or
# `mpirun -n 2 python demos/frequency_response.py` (on a busy machine with Open MPI's
# settings of the README's "Running a scene"). On two ranks the sweep takes half as long (a
# chain a rank), but the branch longer than serially: this rod's 8 elements give a rank too
# little work between the MPI messages of each step, and on a busy machine each message
# waits (the whole demo: 12 min on two ranks at load 2-3, the sweep 1 min 14 s of it;
# `--values 1.06 --branch 1.06 1.03`, a branch of 71 monodromies: 55 s serially, on two
# ranks 5.5 min at load 3 and 13 min at load 6); two ranks here show that shooting runs in
# parallel, for rods large enough to gain. `--values 1.04 1.07 1.10` runs the sweep over
# fewer frequencies, `--branch 0.98 1.14` sets the branch's range (`--branch 1.06 1.03`:
# down the lower branch to its fold and back up the middle one), `--steps-per-period N` its
# steps a period (100) and `--no-branch` leaves it out.

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
parser.add_argument(
    "--branch",
    type=float,
    nargs=2,
    default=[0.98, 1.14],
    metavar=("FROM", "TO"),
    help="the branch of periodic orbits from r = FROM to TO (default: 0.98 1.14)",
)
parser.add_argument(
    "--steps-per-period",
    type=int,
    default=100,
    metavar="N",
    help="the branch's SDIRK steps a forcing period (default: 100)",
)
parser.add_argument(
    "--no-branch",
    action="store_true",
    help="the sweep and the harmonic balance only (no branch of periodic orbits)",
)
args = parser.parse_args()
if not args.no_branch and not (np.isfinite(args.branch).all() and args.branch[0] != args.branch[1]):
    parser.error(f"--branch: FROM and TO must be two different numbers, got {args.branch}")
if args.steps_per_period < 1:
    parser.error(f"--steps-per-period: must be at least 1, got {args.steps_per_period}")

# %% [markdown]
# ## The sweep
#
# `cf.load_sweep` reads and validates the sweep (every member's scene) before anything runs;
# `cf.sweep` deals its two chains to the groups of ranks and writes `sweep.csv`, a row per
# member with its amplitudes (`amp_x`: half the peak-to-peak of x at mid-span [m] over the
# last two periods), whether it `settled` and from which member it `continued`.

# %%
try:
    # --values: the same sweep over other frequencies (its [sweep.vary] changed)
    other = None if args.values is None else {"vary": {"parameters.r": args.values}}
    spec = api.load_sweep(SWEEP, changes=other)
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
# ## The whole response: periodic orbits by shooting
#
# **Shooting.** Over one forcing period T = 2π/(r ω1) [s] the rod's state U (its free
# positions and momenta at t = 0) is carried by N = 100 steps h = T/N of the scene's SDIRK3
# integrator to Φ_T(U; r), the period map. A periodic orbit is a fixed point of it:
#
# $$ R(U, r) = \Phi_T(U; r) - U = 0, $$
#
# solved by Newton's method, (M − I) δU = −R, with the **monodromy matrix**
#
# $$ M = \frac{\partial \Phi_T}{\partial U}, $$
#
# carried through the period with the steps by the variational equations of each stage (per
# stage one factorisation and n back-solves, n the dimension of U: cosserat_fem/analysis/
# periodic.py). The sweep samples each period with 300 steps; the branch takes 100, a third of
# the cost (the scheme's error is then 1e-4 in a multiplier over a period,
# tests/test_periodic.py).
#
# **Floquet multipliers.** A small disturbance δU of the orbit at t = 0 is M δU one period
# later, so the eigenvalues μ of M decide the orbit's stability: it is **stable iff every
# |μ| < 1**. Far from the folds the largest pair is the damped first mode's,
# μ = exp(−ζω1T) exp(±iω_dT), |μ| = exp(−2πζ/r) ≈ 0.94. Where a branch folds back, R_U = M − I
# is singular: a **real multiplier crosses +1** (det(M − I) = Π(μ − 1) changes sign), and the
# orbits between the two folds, the middle branch, have one real μ > 1: unstable, the states
# no sweep can settle in.
#
# **Continuation.** `cf.periodic_branch` follows the orbits (U, r)(s) by pseudo-arclength s
# (cosserat_fem/nls/arclength.py): a step predicts along the tangent t and corrects on
#
# $$ R(U, r) = 0, \qquad \langle t, (U, r) - (\hat U, \hat r) \rangle = 0, $$
#
# in the metric ‖(ΔU, Δr)‖² = w ‖ΔU‖² + Δr², w making 25 mm of amplitude weigh as Δr = 0.1,
# so r may turn back at a fold (dr/ds = 0), which it locates to 1e-6 in s. Each point costs
# the monodromies of its corrector's Newton iterations (one about 34 periods of time marching).
# Under mpirun the shooting is parallel in space: each rank carries its rows of the
# variational equations and the factorisations are MUMPS's. The first orbit is shot at
# r = FROM after three periods from rest. The branch's table is `orbits/orbit_branch.csv`
# (r, amplitude [m], the largest multiplier, dr/ds, the sign of det(M − I), the stability).

# %%
branch = None
if not args.no_branch:
    r_from, r_to = args.branch
    if comm.rank == 0:
        print(f"tracing the periodic orbits from r = {r_from} to {r_to} ...", flush=True)
    try:
        branch = api.periodic_branch(
            base,
            spec.response.period,  # "2*pi/(r*w1)" [s]
            "r",
            r_from,
            r_to,
            settle=3,
            steps_per_period=args.steps_per_period,
            step=0.005,
            out=out / "orbits",
        )
    except CosseratError as exc:
        if comm.rank == 0:
            print(f"frequency_response: {exc}", file=sys.stderr)
        sys.exit(2)


def stretches(branch, low: float, high: float) -> list[tuple[bool, list]]:
    """The branch's points with r in [low, high], in the order traced and split into
    stretches of one stability (stable: True), each fold ending one stretch and starting the
    next (inserted between the two points it lies between)."""
    points = [q for q in branch.points if low <= q.parameter <= high]
    for fold in branch.folds:
        changes = [
            k
            for k in range(1, len(points))
            if points[k - 1].stability != points[k].stability
            and "limit" not in (points[k - 1].kind, points[k].kind)
        ]
        if changes:
            k = min(changes, key=lambda k: abs(points[k].parameter - fold.parameter))
            points.insert(k, fold)
    runs: list[tuple[bool, list]] = []
    run: list = []
    for q in points:
        if run and q.kind != "limit" and run[-1].kind != "limit":
            if (q.stability == "stable") != (run[-1].stability == "stable"):
                runs.append((run[-1].stability == "stable", run))
                run = [run[-1]]
        run.append(q)
        if q.kind == "limit" and len(run) > 1:
            stable = all(x.stability == "stable" for x in run if x.kind != "limit")
            runs.append((stable, run))
            run = [q]
    if len(run) > 1:
        runs.append((all(x.stability == "stable" for x in run if x.kind != "limit"), run))
    return runs


# %% [markdown]
# ## The picture and the quantities of interest
#
# One figure: the harmonic balance (grey, its middle root dotted), the sweep's members
# (markers), the branch of periodic orbits (stable solid, unstable dashed) and its folds
# (circles). The QOI lines: each member's amplitude [m] and the harmonic balance's lowest and
# highest roots at its r; the branch's steps, rejected steps and monodromies; at each fold
# its r, amplitude [m], the largest |μ| and the real multiplier nearest +1; and the range of
# the unstable middle branch's points (r, amplitude [m], largest |μ|).

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
        hb = [duffing.amplitudes(f, x * w1) for x in r]
        y = [v[i] if len(v) == 3 else (v[0] if i in (0, 2) and len(v) == 1 else np.nan) for v in hb]
        ax.plot(
            r,
            1e3 * np.array(y),
            color="0.6",
            lw=1,
            ls="-" if i != 1 else ":",
            label="harmonic balance (one mode)" if i == 0 else None,
        )
    for direction, marker in (("up", "^"), ("down", "v")):
        chain = sorted(
            (float(row["parameters.r"]), float(row["amp_x"]))
            for row in rows
            if row["direction"] == direction
        )
        ax.plot(
            *np.array(chain).T * [[1], [1e3]],
            marker,
            ms=6,
            ls="none",
            mfc="none",
            label=f"cosserat-fem, sweep {direction}",
        )
    if branch is not None:
        drawn = set()
        for stable, run in stretches(branch, *sorted(args.branch)):
            label = "periodic orbits, " + ("stable" if stable else "unstable")
            ax.plot(
                [q.parameter for q in run],
                [1e3 * q.amplitude for q in run],
                color="C2" if stable else "C3",
                ls="-" if stable else "--",
                lw=1.5,
                label=None if label in drawn else label,
            )
            drawn.add(label)
        if branch.folds:
            ax.plot(
                [q.parameter for q in branch.folds],
                [1e3 * q.amplitude for q in branch.folds],
                "ko",
                ms=7,
                mfc="none",
                label="fold: a multiplier at +1",
            )
    ax.set_xlabel("r = Ω / ω1")
    ax.set_ylabel("amplitude of x at mid-span [mm]")
    ax.set_title(
        f"Clamped–clamped rod: jumps, hysteresis and the unstable branch (ζ1 = {duffing.zeta:.2g})"
    )
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
    if branch is not None:
        print(f"-> {out / 'orbits' / 'orbit_branch.csv'} ({branch.reason})")
        print(f"QOI branch_steps = {branch.steps}")
        print(f"QOI branch_rejected = {branch.rejected}")
        print(f"QOI branch_monodromies = {branch.monodromies}")
        folds = sorted(branch.folds, key=lambda q: -q.parameter)
        print(f"QOI branch_folds = {len(folds)}")
        names = ["upper", "lower"] if len(folds) == 2 else [f"{k}" for k in range(len(folds))]
        for name, fold in zip(names, folds, strict=True):
            real = [m.real for m in fold.multipliers if m.imag == 0.0]
            print(f"QOI fold_{name}_r = {fold.parameter:.12e}")
            print(f"QOI fold_{name}_amp_m = {fold.amplitude:.12e}")
            print(f"QOI fold_{name}_mu_abs_max = {abs(fold.multipliers[0]):.12e}")
            print(f"QOI fold_{name}_mu_nearest_one = {min(real, key=lambda m: abs(m - 1)):.12e}")
        unstable = [
            q
            for q in branch.points
            if q.stability != "stable" and min(args.branch) <= q.parameter <= max(args.branch)
        ]
        print(f"QOI unstable_points = {len(unstable)}")
        if unstable:
            for name, values in (
                ("r", [q.parameter for q in unstable]),
                ("amp", [q.amplitude for q in unstable]),
                ("mu_abs", [abs(q.multipliers[0]) for q in unstable]),
            ):
                unit = "_m" if name == "amp" else ""
                print(f"QOI unstable_{name}_min{unit} = {min(values):.12e}")
                print(f"QOI unstable_{name}_max{unit} = {max(values):.12e}")
