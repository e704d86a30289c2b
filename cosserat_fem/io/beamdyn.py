"""BeamDyn's input files (OpenFAST's beam module) read into a scene of this code's single rod.

A BeamDyn case is three text files (OpenFAST docs, "BeamDyn Input Files",
docs/source/user/beamdyn/input_files.rst): the stand-alone **driver** input (analysis type, time
span, gravity, the global frame, root velocity, loads, and the name of the primary file), the
**primary** input (members of key points ``kp_xr kp_yr kp_zr initial_twist`` in the blade frame,
the element order, quadrature, solver settings, outputs, and the name of the blade file), and
the **blade** file (stations η ∈ [0, 1] along the reference axis, each with a 6×6 stiffness and
a 6×6 mass matrix, and the damping). :func:`read_case` reads the three and
:func:`scene_of` makes the scene (the TOML tables cosserat_fem/scene validates). The mapping,
what is taken and what is refused: docs/beamdyn.md.

Frames. BeamDyn's blade frame (X_r, Y_r, Z_r), Z_r along the blade from the root, is this
code's fixed basis (e1, e2, e3): the straight rod runs along e3, its directors d1, d2 are X_r,
Y_r, and the section's axes 1, 2, 3 of the 6×6 matrices are d1, d2, d3, so the stiffness goes
in as it is ((shear 1, shear 2, extension, bending 1, bending 2, torsion) is BeamDyn's order,
docs/sections.md). The driver's loads and gravity, given in its global frame, are turned into
the blade frame by ``GlbDCM`` (row i: the blade axis i in global components, v_r = GlbDCM v_g;
a proper rotation, else refused); ``GlbPos``, a translation of the whole blade, moves no
displacement and is not applied.

Every refusal and every bad entry is a :class:`~cosserat_fem.common.errors.SceneError` of one
line, ``FILE:LINE: KEY: reason`` (the line where it is, or the file alone when a key is
missing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosserat_fem.common.errors import SceneError
from cosserat_fem.common.rotations import quaternion_of_frame
from cosserat_fem.io.reading import check_size, is_file, read_bytes

#: Our discretisation of a BeamDyn case (BeamDyn's order_elem and members are recorded, not
#: used): quartic elements, whose error at the tip falls as h^8 for these smooth cases.
ELEMENTS, DEGREE = 16, 4
#: Key points off the straight line or the circle by more than this fraction of the length:
#: not that shape (the inputs' 6-8 digits leave ~1e-7 of it).
SHAPE_TOLERANCE = 1e-5
#: The mass matrix's translational diagonal must be one m to this relative difference.
MASS_TOLERANCE = 1e-9
#: GlbDCM's rows must be orthonormal to this (its 8 printed digits leave ~1e-8).
FRAME_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Station:
    """A blade station: η ∈ [0, 1], the stiffness K [N | N m | N m²] and mass M [kg/m | kg |
    kg m] in BeamDyn's order (shear 1, shear 2, extension, bending 1, bending 2, torsion),
    and the line of the blade file where its η is."""

    eta: float
    stiffness: np.ndarray
    mass: np.ndarray
    line: int


@dataclass(frozen=True)
class BeamDynCase:
    """The three files read: ``driver``, ``primary``, ``blade`` their paths; the driver's
    settings (``dynamic``, times [s], ``gravity`` [m/s²], ``frame`` GlbDCM, ``origin``
    GlbPos [m], ``root_velocity`` [rad/s], ``distributed`` (force [N/m], moment [N m/m]),
    ``tip`` (force [N], moment [N m]), ``point_loads``), the primary's (``key_points`` (k, 4):
    x, y, z [m], twist [deg]; ``members``: key points per member; ``order_elem``,
    ``quadrature``, ``refine``, ``rho_inf``), the blade's (``stations``, ``damp_type``,
    ``damping`` μ_1..6 [s]); ``lines``: the line of each key read (for messages)."""

    driver: Path
    primary: Path
    blade: Path
    dynamic: bool
    t_initial: float
    t_final: float
    dt: float
    gravity: tuple[float, float, float]
    origin: tuple[float, float, float]
    frame: np.ndarray
    root_velocity: tuple[float, float, float]
    distributed: tuple[float, ...]
    tip: tuple[float, ...]
    point_loads: int
    key_points: np.ndarray
    members: tuple[int, ...]
    order_elem: int
    quadrature: int
    refine: int
    rho_inf: float
    stations: tuple[Station, ...]
    damp_type: int
    damping: tuple[float, ...]
    lines: dict[str, tuple[Path, int]] = field(default_factory=dict)

    def where(self, key: str) -> str:
        """``FILE:LINE`` of ``key`` as read."""
        path, line = self.lines[key]
        return f"{path.name}:{line}"


# ====================================================================== the files' lines
#: The largest input file read [bytes] (BeamDyn's are a few hundred kB).
MAX_INPUT_BYTES = 1 << 26


class _Lines:
    """A text input file of OpenFAST's kind: lines of ``VALUE NAME - description``, tables,
    comments. Keys are found by NAME (the second word), so the sections' order and the
    comment lines do not matter; a missing or bad one is a SceneError naming file, line and
    key."""

    def __init__(self, path: Path) -> None:
        self.path = path
        if not is_file(path):  # a FIFO or a device is refused there, never opened (no hang)
            raise SceneError(f"{path}: cannot read (no such file)")
        check_size(path, MAX_INPUT_BYTES, "a BeamDyn input file")
        text = read_bytes(path, MAX_INPUT_BYTES).decode("utf-8", errors="replace")
        self.lines = text.splitlines()
        self.read: dict[str, tuple[Path, int]] = {}

    def fail(self, line: int | None, key: str, reason: str) -> SceneError:
        place = f"{self.path.name}:{line}" if line else self.path.name
        return SceneError(f"{place}: {key}: {reason}")

    def find(self, key: str) -> int | None:
        """The 0-based index of the line whose second word is ``key``, or None."""
        for i, text in enumerate(self.lines):
            words = text.split()
            if len(words) >= 2 and words[1] == key:
                return i
        return None

    def word(self, key: str, default: str | None = None) -> tuple[str, int]:
        """The value (first word) of ``key`` and its 1-based line."""
        i = self.find(key)
        if i is None:
            if default is not None:
                return default, 0
            raise self.fail(None, key, "not found (a line 'VALUE  " + key + "  - ...')")
        self.read[key] = (self.path, i + 1)
        return self.lines[i].split()[0], i + 1

    def number(self, key: str, default: float | None = None) -> float:
        text, line = self.word(key, None if default is None else repr(default))
        value = _float(text.strip('"'))
        if text.strip('"').upper() == "DEFAULT" and default is not None:
            return default
        if value is None:
            raise self.fail(line, key, f"expected a number, got {text!r}")
        return value

    def integer(self, key: str, default: int | None = None) -> int:
        value = self.number(key, None if default is None else float(default))
        if value != int(value):
            raise self.fail(self.read[key][1], key, f"expected a whole number, got {value!r}")
        return int(value)

    def flag(self, key: str, default: bool | None = None) -> bool:
        text, line = self.word(key, None if default is None else str(default))
        word = text.strip('"').upper()
        if word in ("T", "TRUE"):
            return True
        if word in ("F", "FALSE"):
            return False
        raise self.fail(line, key, f"expected a logical (True or False), got {text!r}")

    def string(self, key: str) -> str:
        text, line = self.word(key)
        full = self.lines[line - 1].strip()
        if full.startswith('"'):
            end = full.find('"', 1)
            if end > 0:
                return full[1:end]
        return text

    def numbers_after(self, start: int, count: int, width: int, key: str) -> list[list[float]]:
        """``count`` rows of ``width`` numbers from the 0-based line ``start`` on (blank lines
        skipped) and the index after them; SceneError naming the first bad row."""
        rows: list[list[float]] = []
        i = start
        while len(rows) < count:
            if i >= len(self.lines):
                raise self.fail(None, key, f"expected {count} rows of {width} numbers, file ends")
            words = self.lines[i].split()
            i += 1
            if not words:
                continue
            values = [_float(w) for w in words[:width]]
            if len(words) < width or any(v is None for v in values):
                raise self.fail(i, key, f"expected {width} numbers, got {self.lines[i - 1]!r}")
            rows.append([float(v) for v in values if v is not None])
        self.end = i
        return rows


def _float(text: str) -> float | None:
    """A finite float of Fortran's spellings (1.E4, 1.0D+03), or None."""
    try:
        value = float(text.replace("D", "E").replace("d", "e"))
    except ValueError:
        return None
    return value if math.isfinite(value) else None


