"""Fuzz-style checks of bad input: scenes, --set values, the command line and damaged
checkpoints, in generated variants (seeded, so that a failure repeats).

The contract (docs/reliability.md): bad input is refused with one line that names the key or
the file, exit status 2, before anything is touched, never with a traceback or an "internal
error"; input that is accepted gives what an undisturbed run gives. Expressions and the
readers of a run's outputs have their own suites (tests/test_expression_fuzz.py,
tests/test_output_fuzz.py); the named defects, tests/test_reliability.py.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import random
import shutil
import string
import subprocess
from pathlib import Path

import pytest
from conftest import PYTHON, ROOT, fails_if_hung, folder_tree, subprocess_env

from cosserat_fem.analysis import budget
from cosserat_fem.cli import main
from cosserat_fem.common.errors import SceneError
from cosserat_fem.scene.build import read_toml, scene_from_dict
from cosserat_fem.scene.describe import describe_scene
from cosserat_fem.scene.schema import SCHEMA

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
BASE = read_toml(SCENE)

#: Values of every kind, and at the edges of double precision, for any key.
HOSTILE = [
    "x",
    "",
    " ",
    "\x00",
    "ｔ",
    "nan",
    True,
    [],
    [1, 2],
    [1, 2, 3],
    ["a", "b", "c"],
    {},
    {"a": 1},
    0,
    -1,
    1,
    0.5,
    -0.0,
    math.nan,
    math.inf,
    -math.inf,
    1e308,
    -1e308,
    1e-308,
    5e-324,
    10**30,
    -(10**30),
    2**63,
    10**400,  # beyond any float (a dict from Python; TOML integers stop at 64 bits)
]


def leaves(table=SCHEMA, prefix: str = "") -> list[str]:
    """Every dotted leaf key of the schema."""
    keys = []
    for name, spec in table.fields.items():
        key = f"{prefix}.{name}" if prefix else name
        keys += leaves(spec, key) if hasattr(spec, "fields") else [key]
    return keys


def with_value(data: dict, key: str, value) -> dict:
    """A copy of ``data`` with ``key`` set to ``value`` (tables made as needed)."""
    out = json.loads(json.dumps(data))
    table = out
    *path, last = key.split(".")
    for name in path:
        table = table.setdefault(name, {})
    table[last] = value
    return out


def check_refusal(exc: SceneError, keys: list[str]) -> None:
    """One line, starting with a dotted key of the scene (or a key's prefix), with a reason."""
    text = str(exc)
    assert "\n" not in text and text.strip() == text
    head, sep, reason = text.partition(": ")
    assert sep and reason.strip(), text
    first = head.split("[")[0].split(" ")[0]
    if reason.startswith("unknown key"):  # it names the key as written, which is not ours
        return
    known = any(k == first or k.startswith(first + ".") for k in keys)
    assert known or first == "parameters" or first.startswith("parameters."), text


def accept_or_refuse(data: dict, keys: list[str]) -> None:
    """scene_from_dict either resolves the scene, whose description and cost estimates
    (validate's) are then made, or refuses it with a one-line SceneError naming a key;
    nothing else escapes."""
    try:
        scene = scene_from_dict(data)
    except SceneError as exc:
        check_refusal(exc, keys)
        return
    describe_scene(scene)
    for command in ("run", "static"):
        try:
            estimate = budget.check(scene, command)
        except SceneError as exc:
            check_refusal(exc, keys)
            continue
        assert 0.0 <= estimate.seconds <= scene.limits.wall_time


KEYS = leaves()


@pytest.mark.parametrize("key", KEYS)
def test_every_key_takes_every_kind_of_value(key):
    """Every leaf key of the schema, set to each of the values of every type and magnitude
    in HOSTILE (strings, lists, tables, non-finite and extreme numbers)."""
    for value in HOSTILE:
        accept_or_refuse(with_value(BASE, key, value), KEYS)


def test_random_structures():
    """500 random mutations of the paper's scene as nested data: a key removed, renamed to a
    near miss or a look-alike, a table replaced by a value or a value by a table, a value
    moved to another key, an unknown key added."""
    rng = random.Random(12)
    for _ in range(500):
        data = json.loads(json.dumps(BASE))
        for _ in range(rng.randint(1, 3)):
            tables = [data]
            table = data
            while isinstance(table, dict) and table and rng.random() < 0.7:
                name = rng.choice(list(table))
                if not isinstance(table[name], dict):
                    break
                table = table[name]
                tables.append(table)
            if not table:
                continue
            name = rng.choice(list(table))
            action = rng.randrange(6)
            if action == 0:
                del table[name]
            elif action == 1:
                table[name + rng.choice(["x", "_", "s"])] = table.pop(name)
            elif action == 2:
                table[name.replace("t", "ｔ", 1) if "t" in name else name.upper()] = table.pop(name)
            elif action == 3:
                table[name] = rng.choice(HOSTILE)
            elif action == 4:
                table[name] = {"nested": table[name]}
            else:
                table[rng.choice(KEYS).rpartition(".")[2]] = rng.choice(HOSTILE)
        accept_or_refuse(data, KEYS)


def test_random_toml_text(tmp_path):
    """300 character-level mutations of the scene file (deletions, insertions of TOML
    punctuation, bytes that are not UTF-8, duplicated lines) read through load_scene: a TOML
    error is one line naming the file; a file that parses is a scene or a refusal."""
    rng = random.Random(7)
    text = SCENE.read_bytes()
    alphabet = [c.encode() for c in '[]="{},.#\n\t \\'] + [b"\xff", b"\xc3", b"\x00", b"1e999"]
    path = tmp_path / "scene.toml"
    for _ in range(300):
        data = bytearray(text)
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(data))
            kind = rng.randrange(3)
            if kind == 0:
                del data[i : i + rng.randint(1, 20)]
            elif kind == 1:
                data[i:i] = rng.choice(alphabet)
            else:
                end = data.find(b"\n", i)
                line = data[data.rfind(b"\n", 0, i) + 1 : end + 1]
                data[end + 1 : end + 1] = line
        path.write_bytes(bytes(data))
        try:
            data_dict = read_toml(path)
        except SceneError as exc:
            assert str(exc).startswith(str(path)) and "\n" not in str(exc)
            continue
        accept_or_refuse(data_dict, KEYS)


