"""poincare.csv: a Poincaré section of a periodically forced run, one row a forcing period,
appended a row at a time and written whole at the run's end beside probes.csv
(:func:`poincare_bytes`, by the observer cosserat_fem/analysis/observers.py
``PoincareSection``) and read back without DOLFINx
(:func:`read_poincare`).

The format, and its names, are kept here and nowhere else: the header
``period,t,x,y,z,theta,psi,phi`` (then the columns of ``output.probe_fields``, as probes.csv's:
cosserat_fem/io/probes.py ``probe_columns``), then ``state_rms``; one row a section time
t_j = (j + φ0/2π) T: the period index j (a whole number), t_j [s], the probe's values there
[m, rad], and the root mean square of the state's entries over the rod's degrees of freedom
(U = (p, q) in the solver's units: lengths in ℓ, angles in rad, rates d/dτ, τ = ω0 t;
dimensionless). Every value but j with 17 significant digits (``%.16e``), separated by
commas, each row ending in a newline.

What the reader checks (a :class:`SceneError` naming the file and the line otherwise): a
regular file of at most :data:`MAX_POINCARE_BYTES`, UTF-8, the header of a known set of
probe columns, every non-blank line as many finite numbers as the header names.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.probes import _HEADERS, _probe_row, probe_columns
from cosserat_fem.io.reading import check_size, decode, excerpt, quoted, read_bytes

#: The file's name in a run's folder.
POINCARE = "poincare.csv"
#: The column of the state's root mean square (module docstring).
STATE_RMS = "state_rms"
MAX_POINCARE_BYTES = 1 << 30


def poincare_columns(fields: tuple[str, ...] = ()) -> tuple[str, ...]:
    """poincare.csv's columns with the ``output.probe_fields`` ``fields``: period, t, x, ...,
    φ, each field's columns, state_rms."""
    return ("period", *probe_columns(fields), STATE_RMS)


def poincare_bytes(columns: tuple[str, ...], rows: np.ndarray) -> bytes:
    """The file's content: the header ``columns`` and ``rows`` (n, len(columns)), the first
    column (the period index) written as a whole number."""
    rows = np.asarray(rows, dtype=float).reshape(-1, len(columns))
    lines = [",".join(columns)]
    for row in rows:
        lines.append(",".join([str(int(row[0])), *(f"{v:.16e}" for v in row[1:])]))
    return ("\n".join(lines) + "\n").encode()


def read_poincare(path: str | Path) -> tuple[tuple[str, ...], np.ndarray]:
    """(columns, rows) of poincare.csv (module docstring); SceneError naming the file and
    line for anything else."""
    path = Path(path)
    check_size(path, MAX_POINCARE_BYTES)
    lines = decode(path, read_bytes(path, MAX_POINCARE_BYTES)).split("\n")
    header = lines[0].rstrip("\r")
    known = {",".join(c): c for c in (("period", *p, STATE_RMS) for p in _HEADERS.values())}
    columns = known.get(header)
    if columns is None:
        raise SceneError(
            f"{quoted(path)}: not a poincare.csv (header {excerpt(header)}, expected "
            f"{','.join(poincare_columns())!r} with the columns of output.probe_fields)"
        )
    rows = []
    for number, text in enumerate(lines[1:], start=2):
        row = _probe_row(path, number, text.encode(), columns)
        if row is not None:
            rows.append(row)
    return columns, np.array(rows, dtype=float).reshape(-1, len(columns))
