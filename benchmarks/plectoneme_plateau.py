# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---
# %% [markdown]
# # The plectoneme's torque after the snap, on refined meshes (issue 30; docs/plectoneme.md)
#
# scenes/plectoneme_plateau.toml (r/L = 5e-3, T = 300 EI/L², a point imperfection at mid-span,
# twist 2 rad/s up to t1 then 0.5 rad/s) run by `cosserat_fem.api.run` with
# benchmarks/plectoneme_run.py's observer: at every accepted step the twist Φ(t), the section
# torque M = e3 · m(0) at the clamp A [N m], B's axial shift [m], the largest lateral
# displacement [m], the active self-contact pairs and the least gaps. The plateau's figures
# are the torque's mean and spread over a window of twist [Φ_a, Φ_b] after the strands meet.
#
#     .venv/bin/python benchmarks/plectoneme_plateau.py [cells ...] [--end t] [--out DIR]
#     .venv/bin/python benchmarks/plectoneme_plateau.py --restart DIR [--end t]
#
# ``--end t`` [s] stops the runs at t (the scene's end, 80 s, otherwise): the steps after the
# strands meet are slow (docs/plectoneme.md), so a run to just past the contact is the one
# that ends in minutes. ``--out DIR`` keeps each run's outputs and checkpoints (every 0.5 s
# of t, and where it stops) in DIR/<cells>, its rows in each checkpoint and in
# DIR/<cells>/rows.npy (every ROWS_EVERY steps, to look at while it runs);
# ``--restart DIR/<cells>`` continues such a run from its last checkpoint in the same folder
# (to the scene's end without ``--end``), its rows after the checkpoint's, so that the
# plateau is taken over the whole run however often it was continued.
# %%
from __future__ import annotations

import math
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem import api
from cosserat_fem.common.errors import CosseratError

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "plectoneme_plateau.toml"
sys.path.insert(0, str(ROOT / "benchmarks"))
import plectoneme_run  # noqa: E402
from plectoneme_run import Record  # noqa: E402


def twist(t: np.ndarray | float, parameters: dict) -> np.ndarray:
    """The scene's turn of B [rad] at t [s]: fast min(t, t1) + rate max(t − t1, 0)."""
    t = np.asarray(t, dtype=float)
    fast, rate, t1 = (float(parameters[k]) for k in ("fast", "rate", "t1"))
    return fast * np.minimum(t, t1) + rate * np.maximum(t - t1, 0.0)


def contact_ply(r: float, T: float, EI: float) -> tuple[float, float]:
    """The uniform two-strand ply of an isotropic rod whose strands touch (each centreline a
    helix of radius r [m] about the ply's axis, its tangent at θ to the axis) beside straight
    tails under the tension T [N]: the angle θ [rad] and the torque M_p [N m] at which the
    ply grows quasi-statically (the plateau; frictionless, the end loop left out),

        M_p = min over θ of (2 r T + EI sin⁴θ / r) / sin 2θ                          (Y.1)

    Turning the end by dΦ at the torque M puts dℓ = 2 r dΦ / sin 2θ of rod into the ply (its
    writhe, −ℓ sin 2θ / (4π r), takes the turn), which pulls dℓ in against T and bends it to
    the helix's curvature sin²θ / r (½ EI κ² dℓ); the twist density M/GJ is the same in the
    ply and the tails, so GJ drops out (docs/plectoneme.md, "The contact ply's torque"). dℓ is
    the rod of both strands; r, T, EI > 0; θ over [1e-6, π/4] (cos 2θ = 0 at the end)."""
    from scipy.optimize import minimize_scalar

    def torque(theta: float) -> float:
        return (2 * r * T + EI * math.sin(theta) ** 4 / r) / math.sin(2 * theta)

    best = minimize_scalar(
        torque, bounds=(1e-6, math.pi / 4), method="bounded", options={"xatol": 1e-12}
    )
    return float(best.x), torque(float(best.x))


def closed_form(scene) -> dict[str, float]:
    """plectoneme_run's closed forms (EI, GJ, T, M_c, Φ_c, the diameter, the later rate) with
    r [m], √(2 EI T) [N m] ("loop": the scale Neukirch & Marko quote, of the snap's torque)
    and the contact ply's θ_p [rad] and torque M_p [N m] (:func:`contact_ply`)."""
    forms = plectoneme_run.closed_form(scene)
    r = forms["diameter"] / 2
    theta, M_p = contact_ply(r, forms["T"], forms["EI"])
    loop = math.sqrt(2 * forms["EI"] * forms["T"])
    return {**forms, "r": r, "loop": loop, "theta_p": theta, "M_p": M_p}