@pytest.mark.parametrize(
    "argv",
    [
        ["validate"],
        ["validate", "/nonexistent.toml"],
        ["validate", str(SCENE), "--set"],
        ["validate", str(SCENE), "--set", "="],
        ["validate", str(SCENE), "--set", "time.step"],
        ["validate", str(SCENE), "--set", "time=1"],
        ["validate", str(SCENE), "--set", "time.step.x=1"],
        ["validate", str(SCENE), "--set", "parameters.a.b=1"],
        ["validate", str(SCENE), "--set", "rod.section={a=1}"],
        ["validate", str(SCENE), "--set", "time.step=[1,2"],
        ["validate", str(SCENE), "--set", "time.end=1e999"],
        ["validate", str(SCENE), "--set", "time.end=-0"],
        ["run", "--restart"],
        ["run", "--restart", "/nonexistent"],
        ["run", str(SCENE), "--restart", "/nonexistent"],
        ["run"],
        ["modes", str(SCENE), "--count", "0"],
        ["modes", str(SCENE), "--count", "-3"],
        ["modes", str(SCENE), "--count", "1e3"],
        ["modes", str(SCENE), "--about", "sideways"],
        ["plot", "/nonexistent"],
        ["render", str(SCENE)],
        ["bogus"],
        ["run", str(SCENE), "--bogus"],
    ],
)
def test_bad_command_lines(argv, capsys):
    """Each refused with exit status 2 and one line on stderr (argparse's own errors too),
    before any work."""
    try:
        status = main(argv)
    except SystemExit as exit_:
        status = exit_.code
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith("cosserat-fem: error: "), err


# ------------------------------------------------------- special files and deep nesting
class Reader:
    """A writer that lets go, after ``after`` seconds, a reader blocked on the FIFO ``path``
    (the defect: open() of a FIFO waits for a writer for ever), so that a test of it fails
    instead of hanging; a no-op when nothing reads (a writer's non-blocking open then fails
    with ENXIO). ``released``: a reader had the FIFO open after ``after`` seconds (it waited:
    a fact, unlike a wall time, that a busy machine does not change)."""

    def __init__(self, path: Path, after: float = 5.0):
        import threading

        self.path, self.after, self.stop = path, after, threading.Event()
        self.released = False
        self.thread = threading.Thread(target=self._release, daemon=True)
        self.thread.start()

    def _release(self) -> None:
        import contextlib
        import os

        if self.stop.wait(self.after):
            return
        with contextlib.suppress(OSError):
            fd = os.open(self.path, os.O_WRONLY | os.O_NONBLOCK)
            self.released = True
            os.write(fd, b'title = "from the FIFO"\n')
            os.close(fd)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


def sweep_of(folder: Path, scene: str | Path) -> Path:
    """A sweep file of one member whose base scene is ``scene``."""
    path = folder / "sweep.toml"
    path.write_text(
        f'[sweep]\nscene = "{scene}"\n[sweep.vary]\n"time.step" = [1e-5]\n', encoding="utf-8"
    )
    return path


