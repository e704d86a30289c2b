"""Stress cases 2 and 4 of docs/stability.md: a 100x longer run (6 s) and forcing near resonance
and above the highest resolved frequency, on the paper's rod and mesh (8 cubic elements).

Usage (from the repository root, after ``make setup``; about 6 minutes, ``--quick`` about 1.5):

    .venv/bin/python benchmarks/stress_dynamics.py [--quick]

The analysis (amplification factors, the schemes applied to one mode and to the linearised rod,
the initial states) is shared with ``tests/test_stress_dynamics.py``, which holds the short
versions. Tables go to stdout (Markdown), numbers to ``benchmarks/results/stress_dynamics.json``.

1. Free vibration in mode 1 (x(ℓ) = 1e-3 ℓ, the centre line unstretched), 0 ≤ t ≤ 6 s:
   measured damping ratio against the scheme's, energy at 6 s against |y_n|² of the scheme on
   the one-mode system; the midpoint rule with the frozen Jacobian at stol = 1e-8.
2. The nonlinear rod released from the static state under a tip force (3e3, 2e3, 0) N, 6 s:
   the energy error of each scheme.
3. Resonance (Ω = ω1) and beating (Ω = ω1 + 2π/0.3 s) under f_x = q0 sin(πs/ℓ) sin Ωt.
4. Ω above the highest frequency of the mesh: Ω = 1e6 rad/s and the worst alias ΩΔt = 10π, at
   the paper's step, against the linearised rod integrated by the same scheme and against the
   semi-discrete (exact in time) response.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sl

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import test_stress_dynamics as sd  # noqa: E402

from cosserat_fem.reference.timoshenko import (  # noqa: E402
    modal_loads,
    mode_shapes,
)

RESULTS = ROOT / "benchmarks" / "results"
SCHEMES = ["midpoint", "galpha-0.8", "galpha-0.5", "bdf2", "sdirk3", "sdirk4"]
FORCED = ["midpoint", "galpha-0.8", "bdf2", "sdirk3"]


def scratch() -> Path:
    return Path(tempfile.mkdtemp(prefix="stress-dynamics-"))


def table(title: str, header: list[str], rows: list[list]) -> None:
    print(f"\n### {title}\n")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in rows:
        print("| " + " | ".join(str(c) for c in row) + " |")
    sys.stdout.flush()


#: The scene's frozen Jacobian at the schema's Newton tolerance (the paper's scene sets 1e-7 for
#: SDIRK3; the midpoint rule's energy needs 1e-8: docs/decisions.md).
FROZEN_NEWTON = ["solver.stol=1e-8"]


def g(x: float) -> str:
    return f"{x:.3g}"


# ------------------------------------------------------------------ 1. linear free vibration
def free_vibration_study(end: float) -> list[dict]:
    state, omega1 = sd.mode_one_state(1e-3)
    E0 = sd.energy_of(sd.UNLOADED, state)
    eps = E0 / (100.0 * sd.energy_of(sd.UNLOADED, sd.mode_one_state(1e-4)[0])) - 1.0
    h = 8e-4
    rows, out = [], []
    runs = [(name, sd.FULL_NEWTON) for name in SCHEMES]
    runs += [("midpoint", FROZEN_NEWTON), ("sdirk3", FROZEN_NEWTON)]
    for name, solver in runs:
        overrides = sd.UNLOADED + solver + sd.INTEGRATORS[name]
        overrides += [f"time.step={h}", f"time.end={end}"]
        t0 = time.perf_counter()
        t, E = sd.free_vibration(scratch(), overrides, state, E0)
        wall = time.perf_counter() - t0
        predicted = sd.one_mode_energy(name, omega1, h, len(E))
        xi = sd.damping_ratio(name, omega1 * h)
        if name == "midpoint":
            xi_measured = float("nan")
        else:
            xi_measured = -np.polyfit(t[20:], np.log(E[20:]), 1)[0] / (2.0 * omega1)
        label = name + ("" if solver != FROZEN_NEWTON else " (frozen Jacobian, stol = 1e-8)")
        record = {
            "scheme": label,
            "omega_h": omega1 * h,
            "xi": xi,
            "xi_measured": xi_measured,
            "loss_per_period": 1.0 - math.exp(-4.0 * math.pi * xi),
            "E_end": float(E[-1]),
            "E_end_predicted": float(predicted[-1]),
            "max_deviation_over_eps": float(np.abs(E - predicted).max() / eps),
            "max_abs_E_minus_1": float(np.abs(E - 1.0).max()),
            "largest_step_increase_after_20": float(np.diff(E[20:]).max()),
            "eps": eps,
            "wall_s": wall,
        }
        out.append(record)
        rows.append(
            [
                label,
                g(xi),
                g(xi_measured),
                g(record["loss_per_period"]),
                f"{E[-1]:.6f}",
                f"{predicted[-1]:.6f}",
                g(record["max_deviation_over_eps"]),
                g(record["largest_step_increase_after_20"]),
                f"{wall:.1f}",
            ]
        )
    table(
        f"Mode 1 released at 1e-3 ℓ, Δt = 0.8 ms (ω1Δt = {omega1 * h:.3f}), 0 ≤ t ≤ {end:g} s, "
        f"ε = {eps:.2e}",
        [
            "scheme",
            "ξ (scheme)",
            "ξ measured",
            "energy lost a period",
            "E(end)/E0",
            "one-mode prediction",
            "max dev. / ε",
            "largest step increase",
            "wall [s]",
        ],
        rows,
    )
    return out


# ------------------------------------------------------------------ 2. nonlinear free vibration
def nonlinear_study(end: float) -> list[dict]:
    force = ["loads.end.force=[3e3,2e3,0]", "static.load_steps=4"]
    static, _ = sd.solve_static(sd.scene_of(sd.UNLOADED + force))
    state = static.U.x.array.reshape(-1, 12).copy()
    E0 = sd.energy_of(sd.UNLOADED, state)
    runs = [("midpoint", h, sd.FULL_NEWTON) for h in (4e-4, 2e-4, 1e-4)]
    runs += [(name, 4e-4, sd.FULL_NEWTON) for name in ("galpha-0.8", "bdf2")]
    runs += [("midpoint", 1e-4, FROZEN_NEWTON)]
    rows, out = [], []
    for name, h, solver in runs:
        overrides = sd.UNLOADED + solver + sd.INTEGRATORS[name]
        overrides += [f"time.step={h}", f"time.end={end}"]
        t0 = time.perf_counter()
        t, E = sd.free_vibration(scratch(), overrides, state, E0)
        wall = time.perf_counter() - t0
        e = E - 1.0
        sixth = len(e) // 6
        windows = [float(np.abs(e[i : i + sixth]).max()) for i in range(0, 6 * sixth, sixth)]
        name = name + ("" if solver != FROZEN_NEWTON else " (frozen Jacobian, stol = 1e-8)")
        record = {
            "scheme": name,
            "h": h,
            "E0": E0,
            "max_abs": float(np.abs(e).max()),
            "E_end_minus_1": float(e[-1]),
            "max_per_sixth": windows,
            "largest_step_increase": float(np.diff(E).max()),
            "wall_s": wall,
        }
        out.append(record)
        rows.append(
            [name, f"{h * 1e3:g}", g(record["max_abs"]), g(e[-1])]
            + [" ".join(g(w) for w in windows), g(record["largest_step_increase"]), f"{wall:.0f}"]
        )
    table(
        f"Released from the static state under (3e3, 2e3, 0) N (E0 = {E0:.2f} J), "
        f"0 ≤ t ≤ {end:g} s",
        [
            "scheme",
            "Δt [ms]",
            "max |E/E0 − 1|",
            "E(end)/E0 − 1",
            "max |E/E0 − 1| in each sixth of the run",
            "largest step increase",
            "wall [s]",
        ],
        rows,
    )
    return out


# ------------------------------------------------------------------ 3. resonance and beating
def resonance_study(end: float) -> list[dict]:
    beam, _ = sd.bending_planes(sd.scene_of(sd.UNLOADED))
    _, modes = sd.compute_modes(sd.scene_of(sd.UNLOADED), 1)
    omega1 = modes[0].omega
    mode = mode_shapes(beam, 1)[0]
    q0, h = 5.0, 2e-4
    Q1 = modal_loads(beam, q0, None, [mode])[0]
    tip = mode.W(beam.length)
    modal = tip * Q1 / (2.0 * mode.omega)
    rows, beats, out = [], [], []
    for name in FORCED:
        load = [sd.SINE_X.format(q0=q0), f"parameters.W={omega1!r}"]
        t0 = time.perf_counter()
        t, x = sd.tip_history(
            scratch(), sd.INTEGRATORS[name] + load + [f"time.step={h}", f"time.end={end}"]
        )
        wall = time.perf_counter() - t0
        measured = sd.growth_rate(t, x, omega1)
        K, M, f = sd.one_mode(omega1, Q1)
        eta = sd.scheme_response(K, M, f, lambda s: math.sin(omega1 * s), h, len(t) - 1, name)
        scheme = sd.growth_rate(t, tip * eta[:, 0], omega1)
        out.append(
            {
                "case": "resonance",
                "scheme": name,
                "growth_m_per_s": measured,
                "modal": modal,
                "scheme_one_mode": scheme,
                "tip_end": float(np.abs(x[-len(x) // 40 :]).max()),
                "wall_s": wall,
            }
        )
        rows.append(
            [
                name,
                f"{measured:.6e}",
                g(measured / modal - 1.0),
                g(scheme / modal - 1.0),
                g(measured / scheme - 1.0),
                g(out[-1]["tip_end"]),
                f"{wall:.1f}",
            ]
        )
    table(
        f"Resonance: q0 = {q0:g} N/m at Ω = ω1 = {omega1:.4f} rad/s, Δt = 0.2 ms, "
        f"0 ≤ t ≤ {end:g} s; modal growth W1(ℓ)Q1/(2ω1) = {modal:.6e} m/s",
        [
            "scheme",
            "growth [m/s]",
            "vs modal",
            "scheme on mode 1 vs modal",
            "vs scheme on mode 1",
            "tip amplitude at end [m]",
            "wall [s]",
        ],
        rows,
    )
    beat = 0.3
    Omega = omega1 + 2.0 * math.pi / beat
    peak = abs(tip * Q1 / (mode.omega**2 - Omega**2)) * (1.0 + Omega / omega1)
    for name in FORCED:
        load = [sd.SINE_X.format(q0=q0), f"parameters.W={Omega!r}"]
        t, x = sd.tip_history(
            scratch(), sd.INTEGRATORS[name] + load + [f"time.step={h}", f"time.end={2 * beat}"]
        )
        free = fitted_free_frequency(t, x, Omega, omega1)
        omega_scheme = np.angle(sd.amplification(name, 1j * omega1 * h)) / h
        period = 2.0 * math.pi / (Omega - free)
        minima = envelope_minima(t, x)
        out.append(
            {
                "case": "beating",
                "scheme": name,
                "beat_period_fit": period,
                "beat_period_scheme": 2.0 * math.pi / (Omega - omega_scheme),
                "envelope_minima_s": minima,
                "peak": float(np.abs(x).max()),
                "peak_modal": peak,
            }
        )
        beats.append(
            [
                name,
                f"{period:.6f}",
                f"{2.0 * math.pi / (Omega - omega_scheme):.6f}",
                ", ".join(f"{m:.4f}" for m in minima),
                f"{np.abs(x).max():.4e}",
                g(np.abs(x).max() / peak - 1.0),
            ]
        )
    table(
        f"Beating: Ω = ω1 + 2π/{beat:g} s = {Omega:.4f} rad/s, 0 ≤ t ≤ {2 * beat:g} s; "
        f"beat period 2π/(Ω − ω1) = {beat:g} s, peak |A|(1 + Ω/ω1) = {peak:.4e} m",
        [
            "scheme",
            "beat period (fit) [s]",
            "2π/(Ω − ω̃) of the scheme [s]",
            "envelope minima [s]",
            "peak [m]",
            "peak vs modal",
        ],
        beats,
    )
    return out


def fitted_free_frequency(t, x, Omega, guess) -> float:
    from scipy.optimize import minimize_scalar

    def misfit(omega):
        basis = np.column_stack(
            [np.sin(Omega * t), np.cos(Omega * t), np.sin(omega * t), np.cos(omega * t)]
        )
        c, *_ = np.linalg.lstsq(basis, x, rcond=None)
        return float(np.sum((basis @ c - x) ** 2))

    return float(minimize_scalar(misfit, bracket=(guess - 0.5, guess + 0.5), tol=1e-12).x)


def envelope_minima(t, x) -> list[float]:
    """Times of the interior minima of the envelope |x + i H[x]| (analytic signal)."""
    from scipy.signal import hilbert

    env = np.abs(hilbert(x))
    trim = len(t) // 20  # the transform's end effects
    idx = [
        i
        for i in range(trim, len(env) - trim)
        if env[i] < env[i - 1]
        and env[i] <= env[i + 1]
        and env[i] == env[max(0, i - 200) : i + 200].min()
    ]
    return [float(t[i]) for i in idx]


# ------------------------------------------------------------------ 4. above the mesh
def above_study(end: float) -> list[dict]:
    K, M, f, tip, omega0 = sd.linear_system(['loads.force_density=["2e3*sin(pi*s/L)",0,0]'])
    lam, vecs = sl.eig(K, M)
    order = np.argsort(lam.real)
    lam, vecs = lam.real[order], vecs.real[:, order]
    omega = omega0 * np.sqrt(lam)
    omega_max = float(omega[-1])
    length = sd.scene_of([]).rod.length
    static = length * np.linalg.solve(K, -f)[tip]
    h = 3e-5
    out = []
    rows = []
    for Omega in (1e6, 10.0 * math.pi / h):
        theta = math.remainder(Omega * h, 2.0 * math.pi)
        semi = semi_discrete_tip(K, M, f, tip, omega0, Omega, end, h, vecs, lam) * length
        for name in FORCED + (["galpha-0.5"] if Omega != 1e6 else []):
            load = [
                'loads.force_density=["2e3*sin(pi*s/L)*sin(W*t)",0,0]',
                f"parameters.W={Omega!r}",
            ]
            t0 = time.perf_counter()
            t, x = sd.tip_history(
                scratch(), sd.INTEGRATORS[name] + load + [f"time.step={h}", f"time.end={end}"]
            )
            wall = time.perf_counter() - t0
            y = sd.scheme_response(
                K,
                M,
                f,
                lambda tau, W=Omega: math.sin(W * tau / omega0),
                omega0 * h,
                len(t) - 1,
                name,
            )
            linear = length * y[:, tip]
            half = len(x) // 2
            record = {
                "Omega": Omega,
                "Omega_h": Omega * h,
                "alias_rad_per_step": theta,
                "scheme": name,
                "max_tip": float(np.abs(x).max()),
                "max_tip_over_static": float(np.abs(x).max() / static),
                "second_half_over_first": float(np.abs(x[half:]).max() / np.abs(x[:half]).max())
                if np.abs(x[:half]).max() > 1e-8 * static
                else float("nan"),
                "vs_linear_scheme": float(np.abs(x - linear).max() / np.abs(linear).max())
                if np.abs(linear).max() > 1e-8 * static
                else float("nan"),
                "semi_discrete_max_tip": float(np.abs(semi).max()),
                "wall_s": wall,
            }
            out.append(record)
            rows.append(
                [
                    f"{Omega:.6g}",
                    name,
                    g(record["max_tip"]),
                    g(record["max_tip_over_static"]),
                    g(record["max_tip"] / record["semi_discrete_max_tip"]),
                    g(record["second_half_over_first"]),
                    g(record["vs_linear_scheme"]),
                ]
            )
    table(
        f"Ω above ω_max = {omega_max:.4g} rad/s (8 cubic elements), q0 = 2e3 N/m, Δt = 30 μs, "
        f"0 ≤ t ≤ {end:g} s; static deflection {static:.4e} m; alias of Ω = 1e6: "
        f"{math.remainder(1e6 * h, 2 * math.pi):.3f} rad a step",
        [
            "Ω [rad/s]",
            "scheme",
            "max |x(ℓ)| [m]",
            "/ static",
            "/ semi-discrete",
            "2nd half / 1st half",
            "vs same scheme on the linearised rod",
        ],
        rows,
    )
    return out + [{"omega_max": omega_max, "static_tip": static}]


def semi_discrete_tip(K, M, f, tip, omega0, Omega, end, h, vecs, lam) -> np.ndarray:
    """The linearised rod's x(ℓ)/ℓ exact in time (modal superposition, Duhamel), from rest, on
    the step grid: η_k'' + λ_k η_k = −(Φ⁻¹ M⁻¹ f)_k sin(W τ), τ = ω0 t, W = Ω/ω0."""
    Q = -np.linalg.solve(vecs, np.linalg.solve(M, f))
    W = Omega / omega0
    tau = omega0 * np.arange(round(end / h) + 1) * h
    w = np.sqrt(lam)
    eta = Q / (w**2 - W**2) * (np.sin(W * tau)[:, None] - (W / w) * np.sin(np.outer(tau, w)))
    return eta @ vecs[tip]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs (about a minute)")
    args = parser.parse_args()
    scale = 0.1 if args.quick else 1.0
    t0 = time.perf_counter()
    results = {
        "free_vibration": free_vibration_study(6.0 * scale),
        "nonlinear": nonlinear_study(6.0 * scale),
        "resonance": resonance_study(1.2 * max(scale, 0.5)),
        "above": above_study(0.3 * max(scale, 0.2)),
    }
    results["wall_s"] = time.perf_counter() - t0
    RESULTS.mkdir(parents=True, exist_ok=True)
    name = "stress_dynamics_quick.json" if args.quick else "stress_dynamics.json"
    (RESULTS / name).write_text(json.dumps(results, indent=1))
    print(f"\nwall time {results['wall_s']:.0f} s; results in {RESULTS / name}")


if __name__ == "__main__":
    main()
