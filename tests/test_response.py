"""Frequency responses (cosserat_fem/studies/response.py, the [sweep.response] of a sweep): settled
periods, amplitudes and phases, continuation along a chain of members, and the linear
response against the closed-form modal steady state.

The reference of the linear test is tests/modal_checks.py's ``linear_steady_state``: the
linearised equations solved in the frequency domain, (K + iΩC − Ω²M) P = f̂, which for
Kelvin–Voigt damping (C = τ_d ω0 K) is the modal steady state Σ_n φ_n ψ_nᵀ f̂ /
(λ_n (1 + iΩ τ_d ω0) − Ω²) over every mode of the same discretisation: it shares nothing with
the time loop, the nonlinear residual or the settling criterion that it checks.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, read_table, run_command, said, sweep_serial_and_mpi

from cosserat_fem import api
from cosserat_fem.common.errors import SceneError
from cosserat_fem.studies.response import PeriodicResponse, ResponseSettings, continued_start

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
OMEGA1 = 207.0236  # rad/s, the paper's first bending frequency (about d2: x), its omega0
ZETA1 = 0.1  # the first mode's damping ratio, ζ1 = τ_d ω1 / 2
TAU_D = 2 * ZETA1 / OMEGA1  # s, Kelvin–Voigt retardation time

#: The paper's rod, 4 cubic elements, Kelvin–Voigt damping, 1 N/m in x at r ω0: linear
#: (tip amplitude ~2e-5 m: the geometric terms are (u/ℓ)² ~ 1e-9 of the response).
SET = {
    "time.step": 1e-4,
    "output.xdmf": False,
    "output.checkpoint": False,
    "damping.retardation_time": TAU_D,
    "discretisation.elements": 4,
    "loads.force_density": ["1*sin(pi*s/L)*sin(r*omega0*t)", 0, 0],
    "parameters.r": 1.0,
}


def sweep_file(folder: Path, values: list[float], response: dict, **sweep) -> Path:
    """A sweep of the paper's rod (:data:`SET`) over r = Ω/ω0 with ``response`` settings."""
    import json

    lines = ["[sweep]", f'scene = "{PAPER}"', 'keep = "probes"']
    lines += [f"{k} = {json.dumps(v)}" for k, v in sweep.items()]
    lines += ["[sweep.set]", *(f'"{k}" = {json.dumps(v)}' for k, v in SET.items())]
    lines += ["[sweep.vary]", f'"parameters.r" = {json.dumps(values)}', "[sweep.response]"]
    lines += [f"{k} = {json.dumps(v)}" for k, v in response.items()]
    path = folder / "sweep.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


PERIOD = {"period": "2*pi/(r*omega0)"}
#: Up and down chains that check the dealing, not the physics: 40 steps a period, settled at
#: a change below 5e-2 for one period (5-6 periods a member).
SHORT_CHAINS = {
    **PERIOD,
    "continuation": "parameters.r",
    "direction": "both",
    "tolerance": 5e-2,
    "steps_per_period": 40,
    "settled_periods": 1,
    "measure_periods": 1,
}


@pytest.fixture(scope="module")
def linear_sweep(tmp_path_factory):
    """Three members about the first resonance, r = 0.9, 1, 1.1, continued upwards."""
    folder = tmp_path_factory.mktemp("linear")
    path = sweep_file(folder, [0.9, 1.0, 1.1], {**PERIOD, "continuation": "parameters.r"})
    spec = api.load_sweep(path)
    api.sweep(spec, folder / "out")
    return spec, folder / "out", read_table(folder / "out" / "sweep.csv")


