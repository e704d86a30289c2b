"""Damaged, truncated, foreign or hostile run outputs: ``plot`` and ``render`` refuse them cleanly.

Defect D12: ``cosserat-fem plot DIR`` on a folder whose probes.csv is binary ended in
``internal error: UnicodeDecodeError`` (exit 1). The contract (cosserat_fem/output/results.py,
module docstring): bad input gets one line that names the file and what is wrong, exit status 2,
never a traceback and never "internal error"; a run killed at any moment still plots what it
has (a cut last probe row, a scratch ``solution.xdmf-partial``, an XDMF file without frames).

How: a genuine small run (the paper's scene to t = 0.6 ms, 21 probe rows, 11 XDMF frames of 25
points) is made once per module; a helper (this file run as a script, with the venv's Python)
copies it once per case, damages the copy and reads it in-process with
``cosserat_fem.output.results.open_run`` / ``Run.series`` (and, for some, ``plot.plot_run`` at a low
resolution and ``render.magnification``), and writes a JSON report that the tests below judge.
One subprocess, because h5py (the reader's) and DOLFINx (which other test files import into
pytest's process) cannot share one (see cosserat_fem/output/results.py). The cases:

* generated from ``random.Random(SEED)``: truncations of each file at random offsets, random
  byte flips, random line deletions/duplications/swaps of the text files, every pair of files
  swapped;
* written by hand: binary/non-UTF-8/empty files, a header only, rows with wrong counts,
  non-numbers, NaN/inf, files that are folders, FIFOs, links to /dev/zero or to nothing, huge
  (sparse) files, XDMF that is not XML or lacks Domain/Grid/Time/Attribute/DataItem, bad Time
  values, DataItem text without ``file:/path``, references out of the folder, to a missing
  .h5 or dataset, truncated or random .h5 files, arrays of the wrong shape or kind, topology
  indices out of range, entity-expansion bombs, summary.json of wrong types;
* the states a killed run leaves (tests/test_kill.py), which must read and plot.

A read must give finite arrays of consistent shapes; a refusal must be a SceneError of one line
naming the damaged file; anything else fails. A few cases go through the command line as well
(exit 2, exactly one stderr line). Runtime: ~15 s (the run ~2 s, the helper ~8 s, six CLI
calls ~1 s each).
"""

from __future__ import annotations

import json
import os
import random
import re
import resource
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from conftest import HUNG_AFTER, PYTHON, ROOT, run_command, subprocess_env

SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
SETTINGS = ("time.end=0.0006", "output.xdmf_interval=6e-5")
SEED = 20240612
#: The files a case damages: the text files, frame 0's HDF5 file and the mesh's (one file a
#: frame in the frames folder, cosserat_fem/io/xdmf.py; the other frames are copied as they are).
FILES = (
    "probes.csv",
    "summary.json",
    "solution.xdmf",
    "solution.frames/000000.h5",
    "solution.frames/mesh.h5",
)
TEXT_FILES = FILES[:3]
FRAMES = "solution.frames"
BOMB_SECONDS = 1.0  # CPU s: an entity bomb must be refused this fast (measured ~1 ms)
# The helper's guards against a reader that runs away (the old one read the 10^9-point
# geometry: 24 GB, until the OOM killer stopped it; one that opened the FIFO would block for
# ever): a memory limit (address space; the helper peaks at ~0.3 GB of it) and a time limit
# per case, which make either a reported failure of that case.
HELPER_MEMORY = 3 << 30  # bytes
CASE_SECONDS = 20


# --- the cases (built and run in the helper subprocess) ------------------------------------


@dataclass
class Case:
    """One damaged copy of the genuine run: ``damage(folder)`` changes it; ``names``: the
    files a refusal must name (one of them); ``expect``: "read", "refuse" or None (either);
    ``plot``: also run plot_run; ``rows``: the probe rows a read must give, if known."""

    category: str
    name: str
    damage: object
    names: tuple[str, ...]
    expect: str | None = None
    plot: bool = False
    rows: int | None = None
    extra: dict = field(default_factory=dict)


def _edit(folder: Path, name: str, fn) -> None:
    path = folder / name
    path.write_bytes(fn(path.read_bytes()))


def _bytes(name: str, fn):
    """Damage: the bytes of ``name`` become ``fn(bytes)``."""
    return lambda folder: _edit(folder, name, fn)


def _sparse(name: str, size: int):
    """Damage: ``name`` becomes a sparse file of ``size`` bytes (zeros, no disk)."""

    def damage(folder: Path) -> None:
        with open(folder / name, "wb") as stream:
            stream.truncate(size)

    return damage


def _text(folder: Path, name: str, fn) -> None:
    path = folder / name
    path.write_text(fn(path.read_text(encoding="utf-8")), encoding="utf-8")


def _replace(name: str, old: str, new: str, count: int = 1):
    def damage(folder: Path) -> None:
        def fn(text: str) -> str:
            assert old in text, (name, old)
            return text.replace(old, new, count)

        _text(folder, name, fn)

    return damage


def _write(name: str, data: bytes | str):
    def damage(folder: Path) -> None:
        path = folder / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)
        if isinstance(data, str):
            path.write_text(data, encoding="utf-8")
        else:
            path.write_bytes(data)

    return damage


def _swap(a: str, b: str):
    """Damage: file ``a`` holds the bytes of file ``b``."""
    return lambda folder: (folder / a).write_bytes((folder / b).read_bytes())


def _replace_path(name: str, make):
    """Replace the file or folder ``name`` by what ``make(path)`` puts there (a folder, a FIFO,
    ..., nothing)."""

    def damage(folder: Path) -> None:
        path = folder / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
        make(path)

    return damage


def _h5(edit, name: str = FILES[3]):
    """Edit the HDF5 file ``name`` (default frame 0's) with h5py: ``edit(file)``."""

    def damage(folder: Path) -> None:
        import h5py

        with h5py.File(folder / name, "r+") as f:
            edit(f)

    return damage


def _every_frame(edit):
    """Edit every frame's HDF5 file with h5py: ``edit(file)``."""

    def damage(folder: Path) -> None:
        for path in sorted((folder / FRAMES).glob("[0-9]*.h5")):
            _h5(edit, str(path.relative_to(folder)))(folder)

    return damage


def _dataset(name: str, make):
    """Replace dataset ``name`` (of mesh.h5 for /Mesh/..., else of frame 0's file) by
    ``make(old values)`` (an array), or by what ``make(old values, file, name)`` creates when
    it takes three arguments."""

    def edit(f) -> None:
        import numpy as np

        old = np.asarray(f[name])
        del f[name]
        if make.__code__.co_argcount == 3:
            make(old, f, name)
        else:
            f[name] = make(old)

    return _h5(edit, FILES[4] if name.startswith("/Mesh/") else FILES[3])


def _both(*damages):
    def damage(folder: Path) -> None:
        for d in damages:
            d(folder)

    return damage


