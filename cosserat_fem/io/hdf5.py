"""HDF5 files made in memory by the HDF5 C library of this process (DOLFINx's), through ctypes:
the frame files of cosserat_fem/io/xdmf.py and karhunen_loeve.py's pod.xdmf. h5py brings an
HDF5 library of its own, which cannot share a process with DOLFINx's (the readers use h5py, in
a process without DOLFINx). Imports no DOLFINx: the library is found among those the process
has loaded, else by name.
Tests: tests/test_xdmf_writer.py, tests/test_pod.py.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import re
from pathlib import Path

import numpy as np


class Hdf5:
    """HDF5 files made in memory by the HDF5 C library that DOLFINx has loaded, called through
    ctypes (h5py brings a library of its own, which cannot share a process with DOLFINx's).

    :meth:`image` builds a file with the core driver and no backing store and returns its
    bytes: the library never writes to disk, so a write that fails (disk full, ``ulimit -f``)
    is Python's OSError, never a failure inside HDF5. The files have superblock version 0 and
    contiguous datasets, as DOLFINx writes them: readable by every HDF5 since 1.8, and no
    "file open for writing" flag is ever set in them. HDF5's own error report on stderr is
    switched off during the calls (a failure raises RuntimeError)."""

    _lib = None

    def __init__(self):
        lib = self.library()
        hid = ctypes.c_int64
        self.lib = lib
        self.float64 = (
            hid.in_dll(lib, "H5T_IEEE_F64LE_g").value,
            hid.in_dll(lib, "H5T_NATIVE_DOUBLE_g").value,
        )
        self.int64 = (
            hid.in_dll(lib, "H5T_STD_I64LE_g").value,
            hid.in_dll(lib, "H5T_NATIVE_INT64_g").value,
        )
        self.fapl = lib.H5Pcreate(hid.in_dll(lib, "H5P_CLS_FILE_ACCESS_ID_g").value)
        self.lcpl = lib.H5Pcreate(hid.in_dll(lib, "H5P_CLS_LINK_CREATE_ID_g").value)
        self.dcpl = lib.H5Pcreate(hid.in_dll(lib, "H5P_CLS_DATASET_CREATE_ID_g").value)
        if (
            min(self.fapl, self.lcpl, self.dcpl) < 0
            or lib.H5Pset_fapl_core(self.fapl, 1 << 16, 0) < 0
            or lib.H5Pset_create_intermediate_group(self.lcpl, 1) < 0
            or lib.H5Pset_obj_track_times(self.dcpl, 0) < 0  # the same bytes for the same data
        ):
            raise RuntimeError("HDF5: cannot set up in-memory files")

    @classmethod
    def library(cls) -> ctypes.CDLL:
        """The HDF5 C library already in this process (DOLFINx's), with the prototypes used."""
        if cls._lib is not None:
            return cls._lib
        found = None
        pattern = re.compile(r"/libhdf5(?:_openmpi|_mpich|_serial)?\.so(?:\.[0-9]+)*$")
        try:
            with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
                for line in maps:
                    fields = line.split(maxsplit=5)
                    if len(fields) == 6 and pattern.search(fields[5].strip()):
                        found = fields[5].strip()
                        break
        except OSError:
            pass
        for name in ("hdf5_openmpi", "hdf5_mpich", "hdf5_serial", "hdf5"):
            found = found or ctypes.util.find_library(name)
        if not found:
            raise RuntimeError("the HDF5 C library (DOLFINx's) was not found")
        lib = ctypes.CDLL(found)
        hid, herr, size = ctypes.c_int64, ctypes.c_int, ctypes.c_size_t
        pointer, text = ctypes.c_void_p, ctypes.c_char_p
        for name, result, arguments in (
            ("H5open", herr, []),
            ("H5Fcreate", hid, [text, ctypes.c_uint, hid, hid]),
            ("H5Fopen", hid, [text, ctypes.c_uint, hid]),
            ("H5Fflush", herr, [hid, ctypes.c_int]),
            ("H5Fget_file_image", ctypes.c_ssize_t, [hid, pointer, size]),
            ("H5Fclose", herr, [hid]),
            ("H5Pcreate", hid, [hid]),
            ("H5Pset_fapl_core", herr, [hid, size, ctypes.c_uint]),
            ("H5Pset_create_intermediate_group", herr, [hid, ctypes.c_uint]),
            ("H5Pset_obj_track_times", herr, [hid, ctypes.c_uint]),
            ("H5Screate_simple", hid, [ctypes.c_int, pointer, pointer]),
            ("H5Sget_simple_extent_ndims", ctypes.c_int, [hid]),
            ("H5Sget_simple_extent_dims", ctypes.c_int, [hid, pointer, pointer]),
            ("H5Sclose", herr, [hid]),
            ("H5Dcreate2", hid, [hid, text, hid, hid, hid, hid, hid]),
            ("H5Dopen2", hid, [hid, text, hid]),
            ("H5Dget_space", hid, [hid]),
            ("H5Dwrite", herr, [hid, hid, hid, hid, hid, pointer]),
            ("H5Dread", herr, [hid, hid, hid, hid, hid, pointer]),
            ("H5Dget_offset", ctypes.c_uint64, [hid]),
            ("H5Dclose", herr, [hid]),
            ("H5Eget_auto2", herr, [hid, pointer, pointer]),
            ("H5Eset_auto2", herr, [hid, pointer, pointer]),
        ):
            function = getattr(lib, name)
            function.restype, function.argtypes = result, arguments
        if lib.H5open() < 0:
            raise RuntimeError(f"HDF5: cannot initialise {found}")
        cls._lib = lib
        return lib

    @contextlib.contextmanager
    def _quiet(self):
        """HDF5's printing of its error stack off (restored after)."""
        handler, data = ctypes.c_void_p(), ctypes.c_void_p()
        self.lib.H5Eget_auto2(0, ctypes.byref(handler), ctypes.byref(data))
        self.lib.H5Eset_auto2(0, None, None)
        try:
            yield
        finally:
            self.lib.H5Eset_auto2(0, handler, data)

    def image(self, datasets: list[tuple[str, np.ndarray]]) -> tuple[ctypes.Array, list[int]]:
        """The bytes of an HDF5 file holding the float64 or int64 ``datasets`` (name: a path
        from the root, its groups made as needed), and where each dataset's values begin in
        them; RuntimeError if HDF5 fails."""
        lib = self.lib
        with self._quiet():
            f = lib.H5Fcreate(b"cosserat-fem-image.h5", 2, 0, self.fapl)  # H5F_ACC_TRUNC
            if f < 0:
                raise RuntimeError("HDF5: cannot make an in-memory file")
            try:
                offsets = [self._dataset(f, name, values) for name, values in datasets]
                size = lib.H5Fget_file_image(f, None, 0) if lib.H5Fflush(f, 0) >= 0 else -1
                image = ctypes.create_string_buffer(max(size, 0))
                if size <= 0 or lib.H5Fget_file_image(f, image, size) != size:
                    raise RuntimeError("HDF5: cannot take the in-memory file's image")
            finally:
                lib.H5Fclose(f)
        return image, offsets

    def _dataset(self, f: int, name: str, values: np.ndarray) -> int:
        """Make and write a dataset in the open file f; where its values begin in the file."""
        lib = self.lib
        dims = (ctypes.c_uint64 * values.ndim)(*values.shape)
        stored, memory = self.float64 if values.dtype == np.float64 else self.int64
        if values.dtype not in (np.float64, np.int64) or not values.flags.c_contiguous:
            raise TypeError(f"HDF5 dataset {name}: C-ordered float64 or int64 values only")
        space = lib.H5Screate_simple(values.ndim, dims, None)
        dataset = lib.H5Dcreate2(f, name.encode(), stored, space, self.lcpl, self.dcpl, 0)
        lib.H5Sclose(space)
        if dataset < 0:
            raise RuntimeError(f"HDF5: cannot make the dataset {name}")
        try:
            if lib.H5Dwrite(dataset, memory, 0, 0, 0, values.ctypes.data) < 0:
                raise RuntimeError(f"HDF5: cannot write the dataset {name}")
            return lib.H5Dget_offset(dataset)
        finally:
            lib.H5Dclose(dataset)

    def read(self, path: Path, name: str) -> np.ndarray:
        """The dataset ``name`` of the HDF5 file ``path`` as float64; RuntimeError if it cannot
        be read."""
        lib = self.lib
        with self._quiet():
            f = lib.H5Fopen(str(path).encode(), 0, 0)  # H5F_ACC_RDONLY
            if f < 0:
                raise RuntimeError(f"HDF5: cannot open {str(path)!r}")
            try:
                dataset = lib.H5Dopen2(f, name.encode(), 0)
                if dataset < 0:
                    raise RuntimeError(f"HDF5: no dataset {name} in {str(path)!r}")
                try:
                    space = lib.H5Dget_space(dataset)
                    ndims = lib.H5Sget_simple_extent_ndims(space)
                    dims = (ctypes.c_uint64 * max(ndims, 1))()
                    lib.H5Sget_simple_extent_dims(space, dims, None)
                    lib.H5Sclose(space)
                    values = np.empty(tuple(dims[: max(ndims, 0)]), dtype=np.float64)
                    if (
                        ndims < 0
                        or lib.H5Dread(dataset, self.float64[1], 0, 0, 0, values.ctypes.data) < 0
                    ):
                        raise RuntimeError(f"HDF5: cannot read {name} of {str(path)!r}")
                finally:
                    lib.H5Dclose(dataset)
            finally:
                lib.H5Fclose(f)
        return values
