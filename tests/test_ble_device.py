"""The BLE plugin through the real BleakClient/BleakScanner on a fake radio (ble_fakes)."""

from __future__ import annotations

import numpy as np
import pytest
from ble_fakes import BACKENDS, RADIO, FakeClient, FakePeripheral, NoAdapterClient, NoAdapterScanner
from waiting import wait_until

from tactile_studio.cli import main
from tactile_studio.devices import AcquisitionEngine
from tactile_studio.devices.ble_payload import encode_packets
from tactile_studio.devices.discovery import scan_ble
from tactile_studio.devices.engine import ERROR, RECONNECTING, RUNNING
from tactile_studio.errors import DeviceNotFound, SettingsError
from tactile_studio.plugins import ble_device
from tactile_studio.plugins.ble_device import BleDevice
from tactile_studio.storage import Recorder, SessionFile


@pytest.fixture(autouse=True)
def radio():
    RADIO.clear()
    yield RADIO
    RADIO.clear()


def frames(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 65536, (n, 180)).astype(np.uint16)


def device(**settings) -> BleDevice:
    return BleDevice(bleak_backends=BACKENDS, **{"scan_timeout": 0.2, **settings})


def test_scan_filters_by_name_and_service():
    FakePeripheral("AA:01", "ShearSense-01", rssi=-70).install()
    FakePeripheral("AA:02", "ShearSense-02", rssi=-40).install()
    FakePeripheral("AA:03", "Heart rate", services=("180d",)).install()
    found = scan_ble(0.1, backend=BACKENDS[1])
    assert {a for a, _, _ in found} == {"AA:01", "AA:02", "AA:03"}
    by_name = scan_ble(0.1, name="shearsense", backend=BACKENDS[1])
    assert by_name == [("AA:02", "ShearSense-02", -40), ("AA:01", "ShearSense-01", -70)]
    by_service = scan_ble(0.1, service_uuid="180d", backend=BACKENDS[1])
    assert [a for a, _, _ in by_service] == ["AA:03"]


def test_frames_split_lost_and_corrupt_are_reassembled_and_counted():
    per = FakePeripheral(mtu=23).install()  # 23 notifications per frame
    engine = AcquisitionEngine(device())
    try:
        engine.start()
        assert per.subscribed.wait(10)
        f = frames(30)
        for i, row in enumerate(f):
            if i == 10:
                per.send_frame(i, row, drop=(5,))  # a lost notification
            elif i == 20:
                bad = encode_packets(i, row, 23)
                bad[4] = bad[4][:6] + bytes([bad[4][6] ^ 0xFF]) + bad[4][7:]
                for p in bad:  # a corrupted byte
                    per.notify(p)
            else:
                per.send_frame(i, row)
        assert wait_until(lambda: engine.frames == 28)
        chunk = engine.read_since(0)
        keep = [i for i in range(30) if i not in (10, 20)]
        np.testing.assert_array_equal(chunk.raw, f[keep])
        np.testing.assert_array_equal(chunk.seq, keep)
        assert wait_until(lambda: engine.counters()["malformed"] == 2)
        c = engine.counters()
        assert c["malformed_by_kind"] == {"incomplete": 1, "bad_crc": 1}
        assert (c["gaps"], c["missing_frames"]) == (2, 2)
    finally:
        engine.stop()


def test_disconnect_reconnects_with_a_gap_and_the_recording_continues(tmp_path):
    per = FakePeripheral(mtu=247).install()
    engine = AcquisitionEngine(device())
    recorder = Recorder(engine, tmp_path / "ble.h5")
    f = frames(40)
    try:
        engine.start()
        recorder.start()
        assert per.subscribed.wait(10)
        for i in range(20):
            per.send_frame(i, f[i])
        assert wait_until(lambda: engine.frames == 20)
        per.available = False  # out of range: reconnect attempts fail for a while
        per.drop_link()
        assert wait_until(lambda: engine.state == RECONNECTING)
        assert wait_until(lambda: engine.reconnect_attempts >= 2)
        per.available = True
        assert wait_until(lambda: engine.state == RUNNING and per.subscribed.is_set())
        for i in range(20, 40):  # the device restarted its numbering
            per.send_frame(i - 20, f[i])
        assert wait_until(lambda: engine.frames == 40)
    finally:
        engine.stop()
        recorder.stop()
    assert per.connects == 2
    with SessionFile(tmp_path / "ble.h5") as s:
        summary, raw, seq = s.summary(), s.raw(), s.column("seq")
    np.testing.assert_array_equal(raw, f)
    np.testing.assert_array_equal(seq, np.arange(40))  # no false sequence gap
    assert summary["reconnects"] == 1 and summary["malformed"] == 0
    gaps = [e for e in summary["events"] if e["kind"] == "gap"]
    assert len(gaps) == 1 and gaps[0]["seconds"] > 0 and gaps[0]["cause"] == "reconnect"


