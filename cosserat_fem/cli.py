"""Command line: ``cosserat-fem run|static|modes|stability|continue SCENE [--out DIR]
[--set KEY=VALUE ...]``, ``cosserat-fem orbits SCENE --period EXPR [--parameter KEY --from A
--to B]`` (one periodic orbit, or their branch; ``--restart DIR`` continues a branch) and
``cosserat-fem lyapunov SCENE --period EXPR --periods N`` (cosserat_fem/analysis/orbit_runs.py),
``cosserat-fem rom build|run|validate`` for reduced models of POD modes
(cosserat_fem/rom/runs.py; docs/rom.md §11),
``cosserat-fem beamdyn DRIVER [--out DIR]`` for a case of BeamDyn's input files
(cosserat_fem/io/beamdyn.py), ``cosserat-fem sweep SWEEP [--out DIR]`` for the members of a
sweep file (cosserat_fem/studies/sweep_run.py), and ``cosserat-fem run --restart DIR
[--set time.end=...]`` to continue a stopped run;
``cosserat-fem plot|render RUN_DIR [--out DIR]`` draw a run's outputs (plot: a sweep's table
too; no DOLFINx needed), and ``cosserat-fem pod RUN_DIR [--modes K] [--out DIR]`` gives the
Karhunen–Loève (POD) modes of a run's XDMF frames (cosserat_fem/studies/karhunen_loeve.py; no
DOLFINx either).

Exit status: 0 success, 2 bad input (scene, options, output folder, a run that would
exceed its limits, MPI ranks given different command lines), 3 numerical trouble, 4 a run
stopped by an output it could not write (disk full, file size limit) or by a limit
(limits.wall_time), or a sweep with members so stopped; 130 interrupted (SIGINT; under mpirun
every rank stops at the same step); 1 an internal error. A run that stops keeps the outputs
written so far and its checkpoint. Errors are one line on
stderr; ``--debug`` shows the traceback as well, and Python's warnings (which go to the log
at ``--verbose`` otherwise).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import traceback
import warnings
from pathlib import Path

from cosserat_fem import __version__
from cosserat_fem.common.errors import CosseratError, SceneError, SolverError, StopError, out_folder
from cosserat_fem.scene.schema import Removal


def _factor_range(sub: argparse.ArgumentParser, what: str) -> None:
    """--range LOW HIGH: load factors (every load of the scene × f), default 0 1."""
    sub.add_argument(
        "--range",
        nargs=2,
        type=float,
        default=(0.0, 1.0),
        metavar=("LOW", "HIGH"),
        help=f"{what} (every load of the scene × f; default 0 1)",
    )


def _common(
    sub: argparse.ArgumentParser, scene_optional: bool = False, texts: dict[str, str] | None = None
) -> None:
    """The arguments every command takes; ``texts``: another help for "scene", "out" and
    "set" (a sweep's), and "metavar" for the scene."""
    texts = texts or {}
    sub.add_argument(
        "scene",
        nargs="?" if scene_optional else None,
        metavar=texts.get("metavar"),
        help=texts.get("scene", "scene file (TOML), e.g. scenes/cao_tucker_2008.toml"),
    )
    sub.add_argument(
        "--out",
        metavar="DIR",
        help=texts.get(
            "out",
            "output folder (default: output.directory; static and modes: its static/ and modes/)",
        ),
    )
    sub.add_argument(
        "--set",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        dest="overrides",
        help=texts.get(
            "set",
            "override a scene value by its dotted key, e.g. --set time.step=1e-5 (repeatable)",
        ),
    )
    sub.add_argument(
        "--unset",
        metavar="KEY",
        action="append",
        dest="overrides",
        type=Removal,
        help="remove a key or a table of the scene, e.g. --unset rod.section.a; in order with "
        "--set (repeatable)",
    )
    sub.add_argument(
        "--petsc",
        metavar="NAME[=VALUE]",
        action="append",
        dest="overrides",
        type=_petsc_override,
        help="a PETSc option of the SNES solver, without its prefix cosserat_, e.g. --petsc "
        "snes_type=newtontr --petsc snes_monitor: --set solver.petsc.NAME=VALUE, which "
        'chooses SNES (solver.nonlinear = "auto"; README, "The solver") (repeatable)',
    )
    sub.add_argument("--quiet", action="store_true", help="print nothing on success")
    sub.add_argument(
        "--verbose", action="store_true", help="also log step rejections, checkpoints, ..."
    )
    sub.add_argument("--debug", action="store_true", help="show tracebacks on errors")


def _petsc_override(text: str) -> str:
    """``--petsc NAME[=VALUE]`` as the override ``solver.petsc.NAME=VALUE`` (a leading "-" of
    NAME dropped, as PETSc's command line writes it; no VALUE: an option without one)."""
    name, _, value = text.partition("=")
    name = name.strip().removeprefix("-")
    if not name:
        raise argparse.ArgumentTypeError(f"expected NAME[=VALUE], got {text!r}")
    return f"solver.petsc.{name}={value}"


class _Parser(argparse.ArgumentParser):
    """argparse with the one-line errors of the rest of the command line (exit status 2)."""

    def error(self, message: str):
        """One line on stderr naming the problem and ``--help``, then exit status 2 (never
        returns)."""
        print(
            f"cosserat-fem: error: {' '.join(message.split())} (see {self.prog} --help)",
            file=sys.stderr,
        )
        sys.exit(2)


def _parser() -> argparse.ArgumentParser:
    """The parser of the commands run, static, validate, modes, sweep, plot, render and pod
    and their options."""
    parser = _Parser(
        prog="cosserat-fem",
        description="Nonlinear dynamics of Cosserat rods (Cao & Tucker 2008) with FEniCSx.",
    )
    parser.add_argument("--version", action="version", version=f"cosserat-fem {__version__}")
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", parser_class=_Parser
    )
    run = sub.add_parser("run", help="integrate a scene in time and write its outputs")
    _common(run, scene_optional=True)
    run.add_argument(
        "--restart",
        metavar="DIR",
        help="continue the run in DIR from its last checkpoint (no SCENE: the checkpoint's own "
        "is used; --set may change time.end, time.max_halvings, solver.*, output.checkpoint*)",
    )
    _common(sub.add_parser("static", help="static equilibrium by load stepping"))
    _common(
        sub.add_parser(
            "beamdyn", help="read a BeamDyn case (its driver input) and run it (docs/beamdyn.md)"
        ),
        texts={
            "metavar": "DRIVER",
            "scene": "BeamDyn's stand-alone driver input (bd_driver.inp), naming the primary file",
            "out": "output folder (default: results/<the driver's folder name>)",
        },
    )
    _common(
        sub.add_parser(
            "validate", help="check a scene and print it resolved, with units, doing no work"
        )
    )
    modes = sub.add_parser("modes", help="natural frequencies and mode shapes (SLEPc)")
    _common(modes)
    modes.add_argument("--count", type=int, default=10, help="number of modes (default 10)")
    modes.add_argument(
        "--about",
        choices=("undeformed", "static"),
        default="undeformed",
        help="linearise about the straight rod or the static state under the scene's loads",
    )
    stab = sub.add_parser(
        "stability",
        help="stability of the static states under a load "
        "factor, and the critical factor (buckling or flutter)",
    )
    _common(stab)
    _factor_range(stab, "load factors f to search")
    stab.add_argument(
        "--samples", type=int, default=5, help="equally spaced factors visited first (default 5)"
    )
    stab.add_argument(
        "--tolerance",
        type=float,
        default=1e-8,
        help="of the critical factor's root finder, |Δf| <= tol (1 + |f|) (default 1e-8)",
    )
    stab.add_argument(
        "--count", type=int, default=6, help="eigenvalues nearest 0 at each state (default 6)"
    )
    cont = sub.add_parser(
        "continue",
        help="the static equilibrium path in the load factor by pseudo-arclength "
        "continuation: around folds, bifurcations located and switched onto (branches.csv)",
    )
    _common(cont, scene_optional=True)
    _factor_range(cont, "load factors the branches stay in")
    for option, kind, default, text in (
        ("--step", float, 0.05, "first arclength step"),
        ("--max-step", float, 1.0, "largest arclength step"),
        ("--max-points", int, None, "points per branch at most (200)"),
        ("--switch", int, 1, "bifurcation points of the first branch to switch branch at"),
    ):
        cont.add_argument(option, type=kind, default=default, help=f"{text} (default {default})")
    cont.add_argument(
        "--restart",
        metavar="DIR",
        help="trace a branch of the continuation in DIR on from its last point, with its scene "
        "and settings (no SCENE; --max-points may be raised)",
    )
    cont.add_argument(
        "--branch", type=int, default=-1, help="with --restart: the branch (default the last)"
    )
    cont.add_argument(
        "--probe",
        type=float,
        metavar="S",
        help="arclength [m] of the point reported in branches.csv (default the free end, "
        "else mid-span)",
    )
    _orbit_parsers(sub)
    _rom_parsers(sub)
    sweep = sub.add_parser(
        "sweep",
        help="run the members of a sweep file (under mpirun: groups of ranks)",
        description="Run the members of a sweep file not finished in --out (under mpirun: "
        "groups of sweep.group_size ranks); started again with the same --out, a sweep "
        "continues where it stopped (docs/sweeps.md).",
    )
    _common(sweep, texts=_SWEEP_TEXTS)
    plot = sub.add_parser(
        "plot",
        help="PNG figures of a run (free-end histories, x(s,t) and y(s,t) surfaces), "
        "of a sweep (its members' largest free-end values against the varied key; "
        "bifurcation.png with [sweep.poincare]), of a continuation (bifurcation.png), "
        "of an orbit branch (orbit_branch.png) or of a Lyapunov run (lyapunov.png)",
    )
    _run_dir(plot)
    plot.add_argument(
        "--column",
        default="norm",
        help="of a continuation's branches.csv: what the load factor is drawn against "
        "(norm, x, y, z, theta, psi, phi; default norm)",
    )
    render = sub.add_parser(
        "render", help="3D pictures and an animation of a run's rod (pyvista, off-screen)"
    )
    _run_dir(render)
    render.add_argument(
        "--scale",
        type=float,
        default=None,
        help="displacement magnification (default: the largest becomes ~1/5 of the length)",
    )
    render.add_argument(
        "--format", choices=("gif", "mp4"), default="gif", help="animation format (default gif)"
    )
    render.add_argument(
        "--frames", type=int, default=120, help="most frames in the animation (default 120)"
    )
    pod = sub.add_parser(
        "pod", help="Karhunen-Loeve (POD) modes of a run's XDMF frames: pod.csv, pod.xdmf, pod.png"
    )
    _run_dir(pod)
    pod.add_argument(
        "--modes",
        type=int,
        default=None,
        metavar="K",
        help="number of modes (default: 10, or the number of frames if fewer)",
    )
    pod.add_argument(
        "--weighting",
        choices=("displacement", "kinetic"),
        default="displacement",
        help="inner product: displacement x, y, z (default), or kinetic: x, y, z and the angles "
        "weighted by rho A and rho I (the mass inner product; needs the angles in the XDMF)",
    )
    pod.add_argument(
        "--keep-mean", action="store_true", help="do not subtract the time mean of the frames first"
    )
    return parser


