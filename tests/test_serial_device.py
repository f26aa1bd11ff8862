"""The real serial plugin (pyserial) on a real pty, fed by the emulator in-process."""

from __future__ import annotations

import os

import numpy as np
import pytest
from serial_helpers import received_all
from waiting import wait_until

from tactile_studio.cli import main
from tactile_studio.devices import AcquisitionEngine, create_device
from tactile_studio.devices.engine import ERROR, RECONNECTING, RUNNING
from tactile_studio.devices.line_decoder import KINDS
from tactile_studio.devices.serial_emulator import Corruption, SerialEmulator, array_source
from tactile_studio.errors import DeviceLost, DeviceNotFound, SettingsError
from tactile_studio.storage import Recorder, SessionFile


def source(seed: int = 0, n: int = 997):
    """A recording-like source: baseline counts with noise, every digit count present."""
    rng = np.random.default_rng(seed)
    raw = rng.normal(30000, 8000, (n, 180)).clip(0, 65535)
    raw[rng.random(raw.shape) < 0.01] = rng.integers(0, 1000)
    return array_source(raw.astype(np.uint16))


@pytest.fixture
def emulator(tmp_path):
    emu = SerialEmulator(source(), rate_hz=500, corruption=Corruption(0.3, seed=7),
                         link=tmp_path / "port",
                         keep_sent=True, reader_grace=0.05)
    emu.open()
    yield emu
    emu.close()


@pytest.fixture
def engine(emulator):
    eng = AcquisitionEngine(create_device("serial", {"port": emulator.port}))
    yield eng
    eng.stop()


def test_good_frames_arrive_exactly_and_bad_lines_are_counted_by_kind(emulator, engine):
    engine.start()
    emulator.send_lines(400)
    assert wait_until(received_all(engine, emulator))
    rep = emulator.report()
    assert set(rep["malformed_by_kind"]) == set(KINDS)  # every kind was exercised
    assert engine.counters()["malformed_by_kind"] == rep["malformed_by_kind"]
    chunk = engine.read_since(0)
    np.testing.assert_array_equal(chunk.raw, emulator.sent_frames())
    assert np.all(np.diff(chunk.host_time) >= 0)


def test_unplug_reconnects_with_a_gap_and_the_recording_continues(emulator, engine, tmp_path):
    out = tmp_path / "s.h5"
    recorder = Recorder(engine, out)
    engine.start()
    recorder.start()
    emulator.send_lines(150)
    assert wait_until(received_all(engine, emulator))

    emulator.unplug(drain=10.0)  # the cable is pulled
    assert wait_until(lambda: engine.state == RECONNECTING)
    assert wait_until(lambda: engine.reconnect_attempts >= 2)  # retrying, port absent
    emulator.open()  # plugged back in, a new pty behind the same link
    assert wait_until(lambda: engine.state == RUNNING and engine.reconnects == 1)
    emulator.send_lines(150)
    assert wait_until(received_all(engine, emulator))
    engine.stop()
    recorder.stop()

    rep = emulator.report()
    with SessionFile(out) as s:
        summary, raw = s.summary(), s.raw()
    assert summary["frames"] == rep["good"]
    assert summary["malformed_by_kind"] == rep["malformed_by_kind"]
    assert summary["reconnects"] == 1 and summary["closed_cleanly"]
    gaps = [e for e in summary["events"] if e["kind"] == "gap"]
    assert len(gaps) == 1 and gaps[0]["seconds"] > 0
    np.testing.assert_array_equal(raw, emulator.sent_frames())


def test_a_vanished_port_is_noticed_while_silent(emulator):
    dev = create_device("serial", {"port": emulator.port})
    dev.open()
    try:
        os.unlink(emulator.port)  # the device node disappears, no read error yet
        with pytest.raises(DeviceLost, match="vanished"):
            for _ in range(100):
                dev.read(10)
        with pytest.raises(DeviceNotFound):
            dev.reopen()
    finally:
        dev.close()
        dev.close()  # twice is fine


def test_garbage_at_the_wrong_baud_rate_is_a_one_line_error(tmp_path):
    emu = SerialEmulator(source(), rate_hz=2000, corruption=Corruption(1.0, ["undecodable"]),
                         link=tmp_path / "port", reader_grace=0.05)
    emu.open()
    engine = AcquisitionEngine(create_device("serial", {"port": emu.port}))
    try:
        engine.start()
        emu.start()
        assert wait_until(lambda: engine.state == ERROR)
        assert "wrong baud rate" in engine.error and "\n" not in engine.error
        assert engine.frames == 0
    finally:
        engine.stop()
        emu.close()


def test_bad_port_baud_and_layout_give_one_line_errors(capsys, tmp_path):
    dev = create_device("serial", {"port": "/dev/does-not-exist"})
    with pytest.raises(DeviceNotFound, match="/dev/does-not-exist: not found") as err:
        dev.open()
    assert "\n" not in str(err.value)
    for settings in ({"baud": "fast"}, {"baud": 0}, {"layout": "nope"},
                     {"channels": 64}, {"speed": 3}):
        with pytest.raises(SettingsError):
            create_device("serial", {"port": "/dev/null", **settings})
    for extra in ([], ["--set", "baud=-9600"]):
        code = main(["record", "--device", "serial", "--set", "port=/dev/does-not-exist",
                     *extra, "--seconds", "1", "--out", str(tmp_path / "x.h5")])
        err_text = capsys.readouterr().err.strip()
        assert code == 1
        assert len(err_text.splitlines()) == 1 and "Traceback" not in err_text
        assert "error:" in err_text
        assert not (tmp_path / "x.h5").exists()


def test_record_and_info_commands_through_serial(emulator, tmp_path, capsys):
    import json

    emulator.start()
    out = tmp_path / "rec.h5"
    assert main(["record", "--device", "serial", "--set", f"port={emulator.port}",
                 "--seconds", "1", "--out", str(out)]) == 0
    emulator.stop()
    capsys.readouterr()
    assert main(["info", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    rep = emulator.report()
    assert 0 < summary["frames"] <= rep["good"]
    assert summary["metadata"]["device"]["plugin"] == "serial"
    assert summary["metadata"]["device"]["port"] == emulator.port
    for kind, n in summary["malformed_by_kind"].items():
        assert n <= rep["malformed_by_kind"][kind]


def test_discover_hook_lists_ports_as_the_os_reports_them():
    from tactile_studio.devices.discovery import list_serial_ports
    from tactile_studio.plugins.serial_device import SerialDevice

    ports = list_serial_ports()
    assert all(isinstance(d, str) and isinstance(desc, str) for d, desc, _ in ports)
    assert all(vp == "" or len(vp) == 9 and vp[4] == ":" for _, _, vp in ports)
    assert SerialDevice.discover_setting == "port"
    assert SerialDevice.supports_discover and SerialDevice.discover_instant
    found = SerialDevice.discover(SerialDevice.validate_settings({}))
    assert [value for value, _ in found] == [d for d, _, _ in ports]
