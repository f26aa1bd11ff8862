"""Faults while recording end one way (issue 33): a full disk or the file-size limit, a
device lost for good, frames the recorder lost. Through the real commands: ``record`` in
a subprocess under ``RLIMIT_FSIZE``, a pty serial emulator that dies and never comes
back; the one line, the exit status 3, and a file that opens with what was kept."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
from waiting import wait_until

from tactile_studio.acquisition.events import RecordingStopped
from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.acquisition.outcome import recording_outcome
from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
from tactile_studio.errors import EXIT_INCOMPLETE, SessionFileError
from tactile_studio.storage import SessionFile

LIMIT_BYTES = 3 * 1024 * 1024


def _cli(args: list[str], cwd: Path, limit: int | None = None, **kw) -> subprocess.Popen:
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(cwd / "data"),
           "TACTILE_STUDIO_CACHE_DIR": str(cwd / "cache")}

    def limit_file_size() -> None:
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))

    return subprocess.Popen([sys.executable, "-m", "tactile_studio", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=limit_file_size, **kw)


def _error_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.startswith("tactile-studio: error:")]
    assert len(lines) == 1, stderr[-3000:]
    return lines[0]


def test_the_file_size_limit_stops_the_recording_cleanly_and_the_file_opens(tmp_path):
    out = tmp_path / "x.h5"
    proc = _cli(["record", "--device", "simulated", "--set", "rate=1000", "--seconds", "60",
                 "--out", str(out)], tmp_path, limit=LIMIT_BYTES)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == EXIT_INCOMPLETE, stderr[-3000:]  # was a segfault (139)
    assert "Traceback" not in stderr
    line = _error_line(stderr)
    assert str(out) in line and "file too large" in line and "kept" in line
    assert "running" not in stdout.splitlines()[-1]
    with SessionFile(out) as s:  # was refused as "truncated"
        n = s.n_frames
        times = s.column("device_time")
        assert not s.closed_cleanly and s.cut_short
        summary = s.summary()
    assert n > 1000 and f"kept {n} frames" in line
    assert np.all(np.diff(times) > 0)  # the allocated but unwritten zero rows are not frames
    assert abs(summary["duration_s"] - n / 1000.0) < 0.05
    info = subprocess.run([sys.executable, "-m", "tactile_studio", "info", "--json", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert info.returncode == 0, info.stderr
    assert json.loads(info.stdout)["frames"] == n


def test_collect_under_the_file_size_limit_ends_with_the_same_line(tmp_path):
    """collect: the runner stops at the write error; its file opens with what was kept
    (its frame datasets claim rows never stored: counted out, not refused)."""
    out = tmp_path / "out"
    proc = _cli(["collect", "--protocol", "shear9", "--participant", "P01", "--device",
                 "simulated", "--virtual-participant", "--speed", "0", "--out", str(out)],
                tmp_path, limit=LIMIT_BYTES)
    _, stderr = proc.communicate(timeout=240)
    assert proc.returncode == EXIT_INCOMPLETE, stderr[-3000:]
    assert "Traceback" not in stderr
    line = _error_line(stderr)
    (path,) = out.glob("*.h5")
    assert line.count(str(path)) == 1 and "write failed: file too large" in line
    with SessionFile(path) as s:
        assert s.cut_short and s.n_frames > 1000 and f"kept {s.n_frames} frames" in line
        assert np.all(np.diff(s.column("device_time")) > 0)


def test_characterise_stops_at_the_write_error_instead_of_measuring_on(tmp_path):
    out = tmp_path / "run"
    proc = _cli(["characterise", "--set", "speed=0", "--set", "gesture=idle", "--taxels",
                 "C4,C3,D4", "--out", str(out)], tmp_path, limit=1_500_000)
    _, stderr = proc.communicate(timeout=240)
    assert proc.returncode == EXIT_INCOMPLETE, stderr[-3000:]
    assert "Traceback" not in stderr
    line = _error_line(stderr)
    assert "session.h5: write failed: file too large" in line
    with SessionFile(out / "session.h5") as s:
        assert s.n_frames > 0


def test_listen_says_a_recording_it_was_told_to_make_ended_short(tmp_path):
    """The remote control (``listen``): a script's recording that hits the size limit is
    stopped at once, the script sees it stopped, and the command ends with exit 3."""
    import signal
    import time

    from tactile_studio.streams.remote_control import send_commands

    proc = _cli(["listen", "--device", "simulated", "--set", "rate=1000", "--port", "0",
                 "--out", str(tmp_path / "rec")], tmp_path, limit=LIMIT_BYTES)
    try:
        line = proc.stderr.readline()
        assert "listening on 127.0.0.1:" in line, line + proc.stderr.read()
        port = int(line.split("127.0.0.1:")[1].split()[0])
        assert send_commands(["start"], port) == ["OK"]
        deadline = time.monotonic() + 60  # a bound for a hung process, not a timing check
        status = {"recording": True}
        while status["recording"] and time.monotonic() < deadline:
            status = json.loads(send_commands(["status"], port)[0])
            time.sleep(0.1)
        assert status["recording"] is False  # stopped by the write error, not by us
    finally:
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == EXIT_INCOMPLETE, stderr[-3000:]
    assert "Traceback" not in stderr
    assert "write failed: file too large" in _error_line(stderr)


def test_a_truncated_copy_is_still_refused_in_one_line(tmp_path):
    """Opening files cut short must not open (or hang on) a file cut by copying."""
    out = tmp_path / "whole.h5"
    proc = _cli(["record", "--device", "simulated", "--set", "rate=500", "--seconds", "1",
                 "--out", str(out)], tmp_path)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 0, stderr
    cut = tmp_path / "cut.h5"
    cut.write_bytes(out.read_bytes()[: out.stat().st_size // 3])
    try:
        SessionFile(cut).close()
    except SessionFileError as exc:
        assert "cut.h5" in str(exc)
    else:
        raise AssertionError("a file cut to a third opened")
    cut.unlink()


def source(n: int = 997):
    rng = np.random.default_rng(0)
    return array_source(rng.normal(30000, 8000, (n, 180)).clip(0, 65535).astype(np.uint16))


def test_a_device_lost_for_good_ends_record_with_exit_3_saying_so(tmp_path):
    emu = SerialEmulator(source(), rate_hz=200, link=tmp_path / "port", reader_grace=0.05)
    emu.open()
    emu.start()
    out = tmp_path / "lost.h5"
    proc = _cli(["record", "--device", "serial", "--set", f"port={emu.port}", "--seconds",
                 "6", "--out", str(out)], tmp_path)
    try:
        def some_frames() -> bool:
            try:
                with SessionFile(out) as s:
                    return s.n_frames >= 100
            except SessionFileError:
                return False
        wait_until(some_frames, timeout=60, what="frames in the file")
    finally:
        emu.close()  # unplugged for good: the port is gone and never comes back
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == EXIT_INCOMPLETE, stdout[-2000:] + stderr[-2000:]
    assert "Traceback" not in stderr
    line = _error_line(stderr)
    assert str(out) in line and "device lost" in line and "s into the recording" in line
    assert "tried to reconnect for" in line
    with SessionFile(out) as s:
        assert s.n_frames >= 100 and f"kept {s.n_frames} frames" in line


def test_frames_the_recorder_lost_are_in_the_final_line_and_make_it_incomplete(tmp_path):
    """A recorder that falls a whole ring behind: an ``overrun`` in the file, and the
    outcome every command uses says how many frames were lost (exit 3)."""
    acq = LiveAcquisition(capacity=256)
    acq.open("simulated", {"rate": 1000, "speed": 4})
    out = tmp_path / "overrun.h5"
    rec = acq.start_recording(out, start=False)  # nobody pulls: the ring overruns
    acq.start()
    wait_until(lambda: acq.engine.frames > 2000, timeout=60, what="2000 frames")
    seen = []
    acq.add_listener(seen.append)
    acq.close()
    outcome = acq.outcome
    assert rec.dropped > 0 and outcome is not None and not outcome.complete
    assert outcome.exit_code == EXIT_INCOMPLETE
    assert f"{rec.dropped} frames lost" in outcome.line and str(out) in outcome.line
    stopped = [e for e in seen if isinstance(e, RecordingStopped)]
    assert stopped and stopped[0].message == outcome.line


def test_the_outcome_of_a_complete_recording_is_the_usual_line():
    summary = {"path": "a.h5", "frames": 100, "duration_s": 1.0, "rate_hz": 100.0,
               "malformed": 0, "gaps": 0,
               "events": [{"kind": "connect", "frame": 0, "time": 10.0},
                          {"kind": "disconnect", "reason": "gone", "frame": 50, "time": 12.0},
                          {"kind": "reconnect", "frame": 50, "time": 13.0},
                          {"kind": "disconnect", "device": "x", "frame": 100, "time": 14.0}]}
    outcome = recording_outcome(summary, started_at=10.0, ended_at=14.0)
    assert outcome.complete and outcome.exit_code == 0
    assert outcome.line == "wrote a.h5: 100 frames, 1.00 s, 100.0 Hz, malformed 0, gaps 0"
    summary["events"] = summary["events"][:2]
    lost = recording_outcome(summary, started_at=10.0, ended_at=20.0, reconnect_attempts=7)
    assert lost.exit_code == EXIT_INCOMPLETE
    assert ("device lost 2.0 s into the recording (gone); tried to reconnect for 8.0 s, "
            "7 attempts") in lost.line


def test_info_says_how_many_frames_a_file_lost(tmp_path, capsys):
    """The recording's last line said 1786 frames lost; ``info`` on the file said only
    'gaps 0' and its 0.26 s, as if the file were whole. It now says what was lost, and
    ``info --json`` has ``frames_lost`` (recorder overruns, device sequence gaps)."""
    from tactile_studio.cli import main

    acq = LiveAcquisition(capacity=256)
    acq.open("simulated", {"rate": 1000, "speed": 4})
    out = tmp_path / "overrun.h5"
    rec = acq.start_recording(out, start=False)  # nobody pulls: the ring overruns
    acq.start()
    wait_until(lambda: acq.engine.frames > 2000, timeout=60, what="2000 frames")
    acq.close()
    assert rec.dropped > 0
    capsys.readouterr()
    assert main(["info", "--json", str(out)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["frames_lost"] == {"overrun": rec.dropped, "missing": 0}
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"lost:       {rec.dropped} frames (the recorder fell behind: {rec.dropped}" in text
    assert main(["info", str(tmp_path)]) == 0  # a folder's table notes it too
    assert f"{rec.dropped} frames lost" in capsys.readouterr().out