# ================================================================================ reading
def read_case(driver: str | Path) -> BeamDynCase:
    """The BeamDyn case of the stand-alone driver input ``driver`` and the primary and blade
    files it names (relative to the file naming them). SceneError ``FILE:LINE: KEY: reason``
    for a missing or unreadable entry."""
    drv = _Lines(Path(driver))
    dynamic = drv.flag("DynamicSolve")
    t_initial, t_final, dt = (drv.number(k) for k in ("t_initial", "t_final", "dt"))
    gravity = tuple(drv.number(k) for k in ("Gx", "Gy", "Gz"))
    origin = tuple(drv.number(f"GlbPos({i})") for i in (1, 2, 3))
    dcm_at = drv.find("GlbPos(3)")
    assert dcm_at is not None, "read above"
    # the 3 rows of GlbDCM: the first three lines of three numbers after GlbPos(3)
    start = next(
        (i for i in range(dcm_at + 1, len(drv.lines)) if _row(drv.lines[i], 3)), len(drv.lines)
    )
    frame = np.array(drv.numbers_after(start, 3, 3, "GlbDCM"))
    drv.read["GlbDCM"] = (drv.path, start + 1)
    root_velocity = tuple(drv.number(f"RootVel({i})", 0.0) for i in (4, 5, 6))
    distributed = tuple(drv.number(f"DistrLoad({i})") for i in range(1, 7))
    tip = tuple(drv.number(f"TipLoad({i})") for i in range(1, 7))
    point_loads = drv.integer("NumPointLoads", 0)
    primary_path = drv.path.parent / drv.string("InputFile")

    pri = _Lines(primary_path)
    members_total = pri.integer("member_total")
    kp_total = pri.integer("kp_total")
    first = pri.find("kp_total")
    assert first is not None, "read above"
    member_rows = pri.numbers_after(first + 1, members_total, 2, "member_total")
    members = tuple(int(r[1]) for r in member_rows)
    if sum(members) - members_total + 1 != kp_total:
        raise pri.fail(
            pri.read["kp_total"][1],
            "kp_total",
            f"{kp_total} is not the members' key points {list(members)} less the shared "
            "ones (sum n_i - member_total + 1)",
        )
    # the key points: kp_total rows of 4 numbers after the two header lines (kp_xr ..., units)
    header = next((i for i in range(pri.end, len(pri.lines)) if "kp_xr" in pri.lines[i]), None)
    if header is None:
        raise pri.fail(
            None, "kp_xr", "the key points' table (header 'kp_xr kp_yr kp_zr') not found"
        )
    key_points = np.array(pri.numbers_after(header + 2, kp_total, 4, "kp_xr"))
    pri.read["kp_xr"] = (pri.path, header + 3)
    order_elem = pri.integer("order_elem")
    quadrature = pri.integer("quadrature", 1)
    refine = pri.integer("refine", 1)
    rho_inf = pri.number("rhoinf", 0.0)
    blade_path = pri.path.parent / pri.string("BldFile")

    bld = _Lines(blade_path)
    station_total = bld.integer("station_total")
    if station_total < 2:
        raise bld.fail(
            bld.read["station_total"][1],
            "station_total",
            f"at least 2 stations (the blade's root and tip), got {station_total}",
        )
    damp_type = bld.integer("damp_type", 0)
    mu_header = next((i for i, t in enumerate(bld.lines) if t.split()[:1] == ["mu1"]), None)
    damping: tuple[float, ...] = (0.0,) * 6
    if mu_header is not None:
        damping = tuple(bld.numbers_after(mu_header + 2, 1, 6, "mu1")[0])
        bld.read["mu1"] = (bld.path, mu_header + 3)
    props = next(
        (i for i, t in enumerate(bld.lines) if "distributed properties" in t.lower()), None
    )
    if props is None:
        raise bld.fail(None, "Distributed Properties", "the section's header line not found")
    stations = []
    at = props + 1
    for k in range(station_total):
        (eta,) = bld.numbers_after(at, 1, 1, f"station {k + 1} eta")[0]
        line = bld.end
        stiffness = np.array(bld.numbers_after(bld.end, 6, 6, f"station {k + 1} stiffness"))
        mass = np.array(bld.numbers_after(bld.end, 6, 6, f"station {k + 1} mass"))
        at = bld.end
        stations.append(Station(eta, stiffness, mass, line))
    lines = {**drv.read, **pri.read, **bld.read}
    return BeamDynCase(
        driver=drv.path,
        primary=pri.path,
        blade=bld.path,
        dynamic=dynamic,
        t_initial=t_initial,
        t_final=t_final,
        dt=dt,
        gravity=(gravity[0], gravity[1], gravity[2]),
        origin=(origin[0], origin[1], origin[2]),
        frame=frame,
        root_velocity=(root_velocity[0], root_velocity[1], root_velocity[2]),
        distributed=distributed,
        tip=tip,
        point_loads=point_loads,
        key_points=key_points,
        members=members,
        order_elem=order_elem,
        quadrature=quadrature,
        refine=refine,
        rho_inf=rho_inf,
        stations=tuple(stations),
        damp_type=damp_type,
        damping=damping,
        lines=lines,
    )


