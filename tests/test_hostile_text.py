"""What a file says never drives the terminal (issue 43, the hunt): a session whose
participant, condition, notes, gesture names and event kinds hold escape sequences, a
bell and a carriage return. ``info`` in a terminal (a real pty: rich tables), ``info DIR``
and ``check`` piped: every one of those characters is shown escaped; ``--json`` is the
JSON it was. Before, ``info`` in a terminal and the study lines of ``info DIR`` wrote them
raw (the window retitled, the screen cleared, text turned red)."""

from __future__ import annotations

import json
import os
import pty
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.sensor.layout import get_layout
from tactile_studio.storage.format.session_writer import SessionWriter
from tactile_studio.terminal import printable

pytestmark = pytest.mark.damaged_files  # one event without a frame, on purpose

EVIL = "\x1b]0;owned\x07\x1b[2J\x1b[31mRED\r\u202e"
RAW = ("\x1b", "\x07", "\r", "\u202e")


def _hostile(path: Path) -> Path:
    layout = get_layout("shearsense-6x6")
    n = 40
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name,
                                      "nominal_rate_hz": 43.0},
                       {"source": "collect", "participant": f"P01{EVIL}",
                        "condition": f"FLAT{EVIL}", "notes": f"note{EVIL}",
                        "gestures": [f"Poke{EVIL}"]}) as w:
        w.append_frames(np.full((n, layout.n_channels), 1000, np.uint16), np.arange(n) / 43,
                        1e9 + np.arange(n) / 43)
        w.add_trial({"index": 0, "gesture": f"Poke{EVIL}", "key": "p", "start_sample": 2,
                     "end_sample": 10, "start_time": 0.0, "end_time": 0.2})
        w.add_event(f"marker{EVIL}", frame=3, text=EVIL)
        w._record({"type": "event", "kind": f"odd{EVIL}", "time": 1e9})  # no frame
    return path


def _in_a_terminal(argv: list[str]) -> str:
    """The real program with its stdout on a pseudo-terminal; what the terminal got."""
    master, slave = pty.openpty()
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    env.update(TERM="xterm", COLUMNS="200")
    proc = subprocess.Popen([sys.executable, "-m", "tactile_studio", *argv], stdout=slave,
                            stderr=subprocess.PIPE, env=env)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # the program closed its end
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    assert proc.wait(timeout=60) == 0, proc.stderr.read()
    return b"".join(chunks).decode("utf-8", "replace")


def test_info_in_a_terminal_shows_a_files_escape_sequences_as_text(tmp_path: Path) -> None:
    path = _hostile(tmp_path / "hostile.h5")
    shown = _in_a_terminal(["info", str(path)])
    assert "P01" in shown and "note" in shown and "RED" in shown
    # rich draws its own styles, and the pty turns each newline into CR LF; nothing else
    assert "]0;owned" in shown and "\x07" not in shown and "\u202e" not in shown
    assert "\x1b]0;" not in shown and "\x1b[2J" not in shown
    assert "\r" not in shown.replace("\r\n", "")


def test_piped_outputs_escape_what_a_file_says_and_json_stays_json(tmp_path: Path,
                                                                     capsys) -> None:
    path = _hostile(tmp_path / "hostile.h5")
    assert main(["info", str(tmp_path)]) == 0  # the study: people, conditions, gaps
    out, err = capsys.readouterr()
    assert printable("P01" + EVIL) in out and not any(c in out + err for c in RAW), out
    assert main(["check", str(path)]) == 5  # an event without a frame: named with its kind
    out, err = capsys.readouterr()
    assert "\\u001b]0;owned" in err and not any(c in out + err for c in RAW), err
    assert main(["info", "--json", str(path)]) == 0
    out, _ = capsys.readouterr()
    assert json.loads(out)["participant"] == "P01" + EVIL  # the interface: unchanged
