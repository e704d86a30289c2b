"""Continuation of the rod's equilibria (cosserat_fem/analysis/paths.py on the engine of
cosserat_fem/nls/arclength.py): the post-buckled elastica and the roll-up.

**The post-buckled column.** scenes/rollup.toml without its moment, under the dead axial end
load −P_E e3, P_E = π² EI/(4ℓ²) (clamped-free), so λ = P/P_E. The straight rod solves the
static equations at every λ (the primary branch: axial shortening only); its R_u loses
definiteness where the first buckling mode appears, at P (1 + aP) = P_E, a = 1/κGA − 1/EA
(tests/test_stability.py derives it): λ_cr = (√(1 + 4aP_E) − 1)/(2aP_E) = 0.999287356.
There det R_u changes sign while λ keeps growing along the branch: a (pitchfork) bifurcation.
On the buckled branch the free end turns by α = ψ(ℓ) and

    EI ψ'' + P sin ψ (1 + aP cos ψ) = 0,   ψ(0) = 0, ψ'(ℓ) = 0

(cosserat_fem/reference/elastica.py, buckled_column_load, which solves it by quadrature to
1e-14): the rod's exact load at each α. The elastica's closed form P/P_E = (2K(k)/π)²,
k = sin(α/2), is its a = 0 limit. Between the two: the term aP cos ψ changes the effective
load by a relative amount between −aP and aP (cos ψ ∈ [−1, 1]), so the two differ by at most
aP = aP_E λ relative, aP_E = 7.14e-4 for this section (measured: −6.7e-4 at the onset, where
it is −aP_E exactly, +2.6e-4 at α = 120°).

**Discretisation.** ψ is approximated by quartic elements; the load at a given tip angle is a
ratio of energies, whose error falls as h^(2k) = h^8: measured 4.1e-7 relative (worst over
the branch, to its last point at α = 128°) on 8 P4 elements, 1.7e-9 on 16 (ratio 240 ≈ 2^8);
the tests assert 1e-6 and 5e-9. The bifurcation's λ is an eigenvalue's zero, converging alike
(measured 3e-11 from λ_cr on 8 elements), and located by the engine to 1e-9 in arclength
(dλ/ds ≈ 1 on the primary branch): 2e-9 is asserted.
"""

from __future__ import annotations

import json
import math
import shutil
import time

import numpy as np
import pytest
from conftest import ROOT, run_command
from scipy.optimize import brentq
from scipy.special import ellipk, jv

import cosserat_fem as cf
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.common.errors import SceneError
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.reference.elastica import buckled_column_load

ROLLUP = ROOT / "scenes" / "rollup.toml"


def column(elements: int):
    """(scene, EI, EA, κGA, ℓ, P_E) of the clamped-free column under −P_E e3."""
    scene0 = cf.load(ROLLUP, {"loads.end": cf.UNSET})
    rod = scene0.rod_constants()
    section = rod.section
    EI, L = rod.young_modulus * section.c22, rod.length
    EA = rod.young_modulus * section.area
    kGA = section.shear_coefficient * rod.shear_modulus * section.area
    P_E = math.pi**2 * EI / (4 * L**2)
    overrides = {
        "loads.end": cf.UNSET,
        "loads.end.force": [0, 0, -P_E],
        "discretisation.elements": elements,
        "discretisation.degree": 4,
    }
    return cf.load(ROLLUP, overrides), EI, EA, kGA, L, P_E


def buckled(elements: int):
    scene, EI, EA, kGA, L, P_E = column(elements)
    result = cf.continuation(
        scene,
        -0.5,
        2.5,
        step=0.02,
        max_step=0.25,
        stop=lambda q: "turned" if abs(q.tip[4]) > math.radians(125) else None,
    )
    return result, EI, EA, kGA, L, P_E


def worst_error(branch, EI, EA, kGA, L, P_E) -> float:
    """The largest |λ/λ_rod(α) − 1| over the branch's points beyond the bifurcation."""
    return max(
        abs(q.factor * P_E / buckled_column_load(q.tip[4], L, EI, EA, kGA) - 1)
        for q in branch.points[1:]
    )


def test_reference_is_the_elastica_without_extension():
    """buckled_column_load with EA = κGA = ∞ is the closed form (2K(k)/π)² P_E to 1e-13
    (Gauss–Legendre on an analytic integrand, Brent to 1e-15), and with a > 0 its α → 0
    limit is P(1 + aP) = P_E."""
    for alpha in (0.3, 1.5, 2.1, 2.6):
        k = math.sin(alpha / 2)
        closed = (2 * ellipk(k * k) / math.pi) ** 2 * math.pi**2 / 4
        assert buckled_column_load(alpha, 1.0, 1.0) == pytest.approx(closed, rel=1e-13)
    P = buckled_column_load(1e-7, 1.0, 1.0, EA=50.0, GAk=20.0)
    a = 1 / 20.0 - 1 / 50.0
    assert P * (1 + a * P) == pytest.approx(math.pi**2 / 4, rel=1e-12)


def test_post_buckled_elastica():
    """8 P4 elements (module docstring): the primary branch has one bifurcation, at λ_cr to
    2e-9, and no fold; the switched branch, traced both ways, turns the end to α > 120° and
    α < −120°, mirror images (the same λ at ±α to 1e-9: the two directions solve mirrored
    problems); λ(α) is the rod's exact load to 1e-6, and the elastica's closed form to
    aP_E λ + 1e-6."""
    result, EI, EA, kGA, L, P_E = buckled(8)
    a = 1 / kGA - 1 / EA
    critical = (math.sqrt(1 + 4 * a * P_E) - 1) / (2 * a * P_E)
    up, down, *switched = result.branches
    assert [q.kind for q in up.special] == ["bifurcation"] and down.special == []
    assert abs(up.special[0].factor - critical) < 2e-9
    assert up.points[-1].factor == 2.5 and down.points[-1].factor == -0.5
    assert len(switched) == 2
    ends = sorted(b.points[-1].tip[4] for b in switched)
    assert ends[0] < -math.radians(120) and ends[1] > math.radians(120)
    for branch in switched:
        assert branch.reason == "turned" and branch.special == []
        assert worst_error(branch, EI, EA, kGA, L, P_E) < 1e-6
        for q in branch.points[1:]:
            k = math.sin(abs(q.tip[4]) / 2)
            closed = (2 * ellipk(k * k) / math.pi) ** 2
            assert abs(q.factor / closed - 1) < a * P_E * q.factor + 1e-6
    one, other = ([q.factor for q in b.points] for b in switched)
    assert np.allclose(one, other, rtol=0, atol=1e-9)


@pytest.mark.long
def test_post_buckled_elastica_converges():
    """16 P4 elements: the branch's worst error against the rod's exact load falls below 5e-9
    (h^8 from 8 elements' 4.1e-7: 1.7e-9 measured)."""
    result, *stiffness = buckled(16)
    for branch in result.branches[2:]:
        assert worst_error(branch, *stiffness) < 5e-9


def rollup_tip(scene, tip) -> tuple[float, float]:
    """(gap |r(ℓ) − r(0)|/ℓ, ψ(ℓ)/(4π) − 1) of a two-turn roll-up's tip."""
    ell = scene.rod.length
    return math.hypot(tip[0], tip[1], ell + tip[2]) / ell, tip[4] / (4 * math.pi) - 1


def test_rollup_two_turns_by_continuation():
    """scenes/rollup.toml rolled into two full circles (40 P4 elements, as
    tests/test_large_deflection.py): the continuation's last point is at λ = 1 exactly and
    its tip is load stepping's to 1e-12 (both the same discrete equilibrium, each Newton
    converged below 1e-13 in the update), the gap 7.0e-10 ℓ < 1e-8 ℓ and the angle 4π to 1e-8.

    The steps: the roll-up's angle ψ = 4πλ s/ℓ is linear in λ, so the tangent predicts it
    exactly, and the refinement solves the positions for it (paths.RodPath.refine_prediction:
    the force balance is linear in them): each corrector converges in one or two iterations,
    and each step grows by max_grow = 4. From the first step, 0.1 in arclength, to λ = 1,
    about 3.3 of arclength, that is 3-4 steps and the one back to the bound: at most 6 steps
    are asserted, none rejected, and fewer than a fifth of load stepping's Newton iterations
    (32 steps, 254 iterations) in Jacobian assemblies (measured: 4 steps, the last the point
    at the bound, and 20).
    Without the refinement, Newton's basin in this stiff rod holds about 0.06 of λ per step
    and continuation takes 17 steps (docs/continuation.md)."""
    overrides = {"parameters.turns": 2, "discretisation.elements": 40}
    scene = cf.load(ROLLUP, overrides)
    result = cf.continuation(scene, 0.0, 1.0, step=0.1, max_step=8.0, directions=(1,))
    (branch,) = result.branches
    end = branch.points[-1]
    assert end.factor == 1.0 and branch.reason == "p reached 1"
    gap, angle = rollup_tip(scene, end.tip)
    stepping = static_path(
        cf.load(ROLLUP, {**overrides, "static.load_steps": 32}), write_outputs=False
    )
    gap_ls, angle_ls = rollup_tip(scene, PointProbe(stepping.model, 1.0).values())
    assert gap < 1e-8 and abs(angle) < 1e-8
    assert abs(gap - gap_ls) < 1e-12 and abs(angle - angle_ls) < 1e-12
    assert branch.steps <= 6 and branch.rejected == 0
    assert result.jacobian_assemblies < sum(stepping.iterations) / 5


