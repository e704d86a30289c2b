"""The JIT cache survives killed and failed compiles, and keeps the compiler quiet.

:mod:`cosserat_fem.common.jit` (defects D7 and D16). Every test compiles a tiny P1 form whose
constant is random, into a private cache directory, so the module is new. Each test that covers a
defect also checks that plain FFCx behaves as the defect report says (so the test would fail without
:func:`cosserat_fem.common.jit.install`).
"""

from __future__ import annotations

import fcntl
import json
import os
import random
import signal
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

import pytest
from conftest import damage_library, jit_installed

from cosserat_fem.common import jit
from cosserat_fem.common.errors import CosseratError

PYTHON = sys.executable

# Compiles constant * u * v * dx into args["cache"] with dolfinx.jit.ffcx_jit (which says
# whether it compiled or loaded from the cache) and prints the outcome as JSON. The mesh and
# element modules come from the default cache (compiled there with the usual compiler if it is
# cold, as on a fresh machine); args["cc"], a slowed compiler, is used for the form only.
SCRIPT = r"""
import json, os, sys, time
args = json.loads(sys.argv[1])
import ufl
from dolfinx import fem, mesh
from dolfinx.jit import ffcx_jit
from mpi4py import MPI
from cosserat_fem.common import jit
if args["install"]:
    jit.install()
msh = mesh.create_unit_interval(MPI.COMM_SELF, 2)
V = fem.FunctionSpace(msh, ("Lagrange", 1))
form = args["constant"] * ufl.TrialFunction(V) * ufl.TestFunction(V) * ufl.dx
if args.get("cc"):  # the slowed compiler for the form alone, not for the elements above
    os.environ["CC"] = args["cc"]
if args.get("go"):
    open(args["ready"], "w").close()
    while not os.path.exists(args["go"]):
        time.sleep(0.002)
start = time.monotonic()
try:
    params = {"cache_dir": args["cache"], "timeout": args.get("timeout", 10)}
    code = ffcx_jit(MPI.COMM_SELF, form, jit_params=params)[2]
    result = {"compiled": code[0] is not None}
except Exception as exc:
    result = {"error": f"{type(exc).__name__}: {exc}"}
result["seconds"] = time.monotonic() - start
print(json.dumps(result))
"""


def constant() -> float:
    return 1.2345 + random.random()


def slow_compiler(tmp_path: Path, seconds: float) -> str:
    """A C compiler (for the form's compile: args["cc"]; it also links) that sleeps first: a
    compile that is surely still running when another process arrives or the test kills it."""
    cc = sysconfig.get_config_var("CC").split()[0]
    wrapper = tmp_path / "slowcc"
    wrapper.write_text(f'#!/bin/sh\nsleep {seconds}\nexec {cc} "$@"\n')
    wrapper.chmod(0o755)
    return str(wrapper)


_started: list[subprocess.Popen] = []


@pytest.fixture(autouse=True)
def reap():
    """Kill what a failed test left running (e.g. a process waiting for the go file)."""
    yield
    while _started:
        proc = _started.pop()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()


