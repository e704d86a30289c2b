"""``cosserat-fem plot RUN_DIR``: PNG figures of any run, with matplotlib (Agg, no screen).

A continuation's folder (branches.csv) gets ``bifurcation.png``, the bifurcation diagram
(:func:`plot_branches`); an orbit branch's (orbit_branch.csv) ``orbit_branch.png``
(:func:`plot_orbit_branch`), a Lyapunov run's (lyapunov.csv) ``lyapunov.png``
(:func:`plot_lyapunov`). A sweep's folder (cosserat_fem/studies/sweep_run.py) gets
``sweep.png``: each member's largest
free-end displacements and angles against the varied key (:func:`plot_sweep`), and a frequency
response's also ``response.png``: amplitudes and phases against the forcing's key, a curve per
chain (:func:`plot_response`), and a bifurcation diagram's ([sweep.poincare]: bifurcation.csv)
also ``bifurcation.png``: a dot per section point against the swept key
(:func:`plot_bifurcation`). A run's folder gets:

* ``free_end.png``: the free-end histories of probes.csv, x, y, z [m] and θ, ψ, φ [rad]
  against t [s] (the load factor for a static run), laid out as the paper's Fig. 4;
* ``x_surface.png``, ``y_surface.png``: the surfaces x(s,t) and y(s,t) [m] over the rod and
  the XDMF frames (the paper's Figs. 5 and 6); a run with a single frame gets the curves
  x(s), y(s) instead.

Figures are 10 × 8 and 7 × 5 inches at 130 dpi: 1300 × 1040 and 910 × 650 pixels. Reads the
run with :mod:`cosserat_fem.output.results` (no DOLFINx), all of it before drawing anything: a
damaged file is bad input (one line naming it, exit 2) and leaves no figure behind. Non-finite
values are refused there, not plotted. A run killed at any moment plots what it has: a cut last
probe row is dropped, and an XDMF file without frames yet gives the free-end figure alone.
matplotlib comes from Debian (python3-matplotlib, see .ci/setup.sh).

Every file of ``plot``, ``render`` and ``pod`` is made in memory and written by
:func:`write_output`, whole or not at all: a write that fails (disk full, ``ulimit -f``, an
I/O error) is an :class:`~cosserat_fem.common.errors.OutputError` naming the file (exit 4, as a
run's outputs), and leaves no cut file (nor a library's traceback) behind.
Tests: tests/test_visualisation.py, tests/test_output_fuzz.py,
tests/test_sweep.py::test_plot_draws_a_sweep_from_its_table_or_its_parts.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np

from cosserat_fem.common.errors import CosseratError, SceneError, out_folder
from cosserat_fem.io.output_files import output_folder, write_output
from cosserat_fem.io.probes import PROBE_COLUMNS, PROBES
from cosserat_fem.io.run_folder import SUMMARY, read_summary
from cosserat_fem.io.sweep_table import (
    BIFURCATION,
    MEMBERS,
    RECORD,
    SWEEP_TABLE,
    check_sweep_rows,
    read_bifurcation,
    read_record,
    read_sweep_rows,
)
from cosserat_fem.io.xdmf import XDMF, NoFramesError, RodSeries
from cosserat_fem.output.results import Run, open_run

DPI = 130
HISTORY_SIZE = (10.0, 8.0)  # inches
SURFACE_SIZE = (7.0, 5.0)


def _pyplot():
    """matplotlib.pyplot with the Agg backend; CosseratError if matplotlib is missing."""
    try:
        import matplotlib
    except ImportError as exc:
        raise CosseratError(
            f"plot needs matplotlib ({exc}): apt-get install python3-matplotlib"
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _label(text: str) -> str:
    """``text`` (a scene's title: user input) drawn literally: a ``$`` would start mathtext,
    whose parser raises on most strings that are not TeX."""
    return text.replace("$", r"\$")


def _save(fig, path: Path, command: str = "plot") -> Path:
    """``fig`` as PNG at DPI to ``path`` (:func:`write_output`), then closed."""
    plt = _pyplot()
    image = io.BytesIO()
    try:
        fig.savefig(image, format="png", dpi=DPI)
    finally:
        plt.close(fig)
    return write_output(path, image.getbuffer(), command)


def drawn_lines(fig) -> dict[str, np.ndarray]:
    """The lines a matplotlib figure draws, read back from its artists (for a test of what a
    figure shows, or to draw it again): for the i-th axes of ``fig`` and its j-th line,
    ``"axes{i}/line{j}"`` → (2, n) float array of x and y as drawn (data coordinates), and the
    0-d string arrays ``"axes{i}/ylabel"`` and ``"axes{i}/line{j}/label"`` (matplotlib names
    an unlabelled line "_child<n>"). ``np.savez(path, **drawn_lines(fig))`` keeps them."""
    data: dict[str, np.ndarray] = {}
    for i, ax in enumerate(fig.get_axes()):
        data[f"axes{i}/ylabel"] = np.array(ax.get_ylabel())
        for j, line in enumerate(ax.get_lines()):
            xy = np.array([line.get_xdata(), line.get_ydata()], dtype=float)
            data[f"axes{i}/line{j}"] = xy
            data[f"axes{i}/line{j}/label"] = np.array(line.get_label())
    return data


def plot_free_end(run: Run, out: Path) -> Path:
    """free_end.png: the probe's x, y, z [m] and θ, ψ, φ [rad] against t [s] (the load factor for
    a static run), laid out as the paper's Fig. 4."""
    plt = _pyplot()
    rows = run.probes
    if rows is None:
        raise SceneError(f"plot: {str(run.directory / PROBES)!r}: no probes to plot")
    t = rows[:, 0]
    fig, axes = plt.subplots(3, 2, figsize=HISTORY_SIZE, sharex=True)
    at = run.probe_place
    panels = [(1, f"x({at}) [m]"), (4, f"θ({at}) [rad]"), (2, f"y({at}) [m]")]
    panels += [(5, f"ψ({at}) [rad]"), (3, f"z({at}) [m]"), (6, f"φ({at}) [rad]")]
    marker = "o-" if len(t) < 40 else "-"
    for ax, (column, label) in zip(axes.flat, panels, strict=True):
        ax.plot(t, rows[:, column], marker, lw=0.8, ms=3)
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel(run.time_label)
    where = "Free end" if at == "ℓ" else f"At {at}"
    fig.suptitle(_label(f"{where}: {run.title}"), fontsize=10)
    fig.tight_layout()
    return _save(fig, out / "free_end.png")