def test_bad_input_names_the_option(tmp_path):
    """One SceneError naming the option (a probe outside [0, ℓ] too); a scene in the y-z
    plane (θ alone, no chart) refused naming discretisation.planar."""
    scene = cf.load(ROLLUP)
    for kwargs, name in (
        ({"step": -1.0}, "step"),
        ({"max_points": 1}, "max_points"),
        ({"directions": (2,)}, "directions"),
        ({"switch": -1}, "switch"),
        ({"probe": "end"}, "probe"),
        ({"probe": 1.5}, "probe"),  # beyond the rod's length, 1 m
    ):
        with pytest.raises(SceneError, match=f"^{name}"):
            cf.continuation(scene, **kwargs)
    with pytest.raises(SceneError, match="high"):
        cf.continuation(scene, 1.0, 0.5)
    in_yz = cf.load(ROLLUP, {"loads.end.torque": [1.0, 0, 0]})  # bent about e1: θ alone
    with pytest.raises(SceneError, match="^discretisation.planar"):
        cf.continuation(in_yz)


def test_branch_file(tmp_path):
    """branches.csv: the header, one row per point of each branch (special points too), the
    last row of the primary branch at λ = high."""
    scene = cf.load(ROLLUP, {"discretisation.elements": 4, "parameters.turns": 0.25})
    result = cf.continuation(scene, 0.0, 1.0, step=0.2, directions=(1,), out=tmp_path)
    lines = (tmp_path / "branches.csv").read_text().splitlines()
    assert lines[0].split(",")[:3] == ["branch", "load_factor", "x"]
    assert len(lines) == 1 + len(result.branches[0].points)
    assert float(lines[-1].split(",")[1]) == 1.0


COLUMN_OPTIONS = [
    "--unset",
    "loads.end",
    "--set",
    "discretisation.elements=8",
    "--set",
    'loads.end.force=[0,0,"-pi**2*EI/(4*L**2)"]',
]


def read_branches(path) -> list[dict]:
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    return [dict(zip(header, line.split(","), strict=True)) for line in lines[1:]]


@pytest.mark.long
def test_continue_command_serial_and_mpi(tmp_path):
    """``cosserat-fem continue`` on the column (8 P4) over λ ∈ [0, 1.5], 1 and 2 ranks:
    branches.csv's bifurcation at λ_cr on both to 2e-9 (the locating tolerance; MUMPS under
    MPI orders and rounds differently, 1e-13, far below it), and the switched branches'
    ends at λ = 1.5 (branches 1 and 2: the primary one is traced one way only, λ ≥ 0)
    turned by the same |ψ| to 1e-9 (one discrete equilibrium, each Newton
    converged below 1e-10 in the update; the null vector's sign, which picks the branch
    traced first, may differ). Bad input: exit 2, one line naming the option."""
    ends, critical = [], []
    for ranks in (1, 2):
        out = tmp_path / f"r{ranks}"
        options = "--range 0 1.5 --step 0.02 --max-step 0.25 --out".split()
        command = ["-m", "cosserat_fem.cli", "continue", str(ROLLUP), *COLUMN_OPTIONS]
        proc = run_command([*command, *options, str(out)], ranks)
        assert proc.returncode == 0, proc.stderr
        rows = read_branches(out / "branches.csv")
        (bif,) = [r for r in rows if r["point"] == "bifurcation" and r["branch"] == "0"]
        critical.append(float(bif["load_factor"]))
        ends.append(
            sorted(
                abs(float(r["psi"]))
                for r in rows
                if r["branch"] in ("1", "2") and r["point"] == "end"
            )
        )
        assert "bifurcation point at load factor 0.99928735" in proc.stdout
    assert abs(critical[0] - 0.999287356) < 2e-9 and abs(critical[0] - critical[1]) < 2e-9
    assert len(ends[0]) == 2 and np.allclose(ends[0], ends[1], rtol=0, atol=1e-9)
    proc = run_command(
        ["-m", "cosserat_fem.cli", "continue", str(ROLLUP), "--step", "-1", "--out", str(tmp_path)]
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "--step" in proc.stderr


def test_continue_command_bad_option(tmp_path):
    """A bad option: exit 2, one line on stderr naming it (no solve is started)."""
    proc = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "continue",
            str(ROLLUP),
            "--max-points",
            "1",
            "--out",
            str(tmp_path),
        ]
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "--max-points" in proc.stderr


@pytest.mark.parametrize(
    "scene, overrides, message",
    [
        (ROLLUP, ["loads.end.torque=[1.0, 0, 0]"], "discretisation.planar: continuation does"),
        (ROOT / "scenes" / "free_ring.toml", [], "reference.closed: a closed rod has modes"),
        (ROLLUP, ['supports.start="free"'], "supports: a static equilibrium needs the rod"),
    ],
)
def test_a_refused_continuation_leaves_no_folder(tmp_path, scene, overrides, message):
    """A scene that continuation cannot follow (the roll-up bent about e1, so solved in the
    y-z plane by discretisation.planar = "auto"; a closed ring; the rod held at neither end)
    is refused from the scene alone: exit 2, one line naming the key, and the --out folder
    not made (before: made, locked, then refused when the path's model was built)."""
    out = tmp_path / "out"
    sets = [a for o in overrides for a in ("--set", o)]
    proc = run_command(["-m", "cosserat_fem.cli", "continue", str(scene), *sets, "--out", str(out)])
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert message in line and "Traceback" not in proc.stderr
    assert not out.exists()


def test_a_finished_branch_is_not_restarted(tmp_path):
    """The roll-up (scenes/rollup.toml, its 40 P4 elements) traced to λ = 1 ends "p reached
    1"; ``continue --restart`` of it: exit 2, one line naming --restart and "already ended",
    and branches.csv byte for byte as it was (before: a restart stepped past the bound again
    and appended a second row at λ = 1). ``--branch`` without ``--restart``: exit 2, one line
    naming --branch (before: ignored); --probe beyond the rod (5 m of 1 m): exit 2, and no
    --out folder made (before: made, then refused)."""
    out = tmp_path / "rollup"
    command = ["-m", "cosserat_fem.cli", "continue"]
    proc = run_command(
        [*command, str(ROLLUP), "--step", "0.1", "--max-step", "8", "--out", str(out)]
    )
    assert proc.returncode == 0 and "p reached 1" in proc.stdout, proc.stderr
    table = (out / "branches.csv").read_bytes()
    again = run_command([*command, "--restart", str(out)])
    assert again.returncode == 2 and again.stderr.strip().count("\n") == 0, again.stderr
    assert (
        "--restart: branch 0 in " in again.stderr and "already ended: p reached 1" in again.stderr
    )
    assert (out / "branches.csv").read_bytes() == table
    stray = run_command([*command, str(ROLLUP), "--branch", "0", "--out", str(tmp_path / "b")])
    assert stray.returncode == 2 and stray.stderr.strip().count("\n") == 0, stray.stderr
    assert "--branch" in stray.stderr and not (tmp_path / "b").exists()
    cut = tmp_path / "cut"
    three = ["--step", "0.1", "--max-step", "8", "--max-points", "3", "--out", str(cut)]
    assert run_command([*command, str(ROLLUP), *three]).returncode == 0
    table = (cut / "branches.csv").read_bytes()
    idle = run_command([*command, "--restart", str(cut)])  # max_points 3 reached: none to add
    assert idle.returncode == 2 and idle.stderr.strip().count("\n") == 0, idle.stderr
    assert "--max-points: branch 0 in " in idle.stderr and "has 3 points" in idle.stderr
    assert (cut / "branches.csv").read_bytes() == table
    far = run_command([*command, str(ROLLUP), "--probe", "5", "--out", str(tmp_path / "p")])
    assert far.returncode == 2 and "probe (--probe): must lie in [0, 1.0]" in far.stderr
    assert not (tmp_path / "p").exists()  # refused before the folder is made


