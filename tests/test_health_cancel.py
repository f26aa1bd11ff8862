"""Ctrl-C in the sensor engineer's long commands says what was kept, in one line, exit 130:
a wellness check or calibration stores nothing until it is complete (the line said
'finished work was kept'), a characterisation keeps the taxels it finished in its folder
(the line named no folder); a job's own cancel line (a sweep's 'N of M tasks finished')
reaches the user instead of the general one."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

from tactile_studio.errors import EXIT_CANCELLED
from tactile_studio.storage.books.logbook import Logbook


def _env(tmp_path: Path) -> dict[str, str]:
    return {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(tmp_path / "data"),
            "TACTILE_STUDIO_CACHE_DIR": str(tmp_path / "cache"),
            "TACTILE_STUDIO_SETTINGS": str(tmp_path / "s.ini")}


def _interrupt(args: list[str], tmp_path: Path, ready) -> tuple[int, list[str]]:  # noqa: ANN001
    """Run the CLI, send Ctrl-C once ``ready(stderr_line)`` is true; (status, lines)."""
    proc = subprocess.Popen([sys.executable, "-m", "tactile_studio", *args], cwd=tmp_path,
                            env=_env(tmp_path), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    seen = []
    try:
        for line in proc.stderr:
            seen.append(line)
            if ready(line):
                break
        proc.send_signal(signal.SIGINT)
        _, rest = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = "".join(seen) + rest
    assert "Traceback" not in err, err
    return proc.returncode, [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]


def test_a_cancelled_calibration_says_nothing_was_stored(tmp_path, monkeypatch):
    sim = ["--device", "simulated", "--sensor", "sim-0", "--auto"]
    first = subprocess.run([sys.executable, "-m", "tactile_studio", "calibrate", *sim,
                            "--set", "speed=0", "--loads-g", "20,50,100", "--taxels", "B2",
                            "--out", str(tmp_path / "cal1.json")], env=_env(tmp_path),
                           cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    # real time: the rest alone takes 3 s, Ctrl-C lands inside it
    code, lines = _interrupt(["calibrate", *sim, "--loads-g", "20,50,100", "--out",
                              str(tmp_path / "cal2.json")], tmp_path,
                             lambda ln: ln.startswith("calibrate ["))
    assert code == EXIT_CANCELLED
    assert lines == ["tactile-studio: calibration of sim-0 cancelled: nothing was stored; "
                     "its active calibration is unchanged"]
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))
    with Logbook() as book:
        assert [c["id"] for c in book.calibrations("sim-0")] == [1]
        assert book.active_calibration("sim-0") == 1
    assert not (tmp_path / "cal2.json").exists()


def test_a_cancelled_characterisation_names_its_folder_and_what_it_finished(tmp_path):
    out = tmp_path / "char"

    def one_taxel_done(line: str) -> bool:
        return "B5:" in line  # B2 finished, B5 under way

    code, lines = _interrupt(["characterise", "--device", "simulated", "--set", "speed=0",
                              "--set", "gesture=idle", "--taxels", "B2,B5,E2",
                              "--sequence", "all",
                              "--cycles", "2000", "--out", str(out)], tmp_path,
                             one_taxel_done)
    assert code == EXIT_CANCELLED
    done = json.loads((out / "characterisation.json").read_text())
    n = len(done["taxels"])
    assert done["aborted"] and 1 <= n < 3
    assert lines == [f"tactile-studio: characterisation cancelled: {n} of 3 taxel(s) "
                     f"finished, kept in {out} (report.html)"]
