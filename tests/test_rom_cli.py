"""The reduced model's commands (cosserat_fem/rom/runs.py, docs/rom.md §11): ``rom build`` and
``rom run`` against ``cf.rom.run``, a reduced run's restart, a sweep of reduced members
trained on two of them against its full sweep, ``rom validate`` against the errors computed
from the probes.csv files it leaves, ``mpirun -n 2 rom run`` against serial, and the bad
inputs' one-line refusals."""

from __future__ import annotations

import hashlib
import json
import math
import os

import numpy as np
import pytest
from conftest import ROOT, fails_if_hung, read_table, run_command
from test_rom_qloop import largest_norm, restart_bound

import cosserat_fem as cf
from cosserat_fem.cli import main
from cosserat_fem.rom.basis import relative_l2

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
#: The paper's scene over a tenth of its span: 200 steps of 30 µs.
SHORT = ["--set", "time.end=0.006"]
#: docs/rom.md §7: a reduced run's relative L2 free-end error is at most 10 √ε, ε the
#: energy left out of its basis (measured 1.4-7.0 √ε on the paper's scene).
ERROR_CONSTANT = 10.0
TOLERANCE = 1e-8  # of the bases here: ε ≈ 5e-9, √ε ≈ 7e-5, 10 √ε ≈ 7e-4


def cli(*args: str, ranks: int = 1):
    return run_command(["-m", "cosserat_fem.cli", *args], ranks)


def probes(folder) -> np.ndarray:
    return np.loadtxt(folder / "probes.csv", delimiter=",", skiprows=1)


