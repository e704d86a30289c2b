"""Unit tests of cosserat_fem/io/reading.py, the checks every reader of a run's files makes: a
regular file (a folder, a FIFO, a link to nothing named as such), of bounded size, UTF-8 text
(the first bad byte and its offset named), finite numbers within MAX_MAGNITUDE; text from a
file quoted with ``repr`` in a message, so no control character reaches the terminal.

Exact comparisons: the messages and values are built from the inputs by string operations and
exact float conversions (float(10**100) is the double nearest 1e100, the same as the literal).
"""

from __future__ import annotations

import math
import os

import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.reading import (
    MAX_MAGNITUDE,
    check_size,
    decode,
    excerpt,
    finite_number,
    is_file,
    json_kind,
    read_bytes,
    short_reason,
)

pytestmark = pytest.mark.unit


def test_excerpt_quotes_and_shortens():
    assert excerpt("t,x") == "'t,x'"
    assert excerpt("\x1b[31mred\x07") == "'\\x1b[31mred\\x07'"  # no control character left
    assert excerpt("a" * 40) == repr("a" * 40)  # 40 characters: kept whole
    assert excerpt("a" * 41) == repr("a" * 40 + "...")
    assert excerpt("abcdef", size=3) == "'abc...'"


def test_short_reason():
    assert short_reason(OSError("unable\n   to open\tfile")) == "unable to open file"
    assert short_reason(KeyError()) == "KeyError"  # no text: the exception's name
    long = short_reason(ValueError("x" * 400))
    assert long == "x" * 157 + "..." and len(long) == 160


@pytest.mark.parametrize(
    ("value", "kind"),
    [
        (True, "a boolean"),  # bool before int: True is an int in Python
        (None, "null"),
        ({}, "an object"),
        ([1], "an array"),
        ("1", "a string"),
        (1, "a number"),
        (1.5, "a number"),
    ],
)
def test_json_kind(value, kind):
    assert json_kind(value) == kind


@pytest.mark.parametrize(
    ("value", "number"),
    [
        (1, 1.0),
        (-2.5, -2.5),
        (MAX_MAGNITUDE, 1e100),
        (-(10**100), -1e100),  # an int within the bound, converted exactly
        (True, None),  # a JSON boolean is not a number
        ("1", None),
        (None, None),
        (math.nan, None),
        (math.inf, None),
        (1.0000000000001e100, None),  # beyond the bound by 1e-13 relative: 450 ulps
        (10**400, None),  # an int too large for a float (OverflowError)
    ],
)
def test_finite_number(value, number):
    assert finite_number(value) == number


def test_is_file(tmp_path):
    regular = tmp_path / "probes.csv"
    regular.write_text("t\n")
    assert is_file(regular)
    (tmp_path / "link").symlink_to(regular)
    assert is_file(tmp_path / "link")  # links are followed for reading
    assert not is_file(tmp_path / "missing")
    cases = {tmp_path: "is a folder, not a file"}
    os.mkfifo(tmp_path / "fifo")
    cases[tmp_path / "fifo"] = "is not a regular file (a device, FIFO or socket)"
    (tmp_path / "dangling").symlink_to(tmp_path / "missing")
    cases[tmp_path / "dangling"] = "is a link to nothing (or a loop of links)"
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    cases[tmp_path / "loop"] = "is a link to nothing (or a loop of links)"
    for path, problem in cases.items():
        with pytest.raises(SceneError) as raised:
            is_file(path)
        assert str(raised.value) == f"{str(path)!r}: {problem}"


def test_size_bound(tmp_path):
    """A file of exactly ``limit`` bytes is read; one byte more is refused with its size."""
    path = tmp_path / "summary.json"
    limit = 1 << 20
    path.write_bytes(b"x" * limit)
    assert read_bytes(path, limit) == b"x" * limit
    path.write_bytes(b"x" * (limit + 1))
    with pytest.raises(SceneError) as raised:
        read_bytes(path, limit)
    assert str(raised.value) == (
        f"{str(path)!r}: 1048577 bytes, more than the 1 MiB a run's file can have; "
        "not a run's output"
    )
    with pytest.raises(SceneError, match=r": cannot read it \("):
        check_size(tmp_path / "missing", 1024)


def test_decode_names_the_first_bad_byte(tmp_path):
    path = tmp_path / "probes.csv"
    assert decode(path, "t,ω\n".encode()) == "t,ω\n"
    with pytest.raises(SceneError) as raised:
        decode(path, b"t,x\n0,\xff\xfe", where="line 2: ")
    assert str(raised.value) == (
        f"{str(path)!r}: line 2: not UTF-8 text (byte 0xff at offset 6); not a run's output"
    )
    with pytest.raises(SceneError, match=r"\(byte 0xe2 at offset 1\)"):
        decode(path, "tω".encode()[:1] + "…".encode()[:2])  # a truncated 3-byte sequence
