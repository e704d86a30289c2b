"""The paper's scene as a user runs it, against a baseline commit and PyElastica, in one run.

    .venv/bin/python benchmarks/speed.py [--baseline REV] [--repeats 5] [--no-elastica]

What issue 15 asks to compare, measured side by side on this machine (whose speed drifts
2-3x within an hour, so only ratios of interleaved runs mean anything):

* ``whole``: ``cosserat-fem run scenes/cao_tucker_2008.toml --out DIR --quiet``, the whole
  process as shipped (outputs, XDMF and checkpoints included), wall time;
* ``loop``: the solve loop without output of a run with ``output.xdmf=false``, as its
  summary.json reports it (``wall_time_s.solve_loop_without_output``), and the Newton
  iterations of the run;
* ``precise``: the current tree's solve loop in :data:`PRECISE`, the cheapest configuration
  found with error ≤ 1e-4, against the baseline's default loop (goal 3 of issue 15), with its
  error against the benchmark's reference (benchmarks/work_precision.py) if results/reference.npz
  is there;
* ``elastica``: PyElastica 1.0.0 on the same rod at N = 400 elements (benchmarks/pyelastica),
  the whole process, at 0.9 of its largest stable step (results/stable_dt.json; made by its
  stable_dt.py when missing). Without PyElastica's venv (benchmarks/pyelastica/setup.sh) the
  script stops with one line, unless ``--no-elastica`` is given.

Each of the current tree and the baseline (a git revision checked out into a temporary
worktree, run with its own scene file) is run once to warm the JIT cache, then the cases are
taken in rounds (baseline, current, PyElastica, ...) ``--repeats`` times; the table gives the
medians and the ratios baseline/current and PyElastica/current. Written to
benchmarks/results/speed.md and speed.json (not committed).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
ELASTICA = ROOT / "benchmarks" / "pyelastica"
ELASTICA_VENV = Path(os.environ.get("PYELASTICA_VENV", RESULTS / "pyelastica-venv"))
ELASTICA_N = 400
SCENE = "scenes/cao_tucker_2008.toml"
#: The main of the day issue 15 was filed (its 5.1 s and 2.6 s were measured on it).
DEFAULT_BASELINE = "0c7f4d2"
#: Issue 15's goal 3, error ≤ 1e-4 at the baseline's cost of its 1e-3 (the default scene):
#: quartic elements, five of them, SDIRK3 at 15 μs (the cheapest such configuration of a study
#: of 63, docs/decisions.md "Accuracy per cost").
PRECISE = ("discretisation.degree=4", "discretisation.elements=5", "time.step=1.5e-5")


def _env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}


def timed(command: list[str], cwd: Path, env: dict[str, str]) -> float:
    """Wall time [s] of a process that must succeed."""
    t0 = time.perf_counter()
    proc = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed: {proc.stderr[-2000:]}")
    return wall


class Tree:
    """A source tree of cosserat-fem run with the venv's Python (``python -m cosserat_fem.cli``)."""

    def __init__(self, name: str, path: Path, work: Path):
        self.name, self.path, self.work = name, path, work

    def _run(self, out: Path, extra: list[str]) -> float:
        shutil.rmtree(out, ignore_errors=True)
        command = [sys.executable, "-m", "cosserat_fem.cli", "run", SCENE, "--out", str(out)]
        command += ["--quiet", *(f"--set={x}" for x in extra)]
        return timed(command, self.path, _env(self.path))

    def whole(self) -> float:
        return self._run(self.work / f"{self.name}-whole", [])

    def loop(self, extra: tuple[str, ...] = (), tag: str = "loop") -> tuple[float, int]:
        out = self.work / f"{self.name}-{tag}"
        self._run(out, ["output.xdmf=false", *extra])
        summary = json.loads((out / "summary.json").read_text())
        return summary["wall_time_s"]["solve_loop_without_output"], summary["newton"]["iterations"]

    def error(self, tag: str) -> float | None:
        """The benchmark error (benchmarks/work_precision.py) of the run ``tag``'s probes, if
        the reference (results/reference.npz, made by ``make bench``) is there."""
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from work_precision import probe_error

        probes = np.loadtxt(
            self.work / f"{self.name}-{tag}" / "probes.csv", delimiter=",", skiprows=1
        )
        return probe_error(probes)


def elastica_dt() -> float:
    """0.9 of PyElastica's largest stable step at N = ELASTICA_N (stable_dt.py, cached)."""
    path = ELASTICA / "results" / "stable_dt.json"
    rows = json.loads(path.read_text())["rows"] if path.exists() else []
    found = [r for r in rows if r["N"] == ELASTICA_N]
    if not found:
        out = ELASTICA / "results" / f"stable_dt_{ELASTICA_N}.json"
        if not out.exists():
            command = [str(ELASTICA_VENV / "bin" / "python"), str(ELASTICA / "stable_dt.py")]
            subprocess.run([*command, "--elements", str(ELASTICA_N), "--out", str(out)], check=True)
        found = [r for r in json.loads(out.read_text())["rows"] if r["N"] == ELASTICA_N]
    return 0.9 * found[0]["dt_stable"]