@pytest.fixture(scope="module")
def basis_file(tmp_path_factory):
    """``rom build`` of the short paper scene (its own run, tolerance 1e-8), the training
    run kept."""
    folder = tmp_path_factory.mktemp("basis")
    proc = cli(
        "rom", "build", str(PAPER), *SHORT, "--tolerance", str(TOLERANCE),
        "--out", str(folder / "paper"), "--keep", str(folder / "training"),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "-> " in proc.stdout and "paper.npz" in proc.stdout
    return folder / "paper.npz"


@pytest.fixture(scope="module")
def reduced_run(basis_file):
    """The folder of the serial ``rom run`` of the short paper scene on :func:`basis_file`
    (read, never written, by the tests that use it)."""
    out = basis_file.parent / "reduced"
    proc = cli("rom", "run", str(PAPER), *SHORT, "--basis", str(basis_file), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    return out


def test_rom_run_is_cf_rom_run_and_restarts(basis_file, reduced_run, tmp_path):
    """``rom run`` of the short paper scene on the basis of ``rom build`` writes probes.csv,
    XDMF and summary.json as ``run`` does, and its probes equal ``cf.rom.run``'s on the same
    file (in this process) to 1e-12 of the largest |x, y, z|: the same code path, the same
    arithmetic; probes.csv's 17 significant digits give the doubles back. The full model
    differs from it by the reduction's error (≈ 1e-4 here, > 1e-12 by far), which this test
    would see. summary.json's rom names the file, its SHA-256 and modes.

    Restart: the run to 3 ms continued by ``rom run --restart`` to 6 ms equals the straight run
    within test_rom_qloop.restart_bound of the largest |x, y, z| (the continued run's chord
    Newton starts with a fresh J_r where the straight one keeps its frozen one: each stage
    solve of the 100 steps after the restart stops within stol ‖U‖ of its solution, which
    SDIRK3 passes on with a factor of at most 2.20 a step and the stable dynamics do not
    amplify; 2.6e-3 of the motion here, measured 4.3e-9); ``run --restart`` (the full
    model) and a restart on another basis are refused in one line.

    The indicator's modal state is in the checkpoint (``carried``): the continued run's E
    (10.7) is the straight run's at every sample. Before the restart they are the same
    computation's (equal to 1e-12). After it, the states differ by δ, the probes' largest
    relative difference (measured 4.3e-9). E is linear in the defect R = F(U_red) that
    forces the modes (10.5). A state moved by δ|U| moves R by about |J| δ|U|, and
    |R| ≈ E |J U| (R is the force the reduced state leaves out, and E the relative error
    it makes). So |ΔE|/E ≲ δ/E at each sample. The test allows 10 δ/E, i.e. |ΔE| ≤ 10 δ
    (10: a margin for the two "about"s; E ≥ 1e-4 here, so the bound is ≥ 4e-4 relative;
    measured |ΔE| ≤ 0.087 δ, at most 3.3e-6 relative). Without the state, the modes start
    from zero at 3 ms: ΔE/E = O(1)."""
    out = reduced_run
    mine = probes(out)
    assert mine.shape == (201, 7)
    assert (out / "solution.xdmf").is_file() and (out / "solution.frames" / "mesh.h5").is_file()
    summary = json.loads((out / "summary.json").read_text())
    document = json.loads(basis_file.with_suffix(".json").read_text())
    assert summary["status"] == "completed" and summary["newton"]["loop"] == "galerkin"
    rom = summary["rom"]
    assert rom["model"] == "reduced"
    assert rom["basis"]["sha256"] == hashlib.sha256(basis_file.read_bytes()).hexdigest()
    assert rom["basis"]["modes"] == document["provenance"]["modes"]
    assert rom["basis"]["energy_left_out"] <= TOLERANCE
    # the error indicator's entries beside the basis's record (both observers fill "rom")
    assert rom["indicator"]["max"] > 0 and rom["outside_training"] == []
    scene = cf.load(PAPER, {"time.end": 0.006})
    norms: list = []
    python = cf.rom.run(scene, basis_file, observers=[largest_norm(norms)])
    scale = np.abs(python.probes[:, 1:4]).max()
    assert np.abs(mine[:, 1:] - python.probes[:, 1:]).max() <= 1e-12 * scale
    full = probes(basis_file.parent / "training" / "scene")
    error = relative_l2(mine[:, 1:4], full[:, 1:4])
    assert 1e-12 < error <= ERROR_CONSTANT * math.sqrt(rom["basis"]["energy_left_out"])

    half = tmp_path / "half"
    args = ["--basis", str(basis_file)]
    proc = cli("rom", "run", str(PAPER), "--set", "time.end=0.003", *args, "--out", str(half))
    assert proc.returncode == 0, proc.stderr
    refused = cli("run", "--restart", str(half), "--set", "time.end=0.006")
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1
    assert "is a reduced run" in refused.stderr and "Traceback" not in refused.stderr
    other = tmp_path / "other"
    (other.with_suffix(".npz")).write_bytes(basis_file.read_bytes() + b"\0")
    other.with_suffix(".json").write_bytes(basis_file.with_suffix(".json").read_bytes())
    later = ["--set", "time.end=0.006"]
    refused = cli("rom", "run", "--restart", str(half), *later, "--basis", f"{other}.npz")
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1
    assert "--basis: not the basis the run" in refused.stderr
    proc = cli("rom", "run", "--restart", str(half), *later, *args)
    assert proc.returncode == 0, proc.stderr
    continued = probes(half)
    assert continued.shape == mine.shape
    bound = restart_bound(scene.solver.stol, 100, max(norms), scale)
    assert np.abs(continued[:, 1:4] - mine[:, 1:4]).max() <= bound * scale
    # the indicator's record spans both parts, its modes carried through the restart
    first = json.loads((half / "summary.json").read_text())["rom"]["indicator"]
    whole = summary["rom"]["indicator"]
    assert first["carried"] and first["restarts"] == [pytest.approx(0.003, rel=1e-12)]
    assert first["times"] == pytest.approx(whole["times"], rel=1e-12)
    split = int(np.searchsorted(whole["times"], 0.003, side="right"))
    assert first["values"][:split] == pytest.approx(whole["values"][:split], rel=1e-12)
    delta = np.abs(continued[:, 1:4] - mine[:, 1:4]).max() / scale
    E, again = np.array(whole["values"][split:]), np.array(first["values"][split:])
    assert len(E) >= 5 and np.all(np.abs(again - E) / E <= 10 * max(delta, 1e-16) / E)
    assert first["max"] == pytest.approx(whole["max"], rel=10 * max(delta, 1e-16) / E.min())


def test_two_ranks_equal_one(basis_file, reduced_run, tmp_path):
    """``mpirun -n 2 rom run`` equals the serial run (:func:`reduced_run`) to 1e-9 of the
    largest |x, y, z|: the two differ by the order of sums (the reduced residual's
    allreduce, the distributed assembly), each Newton solve to rtol 1e-10, as
    tests/test_rom.py (d) (measured 2e-16 m, 2e-13 relative)."""
    runs = {1: probes(reduced_run)}
    out = tmp_path / "n2"
    args = ["--basis", str(basis_file), "--out", str(out), "--quiet"]
    proc = cli("rom", "run", str(PAPER), *SHORT, *args, ranks=2)
    assert proc.returncode == 0, proc.stderr
    runs[2] = probes(out)
    scale = np.abs(runs[1][:, 1:4]).max()
    assert np.abs(runs[1] - runs[2]).max() <= 1e-9 * scale


#: A sweep of the short paper scene over the load's amplitude f0 (1 to 3 kN/m, 5 members).
SWEEP = """[sweep]
scene = "{scene}"
keep = "probes"
[sweep.set]
"time.end" = 0.006
"output.xdmf" = false
"parameters.f0" = 2e3
"loads.force_density" = ["f0*sin(pi*s/L)*sin(8*omega0*t)", "f0*sin(pi*s/L)*sin(8*omega0*t)", 0]
[sweep.vary]
"parameters.f0" = {{ start = 1e3, stop = 3e3, num = 5 }}
"""
ROM = f"[sweep.rom]\ntrain = [0, 4]\ntolerance = {TOLERANCE}\n"


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """The amplitude sweep run in full and with [sweep.rom] trained on members 0 and 4."""
    folder = tmp_path_factory.mktemp("sweeps")
    full, reduced = folder / "full.toml", folder / "reduced.toml"
    full.write_text(SWEEP.format(scene=PAPER))
    reduced.write_text(SWEEP.format(scene=PAPER) + ROM)
    for path in (full, reduced):
        cf.sweep(cf.load_sweep(path), folder / path.stem)
    return folder


def test_reduced_sweep_members_are_within_the_bound(sweeps):
    """Every member of the reduced sweep (trained on members 0 and 4 only, f0 = 1 and 3 kN/m)
    is within 10 √ε of its full member, relative L2 of the free end (docs/rom.md §7, ε the
    basis's energy left out): the tip deflects 1e-3 ℓ, so the members' responses are, to
    O(1e-3), multiples of one another and each lies in the training span to the same ε
    (measured 0.9-2.8 √ε, √ε = 7.6e-5). The table says "reduced" for each member and
    "full" nowhere; the basis trained in rom/ names its two runs."""
    rows = read_table(sweeps / "reduced" / "sweep.csv")
    assert [r["model"] for r in rows] == ["reduced"] * 5
    assert [r["status"] for r in rows] == ["completed"] * 5
    assert "model" not in read_table(sweeps / "full" / "sweep.csv")[0]
    document = json.loads((sweeps / "reduced" / "rom" / "basis.json").read_text())
    assert [run["name"] for run in document["provenance"]["runs"]] == ["m00000", "m00004"]
    eps = document["provenance"]["energy_left_out"]
    assert 0 < eps <= TOLERANCE
    for m in range(5):
        full = probes(sweeps / "full" / "members" / f"m{m:05d}")[:, 1:4]
        reduced = probes(sweeps / "reduced" / "members" / f"m{m:05d}")[:, 1:4]
        error = relative_l2(reduced, full)
        assert 0 < error <= ERROR_CONSTANT * math.sqrt(eps), (m, error)


def test_validate_reports_the_errors_of_its_probes(sweeps, tmp_path, capsys):
    """``rom validate --sweep --members 0:5:2`` on the sweep's trained basis: validation.csv
    has members 0, 2, 4, and each error equals the relative L2 error computed here from the
    probes.csv of its full and reduced runs to 1e-12 relative (the same doubles, read back
    from 17 digits: only the order of the sums differs); each reduced run equals the reduced
    sweep's member (the same run) to 1e-12 of its largest value; the indicator reads "n/a"
    where the reduced solver reports none."""
    path = sweeps / "reduced.toml"
    basis = sweeps / "reduced" / "rom" / "basis.npz"
    out = tmp_path / "validation"
    args = ["--sweep", str(path), "--members", "0:5:2", "--basis", str(basis), "--out", str(out)]
    assert main(["rom", "validate", *args]) == 0
    printed = capsys.readouterr().out
    rows = read_table(out / "validation.csv")
    assert [r["target"] for r in rows] == ["m00000", "m00002", "m00004"]
    for row in rows:
        name = row["target"]
        full = probes(out / "full" / name)[:, 1:4]
        reduced = probes(out / "reduced" / name)[:, 1:4]
        assert float(row["error"]) == pytest.approx(relative_l2(reduced, full), rel=1e-12)
        sweep = probes(sweeps / "reduced" / "members" / name)[:, 1:4]
        assert np.abs(sweep - reduced).max() <= 1e-12 * np.abs(sweep).max()
        summary = json.loads((out / "reduced" / name / "summary.json").read_text())
        indicator = summary["rom"]["indicator"]["max"]
        assert row["indicator"] == repr(float(indicator))
        assert f"{float(row['error']):.3e}" in printed


def test_frequency_response_with_reduced_members(tmp_path):
    """tests/test_response.py's linear rod (4 elements, Kelvin-Voigt damping ζ1 = 0.1) forced
    at r = 0.9, 1, 1.1 ω0, chains up and down, each member from its predecessor's final state,
    in full and with [sweep.rom] trained on r = 0.9 and 1.1 from rest: every reduced member
    settles after as many periods as its full one and its probes are within 10 √ε of the full
    member's, relative L2 (docs/rom.md §7; the chain hands on the reduced state, and the
    bound holds for the chain as for one run: measured 1.1-1.3 √ε, √ε = 5.9e-6 at 2 modes).
    The table's model column is "reduced", and its amplitudes are the full ones to 10 √ε of
    theirs: a half range moves by at most the largest change of its samples, max |Δx| over
    the window, which for an error spread over the run as the L2 measure sees it is the
    relative L2 error times the amplitude (measured 1.4e-6 relative, 40x under the bound)."""
    from test_response import SHORT_CHAINS, sweep_file

    rows = {}
    for name, rom in (("full", ""), ("reduced", ROM.replace("[0, 4]", "[0, 2]"))):
        (tmp_path / name).mkdir()
        path = sweep_file(tmp_path / name, [0.9, 1.0, 1.1], SHORT_CHAINS)
        path.write_text(path.read_text() + rom)
        cf.sweep(cf.load_sweep(path), tmp_path / name / "out")
        rows[name] = read_table(tmp_path / name / "out" / "sweep.csv")
    document = json.loads((tmp_path / "reduced" / "out" / "rom" / "basis.json").read_text())
    bound = ERROR_CONSTANT * math.sqrt(document["provenance"]["energy_left_out"])
    assert [r["model"] for r in rows["reduced"]] == ["reduced"] * 6
    for full, reduced in zip(rows["full"], rows["reduced"], strict=True):
        assert reduced["status"] == "completed" and reduced["periods"] == full["periods"]
        name = f"m{int(full['member']):05d}"
        x = [probes(tmp_path / k / "out" / "members" / name)[:, 1:4] for k in ("full", "reduced")]
        assert relative_l2(x[1], x[0]) <= bound, name
        amp = float(full["amp_x"])
        assert abs(float(reduced["amp_x"]) - amp) <= bound * amp, name


def test_the_sweep_key_chooses_the_model_and_the_basis_is_the_sweeps(basis_file, tmp_path):
    """model = "full" needs no basis and keeps the model column; a sweep on a basis file is
    another sweep (its fingerprint: a folder holding it refuses the other) when the file's
    bytes change, the same when they do not."""
    from cosserat_fem.studies.sweep_run import columns

    full = cf.load_sweep(_sweep_with(tmp_path, "full", '[sweep.rom]\nmodel = "full"\n'))
    assert not full.reduced and "model" in columns(full)
    copy = tmp_path / "copy.npz"
    copy.write_bytes(basis_file.read_bytes())
    copy.with_suffix(".json").write_bytes(basis_file.with_suffix(".json").read_bytes())
    on = cf.load_sweep(_sweep_with(tmp_path, "on", '[sweep.rom]\nbasis = "copy.npz"\n'))
    assert on.reduced and on.rom.digest == hashlib.sha256(copy.read_bytes()).hexdigest()
    again = cf.load_sweep(_sweep_with(tmp_path, "on", '[sweep.rom]\nbasis = "copy.npz"\n'))
    assert again.fingerprint() == on.fingerprint()
    copy.write_bytes(basis_file.read_bytes() + b"\0")
    changed = cf.load_sweep(_sweep_with(tmp_path, "on", '[sweep.rom]\nbasis = "copy.npz"\n'))
    assert changed.fingerprint() != on.fingerprint()


def _sweep_with(folder, name: str, rom: str) -> str:
    path = folder / f"{name}.toml"
    path.write_text(SWEEP.format(scene=PAPER) + rom)
    return str(path)


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["rom", "run", str(PAPER)], "rom run --basis: give the basis file"),
        (["rom", "run", str(PAPER), "--basis", "{tmp}/none.npz"], "--basis: no basis file"),
        (["rom", "build", str(PAPER), "--tolerance", "1e-8"], "rom build --out:"),
        (
            ["rom", "build", str(PAPER), "--tolerance", "2", "--out", "{tmp}/b"],
            "--tolerance: must be a number in [0, 1), got 2.0",
        ),
        (
            ["rom", "build", str(PAPER), "--modes", "3", "--out", "{tmp}/file/b"],
            "--out: cannot write to",
        ),
        (
            ["rom", "validate", str(PAPER), "--basis", "{tmp}/none.npz", "--out", "{tmp}/s"],
            "--basis: no basis file",
        ),
        (
            ["rom", "build", str(PAPER), "--tolerance", "1e-8", "--modes", "3", "--out", "b"],
            "--tolerance, --modes: give one",
        ),
        (
            ["rom", "build", "--sweep", "{sweep}", "--members", "0,9", "--modes", "2"]
            + ["--out", "{tmp}/b"],
            "--members: member 9 out of range (the sweep has members 0 to 4)",
        ),
        (["sweep", "{norom}", "--out", "{tmp}/s"], "sweep.rom: the reduced members need a basis"),
        (["sweep", "{far}", "--out", "{tmp}/s"], "sweep.rom.train: member 7 out of range"),
        (["sweep", "{nofile}", "--out", "{tmp}/s"], "sweep.rom.basis: no basis file"),
        (
            ["rom", "build", str(PAPER), "--modes", "3", "--ecsw", "1.5", "--out", "{tmp}/b"],
            "--ecsw: must be a number in (0, 1), got 1.5",
        ),
        (["sweep", "{ecsw}", "--out", "{tmp}/s"], "sweep.rom.ecsw: must be a number in (0, 1)"),
        (["sweep", "{grouped}", "--out", "{tmp}/s"], "sweep.rom.ecsw: hyper-reduced members"),
    ],
)
def test_bad_input_is_one_line(tmp_path, capsys, argv, fragment):
    """Each bad input: exit status 2, one line on stderr naming the option or key, no
    traceback, before any run (nothing written in the output folder)."""
    files = {
        name: _sweep_with(tmp_path, name, rom)
        for name, rom in (
            ("sweep", ""),
            ("norom", "[sweep.rom]\ntolerance = 1e-8\n"),
            ("far", "[sweep.rom]\ntrain = [0, 7]\nmodes = 3\n"),
            ("nofile", '[sweep.rom]\nbasis = "missing.npz"\n'),
            ("ecsw", "[sweep.rom]\ntrain = [0]\nmodes = 2\necsw = 0\n"),
        )
    }
    grouped = SWEEP.format(scene=PAPER).replace("[sweep]\n", "[sweep]\ngroup_size = 2\n", 1)
    files["grouped"] = str(tmp_path / "grouped.toml")
    (tmp_path / "grouped.toml").write_text(
        grouped + "[sweep.rom]\ntrain = [0]\nmodes = 2\necsw = 0.01\n"
    )
    (tmp_path / "file").write_text("")  # a file where a folder is asked for
    argv = [a.format(tmp=tmp_path, **files) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0], err
    assert not (tmp_path / "s").exists() and not (tmp_path / "b.npz").exists()


