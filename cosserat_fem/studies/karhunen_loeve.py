"""Proper orthogonal decomposition (Karhunen–Loève modes) of a run's response: ``cf.pod`` and
``cosserat-fem pod`` (the module is not named pod.py: ``cosserat_fem.pod`` is the API's
function, which a submodule of that name would shadow once imported).

The paper's last section proposes reduced models by the Karhunen–Loève method; this module
gives the modes, their energies and their time coefficients from snapshots u_i = u(·, t_i),
i = 1..T, of the rod's fields at its output times (docs/pod.md).

**Inner product.** Fields are functions of the arc length s [m] with C components (x, y, z
[m]; with the kinetic weighting also θ, ψ, φ [rad]). Their inner product is the L² product
along the rod with a weight per component,

    ⟨u, v⟩ = ∫₀^ℓ Σ_c w_c u_c(s) v_c(s) ds  ≈  Σ_j q_j Σ_c w_c u_c(s_j) v_c(s_j),

q_j the trapezoidal weights of the stations s_j (the L² product of the piecewise linear
interpolant, lumped; so the modes and energies converge as the stations are refined and do
not depend on how they are spaced). Weightings (``weighting``):

* ``"displacement"`` (default): x, y, z with w_c = 1; energies in m³ (m² of displacement
  times m of rod).
* ``"kinetic"``: x, y, z with w = ρA [kg/m] and θ, ψ, φ with ρ c11, ρ c22, ρ I3 [kg m] (the
  weights of the kinetic energy, as cosserat_fem/analysis/modal.py classifies modes): the mass inner
  product of the linearised rod, for which the POD modes of a free vibration are its normal
  modes (Feeny & Kappagantu 1998); energies in kg m².

**Correlation operator and eigenproblem.** With the mean ū = (1/T) Σ_i u_i removed (the
Karhunen–Loève convention; ``remove_mean=False`` keeps it), the spatial correlation operator
R φ = (1/T) Σ_i u_i ⟨u_i, φ⟩ has eigenpairs R φ_k = λ_k φ_k, λ_1 ≥ λ_2 ≥ ... ≥ 0, ⟨φ_k, φ_l⟩
= δ_kl. The method of snapshots solves the T × T problem C a = λ a with C_ik = (1/T)
⟨u_i, u_k⟩; here through the SVD of A_{i,(j,c)} = √(q_j w_c / T) u_c(s_j, t_i) = U Σ Vᵀ
(C = A Aᵀ, so λ_k = σ_k², the eigenvectors of C are U's columns), which keeps the small
energies accurate to round-off of the large ones instead of its square. Then

    φ_k(s_j)_c = V_{(j,c),k} / √(q_j w_c),    a_k(t_i) = ⟨u_i − ū, φ_k⟩ = √T σ_k U_ik,

and λ_k = (1/T) Σ_i a_k(t_i)², the mean square of mode k's coefficient: its "energy".
Fractions are λ_k / Σ_all λ (the total Σ λ = (1/T) Σ_i ‖u_i − ū‖²), cumulative their running
sums. Sign convention: each shape's component of largest magnitude is positive.

Snapshots come from the Python API's run result (``cf.run(scene, fields=stations)``) or from
a run folder's XDMF output (:func:`read_run`; read with h5py, which cannot share a process
with DOLFINx: in a process that has loaded DOLFINx the folder is read by a child process).
:func:`write_pod` writes pod.csv, pod.xdmf (+ pod.frames/) and pod.png. No DOLFINx here.
Tests: tests/test_pod.py.
"""

from __future__ import annotations

import csv
import io
import math
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import CosseratError, SceneError
from cosserat_fem.io.probes import PROBE_COLUMNS
from cosserat_fem.io.xdmf import xdmf_mesh_xml

WEIGHTINGS = ("displacement", "kinetic")
#: Components of the snapshots: displacement (x, y, z) [m], angles (θ, ψ, φ) [rad].
COMPONENTS = PROBE_COLUMNS[1:]
#: Default number of modes reported (fewer if there are fewer snapshots).
DEFAULT_MODES = 10
#: The files :func:`write_pod` writes in its folder.
POD_CSV, POD_XDMF, POD_PNG = "pod.csv", "pod.xdmf", "pod.png"


