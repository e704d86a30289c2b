"""Command line: ``cosserat-fem run SCENE [--out DIR] [--set KEY=VALUE ...]``.

Exit status: 0 success, 2 bad input (scene, options, output folder), 3 numerical trouble
(the run stopped; outputs written so far are kept). Errors are one line on stderr; ``--debug``
shows the traceback as well.
"""

from __future__ import annotations

import argparse
import sys
import traceback

from . import __version__
from .errors import CosseratError, SceneError, SolverError


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cosserat-fem",
        description="Nonlinear dynamics of Cosserat rods (Cao & Tucker 2008) with FEniCSx.",
    )
    parser.add_argument("--version", action="version", version=f"cosserat-fem {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run = sub.add_parser("run", help="integrate a scene in time and write its outputs")
    run.add_argument("scene", help="scene file (TOML), e.g. scenes/cao_tucker_2008.toml")
    run.add_argument("--out", metavar="DIR", help="output folder (default: output.directory)")
    run.add_argument(
        "--set",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        dest="overrides",
        help="override a scene value by its dotted key, e.g. --set time.step=1e-5 (repeatable)",
    )
    run.add_argument("--quiet", action="store_true", help="print nothing on success")
    run.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    return parser


def _run(args) -> int:
    from mpi4py import MPI

    from .scene import load_scene
    from .simulation import run

    scene = load_scene(args.scene, args.overrides)
    result = run(scene, args.out)
    if MPI.COMM_WORLD.rank == 0 and not args.quiet:
        s = result.summary
        wall = s["wall_time_s"]
        nt = s["newton"]
        print(
            f"cosserat-fem: {s['steps']} steps to t = {s['time_reached_s']:.6g} s, "
            f"{s['dofs']} dofs, {nt['iterations']} Newton iterations, "
            f"{nt['jacobian_assemblies']} Jacobians; solve loop {wall['solve_loop']:.2f} s "
            f"(total {wall['total']:.2f} s) -> {result.out_dir}"
        )
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "run":
            return _run(args)
    except SceneError as exc:
        _report(exc, args)
        return 2
    except SolverError as exc:
        _report(exc, args)
        return 3
    except CosseratError as exc:
        _report(exc, args)
        return 1
    except KeyboardInterrupt:
        print("cosserat-fem: interrupted", file=sys.stderr)
        return 130
    return 1


def _report(exc: Exception, args) -> None:
    """One line on stderr, from rank 0 only (every rank raises the same collective error)."""
    from mpi4py import MPI

    if MPI.COMM_WORLD.rank != 0:
        return
    if getattr(args, "debug", False):
        traceback.print_exc()
    print(f"cosserat-fem: error: {exc}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
