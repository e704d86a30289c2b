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

Damaged, truncated, foreign or hostile files are bad input: a :class:`SceneError` (exit 2)
whose one-line message names the file at fault, most often first (text taken from a file is
quoted with ``repr``, so no control character reaches the terminal), never another
exception. What is read has passed these checks:

* Every file is a regular file (not a folder, device, FIFO or dangling link: looked at before
  it is opened, and opened without blocking, cosserat_fem/safe_files.py) of at most
  :data:`MAX_PROBES_BYTES`, :data:`MAX_SUMMARY_BYTES` or :data:`MAX_XDMF_BYTES`; text is
  UTF-8.
* Numbers: finite and at most :data:`MAX_MAGNITUDE` in magnitude. NaN and inf are refused,
  not plotted: a run never writes them (it stops with a SolverError before a non-finite
  state reaches its outputs), so they mean damage; and matplotlib and VTK fail on values
  near the float range anyway.
* probes.csv: the header ``t,x,y,z,theta,psi,phi``, optionally followed by the columns of
  ``output.probe_fields`` (:data:`PROBE_FIELD_COLUMNS`, in that order), then every whole line
  as many numbers as the header names (blank lines are skipped). The text after the last
  newline is a row cut by a killed run and is dropped, whatever it holds; an empty file or a
  cut header (a run killed as it made the file) reads as no rows.
* summary.json: a JSON object; ``kind`` and ``scene.title`` strings, ``scene`` and
  ``scene.rod`` objects, ``scene.rod.length`` a positive number, where present.
* solution.xdmf: XML without entity declarations (an entity-expansion bomb is refused before
  anything is expanded), root ``Xdmf`` with a ``Domain`` (after the root, the writer's
  processing instruction of spare blanks, ``<?cosserat-fem-spare ...?>``, or any other, is
  skipped; frames may be separated by runs of blanks); each frame a ``Time`` whose value
  is a number, each ``Attribute`` a name and an HDF ``DataItem`` ``file.h5:/dataset`` whose
  file is a plain name in the XDMF file's folder (the single-file layout of earlier versions:
  ``solution.h5``, ``solution-restart<n>.h5``) or a file of the frames folder beside it,
  ``<name>.frames/mesh.h5`` or ``<name>.frames/<digits>.h5`` (one file a frame, written by
  :class:`cosserat_fem.output.XdmfWriter`; one folder level, no ``..``, no absolute path,
  nothing else); each dataset there, numeric, of the XML's ``Dimensions``; the geometry
  (N, 2 or 3) as its ``GeometryType`` says, N >= 2 points spanning a positive length; the
  topology integers in [0, N) (a message about the geometry or topology names its .h5 file
  first); every array (N, 3). At most :data:`MAX_VALUES` numbers are
  read from the .h5 files of one XDMF file. An XDMF file without any frame (a run killed
  before its first) raises :class:`NoFramesError`, which ``plot`` takes as "no surfaces"
  when probes.csv has rows.
* A scratch ``solution.xdmf-partial`` or ``summary.json.tmp`` left by a killed run is never
  read.
