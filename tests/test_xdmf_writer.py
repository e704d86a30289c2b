"""The XDMF writer's parts (cosserat_fem/io/xdmf.py, ``XdmfSeries``, and its DOLFINx side,
cosserat_fem/output/fields.py, ``XdmfWriter``), in this process.

* Frame files: the image copied from a template (``_FrameImages``) is, byte for byte, the file
  HDF5 itself makes for the same names and values, for times whose keys have many lengths.
* The XML grows in place without ever being ill-formed: every prefix of the staged write
  (inside the spare processing instruction) leaves the published document as it was; the
  blanks that publish the frame lie within one page (Linux may cut a killed write only
  between pages); the XML names exactly the frames added, whether they went in place or by a
  rewrite, and a series with and without spare room gives the same document.
* A resumed series whose mesh file lists the points in another order (DOLFINx's, under MPI,
  in the writer before) gets its new frames in that order.
* ``mpirun -n 2`` writes the serial run's files, byte for byte, for the same states (rank 0
  gathers the values and writes every file; the points are numbered along the rod).

The killed runs themselves: tests/test_kill.py, test_kill_random.py, test_kill_window.py.
"""

from __future__ import annotations

import filecmp
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from conftest import ROOT, run_command
from xdmf_files import H5File, read_arrays

from cosserat_fem.io import xdmf
from cosserat_fem.io.hdf5 import Hdf5
from cosserat_fem.output import fields
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import load_scene

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
TIMES = [0.0, 2.4e-4, 4.8e-4, 1e-5, 0.06, 1.5, 3.0, 123.25, 1e-300, -7.5e-3, 2.0 / 3.0]


@pytest.fixture(scope="module")
def model():
    return build_model(load_scene(SCENE, ["discretisation.elements=4"]))


def frames_named(path) -> list[str]:
    """The Time values of the frames of the published XML (which must be well-formed)."""
    root = ET.parse(path).getroot()
    return [g.find("Time").get("Value") for g in root.iterfind("Domain/Grid/Grid")]


def test_copied_frame_images_are_hdf5s_own():
    h5 = Hdf5()
    arrays = ["displacement", "angles", "strain_v"]
    images = xdmf._FrameImages(h5, arrays)
    rng = np.random.default_rng(1)
    for t in TIMES * 2:  # the second time round, every length has its template
        key = xdmf._time_text(t).replace(".", "_")
        values = rng.standard_normal((13, 9))
        made = bytes(images(key, values))
        datasets = [
            (f"/Function/{name}/{key}", np.ascontiguousarray(values[:, 3 * i : 3 * i + 3]))
            for i, name in enumerate(arrays)
        ]
        assert made == bytes(h5.image(datasets)[0]), t
    lengths = {len(xdmf._time_text(t)) for t in TIMES}
    assert all(images._templates[n] is not None for n in lengths)  # all copied, none made


def test_frame_files_read_back(tmp_path):
    h5 = Hdf5()
    images = xdmf._FrameImages(h5, ["displacement", "angles"])
    values = np.arange(30.0).reshape(5, 6)
    images("0_5", values)  # the template of this length
    path = tmp_path / "frame.h5"
    xdmf._write_file(path, images("0_7", values))
    f = H5File(path)  # the HDF5 C library, as ParaView reads it
    try:
        np.testing.assert_array_equal(f.read("/Function/displacement/0_7"), values[:, :3])
        np.testing.assert_array_equal(f.read("/Function/angles/0_7"), values[:, 3:])
    finally:
        f.close()


@pytest.mark.parametrize("spare", [(16 << 10, 4 << 20), (1500, 1500), (0, 0)])
def test_the_xml_is_well_formed_at_every_step_of_an_append(model, tmp_path, monkeypatch, spare):
    monkeypatch.setattr(xdmf.XdmfSeries, "SPARE", spare)
    path = tmp_path / "s.xdmf"
    writer = fields.XdmfWriter(path, model, ("displacement",), run_id="id")
    doc = writer.files._doc
    steps = {"in place": 0, "rewritten": 0}
    real_append = doc.append

    def append(frame):
        """Every state the two writes of an append can leave, checked before it is made."""
        before = frames_named(path)
        start, tail = doc._tail + xdmf._SWITCH, doc._new_tail(frame)
        staged = b"".join(
            [b" ", frame, b" " * (tail - start - 1 - len(frame)), xdmf._XDMF_TAIL, xdmf._SPARE_OPEN]
        )
        fd = os.open(path, os.O_RDWR)
        try:
            original = os.pread(fd, len(staged), start)
            for cut in range(0, len(staged) + 1, 7):  # a kill inside the staged write
                os.pwrite(fd, staged[:cut] + original[cut:], start)
                assert frames_named(path) == before, cut
            os.pwrite(fd, original, start)
        finally:
            os.close(fd)
        switch = doc._tail
        assert switch // xdmf._PAGE == (switch + xdmf._SWITCH - 1) // xdmf._PAGE
        real_append(frame)
        steps["in place"] += 1

    monkeypatch.setattr(doc, "append", append)
    real_rewrite = doc.rewrite

    def rewrite(frame, room):
        real_rewrite(frame, room)
        steps["rewritten"] += 1

    monkeypatch.setattr(doc, "rewrite", rewrite)
    for i, t in enumerate(TIMES[:8]):
        writer.write(t)
        assert frames_named(path) == [xdmf._time_text(s) for s in TIMES[: i + 1]]
        assert path.read_bytes().endswith(b"?>\n")
    writer.close()
    if spare[1] == 0:
        assert steps == {"in place": 0, "rewritten": 8}
    elif spare[1] == 1500:  # room for one frame of ~1 kB: in place and rewrites alternate
        assert steps["in place"] >= 2 and steps["rewritten"] >= 2
    else:
        assert steps == {"in place": 8, "rewritten": 0}
    text = path.read_bytes()
    document = text[: text.index(b"</Xdmf>\n") + 8]
    squeezed = b" ".join(document.split())  # the blanks left by appends aside
    expected = b"".join([doc._head(), *doc.frames, xdmf._XDMF_TAIL])
    assert squeezed == b" ".join(expected.split())