def _row(text: str, width: int) -> bool:
    """Whether ``text`` starts with ``width`` numbers."""
    words = text.split()
    return len(words) >= width and all(_float(w) is not None for w in words[:width])


# ================================================================================ geometry
@dataclass(frozen=True)
class Axis:
    """The reference axis of the key points: ``length`` [m], ``radius`` [m] for an arc (None:
    straight), and ``twist`` [rad] (BeamDyn's initial_twist, about −Z_r) as a number or an
    expression of s, or None (untwisted)."""

    length: float
    radius: float | None = None
    twist: float | str | None = None


def reference_axis(case: BeamDynCase) -> Axis:
    """The rest shape of the key points: a straight line along Z_r from the origin, twisted
    or not, or an untwisted circular arc in the X_r-Z_r plane leaving the origin along Z_r
    and bending towards +X_r (this code's ``arc``). BeamDyn fits its reference line and twist
    through each member's key points (a cubic spline, later a least-squares polynomial); for
    these shapes the line meant is the line or the circle, and the twist is taken linear
    between the key points (docs/beamdyn.md). Any other key points are refused naming the
    table."""
    kp = case.key_points
    where = case.where("kp_xr")
    points = kp[:, :3]
    if np.any(points[0] != 0.0):
        raise SceneError(f"{where}: kp_xr: the first key point (the root) must be the origin")
    chord = np.linalg.norm(points[-1])
    if chord == 0.0:
        raise SceneError(f"{where}: kp_zr: the key points do not leave the root")
    twisted = bool(np.any(kp[:, 3] != 0.0))
    if np.all(np.abs(points[:, :2]) <= SHAPE_TOLERANCE * chord) and np.all(
        np.diff(points[:, 2]) > 0
    ):
        length = float(points[-1, 2])
        twist = None
        if twisted:
            twist = piecewise_linear(points[:, 2] / length, np.radians(kp[:, 3]), length)
        return Axis(length, twist=twist)
    if twisted:
        row = int(np.flatnonzero(kp[:, 3])[0])
        raise SceneError(
            f"{where}: initial_twist: key point {row + 1} has a twist of {kp[row, 3]} deg; a "
            "twist is taken on a straight axis only in this version (docs/beamdyn.md)"
        )
    # a circle through the root tangent to e3 in the x-z plane: centre (R, 0, 0),
    # (x - R)^2 + z^2 = R^2, i.e. R = (x^2 + z^2) / (2 x) at every other key point
    x, y, z = points[1:, 0], points[1:, 1], points[1:, 2]
    if np.all(np.abs(y) <= SHAPE_TOLERANCE * chord) and np.all(x > 0.0):
        radii = (x**2 + z**2) / (2.0 * x)
        radius = float(radii[-1])
        angles = np.arctan2(z, radius - x)  # the angle turned at each key point
        if np.all(np.abs(radii - radius) <= SHAPE_TOLERANCE * radius) and np.all(
            np.diff(np.concatenate(([0.0], angles))) > 0.0
        ):
            return Axis(float(radius * angles[-1]), radius)
    raise SceneError(
        f"{where}: kp_xr: the key points are neither a straight line along kp_zr nor a "
        "circular arc leaving the root along kp_zr in the kp_xr-kp_zr plane bending to +kp_xr; "
        "other splines of key points are not taken in this version"
    )


