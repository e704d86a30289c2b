"""What a run tells its user while it runs and when it ends (command line only).

* :class:`ProgressBar`: one status line on a terminal, rewritten at most every 0.25 s: time
  reached, percentage, steps, Newton iterations per step, elapsed and estimated remaining wall
  time. It stays silent when stderr is not a terminal (CI logs, pipes), under ``--quiet``, and
  on every MPI rank but 0; costs nothing measurable (one clock read a step).
* :func:`summary_screen`: the end-of-run summary, a dozen lines from ``summary.json``.
* :func:`configure_logging`: ``--quiet`` (errors only), default (warnings), ``--verbose``
  (what the solver decides: step rejections, Jacobian refreshes, checkpoints) on rank 0.
"""

from __future__ import annotations

import logging
import sys
import time
from typing import TextIO

LOGGER = logging.getLogger("cosserat_fem")


def configure_logging(level: str, rank: int) -> None:
    """``level``: "quiet", "normal" or "verbose"; ranks other than 0 log errors only."""
    levels = {"quiet": logging.ERROR, "normal": logging.WARNING, "verbose": logging.INFO}
    LOGGER.setLevel(levels[level] if rank == 0 else logging.ERROR)
    if not any(getattr(h, "_cosserat", False) for h in LOGGER.handlers):
        handler = logging.StreamHandler(sys.stderr)
        # On a terminal a log line first clears the progress bar's line (it is redrawn).
        clear = "\r\033[K" if sys.stderr.isatty() else ""
        handler.setFormatter(logging.Formatter(clear + "cosserat-fem: %(message)s"))
        handler._cosserat = True  # type: ignore[attr-defined]
        LOGGER.addHandler(handler)
    LOGGER.propagate = False


def _clock(seconds: float) -> str:
    """Seconds as "12.3 s" below a minute, else m:ss or h:mm:ss (negative as 0)."""
    seconds = max(0.0, seconds)
    if seconds < 60:
        return f"{seconds:4.1f} s"
    minutes, seconds = divmod(int(seconds + 0.5), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{seconds:02d}" if hours else f"{minutes}:{seconds:02d}"


class ProgressBar:
    """Call with (t, steps, newton_iterations) after each output step (see module docstring)."""

    INTERVAL = 0.25  # s between redraws

    def __init__(self, start: float, end: float, stream: TextIO | None = None, enabled=None):
        self.start, self.end = start, end
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = self.stream.isatty()
        self.enabled = bool(enabled)
        self._t0 = time.monotonic()
        self._next = self._t0
        self._width = 0

    def __call__(self, t: float, steps: int, iterations: int) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now < self._next and t < self.end:
            return
        self._next = now + self.INTERVAL
        fraction = min(1.0, (t - self.start) / (self.end - self.start))
        elapsed = now - self._t0
        eta = elapsed * (1.0 - fraction) / fraction if fraction > 0 else float("nan")
        filled = int(20 * fraction)
        line = (
            f"[{'#' * filled}{'.' * (20 - filled)}] {100 * fraction:5.1f}%  t = {t:.6g} s  "
            f"{steps} steps  {iterations / max(steps, 1):.2f} it/step  "
            f"elapsed {_clock(elapsed)}  ETA {_clock(eta) if fraction > 0 else '?'}"
        )
        self._width = max(self._width, len(line))
        self.stream.write("\r" + line.ljust(self._width))
        self.stream.flush()

    def close(self) -> None:
        if self.enabled and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()


def summary_screen(summary: dict, out_dir) -> str:
    """The end-of-run summary (from the run's summary dict) as lines of text."""
    wall, newton = summary["wall_time_s"], summary["newton"]
    accepted = summary.get("accepted_steps") or summary["steps"]
    per_step = newton["iterations"] / max(accepted, 1)
    from .forms.kinematics import P_NAMES  # here: the CLI imports this module for every command

    positions = [u for u in summary["solved_unknowns"] if u in P_NAMES]
    lines = [
        f"cosserat-fem: {summary['status']}: t = {summary['time_reached_s']:.6g} s in "
        f"{summary['steps']} output steps ({accepted} steps taken, "
        f"{summary.get('rejected_steps', 0)} rejected"
        + (
            f", smallest {summary['smallest_step_s']:.3g} s"
            if summary.get("smallest_step_s")
            else ""
        )
        + ")",
        f"  model:   {summary['dofs']} dofs, {summary['elements']} elements of degree "
        f"{summary['degree']}, unknowns {', '.join(positions)}"
        f" and their rates; {summary['integrator']}, {summary['mpi_ranks']} MPI rank(s)",
        f"  skipped: {', '.join(summary['skipped_terms']) or 'nothing'}",
        f"  Newton:  {newton['iterations']} iterations ({per_step:.2f}"
        f" a step, at most {newton['max_iterations_in_a_solve']} in a solve), "
        f"{newton['jacobian_assemblies']} Jacobian assemblies, {newton['retries']} retries",
        f"  wall:    {wall['total']:.2f} s = set-up {wall['setup']:.2f} (JIT "
        f"{wall['jit_compile']:.2f}) + solve loop {wall['solve_loop']:.2f} (output "
        f"{wall['output']:.2f})",
        f"  output:  {out_dir} (probes.csv, summary.json"
        + (", solution.xdmf" if summary["scene"]["output"]["xdmf"] else "")
        + (
            f", {summary['checkpoints_written']} checkpoints"
            if summary["checkpoints_written"]
            else ""
        )
        + ")",
    ]
    if summary.get("restarts"):
        lines.insert(
            1, f"  restart {summary['restarts']} from t = {summary['restarted_from_s']:.6g} s"
        )
    if summary.get("message"):
        lines.append(f"  stopped: {summary['message']}")
    return "\n".join(lines)
