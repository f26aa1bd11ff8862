"""Ctrl-C while a command is still starting (issue 43, case 17): one line and exit 130 at
every point of start-up, never a KeyboardInterrupt traceback out of an import.

Deterministic: the real program (the console script and ``python -m tactile_studio``) is
started with a ``sitecustomize`` that stops it inside the import of a chosen module and
says so on stderr; SIGINT is sent after that marker, so it lands exactly there whatever
the machine's load. Budget: a few seconds (one process per point, each stopped early).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tactile_studio.errors import EXIT_CANCELLED

EXE = str(Path(sys.executable).parent / "tactile-studio")
MARK = "STOPPED-IN-IMPORT"

# The marker's finder: it stops the program when the named module is first imported
# (the test's own instrument, not the program's code; the import then goes on as usual).
SITECUSTOMIZE = f'''
import os, sys, time

class _StopAt:
    target = os.environ["TS_STOP_AT_IMPORT"]

    def find_spec(self, name, path=None, target=None):
        if name == self.target:
            sys.meta_path.remove(self)
            sys.stderr.write("{MARK} " + name + "\\n")
            sys.stderr.flush()
            time.sleep(60)  # the test's SIGINT ends this
        return None

sys.meta_path.insert(0, _StopAt())
'''

ENTRIES = {"console-script": [EXE], "python-m": [sys.executable, "-m", "tactile_studio"]}

# where start-up is stopped: the command line's package (its first import), a command's
# module while the parser is built, and a module the command imports once it has begun
POINTS = [
    ("tactile_studio.cli", ["info", "missing.h5"], "starting"),
    ("tactile_studio.cli.learn", ["info", "missing.h5"], "starting"),
    ("tactile_studio.storage.exchange.exporters", ["export", "missing.h5", "--format", "npz"],
     "running"),
]


def _interrupt_at(tmp_path: Path, entry: list[str], module: str, argv: list[str]):
    site = tmp_path / "site"
    site.mkdir(exist_ok=True)
    (site / "sitecustomize.py").write_text(SITECUSTOMIZE)
    env = {**os.environ, "TS_STOP_AT_IMPORT": module,
           "PYTHONPATH": os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH"))
                                         if p),
           "TACTILE_STUDIO_DATA_DIR": str(tmp_path / "data"),
           "TACTILE_STUDIO_CACHE_DIR": str(tmp_path / "cache")}
    # Ctrl-C reaches it as from a terminal even when this suite runs in the background
    # (a non-interactive shell starts background jobs with SIGINT ignored, and a child
    # inherits that: Python then installs no KeyboardInterrupt handler at all)
    proc = subprocess.Popen([*entry, *argv], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        first = proc.stderr.readline()
        assert first.strip() == f"{MARK} {module}", first + proc.stderr.read()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err


@pytest.mark.parametrize("entry", ENTRIES.values(), ids=ENTRIES.keys())
@pytest.mark.parametrize(("module", "argv", "when"), POINTS,
                         ids=[p[0].rsplit(".", 1)[-1] for p in POINTS])
def test_ctrl_c_while_starting_is_one_line_and_130(tmp_path: Path, entry, module, argv,
                                                   when) -> None:
    code, err = _interrupt_at(tmp_path, entry, module, argv)
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert code == EXIT_CANCELLED, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    if when == "starting":
        assert lines[0] == "tactile-studio: interrupted while starting; nothing was done"
    else:  # the command had begun: its own ending for Ctrl-C
        assert lines[0].startswith("tactile-studio: "), err
