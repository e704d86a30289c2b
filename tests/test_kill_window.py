"""SIGKILL at every write of one XDMF frame damages no frame the published XML names.

A frame is written by rank 0 with plain system calls (cosserat_fem/io/xdmf.py,
``XdmfSeries``): the frame's HDF5 file, made in memory, in one write to a new file; then the
XML, in place: the frame and new closing tags written into the spare room at its end (inside
a processing instruction, so the document does not change), then one write of blanks, within
one memory page, over the old closing tags. When the spare room is used up the XML is
rewritten under a working name and renamed. Random kills (tests/test_kill_random.py) rarely
fall between two of these calls; here every one is hit on purpose.

How: the run (the paper's scene to t = 0.6 ms, an XDMF frame every step) runs in a child
process with a small shared library preloaded (``LD_PRELOAD``, compiled here with gcc, which
the form compiler needs anyway) that wraps the C library's calls that change files (write,
pwrite, writev, pwritev, ftruncate, rename, unlink). The child wraps ``XdmfWriter.write``:
a first run, not killed, lists the calls of frames 6-13 (their offsets and sizes); the frame
killed is the first of them whose XML write crosses a page boundary. Then one run is killed
before each call n = 1 ... N of that frame, and, for each call that crosses a page boundary,
one run is killed after the call has written up to the first boundary: Linux copies a write
into the page cache a page at a time and checks for a fatal signal between pages, so this is
the partial write a SIGKILL can leave; a write within one page is whole or not done. After
every kill: solution.xdmf is well-formed, every dataset it names is readable with the HDF5 C
library (tests/xdmf_files.py) with the XML's dimensions and finite values, it names exactly
the frames before the one in flight, and each frame's free-end values equal the probes.csv row
of its time (to 1e-12, as tests/test_kill.py). Both ways of adding a frame are tested: in
place (the default) and by a rewrite (no spare room: ``XdmfWriter.SPARE = (0, 0)``). The
test also checks the premise of the in-place write: its last call is the blanks over the old
closing tags, within one page.

History: when every frame went into one .h5 (measured 2026-12-01 with the code before the
per-frame files), the HDF5 close made 9 write calls and the kills before writes 2-6 all lost
frame 0; with DOLFINx writing one file a frame the close made 4 and no kill lost a frame. Now
a frame makes 3 calls in place (the frame file, the staged frame, the blanks) and 4 when the
XML is rewritten (the frame file, an unlink of a stale working file, the new XML, the
rename): 11 kills in all (5 in place, 6 by a rewrite; with the page-boundary cuts) after two
listing runs. Runtime: ~1-2 s a run.
"""

from __future__ import annotations

import io
import json
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
FIRST, LAST = 6, 14  # the frames (from 0) listed; the one killed is among them
PAGE = 4096  # bytes: the granularity at which Linux may cut a killed write
VALUE_TOL = 1e-12  # m, rad
TIME_TOL = 1e-15  # s

SHIM = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <signal.h>
#include <stdio.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>
#define MAX_CALLS 64
static long armed = 0, seen = 0, split = 0;
static char kinds[MAX_CALLS][12];
static long long offsets[MAX_CALLS], sizes[MAX_CALLS];
/* n > 0: SIGKILL before call n (split: after its bytes up to the first page boundary);
   n < 0: count and list the calls only. */
void shim_arm(long n, long cut) { armed = n; seen = 0; split = cut; }
long shim_disarm(void) { armed = 0; return seen; }
const char *shim_kind(long i) { return kinds[i]; }
long long shim_offset(long i) { return offsets[i]; }
long long shim_size(long i) { return sizes[i]; }
/* Before a call: note it; 1 if the call is to be cut at the first page boundary. */
static int hit(const char *kind, long long offset, long long size) {
  if (!armed) return 0;
  if (seen < MAX_CALLS) {
    snprintf(kinds[seen], sizeof kinds[seen], "%s", kind);
    offsets[seen] = offset; sizes[seen] = size;
  }
  seen++;
  if (armed > 0 && seen == armed) {
    if (split && offset >= 0 && offset % 4096 + size > 4096) return 1;
    kill(getpid(), SIGKILL);
  }
  return 0;
}
static size_t first_part(long long offset) { return (size_t)(4096 - offset % 4096); }
#define NEXT(f) static __typeof__(f) *real; if (!real) real = dlsym(RTLD_NEXT, #f)
ssize_t write(int d, const void *b, size_t n) {
  NEXT(write);
  off_t at = lseek(d, 0, SEEK_CUR);
  if (hit("write", at, n)) { real(d, b, first_part(at)); kill(getpid(), SIGKILL); }
  return real(d, b, n); }