def _orbit_parsers(sub) -> None:
    """The parsers of ``orbits`` and ``lyapunov``."""
    orbits = sub.add_parser(
        "orbits",
        help="periodic orbits of a forced rod by shooting: one with its Floquet multipliers, "
        "or with --parameter, --from, --to their branch by continuation (orbit_branch.csv)",
    )
    _common(orbits, scene_optional=True)
    _period(orbits)
    orbits.add_argument("--parameter", metavar="KEY", help="the scene parameter varied")
    orbits.add_argument("--from", dest="start", type=float, metavar="A", help="its first value")
    orbits.add_argument("--to", dest="end", type=float, metavar="B", help="its last value")
    for option, kind, default, text in (
        ("--steps-per-period", int, 300, "SDIRK steps a period"),
        ("--settle", int, 0, "periods time-marched from rest before shooting"),
        ("--step", float, 0.005, "first arclength step"),
        ("--max-step", float, 0.01, "largest arclength step"),
        ("--max-points", int, None, "points of the branch at most (300)"),
    ):
        orbits.add_argument(option, type=kind, default=default, help=f"{text} (default {default})")
    orbits.add_argument(
        "--restart",
        metavar="DIR",
        help="trace the orbit branch in DIR on from its last point, with its scene and "
        "settings (no SCENE; --max-points may be raised)",
    )
    lyap = sub.add_parser(
        "lyapunov",
        help="the largest Lyapunov exponent of a forced rod and its Poincare section "
        "(poincare.csv, lyapunov.csv)",
    )
    _common(lyap)
    _period(lyap)
    lyap.add_argument("--periods", type=int, required=True, help="forcing periods to run")
    lyap.add_argument(
        "--every", type=int, default=1, help="periods between renormalisations (default 1)"
    )
    lyap.add_argument(
        "--discard", type=int, default=0, help="intervals left out of the average (default 0)"
    )


