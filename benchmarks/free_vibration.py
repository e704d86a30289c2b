"""A verification helper, off the product path: the frequency of a rod's free vibration,
measured by a run (tests/test_backbone.py and benchmarks/verify.py compare it with the
backbone curves of cosserat_fem/reference/backbone.py)."""

from __future__ import annotations

import math

import numpy as np

from cosserat_fem.api import run
from cosserat_fem.rod.model import build_model


def free_vibration_frequency(scene, shape, amplitude: float) -> float:
    """ω [rad/s] of the rod's free vibration from rest in ``shape(amplitude, ℓ, s)`` (the
    displacements x(s), z(s) − s [m] and the angle ψ(s) [rad] at s [m], e.g. those of
    cosserat_fem/reference/backbone.py): π over the mean spacing of the probe's x zero
    crossings (a least-squares line through them, each found by linear interpolation; a
    response symmetric in ± has its odd harmonics vanish there too). ``scene`` gives the
    span: at least four crossings are needed."""
    model = build_model(scene, planar=False)
    s = model.V.tabulate_dof_coordinates()[:, 0] * model.length
    x, z, psi = shape(amplitude, model.length, s)
    state = np.zeros((len(s), 12))
    state[:, 0], state[:, 2], state[:, 4] = x / model.length, z / model.length, psi
    probes = run(scene, initial_state=state.ravel()).probes
    t, tip = probes[:, 0], probes[:, 1]
    k = np.flatnonzero(np.sign(tip[1:]) != np.sign(tip[:-1]))
    if len(k) < 4:
        raise ValueError(f"free_vibration_frequency: {len(k)} zero crossings; run longer")
    crossings = t[k] - tip[k] * (t[k + 1] - t[k]) / (tip[k + 1] - tip[k])
    return math.pi / np.polyfit(np.arange(len(crossings)), crossings, 1)[0]