# ================================================================================ sections
def piecewise_linear(eta: np.ndarray, values: np.ndarray, length: float) -> float | str:
    """f(s) interpolating ``values`` at s = η ℓ linearly between the stations, as BeamDyn
    interpolates its stations: a number if constant, else the expression
    v0 + m0 (s − s0) + Σ_k (m_k − m_{k−1}) ramp(s − s_k) (scene/expressions.py's ramp)."""
    if np.all(values == values[0]):
        return float(values[0])
    s = eta * length
    slopes = np.diff(values) / np.diff(s)
    terms = [f"{values[0]!r}", f"{slopes[0]!r}*s"]
    terms += [
        f"{slopes[k] - slopes[k - 1]!r}*ramp(s - {s[k]!r})"
        for k in range(1, len(slopes))
        if slopes[k] != slopes[k - 1]
    ]
    return " + ".join(terms).replace("+ -", "- ")


def _check_mass(case: BeamDynCase) -> None:
    """Refuse what the rod's inertia cannot hold: a mass centre off the axis (entries m Xcm,
    m Ycm) and a cross product of inertia i_cp, or unequal translational masses."""
    names = {
        (0, 5): "-m Ycm",
        (1, 5): "m Xcm",
        (2, 3): "m Ycm",
        (2, 4): "-m Xcm",
        (3, 4): "-i_cp",
    }
    for station in case.stations:
        M = station.mass
        scale = float(np.abs(M).max())
        for i in range(6):
            for j in range(i + 1, 6):
                if M[i, j] != 0.0 or M[j, i] != 0.0:
                    what = names.get((i, j), "a coupling the sectional mass matrix has not")
                    raise SceneError(
                        f"{case.blade.name}:{station.line}: mass[{i + 1}][{j + 1}] ({what}) = "
                        f"{M[i, j]!r}: a mass centre off the axis or a product of inertia is "
                        "not taken in this version (docs/beamdyn.md)"
                    )
        m = M[0, 0]
        if abs(M[1, 1] - m) > MASS_TOLERANCE * scale or abs(M[2, 2] - m) > MASS_TOLERANCE * scale:
            raise SceneError(
                f"{case.blade.name}:{station.line}: mass[1..3][1..3]: the three translational "
                f"masses differ ({M[0, 0]!r}, {M[1, 1]!r}, {M[2, 2]!r}); one m is taken"
            )