def _rom_parsers(sub) -> None:
    """The parsers of ``rom build``, ``rom run`` and ``rom validate`` (cosserat_fem/rom/runs.py;
    docs/rom.md §11)."""
    rom = sub.add_parser(
        "rom", help="reduced models from POD modes: build a basis, run on it, validate it"
    )
    commands = rom.add_subparsers(
        dest="rom_command", required=True, metavar="ROM_COMMAND", parser_class=_Parser
    )
    build = commands.add_parser(
        "build", help="a basis from full runs of scenes or of a sweep's members (FILE.npz, .json)"
    )
    _common(
        build,
        scene_optional=True,
        texts={
            "metavar": "SCENE ...",
            "scene": "scene files (TOML) to train on",
            "out": "the basis file: FILE.npz and FILE.json (required)",
        },
    )
    build.add_argument("scenes", nargs="*", metavar="SCENE", help=argparse.SUPPRESS)
    _rom_members(build)
    build.add_argument(
        "--tolerance", type=float, metavar="EPS", help="energy left out, docs/rom.md (3), e.g. 1e-8"
    )
    build.add_argument("--modes", type=int, metavar="K", help="the number of modes instead")
    build.add_argument(
        "--every", type=int, default=1, metavar="N", help="a snapshot every N outputs (default 1)"
    )
    build.add_argument("--keep", metavar="DIR", help="keep the training runs' outputs in DIR/<run>")
    build.add_argument(
        "--ecsw",
        type=float,
        metavar="TAU",
        help="hyper-reduce: ECSW's elements and weights to the fit tolerance TAU (serial)",
    )
    run = commands.add_parser(
        "run", help="a reduced run: probes.csv, XDMF and summary.json as a full run's"
    )
    _common(
        run, scene_optional=True, texts={"out": "output folder (default: output.directory/reduced)"}
    )
    run.add_argument("--basis", metavar="FILE", help="the basis file (.npz) of rom build")
    run.add_argument(
        "--restart", metavar="DIR", help="continue the reduced run in DIR (on the same basis)"
    )
    check = commands.add_parser(
        "validate", help="runs in full and reduced: the free-end errors beside the indicator"
    )
    _common(
        check,
        scene_optional=True,
        texts={
            "out": "output folder: full/, reduced/, validation.csv "
            "(default: results/rom_validation)"
        },
    )
    check.add_argument("--basis", metavar="FILE", help="the basis file (.npz) of rom build")
    _rom_members(check)


def _rom_members(sub: argparse.ArgumentParser) -> None:
    sub.add_argument("--sweep", metavar="FILE", help="a sweep file whose members are run")
    sub.add_argument(
        "--members",
        metavar="LIST",
        help="of --sweep: '0,10,20', a range 'start:stop:step' ('::20': every 20th) or "
        "'random:N' (N drawn, the same every time)",
    )


def _period(sub: argparse.ArgumentParser) -> None:
    sub.add_argument(
        "--period",
        metavar="EXPR",
        help="the forcing period [s], or an expression of the scene's constants, e.g. "
        "'2*pi/(r*w1)'",
    )


#: The help of sweep's arguments (its SCENE is a sweep file).
_SWEEP_TEXTS = {
    "metavar": "SWEEP",
    "scene": "sweep file (TOML), e.g. scenes/sweeps/paper_forcing.toml",
    "out": "output folder (default: results/<the sweep file's name>); the same folder "
    "continues a sweep that stopped",
    "set": "override a value of the base scene by its dotted key, after the sweep file's "
    "[sweep.set], e.g. --set time.end=0.01 (repeatable; not a key every member sets)",
}


def _run_dir(sub: argparse.ArgumentParser) -> None:
    """The arguments of the commands that read a run's outputs (plot, render, pod)."""
    sub.add_argument("run_dir", metavar="RUN_DIR", help="the folder of a run (its --out)")
    sub.add_argument("--out", metavar="DIR", help="where the files go (default: RUN_DIR)")
    sub.add_argument("--quiet", action="store_true", help="print nothing on success")
    sub.add_argument("--verbose", action="store_true", help=argparse.SUPPRESS)
    sub.add_argument("--debug", action="store_true", help="show tracebacks on errors")


class _StdoutClosed(Exception):
    """The reader of stdout has gone (``cosserat-fem modes ... | head -2``)."""


def _say(*values, **options) -> None:
    """print() to stdout, flushed at once, so that a reader that has gone is met here:
    :class:`_StdoutClosed` (the command then ends quietly: :func:`_stdout_closed`)."""
    try:
        print(*values, **options, flush=True)
    except BrokenPipeError:
        raise _StdoutClosed from None