"""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
import xml.parsers.expat
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from . import safe_files
from .errors import CosseratError, SceneError
from .io.probes import PROBE_COLUMNS, read_probe_table
from .io.reading import (
    MAX_MAGNITUDE,
    decode,
    excerpt,
    finite_number,
    is_file,
    json_kind,
    quoted,
    read_bytes,
    short_reason,
)

#: Largest files read [bytes]: an XDMF file ~1-2.5 kB a frame (some 60 000 frames),
#: summary.json ~4 kB.
MAX_XDMF_BYTES = 128 << 20
MAX_SUMMARY_BYTES = 16 << 20
#: Most numbers read from the .h5 files of one XDMF file (800 MB as float64; the default
#: run holds ~1e5, a run of 10 000 frames of all six arrays on 300 points ~5e7).
MAX_VALUES = 10**8
#: Longest title shown in a figure [characters].
MAX_TITLE = 120


class NoFramesError(SceneError):
    """An XDMF file that holds no frame (yet): a run killed before it wrote its first."""


@dataclass
class RodSeries:
    """The XDMF time series, points ordered along the rod.

    ``s`` [m] arc length of each point, ``reference`` (N, 3) the reference centreline
    (0, 0, s), ``times`` (T,) [s] (the load factor for a static run, the mode number for
    modes.xdmf), ``arrays`` name -> (T, N, 3) (see cosserat_fem/output.py for names, units
    and bases). N >= 2, T >= 1, every value finite (see the module docstring)."""

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
            raise SceneError(f"{self.directory}: no solution.xdmf (was output.xdmf = false?)")
        return read_xdmf(self.xdmf, length=self.length)


def open_run(directory: str | Path, command: str) -> Run:
    """The outputs of the run in ``directory``; a folder without any is bad input, and so is a
    damaged file (see the module docstring). The XDMF file is read by :meth:`Run.series`."""
    path = Path(directory)
    if not path.is_dir():
        raise SceneError(f"{command}: {str(path)!r} is not a folder")
    summary_path, probes_path = path / "summary.json", path / "probes.csv"
    summary = read_summary(summary_path) if is_file(summary_path) else None
    columns, probes = read_probe_table(probes_path) if is_file(probes_path) else (None, None)
    xdmf = path / "solution.xdmf"
    run = Run(path, summary, probes, xdmf if is_file(xdmf) else None, columns or PROBE_COLUMNS)
    if run.probes is None and run.xdmf is None:
        raise SceneError(
            f"{command}: {str(path)!r} holds no run outputs (probes.csv, solution.xdmf); "
            "give the folder of a run (cosserat-fem run/static --out DIR)"
        )
    return run


def read_summary(path: str | Path) -> dict:
    """summary.json as a dict, with the fields that plot and render use checked: ``kind`` and
    ``scene.title`` strings, ``scene.rod.length`` a positive number, where present."""
    path = Path(path)
    text = decode(path, read_bytes(path, MAX_SUMMARY_BYTES))
    try:
        summary = json.loads(text)
    except (ValueError, RecursionError) as exc:  # RecursionError: [[[[... nested too deep
        message = str(exc) if isinstance(exc, ValueError) else "nested too deep"
        raise SceneError(f"{quoted(path)}: not JSON ({message})") from None
    if not isinstance(summary, dict):
        raise SceneError(
            f"{quoted(path)}: not a run's summary (a JSON object) but {json_kind(summary)}"
        )

    def bad(key: str, expected: str, value: object) -> SceneError:
        return SceneError(f"{quoted(path)}: {key} must be {expected}, got {json_kind(value)}")

    kind = summary.get("kind")
    if kind is not None and not isinstance(kind, str):
        raise bad("kind", "a string", kind)
    scene = summary.get("scene")
    if scene is None:
        return summary
    if not isinstance(scene, dict):
        raise bad("scene", "an object", scene)
    title = scene.get("title")
    if title is not None and not isinstance(title, str):
        raise bad("scene.title", "a string", title)
    rod = scene.get("rod")
    if rod is not None and not isinstance(rod, dict):
        raise bad("scene.rod", "an object", rod)
    length = (rod or {}).get("length")
    if length is not None:
        number = finite_number(length)
        if number is None or number <= 0:
            shown = json_kind(length)
            if not isinstance(length, bool) and isinstance(length, int | float):
                shown = repr(length) if len(repr(length)) <= 20 else repr(length)[:17] + "..."
            raise SceneError(
                f"{quoted(path)}: scene.rod.length must be a positive number, got {shown}"
            )
    return summary


def _h5py():
    """h5py; CosseratError if it is missing (the plot extra)."""
    try:
        import h5py
    except ImportError as exc:
        raise CosseratError(
            f"reading the XDMF file needs h5py ({exc}); install the plot extra: "
            "pip install -e .[plot]"
        ) from None
    return h5py


#: What h5py raises on a damaged file or dataset (HDF5 errors are OSError, KeyError,
#: ValueError or RuntimeError; TypeError and IndexError for odd types and shapes).
_H5_ERRORS = (OSError, RuntimeError, ValueError, TypeError, KeyError, IndexError)


#: The names of the files in an XDMF file's frames folder (cosserat_fem/output.py,
#: ``frames_folder``): the mesh's and one a frame; what a new series removes there.
FRAME_NAME = re.compile(r"(?:mesh|[0-9]{6,})\.h5")
#: The one reference that is not a plain name: a file of the frames folder beside the XDMF file:
#: one folder level, no ".." or absolute path.
_FRAME_FILE = re.compile(r"[^/\\]+\.frames/" + FRAME_NAME.pattern)


class _Datasets:
    """Open .h5 files of one XDMF file, by the ``file.h5:/path`` references of its XML."""

    def __init__(self, xdmf: Path):
        self.xdmf = xdmf
        self.folder = xdmf.parent
        self.files: dict[str, object] = {}
        self.budget = MAX_VALUES

    def __enter__(self) -> _Datasets:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _bad(self, what: str, problem: str) -> SceneError:
        return SceneError(f"{quoted(self.xdmf)}: {what}: {problem}")

    def _open(self, name: str, what: str):
        """The h5py File ``name`` of the XDMF file's folder, opened once; SceneError if it is
        missing or not HDF5."""
        if name not in self.files:
            path = self.folder / name
            if not is_file(path):
                raise self._bad(what, f"refers to {str(path)!r}, which does not exist")
            h5py = _h5py()
            try:
                self.files[name] = h5py.File(path, "r")
            except _H5_ERRORS as exc:
                raise SceneError(
                    f"{quoted(path)}: not a readable HDF5 file ({short_reason(exc)}); referred "
                    f"to by {self.xdmf.name}"
                ) from None
        return self.files[name]

    def where(self, item: ET.Element, what: str) -> str:
        """The dataset of DataItem ``item`` (of ``what``) for a message: the .h5 file first,
        then the XDMF file."""
        name, _, dataset = (item.text or "").strip().partition(":")
        in_xml = f"({what} in {self.xdmf.name})"
        return f"{quoted(self.folder / name)}: dataset {excerpt(dataset)} {in_xml}"

    def read(self, item: ET.Element, what: str, shape: tuple[int, ...] | None = None):
        """The dataset that DataItem ``item`` (of ``what``) refers to, as float64, after the
        checks of the module docstring; ``shape`` the one it must have, if known."""
        if item.get("Format", "XML") != "HDF":
            problem = f"DataItem Format {excerpt(item.get('Format', 'XML'))} is not supported"
            raise self._bad(what, problem + " (HDF only)")
        text = (item.text or "").strip()
        name, colon, dataset = text.partition(":")
        if not (colon and name and dataset):
            raise self._bad(what, f"DataItem {excerpt(text)} is not 'file.h5:/dataset'")
        plain = not ("/" in name or "\\" in name or name in (".", ".."))
        if not (plain or _FRAME_FILE.fullmatch(name)):
            raise self._bad(
                what,
                f"{excerpt(name)} is not a file name in the XDMF file's folder, nor a frame file "
                "'<name>.frames/<digits>.h5' or '<name>.frames/mesh.h5'",
            )
        dims = item.get("Dimensions")
        expected = None
        if dims is not None:
            try:
                expected = tuple(int(n) for n in dims.split())
            except ValueError:
                raise self._bad(what, f"Dimensions {excerpt(dims)} are not integers") from None
        h5 = self._open(name, what)
        h5_where = self.where(item, what)
        h5py = _h5py()
        try:
            obj = h5.get(dataset)
            if obj is None:
                raise SceneError(f"{h5_where}: not there")
            if not isinstance(obj, h5py.Dataset):
                raise SceneError(f"{h5_where}: not a dataset")
            if obj.shape is None:
                raise SceneError(f"{h5_where}: holds nothing (an empty dataspace)")
            if obj.dtype.kind not in "iuf":
                raise SceneError(f"{h5_where}: holds {obj.dtype} values, not numbers")
            if expected is not None and obj.shape != expected:
                raise SceneError(f"{h5_where}: shape {obj.shape}, the XML says {expected}")
            if shape is not None and obj.shape != shape:
                raise SceneError(f"{h5_where}: shape {obj.shape}, expected {shape}")
            if obj.size > self.budget:
                raise SceneError(f"{h5_where}: more than {MAX_VALUES} values in all; too large")
            self.budget -= obj.size
            values = np.asarray(obj[()], dtype=float)
        except _H5_ERRORS as exc:
            raise SceneError(f"{h5_where}: cannot read it ({short_reason(exc)})") from None
        if values.size and not (
            np.isfinite(values).all() and np.abs(values).max() <= MAX_MAGNITUDE
        ):
            raise SceneError(
                f"{h5_where}: holds values that are not finite or beyond ±{MAX_MAGNITUDE:g} "
                "(a run writes none)"
            )
        return values

    def close(self) -> None:
        """Close the open .h5 files (errors ignored)."""
        for f in self.files.values():
            try:
                f.close()
            except _H5_ERRORS:
                pass


class _EntityDeclared(Exception):
    pass


class _RootReached(Exception):
    pass


def _parse_xml(path: Path) -> ET.Element:
    """The root of the XML file ``path``; a file declaring entities is refused before any is
    expanded (billion laughs: expat >= 2.4 stops a bomb too, but not every Python has it)."""
    data = read_bytes(path, MAX_XDMF_BYTES)
    if not data.strip():
        raise SceneError(f"{quoted(path)}: empty file, not an XDMF file")
    scan = xml.parsers.expat.ParserCreate()

    def entity(name, *args):
        raise _EntityDeclared(name)

    def root(name, attributes):
        raise _RootReached  # the DTD, where entities are declared, lies before the root

    scan.EntityDeclHandler = entity
    scan.StartElementHandler = root
    try:
        scan.Parse(data, True)
    except _RootReached:
        pass
    except _EntityDeclared as exc:
        raise SceneError(
            f"{quoted(path)}: declares the XML entity {excerpt(str(exc))}; an XDMF file of a run "
            "declares none (refused: entity expansion)"
        ) from None
    except (xml.parsers.expat.ExpatError, ValueError, LookupError) as exc:
        raise SceneError(f"{quoted(path)}: not a readable XDMF file (XML: {exc})") from None
    try:
        return ET.fromstring(data)
    except (ET.ParseError, ValueError, LookupError) as exc:
        raise SceneError(f"{quoted(path)}: not a readable XDMF file (XML: {exc})") from None


def _item(path: Path, grid: ET.Element, part: str, where: str) -> ET.Element:
    """The DataItem of ``grid``'s ``part`` (Geometry or Topology)."""
    item = grid.find(f"{part}/DataItem")
    if item is None:
        raise SceneError(f"{quoted(path)}: {where} has no {part} with a DataItem")
    return item


