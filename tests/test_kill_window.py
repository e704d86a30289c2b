"""SIGKILL inside HDF5's close of a frame damages no frame the published XML names.

The close of an HDF5 file writes its metadata in place: group B-trees and heaps, object
headers, the superblock. When every frame went into one file, those were shared with the
earlier frames, and a kill between two of these writes lost earlier frames (CI once failed in
tests/test_kill_random.py with ``KeyError: 'no dataset /Function/angles/0'``: frame 0 gone).
The window is ~0.1 ms a frame, so random kills hit it rarely; here it is hit on purpose, at
every write of one close.

How: the run (the paper's scene to t = 0.6 ms, an XDMF frame every step) runs in a child
process with a small shared library preloaded (``LD_PRELOAD``, compiled here with gcc, which
the form compiler needs anyway) that wraps the C library's write calls (write, pwrite,
pwritev, ftruncate). The child wraps DOLFINx's ``XDMFFile`` so that, during the close of the
file of frame ``FRAME`` (the writer opens and closes one XDMFFile for the mesh, then one a
frame), the library counts the write calls and sends SIGKILL to its own process just before
the n-th. A first run, not killed, counts the write calls of that close (N); then one run is
killed before each write n = 1 ... N. After every kill: solution.xdmf is well-formed, every
dataset it names is readable with the HDF5 C library (tests/xdmf_files.py) with the XML's
dimensions and finite values, it names exactly the ``FRAME`` frames before the one in
flight, and each frame's free-end values equal the probes.csv row of its time (to 1e-12, as
tests/test_kill.py). File names are not checked here, so the same test runs on the earlier
single-file layout.

On that layout (one .h5 for all frames; measured 2026-12-01 with PYTHONPATH set to the code
before the per-frame files) the close made 9 write calls and the kills before writes 2-6 all
lost frame 0 ("no dataset /Function/displacement/0", "... /angles/0"); with one file a frame
the close makes 4 and every kill leaves all earlier frames readable. Runtime: ~1 s a run.
"""

from __future__ import annotations

import io
import re
import shutil
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import PYTHON, ROOT, subprocess_env
from xdmf_files import read_xdmf

SCENE = str(ROOT / "scenes" / "cao_tucker_2008.toml")
DT = 3e-5  # s, the scene's time.step
FRAME = 6  # the frame (from 0) whose close is killed: frames 0-5 are published before it
VALUE_TOL = 1e-12  # m, rad
TIME_TOL = 1e-15  # s

SHIM = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <signal.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>
static long armed = 0, seen = 0;
void shim_arm(long n) { armed = n; seen = 0; }     /* n > 0: SIGKILL before write n */
long shim_disarm(void) { armed = 0; return seen; } /* the write calls since shim_arm */
static void hit(void) {
  if (armed) { seen++; if (armed > 0 && seen == armed) kill(getpid(), SIGKILL); }
}
#define NEXT(f) static __typeof__(f) *real; if (!real) real = dlsym(RTLD_NEXT, #f)
ssize_t write(int d, const void *b, size_t n) { NEXT(write); hit(); return real(d, b, n); }
ssize_t pwrite(int d, const void *b, size_t n, off_t o) {
  NEXT(pwrite); hit(); return real(d, b, n, o); }
ssize_t pwrite64(int d, const void *b, size_t n, off_t o) {
  NEXT(pwrite64); hit(); return real(d, b, n, o); }
ssize_t writev(int d, const struct iovec *v, int c) { NEXT(writev); hit(); return real(d, v, c); }
ssize_t pwritev(int d, const struct iovec *v, int c, off_t o) {
  NEXT(pwritev); hit(); return real(d, v, c, o); }
int ftruncate(int d, off_t l) { NEXT(ftruncate); hit(); return real(d, l); }
"""

CHILD = r"""
import ctypes, os, sys, types
shim = ctypes.CDLL(os.environ["KILL_SHIM"])  # the preloaded library itself
shim.shim_arm.argtypes = [ctypes.c_long]
shim.shim_disarm.restype = ctypes.c_long
from dolfinx import io as dolfinx_io
from cosserat_fem import output
from cosserat_fem.cli import main

