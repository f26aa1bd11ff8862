"""The live main window, driven like a user: real widgets, engine and simulated sensor.

Offscreen Qt (tests/conftest.py); settings go to a temporary INI file so the user's
preferences are never touched. Waits use qtbot.waitUntil, never fixed sleeps.
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage
from ui_helpers import hover_cell_with_mouse

import tactile_studio.devices.registry as registry
from tactile_studio import cli
from tactile_studio.devices.contract import DevicePlugin, FrameBatch
from tactile_studio.errors import DeviceNotFound
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage import SessionFile
from tactile_studio.ui.app import close_on_signals, ensure_app
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV

FAST = {"rate": "200", "gesture": "Twist"}  # 100 baseline frames in half a second


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


@pytest.fixture
def window(qtbot):
    w = MainWindow(device="simulated", settings=FAST)
    qtbot.addWidget(w)
    w.show()
    yield w
    w.shutdown()


def _tare_events(engine) -> int:
    return sum(1 for e in engine.events_since(0) if e["kind"] == "tare")


def test_live_view_end_to_end(qtbot, window, tmp_path, monkeypatch):
    w = window
    assert w.panel.connect_device()
    engine = w.acquisition.engine
    qtbot.waitUntil(lambda: engine.state == "running" and engine.baseline is not None,
                    timeout=15000)

    # frames arrive and are painted: counter rises, the image is real data
    first = engine.frames
    qtbot.waitUntil(lambda: engine.frames > first + 20, timeout=10000)
    qtbot.waitUntil(lambda: w.heatmap.image_data() is not None, timeout=5000)
    qtbot.waitUntil(lambda: w.display_fps() > 0 and w.latency.last() is not None,
                    timeout=10000)
    img = w.heatmap.image_data()
    assert img.shape == (6, 6) and np.all(np.isfinite(img)) and np.ptp(img) > 0
    w.refresh_status()
    assert "running" in w.status.state.text() and "Hz" in w.status.rate.text()
    assert "frames" in w.panel.detail_label.text()
    assert 0 <= w.latency.last() < 5.0

    # tare: a new baseline is taken
    before = _tare_events(engine)
    qtbot.mouseClick(w.panel.tare_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: _tare_events(engine) == before + 1, timeout=10000)

    # physical <-> virtual
    qtbot.mouseClick(w.heatmap.virtual_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: w.heatmap.image_data().shape == (11, 11), timeout=5000)
    assert w.live.virtual and w.virtual_action.isChecked()
    hover_cell_with_mouse(qtbot, w.heatmap, 4, 7)
    qtbot.waitUntil(lambda: w.heatmap.readout.text().startswith("C4-C5"), timeout=5000)
    assert "between C4, C5" in w.heatmap.readout.text()
    qtbot.mouseClick(w.heatmap.physical_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: w.heatmap.image_data().shape == (6, 6), timeout=5000)

    # hover readout names the taxel under the pointer
    hover_cell_with_mouse(qtbot, w.heatmap, 2, 3)
    qtbot.waitUntil(lambda: w.heatmap.readout.text().startswith("C4 "), timeout=5000)
    assert "kPa" in w.heatmap.readout.text() and "raw" in w.heatmap.readout.text()

    # the strip chart follows the selected taxels; a click toggles one
    w.set_strip_taxels([(2, 2)])
    qtbot.waitUntil(lambda: w.strip.curve_names() == ["C3"], timeout=5000)
    w.heatmap.cellClicked.emit(3, 3)
    qtbot.waitUntil(lambda: w.strip.curve_names() == ["C3", "D4"], timeout=5000)

    # record to a file chosen in the (stubbed) dialog, then stop
    path = tmp_path / "live.h5"
    monkeypatch.setattr(w.panel, "ask_record_path", lambda: str(path))
    qtbot.mouseClick(w.panel.record_button, Qt.MouseButton.LeftButton)
    assert w.acquisition.recorder is not None
    qtbot.waitUntil(lambda: w.acquisition.status().recorded_frames > 20, timeout=10000)
    qtbot.mouseClick(w.panel.record_button, Qt.MouseButton.LeftButton)
    assert w.acquisition.recorder is None and not w.panel.record_button.isChecked()
    with SessionFile(path) as s:
        assert s.n_frames > 20 and s.closed_cleanly
        assert s.metadata["device"]["plugin"] == "simulated"

    # disconnect
    qtbot.mouseClick(w.panel.disconnect_button, Qt.MouseButton.LeftButton)
    assert engine.state == "stopped"
    w.refresh_status()
    assert "No device" in w.status.state.text() or "stopped" in w.status.state.text()
    assert not w.panel.tare_button.isEnabled()


def test_bad_setting_shows_one_line_error_and_blocks_connect(qtbot, window):
    w = window
    w.panel._fields["rate"].set_text("fast")
    assert "rate" in w.panel.error_text() and "not a valid float" in w.panel.error_text()
    assert "\n" not in w.panel.error_text()
    assert not w.panel.connect_button.isEnabled()
    assert w.panel._fields["rate"].editor.property("invalid") is True
    assert not w.panel.connect_device() and w.acquisition.engine is None
    w.panel._fields["rate"].set_text("0")
    assert "below the minimum" in w.panel.error_text()
    w.panel._fields["rate"].set_text("200")
    assert w.panel.error_text() == "" and w.panel.connect_button.isEnabled()
    # a value only the plugin itself can refuse (unknown gesture) -> inline error too
    w.panel._fields["gesture"].set_text("juggling")
    assert not w.panel.connect_device()
    assert "unknown gesture" in w.panel.error_text()


class _NoSensor(DevicePlugin):
    """A plugin whose device is never there: open() fails in the engine thread."""

    name = "nosensor"
    description = "always missing"

    @property
    def layout(self):
        return SHEARSENSE_6X6

    @property
    def nominal_rate_hz(self) -> float:
        return 43.0

    def open(self) -> None:
        raise DeviceNotFound("nosensor: no sensor on /dev/ttyFAKE")

    def read(self, max_frames: int) -> FrameBatch:  # pragma: no cover - never opened
        raise AssertionError

    def close(self) -> None:
        pass


@pytest.fixture
def nosensor():
    """The broken plugin registered in this process, as a notebook would add one."""
    registry.register_device(_NoSensor)
    yield _NoSensor
    registry.unregister_device(_NoSensor.name)


def test_plugin_error_is_shown_and_the_app_lives_on(qtbot, nosensor):
    w = MainWindow(device="nosensor")
    qtbot.addWidget(w)
    w.show()
    assert w.panel.connect_device()
    qtbot.waitUntil(lambda: w.acquisition.engine.state == "error", timeout=5000)
    w.refresh_status()
    assert w.panel.error_text() == "nosensor: no sensor on /dev/ttyFAKE"
    assert "no sensor on /dev/ttyFAKE" in w.status.state.text()
    # the app lives on: another device connects and streams
    assert w.panel.set_device("simulated", FAST)
    assert w.panel.connect_device()
    qtbot.waitUntil(lambda: w.heatmap.image_data() is not None, timeout=10000)
    w.refresh_status()
    assert w.panel.error_text() == ""
    w.shutdown()


def test_settings_persist_across_windows(qtbot, tmp_path):
    w1 = MainWindow()  # nothing saved yet: the default device, not connected
    qtbot.addWidget(w1)
    assert w1.panel.device_name() == "simulated" and w1.acquisition.engine is None
    w1.panel._fields["rate"].set_text("123")
    w1.panel._fields["noise"].set_text("7.5")
    w1.set_virtual(True)
    w1.heatmap.set_arrow_scale(0.8)
    w1.heatmap.set_range(None)
    w1.set_strip_taxels([(1, 1), (4, 5)])
    w1.show()
    w1.resize(790, 560)
    saved_size = (w1.width(), w1.height())  # the minimum width may clamp it
    w1.close()  # saves

    w2 = MainWindow()
    qtbot.addWidget(w2)
    assert w2.panel.device_name() == "simulated"
    assert w2.panel.values()["rate"] == "123" and w2.panel.values()["noise"] == "7.5"
    assert w2.heatmap.virtual and w2.live.virtual
    assert w2.heatmap.arrow_scale == pytest.approx(0.8)
    assert w2.heatmap.fixed_max is None and w2.heatmap.auto_range.isChecked()
    assert w2.strip_taxels == [(1, 1), (4, 5)]
    assert (w2.width(), w2.height()) == saved_size and saved_size[1] == 560
    assert (tmp_path / "settings.ini").exists()
    # choosing another device and coming back brings this device's settings back
    w2.panel.device_box.setCurrentIndex(w2.panel.device_box.findData("replay"))
    assert "rate" not in w2.panel.values()
    w2.panel.device_box.setCurrentIndex(w2.panel.device_box.findData("simulated"))
    assert w2.panel.values()["rate"] == "123"
    w2.shutdown()
    # an explicit device + settings (as from the command line) override saved ones
    w3 = MainWindow(device="simulated", settings={"noise": "3"})
    qtbot.addWidget(w3)
    assert w3.panel.values()["rate"] == "123" and w3.panel.values()["noise"] == "3"
    w3.shutdown()


def test_snapshot_command_writes_a_png(qtbot, tmp_path, capsys):
    out = tmp_path / "shot.png"
    code = cli.main(["snapshot", "--device", "simulated", "--set", "rate=200",
                     "--set", "gesture=Twist", "--seconds", "1.5", "--virtual",
                     "--hover", "C3", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    image = QImage(str(out))
    assert not image.isNull() and image.width() >= 800 and image.height() >= 500


@pytest.mark.parametrize("argv, message", [
    (["--device", "nope"], "unknown device 'nope'"),
    (["--set", "rate=fast"], "setting rate: 'fast' is not a valid float"),
    (["--set", "colour=red"], "unknown setting 'colour'"),
])
def test_snapshot_bad_device_or_setting_is_one_line(tmp_path, capsys, argv, message):
    code = cli.main(["snapshot", *argv, "--out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err
    assert code == 1 and message in err and err.count("\n") == 1
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["sigterm", "ctrl-c"])
def test_a_signal_closes_the_window_and_finishes_its_recording(qtbot, window, tmp_path, sig):
    # `kill` or Ctrl-C in the terminal the app was started from: a real signal to this
    # process, handled as run_gui handles it
    assert window.panel.connect_device()
    path = tmp_path / "killed.h5"
    assert window.panel.start_recording(str(path))
    qtbot.waitUntil(lambda: window.acquisition.status().recorded_frames > 20, timeout=10000)
    with close_on_signals(ensure_app()):
        os.kill(os.getpid(), sig)
        qtbot.waitUntil(lambda: not window.isVisible(), timeout=10000)
    assert window.acquisition.recorder is None and not window.acquisition.engine.running
    with SessionFile(path) as s:
        assert s.closed_cleanly and s.n_frames > 20