def test_branch_that_cannot_go_on_is_written(tmp_path):
    """A continuation that cannot go on ends with its branch written up to its last point and
    the reason (issue 27 item 5). The roll-up to two turns (4 elements) with the corrector
    allowed 2 Newton iterations: the quadratic convergence from the predictor's error, which
    grows with the step and the curvature of the path, needs more as the rod rolls up, so the
    step halves below min_step = 0.05 and the branch stops there (measured at λ = 0.29). The
    files then hold exactly the engine's points: branches.csv one row per point (the last
    one's λ that of the last point, repr round-trips a float), branches.json the reason, and
    branch_0.xdmf one frame per point, its times the indices 0, 1, ..., its free end's ψ the
    probe's (the same interpolant at the same node, evaluated two ways: 1e-12 rad of
    round-off). The progress callback is called once per accepted point (the start is not
    one) with the branch's count of points and λ."""
    from xdmf_files import read_xdmf

    scene = cf.load(
        ROLLUP,
        {"discretisation.elements": 4, "parameters.turns": 2, "solver.max_iterations": 2},
    )
    calls = []
    result = cf.continuation(
        scene,
        0.0,
        1.0,
        step=0.2,
        min_step=0.05,
        directions=(1,),
        out=tmp_path,
        progress=lambda *args: calls.append(args),
    )
    (branch,) = result.branches
    assert branch.reason.startswith("step below min_step 0.05")
    assert len(branch.points) >= 3 and branch.points[-1].factor < 1.0
    rows = read_branches(tmp_path / "branches.csv")
    assert [float(r["load_factor"]) for r in rows] == [q.factor for q in branch.points]
    (entry,) = json.loads((tmp_path / "branches.json").read_text())
    assert entry["reason"] == branch.reason and entry["points"] == len(branch.points)
    times, angles = read_xdmf(tmp_path / "branch_0.xdmf")["angles"]
    assert list(times) == list(range(len(branch.points)))
    psi = np.array([q.tip[4] for q in branch.points])
    assert np.allclose(angles[:, 1], psi, rtol=0, atol=1e-12)
    assert len(calls) == len(branch.points) - 1
    assert calls[-1] == (0, len(branch.points), branch.points[-1].factor)


def _branches_csv(path, stability: bool) -> None:
    """A branches.csv of two branches by hand (write_branches' columns), the primary with its
    det R_u changing sign and a located bifurcation at λ = 1, norm = 0.1."""
    from cosserat_fem.analysis.paths import BRANCH_COLUMNS

    header = [*BRANCH_COLUMNS, *(["stability"] if stability else [])]
    table = [
        (0, 0.0, 0.0, 1, "start", "stable"),
        (0, 0.5, 0.05, 1, "regular", "stable"),
        (0, 1.5, 0.15, -1, "end", "unstable"),
        (0, 1.0, 0.1, 1, "bifurcation", ""),
        (1, 1.0, 0.1, 1, "start", "stable"),
        (1, 1.2, 0.4, 1, "end", "stable"),
    ]
    lines = [",".join(header)]
    for b, lam, norm, det, kind, stab in table:
        row = dict.fromkeys(header, "0.0")
        row.update(branch=str(b), load_factor=repr(lam), norm=repr(norm), det_sign=repr(det))
        row.update(point=kind, **({"stability": stab} if stability else {}))
        lines.append(",".join(row[c] for c in header))
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("stability", [False, True])
def test_bifurcation_diagram(tmp_path, monkeypatch, stability):
    """``plot`` on a continuation's folder: bifurcation.png with λ against the column, each
    branch's points joined in order (segment by segment, each styled by its end point: the
    primary's last segment, det R_u < 0 or "unstable", dashed, the others solid), the
    bifurcation point marked at (0.1, 1.0) and not joined into its branch; the legend names
    the stability when branches.csv has the column, else the sign of det R_u. A column that
    is not one: one line naming --column, exit 2."""
    import cosserat_fem.plot as plot

    _branches_csv(tmp_path / "branches.csv", stability)
    figures = []
    save = plot._save
    monkeypatch.setattr(
        plot,
        "_save",
        lambda fig, path, *a: (figures.append(plot.drawn_lines(fig)), save(fig, path))[1],
    )
    (path,) = plot.plot_run(tmp_path, column="norm")
    assert path == tmp_path / "bifurcation.png" and path.stat().st_size > 0
    (lines,) = figures
    xy = [lines[f"axes0/line{j}"] for j in range(4)]
    assert np.array_equal(xy[0], [[0.0, 0.05], [0.0, 0.5]])  # branch 0, first segment
    assert np.array_equal(xy[2], [[0.1, 0.4], [1.0, 1.2]])  # branch 1
    assert np.array_equal(xy[3], [[0.1], [1.0]])  # the bifurcation point
    assert str(lines["axes0/line3/label"]) == "bifurcation point"
    labels = {str(lines[f"axes0/line{j}/label"]) for j in range(3)}
    assert labels >= ({"stable", "unstable"} if stability else {"det R_u > 0", "det R_u < 0"})
    proc = run_command(["-m", "cosserat_fem.cli", "plot", str(tmp_path), "--column", "speed"])
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "--column" in proc.stderr


def test_restart_equals_the_whole_branch(tmp_path):
    """A continuation cut in two equals the whole one, bit for bit (issue 27 item 5). The
    roll-up (4 elements, one turn), λ growing, no switch, to λ = 1: once whole, once cut
    by max_points = 5 and then restarted from its folder with max_points = 40. The restart saves the
    branch's last three points (u, t_u exactly, as float64 npz; λ, dλ/ds, the determinant by
    repr in JSON), the next step and the count of points: the resumed trace then performs
    the same floating-point operations on the same arrays (the predictor, the refinement, the
    corrector's assemblies and LU factorisations of a fresh problem are functions of (u, λ)
    alone, serially deterministic), so the points are equal exactly, and so are the files:
    branches.csv byte for byte (no special point on this path, so the rows are in the same
    order), branch_0.xdmf's times and free-end values. Also: restart of a folder without a
    continuation is one SceneError naming --restart."""
    from xdmf_files import read_xdmf

    scene = cf.load(ROLLUP, {"discretisation.elements": 4, "parameters.turns": 1})
    options = dict(step=0.05, max_step=0.3, switch=0, directions=(1,))
    whole = cf.continuation(scene, 0.0, 1.0, max_points=40, out=tmp_path / "whole", **options)
    cut = tmp_path / "cut"
    first = cf.continuation(scene, 0.0, 1.0, max_points=5, out=cut, **options)
    assert first.branches[0].reason == "5 points (max_points)"
    second = cf.continuation(None, max_points=40, restart=cut)
    (w,) = whole.branches
    (b,) = second.branches
    assert w.reason == b.reason == "p reached 1" and not w.special and len(w.points) > 6
    assert [q.factor for q in w.points[2:]] == [q.factor for q in b.points]
    assert all(np.array_equal(p.tip, q.tip) for p, q in zip(w.points[2:], b.points, strict=True))
    assert (cut / "branches.csv").read_text() == (tmp_path / "whole" / "branches.csv").read_text()
    for array in ("displacement", "angles"):
        times, values = read_xdmf(cut / "branch_0.xdmf")[array]
        times_w, values_w = read_xdmf(tmp_path / "whole" / "branch_0.xdmf")[array]
        assert list(times) == list(times_w) == list(range(len(w.points)))
        assert np.array_equal(values, values_w)
    (tmp_path / "empty").mkdir()
    with pytest.raises(SceneError, match="^--restart: .* holds no continuation"):
        cf.continuation(None, restart=tmp_path / "empty")


def test_continue_command_restart(tmp_path):
    """``continue --restart DIR``: the branch cut at --max-points 5 goes on to λ = 1 (its last
    row at the bound, the reason printed), with the folder's scene and settings; with a SCENE
    or --set beside it, or with neither SCENE nor --restart: exit 2, one line naming the
    option."""
    out = tmp_path / "c"
    base = ["-m", "cosserat_fem.cli", "continue"]
    small = ["--set", "discretisation.elements=4", "--set", "parameters.turns=1"]
    first = [*base, str(ROLLUP), *small, "--max-points", "5", "--switch", "0", "--out", str(out)]
    proc = run_command(first)
    assert proc.returncode == 0, proc.stderr
    assert "5 points (max_points)" in proc.stdout
    proc = run_command([*base, "--restart", str(out), "--max-points", "40"])
    assert proc.returncode == 0, proc.stderr
    assert "p reached 1" in proc.stdout
    assert read_branches(out / "branches.csv")[-1]["load_factor"] == "1.0"
    for bad, name in (
        ([*base, str(ROLLUP), "--restart", str(out)], "--restart"),
        ([*base, "--restart", str(out), "--set", "parameters.turns=2"], "--restart"),
        (base, "SCENE"),
    ):
        proc = run_command(bad)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.strip().count("\n") == 0 and name in proc.stderr


class Killed(Exception):
    """A continuation stopped from outside in the middle of a branch."""


def kill_after(points: int):
    """A ``stop`` that raises :class:`Killed` at its ``points``-th call (the branch's point
    of that index: the first is after the start)."""
    calls = []

    def stop(q):
        calls.append(q.factor)
        if len(calls) == points:
            raise Killed(f"killed at load factor {q.factor!r}")
        return None

    return stop


