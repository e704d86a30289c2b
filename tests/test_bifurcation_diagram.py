"""Bifurcation diagrams from sweeps ([sweep.poincare]: cosserat_fem/studies/sweep_spec.py,
sweep_run.py ``gather_sections``; bifurcation.csv, cosserat_fem/io/sweep_table.py;
bifurcation.png, cosserat_fem/plot.py ``plot_bifurcation``).

The fast tests run a coarse buckled beam (scenes/buckled_beam.toml on 2 elements, 20 steps a
period, 4 periods a member): bifurcation.csv holds each member's poincare.csv rows from the
``discard``-th on, exactly (the same numbers, read back from the same run); a chain's member
starts from its predecessor's final state at the forcing's phase carried over; the figure
draws those points; bad keys are one line naming the key.

The long test is the physics: the buckled beam at γ = 0.20, 0.25, 0.28 on the
Duffing–Holmes route (docs/chaos.md), its section against the one-mode reduction's orbits
(cosserat_fem/reference/buckled_beam.py), serially and under ``mpirun -n 2``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, read_table, run_command

from cosserat_fem import api
from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.poincare import read_poincare
from cosserat_fem.io.sweep_table import BIFURCATION
from cosserat_fem.studies.response import continued_start
from cosserat_fem.studies.sweep_run import SECTION_NAMES, bifurcation_columns

BUCKLED = ROOT / "scenes" / "buckled_beam.toml"
#: scenes/buckled_beam.toml's forcing frequency [rad/s] and its f0 per unit of γ [N/m]
#: (f0 = γ ρA a_s k: 18.633909980139364 N/m at γ = 0.28, the scene's value).
OM = 174.35653081884595
F_PER_GAMMA = 18.633909980139364 / 0.28
T = 2 * math.pi / OM
A_S = 0.005773502691896259  # m, the buckled mid-span deflection a_s (the scene's As)


def section_sweep(
    folder: Path,
    gammas,
    periods: int,
    discard: int,
    coarse: bool = True,
    poincare: str = 'continuation = "parameters.f0"\n',
    group_size: int = 1,
) -> Path:
    """A sweep of scenes/buckled_beam.toml over f0 at ``gammas``, each member ``periods``
    forcing periods without XDMF, [sweep.poincare] at the forcing's period with ``discard``
    and the lines ``poincare``; ``coarse``: 2 cubic elements, 20 steps a period."""
    fixed = {"time.end": periods * T, "output.xdmf": False}
    if coarse:
        fixed.update({"discretisation.elements": 2, "time.step": T / 20})
    values = ", ".join(repr(g * F_PER_GAMMA) for g in gammas)
    text = (
        f'[sweep]\nscene = "{BUCKLED}"\nkeep = "probes"\ngroup_size = {group_size}\n'
        "[sweep.set]\n"
        + "".join(f'"{k}" = {json.dumps(v)}\n' for k, v in fixed.items())
        + f'[sweep.vary]\n"parameters.f0" = [{values}]\n'
        + f'[sweep.poincare]\nperiod = "2*pi/Om"\ndiscard = {discard}\n{poincare}'
    )
    path = folder / "section_sweep.toml"
    path.write_text(text, encoding="utf-8")
    return path


def points_of(out: Path) -> list[dict]:
    return read_table(out / BIFURCATION)


def test_a_sweep_gathers_every_members_section_into_bifurcation_csv(tmp_path):
    """Two members in a chain up in f0 (γ = 0.20, 0.28), 4 periods each, discard = 1.
    bifurcation.csv has the columns member, f0, direction, point, period, t, x ... φ,
    state_rms, and for each member the rows of its poincare.csv from the second on, the same
    numbers (repr of the 17-digit values). Member 0 runs from t = 0: sections j = 0 ... 4,
    4 points kept; member 1 starts at continued_start(end of member 0) ∈ [0, T) (the forcing's
    phase carried over: its t0 mod T equals member 0's end mod T, to the 11 digits probes.csv
    prints t with) from member 0's final state: its first probe row is member 0's last,
    value for value."""
    out = tmp_path / "out"
    spec = api.load_sweep(section_sweep(tmp_path, (0.20, 0.28), periods=4, discard=1))
    assert [c for c in spec.chains] == [(0, 1)]
    api.sweep(spec, out)
    rows = points_of(out)
    assert list(rows[0]) == bifurcation_columns(spec)
    assert list(rows[0])[:4] == ["member", "parameters.f0", "direction", "point"]
    for member in (0, 1):
        folder = out / "members" / f"m{member:05d}"
        columns, section = read_poincare(folder / "poincare.csv")
        mine = [r for r in rows if r["member"] == str(member)]
        assert [int(r["point"]) for r in mine] == list(range(len(section) - 1))
        assert json.loads(mine[0]["parameters.f0"]) == spec.members[member].values["parameters.f0"]
        assert {r["direction"] for r in mine} == {"up"}
        take = [columns.index(c) for c in SECTION_NAMES]
        got = np.array([[float(r[c]) for c in SECTION_NAMES] for r in mine])
        assert np.array_equal(got, section[1:, take])
    assert len([r for r in rows if r["member"] == "0"]) == 4
    first = read_table(out / "members" / "m00000" / "probes.csv")
    second = read_table(out / "members" / "m00001" / "probes.csv")
    end = float(first[-1]["t"])
    start = float(second[0]["t"])
    assert 0.0 <= start < T
    # probes.csv prints t with 11 digits: 1e-11 s here, 5e-10 of T
    assert abs(start - continued_start(end, T, T)) <= 2e-11
    assert abs((end - start) / T - round((end - start) / T)) <= 1e-9
    assert {k: v for k, v in second[0].items() if k != "t"} == {
        k: v for k, v in first[-1].items() if k != "t"
    }


def test_plot_draws_a_dot_per_section_point(tmp_path, monkeypatch):
    """``plot`` of the sweep's folder draws bifurcation.png (910 × 650 px) beside sweep.png:
    one set of dots (the chain up), at (f0, x) of every row of bifurcation.csv (x: the
    coordinate that spreads the most; y and z are still, the beam bends in x); a value that is
    not a number in bifurcation.csv is refused in one line naming the file."""
    import struct

    from cosserat_fem import plot

    out = tmp_path / "out"
    api.sweep(api.load_sweep(section_sweep(tmp_path, (0.20, 0.28), 3, 1)), out)
    drawn = {}
    save = plot._save

    def keep(fig, path, command="plot"):
        drawn[path.name] = plot.drawn_lines(fig)
        return save(fig, path, command)

    monkeypatch.setattr(plot, "_save", keep)
    paths = plot.plot_run(out)
    assert [p.name for p in paths] == ["sweep.png", "bifurcation.png"]
    png = (out / "bifurcation.png").read_bytes()
    assert struct.unpack(">II", png[16:24]) == (910, 650)
    rows = points_of(out)
    want = np.array([[float(r["parameters.f0"]), float(r["x"])] for r in rows]).T
    lines = drawn["bifurcation.png"]
    assert np.array_equal(lines["axes0/line0"], want)
    assert "axes0/line1" not in lines
    text = (out / BIFURCATION).read_text(encoding="utf-8").replace(rows[0]["x"], "nan", 1)
    (out / BIFURCATION).write_text(text, encoding="utf-8")
    proc = run_command(["-m", "cosserat_fem.cli", "plot", str(out)])
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "bifurcation.csv" in proc.stderr and "'x'" in proc.stderr


@pytest.mark.parametrize(
    "poincare, message",
    [
        ('period = "2*pi/Om"\nevery = 2\n', "sweep.poincare.every: unknown key"),
        ("phase = 0.0\n", "sweep.poincare.period: required"),
        ('period = "-2*pi/Om"\n', "sweep.poincare.period: '-2*pi/Om' = "),
        ('period = "2*pi/Omega"\n', "sweep.poincare.period"),
        ('period = "2*pi/Om"\nphase = "zero"\n', "sweep.poincare.phase: must be a finite"),
        ('period = "2*pi/Om"\ndiscard = -1\n', "sweep.poincare.discard: must be a whole"),
        ('period = "2*pi/Om"\ndiscard = 1.5\n', "sweep.poincare.discard: must be a whole"),
        ('period = "2*pi/Om"\ndiscard = 2\n', "sweep.poincare.discard: 2 leaves none of the"),
        (
            'period = "2.1*pi/Om"\n',
            "loads.force_density: 'f0*sin(pi*s/L)*cos(Om*t)' is not periodic with "
            "sweep.poincare.period",
        ),
        (
            'period = "2*pi/Om"\ncontinuation = "parameters.D"\n',
            "sweep.poincare.continuation: must be one of the varied keys",
        ),
        ('period = "2*pi/Om"\ndirection = "up"\n', "sweep.poincare.direction: needs"),
        (
            'period = "2*pi/Om"\ncontinuation = "parameters.f0"\ndirection = "sideways"\n',
            "sweep.poincare.direction: must be one of",
        ),
    ],
)
def test_a_bad_poincare_key_is_refused_in_one_line_naming_it(tmp_path, poincare, message):
    """Each malformed [sweep.poincare] is a SceneError whose one line names the key, before
    any member runs (the period is evaluated at every member's constants: an unknown name or
    a negative value is refused with the sweep, and so is a period that the load cos(Ωt)
    does not repeat after, 2.1π/Ω, and a discard of 2 points when a member's one period
    holds at most 2, t = 0 and T)."""
    path = section_sweep(tmp_path, (0.20,), 1, 0)
    text = path.read_text(encoding="utf-8").split("[sweep.poincare]")[0]
    path.write_text(text + "[sweep.poincare]\n" + poincare, encoding="utf-8")
    with pytest.raises(SceneError) as info:
        api.load_sweep(path)
    assert message in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_a_bad_poincare_key_on_the_command_line_exits_2_in_one_line(tmp_path):
    """``cosserat-fem sweep`` of a sweep whose [sweep.poincare] gives a continuation beside
    [sweep.response]'s: exit 2, one line naming the key, no member run (no --out folder)."""
    path = section_sweep(tmp_path, (0.20, 0.28), 1, 0)
    path.write_text(
        path.read_text(encoding="utf-8")
        + '[sweep.response]\nperiod = "2*pi/Om"\ncontinuation = "parameters.f0"\n',
        encoding="utf-8",
    )
    out = tmp_path / "out"
    proc = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)])
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "sweep.poincare.continuation: the chains are sweep.response" in proc.stderr
    assert not out.exists()


