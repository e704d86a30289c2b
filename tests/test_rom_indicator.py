"""The reduced model's own error (issue 28 item 3; cosserat_fem/rom/indicator.py, docs/rom.md
§10): its indicator against the true relative L2 free-end error of docs/rom.md §7 (the reduced
run against the full one), on the paper's scene trained on its own run and under loads outside
the training, the flags of a run outside its training, and the whip in 3D through its chart's
moves (and the refusal of a basis file, which has no snapshots to follow them with).

The estimate carries the residual's forcing in the rod's normal modes (10.5)-(10.8) and has
no calibrated constant (C = 1): the ratios E/error below are what the transport gives, and
[1/3, 3] (the issue's factor) is what the tests hold. Over 0.006 s they lie in 0.41-1.04,
over 0.06 s in 0.71-2.43 (docs/rom.md §10): the margin to either bound is 1.2x or more."""

from __future__ import annotations

import json
import logging
from dataclasses import replace

import pytest
from conftest import ROOT, run_command

import cosserat_fem as cf
from cosserat_fem.common.errors import SolverError
from cosserat_fem.rom import basis as rb
from cosserat_fem.rom import galerkin
from cosserat_fem.rom import indicator as ri
from cosserat_fem.rom.indicator import IndicatorSettings
from cosserat_fem.timestepping.events import Observer

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
WHIP = ROOT / "scenes" / "whip.toml"
SHORT = {"time.end": 0.006}
#: The paper's load 3 times larger; at another frequency (5 ω0 for 8 ω0); in another direction
#: (f2 half of f1 instead of equal).
LOADS = {
    "3x": ["6e3*sin(pi*s/L)*sin(8*omega0*t)"] * 2 + [0],
    "frequency": ["2e3*sin(pi*s/L)*sin(5*omega0*t)"] * 2 + [0],
    "direction": ["2e3*sin(pi*s/L)*sin(8*omega0*t)", "1e3*sin(pi*s/L)*sin(8*omega0*t)", 0],
}
MODES = (4, 8, 12)


def _error(reduced, full) -> float:
    return rb.relative_l2(reduced.probes[:, 1:4], full.probes[:, 1:4])


@pytest.fixture(scope="module")
def short_training():
    """The paper's scene over 0.006 s (200 steps) run in full, every output a snapshot."""
    scene = cf.load(PAPER, SHORT)
    basis, (full,) = rb.train([scene], tolerance=1e-14)
    return scene, basis, full


def test_indicator_tracks_the_error_on_the_training_scene(short_training):
    """(a) Trained on its own run, k = 4, 8, 12 modes: the final estimate E (10.7) over the true
    relative L2 free-end error lies in [1/3, 3] (the issue's factor; measured 0.96, 0.71, 0.41
    for errors 5.5e-3, 1.6e-4, 3.0e-5; the last the nearest the bound: sampled every 10th
    step, the residual's content above ~50 ω0 is aliased; every step gives 1.08), and E falls
    with the error as modes are added. The run is not flagged outside its training (its own
    load, its own range: no entry, no warning) and at k = 8, 12, errors 50-300 times below the
    tolerance 1e-2, not exceeded. summary["rom"]
    holds the contract that `rom validate` reads (keys and types), E sampled every 10th step:
    20 samples over 200 steps."""
    scene, basis, full = short_training
    estimates = []
    for k in MODES:
        reduced = galerkin.run(scene, basis.truncated(k))
        error, rom = _error(reduced, full), reduced.summary["rom"]
        indicator = rom["indicator"]
        estimates.append(indicator["final"])
        assert 1 / 3 <= indicator["final"] / error <= 3, (k, indicator["final"], error)
        assert rom["outside_training"] == []
        assert set(indicator) >= {"max", "final", "tolerance", "exceeded", "every", "times"}
        assert indicator["every"] == 10 and indicator["tolerance"] == 1e-2
        assert len(indicator["times"]) == len(indicator["values"]) == 20
        assert isinstance(indicator["exceeded"], bool)
        if k > 4:
            assert not indicator["exceeded"]
    assert estimates[0] > estimates[1] > estimates[2]