def section_table(case: BeamDynCase, length: float, inertia: bool = True) -> dict[str, Any]:
    """[rod.section] of the stations: the 6×6 stiffness, μ and (I11, I22, I33) as
    piecewise-linear expressions of s [m], and a "constants" shape whose ρ A, E c_ii, G c33
    are the root's (the shape gives the scaling (47) only; docs/sections.md §3). With
    ``inertia`` False (a static case without gravity, which no mass enters) the mass matrices
    are read and neither checked nor taken."""
    stations = case.stations
    eta = np.array([st.eta for st in stations])
    if eta[0] != 0.0 or eta[-1] != 1.0 or np.any(np.diff(eta) <= 0.0):
        raise SceneError(
            f"{case.blade.name}:{stations[0].line}: eta: the stations must rise from 0 to 1, "
            f"got {eta.tolist()}"
        )
    if inertia:
        _check_mass(case)
    K = np.array([st.stiffness for st in stations])
    M = np.array([st.mass for st in stations])
    rows = [[piecewise_linear(eta, K[:, i, j], length) for j in range(6)] for i in range(6)]
    table: dict[str, Any] = {
        "shape": "constants",
        "area": 1.0,
        "c11": float(K[0, 3, 3] / K[0, 2, 2]),
        "c22": float(K[0, 4, 4] / K[0, 2, 2]),
        "c33": float(K[0, 5, 5] / K[0, 0, 0]),
        "shear_coefficient": 1.0,
        "stiffness": rows,
    }
    if inertia and np.any(M != 0.0):
        table["mass_per_length"] = piecewise_linear(eta, M[:, 0, 0], length)
        table["inertia"] = [piecewise_linear(eta, M[:, k, k], length) for k in (3, 4, 5)]
    return table