@dataclass
class Snapshots:
    """Fields at stations along the rod at the snapshot times.

    ``s`` (N,) [m] arc lengths, strictly increasing; ``times`` (T,) [s]; ``values`` (T, N, C)
    in SI units, components ``components`` (a prefix of :data:`COMPONENTS`: 3 or 6);
    ``rod``: (ρA [kg/m], ρ I1, ρ I2, ρ I3 [kg m]) for the kinetic weighting, or None."""

    s: np.ndarray
    times: np.ndarray
    values: np.ndarray
    rod: tuple[float, float, float, float] | None = None

    @property
    def components(self) -> tuple[str, ...]:
        return COMPONENTS[: self.values.shape[2]]


@dataclass
class PodResult:
    """The POD of :class:`Snapshots` (module docstring for the equations).

    ``energies`` (K,) λ_k [m³ or kg m²]; ``fractions``, ``cumulative`` (K,) of the total
    energy ``total``; ``shapes`` (K, N, C) φ_k at the stations, ⟨φ_k, φ_l⟩ = δ_kl, sign
    convention of the module docstring (units: those of u over √(units of λ)); ``coefficients``
    (T, K) a_k(t_i) [√(units of λ)]; ``mean`` (N, C) ū (zeros with ``remove_mean=False``);
    ``weights`` (C,) w_c and ``quadrature`` (N,) q_j [m] of the inner product."""

    s: np.ndarray
    times: np.ndarray
    components: tuple[str, ...]
    weighting: str
    remove_mean: bool
    energies: np.ndarray
    fractions: np.ndarray
    cumulative: np.ndarray
    total: float
    shapes: np.ndarray
    coefficients: np.ndarray
    mean: np.ndarray
    weights: np.ndarray
    quadrature: np.ndarray
    files: list[Path] = field(default_factory=list)

    @property
    def unit(self) -> str:
        """The unit of the energies."""
        return "m^3" if self.weighting == "displacement" else "kg m^2"

    def inner(self, u: np.ndarray, v: np.ndarray) -> float:
        """⟨u, v⟩ of two fields (N, C) at the stations, in this POD's inner product."""
        return float(np.einsum("j,c,jc,jc->", self.quadrature, self.weights, u, v))


def trapezoid_weights(s: np.ndarray) -> np.ndarray:
    """q_j [m] of the trapezoidal rule on the stations s (N ≥ 2, strictly increasing):
    Σ_j q_j f(s_j) ≈ ∫ f ds, exact for piecewise linear f."""
    h = np.diff(s)
    q = np.zeros_like(s)
    q[:-1] += 0.5 * h
    q[1:] += 0.5 * h
    return q


def kinetic_weights(rod) -> tuple[float, float, float, float]:
    """(ρA [kg/m], ρ I1, ρ I2, ρ I3 [kg m]) of a :class:`~cosserat_fem.forms.groups.RodConstants`
    (I: its rotary inertias per unit ρ, as the balance laws and the modes use them)."""
    rho = rod.density
    return (rho * rod.section.area, *(rho * c for c in rod.rotary_inertias))


