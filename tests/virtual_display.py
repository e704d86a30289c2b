"""An X display of a test's own, for ParaView's ``pvpython`` (which needs one to render here).

``xvfb-run -a pvpython`` failed one time in three here (3 of 8 runs, 2026-12-03) and once in CI:
VTK's "bad X server connection", SIGABRT in vtkXOpenGLRenderWindow::CreateAWindow. ParaView
opens a connection to probe the display and closes it; the X server, the last client gone,
resets, and ParaView's next connection meets the server mid-reset. ``-noreset`` keeps the
server as it is (8 of 8 here). And ``-displayfd`` lets the server choose a display number whose
sockets it could bind, and tell it: ``xvfb-run -a`` looks at the lock files in /tmp only, so a
server of another job with a /tmp of its own (a container sharing the network namespace) can
hold the abstract socket ``@/tmp/.X11-unix/X<n>`` that the client tries first.
"""

from __future__ import annotations

import os
import select
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager


class NoDisplay(RuntimeError):
    """Xvfb did not start or did not say which display it took."""


@contextmanager
def virtual_display(timeout: float = 60.0) -> Iterator[str]:
    """Start Xvfb on a display it chooses; yield ``DISPLAY`` (":N"); stop it on leaving.

    ``timeout`` [s] bounds the wait for the server's display number (a hang limit: it starts
    in well under a second here). Local connections need no cookie: Xvfb without ``-auth``
    admits clients of this machine only, and ``-nolisten tcp`` keeps it off the network.
    """
    if shutil.which("Xvfb") is None:
        raise NoDisplay("Xvfb is not installed")
    read, write = os.pipe()
    with tempfile.TemporaryFile() as log:
        server = subprocess.Popen(
            [
                "Xvfb",
                "-displayfd",
                str(write),
                "-screen",
                "0",
                "1280x1024x24",
                "-nolisten",
                "tcp",
                "-noreset",
            ],
            pass_fds=(write,),
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=log,
        )
        os.close(write)
        try:
            number = b""
            while not number.endswith(b"\n"):
                ready, _, _ = select.select([read], [], [], timeout)
                chunk = os.read(read, 64) if ready else b""
                if not chunk:  # timed out, or the server closed the pipe (it exited)
                    log.seek(0)
                    said = log.read().decode(errors="replace").strip().splitlines()[-3:]
                    raise NoDisplay(f"Xvfb gave no display number: {' | '.join(said)}")
                number += chunk
            yield f":{int(number)}"
        finally:
            os.close(read)
            server.terminate()
            try:
                server.wait(timeout=30)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def run_pvpython(args: list[str], env: dict[str, str], timeout: float = 300.0):
    """``pvpython ARGS`` on a display of its own (:func:`virtual_display`), with the
    environment ``env`` (the tests' subprocess_env); its CompletedProcess, output captured."""
    with virtual_display() as display:  # not xvfb-run: see the module docstring
        return subprocess.run(
            ["pvpython", *args],
            capture_output=True,
            text=True,
            timeout=timeout,
            env={**env, "DISPLAY": display},
        )
