"""solution.xdmf (and modes.xdmf, pod.xdmf): a time series of point arrays on the rod's
centreline for ParaView, the XML beside a folder of HDF5 files, one a frame. The writer of the
files (:class:`XdmfSeries`, given the values by cosserat_fem/output/fields.py's
:class:`~cosserat_fem.output.fields.XdmfWriter`), their reader without DOLFINx (:func:`read_xdmf`),
and a restart's check and cut of them (:func:`xdmf_problem`, :func:`cut_xdmf`). The format's names
are kept here and nowhere else.

Files: the XML ``<name>.xdmf`` and the folder ``<name>.frames/`` (:func:`frames_folder`) of HDF5
files: the mesh in ``mesh.h5`` (``/Mesh/mesh/geometry``, ``/Mesh/mesh/topology``), frame i
(from 0, restarts included) in ``<i, 6 digits>.h5`` (``/Function/<array>/<t>``, t as in the
XML's Time with "_" for "."), e.g. ``solution.frames/000012.h5``; the XML names them relative to
its own folder. One temporal collection ``rod`` (:data:`XDMF_GRID`) whose frames each carry the
mesh (Topology, Geometry), the Time and every array (:data:`FIELD_ARRAYS`), float64, so that
ParaView shows one dataset; the run's identity in an Information element (:data:`RUN_ID`).
After ``</Xdmf>`` the XML ends with a processing instruction ``<?cosserat-fem-spare ...?>`` of
blanks: room for the frames to come.

The reader (for ``cosserat-fem plot``/``render``, without DOLFINx: h5py cannot be used in a
process that has loaded DOLFINx, the two HDF5 libraries clash: "Not a datatype"; so h5py is
imported only when a file is read, and the writer's HDF5 is DOLFINx's, through
cosserat_fem/io/hdf5.py) also reads files of the earlier layouts (DOLFINx's: a "mesh" grid with
σ = s/ℓ along the first axis and one collection per array; one HDF5 file for all frames,
``solution.h5``, ``solution-restart<n>.h5``). What it reads has passed these checks (bad input
otherwise: a SceneError naming the file at fault): XML of at most :data:`MAX_XDMF_BYTES`
without entity declarations (an entity-expansion bomb is refused before anything is
expanded), root ``Xdmf`` with a ``Domain`` (after the root, the writer's processing instruction
of spare blanks, or any other, is skipped; frames may be separated by runs of blanks); each
frame a ``Time`` whose value is a number, each ``Attribute`` a name and an HDF ``DataItem``
``file.h5:/dataset`` whose file is a plain name in the XDMF file's folder or a file of the
frames folder beside it, ``<name>.frames/mesh.h5`` or ``<name>.frames/<digits>.h5`` (one folder
level, no ``..``, no absolute path, nothing else); each dataset there, numeric, of the XML's
``Dimensions``; the geometry (N, 2 or 3) as its ``GeometryType`` says, N >= 2 points spanning a
positive length; the topology integers in [0, N) (a message about the geometry or topology
names its .h5 file first); every array (N, 3), finite. At most :data:`MAX_VALUES` numbers are
read from the .h5 files of one XDMF file. An XDMF file without any frame (a run killed before
its first) raises :class:`NoFramesError`, which ``plot`` takes as "no surfaces" when probes.csv
has rows. A scratch ``solution.xdmf-partial`` left by a killed run is never read.

No file is written through a link, and no special file is opened
(cosserat_fem/common/safe_files.py): every XDMF and HDF5 file is a new file or renamed over the old
name. Tests: tests/test_xdmf_writer.py, tests/test_kill.py, tests/test_kill_window.py,
tests/test_restart.py, tests/test_output_fuzz.py.
"""

from __future__ import annotations

import io
import math
import mmap
import os
import re
import resource
import time
import xml.etree.ElementTree as ET
import xml.parsers.expat
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import CosseratError, OutputError, SceneError
from cosserat_fem.io.hdf5 import Hdf5
from cosserat_fem.io.reading import (
    MAX_MAGNITUDE,
    excerpt,
    is_file,
    quoted,
    read_bytes,
    short_reason,
)