def pod(
    snapshots: Snapshots,
    modes: int | None = None,
    weighting: str = "displacement",
    remove_mean: bool = True,
) -> PodResult:
    """The ``modes`` leading POD modes of ``snapshots`` (default min(10, T)); SceneError
    naming the argument for bad input: ``modes`` not in [1, T], an unknown ``weighting``, the
    kinetic weighting without angles or rod constants, stations not strictly increasing or
    fewer than two, values that are not finite."""
    s = np.asarray(snapshots.s, dtype=float)
    times = np.asarray(snapshots.times, dtype=float)
    values = np.asarray(snapshots.values, dtype=float)
    if weighting not in WEIGHTINGS:
        raise SceneError(f"weighting: must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    if (
        values.ndim != 3
        or values.shape[2] not in (3, 6)
        or values.shape[:2] != (len(times), len(s))
    ):
        raise SceneError(
            f"snapshots: values must have the shape (times {len(times)}, stations {len(s)}, "
            f"3 or 6), got {values.shape}"
        )
    count = len(times)
    if modes is None:
        modes = min(DEFAULT_MODES, count)
    if (
        isinstance(modes, bool)
        or not isinstance(modes, int | np.integer)
        or not (1 <= modes <= count)
    ):
        raise SceneError(
            f"modes (--modes): must be a whole number in [1, {count}] (the number of "
            f"snapshots), got {modes!r}"
        )
    if len(s) < 2 or not (np.isfinite(s).all() and (np.diff(s) > 0).all()):
        raise SceneError(
            "stations: need at least two, finite and strictly increasing along the rod"
        )
    if not np.isfinite(times).all():
        raise SceneError("snapshots: times that are not finite")
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.argwhere(bad)[0][0])
        raise SceneError(f"snapshots: values that are not finite (at t = {times[i]:.6g} s)")
    if weighting == "kinetic":
        if values.shape[2] != 6:
            raise SceneError(
                "weighting: 'kinetic' needs the angles θ, ψ, φ as well as the "
                'displacement (output.fields = ["displacement", "angles"])'
            )
        if snapshots.rod is None or not all(w > 0 for w in snapshots.rod):
            raise SceneError("weighting: 'kinetic' needs the rod's ρA, ρI1, ρI2, ρI3 (> 0)")
        rho_a, *rho_i = snapshots.rod
        weights = np.array([rho_a] * 3 + list(rho_i))
    else:
        values = values[:, :, :3]
        weights = np.ones(3)
    quadrature = trapezoid_weights(s)
    mean = values.mean(axis=0) if remove_mean else np.zeros(values.shape[1:])
    scale = np.sqrt(quadrature[:, None] * weights[None, :])  # √(q_j w_c)
    A = ((values - mean) * scale).reshape(count, -1) / math.sqrt(count)
    shapes_all, sigma, U = snapshot_svd(A.T)
    Vt = shapes_all.T
    energies_all = sigma**2
    total = float(energies_all.sum())
    if not total > 0.0:
        raise SceneError(
            "snapshots: the fields do not vary over the snapshots (mean removed): no modes to find"
        )
    k = min(modes, len(sigma))
    shapes = Vt[:k].reshape(k, *values.shape[1:]) / scale
    coefficients = math.sqrt(count) * U[:, :k] * sigma[:k]
    for i in range(k):  # the component of largest magnitude positive
        flat = shapes[i].ravel()
        if flat[np.argmax(np.abs(flat))] < 0:
            shapes[i] *= -1.0
            coefficients[:, i] *= -1.0
    energies = np.zeros(modes)
    energies[:k] = energies_all[:k]
    if k < modes:  # more modes asked than the snapshots' dimension: zero energies, no shapes
        shapes = np.concatenate([shapes, np.zeros((modes - k, *values.shape[1:]))])
        coefficients = np.hstack([coefficients, np.zeros((count, modes - k))])
    fractions = energies / total if total > 0 else np.zeros(modes)
    return PodResult(
        s=s,
        times=times,
        components=COMPONENTS[: values.shape[2]],
        weighting=weighting,
        remove_mean=remove_mean,
        energies=energies,
        fractions=fractions,
        cumulative=np.cumsum(fractions),
        total=total,
        shapes=shapes,
        coefficients=coefficients,
        mean=mean,
        weights=weights,
        quadrature=quadrature,
    )


