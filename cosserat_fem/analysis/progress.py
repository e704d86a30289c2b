"""What a command tells its user while it works and when it ends (command line only).

* :class:`StatusLine`: one status line on a terminal, rewritten at most every 0.25 s: a bar,
  the percentage, what is being done, the elapsed and the estimated remaining wall time. The
  estimate is the rate measured from the first update on, so that what comes before it (the
  set-up, a JIT compile that falls in a run's first step) does not count as work done at
  that rate: a run whose compile took 100 s of a first step of 1 % showed 2:45:00 where
  99 steps of 1 s are left. It stays silent when stderr is not a terminal (CI logs, pipes),
  under ``--quiet``, and on every MPI rank but 0; costs nothing measurable (one clock read an
  update).
* :class:`ProgressBar`: the status line of a run (time reached, steps, Newton iterations a
  step); ``render`` shows its pictures and frames on a :class:`StatusLine`.
* :class:`SweepProgress`: a sweep's line per member finished (in logs and pipes too: a
  sweep is long and its lines are few), with the members done and the estimated time left.
* :class:`ContinuationProgress`: a continuation's status line (branches done, the point,
  its load factor).
* :func:`summary_screen`: the end-of-run summary, a dozen lines from ``summary.json``.
* :func:`configure_logging`: ``--quiet`` (errors only), default (warnings), ``--verbose``
  (what the solver decides: step rejections, Jacobian refreshes, checkpoints) on rank 0.

Tests: tests/test_ux.py.
"""

from __future__ import annotations

import logging
import sys
import time
from typing import TextIO

from cosserat_fem.common.log import LOGGER
from cosserat_fem.io.probes import PROBES
from cosserat_fem.io.run_folder import SUMMARY
from cosserat_fem.io.xdmf import XDMF


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


def remaining(since: float, done_then: float, now: float, done: float, total: float) -> str:
    """The time left at the rate measured since ``since`` (when ``done_then`` of ``total``
    was done): "?" until some work has been measured."""
    if done <= done_then:
        return "?"
    return _clock((now - since) * (total - done) / (done - done_then))


class StatusLine:
    """One status line on a terminal (module docstring): :meth:`show` with the fraction done
    and a text; :meth:`close` clears it."""

    INTERVAL = 0.25  # s between redraws

    def __init__(self, stream: TextIO | None = None, enabled=None):
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = self.stream.isatty()
        self.enabled = bool(enabled)
        self._t0 = time.monotonic()
        self._next = self._t0
        self._first: tuple[float, float] | None = None  # (clock, fraction) at the first update
        self._width = 0

    def show(self, fraction: float, text: str) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        fraction = min(1.0, max(0.0, fraction))
        if self._first is None:
            self._first = (now, fraction)
        if now < self._next and fraction < 1.0:
            return
        self._next = now + self.INTERVAL
        filled = int(20 * fraction)
        eta = remaining(*self._first, now, fraction, 1.0)
        line = (
            f"[{'#' * filled}{'.' * (20 - filled)}] {100 * fraction:5.1f}%  {text}  "
            f"elapsed {_clock(now - self._t0)}  ETA {eta}"
        )
        self._width = max(self._width, len(line))
        self.stream.write("\r" + line.ljust(self._width))
        self.stream.flush()

    def count(self, done: int, total: int, what: str) -> None:
        """:meth:`show` of ``done`` items of ``total``, the last being ``what``."""
        self.show(done / total if total else 1.0, what)

    def close(self) -> None:
        if self.enabled and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()


class ProgressBar(StatusLine):
    """Call with (t, steps, newton_iterations) after each output step: a run's status line
    (time reached, steps, Newton iterations a step)."""

    def __init__(self, start: float, end: float, stream: TextIO | None = None, enabled=None):
        super().__init__(stream, enabled)
        self.start, self.end = start, end

    def __call__(self, t: float, steps: int, iterations: int) -> None:
        self.show(
            (t - self.start) / (self.end - self.start),
            f"t = {t:.6g} s  {steps} steps  {iterations / max(steps, 1):.2f} it/step",
        )


class SweepProgress:
    """A sweep's progress: call with a member's row when it is written; one line on
    ``stream`` (stderr): the member, its status and wall time, how many of the sweep's
    members to run are done, and the time left at the rate since the sweep began.

    ``counter`` (shared by the groups of an MPI sweep: cosserat_fem/studies/sweep_run.py's one-sided
    ``_Counter``, its ``next()`` the count before this member) numbers the members in the
    order they finish whichever group ran them; each group's first rank, which writes the
    row, prints the line (world rank 0 when the sweep runs as one group)."""

    def __init__(self, total: int, counter=None, stream: TextIO | None = None):
        self.total, self.counter = total, counter
        self.stream = stream if stream is not None else sys.stderr
        self._t0 = time.monotonic()
        self._done = 0

    def __call__(self, row: dict) -> None:
        done = self.counter.next() + 1 if self.counter is not None else self._done + 1
        self._done = done
        now = time.monotonic()
        self.stream.write(
            f"cosserat-fem: sweep member {row['member']} {row['status']} in "
            f"{float(row['wall_s']):.3g} s; {done} of {self.total} done, elapsed "
            f"{_clock(now - self._t0).strip()}, ETA "
            f"{remaining(self._t0, 0, now, done, self.total).strip()}\n"
        )
        self.stream.flush()


def summary_screen(summary: dict, out_dir) -> str:
    """The end-of-run summary (from the run's summary dict) as lines of text."""
    wall, newton = summary["wall_time_s"], summary["newton"]
    accepted = summary.get("accepted_steps") or summary["steps"]
    per_step = newton["iterations"] / max(accepted, 1)
    from cosserat_fem.forms.kinematics import (
        P_NAMES,  # here: the CLI imports this module for every command
    )

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
        f"  output:  {out_dir} ({PROBES}, {SUMMARY}"
        + (f", {XDMF}" if summary["scene"]["output"]["xdmf"] else "")
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


class ContinuationProgress(StatusLine):
    """Call with (branches finished, points on the branch being traced, its λ) after each
    point (cosserat_fem/analysis/branch_outputs.py): a continuation's status line. The
    fraction is the points over ``max_points``, the most a branch may have (a branch that
    reaches a bound of the range sooner ends the bar early)."""

    def __init__(self, max_points: int, stream: TextIO | None = None, enabled=None):
        super().__init__(stream, enabled)
        self.max_points = max_points

    def __call__(self, branches: int, points: int, load_factor: float) -> None:
        self.show(
            points / self.max_points,
            f"{branches} branches done, point {points}, load factor {load_factor:.6g}",
        )