def plot_surfaces(run: Run, out: Path, series: RodSeries | None = None) -> list[Path]:
    """x(s, t) and y(s, t) of ``series`` (default: read from the run's XDMF file)."""
    plt = _pyplot()
    series = run.series() if series is None else series
    if "displacement" not in series.arrays:
        raise SceneError(f"{str(run.xdmf)!r}: no displacement array (output.fields)")
    disp = series.arrays["displacement"]  # (T, N, 3)
    paths = []
    for column, name in ((0, "x"), (1, "y")):
        fig = plt.figure(figsize=SURFACE_SIZE)
        if len(series.times) > 1:
            ax = fig.add_subplot(projection="3d")
            S, T = np.meshgrid(series.s, series.times)
            # Antialiased and shaded: without, mplot3d's depth sorting of the thin facets
            # (many frames, few points) drew spikes through the surface.
            ax.plot_surface(
                S,
                T,
                disp[:, :, column],
                cmap="viridis",
                linewidth=0,
                antialiased=True,
                shade=True,
                rcount=min(len(series.times), 300),
                ccount=min(len(series.s), 200),
            )
            ax.view_init(elev=30, azim=-60)
            ax.set_xlabel("s [m]")
            ax.set_ylabel(run.time_label)
            ax.set_zlabel(f"{name}(s,t) [m]")
            ax.ticklabel_format(axis="z", style="sci", scilimits=(-2, 2))
        else:
            ax = fig.add_subplot()
            ax.plot(series.s, disp[0, :, column], "o-", ms=3)
            ax.set_xlabel("s [m]")
            ax.set_ylabel(f"{name}(s) [m] at {run.time_label} = {series.times[0]:.6g}")
            ax.grid(alpha=0.3)
        ax.set_title(_label(f"{name}(s, t): {run.title}"), fontsize=9)
        fig.tight_layout()
        paths.append(_save(fig, out / f"{name}_surface.png"))
    return paths


#: What sweep.png draws against the varied key: the free end's largest |x|, |y|, |z| [m] and
#: |θ|, |ψ|, |φ| [rad] over each member's run (cosserat_fem/studies/sweep_run.py's table).
SWEEP_PANELS = (
    ("max_abs_x", "max |x| [m]"),
    ("max_abs_theta", "max |θ| [rad]"),
    ("max_abs_y", "max |y| [m]"),
    ("max_abs_psi", "max |ψ| [rad]"),
    ("max_abs_z", "max |z| [m]"),
    ("max_abs_phi", "max |φ| [rad]"),
)


def _number(text: str) -> float:
    try:
        value = json.loads(text) if text != "" else float("nan")
        return float(value) if not isinstance(value, bool) else float("nan")
    except (ValueError, TypeError):
        return float("nan")