def test_a_sweep_trained_basis_flags_the_amplitudes_it_was_not_trained_on(tmp_path):
    """A basis trained on a sweep over the amplitude a ∈ {1e3, 2e3} N/m of the paper's load
    (a a parameter of its expression, 3 ms): a run at a = 1.5e3, inside the trained range,
    is not flagged "load"; at a = 4e3 = 2 a2, beyond a2 by 2 widths of the range (the flag
    admits a quarter of one, indicator.outside_loads), it is, in one warning line naming
    parameters.a and the range [1000, 2000]. The loads' text is the same in all three runs:
    the text comparison of before saw none of this."""
    amplitude = "a*sin(pi*s/L)*sin(8*omega0*t)"
    sweep = tmp_path / "amplitudes.toml"
    sweep.write_text(
        f'[sweep]\nscene = "{PAPER}"\n[sweep.set]\n"time.end" = 0.003\n'
        f'"loads.force_density" = ["{amplitude}", "{amplitude}", 0]\n"parameters.a" = 1e3\n'
        '[sweep.vary]\n"parameters.a" = [1e3, 2e3]\n'
    )
    basis = cf.rom.build(sweep=cf.load_sweep(sweep), tolerance=1e-8)
    trained = [run["load_values"]["values"]["parameters.a"] for run in basis.provenance["runs"]]
    assert trained == [1e3, 2e3]
    flags = {}
    for a in (1.5e3, 4e3):
        scene = cf.load(
            PAPER,
            {
                "time.end": 0.003,
                "loads.force_density": [amplitude, amplitude, 0],
                "parameters.a": a,
            },
        )
        flags[a] = {
            e["what"]: e for e in cf.rom.run(scene, basis).summary["rom"]["outside_training"]
        }
    assert "load" not in flags[1.5e3]
    reason = flags[4e3]["load"]["reason"]
    assert "parameters.a = 4000 outside the trained range [1000, 2000]" in reason
    assert "\n" not in reason


@pytest.mark.parametrize("load", sorted(LOADS))
def test_indicator_flags_a_load_outside_the_training(short_training, load, caplog, tmp_path):
    """(b) The basis of the paper's run, run under another load (3x larger, at 5 ω0 instead of
    8 ω0, f2 = f1/2): the true error grows over the training's at k = 8, 12 (3x: 12x, 18x;
    frequency: 1.9x, 5.4x; direction: 4.9x, 13x; at k = 4: 2.1x, 0.75x, 3.3x, the training's
    own error being large there), and the estimate with it: E/error in [1/3, 3] for each k
    (measured 3x: 0.72, 0.88, 1.00; frequency: 0.96, 1.04, 1.04; direction: 0.96, 0.93, 0.98;
    without the coupling (10.8) the 3x load's were 0.43, 0.52, 0.84).
    The run says so: a warning line naming the load, an entry "load" in summary.json's
    rom.outside_training (with its time, the start), and for the larger amplitude also
    "amplitude" (its W-norm past 1.25 times the training's largest). Where the true error
    exceeds the tolerance (3x and direction at k = 4: 1.2e-2, 1.8e-2), ``exceeded`` is true."""
    scene, basis, _ = short_training
    other = cf.load(PAPER, {**SHORT, "loads.force_density": LOADS[load]})
    full = cf.run(other)
    for k in MODES:
        own = _error(galerkin.run(scene, basis.truncated(k), indicator=None), _own(short_training))
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="cosserat_fem"):
            reduced = galerkin.run(other, basis.truncated(k), out=tmp_path / f"{load}{k}")
        error = _error(reduced, full)
        summary = json.loads((tmp_path / f"{load}{k}" / "summary.json").read_text())
        indicator, outside = summary["rom"]["indicator"], summary["rom"]["outside_training"]
        if k > 4:
            assert error > own, (k, error, own)
        assert 1 / 3 <= indicator["final"] / error <= 3, (k, indicator["final"], error)
        whats = [entry["what"] for entry in outside]
        assert "load" in whats and outside[whats.index("load")]["time"] == 0.0
        if load == "3x":
            assert "amplitude" in whats
        lines = [r.getMessage() for r in caplog.records if "outside its training" in r.message]
        assert any("load" in line and "\n" not in line for line in lines), lines
        if error > indicator["tolerance"]:
            assert indicator["exceeded"], (k, error, indicator["max"])