def test_the_linear_response_is_the_modal_steady_state(linear_sweep):
    """The free end's first harmonic (amplitude and phase, of x and of ψ) equals the linear
    steady state, within what the settling criterion leaves of the start-up transient.

    A transient e^{−ζωt} that changed a column by δ S (the row's ``change`` δ, relative to
    the motion's size S in one unit: the largest of the half ranges of x/ℓ, y/ℓ, z/ℓ and of
    θ, ψ, φ; here ψ's, 1.38 x/ℓ at the tip) over the last period is still at most
    δ S / (1 − e^{−ζ1 ω1 T}) of it: the first mode decays slowest (ζ_n ω_n = τ_d ω_n²/2
    grows with n). Relative to the column's own size h1_c that is δ / (1 − e^{−ζ1 ω1 T})
    S_c / h1_c (S_c = ℓ S for x, S for ψ). Beyond it, SDIRK3's error in the steady state at
    Ω Δt ≤ 0.023 is O((Ω Δt)³) ~ 1e-5 times the resonance's amplification (1/2ζ1 = 5), and
    the geometric terms ~1e-9: 1e-4 covers both. The phase's error is the same relative
    amount in radians. Measured (r = 0.9, 1, 1.1): amplitude 4.2e-5, 1.4e-4, 3.1e-4 and phase
    2.2e-4, 4.1e-4, 2.1e-4 of x, against bounds 6.3e-4, 8.8e-4, 1.1e-3 (ψ: 4.9e-4, 6.7e-4,
    8.0e-4)."""
    from modal_checks import linear_steady_state

    spec, _, rows = linear_sweep
    for member, row in zip(spec.members, rows, strict=True):
        assert row["status"] == "completed" and row["settled"] == "true", row
        period = spec.period(member)
        reference = linear_steady_state(spec.scene(member), 2 * math.pi / period)
        left = float(row["change"]) / (1 - math.exp(-ZETA1 * OMEGA1 * period))
        size = max(
            *(float(row[f"amp_{c}"]) for c in ("x", "y", "z")),  # ℓ = 1 m
            *(float(row[f"amp_{c}"]) for c in ("theta", "psi", "phi")),
        )
        for column, index in (("x", 0), ("psi", 4)):
            h1, phase = float(row[f"h1_{column}"]), float(row[f"phase_{column}"])
            bound = left * size / h1 + 1e-4
            assert abs(h1 / abs(reference[index]) - 1) <= bound, (row, column, reference)
            assert abs(phase - np.angle(reference[index])) <= bound, (row, column)
        bound = left * size / float(row["h1_x"]) + 1e-4
        assert float(row["amp_x"]) == pytest.approx(float(row["h1_x"]), rel=bound)
        assert abs(float(row["mean_x"])) <= bound * float(row["h1_x"])


def test_a_chain_continues_its_previous_member(linear_sweep):
    """Each member after the first starts from its predecessor's final state at the time the
    forcing has its phase (the load is continuous across the switch), and it is that run
    alone: the same probes.csv byte for byte, the same measured response."""
    spec, out, rows = linear_sweep
    assert [r["previous"] for r in rows] == ["", "0", "1"]
    assert [r["direction"] for r in rows] == ["up"] * 3
    for before, row, member in zip(rows, rows[1:], spec.members[1:], strict=False):
        t_end, start = float(before["end_s"]), float(row["start_s"])
        period_before, period = spec.period(spec.members[member.index - 1]), spec.period(member)
        assert 0 <= start < period
        assert start / period == pytest.approx(math.modf(t_end / period_before)[0], abs=1e-12)
    member = spec.members[2]
    with np.load(out / "members" / "m00001" / "final_state.npz") as data:
        state = data["U0"]
    scene = spec.scene(member, spec.span(member, float(rows[2]["start_s"])))
    response = PeriodicResponse(spec.response, spec.period(member), 1.0)
    alone = out.parent / "alone"
    api.run(scene, alone, observers=[response], initial_state=state)
    assert (alone / "probes.csv").read_bytes() == (
        out / "members" / "m00002" / "probes.csv"
    ).read_bytes()
    assert repr(response.result["h1_x"]) == rows[2]["h1_x"]
    assert int(rows[2]["periods"]) == response.result["periods"]


def test_a_restarted_chain_continues_from_the_saved_state(linear_sweep, tmp_path):
    """A sweep killed during its third member (its row cut) runs only that member again,
    from the second's saved final state: the same row to the last digit."""
    spec, out, rows = linear_sweep
    import shutil

    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    part = copy / "table" / "group-0.csv"
    lines = part.read_text(encoding="utf-8").splitlines(keepends=True)
    part.write_text("".join(lines[:3]) + lines[3][:50], encoding="utf-8")
    (copy / "sweep.csv").unlink()
    result = api.sweep(spec, copy)
    assert (result.ran, result.skipped) == (1, 2)
    again = read_table(copy / "sweep.csv")
    for old, new in zip(rows, again, strict=True):
        assert {k: v for k, v in old.items() if k != "wall_s"} == {
            k: v for k, v in new.items() if k != "wall_s"
        }


