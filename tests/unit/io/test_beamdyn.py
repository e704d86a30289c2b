"""Unit tests of cosserat_fem/io/beamdyn.py, BeamDyn's input files read into a scene: the
entries read (against the files' text in tests/data/beamdyn/), the rest shape of the key
points (line, circle, refused), the stations' piecewise-linear law as an expression of s
(against numpy's interp), the mass matrix's refusals, BeamDyn's rotation parameters, and
one-line messages naming file, line and key.

Tolerances: entries are exact (float of the text); the circle's radius and length to 1e-12 of
the closed form of three points; an expression's evaluation against np.interp to 1e-12
relative (the ramp sum's round-off); the Wiener–Milenkovic parameters to 1e-13 (a quaternion
of a rotation matrix built from the same angle).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.beamdyn import (
    piecewise_linear,
    read_case,
    reference_axis,
    scene_of,
    section_table,
    wiener_milenkovic,
)
from cosserat_fem.scene.expressions import Expression

pytestmark = pytest.mark.unit

DATA = Path(__file__).resolve().parents[2] / "data" / "beamdyn"


def test_the_three_files_are_read():
    """bd_curved_beam: the driver's tip force, the primary's key points and element order,
    the blade's two stations with their 6×6 matrices and damping, the lines of the keys."""
    case = read_case(DATA / "bd_curved_beam" / "bd_driver.inp")
    assert not case.dynamic and case.dt == 0.002
    assert case.tip == (0.0, 600.0, 0.0, 0.0, 0.0, 0.0)
    assert case.gravity == (0.0, 0.0, 0.0) and np.array_equal(case.frame, np.eye(3))
    assert case.members == (3,) and case.order_elem == 10 and case.quadrature == 1
    assert case.key_points[2].tolist() == [29.2893, 0.0, 70.7107, 0.0]
    assert [st.eta for st in case.stations] == [0.0, 1.0]
    assert (
        case.stations[1].stiffness[0, 0] == 41.6667e5
        and case.stations[1].stiffness[5, 5] == 8.333e5
    )
    assert not case.stations[0].mass.any()
    assert case.damp_type == 1 and case.damping == (1e-3,) * 6
    assert case.where("TipLoad(2)") == "bd_driver.inp:34"
    assert case.where("kp_xr") == "bd_primary.inp:25"


def test_the_rest_shapes_of_the_key_points():
    """A straight line along Z: its length; three points of a circle leaving the root along Z
    bending to +X: the circle (R from the last point, R (x² + z²)/(2x)); else refused."""
    straight = read_case(DATA / "bd_isotropic_rollup" / "bd_driver.inp")
    assert reference_axis(straight) == type(reference_axis(straight))(10.0)
    curved = read_case(DATA / "bd_curved_beam" / "bd_driver.inp")
    axis = reference_axis(curved)
    radius = (29.2893**2 + 70.7107**2) / (2 * 29.2893)
    assert axis.radius == pytest.approx(radius, rel=1e-12)
    assert axis.length == pytest.approx(radius * math.atan2(70.7107, radius - 29.2893), rel=1e-12)
    bent = curved.key_points.copy()
    bent[1, 0] = 9.0  # off the circle by 1.4 m
    with pytest.raises(SceneError, match=r"^bd_primary.inp:25: kp_xr: the key points are neither"):
        reference_axis(dataclasses.replace(curved, key_points=bent))
    twisted = curved.key_points.copy()
    twisted[2, 3] = 5.0
    with pytest.raises(SceneError, match=r"^bd_primary.inp:25: initial_twist: key point 3"):
        reference_axis(dataclasses.replace(curved, key_points=twisted))


def test_the_five_mw_blade_twist_and_damping():
    """bd_5MW_dynamic_gravity_Az00: 49 key points on Z_r with a twist of 13.308° at the root
    to 0 at the tip, read as an expression of s equal to the key points' twist [rad] at each
    key point (1e-12); its rest frame a curve with d0_1 = (cos φ, −sin φ, 0); the six unequal
    damping coefficients μ = (1, 1, 1, 1.4, 2.2, 2.2)e-3 s taken as the six retardation times
    as they are (same strain order); modal damping and a negative μ_i refused naming the
    entry."""
    case = read_case(DATA / "bd_5MW_dynamic_gravity_Az00" / "bd_driver.inp")
    assert len(case.stations) == 49 and case.dynamic and case.origin == (0.0, 0.0, 1.0)
    axis = reference_axis(case)
    assert axis.length == 61.5 and isinstance(axis.twist, str)
    z, twist = case.key_points[:, 2], np.radians(case.key_points[:, 3])
    got = Expression.parse(axis.twist, {"s"}).evaluate(s=z)
    np.testing.assert_allclose(got, twist, rtol=0, atol=1e-12)
    scene = scene_of(case)
    assert scene["damping"] == {"retardation_time": [1e-3, 1e-3, 1e-3, 1.4e-3, 2.2e-3, 2.2e-3]}
    assert scene["reference"]["director"][1] == f"-sin({axis.twist})"
    negative = dataclasses.replace(case, damping=(1e-3, 1e-3, -1e-3, 1.4e-3, 2.2e-3, 2.2e-3))
    with pytest.raises(SceneError, match=r"^beam_props.inp:9: mu1: the damping coefficients"):
        scene_of(negative)
    with pytest.raises(SceneError, match=r"^beam_props.inp:5: damp_type: 2 \(modal"):
        scene_of(dataclasses.replace(case, damp_type=2))