def test_stored_and_cached_modes_give_the_run_time_estimate(short_training, tmp_path):
    """(g) The modes of (10.5) solved at run time, found in the process's cache, and read from
    the basis file (indicator.stored_modes; the file without them, as an older one, read too):
    k = 8, the cache emptied first. (1) the basis without its modes: SLEPc solves
    (``modes_from`` "solved", one solve counted); (2) again: "cached", no solve; (3) the basis
    written and read back with its modes: "basis", no solve; (4) the basis written without
    them and read back: "cached". (2) and (3) use the very values of (1)'s solve (the file
    keeps its doubles; pod_basis's solve went into the cache, which (1) then recomputes
    identically), in the same arithmetic: their estimates are (1)'s to 1e-14 relative. (5)
    the cache emptied, solved anew: its modes may differ from (1)'s by the solver's tolerance
    1e-10 (a relative residual; over the relative gap of the lowest modes, ≥ 0.1 here, 1e-9
    a mode; a sign flip of φ_j flips η_j with it and leaves e unchanged), which E, a sum of
    30 modes' contributions, carries at most 30 times: asserted 1e-7 relative (measured:
    equal)."""
    scene, basis, _ = short_training
    bare = replace(basis.truncated(8), error_modes=None, error_lambda=None)
    rb.write_basis(basis.truncated(8), short_training[2].model, tmp_path / "with")
    rb.write_basis(bare, short_training[2].model, tmp_path / "without")
    ri._MODES.clear()
    solves = ri.SOLVES[0]
    runs = []
    for chosen in (bare, bare, tmp_path / "with.npz", tmp_path / "without.npz", None):
        if chosen is None:
            ri._MODES.clear()
            chosen = bare
        runs.append(galerkin.run(scene, chosen).summary["rom"]["indicator"])
    assert [r["modes_from"] for r in runs] == ["solved", "cached", "basis", "cached", "solved"]
    assert ri.SOLVES[0] - solves == 2
    for again in runs[1:4]:
        assert again["values"] == pytest.approx(runs[0]["values"], rel=1e-14, abs=0)
    assert runs[4]["values"] == pytest.approx(runs[0]["values"], rel=1e-7, abs=0)
    assert runs[2]["setup_wall_time_s"] < runs[0]["setup_wall_time_s"]


def test_a_sweeps_members_share_one_set_up(tmp_path):
    """(h) A sweep of the short paper scene over the load's amplitude f0 (1, 2, 3 kN/m;
    [sweep.rom] trained on member 0, 4 modes): the force density does no work that is not
    linear in the state, so the members' modes are the training's (indicator.rod_key): the
    process solves for them once, when the basis is built (one SLEPc solve counted for the
    sweep), and the three members read them from the basis file (``modes_from`` "basis")."""
    sweep = tmp_path / "amplitude.toml"
    sweep.write_text(
        f"""[sweep]
scene = "{PAPER}"
keep = "probes"
[sweep.set]
"time.end" = 0.003
"output.xdmf" = false
"parameters.f0" = 2e3
"loads.force_density" = ["f0*sin(pi*s/L)*sin(8*omega0*t)", "f0*sin(pi*s/L)*sin(8*omega0*t)", 0]
[sweep.vary]
"parameters.f0" = {{ start = 1e3, stop = 3e3, num = 3 }}
[sweep.rom]
train = [0]
modes = 4
"""
    )
    ri._MODES.clear()
    solves = ri.SOLVES[0]
    cf.sweep(cf.load_sweep(sweep), tmp_path / "out")
    assert ri.SOLVES[0] - solves == 1
    cached = {}
    for path in sorted((tmp_path / "out").rglob("summary.json")):
        rom = json.loads(path.read_text()).get("rom", {})
        if "indicator" in rom:
            cached[path.parent.name] = rom["indicator"]["modes_from"]
    assert sorted(cached.values()) == ["basis"] * 3, cached


def _own(training):
    return training[2]


class _Solver(Observer):
    """Keeps the run's solver (its ``chart_moves``)."""

    solver = None

    def started(self, loop) -> None:
        self.solver = loop.solver


IN_3D = {"discretisation.planar": "off", "output.xdmf": False}