def _stdout_closed() -> int:
    """The end of a command whose stdout's reader has gone (``| head``): what is left to print
    goes to /dev/null, nothing is said, and the status is 0. The work (files written) is
    done by the time anything is printed, and only the report on it was cut, by the
    reader's choice; a shell pipeline with ``pipefail`` then does not fail for it
    (docs/decisions.md)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # a stdout without a file descriptor (in a test)
        pass
    return 0


def _ignore_sigpipe(command: str) -> None:
    """A write to a closed pipe raises BrokenPipeError (Python ignores SIGPIPE) rather than
    SIGPIPE ending the process. PETSc installs its own handler for it when it starts
    (``Caught signal number 13 Broken Pipe`` and MPI_ABORT, exit 59, for a progress line or a
    log record written into a closed pipe): the commands that solve start it first, and
    SIGPIPE is ignored again after it."""
    if command in ("run", "static", "modes", "sweep", "rom"):
        from petsc4py import PETSc  # noqa: F401 - initialises PETSc, with its signal handlers
    with contextlib.suppress(ValueError):  # only the main thread may set handlers
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)


def _draw(args) -> int:
    """Figures (cosserat_fem/plot.py) or pictures and an animation (cosserat_fem/render.py) of
    the run in args.run_dir; no DOLFINx."""
    if args.command == "plot":
        from cosserat_fem.plot import plot_run

        paths = plot_run(args.run_dir, args.out, args.column)
    else:
        from cosserat_fem.analysis.progress import StatusLine
        from cosserat_fem.render import render_run

        bar = StatusLine(enabled=False if args.quiet else None)  # on a terminal only
        try:
            paths = render_run(
                args.run_dir, args.out, args.scale, args.format, args.frames, progress=bar.count
            )
        finally:
            bar.close()
    if not args.quiet:
        _say("-> " + ", ".join(str(p) for p in paths))
    return 0


def _pod(args) -> int:
    """``pod``: the POD of a run's XDMF frames (cosserat_fem/studies/karhunen_loeve.py, no DOLFINx)
    into
    --out (default the run's folder); the energies as a table and the files' paths."""
    from mpi4py import MPI

    from cosserat_fem import api

    out = args.run_dir if args.out is None else args.out
    result = api.pod(
        args.run_dir,
        modes=args.modes,
        weighting=args.weighting,
        remove_mean=not args.keep_mean,
        out=out,
    )
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        _say(
            f"cosserat-fem: POD of {len(result.times)} frames at {len(result.s)} points "
            f"({result.weighting} weighting, mean {'removed' if result.remove_mean else 'kept'}"
            f"), total energy {result.total:.6g} {result.unit}"
        )
        _say(
            f"{'mode':>4} {'energy [' + result.unit + ']':>20} {'fraction':>12} {'cumulative':>12}"
        )
        for k, (e, f, c) in enumerate(
            zip(result.energies, result.fractions, result.cumulative, strict=True), start=1
        ):
            _say(f"{k:4d} {e:20.10e} {f:12.6e} {c:12.6f}")
        _say("-> " + ", ".join(str(p) for p in result.files))
    return 0


#: Where a command writes without --out: ``run`` into the scene's output.directory, ``static``
#: and ``modes`` into folders of their own beneath it (a static solve would replace a run's
#: probes.csv, summary.json and checkpoint; modes would mix its files into the run's folder).
OWN_FOLDER = {
    "static": "static",
    "modes": "modes",
    "stability": "stability",
    "continue": "continuation",
    "orbits": "orbits",
    "lyapunov": "lyapunov",
    "rom": "reduced",
}


def _scene_or_restart(args, command: str):
    """(scene, checkpoint, start time [s], folder) of ``command``'s run: the SCENE file with
    its overrides into --out or the command's own folder (:func:`_out`), or the run in
    --restart DIR continued in its own folder (checkpoint given, folder None)."""
    from cosserat_fem import api

    if args.restart is not None:
        if args.scene is not None or args.out is not None:
            which = "SCENE" if args.scene is not None else "--out"
            raise SceneError(
                f"{command} --restart: {which} cannot be given (the run continues in its own "
                "folder with its own scene)"
            )
        scene, checkpoint = api.resume(args.restart, args.overrides)
        return scene, checkpoint, checkpoint.time, None
    if args.scene is None:
        raise SceneError(f"{command}: give a SCENE file, or --restart DIR to continue a run")
    scene = api.load(args.scene, args.overrides)
    return scene, None, scene.time.start, _out(args, scene)


def _out(args, scene=None, command: str | None = None) -> str:
    """--out (checked by the API: an empty name is refused, not the current folder), or the
    default folder of ``command`` (default: the command run): :data:`OWN_FOLDER`, and a
    sweep's results/<the sweep file's name>."""
    if args.out is not None:
        return args.out
    command = command or args.command
    if command == "sweep":
        return str(Path("results") / Path(args.scene).stem)
    own = OWN_FOLDER.get(command)
    return str(Path(scene.output.directory) / own) if own else scene.output.directory


def _run(args) -> int:
    """``run``: a scene, or ``--restart DIR``, through the Python API (cosserat_fem/api.py)."""
    from mpi4py import MPI

    from cosserat_fem import api
    from cosserat_fem.analysis.progress import ProgressBar, summary_screen

    rank = MPI.COMM_WORLD.rank
    scene, checkpoint, start, out = _scene_or_restart(args, "run")
    # The bar on a terminal (it decides), never under --quiet or off rank 0.
    enabled = None if rank == 0 and not args.quiet else False
    bar = ProgressBar(start, scene.time.end, enabled=enabled)
    try:
        result = api.run(scene, out, restart=checkpoint, progress=bar, record=False)
    finally:
        bar.close()
    if rank == 0 and not args.quiet:
        _say(summary_screen(result.summary, result.out_dir))
    return 0


def _static(args) -> int:
    """``static``: load stepping through the Python API; the probe's final values."""
    from mpi4py import MPI

    from cosserat_fem import api
    from cosserat_fem.forms.kinematics import P_NAMES

    scene = api.load(args.scene, args.overrides)
    result = api.static(scene, _out(args, scene))
    tip = result.probes[-1, 1 : 1 + len(P_NAMES)]  # the six of P_NAMES; probe_fields follow
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        _say(
            f"cosserat-fem: static, {len(result.load_factors) - 1} load steps "
            f"({result.bisections} halvings), {sum(result.iterations)} Newton iterations"
        )
        _say("  probe: " + ", ".join(f"{n} = {v:.10g}" for n, v in zip(P_NAMES, tip, strict=True)))
    return 0


def _beamdyn(args) -> int:
    """``beamdyn``: the BeamDyn case of a driver input (cosserat_fem/io/beamdyn.py) run as its
    driver says, static (load stepping) or dynamic (in time), through the Python API; the tip's
    displacement and rotation as BeamDyn's TipTD and TipRD (Wiener-Milenkovic) channels."""
    from mpi4py import MPI

    from cosserat_fem import api
    from cosserat_fem.io.beamdyn import read_case, scene_of, tip_of

    case = read_case(args.scene)
    scene = api.load(scene_of(case), args.overrides)
    out = args.out if args.out is not None else scene.output.directory
    if case.dynamic:
        result = api.run(scene, out, record=True)
    else:
        result = api.static(scene, out)
    tip = tip_of(scene, result.probes[-1])
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        kind = "dynamic" if case.dynamic else "static"
        _say(f"cosserat-fem: BeamDyn case {case.driver} ({kind}), outputs in {out}")
        for name, values in tip.items():
            _say(f"  {name}xr, yr, zr = " + ", ".join(f"{v:.10g}" for v in values))
    return 0


def _modes(args) -> int:
    """``modes``: about the straight rod or the static state, through the Python API."""
    from mpi4py import MPI

    from cosserat_fem import api

    scene = api.load(args.scene, args.overrides)
    out = _out(args, scene)
    modes = api.modes(scene, args.count, args.about, out)
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        _say(f"{'mode':>4} {'omega [rad/s]':>16} {'f [Hz]':>12}  kind")
        for i, mode in enumerate(modes, start=1):
            note = f"  ({mode.note})" if mode.note else ""
            _say(f"{i:4d} {mode.omega:16.6f} {mode.frequency_hz:12.4f}  {mode.kind}{note}")
        names = ("modes.csv", "modes.xdmf", "modes.json")
        _say("-> " + ", ".join(str(Path(out) / name) for name in names))
    return 0


def _stability(args) -> int:
    """``stability``: the states over --range and the critical factor, through the Python
    API; a line per state visited, then the critical factor and stability.json's path."""
    from mpi4py import MPI

    from cosserat_fem import api

    scene = api.load(args.scene, args.overrides)
    out = _out(args, scene)
    low, high = args.range
    result = api.stability(
        scene, low, high, samples=args.samples, tolerance=args.tolerance, count=args.count, out=out
    )
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        _say(f"{'factor':>16}  {'state':<10}  lowest eigenvalues (units of omega0^2)")
        for point in result.points:
            lams = ", ".join(
                f"{lam.real:.6g}{lam.imag:+.3g}i" if lam.imag else f"{lam.real:.6g}"
                for lam in point.eigenvalues[:3]
            )
            _say(f"{point.factor:16.10g}  {point.status:<10}  {lams}")
        if result.critical is None:
            _say(f"cosserat-fem: stability: no critical factor ({result.reason})")
        else:
            _say(
                f"cosserat-fem: stability: {result.kind} at load factor {result.critical:.10g} "
                f"(in [{result.bracket[0]:.6g}, {result.bracket[1]:.6g}], tolerance "
                f"{result.tolerance:g})"
            )
        _say(f"-> {Path(out) / 'stability.json'}")
    return 0


def _restart_only(args, what: str) -> str:
    """--restart DIR of ``continue`` or ``orbits``; SceneError if a SCENE, --set or --out is
    given too (the ``what`` goes on in its own folder with its own scene)."""
    if args.scene is not None or args.overrides or args.out is not None:
        raise SceneError(
            f"{args.command} --restart: give no SCENE, --set or --out (the {what} goes on "
            "in its own folder with its own scene)"
        )
    return args.restart


def _out_named(command):
    """``command`` (continue, orbits, lyapunov) with its folder's refusals naming --out when
    it was given, not output.directory (io/folder_lock.py ``named_by``)."""

    def named(args) -> int:
        from cosserat_fem.io.folder_lock import named_by

        with named_by("--out" if args.out is not None else None):
            return command(args)

    named.__doc__ = command.__doc__
    return named


@_out_named
def _continue(args) -> int:
    """``continue``: the branches through the Python API; a line per branch (its origin,
    points, λ and the free end's angle ψ at its end, why it ended), one per special point,
    then branches.csv's path."""
    from mpi4py import MPI

    from cosserat_fem import api
    from cosserat_fem.analysis.progress import ContinuationProgress

    # The bar on a terminal (it decides), never under --quiet or off rank 0.
    enabled = None if MPI.COMM_WORLD.rank == 0 and not args.quiet else False
    bar = ContinuationProgress(args.max_points or 200, enabled=enabled)
    if args.restart is not None:
        out = _restart_only(args, "continuation")
        result = api.continuation(
            None, max_points=args.max_points, restart=out, branch=args.branch, progress=bar
        )
    else:
        if args.scene is None:
            raise SceneError("continue: give a SCENE file, or --restart DIR")
        if args.branch != -1:
            raise SceneError("continue --branch: only with --restart DIR (the branch traced on)")
        scene = api.load(args.scene, args.overrides)
        out = _out(args, scene)
        low, high = args.range
        result = api.continuation(
            scene,
            low,
            high,
            step=args.step,
            max_step=args.max_step,
            max_points=args.max_points,
            switch=args.switch,
            out=out,
            progress=bar,
            probe=args.probe,
        )
    bar.close()
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        for i, branch in enumerate(result.branches, start=result.first_branch):
            end = branch.points[-1]
            _say(
                f"branch {i} ({branch.origin}): {branch.steps} steps, to load factor "
                f"{end.factor:.10g}, psi = {end.tip[4]:.10g} rad: {branch.reason}"
            )
            for point in branch.special:
                note = f" ({point.note})" if point.note else ""
                _say(f"  {point.kind} point at load factor {point.factor:.10g}{note}")
        _say(f"-> {Path(out) / 'branches.csv'}")
    return 0


@_out_named
def _orbits(args) -> int:
    """``orbits``: one orbit and its multipliers, or with a range the branch (or
    ``--restart DIR``) through the Python API; a line per special point and why the branch
    ended (on stderr too unless it reached the range's end)."""
    from mpi4py import MPI

    from cosserat_fem import api
    from cosserat_fem.analysis.orbit_runs import SUMMARY, OrbitProgress

    root = MPI.COMM_WORLD.rank == 0
    ranged = (args.parameter, args.start, args.end)
    if args.restart is None and all(v is None for v in ranged):
        return _one_orbit(args)
    enabled = None if root and not args.quiet else False
    bar = OrbitProgress(args.max_points or 300, enabled=enabled)
    try:
        if args.restart is not None:
            out = _restart_only(args, "branch")
            branch, summary = api.orbits(
                None, max_points=args.max_points, restart=out, progress=bar
            )
        else:
            for value, flag in zip(ranged, ("--parameter", "--from", "--to"), strict=True):
                if value is None:
                    raise SceneError(f"orbits {flag}: give --parameter, --from and --to")
            if args.scene is None:
                raise SceneError("orbits: give a SCENE file, or --restart DIR")
            scene = api.load(args.scene, args.overrides)
            out = _out(args, scene)
            branch, summary = api.orbits(
                scene,
                args.period,
                args.parameter,
                args.start,
                args.end,
                settle=args.settle,
                steps_per_period=args.steps_per_period,
                step=args.step,
                max_step=args.max_step,
                max_points=args.max_points,
                out=out,
                progress=bar,
            )
    finally:
        bar.close()
    if root:
        if not summary["reason"].startswith("p reached"):
            print(f"cosserat-fem: orbits: the branch ended: {summary['reason']}", file=sys.stderr)
        if not args.quiet:
            last = branch.points[-1]
            _say(
                f"cosserat-fem: orbits: {summary['points']} orbits, {summary['steps']} steps "
                f"({summary['monodromies']} monodromies), to {summary['parameter']} = "
                f"{last.parameter:.10g}, amplitude {last.amplitude:.6g} m "
                f"({last.stability}): {summary['reason']}"
            )
            for point in summary["special"]:
                _say(
                    f"  {point['kind']} point at {summary['parameter']} = "
                    f"{point['parameter']:.10g}, amplitude {point['amplitude']:.6g} m"
                )
            _say(f"-> {Path(out) / 'orbit_branch.csv'}, {Path(out) / SUMMARY}")
    from cosserat_fem.analysis.orbit_runs import WALL_TIME_STOP

    return 4 if summary["reason"].startswith(WALL_TIME_STOP) else 0  # a stopped run's code


def _one_orbit(args) -> int:
    """``orbits SCENE --period EXPR`` without a range: the orbit near rest (after
    --settle periods), its amplitude and Floquet multipliers; summary.json in --out."""
    import json

    from mpi4py import MPI

    from cosserat_fem import api
    from cosserat_fem.analysis.branch_outputs import replace_on_root
    from cosserat_fem.analysis.orbit_runs import SUMMARY, check_periodic, period_value
    from cosserat_fem.io.folder_lock import folders_held
    from cosserat_fem.io.run_folder import prepare_output_dir

    if args.scene is None:
        raise SceneError("orbits: give a SCENE file, or --restart DIR")
    scene = api.load(args.scene, args.overrides)
    if args.period is None:
        raise SceneError("orbits --period: give the forcing period [s] or its expression")
    value = period_value(scene, args.period)
    check_periodic(scene, value)
    api._check_shooting(scene, args.settle, args.steps_per_period, True)
    api._shooting_budget(scene, value, args.settle, args.steps_per_period)
    comm = MPI.COMM_WORLD
    with folders_held():
        folder = prepare_output_dir(Path(_out(args, scene)), comm, "orbits")
        orbit = api.periodic_orbit(
            scene, args.period, settle=args.settle, steps_per_period=args.steps_per_period
        )
        mu = [[float(m.real), float(m.imag)] for m in orbit.multipliers]
        summary = {
            "command": "orbit",
            "period": orbit.period,
            "amplitude": orbit.amplitude,
            "stability": orbit.stability,
            "iterations": orbit.iterations,
            "residual": orbit.residual,
            "multipliers": mu,
        }
        replace_on_root(folder / SUMMARY, (json.dumps(summary, indent=1) + "\n").encode(), comm)
    if comm.rank == 0 and not args.quiet:
        _say(
            f"cosserat-fem: orbit: period {orbit.period:.10g} s, amplitude "
            f"{orbit.amplitude:.6g} m, {orbit.stability}, {orbit.iterations} Newton iterations"
        )
        _say(f"{'|mu|':>14} {'Re mu':>14} {'Im mu':>14}")
        for m in orbit.multipliers[:6]:
            _say(f"{abs(m):14.8f} {m.real:14.8f} {m.imag:14.8f}")
        _say(f"-> {folder / SUMMARY}")
    return 0


@_out_named
def _lyapunov(args) -> int:
    """``lyapunov``: the exponent through the Python API; its value and the files."""
    from mpi4py import MPI

    from cosserat_fem import api

    if args.period is None:
        raise SceneError("lyapunov --period: give the forcing period [s] or its expression")
    scene = api.load(args.scene, args.overrides)
    out = _out(args, scene)
    result = api.lyapunov_run(
        scene, args.period, periods=args.periods, every=args.every, discard=args.discard, out=out
    )
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        _say(
            f"cosserat-fem: lyapunov: largest exponent {result.exponent:.8g} 1/s over "
            f"{result.times.size} intervals ({result.discard} discarded)"
        )
        _say("-> " + ", ".join(str(p) for p in result.files))
    return 0


def _sweep(args) -> int:
    """``sweep``: the members of a sweep file (cosserat_fem/studies/sweep_run.py) into --out
    (default
    results/<the sweep file's name>); a summary line and the table's path."""
    from mpi4py import MPI

    from cosserat_fem import api

    spec = api.load_sweep(args.scene, args.overrides)
    out = _out(args)
    result = api.sweep(spec, out, progress=not args.quiet)
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        statuses = [row["status"] for row in result.rows]
        counts = ", ".join(f"{s} {statuses.count(s)}" for s in dict.fromkeys(statuses))
        _say(
            f"cosserat-fem: sweep of {len(spec.members)} members: ran {result.ran}, skipped "
            f"{result.skipped} finished before; {counts}"
        )
        _say(f"-> {result.table}")
    return 0


def _rom(args) -> int:
    """``rom build|run|validate`` (cosserat_fem/rom/runs.py): the basis's files, a reduced run's
    summary, or the validation's table."""
    from mpi4py import MPI

    from cosserat_fem import api
    from cosserat_fem.analysis.progress import ProgressBar, summary_screen
    from cosserat_fem.rom import runs
    from cosserat_fem.rom.basis import basis_paths
    from cosserat_fem.scene.build import refuse_structure

    root = MPI.COMM_WORLD.rank == 0 and not args.quiet
    sweep = api.load_sweep(args.sweep, args.overrides) if getattr(args, "sweep", None) else None
    if args.rom_command == "build":
        if args.out is None:
            raise SceneError("rom build --out: give the basis file's name (FILE: FILE.npz, .json)")
        files = [args.scene, *args.scenes] if args.scene is not None else []
        scenes = [api.load(s, args.overrides) for s in files]
        for scene in scenes:
            refuse_structure(scene, "rom")
        if not scenes and sweep is None:
            raise SceneError("rom build: give SCENE files or --sweep FILE to train on")
        basis = runs.build(
            scenes,
            args.out,
            sweep=sweep,
            members=args.members,
            tolerance=args.tolerance,
            modes=args.modes,
            every=args.every,
            keep=args.keep,
            ecsw=args.ecsw,
        )
        if root:
            _say(
                f"cosserat-fem: rom build: {basis.modes} modes of "
                f"{basis.provenance['snapshots']} snapshots of "
                f"{len(basis.provenance['runs'])} runs, energy left out "
                f"{basis.energy_left_out():.3e}"
            )
            fit = basis.provenance.get("ecsw")
            if fit is not None:
                _say(
                    f"cosserat-fem: rom build: ECSW kept {fit['elements']} of {fit['of']} "
                    f"elements, fit error {fit['fit_error']:.3e} (tolerance {fit['tolerance']:g})"
                )
            npz, meta = basis_paths(args.out)
            _say(f"-> {npz}, {meta}")
        return 0
    if args.basis is None:
        raise SceneError(f"rom {args.rom_command} --basis: give the basis file (rom build --out)")
    if args.rom_command == "validate":
        scenes = [api.load(args.scene, args.overrides)] if args.scene else []
        if args.scene is None and sweep is None:
            raise SceneError("rom validate: give a SCENE or --sweep FILE")
        out = args.out or str(Path("results") / "rom_validation")
        result = runs.validate(args.basis, scenes, out, sweep=sweep, members=args.members)
        if root:
            for line in runs.validation_lines(result):
                _say(line)
            _say(f"-> {result.table}")
        return 0
    scene, checkpoint, start, out = _scene_or_restart(args, "rom run")
    bar = ProgressBar(start, scene.time.end, enabled=None if root else False)
    try:
        result = runs.run(scene, args.basis, out, restart=checkpoint, progress=bar, record=False)
    finally:
        bar.close()
    if root:
        _say(summary_screen(result.summary, result.out_dir))
    return 0


def _validate(args) -> int:
    """The scene resolved, and what ``run`` and ``static`` of it cost at least
    (cosserat_fem/analysis/budget.py), refused if that exceeds its limits (exit 2), as they would
    refuse it."""
    from mpi4py import MPI

    from cosserat_fem.analysis import budget
    from cosserat_fem.common.parallel import ranks_on_node
    from cosserat_fem.scene.build import load_scene
    from cosserat_fem.scene.describe import describe_scene

    comm = MPI.COMM_WORLD
    scene = load_scene(args.scene, args.overrides)
    node = ranks_on_node(comm)
    costs = {
        c: budget.check(scene, c, out_folder(_out(args, scene, c)), node, comm.size, comm=comm)
        for c in ("run", "static")
    }
    if comm.rank == 0 and not args.quiet:
        _say(describe_scene(scene))
        for command, estimate in costs.items():
            _say(f"  {command}: {estimate.describe()} (estimated lower bounds)")
    return 0


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status (module docstring)."""
    try:
        before = signal.signal(signal.SIGINT, _interrupted)
    except ValueError:  # only the main thread may set handlers
        before = None
    try:
        try:
            try:
                args = _parser().parse_args(argv)
            finally:
                sys.stdout.flush()  # --help and --version, perhaps into a closed pipe
        except BrokenPipeError:
            return _stdout_closed()
        status = _main(args)
        if status != 0:
            from cosserat_fem.common.parallel import agree_or_abort, cancel_abort

            # An error or an interrupt that the other ranks did not meet must not hang them;
            # a second Ctrl-C does not cut this wait short (it ends within ABORT_AFTER s).
            if before is not None:
                signal.signal(signal.SIGINT, signal.SIG_IGN)
            agree_or_abort(status)
            cancel_abort()  # every rank is on its way out
        return status
    finally:
        if before is not None:
            signal.signal(signal.SIGINT, before)


def _interrupted(signum, frame) -> None:
    """SIGINT: KeyboardInterrupt (the run records "interrupted", exit status 130). Under
    mpirun the signal may reach this rank alone (``kill -INT``; Open MPI's mpirun itself
    sends SIGTERM to every rank), and a rank that stopped at once would leave the others
    waiting for it: it is remembered instead, and every rank of the run stops at its next
    step (parallel.interrupt); the job is aborted if it has not ended within
    parallel.ABORT_AFTER s (what was computed is kept, as after a kill)."""
    if "mpi4py.MPI" in sys.modules:  # not before: MPI is not initialised, no job to hang
        from cosserat_fem.common.parallel import interrupt

        if interrupt():
            return
    raise KeyboardInterrupt


def _main(args) -> int:
    """Run the command of ``args``; returns its exit status (module docstring): 0, 2 for a
    SceneError, 3 a SolverError, 4 a StopError, 1 any other error, 130 Ctrl-C, each error
    reported as one line (:func:`_report`)."""
    from mpi4py import MPI

    from cosserat_fem.analysis.progress import configure_logging
    from cosserat_fem.common.parallel import prepare_agreement

    level = "quiet" if args.quiet else "verbose" if args.verbose else "normal"
    configure_logging(level, MPI.COMM_WORLD.rank)
    prepare_agreement()
    # A write past the file size limit (ulimit -f) fails with EFBIG, which the outputs report
    # (exit 4), instead of SIGXFSZ killing the process with a core dump.
    with contextlib.suppress(ValueError):  # only the main thread may set handlers
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    # Python's warnings (numpy's on non-finite values, FFCx's) go to the log, not around the
    # one-line messages: shown with --verbose or --debug.
    if not args.debug:
        warnings.simplefilter("ignore" if not args.verbose else "default")
    try:
        _same_command_line(args, MPI.COMM_WORLD)  # first: the ranks must agree on it
        _ignore_sigpipe(args.command)
        if args.command == "validate":
            return _validate(args)
        if args.command == "run":
            return _run(args)
        if args.command in ("plot", "render"):
            return _draw(args)
        if args.command == "modes":
            return _modes(args)
        if args.command == "static":
            return _static(args)
        if args.command == "beamdyn":
            return _beamdyn(args)
        if args.command == "stability":
            return _stability(args)
        if args.command == "continue":
            return _continue(args)
        if args.command == "sweep":
            return _sweep(args)
        if args.command == "orbits":
            return _orbits(args)
        if args.command == "lyapunov":
            return _lyapunov(args)
        if args.command == "pod":
            return _pod(args)
        if args.command == "rom":
            return _rom(args)
    except SceneError as exc:
        _report(exc, args)
        return 2
    except SolverError as exc:
        _report(exc, args)
        return 3
    except StopError as exc:
        _report(exc, args)
        return 4
    except CosseratError as exc:
        _report(exc, args)
        return 1
    except _StdoutClosed:
        return _stdout_closed()
    except KeyboardInterrupt:
        print("cosserat-fem: interrupted", file=sys.stderr)
        return 130
    except RuntimeError as exc:
        if str(exc).startswith(_MPI_JIT_FAILURE):  # dolfinx's wrapper of rank 0's JIT error
            _report(CosseratError(str(exc).removeprefix(_MPI_JIT_FAILURE)), args, exc)
            return 1
        _report_internal(exc, args)
        return 1
    except Exception as exc:  # an internal error: one line, the traceback with --debug
        _report_internal(exc, args)
        return 1
    return 1


#: The command line's names of the arguments whose name is not --<dest>.
_NAMES = {"scene": "SCENE", "run_dir": "RUN_DIR", "overrides": "--set", "command": "COMMAND"}


def _same_command_line(args, comm) -> None:
    """SceneError on every rank unless every MPI rank was given the same command line
    (``mpirun sh -c '... $SCENE_$OMPI_COMM_WORLD_RANK'``, a --set taken from the
    environment): ranks given different scenes would compute a blend, or hang. Collective."""
    if comm.size == 1:
        return
    given = comm.allgather(sorted(vars(args).items()))
    for rank, other in enumerate(given[1:], start=1):
        if other != given[0]:
            name, mine = next(
                (k, v) for (k, v), o in zip(given[0], other, strict=False) if (k, v) != o
            )
            theirs = dict(other).get(name)
            option = _NAMES.get(name, "--" + name.replace("_", "-"))
            if option == "SCENE" and args.command == "sweep":
                option = "SWEEP"
            raise SceneError(
                f"{option}: the MPI ranks were given different command lines "
                f"(rank 0: {mine!r}, rank {rank}: {theirs!r}); give every rank "
                "the same"
            )


#: How dolfinx.jit.mpi_jit_decorator wraps a compile error of rank 0 under MPI.
_MPI_JIT_FAILURE = "Failed just-in-time compilation of form: "


def _report(exc: Exception, args, cause: BaseException | None = None) -> None:
    """One line on stderr, from rank 0 only (every rank raises the same collective error)."""
    from mpi4py import MPI

    if MPI.COMM_WORLD.rank != 0:
        return
    if getattr(args, "debug", False):
        traceback.print_exception(cause or exc)
    print(f"cosserat-fem: error: {exc}", file=sys.stderr)


def _report_internal(exc: Exception, args) -> None:
    """An internal error (a bug), one line from every rank that meets it (it may be one
    rank alone: its message must not be lost), named by rank under MPI."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    if getattr(args, "debug", False):
        traceback.print_exception(exc)
    where = f" (rank {comm.rank})" if comm.size > 1 else ""
    text = f"internal error: {type(exc).__name__}: {exc}".splitlines()[0]
    print(f"cosserat-fem: error{where}: {CosseratError(text)}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