@pytest.mark.parametrize("case", ["scene", "run", "sweep", "sweep.scene"])
def test_a_fifo_given_as_input_is_refused_at_once(tmp_path, capsys, case):
    """A FIFO as the scene (validate, run), the sweep file or the sweep's base scene: refused
    in one line naming the file and what it is, without opening it (before: open() waited for
    a writer for ever; here a writer lets it go after 5 s, which fails the test instead)."""
    import os

    fifo = tmp_path / "input.toml"
    os.mkfifo(fifo)
    command = {"scene": "validate", "run": "run", "sweep": "sweep", "sweep.scene": "sweep"}[case]
    given = sweep_of(tmp_path, fifo) if case == "sweep.scene" else fifo
    reader = Reader(fifo)
    try:
        status = main([command, str(given), "--out", str(tmp_path / "out")])
    finally:
        reader.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert not reader.released
    assert status == 2 and len(err) == 1, err
    assert (
        err[0].startswith(f"cosserat-fem: error: {fifo}: ")
        and "is a FIFO, not a regular file" in err[0]
    ), err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["validate", "sweep"])
def test_dev_zero_given_as_input_is_refused_unread(command):
    """/dev/zero as the scene or the sweep file: refused as a character device, unread
    (before: read without bound, a MemoryError after 3 GB and ~30 s here). The process's
    address space is limited to 2 GiB so that the defect fails the test, not the machine."""
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    proc = subprocess.run(
        [PYTHON, "-m", "cosserat_fem.cli", command, "/dev/zero"],
        cwd=ROOT,
        env=subprocess_env(),
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=limit,
    )
    kind = "scene" if command == "validate" else "sweep"
    assert proc.returncode == 2, proc.stderr
    assert (
        proc.stderr == f"cosserat-fem: error: /dev/zero: {kind} file is a character device, "
        "not a regular file\n"
    )


def nested(depth: int, inner: str = "1") -> str:
    """A TOML value nested ``depth`` lists deep."""
    return "[" * depth + inner + "]" * depth