def test_plot_draws_the_response_of_each_chain(linear_sweep, tmp_path):
    """``cosserat-fem plot DIR`` of a frequency response: sweep.png and response.png (1300 ×
    1040 px), the latter with a row of panels per moving column (here x and ψ)."""
    import struct

    _, out, _ = linear_sweep
    proc = run_command(["-m", "cosserat_fem.cli", "plot", str(out), "--out", str(tmp_path)])
    assert proc.returncode == 0, proc.stderr
    png = (tmp_path / "response.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and struct.unpack(">II", png[16:24]) == (1300, 1040)
    assert (tmp_path / "sweep.png").is_file()


def _copy(out: Path, folder: Path) -> Path:
    """A copy of a sweep's folder without its members' folders but their summary.json."""
    import shutil

    shutil.copytree(out, folder, ignore=shutil.ignore_patterns("*.npz", "probes.csv"))
    return folder


@pytest.fixture
def figures(monkeypatch):
    """plot's figures drawn but not rasterised (savefig is most of a figure's time): the
    number of axes of each figure, by file name."""
    from cosserat_fem import plot

    drawn: dict[str, int] = {}

    def save(fig, path):
        drawn[path.name] = len(fig.axes)
        plot._pyplot().close(fig)
        return path

    monkeypatch.setattr(plot, "_save", save)
    return drawn


def _mutate(rng, folder: Path) -> str:
    """One random damage to a sweep's table (sweep.csv, or its part with sweep.csv gone) or
    to its sweep.json: a column or a field removed, a field replaced, characters cut or
    inserted, a line repeated. What was done."""
    name = rng.choice(["sweep.csv", "sweep.json", "table/group-0.csv"])
    if name.startswith("table"):
        (folder / "sweep.csv").unlink()
    path = folder / name
    text = path.read_text(encoding="utf-8")
    lines = [line.split(",") for line in text.splitlines()]
    kind = rng.randrange(6)
    row = rng.randrange(len(lines))
    column = rng.randrange(len(lines[row]))
    if kind == 0:
        lines = [line[:column] + line[column + 1 :] for line in lines]
    elif kind == 1:
        del lines[row][column]
    elif kind == 2:
        lines[row][column] = rng.choice(
            [
                "",
                "x",
                "nan",
                "1e999",
                "true",
                "[1]",
                '"a,b"',
                "-1",
                "99",
                "parameters.r",
                "{}",
                "null",
            ]
        )
    if kind <= 2:
        text = "".join(",".join(line) + "\n" for line in lines)
    elif kind == 3:
        i = rng.randrange(len(text))
        text = text[:i] + text[i + rng.randint(1, 30) :]
    elif kind == 4:
        i = rng.randrange(len(text))
        text = text[:i] + rng.choice(',"\n{}[]:x1') + text[i:]
    else:
        repeated = text.splitlines(keepends=True)
        repeated.insert(rng.randrange(len(repeated) + 1), rng.choice(repeated))
        text = "".join(repeated)
    path.write_text(text, encoding="utf-8")
    return f"{name}: damage {kind}"


def _edit_table(folder: Path, edit) -> None:
    """sweep.csv's lines as lists of fields, changed in place by ``edit``."""
    table = folder / "sweep.csv"
    lines = [line.split(",") for line in table.read_text(encoding="utf-8").splitlines()]
    edit(lines)
    table.write_text("".join(",".join(line) + "\n" for line in lines), encoding="utf-8")


def _drop_column(name: str):
    def edit(lines):
        at = lines[0].index(name)
        lines[:] = [line[:at] + line[at + 1 :] for line in lines]

    return edit


DAMAGES = {
    "no amp_x": lambda folder: _edit_table(folder, _drop_column("amp_x")),
    "no phase_x": lambda folder: _edit_table(folder, _drop_column("phase_x")),
    "no varied column": lambda folder: _edit_table(folder, _drop_column("parameters.r")),
    "a short row": lambda folder: _edit_table(folder, lambda lines: lines[2].pop(5)),
    "a long row": lambda folder: _edit_table(folder, lambda lines: lines[2].append("1")),
    "continuation elsewhere": lambda folder: (folder / "sweep.json").write_text(
        '{"members": 3, "varied": ["parameters.r"], "continuation": "amp_x"}'
    ),
    "continuation not text": lambda folder: (folder / "sweep.json").write_text(
        '{"members": 3, "varied": ["parameters.r"], "continuation": [1]}'
    ),
    "varied not a list": lambda folder: (folder / "sweep.json").write_text(
        '{"members": 3, "varied": "parameters.r"}'
    ),
    "a record of another sweep": lambda folder: (folder / "sweep.json").write_text(
        '{"members": 3, "varied": ["time.step"]}'
    ),
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_plot_refuses_damaged_response_tables_in_one_line(linear_sweep, tmp_path, figures, damage):
    """``plot`` of a frequency response whose table or sweep.json is damaged ended in
    internal errors: KeyError 'amp_x', 'phase_x', 'parameters.r' (a column cut off), or a
    continuation key that is no column; TypeError (a row short of fields: its missing ones
    None, sorted against strings). Each is refused in one line naming the file, before
    anything is drawn."""
    from cosserat_fem.plot import plot_run

    _, out, _ = linear_sweep
    folder = _copy(out, tmp_path / "copy")
    DAMAGES[damage](folder)
    with pytest.raises(SceneError) as caught:
        plot_run(folder)
    assert "\n" not in str(caught.value) and str(folder) in str(caught.value)
    assert figures == {}


@pytest.mark.long
def test_plot_of_randomly_damaged_response_tables(linear_sweep, tmp_path, figures):
    """120 seeded damages (:func:`_mutate`) of a frequency response's table, its part or
    sweep.json: each is drawn or refused with one line naming a file (a SceneError), never
    another exception. (~1 min: a drawn case draws two figures.)"""
    import random

    from cosserat_fem.plot import plot_run

    _, out, _ = linear_sweep
    rng = random.Random(25)
    outcomes = {"drawn": 0, "refused": 0}
    for i in range(120):
        folder = _copy(out, tmp_path / f"case{i}")
        what = _mutate(rng, folder)
        try:
            plot_run(folder)
            outcomes["drawn"] += 1
        except SceneError as exc:
            text = str(exc)
            assert "\n" not in text and str(folder) in text, (what, text)
            outcomes["refused"] += 1
    assert outcomes["drawn"] >= 5 and outcomes["refused"] >= 30, outcomes


@pytest.mark.parametrize("case", ["beyond", "twice", "other values", "other part"])
def test_plot_refuses_rows_that_are_not_the_sweeps(linear_sweep, tmp_path, figures, case):
    """Rows that are not the sweep's were merged into its figures silently: a row of a member
    the sweep does not have, a member's second row, a row whose varied values are not the
    member's (a table of another sweep of the same key), a table part of another sweep beside
    the sweep's own. Each is refused in one line naming the table, and nothing is drawn."""
    from cosserat_fem.plot import plot_run

    _, out, _ = linear_sweep
    folder = _copy(out, tmp_path / "copy")
    table = folder / "sweep.csv"
    header, *lines = table.read_text(encoding="utf-8").splitlines(keepends=True)
    if case == "beyond":
        lines.append(lines[-1].replace("2,", "7,", 1))
    elif case == "twice":
        lines.append(lines[0])
    elif case == "other values":
        lines[1] = lines[1].replace(",1.0,", ",1.05,", 1)
    else:  # a part of a sweep without a response: other columns
        table.unlink()
        part = folder / "table" / "group-1.csv"
        columns = header.rstrip("\n").split(",")
        short = columns[: columns.index("direction")] + ["message"]
        part.write_text(
            ",".join(short) + "\n" + ",".join(["3"] + ["0"] * (len(short) - 1)) + "\n",
            encoding="utf-8",
        )
    if case != "other part":
        table.write_text(header + "".join(lines), encoding="utf-8")
    with pytest.raises(SceneError) as caught:
        plot_run(folder)
    assert "\n" not in str(caught.value) and str(folder) in str(caught.value)
    assert figures == {}


def test_plot_draws_no_round_off_as_a_response(linear_sweep, tmp_path, figures):
    """ψ at the mid-span of the clamped rod's symmetric mode is round-off, 1e-16 rad with a
    random phase; response.png drew it as a response (a column counted as moving when its
    largest amplitude was 1e-3 of its group's, here the angles' own largest: itself). A
    column now moves when it is 1e-3 of the motion's size S in its unit (S the largest of
    x/ℓ and the angles over the members, ℓ from the members' summary.json, as
    cosserat_fem/studies/response.py measures settling): the linear sweep's x and ψ (1.7e-5 and
    2.3e-5: both drawn, two rows of panels), and with ψ replaced by round-off x alone (one
    row). Its z, 8e-11 m (second order), is not drawn in either."""
    import random

    from cosserat_fem.plot import plot_run

    _, out, _ = linear_sweep
    plot_run(_copy(out, tmp_path / "linear"))
    assert figures["response.png"] == 4  # x and ψ: amplitude and phase each
    folder = _copy(out, tmp_path / "round-off")
    table = folder / "sweep.csv"
    header, *lines = table.read_text(encoding="utf-8").splitlines(keepends=True)
    columns = header.rstrip("\n").split(",")
    rng = random.Random(16)
    rows = []
    for line in lines:
        fields = line.rstrip("\n").split(",")
        fields[columns.index("amp_psi")] = repr(1e-16 * rng.random())
        fields[columns.index("phase_psi")] = repr(rng.uniform(-math.pi, math.pi))
        rows.append(",".join(fields) + "\n")
    table.write_text(header + "".join(rows), encoding="utf-8")
    plot_run(folder)
    assert figures["response.png"] == 2  # x alone
    from cosserat_fem.plot import moving_columns

    one = np.ones(3)
    amps = {
        "x": 1e-3 * one,
        "y": 0 * one,
        "z": 1e-9 * one,
        "theta": 0 * one,
        "psi": 1e-16 * one,
        "phi": 2e-6 * one,
    }
    assert moving_columns(amps, one) == ["x", "phi"]  # φ: 2e-3 of S = 1e-3
    assert moving_columns(amps, 10 * one) == ["x", "phi"]  # S = 1e-4: φ 2e-2 of it
    assert moving_columns(amps, 1e-3 * one) == ["x"]  # S = 1: φ 2e-6 of it


class _Probe:
    """A probe of a synthetic signal: x(t) given, the other columns 0."""

    is_owner, owner = True, 0

    def __init__(self, signal):
        self.signal, self.t = signal, 0.0

    def values(self):
        return np.array([self.signal(self.t), 0, 0, 0, 0, 0], dtype=float)


class _Loop:
    def __init__(self):
        self.reason = None

    def request_end(self, reason):
        self.reason = reason


def _feed(signal, settings, period, step, until):
    """Feed ``signal`` at every ``step`` to a PeriodicResponse until it ends the run or
    ``until``; the observer and the time it ended."""
    from mpi4py import MPI

    probe, loop = _Probe(signal), _Loop()
    observer = PeriodicResponse(settings, period, 1.0)
    observer.attach(probe, MPI.COMM_SELF, 0.0, 1.0)
    k = 0
    while loop.reason is None and k * step < until:
        k += 1
        probe.t = k * step
        observer.output(loop, k, probe.t)
    loop.state = type("S", (), {"t": probe.t})
    observer.ended(loop, None)
    return observer, probe.t


def test_a_steady_harmonic_is_measured_exactly_and_settles_at_once():
    """x = m + A sin(Ωt + φ), 1000 samples a period: settled after 1 + settled_periods
    periods (the first change is that of periods 1 and 2, then three in a row); amplitude,
    phase and mean to O((ΩΔt)²) ~ 4e-5 of the trapezoidal projections (the half range to
    1 − cos(πΔt/T) ~ 5e-6), so 1e-4."""
    A, phi, m, T = 2.0, 0.7, 0.3, 0.01
    settings = ResponseSettings("T", tolerance=1e-3)
    omega = 2 * math.pi / T
    observer, t = _feed(lambda t: m + A * math.sin(omega * t + phi), settings, T, T / 1000, 1.0)
    assert observer.result["settled"] and observer.result["periods"] == 4
    assert t == pytest.approx(4 * T, rel=1e-12)
    assert observer.result["h1_x"] == pytest.approx(A, rel=1e-4)
    assert observer.result["phase_x"] == pytest.approx(phi, abs=1e-4)
    assert observer.result["mean_x"] == pytest.approx(m, rel=1e-4)
    assert observer.result["amp_x"] == pytest.approx(A, rel=1e-4)


def test_what_the_criterion_leaves_of_a_transient_is_bounded_by_the_damping():
    """x = A sin Ωt + B e^{−αt} sin ω_n t (a forced response and a free transient at 1.3 Ω):
    the amplitude measured once settled differs from A by at most δ / (1 − e^{−αT}) (the
    module docstring's bound, δ the last period's change) plus 1e-4 of sampling; and a run
    too short to settle is flagged."""
    A, B, T = 1.0, 0.5, 0.01
    omega = 2 * math.pi / T
    alpha = 0.05 * 1.3 * omega  # ζ = 0.05
    settings = ResponseSettings("T", tolerance=1e-3)

    def signal(t):
        return A * math.sin(omega * t) + B * math.exp(-alpha * t) * math.sin(1.3 * omega * t)

    observer, _ = _feed(signal, settings, T, T / 500, 10.0)
    result = observer.result
    assert result["settled"]
    bound = result["change"] / (1 - math.exp(-alpha * T)) + 1e-4
    assert abs(result["h1_x"] - A) <= bound * A
    short, _ = _feed(signal, settings, T, T / 500, 5 * T)
    assert not short.result["settled"] and short.result["periods"] == 5


def test_a_continued_start_carries_the_forcing_phase():
    """The start in [0, T) of the next member has the phase the last forcing had."""
    for end, before, period in ((0.371, 0.0303, 0.0275), (1.0, 0.3, 0.5), (2.5e-3, 1e-3, 7e-3)):
        start = continued_start(end, before, period)
        assert 0 <= start < period
        for wave in (math.sin, math.cos):  # the same phase, not its mirror π − φ
            assert wave(2 * math.pi * start / period) == pytest.approx(
                wave(2 * math.pi * end / before), abs=1e-12
            )


@pytest.mark.parametrize(
    ("response", "message"),
    [
        ({**PERIOD, "colour": 1}, "sweep.response.colour: unknown key"),
        ({"continuation": "parameters.r"}, "sweep.response.period: required"),
        (
            {**PERIOD, "direction": "up"},
            "sweep.response.direction: needs sweep.response.continuation",
        ),
        (
            {**PERIOD, "continuation": "time.step"},
            "sweep.response.continuation: must be one of the varied keys (parameters.r)",
        ),
        (
            {**PERIOD, "continuation": "parameters.r", "direction": "sideways"},
            "sweep.response.direction: must be one of 'up', 'down', 'both'",
        ),
        (
            {"period": "-2*pi/(r*omega0)"},
            "sweep member 0 (parameters.r = 0.9): "
            "sweep.response.period: '-2*pi/(r*omega0)' = -0.0337",
        ),
        (
            {"period": "2*pi/(q*omega0)"},
            "sweep member 0 (parameters.r = 0.9): sweep.response.period: ",
        ),
        (
            {"period": "2*pi/(50*r*omega0)"},
            "sweep member 0 (parameters.r = 0.9): time.step: 0.0001 s samples the forcing period",
        ),
        (
            {**PERIOD, "measure_periods": 5},
            "sweep.response.measure_periods: at most settled_periods + 1 = 4",
        ),
        ({**PERIOD, "max_periods": 2}, "sweep.response.max_periods: at least"),
        ({**PERIOD, "tolerance": 0}, "sweep.response.tolerance: must be a positive number"),
        ({**PERIOD, "tolerance": 1.5}, "sweep.response.tolerance: must be < 1"),
        ({**PERIOD, "steps_per_period": 8}, "sweep.response.steps_per_period: at least 16"),
        (
            {**PERIOD, "max_periods": 10**9, "steps_per_period": 1000},
            "sweep member 0 "
            "(parameters.r = 0.9): sweep.response.max_periods: 1000000000 periods of 0.0337223 s: ",
        ),
        (
            {"period": "1e306"},
            "sweep member 0 (parameters.r = 0.9): sweep.response.max_periods: "
            "200 periods of 1e+306 s are not a finite number of steps",
        ),
    ],
)
def test_a_malformed_response_is_refused_before_any_member_runs(tmp_path, response, message):
    path = sweep_file(tmp_path, [0.9, 1.1], response)
    with pytest.raises(SceneError) as caught:
        api.load_sweep(path)
    assert str(caught.value).startswith(message), str(caught.value)
    assert "\n" not in str(caught.value)


def test_several_load_amplitudes_make_a_chain_each(tmp_path):
    """Varying the load's amplitude F as well as r: a chain per amplitude, each continued along
    r. In the linear regime the whole run scales with the load, its start-up transient too, so
    the chains settle after the same periods and twice the load gives twice the first harmonic
    and the same phase, up to the geometric terms, (u/ℓ)² ~ 1e-9 of the response at these
    2e-5 m: within 1e-8 (measured 2.6e-10 and 2.1e-10 in amplitude, 4e-11 rad in phase)."""
    path = sweep_file(tmp_path, [0.95, 1.05], {**PERIOD, "continuation": "parameters.r"})
    text = path.read_text(encoding="utf-8")
    text = text.replace('"1*sin(pi*s/L)*sin(r*omega0*t)"', '"F*sin(pi*s/L)*sin(r*omega0*t)"')
    text = text.replace('"parameters.r" = 1.0\n', '"parameters.r" = 1.0\n"parameters.F" = 1.0\n')
    text = text.replace("[sweep.vary]\n", '[sweep.vary]\n"parameters.F" = [1.0, 2.0]\n')
    path.write_text(text, encoding="utf-8")
    spec = api.load_sweep(path)
    assert sorted(spec.chains) == [(0, 1), (2, 3)]
    rows = api.sweep(spec, tmp_path / "out").rows
    assert [r["previous"] for r in rows] == ["", "0", "", "2"]
    for one, two in zip(rows[:2], rows[2:], strict=True):
        assert one["periods"] == two["periods"]
        assert float(two["h1_x"]) / float(one["h1_x"]) == pytest.approx(2.0, rel=1e-8)
        assert float(two["phase_x"]) == pytest.approx(float(one["phase_x"]), abs=1e-8)


def test_a_case_without_the_continuation_key_is_refused(tmp_path):
    path = sweep_file(tmp_path, [0.9], {**PERIOD, "continuation": "parameters.r"})
    text = path.read_text(encoding="utf-8").replace(
        '[sweep.vary]\n"parameters.r" = [0.9]\n',
        '[[sweep.case]]\n"parameters.r" = 0.9\n[[sweep.case]]\n"time.step" = 5e-5\n',
    )
    path.write_text(text, encoding="utf-8")
    with pytest.raises(
        SceneError,
        match=r"^sweep.response.continuation: 'parameters.r' is not "
        r"set in member 1 \(every case must give it\)$",
    ):
        api.load_sweep(path)


def test_after_a_failed_member_its_chain_goes_on_from_rest(tmp_path, monkeypatch):
    """The middle member of a chain fails (its response observer raises at the start): it is
    recorded, and the next member starts from rest (``previous`` empty) at its scene's start,
    as the first did; a loose tolerance keeps it short."""
    from cosserat_fem.studies import sweep_run as sweep

    path = sweep_file(
        tmp_path, [0.95, 1.0, 1.05], {**PERIOD, "continuation": "parameters.r", "tolerance": 1e-2}
    )
    forced = sweep._forced

    def failing(spec, member, before):
        if member.index == 1:
            raise SceneError("injected: member 1 cannot start")
        return forced(spec, member, before)

    monkeypatch.setattr(sweep, "_forced", failing)
    rows = api.sweep(api.load_sweep(path), tmp_path / "out").rows
    assert [r["status"] for r in rows] == ["completed", "error", "completed"]
    assert rows[1]["message"] == "SceneError: injected: member 1 cannot start"
    assert [r["previous"] for r in rows] == ["", "0", ""]  # the failed one had its start
    assert float(rows[2]["start_s"]) == 0.0


# Long set (make test within 3 minutes): the chains' serial sweep stays in make test.
@pytest.mark.long
@pytest.mark.mpi
def test_up_and_down_chains_under_mpi_equal_the_serial_sweep(tmp_path):
    """direction = "both": each r twice, an upward and a downward chain (4 members); under
    mpirun -n 2 the two chains go to the two groups and the table is the serial one (all but
    wall times: each chain runs on one rank, the serial operations). It checks the dealing
    and the continuation, not the physics: :data:`SHORT_CHAINS`. The same sweep on groups of
    two ranks is refused in the same folder; run in its own (MUMPS):
    test_chains_on_a_group_of_two_ranks_continue_each_ranks_part, in the long set."""
    path = sweep_file(tmp_path, [0.95, 1.05], SHORT_CHAINS)
    tables = sweep_serial_and_mpi(path, tmp_path)
    assert tables[1] == tables[2]
    rows = tables[1]
    assert [(r["direction"], r["parameters.r"], r["previous"]) for r in rows] == [
        ("up", "0.95", ""),
        ("up", "1.05", "0"),
        ("down", "0.95", "3"),
        ("down", "1.05", ""),
    ]
    # The same sweep on groups of two ranks is another sweep for the folder (its saved states
    # are parts of a two-rank partition): refused in one line, before anything runs.
    grouped = sweep_file(tmp_path, [0.95, 1.05], SHORT_CHAINS, group_size=2)
    proc = run_command(
        ["-m", "cosserat_fem.cli", "sweep", str(grouped), "--out", str(tmp_path / "n2")], 2
    )
    errors = said(proc.stderr)
    assert proc.returncode == 2 and len(errors) == 1 and "holds another sweep" in errors[0]
    assert "Traceback" not in proc.stderr


@pytest.mark.long  # four members on a group of two ranks: ~8 s on two idle cores, 25 s busy
@pytest.mark.mpi
def test_chains_on_a_group_of_two_ranks_continue_each_ranks_part(tmp_path):
    """group_size = 2 under mpirun -n 2: each chain runs on both ranks (MUMPS, each rank's part
    of the state saved and continued): the serial sweep's periods, and its amplitudes to the
    LU's rounding (a state continued from a wrong part would be off by its whole size). The
    members' changes in their last period were 0.029-0.049 against the tolerance 5e-2: the
    LU's and MUMPS's rounding, ~1e-13 relative, cannot move a member's settling period. With
    300 steps a period and a tolerance of 1e-2 these members took 38 s on a quiet machine and
    over 600 s on a busy one: a step of a 4-element rod on two ranks is a few MPI messages."""
    serial = tmp_path / "serial"
    proc = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "sweep",
            str(sweep_file(tmp_path, [0.95, 1.05], SHORT_CHAINS)),
            "--out",
            str(serial),
        ]
    )
    assert proc.returncode == 0, proc.stderr
    rows = read_table(serial / "sweep.csv")
    grouped = tmp_path / "two"
    grouped.mkdir()
    out = tmp_path / "grouped"
    proc = run_command(
        [
            "-m",
            "cosserat_fem.cli",
            "sweep",
            str(sweep_file(grouped, [0.95, 1.05], SHORT_CHAINS, group_size=2)),
            "--out",
            str(out),
        ],
        2,
    )
    assert proc.returncode == 0, proc.stderr
    two = read_table(out / "sweep.csv")
    assert [r["previous"] for r in two] == [r["previous"] for r in rows]
    for serial_row, grouped_row in zip(rows, two, strict=True):
        assert grouped_row["periods"] == serial_row["periods"]
        assert float(grouped_row["h1_x"]) == pytest.approx(float(serial_row["h1_x"]), rel=1e-6)
    with np.load(out / "members" / "m00000" / "final_state.npz") as data:
        assert sorted(k for k in data.files if k.startswith("U")) == ["U0", "U1"]


