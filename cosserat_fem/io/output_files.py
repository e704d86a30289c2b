"""The files a command makes whole in memory and writes at once (``plot``, ``render``, ``pod``):
the folder they go to (:func:`output_folder`) and the write, whole or not at all
(:func:`write_output`). A write that fails for a passing reason (a full disk, a quota, the file
size limit, the device) is an OutputError (exit 4); a place that cannot be written, bad input
(a SceneError, exit 2); either names the file in one line.
Tests: tests/test_visualisation.py::test_plot_on_a_full_disk_stops_with_exit_4,
::test_render_on_a_full_disk_stops_with_exit_4;
tests/test_pod.py::test_pod_on_a_full_disk_stops_with_exit_4_and_no_cut_file.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import OutputError, SceneError, out_folder

#: The errors of a write that the place itself does not explain (a full disk, a quota, the
#: file size limit, the device): a stopped output (exit 4) rather than bad input.
_WRITE_FAILURES = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


def output_folder(out: str | Path | None, directory: Path, command: str) -> Path:
    """``out`` (made if missing) or ``directory`` (the run's folder); a folder that cannot be
    made is bad input, or an OutputError when the disk is full or failing."""
    target = out_folder(out, f"{command} --out") or directory
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        kind = OutputError if exc.errno in _WRITE_FAILURES else SceneError
        raise kind(f"{command} --out: cannot write to {str(target)!r} ({exc})") from None
    return target


def write_output(path: Path, data, command: str) -> Path:
    """``data`` (bytes-like) as the file ``path``, whole or not at all
    (:func:`cosserat_fem.common.safe_files.replace`: a hidden scratch file beside it renamed over
    it, so a link at ``path`` is replaced, never written through). OutputError naming ``path`` if
    it cannot be written; the scratch file is removed and a file that was at ``path`` before is
    kept."""
    try:
        safe_files.replace(path, data, path.with_name(f".{path.name}.{os.getpid()}.partial"))
    except OSError as exc:
        raise OutputError(
            f"{command}: cannot write {str(path)!r} ({exc.strerror or exc})"
        ) from None
    return path