@pytest.mark.parametrize(
    ("text", "where"),
    [
        (f"a = {nested(2000)}\n", ""),  # the TOML reader's recursion
        ("[" + ".".join(["a"] * 5000) + "]\n", "a.a.a"),  # 5000 tables, no recursion in it
        (f"a = {nested(40)}\n", ""),  # within Python's stack, deeper than any scene
        ("x = " + "{y = " * 40 + "1" + "}" * 40 + "\n", "x.y.y"),  # inline tables
    ],
    ids=["2000 lists", "5000 tables", "40 lists", "40 inline tables"],
)
def test_deep_nesting_is_refused_in_one_line(tmp_path, capsys, text, where):
    """Tables and lists nested deeper than schema.MAX_DEPTH (32; a scene needs 3, a sweep
    5) in a scene file, a sweep file and a base scene: one line naming the file (and the
    tables on the way), exit 2 (before: RecursionError, an internal error, or a scene
    error from a RecursionError deep inside)."""
    path = tmp_path / "deep.toml"
    path.write_text(text, encoding="utf-8")
    for argv in (
        ["validate", str(path)],
        ["sweep", str(path)],
        ["sweep", str(sweep_of(tmp_path, path))],
    ):
        assert main([*argv, "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"cosserat-fem: error: {path}: {where}"), err
        assert err[0].endswith("nested deeper than 32 levels of tables and lists"), err


@pytest.mark.parametrize("depth", [40, 2000])
def test_deep_nesting_in_overrides_and_dicts_is_refused(capsys, depth):
    """The same through ``--set`` (a TOML value) and the Python API (cf.load of a dict, an
    override given as a mapping): a SceneError naming the key, or the scene's source."""
    from cosserat_fem import api

    assert main(["validate", str(SCENE), "--set", f"time.end={nested(depth)}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "cosserat-fem: error: time.end: nested deeper than 32 levels of tables and lists"
    ]
    value: list = []
    for _ in range(depth):
        value = [value]
    with pytest.raises(SceneError, match=r"^time\.end: nested deeper than 32 levels"):
        api.load(SCENE, {"time.end": value})
    with pytest.raises(SceneError, match=r"^<dict>: title: nested deeper than 32 levels"):
        api.load({**BASE, "title": value})


# ------------------------------------------------------------------------ damaged restarts
RESTART = ["--set", "time.end=0.0045"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A completed run of 100 steps (checkpoints every 10) and the uninterrupted run of 150
    steps that its restart must reproduce byte for byte."""
    root = tmp_path_factory.mktemp("restart-fuzz")
    for name, end in (("base", "0.003"), ("whole", "0.0045")):
        assert (
            main(
                [
                    "run",
                    str(SCENE),
                    "--out",
                    str(root / name),
                    "--quiet",
                    "--set",
                    f"time.end={end}",
                ]
            )
            == 0
        )
    return root / "base", root / "whole"


def _files(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _damage(rng: random.Random, folder: Path) -> str:
    """Damage one file of a run folder at random; what was done."""
    targets = [
        "checkpoint/checkpoint.json",
        "checkpoint/state0.rank0.npz",
        "checkpoint/state1.rank0.npz",
        "probes.csv",
        "summary.json",
        "solution.xdmf",
    ]
    name = rng.choice(targets)
    path = folder / name
    data = bytearray(path.read_bytes())
    kind = rng.randrange(5)
    if kind == 0 and data:
        del data[rng.randrange(len(data)) :]
        what = "truncated"
    elif kind == 1 and data:
        i = rng.randrange(len(data))
        data[i] ^= 1 << rng.randrange(8)
        what = f"bit flipped at {i}"
    elif kind == 2:
        data = bytearray(rng.randbytes(rng.randint(0, 300)))
        what = "random bytes"
    elif kind == 3:
        path.unlink()
        return f"{name} deleted"
    else:
        text = data.decode("utf-8", "replace")
        i = rng.randrange(len(text) + 1)
        data = bytearray((text[:i] + rng.choice(string.printable) + text[i:]).encode())
        what = "a character inserted"
    path.write_bytes(bytes(data))
    return f"{name} {what}"


def _restart_damaged_copies(runs, tmp_path: Path, seed: int, count: int, restart) -> dict:
    """``count`` copies of the base run, each with one file damaged (:func:`_damage`), each
    continued by ``restart(folder)``: None if it continued, else its one-line refusal. A
    refusal names no internal error and leaves every file as it was; a continuation gives the
    uninterrupted run's probes byte for byte. The outcomes, counted."""
    base, whole = runs
    expected = (whole / "probes.csv").read_bytes()
    rng = random.Random(seed)
    outcomes = {"refused": 0, "continued": 0}
    for i in range(count):
        folder = Path(shutil.copytree(base, tmp_path / f"case{i}"))
        what = _damage(rng, folder)
        before = _files(folder)
        refusal = restart(folder)
        if refusal is None:
            outcomes["continued"] += 1
            assert (folder / "probes.csv").read_bytes() == expected, what
        else:
            outcomes["refused"] += 1
            assert "\n" not in refusal, (what, refusal)
            assert "internal error" not in refusal and "Traceback" not in refusal, (what, refusal)
            assert _files(folder) == before, what
        shutil.rmtree(folder)
    print(outcomes)
    return outcomes


def test_damaged_run_folders_restart_exactly_or_not_at_all(runs, tmp_path, capsys):
    """40 run folders, each with one file damaged at random (truncation, a flipped bit,
    random bytes, deletion, an inserted character: the index, either state slot, probes.csv,
    summary.json, solution.xdmf). The restart either refuses with exit 2, one line, and
    every file as it was, or continues, and then its probes are those of the uninterrupted
    run byte for byte (a damaged newest state slot falls back to the previous checkpoint,
    which the bit-exact restart also brings to the same bytes). The HDF5 files are not
    damaged here: frames already written are the reader's business (test_output_fuzz)."""

    def restart(folder: Path) -> str | None:
        capsys.readouterr()
        status = main(["run", "--restart", str(folder), "--quiet", *RESTART])
        err = capsys.readouterr().err.strip().splitlines()
        if status == 0:
            return None
        assert status == 2 and len(err) == 1, err
        return err[0]

    outcomes = _restart_damaged_copies(runs, tmp_path, 2024, 40, restart)
    assert outcomes["refused"] >= 10 and outcomes["continued"] >= 1, outcomes


# ---------------------------------------------------------------- tables of loads (data)
#: Malformed table files, each a component of loads.end.force (key loads.end.force[1]) with
#: the words its one-line refusal must hold.
BAD_TABLES = [
    (b"", {}, "holds no header line"),
    (b"# only a comment\n\n", {}, "holds no header line"),
    (b"t, F\n", {}, "a header but no rows"),
    (b"x, F\n0, 1\n1, 2\n", {}, "needs a column t"),
    (b"t, F, F\n0, 1, 2\n", {}, "names column 'F' twice"),
    (b"t, , F\n0, 1, 2\n", {}, "column 2 of the header has no name"),
    (b"0, 1\n1, 2\n", {}, "must name the columns"),
    (b"t, F\n0, 1\n1\n", {}, "line 3: 1 values, the header names 2"),
    (b"t, F\n0, 1\n1, abc\n", {}, "line 3: column F: not a number"),
    (b"t, F\n0, nan\n1, 2\n", {}, "line 2: column F: not a finite number"),
    (b"t, F\n0, 1\n1, -inf\n", {}, "line 3: column F: not a finite number"),
    (b"t, F\n0, 1\n1e999, 2\n", {}, "line 3: column t: not a finite number"),
    (b"t, F\n0, 1\n2, 2\n1, 3\n", {}, "line 4: t = 1.0 does not increase"),
    (b"t, F\n0, 1\n0, 2\n1, 3\n", {}, "line 3: t = 0.0 does not increase"),
    (b"t, F\n0, 1\n1, 2\n2, 3\n", {"interpolation": "cubic"}, "3 rows; interpolation"),
    (b"t, F\n0, 1\n", {}, '1 rows; interpolation "linear" needs at least 2'),
    (b"t, F\n0, \xff\n", {}, "is not UTF-8 text"),
    (b"t, F\n0, 1\n1, 2\n", {"column": "G"}, ".column: "),
    (b"t, F\n0, 1\n1, 2\n", {"column": "t"}, 'has no value column "t"'),
    (b"t, s, F\n0, 0, 1\n0, 1, 1\n1, 0, 1\n", {}, "not a full grid"),
    (b"t, s, F\n0, 1, 1\n0, 0, 1\n1, 1, 1\n1, 0, 1\n", {}, "line 3: s = 0.0 does not increase"),
    (b"t, s, F\n0, 0, 1\n0, 1, 1\n1, 0, 1\n1, 2, 1\n", {}, "line 5: not a full grid"),
    (b"t, s, F\n1, 0, 1\n1, 1, 1\n0, 0, 1\n0, 1, 1\n", {}, "line 4: t = 0.0 is before"),
    (b"t, s, F\n0, 0, 1\n0, 1, 1\n1, 0, 1\n1, 1, 1\n", {}, "not on the arc length s"),
    (b"t, F\n0, 1\n1e-3, 2\n", {}, "covers t in [0, 0.001] s, the scene needs [0, 0.06] s"),
    (b"t, F\n0, 1\n1, 2\n", {"sha256": "0" * 64}, ".sha256: "),
    (b"t, F\n0, 1\n1, 2\n", {"colum": "F"}, "colum: unknown key (did you mean"),
    (b"t, F\n0, 1\n1, 2\n", {"interpolation": "cubik"}, '(did you mean "cubic"?)'),
    (b"t, F\n0, 1\n1, 2\n", {"outside": "never"}, "outside: must be one of"),
    (b"t, F\n0, 1\n1, 2\n", {"column": ""}, "column: must be a non-empty string"),
    (b"t, F\n0, 1\n1, 2\n", {"table": 1}, "table: must be a non-empty string"),
]


def _table_scene(
    tmp_path: Path, content: bytes | None, spec: dict, key: str = "loads.end.force", index: int = 1
) -> list[str]:
    """validate's argv for the paper's scene (in tmp_path) with a table component at
    ``key[index]``: ``content`` written to t.csv (None: the spec's own table)."""
    scene = tmp_path / "scene.toml"
    if not scene.exists():
        shutil.copy(SCENE, scene)
    if content is not None:
        (tmp_path / "t.csv").write_bytes(content)
    entries = {"table": "t.csv", "column": "F", **spec}
    inline = "{" + ", ".join(f"{k} = {json.dumps(v)}" for k, v in entries.items()) + "}"
    vector = ["0", "0", "0"]
    vector[index] = inline
    return ["validate", str(scene), "--set", f"{key}=[{', '.join(vector)}]"]


def _refused(argv: list[str], capsys) -> str:
    """The one stderr line of a refusal with exit status 2."""
    capsys.readouterr()
    status = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, (argv, status, err)
    assert "internal error" not in err[0] and "Traceback" not in err[0], err
    return err[0].removeprefix("cosserat-fem: error: ")


@pytest.mark.parametrize("content, spec, words", BAD_TABLES)
def test_malformed_tables_are_refused_in_one_line(tmp_path, capsys, content, spec, words):
    """Each malformed table (cosserat_fem/scene/load_data.py: header, rows, numbers, monotone t, a
    full grid, rows enough for the interpolation, the span the scene needs, the content the
    scene pins, the inline table's keys) is refused by validate with exit 2 and one line that
    names the component's key and says what is wrong (and where: the line of the file)."""
    line = _refused(_table_scene(tmp_path, content, spec), capsys)
    assert line.startswith("loads.end.force[1]"), line
    assert words in line, line


def test_tables_that_are_not_regular_files_or_too_large_are_refused(tmp_path, capsys):
    """A missing file, a directory, a FIFO (which would block a reader waiting for a writer:
    opened without blocking, and refused), a link to one, /dev/zero (endless) and a file
    beyond the 16 MiB limit (sparse: refused from its size, unread): one line each."""
    import os

    from cosserat_fem.scene.load_data import MAX_TABLE_BYTES

    (tmp_path / "dir").mkdir()
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "link").symlink_to(tmp_path / "fifo")
    with open(tmp_path / "big.csv", "wb") as stream:
        stream.truncate(MAX_TABLE_BYTES + 1)
    cases = [
        ("missing.csv", "was not found"),
        ("dir", "is a folder, not a regular file"),
        ("fifo", "is a FIFO, not a regular file"),
        ("link", "is a FIFO, not a regular file"),
        ("/dev/zero", "is a character device, not a regular file"),
        ("big.csv", "holds 16777217 bytes, more than the 16 MiB allowed"),
    ]
    for name, words in cases:
        line = _refused(_table_scene(tmp_path, None, {"table": name}), capsys)
        assert line.startswith("loads.end.force[1].table: ") and words in line, line


def test_tables_where_they_do_not_belong_are_refused(tmp_path, capsys):
    """A table as gravity or an initial field (numbers, expressions of s), a step table or a
    grid as a support's motion, a table whose grid does not cover the rod: one line each,
    naming the key."""
    good = b"t, F\n0, 0\n1, 1\n"
    grid = b"t, s, F\n0, 0, 1\n0, 0.5, 1\n1, 0, 1\n1, 0.5, 1\n"
    cases = [
        (good, {}, "loads.gravity", 0, "loads.gravity[0]: must be a number or an expression"),
        (good, {}, "initial.velocity", 0, "initial.velocity[0]: must be a number or an"),
        (
            good,
            {"interpolation": "previous"},
            "supports.start_motion",
            0,
            'supports.start_motion[0].interpolation: "previous" is not allowed',
        ),
        (grid, {}, "supports.start_motion", 0, "supports.start_motion[0]: table"),
        (
            grid,
            {},
            "loads.force_density",
            0,
            "loads.force_density[0]: table 't.csv' column 'F' (linear) covers s in [0, 0.5] m",
        ),
    ]
    for content, spec, key, index, words in cases:
        line = _refused(_table_scene(tmp_path, content, spec, key, index), capsys)
        assert line.startswith(words), line


def test_a_good_table_is_shown_by_validate(tmp_path, capsys):
    """A table (with a byte-order mark and comments, as spreadsheets and loggers write) is
    accepted; validate shows its keys with the load's unit and what it holds."""
    content = "\ufeff# logged\nt, F\n0, 0\n# a pause\n0.1, 5\n".encode()
    argv = _table_scene(tmp_path, content, {"interpolation": "pchip"})
    capsys.readouterr()
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert 'loads.end.force = ["0", {table = "' in out and '"}, "0"] [N]' in out
    assert 'interpolation = "pchip", outside = "refuse", sha256 = "' in out
    assert "loads.end.force[1] [N]: table " in out and "2 rows, t in [0, 0.1] s" in out


# --------------------------------------------------------------- the Python API's restart
def _differing(a: dict, b: dict, prefix: str = "") -> set[str]:
    """The dotted leaf keys in which two scenes' dicts differ (a key on one side only too)."""
    keys = set()
    for name in {*a, *b}:
        key = f"{prefix}.{name}" if prefix else name
        x, y = a.get(name, KeyError), b.get(name, KeyError)
        if isinstance(x, dict) and isinstance(y, dict) and x and y:
            keys |= _differing(x, y, key)
        elif x != y or isinstance(x, bool) != isinstance(y, bool):
            keys.add(key)
    return keys


def _neighbours(key: str, value) -> list:
    """Valid-looking values near ``value`` (the checkpoint's at ``key``): a number scaled and
    shifted, a flag flipped, the other choices of a choice, a text or expression extended
    (the same function in other words is another scene's text: refused too), a list with
    one element changed."""
    from cosserat_fem.scene.schema import _lookup_spec

    spec = _lookup_spec(key.split("."))
    if isinstance(value, bool):
        return [not value]
    if isinstance(value, int | float):
        return [value * 1.5, value + 1, value / 2] if value else [1, 0.5]
    if isinstance(value, str):
        others = [c for c in getattr(spec, "choices", ()) if c != value]
        return others or [value + "x", f"({value})*1", 1.0]
    if isinstance(value, list) and value:
        head = value[0]
        changed = (
            head + 1
            if isinstance(head, int | float) and not isinstance(head, bool)
            else (f"({head})*2" if isinstance(head, str) else head)
        )
        return [[changed, *value[1:]], value[:-1]]
    return []


#: Values that a key takes only with others (a shape and its keys; an initial field that
#: meets the clamped end): (key, value), and the overrides that go with them.
SHAPED = [
    ("initial.velocity", ["1e-3*s/L", 0, 0]),
    ("initial.displacement", ["1e-4*(s/L)**2", 0, 0]),
    ("reference.shape", "arc"),
]
SHAPED_WITH = {("reference.shape", "arc"): {"reference.radius": 10.0}}


def test_an_api_restart_refuses_every_scene_but_the_checkpoints(runs, tmp_path):
    """cf.run(scene, restart=checkpoint) with the checkpoint's scene changed in every leaf key
    of the schema to each of the HOSTILE values and to values near its own (_neighbours;
    those that make a valid scene at all): a scene that differs from the checkpoint's run in
    a key a restart may not change (cosserat_fem/analysis/restart.py: RESTART_KEYS) is refused
    with a SceneError naming one of those keys; one that differs only in keys it may change
    but whose time.end does not pass the checkpoint (t = 3 ms) names time.end; none touches
    the folder. Those left would continue the run (what they give: the next test)."""
    import cosserat_fem as cf
    from cosserat_fem.analysis.restart import _may_change
    from cosserat_fem.io.checkpoint import load_checkpoint

    base = Path(shutil.copytree(runs[0], tmp_path / "copy"))  # a failure may run into it
    before = _files(base)
    checkpoint = load_checkpoint(base)
    held = checkpoint.meta["scene"]
    later = with_value(held, "time.end", 0.0045)  # a change of one key alone then continues
    outcomes = {"invalid": 0, "refused": 0, "would continue": 0}
    tables: set[str] = set()  # the top-level tables of the keys refused
    for key in KEYS:
        table = later
        for name in key.split(".")[:-1]:
            table = table.get(name, {}) if isinstance(table, dict) else {}
        own = table.get(key.rpartition(".")[2]) if isinstance(table, dict) else None
        extra = [0.003] if key == "time.end" else []  # at the checkpoint
        extra += [v for k, v in SHAPED if k == key]
        for value in [*HOSTILE, *_neighbours(key, own), *extra]:
            try:
                scene = scene_from_dict(
                    with_value(later, key, value), overrides=SHAPED_WITH.get((key, str(value)), ())
                )
            except SceneError:
                outcomes["invalid"] += 1
                continue
            fixed = {
                k
                for k in _differing(json.loads(json.dumps(scene.to_dict())), held)
                if not _may_change(k)
            }
            if not fixed and scene.time.end > checkpoint.time:
                outcomes["would continue"] += 1
                continue
            with pytest.raises(SceneError) as caught:
                cf.run(scene, restart=checkpoint)
            named = str(caught.value).split(":", 1)[0]  # a key, or a key of a table named
            assert any(
                named == k or named.startswith(k + ".") or k.startswith(named + ".")
                for k in fixed or {"time.end"}
            ), (key, value, str(caught.value), fixed)
            outcomes["refused"] += 1
            tables.add(key.split(".")[0])
    assert _files(base) == before
    print(outcomes)
    assert outcomes["refused"] >= 150 and outcomes["would continue"] >= 50, outcomes
    # every kind of key but a [structure] and a [contact] (their nodes, members and obstacles
    # are arrays of tables, which this fuzz does not write; a structure's restart:
    # tests/test_structures.py; a contact run's restart: tests/test_contact.py)
    assert tables == set(SCHEMA.fields) - {"solver", "limits", "structure", "contact"}


@pytest.mark.parametrize(
    ("overrides", "out"),
    [
        ({"time.end": 0.0045}, None),
        ({"time.end": 0.0045, "limits.wall_time": 1e5, "output.checkpoint_interval": 0}, None),
        ({"time.end": 0.0045, "time.max_halvings": 2}, "same"),
        ({"time.end": 0.0045}, "other"),
        ({"time.end": 0.003}, None),  # at the checkpoint
        ({"time.end": 0.0015}, None),  # before it
    ],
)
def test_an_api_restart_continues_exactly_or_refuses(runs, tmp_path, overrides, out):
    """The API's restart of the 100-step run with its own scene and the keys a restart may
    change (time.end after the checkpoint, limits, the checkpoints' interval, max_halvings),
    out= none or the checkpoint's folder: the probes of the uninterrupted 150-step run, byte
    for byte. out= another folder (it was silently ignored), time.end at or before the
    checkpoint: refused by name, and the folder is as it was."""
    import cosserat_fem as cf
    from cosserat_fem.io.checkpoint import load_checkpoint

    base, whole = runs
    folder = Path(shutil.copytree(base, tmp_path / "copy"))
    checkpoint = load_checkpoint(folder)
    scene = scene_from_dict(checkpoint.meta["scene"], overrides=overrides)
    target = {None: None, "same": folder, "other": tmp_path / "other"}[out]
    if out == "other" or overrides["time.end"] <= checkpoint.time:
        before = _files(folder)
        with pytest.raises(SceneError, match="^out: " if out == "other" else "^time.end: "):
            cf.run(scene, target, restart=checkpoint)
        assert _files(folder) == before and not (tmp_path / "other").exists()
        return
    cf.run(scene, target, restart=checkpoint)
    assert (folder / "probes.csv").read_bytes() == (whole / "probes.csv").read_bytes()


def test_damaged_run_folders_through_the_api(runs, tmp_path):
    """20 run folders each with one file damaged at random (as for the command line above),
    continued through the Python API (cf.resume, then cf.run(scene, restart=checkpoint)):
    each either refuses with a one-line SceneError and every file as it was, or continues to
    the uninterrupted run's probes byte for byte."""
    import cosserat_fem as cf

    def restart(folder: Path) -> str | None:
        try:
            scene, checkpoint = cf.resume(folder, {"time.end": 0.0045})
            cf.run(scene, restart=checkpoint)
        except SceneError as exc:
            return str(exc)
        return None

    outcomes = _restart_damaged_copies(runs, tmp_path, 2025, 20, restart)
    assert outcomes["refused"] >= 5 and outcomes["continued"] >= 1, outcomes


# ----------------------------------------------------- run folders with links and special files
#: Names in a run folder (files, folders, scratch names) that a case replaces.
FOLDER_NAMES = [
    "checkpoint/checkpoint.json",
    "checkpoint/state0.rank0.npz",
    "checkpoint/state1.rank0.npz",
    "checkpoint/checkpoint.json.tmp",
    "probes.csv",
    "summary.json",
    "summary.json.tmp",
    "solution.xdmf",
    "solution.xdmf-partial",
    "solution.frames/mesh.h5",
    "solution.frames/000003.h5",
    "solution.frames/000099.h5",
    ".cosserat-fem.lock",
    "checkpoint",
    "solution.frames",
]
#: What a case puts at a name: a FIFO, a symbolic or hard link to the same name in a copy
#: outside the folder (the copy must stay as it was), a link to /dev/zero, a dangling link.
LINK_KINDS = ("fifo", "symlink", "hardlink", "dev-zero", "dangling")


def _plant(rng: random.Random, folder: Path, outside: Path) -> str:
    """Replace one name of ``folder`` at random by a special file or a link; what was done."""
    name, kind = rng.choice(FOLDER_NAMES), rng.choice(LINK_KINDS)
    path, there = folder / name, outside / name
    if path.parent.is_symlink() or not path.parent.is_dir():  # replaced by an earlier damage
        return f"{name} left (its folder was replaced)"
    if kind == "hardlink" and not there.is_file():
        kind = "symlink"
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "symlink":
        path.symlink_to(there)
    elif kind == "hardlink":
        os.link(there, path)
    elif kind == "dev-zero":
        path.symlink_to("/dev/zero")
    else:
        path.symlink_to(folder / "nothing-here")
    return f"{name} as {kind}"


def _tree(folder: Path) -> dict[str, str]:
    """conftest.folder_tree but the lock file, which any writer, even one refused, takes over
    (a link or FIFO there is replaced, cosserat_fem/io/run_folder.py)."""
    return folder_tree(folder, skip=(".cosserat-fem.lock",))


# Long set (make test within 3 minutes): make test keeps test_run_folders' link and FIFO cases.
@pytest.mark.long
def test_run_folders_with_links_and_special_files(runs, tmp_path, capsys):
    """30 copies of a run's folder, each with one to three names (files, scratch names, the
    checkpoint and frames folders, the lock file) replaced at random by a FIFO, a symbolic or
    hard link to the same name in a copy outside the folder, a link to /dev/zero or one to
    nothing; then ``run --restart`` (20 cases) or a new ``run`` (10). Nothing may hang (60 s,
    against ~1 s), the copy outside must stay byte for byte as it was, and each command either
    refuses with exit 2, one line and the folder as it was, or goes on: a restart to the
    uninterrupted run's probes byte for byte, a new run to exit 0."""
    base, whole = runs
    expected = (whole / "probes.csv").read_bytes()
    outside = Path(shutil.copytree(base, tmp_path / "outside", symlinks=True))
    there = _tree(outside)
    rng = random.Random(2512)
    outcomes: dict[str, int] = {}
    for i in range(30):
        folder = Path(shutil.copytree(base, tmp_path / f"case{i}", symlinks=True))
        what = "; ".join(_plant(rng, folder, outside) for _ in range(rng.randint(1, 3)))
        before = _tree(folder)
        restart = i < 20
        args = (
            ["run", "--restart", str(folder), *RESTART]
            if restart
            else ["run", str(SCENE), "--out", str(folder), "--set", "time.end=0.0003"]
        )
        capsys.readouterr()
        with fails_if_hung(60, what):
            status = main([*args, "--quiet"])
        err = capsys.readouterr().err.strip().splitlines()
        assert _tree(outside) == there, what
        key = f"{'restart' if restart else 'new run'} {'refused' if status else 'went on'}"
        outcomes[key] = outcomes.get(key, 0) + 1
        if status == 0:
            if restart:
                assert (folder / "probes.csv").read_bytes() == expected, what
        else:
            assert status == 2 and len(err) == 1, (what, err)
            assert "internal error" not in err[0] and "Traceback" not in err[0], (what, err)
            assert _tree(folder) == before, what
        shutil.rmtree(folder)
    print(outcomes)
    assert outcomes.get("restart refused", 0) >= 3 and outcomes.get("restart went on", 0) >= 3
    assert outcomes.get("new run went on", 0) >= 3, outcomes
