"""The two bending planes of a scene's rectangular rod as linear Timoshenko beams.

The rod of a scene bends in x about d2 (second moment c22 = b a³/12, angle ψ ≈ x') and in y
about d1 (c11 = a b³/12, angle θ ≈ −y'); for small motions each plane is a Timoshenko beam
(:mod:`.timoshenko`). This module only reads numbers from the scene (no DOLFINx).
"""

from __future__ import annotations

import math

import numpy as np

from cosserat_fem.reference.second_order import RodData
from cosserat_fem.reference.timoshenko import TimoshenkoBeam, forced_response, natural_frequencies


def bending_planes(scene) -> tuple[TimoshenkoBeam, TimoshenkoBeam]:
    """(x-plane, y-plane) Timoshenko beams of the scene's rectangular rod."""
    rod = RodData.from_scene(scene)
    return rod.beam_x, rod.beam_y


def sine_load_response(
    scene, times: np.ndarray, q0: float, omega: float, s: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Linear x(s,t), y(s,t) [m] from rest for f_x = f_y = q0 sin(πs/ℓ) sin(Ωt) (the paper's
    load; q0 [N/m], Ω [rad/s]) at the stations ``s`` [m] (default the free end, s = ℓ), each
    of shape ``times.shape + s.shape``.

    Exact modal superposition with static correction: 25 modes in x and 20 in y (all well
    below the cut-off frequencies; truncation error < 1e-8 of the tip deflection).
    """
    x_plane, y_plane = bending_planes(scene)
    x, _ = forced_response(x_plane, q0, omega, times, s=s, modes=25, static_correction=True)
    y, _ = forced_response(y_plane, q0, omega, times, s=s, modes=20, static_correction=True)
    return x, y


def sine_load_tip_response(
    scene, times: np.ndarray, q0: float, omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """Linear x(ℓ,t), y(ℓ,t) from rest for the paper's load: :func:`sine_load_response` at
    the free end."""
    return sine_load_response(scene, times, q0, omega)


def linear_spectrum(scene, count: int) -> list[tuple[float, str]]:
    """The ``count`` lowest natural frequencies [rad/s] of the scene's clamped-free rod, with
    their kinds, from the closed forms of the linearised Cosserat rod: Timoshenko bending in
    both planes, axial bar ω_k = (2k−1) π/(2ℓ) √(E/ρ), torsion bar
    ω_k = (2k−1) π/(2ℓ) √(G c33/(ρ (c11 + c22))) (consistent rotary inertia)."""
    rod = RodData.from_scene(scene)
    x_plane, y_plane = rod.beam_x, rod.beam_y
    spectrum = [(w, "bending-x") for w in natural_frequencies(x_plane, count)]
    spectrum += [(w, "bending-y") for w in natural_frequencies(y_plane, count)]
    bar = math.pi / (2.0 * rod.length)
    axial = math.sqrt(rod.young / rod.density)
    torsion = math.sqrt(rod.shear * rod.c33 / (rod.density * rod.torsion_inertia("polar")))
    for k in range(1, count + 1):
        spectrum.append(((2 * k - 1) * bar * axial, "axial"))
        spectrum.append(((2 * k - 1) * bar * torsion, "torsion"))
    return sorted(spectrum)[:count]