def plot_sweep(directory: str | Path, out: str | Path | None = None) -> list[Path]:
    """sweep.png: the free end's largest displacements and angles of each member against the
    sweep's varied key (the member number when more than one key varies, or none is a
    number); members that did not complete are marked with a cross at zero."""
    directory = Path(directory)
    columns, rows = read_sweep_rows(directory)
    missing = {"member", "status", "wall_s", "steps", *(c for c, _ in SWEEP_PANELS)}
    missing -= set(columns)
    if missing:
        raise SceneError(
            f"plot: {str(directory)!r} holds no sweep's table (no column {sorted(missing)[0]!r})"
        )
    if not rows:
        raise SceneError(f"plot: the sweep in {str(directory)!r} has no finished member yet")
    record = _sweep_record(directory)
    varied = list(check_sweep_rows(directory, columns, rows, record))
    if "h1_x" in columns:  # a frequency response: its columns checked before anything is drawn
        _check_response(directory, columns, varied, record)

    key = varied[0] if len(varied) == 1 else None
    x = [_number(row[key]) for row in rows] if key else []
    if key is None or not np.isfinite(x).all():
        key, x = "member", [float(row["member"]) for row in rows]
    done = np.array([row["status"] == "completed" for row in rows])
    target = output_folder(out, directory, "plot")
    plt = _pyplot()
    fig, axes = plt.subplots(3, 2, figsize=HISTORY_SIZE, sharex=True)
    for ax, (column, label) in zip(axes.flat, SWEEP_PANELS, strict=True):
        y = np.array([_number(row[column]) for row in rows])
        ax.plot(np.array(x)[done], y[done], "o-", lw=0.8, ms=3)
        if (~done).any():
            ax.plot(
                np.array(x)[~done], np.zeros((~done).sum()), "x", color="C3", label="not completed"
            )
            ax.legend(fontsize=7)
        ax.set_ylabel(label)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel(_label(key))
    fig.suptitle(_label(f"Sweep of {len(rows)} members: {directory.name}"), fontsize=10)
    fig.tight_layout()
    paths = [_save(fig, target / "sweep.png")]
    if "h1_x" in columns:
        paths.append(plot_response(directory, rows, varied, target, record))
    if (directory / BIFURCATION).is_file():
        paths.append(plot_bifurcation(directory, varied, target, record))
    return paths


#: The section's coordinates a bifurcation diagram may draw: the probe point's x, y, z [m].
SECTION_COORDINATES = ("x", "y", "z")


def plot_bifurcation(directory: Path, varied: list[str], target: Path, record: dict) -> Path:
    """bifurcation.png of a sweep with [sweep.poincare] (cosserat_fem/studies/sweep_run.py's
    bifurcation.csv): a dot per section point, the probe point's coordinate that spreads the
    most over all points (the largest range of x, y, z [m]; x at a tie) against the
    continuation key (sweep.json) or the first varied key of numbers (else the member's
    number); the chains up ● and down ▲ in two colours. A value that is not a finite number
    is bad input naming the file, before anything is drawn."""
    path = directory / BIFURCATION
    rows = read_bifurcation(directory, varied)
    key = record.get("continuation") or next(
        (k for k in varied if rows and np.isfinite(_number(rows[0][k]))), "member"
    )
    names = [key, *SECTION_COORDINATES] if key != "member" else list(SECTION_COORDINATES)
    values = {c: np.array([_number(r[c]) for r in rows]) for c in names}
    if key == "member":
        values[key] = np.array([float(r["member"]) for r in rows])
    bad = next((c for c in names if not np.isfinite(values[c]).all()), None)
    if bad is not None:
        raise SceneError(f"plot: {str(path)!r}: a value of {bad!r} that is not a finite number")
    spread = [np.ptp(values[c]) if rows else 0.0 for c in SECTION_COORDINATES]
    column = SECTION_COORDINATES[int(np.argmax(spread))]
    directions = np.array([r["direction"] for r in rows])
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=SURFACE_SIZE)
    for i, direction in enumerate(dict.fromkeys(directions)):
        on = directions == direction
        marker = "^" if direction == "down" else "o"
        label = f"chain {direction}" if direction else None
        ax.plot(values[key][on], values[column][on], marker, ms=2.0, color=f"C{i}", label=label)
    if len(set(directions)) > 1:
        ax.legend(fontsize=7)
    ax.set_xlabel(_label(key))
    ax.set_ylabel(f"{column} at the probe point [m], once a period")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    ax.grid(alpha=0.3)
    members = len({r["member"] for r in rows})
    ax.set_title(
        _label(f"Bifurcation diagram: {len(rows)} section points of {members} members"),
        fontsize=10,
    )
    fig.tight_layout()
    return _save(fig, target / "bifurcation.png")


def _sweep_record(directory: Path) -> dict:
    """The sweep's sweep.json (cosserat_fem/studies/sweep_run.py) as a dict; SceneError naming it if
    it
    cannot be read or is not an object."""
    path = directory / RECORD
    record, reason = read_record(path)
    if reason or record is None:
        raise SceneError(f"plot: {str(path)!r} is not a sweep's record ({reason})")
    return record


