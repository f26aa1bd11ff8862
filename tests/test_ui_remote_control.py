"""The main window as an experiment script's recorder (File > Remote control, off by
default, the port in the status bar) and its stream-health warning, with real widgets,
a real socket client and a real serial pty going quiet.

Budget: ~6 s. Waits use qtbot.waitUntil, never fixed sleeps."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
from tactile_studio.storage import SessionFile
from tactile_studio.storage.format.session_compress import wait_for_compression
from tactile_studio.streams.remote_control import send_commands
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV, app_settings

FAST = {"rate": "200", "gesture": "Twist"}


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


def test_a_script_records_through_the_window_and_the_port_is_shown(qtbot, tmp_path):
    s = app_settings()
    s.setValue("remote_control/port", 0)          # any free port
    s.setValue("remote_control/folder", str(tmp_path / "rec"))
    w = MainWindow(device="simulated", settings=FAST, persist=False)
    qtbot.addWidget(w)
    w.show()
    try:
        toggle = w.remote_control
        assert not toggle.action.isChecked() and toggle.control is None  # off by default
        assert not w.status.remote.isVisible()
        assert w.panel.connect_device()
        qtbot.waitUntil(lambda: w.acquisition.engine.frames > 20, timeout=15000)
        toggle.action.setChecked(True)
        port = toggle.control.port
        assert w.status.remote.text() == f"remote :{port}" and w.status.remote.isVisible()
        replies: list[str] = []
        script = ["filename {participant:P05} {task:pat} {run:2}", "start", "mark go", "bogus"]
        client = threading.Thread(target=lambda: replies.extend(send_commands(script, port)))
        client.start()
        qtbot.waitUntil(lambda: not client.is_alive(), timeout=15000)
        assert replies[:3] == ["OK", "OK", "OK"] and replies[3].startswith("error: unknown")
        assert w.acquisition.recording
        rec = w.acquisition.recorder
        qtbot.waitUntil(lambda: rec.rows_written > 20, timeout=10000)
        stop = threading.Thread(target=lambda: replies.extend(send_commands(["stop"], port)))
        stop.start()
        qtbot.waitUntil(lambda: not stop.is_alive(), timeout=15000)
        assert replies[-1] == "OK" and not w.acquisition.recording
        toggle.action.setChecked(False)
        assert toggle.control is None and not w.status.remote.isVisible()
        assert str(app_settings().value("remote_control/enabled")) == "false"
    finally:
        w.shutdown()
    path = tmp_path / "rec/sub-P05/sub-P05_task-pat_run-002_tactile.h5"
    wait_for_compression(path)
    with SessionFile(path) as s:
        assert s.metadata["participant"] == "P05" and s.metadata["task"] == "pat"
        assert [e["text"] for e in s.events if e["kind"] == "marker"] == ["go"]


def test_a_silent_device_shows_a_warning_in_the_status_bar(qtbot, tmp_path):
    raw = np.random.default_rng(2).integers(30000, 31000, (300, 180)).astype(np.uint16)
    emu = SerialEmulator(array_source(raw), rate_hz=500, link=tmp_path / "port",
                         reader_grace=0.05)
    emu.open()
    w = MainWindow(device="serial", settings={"port": emu.port}, persist=False)
    qtbot.addWidget(w)
    w.show()
    try:
        w.acquisition.silence_warning_s = 0.3
        assert w.panel.connect_device()
        w.acquisition.start_recording(tmp_path / "s.h5")
        emu.send_lines(120)
        qtbot.waitUntil(lambda: w.acquisition.engine.frames >= 120, timeout=10000)
        qtbot.waitUntil(lambda: w.status.warning.isVisible(), timeout=10000)
        assert "serial sent no frames for 0.3 s" in w.status.warning.text()
        w.grab().save(str(tmp_path / "warning.png"))
        emu.send_lines(20)
        qtbot.waitUntil(lambda: not w.status.warning.isVisible(), timeout=10000)
        w.acquisition.stop_recording()
    finally:
        w.shutdown()
        emu.close()


def test_switching_the_remote_control_off_ends_a_connected_client(qtbot, tmp_path):
    """Toggled off while a script was connected: its next command waited 30 s for an
    answer nobody would give (and on again, the old connection still fed the old
    listener). Now the connection ends at once, the window's recording goes on, and a
    script that connects again is served by the new listener."""
    import socket

    from remote_helpers import WAIT_S, read_to_end

    app_settings().setValue("remote_control/port", 0)
    app_settings().setValue("remote_control/folder", str(tmp_path / "rec"))
    w = MainWindow(device="simulated", settings=FAST, persist=False)
    qtbot.addWidget(w)
    w.show()
    try:
        toggle = w.remote_control
        assert w.panel.connect_device()
        qtbot.waitUntil(lambda: w.acquisition.engine.frames > 5, timeout=15000)
        toggle.action.setChecked(True)
        client = socket.create_connection(("127.0.0.1", toggle.control.port), timeout=WAIT_S)
        replies: list[bytes] = []

        def script() -> None:
            client.sendall(b"filename {participant:P3}\nstart\n")
            f = client.makefile("rb")
            replies.extend([f.readline(), f.readline()])

        thread = threading.Thread(target=script)
        thread.start()
        qtbot.waitUntil(lambda: not thread.is_alive(), timeout=15000)
        assert replies == [b"OK\n", b"OK\n"] and w.acquisition.recording
        toggle.action.setChecked(False)
        assert read_to_end(client) == b""  # closed, not left waiting
        client.close()
        assert w.acquisition.recording  # the window's recording is the window's
        toggle.action.setChecked(True)
        again: list[str] = []
        thread = threading.Thread(target=lambda: again.extend(
            send_commands(["stop"], toggle.control.port)))
        thread.start()
        qtbot.waitUntil(lambda: not thread.is_alive(), timeout=15000)
        assert again == ["OK"] and not w.acquisition.recording
    finally:
        w.shutdown()
    path = tmp_path / "rec/sub-P3/sub-P3_tactile.h5"
    wait_for_compression(path)
    with SessionFile(path) as s:
        assert s.metadata["participant"] == "P3"
