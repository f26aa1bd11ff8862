"""``record`` stopped before its ``--seconds`` by Ctrl-C or SIGTERM ends as ``collect`` and
``train`` do: its summary line, the file kept, and exit 130 (cancelled; README's exit
status table). Walking issue 33 it exited 0, as if the recording had run its length.

Budget: ~6 s (two short recordings in subprocesses).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tactile_studio.errors import EXIT_CANCELLED
from tactile_studio.storage import SessionFile


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_record_stopped_early_exits_130_keeping_the_file(tmp_path: Path, sig) -> None:
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(tmp_path / "data"),
           "TACTILE_STUDIO_CACHE_DIR": str(tmp_path / "cache")}
    out = tmp_path / "short.h5"
    proc = subprocess.Popen([sys.executable, "-m", "tactile_studio", "record", "--device",
                             "simulated", "--seconds", "600", "--out", str(out)],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        first = proc.stderr.readline()  # the progress line: frames are being written
        assert first.startswith("recording short.h5"), first + proc.stderr.read()
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == EXIT_CANCELLED, stderr
    assert f"wrote {out}:" in stdout and "Traceback" not in stderr
    assert stderr.strip().splitlines()[-1] == "tactile-studio: cancelled; finished work was kept"
    with SessionFile(out) as s:
        assert s.closed_cleanly and s.n_frames > 0