#: The file's name in a run's folder.
XDMF = "solution.xdmf"
#: The point arrays of each ``output.fields`` entry, in the order they are written.
FIELD_ARRAYS: dict[str, tuple[str, ...]] = {
    "displacement": ("displacement",),
    "angles": ("angles",),
    "strains": ("strain_v", "curvature_u"),
    "forces": ("force_n", "torque_m"),
    "directors": ("director_d1", "director_d2", "director_d3"),
    "contact": ("contact_load", "contact_gap"),
}

#: The folder of an XDMF file's HDF5 files: ``<stem>.frames`` beside ``<stem>.xdmf``.
FRAMES_SUFFIX = ".frames"
#: The HDF5 file of the mesh in that folder (written once, when the series starts).
MESH_FILE = "mesh.h5"
#: Digits of a frame file's name: frame i (from 0) is ``<stem>.frames/<i, zero padded>.h5``.
FRAME_DIGITS = 6


def frames_folder(xdmf: Path) -> Path:
    """The folder of the HDF5 files of the XDMF file ``xdmf`` (see :class:`XdmfWriter`)."""
    xdmf = Path(xdmf)
    return xdmf.with_name(xdmf.stem + FRAMES_SUFFIX)


def frame_file(index: int) -> str:
    """The name, in :func:`frames_folder`, of the HDF5 file of frame ``index`` (from 0)."""
    return f"{index:0{FRAME_DIGITS}d}.h5"


#: The names of the files in an XDMF file's frames folder
#: (:func:`frames_folder`): the mesh's and one a frame; what a new series removes there.
FRAME_NAME = re.compile(
    rf"(?:{re.escape(Path(MESH_FILE).stem)}|[0-9]{{{FRAME_DIGITS},}}){re.escape(Path(MESH_FILE).suffix)}"
)
#: The one reference that is not a plain name: a file of the frames folder beside the XDMF file:
#: one folder level, no ".." or absolute path.
_FRAME_FILE = re.compile(rf"[^/\\]+{re.escape(FRAMES_SUFFIX)}/" + FRAME_NAME.pattern)

#: Largest XDMF file read [bytes]: ~1-2.5 kB a frame (some 60 000 frames).
MAX_XDMF_BYTES = 128 << 20
#: Most numbers read from the .h5 files of one XDMF file (800 MB as float64; the default
#: run holds ~1e5, a run of 10 000 frames of all six arrays on 300 points ~5e7).
MAX_VALUES = 10**8


#: The datasets of the mesh in :data:`MESH_FILE` (as DOLFINx's XDMFFile named them).
MESH_GEOMETRY, MESH_TOPOLOGY = "/Mesh/mesh/geometry", "/Mesh/mesh/topology"


def function_dataset(array: str, key: str) -> str:
    """The dataset of the point array ``array`` of the frame ``key`` in its frame file."""
    return f"/Function/{array}/{key}"


def xdmf_mesh_xml(file: str, points: int, cells: int) -> str:
    """The Topology and Geometry of a frame: the mesh in the HDF5 file ``file`` (relative to
    the XML), as DOLFINx's XDMFFile wrote them (this module's frames and
    karhunen_loeve.py's pod.xdmf)."""
    name = escape(file)
    return (
        f'        <Topology TopologyType="PolyLine" NumberOfElements="{cells}" '
        'NodesPerElement="2">\n'
        f'          <DataItem Dimensions="{cells} 2" NumberType="Int" Format="HDF">{name}:'
        f"{MESH_TOPOLOGY}</DataItem>\n"
        "        </Topology>\n"
        '        <Geometry GeometryType="XYZ">\n'
        f'          <DataItem Dimensions="{points} 3" Format="HDF" Precision="8">{name}:'
        f"{MESH_GEOMETRY}</DataItem>\n"
        "        </Geometry>\n"
    )