def test_a_final_state_after_a_chart_move_is_saved_in_the_fixed_basis():
    """A chain's saved state (sweep._final_state) has its angles measured from the fixed basis
    when the rod's chart moved during the member: at the free end those the probe reports (its
    own fixed-basis angles, cosserat_fem/output/fields.py), positions untouched, and the rates
    giving
    the same ŵ = Mm (θ̇, ψ̇, φ̇) (26) as the chart's; without a move, the state bit for bit."""
    from cosserat_fem.output.fields import PointProbe
    from cosserat_fem.rod.charts import angular_map, euler_matrix, quaternion_of_frame
    from cosserat_fem.rod.model import build_model
    from cosserat_fem.studies.sweep_run import _final_state

    model = build_model(api.load(PAPER, {"time.end": 3e-5}))
    model.use_chart(active=False)
    s = model.V.tabulate_dof_coordinates()[:, 0]
    full = np.zeros((len(s), 12))
    full[:, 0], full[:, 1] = 0.01 * s, -0.02 * s**2
    full[:, 3], full[:, 4], full[:, 5] = 0.3 * s, 0.2 * s, -0.1 * s
    full[:, 9], full[:, 10], full[:, 11] = 0.05, -0.02 * s, 0.01
    model.U.x.array[:] = model.layout.from_full(full, len(s))
    assert np.array_equal(_final_state(model), full.ravel())  # the chart at the fixed basis
    model.set_chart(quaternion_of_frame(euler_matrix(1.2 * s, 0.4 * s, 0.0 * s)))
    saved = _final_state(model).reshape(-1, 12)
    tip = int(np.argmax(s))
    assert saved[tip, 3:6] == pytest.approx(PointProbe(model, 1.0).values()[3:6], abs=1e-12)
    assert np.array_equal(saved[:, :3], full[:, :3]) and np.array_equal(saved[:, 6:9], full[:, 6:9])
    w_chart = np.einsum("nij,nj->ni", angular_map(full[:, 3], full[:, 5]), full[:, 9:12])
    w_saved = np.einsum("nij,nj->ni", angular_map(saved[:, 3], saved[:, 5]), saved[:, 9:12])
    assert w_saved == pytest.approx(w_chart, abs=1e-12)
