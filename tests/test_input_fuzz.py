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
import random
import shutil
import string
import subprocess
from pathlib import Path

import pytest
from conftest import PYTHON, ROOT, subprocess_env

from cosserat_fem import budget
from cosserat_fem.cli import main
from cosserat_fem.describe import describe_scene
from cosserat_fem.errors import SceneError
from cosserat_fem.scene import read_toml, scene_from_dict
from cosserat_fem.schema import SCHEMA

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
    with ENXIO)."""

    def __init__(self, path: Path, after: float = 5.0):
        import threading

        self.path, self.after, self.stop = path, after, threading.Event()
        self.thread = threading.Thread(target=self._release, daemon=True)
        self.thread.start()

    def _release(self) -> None:
        import contextlib
        import os

        if self.stop.wait(self.after):
            return
        with contextlib.suppress(OSError):
            fd = os.open(self.path, os.O_WRONLY | os.O_NONBLOCK)
            os.write(fd, b'title = "from the FIFO"\n')
            os.close(fd)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


def sweep_of(folder: Path, scene: str | Path) -> Path:
    """A sweep file of one member whose base scene is ``scene``."""
    path = folder / "sweep.toml"
    path.write_text(f'[sweep]\nscene = "{scene}"\n[sweep.vary]\n"time.step" = [1e-5]\n',
                    encoding="utf-8")  # fmt: skip
    return path


@pytest.mark.parametrize("case", ["scene", "run", "sweep", "sweep.scene"])
def test_a_fifo_given_as_input_is_refused_at_once(tmp_path, capsys, case):
    """A FIFO as the scene (validate, run), the sweep file or the sweep's base scene: refused
    in one line naming the file and what it is, at once (before: open() waited for a writer
    for ever; here a writer lets it go after 5 s, which fails the test instead)."""
    import os
    import time

    fifo = tmp_path / "input.toml"
    os.mkfifo(fifo)
    command = {"scene": "validate", "run": "run", "sweep": "sweep", "sweep.scene": "sweep"}[case]
    given = sweep_of(tmp_path, fifo) if case == "sweep.scene" else fifo
    reader, start = Reader(fifo), time.monotonic()
    try:
        status = main([command, str(given), "--out", str(tmp_path / "out")])
    finally:
        reader.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert time.monotonic() - start < 5.0
    assert status == 2 and len(err) == 1, err
    assert err[0].startswith(f"cosserat-fem: error: {fifo}: ") and "is a FIFO, not a regular " \
        "file" in err[0], err  # fmt: skip
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["validate", "sweep"])
def test_dev_zero_given_as_input_is_refused_unread(command):
    """/dev/zero as the scene or the sweep file: refused as a character device, unread
    (before: read without bound, a MemoryError after 3 GB and ~30 s here). The process's
    address space is limited to 2 GiB so that the defect fails the test, not the machine."""
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    proc = subprocess.run([PYTHON, "-m", "cosserat_fem.cli", command, "/dev/zero"], cwd=ROOT,
                          env=subprocess_env(), capture_output=True, text=True, timeout=120,
                          preexec_fn=limit)  # fmt: skip
    kind = "scene" if command == "validate" else "sweep"
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == f"cosserat-fem: error: /dev/zero: {kind} file is a character device, " \
        "not a regular file\n"  # fmt: skip


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
    for argv in (["validate", str(path)], ["sweep", str(path)],
                 ["sweep", str(sweep_of(tmp_path, path))]):  # fmt: skip
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
    assert err == ["cosserat-fem: error: time.end: nested deeper than 32 levels of tables and "
                   "lists"]  # fmt: skip
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
        assert main(["run", str(SCENE), "--out", str(root / name), "--quiet",
                     "--set", f"time.end={end}"]) == 0  # fmt: skip
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


def test_damaged_run_folders_restart_exactly_or_not_at_all(runs, tmp_path, capsys):
    """40 run folders, each with one file damaged at random (truncation, a flipped bit,
    random bytes, deletion, an inserted character: the index, either state slot, probes.csv,
    summary.json, solution.xdmf). The restart either refuses with exit 2, one line, and
    every file as it was, or continues, and then its probes are those of the uninterrupted
    run byte for byte (a damaged newest state slot falls back to the previous checkpoint,
    which the bit-exact restart also brings to the same bytes). The HDF5 files are not
    damaged here: frames already written are the reader's business (test_output_fuzz)."""
    base, whole = runs
    expected = (whole / "probes.csv").read_bytes()
    rng = random.Random(2024)
    outcomes = {"refused": 0, "continued": 0}
    for i in range(40):
        folder = Path(shutil.copytree(base, tmp_path / f"case{i}"))
        what = _damage(rng, folder)
        before = _files(folder)
        capsys.readouterr()
        status = main(["run", "--restart", str(folder), "--quiet", *RESTART])
        err = capsys.readouterr().err.strip().splitlines()
        if status == 0:
            outcomes["continued"] += 1
            assert (folder / "probes.csv").read_bytes() == expected, what
        else:
            outcomes["refused"] += 1
            assert status == 2 and len(err) == 1, (what, err)
            assert "internal error" not in err[0] and "Traceback" not in err[0], (what, err)
            assert _files(folder) == before, what
        shutil.rmtree(folder)
    print(outcomes)
    assert outcomes["refused"] >= 10 and outcomes["continued"] >= 1, outcomes
