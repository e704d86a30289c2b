"""The scene schema: every key of a scene file, its type, range, unit and default, and the
validation of a scene's raw data against it, ``--set`` overrides and TOML reading.

:data:`SCHEMA` is the table of tables, derived from the resolved scene's dataclasses
(cosserat_fem/scene/resolved.py), on whose fields each key is declared once
(cosserat_fem/scene/keys.py: :func:`~cosserat_fem.scene.keys.key`); its leaves (:class:`Number`,
:class:`Choice`, ...) check one value each. :func:`check_scene` validates a scene's data
(unknown keys get a "did you mean"), every problem a single
:class:`~cosserat_fem.common.errors.SceneError` whose message starts with the dotted key at fault,
states what is allowed and shows the offending value. The resolved scene is
cosserat_fem/scene/resolved.py, building it cosserat_fem/scene/build.py.

Overrides: the value is read as a TOML value if possible (``1e-5``, ``true``, ``"bdf2"``,
``[0, 0, "1e3*t"]``), else taken as a bare string (``time.integrator=bdf2``); ``--unset KEY``
(:class:`Removal`, :data:`UNSET` in a mapping) removes a key or a table. Overriding one of
``rod.material.poisson_ratio`` / ``rod.material.shear_modulus`` removes the other, so that
either can be set from the command line whichever the file gives.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from cosserat_fem.common.errors import SceneError, show_value
from cosserat_fem.common.safe_files import Unreadable, read_on_root
from cosserat_fem.scene.keys import (  # noqa: F401 - the names other modules read from here
    LOAD_TABLE,
    MAX_DEPTH,
    MAX_INPUT_BYTES,
    PETSC_PREFIX,
    XDMF_DEFAULT_FIELDS,
    XDMF_FIELDS,
    Field,
    Number,
    Parameters,
    PetscOptions,
    Table,
    Text,
    check_table,
    join_key,
    leaf_paths,
    unknown_key,
)
from cosserat_fem.scene.resolved import Scene

_EXCLUSIVE = ("rod.material.poisson_ratio", "rod.material.shear_modulus")

#: The scene schema (nested tables; leaves carry type, range, unit and default), derived from
#: the resolved scene whose fields declare the keys.
SCHEMA = Table.of(Scene)


# ================================================================================= overrides
def _lookup_spec(path: list[str]) -> Any:
    """The schema entry at a dotted path (``parameters.X`` accepted); SceneError if unknown."""
    spec: Any = SCHEMA
    for depth, name in enumerate(path):
        key = ".".join(path[: depth + 1])
        if isinstance(spec, Parameters):
            if depth != len(path) - 1:
                raise SceneError(f"{key}: parameters are numbers, not tables")
            return Number()
        if isinstance(spec, PetscOptions):
            if depth != len(path) - 1:
                raise SceneError(f"{key}: a PETSc option's value is not a table")
            return Text()
        if not isinstance(spec, Table):
            raise SceneError(f"{key}: unknown key; {'.'.join(path[:depth])} is not a table")
        if name not in spec.fields:
            raise unknown_key(key, list(spec.fields), SCHEMA)
        spec = spec.fields[name]
    return spec


#: what :func:`default_of` gives for a key without a default
NO_DEFAULT = object()


def default_of(key: str) -> Any:
    """The schema's default of the dotted leaf ``key`` as a scene's table writes it, or
    NO_DEFAULT (a required key, one without a default, a table, a key the schema does not
    know). A key added to the schema keeps the old
    behaviour at its default: what a checkpoint or a scene written before it ran as."""
    try:
        spec = _lookup_spec(key.split("."))
    except SceneError:
        return NO_DEFAULT
    if not isinstance(spec, Field) or spec.required or spec.default is None:
        return NO_DEFAULT
    return spec.to_value(spec.default)  # as a scene's table writes it


def _override_value(key: str, text: str) -> Any:
    """A TOML value if ``text`` parses as one, else the bare string; SceneError naming
    ``key`` if it nests too deep for the TOML reader."""
    try:
        document = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:
        raise SceneError(
            f"{key}: nested deeper than {MAX_DEPTH} levels of tables and lists"
        ) from None
    return document["v"] if list(document) == ["v"] else text


Overrides = Sequence[str] | Mapping[str, Any]


class Removal(str):
    """An override that removes its key, the command line's ``--unset KEY``: the key itself, a
    ``str``, so that a list of overrides stays a list of strings, in the order given."""


class _Unset:
    def __repr__(self) -> str:
        return "UNSET"


#: The value that removes a key in a mapping of overrides (``{"rod.section.a": UNSET}``, the
#: Python API's ``cf.UNSET``), as a :class:`Removal` does in a list.
UNSET = _Unset()


def remove_key(data: dict[str, Any], key: str) -> None:
    """Remove the dotted ``key``, a value or a whole table, from ``data`` (the overrides'
    ``--unset KEY`` and :data:`UNSET`): so that a table can change its shape from the command
    line (``--unset rod.section.a --unset rod.section.b --set rod.section.shape=circle``) and a
    default or an absent table be had again. SceneError for a key the schema does not have
    (with a did-you-mean) or the scene does not hold: nothing is removed silently."""
    path = [part.strip() for part in key.split(".")]
    _lookup_spec(path)
    table: Any = data
    for name in path[:-1]:
        table = table.get(name) if isinstance(table, dict) else None
    if not isinstance(table, dict) or path[-1] not in table:
        raise SceneError(f"{key}: not in the scene, nothing to remove (--unset)")
    del table[path[-1]]


def apply_overrides(data: dict[str, Any], overrides: Overrides) -> dict[str, Any]:
    """Return a copy of ``data`` with the overrides applied in order: ``dotted.key=value``
    strings (the command line's ``--set``; the value read as TOML) and :class:`Removal` overrides
    (``--unset``), or a mapping of dotted keys to values (the Python API; :data:`UNSET`
    removes a key)."""
    result = _copy_tables(data)
    items = overrides.items() if isinstance(overrides, Mapping) else map(_split, overrides)
    for key, value in items:
        key = str(key).strip()
        if value is UNSET:
            remove_key(result, key)
            continue
        path = [part.strip() for part in key.split(".")]
        spec = _lookup_spec(path)
        check_depth(value, key, len(path) + 1)
        if isinstance(spec, Table | Parameters):
            raise SceneError(f"{key}: is a table; set one of its keys instead (--set {key}.X=...)")
        _set_path(result, path, value)
        if key in _EXCLUSIVE:
            other = _EXCLUSIVE[1 - _EXCLUSIVE.index(key)]
            _table_at(result, path[:-1]).pop(other.rpartition(".")[2], None)
    return result


def _split(text: str) -> tuple[str, Any]:
    """(key, value) of a ``dotted.key=value`` override, (key, UNSET) of a :class:`Removal`."""
    if isinstance(text, Removal):
        return str(text), UNSET
    raw_key, sep, raw_value = text.partition("=")
    if not sep or not raw_key.strip():
        raise SceneError(f"--set {text!r}: expected dotted.key=value")
    return raw_key.strip(), _override_value(raw_key.strip(), raw_value.strip())


def _copy_tables(data: Any) -> Any:
    """Copy nested dicts (values shared otherwise)."""
    return {k: _copy_tables(v) for k, v in data.items()} if isinstance(data, dict) else data


def _table_at(data: dict[str, Any], path: list[str]) -> dict[str, Any]:
    """The table at ``path``, created if absent; SceneError if something else is there."""
    table = data
    for depth, name in enumerate(path):
        table = table.setdefault(name, {})
        if not isinstance(table, dict):
            key = ".".join(path[: depth + 1])
            raise SceneError(f"{key}: must be a table, got {show_value(table)}")
    return table


def _set_path(data: dict[str, Any], path: list[str], value: Any) -> None:
    _table_at(data, path[:-1])[path[-1]] = value


def read_input(
    path: str | Path, what: str = "scene file", comm=None, same_name: bool = True
) -> bytes:
    """The bytes of the input file ``path`` (a scene or a sweep file), read once: rank 0 of
    ``comm`` (default MPI's world) reads it and every rank gets its bytes, so that every rank
    parses the same input (a file edited while the job starts, or a copy per node, cannot
    give the ranks different scenes). Collective. SceneError on every rank if the ranks name
    different files (unless not ``same_name``: a name made from rank 0's input, which may
    resolve otherwise on another rank), or if the file is not a regular file of at most
    :data:`MAX_INPUT_BYTES` (a FIFO, ``/dev/zero``: cosserat_fem/common/safe_files.py)."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD if comm is None else comm
    name = str(path)
    if comm.size > 1 and same_name:
        names = comm.allgather(name)
        other = next((r for r, n in enumerate(names) if n != names[0]), None)
        if other is not None:
            raise SceneError(
                f"{names[0]}: the MPI ranks name different {what}s (rank "
                f"{other}: {names[other]!r}); give every rank the same file"
            )
    try:
        return read_on_root(path, MAX_INPUT_BYTES, comm)
    except Unreadable as exc:
        raise SceneError(f"{name}: {what} {exc}") from None


def parse_toml(raw: bytes, path: str | Path) -> dict[str, Any]:
    """The TOML document ``raw`` (the content of ``path``); every failure (not UTF-8,
    malformed, nested deeper than :data:`MAX_DEPTH`) is a SceneError naming ``path``."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: malformed TOML: {exc}") from None
    except RecursionError:
        raise SceneError(
            f"{path}: nested deeper than {MAX_DEPTH} levels of tables and lists"
        ) from None
    check_depth(data, str(path))
    return data


def read_toml(path: str | Path, what: str = "scene file", comm=None) -> dict[str, Any]:
    """Read a TOML file once for every rank (:func:`read_input`) and parse it
    (:func:`parse_toml`); every failure is a SceneError naming the file. Collective."""
    return parse_toml(read_input(path, what, comm), path)


def check_depth(data: Any, where: str, depth: int = 1) -> None:
    """SceneError if tables and lists nest deeper than :data:`MAX_DEPTH` in ``data`` (itself
    at level ``depth``), naming ``where`` and the keys of the tables on the way (checked
    without recursion: a document nested thousands deep, which TOML's dotted keys allow,
    must not exhaust Python's stack)."""
    stack: list[tuple[Any, int, str]] = [(data, depth, "")]
    while stack:
        value, level, key = stack.pop()
        if level > MAX_DEPTH:
            raise SceneError(
                f"{where}: {key + ': ' if key else ''}nested deeper than "
                f"{MAX_DEPTH} levels of tables and lists"
            )
        if isinstance(value, dict):
            items = [
                (join_key(key, str(name)) if len(key) < 60 else key, item)
                for name, item in value.items()
            ]
        else:
            items = [(key, item) for item in value] if isinstance(value, list | tuple) else []
        stack += [
            (item, level + 1, inner)
            for inner, item in items
            if isinstance(item, dict | list | tuple)
        ]


def check_scene(data: dict[str, Any]) -> dict[str, Any]:
    """The scene's data validated against :data:`SCHEMA`, defaults filled in (raw values:
    expressions are still strings; cosserat_fem/scene/build.py builds the resolved scene)."""
    return check_table("", data, SCHEMA)


def leaf_keys() -> list[str]:
    """Every dotted key of the schema (tables included)."""
    return leaf_paths(SCHEMA)