GEOMETRY = "/Mesh/mesh/geometry"
TOPOLOGY = "/Mesh/mesh/topology"
DISP0 = "/Function/displacement/0"
FIRST_TIME = '<Time Value="0" />'
DISP0_ITEM = "solution.frames/000000.h5:/Function/displacement/0"


def _billion_laughs() -> str:
    entities = '<!ENTITY lol0 "lollollollollollollollollollol">' + "".join(
        f'<!ENTITY lol{i} "' + f"&lol{i - 1};" * 10 + '">' for i in range(1, 10)
    )
    return (
        f'<?xml version="1.0"?>\n<!DOCTYPE Xdmf [{entities}]>\n'
        "<Xdmf><Domain>&lol9;</Domain></Xdmf>\n"
    )


def _quadratic_blowup() -> str:
    big = "x" * 200_000
    return (
        f'<?xml version="1.0"?>\n<!DOCTYPE Xdmf [<!ENTITY a "{big}">]>\n'
        "<Xdmf><Domain>" + "&a;" * 20_000 + "</Domain></Xdmf>\n"
    )


def _single_file(folder: Path) -> None:
    """solution.h5: every dataset of the frames folder's files in one file (the single-file
    layout of earlier versions; each frame's datasets are named by its time, so none clash)."""
    import h5py

    def copy(out, f) -> None:
        names: list[str] = []
        f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
        for name in names:
            out[name] = f[name][()]

    with h5py.File(folder / "solution.h5", "w") as out:
        for source in sorted((folder / FRAMES).glob("*.h5")):
            with h5py.File(source, "r") as f:
                copy(out, f)


def _single_file_layout(folder: Path) -> None:
    """The genuine run as XdmfWriter wrote it before one file a frame: the same XML naming
    solution.h5 only, which holds every dataset; the frames folder removed."""
    _single_file(folder)
    shutil.rmtree(folder / FRAMES)
    single = re.compile(r"solution\.frames/\w+\.h5:")
    _text(folder, "solution.xdmf", lambda t: single.sub("solution.h5:", t))


def _earlier_layout(folder: Path) -> None:
    """The genuine data in DOLFINx's own layout: a grid "mesh" with σ along the first axis (XY,
    as DOLFINx writes an interval mesh) and one temporal collection per array; summary.json's
    rod.length set to 2 m, so that s = σ ℓ spans 2 m."""
    import h5py
    import numpy as np

    summary = json.loads((folder / "summary.json").read_text())
    summary["scene"]["rod"]["length"] = 2.0
    (folder / "summary.json").write_text(json.dumps(summary))
    _single_file(folder)
    with h5py.File(folder / "solution.h5", "r+") as f:
        z = np.asarray(f[GEOMETRY])[:, 2]  # s on the genuine rod of 1 m: σ
        f["/Mesh/old/geometry"] = np.column_stack([z, np.zeros_like(z)])
        f["/Mesh/old/topology"] = np.asarray(f[TOPOLOGY])
        times = sorted(f["/Function/displacement"].keys())
    n, cells = len(z), len(z) - 1
    parts = [
        '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n',
        '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n<Domain>\n',
        '<Grid Name="mesh" GridType="Uniform">\n',
        f'<Topology TopologyType="PolyLine" NumberOfElements="{cells}" NodesPerElement="2">\n',
        f'<DataItem Dimensions="{cells} 2" NumberType="Int" Format="HDF">'
        "solution.h5:/Mesh/old/topology</DataItem>\n</Topology>\n",
        f'<Geometry GeometryType="XY"><DataItem Dimensions="{n} 2" Format="HDF">'
        "solution.h5:/Mesh/old/geometry</DataItem></Geometry>\n</Grid>\n",
    ]
    for array in ("displacement", "angles"):
        parts.append(f'<Grid Name="{array}" GridType="Collection" CollectionType="Temporal">\n')
        for key in times:
            parts.append(
                f'<Grid Name="{array}" GridType="Uniform">\n<xi:include xpointer="xpointer('
                "/Xdmf/Domain/Grid[@GridType='Uniform'][1]/*[self::Topology or "
                f'self::Geometry])" />\n<Time Value="{key.replace("_", ".")}" />\n'
                f'<Attribute Name="{array}" AttributeType="Vector" Center="Node">\n'
                f'<DataItem Dimensions="{n} 3" Format="HDF">solution.h5:/Function/{array}/'
                f"{key}</DataItem>\n</Attribute>\n</Grid>\n"
            )
        parts.append("</Grid>\n")
    parts.append("</Domain>\n</Xdmf>\n")
    (folder / "solution.xdmf").write_text("".join(parts), encoding="utf-8")


MESH_ONLY = (
    '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
    '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n  <Domain>\n'
    '    <Grid Name="rod" GridType="Collection" CollectionType="Temporal">\n'
    "    </Grid>\n  </Domain>\n</Xdmf>\n"
)  # what XdmfSeries publishes before its first frame (cosserat_fem/io/xdmf.py)


