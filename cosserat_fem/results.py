"""Reading a run's outputs without DOLFINx: probes.csv, summary.json and the XDMF time series.

For ``cosserat-fem plot`` and ``cosserat-fem render`` (cosserat_fem/plot.py, render.py), which
must also work on a machine without the solver stack: numpy, the standard library's XML
parser and h5py (the ``plot``/``render`` extras) only. The XDMF file is the one of
:class:`cosserat_fem.output.XdmfWriter`: one temporal collection whose frames each carry the
mesh (the reference centreline (0, 0, s) [m]), the time and the point arrays. Files of the
earlier layout (DOLFINx's: a "mesh" grid with σ = s/ℓ along the first axis and one
collection per array) are read too.

h5py cannot be used in a process that has loaded DOLFINx (the two HDF5 libraries clash:
"Not a datatype"), so this module never imports DOLFINx and should not be imported next to
it; tests read the files through ``cosserat-fem plot``/``render`` in a subprocess.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import CosseratError, SceneError

PROBE_COLUMNS = ("t", "x", "y", "z", "theta", "psi", "phi")


@dataclass
class RodSeries:
    """The XDMF time series, points ordered along the rod.

    ``s`` [m] arc length of each point, ``reference`` (N, 3) the reference centreline
    (0, 0, s), ``times`` (T,) [s] (the load factor for a static run, the mode number for
    modes.xdmf), ``arrays`` name -> (T, N, 3) (see cosserat_fem/output.py for names, units
    and bases)."""

    s: np.ndarray
    reference: np.ndarray
    times: np.ndarray
    arrays: dict[str, np.ndarray]

    @property
    def length(self) -> float:
        return float(self.s[-1] - self.s[0])

    def positions(self, scale: float = 1.0) -> np.ndarray:
        """(T, N, 3) points of the deformed centreline r = (0, 0, s) + scale × displacement."""
        return self.reference[None, :, :] + scale * self.arrays["displacement"]


@dataclass
class Run:
    """A run folder's outputs: summary (or None), probes (rows, or None), XDMF path (or None)."""

    directory: Path
    summary: dict | None
    probes: np.ndarray | None
    xdmf: Path | None

    @property
    def time_label(self) -> str:
        """What the probes' t column and the XDMF times are."""
        if self.summary and self.summary.get("kind") == "static":
            return "load factor"
        return "t [s]"

    @property
    def title(self) -> str:
        scene = (self.summary or {}).get("scene", {})
        return scene.get("title") or self.directory.name

    @property
    def length(self) -> float | None:
        scene = (self.summary or {}).get("scene", {})
        return scene.get("rod", {}).get("length")

    def series(self) -> RodSeries:
        if self.xdmf is None:
            raise SceneError(f"{self.directory}: no solution.xdmf (was output.xdmf = false?)")
        return read_xdmf(self.xdmf, length=self.length)