#: The columns response.png reads (cosserat_fem/studies/sweep_run.py, RESPONSE_COLUMNS and
#: MEASURES).
RESPONSE_NEEDS = (
    "direction",
    "settled",
    *(f"{m}_{c}" for m in ("amp", "phase") for c in PROBE_COLUMNS[1:]),
)
#: A column moves when its largest amplitude is at least this fraction of the motion's size.
MOVING = 1e-3


def _check_response(directory: Path, columns: list[str], varied: list[str], record: dict):
    """SceneError naming the file unless the table has the columns of a frequency response
    and sweep.json's continuation key is one of its varied keys (or none)."""
    absent = [c for c in RESPONSE_NEEDS if c not in columns]
    if absent:
        raise SceneError(
            f"plot: {str(directory / SWEEP_TABLE)!r} has no column {absent[0]!r} "
            "of a frequency response"
        )
    key = record.get("continuation")
    if key is not None and key not in varied:
        raise SceneError(
            f"plot: {str(directory / RECORD)!r}: its continuation "
            f"{str(key)[:60]!r} is not a varied key of the sweep"
        )


def _member_lengths(directory: Path, rows: list[dict]) -> np.ndarray:
    """ℓ [m] of each row's member, from its summary.json's scene (NaN where there is none or
    it cannot be read: a member that failed)."""
    from cosserat_fem.studies.sweep_spec import Member

    lengths = np.full(len(rows), np.nan)
    for i, row in enumerate(rows):
        path = directory / MEMBERS / Member(int(row["member"]), {}).name / SUMMARY
        try:
            summary = read_summary(path) if path.is_file() else {}
        except SceneError:
            continue
        length = ((summary.get("scene") or {}).get("rod") or {}).get("length")
        lengths[i] = np.nan if length is None else float(length)
    return lengths


def moving_columns(amps: dict[str, np.ndarray], lengths: np.ndarray) -> list[str]:
    """The probe's columns that move over a frequency response, from their amplitudes (half
    ranges) per member ``amps`` [m, rad] and the members' rod lengths ℓ [m]: those whose
    largest amplitude is at least :data:`MOVING` of the motion's size S in its unit, S the
    largest of x/ℓ, y/ℓ, z/ℓ and θ, ψ, φ over the members (cosserat_fem/studies/response.py measures
    its settling in the same unit). A column that the motion leaves alone holds round-off (ψ
    at the mid-span of a symmetric mode: 1e-16 rad with a random phase), not a response.
    Without any ℓ, each group (lengths, angles) is measured against its own largest. At
    least x."""
    unit = {c: lengths if RESPONSE_UNITS[c] == "m" else np.ones_like(lengths) for c in amps}
    with np.errstate(invalid="ignore"):
        scaled = {c: np.nanmax(np.abs(a) / unit[c], initial=0.0) for c, a in amps.items()}
    largest = {c: np.nanmax(np.abs(a), initial=0.0) for c, a in amps.items()}
    if np.isfinite(lengths).any():
        size = max(scaled.values())
        moving = [c for c in amps if scaled[c] > 0 and scaled[c] >= MOVING * size]
    else:
        group = {
            c: max(largest[d] for d in amps if RESPONSE_UNITS[d] == RESPONSE_UNITS[c]) for c in amps
        }
        moving = [c for c in amps if largest[c] > 0 and largest[c] >= MOVING * group[c]]
    return moving or ["x"]


#: The probe's columns (cosserat_fem/studies/response.py) and their units.
RESPONSE_UNITS = dict(zip(PROBE_COLUMNS[1:], ("m",) * 3 + ("rad",) * 3, strict=True))
RESPONSE_SYMBOLS = dict(zip(PROBE_COLUMNS[1:], ("x", "y", "z", "θ", "ψ", "φ"), strict=True))


