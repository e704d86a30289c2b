"""``cosserat-fem render RUN_DIR``: the rod drawn in 3D, off-screen, with pyvista (VTK).

From the run's XDMF (read by :mod:`cosserat_fem.output.results`, no DOLFINx) it writes

* ``rod_peak.png``: the deformed rod at the frame of largest displacement (anywhere),
* ``rod_last.png``: at the last frame,
* ``rod_frames.png``: a few frames over each other, darker with time,
* ``rod.gif`` (or ``rod.mp4`` with ``--format mp4``, which needs imageio-ffmpeg): the
  animation over all frames (at most ``--frames`` of them, evenly spaced).

The rod is the deformed centreline r(s, t) = (0, 0, s) + k (x, y, z)(s, t) [m] as a tube,
coloured by the magnitude of the contact torque |m| [N m] when the file has it (else of the
displacement), with the undeformed rod as a thin grey line and the axes labelled in metres.
Deflections of a stiff rod are a small fraction of its length: the magnification k (written
in every picture) is chosen so that the largest displacement is about a fifth of the length,
rounded down to 1, 2 or 5 times a power of ten, at most 1e12 (``--scale`` sets it, within
the same bound; 1 for large deflections). pyvista and vtk come from PyPI (the ``render``
extra). With no X display VTK renders through EGL; under ``xvfb-run`` through X.

The run is read and checked by :mod:`cosserat_fem.output.results` before anything is drawn: a
damaged file is bad input (one line naming it, exit 2), and so is an XDMF file without frames. Every
picture and the GIF are encoded in memory and written whole (cosserat_fem/plot.py
``write_output``; an MP4, which ffmpeg writes, goes to a hidden file renamed when complete): a
write that fails is an OutputError naming the file (exit 4), with no cut file left.
``progress`` (a :class:`~cosserat_fem.analysis.progress.StatusLine`, on a terminal) shows the
pictures and the animation's frames as they are made.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path

import numpy as np

from cosserat_fem.common.errors import CosseratError, OutputError, SceneError, out_folder
from cosserat_fem.io.output_files import output_folder, write_output
from cosserat_fem.io.xdmf import RodSeries
from cosserat_fem.output.results import open_run

WINDOW = (1024, 768)  # pixels of every picture and animation frame
#: Largest automatic magnification (a displacement below ~1e-13 of the length is round-off;
#: and 0.2 ℓ over a subnormal peak would overflow to inf).
MAX_SCALE = 1e12


def _pyvista():
    """pyvista set for off-screen rendering (EGL without an X display); CosseratError if it is
    missing."""
    if not os.environ.get("DISPLAY"):
        # No X server: use EGL directly instead of trying X first (and warning).
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import pyvista
    except ImportError as exc:
        raise CosseratError(
            f"render needs pyvista ({exc}); install the render extra: pip install -e .[render]"
        ) from None
    pyvista.OFF_SCREEN = True
    return pyvista


def magnification(series: RodSeries) -> float:
    """Largest displacement → about a fifth of the length, rounded down to 1, 2, 5 × 10^n,
    never below 1 nor above MAX_SCALE."""
    peak = float(np.abs(series.arrays["displacement"]).max())
    if peak == 0.0 or peak >= 0.2 * series.length:
        return 1.0
    raw = min(0.2 * series.length / peak, MAX_SCALE)
    decade = 10.0 ** math.floor(math.log10(raw))
    step = max(m for m in (1.0, 2.0, 5.0) if m * decade <= raw * (1 + 1e-12))
    return max(1.0, step * decade)


class _Scene:
    """One pyvista plotter for every picture: the undeformed rod, the frame of the axes, the
    colour bar and the camera are set up once; a picture replaces the tube(s) and the
    caption and renders once (its cost: docs/decisions.md, "render: one plotter for every
    picture"; tests/test_visualisation.py::test_plot_and_render_a_run)."""

    def __init__(self, series: RodSeries, scale: float, title: str, time_label: str):
        pv = _pyvista()
        self.pv = pv
        self.series, self.scale = series, scale
        self.title, self.time_label = title, time_label
        self.positions = series.positions(scale)  # (T, N, 3)
        if "torque_m" in series.arrays:
            self.colour_name = "torque m [N m]"
            self.colour = np.linalg.norm(series.arrays["torque_m"], axis=2)
        else:
            self.colour_name = "displacement [m]"
            self.colour = np.linalg.norm(series.arrays["displacement"], axis=2)
        top = float(self.colour.max())
        self.clim = (0.0, top if top > 0 else 1.0)
        self.radius = 0.012 * series.length
        lo = np.minimum(self.positions.min(axis=(0, 1)), series.reference.min(axis=0))
        hi = np.maximum(self.positions.max(axis=(0, 1)), series.reference.max(axis=0))
        pad = 0.05 * series.length
        # Lateral extents symmetric about the undeformed axis, so that the middle tick is 0.
        half = np.maximum(np.abs(lo[:2]), np.abs(hi[:2])) + pad
        bounds = (-half[0], half[0], -half[1], half[1], lo[2], hi[2])
        try:
            p = pv.Plotter(off_screen=True, window_size=WINDOW)
        except Exception as exc:  # no OpenGL context at all
            raise CosseratError(f"render: VTK cannot render off-screen here ({exc})") from None
        self.plotter = p
        p.set_background("white")
        # No depth peeling: with it, Mesa's off-screen renderer (EGL and xvfb alike) drew
        # translucent tubes not at all, and rod_frames.png showed its last frame alone.
        p.add_mesh(self._polyline(series.reference), color="darkgrey", line_width=2, render=False)
        p.add_mesh(pv.Box(bounds=bounds), opacity=0.0, render=False)  # fixes the framing
        # The tick labels give the true x and y of the drawn rod (the lateral coordinates of
        # the picture are magnified by ``scale``; the axial one is s + scale z ≈ s).
        ranges = [
            bounds[0] / scale,
            bounds[1] / scale,
            bounds[2] / scale,
            bounds[3] / scale,
            bounds[4],
            bounds[5],
        ]
        p.show_bounds(
            bounds=bounds,
            axes_ranges=ranges,
            xtitle="x [m]",
            ytitle="y [m]",
            ztitle="z [m]",
            color="black",
            grid=False,
            location="outer",
            font_size=10,
            fmt="%.2g",
            n_xlabels=3,
            n_ylabels=3,
            n_zlabels=5,
            render=False,
        )
        self.caption = p.add_text(
            "", position="upper_left", font_size=11, color="black", render=False
        )
        self.tubes: list = []
        self._actors: list = []
        # Camera: from the −y side, a little from +x and above, z (the rod) up.
        centre = 0.5 * (np.array(bounds[::2]) + np.array(bounds[1::2]))
        size = float(np.linalg.norm(np.array(bounds[1::2]) - np.array(bounds[::2])))
        view = np.array([0.55, -1.0, 0.4])
        view /= np.linalg.norm(view)
        p.camera_position = [tuple(centre + 1.6 * size * view), tuple(centre), (0.0, 0.0, 1.0)]
        p.reset_camera(render=False)
        p.camera.zoom(0.8)  # room for the axes' labels and the caption

    def _polyline(self, points: np.ndarray):
        """One polyline through the points (``lines_from_points`` makes a cell a segment, and
        a tube of those is a stack of capped pieces whose caps show through translucency)."""
        cells = np.concatenate([[len(points)], np.arange(len(points))])
        return self.pv.PolyData(np.asarray(points, dtype=float), lines=cells)  # no vertex cells

    def _tube(self, frame: int):
        line = self._polyline(self.positions[frame])
        line.point_data[self.colour_name] = self.colour[frame]
        return line.tube(radius=self.radius, n_sides=20, capping=True)

    def _caption(self, frame: int) -> str:
        """The caption of ``frame``: title, time (or load factor) and magnification."""
        t = self.series.times[frame]
        return (
            f"{self.title}\n{self.time_label} = {t:.6g}   displacement x {self.scale:g}"
            "   (grey: undeformed, along z)"
        )

    def show(self, frames: list[int], text: str) -> None:
        """The tubes of ``frames`` (the last opaque, earlier ones fainter) and the caption."""
        p = self.plotter
        while len(self.tubes) < len(frames):
            tube = self._tube(frames[len(self.tubes)])
            actor = p.add_mesh(
                tube,
                scalars=self.colour_name,
                clim=self.clim,
                cmap="viridis",
                show_scalar_bar=not self.tubes,
                render=False,
                scalar_bar_args={
                    "title": f"{self.colour_name}\n(magnitude)",
                    "color": "black",
                    "vertical": True,
                    "position_x": 0.84,
                    "position_y": 0.1,
                    "width": 0.06,
                    "title_font_size": 14,
                    "label_font_size": 12,
                    "fmt": "%.3g",
                },
            )
            self.tubes.append(tube)
            self._actors.append(actor)
        for i, (tube, actor) in enumerate(zip(self.tubes, self._actors, strict=True)):
            if i < len(frames):
                tube.copy_from(self._tube(frames[i]))
                faint = 0.25 + 0.5 * i / max(1, len(frames) - 1)
                actor.prop.opacity = 1.0 if i == len(frames) - 1 else faint
            actor.SetVisibility(i < len(frames))
        self.caption.set_text("upper_left", text)
        self.plotter.render()  # screenshot() alone returned the previous picture

    def picture(self, frames: list[int], text: str, path: Path) -> Path:
        """The picture of ``frames`` as the PNG file ``path`` (the bytes pyvista's screenshot
        writes: PIL's PNG of the rendered image)."""
        from PIL import Image

        self.show(frames, text)
        image = io.BytesIO()
        Image.fromarray(self.plotter.screenshot(return_img=True)).save(image, format="PNG")
        return write_output(path, image.getbuffer(), "render")

    def image(self, frame: int) -> np.ndarray:
        self.show([frame], self._caption(frame))
        return self.plotter.screenshot(return_img=True)

    def close(self) -> None:
        self.plotter.close()


def render_run(
    directory: str | Path,
    out: str | Path | None = None,
    scale: float | None = None,
    fmt: str = "gif",
    max_frames: int = 120,
    fps: int = 15,
    progress=None,
) -> list[Path]:
    """The pictures and the animation of the run in ``directory`` (see the module docstring);
    ``progress(done, total, what)`` after each picture and animation frame, if given."""
    if fmt not in ("gif", "mp4"):
        raise SceneError(f"render --format: must be gif or mp4, got {fmt!r}")
    if max_frames < 1:
        raise SceneError(f"render --frames: must be at least 1, got {max_frames}")
    if scale is not None and not (math.isfinite(scale) and 0 < scale <= MAX_SCALE):
        raise SceneError(
            f"render --scale: must be a number in (0, {MAX_SCALE:g}] (beyond, the "
            f"picture shows round-off of the length), got {scale!r}"
        )
    out_folder(out, "render --out")
    run = open_run(directory, "render")
    series = run.series()
    if "displacement" not in series.arrays:
        raise SceneError(f"render: {str(run.xdmf)!r} has no displacement (output.fields)")
    k = magnification(series) if scale is None else scale
    drawn = series.positions(k)
    if not np.isfinite(drawn).all():
        raise SceneError(f"render --scale: {k:g} magnifies the displacement beyond the float range")
    # A frame whose points all coincide (to double precision) has no tube: VTK's tube filter
    # gives an empty mesh, which pyvista refuses to draw. No run writes one.
    single = np.flatnonzero(np.abs(np.diff(drawn, axis=1)).max(axis=(1, 2)) == 0.0)
    if single.size:
        raise SceneError(
            f"render: {str(run.xdmf)!r}: at time {series.times[single[0]]:.6g} every point of "
            f"the rod (displaced x {k:g}) is at one place; nothing to draw"
        )
    target = output_folder(out, run.directory, "render")
    scene = _Scene(series, k, run.title, run.time_label)
    count = len(series.times)
    frames = sorted(set(np.linspace(0, count - 1, min(max_frames, count)).round().astype(int)))
    total = 3 + len(frames)

    def made(done: int, what: str) -> None:
        if progress is not None:
            progress(done, total, what)

    paths = []
    try:
        # The frame where the rod is displaced most (anywhere along it: an end may be held).
        largest = np.linalg.norm(series.arrays["displacement"], axis=2).max(axis=1)
        peak, last = int(np.argmax(largest)), len(series.times) - 1
        paths.append(scene.picture([peak], scene._caption(peak), target / "rod_peak.png"))
        made(1, "rod_peak.png")
        paths.append(scene.picture([last], scene._caption(last), target / "rod_last.png"))
        made(2, "rod_last.png")
        some = sorted(set(np.linspace(0, last, min(8, last + 1)).round().astype(int).tolist()))
        text = (
            f"{run.title}\n{len(some)} frames, {run.time_label} = "
            f"{series.times[some[0]]:.4g} ... {series.times[some[-1]]:.4g}   displacement x {k:g}"
        )
        paths.append(scene.picture(some, text, target / "rod_frames.png"))
        made(3, "rod_frames.png")
        name = f"rod.{fmt}"
        paths.append(
            _animate(
                scene,
                target / name,
                frames,
                fps,
                lambda i: made(3 + i, f"{name}, frame {i} of {len(frames)}"),
            )
        )
    finally:
        scene.close()
    return paths


def _animate(scene: _Scene, path: Path, frames: list[int], fps: int, made) -> Path:
    """The animation (GIF or MP4 by ``path``'s suffix) of ``frames`` at ``fps`` frames a
    second, ``made(i)`` after the i-th; a GIF made in memory and written whole, an MP4 written
    by ffmpeg to a hidden file that is renamed when complete (removed if not). OutputError if
    it cannot be written, CosseratError if imageio is missing or fails."""
    try:
        import imageio.v2 as imageio
    except ImportError as exc:
        raise CosseratError(f"render needs imageio for the animation ({exc})") from None
    gif = path.suffix == ".gif"
    options = {"duration": 1000.0 / fps, "loop": 0} if gif else {"fps": fps}
    work = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")
    image = io.BytesIO()
    try:
        with (
            imageio.get_writer(image, format="GIF", **options)
            if gif
            else imageio.get_writer(work, **options) as writer
        ):
            for i, frame in enumerate(frames, start=1):
                # imageio's v2 writer has append_data; its stub types the writer as the
                # base class, which does not declare it
                writer.append_data(scene.image(int(frame)))  # type: ignore[attr-defined]
                made(i)
        if not gif:
            os.replace(work, path)
    except OSError as exc:
        raise OutputError(f"render: cannot write {str(path)!r} ({exc.strerror or exc})") from None
    except (ImportError, ValueError, RuntimeError) as exc:
        raise CosseratError(f"render: cannot write {str(path)!r} ({exc})") from None
    finally:
        work.unlink(missing_ok=True)
    return write_output(path, image.getbuffer(), "render") if gif else path
