"""LabRecorder's remote control: ``tactile-studio listen`` driven over a real socket by
a plain client, as an experiment script would (filename -> start -> mark -> stop), and
the file names LabRecorder's templates give.

Budget: ~5 s (one subprocess streaming the simulator)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tactile_studio.storage import SessionFile
from tactile_studio.streams.remote_control import send_commands
from tactile_studio.streams.remote_names import CommandError, parse_filename, recording_path

EXE = str(Path(sys.executable).parent / "tactile-studio")
WAIT_S = 30.0  # a safety net for a hung process, never a timing assertion


def test_file_names_follow_bids_and_labrecorder_templates(tmp_path):
    f = parse_filename("{root:study} {participant:P01} {session:S1} {task:T} {run:1}")
    assert recording_path(f, tmp_path) == \
        tmp_path / "study/sub-P01/ses-S1/sub-P01_ses-S1_task-T_run-001_tactile.h5"
    f = parse_filename("{root:data/pilot} {template:exp_%p_%b_run%n.xdf} {participant:P9} "
                       "{task:X} {run:12} {modality:eeg}")
    assert recording_path(f, tmp_path) == tmp_path / "data/pilot/exp_P9_X_run012.h5"
    assert recording_path({}, tmp_path) == tmp_path / "tactile.h5"
    for bad in ("", "participant:P01", "{colour:red}", "{run:one}", "{participant:P01} junk"):
        with pytest.raises(CommandError):
            parse_filename(bad)


def test_a_script_drives_listen_through_filename_start_mark_stop(tmp_path):
    out = tmp_path / "rec"
    proc = subprocess.Popen([EXE, "listen", "--device", "simulated", "--set", "rate=200",
                             "--port", "0", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()
        assert "listening on 127.0.0.1:" in line, line + proc.stderr.read()
        port = int(line.split("127.0.0.1:")[1].split()[0])
        replies = send_commands([
            "hello", "select none", "start", "select all", "stop",
            "filename {participant:P01} {session:S1} {task:T} {run:1}",
            "filename {colour:red}", "status", "start", "start"], port)
        assert replies[0].startswith("error: unknown command 'hello'")
        assert replies[1] == "OK" and replies[2].startswith("error: no stream selected")
        assert replies[3] == "OK" and replies[4] == "error: not recording"
        assert replies[5] == "OK" and replies[6].startswith("error: filename: unknown field")
        status = json.loads(replies[7])
        assert status["device"] == "simulated" and status["recording"] is False
        assert replies[8] == "OK" and replies[9].startswith("error: already recording")
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:  # a condition with a bound, not a timing check
            status = json.loads(send_commands(["status"], port)[0])
            if status["frames"] >= 50:
                break
            time.sleep(0.05)
        assert status["recording"] is True and status["frames"] >= 50
        assert send_commands(["mark stimulus on", "mark", "stop"], port) == \
            ["OK", "error: mark needs a text, e.g. mark stimulus_on", "OK"]
    finally:
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=WAIT_S)
    assert proc.returncode in (0, 130), stderr
    path = out / "sub-P01/ses-S1/sub-P01_ses-S1_task-T_run-001_tactile.h5"
    assert f"wrote {path}" in stdout
    assert status["file"] == str(path)
    with SessionFile(path) as s:
        assert s.metadata["participant"] == "P01" and s.metadata["task"] == "T"
        assert s.metadata["session_label"] == "S1" and s.metadata["source"] == "remote"
        assert s.n_frames >= 50
        (mark,) = [e for e in s.events if e["kind"] == "marker"]
        assert mark["text"] == "stimulus on" and 50 <= mark["frame"] <= s.n_frames


def test_the_psychopy_style_script_in_the_docs_works(tmp_path):
    doc = (Path(__file__).parents[1] / "docs" / "lsl.md").read_text()
    script = doc.split("<!-- remote-control-script -->\n```python\n")[1].split("```")[0]
    (tmp_path / "experiment.py").write_text(script)
    out = tmp_path / "rec"
    proc = subprocess.Popen([EXE, "listen", "--set", "rate=100", "--port", "0",
                             "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()
        port = line.split("127.0.0.1:")[1].split()[0]
        run = subprocess.run([sys.executable, str(tmp_path / "experiment.py"), port],
                             capture_output=True, text=True, timeout=WAIT_S)
        assert run.returncode == 0, run.stdout + run.stderr
        assert json.loads(run.stdout)["recording"] is False
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=WAIT_S)
    with SessionFile(out / "sub-P01/ses-S1/sub-P01_ses-S1_task-stroke_run-001_tactile.h5") as s:
        marks = [e["text"] for e in s.events if e["kind"] == "marker"]
        assert marks == [f"trial_{i}_{w}" for i in range(3) for w in ("cue", "end")]
        assert s.n_frames > 0


def test_a_recording_without_frames_is_an_error_not_a_silent_empty_file(tmp_path):
    """The core driven on this thread (``handle``), a serial pty that sends nothing."""
    import numpy as np

    from tactile_studio.acquisition.live_acquisition import LiveAcquisition
    from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
    from tactile_studio.streams.remote_control import RemoteControl

    emu = SerialEmulator(array_source(np.zeros((10, 180), np.uint16)), link=tmp_path / "port")
    emu.open()
    session = LiveAcquisition()
    try:
        session.open("serial", {"port": emu.port})
        session.start()
        control = RemoteControl(session, tmp_path / "rec")
        assert control.handle("filename {participant:P02}") == "OK"
        assert control.handle("start") == "OK"
        reply = control.handle("stop")
        path = tmp_path / "rec/sub-P02/sub-P02_tactile.h5"
        assert reply == f"error: {path}: no frames were recorded (the device sent none)"
        assert json.loads(control.handle("status"))["recording"] is False
    finally:
        session.close()
        emu.close()
