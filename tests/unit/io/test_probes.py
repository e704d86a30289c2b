"""Unit tests of cosserat_fem/io/probes.py: probes.csv written by ProbeWriter and read back by
read_probe_table, without DOLFINx (a stand-in probe with the attributes the writer reads: its
columns, its values, whether it owns the point, the communicator, here MPI.COMM_SELF).

* Round trip. Every value but t is written with ``%.16e``, 17 significant digits, enough to
  name every IEEE double (IEEE 754-2008, 5.12.2: 17 digits for binary64), so it reads back
  exactly; t is written with 11 digits (``%.10e``) and reads back as exactly
  ``float("%.10e" % t)``. Exact comparisons: correctly rounded conversions both ways.
* A killed run's cut last line is dropped; an empty file or a cut header is no rows; a header
  of unknown columns, or a row with the wrong count or a non-finite value, is one line naming
  the file (and the line).
* :meth:`ProbeWriter.digest` is the SHA-256 of the file's bytes; ``probe_prefix`` of all the
  rows gives the same; ``last_probe_row`` is the last row written.
"""

from __future__ import annotations

import hashlib
from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.probes import (
    PROBE_COLUMNS,
    ProbeWriter,
    last_probe_row,
    probe_columns,
    probe_prefix,
    read_probe_table,
)

pytestmark = pytest.mark.unit


class StandInProbe:
    """What ProbeWriter reads of a probe (cosserat_fem/output/fields.py PointProbe): its
    columns, its values now, whether this rank owns the point, and the mesh's communicator."""

    def __init__(self, columns: tuple[str, ...], rows: np.ndarray):
        self.columns = columns
        self.is_owner = True
        self.U = SimpleNamespace(
            function_space=SimpleNamespace(mesh=SimpleNamespace(comm=MPI.COMM_SELF))
        )
        self._rows = iter(rows)

    def values(self) -> np.ndarray:
        return next(self._rows)


def rows_of(n: int, columns: int) -> np.ndarray:
    """Random values of both signs from 1e-30 to 1e30, every bit of the mantissa used."""
    rng = np.random.default_rng(26)
    return rng.standard_normal((n, columns)) * 10.0 ** rng.integers(-30, 30, (n, columns))


def test_the_columns():
    assert probe_columns() == PROBE_COLUMNS == ("t", "x", "y", "z", "theta", "psi", "phi")
    assert probe_columns(("directors", "quaternion"))[7:11] == ("q0", "q1", "q2", "q3")
    assert len(probe_columns(("directors",))) == 7 + 9


@pytest.mark.parametrize("fields", [(), ("quaternion",), ("quaternion", "directors")])
def test_round_trip(tmp_path, fields):
    columns = probe_columns(fields)
    n = 37
    values = rows_of(n, len(columns) - 1)
    times = np.cumsum(np.full(n, 1 / 3))  # 1/3 k: not exact in 11 digits
    path = tmp_path / "probes.csv"
    writer = ProbeWriter(path, StandInProbe(columns, values), flush_every=8)
    for t in times:
        writer.write(t)
    digest = writer.digest()
    writer.close()
    read_columns, table = read_probe_table(path)
    assert read_columns == columns
    assert table.shape == (n, len(columns))
    assert table[:, 0].tolist() == [float(f"{t:.10e}") for t in times]
    assert np.array_equal(table[:, 1:], values)
    data = path.read_bytes()
    assert digest == hashlib.sha256(data).hexdigest()
    size, prefix = probe_prefix(path, n)
    assert (size, prefix.hexdigest()) == (len(data), digest)
    assert np.array_equal(last_probe_row(path)[1:], values[-1])


def test_a_cut_last_line_is_dropped(tmp_path):
    path = tmp_path / "probes.csv"
    path.write_text("t,x,y,z,theta,psi,phi\n" + "1,2,3,4,5,6,7\n" + "2,3,4,5,6,7,8\n" + "3,4,5,")
    columns, table = read_probe_table(path)
    assert columns == PROBE_COLUMNS
    assert table.tolist() == [[1, 2, 3, 4, 5, 6, 7], [2, 3, 4, 5, 6, 7, 8]]
    for text in ("", "t,x,y,z,th"):  # killed as the file was made: no rows
        path.write_text(text)
        columns, table = read_probe_table(path)
        assert columns == PROBE_COLUMNS and table.shape == (0, 7)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("t,x,y\n1,2,3\n", "not a probes.csv (header 't,x,y'"),
        ("time,x\n", "not a probes.csv"),
        ("t,x,y,z,theta,psi,phi\n1,2,3\n", "line 2"),
        ("t,x,y,z,theta,psi,phi\n1,2,3,4,5,6,nan\n", "line 2"),
        ("t,x,y,z,theta,psi,phi\n1,2,3,4,5,6,7\n1,2,3,4,5,6,1e300\n", "line 3"),
    ],
)
def test_bad_tables_are_one_line_naming_the_file(tmp_path, text, words):
    path = tmp_path / "probes.csv"
    path.write_text(text)
    with pytest.raises(SceneError) as raised:
        read_probe_table(path)
    message = str(raised.value)
    assert message.startswith(repr(str(path)) + ": ") and words in message, message
