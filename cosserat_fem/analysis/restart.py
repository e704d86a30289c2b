"""The rules of a restart's scene (``cosserat-fem run --restart DIR``, ``cf.resume``,
``cf.run(scene, restart=checkpoint)``): the scene is the checkpoint's own, and only keys that do
not change the discrete problem may be overridden (:data:`RESTART_KEYS`), e.g.
``--set time.end=0.12`` to continue a completed run. The checkpoint's files are
cosserat_fem/io/checkpoint.py's; the checks of the outputs a restart continues and their cut
back to the checkpoint, cosserat_fem/io/run_folder.py's (``check_outputs``, ``cut_outputs``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from cosserat_fem.common.errors import SceneError, show_value
from cosserat_fem.io.checkpoint import Checkpoint

#: Scene keys a restart may override (prefixes end with "."): none changes the discretisation,
#: the model or the output grid.
RESTART_KEYS = (
    "time.end",
    "time.max_halvings",
    "solver.",
    "output.checkpoint",
    "output.checkpoint_interval",
    "limits.",
)
#: Keys a restart keeps, whatever the overrides (messages do not suggest them).
FIXED_KEYS = ("time.start", "time.step")


def _may_change(key: str) -> bool:
    """Whether a restart may change the dotted scene key ``key`` (:data:`RESTART_KEYS`)."""
    return any(key == k or (k.endswith(".") and key.startswith(k)) for k in RESTART_KEYS)


def _allowed() -> str:
    return ", ".join(k + "*" if k.endswith(".") else k for k in RESTART_KEYS)


def restart_overrides(overrides: Sequence[str]) -> None:
    """SceneError unless every ``--set`` (and ``--unset``) key of a restart is one of
    :data:`RESTART_KEYS`."""
    from cosserat_fem.scene.schema import Removal

    for text in overrides:
        key = text.split("=", 1)[0].strip()
        if not _may_change(key):
            option = "--unset" if isinstance(text, Removal) else "--set"
            raise SceneError(
                f"{option} {key}: cannot change on --restart (the checkpoint's discrete "
                f"problem is fixed); allowed: {_allowed()}"
            )


def _leaves(table: dict, prefix: str = "") -> dict[str, Any]:
    """{dotted key: value} of the nested tables of a scene's dict (lists are values)."""
    out: dict[str, Any] = {}
    for name, value in table.items():
        key = f"{prefix}.{name}" if prefix else str(name)
        out.update(_leaves(value, key) if isinstance(value, dict) and value else {key: value})
    return out


_ABSENT = object()


def _shown(value: Any) -> str:
    return "no value" if value is _ABSENT else show_value(value)


def check_restart_scene(checkpoint: Checkpoint, scene) -> None:
    """SceneError naming the first key (in the scene file's order) in which ``scene`` differs
    from the scene the checkpoint's run was run with, unless a restart may change it
    (:data:`RESTART_KEYS`), or if its time.end is not later than the checkpoint. What both
    ``run --restart`` (its scene is the checkpoint's with ``--set``) and the Python API's
    ``cf.run(scene, restart=checkpoint)`` (any scene) pass through, before anything is
    touched: a scene of other constants, loads or discretisation would continue the
    checkpoint's state as another problem, a splice of two runs."""
    from cosserat_fem.scene.build import check_later_end
    from cosserat_fem.scene.schema import NO_DEFAULT, default_of

    held = _leaves(checkpoint.meta["scene"])
    given = _leaves(json.loads(json.dumps(scene.to_dict())))  # as the index holds it
    for key in dict.fromkeys([*given, *held]):
        new, old = given.get(key, _ABSENT), held.get(key, _ABSENT)
        if old is _ABSENT and new is not _ABSENT:  # a key added since the run: its default
            old = default_of(key)
            old = _ABSENT if old is NO_DEFAULT else old
        same = new == old and isinstance(new, bool) == isinstance(old, bool)
        if not same and not _may_change(key):
            raise SceneError(
                f"{key}: {_shown(new)} where the checkpoint's run has {_shown(old)}; a restart "
                f"continues the checkpoint's problem and may change only {_allowed()} "
                "(cf.resume(folder, overrides) gives its scene)"
            )
    check_later_end(scene.time.end, checkpoint.time)