def test_the_example_route_sweep_is_one_chain_up_in_gamma():
    """scenes/sweeps/buckled_beam_route.toml: 41 members, γ = f0 / (ρA a_s k) from 0.20 to
    0.40 by 0.005 (to round-off), one chain in increasing f0, the section every forcing period
    2π/Om (the scene's Om) with 20 points of each member left out."""
    spec = api.load_sweep(ROOT / "scenes" / "sweeps" / "buckled_beam_route.toml")
    gammas = [m.values["parameters.f0"] / F_PER_GAMMA for m in spec.members]
    assert np.allclose(gammas, 0.20 + 0.005 * np.arange(41), rtol=0, atol=1e-12)
    assert spec.chains == (tuple(range(41)),) and spec.continuation == "parameters.f0"
    assert spec.poincare is not None and spec.poincare.discard == 20
    assert spec.section_period(spec.members[0]) == pytest.approx(T, rel=1e-15)


def reduction_points(gamma: float) -> np.ndarray:
    """The one-mode reduction's section points x/a_s of its right-well attractor at γ
    (δ = 0.3, ω = 1.2): the period-1 orbit at 0.20 and 0.25, the period-2 orbit's two points
    at 0.28 (cosserat_fem/reference/buckled_beam.py, Newton on the flow; its multipliers
    checked ≤ 0.46 in modulus: the orbit attracts)."""
    from cosserat_fem.reference.buckled_beam import duffing_flow, duffing_orbit

    guess, period = {0.20: ((0.57, 0.41), 1), 0.25: ((0.43, 0.34), 1)}.get(
        gamma, ((0.246, 0.237), 2)
    )
    point, multipliers = duffing_orbit(gamma, guess, period)
    assert np.abs(multipliers).max() <= 0.46, (gamma, multipliers)
    orbit = [point[0]]
    if period == 2:
        orbit.append(duffing_flow(gamma, 0.3, 1.2, point, 1, 1e-12)[0][0])
    return np.sort(orbit)


