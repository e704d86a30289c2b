"""Unit tests of cosserat_fem/io/poincare.py: poincare.csv written by ``poincare_bytes`` and
read back by ``read_poincare``, without DOLFINx.

* Round trip: every value but the period index is written with ``%.16e``, 17 significant
  digits, enough to name every IEEE double (IEEE 754-2008, 5.12.2), so it reads back exactly;
  the index is a whole number. Exact comparisons: correctly rounded conversions both ways.
* A header of unknown columns, or a row with the wrong count or a value that is not a finite
  number, is one line naming the file (and the line).
"""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.poincare import (
    POINCARE,
    STATE_RMS,
    poincare_bytes,
    poincare_columns,
    read_poincare,
)

pytestmark = pytest.mark.unit


@pytest.mark.parametrize("fields", [(), ("quaternion",), ("quaternion", "directors")])
def test_rows_read_back_exactly(tmp_path, fields):
    columns = poincare_columns(fields)
    assert columns[:2] == ("period", "t") and columns[-1] == STATE_RMS
    rng = np.random.default_rng(3)
    rows = rng.standard_normal((5, len(columns))) * 10.0 ** rng.integers(-30, 30, (5, 1))
    rows[:, 0] = np.arange(5) + 7
    path = tmp_path / POINCARE
    path.write_bytes(poincare_bytes(columns, rows))
    read_columns, read_rows = read_poincare(path)
    assert read_columns == columns
    assert np.array_equal(read_rows, rows)


def test_no_rows_is_an_empty_table(tmp_path):
    path = tmp_path / POINCARE
    path.write_bytes(poincare_bytes(poincare_columns(), np.empty((0, 9))))
    columns, rows = read_poincare(path)
    assert rows.shape == (0, len(columns)) == (0, 9)


@pytest.mark.parametrize(
    "text, message",
    [
        ("t,x\n1,2\n", "not a poincare.csv"),
        ("period,t,x,y,z,theta,psi,phi,state_rms\n1,2,3\n", "line 2 has 3 values"),
        ("period,t,x,y,z,theta,psi,phi,state_rms\n1,2,3,4,5,6,7,8,nan\n", "line 2, column"),
        ("period,t,x,y,z,theta,psi,phi,state_rms\n1,2,3,4,5,6,7,8,x\n", "is not a number"),
    ],
)
def test_a_damaged_file_is_one_line_naming_it(tmp_path, text, message):
    path = tmp_path / POINCARE
    path.write_text(text)
    with pytest.raises(SceneError, match=message) as caught:
        read_poincare(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)