# --- the writer ---------------------------------------------------------------------------------
class _FrameImages:
    """The bytes of the frame files of a series: the datasets ``/Function/<array>/<key>``,
    each (points, 3), made by HDF5 (:class:`Hdf5`) for the first key of each length and then
    by copying an image of that length with the key and the values put in their places (the cost
    of each: docs/decisions.md, "XDMF frames"). The copy is used only if, for that first frame,
    it gives the very bytes HDF5 made (superblock 0 and the object formats of HDF5 1.8 carry no
    checksums, and time stamps are off, so the bytes depend on the names and values alone);
    otherwise HDF5 makes every frame's file."""

    def __init__(self, h5: Hdf5, arrays: list[str]):
        self.h5, self.arrays = h5, arrays
        self._templates: dict[int, tuple[bytes, list[int], list[int]] | None] = {}

    def _datasets(self, key: str, values: np.ndarray) -> list[tuple[str, np.ndarray]]:
        return [
            (function_dataset(name, key), np.ascontiguousarray(values[:, 3 * i : 3 * i + 3]))
            for i, name in enumerate(self.arrays)
        ]

    def __call__(self, key: str, values: np.ndarray):
        """The bytes (bytes-like) of the file of ``values`` (points, 3 per array) at ``key``."""
        if len(key) not in self._templates:
            image = self.h5.image(self._datasets(key, values))[0]
            self._templates[len(key)] = self._template(key, values, bytes(image))
            return image
        template = self._templates[len(key)]
        if template is None:
            return self.h5.image(self._datasets(key, values))[0]
        return self._copy(template, key, values)

    def _copy(self, template, key: str, values: np.ndarray) -> bytearray:
        base, keys, data = template
        image = bytearray(base)
        name = key.encode()
        for at in keys:
            image[at : at + len(name)] = name
        n = len(values)
        for i, at in enumerate(data):
            into = np.frombuffer(image, dtype="<f8", count=3 * n, offset=at).reshape(n, 3)
            into[:] = values[:, 3 * i : 3 * i + 3]
        return image

    def _template(self, key: str, values: np.ndarray, made: bytes):
        """(image, where the key is, where the values are) for keys of len(key), from images
        of the keys "aa..." and "bb..." (the key: the bytes where they differ); None unless
        the copy for ``key`` and ``values`` is ``made``, HDF5's image of them."""
        length, zero = len(key), np.zeros_like(values)
        image_a, data = self.h5.image(self._datasets("a" * length, zero))
        b = bytes(self.h5.image(self._datasets("b" * length, zero))[0])
        a = bytes(image_a)
        if not len(a) == len(b) == len(made):
            return None
        differ = np.flatnonzero(np.frombuffer(a, np.uint8) != np.frombuffer(b, np.uint8))
        keys = [int(at) for at in differ[::length]] if differ.size else []
        if len(differ) != length * len(self.arrays) or any(
            a[at : at + length] != b"a" * length for at in keys
        ):
            return None
        template = (a, keys, [int(at) for at in data])
        return template if self._copy(template, key, values) == made else None


def _time_text(t: float) -> str:
    """A frame's time as the XML gives it (as DOLFINx's XDMFFile did: 17 significant digits);
    with "_" for "." it names the frame's datasets."""
    return f"{t:.17g}"


def _free_bytes(folder: Path) -> int:
    """The bytes free (to this user) in the file system of ``folder``."""
    info = os.statvfs(folder)
    return info.f_bavail * info.f_frsize