def plot_response(
    directory: Path, rows: list[dict], varied: list[str], target: Path, record: dict
) -> Path:
    """response.png of a frequency response (a sweep with [sweep.response]; ``record`` its
    sweep.json, its table checked by :func:`_check_response`): the probe point's amplitude
    (half range, ``amp_c``) and the phase of its first harmonic against the load's
    (``phase_c``, unwrapped along a chain) for each column that moves
    (:func:`moving_columns`), against the continuation key (sweep.json) or the varied key;
    a line per chain, upward ▲ solid, downward ▼ dashed; a member that did not settle drawn
    hollow, one that failed as a cross at zero."""
    key = record.get("continuation") or next(
        (k for k in varied if np.isfinite(_number(rows[0][k]))), "member"
    )
    others = [k for k in varied if k != key]
    amps = {c: np.array([_number(r[f"amp_{c}"]) for r in rows]) for c in RESPONSE_UNITS}
    moving = moving_columns(amps, _member_lengths(directory, rows))
    lines: dict[tuple, list[dict]] = {}
    for row in rows:
        lines.setdefault((*(row[k] for k in others), row.get("direction", "")), []).append(row)
    plt = _pyplot()
    fig, axes = plt.subplots(len(moving), 2, figsize=HISTORY_SIZE, sharex=True, squeeze=False)
    for i, (label, chain) in enumerate(sorted(lines.items())):
        chain.sort(key=lambda r: _number(r[key]) if key != "member" else int(r["member"]))
        x = np.array([_number(r[key]) if key != "member" else float(r["member"]) for r in chain])
        done = np.array([r["status"] == "completed" for r in chain])
        settled = np.array([r["settled"] == "true" for r in chain]) & done
        direction = label[-1]
        style = {"up": ("^", "-"), "down": ("v", "--")}.get(direction, ("o", "-"))
        name = ", ".join(
            [f"{k} = {v}" for k, v in zip(others, label, strict=False)]
            + ([direction] if direction else [])
        )
        for row_axes, column in zip(axes, moving, strict=True):
            for ax, measure in zip(row_axes, ("amp", "phase"), strict=True):
                y = np.array([_number(r[f"{measure}_{column}"]) for r in chain])
                if measure == "phase" and done.any():  # continuous along the chain
                    y[done] = np.unwrap(y[done])
                ax.plot(
                    x[done],
                    y[done],
                    ls=style[1],
                    lw=0.9,
                    color=f"C{i}",
                    label=_label(name) if name else None,
                )
                ax.plot(x[settled], y[settled], style[0], ms=4, color=f"C{i}")
                loose = done & ~settled
                ax.plot(x[loose], y[loose], style[0], ms=5, mfc="none", color="C3")
                ax.plot(x[~done], np.zeros((~done).sum()), "x", color="C3")
    for row_axes, column in zip(axes, moving, strict=True):
        symbol, unit = RESPONSE_SYMBOLS[column], RESPONSE_UNITS[column]
        row_axes[0].set_ylabel(f"amplitude of {symbol} [{unit}]")
        row_axes[1].set_ylabel(f"phase of {symbol} [rad]")
        row_axes[0].ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
        for ax in row_axes:
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel(_label(key))
    if len(lines) > 1 or any(label[-1] for label in lines):
        axes[0][0].legend(fontsize=7)
    unsettled = sum(r["status"] == "completed" and r["settled"] != "true" for r in rows)
    note = f"; {unsettled} not settled (hollow)" if unsettled else ""
    fig.suptitle(
        _label(f"Frequency response at the probe point: {directory.name}{note}"), fontsize=10
    )
    fig.tight_layout()
    return _save(fig, target / "response.png")


#: A continuation's folder holds it (cosserat_fem/analysis/paths.py, write_branches).
BRANCHES = "branches.csv"
#: The columns of branches.csv a diagram may draw λ against (``plot --column``).
DIAGRAM_COLUMNS = ("norm", "x", "y", "z", "theta", "psi", "phi")
_DIAGRAM_UNITS = {"norm": "RMS of U", "x": "m", "y": "m", "z": "m"}
#: branches.csv's kinds of located special points, marked on the diagram.
SPECIAL_MARKERS = {"limit": ("s", "k"), "bifurcation": ("D", "k")}


def read_branch_rows(path: Path, column: str) -> list[dict]:
    """branches.csv's rows as {"branch": int, "load_factor", ``column``: float, "point": str,
    "stability": str or "" (a column a newer file may have), "det_sign": float}; a file
    without those columns or with a value that is not a finite number is bad input naming
    the file and the row."""
    from cosserat_fem.common.safe_files import read_text

    name = str(path)
    try:
        lines = read_text(path, 1 << 30).splitlines()
    except (OSError, ValueError) as exc:
        raise SceneError(f"plot: cannot read {name!r} ({exc})") from None
    header = lines[0].split(",") if lines else []
    for needed in ("branch", "load_factor", column, "point"):
        if needed not in header:
            raise SceneError(f"plot: {name!r} has no column {needed!r}")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        values = line.split(",")
        if len(values) != len(header):
            raise SceneError(
                f"plot: {name!r} line {number}: {len(values)} values, not {len(header)}"
            )
        row = dict(zip(header, values, strict=True))
        try:
            parsed: dict = {
                "branch": int(row["branch"]),
                "load_factor": float(row["load_factor"]),
                column: float(row[column]),
                "det_sign": float(row.get("det_sign", "nan")),
            }
        except ValueError:
            raise SceneError(f"plot: {name!r} line {number}: not a number") from None
        if not (math.isfinite(parsed["load_factor"]) and math.isfinite(parsed[column])):
            raise SceneError(f"plot: {name!r} line {number}: not a finite number")
        parsed["point"] = row["point"]
        parsed["stability"] = row.get("stability", "")
        rows.append(parsed)
    if not rows:
        raise SceneError(f"plot: {name!r} holds no point")
    return rows