def start(args: dict) -> subprocess.Popen:
    proc = subprocess.Popen(
        [PYTHON, "-c", SCRIPT, json.dumps(args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, for killpg
    )
    _started.append(proc)
    return proc


def outcome(proc: subprocess.Popen, timeout: float = 60) -> dict:
    out, err = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, err
    return json.loads(out.strip().splitlines()[-1])


def run(args: dict) -> dict:
    return outcome(start(args))


def files(cache: Path, suffix: str) -> list[Path]:
    return sorted(cache.glob("libffcx_forms_*" + suffix))


def lock_is_free(lock: Path) -> bool:
    with open(lock) as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        return True


@pytest.fixture
def installed():
    """install() for the test; afterwards the state before it (the lead may install at start)."""
    with jit_installed():
        yield


@pytest.fixture(scope="module")
def space():
    from dolfinx import fem, mesh
    from mpi4py import MPI

    return fem.FunctionSpace(mesh.create_unit_interval(MPI.COMM_SELF, 2), ("Lagrange", 1))


def mass_form(space, cache: Path, value: float | None = None, **jit_params):
    import ufl
    from dolfinx import fem

    value = constant() if value is None else value
    a = value * ufl.TrialFunction(space) * ufl.TestFunction(space) * ufl.dx
    return fem.form(a, jit_params={"cache_dir": str(cache), **jit_params})


@pytest.mark.long
@pytest.mark.parametrize("killed", ["install", "plain"])
def test_killed_compile_does_not_block_the_next_run(tmp_path, killed):
    """D7: a compile killed with SIGKILL (its whole process group, as Ctrl-C in a terminal
    would, here while the slowed C compiler runs) leaves <module>.c without <module>.c.cached.

    Plain FFCx then waits `timeout` seconds (10 by default, 1 here) and raises "JIT compilation
    timed out" on every later run. With install() the next process gets the module's lock
    (the dead process's lock died with it), knows the compile died, and compiles at once. The
    killed compile ran with install() or, as caches broken before this fix, without it.
    """
    cache = tmp_path / "cache"
    args = {"cache": str(cache), "constant": constant(), "install": killed == "install"}
    proc = start({**args, "cc": slow_compiler(tmp_path, 30)})
    deadline = time.monotonic() + 60
    while not any(f.stat().st_size > 0 for f in files(cache, ".c")):  # source written: gcc
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the compile did not start"
        time.sleep(0.01)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate()
    assert files(cache, ".c") and not files(cache, ".c.cached")

    plain = run({**args, "install": False, "timeout": 1})
    assert "JIT compilation timed out" in plain.get("error", ""), plain

    # With FFCx's wait cut to 1 s, as for plain above: a wait for the dead compile would end
    # in "timed out"; whatever the machine's load, the module is compiled at once instead.
    fixed = run({**args, "install": True, "timeout": 1})
    assert fixed.get("compiled") is True, fixed
    assert len(files(cache, ".c.cached")) == 1 and not files(cache, ".c.failed")
    assert run({**args, "install": True})["compiled"] is False  # now a warm cache


@pytest.mark.long
def test_live_concurrent_compile_is_waited_for(tmp_path):
    """Two processes that need the same new module at the same moment: one compiles (slowed
    to ~3 s), the other waits for it on the lock and then loads the result; nobody takes the
    live compile for a dead one and compiles over it. Plain FFCx passes all but the lock check
    (its 10 s wait is long enough here): this guards install() against a regression."""
    cache = tmp_path / "cache"
    cc = slow_compiler(tmp_path, 1.5)
    procs, value = [], constant()
    for i in range(2):
        args = {
            "cache": str(cache),
            "constant": value,
            "install": True,
            "ready": str(tmp_path / f"ready{i}"),
            "go": str(tmp_path / "go"),
            "cc": cc,
        }
        procs.append(start(args))
    deadline = time.monotonic() + 60
    while not all((tmp_path / f"ready{i}").exists() for i in range(2)):
        assert time.monotonic() < deadline and all(p.poll() is None for p in procs)
        time.sleep(0.01)
    (tmp_path / "go").touch()
    results = [outcome(p) for p in procs]
    assert sorted(r.get("compiled") for r in results) == [False, True], results
    waiter = next(r for r in results if not r["compiled"])
    assert waiter["seconds"] > 0.5, results  # it did arrive during the compile
    assert len(files(cache, ".c.cached")) == 1 and not files(cache, ".c.failed")
    assert lock_is_free(files(cache, ".lock")[0])


def test_wait_for_a_hung_compile_names_the_process(tmp_path, monkeypatch, space, installed):
    """A live compile that outlasts the wait (jit.WAIT_TIMEOUT, 300 s; 0.5 s here) gives a
    one-line error naming the C file, the process compiling it and its lock file."""
    cache, value = tmp_path / "cache", constant()
    args = {"cache": str(cache), "constant": value, "install": True}
    proc = start({**args, "cc": slow_compiler(tmp_path, 30)})
    try:
        deadline = time.monotonic() + 60
        while not files(cache, ".c"):  # created once the lock is held
            assert proc.poll() is None and time.monotonic() < deadline, "no compile started"
            time.sleep(0.01)
        monkeypatch.setattr(jit, "WAIT_TIMEOUT", 0.5)
        with pytest.raises(jit.JITLockTimeout) as info:
            mass_form(space, cache, value, timeout=0)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
    message = str(info.value)
    assert "\n" not in message and isinstance(info.value, TimeoutError)
    assert f"process {proc.pid}" in message
    assert str(files(cache, ".c")[0]) in message and str(files(cache, ".lock")[0]) in message


def test_compiler_warnings_do_not_reach_stderr(tmp_path, capfd, space, installed):
    """D16: gcc runs in a subprocess that inherits fd 2. FFCx's code for a cell integral
    leaves parameters unused (w, c, entity_local_index, ...), so -Wextra makes gcc warn on any
    form; Debian's -Wall warns on some. Plain FFCx lets the warnings through (checked first, so
    that the test proves something); with install() they stay off the terminal."""
    wextra = {"cffi_extra_compile_args": ["-O2", "-g0", "-Wextra"]}
    jit.uninstall()
    try:
        mass_form(space, tmp_path / "plain", **wextra)
    finally:
        jit.install()
    assert "warning: unused parameter" in capfd.readouterr().err

    mass_form(space, tmp_path / "patched", **wextra)
    assert "warning" not in capfd.readouterr().err

    with jit.capture_stderr() as captured:  # the helper on its own: any child's fd 2
        subprocess.run(["sh", "-c", "echo from-a-child >&2"], check=True)
    assert captured.text == "from-a-child\n"
    assert capfd.readouterr().err == ""


def test_a_compile_leaves_no_object_and_an_empty_source_that_plain_ffcx_still_loads(tmp_path):
    """After a compile (a process with install): no ``.o`` and an empty ``.c``
    (:func:`jit._trim`), the library and ``.c.cached`` in place; plain FFCx (a process
    without install) then loads the module from the cache instead of compiling it again, as
    with the full source (its marker is the file, not its content)."""
    cache, value = tmp_path / "cache", constant()
    assert run({"install": True, "cache": str(cache), "constant": value})["compiled"] is True
    assert files(cache, ".c.cached") and files(cache, ".so") and not files(cache, ".o")
    (source,) = files(cache, ".c")
    assert source.stat().st_size == 0
    assert run({"install": False, "cache": str(cache), "constant": value})["compiled"] is False


def test_compile_failure_is_one_line_naming_the_log(tmp_path, capfd, space, installed):
    """A failing C compile (a header with #error forced in by -include) raises one line with
    the compiler's first error and the path of the full log. Plain FFCx raises cffi's
    "CompileError: command 'x86_64-linux-gnu-gcc' failed with exit code 1", with gcc's lines on
    stderr and no log. A second attempt fails the same way (no timeout)."""
    header = tmp_path / "broken.h"
    header.write_text("#error cosserat_test_broken_header\n")
    cache = tmp_path / "cache"
    broken = {"cffi_extra_compile_args": ["-O2", "-include", str(header)], "timeout": 1}
    for _ in range(2):
        with pytest.raises(jit.JITCompileError) as info:
            mass_form(space, cache, **broken)
        message = str(info.value)
        assert isinstance(info.value, CosseratError)
        assert "\n" not in message
        assert "error: #error cosserat_test_broken_header" in message
        log = info.value.log_path
        assert str(log) in message and log.exists()
        assert "cosserat_test_broken_header" in log.read_text()
    assert "cosserat_test_broken_header" not in capfd.readouterr().err
    assert files(cache, ".c.failed") and not files(cache, ".c")
    assert lock_is_free(files(cache, ".lock")[0])


def test_interrupted_compile_leaves_nothing_that_blocks(tmp_path, monkeypatch, space, installed):
    """KeyboardInterrupt during the C compile: FFCx renames .c to .c.failed only on Exception,
    so plain FFCx leaves .c behind and the next compile times out. With install() the .c is
    renamed (so even processes without install() are not blocked) and the lock is free."""
    import cffi

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    cache, value = tmp_path / "cache", constant()
    with monkeypatch.context() as patch:
        patch.setattr(cffi.FFI, "compile", interrupted)
        with pytest.raises(KeyboardInterrupt):
            mass_form(space, cache, value, timeout=1)
    assert not files(cache, ".c") and files(cache, ".c.failed")
    assert lock_is_free(files(cache, ".lock")[0])
    jit.uninstall()  # plain FFCx compiles it now (it would time out on a leftover .c)
    try:
        mass_form(space, cache, value, timeout=1)
    finally:
        jit.install()
    assert len(files(cache, ".c.cached")) == 1


# --- a damaged library in the cache (issue 25 item 15) --------------------------------------


DAMAGES = ["cut", "cut, no record", "missing", "altered", "zeroed tail, no record"]


@pytest.mark.parametrize("how", DAMAGES)
def test_a_damaged_library_is_compiled_again(tmp_path, caplog, space, installed, how):
    """Item 15: FFCx trusts <module>.c.cached and loads whatever library lies beside it. A
    library cut short is mapped past its end: the first call into it dies of SIGBUS (PETSc's
    handler: exit 59; tests/test_jit_cache.py::test_a_damaged_cache_costs_a_compile_not_a_run
    shows it in a run); a missing one raised ModuleNotFoundError. With install() the library
    is checked before it is loaded, compiled again, and one warning names it and says so;
    afterwards it is whole (its recorded SHA-256 matches) and the next load is silent."""
    import ufl
    from dolfinx import fem

    cache = tmp_path / "cache"
    a = constant() * ufl.TrialFunction(space) * ufl.TestFunction(space) * ufl.dx
    params = {"cache_dir": str(cache)}
    fem.form(a, jit_params=params)  # one UFL form: one module name for every compile
    (library,) = files(cache, sysconfig.get_config_var("EXT_SUFFIX"))
    digest = library.with_name(library.name + jit.DIGEST_SUFFIX)
    assert jit.library_damage(library) is None and digest.exists()
    damage_library(library, how)
    assert jit.library_damage(library) is not None
    with caplog.at_level("WARNING", logger="cosserat_fem.common.jit"):
        fem.form(a, jit_params=params)
    warned = [r.getMessage() for r in caplog.records if r.name == "cosserat_fem.common.jit"]
    assert len(warned) == 1 and str(library) in warned[0], warned
    assert "damaged" in warned[0] and "compiling it again" in warned[0]
    assert jit.library_damage(library) is None and digest.exists()
    assert files(cache, sysconfig.get_config_var("EXT_SUFFIX")) == [library]
    caplog.clear()
    with caplog.at_level("WARNING", logger="cosserat_fem.common.jit"):
        fem.form(a, jit_params=params)
    assert not [r for r in caplog.records if r.name == "cosserat_fem.common.jit"]


def test_every_cut_of_a_library_is_found(tmp_path, space, installed):
    """:func:`cosserat_fem.common.jit.elf_damage` without a digest: the linker (GNU ld, as every
    linker that cffi calls here) writes the section header table last, so a library cut
    anywhere lacks part of it (or of its headers); a cut at each 1/32 of the file, and one
    byte short, are each found. The whole library passes."""
    mass_form(space, tmp_path, constant())
    (library,) = files(tmp_path, sysconfig.get_config_var("EXT_SUFFIX"))
    data = library.read_bytes()
    assert jit.elf_damage(data) is None
    for size in sorted({len(data) * k // 32 for k in range(32)} | {len(data) - 1}):
        assert jit.elf_damage(data[:size]) is not None, size


@pytest.mark.long
def test_a_damaged_cache_costs_a_compile_not_a_run(tmp_path):
    """Item 15, as a user met it: a run, then every library in its cache cut in half and the
    digests gone (a partial copy of a cache from before digests were recorded): the next run
    died of SIGBUS in the first form it called (PETSc's "Caught signal number 7 BUS", exit 59)
    and said nothing of the cache. Now it completes (exit 0), with one warning per library
    naming it, FFCx's forms and the project's C Newton loop (native_newton.py) alike."""
    from conftest import ROOT, run_command

    env = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}  # a private cache: never the shared one
    scene = str(ROOT / "scenes" / "cao_tucker_2008.toml")
    args = [
        "-m",
        "cosserat_fem.cli",
        "run",
        scene,
        "--set",
        "time.end=0.0003",
        "--set",
        "discretisation.elements=4",
        "--set",
        "output.xdmf=false",
    ]
    first = run_command([*args, "--out", str(tmp_path / "a")], env=env, timeout=300)
    assert first.returncode == 0, first.stderr
    cache = tmp_path / "xdg" / "fenics"
    libraries = sorted(cache.glob("*" + sysconfig.get_config_var("EXT_SUFFIX")))
    assert any(p.name.startswith("cosserat_newton_loop_") for p in libraries)
    for library in libraries:
        damage_library(library, "cut, no record")
    second = run_command([*args, "--out", str(tmp_path / "b")], env=env, timeout=300)
    assert second.returncode == 0, second.stderr
    warned = [line for line in second.stderr.splitlines() if "damaged" in line]
    assert sorted(w.split("damaged ")[1].split(" (")[0] for w in warned) == [
        str(p) for p in libraries
    ]
    assert all(jit.library_damage(p) is None for p in libraries)