def _blocks(size: int) -> int:
    """``size`` bytes rounded up to whole blocks of 4 KiB (what a file of that size takes)."""
    return -(-size // 4096) * 4096


#: ``data`` (bytes-like) into a new file ``path`` (whatever had the name is replaced: never
#: written through a link; cosserat_fem/common/safe_files.py).
_write_file = safe_files.write_new


class XdmfSeries:
    """The files of an XDMF time series of point arrays on a polyline, written by one process
    (rank 0 of a run; cosserat_fem/output/fields.py's
    :class:`~cosserat_fem.output.fields.XdmfWriter` gives it the values): the format of the module
    docstring, kill-safe.

    Kill-safe: after a kill at any moment (SIGKILL included), ``<name>.xdmf`` is well-formed
    and names exactly the frames written before, each in a complete HDF5 file that is never
    opened for writing again (the file of a frame killed in flight, which it does not name, is
    replaced by the next write of that frame or deleted by a restart). A frame is (1) written
    into a new HDF5 file (its bytes made in memory, :class:`~cosserat_fem.io.hdf5.Hdf5`) and
    (2) added to the XML in place: the frame and new closing tags are written into the spare
    room, still inside the processing instruction (the document is unchanged), then one write
    of blanks, which lies within one memory page (Linux does not split such a write on a kill),
    turns the old closing tags and the instruction's opening into whitespace. When the room is
    used up, the XML is written anew, with room as large as the file was (16 KiB to 4 MiB; less
    under a file size limit), under a working name and renamed onto ``<name>.xdmf``. A frame is
    written only if its file and the XML fit in the file system and under ``ulimit -f``, else
    an OutputError (the frames before kept). Why this layout and what it costs:
    docs/decisions.md, "XDMF frames".
    """

    #: The least and the most spare room [bytes] after ``</Xdmf>`` when the XML is rewritten.
    SPARE = (16 << 10, 4 << 20)

    def __init__(
        self,
        path: Path,
        arrays: list[str],
        geometry: np.ndarray,
        topology: np.ndarray,
        resume: int | None = None,
        run_id: str | None = None,
    ):
        """``arrays``: the names of the point arrays of every frame (:data:`FIELD_ARRAYS`),
        each (points, 3); ``geometry`` (points, 3) [m] and ``topology`` (segments, 2): the
        mesh, its points in the order :meth:`write` gets the values. ``resume = frames``:
        continue the existing XML, which holds ``frames`` frames (cut back to them, later frame
        files deleted: cosserat_fem/io/checkpoint.py), in its mesh's order of the points; the new
        frames go into new frame files from index ``frames`` on. Otherwise the XML and the
        frames folder of an earlier series are removed first. ``run_id``: the identity of the
        run, written into the XML (checked by a restart). OutputError if the files cannot be
        written."""
        self.path = Path(path)
        self.arrays = list(arrays)
        self.geometry, self.topology = geometry, topology
        suffix = self.path.suffix or ".xdmf"
        # A rewritten XML is written under this name, then renamed onto self.path.
        self._work = self.path.with_name(self.path.stem + suffix + "-partial")
        self.folder = frames_folder(self.path)
        self._doc: _XdmfDocument | None = None
        self._to_file: np.ndarray | None = None  # a resumed file's order of the points
        self._free = (0, -math.inf)  # free bytes of the file system, and until when to trust
        self.writes = 0 if resume is None else resume
        try:
            self._h5 = Hdf5()
            self._images = _FrameImages(self._h5, self.arrays)
            if resume is not None:
                self._resume()
            else:
                self._start(run_id)
        except OutputError:
            raise
        except (OSError, RuntimeError, ValueError, ET.ParseError) as exc:
            raise OutputError(
                f"output: cannot write the XDMF file {str(self.path)!r} "
                f"({getattr(exc, 'strerror', None) or exc})"
            ) from None

    @property
    def _document(self) -> _XdmfDocument:
        """The XML of the series, set by ``_start`` or ``_resume`` in the constructor."""
        if self._doc is None:
            raise RuntimeError("XdmfSeries: the XML was not started")
        return self._doc

    @property
    def h5(self) -> Path:
        """The HDF5 file the next frame goes into."""
        return self.folder / frame_file(self.writes)

    def _start(self, run_id: str | None) -> None:
        """A new series (rank 0): the XML and the frames of an earlier one removed (the XML
        first; in the frames folder only the files it writes, :data:`FRAME_NAME`: a user's
        files or folders there stay), ``mesh.h5`` written, the XML without frames published."""
        safe_files.remove_name(self.path)
        safe_files.remove_own_files(self.folder, FRAME_NAME)
        self.folder.mkdir(exist_ok=True)
        self._doc = _XdmfDocument(self.path, self._work, self._write_mesh(), run_id)
        self._rewrite(None, "the XDMF file")

    def _write_mesh(self) -> str:
        """``mesh.h5`` written (rank 0; OutputError if it may not fit); the Topology and
        Geometry that name it."""
        image = self._h5.image([(MESH_GEOMETRY, self.geometry), (MESH_TOPOLOGY, self.topology)])[0]
        self._check_room(len(image), 0, "the XDMF mesh", self.folder / MESH_FILE)
        _write_file(self.folder / MESH_FILE, image)
        return xdmf_mesh_xml(
            self.folder.name + "/" + MESH_FILE, len(self.geometry), len(self.topology)
        )

    def _resume(self) -> None:
        """Continue the published XML (rank 0): its frames and mesh kept, the values of the
        new frames put in the order of that mesh's points; the XML published anew (the same
        document, with spare room)."""
        text = safe_files.read_text(self.path)
        self._doc = _XdmfDocument.parse(self.path, self._work, text)
        self.folder.mkdir(exist_ok=True)  # outputs of the single-file layout
        if self._document.mesh is None:  # no frame yet: the mesh as a new series writes it
            self._document.mesh = self._write_mesh()
        else:
            self._to_file = self._file_order()
        self._rewrite(None, "the XDMF file")

    def _file_order(self) -> np.ndarray | None:
        """The output point (numbered in the order of σ) at each point of the resumed file's
        mesh (None if they are the same): earlier writers numbered the points as DOLFINx's
        output mesh did (under MPI not in the order of σ)."""
        item = ET.fromstring(f"<m>{self._document.mesh}</m>").find("Geometry/DataItem")
        text = item.text if item is not None else None  # no item: no file (OSError below)
        name, _, dataset = (text or "").strip().partition(":")
        os.close(safe_files.open_regular(self.path.parent / name))  # HDF5 would wait on a FIFO
        x = self._h5.read(self.path.parent / name, dataset)
        mine = self.geometry
        if x.shape == mine.shape:
            if np.array_equal(x, mine):
                return None
            order = np.argsort(x[:, 2], kind="stable")  # the file's points in the order of σ
            if np.allclose(x[order], mine, rtol=0.0, atol=1e-12 * max(mine[-1, 2], 1.0)):
                at = np.empty_like(order)
                at[order] = np.arange(len(order))
                return at
        raise OutputError(
            f"output: cannot continue {str(self.path)!r}: its mesh ({name}) is not this "
            "rod's output mesh"
        )

    def _check_room(self, file_bytes: int, xml_bytes: int, what: str, where: Path) -> None:
        """OutputError unless a new file of ``file_bytes`` and an XML of ``xml_bytes`` (0: not
        rewritten) fit under ``ulimit -f`` and in the file system (the limits are kept for
        :meth:`_rewrite`)."""
        soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        limit: float = math.inf if soft == resource.RLIM_INFINITY else soft
        need = _blocks(file_bytes) + _blocks(xml_bytes) + (64 << 10)
        now = time.monotonic()
        # The free space is asked for again after a second, or when less than 1 GiB more than
        # needed is left; in between it is counted down (statvfs's cost: docs/decisions.md,
        # "XDMF frames", room before a frame).
        if now > self._free[1] or self._free[0] < need + (1 << 30):
            self._free = (_free_bytes(self.folder), now + 1.0)
        free = self._free[0]
        self._limits = (limit, free)
        problem = None
        if max(file_bytes, xml_bytes) > limit:
            problem = f"the file size limit (ulimit -f) of {limit} bytes would be reached"
        elif need > free:
            problem = f"no space left on the device ({free} bytes free)"
        if problem:
            raise OutputError(
                f"output: {what} was not written to {str(where)!r}: {problem}; the frames "
                "before are kept"
            )
        self._free = (free - need + (64 << 10), self._free[1])

    def _rewrite(self, frame: bytes | None, what: str, written: int = 0) -> None:
        """The XML published anew with ``frame`` added (rank 0), with spare room (class
        docstring) as far as the limits allow; ``written``: bytes written since the limits
        were taken."""
        size = self._document.rewrite_size(frame)
        if frame is None:
            self._check_room(0, size, what, self.path)
        limit, free = self._limits
        free -= _blocks(written) + _blocks(size) + (64 << 10)
        low, high = self.SPARE
        spare = min(max(size, low), high, limit - size, free)
        self._document.rewrite(frame, int(max(spare, 0)))

    def write(self, t: float, values: np.ndarray) -> None:
        """A frame at t [s] (a load factor, a mode number) of ``values`` (points, 3 per array,
        in the order of :attr:`arrays`); OutputError if it may not fit or is not written, the
        frames before kept."""
        try:
            self._write_frame(t, values)
        except OutputError:
            raise
        except (OSError, RuntimeError) as exc:
            raise OutputError(
                f"output: cannot write the XDMF frame at t = {t:.6g} to "
                f"{str(self.folder)!r} ({getattr(exc, 'strerror', None) or exc}); the "
                "frames before are kept"
            ) from None
        self.writes += 1

    def _write_frame(self, t: float, values: np.ndarray) -> None:
        """Rank 0: the frame's HDF5 file, then the frame added to the XML (class docstring)."""
        if self._to_file is not None:
            values = values[self._to_file]
        value = _time_text(t)
        key = value.replace(".", "_")
        image = self._images(key, values)
        h5 = self.h5
        frame = self._document.frame(
            value, f"{self.folder.name}/{h5.name}", key, self.arrays, len(values)
        )
        rewrite = not self._document.fits(frame)
        what = f"the XDMF frame at t = {t:.6g}"
        xml_bytes = self._document.rewrite_size(frame) if rewrite else 0
        self._check_room(len(image), xml_bytes, what, h5)
        _write_file(h5, image)
        if rewrite:
            self._rewrite(frame, what, len(image))
        else:
            self._document.append(frame)

    def close(self) -> None:
        """Close the XML (rank 0); the files are complete after every frame."""
        if self._doc is not None:
            self._doc.close()


_XDMF_HEAD = (
    '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
    '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
)
#: The one temporal collection of the published XML (and the name of each of its frames).
XDMF_GRID = "rod"
#: The name of the Information element of the Domain that holds the run's identity.
RUN_ID = "run_id"
#: The end of the document, and the opening of the processing instruction of spare room after
#: it (closed by ``?>`` at the end of the file): the blanks a frame is added with replace them.
#: (the XML after the last frame).
XDMF_TAIL = "    </Grid>\n  </Domain>\n</Xdmf>\n"
_XDMF_TAIL = XDMF_TAIL.encode()
_SPARE_OPEN = b"<?cosserat-fem-spare"
_SPARE_CLOSE = b"?>\n"
_SWITCH = len(_XDMF_TAIL) + len(_SPARE_OPEN)
_PAGE = max(mmap.PAGESIZE, 4096)


def _pad(offset: int) -> int:
    """Blanks to put at ``offset`` so that the _SWITCH bytes after them lie in one page."""
    within = offset % _PAGE
    return 0 if within + _SWITCH <= _PAGE else _PAGE - within


def xdmf_run_id(root: ET.Element) -> str | None:
    """The run identity written into an XDMF file by :class:`XdmfWriter` (None if none)."""
    domain = root.find("Domain")
    item = None if domain is None else domain.find(f"Information[@Name='{RUN_ID}']")
    return None if item is None else item.get("Value")


def xdmf_head(grid: str, run_id: str | None = None) -> str:
    """The XML up to the first frame: the document, its Domain (with the run's identity, if
    any) and the temporal collection ``grid``; :data:`XDMF_TAIL` closes them."""
    identity = ""
    if run_id is not None:
        identity = f"    <Information Name={quoteattr(RUN_ID)} Value={quoteattr(run_id)} />\n"
    return (
        f"{_XDMF_HEAD}  <Domain>\n{identity}"
        f'    <Grid Name="{grid}" GridType="Collection" CollectionType="Temporal">\n'
    )


def xdmf_frame_xml(
    grid: str, mesh: str, value: str, file: str, key: str, arrays: list[str], points: int
) -> str:
    """The text of a frame of the collection ``grid`` at the time ``value``: ``mesh`` (its
    Topology and Geometry, :func:`xdmf_mesh_xml`), and its ``arrays`` (each ``points`` x 3),
    the datasets :func:`function_dataset` (array, ``key``) of the HDF5 file ``file``
    (relative to the XML)."""
    parts = [
        f'      <Grid Name="{grid}" GridType="Uniform">\n',
        mesh,
        f"        <Time Value={quoteattr(value)} />\n",
    ]
    where = escape(file)
    for name in arrays:
        parts.append(
            f'        <Attribute Name="{name}" AttributeType="Vector" Center="Node">\n'
            f'          <DataItem Dimensions="{points} 3" Format="HDF" Precision="8">'
            f"{where}:{escape(function_dataset(name, key))}</DataItem>\n"
            "        </Attribute>\n"
        )
    parts.append("      </Grid>\n")
    return "".join(parts)


def _element_text(element: ET.Element, level: int) -> str:
    """``element`` as indented XML text at depth ``level``; float DataItems marked
    ``Precision="8"`` (they are float64 in the .h5; unmarked, ParaView reads float32)."""
    for item in element.iter("DataItem"):
        if item.get("NumberType", "Float") == "Float" and "Precision" not in item.attrib:
            item.set("Precision", "8")
    ET.indent(element, space="  ", level=level)
    element.tail = None
    return "  " * level + ET.tostring(element, encoding="unicode") + "\n"


class _XdmfDocument:
    """The published XDMF XML, held by rank 0, and its file: one temporal collection ``rod``
    whose frames each hold the mesh (Topology, Geometry), the Time and every array of that
    time, so that ParaView shows one dataset carrying all the arrays (DOLFINx writes one
    collection per function, which ParaView shows as separate blocks: "Warp By Vector" with
    ``displacement`` would then move only the displacement block). How a frame is added
    (:meth:`append`, :meth:`rewrite`): :class:`XdmfWriter`."""

    def __init__(
        self,
        path: Path,
        work: Path,
        mesh: str | None,
        run_id: str | None,
        frames: list[bytes] | None = None,
    ):
        """``mesh``: the Topology and Geometry of every frame; ``work``: the working name of a
        rewrite; ``frames``: those of a published file."""
        self.path, self.work = path, work
        self.mesh, self.run_id = mesh, run_id
        self.frames: list[bytes] = frames or []
        self._frame_bytes = sum(map(len, self.frames))
        self._fd: int | None = None  # the published file, open for the appends
        self._tail = self._end = 0  # where its closing tags and its "?>" begin

    @classmethod
    def parse(cls, path: Path, work: Path, xml: str) -> _XdmfDocument:
        """The document of a published file (of any earlier writer): its run's identity, its
        frames, and the mesh of the first (else of the grid "mesh", else none)."""
        root = ET.fromstring(xml)
        domain = root.find("Domain")
        if domain is None:
            raise ValueError("no Domain element")
        collection = domain.find(f"Grid[@Name='{XDMF_GRID}']")
        grids = [] if collection is None else collection.findall("Grid")
        mesh = grids[0] if grids else domain.find("Grid[@Name='mesh']")
        parts = [] if mesh is None else [mesh.find("Topology"), mesh.find("Geometry")]
        text = "".join(_element_text(e, 4) for e in parts if e is not None) or None
        frames = [_element_text(g, 3).encode() for g in grids]
        return cls(path, work, text, xdmf_run_id(root), frames)

    def frame(self, value: str, file: str, key: str, arrays: list[str], points: int) -> bytes:
        """The text of a frame (:func:`xdmf_frame_xml`) of the collection ``rod``."""
        if self.mesh is None:
            raise RuntimeError("XDMF: a frame without a mesh")
        return xdmf_frame_xml(XDMF_GRID, self.mesh, value, file, key, arrays, points).encode()

    def _head(self) -> bytes:
        return xdmf_head(XDMF_GRID, self.run_id).encode()

    def rewrite_size(self, frame: bytes | None) -> int:
        """The bytes of a rewrite with ``frame`` added, without spare room (at most)."""
        extra = 0 if frame is None else len(frame)
        head = len(self._head()) + self._frame_bytes + extra
        return head + _SWITCH + _SWITCH + len(_SPARE_CLOSE)

    def rewrite(self, frame: bytes | None, spare: int) -> None:
        """Publish the document, with ``frame`` added, and ``spare`` blanks of room after it:
        written under the working name, then renamed onto the published file (atomic)."""
        frames = self.frames if frame is None else [*self.frames, frame]
        text = self._head() + b"".join(frames)
        text += b" " * _pad(len(text))
        data = b"".join([text, _XDMF_TAIL, _SPARE_OPEN, b" " * spare, _SPARE_CLOSE])
        self.work.unlink(missing_ok=True)  # a new file (truncating one costs a discard)
        fd = safe_files.create(self.work)
        try:
            safe_files.write_all(fd, data, 0)
            os.replace(self.work, self.path)
        except BaseException:
            os.close(fd)
            self.work.unlink(missing_ok=True)
            raise
        self.close()
        self._fd, self._tail, self._end = fd, len(text), len(data) - len(_SPARE_CLOSE)
        if frame is not None:
            self.frames.append(frame)
            self._frame_bytes += len(frame)

    def _new_tail(self, frame: bytes) -> int:
        """Where the closing tags begin once ``frame`` is appended."""
        tail = self._tail + _SWITCH + 1 + len(frame)
        return tail + _pad(tail)

    def fits(self, frame: bytes) -> bool:
        """Whether ``frame`` can be appended in the spare room."""
        return self._fd is not None and self._new_tail(frame) + _SWITCH <= self._end

    def append(self, frame: bytes) -> None:
        """Add ``frame`` in place (it :meth:`fits`): (1) the frame, blanks, the closing tags
        and the opening of the spare's processing instruction written into the spare, which
        lies inside that instruction (the document is unchanged, whatever part of this is
        written); (2) the old closing tags and opening, in one page, made blanks."""
        if self._fd is None:
            raise RuntimeError("XDMF: an append to a file that is not open (see fits)")
        start = self._tail + _SWITCH
        tail = self._new_tail(frame)
        staged = b"".join(
            [b" ", frame, b" " * (tail - start - 1 - len(frame)), _XDMF_TAIL, _SPARE_OPEN]
        )
        safe_files.write_all(self._fd, staged, start)
        safe_files.write_all(self._fd, b" " * _SWITCH, self._tail)
        self._tail = tail
        self.frames.append(frame)
        self._frame_bytes += len(frame)

    def close(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)


# --- a restart ----------------------------------------------------------------------------------
ET.register_namespace("xi", "http://www.w3.org/2001/XInclude")


def xdmf_problem(path: Path, frames: int, run_id: str) -> str | None:
    """Why the XDMF file cannot be continued from ``frames`` frames of run ``run_id``."""
    root = ET.fromstring(safe_files.read_regular(path))
    if xdmf_run_id(root) != run_id:
        return f"{str(path)!r} was written by another run than the checkpoint's"
    domain = root.find("Domain")
    collection = None if domain is None else domain.find(f"Grid[@Name='{XDMF_GRID}']")
    steps = [] if collection is None else collection.findall("Grid")
    if len(steps) < frames:
        return f"{str(path)!r} holds {len(steps)} frames, fewer than the checkpoint's {frames}"
    for step in steps[:frames]:
        for item in step.iter("DataItem"):
            name = (item.text or "").strip().split(":", 1)[0]
            target = path.parent / name
            if not target.is_file():
                what = "is missing"
                if target.exists():
                    what = f"is {safe_files.kind(target.stat().st_mode)}, not a regular file"
                return f"{str(path)!r} refers to {name}, which {what}"
    return None


def cut_xdmf(path: Path, frames: int) -> None:
    """Keep the first ``frames`` time steps of every temporal collection of the XDMF file
    (written by rank 0 only; replaced atomically, a link replaced, not followed)."""
    root = ET.fromstring(safe_files.read_regular(path))
    tree = ET.ElementTree(root)
    for collection in root.iter("Grid"):
        if collection.get("GridType") != "Collection":
            continue
        for step in collection.findall("Grid")[frames:]:
            collection.remove(step)
    text = io.BytesIO()
    tree.write(text, encoding="utf-8", xml_declaration=True)
    safe_files.replace(path, text.getvalue())


# --- the reader ---------------------------------------------------------------------------------
class NoFramesError(SceneError):
    """An XDMF file that holds no frame (yet): a run killed before it wrote its first."""


@dataclass
class RodSeries:
    """The XDMF time series, points ordered along the rod.

    ``s`` [m] arc length of each point, ``reference`` (N, 3) the reference centreline
    (0, 0, s), ``times`` (T,) [s] (the load factor for a static run, the mode number for
    modes.xdmf), ``arrays`` name -> (T, N, 3) (see cosserat_fem/output/fields.py's XdmfWriter for
    names, units and bases). N >= 2, T >= 1, every value finite (see the module docstring)."""

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


def import_h5py():
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


class _Datasets:
    """Open .h5 files of one XDMF file, by the ``file.h5:/path`` references of its XML."""

    def __init__(self, xdmf: Path):
        self.xdmf = xdmf
        self.folder = xdmf.parent
        self.files: dict[str, Any] = {}  # h5py.File objects
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
            h5py = import_h5py()
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
                f"'<name>{FRAMES_SUFFIX}/<digits>.h5' or '<name>{FRAMES_SUFFIX}/{MESH_FILE}'",
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
        h5py = import_h5py()
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