out, target, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
XDMFFile = dolfinx_io.XDMFFile

class Killing:
    closes = 0

    def __init__(self, *args):
        self.file = XDMFFile(*args)

    def write_mesh(self, *args):
        self.file.write_mesh(*args)

    def write_function(self, *args):
        self.file.write_function(*args)

    def close(self):
        Killing.closes += 1
        if Killing.closes == target:
            shim.shim_arm(n)
        self.file.close()
        seen = shim.shim_disarm()
        if Killing.closes == target:
            print(f"writes in the close: {seen}", flush=True)

output.io = types.SimpleNamespace(XDMFFile=Killing)
sys.exit(main(["run", SCENE, "--out", out, "--quiet", "--set", "time.end=0.0006",
               "--set", "output.xdmf_interval=0"]))
"""


@pytest.fixture(scope="module")
def shim(tmp_path_factory) -> Path:
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.fail("gcc not found (the form compiler needs it too)")
    folder = tmp_path_factory.mktemp("shim")
    (folder / "shim.c").write_text(SHIM)
    library = folder / "shim.so"
    subprocess.run([gcc, "-shared", "-fPIC", "-O2", "-o", str(library), str(folder / "shim.c"),
                    "-ldl"], check=True)  # fmt: skip
    return library


def run_child(shim: Path, out: Path, n: int) -> subprocess.CompletedProcess:
    """The run into ``out``, killed before the n-th write call of frame FRAME's close (n = -1:
    not killed, the write calls counted)."""
    env = subprocess_env() | {"KILL_SHIM": str(shim), "LD_PRELOAD": str(shim)}
    script = f"SCENE = {SCENE!r}\n" + CHILD
    # Close 1 is the mesh's, close k + 2 frame k's.
    args = [PYTHON, "-c", script, str(out), str(FRAME + 2), str(n)]
    # Not cwd=ROOT: python -c puts the working folder first on sys.path, before PYTHONPATH.
    return subprocess.run(args, cwd=out.parent, env=env, capture_output=True, text=True,
                          timeout=300)  # fmt: skip


def check_outputs(out: Path) -> None:
    """Every frame the XML names readable, the frames before the killed one all there, each
    with the probes' values of its time."""
    text = (out / "probes.csv").read_text()
    probes = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, ndmin=2)
    series = read_xdmf(out / "solution.xdmf", names=False)
    times, disp = series["displacement"]
    times_a, ang = series["angles"]
    assert np.array_equal(times, times_a)
    assert np.allclose(times, np.arange(FRAME) * DT, rtol=0, atol=TIME_TOL), times
    rows = probes[: len(times)]
    assert np.allclose(rows[:, 0], times, rtol=0, atol=TIME_TOL)
    assert np.abs(disp - rows[:, 1:4]).max() <= VALUE_TOL
    assert np.abs(ang - rows[:, 4:7]).max() <= VALUE_TOL
    assert np.abs(disp[-1]).max() > 0  # the rod has moved: a real comparison


def test_sigkill_at_every_write_of_a_frames_close(shim, tmp_path):
    counted = run_child(shim, tmp_path / "counted", -1)
    assert counted.returncode == 0, counted.stderr
    writes = int(re.search(r"writes in the close: (\d+)", counted.stdout)[1])
    assert writes >= 2, counted.stdout  # the close does write its metadata
    failures = []
    for n in range(1, writes + 1):
        out = tmp_path / f"killed{n}"
        proc = run_child(shim, out, n)
        assert proc.returncode == -signal.SIGKILL, (n, proc.stderr[-2000:])
        try:
            check_outputs(out)
        except (AssertionError, KeyError, OSError) as exc:
            failures.append(f"killed before write {n} of {writes}: {type(exc).__name__} {exc}")
    assert not failures, "\n".join(failures)
