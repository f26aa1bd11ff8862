"""Finding real devices: serial ports and BLE peripherals. Qt-free, for the CLI and the UI.

Both functions block (the BLE scan for ``timeout`` seconds): the UI calls them from a
worker, never from its event loop.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Iterable
from typing import Any

from tactile_studio.errors import DeviceNotFound

SerialPort = tuple[str, str, str]  # (device, description, "VID:PID" or "")


def serial_ports_from(infos: Iterable[Any]) -> list[SerialPort]:
    """(device, description, "VID:PID" or "") of pyserial ``ListPortInfo`` records, sorted.
    A VID:PID means a USB device; legacy ports (``/dev/ttyS0``, COM1) have none."""
    found = []
    for p in sorted(infos, key=lambda p: p.device):
        vid_pid = f"{p.vid:04X}:{p.pid:04X}" if p.vid is not None and p.pid is not None else ""
        desc = p.description if p.description and p.description != "n/a" else ""
        found.append((p.device, desc, vid_pid))
    return found


def list_serial_ports() -> list[SerialPort]:
    """Every serial port the OS knows: (device, description, "VID:PID" or "")."""
    from serial.tools import list_ports

    return serial_ports_from(list_ports.comports())


def describe_serial_ports(ports: list[SerialPort]) -> str:
    """One line naming every port, e.g. "found: /dev/ttyS0 (not USB), /dev/ttyUSB0 (CP2102
    USB to UART, 10C4:EA60)"."""
    if not ports:
        return "no serial ports found"
    parts = []
    for dev, desc, vid_pid in ports:
        what = ", ".join(x for x in (desc, vid_pid or "not USB") if x)
        parts.append(f"{dev} ({what})")
    return "found: " + ", ".join(parts)


def pick_serial_port(ports: list[SerialPort]) -> str:
    """The port to open when none is set: the one USB serial device, if exactly one.

    Legacy ports without a VID:PID are never picked (they exist on most PCs and are never
    the receiver); with none or several USB devices the user must choose, and the error
    lists what was found.
    """
    usb = [dev for dev, _, vid_pid in ports if vid_pid]
    if len(usb) == 1:
        return usb[0]
    why = "no USB serial device" if not usb else f"{len(usb)} USB serial devices"
    raise DeviceNotFound(f"serial: no port set and {why} ({describe_serial_ports(ports)}); "
                         "choose one with --set port=... (`tactile-studio ports` lists them)")


def bluetooth_unavailable(exc: BaseException) -> DeviceNotFound:
    """A one-line error for an absent adapter or Bluetooth stack (bleak and OS errors)."""
    from bleak.exc import BleakBluetoothNotAvailableError

    if isinstance(exc, BleakBluetoothNotAvailableError):
        msg = str(exc.args[0]) if exc.args else "unknown reason"
        return DeviceNotFound(f"Bluetooth is not available: {msg}")
    detail = str(exc).strip() or type(exc).__name__
    return DeviceNotFound("Bluetooth is not available "
                          f"(no adapter or no Bluetooth service: {detail})")


async def find_ble(timeout: float, name: str = "", service_uuid: str = "",
                   backend: type | None = None) -> list[tuple[Any, Any]]:
    """Scan for ``timeout`` s; (BLEDevice, AdvertisementData) pairs matching the filters,
    strongest signal first. ``name`` matches a prefix of the advertised or OS name
    (case-insensitive); ``service_uuid`` must be advertised. Raises DeviceNotFound when
    there is no adapter."""
    from bleak import BleakScanner
    from bleak.exc import BleakError

    kwargs: dict[str, Any] = {}
    if service_uuid:
        kwargs["service_uuids"] = [service_uuid]
    if backend is not None:
        kwargs["backend"] = backend
    try:
        found = await BleakScanner.discover(timeout=timeout, return_adv=True, **kwargs)
    except (BleakError, OSError) as exc:
        raise bluetooth_unavailable(exc) from None
    wanted = name.lower()
    out = []
    for dev, adv in found.values():
        label = (adv.local_name or dev.name or "").lower()
        if wanted and not label.startswith(wanted):
            continue
        if service_uuid and service_uuid.lower() not in [u.lower() for u in adv.service_uuids]:
            continue
        out.append((dev, adv))
    out.sort(key=lambda pair: -pair[1].rssi)
    return out


def run_coroutine(coro: Any) -> Any:
    """Run ``coro`` to completion on a fresh event loop in a helper thread, so it works
    whether or not the caller's thread already runs an asyncio loop."""
    result: dict[str, Any] = {}

    def target() -> None:
        try:
            result["value"] = asyncio.run(coro)
        except BaseException as exc:  # handed back to the caller's thread
            result["error"] = exc

    thread = threading.Thread(target=target, name="ble-scan", daemon=True)
    thread.start()
    thread.join()
    if "error" in result:
        raise result["error"]
    return result["value"]


def scan_ble(timeout: float = 5.0, name: str = "", service_uuid: str = "", *,
             backend: type | None = None) -> list[tuple[str, str, int]]:
    """BLE peripherals found in ``timeout`` s: (address, name, rssi), strongest first.

    ``backend`` is a test seam (a bleak ``BaseBleakScanner`` subclass), not for users.
    """
    pairs = run_coroutine(find_ble(timeout, name, service_uuid, backend))
    return [(dev.address, adv.local_name or dev.name or "", int(adv.rssi)) for dev, adv in pairs]
