"""A sweep file: a base scene and the members that vary it (``cosserat-fem sweep``).

A sweep file is TOML with one table, ``[sweep]``::

    [sweep]
    scene = "../scenes/cao_tucker_2008.toml"   # the base scene, relative to this file
    combine = "product"        # how the [sweep.vary] lists combine: "product" or "zip"
    max_members = 1000         # a sweep with more members is refused
    group_size = 1             # MPI ranks that run each member (mpirun -n: a multiple of it)
    keep = "run"               # each member's folder: "run" (all its outputs) or "probes"

    [sweep.set]                # the same for every member: dotted scene keys
    "time.end" = 0.006

    [sweep.vary]               # the varied keys: a list of values, or a range
    "time.step" = [1e-5, 2e-5, 3e-5]
    "rod.material.young_modulus" = { start = 6.9e10, stop = 7.3e10, num = 5 }

or, instead of ``[sweep.vary]``, a table of cases, each a set of dotted keys::

    [[sweep.case]]
    "time.step" = 1e-5
    [[sweep.case]]
    "time.step" = 2e-5
    "solver.stol" = 1e-8

A frequency response adds ``[sweep.response]`` (cosserat_fem/studies/response.py)::

    [sweep.response]
    period = "2*pi/(r*omega0)"   # s: the forcing's period, of L, omega0 and the parameters
    continuation = "parameters.r"  # a varied key: each member starts from the final state
                                 #   of the one before it in its chain (optional)
    direction = "up"             # chains by increasing ("up"), decreasing ("down") values of
                                 #   that key, or "both" (each member twice)
    tolerance = 1e-3             # settled: a relative change per period below this ...
    settled_periods = 3          # ... for so many periods in a row
    measure_periods = 2          # amplitudes over the last periods (<= settled_periods + 1)
    max_periods = 200            # a member runs at most so many periods (time.end ignored)
    steps_per_period = 600       # optional: time.step = period / this (every period sampled
                                 #   at the same phases: the change per period is exact)

A bifurcation diagram adds ``[sweep.poincare]``: each member records its Poincaré section
(cosserat_fem/analysis/observers.py ``PoincareSection``: poincare.csv in its folder) and the
sweep gathers the points of every member into ``bifurcation.csv`` beside sweep.csv
(cosserat_fem/io/sweep_table.py)::

    [sweep.poincare]
    period = "2*pi/Om"           # s: the section's period T (the forcing's), an expression
                                 #   of L, omega0 and the parameters
    phase = 0.0                  # rad: the section at t_j = (j + phase/2π) T
    discard = 20                 # the first points of each member left out of
                                 #   bifurcation.csv (the transient; kept in poincare.csv)
    continuation = "parameters.f0"  # a varied key: each member starts from the final state
                                 #   of the one before it in its chain (optional)
    direction = "up"             # "up", "down" or "both", as for a response

Members run on a reduced model (docs/rom.md §11; cosserat_fem/rom/runs.py) with
``[sweep.rom]``; the table's ``model`` column says which model each member used, and its
``indicator`` column the reduced run's error indicator where the solver reports one::

    [sweep.rom]
    model = "reduced"            # "reduced" (default) or "full": every member in full
    basis = "paper_basis.npz"    # a basis file of ``cosserat-fem rom build`` (relative to
                                 #   this file), or instead:
    train = [0, 10]              # members run in full first (from rest), the basis made of
                                 #   their snapshots (rom/basis.npz in the sweep's folder,
                                 #   their outputs in rom/training/; a restarted sweep reuses it)
    tolerance = 1e-8             # with train: the energy left out (docs/rom.md (3)), or
    modes = 12                   #   the number of modes
    every = 1                    # with train: a snapshot every so many outputs
    ecsw = 1e-2                  # with train: hyper-reduced (docs/rom.md §9), ECSW's fit
                                 #   tolerance; its members run on one rank each

With a continuation, a member runs its scene's time span (time.end − time.start) from the
start that carries the forcing's phase over from its predecessor's end
(response.continued_start): the chain follows one attractor as the key steps, where members
from the scene's initial state would each fall into whichever attractor that state leads
to. With ``[sweep.response]`` too, its continuation makes the chains (one given here is
refused) and its settings the span.

A chain is the members that share the values of every other varied key, ordered by the
continuation key; without a continuation each member is a chain of its own, from the
scene's initial state.

A range ``{start, stop, num}`` is ``num`` values from ``start`` to ``stop``, both included and
written exactly (``num = 1``: ``start``). Members are numbered from 0 in the order of the
product (the last key varying fastest), the zip or the cases. Every member's scene is built
and validated before any member runs: a malformed sweep (an unknown key of its own or of the
scene, an empty list or range, a value the scene's schema refuses, more members than
``max_members``, a member its run would refuse: a closed rod, a cost over its limits) is a
one-line SceneError naming the key and the value, or the member and its values. The command
line's ``--set`` changes the base scene after ``[sweep.set]``; a key that every member sets
is refused there (it would never be used).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from cosserat_fem.analysis import budget
from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import SceneError, show_value
from cosserat_fem.scene.build import (
    Scene,
    refuse_closed,
    refuse_structure,
    scene_from_dict,
    structure_from_file,
)
from cosserat_fem.scene.load_data import TableStore
from cosserat_fem.scene.schema import apply_overrides, parse_toml, read_input, read_toml
from cosserat_fem.studies.response import DIRECTIONS, ResponseSettings, check_sampling, period_of

KEYS = {
    "scene",
    "combine",
    "max_members",
    "group_size",
    "keep",
    "set",
    "vary",
    "case",
    "response",
    "poincare",
    "rom",
}
ROM_KEYS = {"model", "basis", "train", "tolerance", "modes", "every", "ecsw"}
ROM_MODELS = ("reduced", "full")
POINCARE_KEYS = {"period", "phase", "discard", "continuation", "direction"}
RESPONSE_KEYS = {
    "period",
    "continuation",
    "direction",
    "tolerance",
    "settled_periods",
    "measure_periods",
    "max_periods",
    "steps_per_period",
}
#: The most members a sweep may have: each rank validates every member before any runs and keeps
#: its values (why: docs/decisions.md, "Sweeps: every member validated first, its scene built
#: again when it runs";
#: tests/test_sweep.py::test_a_malformed_sweep_is_refused_before_any_member_runs).
MAX_MEMBERS = 100_000
COMBINE = ("product", "zip")
KEEP = ("run", "probes")
RANGE_KEYS = {"start", "stop", "num"}


@dataclass(frozen=True)
class SectionSettings:
    """A bifurcation diagram's ``[sweep.poincare]`` (module docstring): ``period`` [s], an
    expression of the scene's constants; ``phase`` [rad]; ``discard``, the points of each
    member left out of bifurcation.csv; ``continuation`` and ``direction``, the chains as
    :class:`~cosserat_fem.studies.response.ResponseSettings`'s."""

    period: str
    phase: float = 0.0
    discard: int = 0
    continuation: str | None = None
    direction: str = "up"


