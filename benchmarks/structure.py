# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---
# %% [markdown]
# # The shape of the code: sizes, imports and the walk of a run
#
# Issue 26 asks for figures before and after its restructuring: module sizes, the longest
# functions, import cycles, upward imports, and "the walk": a scene followed from the run entry
# through the calls, how many times it goes back up to a module it has left. This script
# measures all of them on the tree it is run from, so that two checkouts compare by running it
# in each:
#
#     .venv/bin/python benchmarks/structure.py             # a report on stdout
#     .venv/bin/python benchmarks/structure.py --json out.json
#
# **Definitions.**
#
# * A *module* is a file of the package `cosserat_fem` (a subpackage's files each count).
# * An *import* is an `import` or `from ... import` of a module of the package, at module
#   level (executed on import) or inside a function (deferred). A *cycle* is a strongly
#   connected set of modules of the import graph; both graphs are reported, the module-level
#   one (a cycle there is resolved by Python's import order) and the one with deferred imports
#   (a deferred import usually hides a cycle of design).
# * An *upward import* goes from a module of a lower layer to a module of a higher one, the
#   layers being :data:`LAYERS` (bottom first). A module not named there is reported as
#   unplaced.
# * *The walk*: the command `cosserat-fem run` of the paper's scene (three steps, no files
#   but the run's folder in a temporary place) is traced call by call (`sys.setprofile`). At
#   each call into a function of a module M of the package, the stack of the package's modules
#   is taken from the calling frames (outermost first, repeats collapsed). If M is on that
#   stack but is not its innermost module, the run has gone back up to a module it had left:
#   the pair (the innermost module, M.function) is recorded. The walk is the number of
#   distinct pairs; they are listed by M. A callback the design wants (an observer called by
#   the time loop) counts like any other: the number is a measure, not a verdict.

# %%
from __future__ import annotations

import argparse
import ast
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "cosserat_fem"
SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"

#: The layers, bottom first; a module is placed by the first pattern that names it (its
#: dotted name below the package, or a prefix ending in "." for a subpackage). Issue 26 names
#: scene, model, solve, run, files and studies; "base" holds what every layer may use,
#: "formats" the files' formats (io/: names, writers, readers, no DOLFINx), "files" what is
#: sampled on the mesh for them and read back (fields, results), and "interface" the command
#: line and the API.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("base", ("common.",)),
    # The file formats (io/) depend on base only, and the scene's validation names their
    # columns and arrays (schema -> io.probes, io.xdmf): they sit below the scene.
    ("formats", ("io.",)),
    ("scene", ("scene.",)),
    ("model", ("forms.", "rod.", "reference.")),
    ("solve", ("nls.", "timestepping.")),
    ("files", ("output.",)),
    ("run", ("analysis.",)),
    ("studies", ("studies.",)),
    # The reduced model (issue 28) runs the full model (analysis) and the POD (studies).
    ("rom", ("rom", "rom.")),
    # The package's __init__ gives the API's names (imported from api on first use).
    ("interface", ("__init__", "api", "cli", "plot", "render")),
]


def module_name(path: Path) -> str:
    """``forms/kinematics.py`` -> ``forms.kinematics``; a package's ``__init__.py`` -> its name."""
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts) or "__init__"


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def layer_of(name: str) -> int | None:
    for index, (_, patterns) in enumerate(LAYERS):
        for pattern in patterns:
            if name == pattern or (pattern.endswith(".") and name.startswith(pattern)):
                return index
            if pattern.endswith(".") and name == pattern[:-1]:
                return index
    return None


# %% [markdown]
# ## Sizes and the longest functions


# %%
def sizes(found: dict[str, Path]) -> dict:
    lines = {name: len(p.read_text(encoding="utf-8").splitlines()) for name, p in found.items()}
    functions = []
    for name, path in found.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions.append((node.end_lineno - node.lineno + 1, f"{name}.{node.name}"))
    functions.sort(reverse=True)
    return {
        "modules": len(lines),
        "lines": sum(lines.values()),
        "largest_modules": sorted(lines.items(), key=lambda item: -item[1])[:10],
        "longest_functions": [(f, n) for n, f in functions[:10]],
        "top_level_modules": sum("." not in name for name in found),
    }


# %% [markdown]
# ## Imports: cycles and upward imports


# %%
def _resolve(current: str, is_package: bool, node: ast.ImportFrom | ast.Import) -> list[str]:
    """The package's modules an import statement names (dotted below the package)."""
    if isinstance(node, ast.Import):
        return [a.name.split(".", 1)[1] for a in node.names if a.name.startswith("cosserat_fem.")]
    if node.level == 0:
        if node.module is None or not node.module.startswith("cosserat_fem"):
            return []
        base = node.module.split(".")[1:]
    else:
        here = current.split(".") if current != "__init__" else []
        package = here if is_package else here[:-1]
        base = package[: len(package) - (node.level - 1)]
        base += node.module.split(".") if node.module else []
    names = [".".join(base)] if base else []
    names += [".".join([*base, a.name]) for a in node.names]  # from . import x: x may be a module
    return names