def open_run(directory: str | Path, command: str) -> Run:
    """The outputs of the run in ``directory``; a folder without any is bad input."""
    path = Path(directory)
    if not path.is_dir():
        raise SceneError(f"{command}: {str(path)!r} is not a folder")
    summary = None
    if (path / "summary.json").is_file():
        try:
            summary = json.loads((path / "summary.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise SceneError(
                f"{command}: cannot read {str(path / 'summary.json')!r} ({exc})"
            ) from None
    probes = read_probes(path / "probes.csv") if (path / "probes.csv").is_file() else None
    xdmf = path / "solution.xdmf"
    run = Run(path, summary, probes, xdmf if xdmf.is_file() else None)
    if run.probes is None and run.xdmf is None:
        raise SceneError(
            f"{command}: {str(path)!r} holds no run outputs (probes.csv, solution.xdmf); "
            "give the folder of a run (cosserat-fem run/static --out DIR)"
        )
    return run


def read_probes(path: Path) -> np.ndarray:
    """Rows (t, x, y, z, θ, ψ, φ) of probes.csv; a cut last line (a killed run) is dropped."""
    rows = []
    with open(path, encoding="utf-8") as stream:
        header = stream.readline().strip().split(",")
        if tuple(header) != PROBE_COLUMNS:
            raise SceneError(f"{str(path)!r}: not a probes.csv (header {','.join(header)!r})")
        for line in stream:
            values = line.strip().split(",")
            if len(values) != len(PROBE_COLUMNS):
                continue
            try:
                rows.append([float(v) for v in values])
            except ValueError:
                continue
    return np.array(rows).reshape(-1, len(PROBE_COLUMNS))


def _h5py():
    try:
        import h5py
    except ImportError as exc:
        raise CosseratError(
            f"reading the XDMF file needs h5py ({exc}); install the plot extra: "
            "pip install -e .[plot]"
        ) from None
    return h5py


class _Datasets:
    """Open .h5 files of one XDMF file, by the ``file.h5:/path`` references of its XML."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.files: dict[str, object] = {}

    def read(self, item: ET.Element) -> np.ndarray:
        if item.get("Format") != "HDF":
            raise SceneError(f"XDMF: DataItem format {item.get('Format')!r} is not supported")
        name, dataset = item.text.strip().split(":", 1)
        if name not in self.files:
            try:
                self.files[name] = _h5py().File(self.folder / name, "r")
            except OSError as exc:
                raise SceneError(
                    f"XDMF: cannot open {str(self.folder / name)!r} ({exc})"
                ) from None
        try:
            return np.asarray(self.files[name][dataset], dtype=float)
        except KeyError:
            raise SceneError(f"XDMF: {name} holds no dataset {dataset}") from None

    def close(self) -> None:
        for f in self.files.values():
            f.close()


def read_xdmf(path: str | Path, length: float | None = None) -> RodSeries:
    """The time series of ``path`` (see the module docstring). ``length`` [m] is used only
    for files of the earlier layout, whose mesh coordinate is σ = s/ℓ (default 1)."""
    path = Path(path)
    try:
        domain = ET.parse(path).getroot().find("Domain")
    except (OSError, ET.ParseError) as exc:
        raise SceneError(f"{str(path)!r}: not a readable XDMF file ({exc})") from None
    mesh_grid = domain.find("Grid[@Name='mesh']")
    frames: dict[float, dict[str, ET.Element]] = {}
    geometry_item = topology_item = None
    for collection in domain.findall("Grid[@GridType='Collection']"):
        for grid in collection.findall("Grid"):
            t = float(grid.find("Time").get("Value"))
            frame = frames.setdefault(t, {})
            for attribute in grid.findall("Attribute"):
                frame[attribute.get("Name")] = attribute.find("DataItem")
            if geometry_item is None and grid.find("Geometry") is not None:
                geometry_item = grid.find("Geometry/DataItem")
                topology_item = grid.find("Topology/DataItem")
    if geometry_item is None:
        if mesh_grid is None:
            raise SceneError(f"{str(path)!r}: no mesh in the XDMF file")
        geometry_item = mesh_grid.find("Geometry/DataItem")
        topology_item = mesh_grid.find("Topology/DataItem")
    if not frames:
        raise SceneError(f"{str(path)!r}: the XDMF file holds no time steps")
    data = _Datasets(path.parent)
    try:
        x = data.read(geometry_item)
        cells = data.read(topology_item).astype(int)
        times = np.array(sorted(frames))
        names = sorted(set.intersection(*(set(frames[t]) for t in times)))
        arrays = {n: np.array([data.read(frames[t][n]) for t in times]) for n in names}
    finally:
        data.close()
    if x.shape[1] == 3 and not x[:, :2].any():
        s = x[:, 2]
    else:  # earlier layout: σ = s/ℓ along the first axis
        s = x[:, 0] * (1.0 if length is None else length)
    if cells.size and cells.max() >= len(s):
        raise SceneError(f"{str(path)!r}: topology refers to missing points")
    order = np.argsort(s, kind="stable")
    s = s[order]
    reference = np.zeros((len(s), 3))
    reference[:, 2] = s
    return RodSeries(
        s=s,
        reference=reference,
        times=times,
        arrays={n: a[:, order, :] for n, a in arrays.items()},
    )
