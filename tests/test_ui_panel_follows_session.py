"""The device panel shows what the session decides: when the stream ends, the session
(polled by the main window) closes the recording and the Record button follows its event."""

from __future__ import annotations

import pytest
from waiting import wait_until

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.storage import SessionFile
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV

WAIT_MS = 20000


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


def test_recording_stops_with_the_stream_and_the_button_follows(qtbot, tmp_path) -> None:
    src = LiveAcquisition()
    src.open("simulated", {"rate": "400", "speed": "8"})
    rec = src.start_recording(tmp_path / "src.h5")
    src.start()
    wait_until(lambda: rec.rows_written >= 600, what="1.5 s of source frames")
    src.close()
    w = MainWindow(device="replay", settings={"path": str(tmp_path / "src.h5")},
                   connect=True, persist=False)
    qtbot.addWidget(w)
    changes: list[str] = []
    w.panel.recordingChanged.connect(changes.append)
    try:
        qtbot.waitUntil(lambda: w.acquisition.status().state == "running", timeout=WAIT_MS)
        assert w.panel.start_recording(str(tmp_path / "copy.h5"))
        assert w.panel.record_button.isChecked()
        qtbot.waitUntil(lambda: w.acquisition.status().state == "finished", timeout=WAIT_MS)
        qtbot.waitUntil(lambda: not w.panel.record_button.isChecked(), timeout=WAIT_MS)
        assert w.acquisition.recorder is None
        assert w.panel.record_label.text() == f"Saved {tmp_path / 'copy.h5'}"
        assert changes == [str(tmp_path / "copy.h5"), ""]
    finally:
        w.shutdown()
    with SessionFile(tmp_path / "copy.h5") as s:
        assert s.closed_cleanly and s.n_frames > 0