def _time(path: Path, grid: ET.Element, index: int) -> float:
    """The Time Value of frame ``index`` (from 0): t [s], a load factor or a mode number;
    SceneError if it is missing or not a finite number within MAX_MAGNITUDE."""
    time = grid.find("Time")
    value = None if time is None else time.get("Value")
    if value is None:
        raise SceneError(f"{quoted(path)}: frame {index + 1} has no Time Value")
    try:
        t = float(value)
    except ValueError:
        t = math.nan
    if not (math.isfinite(t) and abs(t) <= MAX_MAGNITUDE):
        raise SceneError(
            f"{quoted(path)}: frame {index + 1}: Time Value {excerpt(value)} is not a finite number"
        )
    return t


#: Columns of the geometry by its GeometryType (XDMF's default is XYZ).
_GEOMETRY_COLUMNS = {"XYZ": 3, "XY": 2}


def read_xdmf(path: str | Path, length: float | None = None) -> RodSeries:
    """The time series of ``path`` (see the module docstring). ``length`` [m] is used only
    for files of the earlier layout, whose mesh coordinate is σ = s/ℓ (default 1)."""
    path = Path(path)
    if not is_file(path):
        raise SceneError(f"{quoted(path)}: no such file")
    root = _parse_xml(path)
    if root.tag != "Xdmf":
        raise SceneError(f"{quoted(path)}: not an XDMF file (root element {excerpt(root.tag)})")
    domain = root.find("Domain")
    if domain is None:
        raise SceneError(f"{quoted(path)}: not an XDMF file of a run (no Domain)")
    frames: dict[float, dict[str, ET.Element]] = {}
    mesh: ET.Element | None = None  # the grid holding Geometry and Topology
    index = 0
    for collection in domain.findall("Grid[@GridType='Collection']"):
        for grid in collection.findall("Grid"):
            t = _time(path, grid, index)
            frame = frames.setdefault(t, {})
            for attribute in grid.findall("Attribute"):
                name = attribute.get("Name")
                if not name:
                    raise SceneError(
                        f"{quoted(path)}: frame {index + 1} has an Attribute without a Name"
                    )
                item = attribute.find("DataItem")
                if item is None:
                    raise SceneError(
                        f"{quoted(path)}: frame {index + 1}: Attribute {excerpt(name)} has no "
                        "DataItem"
                    )
                frame[name] = item
            if mesh is None and grid.find("Geometry") is not None:
                mesh = grid
            index += 1
    if not frames:
        raise NoFramesError(f"{quoted(path)}: the XDMF file holds no time steps (yet)")
    where = "the first frame's mesh"
    if mesh is None:
        mesh, where = domain.find("Grid[@Name='mesh']"), "the grid 'mesh'"
        if mesh is None:
            raise SceneError(f"{quoted(path)}: no mesh in the XDMF file (no Geometry)")
    geometry = mesh.find("Geometry")
    if geometry is None:
        raise SceneError(f"{quoted(path)}: {where} has no Geometry")
    geometry_type = geometry.get("GeometryType", "XYZ")
    columns = _GEOMETRY_COLUMNS.get(geometry_type)
    if columns is None:
        raise SceneError(
            f"{quoted(path)}: GeometryType {excerpt(geometry_type)} is not supported (XYZ, XY)"
        )
    geometry_item = _item(path, mesh, "Geometry", where)
    topology_item = _item(path, mesh, "Topology", where)
    with _Datasets(path) as data:
        x = data.read(geometry_item, "geometry")
        if x.ndim != 2 or x.shape[1] != columns or len(x) < 2:
            raise SceneError(
                f"{data.where(geometry_item, 'geometry')}: shape {x.shape}; expected "
                f"(N, {columns}) for GeometryType {geometry_type}, N >= 2 points"
            )
        cells = data.read(topology_item, "topology")
        if cells.ndim != 2 or cells.shape[1] < 2 or len(cells) < 1:
            raise SceneError(
                f"{data.where(topology_item, 'topology')}: shape {cells.shape}; expected "
                "(cells, points per cell >= 2)"
            )
        if (cells != np.round(cells)).any() or cells.min() < 0 or cells.max() >= len(x):
            raise SceneError(
                f"{data.where(topology_item, 'topology')}: refers to points that are not "
                f"there (indices must be integers in [0, {len(x) - 1}])"
            )
        times = np.array(sorted(frames))
        names = sorted(set.intersection(*(set(frames[t]) for t in times)))
        count = len(times) * len(names) * len(x) * 3
        if count > data.budget:
            raise SceneError(
                f"{quoted(path)}: {len(times)} frames of {len(names)} arrays on {len(x)} "
                f"points: more than {MAX_VALUES} values; too large"
            )
        arrays = {}
        for n in names:
            values = np.empty((len(times), len(x), 3))
            for i, t in enumerate(times):
                what = f"{excerpt(n)} at time {t:.6g}"
                values[i] = data.read(frames[t][n], what, shape=(len(x), 3))
            arrays[n] = values
    if columns == 3 and not x[:, :2].any():
        s = x[:, 2]
    else:  # earlier layout: σ = s/ℓ along the first axis
        s = x[:, 0] * (1.0 if length is None else length)
    if not s.max() > s.min():
        where = f"{quoted(path)} (geometry {(geometry_item.text or '').strip()!r})"
        raise SceneError(f"{where}: the mesh has no length (all its points at one s)")
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


