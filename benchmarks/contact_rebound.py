# %% [markdown]
# # A rod dropped flat on a plane: how far the integrators let it rebound (docs/contact.md)
#
# The rod of tests/test_contact.py released flat 1 mm above the plane (μ = 0.5), BDF2 and
# generalized-α (ρ∞ = 0.5) at 1 ms, 60 ms: its end's height after the impact at ~14 ms. A
# rigid section on a rigid plane would stay (an inelastic impact); the gap row stops the
# nodes, and the time loop solves the landing step by the midpoint rule
# (cosserat_fem/timestepping/loop.py, "Impacts"), whose restitution for a node δ above the
# plane at the start of the step in which it lands, falling at V, is |1 − 2δ/(V h)|: here
# δ = 0.039 mm, V = 0.137 m/s, e = 0.44, a rebound to (e V)²/(2 g) = 0.18 mm with either
# method (measured 0.184 mm BDF2, 0.187 mm generalized-α; before the midpoint steps 0.27 and
# 0.45 mm).
#
#     .venv/bin/python benchmarks/contact_rebound.py

# %%
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_contact import rod_on_plane  # noqa: E402

from cosserat_fem import api  # noqa: E402
from cosserat_fem.scene.build import scene_from_dict  # noqa: E402

if __name__ == "__main__":
    for integrator in ("bdf2", "generalized-alpha"):
        data = rod_on_plane(10, mu=0.5)
        data["initial"] = {"displacement": ["0.001", 0, 0]}
        data["time"] = {"end": 0.06, "step": 0.001, "integrator": integrator}
        probes = api.run(scene_from_dict(data)).probes
        after = probes[probes[:, 0] > 0.016]
        print(f"{integrator}: highest after the impact {after[:, 1].max():.3e} m (from 1e-3 m)")
