"""Kelvin–Voigt damping per strain component: ``damping.retardation_time`` as six μ_i, in the
section's strain order (shear 1, shear 2, extension, bending 1, bending 2, torsion;
docs/sections.md §1), the viscous parts diag(μ) K ε̇ (forms/general_form.py
KelvinVoigtDamping, BeamDyn's stiffness-proportional damping).

The closed form. Linearised about the straight rod, the paper's rod (rectangle, K diagonal)
splits into four uncoupled motions, each with its own strains: extension (v3), torsion (u3),
bending in the x plane (x, ψ: shear v1 and bending u2) and in the y plane (y, θ: v2 and u1).
Give the components of one motion the same μ, μ = (μx, μy, μz, μy, μx, μt); then on that
motion's subspace the semi-discrete damping operator is μ_motion × its stiffness operator, so
each of its modes keeps its shape and decays as exp(−μ ω_n² t/2), ζ_n = μ ω_n/2, ω_n the
undamped FE frequency (``compute_modes``); and each motion's rate is set by its own μ only.
Were one μ applied to all (the scalar law with μx), the axial mode would decay 19x faster
than asserted (μx/μz), the torsion mode 6.8x, the y plane's 0.75x: an O(1) failure; and a
component given a neighbour's μ (an index off by one) fails as much.

The tolerance, from the time discretisation (SDIRK3, the paper scene's integrator; the space
discretisation enters through ω_n, which is the FE model's own): SDIRK3 loses ~(ω h)⁴/24 of
the amplitude a step, a rate error (ω h)⁴/(24 h), relative to ζ ω: (ω h)³/(24 ζ); the peaks
are read on the step grid by a parabola through three samples, a relative error of order
(ω h)²/12 in each peak, which the fit over a few peaks spreads into the rate by about that
much again. At the steps below (ω h ≤ 0.04) these are ≤ 1.3e-4 and ≤ 1.3e-4: measured
2.9e-4 (axial), 2.7e-5 (torsion), 5.0e-5 and 1.3e-4 (bending x, y); allowed 1e-3 for each.
"""

from __future__ import annotations

import math

import pytest
from conftest import ROOT, run_command
from test_scene_features import _first_bending_mode, decay_rate, released, scene

from cosserat_fem.analysis.equilibria import compute_modes


@pytest.fixture(scope="module")
def first():
    """The first undamped FE frequency [rad/s] of each kind of the paper's rod."""
    _, modes = compute_modes(scene({}), 12)
    return {m.kind: m.omega for m in reversed(modes)}


def _times(first) -> tuple[float, ...]:
    """μ = (μx, μy, μz, μy, μx, μt) for ζ = 1 % (x plane), 2 % (y plane), 2 % (axial),
    3 % (torsion) in each motion's first mode: μ = 2 ζ/ω, from 5.0e-6 s (μz) to 1.3e-4 s (μy)."""
    mux, muy = 2 * 0.01 / first["bending-x"], 2 * 0.02 / first["bending-y"]
    muz, mut = 2 * 0.02 / first["axial"], 2 * 0.03 / first["torsion"]
    return (mux, muy, muz, muy, mux, mut)


def test_extension_and_torsion_decay_at_their_own_retardation_times(tmp_path, first):
    """Released at once from the first axial mode z = 1e-6 sin(π s/(2ℓ)) m at rest and the
    first torsion mode φ̇ = 1e-4 ω_t sin(π s/(2ℓ)) (exact modes of the continuum; linear at
    these amplitudes, extension and torsion uncoupled): the tip's z decays at μ3 ω_z²/2 and its
    φ at μ6 ω_t²/2 (module docstring), within 1e-3. SDIRK3, h = 5 μs (ω h = 0.040, 0.021),
    6 ms (7 peaks of z, 4 of φ)."""
    mu = _times(first)
    wz, wt = first["axial"], first["torsion"]
    initial = {
        "displacement": [0, 0, "1e-6*sin(pi*s/(2*L))"],
        "angle_rates": [0, 0, f"{1e-4 * wt!r}*sin(pi*s/(2*L))"],
    }
    data, summary = released(tmp_path, initial, {"retardation_time": list(mu)}, 0.006, 5e-6)
    assert "kelvin_voigt" not in summary["skipped_terms"]
    for column, omega, mu_i in ((3, wz, mu[2]), (6, wt, mu[5])):
        rate, peaks = decay_rate(data[:, 0], data[:, column])
        assert peaks >= 3, column
        assert rate == pytest.approx(mu_i * omega**2 / 2, rel=1e-3), column