def _diagram_style(rows: list[dict]) -> tuple[str, dict]:
    """How the parts of a branch are told apart: by branches.csv's ``stability`` column
    ("stable" solid, "unstable" dashed, anything else dotted) when it has one, else by the
    sign of det R_u (solid > 0, dashed < 0), which is not stability (it counts the negative
    eigenvalues' parity) and is labelled as such."""
    if any(r["stability"] for r in rows):
        return "stability", {"stable": "-", "unstable": "--"}
    return "det_sign", {"det R_u > 0": "-", "det R_u < 0": "--"}


def plot_branches(
    directory: str | Path, out: str | Path | None = None, column: str = "norm"
) -> Path:
    """bifurcation.png of the continuation in ``directory`` (its branches.csv): the load factor
    λ against ``column`` (:data:`DIAGRAM_COLUMNS`: the state's RMS norm or the free end's
    x, y, z [m], θ, ψ, φ [rad]), a colour per branch, each branch's points joined in the
    order traced, the parts told apart by :func:`_diagram_style` (a segment takes its end
    point's style), and the located limit points (squares) and bifurcation points
    (diamonds) marked."""
    if column not in DIAGRAM_COLUMNS:
        raise SceneError(
            f"plot --column: must be one of {', '.join(DIAGRAM_COLUMNS)}, got {column!r}"
        )
    directory = Path(directory)
    rows = read_branch_rows(directory / BRANCHES, column)
    target = output_folder(out, directory, "plot")
    key, styles = _diagram_style(rows)
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=SURFACE_SIZE)
    used: set[str] = set()
    for b in sorted({r["branch"] for r in rows}):
        points = [r for r in rows if r["branch"] == b and r["point"] not in SPECIAL_MARKERS]
        x = np.array([r[column] for r in points])
        y = np.array([r["load_factor"] for r in points])
        for i in range(1, len(points)):
            if key == "stability":
                part = points[i]["stability"]
            else:
                part = "det R_u > 0" if points[i]["det_sign"] > 0 else "det R_u < 0"
            style = styles.get(part, ":")
            label = part if part not in used and part else "_nolegend_"
            used.add(part)
            ax.plot(
                x[i - 1 : i + 1], y[i - 1 : i + 1], style, color=f"C{b % 10}", lw=1.2, label=label
            )
        if len(points) == 1:
            ax.plot(x, y, "o", color=f"C{b % 10}", ms=3)
    for kind, (marker, colour) in SPECIAL_MARKERS.items():
        found = [r for r in rows if r["point"] == kind]
        if found:
            ax.plot(
                [r[column] for r in found],
                [r["load_factor"] for r in found],
                marker,
                color=colour,
                ms=6,
                ls="none",
                label=f"{kind} point",
            )
    unit = _DIAGRAM_UNITS.get(column, "rad")
    ax.set_xlabel(f"{column} [{unit}]" if column != "norm" else f"norm ({unit})")
    ax.set_ylabel("load factor λ")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(_label(f"Branches of {directory.name}"), fontsize=10)
    fig.tight_layout()
    return _save(fig, target / "bifurcation.png")


#: An orbit branch's folder holds it (cosserat_fem/analysis/orbit_runs.py; its columns
#: cosserat_fem/analysis/periodic.py's ORBIT_COLUMNS).
ORBIT_BRANCH = "orbit_branch.csv"
#: A Lyapunov run's folder holds it (cosserat_fem/analysis/orbit_runs.py): time, stretch,
#: running exponent.
LYAPUNOV = "lyapunov.csv"
#: Markers of an orbit branch's special points by kind; any other kind: "x".
ORBIT_MARKERS = {"limit": "s", "period-doubling": "^", "torus": "D", "bifurcation": "v"}
#: The kinds of an orbit branch's points that are points of the branch (not located ones).
BRANCH_POINTS = ("start", "regular", "end")