# --- a sweep's table (cosserat_fem/sweep_run.py) ----------------------------------------------
#: A sweep's table, and the folder of its parts (one a group of ranks: table/group-<k>.csv).
SWEEP_TABLE, SWEEP_PARTS = "sweep.csv", "table"
#: A member's status when it stopped for a passing reason (a full disk, limits.wall_time): not
#: finished; a sweep started again runs it, and its later row takes the stopped one's place.
STOPPED = "stopped"


def read_sweep_rows(directory: str | Path, parts_only: bool = False) -> tuple[list[str], list]:
    """(columns, rows) of the sweep in ``directory``: its sweep.csv, or its table parts (with
    ``parts_only``, or while there is no sweep.csv: a sweep killed or still running). A cut
    last line of a file (a kill) is left out, not changed on disk; the rows (dicts of text)
    come sorted by member. An unreadable file (a special file: refused, never opened) or a
    member that is not a number is bad input."""
    import csv

    directory = Path(directory)
    table = directory / SWEEP_TABLE
    if not parts_only and is_file(table):
        sources = [table]
    else:
        sources = sorted((directory / SWEEP_PARTS).glob("group-*.csv"))
    columns: list[str] = []
    rows: list[dict] = []
    for source in sources:
        try:
            text = safe_files.read_text(source)
        except (OSError, UnicodeDecodeError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) else exc
            raise SceneError(f"{quoted(source)}: cannot read it ({reason})") from None
        reader = csv.DictReader(text[: text.rfind("\n") + 1].splitlines())
        rows += _whole_rows(source, reader, columns)
        columns = list(reader.fieldnames or columns)
    if sources != [table]:
        rows = _latest_rows(rows)
    try:
        rows.sort(key=lambda row: int(row["member"]))
    except (KeyError, TypeError, ValueError):
        raise SceneError(f"{quoted(directory)}: not a sweep's table (a member that is not a "
                         "number)") from None  # fmt: skip
    return columns, rows