@dataclass(frozen=True)
class RomSettings:
    """A sweep's ``[sweep.rom]`` (module docstring): the members' ``model``, and their basis:
    ``basis`` the path of a basis file (resolved), or the members ``train`` whose full runs
    make it, with ``tolerance`` or ``modes``, ``every`` and ``ecsw`` (hyper-reduced: ECSW's
    tolerance; None: Galerkin); ``digest`` the basis file's
    SHA-256 (the sweep's fingerprint: another basis is another sweep)."""

    model: str = "reduced"
    basis: str | None = None
    train: tuple[int, ...] = ()
    tolerance: float | None = None
    modes: int | None = None
    every: int = 1
    digest: str | None = None
    ecsw: float | None = None

    @property
    def reduced(self) -> bool:
        return self.model == "reduced"


@dataclass(frozen=True)
class Member:
    """One member: its number and its values of the varied keys (dotted key → value)."""

    index: int
    values: dict[str, Any]
    direction: str = ""  # a frequency response's chain: "up" or "down" ("" without one)

    @property
    def name(self) -> str:
        """Its folder's name under the sweep's ``members/``."""
        return f"m{self.index:05d}"

    def describe(self) -> str:
        text = ", ".join(f"{k} = {show_value(v)}" for k, v in self.values.items())
        return f"{text}, {self.direction}" if self.direction else text


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: the base scene's data (with ``[sweep.set]`` and the command line's
    overrides applied), the members, and how to run them."""

    base: dict[str, Any]
    source: str
    members: tuple[Member, ...]
    varied: tuple[str, ...]
    group_size: int = 1
    keep: str = "run"
    response: ResponseSettings | None = None
    #: Members run one after another, each from the previous one's final state (a frequency
    #: response's continuation); without one, every member is a chain of its own.
    chains: tuple[tuple[int, ...], ...] = ()
    #: The tables of loads given by data, read once when the sweep was validated (every
    #: member's scene is built from them: no rank reads a file again,
    #: cosserat_fem/scene/load_data.py).
    tables: TableStore = field(default_factory=TableStore, compare=False, repr=False)
    #: SHA-256 of the base scene file's bytes (the members' scene_file_sha256)
    source_sha256: str = ""
    #: A bifurcation diagram's Poincaré section of every member ([sweep.poincare]).
    poincare: SectionSettings | None = None
    #: The members' reduced model ([sweep.rom]), None: every member in full.
    rom: RomSettings | None = None

    @property
    def reduced(self) -> bool:
        """Whether the members run on a reduced model."""
        return self.rom is not None and self.rom.reduced

    def scene(self, member: Member, extra: dict[str, Any] | None = None) -> Scene:
        """The member's resolved scene (validated with the sweep; built again here rather
        than kept, so that memory does not grow with the sweep on every rank; why:
        docs/decisions.md, "Sweeps: every member validated first, ...");
        ``extra``: dotted keys set besides its values (a forced member's time span)."""
        scene = scene_from_dict(
            self.base, self.source, {**member.values, **(extra or {})}, tables=self.tables
        )
        return replace(scene, source_sha256=self.source_sha256)

    def fingerprint(self) -> str:
        """What identifies the sweep's work: the base scene, every member's values, the
        response's settings and the content (SHA-256) of every table (a restarted sweep must
        be the same sweep), all but the limits (``limits.*``: they decide whether a member runs
        to its end, not what it computes, so a sweep stopped by limits.wall_time continues with
        a larger one)."""
        members = [
            [_no_limits(m.values), m.direction] if m.direction else _no_limits(m.values)
            for m in self.members
        ]
        document: dict[str, Any] = {"base": _no_limits(self.base), "members": members}
        if self.tables.files:
            document["tables"] = self.tables.digests()
        if self.response is not None:
            document["response"] = self.response.__dict__
        if self.poincare is not None:
            document["poincare"] = self.poincare.__dict__
        if self.rom is not None:
            document["rom"] = self.rom.__dict__
        if self.chains_continue:  # the saved states are parts of a group's partition
            document["group_size"] = self.group_size
        return json.dumps(document, sort_keys=True, default=str)

    @property
    def continuation(self) -> str | None:
        """The varied key the chains step along ([sweep.response]'s or [sweep.poincare]'s),
        or None."""
        for settings in (self.response, self.poincare):
            if settings is not None and settings.continuation is not None:
                return settings.continuation
        return None

    @property
    def chains_continue(self) -> bool:
        """Whether each member of a chain starts from the previous one's final state."""
        return self.continuation is not None

    def section_period(self, member: Member) -> float:
        """The Poincaré section's period [s] at the member's constants (sweep.poincare.period)."""
        assert self.poincare is not None
        scene = self.scene(member)
        return period_of(
            self.poincare, scene.expression_names(), f"member {member.index}", POINCARE_PERIOD
        )

    def period(self, member: Member) -> float:
        """A forced member's forcing period [s] (sweep.response.period at its constants)."""
        assert self.response is not None
        scene = self.scene(member)
        return period_of(self.response, scene.expression_names(), f"member {member.index}")

    def span(self, member: Member, start: float) -> dict[str, float]:
        """A forced member's time span from ``start`` [s] (:func:`forced_span`)."""
        assert self.response is not None
        return forced_span(self.response, self.scene(member), start, f"member {member.index}")[1]


def _no_limits(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` (a scene's tables, or a member's dotted keys) without the limits."""
    return {
        k: v for k, v in values.items() if k != "limits" and not _dotted(k).startswith("limits.")
    }


def forced_span(response: ResponseSettings, scene: Scene, start: float, where: str):
    """(T [s], the time span from ``start`` [s] as dotted keys time.start, time.end,
    time.step): max_periods periods of the forcing's T, rounded up to whole steps of the
    scene's time.step or of T / steps_per_period. SceneError naming sweep.response.max_periods
    if that many steps are not a finite number."""
    period = period_of(response, scene.expression_names(), where)
    per = response.steps_per_period
    step = period / per if per else scene.time.step
    steps = response.max_periods * period / step
    if not math.isfinite(steps) or not math.isfinite(start + steps * step):
        raise SceneError(
            f"sweep.response.max_periods: {response.max_periods} periods of "
            f"{period:.6g} s are not a finite number of steps of {step:.6g} s at "
            f"{where}"
        )
    steps = math.ceil(steps - 1e-9)
    return period, {"time.start": start, "time.end": start + steps * step, "time.step": step}


def _positive_int(table: dict, key: str, default: int, where: str = "sweep") -> int:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise SceneError(f"{where}.{key}: must be a positive integer, got {show_value(value)}")
    return value


def _choice(table: dict, key: str, choices: tuple[str, ...], where: str = "sweep") -> str:
    """``table[key]``, one of ``choices`` (default: the first), checked: the one line names
    ``where``.key."""
    value = table.get(key, choices[0])
    if value not in choices:
        raise SceneError(
            f"{where}.{key}: must be one of {', '.join(repr(c) for c in choices)}, got "
            f"{show_value(value)}"
        )
    return value


def _values(key: str, raw: Any) -> list[Any]:
    """The values of a varied key: a non-empty list, or a range {start, stop, num}."""
    where = f"sweep.vary.{json.dumps(key)}"
    if isinstance(raw, dict):
        if set(raw) != RANGE_KEYS:
            raise SceneError(
                f"{where}: a range has the keys start, stop and num, got {show_value(sorted(raw))}"
            )
        start, stop, num = raw["start"], raw["stop"], raw["num"]
        for name, value in (("start", start), ("stop", stop)):
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not math.isfinite(value)
            ):
                raise SceneError(
                    f"{where}.{name}: must be a finite number, got {show_value(value)}"
                )
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise SceneError(
                f"{where}.num: an empty range: num must be a positive integer, "
                f"got {show_value(num)}"
            )
        if num == 1:
            return [start]
        if math.isfinite(stop - start):
            return [start + (stop - start) * i / (num - 1) for i in range(num - 1)] + [stop]
        # stop − start beyond the largest double (e.g. -1e308 ... 1e308): the same points as
        # weights of the ends, each term finite
        return [start * (1 - i / (num - 1)) + stop * (i / (num - 1)) for i in range(num - 1)] + [
            stop
        ]
    if not isinstance(raw, list) or not raw:
        raise SceneError(
            f"{where}: must be a non-empty list of values or a range "
            f"{{start, stop, num}}, got {show_value(raw)}"
        )
    return list(raw)


def _members(table: dict, combine: str) -> tuple[list[dict[str, Any]], tuple[str, ...]]:
    """Each member's values, and the varied keys in order."""
    vary, cases = table.get("vary"), table.get("case")
    if (vary is None) == (cases is None):
        raise SceneError("sweep: give either [sweep.vary] or [[sweep.case]] (one of them)")
    if cases is not None:
        if not isinstance(cases, list) or not cases or not all(isinstance(c, dict) for c in cases):
            raise SceneError("sweep.case: must be a non-empty array of tables [[sweep.case]]")
        keys = tuple(dict.fromkeys(k for case in cases for k in case))
        for i, case in enumerate(cases):
            if not case:
                raise SceneError(f"sweep.case[{i}]: an empty case (give at least one key)")
        return [dict(case) for case in cases], keys
    if not isinstance(vary, dict) or not vary:
        raise SceneError("sweep.vary: must be a table of at least one dotted key")
    keys = tuple(vary)
    lists = [_values(key, vary[key]) for key in keys]
    if combine == "zip":
        lengths = {len(v) for v in lists}
        if len(lengths) > 1:
            sizes = ", ".join(
                f"{json.dumps(k)}: {len(v)}" for k, v in zip(keys, lists, strict=True)
            )
            raise SceneError(f"sweep.vary: combine = 'zip' needs lists of one length, got {sizes}")
        rows: Iterator[tuple[Any, ...]] = zip(*lists, strict=True)
    else:
        rows = itertools.product(*lists)
    return [dict(zip(keys, row, strict=True)) for row in rows], keys


def _positive_number(table: dict, key: str, default: float) -> float:
    value = table.get(key, default)
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not (math.isfinite(value) and value > 0)
    ):
        raise SceneError(
            f"sweep.response.{key}: must be a positive number, got {show_value(value)}"
        )
    return float(value)


def _periodic_table(table: Any, known: set[str], where: str, what: str) -> str | None:
    """The text of the period of the sweep file's table ``where`` ([sweep.response] or
    [sweep.poincare]), None without the table; SceneError naming the key if it is not a
    table, has a key not ``known`` or no period (``what``, in the message)."""
    if table is None:
        return None
    if not isinstance(table, dict):
        raise SceneError(f"{where}: must be a table, got {show_value(table)}")
    unknown = sorted(set(table) - known)
    if unknown:
        raise SceneError(f"{where}.{unknown[0]}: unknown key (known: {', '.join(sorted(known))})")
    period = table.get("period")
    if isinstance(period, bool) or not isinstance(period, str | int | float):
        raise SceneError(
            f"{where}.period: required, {what} in s (an expression of L, omega0 and the "
            f"parameters), got {show_value(period)}"
        )
    return str(period)


def _chain_keys(table: dict, varied: tuple[str, ...], where: str) -> tuple[str | None, str]:
    """The continuation key (a varied key, or None) and the direction of the chains of the
    sweep file's table ``where`` ([sweep.response] or [sweep.poincare]), checked."""
    continuation = table.get("continuation")
    if continuation is not None and continuation not in varied:
        raise SceneError(
            f"{where}.continuation: must be one of the varied keys "
            f"({', '.join(varied)}), got {show_value(continuation)}"
        )
    direction = _choice(table, "direction", DIRECTIONS, where)
    if "direction" in table and continuation is None:
        raise SceneError(
            f"{where}.direction: needs {where}.continuation (the varied key the members step along)"
        )
    return continuation, direction


def _response(table: Any, varied: tuple[str, ...]) -> ResponseSettings | None:
    """The [sweep.response] table checked (module docstring), or None."""
    period = _periodic_table(table, RESPONSE_KEYS, "sweep.response", "the forcing's period")
    if period is None:
        return None
    continuation, direction = _chain_keys(table, varied, "sweep.response")
    settled = _positive_int(table, "settled_periods", 3, "sweep.response")
    measure = _positive_int(table, "measure_periods", 2, "sweep.response")
    most = _positive_int(table, "max_periods", 200, "sweep.response")
    if measure > settled + 1:
        raise SceneError(
            f"sweep.response.measure_periods: at most settled_periods + 1 = "
            f"{settled + 1} (the periods measured must be settled), got {measure}"
        )
    if most < settled + 1:
        raise SceneError(
            f"sweep.response.max_periods: at least settled_periods + 1 = {settled + 1}, got {most}"
        )
    per = table.get("steps_per_period")
    if per is not None:
        per = _positive_int(table, "steps_per_period", 1, "sweep.response")
        if per < 16:
            # Fewer samples miss a peak by more than 1 − cos(π/16) = 1.9 % of the amplitude
            # and cannot resolve a nonlinear response's harmonics up to the 7th (Nyquist).
            raise SceneError(
                f"sweep.response.steps_per_period: at least 16 (the half range "
                f"would miss a peak by more than 2 %), got {per}"
            )
    tolerance = _positive_number(table, "tolerance", 1e-3)
    if tolerance >= 1.0:
        raise SceneError(
            f"sweep.response.tolerance: must be < 1 (a relative change), got "
            f"{show_value(tolerance)}"
        )
    return ResponseSettings(period, continuation, direction, tolerance, settled, measure, most, per)


#: The dotted key of a section's period, named when it is refused.
POINCARE_PERIOD = "sweep.poincare.period"


def _poincare(
    table: Any, varied: tuple[str, ...], response: ResponseSettings | None
) -> SectionSettings | None:
    """The [sweep.poincare] table checked (module docstring), or None."""
    period = _periodic_table(table, POINCARE_KEYS, "sweep.poincare", "the section's period")
    if period is None:
        return None
    phase = table.get("phase", 0.0)
    if isinstance(phase, bool) or not isinstance(phase, int | float) or not math.isfinite(phase):
        raise SceneError(
            f"sweep.poincare.phase: must be a finite angle in rad, got {show_value(phase)}"
        )
    discard = table.get("discard", 0)
    if isinstance(discard, bool) or not isinstance(discard, int) or discard < 0:
        raise SceneError(
            f"sweep.poincare.discard: must be a whole number of points >= 0, got "
            f"{show_value(discard)}"
        )
    if "continuation" in table and response is not None and response.continuation is not None:
        raise SceneError(
            "sweep.poincare.continuation: the chains are sweep.response.continuation's "
            "(give them in one place)"
        )
    continuation, direction = _chain_keys(table, varied, "sweep.poincare")
    return SectionSettings(period, float(phase), discard, continuation, direction)


def _check_section(poincare: SectionSettings, scene: Scene, where: str) -> None:
    """A member's section checked against its scene: its period T one that the scene's load
    expressions repeat after (orbit_runs.check_periodic), and ``discard`` fewer than the
    section points its time span can hold (at most ⌊span/T⌋ + 1), so that it adds points
    to bifurcation.csv."""
    from cosserat_fem.analysis.orbit_runs import check_periodic

    period = period_of(poincare, scene.expression_names(), where, POINCARE_PERIOD)
    check_periodic(scene, period, POINCARE_PERIOD)
    span = scene.time.end - scene.time.start
    most = math.floor(span / period * (1.0 + 1e-9)) + 1
    if poincare.discard >= most:
        raise SceneError(
            f"sweep.poincare.discard: {poincare.discard} leaves none of the at most {most} "
            f"section points of a member's time span {span:.6g} s (T = {period:.6g} s)"
        )


def _chains(
    values: list[dict[str, Any]],
    varied: tuple[str, ...],
    settings: ResponseSettings | SectionSettings | None,
    table: str = "sweep.response",
) -> tuple[list[Member], list[tuple[int, ...]]]:
    """The members and the chains they run in (module docstring), by the continuation and
    direction of ``settings`` (of the sweep file's ``table``)."""
    if settings is None or settings.continuation is None:
        return [Member(i, v) for i, v in enumerate(values)], [(i,) for i in range(len(values))]
    key = settings.continuation
    for i, v in enumerate(values):
        if key not in v:
            raise SceneError(
                f"{table}.continuation: {key!r} is not set in member {i} (every case must give it)"
            )
        if isinstance(v[key], bool) or not isinstance(v[key], int | float):
            raise SceneError(
                f"{table}.continuation: {key!r} must take numbers, got "
                f"{show_value(v[key])} in member {i}"
            )
    lines: dict[str, list[int]] = {}
    for i, v in enumerate(values):
        rest = json.dumps([[k, v[k]] for k in varied if k != key], default=str)
        lines.setdefault(rest, []).append(i)
    directions = ("up", "down") if settings.direction == "both" else (settings.direction,)
    members: list[Member] = []
    chains: list[tuple[int, ...]] = []
    for direction in directions:
        offset = len(members)
        members += [Member(offset + i, v, direction) for i, v in enumerate(values)]
        for line in lines.values():
            ordered = sorted(line, key=lambda i: values[i][key], reverse=direction == "down")
            chains.append(tuple(offset + i for i in ordered))
    return members, chains


def _count(table: dict, combine: str) -> int:
    """The number of members, before they are made (a product can be huge)."""
    if table.get("case") is not None and isinstance(table["case"], list):
        return len(table["case"])
    vary = table.get("vary")
    if not isinstance(vary, dict):
        return 0
    sizes = [
        len(_values(key, raw))
        if not isinstance(raw, dict)
        else (num if isinstance(num := raw.get("num"), int) else 0)
        for key, raw in vary.items()
    ]
    return max(sizes, default=0) if combine == "zip" else math.prod(sizes)


def load_sweep(
    path: str | Path, overrides=(), changes: Mapping[str, Any] | None = None
) -> SweepSpec:
    """Read and validate a sweep file (module docstring); ``overrides``: dotted scene keys
    applied to the base scene after ``[sweep.set]`` (the command line's ``--set``: it wins);
    ``changes``: the sweep file's own [sweep] table changed before it is checked, tables
    merged key by key and any other value replaced (e.g. ``{"vary": {"parameters.r":
    [0.9, 1.1]}, "rom": {"train": [0, 4]}}``: the same sweep over other values, as if the file
    said so). Collective under MPI: rank 0 reads the sweep file and the base scene, every
    rank parses their bytes (schema.read_input)."""
    path = Path(path)
    data = read_toml(path, "sweep file")
    if changes and isinstance(data.get("sweep"), dict):  # else refused below, as without
        data["sweep"] = _merged(data["sweep"], changes)
    table = data.get("sweep")
    unknown = sorted(set(data) - {"sweep"})
    if unknown:
        raise SceneError(f"{unknown[0]}: not a table of a sweep file (only [sweep])")
    if not isinstance(table, dict):
        raise SceneError(f"{path}: a sweep file needs a [sweep] table")
    unknown = sorted(set(table) - KEYS)
    if unknown:
        raise SceneError(f"sweep.{unknown[0]}: unknown key (known: {', '.join(sorted(KEYS))})")
    if "scene" not in table or not isinstance(table["scene"], str) or not table["scene"]:
        raise SceneError(
            "sweep.scene: required, the base scene file (relative to the sweep "
            f"file), got {show_value(table.get('scene'))}"
        )
    combine = _choice(table, "combine", COMBINE)
    keep = _choice(table, "keep", KEEP)
    group_size = _positive_int(table, "group_size", 1)
    max_members = _positive_int(table, "max_members", 1000)
    if max_members > MAX_MEMBERS:
        raise SceneError(
            f"sweep.max_members: at most {MAX_MEMBERS} (every rank validates every "
            f"member first), got {max_members}"
        )
    fixed = table.get("set", {})
    if not isinstance(fixed, dict):
        raise SceneError(f"sweep.set: must be a table of dotted keys, got {show_value(fixed)}")
    count = _count(table, combine)
    if count > max_members:
        raise SceneError(
            f"sweep.max_members: the sweep has {count} members, more than "
            f"max_members = {max_members}"
        )
    values, varied = _members(table, combine)
    scene_path = (path.parent / table["scene"]).resolve()
    raw = read_input(scene_path, "scene file (sweep.scene)", same_name=False)  # rank 0's
    tables = TableStore.collective(scene_path.parent)
    # a structure's file of line cells read once, here: the members hold its geometry, which
    # the sweep's fingerprint then covers (no member reads the file again)
    base_data = structure_from_file(
        _base(parse_toml(raw, scene_path), fixed, overrides, values), tables
    )
    response = _response(table.get("response"), varied)
    poincare = _poincare(table.get("poincare"), varied, response)
    if response is not None and response.continuation is not None:
        members, chains = _chains(values, varied, response)
    else:
        members, chains = _chains(values, varied, poincare, "sweep.poincare")
    if len(members) > max_members:
        raise SceneError(
            f"sweep.max_members: the sweep has {len(members)} members (both "
            f"directions), more than max_members = {max_members}"
        )
    for member in members[: len(values)]:
        try:
            _check_member(base_data, str(scene_path), member, response, group_size, tables)
            if poincare is not None:
                scene = scene_from_dict(base_data, str(scene_path), member.values, tables=tables)
                _check_section(poincare, scene, f"member {member.index}")
        except SceneError as exc:
            raise SceneError(f"sweep member {member.index} ({member.describe()}): {exc}") from None
    rom = _rom(table.get("rom"), path, len(members), group_size)
    if "structure" in base_data:  # plain members only: a structure's run (docs/structures.md)
        for name, given in (("poincare", poincare), ("rom", rom)):
            if given is not None:
                raise SceneError(
                    f"sweep.{name}: not supported on a structure yet (a sweep of plain "
                    "members is); see docs/structures.md"
                )
    tables.seal()  # every member's tables are read: none is read again in a group
    return SweepSpec(
        base_data,
        str(scene_path),
        tuple(members),
        varied,
        group_size,
        keep,
        response,
        tuple(chains),
        tables,
        hashlib.sha256(raw).hexdigest(),
        poincare,
        rom,
    )


def _merged(table: dict[str, Any], changes: Mapping[str, Any]) -> dict[str, Any]:
    """``table`` with ``changes`` merged in: a mapping into a table key by key, ``UNSET``
    (cosserat_fem/scene/schema.py) removing the key, any other value replacing (what comes
    out is checked as a file's table is)."""
    from cosserat_fem.scene.schema import UNSET

    merged = dict(table)
    for key, value in changes.items():
        if value is UNSET:
            merged.pop(key, None)
        elif isinstance(value, Mapping) and isinstance(merged.get(key), dict):
            merged[key] = _merged(merged[key], value)
        else:
            merged[key] = value
    return merged


def _rom(table: Any, path: Path, count: int, group_size: int) -> RomSettings | None:
    """The [sweep.rom] table checked (module docstring), or None; the basis file must exist
    (read by rank 0, its SHA-256 every rank's)."""
    if table is None:
        return None
    if not isinstance(table, dict):
        raise SceneError(f"sweep.rom: must be a table, got {show_value(table)}")
    unknown = sorted(set(table) - ROM_KEYS)
    if unknown:
        raise SceneError(
            f"sweep.rom.{unknown[0]}: unknown key (known: {', '.join(sorted(ROM_KEYS))})"
        )
    model = _choice(table, "model", ROM_MODELS, "sweep.rom")
    basis, train = table.get("basis"), table.get("train")
    if basis is None and train is None:
        if model == "full":
            return RomSettings(model)
        raise SceneError(
            "sweep.rom: the reduced members need a basis: give basis = FILE (of cosserat-fem "
            "rom build) or train = [members]"
        )
    if basis is not None and train is not None:
        raise SceneError("sweep.rom.train: give basis or train, not both")
    every = _positive_int(table, "every", 1, "sweep.rom")
    if basis is not None:
        for key in ("tolerance", "modes", "every", "ecsw"):
            if key in table:
                raise SceneError(f"sweep.rom.{key}: only with train (the basis file has its modes)")
        if not isinstance(basis, str) or not basis:
            raise SceneError(f"sweep.rom.basis: a basis file's path, got {show_value(basis)}")
        file = (path.parent / basis).resolve()
        if file.suffix != ".npz":
            file = file.with_suffix(".npz")
        digest = _digest(file)
        if digest is None:
            raise SceneError(f"sweep.rom.basis: no basis file {str(file)!r}")
        return RomSettings(model, str(file), digest=digest)
    if not isinstance(train, list) or not train:
        raise SceneError(f"sweep.rom.train: a non-empty list of members, got {show_value(train)}")
    for m in train:
        if isinstance(m, bool) or not isinstance(m, int) or not 0 <= m < count:
            raise SceneError(
                f"sweep.rom.train: member {show_value(m)} out of range (the sweep has members "
                f"0 to {count - 1})"
            )
    tolerance, modes = table.get("tolerance"), table.get("modes")
    if (tolerance is None) == (modes is None):
        raise SceneError("sweep.rom.tolerance: give tolerance (the energy left out) or modes")
    if modes is not None:
        modes = _positive_int(table, "modes", 1, "sweep.rom")
    if tolerance is not None and (
        isinstance(tolerance, bool)
        or not isinstance(tolerance, int | float)
        or not 0.0 <= tolerance < 1.0
    ):
        raise SceneError(
            f"sweep.rom.tolerance: must be a number in [0, 1), got {show_value(tolerance)}"
        )
    ecsw = table.get("ecsw")
    if ecsw is not None:
        if isinstance(ecsw, bool) or not isinstance(ecsw, int | float) or not 0.0 < ecsw < 1.0:
            raise SceneError(f"sweep.rom.ecsw: must be a number in (0, 1), got {show_value(ecsw)}")
        if group_size > 1:
            raise SceneError(
                "sweep.rom.ecsw: hyper-reduced members run on one rank each (sweep.group_size "
                f"= 1), got group_size = {group_size}"
            )
    return RomSettings(
        model,
        None,
        tuple(dict.fromkeys(train)),
        None if tolerance is None else float(tolerance),
        modes,
        every,
        ecsw=None if ecsw is None else float(ecsw),
    )


def _digest(file: Path) -> str | None:
    """SHA-256 of ``file`` read by rank 0, every rank's (None if it cannot be read)."""
    world = _world()
    digest = None
    if world.rank == 0:
        try:
            digest = hashlib.sha256(safe_files.read_regular(file)).hexdigest()
        except OSError:
            digest = None
    return world.bcast(digest, root=0) if world.size > 1 else digest


def _dotted(key: str) -> str:
    """A dotted key as overrides read it (blanks around its parts removed)."""
    return ".".join(part.strip() for part in str(key).split("."))


def _base(data: dict, fixed: dict, overrides, values: list[dict[str, Any]]) -> dict:
    """The base scene's data with ``[sweep.set]`` and then the command line's ``--set``
    applied, each error named by where the key came from. A ``--set`` key that every member
    sets is refused: the members' values would silently replace it (``[sweep.set]`` may give
    one, e.g. a parameter's value at rest: the file says what its members vary)."""
    always = set.intersection(*({_dotted(k) for k in v} for v in values)) if values else set()
    given = [
        str(k) if isinstance(overrides, Mapping) else str(k).partition("=")[0] for k in overrides
    ]
    taken = next((k for k in given if _dotted(k) in always), None)
    if taken is not None:
        raise SceneError(
            f"--set {_dotted(taken)}: every member of the sweep sets it "
            "(sweep.vary or sweep.case), so this value would never be used"
        )
    try:
        data = apply_overrides(data, fixed)
    except SceneError as exc:
        raise SceneError(f"sweep.set: {exc}") from None
    return apply_overrides(data, overrides)


def _world():
    """MPI's world: every rank validates every member alike, and a refusal that rests on what
    one rank sees (its process's memory limits) must be every rank's (budget.check)."""
    from mpi4py import MPI

    return MPI.COMM_WORLD


def _check_member(
    data: dict,
    source: str,
    member: Member,
    response: ResponseSettings | None,
    group_size: int,
    tables: TableStore,
) -> None:
    """A member's scene validated, and refused as its run would refuse it (a closed rod; the
    cost of its run, or of a forced member's longest run, over its limits: budget.py, the
    memory of a group's rank counted as a share of one node's, a certain lower bound)."""
    scene = scene_from_dict(data, source, member.values, tables=tables)
    refuse_closed(scene, "run")
    if response is not None:  # a frequency response's chains continue a single rod's state
        refuse_structure(scene, "a sweep with a [sweep.response]")
    if response is None:
        budget.check(scene, "run", ranks=group_size, comm=_world())
        return
    where = f"member {member.index}"
    period, span = forced_span(response, scene, scene.time.start, where)
    if response.steps_per_period is None:
        check_sampling(response, period, scene.time.step, where)
    longest = scene_from_dict(data, source, {**member.values, **span}, tables=tables)
    try:
        budget.check(longest, "run", ranks=group_size, comm=_world())
    except SceneError as exc:
        raise SceneError(
            f"sweep.response.max_periods: {response.max_periods} periods of {period:.6g} s: {exc}"
        ) from None