def test_killed_continuation_restarts_from_its_last_point(tmp_path):
    """A continuation killed mid-branch (its ``stop`` raises at the branch's 4th point, before
    the branch ends and any of branches.csv, branches.json, branch_0.xdmf is written)
    restarts from the last point it reached: the restart data are saved after each point
    (path_restart.py). The roll-up (4 elements, one turn) to λ = 1, reported at the probe
    s = ℓ/2 (--probe) instead of the free end: the restarted branch's points are the whole
    run's from its index 2 on (the three saved, 2-4, then the continued ones), equal exactly
    (the same floating-point operations on the same arrays: the argument of
    test_restart_equals_the_whole_branch), their ``tip`` the mid-span point's (the probe
    survives the restart; the free end's differs by O(ℓ)). The killed run's branches.csv
    holds the branch's rows as they were accepted, the whole run's first 5 (the start and
    the 4 told: before, no file, and the restart began it at the saved points, rows 0-1
    lost), and restart.json names them; the restart appends the rest, so the file is the
    whole run's byte for byte (the same rows computed in the same order); branch_0.xdmf
    has the killed run's frames 0-4 (written as the points came; before, none, and the
    restart wrote them from the saved points on, times 2, 3, ...), then all of the whole
    run's, times 0, 1, ...; restart.json's saved end stays one the arrays fit (the
    slots)."""
    from xdmf_files import read_xdmf

    scene = cf.load(ROLLUP, {"discretisation.elements": 4, "parameters.turns": 1})
    half = scene.rod.length / 2
    options = dict(step=0.05, max_step=0.3, switch=0, directions=(1,), probe=half)
    whole = cf.continuation(scene, 0.0, 1.0, max_points=40, out=tmp_path / "whole", **options)
    cut = tmp_path / "cut"
    with pytest.raises(Killed):
        cf.continuation(scene, 0.0, 1.0, max_points=40, out=cut, stop=kill_after(4), **options)
    rows_w = (tmp_path / "whole" / "branches.csv").read_text().splitlines()
    assert (cut / "branches.csv").read_text().splitlines() == rows_w[:6]
    assert list(read_xdmf(cut / "branch_0.xdmf")["displacement"][0]) == list(range(5))
    record = json.loads((cut / "continuation" / "restart.json").read_text())
    assert record["branches"]["0"]["first_index"] == 2 and record["probe"] == half
    assert record["branches"]["0"]["rows"] == 5
    second = cf.continuation(None, restart=cut)
    (w,) = whole.branches
    (b,) = second.branches
    assert w.reason == b.reason == "p reached 1" and len(w.points) > 6
    assert [q.factor for q in w.points[2:]] == [q.factor for q in b.points]
    assert all(np.array_equal(p.tip, q.tip) for p, q in zip(w.points[2:], b.points, strict=True))
    assert (cut / "branches.csv").read_text() == (tmp_path / "whole" / "branches.csv").read_text()
    times, values = read_xdmf(cut / "branch_0.xdmf")["displacement"]
    times_w, values_w = read_xdmf(tmp_path / "whole" / "branch_0.xdmf")["displacement"]
    assert list(times) == list(times_w) == list(range(len(w.points)))
    assert np.array_equal(values, values_w)


def test_a_killed_restart_keeps_its_rows(tmp_path):
    """The roll-up of test_restart_equals_the_whole_branch cut at max_points = 5 (the branch
    ended: its 5 rows), restarted with max_points = 40 and killed at the restart's 3rd
    point: branches.csv holds the 5 rows and the 3 new ones, appended as they came (before:
    none of them, the file was written as a restart ended); restarted again, the file is
    the whole run's byte for byte (the restart cuts it to the rows restart.json names and
    appends the rest; before, the rows between the first part's and the last saved points
    were lost)."""
    scene = cf.load(ROLLUP, {"discretisation.elements": 4, "parameters.turns": 1})
    options = dict(step=0.05, max_step=0.3, switch=0, directions=(1,))
    cf.continuation(scene, 0.0, 1.0, max_points=40, out=tmp_path / "whole", **options)
    rows_w = (tmp_path / "whole" / "branches.csv").read_text().splitlines()
    cut = tmp_path / "cut"
    cf.continuation(scene, 0.0, 1.0, max_points=5, out=cut, **options)
    assert (cut / "branches.csv").read_text().splitlines() == rows_w[:6]
    with pytest.raises(Killed):
        cf.continuation(None, max_points=40, restart=cut, stop=kill_after(3))
    assert (cut / "branches.csv").read_text().splitlines() == rows_w[:9]
    record = json.loads((cut / "continuation" / "restart.json").read_text())
    assert record["branches"]["0"]["rows"] == 8
    (b,) = cf.continuation(None, restart=cut).branches
    assert b.reason == "p reached 1"
    assert (cut / "branches.csv").read_text().splitlines() == rows_w


def pitchfork_column():
    """The column of test_post_buckled_elastica (8 P4 cells under P_E) on [−0.5, 1.5], both
    ways, switched at λ_cr = 0.99929: four branches, the primary to λ = 1.5 (10 points)
    and to −0.5 (in tension, no bifurcation), then the buckled branch both ways (7 points
    each, to λ = 1.5). ((scene, options), the whole run's result and folder are made once
    per test: 2 s.)"""
    overrides = {
        "loads.end": cf.UNSET,
        "discretisation.elements": 8,
        "loads.end.force": [0, 0, "-pi**2*EI/(4*L**2)"],
    }
    scene = cf.load(ROLLUP, overrides)
    return scene, dict(step=0.05, max_step=0.2, directions=(1, -1), max_points=30)


def told_before(result, branch: int) -> int:
    """``stop``'s calls before branch ``branch`` (it is told of every point but each
    branch's start and its end at a bound)."""
    return sum(len(b.points) - 2 for b in result.branches[:branch])


def assert_same_folders(cut, whole) -> None:
    """branches.csv byte for byte, branches.json equal, and every branch's XDMF frames
    (times and values) equal to the whole run's."""
    from xdmf_files import read_xdmf

    assert (cut / "branches.csv").read_text() == (whole / "branches.csv").read_text()
    assert (cut / "branches.json").read_text() == (whole / "branches.json").read_text()
    for i in range(len(json.loads((whole / "branches.json").read_text()))):
        for array in ("displacement", "angles"):
            times, values = read_xdmf(cut / f"branch_{i}.xdmf")[array]
            times_w, values_w = read_xdmf(whole / f"branch_{i}.xdmf")[array]
            assert list(times) == list(times_w)
            assert np.array_equal(values, values_w)


@pytest.fixture(scope="module")
def pitchfork_whole(tmp_path_factory):
    """The whole continuation of :func:`pitchfork_column` in its folder: (result, folder)."""
    scene, options = pitchfork_column()
    folder = tmp_path_factory.mktemp("pitchfork") / "whole"
    result = cf.continuation(scene, -0.5, 1.5, out=folder, **options)
    return result, folder


@pytest.mark.parametrize(
    ("branch", "point"),
    [(0, 4), (2, 3), (3, 2)],
    ids=["primary's first direction", "switch's first direction", "switch's second direction"],
)
def test_a_killed_continuation_traces_the_branches_after_it(
    tmp_path, pitchfork_whole, branch, point
):
    """Issue 27's leftover: a continuation killed mid-branch restarts that branch and then
    traces every branch the whole run traces after it, in its order. The column of
    :func:`pitchfork_column` (4 branches: 10, 5, 7, 7 points; the whole run's) killed at the
    ``point``-th told point of branch ``branch``: in the primary branch's first direction
    (everything after is pending: the primary's second direction and the switch, at a
    bifurcation located before the kill), in the switched branch's first direction (its
    second pending) and in its second. The restart (``continue --restart``'s default, the
    last branch saved) returns the killed branch from its saved points on and the branches
    after it; its λ are the whole run's exactly, and branches.csv is the whole run's byte
    for byte, branches.json equal, every branch's XDMF frames equal (times and values; the
    killed branch's frames were written as its points came, and the restart cuts them back
    to its saved end and appends the rest): the queue saved with each end (the tasks to come and the
    bifurcation points found, their arrays exact in npz, their scalars by repr) makes the
    restart perform the same floating-point operations on the same arrays as the whole run
    (serially deterministic: test_restart_equals_the_whole_branch). Before, the restart
    traced the killed branch alone. ``first_branch`` names the killed branch's index (the
    command line numbers the branches it prints by it). A folder whose restart.json has no
    queue (written before it was saved) keeps that: only the killed branch is traced."""
    whole, whole_folder = pitchfork_whole
    assert [len(b.points) for b in whole.branches] == [10, 5, 7, 7]
    assert [q.kind for q in whole.branches[0].special] == ["bifurcation"]
    scene, options = pitchfork_column()
    cut = tmp_path / "cut"
    with pytest.raises(Killed):
        stop = kill_after(told_before(whole, branch) + point)
        cf.continuation(scene, -0.5, 1.5, out=cut, stop=stop, **options)
    old = tmp_path / "old"
    shutil.copytree(cut, old)
    ends = json.loads((cut / "continuation" / "restart.json").read_text())["branches"]
    assert sorted(map(int, ends)) == list(range(branch + 1))
    first = ends[str(branch)]["first_index"]
    assert first == point - 2  # the start and the told points, the last three kept
    result = cf.continuation(None, restart=cut)
    assert len(result.branches) == 4 - branch and result.first_branch == branch
    assert [q.factor for q in result.branches[0].points] == [
        q.factor for q in whole.branches[branch].points[first:]
    ]
    for b, w in zip(result.branches[1:], whole.branches[branch + 1 :], strict=True):
        assert [q.factor for q in b.points] == [q.factor for q in w.points]
        assert b.origin == w.origin and b.reason == w.reason
    assert_same_folders(cut, whole_folder)
    record = json.loads((old / "continuation" / "restart.json").read_text())
    for end in record["branches"].values():
        end.pop("queue")
    (old / "continuation" / "restart.json").write_text(json.dumps(record))
    assert len(cf.continuation(None, restart=old).branches) == 1