def _latest_rows(rows: list[dict]) -> list[dict]:
    """The rows of a sweep's table parts without those a later run replaced: a member's
    "stopped" row gives way to a row of its run again, or to its last stopped row (the parts
    are read in the order of their groups, not of time). Two rows of a member that did not
    stop are both kept (not the rows of one sweep: check_sweep_rows refuses them)."""
    ran = {row.get("member") for row in rows if row.get("status") != STOPPED}
    last_stop = {row.get("member"): row for row in rows
                 if row.get("status") == STOPPED and row.get("member") not in ran}  # fmt: skip
    return [row for row in rows
            if row.get("status") != STOPPED or last_stop.get(row.get("member")) is row]  # fmt: skip


def _whole_rows(source: Path, reader, columns: list[str]) -> list[dict]:
    """The rows of one file of a sweep's table, each with a field for every column of its
    header, the header the same as the other files' (``columns``, if read); SceneError naming
    the file and line otherwise: rows of another table, or damaged, are not merged."""
    header = reader.fieldnames
    if header is None:  # an empty part: its group was killed before it wrote its header
        return []
    if columns and list(header) != columns:
        raise SceneError(f"{quoted(source)}: its columns are not those of the sweep's other "
                         "table parts: not the same sweep's table")  # fmt: skip
    if len(set(header)) != len(header) or "" in header:
        raise SceneError(f"{quoted(source)}: a header with an empty or repeated column; not a "
                         "sweep's table")  # fmt: skip
    rows = []
    for row in reader:
        extra = row.pop(None, None) or []  # fields beyond the header's
        missing = sum(row[k] is None for k in header)  # fields short of it
        if extra or missing:
            raise SceneError(f"{quoted(source)}: line {reader.line_num} has "
                             f"{len(header) + len(extra) - missing} fields, not the header's "
                             f"{len(header)}")  # fmt: skip
        rows.append(row)
    return rows