def distinct(x: np.ndarray, gap: float = 1e-2) -> int:
    """The number of clusters of the sorted values ``x`` split where they jump by > ``gap``."""
    return 1 + int((np.diff(np.sort(x)) > gap).sum())


@pytest.mark.long
@pytest.mark.mpi
def test_the_buckled_beams_diagram_has_the_reductions_periods_and_points(tmp_path):
    """scenes/buckled_beam.toml (8 cubic elements, SDIRK3 at 100 steps a period) at γ = 0.20,
    0.25, 0.28 in two chains (up and down in f0, ``direction = "both"``: six members), 30
    periods a member, the first 15 points left out. The reduction's attractor there: period 1
    at 0.20 and 0.25, period 2 at 0.28 (its first doubling at γ = 0.26558); its section
    converges from the chains' starts to within 1e-5 by the 15th period (multipliers ≤ 0.46 a
    period; the reduction chained alike, checked when this test was written: 2e-6).

    Each member's points fall in as many clusters (gaps > 1e-2 a_s; the period-2 points are
    0.34 a_s apart) as the reduction's period, repeat with it (|x_{j+n} − x_j| ≤ 1e-3 a_s),
    and lie within 2e-3 a_s of the reduction's points, each of which they hit: docs/chaos.md
    (tests/test_chaos.py) sums what separates the rod from its one-mode reduction, the
    geometrically exact terms (π a_s/ℓ)² = 3.3e-4, shear and rotary inertia 8.2e-5, axial
    inertia 1.2e-4, SDIRK3's (2π/100)³ = 2.5e-4, carried to the orbit by 1/|1 − μ| ≤ 1.3,
    doubled: 2e-3 (measured at γ = 0.20, 0.25, 0.28: 3.4e-4, 1.9e-4, 4.8e-4 up, 3.3e-4,
    1.9e-4, 5.2e-4 down).

    ``mpirun -n 2`` (two groups of one rank, a chain each) gives the same bifurcation.csv
    (the same rows, members, points, periods) with every coordinate within 1e-7 a_s: each
    step's state is Newton's to stol = 1e-10 of its size, the section a state on an orbit
    that contracts perturbations by |μ| ≤ 0.46 a period, so a difference of roundings in
    100 steps a period stays below 100 · 1e-10 / (1 − 0.46) ≈ 1.9e-8 of the state's size,
    ≤ 1.5 a_s: 2.8e-8 a_s, held with a margin of 3.5 (measured: 0 with groups of one rank,
    1.7e-11 a_s with one group of two ranks, whose run took 4.5 min: not tested). The test
    takes 94-135 s on the 2 shared cores, serial and mpirun together."""
    gammas = (0.20, 0.25, 0.28)
    periods = {0.20: 1, 0.25: 1, 0.28: 2}
    path = section_sweep(
        tmp_path,
        gammas,
        periods=30,
        discard=15,
        coarse=False,
        poincare='continuation = "parameters.f0"\ndirection = "both"\n',
    )
    tables = {}
    for ranks in (1, 2):
        out = tmp_path / f"n{ranks}"
        proc = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(out)], ranks)
        assert proc.returncode == 0, proc.stderr
        tables[ranks] = points_of(out)
    serial = tables[1]
    for member in range(6):
        mine = [r for r in serial if r["member"] == str(member)]
        assert len(mine) == 31 - 15  # sections j = 0 ... 30 (a chain's start: 0 or T, ± ε)
        gamma = json.loads(mine[0]["parameters.f0"]) / F_PER_GAMMA
        gamma = min(gammas, key=lambda g: abs(g - gamma))
        x = np.array([float(r["x"]) for r in mine]) / A_S
        n = periods[gamma]
        assert distinct(x) == n, (member, gamma, x)
        assert np.abs(x[n:] - x[:-n]).max() <= 1e-3, (member, gamma, x)
        orbit = reduction_points(gamma)
        nearest = np.abs(x[:, None] - orbit[None, :])
        assert nearest.min(axis=1).max() <= 2e-3, (member, gamma, x, orbit)
        assert set(np.argmin(nearest, axis=1)) == set(range(n))
    labels = [*(k for k in serial[0] if k not in SECTION_NAMES), "period"]
    assert [[r[k] for k in labels] for r in tables[2]] == [[r[k] for k in labels] for r in serial]
    coordinates = ("x", "y", "z")
    a = np.array([[float(r[c]) for c in coordinates] for r in serial])
    b = np.array([[float(r[c]) for c in coordinates] for r in tables[2]])
    assert np.abs(a - b).max() <= 1e-7 * A_S