def test_bending_decays_at_the_retardation_times_of_its_plane(tmp_path, first):
    """Released from the first Euler–Bernoulli mode in both planes at once (tips 1 mm), μx =
    μ1 = μ5 (shear 1, bending 2: the x plane) and μy = μ2 = μ4 (the y plane), μx/μy = 0.75:
    the tips' x and y decay at μ5 ω_x²/2 and μ4 ω_y²/2 (ζ 1 % and 2 %), within 1e-3. The
    initial shape's higher-mode content decays ≥ 39x faster (rates ∝ ω²), so only peaks after
    the first period are fitted (tests/test_scene_features.py, the scalar law's test). SDIRK3,
    h = 0.1 ms (ω h = 0.021, 0.031), 0.13 s (≥ 3 peaks in each plane)."""
    mu = _times(first)
    wx, wy = first["bending-x"], first["bending-y"]
    shape, slope, _ = _first_bending_mode(1e-3)
    initial = {"displacement": [shape, shape, 0], "angles": [f"-{slope}", slope, 0]}
    data, _ = released(tmp_path, initial, {"retardation_time": list(mu)}, 0.13, 1e-4)
    late = data[:, 0] > 2 * math.pi / wx
    for column, omega, mu_i in ((1, wx, mu[4]), (2, wy, mu[3])):
        rate, peaks = decay_rate(data[late, 0], data[late, column])
        assert peaks >= 3, column
        assert rate == pytest.approx(mu_i * omega**2 / 2, rel=1e-3), column


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("[1e-4, 1e-4, 1e-4]", "damping.retardation_time: must be a number >= 0 [s] or a list"),
        ("[1e-4, 1e-4, -1e-4, 1e-4, 1e-4, 1e-4]", "damping.retardation_time[2]: must be >= 0"),
        ('[1e-4, 1e-4, 1e-4, 1e-4, 1e-4, "x"]', "damping.retardation_time[5]: must be a number"),
    ],
)
def test_bad_retardation_times_are_one_line(tmp_path, value, message):
    """Six numbers or one: a list of another length, a negative or a non-number entry is one
    line naming the key (and the entry), exit status 2, no traceback, nothing run."""
    proc = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "run",
            str(ROOT / "scenes" / "cao_tucker_2008.toml"),
            "--out",
            str(tmp_path / "x"),
            "--set",
            f"damping.retardation_time={value}",
        ]
    )
    assert proc.returncode == 2
    assert message in proc.stderr, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert not (tmp_path / "x" / "probes.csv").exists()


def test_six_retardation_times_are_written_as_read():
    """The scene keeps the value as given, a number or six (a tuple); written back
    (``Scene.to_dict``, what a checkpoint and summary.json hold) as the number or the list,
    and read again it is the same scene: a restart runs the damping it ran."""
    from cosserat_fem.scene.build import scene_from_dict

    six = [1e-4, 2e-4, 1e-5, 2e-4, 1e-4, 3e-5]
    for value, resolved in ((six, tuple(six)), (2e-4, 2e-4)):
        sc = scene({"damping": {"retardation_time": value}})
        assert sc.damping.retardation_time == resolved and sc.damping.kelvin_voigt
        written = sc.to_dict()
        assert written["damping"]["retardation_time"] == value
        assert scene_from_dict(written) == sc
    assert not scene({"damping": {"retardation_time": [0.0] * 6}}).damping.kelvin_voigt
