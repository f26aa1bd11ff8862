"""Which serial port to open when none is set, and errors that always name the port.

The choice is made from pyserial's own ``ListPortInfo`` records, built here as pyserial
builds them, so the rule is exercised on machines without any USB serial device."""

from __future__ import annotations

import os

import pytest
from serial.tools.list_ports_common import ListPortInfo

from tactile_studio.cli import main, session_cmds
from tactile_studio.devices import create_device
from tactile_studio.devices.discovery import (
    list_serial_ports,
    pick_serial_port,
    serial_ports_from,
)
from tactile_studio.errors import DeviceNotFound, SettingsError


def _port(device: str, vid: int | None = None, pid: int | None = None,
          description: str = "n/a") -> ListPortInfo:
    info = ListPortInfo(device, skip_link_detection=True)
    info.vid, info.pid, info.description = vid, pid, description
    return info


LEGACY = _port("/dev/ttyS0")
RECEIVER = _port("/dev/ttyUSB0", 0x10C4, 0xEA60, "CP2102 USB to UART Bridge Controller")
OTHER_USB = _port("/dev/ttyACM0", 0x2341, 0x0043, "Arduino Uno")


def test_ports_are_read_from_pyserial_records():
    assert serial_ports_from([RECEIVER, LEGACY]) == [
        ("/dev/ttyS0", "", ""),
        ("/dev/ttyUSB0", "CP2102 USB to UART Bridge Controller", "10C4:EA60")]


def test_the_single_usb_device_is_picked_beside_legacy_ports():
    assert pick_serial_port(serial_ports_from([LEGACY, RECEIVER])) == "/dev/ttyUSB0"
    assert pick_serial_port(serial_ports_from([RECEIVER])) == "/dev/ttyUSB0"


def test_a_legacy_port_alone_is_never_opened():
    with pytest.raises(DeviceNotFound) as err:
        pick_serial_port(serial_ports_from([LEGACY, _port("/dev/ttyS1")]))
    msg = str(err.value)
    assert "\n" not in msg
    assert "no USB serial device" in msg
    assert "/dev/ttyS0 (not USB)" in msg and "/dev/ttyS1 (not USB)" in msg
    assert "--set port=" in msg


def test_several_usb_devices_are_listed_for_the_user_to_choose():
    with pytest.raises(DeviceNotFound) as err:
        pick_serial_port(serial_ports_from([RECEIVER, OTHER_USB, LEGACY]))
    msg = str(err.value)
    assert "2 USB serial devices" in msg and "--set port=" in msg
    assert "/dev/ttyACM0 (Arduino Uno, 2341:0043)" in msg
    assert "/dev/ttyUSB0 (CP2102 USB to UART Bridge Controller, 10C4:EA60)" in msg


def test_no_ports_at_all():
    with pytest.raises(DeviceNotFound, match="no serial ports found.*--set port="):
        pick_serial_port([])


def test_the_plugin_without_a_port_follows_the_rule_on_this_machine():
    ports = list_serial_ports()
    usb = [d for d, _, vp in ports if vp]
    if len(usb) == 1:
        pytest.skip("this machine has exactly one USB serial device; it would be opened")
    dev = create_device("serial", {})
    with pytest.raises(DeviceNotFound, match="--set port=") as err:
        dev.open()
    for d, _, _ in ports:  # whatever exists (e.g. a legacy /dev/ttyS0) is named, not opened
        assert d in str(err.value)
    dev.close()


def test_setting_errors_name_the_port():
    with pytest.raises(SettingsError, match="port /dev/ttyUSB7.*channels=64"):
        create_device("serial", {"port": "/dev/ttyUSB7", "channels": 64})
    with pytest.raises(SettingsError, match="port /dev/ttyUSB7.*layout"):
        create_device("serial", {"port": "/dev/ttyUSB7", "layout": "nope"})


def test_record_names_a_silent_port(tmp_path, capsys, monkeypatch):
    """A real pty that never sends a byte: `record` gives up naming device and port."""
    monkeypatch.setattr(session_cmds, "FIRST_FRAME_TIMEOUT_S", 0.5)
    master, slave = os.openpty()
    try:
        port = os.ttyname(slave)
        out = tmp_path / "silent.h5"
        code = main(["record", "--device", "serial", "--set", f"port={port}",
                     "--seconds", "1", "--out", str(out)])
        err = capsys.readouterr().err.strip()
    finally:
        os.close(master)
        os.close(slave)
    assert code == 1
    assert len(err.splitlines()) == 1
    assert f"device serial on {port}: no frames within 0.5 s" in err
    assert not out.exists()
