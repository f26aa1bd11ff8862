"""Finding real devices: serial ports and BLE peripherals. Qt-free, for the CLI and the UI.

Both functions block (the BLE scan for ``timeout`` seconds): the UI calls them from a
worker, never from its event loop.
"""

from __future__ import annotations

import asyncio
import threading
from typing import Any

from tactile_studio.errors import DeviceNotFound


def list_serial_ports() -> list[tuple[str, str, str]]:
    """Every serial port the OS knows: (device, description, "VID:PID" or "")."""
    from serial.tools import list_ports

    found = []
    for p in sorted(list_ports.comports(), key=lambda p: p.device):
        vid_pid = f"{p.vid:04X}:{p.pid:04X}" if p.vid is not None and p.pid is not None else ""
        desc = p.description if p.description and p.description != "n/a" else ""
        found.append((p.device, desc, vid_pid))
    return found


def bluetooth_unavailable(exc: BaseException) -> DeviceNotFound:
    """A one-line error for an absent adapter or Bluetooth stack (bleak and OS errors)."""
    from bleak.exc import BleakBluetoothNotAvailableError

    if isinstance(exc, BleakBluetoothNotAvailableError):
        msg = str(exc.args[0]) if exc.args else "unknown reason"
        return DeviceNotFound(f"Bluetooth is not available: {msg}")
    detail = str(exc).strip() or type(exc).__name__
    return DeviceNotFound(f"Bluetooth is not available (no adapter or no Bluetooth service: {detail})")


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