def test_a_continuation_killed_between_two_branches_traces_the_rest(
    tmp_path, pitchfork_whole, monkeypatch
):
    """The column of :func:`pitchfork_column` killed just after the primary branch's second
    direction ended (its files and its final restart data written, before the switch's
    first point: BranchOutputs.end raising once it has saved), then restarted: no branch is
    resumed, the queue's switch (at the bifurcation point located on the first branch,
    read back from branch 0's saved arrays) is traced both ways, and the folder is the
    whole run's (branches.csv byte for byte, branches.json, every XDMF frame)."""
    from cosserat_fem.analysis.branch_outputs import BranchOutputs

    whole, whole_folder = pitchfork_whole
    scene, options = pitchfork_column()
    end = BranchOutputs.end

    def killed_end(self, problem, branch, special_rows=None):
        end(self, problem, branch, special_rows)
        if self.index == 1:
            raise Killed("killed between branches 1 and 2")

    cut = tmp_path / "cut"
    with monkeypatch.context() as patch:
        patch.setattr(BranchOutputs, "end", killed_end)
        with pytest.raises(Killed):
            cf.continuation(scene, -0.5, 1.5, out=cut, **options)
    ends = json.loads((cut / "continuation" / "restart.json").read_text())["branches"]
    assert ends["1"]["reason"] == "p reached -0.5"
    assert [t["kind"] for t in ends["1"]["queue"]["pending"]] == ["switches"]
    assert ends["1"]["queue"]["found"] == [["special", 0, 0]]
    result = cf.continuation(None, restart=cut)
    assert [b.origin for b in result.branches] == [b.origin for b in whole.branches[2:]]
    for b, w in zip(result.branches, whole.branches[2:], strict=True):
        assert [q.factor for q in b.points] == [q.factor for q in w.points]
    assert_same_folders(cut, whole_folder)


def test_a_kill_after_a_point_s_rows_and_frame_is_cut_back(tmp_path, pitchfork_whole, monkeypatch):
    """The column of :func:`pitchfork_column` killed after the 3rd point of branch 2 had its
    row appended to branches.csv and its frame to branch_2.xdmf, before its end was saved
    (BranchOutputs.save raising there): the files hold a row and a frame more than the saved
    end names (4 frames, the end at point 2); the restart cuts both back to it (the XML to
    its frames, the later frame files removed) and appends the rest, so the folder is the
    whole run's (branches.csv byte for byte, branches.json, every XDMF frame, frame i in its
    file i; before the cut, the frame stayed and the restart wrote its file again, a time
    twice in the XML)."""
    from xdmf_files import read_xdmf

    from cosserat_fem.analysis.branch_outputs import BranchOutputs

    whole, whole_folder = pitchfork_whole
    scene, options = pitchfork_column()
    save = BranchOutputs.save

    def killed_save(self, branch, comm, final=False):
        if self.index == 2 and len(branch.points) == 4 and not final:
            raise Killed("killed before the end of point 3 was saved")
        save(self, branch, comm, final)

    cut = tmp_path / "cut"
    with monkeypatch.context() as patch:
        patch.setattr(BranchOutputs, "save", killed_save)
        with pytest.raises(Killed):
            cf.continuation(scene, -0.5, 1.5, out=cut, **options)
    end = json.loads((cut / "continuation" / "restart.json").read_text())["branches"]["2"]
    assert end["first_index"] + len(end["points"]) == 3
    assert list(read_xdmf(cut / "branch_2.xdmf")["displacement"][0]) == [0, 1, 2, 3]
    rows = (cut / "branches.csv").read_text().splitlines()
    assert len(rows) - 1 == end["rows"] + 1
    cf.continuation(None, restart=cut)
    assert_same_folders(cut, whole_folder)


def test_a_killed_restart_traces_the_rest_when_restarted(tmp_path, pitchfork_whole):
    """The column of :func:`pitchfork_column` killed in its first branch (4th point), its
    restart killed in its turn in the switched branch's first direction (3rd point of
    branch 2), restarted again: the folder is the whole run's (branches.csv byte for byte,
    branches.json, every XDMF frame), the second restart's branches the whole run's from
    branch 2 on (its points from the saved ones on)."""
    whole, whole_folder = pitchfork_whole
    scene, options = pitchfork_column()
    cut = tmp_path / "cut"
    with pytest.raises(Killed):
        cf.continuation(scene, -0.5, 1.5, out=cut, stop=kill_after(4), **options)
    first = json.loads((cut / "continuation" / "restart.json").read_text())["branches"]
    assert first["0"]["first_index"] == 2
    told = told_before(whole, 2) - 4  # the restart's, before branch 2
    with pytest.raises(Killed):
        cf.continuation(None, restart=cut, stop=kill_after(told + 3))
    ends = json.loads((cut / "continuation" / "restart.json").read_text())["branches"]
    assert sorted(ends) == ["0", "1", "2"] and ends["2"]["first_index"] == 1
    result = cf.continuation(None, restart=cut)
    assert [len(b.points) for b in result.branches] == [6, 7]
    assert [q.factor for q in result.branches[0].points] == [
        q.factor for q in whole.branches[2].points[1:]
    ]
    assert [q.factor for q in result.branches[1].points] == [
        q.factor for q in whole.branches[3].points
    ]
    assert_same_folders(cut, whole_folder)


MPI_STOP_ERROR = """
import sys
from mpi4py import MPI
import cosserat_fem as cf
rank = MPI.COMM_WORLD.rank
scene = cf.load(sys.argv[1], {"discretisation.elements": 4, "parameters.turns": 1})

def stop(q):
    if rank == 0 and q.factor > 0.2:
        raise ValueError("the stop callback failed on rank 0")
    return None

try:
    cf.continuation(scene, 0.0, 1.0, step=0.05, max_step=0.3, switch=0, directions=(1,), stop=stop)
except ValueError as exc:
    print(f"rank {rank}: {exc}", flush=True)
    sys.exit(3)
print(f"rank {rank}: no error", flush=True)
"""


def test_one_rank_error_in_stop_ends_every_rank():
    """Under ``mpirun -n 2``, a ``stop`` that raises on rank 0 only (past λ = 0.2 of the
    roll-up's path to 1) ends the continuation on both ranks with that error (its class and
    message: common/parallel.agree after each point), no hang (run_command's limit, 120 s
    here against ~10 s for the run)."""
    proc = run_command(["-c", MPI_STOP_ERROR, str(ROLLUP)], ranks=2, timeout=120)
    assert proc.returncode == 3, proc.stderr
    for rank in (0, 1):
        assert f"rank {rank}: the stop callback failed on rank 0" in proc.stdout


MPI_KILLED_RESTART = """
import json, sys
from mpi4py import MPI
import cosserat_fem as cf

class Killed(Exception):
    pass

scene = cf.load(sys.argv[1], {"discretisation.elements": 4, "parameters.turns": 1})
options = dict(step=0.05, max_step=0.3, switch=0, directions=(1,), probe=scene.rod.length / 2)
calls = []

def stop(q):
    calls.append(q.factor)
    if len(calls) == 4:
        raise Killed("killed")
    return None

try:
    cf.continuation(scene, 0.0, 1.0, max_points=40, out=sys.argv[2], stop=stop, **options)
except Killed:
    pass
(b,) = cf.continuation(None, restart=sys.argv[2]).branches
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps([[q.factor, *map(float, q.tip)] for q in b.points]))
"""


