"""A structure's geometry from a file of line cells (``[structure] file``, docs/structures.md),
read with meshio: Gmsh (.msh), VTK (.vtk, .vtu), XDMF and the other formats meshio reads.

Every point that a line cell uses becomes a node named ``n<i>``, i its index among the file's
points (supports, loads and bodies name it so), at its position [m] (a missing third
coordinate is 0); every 2-node line cell ("line") becomes a straight member named ``c<j>``,
j its index among the file's line cells in order, from its first point to its second, of
``elements`` finite elements. Cells of other kinds (triangles, vertices, Gmsh's physical
points) are left out; curved (higher-order) lines are refused, a member being straight
between its nodes, and so are a cell given twice and a cell from a point to itself. The
result is the ``nodes`` and ``members`` of a [structure] table, so that the scene (and a
restart's copy of it) holds the geometry itself, not the file's name.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.reading import check_size, is_file, quoted

#: The largest file read [bytes].
MAX_LINE_MESH_BYTES = 1 << 28


def read_line_mesh(path: str | Path, elements: int, key: str = "structure.file") -> dict[str, Any]:
    """{"nodes": [...], "members": [...]} of the line cells in ``path`` (module docstring);
    SceneError naming ``key`` for a file that is missing, not a regular file, too large,
    unreadable by meshio, or without 2-node line cells."""
    path = Path(path)
    try:
        if not is_file(path):  # a FIFO or a device is refused there: never opened (no hang)
            raise SceneError(f"{quoted(path)}: no such file")
        check_size(path, MAX_LINE_MESH_BYTES, "a structure's file of line cells")
    except SceneError as exc:
        raise SceneError(f"{key}: {exc}") from None
    import contextlib
    import io

    import meshio

    said = io.StringIO()  # meshio prints its complaints, and may exit: kept for one line
    try:
        with contextlib.redirect_stderr(said), contextlib.redirect_stdout(said):
            mesh = meshio.read(path)
    except (Exception, SystemExit) as exc:  # meshio raises many kinds: the file's fault
        reason = " ".join((str(exc) if not isinstance(exc, SystemExit) else "").split())
        reason = reason or " ".join(said.getvalue().split()) or type(exc).__name__
        raise SceneError(f"{key}: meshio cannot read {quoted(path)} ({reason})") from None
    kinds = {block.type for block in mesh.cells}
    curved = sorted(k for k in kinds if k.startswith("line") and k != "line")
    if curved:
        raise SceneError(
            f"{key}: {quoted(path)} has curved line cells ({', '.join(curved)}); a member is "
            "straight between its two nodes: give 2-node lines"
        )
    lines = [block.data for block in mesh.cells if block.type == "line"]
    if not lines:
        raise SceneError(
            f"{key}: {quoted(path)} has no line cells (found: {', '.join(sorted(kinds)) or 'none'})"
        )
    cells = np.concatenate(lines).astype(int)
    seen: dict[tuple[int, int], int] = {}
    for j, (a, b) in enumerate(cells):
        pair = (min(a, b), max(a, b))
        if a == b:
            raise SceneError(f"{key}: {quoted(path)}: line cell {j} joins point {a} to itself")
        if pair in seen:  # e.g. Gmsh's MSH2 writes a cell once for each physical group
            raise SceneError(
                f"{key}: {quoted(path)}: line cells {seen[pair]} and {j} join the same points "
                f"{pair[0]} and {pair[1]} (two members there would double its stiffness; give "
                "each cell once)"
            )
        seen[pair] = j
    points = np.asarray(mesh.points, dtype=float)
    if points.shape[1] < 3:
        points = np.hstack([points, np.zeros((len(points), 3 - points.shape[1]))])
    used = sorted({int(i) for i in cells.ravel()})
    nodes = [{"name": f"n{i}", "position": [float(x) for x in points[i, :3]]} for i in used]
    members = [
        {"name": f"c{j}", "from": f"n{a}", "to": f"n{b}", "elements": elements}
        for j, (a, b) in enumerate(cells)
    ]
    return {"nodes": nodes, "members": members}