#: how often a run with ``--out`` writes a checkpoint [s of t]
CHECKPOINTS = 0.5
#: how often a run with ``--out`` writes its rows [accepted steps]
ROWS_EVERY = 20


class Kept(Record):
    """:class:`plectoneme_run.Record` whose rows, after ``earlier`` (a continued run's rows up
    to its checkpoint), go into every checkpoint (:meth:`checkpoint_parts`) and are written
    to ``path`` every ROWS_EVERY accepted steps and at the end (:meth:`save`), column 1 the
    scene's twist (:func:`twist` of its ``parameters``)."""

    def __init__(self, path: Path, earlier: np.ndarray, parameters: dict) -> None:
        super().__init__(1.0)
        self.path, self.earlier, self.parameters = path, earlier, parameters

    def step_accepted(self, loop) -> None:
        super().step_accepted(loop)
        if len(self.rows) % ROWS_EVERY == 0:
            self.save()

    def whole(self) -> np.ndarray:
        """The earlier rows and this run's, (steps, 8)."""
        return with_twist(
            np.concatenate([self.earlier, np.array(self.rows).reshape(-1, 8)]), self.parameters
        )

    def checkpoint_parts(self) -> dict:
        """The rows so far, kept with the state they lead to (the time loop's checkpoint
        hook): a continued run takes them from the checkpoint it starts from."""
        return {"rows": {"rows": self.whole()}}

    def save(self) -> None:
        """The rows to ``path``, through a temporary file (a kill leaves the old or the new)."""
        partial = self.path.with_suffix(".partial.npy")
        np.save(partial, self.whole())
        partial.replace(self.path)


def with_twist(rows: np.ndarray, parameters: dict) -> np.ndarray:
    """``rows`` with column 1 the twist Φ(t) of the scene's ``parameters`` [rad] (in place)."""
    rows[:, 1] = twist(rows[:, 0], parameters)
    return rows


def run(
    cells: int, end: float | None = None, out: Path | None = None, restart: Path | None = None
) -> tuple[np.ndarray, float, dict]:
    """The rows (steps, 8) of plectoneme_run's ``Record`` with column 1 the twist Φ(t), on
    ``cells`` P3 cells (half on each member), up to ``end`` [s] (the scene's if None), its
    outputs, checkpoints and rows (:class:`Kept`) in ``out`` if given, or continuing the run
    in ``restart`` from its last checkpoint, there (``cells`` and ``out`` then unused; the
    rows are then the kept ones up to the checkpoint and the new ones); the run's wall time
    [s]; its closed forms (:func:`closed_form`), with "failure" the message of a run that
    stopped and "failed_at" the twist it stopped at."""
    checkpoint = None
    earlier = np.zeros((0, 8))
    if restart is not None:
        overrides: dict = {"output.checkpoint_interval": CHECKPOINTS}
        if end is not None:
            overrides["time.end"] = end
        scene, checkpoint = api.resume(restart, overrides)
        out = restart
        earlier = checkpoint.parts.get("rows", {}).get("rows", earlier)
    else:
        data = tomllib.loads(SCENE.read_text())
        for member in data["structure"]["members"]:
            member["elements"] = cells // 2
        if end is not None:
            data["time"]["end"] = end
        data["output"] = {"checkpoint_interval": CHECKPOINTS, "xdmf_interval": 0.5}
        scene = api.load(data, ())
    if out is None:
        record = Record(1.0)
    else:
        record = Kept(Path(out) / "rows.npy", earlier, scene.parameters)
    forms = closed_form(scene)
    forms["cells"] = sum(member.elements for member in scene.structure.members)
    start = time.perf_counter()
    try:
        api.run(scene, out, observers=[record], record=False, restart=checkpoint)
    except (CosseratError, FloatingPointError) as exc:  # the latter: see docs/plectoneme.md
        forms["failure"] = str(exc)
        forms["failed_at"] = float(twist(record.attempted, scene.parameters))
    if isinstance(record, Kept):
        if record.rows:  # the run started in its folder (a refused folder is not written)
            record.save()
        rows = record.whole()
    else:
        rows = with_twist(np.array(record.rows).reshape(-1, 8), scene.parameters)
    return rows, time.perf_counter() - start, forms


