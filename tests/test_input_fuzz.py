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
from pathlib import Path

import pytest
from conftest import ROOT, fails_if_hung, folder_tree

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
    (a link or FIFO there is replaced, cosserat_fem/run_folder.py)."""
    return folder_tree(folder, skip=(".cosserat-fem.lock",))


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
        args = (["run", "--restart", str(folder), *RESTART] if restart else
                ["run", str(SCENE), "--out", str(folder), "--set", "time.end=0.0003"])
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