ssize_t pwrite(int d, const void *b, size_t n, off_t o) {
  NEXT(pwrite);
  if (hit("pwrite", o, n)) { real(d, b, first_part(o), o); kill(getpid(), SIGKILL); }
  return real(d, b, n, o); }
ssize_t pwrite64(int d, const void *b, size_t n, off_t o) {
  NEXT(pwrite64);
  if (hit("pwrite", o, n)) { real(d, b, first_part(o), o); kill(getpid(), SIGKILL); }
  return real(d, b, n, o); }
ssize_t writev(int d, const struct iovec *v, int c) {
  NEXT(writev); hit("writev", -1, -1); return real(d, v, c); }
ssize_t pwritev(int d, const struct iovec *v, int c, off_t o) {
  NEXT(pwritev); hit("pwritev", -1, -1); return real(d, v, c, o); }
int ftruncate(int d, off_t l) { NEXT(ftruncate); hit("ftruncate", -1, -1); return real(d, l); }
int rename(const char *a, const char *b) { NEXT(rename); hit("rename", -1, -1); return real(a, b); }
int renameat(int fa, const char *a, int fb, const char *b) {
  NEXT(renameat); hit("rename", -1, -1); return real(fa, a, fb, b); }
int unlink(const char *p) { NEXT(unlink); hit("unlink", -1, -1); return real(p); }
int unlinkat(int d, const char *p, int f) {
  NEXT(unlinkat); hit("unlink", -1, -1); return real(d, p, f); }
"""

CHILD = r"""
import ctypes, json, os, sys
shim = ctypes.CDLL(os.environ["KILL_SHIM"])  # the preloaded library itself
shim.shim_arm.argtypes = [ctypes.c_long, ctypes.c_long]
shim.shim_disarm.restype = ctypes.c_long
shim.shim_kind.restype = ctypes.c_char_p
shim.shim_offset.restype = shim.shim_size.restype = ctypes.c_longlong
for f in (shim.shim_kind, shim.shim_offset, shim.shim_size):
    f.argtypes = [ctypes.c_long]
from cosserat_fem.output import fields
from cosserat_fem.io import xdmf
from cosserat_fem.cli import main

out, how, target, n, split = sys.argv[1], sys.argv[2], *map(int, sys.argv[3:6])
if how == "rewrite":
    xdmf.XdmfSeries.SPARE = (0, 0)  # no spare room: every frame rewrites the XML
write = fields.XdmfWriter.write

def killing(self, t, U=None):
    frame = self.writes
    watched = frame == target or (target < 0 and FIRST <= frame < LAST)
    if watched:
        shim.shim_arm(n if frame == target else -1, split)
    write(self, t, U)
    if watched:
        count = shim.shim_disarm()
        calls = [[shim.shim_kind(i).decode(), shim.shim_offset(i), shim.shim_size(i)]
                 for i in range(count)]
        print("calls", json.dumps({"frame": frame, "calls": calls}), flush=True)

fields.XdmfWriter.write = killing
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
    subprocess.run(
        [gcc, "-shared", "-fPIC", "-O2", "-o", str(library), str(folder / "shim.c"), "-ldl"],
        check=True,
    )
    return library