@pytest.fixture(scope="module")
def whip_bases():
    """The whip's bases of its first 0.4 ms (tolerance 1e-10), in 3D (k = 31; the training
    run's chart moved at 0.24 ms: its snapshots are kept with their charts) and in its plane
    (k = 30, no chart)."""
    return {
        name: rb.train([cf.load(WHIP, {**setting, "time.end": 4e-4})], tolerance=1e-10)
        for name, setting in (("3d", IN_3D), ("planar", {"output.xdmf": False}))
    }


def test_the_whip_in_3d_follows_the_chart_as_its_plane_does(whip_bases):
    """(c) The whip (a sudden tip torque, large rotations) in 3D, its basis of its first 0.4 ms,
    run reduced over those 0.4 ms: the chart moves at t = 0.24 ms (as the full run's) and the
    Galerkin run follows it with the basis of the new chart (the snapshots mapped into it,
    POD'd again to the same k; docs/rom.md §9). Its free-end error against the full 3D run is
    the planar reduced run's (no chart) against the planar full run to 10% (measured 6.48e-4
    and 6.58e-4: the 3D and planar full runs are the same motion, tests/test_rotations.py, so a
    move that cost accuracy would show as a 3D error above the planar one; 10% is the
    difference of the two discretisations' reduced runs allowed). The state's projection error
    onto the new basis, relative in the W-norm, is below the run's error at the move (measured
    5.4e-4 against 1.0e-3 at 0.24 ms; asserted ≤ 1e-3: the move adds less than the error
    already made). The indicator is carried through the move and stays under its tolerance
    (E = 5.7e-5; it underestimates the whip in 3D tenfold with or without the move, docs/rom.md
    §9), as the error does. This test does not tell the basis per chart from a projection onto
    the unchanged basis (that also gives 6.47e-4 here: the training's snapshots after its own
    move at 0.24 ms speak the new chart); (c4) does."""
    errors = {}
    for name, setting in (("3d", IN_3D), ("planar", {"output.xdmf": False})):
        scene = cf.load(WHIP, {**setting, "time.end": 4e-4})
        keeper = _Solver()
        reduced = galerkin.run(scene, whip_bases[name][0], observers=[keeper])
        errors[name] = _error(reduced, cf.run(scene))
        moves = keeper.solver.chart_moves
        if name == "3d":
            assert [m["time_s"] for m in moves] == pytest.approx([2.4e-4])
            assert moves[0]["projection_error"] <= 1e-3
            assert not reduced.summary["rom"]["indicator"]["exceeded"]
        else:
            assert moves == []
    assert errors["3d"] == pytest.approx(errors["planar"], rel=0.1)


def test_the_whip_in_3d_outside_its_training_is_flagged_as_in_its_plane(whip_bases):
    """(c2) The same basis over the whip's 2 ms in 3D: the reduced run goes through the chart's
    move and completes, with the planar run's failure ((d) below: true error 0.83 in both,
    measured 0.827 and 0.828; the rod whips far beyond what the basis saw), and says so as the
    planar run does: a coordinate leaves the training's range at 0.51 ms (the new chart's range
    of the mapped snapshots) and E exceeds the tolerance (from 0.91 ms, the planar run's
    0.61 ms) and ends above the true error (at its ceiling 1)."""
    scene = cf.load(WHIP, IN_3D)
    reduced = galerkin.run(scene, whip_bases["3d"][0])
    error = _error(reduced, cf.run(scene))
    rom = reduced.summary["rom"]
    assert reduced.summary["status"] == "completed" and error > 0.1
    assert rom["indicator"]["exceeded"] and rom["indicator"]["final"] > error
    flagged = {entry["what"]: entry["time"] for entry in rom["outside_training"]}
    assert "coordinates" in flagged and flagged["coordinates"] < 1e-3


def test_a_basis_file_without_snapshots_is_refused_at_the_chart(whip_bases, tmp_path):
    """(c3) The whip's 3D basis written to a file (V, U_ref, W; not the snapshots) and read for
    the run: at the chart's move (t = 0.24 ms) there is nothing to re-express in the new chart,
    and the run stops with one line saying why and when (SolverError: "chart", "snapshots",
    "at t ="); the summary.json of its folder has the same message and the indicator's
    samples taken up to there (11 steps apart: 1e-5, 1.1e-4, 2.1e-4 s)."""
    basis, (training,) = whip_bases["3d"]
    rb.write_basis(basis, training.model, tmp_path / "whip")
    with pytest.raises(SolverError) as refused:
        galerkin.run(cf.load(WHIP, IN_3D), tmp_path / "whip.npz", out=tmp_path / "run")
    message = str(refused.value)
    assert "\n" not in message and "chart" in message and "snapshots" in message
    assert "at t = 0.00024 s" in message
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["message"] == message
    assert summary["rom"]["indicator"]["times"] == pytest.approx([1e-5, 1.1e-4, 2.1e-4])