def _imports_of(name: str, path: Path, found: dict[str, Path]) -> dict[str, set[str]]:
    """One module's imports of the package: {"module": at module level, "deferred": in
    functions}; imports under ``if TYPE_CHECKING`` are for annotations only and not counted."""
    edges: dict[str, set[str]] = {"module": set(), "deferred": set()}
    is_package = path.name == "__init__.py"

    def visit(node: ast.AST, deferred: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                for target in _resolve(name, is_package, child):
                    if target in found and target != name:
                        edges["deferred" if deferred else "module"].add(target)
            function = isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            visit(child, deferred or function)

    visit(ast.parse(path.read_text(encoding="utf-8")), False)
    return edges


def imports(found: dict[str, Path]) -> dict[str, dict[str, set[str]]]:
    """{module: {"module": names imported at module level, "deferred": inside functions}}."""
    return {name: _imports_of(name, path, found) for name, path in found.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            strong(v)
    return found


def structure(found: dict[str, Path]) -> dict:
    graph = imports(found)
    module_level = {m: e["module"] for m, e in graph.items()}
    every = {m: e["module"] | e["deferred"] for m, e in graph.items()}
    upward, unplaced = [], sorted(m for m in found if layer_of(m) is None)
    for source, targets in every.items():
        low = layer_of(source)
        for target in sorted(targets):
            high = layer_of(target)
            if low is not None and high is not None and high > low:
                upward.append(f"{source} ({LAYERS[low][0]}) -> {target} ({LAYERS[high][0]})")
    return {
        "cycles_module_level": cycles(module_level),
        "cycles_with_deferred": cycles(every),
        "deferred_imports": sum(len(e["deferred"]) for e in graph.values()),
        "upward_imports": sorted(upward),
        "unplaced_modules": unplaced,
    }


# %% [markdown]
# ## The walk of a run


# %%
def walk(end: float = 9e-5) -> dict:
    """Trace ``cosserat-fem run`` of the paper's scene to ``end`` [s] (three steps of 30 μs)."""
    from cosserat_fem.cli import main

    pairs: set[tuple[str, str]] = set()
    prefix = "cosserat_fem."

    def ours(frame) -> str | None:
        name = frame.f_globals.get("__name__", "")
        return name[len(prefix) :] if name.startswith(prefix) else None

    def profile(frame, event, arg) -> None:
        if event != "call":
            return
        callee = ours(frame)
        if callee is None:
            return
        stack: list[str] = []
        caller = frame.f_back
        while caller is not None:
            module = ours(caller)
            if module is not None and (not stack or stack[-1] != module):
                stack.append(module)
            caller = caller.f_back
        stack.reverse()  # outermost first
        if stack and stack[-1] != callee and callee in stack[:-1]:
            pairs.add((stack[-1], f"{callee}.{frame.f_code.co_name}"))

    with tempfile.TemporaryDirectory() as folder:
        argv = [
            "run",
            str(SCENE),
            "--out",
            str(Path(folder) / "run"),
            "--quiet",
            "--set",
            f"time.end={end!r}",
            "--set",
            "output.xdmf=false",
        ]
        sys.setprofile(profile)
        try:
            status = main(argv)
        finally:
            sys.setprofile(None)
    if status != 0:
        raise SystemExit(f"structure: the traced run ended with status {status}")
    by_module = Counter(target.rsplit(".", 1)[0] for _, target in pairs)
    return {
        "walk": len(pairs),
        "reentered_modules": dict(by_module.most_common()),
        "pairs": sorted(f"{source} -> {target}" for source, target in pairs),
    }


# %%
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--json", type=Path, help="write the figures to this file as well")
    parser.add_argument("--no-walk", action="store_true", help="sizes and imports only")
    args = parser.parse_args(argv)
    found = modules()
    report = {"sizes": sizes(found), "imports": structure(found)}
    if not args.no_walk:
        report["walk"] = walk()
    s, i = report["sizes"], report["imports"]
    print(
        f"modules: {s['modules']} ({s['top_level_modules']} at the package's top level), "
        f"{s['lines']} lines"
    )
    print("largest modules: " + ", ".join(f"{n} {k}" for n, k in s["largest_modules"]))
    print("longest functions: " + ", ".join(f"{n} {k}" for n, k in s["longest_functions"]))
    print(f"import cycles at module level: {i['cycles_module_level']}")
    print(f"import cycles with deferred imports: {i['cycles_with_deferred']}")
    print(f"deferred imports: {i['deferred_imports']}")
    print(f"upward imports ({len(i['upward_imports'])}):")
    for line in i["upward_imports"]:
        print(f"  {line}")
    if i["unplaced_modules"]:
        print(f"modules in no layer: {i['unplaced_modules']}")
    if "walk" in report:
        w = report["walk"]
        print(
            f"the walk: {w['walk']} returns to a module left; by module: {w['reentered_modules']}"
        )
        for pair in w["pairs"]:
            print(f"  {pair}")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