def run_child(shim: Path, out: Path, how: str, frame: int = -1, n: int = -1, split: bool = False):
    """The run into ``out`` (``how``: "append" or "rewrite"), killed before call n of frame
    ``frame``'s write, or (``split``) after that call's bytes up to the first page boundary;
    frame -1: not killed, the calls of frames FIRST..LAST-1 listed."""
    env = subprocess_env() | {"KILL_SHIM": str(shim), "LD_PRELOAD": str(shim)}
    script = f"SCENE = {SCENE!r}\nFIRST, LAST = {FIRST}, {LAST}\n" + CHILD
    args = [PYTHON, "-c", script, str(out), how, str(frame), str(n), str(int(split))]
    # Not cwd=ROOT: python -c puts the working folder first on sys.path, before PYTHONPATH.
    return subprocess.run(
        args, cwd=out.parent, env=env, capture_output=True, text=True, timeout=300
    )


def crosses(call: list) -> bool:
    """Whether a write call (kind, offset, size) crosses a page boundary: the kernel may cut
    it there when the process is killed."""
    _, offset, size = call
    return offset >= 0 and offset % PAGE + size > PAGE


def check_outputs(out: Path, frames: int) -> None:
    """Every frame the XML names readable, the ``frames`` frames before the killed one all
    there, each with the probes' values of its time."""
    text = (out / "probes.csv").read_text()
    probes = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, ndmin=2)
    series = read_xdmf(out / "solution.xdmf")
    times, disp = series["displacement"]
    times_a, ang = series["angles"]
    assert np.array_equal(times, times_a)
    assert np.allclose(times, np.arange(frames) * DT, rtol=0, atol=TIME_TOL), times
    rows = probes[: len(times)]
    assert np.allclose(rows[:, 0], times, rtol=0, atol=TIME_TOL)
    assert np.abs(disp - rows[:, 1:4]).max() <= VALUE_TOL
    assert np.abs(ang - rows[:, 4:7]).max() <= VALUE_TOL
    assert np.abs(disp[-1]).max() > 0  # the rod has moved: a real comparison


# Both ways of writing a frame, the in-place append and the rewrite (the XML written anew when
# its spare room is used up: ~25 runs of the child, 15 s at load 5 on two cores), are in the
# long set; tests/test_kill.py's serial SIGKILL holds the promise of readable outputs in make
# test.
@pytest.mark.long
@pytest.mark.parametrize("how", ["append", "rewrite"])
def test_sigkill_at_every_write_of_a_frame(shim, tmp_path, how):
    counted = run_child(shim, tmp_path / "counted", how)
    assert counted.returncode == 0, counted.stderr
    listed = [
        json.loads(line[len("calls ") :])
        for line in counted.stdout.splitlines()
        if line.startswith("calls ")
    ]
    calls = {item["frame"]: item["calls"] for item in listed}
    assert sorted(calls) == list(range(FIRST, LAST)), counted.stdout
    appended = []
    for frame, made in calls.items():
        assert made[0][:2] == ["pwrite", 0], made  # the frame's HDF5 file, in one write
        if [c[0] for c in made] == ["pwrite"] * 3:  # in place
            appended.append(frame)
            assert not crosses(made[-1]), (frame, made)  # the premise: the blanks in one page
        else:
            assert [c[0] for c in made] == ["pwrite", "unlink", "pwrite", "rename"], made
    assert appended == (list(calls) if how == "append" else []), calls
    # The frame killed: the first whose XML write (after the frame file's) crosses a page.
    frame = next((f for f, made in calls.items() if any(map(crosses, made[1:]))), None)
    assert frame is not None, calls  # ~1 kB frames: about one in four crosses
    failures = []
    for n, call in enumerate(calls[frame], start=1):
        for split in (False, True) if crosses(call) else (False,):
            out = tmp_path / f"killed{n}{'-split' if split else ''}"
            proc = run_child(shim, out, how, frame, n, split)
            where = f"killed {'inside' if split else 'before'} call {n} ({call}) of frame {frame}"
            if proc.returncode != -signal.SIGKILL:
                failures.append(f"{where}: exit {proc.returncode}: {proc.stderr[-2000:]}")
                continue
            try:
                check_outputs(out, frame)
            except (AssertionError, KeyError, OSError) as exc:
                failures.append(f"{where}: {type(exc).__name__} {exc}")
    assert not failures, "\n".join(failures)