def test_a_restart_after_a_chart_move_is_refused(whip_bases, tmp_path):
    """(c5) The whip's reduced run in 3D to 0.3 ms (its chart moved at 0.24 ms), continued
    from its checkpoint on the same basis: the checkpoint's chart is the moved one, whose basis
    the run made from its snapshots and the checkpoint does not hold, so the continuation is
    refused in one line naming the chart and the checkpoint (not continued on the first
    chart's basis, which would answer in the wrong angles)."""
    basis, _ = whip_bases["3d"]
    half = tmp_path / "half"
    first = galerkin.run(cf.load(WHIP, {**IN_3D, "time.end": 3e-4}), basis, out=half)
    assert first.summary["chart_resets"] == 1
    later, checkpoint = cf.resume(half, {"time.end": 4e-4})
    with pytest.raises(SolverError) as refused:
        cf.rom.run(later, basis, restart=checkpoint)
    message = str(refused.value)
    assert "\n" not in message and "chart" in message and "checkpoint" in message


def test_the_whip_trained_on_its_own_run_follows_three_moves():
    """(c4) The whip in 3D trained on its own 2 ms (k = 52 at tolerance 1e-10) and run reduced
    over them: the chart moves three times (0.24, 0.90, 1.69 ms, the full run's own moves), the
    basis of each chart made afresh, and the free-end error is 5.3e-5 (asserted ≤ 1e-4: within
    5x of the planar run's 1.2e-5 on its own basis of k = 51, the cost of the three moves'
    projections, 3.4e-3, 1.7e-4, 8.3e-4, with the modes' energy left out ≤ 6e-10 in each new
    chart). The indicator, whose modes are about the straight rod, ends at its ceiling as it
    does in the plane (E = 1 from 0.71 ms: conservative, not within 3; docs/rom.md §10).
    Projected onto the unchanged basis at each move instead (rejected, docs/rom.md §9) the
    error was 1.6e-4 and the third move came at 1.68 ms: this test fails on it."""
    scene = cf.load(WHIP, IN_3D)
    basis, (full,) = rb.train([scene], tolerance=1e-10)
    keeper = _Solver()
    reduced = galerkin.run(scene, basis, observers=[keeper])
    moves = keeper.solver.chart_moves
    assert [m["time_s"] for m in moves] == pytest.approx([2.4e-4, 9.0e-4, 1.69e-3])
    assert max(m["energy_left_out"] for m in moves) <= 1e-8
    assert _error(reduced, full) <= 1e-4
    assert reduced.summary["rom"]["indicator"]["exceeded"]


def test_the_planar_whip_outside_its_training_is_flagged(whip_bases):
    """(d) The whip in its plane (no chart to move) with a basis of its first 0.4 ms run over
    2 ms: the rod whips far beyond what the basis saw. The reduced run completes, but the true
    relative error is 0.83, and the run says so: a coordinate leaves the training's range at
    0.51 ms ("coordinates" in rom.outside_training, before the error is large) and the estimate
    exceeds the tolerance from 0.61 ms and ends at its ceiling 1 (reached at 0.81 ms: an error
    as large as the motion; the modes about the straight rod do not describe a rod rotated by
    π; asserted only beyond the tolerance and the true error, the honest failure of the
    issue's goal)."""
    basis, _ = whip_bases["planar"]
    scene = cf.load(WHIP)
    reduced = galerkin.run(scene, basis, indicator=IndicatorSettings())
    error = _error(reduced, cf.run(scene))
    rom = reduced.summary["rom"]
    assert error > 0.1
    assert rom["indicator"]["exceeded"] and rom["indicator"]["final"] > error
    flagged = {entry["what"]: entry["time"] for entry in rom["outside_training"]}
    assert "coordinates" in flagged and flagged["coordinates"] < 1e-3


