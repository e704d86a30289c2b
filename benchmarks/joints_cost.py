# %% [markdown]
# # The cost of a joint in a run (docs/structures.md, "Joints": one-off measurement)
#
# The double pendulum of tests/test_joints.py with 20 P3 cells a link, 300 steps of 1 ms,
# serial: joined by a spherical joint (the rows of cosserat_fem/nls/constraints.py) and
# rigidly (one shared vertex), interleaved, the medians of ``repeats`` runs [s].
#
#     .venv/bin/python benchmarks/joints_cost.py [repeats]

# %%
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_joints import pendulum  # noqa: E402

from cosserat_fem import api  # noqa: E402
from cosserat_fem.scene.build import scene_from_dict  # noqa: E402


def seconds(joint: bool, out: Path) -> float:
    data = pendulum(1e-3, end=0.3)
    for m in data["structure"]["members"]:
        m["elements"] = 20
    if not joint:
        del data["structure"]["joints"]
    t0 = time.perf_counter()
    api.run(scene_from_dict(data), out)
    return time.perf_counter() - t0


if __name__ == "__main__":
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    times: dict[bool, list[float]] = {True: [], False: []}
    with tempfile.TemporaryDirectory() as folder:
        for k in range(repeats):
            for joint in (True, False):
                times[joint].append(seconds(joint, Path(folder) / f"{joint}{k}"))
    joint, rigid = (float(np.median(times[j])) for j in (True, False))
    print(f"spherical joint {joint:.2f} s, rigid {rigid:.2f} s: ratio {joint / rigid:.3f}")