def check_sweep_rows(directory: str | Path, columns: list[str], rows: list[dict],
                     record: dict) -> tuple[str, ...]:  # fmt: skip
    """The varied keys of the sweep recorded in ``record`` (its sweep.json, from
    cosserat_fem/sweep_run.py) after checking that ``rows`` are its rows: one a member, each
    of a member it has (0 ... members − 1), with the member's values of the varied keys as
    the sweep's table writes them (JSON), and the table's varied columns the record's.
    SceneError naming the table otherwise: a row of another sweep is not merged."""
    where = quoted(Path(directory) / SWEEP_TABLE)
    varied, members = record.get("varied"), record.get("members")
    if not (isinstance(varied, list) and all(isinstance(k, str) for k in varied)
            and isinstance(members, int) and not isinstance(members, bool)):  # fmt: skip
        raise SceneError(f"{quoted(Path(directory) / 'sweep.json')}: not a sweep's record "
                         "(varied, members)")  # fmt: skip
    if "wall_s" not in columns or "steps" not in columns or columns[
            columns.index("wall_s") + 1 : columns.index("steps")] != varied:  # fmt: skip
        raise SceneError(f"{where}: its varied columns are not the sweep's {varied}")
    values = _member_values(record, members)
    seen: set[int] = set()
    for row in rows:
        index = int(row["member"])
        if not 0 <= index < members or index in seen:
            reason = "twice" if index in seen else f"but the sweep has {members} members"
            raise SceneError(f"{where}: a row of member {index}, {reason}: not this sweep's "
                             "rows")  # fmt: skip
        seen.add(index)
        if values is not None and any(row[k] != json.dumps(values[index].get(k))
                                      for k in varied):  # fmt: skip
            raise SceneError(f"{where}: the row of member {index} holds other values of "
                             f"{', '.join(varied)} than the sweep's member: not this sweep's row")
    return tuple(varied)


