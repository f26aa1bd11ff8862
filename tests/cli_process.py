"""A command-line run of our program for a test, in its own process group: the group
(the program and anything it started) is killed when the program ends, times out or the
test is interrupted (pytest-timeout's signal), and on Linux the program is killed when
the test's process dies (a worker ended by a Qt test's timeout, or killed), so nothing
outlives the test. Its output
goes to temporary files, not pipes: a process it left behind holding a pipe would keep
the read waiting after the program itself ended."""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence


def _parent_death_signal() -> Callable[[], None] | None:
    """Linux: a function the child runs before our program starts, asking the kernel for
    SIGKILL when its parent dies (``prctl(PR_SET_PDEATHSIG)``); resolved here, so the
    forked child only calls into libc."""
    if not sys.platform.startswith("linux"):
        return None
    prctl = ctypes.CDLL(None, use_errno=True).prctl

    def die_with_parent() -> None:
        prctl(1, signal.SIGKILL)  # 1: PR_SET_PDEATHSIG

    return die_with_parent


_DIE_WITH_PARENT = _parent_death_signal()


def run_cli(argv: Sequence[str], timeout: float) -> subprocess.CompletedProcess:
    """``subprocess.run(argv, capture_output=True, text=True, timeout=timeout)`` whose
    whole process group ends with it."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(list(argv), stdout=out, stderr=err, text=True,
                                start_new_session=True, preexec_fn=_DIE_WITH_PARENT)
        try:
            proc.wait(timeout=timeout)
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:  # nothing left of it
                pass
            proc.wait()
        out.seek(0)
        err.seek(0)
        return subprocess.CompletedProcess(list(argv), proc.returncode, out.read(), err.read())