def test_killed_restart_under_mpirun_equals_serial(tmp_path):
    """test_killed_continuation_restarts_from_its_last_point under ``mpirun -n 2``: killed at
    the 4th point (every rank's ``stop`` raises there), restarted on 2 ranks; its points equal
    the serial whole run's from index 2 on, λ and the probe's (x, y, z, θ, ψ, φ) to 1e-8
    (ℓ = 1 m: the points are the corrector's to ‖δx‖ ≤ 1e-10, full Newton; the partitions'
    round-off, ~1e-13, is what differs, and the steps taken are the same)."""
    scene = cf.load(ROLLUP, {"discretisation.elements": 4, "parameters.turns": 1})
    options = dict(step=0.05, max_step=0.3, switch=0, directions=(1,))
    whole = cf.continuation(scene, 0.0, 1.0, max_points=40, probe=scene.rod.length / 2, **options)
    proc = run_command(
        ["-c", MPI_KILLED_RESTART, str(ROLLUP), str(tmp_path / "cut")], ranks=2, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    restarted = np.array(json.loads(proc.stdout.strip().splitlines()[-1]))
    expected = np.array([[q.factor, *q.tip] for q in whole.branches[0].points[2:]])
    assert restarted.shape == expected.shape
    assert np.max(np.abs(restarted - expected)) < 1e-8


MPI_KILLED_QUEUE = """
import json, sys
from mpi4py import MPI
import cosserat_fem as cf

class Killed(Exception):
    pass

overrides = {
    "loads.end": cf.UNSET,
    "discretisation.elements": 8,
    "loads.end.force": [0, 0, "-pi**2*EI/(4*L**2)"],
}
scene = cf.load(sys.argv[1], overrides)
options = dict(step=0.05, max_step=0.2, directions=(1, -1), max_points=30)
calls = []

def stop(q):
    calls.append(q.factor)
    if len(calls) == 4:
        raise Killed("killed")
    return None

whole = cf.continuation(scene, -0.5, 1.5, **options)
try:
    cf.continuation(scene, -0.5, 1.5, out=sys.argv[2], stop=stop, **options)
except Killed:
    pass
result = cf.continuation(None, restart=sys.argv[2])
points = [*whole.branches[0].points[2:], *(q for b in whole.branches[1:] for q in b.points)]
rows = [[[q.factor, *map(float, q.tip)] for q in points]]
rows.append([[q.factor, *map(float, q.tip)] for b in result.branches for q in b.points])
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(rows))
"""


@pytest.mark.long
def test_killed_queue_under_mpirun_equals_serial(tmp_path, pitchfork_whole):
    """test_a_killed_continuation_traces_the_branches_after_it under ``mpirun -n 2``: the
    column killed at the 4th point of its first branch, restarted on 2 ranks (each rank
    reads its own arrays of the queue's points: the start, the bifurcation point). The
    restart's points (branch 0 from index 2 on, then branches 1-3 whole) equal those of the
    whole run on 2 ranks, λ and the free end's (x, y, z, θ, ψ, φ) to 1e-8, and the
    primary branches' equal serial's to 1e-8 (the argument of
    test_killed_restart_under_mpirun_equals_serial: the corrector's tolerance 1e-10 with
    full Newton, the partitions' round-off ~1e-13, the same steps taken). The switched
    branches on 2 ranks are not serial's point by point: the null vector's inverse
    iteration (8 solves) starts from each rank's own pseudo-random vector, so its sign and
    its residue of the other modes differ, and so do the first step's direction and the
    steps (measured: λ = 1.013762 against 1.009856 at the first point, the branch mirrored,
    x and ψ of opposite signs); their last points, corrected at λ = 1.5 on the same curve,
    are serial's to 1e-8 up to that sign (x and ψ; the other columns are 0 or even)."""
    whole, _ = pitchfork_whole
    proc = run_command(
        ["-c", MPI_KILLED_QUEUE, str(ROLLUP), str(tmp_path / "cut")], ranks=2, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    mpi_whole, restarted = map(np.array, json.loads(proc.stdout.strip().splitlines()[-1]))
    assert restarted.shape == mpi_whole.shape
    assert np.max(np.abs(restarted - mpi_whole)) < 1e-8
    points = [*whole.branches[0].points[2:], *(q for b in whole.branches[1:] for q in b.points)]
    serial = np.array([[q.factor, *q.tip] for q in points])
    primary = len(whole.branches[0].points) - 2 + len(whole.branches[1].points)
    assert np.max(np.abs(restarted[:primary] - serial[:primary])) < 1e-8
    ends = [len(whole.branches[2].points), len(whole.branches[3].points)]
    last = primary + np.cumsum(ends) - 1  # the switched branches' points at λ = 1.5
    for i in last:
        assert restarted[i, 0] == pytest.approx(1.5, abs=1e-12)
        assert np.max(np.abs(np.abs(restarted[i]) - np.abs(serial[i]))) < 1e-8


def test_killed_on_the_second_branch_keeps_the_first(tmp_path):
    """The roll-up (4 elements, one turn) on [−1, 1], λ growing then falling, killed at the
    4th point of the second branch: branches.csv holds the first branch (written as it
    ended) and the second's first 5 rows (its start and the 4 told, appended as they came),
    branches.json the first; the restart (default: the last branch saved, 1) appends the
    second's rows after its saved points. The file is then the whole run's, byte for byte
    (the argument of test_restart_equals_the_whole_branch; before, the second branch's first
    two rows were lost with the kill), and branches.json has both branches' reasons."""
    scene = cf.load(ROLLUP, {"discretisation.elements": 4, "parameters.turns": 1})
    options = dict(step=0.05, max_step=0.3, switch=0, directions=(1, -1))
    whole = cf.continuation(scene, -1.0, 1.0, max_points=40, out=tmp_path / "whole", **options)
    first, second = whole.branches
    assert first.reason == "p reached 1" and second.reason == "p reached -1"
    calls = len(first.points) - 2 + 4  # stop is told of every point but the start and end
    cut = tmp_path / "cut"
    with pytest.raises(Killed):
        cf.continuation(scene, -1.0, 1.0, max_points=40, out=cut, stop=kill_after(calls), **options)
    rows_w = (tmp_path / "whole" / "branches.csv").read_text().splitlines()
    one = 1 + len(first.points)  # the header and the first branch's rows
    assert (cut / "branches.csv").read_text().splitlines() == rows_w[: one + 5]
    (b,) = cf.continuation(None, restart=cut).branches
    assert [q.factor for q in b.points] == [q.factor for q in second.points[2:]]
    assert (cut / "branches.csv").read_text().splitlines() == rows_w
    reasons = json.loads((cut / "branches.json").read_text())
    assert [r["reason"] for r in reasons] == ["p reached 1", "p reached -1"]


def sigterm_when_saved(command: list[str], index, branch: int = 0, at: int = 20) -> None:
    """Run ``command`` (a ``continue``) and kill it by SIGTERM once restart.json (``index``)
    has branch ``branch``'s saved end at point ``at`` or later (its first_index), within
    300 s; the run must not have ended before."""
    import signal
    import subprocess

    from conftest import PYTHON, stop_tree, subprocess_env

    killed = subprocess.Popen([PYTHON, *command], cwd=ROOT, env=subprocess_env())
    try:
        deadline = time.monotonic() + 300
        first = -1
        while first < at and killed.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
            try:
                first = json.loads(index.read_text())["branches"][str(branch)]["first_index"]
            except (OSError, ValueError, KeyError):
                pass
        assert killed.poll() is None, "the run ended before it could be killed"
        killed.send_signal(signal.SIGTERM)
        killed.wait(timeout=60)
    finally:
        stop_tree(killed)


@pytest.mark.long
def test_continue_killed_by_sigterm_restarts_from_its_last_point(tmp_path):
    """``continue`` killed by SIGTERM (not a Python exception: the process ends wherever it is,
    between the saved arrays and restart.json perhaps) once its saved end is at point 20 or
    later of the roll-up's branch (32 elements, two turns, steps of 0.02: 162 points), then
    ``continue --restart``: its branches.csv is the uninterrupted run's, byte for byte
    (serial: the same operations on the same arrays, test_restart_equals_the_whole_branch),
    whichever point the kill fell on: the killed run's rows were appended as they came, the
    restart cuts the file to those restart.json names (a row written after its saved end
    goes) and appends the rest (before: the rows before the saved first index were lost)."""
    base = ["-m", "cosserat_fem.cli", "continue"]
    case = [str(ROLLUP), "--set", "discretisation.elements=32", "--set", "parameters.turns=2"]
    case += ["--step", "0.02", "--max-step", "0.02", "--switch", "0", "--max-points", "400"]
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    proc = run_command([*base, *case, "--out", str(whole), "--quiet"])
    assert proc.returncode == 0, proc.stderr
    index = cut / "continuation" / "restart.json"
    sigterm_when_saved([*base, *case, "--out", str(cut), "--quiet"], index)
    end = json.loads(index.read_text())["branches"]["0"]
    assert end["first_index"] >= 20 and end["rows"] == end["first_index"] + 3
    assert len((cut / "branches.csv").read_text().splitlines()) - 1 >= end["rows"]
    proc = run_command([*base, "--restart", str(cut), "--quiet"])
    assert proc.returncode == 0, proc.stderr
    rows_w = (whole / "branches.csv").read_text().splitlines()
    rows = (cut / "branches.csv").read_text().splitlines()
    assert len(rows_w) == 163
    assert rows == rows_w


@pytest.mark.long
@pytest.mark.parametrize("branch", [0, 2])
def test_continue_killed_by_sigterm_traces_the_branches_after_it(tmp_path, branch):
    """``continue`` on the column of :func:`pitchfork_column` with steps of 0.01 (four
    branches: 152, 52, 80 and 80 points, 6 s) killed by SIGTERM (the process ends wherever it
    is: between a branch's rows, frames, arrays and restart.json perhaps) once the saved end
    of branch ``branch`` (the primary's first direction, or the switch's first) is at point
    20 or later, then ``continue --restart``: the folder is the uninterrupted run's,
    branches.csv byte for byte, branches.json, every branch's XDMF frames (times and
    values), whichever point the kill fell on (serial: the same operations on the same
    arrays, test_restart_equals_the_whole_branch; the restart cuts each file back to the
    saved end and traces the queue saved with it)."""
    base = ["-m", "cosserat_fem.cli", "continue"]
    case = [
        str(ROLLUP),
        "--unset",
        "loads.end",
        "--set",
        'loads.end.force=[0, 0, "-pi**2*EI/(4*L**2)"]',
    ]
    case += ["--set", "discretisation.elements=8", "--range", "-0.5", "1.5", "--step", "0.01"]
    case += ["--max-step", "0.01", "--max-points", "400"]
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    proc = run_command([*base, *case, "--out", str(whole), "--quiet"])
    assert proc.returncode == 0, proc.stderr
    points = [e["points"] for e in json.loads((whole / "branches.json").read_text())]
    assert points == [152, 52, 80, 80]
    index = cut / "continuation" / "restart.json"
    sigterm_when_saved([*base, *case, "--out", str(cut), "--quiet"], index, branch)
    ends = json.loads(index.read_text())["branches"]
    assert max(map(int, ends)) == branch and ends[str(branch)]["first_index"] >= 20
    proc = run_command([*base, "--restart", str(cut), "--quiet"])
    assert proc.returncode == 0, proc.stderr
    assert_same_folders(cut, whole)


# %% [markdown]
# ## Rods in 3D: the chart moves on the path (issue 27 item 2)


def strip(ratio: float, elements: int = 8):
    """(scene, λ_Prandtl-scaled load P [N], EI_min, EI_max, GJ, ℓ) of a cantilever strip
    clamped at s = 0 along e3: scenes/rollup.toml's rod, section a = 0.04 m (along d1, the
    stiff plane x-z: EI_max = E b a³/12) by b = a/ratio (EI_min = E a b³/12), solved in 3D,
    under the dead tip force P e1 in its stiff plane, P = 4.013 √(EI_min GJ)/ℓ² (Prandtl's
    value, rounded as usually quoted; λ = 1 there)."""
    a = 0.04
    base = {
        "loads.end": cf.UNSET,
        "rod.section.a": a,
        "rod.section.b": a / ratio,
        "discretisation.planar": "off",
        "discretisation.elements": elements,
        "discretisation.degree": 4,
    }
    rod = cf.load(ROLLUP, base).rod_constants()
    section, E, G, L = rod.section, rod.young_modulus, rod.shear_modulus, rod.length
    EI_min, EI_max, GJ = E * section.c11, E * section.c22, G * section.c33
    P = 4.013 * math.sqrt(EI_min * GJ) / L**2
    scene = cf.load(ROLLUP, {**base, "loads.end.force": [P, 0, 0]})
    return scene, P, EI_min, EI_max, GJ, L


def assert_mirror_images(left, right) -> None:
    """The two directions of a switched branch are mirror images about the x-z plane: the
    same λ and (x, −y, z, −θ, ψ, −φ) at each point, to 1e-9 (the corrector's tolerance,
    1e-10 in the metric, with room)."""
    assert len(left.points) == len(right.points)
    for a, b in zip(left.points, right.points, strict=True):
        assert abs(a.factor - b.factor) < 1e-9
        assert np.max(np.abs(a.tip - np.array([1, -1, 1, -1, 1, -1]) * b.tip)) < 1e-9


def test_lateral_torsional_buckling_of_a_cantilever_strip():
    """A cantilever strip under a tip load in its stiff plane buckles sideways and twists
    (lateral–torsional buckling): on the 3D path (the in-plane bending, θ = φ = 0) det R_u
    changes sign at the critical load, located as a bifurcation, and the post-buckled branch
    (tip moving sideways, y ≠ 0, and twisting) is switched onto, both ways.

    **Closed form.** Prandtl (1899) and Michell (1899), for a thin strip without warping
    stiffness (as this rod: no warping) loaded at its centroid:
    P_cr = γ √(EI_min GJ)/ℓ², γ = 2 j, j the first zero of the Bessel function J_{−1/4}
    (Timoshenko & Gere, Theory of Elastic Stability, 2nd ed., §6.4: γ = 4.013);
    γ = 4.012599 computed here. Prandtl's analysis neglects the in-plane (prebuckling)
    deflection; including it raises the load by terms of first order in EI_min/EI_max and
    GJ/EI_max (Michell's factor; for uniform bending exactly
    F = [(1 − EI_min/EI_max)(1 − GJ/EI_max)]^{−1/2}, Pi & Trahair 1992). Both ratios scale as
    (b/a)², so the rod's λ_cr·(4.013/γ) = 1 + c (b/a)² + O((b/a)⁴), and Richardson's
    extrapolation from b/a = 1/20 and 1/40, (4 λ_40 − λ_20)/3, is Prandtl's value up to the
    O((b/a)⁴) remainder, of the size of (F_20 − 1)² ≈ 1e-5: asserted 2e-5 (measured 6e-6).
    Shear and extension change it by EI_min/(κGA ℓ²) ≈ 1e-6 and less. Each located value
    lies above Prandtl's and within the first-order correction: measured
    λ_cr·4.013/γ − 1 = 1.17 (F − 1) at both ratios (3.64e-3 and 9.1e-4; the cantilever's
    coefficient, not uniform bending's 1); asserted in (0, 1.5 (F − 1)). The discretisation
    (8 P4) changes λ_cr by 2e-8 against 16 P4.

    **The post-buckled branches** (b/a = 1/20): the two directions of the switched branch
    are mirror images (y, θ, φ → −y, −θ, −φ at the same λ, to 1e-9: the scene's symmetry
    about the x-z plane), leave the plane (|y| > 0.1 ℓ after 6 points), and λ grows along
    them (a stable symmetric bifurcation: λ > λ_cr at every point)."""
    gamma = 2.0 * brentq(lambda x: jv(-0.25, x), 1.5, 2.5)
    values = {}
    for ratio in (20.0, 40.0):
        scene, P, EI_min, EI_max, GJ, L = strip(ratio)
        switch = 1 if ratio == 20.0 else 0
        result = cf.continuation(
            scene,
            0.0,
            1.1,
            step=0.1,
            max_step=0.25,
            switch=switch,
            directions=(1,),
            max_points=7,
        )
        primary = result.branches[0]
        found = [q for q in primary.special if q.kind == "bifurcation"]
        assert len(found) == 1 and not found[0].note
        excess = found[0].factor * 4.013 / gamma - 1.0
        F = 1.0 / math.sqrt((1.0 - EI_min / EI_max) * (1.0 - GJ / EI_max))
        assert 0.0 < excess < 1.5 * (F - 1.0), (ratio, excess, F - 1.0)
        values[ratio] = 1.0 + excess
        if switch:
            left, right = result.branches[1:]
            assert len(left.points) == 7
            assert_mirror_images(left, right)
            for q in left.points[1:]:
                assert q.factor > found[0].factor
            assert abs(left.points[-1].tip[1]) > 0.1 * L
    extrapolated = (4.0 * values[40.0] - values[20.0]) / 3.0
    print(f"λ_cr: {values}, extrapolated − 1 = {extrapolated - 1.0:.3g}")
    assert abs(extrapolated - 1.0) < 2e-5, values


def rolled_about_e1(elements: int):
    """scenes/rollup.toml rolled up about e1, its section turned (E c11 = EI), in 3D, on
    ``elements`` P4 elements."""
    overrides = {
        "loads.end.torque": ["turns*2*pi*EI/L", 0, 0],
        "rod.section.a": 0.06,
        "rod.section.b": 0.04,
        "discretisation.planar": "off",
        "discretisation.elements": elements,
    }
    return cf.load(ROLLUP, overrides)


def test_rolled_about_e1_in_3d_moves_the_chart(monkeypatch):
    """scenes/rollup.toml rolled up about e1 (the section turned so that E c11 = EI) and
    solved in 3D: the rod bends in the y-z plane through the angle θ, and the free end turns
    by θ(ℓ) = 2πλ to one full circle at λ = 1, past θ = ±π/2 where the Euler-angle chart (18)
    is singular. So the chart moves on the path: at least 3 times (each chart holds the
    rod's rotation within |θ| < π/2 of its own, and the tip turns by 2π), and:

    * the path is continuous across each move: the point before the move (the branch's,
      as ``stop`` saw it) and the same point re-charted and corrected (the engine's base of
      the next step, recorded from Continuation._move_chart) differ by the change of the
      discretisation with the chart (the frame interpolated from the nodal quaternions,
      O(h⁵)): measured ≤ 2.2e-11 m (2.4e-10 m when it was corrected at the same λ);
      asserted 1e-9;
    * no bifurcation is reported (the pure moment's circle is the only path) and det R_u keeps
      its sign on every point;
    * every point lies on the closed-form circle, radius ℓ/(2πλ): the tip
      (0, −(1 − cos κ)/κ, sin κ/κ − ℓ) [m] and θ = κ = 2πλ (10 P4 elements: measured 1.2e-6
      m and 4.2e-6 rad at the most, the elements' error; asserted 3e-6, 1e-5);
    * load stepping (``cf.static``, 16 steps, its chart moved at other loads) reaches the
      same state at λ = 1: measured 9e-11 m; asserted 1e-9 (the Newton tolerance, 1e-10,
      and the chart's change of the discretisation above)."""
    from cosserat_fem.nls.arclength import Continuation

    scene = rolled_about_e1(10)
    seen = []
    moves: list[tuple] = []
    move = Continuation._move_chart

    def recorded(self, point):  # the point and its re-charted image's positions [m]
        moved = move(self, point)
        if moved is not None:
            after = self.problem.tip(moved[0].u, moved[0].chart)[:3]
            moves.append((point.p, after))
        return moved

    monkeypatch.setattr(Continuation, "_move_chart", recorded)
    result = cf.continuation(
        scene, 0.0, 1.0, step=0.05, max_step=0.5, directions=(1,), stop=seen.append
    )
    (branch,) = result.branches
    assert branch.reason.startswith("p reached 1")
    assert branch.charts_moved >= 3 and not branch.special
    assert len(moves) == branch.charts_moved
    assert {q.det_sign for q in branch.points} == {branch.points[0].det_sign}
    before = {q.factor: q.tip[:3] for q in seen}
    jumps = [np.max(np.abs(before[p] - after)) for p, after in moves]
    print(f"moves {branch.charts_moved}, jumps {max(jumps):.3g}, points {len(branch.points)}")
    assert max(jumps) < 1e-9, jumps
    for q in branch.points[1:]:
        k = 2.0 * math.pi * q.factor
        circle = np.array([0.0, -(1.0 - math.cos(k)) / k, math.sin(k) / k - 1.0])
        assert np.max(np.abs(q.tip[:3] - circle)) < 3e-6
        assert abs(q.tip[3] - k) < 1e-5
    stepping = cf.static(scene)
    assert np.max(np.abs(stepping.probes[-1][1:4] - branch.points[-1].tip[:3])) < 1e-9


def test_restart_across_chart_moves_equals_the_whole_branch(tmp_path):
    """A continuation in 3D cut in two equals the whole one bit for bit, with the chart moved
    in both parts: the roll-up about e1 of :func:`test_rolled_about_e1_in_3d_moves_the_chart`
    on 4 P4 elements, cut by max_points = 4 and restarted to λ = 1. The restart data keep each
    saved point's chart (its nodal quaternions, per rank), so the resumed trace measures the
    angles from the same frames and performs the same operations: the same λ and the same
    free-end positions, exactly (the free end's angles are the rod's rotation continued from
    the branch's first reported point, which for the resumed rows is a later one: they may
    differ by turns of 2π, so are not compared). branches.json counts the moves."""
    scene = rolled_about_e1(4)
    options = dict(step=0.05, max_step=0.5, switch=0, directions=(1,))
    whole = cf.continuation(scene, 0.0, 1.0, max_points=40, out=tmp_path / "whole", **options)
    cut = tmp_path / "cut"
    first = cf.continuation(scene, 0.0, 1.0, max_points=4, out=cut, **options)
    (entry,) = json.loads((cut / "branches.json").read_text())
    assert entry["charts_moved"] == first.branches[0].charts_moved >= 1
    second = cf.continuation(None, max_points=40, restart=cut)
    (w,), (a,), (b,) = whole.branches, first.branches, second.branches
    assert w.reason == b.reason == "p reached 1"
    assert a.charts_moved >= 1 and b.charts_moved >= 1
    assert w.charts_moved >= 3 and not w.special and not b.special
    assert [q.factor for q in w.points[1:]] == [q.factor for q in b.points]
    assert all(
        np.array_equal(p.tip[:3], q.tip[:3]) for p, q in zip(w.points[1:], b.points, strict=True)
    )


@pytest.mark.long
def test_a_killed_lee_frame_restarts_across_chart_moves(tmp_path):
    """Lee's frame of :func:`test_lee_frame_switches_out_of_its_plane` (20 P3, 25 points a
    branch, its switched branches moving the chart once each, near the fold where λ turns
    back) killed at the 20th point of the first switched branch (after its move: rows 0-19
    written as the points came, the point of the move as it was accepted), restarted: the
    folder is the whole run's, branches.csv byte for byte, branches.json, every XDMF frame
    (read_arrays: the frame is not straight). Before, the whole run's file showed the
    re-charted point, corrected at the same λ onto another state (the load point 0.47 away
    sideways), where the restart's rows showed the accepted one (docs/decisions.md)."""
    from xdmf_files import read_arrays

    scene = cf.load(
        ROOT / "scenes" / "lee_frame.toml",
        {"parameters.P": 10.0, "discretisation.elements": 20, "discretisation.degree": 3},
    )
    options = dict(step=0.05, max_step=0.05, max_points=25, switch=1, directions=(1,))
    options["probe"] = 144.0
    whole = cf.continuation(scene, -1.0, 1.0, out=tmp_path / "whole", **options)
    assert [b.charts_moved for b in whole.branches] == [0, 1, 1]
    assert all(b.reason == "25 points (max_points)" for b in whole.branches)
    cut = tmp_path / "cut"
    with pytest.raises(Killed):  # every point but the start is told (no bound reached)
        cf.continuation(scene, -1.0, 1.0, out=cut, stop=kill_after(24 + 20), **options)
    assert (
        json.loads((cut / "continuation" / "restart.json").read_text())["branches"]["1"][
            "charts_moved"
        ]
        == 1
    )
    result = cf.continuation(None, restart=cut)
    assert [len(b.points) for b in result.branches] == [7, 25]
    for name in ("branches.csv", "branches.json"):
        assert (cut / name).read_text() == (tmp_path / "whole" / name).read_text()
    for i in range(3):
        _, times, arrays = read_arrays(cut / f"branch_{i}.xdmf")
        _, times_w, arrays_w = read_arrays(tmp_path / "whole" / f"branch_{i}.xdmf")
        assert list(times) == list(times_w) == list(range(25))
        assert all(np.array_equal(arrays[k], arrays_w[k]) for k in arrays_w)


@pytest.mark.long
def test_lee_frame_switches_out_of_its_plane():
    """Lee's frame (scenes/lee_frame.toml, 20 P3, P = 10 λ, the load point probed) solved in
    3D buckles out of its plane at P = 1.69299 (tests/test_snap_through.py) and the engine now
    switches there (before the MUMPS refactorisation fix of RodPath.linearise every step of
    the switched branch failed: docs/continuation.md). The two directions are mirror images
    about the frame's plane (y, θ, φ → −y, −θ, −φ at the same λ: the scene's symmetry; to
    1e-9, the corrector's tolerance with room), they leave the plane (the load point more
    than 40 sideways, measured 51.7) and the chart moves on them (the members turn out of the
    plane by more than 0.9 rad: measured |θ| = 0.99 at the load point, one move each)."""
    scene = cf.load(
        ROOT / "scenes" / "lee_frame.toml",
        {"parameters.P": 10.0, "discretisation.elements": 20, "discretisation.degree": 3},
    )
    result = cf.continuation(
        scene,
        -1.0,
        1.0,
        step=0.05,
        max_step=0.05,
        max_points=25,
        switch=1,
        directions=(1,),
        probe=144.0,
    )
    primary, left, right = result.branches
    (found,) = [q for q in primary.special if q.kind == "bifurcation"]
    assert abs(10.0 * found.factor - 1.69299) < 1e-5
    assert len(left.points) == 25
    assert_mirror_images(left, right)
    assert max(abs(q.tip[1]) for q in left.points) > 40.0
    assert left.charts_moved >= 1 and right.charts_moved >= 1
