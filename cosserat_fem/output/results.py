"""Reading a run's outputs without DOLFINx: a run folder (:func:`open_run`: summary.json,
probes.csv and solution.xdmf). A sweep's table (sweep.csv and its parts) is
cosserat_fem/io/sweep_table.py's.

For ``cosserat-fem plot`` and ``cosserat-fem render`` (cosserat_fem/plot.py, render.py), which
must also work on a machine without the solver stack: numpy, the standard library's XML
parser and h5py (the ``plot``/``render`` extras) only. Each file is read by its format's module
(cosserat_fem/io/: probes.py, xdmf.py, run_folder.py), which says what it checks; h5py cannot
be used in a process that has loaded DOLFINx (the two HDF5 libraries clash: "Not a datatype"),
so this module never imports DOLFINx and should not be imported next to it; tests read the
files through ``cosserat-fem plot``/``render`` in a subprocess.

Damaged, truncated, foreign or hostile files are bad input: a :class:`SceneError` (exit 2)
whose one-line message names the file at fault, most often first (text taken from a file is
quoted with ``repr``, so no control character reaches the terminal), never another
exception (cosserat_fem/io/reading.py). Every file is a regular file (not a folder, device,
FIFO or dangling link: looked at before it is opened, and opened without blocking,
cosserat_fem/common/safe_files.py) of bounded size; numbers are finite and at most
:data:`~cosserat_fem.io.reading.MAX_MAGNITUDE` in magnitude (NaN and inf are refused, not
plotted: a run never writes them, so they mean damage; and matplotlib and VTK fail on values
near the float range anyway). summary.json: a JSON object; ``kind`` and ``scene.title``
strings, ``scene`` and ``scene.rod`` objects, ``scene.rod.length`` a positive number, where
present. A scratch ``solution.xdmf-partial`` or ``summary.json.tmp`` left by a killed run is
never read.
Tests: tests/test_output_fuzz.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.probes import PROBE_COLUMNS, PROBES, read_probe_table
from cosserat_fem.io.reading import is_file
from cosserat_fem.io.run_folder import SUMMARY, read_summary
from cosserat_fem.io.xdmf import XDMF, RodSeries, read_xdmf

#: Largest files read [bytes]: an XDMF file ~1-2.5 kB a frame (some 60 000 frames),
#: summary.json ~4 kB.
#: Longest title shown in a figure [characters].
MAX_TITLE = 120


@dataclass
class Run:
    """A run folder's outputs: summary (or None), probes (rows, or None), XDMF path (or None),
    and the names of the probes' columns."""

    directory: Path
    summary: dict | None
    probes: np.ndarray | None
    xdmf: Path | None
    probe_columns: tuple[str, ...] = PROBE_COLUMNS

    @property
    def time_label(self) -> str:
        """What the probes' t column and the XDMF times are."""
        if self.summary and self.summary.get("kind") == "static":
            return "load factor"
        return "t [s]"

    @property
    def title(self) -> str:
        """The scene's title (else the folder's name) for a picture: control characters as
        blanks, shortened to MAX_TITLE characters."""
        scene = (self.summary or {}).get("scene") or {}
        title = scene.get("title") or self.directory.resolve().name or str(self.directory)
        title = "".join(c if c.isprintable() else " " for c in title[: MAX_TITLE + 1])
        return title if len(title) <= MAX_TITLE else title[: MAX_TITLE - 3] + "..."

    @property
    def length(self) -> float | None:
        scene = (self.summary or {}).get("scene") or {}
        length = (scene.get("rod") or {}).get("length")
        return None if length is None else float(length)

    @property
    def probe_place(self) -> str:
        """Where probes.csv's values are taken, for a label: "ℓ" (the end at s = ℓ), "0", or
        "s = ... m" (from summary.json's probe_s_m; "ℓ" when it does not say)."""
        summary = self.summary or {}
        where, length = summary.get("probe_s_m"), self.length
        if not isinstance(where, int | float) or isinstance(where, bool) or length is None:
            return "ℓ"
        if where == length:
            return "ℓ"
        return "0" if where == 0 else f"s = {where:g} m"

    def series(self) -> RodSeries:
        if self.xdmf is None:
            raise SceneError(f"{self.directory}: no {XDMF} (was output.xdmf = false?)")
        return read_xdmf(self.xdmf, length=self.length)


def open_run(directory: str | Path, command: str) -> Run:
    """The outputs of the run in ``directory``; a folder without any is bad input, and so is a
    damaged file (see the module docstring). The XDMF file is read by :meth:`Run.series`."""
    path = Path(directory)
    if not path.is_dir():
        raise SceneError(f"{command}: {str(path)!r} is not a folder")
    summary_path, probes_path = path / SUMMARY, path / PROBES
    summary = read_summary(summary_path) if is_file(summary_path) else None
    columns, probes = read_probe_table(probes_path) if is_file(probes_path) else (None, None)
    xdmf = path / XDMF
    run = Run(path, summary, probes, xdmf if is_file(xdmf) else None, columns or PROBE_COLUMNS)
    if isinstance(summary, dict) and isinstance(summary.get("scene"), dict):
        if summary["scene"].get("structure") is not None:
            raise SceneError(
                f"{command}: {str(path)!r} is the run of a structure, and {command} reads a "
                "single rod's outputs (docs/structures.md); open its solution.xdmf in ParaView"
            )
    if run.probes is None and run.xdmf is None:
        raise SceneError(
            f"{command}: {str(path)!r} holds no run outputs ({PROBES}, {XDMF}); "
            "give the folder of a run (cosserat-fem run/static --out DIR)"
        )
    return run