def test_a_resumed_series_keeps_its_meshs_order_of_the_points(model, tmp_path):
    """The mesh of a resumed series lists the points in another order (as DOLFINx's output
    mesh did under MPI, in the writer before); the frames written after the resume are in
    that order: read sorted along the rod, they equal those of a series written in one go."""
    whole, resumed = tmp_path / "whole.xdmf", tmp_path / "resumed.xdmf"
    U = model.U
    states = [np.sin(np.arange(U.x.array.size) * (k + 1.0)) * 1e-3 for k in range(4)]
    writer = fields.XdmfWriter(whole, model, ("displacement", "angles"), run_id="a")
    for k, state in enumerate(states):
        U.x.array[:] = state
        writer.write(float(k))
    writer.close()
    writer = fields.XdmfWriter(resumed, model, ("displacement", "angles"), run_id="b")
    for k, state in enumerate(states[:2]):
        U.x.array[:] = state
        writer.write(float(k))
    writer.close()
    # Shuffle the points in the mesh file and in the frames written so far: point j of the
    # file is the output point shuffle[j].
    folder = xdmf.frames_folder(resumed)
    line, h5 = writer.line, writer.files._h5
    shuffle = np.random.default_rng(2).permutation(len(line.geometry))
    at = np.argsort(shuffle)  # where each output point is in the file
    segments = np.sort(at[line.topology], axis=1)
    xdmf._write_file(
        folder / xdmf.MESH_FILE,
        h5.image(
            [("/Mesh/mesh/geometry", line.geometry[shuffle]), ("/Mesh/mesh/topology", segments)]
        )[0],
    )
    for k in range(2):
        name = folder / xdmf.frame_file(k)
        f = H5File(name)
        key = xdmf._time_text(float(k))
        datasets = [
            (f"/Function/{a}/{key}", f.read(f"/Function/{a}/{key}")[shuffle])
            for a in ("displacement", "angles")
        ]
        f.close()
        xdmf._write_file(name, h5.image(datasets)[0])
    writer = fields.XdmfWriter(resumed, model, ("displacement", "angles"), resume=(1, 2))
    assert writer.files._to_file is not None
    for k, state in enumerate(states[2:], start=2):
        U.x.array[:] = state
        writer.write(float(k))
    writer.close()
    points, times, arrays = read_arrays(resumed)
    points_w, times_w, arrays_w = read_arrays(whole)
    np.testing.assert_array_equal(points, points_w)
    np.testing.assert_array_equal(times, times_w)
    for name in arrays_w:
        np.testing.assert_array_equal(arrays[name], arrays_w[name])


SAME_STATES = """
import sys
from pathlib import Path
import numpy as np
from cosserat_fem.rod.model import build_model
from cosserat_fem.output.fields import XdmfWriter
from cosserat_fem.scene.build import load_scene

scene = load_scene(sys.argv[1], ["discretisation.elements=7"])
model = build_model(scene, planar=False)
U, bs = model.U, model.U.function_space.dofmap.index_map_bs
fields = ("displacement", "angles", "strains", "forces")
writer = XdmfWriter(Path(sys.argv[2]) / "s.xdmf", model, fields, run_id="same")
for k in range(3):
    U.interpolate(lambda x: np.array([1e-3 * (k + 1) * np.sin(3 * x[0] + j) for j in range(bs)]))
    writer.write(0.1 * k)
writer.close()
"""


@pytest.mark.mpi
def test_mpirun_writes_the_serial_files(tmp_path):
    script = tmp_path / "same.py"
    script.write_text(SAME_STATES)
    for ranks in (1, 2):
        (tmp_path / str(ranks)).mkdir()
        proc = run_command([str(script), str(SCENE), str(tmp_path / str(ranks))], ranks)
        assert proc.returncode == 0, proc.stderr
    serial, parallel = tmp_path / "1", tmp_path / "2"
    names = sorted(str(p.relative_to(serial)) for p in serial.rglob("*") if p.is_file())
    assert len(names) == 5  # the XML, the mesh and three frames
    match, mismatch, errors = filecmp.cmpfiles(serial, parallel, names, shallow=False)
    assert (mismatch, errors) == ([], []), (mismatch, errors)