def snapshot_svd(A: np.ndarray, comm=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The thin SVD A = Φ Σ Wᵀ of a weighted snapshot matrix A (rows: the weighted unknowns,
    √(weight) times the value; columns: the snapshots): (Φ, σ, W), σ decreasing, the energies
    σ². The one SVD of both POD's: :func:`pod` (the stations' fields) and the reduced basis of
    cosserat_fem/rom/basis.py (the FE unknowns).

    Under MPI (``comm`` of several ranks; collective) each rank holds its rows of A (its owned
    unknowns) and gets its rows of Φ: a tall-skinny QR (each rank's A_r = Q_r R_r, the R_r
    gathered and A's singular values and right vectors taken from the stacked R's, whose SVD
    is A's: Aᵀ A = Σ_r R_rᵀ R_r), so the small energies keep the accuracy of an SVD (not the
    round-off of the largest one, as the eigenvalues of the Gram matrix Aᵀ A would);
    Φ_r = A_r W Σ⁻¹ for the non-zero σ (zero columns where σ = 0)."""
    if comm is None or comm.size == 1:
        Phi, sigma, Wt = np.linalg.svd(A, full_matrices=False)
        return Phi, sigma, Wt.T
    R = np.linalg.qr(A, mode="r") if A.shape[0] else np.zeros((0, A.shape[1]))
    stacked = np.vstack(comm.allgather(R))
    _, sigma, Wt = np.linalg.svd(stacked, full_matrices=False)
    W = Wt.T
    inverse = np.divide(1.0, sigma, out=np.zeros_like(sigma), where=sigma > sigma[0] * 1e-14)
    return A @ W * inverse, sigma, W


def modes_for_tolerance(energies: np.ndarray, tolerance: float) -> int:
    """The fewest modes k ≥ 1 whose energy left out, Σ_{i>k} λ_i / Σ_i λ_i, is at most
    ``tolerance`` (λ the POD energies, decreasing; all of them if none fewer do)."""
    energies = np.asarray(energies, dtype=float)
    total = float(energies.sum())
    left = (total - np.cumsum(energies)) / total if total > 0 else np.zeros(len(energies))
    within = np.flatnonzero(left <= tolerance)
    return int(within[0]) + 1 if within.size else len(energies)


# --- snapshots from a run ------------------------------------------------------------------


def snapshots_of_result(result, stations, rod=None) -> Snapshots:
    """The snapshots of a :class:`~cosserat_fem.analysis.simulation.RunResult` run with ``fields``
    = ``stations`` (σ = s/ℓ in [0, 1]; sorted here along the rod); ``rod``: the rod's
    :class:`~cosserat_fem.forms.groups.RodConstants` (default the run's scene's)."""
    if getattr(result, "field_values", None) is None:
        raise SceneError(
            "result: holds no fields; run with fields=stations (cf.run(scene, "
            "fields=...)) and give the same stations"
        )
    sigma = np.asarray(stations, dtype=float).reshape(-1)
    values = np.asarray(result.field_values, dtype=float)
    held = getattr(result, "field_stations", None)
    if len(sigma) != values.shape[1] or (held is not None and not np.array_equal(sigma, held)):
        raise SceneError(
            f"stations: not those the result was sampled at ({len(sigma)} given, "
            f"it holds {values.shape[1]}; give the fields the run was given)"
        )
    scene = result.model.scene
    rod = scene.rod_constants() if rod is None else rod
    order = np.argsort(sigma, kind="stable")
    return Snapshots(
        s=sigma[order] * rod.length,
        times=np.asarray(result.field_times),
        values=values[:, order, :],
        rod=kinetic_weights(rod),
    )


def read_run(directory: str | Path) -> Snapshots:
    """The snapshots in the XDMF output of the run in ``directory``: the frames of
    solution.xdmf (its points along the rod; displacement, and the angles if written) and
    the rod's constants from summary.json's scene. SceneError (one line naming the folder or
    file) for a folder without a run, a run without XDMF frames, a damaged file."""
    from cosserat_fem.io.xdmf import NoFramesError
    from cosserat_fem.output.results import open_run

    path = Path(directory)
    run = open_run(path, "pod")
    if run.xdmf is None:
        raise SceneError(
            f"pod: {str(path)!r} holds no solution.xdmf (a run with output.xdmf = "
            "false has no snapshots of the fields)"
        )
    rod = _rod_of_summary(run.summary, path)
    try:
        s, times, arrays = _read_series(run.xdmf, run.length)
    except NoFramesError as exc:
        raise SceneError(f"pod: {exc}") from None
    if "displacement" not in arrays:
        raise SceneError(f"pod: {str(run.xdmf)!r} has no displacement array")
    parts = [arrays["displacement"]] + ([arrays["angles"]] if "angles" in arrays else [])
    return Snapshots(s=s, times=times, values=np.concatenate(parts, axis=2), rod=rod)


def _rod_of_summary(summary: dict | None, path: Path):
    """ρA, ρI of the scene in summary.json (None without one); SceneError for a rod curved
    at rest, whose XDMF points are not on the axis the stations are read from."""
    if not summary or not isinstance(summary.get("scene"), dict):
        return None
    scene_dict = summary["scene"]
    reference = scene_dict.get("reference") or {}
    if isinstance(reference, dict) and reference.get("shape", "straight") != "straight":
        raise SceneError(
            f"pod: {str(path)!r} is a run of a rod curved at rest; pod reads "
            "straight rods only (its stations are taken along e3)"
        )
    from cosserat_fem.scene.build import scene_from_dict

    try:
        scene = scene_from_dict(scene_dict, source=f"{path}/summary.json")
    except SceneError:
        return None  # the scene of another version: no rod constants (kinetic refused)
    return kinetic_weights(scene.rod_constants())


def _read_series(xdmf: Path, length: float | None):
    """(s, times, arrays) of :func:`cosserat_fem.output.results.read_xdmf`, in this process, or in a
    child process if this one has loaded DOLFINx (whose HDF5 library h5py cannot share)."""
    if "dolfinx" not in sys.modules:
        from cosserat_fem.io.xdmf import read_xdmf

        series = read_xdmf(xdmf, length=length)
        return series.s, series.times, series.arrays
    # The child sends the arrays through a pipe, not a temporary file: a full disk (or /tmp)
    # must not turn into "cannot read" the run.
    code = (
        "import io, sys, numpy as np\n"
        "from cosserat_fem.io.xdmf import read_xdmf, NoFramesError\n"
        "from cosserat_fem.common.errors import SceneError\n"
        "try:\n"
        "    r = read_xdmf(sys.argv[1], None if sys.argv[2] == '-' else float(sys.argv[2]))\n"
        "except NoFramesError as e:\n"
        "    print(e, file=sys.stderr); sys.exit(3)\n"
        "except SceneError as e:\n"
        "    print(e, file=sys.stderr); sys.exit(2)\n"
        "data = io.BytesIO()\n"
        "np.savez(data, s=r.s, times=r.times, names=np.array(sorted(r.arrays)),"
        " **{'a_' + k: v for k, v in r.arrays.items()})\n"
        "sys.stdout.buffer.write(data.getbuffer())\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(__file__).resolve().parents[1]), env.get("PYTHONPATH", "")]
    )
    arguments = [str(xdmf), "-" if length is None else repr(length)]
    try:
        proc = subprocess.run(
            [sys.executable, "-c", code, *arguments], env=env, capture_output=True, timeout=600
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise SceneError(f"pod: cannot read {str(xdmf)!r} ({exc})") from None
    errors = proc.stderr.decode(errors="replace").strip().splitlines()
    if proc.returncode in (2, 3):
        from cosserat_fem.io.xdmf import NoFramesError

        message = (errors or [f"cannot read {str(xdmf)!r}"])[-1]
        raise (NoFramesError if proc.returncode == 3 else SceneError)(message)
    if proc.returncode != 0:
        raise SceneError(f"pod: cannot read {str(xdmf)!r}: {(errors or ['?'])[-1]}")
    with np.load(io.BytesIO(proc.stdout)) as data:
        arrays = {str(n): data["a_" + str(n)] for n in data["names"]}
        return data["s"], data["times"], arrays


# --- files ---------------------------------------------------------------------------------


def write_pod(result: PodResult, folder: str | Path) -> list[Path]:
    """pod.csv (mode, energy, fraction, cumulative) and pod.xdmf with its folder pod.frames/
    (the shapes as fields on the reference centreline (0, 0, s) [m], one frame a mode, Time =
    the mode number, as modes.xdmf) in ``folder`` (which must exist); the paths.

    The XDMF arrays are the shapes scaled by √λ_k, the root-mean-square field of mode k:
    ``displacement`` [m] and, with the kinetic weighting, ``angles`` [rad]; so ParaView's
    Warp By Vector draws each mode at its size in the run. Each file is made in memory and
    written whole (cosserat_fem/io/output_files.py ``write_output``): OutputError (exit 4)
    naming a file that cannot be written. pod.png is cosserat_fem/plot.py's ``plot_pod``,
    drawn after these two."""
    folder = Path(folder)
    return [_write_csv(result, folder / POD_CSV), _write_xdmf(result, folder / POD_XDMF)]


def _write_csv(result: PodResult, path: Path) -> Path:
    from cosserat_fem.io.output_files import write_output

    stream = io.StringIO(newline="")
    writer = csv.writer(stream)
    writer.writerow(["mode", f"energy_{result.unit.replace(' ', '_')}", "fraction", "cumulative"])
    for k, (e, f, c) in enumerate(
        zip(result.energies, result.fractions, result.cumulative, strict=True), start=1
    ):
        writer.writerow([k, f"{e:.12e}", f"{f:.12e}", f"{c:.12e}"])
    return write_output(path, stream.getvalue().encode("utf-8"), "pod")


def _write_h5(path: Path, datasets: list[tuple[str, np.ndarray]]) -> None:
    """An HDF5 file of float64/int64 datasets, made in memory (with h5py, or, in a process
    that has loaded DOLFINx, with its HDF5 library: cosserat_fem/io/hdf5.py) and written whole:
    HDF5 never writes to the disk itself. (h5py writing to a full disk left HDF5 in a state
    whose clean-up at exit was a segmentation fault.)"""
    from cosserat_fem.io.output_files import write_output

    datasets = [(name, np.ascontiguousarray(v)) for name, v in datasets]
    if "dolfinx" in sys.modules:
        from cosserat_fem.io.hdf5 import Hdf5

        write_output(path, Hdf5().image(datasets)[0], "pod")
        return
    from cosserat_fem.io.xdmf import import_h5py

    image = io.BytesIO()
    with import_h5py().File(image, "w") as h5:
        for name, values in datasets:
            h5.create_dataset(name, data=values)
    write_output(path, image.getbuffer(), "pod")


def _write_xdmf(result: PodResult, path: Path) -> Path:
    """pod.xdmf and pod.frames/ (see :func:`write_pod`), in the layout and XML of
    cosserat_fem/io/xdmf.py (its mesh file, a frame file a mode, one temporal collection,
    here named "pod" and without a run's identity or spare room: written whole, not
    appended); the XML last, so that it never names a frame file that was not written."""
    from cosserat_fem.io.output_files import output_folder, write_output
    from cosserat_fem.io.xdmf import (
        FRAME_NAME,
        MESH_FILE,
        MESH_GEOMETRY,
        MESH_TOPOLOGY,
        XDMF_TAIL,
        frame_file,
        frames_folder,
        function_dataset,
        xdmf_frame_xml,
        xdmf_head,
    )

    frames = frames_folder(path)
    n = len(result.s)
    geometry = np.zeros((n, 3))
    geometry[:, 2] = result.s
    topology = np.column_stack([np.arange(n - 1), np.arange(1, n)]).astype(np.int64)
    arrays = [("displacement", slice(0, 3))]
    if len(result.components) == 6:
        arrays.append(("angles", slice(3, 6)))
    names = [name for name, _ in arrays]
    mesh = xdmf_mesh_xml(f"{frames.name}/{MESH_FILE}", n, n - 1)
    grids = []
    output_folder(frames, frames, "pod")
    try:
        safe_files.remove_own_files(frames, FRAME_NAME)  # an earlier pod's frames, a link
        frames.mkdir(exist_ok=True)
        _write_h5(frames / MESH_FILE, [(MESH_GEOMETRY, geometry), (MESH_TOPOLOGY, topology)])
        for k, (energy, shape) in enumerate(zip(result.energies, result.shapes, strict=True), 1):
            rms = math.sqrt(max(energy, 0.0)) * shape
            _write_h5(
                frames / frame_file(k - 1),
                [(function_dataset(name, str(k)), rms[:, part]) for name, part in arrays],
            )
            grids.append(
                xdmf_frame_xml(
                    "pod", mesh, str(k), f"{frames.name}/{frame_file(k - 1)}", str(k), names, n
                )
            )
    except RuntimeError as exc:  # HDF5 (or h5py) could not make a file in memory
        raise CosseratError(f"pod: cannot make {str(frames)!r} ({exc})") from None
    text = xdmf_head("pod") + "".join(grids) + XDMF_TAIL
    return write_output(path, text.encode("utf-8"), "pod")