# %%
def plateau(rows: np.ndarray, forms: dict, window: tuple[float, float]) -> dict:
    """The torque over the twists Φ in ``window`` [rad]: its mean [N m], spread (max − min)
    [N m] and slope dM/dΦ [N m/rad] (least squares), over M_p, √(2 EI T) and M_c too; B's shift
    over the window [m], the most pairs, the least gap between the nodes over r; nan if the
    run did not reach the window's end."""
    t, phi, M, dz, w, pairs, gap, between = rows.T
    inside = (phi >= window[0]) & (phi <= window[1])
    if phi[-1] < window[1] or inside.sum() < 3:
        return {"mean": math.nan, "spread": math.nan, "slope": math.nan}
    m = M[inside]
    return {
        "mean": float(m.mean()),
        "spread": float(m.max() - m.min()),
        "slope": float(np.polyfit(phi[inside], m, 1)[0]),
        "mean/M_p": float(m.mean() / forms["M_p"]),
        "mean/loop": float(m.mean() / forms["loop"]),
        "mean/M_c": float(m.mean() / forms["M_c"]),
        "shift": (float(dz[inside][0]), float(dz[inside][-1])),
        "pairs": int(pairs[inside].max()),
        "between/r": float(between[inside].min() / forms["r"]),
    }


def report(cells: int, rows: np.ndarray, wall: float, forms: dict) -> None:
    """Print a run: some 30 rows, where it stopped, and the torque's maximum."""
    print(f"\n{cells} P3 cells ({wall:.1f} s, {len(rows)} steps); Φ_c = {forms['phi_c']:.5f} rad")
    print(forms.get("failure", "completed"))
    print(f"  M_p = {forms['M_p']:.5f} N m at θ_p = {math.degrees(forms['theta_p']):.3f}°")
    print("   t [s]   Φ [rad]  M/M_c    M/√(2EIT) M/M_p    Δz_B [m]  max|w| [m] pairs between/r")
    r = forms["r"]
    touching = np.flatnonzero(rows[:, 5] > 0)
    chosen = set(range(0, len(rows), max(1, len(rows) // 30))) | {len(rows) - 1}
    chosen |= {int(touching[0])} if touching.size else set()
    for i in sorted(chosen):
        t, phi, M, dz, w, n, g, gb = rows[i]
        print(
            f"{t:7.3f} {phi:8.4f} {M / forms['M_c']:8.5f} {M / forms['loop']:8.5f} "
            f"{M / forms['M_p']:8.5f} {dz:+9.5f} "
            f"{w:9.5f} {int(n):4d} {gb / r:+8.4f}"
        )
    i = int(np.argmax(rows[:, 2]))
    print(f"  the torque's maximum {rows[i, 2] / forms['M_c']:.6f} M_c at Φ = {rows[i, 1]:.4f} rad")
    if touching.size:
        print(f"  the strands meet at Φ = {rows[touching[0], 1]:.4f} rad")


if __name__ == "__main__" and MPI.COMM_WORLD.size == 1:
    # rad (t = 59-65 s): on 240 cells the torque after the snap relaxes over ~4 s of t from
    # t = 46 s on and rises again from t ≈ 65 s, when the ply has taken 0.87 m of the rod
    # (docs/plectoneme.md, "Past the snap on two meshes")
    window = (56.5, 59.5)
    args = sys.argv[1:]
    options: dict[str, str] = {}
    for name in ("--end", "--out", "--restart"):
        if name in args:
            at = args.index(name)
            options[name] = args[at + 1]
            del args[at : at + 2]
    end = float(options["--end"]) if "--end" in options else None
    out = Path(options["--out"]) if "--out" in options else None
    restart = Path(options["--restart"]) if "--restart" in options else None
    results = {}
    for cells in [int(a) for a in args] or ([0] if restart else [240, 300]):
        folder = None if out is None else out / str(cells)
        rows, wall, forms = run(cells, end, folder, restart)
        cells = forms["cells"]
        report(cells, rows, wall, forms)
        results[cells] = plateau(rows, forms, window)
        print(f"  plateau over Φ in {window}: {results[cells]}")
    means = [results[c]["mean"] for c in results]
    print("\ncells, the plateau's mean [N m] and its change from the coarser mesh")
    for k, c in enumerate(results):
        change = means[k] - means[k - 1] if k else math.nan
        print(f"{c:5d} {means[k]:.6f} {change:+.2e}")