def _csv_table(path: Path, needed: tuple[str, ...]) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of a small CSV file of ours; SceneError naming the file if it cannot
    be read, lacks a ``needed`` column, or a row has not as many values as the header."""
    from cosserat_fem.common.safe_files import read_text

    name = str(path)
    try:
        lines = [ln for ln in read_text(path, 1 << 30).splitlines() if ln.strip()]
    except (OSError, ValueError) as exc:
        raise SceneError(f"plot: cannot read {name!r} ({exc})") from None
    header = lines[0].split(",") if lines else []
    for column in needed:
        if column not in header:
            raise SceneError(f"plot: {name!r} has no column {column!r}")
    rows = [line.split(",") for line in lines[1:]]
    for number, row in enumerate(rows, start=2):
        if len(row) != len(header):
            raise SceneError(f"plot: {name!r} line {number}: {len(row)} values, not {len(header)}")
    if not rows:
        raise SceneError(f"plot: {name!r} holds no point")
    return header, rows


def _finite(text: str, path: Path, number: int, blank_ok: bool = False) -> float:
    if blank_ok and text == "":
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise SceneError(f"plot: {str(path)!r} line {number}: not a number") from None
    if not math.isfinite(value):
        raise SceneError(f"plot: {str(path)!r} line {number}: not a finite number")
    return value


def plot_orbit_branch(directory: str | Path, out: str | Path | None = None) -> Path:
    """orbit_branch.png of the orbit branch in ``directory`` (its orbit_branch.csv): the
    amplitude [m] against the parameter p, the points joined in the order traced (the
    engine's step beyond the range's end left out: :func:`_within_range`), a segment
    solid where its end orbit is stable and dashed where it is not (whatever way: "fold",
    "period-doubling", "torus"), and the located special points marked by kind
    (:data:`ORBIT_MARKERS`; a kind not named there with "x"), labelled by their kind."""
    directory = Path(directory)
    path = directory / ORBIT_BRANCH
    header, rows = _csv_table(path, ("parameter", "amplitude", "stability", "point"))
    at = {c: header.index(c) for c in ("parameter", "amplitude", "stability", "point")}
    points = []
    for number, row in enumerate(rows, start=2):
        p = _finite(row[at["parameter"]], path, number)
        a = _finite(row[at["amplitude"]], path, number)
        points.append((p, a, row[at["stability"]], row[at["point"]]))
    target = output_folder(out, directory, "plot")
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=SURFACE_SIZE)
    branch = _within_range([q for q in points if q[3] in BRANCH_POINTS])
    used: set[str] = set()
    for q0, q1 in zip(branch, branch[1:], strict=False):
        stable = q1[2] == "stable"
        label = "stable" if stable else "unstable"
        ax.plot(
            [q0[0], q1[0]],
            [q0[1], q1[1]],
            "-" if stable else "--",
            color="C0",
            lw=1.2,
            label=label if label not in used else "_nolegend_",
        )
        used.add(label)
    if len(branch) == 1:
        ax.plot([branch[0][0]], [branch[0][1]], "o", color="C0", ms=3)
    for kind in dict.fromkeys(q[3] for q in points if q[3] not in BRANCH_POINTS):
        found = [q for q in points if q[3] == kind]
        ax.plot(
            [q[0] for q in found],
            [q[1] for q in found],
            ORBIT_MARKERS.get(kind, "x"),
            color="k",
            ms=6,
            ls="none",
            label=_label(f"{kind} point"),
        )
    name = "p"
    try:  # the parameter's name, if the folder's summary.json says it
        name = str(json.loads((directory / SUMMARY).read_text())["parameter"])
    except (OSError, ValueError, KeyError, TypeError):
        pass
    ax.set_xlabel(_label(f"parameter {name}"))
    ax.set_ylabel("amplitude [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(_label(f"Periodic orbits of {directory.name}"), fontsize=10)
    fig.tight_layout()
    return _save(fig, target / "orbit_branch.png")


def _within_range(branch: list[tuple]) -> list[tuple]:
    """An orbit branch's points (p first) without the engine's step beyond the range's end:
    the point before a last "end" point (the engine's at the bound) when it lies past it."""
    if len(branch) >= 3 and branch[-1][3] == "end":
        before, beyond, end = branch[-3][0], branch[-2][0], branch[-1][0]
        if (beyond - end) * (end - before) > 0:
            return [*branch[:-2], branch[-1]]
    return branch


def plot_lyapunov(directory: str | Path, out: str | Path | None = None) -> Path:
    """lyapunov.png of the Lyapunov run in ``directory``: its Poincaré section
    (poincare.csv) as the return map of the probe's x, x_{j+1} against x_j [m] (one point
    a period: a period-one orbit is one point, a chaotic one a scattered set), and the
    running exponent λ_n [1/s] against the time [s] (lyapunov.csv)."""
    from cosserat_fem.io.poincare import POINCARE, read_poincare

    directory = Path(directory)
    path = directory / LYAPUNOV
    header, rows = _csv_table(path, ("time", "running_exponent"))
    t_at, l_at = header.index("time"), header.index("running_exponent")
    times, running = [], []
    for number, row in enumerate(rows, start=2):
        times.append(_finite(row[t_at], path, number))
        running.append(_finite(row[l_at], path, number, blank_ok=True))
    columns, section = read_poincare(directory / POINCARE)
    x = section[:, columns.index("x")] if len(section) else np.zeros(0)
    target = output_folder(out, directory, "plot")
    plt = _pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(HISTORY_SIZE[0], SURFACE_SIZE[1]))
    left.plot(x[:-1], x[1:], ".", color="C0", ms=3)
    left.set_xlabel("x at period j [m]")
    left.set_ylabel("x at period j + 1 [m]")
    left.set_title("Poincaré section: return map of x", fontsize=10)
    left.grid(alpha=0.3)
    right.plot(times, running, "-", color="C1", lw=1.2)
    right.axhline(0.0, color="k", lw=0.6)
    right.set_xlabel("t [s]")
    right.set_ylabel("running exponent [1/s]")
    right.set_title("Largest Lyapunov exponent", fontsize=10)
    right.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, target / "lyapunov.png")