def _member_values(record: dict, members: int) -> list[dict] | None:
    """Each member's values of the varied keys, from the record's fingerprint (the sweep's
    JSON document, cosserat_fem/sweep_spec.py), or None where it does not hold them."""
    try:
        listed = json.loads(record.get("fingerprint"))["members"]
    except (TypeError, ValueError, KeyError, RecursionError):
        return None
    if not isinstance(listed, list) or len(listed) != members:
        return None
    values = [m[0] if isinstance(m, list) and len(m) == 2 else m for m in listed]
    return values if all(isinstance(v, dict) for v in values) else None


def xdmf_mesh_xml(file: str, points: int, cells: int) -> str:
    """The Topology and Geometry of a frame: the mesh in the HDF5 file ``file`` (relative to
    the XML), as DOLFINx's XDMFFile wrote them (cosserat_fem/output.py's frames and
    karhunen_loeve.py's pod.xdmf)."""
    name = escape(file)
    return (
        f'        <Topology TopologyType="PolyLine" NumberOfElements="{cells}" '
        'NodesPerElement="2">\n'
        f'          <DataItem Dimensions="{cells} 2" NumberType="Int" Format="HDF">{name}:'
        "/Mesh/mesh/topology</DataItem>\n"
        "        </Topology>\n"
        '        <Geometry GeometryType="XYZ">\n'
        f'          <DataItem Dimensions="{points} 3" Format="HDF" Precision="8">{name}:'
        "/Mesh/mesh/geometry</DataItem>\n"
        "        </Geometry>\n"
    )