def test_connect_by_address_without_scanning_and_read_never_blocks_long():
    per = FakePeripheral("AA:77", name="unnamed", services=("1234",)).install()
    dev = device(address="AA:77")
    try:
        dev.open()
        assert per.subscribed.is_set() and dev.address == "AA:77"
        assert len(dev.read(10)) == 0  # nothing sent: returns empty instead of waiting
        row = frames(1)[0]
        per.send_frame(5, row)
        got = []
        assert wait_until(lambda: got.append(dev.read(10)) or sum(map(len, got)) == 1)
        batch = next(b for b in got if len(b))
        np.testing.assert_array_equal(batch.raw[0], row)
        assert list(batch.seq) == [5] and batch.host_time.shape == (1,)
        assert dev.info()["address"] == "AA:77"
    finally:
        dev.close()
        dev.close()


def test_absent_adapter_missing_device_and_bad_settings_are_one_line_errors():
    for address in ("", "AA:01"):  # scanning, or connecting straight to an address
        dev = BleDevice(bleak_backends=(NoAdapterClient, NoAdapterScanner), address=address)
        with pytest.raises(DeviceNotFound, match="Bluetooth is not available") as err:
            dev.open()
        assert "\n" not in str(err.value)
        dev.close()
    with pytest.raises(DeviceNotFound, match="Bluetooth is not available"):
        scan_ble(0.1, backend=NoAdapterScanner)
    dev = device(name="Nothing")
    with pytest.raises(DeviceNotFound, match="no device named Nothing"):
        dev.open()
    dev.close()
    FakePeripheral("AA:05", char_uuid="0000aaaa-0000-1000-8000-00805f9b34fb").install()
    dev = device(address="AA:05")
    with pytest.raises(DeviceNotFound, match="no characteristic"):
        dev.open()
    dev.close()
    for bad in ({"char_uuid": "not-a-uuid"}, {"layout": "nope"}, {"scan_timeout": 0}):
        with pytest.raises(SettingsError):
            BleDevice(**bad)


def test_module_hook_lets_the_registry_and_cli_path_use_the_fake(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(ble_device, "TEST_BACKENDS", (FakeClient, NoAdapterScanner))
    code = main(["record", "--device", "ble", "--seconds", "1", "--out", str(tmp_path / "x.h5")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1 and "Bluetooth is not available" in err


def test_cli_on_this_machine_fails_cleanly_when_nothing_is_found(tmp_path, capsys):
    """Real backend: no adapter here gives one error line; with an adapter, no such sensor."""
    code = main(["record", "--device", "ble", "--set", "name=NoSuchSensor-XYZ",
                 "--set", "scan_timeout=0.5", "--seconds", "1", "--out", str(tmp_path / "x.h5")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert "Bluetooth is not available" in err or "no device named NoSuchSensor-XYZ" in err


def test_engine_error_state_when_the_peripheral_never_appears():
    engine = AcquisitionEngine(device(name="Ghost"))
    engine.start()
    assert wait_until(lambda: engine.state == ERROR)
    assert "no device named Ghost" in engine.error
    engine.stop()


def test_discover_hook_lists_addresses_for_the_device_panel(monkeypatch):
    monkeypatch.setattr(ble_device, "TEST_BACKENDS", BACKENDS)
    FakePeripheral("AA:09", "ShearSense-09", rssi=-61).install()
    FakePeripheral("AA:10", "Other", services=("180d",)).install()
    assert BleDevice.discover_setting == "address"
    assert BleDevice.supports_discover and not BleDevice.discover_instant
    settings = BleDevice.validate_settings({"scan_timeout": 0.1})
    assert BleDevice.discover(settings) == [("AA:09", "ShearSense-09 AA:09 (-61 dBm)")]