# ================================================================================ the scene
def scene_of(case: BeamDynCase, name: str | None = None) -> dict[str, Any]:
    """The scene (TOML tables) of ``case``: the rod clamped at the root (at the origin: GlbPos,
    a translation of the whole blade, moves no displacement), its rest shape
    (:func:`reference_axis`), the section law of the stations (:func:`section_table`), the
    driver's dead loads (gravity as the force density μ(s) g), static load steps or the time
    span with BeamDyn's damping (:func:`_damping`), and the tip's directors among the probe's
    columns (for BeamDyn's TipRD). Refuses in one line what this rod cannot take
    (docs/beamdyn.md)."""
    frame = _blade_frame(case)
    if any(case.root_velocity):
        raise SceneError(
            f"{case.where('RootVel(4)')}: RootVel: a rotating root is not taken in this version"
        )
    if case.point_loads:
        raise SceneError(
            f"{case.where('NumPointLoads')}: NumPointLoads: point loads along the blade are not "
            "taken in this version"
        )
    axis = reference_axis(case)
    section = section_table(case, axis.length, case.dynamic or any(case.gravity))
    mass = section.get("mass_per_length")
    K0 = case.stations[0].stiffness
    gravity = _turned(frame, case.gravity)
    force: list[float | str] = list(_turned(frame, case.distributed[:3]))
    if any(gravity):
        if mass is None:
            raise SceneError(
                f"{case.where('Gx')}: Gx: gravity on a blade of zero mass (the mass matrices "
                f"of {case.blade.name} are zero)"
            )
        force = [_add(f, g, mass) for f, g in zip(force, gravity, strict=True)]
    rho = float(case.stations[0].mass[0, 0]) or 1.0  # the shape's ρ A: the root's μ (scaling)
    scene: dict[str, Any] = {
        "title": f"BeamDyn case {name or case.driver.parent.name} ({case.driver.name})",
        "rod": {
            "length": axis.length,
            "section": section,
            "material": {
                "density": rho,
                "young_modulus": float(K0[2, 2]),
                "shear_modulus": float(K0[0, 0]),
            },
        },
        "supports": {"start": "clamped", "end": "free"},
        "loads": {
            "force_density": force,
            "torque_density": _turned(frame, case.distributed[3:]),
            "end": {"force": _turned(frame, case.tip[:3]), "torque": _turned(frame, case.tip[3:])},
        },
        "discretisation": {"elements": ELEMENTS, "degree": DEGREE},
        "solver": {"max_iterations": 50},
        "output": {
            "directory": f"results/{name or case.driver.parent.name}",
            "probe_fields": ["directors"],
        },
    }
    if axis.radius is not None:
        scene["reference"] = {"shape": "arc", "radius": axis.radius}
    elif axis.twist is not None:  # d0_1 turned by the twist about -e3
        scene["reference"] = {
            "shape": "curve",
            "position": [0.0, 0.0, "s"],
            "director": [f"cos({axis.twist})", f"-sin({axis.twist})", 0.0],
        }
    if case.dynamic:
        if mass is None:
            raise SceneError(f"{case.where('DynamicSolve')}: DynamicSolve: a blade of zero mass")
        scene["time"] = {
            "start": 0.0,
            "end": case.t_final - case.t_initial,
            "step": case.dt,
            "integrator": "generalized-alpha",
            "rho_inf": case.rho_inf,
        }
        scene["damping"] = _damping(case)
    else:
        scene["static"] = {"load_steps": 20}
        scene["time"] = {"end": case.dt, "step": case.dt}
    return scene


