"""The device panel with real devices: scanning, free text, and the connection's health.

Real widgets (pytest-qt, offscreen), the real serial plugin on a real pty fed by the
serial emulator, and the real BleakScanner above the fake radio of tests/ble_fakes.py.
A pty is not a port the OS lists, so the drop-down is exercised through the BLE scan and
the emulator is reached by typing its link path. Budget: < 15 s.
"""

from __future__ import annotations

import pytest
from ble_fakes import BACKENDS, RADIO, FakePeripheral, NoAdapterClient, NoAdapterScanner
from PySide6.QtCore import Qt

from tactile_studio.acquisition import LiveStatus, format_malformed
from tactile_studio.devices.discovery import list_serial_ports
from tactile_studio.devices.serial_emulator import Corruption, SerialEmulator
from tactile_studio.plugins import ble_device
from tactile_studio.storage.recording.frame_sources import simulated_source
from tactile_studio.ui.device_discovery import DiscoverField
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV


@pytest.fixture(autouse=True)
def isolated(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    RADIO.clear()
    yield
    RADIO.clear()


@pytest.fixture
def window(qtbot):
    w = MainWindow(device="simulated")
    qtbot.addWidget(w)
    w.show()
    yield w
    w.shutdown()


def choose(w: MainWindow, name: str) -> DiscoverField:
    """Pick a plugin in the device box, as a user would."""
    w.panel.device_box.setCurrentIndex(w.panel.device_box.findData(name))
    field = w.panel.discover_field
    assert field is not None and w.panel._fields[field.setting.name] is field
    return field


def test_malformed_counts_read_most_frequent_first():
    assert format_malformed({"non_numeric": 1, "short": 3, "empty": 0}) == "3 short, 1 non_numeric"
    assert format_malformed({"long": 2, "empty": 2}) == "2 empty, 2 long"
    assert format_malformed({}) == "none"
    st = LiveStatus("serial", "reconnecting", None, reconnect_attempts=4,
                    malformed_by_kind={"short": 3})
    assert st.state_text() == "serial: reconnecting (attempt 4)"
    assert "malformed: 3 short" in st.detail_lines()


def test_serial_ports_are_listed_as_soon_as_the_plugin_is_chosen(qtbot, window):
    field = choose(window, "serial")
    assert field.setting.name == "port" and field.editor.isEditable()
    qtbot.waitUntil(lambda: not field.is_scanning(), timeout=10000)
    ports = list_serial_ports()  # whatever this machine has (maybe nothing)
    assert [value for value, _ in field.choices()] == [dev for dev, _, _ in ports]
    for (_, label), (dev, desc, vid_pid) in zip(field.choices(), ports):
        assert dev in label and desc in label and vid_pid in label
    assert ("found" in field.status_text()) and field.scan_button.isEnabled()
    assert window.panel.values().get("port", "") == ""  # the scan never fills it in


def test_ble_scan_lists_name_and_rssi_and_a_choice_fills_the_address(qtbot, window,
                                                                       monkeypatch):
    monkeypatch.setattr(ble_device, "TEST_BACKENDS", BACKENDS)
    FakePeripheral("AA:00:00:00:00:01", "ShearSense-01", rssi=-72).install()
    FakePeripheral("AA:00:00:00:00:02", "ShearSense-02", rssi=-41).install()
    FakePeripheral("AA:00:00:00:00:03", "Heart rate", services=("180d",)).install()
    field = choose(window, "ble")
    assert field.setting.name == "address"
    assert not field.is_scanning() and field.choices() == []  # a radio scan waits for Scan
    window.panel._fields["scan_timeout"].set_text("0.2")

    qtbot.mouseClick(field.scan_button, Qt.MouseButton.LeftButton)
    assert field.status_text() == "scanning…" and not field.scan_button.isEnabled()
    qtbot.waitUntil(lambda: not field.is_scanning(), timeout=10000)
    choices = field.choices()
    assert [value for value, _ in choices] == ["AA:00:00:00:00:02", "AA:00:00:00:00:01"]
    assert "ShearSense-02" in choices[0][1] and "-41 dBm" in choices[0][1]
    assert "ShearSense-01" in choices[1][1] and "-72 dBm" in choices[1][1]
    assert field.status_text().startswith("2 found") and field.scan_button.isEnabled()

    field.editor.setCurrentIndex(1)  # the user picks the second entry
    assert field.text() == "AA:00:00:00:00:01"
    assert window.panel.values()["address"] == "AA:00:00:00:00:01"
    field.editor.lineEdit().clear()
    qtbot.keyClicks(field.editor.lineEdit(), "AA:00:00:00:00:09")  # free text still works
    assert window.panel.values()["address"] == "AA:00:00:00:00:09"
    assert window.panel.is_valid()


def test_ble_scan_without_an_adapter_shows_one_line_error(qtbot, window, monkeypatch):
    monkeypatch.setattr(ble_device, "TEST_BACKENDS", (NoAdapterClient, NoAdapterScanner))
    field = choose(window, "ble")
    window.panel._fields["scan_timeout"].set_text("0.2")
    qtbot.mouseClick(field.scan_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: not field.is_scanning(), timeout=10000)
    error = field.status_text()
    assert "Bluetooth is not available" in error and "\n" not in error
    assert field.status.objectName() == "error" and field.scan_button.isEnabled()
    assert field.choices() == []
    field.set_text("AA:00:00:00:00:07")
    assert window.panel.values()["address"] == "AA:00:00:00:00:07"


def test_serial_emulator_typed_port_connects_counts_bad_lines_and_reconnects(
        qtbot, window, tmp_path):
    emu = SerialEmulator(simulated_source(seed=3, rate=200.0), rate_hz=200,
                         corruption=Corruption(0.25, seed=11), link=tmp_path / "port",
                         reader_grace=0.05)
    emu.open()
    try:
        w = window
        field = choose(w, "serial")
        field.editor.lineEdit().clear()
        qtbot.keyClicks(field.editor.lineEdit(), emu.port)
        qtbot.waitUntil(lambda: not field.is_scanning(), timeout=10000)
        assert field.text() == emu.port  # the automatic scan left the typed text alone
        qtbot.mouseClick(w.panel.connect_button, Qt.MouseButton.LeftButton)
        engine = w.acquisition.engine
        assert engine is not None and w.acquisition.device_name == "serial"

        emu.send_lines(240)
        rep = emu.report()
        assert rep["malformed"] > 0
        qtbot.waitUntil(lambda: engine.frames == rep["good"]
                        and engine.counters()["malformed"] == rep["malformed"], timeout=15000)
        w.refresh_status()
        detail = w.panel.detail_label.text()
        for kind, n in rep["malformed_by_kind"].items():
            assert f"{n} {kind}" in detail
        assert f"{rep['good']} frames" in detail and "Hz measured" in detail
        assert w.panel.state_label.text() == "serial: running"
        qtbot.waitUntil(lambda: w.heatmap.image_data() is not None, timeout=10000)

        emu.unplug(drain=10.0)  # the cable is pulled
        qtbot.waitUntil(lambda: "serial: reconnecting (attempt" in w.panel.state_label.text(),
                        timeout=10000)
        assert w.panel.state_label.property("state") == "reconnecting"
        assert "reconnecting" in w.status.state.text()
        emu.open()  # plugged back in behind the same link
        qtbot.waitUntil(lambda: w.panel.state_label.text() == "serial: running"
                        and "reconnects 1" in w.panel.detail_label.text(), timeout=15000)
        before = engine.frames
        emu.send_lines(20)
        qtbot.waitUntil(lambda: engine.frames > before, timeout=10000)
    finally:
        emu.close()