def elastica(dt: float, work: Path) -> float:
    """Wall time [s] of PyElastica's whole process on the paper's rod (N = ELASTICA_N)."""
    command = [str(ELASTICA_VENV / "bin" / "python"), str(ELASTICA / "cantilever.py")]
    command += ["--elements", str(ELASTICA_N), "--dt", repr(dt), "--end", "0.06"]
    command += ["--out", str(work / "elastica.csv")]
    return timed(command, ROOT, dict(os.environ))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default=DEFAULT_BASELINE, help="a git revision")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-elastica", action="store_true")
    args = parser.parse_args()
    with_elastica = not args.no_elastica
    if with_elastica and not (ELASTICA_VENV / "bin" / "python").exists():
        # Asked for, so not left out in silence: a table without it reads as "not measured".
        sys.exit(
            f"speed: no PyElastica venv at {ELASTICA_VENV}: make it with "
            "bash benchmarks/pyelastica/setup.sh (PYELASTICA_VENV to put it elsewhere), "
            "or pass --no-elastica"
        )
    work = Path(tempfile.mkdtemp(prefix="speed-"))
    base_path = work / "baseline"
    subprocess.run(
        ["git", "worktree", "add", "--detach", str(base_path), args.baseline],
        cwd=ROOT,
        check=True,
        capture_output=True,
    )
    try:
        trees = [Tree("baseline", base_path, work), Tree("current", ROOT, work)]
        dt = elastica_dt() if with_elastica else None
        for tree in trees:  # bytecode for both (as .ci/setup.sh makes it), and the JIT cache
            subprocess.run(
                [sys.executable, "-m", "compileall", "-q", "cosserat_fem", "forms"],
                cwd=tree.path,
                check=True,
                capture_output=True,
            )
            tree.whole()
        samples: dict[str, list[float]] = {}
        iterations: dict[str, int] = {}
        for round_ in range(args.repeats):
            for tree in trees:
                samples.setdefault(f"{tree.name} whole", []).append(tree.whole())
                loop, its = tree.loop()
                samples.setdefault(f"{tree.name} loop", []).append(loop)
                iterations[tree.name] = its
            precise, iterations["precise"] = trees[1].loop(PRECISE, "precise")
            samples.setdefault("current precise", []).append(precise)
            if dt is not None:
                samples.setdefault("elastica whole", []).append(elastica(dt, work))
            print(
                f"round {round_ + 1}: "
                + ", ".join(f"{k} {v[-1]:.3f} s" for k, v in samples.items()),
                flush=True,
            )
        precise_error = trees[1].error("precise")
    finally:
        subprocess.run(
            ["git", "worktree", "remove", "--force", str(base_path)],
            cwd=ROOT,
            check=False,
            capture_output=True,
        )
        shutil.rmtree(work, ignore_errors=True)
    med = {k: statistics.median(v) for k, v in samples.items()}
    lines = [
        f"Interleaved, {args.repeats} rounds, medians [s]; baseline {args.baseline}.",
        "",
        "| case | baseline | current | baseline/current | PyElastica N=400 | PyElastica/current |",
        "|---|---|---|---|---|---|",
    ]
    for case in ("whole", "loop"):
        b, c = med[f"baseline {case}"], med[f"current {case}"]
        e = med.get("elastica whole") if case == "whole" else None
        tail = f"{e:.3g} | {e / c:.1f}" if e is not None else "– | –"
        lines.append(f"| {case} | {b:.3g} | {c:.3g} | {b / c:.2f} | {tail} |")
    b, p = med["baseline loop"], med["current precise"]
    error = precise_error
    lines.append(
        f"| loop, {' '.join(PRECISE)} (error {error:.2e}) | – | {p:.3g} | {b / p:.2f} "
        "(baseline's default/this) | – | – |"
        if error is not None
        else f"| loop, {' '.join(PRECISE)} | – | {p:.3g} | {b / p:.2f} | – | – |"
    )
    lines.append("")
    lines.append(
        f"Newton iterations: baseline {iterations['baseline']}, current {iterations['current']}, "
        f"precise {iterations['precise']}."
    )
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "speed.md").write_text(text, encoding="utf-8")
    (RESULTS / "speed.json").write_text(
        json.dumps({"baseline": args.baseline, "samples": samples, "medians": med}, indent=1),
        encoding="utf-8",
    )
    print(text)


if __name__ == "__main__":
    main()