def test_stations_are_piecewise_linear_in_s():
    """Four stations at uneven η: the expression of s equals np.interp at 201 points; a
    constant entry is a number."""
    eta = np.array([0.0, 0.2, 0.7, 1.0])
    values = np.array([5.0, 4.0, 1.5, 1.0])
    text = piecewise_linear(eta, values, 20.0)
    assert isinstance(text, str)
    s = np.linspace(0.0, 20.0, 201)
    got = Expression.parse(text, {"s"}).evaluate(s=s)
    np.testing.assert_allclose(got, np.interp(s, eta * 20.0, values), rtol=1e-12, atol=0)
    assert piecewise_linear(eta, np.full(4, 3.0), 20.0) == 3.0


def test_the_section_table_of_the_rollup():
    """The isotropic beam: the stiffness as given, μ = 1, (I11, I22, I33) = (1, 1, 2); the
    "constants" shape of the root: E c11 = K44, G A κ = K11, G c33 = K66."""
    case = read_case(DATA / "bd_isotropic_rollup" / "bd_driver.inp")
    table = section_table(case, 10.0)
    assert table["stiffness"][3][3] == 100.0 and table["stiffness"][5][5] == 200.0
    assert table["mass_per_length"] == 1.0 and table["inertia"] == [1.0, 1.0, 2.0]
    assert table["c11"] * 1e4 == 100.0 and table["c33"] * 1e4 == 200.0


def test_a_mass_centre_off_the_axis_is_refused_naming_the_entry():
    """A mass matrix with m Xcm (entry (2, 6)): one line naming the blade file's line and
    the entry."""
    case = read_case(DATA / "bd_isotropic_rollup" / "bd_driver.inp")
    station = case.stations[1]
    mass = station.mass.copy()
    mass[1, 5] = mass[5, 1] = 0.3
    moved = dataclasses.replace(station, mass=mass)
    odd = dataclasses.replace(case, stations=(case.stations[0], moved))
    with pytest.raises(SceneError, match=r"^beam_props.inp:\d+: mass\[2\]\[6\] \(m Xcm\) = 0.3"):
        section_table(odd, 10.0)


def test_driver_entries_the_rod_cannot_take_are_refused():
    """A reflected global frame (GlbDCM of determinant −1), a rotating root, point loads: one
    line each naming the key (a root moved by GlbPos is taken: a translation moves no
    displacement)."""
    case = read_case(DATA / "bd_isotropic_rollup" / "bd_driver.inp")
    frame = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    for change, key in (
        ({"frame": frame}, "GlbDCM"),
        ({"root_velocity": (0.0, 0.0, 1.0)}, "RootVel"),
        ({"point_loads": 1}, "NumPointLoads"),
    ):
        with pytest.raises(SceneError, match=rf"^bd_driver.inp:\d+: {key}"):
            scene_of(dataclasses.replace(case, **change))


