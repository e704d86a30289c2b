# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---
# %% [markdown]
# # The plectoneme with self contact, in time (issue 30; docs/plectoneme.md)
#
# scenes/plectoneme.toml run by `cosserat_fem.api.run` with an observer that records, at
# every accepted step, the twist Φ = rate t, the section torque M = e3 · m(0) at the clamp A
# [N m], B's axial shift [m], the largest lateral displacement [m], the active self-contact
# pairs, the least node-to-cell gap of the pairs found [m] and the least gap between the
# nodes (contact_search.least_gap_between_nodes, what the run's guard checks) [m].
#
#     .venv/bin/python benchmarks/plectoneme_run.py [cells ...]     # default 64
# %%
from __future__ import annotations

import math
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import ufl
from cosserat_fem.forms.resultants import resultants
from dolfinx import fem
from mpi4py import MPI

from cosserat_fem import api
from cosserat_fem.common.errors import CosseratError
from cosserat_fem.output.fields import _directors
from cosserat_fem.timestepping.events import Observer

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "plectoneme.toml"


def closed_form(scene) -> dict[str, float]:
    """EI, GJ [N m²], T [N], M_c [N m] and Φ_c [rad] of the scene's rod (the clamped-clamped
    root with tension, benchmarks/plectoneme_path.py ``buckling_torque``; shear and extension
    dropped)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from plectoneme_path import buckling_torque

    d = scene.rod.section.diameter
    E, nu = scene.rod.material.young_modulus, scene.rod.material.poisson_ratio
    EI = E * math.pi * d**4 / 64
    GJ = EI / (1 + nu)
    T = float(scene.parameters["tension"])
    M = buckling_torque(T, EI, 1.0)
    rate = float(scene.parameters["rate"])
    return {"EI": EI, "GJ": GJ, "T": T, "M_c": M, "phi_c": M / GJ, "diameter": d, "rate": rate}


@dataclass
class Record(Observer):
    """The rows of the module docstring, one an accepted step (serial)."""

    rate: float
    rows: list = field(default_factory=list)
    #: the time [s] of the last step attempted (the failing one if the run stopped)
    attempted: float = 0.0
    _setup: tuple | None = None

    def step_attempted(self, loop, t_new: float) -> None:
        self.attempted = t_new

    def _prepare(self, model) -> tuple:
        V = model.V
        rest = V.tabulate_dof_coordinates() * model.length
        cells = V.mesh.topology.index_map(1).size_local
        dofs = np.array([V.dofmap.cell_dofs(c) for c in range(cells)], dtype=np.int64)
        first = int(np.argmin(rest[dofs].mean(axis=1)[:, 2]))
        at = 0.0 if rest[dofs[first, 0], 2] < rest[dofs[first, 1], 2] else 1.0
        U = model.layout.full(model.U)
        chart, reference = model.chart_form(), model.reference_form()
        res = resultants(U, model.rod, 0.0, chart, reference)
        D = _directors(U, chart, reference)
        m = ufl.as_vector([sum(res.m[i] * D[i, 2] for i in range(3))])
        expression = fem.Expression(m, np.array([[at]]))
        b = int(np.argmax(rest[:, 2]))
        return rest, np.array([first], dtype=np.int32), expression, b

    def step_accepted(self, loop) -> None:
        model = loop.model
        if self._setup is None:
            self._setup = self._prepare(model)
        rest, first, expression, b = self._setup
        bs = model.layout.size
        U = model.U.x.array.reshape(-1, bs)
        x = rest + model.length * U[:, :3]
        torque = float(expression.eval(first).ravel()[0])
        pairs = model.contact.pairs
        between = pairs.geometry.between_nodes(pairs._x)[0] if pairs._x is not None else np.inf
        t = loop.state.t
        self.rows.append(
            (
                t,
                self.rate * t,
                torque,
                float(x[b, 2] - rest[b, 2]),
                float(np.hypot(*(x - rest)[:, :2].T).max()),
                pairs.count(),
                float(pairs.least_gap),
                float(between),
            )
        )


def run(cells: int, overrides: tuple[str, ...] | dict = ()) -> tuple[np.ndarray, float, dict]:
    """The rows (steps, 8) of :class:`Record` of scenes/plectoneme.toml on ``cells`` P3 cells,
    the run's wall time [s] and its closed forms (:func:`closed_form`), with "failure" the
    message of a run that stopped."""
    data = tomllib.loads(SCENE.read_text())
    data["structure"]["members"][0]["elements"] = cells
    scene = api.load(data, overrides)
    record = Record(float(scene.parameters["rate"]))
    start = time.perf_counter()
    forms = closed_form(scene)
    try:
        api.run(scene, None, observers=[record], record=False)
    except (CosseratError, FloatingPointError) as exc:  # the latter: see docs/plectoneme.md
        forms["failure"] = str(exc)
        forms["failed_at"] = record.attempted
    return np.array(record.rows), time.perf_counter() - start, forms


# %%
def figures(rows: np.ndarray, forms: dict) -> dict:
    """The run's figures (docs/plectoneme.md, "With self contact"): the straight torque's
    secant over GJ/L − 1 and B's shift over the stretch T L/EA − 1 (worst) for Φ in
    [Φ_c/4, Φ_c/2], the torque's maximum [N m] over M_c and its Φ, the first twist with a
    pair pressed (nan if none), B's shift there [m], the least node gap of the pairs and
    the least gap between the nodes, over r."""
    t, phi, M, dz, w, pairs, node_gap, between = rows.T
    r = 0.5 * forms["diameter"]
    straight = (phi >= forms["phi_c"] / 4) & (phi <= forms["phi_c"] / 2)
    EA = forms["EI"] * 4 / r**2
    touching = np.flatnonzero(pairs > 0)
    first = touching[0] if touching.size else None
    return {
        "slope": np.polyfit(phi[straight], M[straight], 1)[0] / forms["GJ"] - 1,
        "stretch": float(np.abs(dz[straight] / (forms["T"] / EA) - 1).max()),
        "M_max/M_c": M.max() / forms["M_c"],
        "phi at M_max": phi[np.argmax(M)],
        "onset": phi[first] if first is not None else math.nan,
        "shift at onset": dz[first] if first is not None else math.nan,
        "node gap/r": node_gap[touching].min() / r if touching.size else math.nan,
        "between/r": between.min() / r,
        "last accepted phi": phi[-1],
        "failed at phi": forms.get("failed_at", math.nan) * forms["rate"],
    }


def report(cells: int, rows: np.ndarray, wall: float, forms: dict) -> None:
    """Print a run of :func:`run`: its rows (some 24 and the last 0.3 s) and its figures."""
    print(f"\n{cells} P3 cells ({wall:.1f} s, {len(rows)} steps); Φ_c = {forms['phi_c']:.5f} rad")
    print(forms.get("failure", "completed"))
    print("   t [s]   Φ [rad]  M [N m]   Δz_B [m]  max|w| [m] pairs  gap/r   between/r")
    r = 0.5 * forms["diameter"]
    last = [i for i in range(len(rows)) if rows[i, 0] > rows[-1, 0] - 0.3]
    for i in sorted(set(range(0, len(rows), max(1, len(rows) // 24))) | set(last)):
        t, phi, M, dz, w, n, g, gb = rows[i]
        print(
            f"{t:7.3f} {phi:8.4f} {M:9.5f} {dz:+9.5f} {w:9.5f} {int(n):4d} "
            f"{g / r:+8.3f} {gb / r:+8.3f}"
        )
    for key, value in figures(rows, forms).items():
        print(f"  {key}: {value:.6g}")


if __name__ == "__main__" and MPI.COMM_WORLD.size == 1:
    for cells in [int(a) for a in sys.argv[1:]] or [64]:
        report(cells, *run(cells))