@pytest.fixture(scope="module")
def long_training():
    """The paper's whole 0.06 s (2000 steps) run in full, every output a snapshot."""
    scene = cf.load(PAPER)
    basis, (full,) = rb.train([scene], tolerance=1e-14)
    return scene, basis, full


#: E/error measured over 0.06 s at k = 4, 8, 12 (docs/rom.md §10), for the test's docstring.
LONG_RATIOS = {
    "own": (0.74, 0.97, 0.74),
    "3x": (0.71, 1.00, 1.85),
    "frequency": (0.77, 1.20, 2.43),
    "direction": (0.76, 1.00, 0.87),
}


@pytest.mark.long
@pytest.mark.parametrize("load", ["own", *sorted(LOADS)])
def test_indicator_over_the_paper_span(long_training, load):
    """(e) The paper's whole 0.06 s (docs/rom.md §7's runs: errors 2.6e-2, 1.9e-3, 5.1e-5 at
    k = 4, 8, 12 on its own load; 0.22, 1.6e-2, 9.9e-5 under the 3x load; 5.2e-2, 3.8e-3,
    2.6e-5 at 5 ω0; 2.5e-2, 2.3e-3, 6.7e-5 with f2 = f1/2), the basis of the 0.06 s training
    run: E/error within [1/3, 3] at every k and load (measured: LONG_RATIOS, 0.71-2.43; the
    running sum of the first version gave 0.35-10, the linear transport without the coupling
    (10.8) 0.07-0.84). A run whose true error exceeds the tolerance 1e-2 (k = 4 everywhere,
    and k = 8 under the 3x load) is ``exceeded``; on its own load the one at k = 12 (error
    5.1e-5) is not."""
    scene, basis, full = long_training
    if load != "own":
        scene = cf.load(PAPER, {"loads.force_density": LOADS[load]})
        full = cf.run(scene)
    for k in MODES:
        reduced = galerkin.run(scene, basis.truncated(k))
        error, indicator = _error(reduced, full), reduced.summary["rom"]["indicator"]
        assert 1 / 3 <= indicator["final"] / error <= 3, (load, k, indicator["final"], error)
        if error > indicator["tolerance"]:
            assert indicator["exceeded"], (load, k, error, indicator["max"])
        if load == "own" and k == 12:
            assert not indicator["exceeded"]


MPI_SCRIPT = """
import sys, json, cosserat_fem as cf
from mpi4py import MPI
from cosserat_fem.rom import basis as rb, galerkin
short = {"time.end": 0.006}
if sys.argv[2] == "train":
    basis, (full,) = rb.train([cf.load(sys.argv[1], short)], tolerance=1e-8)
    rb.write_basis(basis, full.model, sys.argv[3])
else:
    loads = {"loads.force_density": ["6e3*sin(pi*s/L)*sin(8*omega0*t)"] * 2 + [0]}
    result = galerkin.run(cf.load(sys.argv[1], {**short, **loads}), sys.argv[3])
    if MPI.COMM_WORLD.rank == 0:
        json.dump(result.summary["rom"], open(sys.argv[4], "w"))
"""


@pytest.mark.long
def test_serial_and_two_ranks_agree(tmp_path):
    """(f) The 3x load's reduced run on a basis file, on one rank and on two: the estimates E
    agree to 1e-9 relative (measured 1.2e-11: the runs differ by the order of sums, the
    residual's allreduce and MUMPS's LU of K against PETSc's, each Newton solve to rtol 1e-10),
    and the flags are the same, at the same times."""
    script = tmp_path / "indicator_mpi.py"
    script.write_text(MPI_SCRIPT)
    basis = tmp_path / "basis"
    trained = run_command([str(script), str(PAPER), "train", str(basis)])
    assert trained.returncode == 0, trained.stderr[-2000:]
    runs = {}
    for ranks in (1, 2):
        out = tmp_path / f"rom{ranks}.json"
        done = run_command([str(script), str(PAPER), "run", str(basis), str(out)], ranks=ranks)
        assert done.returncode == 0, done.stderr[-2000:]
        runs[ranks] = json.loads(out.read_text())
    one, two = runs[1]["indicator"]["values"], runs[2]["indicator"]["values"]
    assert one == pytest.approx(two, rel=1e-9)
    flags = [[(e["what"], e["time"]) for e in run["outside_training"]] for run in runs.values()]
    assert flags[0] == flags[1] and len(flags[0]) == 3
