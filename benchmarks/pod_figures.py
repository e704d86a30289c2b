"""The figures of docs/pod.md's verification: the POD of the linear free vibration of
tests/test_pod.py (the paper's cantilever from ε (φ1 + 0.5 φ2), two periods of mode 1) against
its linear modes, and serial against ``mpirun -n 2``. About 10 s.

    .venv/bin/python benchmarks/pod_figures.py
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_pod as tp  # noqa: E402
from conftest import run_command  # noqa: E402

import cosserat_fem as cf  # noqa: E402
from cosserat_fem.studies.karhunen_loeve import Snapshots, pod  # noqa: E402


def main() -> None:
    result, w1, w2, modes, dt = tp.free_vibration()
    length = result.model.scene.rod.length
    shapes = [tp.sample(m.shape, tp.STATIONS, length) for m in modes]
    t = result.field_times
    print(
        f"ω1 = {w1:.6g}, ω2 = {w2:.6g} rad/s; Δt = {dt:.6g} s; T = {t[-1]:.6g} s; "
        f"{t.size} snapshots at {tp.STATIONS.size} stations"
    )
    cross, selves = tp.window_terms(w1, w2, t[-1])
    for weighting in ("displacement", "kinetic"):
        found = cf.pod(result, tp.STATIONS, modes=4, weighting=weighting)
        phi = [s[:, : len(found.components)] for s in shapes]
        norms = [found.inner(p, p) for p in phi]
        c = found.inner(phi[0], phi[1]) / math.sqrt(norms[0] * norms[1])
        e1, e2 = (tp.EPS * tp.A1) ** 2 * norms[0] / 2, (tp.EPS * tp.A2) ** 2 * norms[1] / 2
        theta = (e2 * abs(c) + cross * math.sqrt(e1 * e2)) / (e1 - e2)
        mac = [found.inner(found.shapes[k], phi[k]) ** 2 / norms[k] for k in range(2)]
        analytic = tp.A2**2 * norms[1] / (tp.A1**2 * norms[0])
        ratio = found.energies[1] / found.energies[0]
        print(
            f"{weighting}: c = {c:.3g}; 1 − MAC = {1 - mac[0]:.3g}, {1 - mac[1]:.3g} (bounds "
            f"{theta**2:.3g}, {(abs(c) + theta) ** 2:.3g}); fractions "
            f"{np.array2string(found.fractions, precision=3)}"
        )
        bound = selves + cross**2 + c**2 + 2 / (t.size - 1)
        print(
            f"  λ2/λ1 = {ratio:.6g}, analytic a2²‖φ2‖²/(a1²‖φ1‖²) = {analytic:.6g}: "
            f"{ratio / analytic - 1:+.3g} (window bound {bound:.3g})"
        )
        rod = tuple(found.weights[[0, 3, 4, 5]]) if len(found.components) == 6 else None
        for name, omegas in (
            ("ω", (w1, w2)),
            ("ω̃", [2 / dt * math.atan(w * dt / 2) for w in (w1, w2)]),
        ):
            c_t = np.array(
                [tp.EPS * a * np.cos(w * t) for a, w in zip((tp.A1, tp.A2), omegas, strict=True)]
            )
            values = np.einsum("kt,knc->tnc", c_t, np.array(phi))
            predicted = pod(Snapshots(found.s, t, values, rod), modes=2, weighting=weighting)
            error = found.energies[:2] / predicted.energies - 1
            print(
                f"  against the two-mode prediction with {name}: {error[0]:+.3g}, {error[1]:+.3g}"
            )
    print(f"(ω Δt)²/12 = {(w1 * dt) ** 2 / 12:.3g}, {(w2 * dt) ** 2 / 12:.3g}")
    proc = run_command(["-c", tp.MPI_SCRIPT, str(tp.SCENE), json.dumps(tp.KICKED)], ranks=2)
    line = [x for x in proc.stdout.splitlines() if x.startswith("ENERGIES")][0]
    parallel = np.array(json.loads(line.split(" ", 1)[1]))
    stations = np.linspace(0.0, 1.0, 97)
    kicked = cf.run(cf.load(tp.SCENE, tp.KICKED), fields=stations)
    serial = cf.pod(kicked, stations, modes=4, weighting="kinetic").energies
    print(
        f"mpirun -n 2 against serial (kicked rod, kinetic): energies {serial}, largest "
        f"relative difference {np.abs(parallel / serial - 1).max():.3g}"
    )


if __name__ == "__main__":
    main()