def test_a_failed_member_has_no_points_and_a_restart_gathers_the_same_diagram(tmp_path):
    """Two members from the scene's initial state (no continuation): γ = 0.20, and f0 =
    1e10 N/m with no halving allowed, whose Newton fails in its first step ("failed": no
    section). bifurcation.csv holds member 0's points alone (3 periods: sections j = 0 ... 3,
    the first left out); the sweep started again with the same --out runs nothing and writes
    the same bifurcation.csv, byte for byte (gathered from the same poincare.csv files)."""
    path = section_sweep(tmp_path, (0.20,), 3, 1, poincare="")
    text = path.read_text(encoding="utf-8")
    head, rest = text.split("[sweep.vary]\n")
    cases = (
        f'[[sweep.case]]\n"parameters.f0" = {0.20 * F_PER_GAMMA!r}\n'
        '[[sweep.case]]\n"parameters.f0" = 1e10\n"time.max_halvings" = 0\n'
    )
    path.write_text(head + cases + "[sweep.poincare]" + rest.split("[sweep.poincare]")[1])
    out = tmp_path / "out"
    spec = api.load_sweep(path)
    first = api.sweep(spec, out)
    assert [r["status"] for r in read_table(first.table)] == ["completed", "failed"]
    rows = points_of(out)
    assert {r["member"] for r in rows} == {"0"} and len(rows) == 3
    before = (out / BIFURCATION).read_bytes()
    again = api.sweep(spec, out)
    assert again.ran == 0 and (out / BIFURCATION).read_bytes() == before
