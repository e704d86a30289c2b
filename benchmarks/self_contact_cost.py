# %% [markdown]
# # The cost of self contact's rows (docs/contact.md, "Self contact")
#
# The hairpin of tests/test_self_contact.py with its long leg and corner 10⁶ times stiffer
# (`rigid_hairpin`), the free leg falling under gravity onto the long leg and lying on it
# (BDF2, h = 2 ms, 0.1 s, Kelvin–Voigt τ = 5 ms): about every node of the free leg ends as a
# slave. Against the same run without contact (the leg falls through: the same unknowns,
# integrator and steps) in the compiled loop, and in the same full-Newton Python loop that
# contact uses. Per Newton iteration (the time loop's wall time without outputs over its
# iterations), medians of interleaved runs.
#
#     .venv/bin/python benchmarks/self_contact_cost.py [cells] [repeats]

# %%
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from contact_cost import compare  # noqa: E402
from test_self_contact import rigid_hairpin  # noqa: E402

from cosserat_fem import api  # noqa: E402
from cosserat_fem.scene.build import scene_from_dict  # noqa: E402


def one(cells: int, contact: bool, full: bool = False) -> tuple[float, int, dict]:
    """Seconds a Newton iteration, the iterations, and the pairs' summary."""
    data = rigid_hairpin(0.0, 0.0, 0.02495, 0.3)
    data["discretisation"]["elements"] = cells
    data["loads"] = {"gravity": [0.0, 0.0, -9.81]}
    data["time"] = {"end": 0.1, "step": 0.002, "integrator": "bdf2"}
    data["damping"] = {"retardation_time": 0.005}
    data["output"] = {"xdmf": False}
    if not contact:
        del data["contact"]
    if full:
        data["solver"] = {"jacobian": "full", "loop": "python"}
    result = api.run(scene_from_dict(data))
    loop = result.summary["wall_time_s"]["solve_loop_without_output"]
    newton = result.summary["newton"]
    return loop / newton["iterations"], newton["iterations"], result.summary.get("contact", {})


if __name__ == "__main__":
    compare(
        one,
        int(sys.argv[1]) if len(sys.argv) > 1 else 39,
        int(sys.argv[2]) if len(sys.argv) > 2 else 3,
        "self contact",
    )
