#!/usr/bin/env python3
"""PyElastica model of the Cao & Tucker (2008) cantilever (peer code for the
cosserat-fem work-precision benchmark).

Runs in its OWN virtual environment (see setup.sh); it must not import
cosserat_fem or dolfinx.

Problem (SI units)
------------------
* straight rod along +e3 from the origin, length l = 1 m, N elements;
  PyElastica directors: d1 = e1 (``normal``), d2 = d3 x d1 = e2, d3 = e3 (tangent).
  The lab frame of the simulation IS the output frame (x along e1, y along e2,
  z along e3), so no rotation of the output is needed.
* rectangular section a = 0.04 m (along d1) x b = 0.06 m (along d2),
  E = 7.1e10 Pa, nu = 0.32, G = E / (2 (1 + nu)), kappa_s = 0.833,
  J = 7.5172112e-7 m^4, rho = 2730 kg/m^3;
  bend/twist matrix B = diag(E I1, E I2, G J) with I1 = a b^3 / 12 (about d1),
  I2 = b a^3 / 12 (about d2); shear/stretch matrix S = diag(kGA, kGA, EA);
  mass second moment per unit length diag(rho I1, rho I2, rho (I1 + I2)).
* clamp: OneEndFixedBC on node 0 (position) and element 0 (directors).
* load: f_x = f_y = 2e3 sin(pi s / l) sin(8 w0 t) N/m, w0 = 207.0236 rad/s,
  lumped to the nodes as f(s_i, t) * (tributary length of node i), i.e. h/2
  for the two end nodes and h for interior nodes (nodal-quadrature lumping;
  sin(pi s/l) vanishes at both ends so the end nodes carry no load).
* no damping; PositionVerlet time stepper.

Output: CSV ``t,x,y,z`` of the free-end node displacement every 1e-5 s (exact
samples when 1e-5 / dt is an integer, otherwise cubic Hermite interpolation
between the two bracketing steps using node positions and velocities), plus a
JSON timing record next to the CSV.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time as _time

import elastica as ea
import numpy as np

# ----------------------------------------------------------------------------
# Problem data
# ----------------------------------------------------------------------------
LENGTH = 1.0
A_THICK = 0.04  # along d1 (e1)
B_WIDTH = 0.06  # along d2 (e2)
AREA = A_THICK * B_WIDTH
I1 = A_THICK * B_WIDTH**3 / 12.0  # about d1  -> bending with displacement along e2
I2 = B_WIDTH * A_THICK**3 / 12.0  # about d2  -> bending with displacement along e1 (soft)
J_TORSION = 7.5172112e-7
YOUNG = 7.1e10
POISSON = 0.32
SHEAR_MOD = YOUNG / (2.0 * (1.0 + POISSON))
KAPPA_SHEAR = 0.833
DENSITY = 2730.0
OMEGA0 = 207.0236
F_AMPL = 2.0e3
SAMPLE_DT = 1.0e-5


class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.CallBacks, ea.Damping):
    pass


class DistributedHarmonicLoad(ea.NoForces):
    """f_x = f_y = F sin(pi s / l) sin(8 w0 t) per unit length, lumped to nodes.

    ``weights[i] = F sin(pi s_i / l) * w_i`` where w_i is the tributary (Voronoi)
    length of node i in the reference configuration (h/2 at the ends, h inside).
    The force is a dead load in the lab frame (PyElastica's ``external_forces``
    are lab-frame nodal forces).
    """

    def __init__(self, weights: np.ndarray, omega: float):
        super().__init__()
        self.weights = np.asarray(weights, dtype=np.float64)
        self.omega = float(omega)

    def apply_forces(self, system, time=0.0):
        amp = math.sin(self.omega * float(time))
        f = self.weights * amp
        system.external_forces[0, :] += f
        system.external_forces[1, :] += f


class TipForce(ea.NoForces):
    """Constant lab-frame force on the last node (static verification)."""

    def __init__(self, force):
        super().__init__()
        self.force = np.asarray(force, dtype=np.float64)

    def apply_forces(self, system, time=0.0):
        system.external_forces[:, -1] += self.force


def override_section(rod: ea.CosseratRod, n: int) -> None:
    """Replace PyElastica's circular-section defaults by the rectangular section.

    Conventions (PyElastica 1.0.0, rod/factory_function.py):
      * ``shear_matrix`` (3,3,n_elems): per element, in the director frame,
        NOT scaled by element length: default diag(27/28 G A, 27/28 G A, E A).
      * ``bend_matrix`` (3,3,n_elems-1): on the interior Voronoi nodes, length-
        weighted average of the element values, NOT scaled by length:
        default diag(E I, E I, G 2I).
      * ``mass_second_moment_of_inertia`` (3,3,n_elems): per ELEMENT, i.e.
        rho * I * rest_length (not per unit length); inverse stored separately.
      * ``mass`` (n_nodes): rho * volume / 2 from each adjacent element with
        volume = pi r^2 l; we pass base_radius = sqrt(A / pi) so volume and the
        nodal masses are already rho A h (/2 at the ends); we reset them anyway.
    Must be done BEFORE ``finalize()``: finalize copies the rod arrays into a
    memory block and turns the rod attributes into views of it.
    """
    h = rod.rest_lengths.copy()
    shear = np.diag([KAPPA_SHEAR * SHEAR_MOD * AREA, KAPPA_SHEAR * SHEAR_MOD * AREA, YOUNG * AREA])
    bend = np.diag([YOUNG * I1, YOUNG * I2, SHEAR_MOD * J_TORSION])
    jmass = np.diag([DENSITY * I1, DENSITY * I2, DENSITY * (I1 + I2)])
    rod.shear_matrix[...] = shear[:, :, None]
    rod.bend_matrix[...] = bend[:, :, None]
    rod.mass_second_moment_of_inertia[...] = jmass[:, :, None] * h[None, None, :]
    for k in range(n):
        rod.inv_mass_second_moment_of_inertia[..., k] = np.linalg.inv(
            rod.mass_second_moment_of_inertia[..., k]
        )
    mass = np.zeros(n + 1)
    mass[:-1] += 0.5 * DENSITY * AREA * h
    mass[1:] += 0.5 * DENSITY * AREA * h
    rod.mass[:] = mass
    # volume only feeds the mass (already set) and the (unused) radius update
    rod.volume[:] = AREA * h


def build(n: int, *, tip_force=None, damping=None, dt=None, shift_clamp=False):
    """Create a finalized simulator for the cantilever with n elements.

    ``shift_clamp`` (NOT the default, not PyElastica's usual set-up): PyElastica's
    clamp acts, to second order, at the centre of element 0 (s = h/2).  With
    ``shift_clamp`` the rod is built from z = -h/2 with h = l / (n - 1/2), so
    the effective clamp sits at z = 0 and the free end at z = l.
    """
    sim = Simulator()
    if shift_clamp:
        h = LENGTH / (n - 0.5)
        start, base_length = np.array([0.0, 0.0, -0.5 * h]), n * h
    else:
        start, base_length = np.zeros(3), LENGTH
    rod = ea.CosseratRod.straight_rod(
        n,
        start=start,
        direction=np.array([0.0, 0.0, 1.0]),
        normal=np.array([1.0, 0.0, 0.0]),
        base_length=base_length,
        base_radius=math.sqrt(AREA / math.pi),
        density=DENSITY,
        youngs_modulus=YOUNG,
        shear_modulus=SHEAR_MOD,
    )
    # sanity: directors d1=e1, d2=e2, d3=e3 (rows of director_collection)
    assert np.allclose(rod.director_collection[..., 0], np.eye(3))
    override_section(rod, n)
    sim.append(rod)
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    if tip_force is None:
        s = rod.position_collection[2].copy()  # arc length from the (effective) clamp
        h = rod.rest_lengths[0]
        trib = np.full(n + 1, h)
        trib[0] = trib[-1] = 0.5 * h
        weights = np.where(s > 0.0, F_AMPL * np.sin(np.pi * s / LENGTH), 0.0) * trib
        sim.add_forcing_to(rod).using(DistributedHarmonicLoad, weights, 8.0 * OMEGA0)
    else:
        sim.add_forcing_to(rod).using(TipForce, tip_force)
    if damping is not None:
        sim.dampen(rod).using(
            ea.AnalyticalLinearDamper, uniform_damping_constant=damping, time_step=dt
        )
    sim.finalize()
    return sim, rod


class NonFinite(RuntimeError):
    pass


def simulate(n, dt, end, *, sample_dt=SAMPLE_DT, record=True, blowup=1.0, shift_clamp=False):
    """Integrate from rest to ``end``.

    Returns (samples[t,x,y,z] or None, steps, wall_s, ok).  ``ok`` is False if
    the tip displacement became non-finite or exceeded ``blowup`` metres
    (checked at every sample time; the run stops there).
    """
    sim, rod = build(n, shift_clamp=shift_clamp)
    stepper = ea.PositionVerlet()
    pos = rod.position_collection  # view into the memory block
    vel = rod.velocity_collection
    x0 = pos[:, -1].copy()
    steps = int(round(end / dt))
    if abs(steps * dt - end) > 1e-9 * max(end, 1.0):
        steps = int(math.ceil(end / dt - 1e-9))
    n_samples = int(round(end / sample_dt)) + 1
    ratio = sample_dt / dt
    k_int = int(round(ratio))
    exact = abs(ratio - k_int) < 1e-9 * ratio and k_int >= 1
    out = np.empty((n_samples, 4)) if record else None
    if record:
        out[0] = (0.0, 0.0, 0.0, 0.0)
    next_sample = 1
    t = np.float64(0.0)
    ok = True
    t_start = _time.perf_counter()
    if exact:
        check_every = k_int
        for i in range(1, steps + 1):
            t = stepper.step(sim, t, dt)
            if i % check_every == 0:
                d = pos[:, -1] - x0
                if not (np.all(np.isfinite(d)) and np.max(np.abs(d)) <= blowup):
                    ok = False
                    break
                if record and next_sample < n_samples:
                    out[next_sample, 0] = round(next_sample * sample_dt, 12)
                    out[next_sample, 1:] = d
                    next_sample += 1
    else:
        # cubic Hermite interpolation between the two steps bracketing each
        # sample time (positions and velocities of the free-end node); the
        # state is copied only on the steps that are needed.
        times = np.round(np.arange(n_samples) * sample_dt, 12)
        hit = np.ceil(times / dt - 1e-9).astype(np.int64)  # first step with t_i >= t_j
        j = 1
        p_old = pos[:, -1].copy()
        v_old = vel[:, -1].copy()
        need_prev = hit[j] - 1 if n_samples > 1 else -1
        need_hit = hit[j] if n_samples > 1 else -1
        for i in range(1, steps + 1):
            t = stepper.step(sim, t, dt)
            if i == need_hit:
                p_new = pos[:, -1].copy()
                v_new = vel[:, -1].copy()
                if not (np.all(np.isfinite(p_new)) and np.max(np.abs(p_new - x0)) <= blowup):
                    ok = False
                    break
                t_old = (i - 1) * dt
                while j < n_samples and hit[j] == i:
                    u = (times[j] - t_old) / dt
                    h00 = 2 * u**3 - 3 * u**2 + 1
                    h10 = u**3 - 2 * u**2 + u
                    h01 = -2 * u**3 + 3 * u**2
                    h11 = u**3 - u**2
                    p = h00 * p_old + h10 * dt * v_old + h01 * p_new + h11 * dt * v_new
                    if record:
                        out[j, 0] = times[j]
                        out[j, 1:] = p - x0
                    j += 1
                next_sample = j
                if j < n_samples:
                    need_prev, need_hit = hit[j] - 1, hit[j]
                    if need_prev == i:
                        p_old, v_old = p_new, v_new
                else:
                    need_prev = need_hit = -1
            elif i == need_prev:
                p_old = pos[:, -1].copy()
                v_old = vel[:, -1].copy()
    wall = _time.perf_counter() - t_start
    if ok:
        d = pos[:, -1] - x0
        ok = bool(np.all(np.isfinite(d)) and np.max(np.abs(d)) <= blowup)
    if record and out is not None:
        out = out[:next_sample]
    return out, steps, wall, ok


def static_check(n=40, force=100.0, dt=None, end=0.3, damping=200.0, shift_clamp=False):
    """Tip-force static deflection (damped dynamic relaxation), both directions."""
    if dt is None:
        dt = 2.0e-6
    res = {}
    for comp, vec in (("x", (force, 0.0, 0.0)), ("y", (0.0, force, 0.0))):
        sim, rod = build(n, tip_force=vec, damping=damping, dt=dt, shift_clamp=shift_clamp)
        stepper = ea.PositionVerlet()
        t = np.float64(0.0)
        x0 = rod.position_collection[:, -1].copy()
        for _ in range(int(round(end / dt))):
            t = stepper.step(sim, t, dt)
        d = rod.position_collection[:, -1] - x0
        EI = YOUNG * (I2 if comp == "x" else I1)
        expected = force * LENGTH**3 / (3 * EI) + force * LENGTH / (KAPPA_SHEAR * SHEAR_MOD * AREA)
        h = LENGTH / n
        # the clamp effectively sits at s = h/2 (see README): effective length l - h/2
        le = LENGTH - h / 2
        expected_shift = force * le**3 / (3 * EI) + force * le / (KAPPA_SHEAR * SHEAR_MOD * AREA)
        res[comp] = {
            "tip_displacement": d.tolist(),
            "expected_beam_theory": expected,
            "expected_clamp_at_h_over_2": expected_shift,
            "rel_err": float(d["xy".index(comp)] / expected - 1.0),
            "rel_err_vs_shifted_clamp": float(d["xy".index(comp)] / expected_shift - 1.0),
        }
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elements", "-N", type=int, default=40)
    ap.add_argument("--dt", type=float, default=1.0e-6)
    ap.add_argument("--end", type=float, default=0.06)
    ap.add_argument("--out", type=str, default=None, help="CSV output path")
    ap.add_argument(
        "--warmup",
        action="store_true",
        help="run a tiny simulation first so numba JIT is excluded from wall_s",
    )
    ap.add_argument(
        "--static-check",
        action="store_true",
        help="verify static tip deflections against beam theory and exit",
    )
    ap.add_argument(
        "--shift-clamp",
        action="store_true",
        help="non-standard variant: build the rod from z=-h/2 so that PyElastica's "
        "effective clamp (centre of element 0) sits at z=0",
    )
    args = ap.parse_args(argv)

    if args.static_check:
        print(json.dumps(static_check(n=args.elements, shift_clamp=args.shift_clamp), indent=1))
        return 0

    compile_s = None
    if args.warmup:
        t0 = _time.perf_counter()
        simulate(args.elements, args.dt, 20 * args.dt, record=False, shift_clamp=args.shift_clamp)
        compile_s = _time.perf_counter() - t0

    samples, steps, wall, ok = simulate(
        args.elements, args.dt, args.end, shift_clamp=args.shift_clamp
    )
    rec = {
        "code": "pyelastica",
        "pyelastica": _pe_version(),
        "elements": args.elements,
        "dt": args.dt,
        "end": args.end,
        "steps": steps,
        "wall_s": wall,
        "compile_s": compile_s,
        "stable": ok,
        "shift_clamp": bool(args.shift_clamp),
    }
    if samples is not None and len(samples):
        rec["max_abs_x"] = float(np.max(np.abs(samples[:, 1])))
        rec["max_abs_y"] = float(np.max(np.abs(samples[:, 2])))
        rec["min_z"] = float(np.min(samples[:, 3]))
        rec["max_z"] = float(np.max(samples[:, 3]))
    print(json.dumps(rec))
    if args.out:
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        np.savetxt(args.out, samples, delimiter=",", header="t,x,y,z", comments="", fmt="%.16e")
        with open(os.path.splitext(args.out)[0] + ".json", "w") as fh:
            json.dump(rec, fh, indent=1)
    return 0 if ok else 2


def _pe_version():
    try:
        from importlib.metadata import version

        return version("pyelastica")
    except Exception:  # pragma: no cover
        return "unknown"


if __name__ == "__main__":
    sys.exit(main())
