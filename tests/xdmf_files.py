"""Reading a run's XDMF/HDF5 output as ParaView would, without DOLFINx or h5py.

The .h5 files are read with the HDF5 C library that DOLFINx itself uses (ctypes), so a file
that the HDF5 library cannot open fails the test, as it would in ParaView. Used by
tests/test_kill.py and tests/test_restart.py.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

# --- HDF5 through its C library ------------------------------------------------------------


class H5File:
    """Read-only access to the datasets of an HDF5 file (libhdf5 >= 1.10: hid_t is 64-bit)."""

    _lib = None

    @classmethod
    def lib(cls):
        if cls._lib is None:
            for name in ("hdf5_openmpi", "hdf5_mpich", "hdf5_serial", "hdf5"):
                found = ctypes.util.find_library(name)
                if found:
                    break
            else:
                pytest.fail("no HDF5 C library found (DOLFINx depends on one: libhdf5-*)")
            lib = ctypes.CDLL(found)
            hid = ctypes.c_int64
            lib.H5Fopen.restype = hid
            lib.H5Fopen.argtypes = [ctypes.c_char_p, ctypes.c_uint, hid]
            lib.H5Dopen2.restype = hid
            lib.H5Dopen2.argtypes = [hid, ctypes.c_char_p, hid]
            lib.H5Dget_space.restype = hid
            lib.H5Dget_space.argtypes = [hid]
            lib.H5Sget_simple_extent_ndims.argtypes = [hid]
            lib.H5Sget_simple_extent_dims.argtypes = [hid, ctypes.c_void_p, ctypes.c_void_p]
            lib.H5Dread.argtypes = [hid, hid, hid, hid, hid, ctypes.c_void_p]
            for fn in ("H5Dclose", "H5Sclose", "H5Fclose"):
                getattr(lib, fn).argtypes = [hid]
            lib.H5Eset_auto2.argtypes = [hid, ctypes.c_void_p, ctypes.c_void_p]
            assert lib.H5open() >= 0
            lib.H5Eset_auto2(0, None, None)  # no error stack on stderr: we raise instead
            cls._lib = lib
        return cls._lib

    def __init__(self, path: Path):
        lib = self.lib()
        self.fid = lib.H5Fopen(str(path).encode(), 0, 0)  # H5F_ACC_RDONLY, H5P_DEFAULT
        if self.fid < 0:
            raise OSError(f"the HDF5 library cannot open {path}")

    def read(self, name: str) -> np.ndarray:
        """The dataset ``name`` as float64 (HDF5 converts integer topology too)."""
        lib = self.lib()
        dset = lib.H5Dopen2(self.fid, name.encode(), 0)
        if dset < 0:
            raise KeyError(f"no dataset {name}")
        try:
            space = lib.H5Dget_space(dset)
            ndims = lib.H5Sget_simple_extent_ndims(space)
            dims = (ctypes.c_uint64 * max(ndims, 1))()
            lib.H5Sget_simple_extent_dims(space, dims, None)
            lib.H5Sclose(space)
            out = np.empty(tuple(dims[:ndims]), dtype=np.float64)
            native_double = ctypes.c_int64.in_dll(lib, "H5T_NATIVE_DOUBLE_g").value
            if lib.H5Dread(dset, native_double, 0, 0, 0, out.ctypes.data) < 0:
                raise OSError(f"cannot read dataset {name}")
            return out
        finally:
            lib.H5Dclose(dset)

    def close(self) -> None:
        self.lib().H5Fclose(self.fid)


def read_xdmf(path: Path, names: bool = True) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{name: (times, free-end values of each frame)} of ``displacement`` and ``angles``, after
    checking every HDF5 reference of the XML: to ``<stem>.frames/mesh.h5`` and one file a
    frame, ``<stem>.frames/<i, 6 digits>.h5``, i = 0, 1, ... in order (restarts included;
    cosserat_fem/io/xdmf.py), with the XML's dimensions, finite values. ``names=False``: any
    file names (e.g. those of the earlier single-file layout, ``<stem>.h5``), the rest checked
    all the same."""
    root = ET.parse(path).getroot()  # raises on a cut or empty file
    folder = re.escape(path.stem) + r"\.frames/"
    mesh_file = re.compile(folder + r"mesh\.h5")
    frame_file = re.compile(folder + r"([0-9]{6})\.h5")
    files: dict[str, H5File] = {}
    try:
        data = {}
        for item in root.iter("DataItem"):
            assert item.get("Format") == "HDF"
            if item.text.strip() in data:  # the mesh, referenced by every frame
                continue
            filename, dataset = item.text.strip().split(":")
            if names:
                assert mesh_file.fullmatch(filename) or frame_file.fullmatch(filename), filename
            if filename not in files:
                files[filename] = H5File(path.parent / filename)
            values = files[filename].read(dataset)
            dims = tuple(int(n) for n in item.get("Dimensions").split())
            assert values.shape == dims, (dataset, values.shape, dims)
            assert np.isfinite(values).all(), dataset
            data[item.text.strip()] = values
        # One temporal collection (cosserat_fem/io/xdmf.py): each frame holds the mesh, the
        # reference centreline (0, 0, s) [m] whose free end has the largest s, and the arrays.
        grids = root.findall("Domain/Grid[@GridType='Collection']/Grid")
        times = np.array([float(g.find("Time").get("Value")) for g in grids])
        for i, grid in enumerate(grids if names else ()):  # frame i in its own file
            for item in grid.findall("Attribute/DataItem"):
                assert frame_file.fullmatch(item.text.split(":")[0])[1] == f"{i:06d}", i
            for item in grid.findall("Topology/DataItem") + grid.findall("Geometry/DataItem"):
                assert mesh_file.fullmatch(item.text.split(":")[0]), item.text
        series = {name: (times, []) for name in ("displacement", "angles")}
        for grid in grids:
            x = data[grid.find("Geometry/DataItem").text.strip()]
            assert x.shape[1] == 3 and not x[:, :2].any()
            tip = int(np.argmax(x[:, 2]))
            for name, (_, tips) in series.items():
                item = grid.find(f"Attribute[@Name='{name}']/DataItem")
                tips.append(data[item.text.strip()][tip])
        series = {name: (t, np.array(tips).reshape(-1, 3)) for name, (t, tips) in series.items()}
        return series
    finally:
        for h5 in files.values():
            h5.close()


def read_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(points (N, 3), times (T,), {array: (T, N, 3)}) of every frame, points sorted along the
    rod (by z, the reference centreline (0, 0, s)); read with the HDF5 C library as above."""
    root = ET.parse(path).getroot()
    grids = root.findall("Domain/Grid[@GridType='Collection']/Grid")
    files: dict[str, H5File] = {}

    def dataset(item) -> np.ndarray:
        filename, name = item.text.strip().split(":")
        if filename not in files:
            files[filename] = H5File(path.parent / filename)
        return files[filename].read(name)

    try:
        points = dataset(grids[0].find("Geometry/DataItem"))
        order = np.argsort(points[:, 2], kind="stable")
        times = np.array([float(g.find("Time").get("Value")) for g in grids])
        names = [a.get("Name") for a in grids[0].findall("Attribute")]
        arrays = {
            name: np.array(
                [dataset(g.find(f"Attribute[@Name='{name}']/DataItem"))[order] for g in grids]
            )
            for name in names
        }
        return points[order], times, arrays
    finally:
        for h5 in files.values():
            h5.close()