def hand_written(genuine: Path) -> list[Case]:
    """The cases of the module docstring's second and third items."""
    import numpy as np

    probes = (genuine / "probes.csv").read_text()
    lines = probes.splitlines(keepends=True)
    header, rows = lines[0], len(lines) - 1
    summary = json.loads((genuine / "summary.json").read_text())

    def summary_with(**changes) -> str:
        data = json.loads(json.dumps(summary))
        for key, value in changes.items():
            target = data
            *path, last = key.split("__")
            for part in path:
                target = target[part]
            target[last] = value
        return json.dumps(data)

    def row_with(value: str, column: int = 3) -> str:
        fields = lines[2].rstrip("\n").split(",")
        fields[column] = value
        return "".join([*lines[:2], ",".join(fields) + "\n", *lines[3:]])

    P, S, X, H, M = FILES
    cases = []

    def refuse(category, name, damage, names):
        cases.append(Case(category, name, damage, names, expect="refuse"))

    def read(category, name, damage, plot=False, rows_=None, names=FILES):
        cases.append(Case(category, name, damage, names, expect="read", plot=plot, rows=rows_))

    # probes.csv
    noise = random.Random(SEED).randbytes(2000)
    refuse("probes", "D12: binary probes.csv", _write(P, noise), (P,))
    latin = _bytes(P, lambda b: b.replace(b"e-", b"\xe9-", 1))
    refuse("probes", "a non-UTF-8 byte in a row", latin, (P,))
    refuse("probes", "NUL bytes", _write(P, b"\0" * 5000), (P,))
    refuse("probes", "UTF-8 byte order mark", _write(P, "\ufeff" + probes), (P,))
    refuse("probes", "wrong header", _write(P, "a,b,c\n1,2,3\n"), (P,))
    refuse("probes", "another CSV's header", _write(P, "t,x,y,z\n0,0,0,0\n"), (P,))
    refuse("probes", "a row of 6 values", _write(P, row_with("1", 3).replace(",1,", ",", 1)), (P,))
    refuse("probes", "a row of 8 values", _write(P, row_with("1,2")), (P,))
    refuse("probes", "a non-number", _write(P, row_with("abc")), (P,))
    refuse("probes", "an empty value", _write(P, row_with("")), (P,))
    refuse("probes", "a NaN", _write(P, row_with("nan")), (P,))
    refuse("probes", "an inf", _write(P, row_with("-inf")), (P,))
    refuse("probes", "a value beyond the float range", _write(P, row_with("1e400")), (P,))
    refuse("probes", "1e308 (matplotlib overflows)", _write(P, row_with("1.7e308")), (P,))
    refuse("probes", "a line of 10 kB", _write(P, header + "0," * 5000 + "\n"), (P,))
    refuse(
        "probes",
        "a row cut in the middle of the file",
        _write(P, "".join(lines[:5]) + lines[5][:40] + "\n" + "".join(lines[6:])),
        (P,),
    )
    refuse("probes", "probes.csv a folder", _replace_path(P, lambda p: p.mkdir()), (P,))
    refuse("probes", "probes.csv a FIFO", _replace_path(P, os.mkfifo), (P,))
    refuse(
        "probes",
        "probes.csv a link to /dev/zero",
        _replace_path(P, lambda p: p.symlink_to("/dev/zero")),
        (P,),
    )
    refuse(
        "probes",
        "probes.csv a link to nothing",
        _replace_path(P, lambda p: p.symlink_to(p.with_name("missing"))),
        (P,),
    )
    refuse(
        "probes", "probes.csv a link to itself", _replace_path(P, lambda p: p.symlink_to(p)), (P,)
    )
    refuse("probes", "a huge (sparse) probes.csv", _sparse(P, (1 << 30) + 1), (P,))
    read("probes", "a header only", _write(P, header), rows_=0)
    read("probes", "an empty probes.csv", _write(P, b""), rows_=0)
    read("probes", "CRLF line ends", _write(P, probes.replace("\n", "\r\n")), rows_=rows)
    read("probes", "a blank line", _write(P, "".join([*lines[:5], "\n", *lines[5:]])), rows_=rows)
    read("probes", "values just within 1e100", _write(P, row_with("-1e99")), True, rows)
    # output.probe_fields: known extra columns, in their order, with as many values a row
    q = ",q0,q1,q2,q3"
    with_q = [header.rstrip("\n") + q + "\n"] + [x.rstrip("\n") + ",1,0,0,0\n" for x in lines[1:]]
    read("probes", "the quaternion's columns", _write(P, "".join(with_q)), True, rows)
    refuse("probes", "the quaternion's header, rows of 7", _write(P, with_q[0] + lines[1]), (P,))
    d = "".join(f",d{j}_{c}" for j in (1, 2, 3) for c in "xyz")
    swapped = header.rstrip("\n") + d + q + "\n" + lines[1].rstrip("\n") + ",0" * 13 + "\n"
    refuse("probes", "the directors before the quaternion", _write(P, swapped), (P,))

    # summary.json
    refuse("summary", "binary summary.json", _write(S, noise), (S,))
    refuse("summary", "an empty summary.json", _write(S, b""), (S,))
    refuse("summary", "not JSON", _write(S, "status: completed\n"), (S,))
    refuse("summary", "a JSON array", _write(S, "[1, 2]"), (S,))
    refuse("summary", "a JSON string", _write(S, '"summary"'), (S,))
    refuse("summary", "null", _write(S, "null"), (S,))
    refuse("summary", "nested 100 000 deep", _write(S, "[" * 100_000 + "]" * 100_000), (S,))
    refuse("summary", "a 5000-digit number", _write(S, '{"a": ' + "9" * 5000 + "}"), (S,))
    refuse("summary", "kind a number", _write(S, summary_with(kind=3)), (S,))
    refuse("summary", "scene a list", _write(S, summary_with(scene=[1])), (S,))
    refuse("summary", "title a number", _write(S, summary_with(scene__title=5)), (S,))
    refuse("summary", "title an object", _write(S, summary_with(scene__title={"a": 1})), (S,))
    refuse("summary", "rod a string", _write(S, summary_with(scene__rod="steel")), (S,))
    refuse("summary", "length a string", _write(S, summary_with(scene__rod__length="1")), (S,))
    refuse("summary", "length true", _write(S, summary_with(scene__rod__length=True)), (S,))
    refuse("summary", "length negative", _write(S, summary_with(scene__rod__length=-1.0)), (S,))
    refuse("summary", "length NaN", _write(S, summary_with(scene__rod__length=float("nan"))), (S,))
    refuse(
        "summary",
        "length 1e400 (inf)",
        _write(S, summary_with(scene__rod__length=1.0).replace('"length": 1.0', '"length": 1e400')),
        (S,),
    )
    refuse("summary", "length 10**300", _write(S, summary_with(scene__rod__length=10**300)), (S,))
    refuse("summary", "summary.json a folder", _replace_path(S, lambda p: p.mkdir()), (S,))
    mathtext = _write(S, summary_with(scene__title=r"$\frac{1}{$ $x^$"))
    read("summary", "a mathtext title", mathtext, plot=True)
    long_title = _write(S, summary_with(scene__title="A" * 10**5))
    read("summary", "a 100 000-character title", long_title, plot=True)
    read(
        "summary",
        "control characters in the title",
        _write(S, summary_with(scene__title="a\x1b[31mred\nline\x00end")),
        plot=True,
    )
    read("summary", "no summary.json", lambda f: (f / S).unlink())
    read("summary", "an empty object", _write(S, "{}"))
    read("summary", "a static run's summary", _write(S, summary_with(kind="static")))

    # solution.xdmf: the XML
    refuse("xdmf", "binary solution.xdmf", _write(X, noise), (X,))
    refuse("xdmf", "an empty solution.xdmf", _write(X, b""), (X,))
    refuse("xdmf", "plain text", _write(X, "hello\n"), (X,))
    refuse("xdmf", "another XML file", _write(X, "<svg><rect/></svg>"), (X,))
    refuse("xdmf", "no Domain", _write(X, "<Xdmf Version='3.0'/>"), (X,))
    refuse("xdmf", "a Grid without Time", _replace(X, FIRST_TIME, ""), (X,))
    refuse("xdmf", "a Time without Value", _replace(X, FIRST_TIME, "<Time />"), (X,))
    refuse("xdmf", "a Time Value not a number", _replace(X, 'Value="0"', 'Value="abc"'), (X,))
    refuse("xdmf", "a Time Value NaN", _replace(X, 'Value="0"', 'Value="nan"'), (X,))
    refuse("xdmf", "an Attribute without a Name", _replace(X, 'Name="displacement" ', ""), (X,))
    refuse(
        "xdmf",
        "an Attribute without DataItem",
        _replace(
            X, f'<DataItem Dimensions="25 3" Format="HDF" Precision="8">{DISP0_ITEM}</DataItem>', ""
        ),
        (X,),
    )
    refuse("xdmf", "DataItem text without file:/path", _replace(X, DISP0_ITEM, "garbage"), (X,))
    refuse("xdmf", "an empty DataItem", _replace(X, DISP0_ITEM, ""), (X,))
    refuse(
        "xdmf",
        "inline XML data",
        _replace(X, 'Format="HDF" Precision="8">' + DISP0_ITEM, 'Format="XML">1 2 3'),
        (X,),
    )
    refuse(
        "xdmf", "Dimensions not integers", _replace(X, 'Dimensions="24 2"', 'Dimensions="a"'), (X,)
    )
    refuse("xdmf", "a missing .h5", _replace(X, f"{M}:", "missing.h5:", 1), (X,))
    refuse("xdmf", "a missing frame file", _replace(X, f"{H}:", f"{FRAMES}/000099.h5:"), (X,))
    refuse("xdmf", "a dataset not in the .h5", _replace(X, DISP0_ITEM, f"{H}:/nothing"), (X,))
    refuse("xdmf", "a group, not a dataset", _replace(X, DISP0_ITEM, f"{H}:/Function"), (X,))
    refuse(
        "xdmf",
        "a reference out of the folder",
        _replace(X, f"{M}:", "../../../../etc/passwd:", 1),
        (X,),
    )
    refuse("xdmf", "an absolute reference", _replace(X, f"{M}:", "/dev/zero:", 1), (X,))
    refuse("xdmf", "summary.json as the .h5", _replace(X, f"{M}:", "summary.json:"), (X, S))
    refuse("xdmf", "the run folder as the .h5", _replace(X, f"{M}:", ".:"), (X,))
    # A file of the frames folder: exactly <name>.frames/<digits or mesh>.h5, one level.
    for bad in (
        f"{FRAMES}/../../../../etc/passwd",
        f"{FRAMES}/../summary.json",
        f"/{FRAMES}/000000.h5",
        f"{FRAMES}/sub/000000.h5",
        f"{FRAMES}//000000.h5",
        f"./{FRAMES}/000000.h5",
        f"{FRAMES}/000000.h5/..",
        "solution.frame/000000.h5",
        f"{FRAMES}/x.h5",
        f"{FRAMES}/.h5",
        f"{FRAMES}\\000000.h5",
        f"{FRAMES}/",
    ):
        refuse("xdmf", f"a reference {bad!r}", _replace(X, f"{H}:", f"{bad}:"), (X,))
    refuse("xdmf", "the frames folder as the .h5", _replace(X, f"{H}:", f"{FRAMES}:"), (X, FRAMES))
    refuse(
        "xdmf",
        "GeometryType X_Y_Z",
        _replace(X, 'GeometryType="XYZ"', 'GeometryType="X_Y_Z"'),
        (X,),
    )
    refuse(
        "xdmf",
        "no Topology",
        _both(
            _replace(X, "<Topology ", "<Topologie ", 1),
            _replace(X, "</Topology>", "</Topologie>", 1),
        ),
        (X,),
    )
    no_geometry = _both(
        _replace(X, "<Geometry ", "<Geometrie ", 11), _replace(X, "</Geometry>", "</Geometrie>", 11)
    )
    refuse("xdmf", "no Geometry", no_geometry, (X,))
    mesh_grid = _replace(X, "<Domain>", '<Domain><Grid Name="mesh" GridType="Uniform"/>')
    refuse("xdmf", "a grid 'mesh' without Geometry", _both(no_geometry, mesh_grid), (X,))
    refuse("xdmf", "billion laughs", _write(X, _billion_laughs()), (X,))
    refuse("xdmf", "quadratic blowup", _write(X, _quadratic_blowup()), (X,))
    refuse(
        "xdmf",
        "an external entity",
        _write(
            X,
            '<?xml version="1.0"?><!DOCTYPE Xdmf [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
            "<Xdmf><Domain>&e;</Domain></Xdmf>",
        ),
        (X,),
    )
    refuse(
        "xdmf",
        "a parameter entity",
        _write(X, '<?xml version="1.0"?><!DOCTYPE Xdmf [<!ENTITY % p "x">]><Xdmf/>'),
        (X,),
    )
    refuse(
        "xdmf",
        "an unknown encoding",
        _write(X, '<?xml version="1.0" encoding="no-such-code"?><Xdmf/>'),
        (X,),
    )
    refuse("xdmf", "nested 100 000 deep", _write(X, "<a>" * 100_000 + "</a>" * 100_000), (X,))
    refuse("xdmf", "a huge (sparse) solution.xdmf", _sparse(X, (1 << 30) + 1), (X,))
    refuse("xdmf", "solution.xdmf a folder", _replace_path(X, lambda p: p.mkdir()), (X,))

    # the HDF5 files (frame 0's, the mesh's) and the arrays
    refuse("h5", "random bytes", _write(H, noise * 20), (H,))
    refuse("h5", "an empty .h5", _write(H, b""), (H,))
    refuse("h5", "the .h5 a folder", _replace_path(H, lambda p: p.mkdir()), (H, X))
    refuse("h5", "random bytes as mesh.h5", _write(M, noise * 20), (M,))
    refuse("h5", "a frame file missing", _replace_path(H, lambda p: None), (H, X))
    refuse("h5", "the frames folder missing", _replace_path(FRAMES, lambda p: None), (H, M, X))
    refuse(
        "h5",
        "the frames folder a file",
        _replace_path(FRAMES, lambda p: p.write_bytes(noise)),
        (H, M, X),
    )
    refuse(
        "h5",
        "the .h5 a link to /dev/zero",
        _replace_path(H, lambda p: p.symlink_to("/dev/zero")),
        (H, X),
    )
    refuse("h5", "geometry with 2 columns", _dataset(GEOMETRY, lambda a: a[:, :2]), (H, X))
    refuse(
        "h5",
        "geometry with 2 columns, XML agreeing",
        _both(
            _dataset(GEOMETRY, lambda a: a[:, :2]),
            _replace(
                X,
                'Dimensions="25 3" Format="HDF" Precision="8">solution.frames/mesh.h5:/Mesh',
                'Dimensions="25 2" Format="HDF" Precision="8">solution.frames/mesh.h5:/Mesh',
                11,
            ),
        ),
        (H, X),
    )
    refuse("h5", "a displacement of 24 points", _dataset(DISP0, lambda a: a[:24]), (H, X))
    refuse(
        "h5",
        "a displacement of 24 points, XML agreeing",
        _both(
            _dataset(DISP0, lambda a: a[:24]),
            _replace(
                X,
                f'"25 3" Format="HDF" Precision="8">{DISP0_ITEM}',
                f'"24 3" Format="HDF" Precision="8">{DISP0_ITEM}',
            ),
        ),
        (H, X),
    )
    refuse("h5", "a scalar displacement", _dataset(DISP0, lambda a: a[:, 0]), (H, X))
    refuse("h5", "topology index out of range", _dataset(TOPOLOGY, lambda a: a + 1), (H, X))
    refuse("h5", "a negative topology index", _dataset(TOPOLOGY, lambda a: a - 1), (H, X))
    refuse("h5", "a fractional topology index", _dataset(TOPOLOGY, lambda a: a + 0.5), (H, X))
    refuse("h5", "a NaN in the displacement", _dataset(DISP0, lambda a: a * np.nan), (H, X))
    refuse("h5", "an inf in the geometry", _dataset(GEOMETRY, lambda a: a + np.inf), (H, X))
    refuse(
        "h5", "strings, not numbers", _dataset(DISP0, lambda a: np.full(a.shape, b"abc")), (H, X)
    )
    refuse(
        "h5", "a group, not a dataset", _dataset(DISP0, lambda a, f, n: f.create_group(n)), (H, X)
    )
    refuse(
        "h5",
        "an empty dataset",
        _dataset(DISP0, lambda a, f, n: f.create_dataset(n, data=__import__("h5py").Empty("f8"))),
        (H, X),
    )
    refuse("h5", "a mesh of no length", _dataset(GEOMETRY, lambda a: a * 0.0), (H, X))
    refuse(
        "h5",
        "a 10^9-point geometry (unallocated)",
        _both(
            _dataset(
                GEOMETRY, lambda a, f, n: f.create_dataset(n, (10**9, 3), "f8", chunks=(1000, 3))
            ),
            _replace(
                X,
                f'Dimensions="25 3" Format="HDF" Precision="8">{M}:/Mesh',
                f'Dimensions="1000000000 3" Format="HDF" Precision="8">{M}:/Mesh',
                11,
            ),
        ),
        (H, X),
    )
    read(
        "h5",
        "subnormal displacements",
        _every_frame(
            lambda f: [
                f[f"/Function/displacement/{k}"].write_direct(np.full((25, 3), 5e-324))
                for k in f["/Function/displacement"]
            ]
        ),
        plot=True,
    )
    huge = _dataset(DISP0, lambda a: np.full(a.shape, 1e99))
    read("h5", "displacements of 1e99 m", huge, plot=True)
    read("h5", "the earlier layout (DOLFINx's)", _earlier_layout, plot=True)

    # The readers' size limits as docs/reliability.md states them (1 GiB of probes.csv, 128 MiB
    # of XDMF, 16 MiB of summary.json, lines of 4096 bytes, 1e8 values from the .h5 files):
    # one byte (or value) over is refused for its size; at the limit the file is read, and
    # refused for what it holds (zeros) or read (a long line of digits).
    for name, limit in ((P, 1 << 30), (X, 128 << 20), (S, 16 << 20)):
        refuse("limits", f"{name}: {limit} bytes", _sparse(name, limit), (name,))
        refuse("limits", f"{name}: {limit + 1} bytes", _sparse(name, limit + 1), (name,))
    padded = "1.0e-3".rjust(4096 - len(lines[2]) + len(lines[2].split(",")[3]), "0")
    read("limits", "a probes.csv line of 4096 bytes", _write(P, row_with(padded)), rows_=rows)
    refuse("limits", "a probes.csv line of 4097 bytes", _write(P, row_with("0" + padded)), (P,))
    over = 10**8 // 3 + 1  # points: 3 (10^8 // 3 + 1) = 10^8 + 2 values, one dataset
    refuse(
        "limits",
        f"a geometry of {3 * over} values (unallocated)",
        _both(
            _dataset(
                GEOMETRY, lambda a, f, n: f.create_dataset(n, (over, 3), "f8", chunks=(1000, 3))
            ),
            _replace(
                X,
                f'Dimensions="25 3" Format="HDF" Precision="8">{M}:/Mesh',
                f'Dimensions="{over} 3" Format="HDF" Precision="8">{M}:/Mesh',
                11,
            ),
        ),
        (M, X),
    )
    read("h5", "the single-file layout (before one file a frame)", _single_file_layout, plot=True)

    # every point displaced onto the fixed end: numbers a run never writes, but plausible
    # ones; plot draws them, render refuses them (test_render_refuses_a_damaged_folder)
    def collapse(folder: Path) -> None:
        import h5py

        with h5py.File(folder / M, "r") as mesh, h5py.File(folder / H, "r+") as frame:
            frame[DISP0].write_direct(-np.asarray(mesh[GEOMETRY]))

    read("h5", "the rod collapsed to a point", collapse, plot=True)

    # what a killed run leaves (tests/test_kill.py): all of it must read and plot
    last = lines[-1]
    for cut in (1, 2, len(last) // 2, len(last) - 1):
        read(
            "kill",
            f"last probe row cut after {cut} characters",
            _write(P, probes[: len(probes) - len(last) + cut]),
            plot=cut == 1,
            rows_=rows - 1,
        )
    read(
        "kill",
        "last row cut inside an exponent",
        _write(P, probes[: probes.rindex("e-") + 3]),
        rows_=rows - 1,
    )
    read("kill", "a cut header", _write(P, header[:3]), rows_=0)
    read("kill", "a scratch solution.xdmf-partial", _write(X + "-partial", noise), plot=True)
    read("kill", "a scratch summary.json.tmp", _write(S + ".tmp", noise))
    read(
        "kill",
        "the frames a step behind the probes",
        _write(P, probes + lines[-1].replace(lines[-1].split(",")[0], "6.3e-04")),
        rows_=rows + 1,
    )
    read("kill", "blocks after the .h5's end", _bytes(H, lambda b: b + noise))
    cases.append(
        Case(
            "kill",
            "an XDMF file without frames yet, one probe row",
            _both(_write(X, MESH_ONLY), _write(P, header + lines[1])),
            FILES,
            expect="no frames",
            plot=True,
            rows=1,
        )
    )
    cases.append(
        Case(
            "kill",
            "no frames and no probe rows yet",
            _both(_write(X, MESH_ONLY), _write(P, header)),
            (P, X),
            expect="no frames",
            plot=True,
            rows=0,
            extra={"plot": "refused"},
        )
    )
    return cases


def generated(genuine: Path, rng: random.Random) -> list[Case]:
    """Truncations, byte flips, line edits and swaps, with parameters drawn from ``rng``."""
    cases = []
    sizes = {name: (genuine / name).stat().st_size for name in FILES}
    probes = (genuine / "probes.csv").read_bytes()
    for name in FILES:
        size = sizes[name]
        offsets = sorted({0, size - 2, *(rng.randrange(size - 1) for _ in range(10))})
        for offset in offsets:
            expect, rows = None, None
            if name == "probes.csv":  # a kill's cut: always read, whole rows only
                expect, rows = "read", max(0, probes[:offset].count(b"\n") - 1)
            elif name == "solution.xdmf":  # the closing tag cut: never XML
                expect = "refuse"
            cases.append(
                Case(
                    "truncate",
                    f"{name} cut at {offset} of {size}",
                    lambda f, n=name, o=offset: _edit(f, n, lambda b: b[:o]),
                    (name,),
                    expect=expect,
                    rows=rows,
                )
            )
        for _ in range(12):
            flips = [(rng.randrange(size), rng.randrange(1, 256)) for _ in range(rng.randint(1, 6))]

            def flip(data: bytes, flips=flips) -> bytes:
                out = bytearray(data)
                for at, mask in flips:
                    out[at] ^= mask
                return bytes(out)

            cases.append(
                Case(
                    "flip",
                    f"{name}: bytes {[(a, hex(m)) for a, m in flips]} flipped",
                    lambda f, n=name, fn=flip: _edit(f, n, fn),
                    (name,),
                )
            )
    for name in TEXT_FILES:
        count = len((genuine / name).read_text().splitlines())
        for _ in range(16):
            op = rng.choice(("delete", "duplicate", "swap"))
            i, j = rng.randrange(count), rng.randrange(count)

            def edit(text: str, op=op, i=i, j=j) -> str:
                lines = text.splitlines(keepends=True)
                if op == "delete":
                    del lines[i]
                elif op == "duplicate":
                    lines.insert(i, lines[i])
                else:
                    lines[i], lines[j] = lines[j], lines[i]
                return "".join(lines)

            what = f"{op} line {i + 1}" + (f" and {j + 1}" if op == "swap" else "")
            cases.append(
                Case(
                    "lines",
                    f"{name}: {what} of {count}",
                    lambda f, n=name, fn=edit: _text(f, n, fn),
                    (name,),
                )
            )
    for a in FILES:
        for b in FILES:
            if a != b:
                cases.append(Case("swap", f"{a} holds {b}", _swap(a, b), (a, b)))
    return cases


# --- the helper: run every case in one process (h5py, no DOLFINx) --------------------------


def _consistency(run, series) -> list[str]:
    """What is wrong with a successful read: non-finite values, inconsistent shapes."""
    import numpy as np

    problems = []
    if run.probes is not None:
        p = run.probes
        if not (isinstance(p, np.ndarray) and p.ndim == 2 and p.shape[1] == len(run.probe_columns)):
            problems.append(f"probes of shape {getattr(p, 'shape', None)}")
        elif not np.isfinite(p).all():
            problems.append("non-finite probes")
    if not isinstance(run.title, str) or not isinstance(run.time_label, str):
        problems.append("title or time label not a string")
    length = run.length
    if length is not None and not (isinstance(length, float) and 0 < length < float("inf")):
        problems.append(f"length {length!r}")
    if series is not None:
        s, T = series.s, len(series.times)
        n = len(s)
        if s.shape != (n,) or n < 2 or not np.isfinite(s).all() or (np.diff(s) < 0).any():
            problems.append(f"s {s!r}")
        if series.reference.shape != (n, 3) or not np.isfinite(series.reference).all():
            problems.append("reference")
        times = series.times
        if T < 1 or not np.isfinite(times).all() or (np.diff(times) <= 0).any():
            problems.append(f"times {times!r}")
        for name, a in series.arrays.items():
            if a.shape != (T, n, 3) or not np.isfinite(a).all():
                problems.append(f"array {name} of shape {a.shape}")
        if not series.length > 0:
            problems.append(f"length {series.length}")
    return problems


class CaseTimeout(Exception):
    """A case ran longer than CASE_SECONDS (raised by SIGALRM, which interrupts even a
    blocking open() of a FIFO)."""


def _alarm(signum, frame):
    raise CaseTimeout(f"more than {CASE_SECONDS} s")


def _attempt(fn):
    """("ok", value) / ("refused", message) for a SceneError / ("crash", type: message)."""
    from cosserat_fem.common.errors import SceneError

    signal.alarm(CASE_SECONDS)
    try:
        return "ok", fn()
    except SceneError as exc:
        return "refused", str(exc)
    except Exception as exc:  # what the contract forbids (MemoryError included): reported
        return "crash", f"{type(exc).__name__}: {exc}"[:500]
    finally:
        signal.alarm(0)


def run_case(case: Case, folder: Path, out: Path) -> dict:
    """Read (and maybe plot) the damaged copy ``folder``."""
    from cosserat_fem import plot, render
    from cosserat_fem.output.results import open_run

    result = {
        "category": case.category,
        "name": case.name,
        "names": case.names,
        "expect": case.expect,
        "rows": case.rows,
        **case.extra,
    }
    start = time.process_time()  # CPU s: the machine's load does not count
    status, value = _attempt(lambda: open_run(folder, "plot"))
    series_status = None
    if status == "ok":
        run, series = value, None
        result["probe_rows"] = None if run.probes is None else int(len(run.probes))
        if run.xdmf is not None:
            series_status, series = _attempt(run.series)
            if series_status != "ok":
                status, value, series = series_status, series, None
        if status == "ok":
            problems = _consistency(run, series)
            if series is not None and "displacement" in series.arrays:
                k_status, k = _attempt(lambda: render.magnification(series))
                if k_status != "ok" or not (1.0 <= k < float("inf")):
                    problems.append(f"magnification: {k_status} {k}")
            result["problems"] = problems
            if series is not None:
                result["shape"] = [len(series.times), len(series.s)]
                result["length"] = series.length
            value = None
    result["read"] = status
    result["message"] = value if isinstance(value, str) else None
    result["series"] = series_status
    result["seconds"] = time.process_time() - start
    if case.plot:
        shutil.rmtree(out, ignore_errors=True)
        plot_status, paths = _attempt(lambda: plot.plot_run(folder, out))
        result["plot_result"] = plot_status
        result["plot_message"] = paths if isinstance(paths, str) else None
        result["plot_files"] = sorted(p.name for p in paths) if plot_status == "ok" else None
    return result


KEEP = {  # cases whose folders the command-line tests use
    "D12: binary probes.csv": "d12",
    "title a number": "title",
    "a negative topology index": "topology",
    "a displacement of 24 points": "points",
    "a Time Value not a number": "time",
    "the rod collapsed to a point": "collapse",
    "an XDMF file without frames yet, one probe row": "mesh_only",
}


def helper_main(genuine: Path, work: Path, report: Path) -> None:
    """Build every case, run it, write the report (a JSON list, one entry per case)."""
    from cosserat_fem import plot

    resource.setrlimit(resource.RLIMIT_AS, (HELPER_MEMORY, HELPER_MEMORY))
    signal.signal(signal.SIGALRM, _alarm)
    plot.DPI = 20  # the figures are drawn all the same, at a twentieth of the pixels
    rng = random.Random(SEED)
    cases = hand_written(genuine) + generated(genuine, rng)
    results = []
    plotted = 0
    for i, case in enumerate(cases):
        folder = work / f"case{i}"
        folder.mkdir(parents=True)
        for name in TEXT_FILES:
            shutil.copyfile(genuine / name, folder / name)
        shutil.copytree(genuine / FRAMES, folder / FRAMES)
        try:
            case.damage(folder)
        except Exception as exc:  # the test's own mistake: say so
            results.append(
                {
                    "category": case.category,
                    "name": case.name,
                    "read": "setup",
                    "message": f"{type(exc).__name__}: {exc}",
                }
            )
            continue
        if case.expect is None and plotted < 6 and case.category != "swap":
            case.plot = True  # a few generated ones through plot_run too
        result = run_case(case, folder, work / "plots")
        plotted += case.plot and case.expect is None and result["read"] == "ok"
        results.append(result)
        if case.name in KEEP:
            folder.rename(work / KEEP[case.name])
        else:
            shutil.rmtree(folder)
    report.write_text(json.dumps(results, indent=1))


# --- the tests ------------------------------------------------------------------------------


def cli(*args: str) -> subprocess.CompletedProcess:
    return run_command(["-m", "cosserat_fem.cli", *args])


@pytest.fixture(scope="module")
def genuine(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fuzz") / "run"
    proc = cli("run", SCENE, "--out", str(out), "--quiet", *(f"--set={s}" for s in SETTINGS))
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def report(genuine, tmp_path_factory) -> tuple[list[dict], Path]:
    work = tmp_path_factory.mktemp("cases")
    path = work / "report.json"
    env = subprocess_env()
    env.setdefault("MPLBACKEND", "Agg")
    proc = subprocess.run(
        [PYTHON, __file__, str(genuine), str(work), str(path)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=HUNG_AFTER,  # the cases took 25 s at load 5 on two cores
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return json.loads(path.read_text()), work


def _failures(results: list[dict]) -> list[str]:
    """Every way a case broke the contract, one line each."""
    bad = []
    for r in results:
        tag = f"[{r['category']}] {r['name']}"
        if r["read"] == "setup":
            bad.append(f"{tag}: the case could not be made: {r['message']}")
            continue
        if r["read"] == "crash":
            bad.append(f"{tag}: {r['message']}")
        elif r["read"] == "refused":
            message = r["message"]
            if "\n" in message or "\r" in message:
                bad.append(f"{tag}: a message of several lines: {message!r}")
            if not any(name in message for name in r["names"]):
                bad.append(f"{tag}: the message names none of {r['names']}: {message}")
            if "internal error" in message or "Traceback" in message:
                bad.append(f"{tag}: {message}")
        elif r["problems"]:
            bad.append(f"{tag}: read, but {r['problems']}")
        expect = r["expect"]
        if expect == "read" and r["read"] != "ok":
            bad.append(f"{tag}: must read, got {r['read']}: {r['message']}")
        if expect == "refuse" and r["read"] != "refused":
            bad.append(f"{tag}: must be refused, got {r['read']}")
        if expect == "no frames" and (
            r["read"] != "refused" or "no time steps" not in (r["message"] or "")
        ):
            bad.append(f"{tag}: must read as no frames, got {r['read']}: {r['message']}")
        if r["rows"] is not None and r["read"] == "ok" and r["probe_rows"] != r["rows"]:
            bad.append(f"{tag}: {r['probe_rows']} probe rows, expected {r['rows']}")
        if "plot_result" in r:
            wanted = r.get("plot", "ok" if r["read"] == "ok" or expect == "no frames" else None)
            got = r["plot_result"]
            if got == "crash" or (wanted is not None and got != wanted):
                bad.append(f"{tag}: plot_run {got}: {r['plot_message']}")
            if got == "refused" and not any(n in r["plot_message"] for n in r["names"]):
                bad.append(f"{tag}: plot_run's message names none of {r['names']}")
    return bad


CATEGORIES = {
    "probes": "probes.csv: binary (D12), non-UTF-8, NUL, wrong header or counts, non-numbers, "
    "NaN/inf, huge values, a folder, FIFO, links, a huge file; a header only, CRLF",
    "summary": "summary.json: not JSON, not an object, nested too deep, fields of wrong types",
    "xdmf": "solution.xdmf: not XML, foreign XML, missing elements, bad Time values and "
    "DataItems, references out of the folder or to missing files/datasets, entity bombs",
    "h5": "the frames folder's HDF5 files: random/empty, missing, wrong shapes and kinds, bad "
    "topology, NaN/inf, a 10^9-point geometry; readable odd values; the earlier layouts",
    "kill": "a killed run's leftovers: cut rows and headers, scratch files, no frames yet",
    "truncate": "every file truncated at random offsets (probes.csv must always read)",
    "flip": "random byte flips in every file",
    "lines": "random line deletions, duplications and swaps in the text files",
    "swap": "every file replaced by another of the run",
    "limits": "files at and one byte over the readers' size limits, a line at and over its "
    "limit, a dataset over the values read",
}


@pytest.mark.long
@pytest.mark.parametrize("category", list(CATEGORIES))
def test_damaged_outputs_are_read_or_refused_cleanly(report, category):
    """Each case of ``category`` (see CATEGORIES) either reads, with finite arrays of
    consistent shapes (and, where it was plotted, plot_run draws it), or is refused with a
    one-line SceneError naming the damaged file; the hand-written cases must give the outcome
    they name (refused, or read with the right number of probe rows: a killed run plots what
    it has). Any other exception is what D12 was (UnicodeDecodeError, ValueError,
    AttributeError, IndexError, ... reached the user as "internal error")."""
    results, _ = report
    mine = [r for r in results if r["category"] == category]
    assert mine, category
    bad = _failures(mine)
    assert not bad, f"{len(bad)} of {len(mine)} cases:\n" + "\n".join(bad)


@pytest.mark.long
def test_the_earlier_layout_is_read(report):
    """An XDMF file of DOLFINx's own layout (grid "mesh" with σ along the first axis, XY, one
    collection per array), made from the genuine data, reads as the same series: 11 frames,
    25 points, s = σ ℓ spanning ℓ = 2 m (summary.json's rod.length, set so). The reader's
    checks (GeometryType columns, Dimensions) must not refuse the layout it was written for."""
    results, _ = report
    (r,) = [r for r in results if r["name"] == "the earlier layout (DOLFINx's)"]
    assert r["read"] == "ok" and r["shape"] == [11, 25], r
    assert abs(r["length"] - 2.0) < 1e-12, r


@pytest.mark.long
def test_the_single_file_layout_is_read(report):
    """Outputs of the single-file layout (every frame in solution.h5, named by the XML as
    ``solution.h5:/...``), made from the genuine data, still read: 11 frames of 25 points."""
    results, _ = report
    (r,) = [r for r in results if r["name"] == "the single-file layout (before one file a frame)"]
    assert r["read"] == "ok" and r["shape"] == [11, 25] and not r["problems"], r
    assert abs(r["length"] - 1.0) < 1e-12, r


@pytest.mark.long
def test_entity_bombs_are_refused_quickly(report):
    """Entity-expansion bombs (billion laughs, quadratic blowup) are refused because the file
    declares entities, before expat expands anything (expat >= 2.4 has its own limit, older
    ones expand gigabytes), within BOMB_SECONDS."""
    results, _ = report
    bombs = {r["name"]: r for r in results if r["name"] in ("billion laughs", "quadratic blowup")}
    assert len(bombs) == 2
    for r in bombs.values():
        assert r["read"] == "refused" and "declares the XML entity" in r["message"], r
        assert r["seconds"] < BOMB_SECONDS, r


@pytest.mark.long
def test_the_readers_size_limits_are_where_the_docs_say(report):
    """docs/reliability.md: plot and render read at most 1 GiB of probes.csv, 128 MiB of XDMF
    XML and 1e8 values from the .h5 files (and 16 MiB of summary.json, lines of 4096 bytes:
    cosserat_fem/output/results.py), and refuse larger files with that reason. A file one byte over
    its limit is refused naming its size, one at the limit is read (and refused for its
    zeros, which is another reason); likewise a probes.csv line and a dataset's values."""
    results, _ = report
    cases = {r["name"]: r for r in results if r["category"] == "limits"}
    for name, limit in (
        ("probes.csv", 1 << 30),
        ("solution.xdmf", 128 << 20),
        ("summary.json", 16 << 20),
    ):
        at, over = cases[f"{name}: {limit} bytes"], cases[f"{name}: {limit + 1} bytes"]
        assert over["read"] == "refused", over
        assert f"{limit + 1} bytes, more than the {limit >> 20} MiB" in over["message"], over
        assert at["read"] == "refused" and "MiB" not in at["message"], at
    long = cases["a probes.csv line of 4097 bytes"]
    assert long["read"] == "refused" and "longer than 4096 bytes" in long["message"], long
    assert cases["a probes.csv line of 4096 bytes"]["read"] == "ok"
    (values,) = [r for name, r in cases.items() if name.startswith("a geometry of")]
    assert values["read"] == "refused" and "more than 100000000 values" in values["message"]


@pytest.mark.long
def test_some_generated_cases_are_read_and_plotted(report):
    """The generated damage is not all refused: some copies (a digit flipped in a value, a
    probe row deleted) are still runs, and read and plot; the fuzzing reaches the readers'
    far ends, not only their first check."""
    results, _ = report
    generated_ = [r for r in results if r["expect"] is None]
    assert sum(r["read"] == "ok" for r in generated_) >= 10
    assert sum(r["read"] == "refused" for r in generated_) >= 50
    assert any(r.get("plot_result") == "ok" and r["read"] == "ok" for r in generated_)


def _one_error_line(proc: subprocess.CompletedProcess, name: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert proc.stderr.count("\n") == 1, proc.stderr
    line = proc.stderr.strip()
    assert line.startswith("cosserat-fem: error: "), line
    assert "internal error" not in line and "Traceback" not in line, line
    assert name in line, line


def test_d12_binary_probes_csv(tmp_path):
    """D12 as reported: a folder whose probes.csv is 2000 random bytes gave ``internal error:
    UnicodeDecodeError`` (exit 1); now exit 2 and one line naming probes.csv and saying it is
    not UTF-8 text."""
    (tmp_path / "probes.csv").write_bytes(random.Random(SEED).randbytes(2000))
    proc = cli("plot", str(tmp_path))
    _one_error_line(proc, "probes.csv")
    assert "UTF-8" in proc.stderr
    assert not list(tmp_path.glob("*.png"))


@pytest.mark.long
@pytest.mark.parametrize(
    "case, name",
    [
        ("d12", "probes.csv"),
        ("title", "summary.json"),
        ("topology", "solution.xdmf"),
        ("points", "solution.frames/000000.h5"),
        ("time", "solution.xdmf"),
    ],
)
def test_plot_refuses_damaged_folders(report, case, name):
    """``cosserat-fem plot`` on copies of the run with binary probes.csv (D12), a title that is
    a number, a negative topology index, a displacement of 24 points on a 25-point mesh, a
    Time Value "abc" (the old reader: internal error, exit 0, exit 0, internal error, internal
    error): exit 2, exactly one stderr line naming the file, and no figure written."""
    _, work = report
    out = work / f"plot-{case}"
    proc = cli("plot", str(work / case), "--out", str(out))
    _one_error_line(proc, name)
    assert not out.exists() or not list(out.iterdir())


@pytest.mark.long
def test_render_refuses_a_damaged_folder(report):
    """``cosserat-fem render --frames 2`` on a copy whose first frame displaces every point
    onto the fixed end (readable numbers, but the rod is a single point; the old render:
    internal error: ValueError, "Empty meshes cannot be plotted", from VTK's tube filter):
    exit 2, one line naming solution.xdmf, no picture. The check comes before pyvista is
    loaded, so this is fast."""
    _, work = report
    out = work / "render-collapse"
    proc = cli("render", str(work / "collapse"), "--frames", "2", "--out", str(out))
    _one_error_line(proc, "solution.xdmf")
    assert "at one place" in proc.stderr
    assert not out.exists() or not list(out.iterdir())


@pytest.mark.parametrize("scale", ["1e308", "1e13", "0", "-1", "nan", "inf"])
def test_render_refuses_a_scale_beyond_its_bound(genuine, tmp_path, scale):
    """``render --scale 1e308`` ended in "internal error: ValueError: Empty meshes cannot be
    plotted" (VTK's tube filter squares coordinates of 1e305 m). --scale is held to the
    automatic magnification's bound, 1e12 (a displacement below ~1e-13 of the length is
    round-off of it): a larger one, like a scale that is not a positive number, is refused
    in one line naming --scale before the run is read (exit 2, no picture)."""
    out = tmp_path / "pictures"
    proc = cli("render", str(genuine), "--scale", scale, "--frames", "2", "--out", str(out))
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cosserat-fem: error: render --scale: "), err
    assert not out.exists()


@pytest.mark.long
def test_plot_a_run_killed_before_its_first_frame(report):
    """A run killed after XdmfWriter published its frameless file and one probe row was
    flushed (t = 0) plots what it has: free_end.png, no surfaces, exit 0 (the old reader
    refused the whole folder: "no mesh in the XDMF file"). render has nothing to draw: exit 2,
    one line."""
    _, work = report
    out = work / "plot-mesh-only"
    proc = cli("plot", str(work / "mesh_only"), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["free_end.png"]
    proc = cli("render", str(work / "mesh_only"), "--frames", "2", "--out", str(out))
    _one_error_line(proc, "solution.xdmf")
    assert "no time steps" in proc.stderr


if __name__ == "__main__":  # the helper: python tests/test_output_fuzz.py GENUINE WORK REPORT
    sys.path.insert(0, str(ROOT))
    helper_main(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]))