def _refuse_stopped_lyapunov(directory: Path) -> None:
    """SceneError naming lyapunov.csv if ``directory`` holds a Lyapunov run that stopped
    before writing it (summary.json's command "lyapunov", its reason quoted)."""
    from cosserat_fem.io.poincare import POINCARE

    if (directory / PROBES).is_file() or not (directory / POINCARE).is_file():
        return
    try:
        summary = read_summary(directory / SUMMARY)
    except SceneError:  # none, or not one: the folder is looked at as a run's
        return
    if summary.get("command") == "lyapunov":
        raise SceneError(
            f"plot: {str(directory / LYAPUNOV)!r} was not written: the Lyapunov run "
            f"{summary.get('status', 'ended')} ({summary.get('reason', 'no reason given')})"
        )


def plot_run(
    directory: str | Path, out: str | Path | None = None, column: str = "norm"
) -> list[Path]:
    """The figures of the run in ``directory``, written to ``out`` (default: that folder); a
    sweep's folder (sweep.json) gets :func:`plot_sweep`, a continuation's (branches.csv)
    :func:`plot_branches` of λ against ``column``. Everything is read (and checked)
    first; a run with neither probe rows nor XDMF frames (killed at its start) is bad input,
    as nothing can be drawn."""
    out_folder(out, "plot --out")  # before anything is read
    if (Path(directory) / RECORD).is_file():
        return plot_sweep(directory, out)
    if (Path(directory) / BRANCHES).is_file():
        return [plot_branches(directory, out, column)]
    if (Path(directory) / ORBIT_BRANCH).is_file():
        return [plot_orbit_branch(directory, out)]
    if (Path(directory) / LYAPUNOV).is_file():
        return [plot_lyapunov(directory, out)]
    _refuse_stopped_lyapunov(Path(directory))
    run = open_run(directory, "plot")
    rows = run.probes is not None and len(run.probes) > 0
    series = None
    if run.xdmf is not None:
        try:
            series = run.series()
        except NoFramesError:
            series = None
        if series is not None and "displacement" not in series.arrays:
            raise SceneError(f"{str(run.xdmf)!r}: no displacement array (output.fields)")
    if not rows and series is None:
        probes = str(run.directory / PROBES)
        xdmf = f"{str(run.xdmf)!r} no frames" if run.xdmf else f"there is no {XDMF}"
        raise SceneError(f"plot: nothing to plot yet: {probes!r} holds no rows and {xdmf}")
    target = output_folder(out, run.directory, "plot")
    paths = []
    if rows:
        paths.append(plot_free_end(run, target))
    if series is not None:
        paths += plot_surfaces(run, target, series)
    return paths


#: Modes drawn in pod.png's shape panels.
DRAWN = 4


def plot_pod(result, path: Path) -> Path:
    """pod.png: the energies λ_k on a log scale (with the cumulative fraction), and the
    leading shapes' displacement components against s (scaled by √λ_k: their rms size)."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    k = np.arange(1, len(result.energies) + 1)
    positive = result.energies > 0
    axes[0].semilogy(k[positive], result.energies[positive], "o-")
    axes[0].set_xlabel("POD mode k")
    axes[0].xaxis.get_major_locator().set_params(integer=True)
    axes[0].set_ylabel(f"energy λ_k [{result.unit}]")
    axes[0].set_title(f"POD energies ({result.weighting} weighting)")
    axes[0].grid(True, which="both", alpha=0.3)
    twin = axes[0].twinx()
    twin.plot(k, result.cumulative, "s--", color="tab:gray", markersize=3)
    twin.set_ylabel("cumulative fraction")
    twin.set_ylim(0.0, 1.05)
    styles = {"x": "-", "y": "--", "z": ":"}
    for i in range(min(DRAWN, len(result.energies))):
        if not result.energies[i] > 0:
            continue
        rms = math.sqrt(result.energies[i]) * result.shapes[i]
        main = int(np.argmax(np.abs(rms[:, :3]).max(axis=0)))
        for c in range(3):
            if np.abs(rms[:, c]).max() >= 1e-2 * np.abs(rms[:, main]).max():  # drawn apart
                axes[1].plot(
                    result.s,
                    rms[:, c],
                    styles["xyz"[c]],
                    color=f"C{i}",
                    label=f"mode {i + 1}: {'xyz'[c]} ({100 * result.fractions[i]:.3g} %)",
                )
    axes[1].set_xlabel("s [m]")
    axes[1].set_ylabel("√λ_k φ_k, displacement [m]")
    axes[1].set_title("leading shapes (rms size in the run)")
    axes[1].grid(True, alpha=0.3)
    axes[1].legend(fontsize=8)
    return _save(fig, path, "pod")
