# %% [markdown]
# # The cost of contact's rows (docs/contact.md, "Limits")
#
# The rod of tests/test_contact.py sliding on a plane (v0 = 1 m/s, μ = 0.5, BDF2, h = 5 ms,
# 0.1 s, every node in contact), against the same rod without the plane (it falls freely:
# the same unknowns, integrator and steps, no rows, the compiled residual). Per Newton
# iteration, medians of interleaved runs; the contact's share is the rows, the Python
# residual and the Jacobian assembled at every iteration (full Newton).
#
#     .venv/bin/python benchmarks/contact_cost.py [cells] [repeats]

# %%
from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_contact import sliding  # noqa: E402

from cosserat_fem import api  # noqa: E402
from cosserat_fem.scene.build import scene_from_dict  # noqa: E402


def one(cells: int, contact: bool, full: bool = False) -> tuple[float, int, str]:
    """Seconds a Newton iteration, iterations, the residual's loop; ``full``: without contact
    the same full Newton with DOLFINx's residual as contact's."""
    data = sliding("bdf2", 0.005, end=0.1)
    data["discretisation"]["elements"] = cells
    if not contact:
        del data["contact"]
    if full:
        data["solver"] = {"jacobian": "full", "loop": "python"}
    t0 = time.perf_counter()
    result = api.run(scene_from_dict(data))
    wall = time.perf_counter() - t0
    newton = result.summary["newton"]
    return wall / newton["iterations"], newton["iterations"], newton["loop"]


def compare(one, cells: int, repeats: int, contact: str = "contact") -> None:
    """``one(cells, contact, full)`` → (seconds an iteration, iterations, a note) for the
    three cases, interleaved ``repeats`` times; prints each run and the medians, with their
    ratios to the full-Newton run without contact."""
    cases = {
        "no contact": (False, False),
        "no contact, full": (False, True),
        contact: (True, False),
    }
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(repeats):
        for name, (on, full) in cases.items():
            per, its, note = one(cells, on, full)
            times[name].append(per)
            print(f"{name}: {its} iterations, {1e3 * per:.2f} ms each ({note})")
    medians = {name: statistics.median(values) for name, values in times.items()}
    for name, value in medians.items():
        ratio = value / medians["no contact, full"]
        print(f"{cells} cells, {name}: {1e3 * value:.2f} ms an iteration ({ratio:.2f})")


if __name__ == "__main__":
    compare(
        one,
        int(sys.argv[1]) if len(sys.argv) > 1 else 100,
        int(sys.argv[2]) if len(sys.argv) > 2 else 3,
    )
