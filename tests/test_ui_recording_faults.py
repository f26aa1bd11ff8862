"""The windows end a recording fault as the commands do (issue 33): a write that fails
(the file-size limit, as a full disk) stops the recording, and a red banner shows the
same one line as ``record`` (acquisition/outcome.py) in the main window and the collection
console. The limit is set on this process around the recording only."""

from __future__ import annotations

import pytest
from console_helpers import open_console_session
from fault_helpers import file_size_limit

from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
from tactile_studio.storage import SessionFile
from tactile_studio.ui.collect.console import CollectConsole
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV

WAIT_MS = 30_000
ROOM = 400_000  # bytes a recording may still add before its writes fail


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


def test_main_window_stops_the_recording_and_shows_a_banner(qtbot, tmp_path):
    w = MainWindow(device="simulated", settings={"rate": "1000"}, connect=True, persist=False)
    qtbot.addWidget(w)
    w.show()
    out = tmp_path / "full.h5"
    try:
        qtbot.waitUntil(lambda: w.acquisition.status().state == "running", timeout=WAIT_MS)
        with file_size_limit(2_000_000):
            assert w.panel.start_recording(str(out))
            qtbot.waitUntil(lambda: w.acquisition.recorder is None, timeout=WAIT_MS)
        assert not w.panel.record_button.isChecked()
        assert w.status.fault.isVisible()
        text = w.status.fault.text()
        assert str(out) in text and "file too large" in text and "kept" in text
        assert "file too large" in w.panel.error_label.toolTip() + w.panel.error_label.text()
        w.grab().save(str(tmp_path / "main_window_fault.png"))
        assert w.acquisition.status().state == "running"  # the live view goes on
    finally:
        w.shutdown()
    with SessionFile(out) as s:
        assert s.n_frames > 0 and s.cut_short


def test_collection_console_ends_the_session_with_a_banner(qtbot, tmp_path):
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    path = open_console_session(qtbot, console, tmp_path / "data", "P09",
                                {"rate": "1000", "gesture": "idle"})
    try:
        with file_size_limit(path.stat().st_size + ROOM):
            qtbot.waitUntil(lambda: console.session is None, timeout=WAIT_MS)
        assert console.fault_banner.isVisible()
        text = console.fault_banner.text()
        assert str(path) in text and "file too large" in text and "kept" in text
        assert console.runner.snapshot().state == "aborted"
        console.grab().save(str(tmp_path / "console_fault.png"))
    finally:
        console.close_session()
    with SessionFile(path) as f:
        assert f.n_frames > 0 and f.cut_short


def test_main_window_says_the_device_was_lost_when_the_recording_ends(qtbot, tmp_path):
    import numpy as np

    raw = np.random.default_rng(0).normal(30000, 8000, (997, 180)).clip(0, 65535)
    emu = SerialEmulator(array_source(raw.astype(np.uint16)), rate_hz=200,
                         link=tmp_path / "port", reader_grace=0.05)
    emu.open()
    emu.start()
    w = MainWindow(device="serial", settings={"port": emu.port}, connect=True, persist=False)
    qtbot.addWidget(w)
    w.show()
    out = tmp_path / "lost.h5"
    try:
        qtbot.waitUntil(lambda: w.acquisition.status().state == "running", timeout=WAIT_MS)
        assert w.panel.start_recording(str(out))
        qtbot.waitUntil(lambda: w.acquisition.recorder.rows_written >= 50, timeout=WAIT_MS)
        emu.close()  # unplugged for good
        qtbot.waitUntil(lambda: w.acquisition.status().state == "reconnecting", timeout=WAIT_MS)
        assert not w.status.fault.isVisible()  # still trying: the recording goes on
        w.panel.stop_recording()
        assert w.status.fault.isVisible()
        text = w.status.fault.text()
        assert str(out) in text and "device lost" in text and "tried to reconnect" in text
    finally:
        w.shutdown()
        emu.close()


def test_collection_console_ends_the_session_when_its_device_ends(qtbot, tmp_path):
    """A device that ended for good (stopped here; failed alike) ends the collection as
    ``collect`` ends it: the runner aborted (the abort in the file), the file closed, and
    a banner naming the device and where the completed trials are. Before, the console
    waited for a device that could not come back, saying nothing."""
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    path = open_console_session(qtbot, console, tmp_path / "data", "P10")
    try:
        qtbot.waitUntil(lambda: console.engine.frames > 0, timeout=WAIT_MS)
        console.engine.stop()
        qtbot.waitUntil(lambda: console.session is None, timeout=WAIT_MS)
        assert console.fault_banner.isVisible()
        text = console.fault_banner.text()
        assert "device simulated: stopped" in text and str(path) in text
        assert console.runner.snapshot().state == "aborted"
    finally:
        console.close_session()
    with SessionFile(path) as f:
        assert [e["kind"] for e in f.events].count("abort") == 1