def _blade_frame(case: BeamDynCase) -> np.ndarray:
    """The driver's GlbDCM, checked to be a proper rotation (orthonormal within FRAME_TOLERANCE,
    the inputs' 8 digits, determinant +1): row i is the blade axis i (X_r, Y_r, Z_r) in the
    global frame's components, so a vector's blade components are GlbDCM v_g. (Identified on
    r-test's bd_5MW_dynamic_gravity_Az90, GlbDCM rows (1, 0, 0), (0, 0, 1), (0, −1, 0) and
    gravity −9.8 m/s² along global Z, whose tip history is bd_5MW_dynamic_gravity_Az00's,
    gravity −9.8 along Y_r: the transpose would give +Y_r and the opposite swing.)"""
    D = np.asarray(case.frame, dtype=float)
    if np.abs(D @ D.T - np.eye(3)).max() > FRAME_TOLERANCE or np.linalg.det(D) < 0.0:
        raise SceneError(
            f"{case.where('GlbDCM')}: GlbDCM: not a rotation (orthonormal rows of determinant "
            f"+1), got {D.tolist()}"
        )
    return D


def _turned(frame: np.ndarray, vector) -> list[float]:
    """The blade components GlbDCM v of a vector ``vector`` given in the global frame."""
    return [float(c) + 0.0 for c in frame @ np.asarray(vector, dtype=float)]


def _add(force: float | str, g: float, mass: float | str) -> float | str:
    """force + μ(s) g [N/m], a number or an expression of s."""
    if g == 0.0:
        return force
    if isinstance(mass, float) and isinstance(force, float):
        return force + mass * g
    return f"{force!r} + {g!r}*({mass})"


def _damping(case: BeamDynCase) -> dict[str, Any]:
    """[damping] of BeamDyn's stiffness-proportional damping (damp_type 1), f_d = diag(μ) C ε̇:
    this code's Kelvin–Voigt law with the six retardation times μ_1..μ_6 [s], in the same
    strain order (forms/general_form.py KelvinVoigtDamping, which follows BeamDyn's diag(μ) C);
    damp_type 0 none; modal damping (2) and a negative μ_i are refused naming the entry."""
    if case.damp_type == 0:
        return {}
    if case.damp_type != 1:
        raise SceneError(
            f"{case.where('damp_type')}: damp_type: {case.damp_type} (modal damping) is not "
            "taken; 0 (none) and 1 (stiffness-proportional) are"
        )
    if "mu1" not in case.lines:
        raise SceneError(f"{case.blade.name}: mu1: damp_type 1 needs the six mu1..mu6")
    if any(mu < 0.0 for mu in case.damping):
        raise SceneError(
            f"{case.where('mu1')}: mu1: the damping coefficients must be >= 0 [s], got "
            f"{list(case.damping)}"
        )
    return {"retardation_time": list(case.damping)} if any(case.damping) else {}


# ================================================================================ outputs
def wiener_milenkovic(rotation: np.ndarray) -> np.ndarray:
    """BeamDyn's rotation parameters c = 4 tan(φ/4) n of the rotation matrix ``rotation``
    (angle φ about the unit axis n; TipRDxr..zr), from its unit quaternion (q0, q), q0 ≥ 0
    (Shepperd's method, common/rotations.py: accurate at every angle, a half turn
    included): c = 4 q/(1 + q0)."""
    q = quaternion_of_frame(np.asarray(rotation, dtype=float).T)  # R = Dᵀ: D = Rᵀ
    return 4.0 * q[1:] / (1.0 + q[0])


def tip_outputs(row: np.ndarray, rest_directors: np.ndarray) -> dict[str, np.ndarray]:
    """BeamDyn's TipTD (the tip's displacement [m]) and TipRD (the Wiener–Milenkovic
    parameters of its rotation from rest) of a probe row (λ or t, x, y, z, θ, ψ, φ, d1_x, ...,
    d3_z: the displacement and the directors, probe field "directors"), the directors at rest
    ``rest_directors`` (3, 3), rows d0_1, d0_2, d0_3."""
    D = np.asarray(row[7:16], dtype=float).reshape(3, 3)  # rows d1, d2, d3
    rotation = D.T @ np.asarray(rest_directors)  # R d0_i = d_i: R = Σ d_i ⊗ d0_i
    return {"TipTD": np.asarray(row[1:4], dtype=float), "TipRD": wiener_milenkovic(rotation)}


def tip_of(scene, row: np.ndarray) -> dict[str, np.ndarray]:
    """:func:`tip_outputs` of a probe row of ``scene`` (a resolved Scene), its directors at rest
    those of its reference at s = ℓ."""
    rest = scene.reference.frames(np.array([scene.rod.length]))[0]
    return tip_outputs(row, rest)