def test_a_rotated_global_frame_turns_the_drivers_vectors():
    """GlbDCM rows (0, 1, 0), (−1, 0, 0), (0, 0, 1) (a quarter turn about Z): the tip force
    (1, 2, 3) N and torque (4, 5, 6) N m and the distributed force (7, 8, 9) N/m given in the
    global frame are GlbDCM v in the blade frame, (2, −1, 3), (5, −4, 6), (8, −7, 9); rows
    skewed by 1e-3 (not orthonormal) are refused naming GlbDCM."""
    case = read_case(DATA / "bd_isotropic_rollup" / "bd_driver.inp")
    frame = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    turned = dataclasses.replace(
        case, frame=frame, tip=(1.0, 2.0, 3.0, 4.0, 5.0, 6.0), distributed=(7.0, 8.0, 9.0, 0, 0, 0)
    )
    loads = scene_of(turned)["loads"]
    assert loads["end"] == {"force": [2.0, -1.0, 3.0], "torque": [5.0, -4.0, 6.0]}
    assert loads["force_density"] == [8.0, -7.0, 9.0]
    skewed = frame + np.array([[0.0, 0.0, 1e-3], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    with pytest.raises(SceneError, match=r"^bd_driver.inp:\d+: GlbDCM: not a rotation"):
        scene_of(dataclasses.replace(case, frame=skewed))


def test_a_static_case_without_gravity_takes_no_mass():
    """bd_static_twisted_with_k1: its mass matrices put the mass centre 1.7e-4 m off the axis
    (m Ycm = 0.1154 kg), which no static case without gravity feels: the scene has no mass
    and the twist is the key points' 0 to 90°; with gravity the offset is refused naming the
    entry."""
    case = read_case(DATA / "bd_static_twisted_with_k1" / "bd_driver.inp")
    scene = scene_of(case)
    assert "mass_per_length" not in scene["rod"]["section"]
    assert scene["reference"]["director"][0] == f"cos({reference_axis(case).twist})"
    twist = Expression.parse(reference_axis(case).twist, {"s"}).evaluate(s=np.array([0.0, 10.0]))
    np.testing.assert_allclose(twist, [0.0, math.pi / 2], atol=1e-12)
    with pytest.raises(SceneError, match=r"^beam_props.inp:\d+: mass\[1\]\[6\] \(-m Ycm\)"):
        scene_of(dataclasses.replace(case, gravity=(0.0, -9.8, 0.0)))


def test_gravity_is_the_weight_of_the_stations():
    """bd_static_cantilever_beam: gravity 9.806 m/s² along X on μ = 1 kg/m is a force
    density of 9.806 N/m along X (not the shape's ρ A g)."""
    case = read_case(DATA / "bd_static_cantilever_beam" / "bd_driver.inp")
    scene = scene_of(case)
    assert scene["loads"]["force_density"] == [9.806, 0.0, 0.0]
    assert "gravity" not in scene["loads"]


@pytest.mark.parametrize("angle", [0.3, 1.25664, 3.0])
def test_wiener_milenkovic_parameters(angle):
    """c = 4 tan(φ/4) n of the rotation by φ about n = (1, 2, 2)/3."""
    n = np.array([1.0, 2.0, 2.0]) / 3.0
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    R = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    np.testing.assert_allclose(wiener_milenkovic(R), 4 * math.tan(angle / 4) * n, atol=1e-13)


def test_a_missing_file_and_a_missing_key_are_one_line(tmp_path):
    """A driver naming a primary file that is not there; a driver without Gx."""
    text = (DATA / "bd_isotropic_rollup" / "bd_driver.inp").read_text()
    (tmp_path / "bd_driver.inp").write_text(text)
    with pytest.raises(SceneError, match=r"bd_primary.inp: cannot read"):
        read_case(tmp_path / "bd_driver.inp")
    (tmp_path / "bd_driver.inp").write_text(text.replace(" Gx ", " G_x "))
    with pytest.raises(SceneError, match=r"^bd_driver.inp: Gx: not found"):
        read_case(tmp_path / "bd_driver.inp")


@pytest.mark.parametrize("angle", [math.pi - 1e-9, math.pi])
def test_wiener_milenkovic_near_a_half_turn_keeps_the_axis_signs(angle):
    """About n = (1, −1, 0)/√2 by φ within 1e-8 of π (q0 < 1e-8: the axis from n nᵀ = (R + I)/2,
    its largest diagonal entry's row giving the others' signs): c = 4 tan(φ/4) n to 1e-7 (the
    branch takes φ = π; 4 tan(φ/4) changes by 2e-9 over the 1e-9 left). Before, every
    component came out positive: (2.83, +2.83, 0) (review of 2026-12-04)."""
    from scipy.spatial.transform import Rotation

    n = np.array([1.0, -1.0, 0.0]) / math.sqrt(2.0)
    R = Rotation.from_rotvec(angle * n).as_matrix()
    np.testing.assert_allclose(wiener_milenkovic(R), 4.0 * math.tan(angle / 4.0) * n, atol=1e-7)


def test_bad_station_totals_and_a_fifo_are_one_line(tmp_path):
    """station_total < 2 in the blade file: one line naming its file, line and key (before:
    an internal IndexError); a blade file that is a FIFO: refused, never opened (no hang)."""
    import os
    import shutil

    case = tmp_path / "case"
    shutil.copytree(DATA / "bd_isotropic_rollup", case)
    blade = case / "beam_props.inp"
    lines = blade.read_text().splitlines()
    at = next(i for i, t in enumerate(lines) if t.split()[1:2] == ["station_total"])
    lines[at] = "0   station_total   - Number of blade input stations (-)"
    blade.write_text("\n".join(lines) + "\n")
    with pytest.raises(SceneError, match=rf"^beam_props.inp:{at + 1}: station_total: at least 2"):
        read_case(case / "bd_driver.inp")
    blade.unlink()
    os.mkfifo(blade)
    with pytest.raises(SceneError, match=r"beam_props.inp': is not a regular file"):
        read_case(case / "bd_driver.inp")
