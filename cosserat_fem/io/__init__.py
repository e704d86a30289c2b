"""The files of a run, one module a format, each format's writer beside its reader.

==================  =====================================================================
module              files
==================  =====================================================================
``probes``          probes.csv: the probe's row a step (:class:`~.probes.ProbeWriter`,
                    :func:`~.probes.read_probe_table`)
``xdmf``            solution.xdmf and its frames folder of HDF5 files: the array names
                    (:data:`~.xdmf.FIELD_ARRAYS`), the files' writer
                    (:class:`~.xdmf.XdmfSeries`), a restart's check and cut, the reader
                    (:func:`~.xdmf.read_xdmf`, h5py)
``checkpoint``      checkpoint/: the index and each rank's state (writer, loader), a restart's
                    checks of the outputs and their cut back to the checkpoint
``run_folder``      a run's folder (lock, claim of an earlier run's outputs, run id) and
                    summary.json (:func:`~.run_folder.write_summary`,
                    :func:`~.run_folder.read_summary`)
``hdf5``            HDF5 files made in memory by the process's HDF5 library (ctypes)
``reading``         the checks every reader makes (regular file, size, UTF-8, finite numbers)
==================  =====================================================================

The names, columns and constants of a format are defined in its module only; the writers, the
schema, the budget and the readers import them from there. No module here imports DOLFINx: what
is sampled or computed on the mesh (probe values, the output fields' UFL) is
cosserat_fem/output/fields.py's. The readers need numpy, the standard library and h5py only, so that
``cosserat-fem plot``/``render`` work without the solver stack (and h5py cannot share a process
with DOLFINx's HDF5: cosserat_fem/io/xdmf.py).
"""