def test_a_basis_of_another_mesh_or_rest_state_is_refused(basis_file, tmp_path, capsys):
    """A basis of the 8-element scene run (or validated) on 12 elements, and training on two
    scenes whose rest states differ (8 and 12 elements: U_ref is not shared), are refused in
    one line naming the key (exit 2), the run before its folder is made and the validation
    before its full run."""
    argv = ["rom", "run", str(PAPER), *SHORT, "--set", "discretisation.elements=12"]
    assert main([*argv, "--basis", str(basis_file), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "elements" in err[0] and "paper.npz" in err[0], err
    assert not (tmp_path / "r").exists()  # refused before its folder is made
    argv = ["rom", "validate", str(PAPER), *SHORT, "--set", "discretisation.elements=12"]
    assert main([*argv, "--basis", str(basis_file), "--out", str(tmp_path / "v")]) == 2
    assert "elements" in capsys.readouterr().err and not (tmp_path / "v").exists()
    other = tmp_path / "twelve.toml"
    text = PAPER.read_text().replace("elements = 8 ", "elements = 12")
    other.write_text(text.replace("end = 0.06 ", "end = 0.0003"))
    short = tmp_path / "short.toml"
    short.write_text(PAPER.read_text().replace("end = 0.06 ", "end = 0.0003"))
    argv = ["rom", "build", str(short), str(other), "--modes", "2", "--out", str(tmp_path / "b")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "snapshots: every run of a basis starts from the same" in err[0]
    assert not (tmp_path / "b.npz").exists()


def test_fifos_at_the_basis_and_table_names_hang_nothing(basis_file, tmp_path, capsys):
    """A FIFO where a reduced command reads or writes a file (a basis's .json, the .npz and
    .json of ``rom build --out``, validation.csv) blocks nothing (each open of a FIFO would
    wait for a writer for ever): the read is refused in one line naming the file and that it
    is a FIFO, the writes replace the FIFOs with the files (a fresh name, then a rename)."""
    copy = tmp_path / "copy"
    (tmp_path / "copy.npz").write_bytes(basis_file.read_bytes())
    os.mkfifo(tmp_path / "copy.json")
    argv = ["rom", "run", str(PAPER), *SHORT, "--basis", str(copy) + ".npz"]
    with fails_if_hung(120, "reading a FIFO as the basis's .json"):
        assert main([*argv, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "copy.npz" in err[0] and "FIFO" in err[0], err
    built = tmp_path / "built"
    for suffix in (".npz", ".json"):
        os.mkfifo(built.with_suffix(suffix))
    argv = ["rom", "build", str(PAPER), "--set", "time.end=0.0003", "--modes", "2"]
    with fails_if_hung(120, "rom build writing over FIFOs"):
        assert main([*argv, "--out", str(built)]) == 0
    assert all(built.with_suffix(s).is_file() for s in (".npz", ".json"))
    document = json.loads(built.with_suffix(".json").read_text())
    assert document["provenance"]["modes"] == 2
    out = tmp_path / "v"
    out.mkdir()
    os.mkfifo(out / "validation.csv")
    argv = ["rom", "validate", str(PAPER), "--set", "time.end=0.0003"]
    with fails_if_hung(120, "rom validate writing over a FIFO"):
        assert main([*argv, "--basis", str(built) + ".npz", "--out", str(out)]) == 0
    rows = read_table(out / "validation.csv")
    assert (out / "validation.csv").is_file() and len(rows) == 1


#: ECSW's fit tolerance of the hyper-reduced bases here, and the error it may add to the
#: Galerkin run's (docs/rom.md §9: at most 0.019 τ measured on the riser, 0.0035 τ on the
#: paper's rod; tests/test_rom_hyper.py holds 0.1 τ).
ECSW = 1e-2
ECSW_ADDED = 0.1


def test_rom_build_ecsw_runs_hyper_reduced(basis_file, tmp_path):
    """``rom build --ecsw τ`` on the short paper scene: the basis file records ECSW's fit
    (its error ≤ τ, the selection's stop rule) and ``rom run`` on it is hyper-reduced (the
    summary's loop "hyper"), within 10 √ε + 0.1 τ of the full run (§7's bound for the Galerkin
    run plus ECSW's added error, tests/test_rom_hyper.py (b))."""
    stem = tmp_path / "hyper"
    args = ["--tolerance", str(TOLERANCE), "--ecsw", str(ECSW), "--out", str(stem)]
    proc = cli("rom", "build", str(PAPER), *SHORT, *args)
    assert proc.returncode == 0, proc.stderr
    document = json.loads(stem.with_suffix(".json").read_text())
    fit = document["provenance"]["ecsw"]
    assert 0 < fit["elements"] <= 8 and fit["fit_error"] <= ECSW
    out = tmp_path / "run"
    proc = cli("rom", "run", str(PAPER), *SHORT, "--basis", f"{stem}.npz", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["newton"]["loop"] == "hyper"
    full = probes(basis_file.parent / "training" / "scene")[:, 1:4]
    eps = document["provenance"]["energy_left_out"]
    error = relative_l2(probes(out)[:, 1:4], full)
    assert 0 < error <= ERROR_CONSTANT * math.sqrt(eps) + ECSW_ADDED * ECSW


def test_a_hyper_reduced_sweep_under_mpirun_equals_serial(tmp_path):
    """[sweep.rom] with ``ecsw``: the basis is trained on rank 0 alone (ECSW is serial) while
    the other rank waits, then the members run hyper-reduced on one rank each. Under
    ``mpirun -n 2`` the basis file is the serial one's (the same serial runs: its bytes
    equal) and every member equals its serial run to 1e-12 of the largest |x, y, z| (the
    same serial arithmetic on each rank; probes.csv's 17 digits give the doubles back); the
    sweep started again keeps its basis file untouched. The training members are within
    10 √ε + 0.1 τ of their full runs (as above)."""
    path = tmp_path / "hyper.toml"
    path.write_text(SWEEP.format(scene=PAPER) + ROM + f"ecsw = {ECSW}\n")
    folders = {}
    for ranks in (1, 2):
        folders[ranks] = tmp_path / f"n{ranks}"
        proc = run_command(
            ["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(folders[ranks])], ranks
        )
        assert proc.returncode == 0, proc.stderr
    basis = [(folders[r] / "rom" / "basis.npz").read_bytes() for r in (1, 2)]
    assert basis[0] == basis[1]
    # started again, the two-rank sweep reads its basis (on one rank, as its members do) and
    # neither trains nor writes it again (before: refused on two ranks, so retrained)
    stamp = (folders[2] / "rom" / "basis.npz").stat().st_mtime_ns
    proc = run_command(["-m", "cosserat_fem.cli", "sweep", str(path), "--out", str(folders[2])], 2)
    assert proc.returncode == 0, proc.stderr
    assert (folders[2] / "rom" / "basis.npz").stat().st_mtime_ns == stamp
    document = json.loads((folders[1] / "rom" / "basis.json").read_text())
    eps = document["provenance"]["energy_left_out"]
    for m in range(5):
        runs = [probes(folders[r] / "members" / f"m{m:05d}") for r in (1, 2)]
        scale = np.abs(runs[0][:, 1:4]).max()
        assert np.abs(runs[0] - runs[1]).max() <= 1e-12 * scale
        summary = json.loads((folders[2] / "members" / f"m{m:05d}" / "summary.json").read_text())
        assert summary["newton"]["loop"] == "hyper"
        if m in (0, 4):  # the training members: their full runs are kept in rom/training
            full = probes(folders[1] / "rom" / "training" / f"m{m:05d}")[:, 1:4]
            error = relative_l2(runs[0][:, 1:4], full)
            assert 0 < error <= ERROR_CONSTANT * math.sqrt(eps) + ECSW_ADDED * ECSW


def test_a_basis_is_its_own_pair_of_files(basis_file, tmp_path, capsys):
    """A basis's name keeps its dots (paper.v1 and paper.v2 are two bases: the suffixes are
    appended, not replaced; before, v2 overwrote v1's files and a run on "v1" used v2's modes
    silently); an .npz beside another basis's .json is refused in one line (its SHA-256 is
    in the .json); a basis of a clamped rod on a pinned one is refused naming the supports
    (the Dirichlet rows every mode holds at zero are not the run's)."""
    short = ["--set", "time.end=0.0003"]
    for name, modes in (("paper.v1", "3"), ("paper.v2", "2")):
        argv = ["rom", "build", str(PAPER), *short, "--modes", modes]
        assert main([*argv, "--out", str(tmp_path / name)]) == 0
    capsys.readouterr()
    files = sorted(p.name for p in tmp_path.iterdir() if p.suffix in (".npz", ".json"))
    assert files == ["paper.v1.json", "paper.v1.npz", "paper.v2.json", "paper.v2.npz"]
    out = tmp_path / "r1"
    argv = ["rom", "run", str(PAPER), *short, "--basis", str(tmp_path / "paper.v1.npz")]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "summary.json").read_text())["rom"]["basis"]["modes"] == 3
    (tmp_path / "mixed.npz").write_bytes((tmp_path / "paper.v1.npz").read_bytes())
    (tmp_path / "mixed.json").write_bytes((tmp_path / "paper.v2.json").read_bytes())
    capsys.readouterr()
    argv = ["rom", "run", str(PAPER), *short, "--basis", str(tmp_path / "mixed.npz")]
    assert main([*argv, "--out", str(tmp_path / "r2")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "mixed.npz" in err[0] and "not the .npz its .json" in err[0], err
    argv = ["rom", "run", str(PAPER), *SHORT, "--set", "supports.start=pinned"]
    assert main([*argv, "--basis", str(basis_file), "--out", str(tmp_path / "r3")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "made for supports" in err[0], err


def test_validate_keeps_every_row_it_made(tmp_path, capsys):
    """``rom validate`` writes validation.csv after each target: the whip in 3D (its basis of
    its first 0.4 ms, 4 modes; the reduced run is refused at the chart's move, docs/rom.md §10
    (c), here at 0.2 ms) gives a row whose status is that one line and no error (before: no
    table at all, the full run's outputs left without it); validated again into the same
    folder over 0.15 ms, before the move, its row is replaced by a completed one (a target's
    row is its latest validation's)."""
    whip = ROOT / "scenes" / "whip.toml"
    in_3d = ["--set", "discretisation.planar=off", "--set", "output.xdmf=false"]
    stem = tmp_path / "whip"
    argv = ["rom", "build", str(whip), *in_3d, "--set", "time.end=4e-4", "--modes", "4"]
    assert main([*argv, "--out", str(stem)]) == 0
    out = tmp_path / "v"
    argv = ["rom", "validate", str(whip), *in_3d, "--basis", f"{stem}.npz", "--out", str(out)]
    assert main(argv) == 0
    (row,) = read_table(out / "validation.csv")
    assert row["target"] == "scene" and row["error"] == "n/a" and "chart" in row["status"]
    assert row["status"].startswith("reduced run at t = 0.000")
    assert "failed: reduced run at t = " in capsys.readouterr().out
    assert main([*argv, "--set", "time.end=1.5e-4"]) == 0
    (row,) = read_table(out / "validation.csv")
    assert row["status"] == "completed" and float(row["error"]) > 0


def test_a_reduced_run_stopped_by_its_wall_time_says_how_to_go_on(basis_file, tmp_path, capsys):
    """A reduced run past limits.wall_time stops with exit 4 and advises ``rom run --restart
    DIR --basis FILE`` (before: ``run --restart DIR``, which refuses a reduced run); that
    advice continues it to the end. The limit: 1.01 times the budget's lower bound of the
    run's cost (cosserat_fem/analysis/budget.py ``estimate``, so it is not refused before it
    starts; tests/test_reliability.py D8): the run's set-up alone, counted from its start,
    exceeds it before the clock is first looked at (step 64 of 200)."""
    from cosserat_fem.analysis.budget import estimate

    bound = estimate(cf.load(PAPER, {"time.end": 0.006}), "run").seconds
    out = tmp_path / "stopped"
    argv = ["rom", "run", str(PAPER), *SHORT, "--basis", str(basis_file), "--out", str(out)]
    assert main([*argv, "--set", f"limits.wall_time={1.01 * bound!r}"]) == 4
    err = capsys.readouterr().err
    assert "rom run --restart DIR --basis FILE" in err and "continue it with run" not in err
    argv = ["rom", "run", "--restart", str(out), "--basis", str(basis_file)]
    assert main([*argv, "--set", "limits.wall_time=600"]) == 0
    assert probes(out).shape == (201, 7)
