"""The ``ble`` device: the sensor over Bluetooth Low Energy (bleak).

bleak is asyncio; the engine and the GUI are not. The plugin runs its own event loop
in its own thread: the notification callback only timestamps each notification and
puts it on a thread-safe queue; ``read`` (the engine thread) takes from the queue for
at most ~0.1 s and reassembles frames (payload: :mod:`tactile_studio.devices.ble_payload`).
A disconnect puts a marker on the queue: ``read`` returns what came before it, then
raises ``DeviceLost``; the engine calls ``reopen()`` with backoff and records the gap.

Test seam (not a user setting): pass ``bleak_backends=(ClientBackend, ScannerBackend)``
to the constructor, or set the module-level :data:`TEST_BACKENDS`, with subclasses of
bleak's ``BaseBleakClient`` / ``BaseBleakScanner``. They go to bleak's own ``backend=``
arguments, so the real ``BleakClient`` / ``BleakScanner`` code runs on top of them.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import queue
import threading
import time
from collections import Counter
from collections.abc import Mapping
from typing import Any

import numpy as np

from tactile_studio.devices.ble_payload import Reassembler
from tactile_studio.devices.contract import DevicePlugin, FrameBatch, Setting, layout_setting
from tactile_studio.devices.discovery import bluetooth_unavailable, find_ble, scan_ble
from tactile_studio.errors import DeviceError, DeviceLost, DeviceNotFound, SettingsError
from tactile_studio.sensor.layout import Layout

SERVICE_UUID = "f0e1c000-7a57-4c1e-8d5e-5a5e0000c0de"
FRAME_CHAR_UUID = "f0e1c001-7a57-4c1e-8d5e-5a5e0000c0de"
TEST_BACKENDS: tuple[type, type] | None = None
"""Test seam: (BaseBleakClient subclass, BaseBleakScanner subclass) used when set."""

_LOST = object()  # queue marker: the link went down
READ_WAIT_S = 0.1


class BleDevice(DevicePlugin):
    name = "ble"
    description = "Sensor over Bluetooth LE: frames in notifications (see docs/devices.md)"
    supports_reconnect = True
    settings_schema = (
        Setting("address", "str", "", "device address (macOS: its UUID); empty: scan and "
                "take the strongest match (`tactile-studio ble-scan` lists them)"),
        Setting("name", "str", "ShearSense", "when scanning: name prefix to match (empty: any)"),
        Setting("service_uuid", "str", SERVICE_UUID, "when scanning: advertised service "
                "UUID to match (empty: any)"),
        Setting("char_uuid", "str", FRAME_CHAR_UUID, "notify characteristic carrying frames"),
        Setting("scan_timeout", "float", 5.0, "seconds to scan", minimum=0.1, maximum=120.0),
        Setting("connect_timeout", "float", 5.0, "seconds to connect", minimum=0.5,
                maximum=120.0),
        Setting("layout", "str", "shearsense-6x6", "sensor layout (channel count and order)"),
        Setting("rate", "float", 43.0, "nominal frame rate in Hz (the real one is measured)",
                minimum=0.1, maximum=10000.0),
    )

    def __init__(self, *, bleak_backends: tuple[type, type] | None = None,
                 **settings: Any) -> None:
        super().__init__(**settings)
        from bleak.uuids import normalize_uuid_str

        for key in ("service_uuid", "char_uuid"):
            value = self.settings[key].strip()
            if value or key == "char_uuid":
                try:
                    self.settings[key] = normalize_uuid_str(value)
                except (ValueError, TypeError, AttributeError):
                    raise SettingsError(f"device ble: setting {key}: {value!r} is not a "
                                        "UUID") from None
        self._layout = layout_setting("ble", self.settings["layout"])
        self._backends = bleak_backends or TEST_BACKENDS or (None, None)
        self.reassembler = Reassembler(self._layout.n_channels)
        self._queue: queue.Queue[Any] = queue.Queue()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._client: Any = None
        self._address = ""
        self._lost: str | None = None
        self._reported: Counter[str] = Counter()

    supports_discover = True
    discover_setting = "address"
    discover_instant = False  # a radio scan listens for scan_timeout seconds

    @classmethod
    def discover(cls, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """(address, label) choices for the ``address`` setting, strongest first: scans
        for ``scan_timeout`` s with the ``name`` and ``service_uuid`` filters; raises
        DeviceNotFound without an adapter."""
        backend = TEST_BACKENDS[1] if TEST_BACKENDS else None
        found = scan_ble(settings["scan_timeout"], settings["name"], settings["service_uuid"],
                         backend=backend)
        return [(addr, f"{label or '?'} {addr} ({rssi} dBm)") for addr, label, rssi in found]

    @property
    def layout(self) -> Layout:
        return self._layout

    @property
    def nominal_rate_hz(self) -> float:
        return float(self.settings["rate"])

    @property
    def address(self) -> str:
        """The peripheral connected to (or last connected to)."""
        return self._address or self.settings["address"]

    # ---- the event-loop thread -------------------------------------------------------
    def _ensure_loop(self) -> asyncio.AbstractEventLoop:
        if self._loop is None:
            loop = asyncio.new_event_loop()
            self._thread = threading.Thread(target=loop.run_forever, name="ble-loop",
                                             daemon=True)
            self._thread.start()
            self._loop = loop
        return self._loop

    def _run(self, coro: Any, timeout: float) -> Any:
        future = asyncio.run_coroutine_threadsafe(coro, self._ensure_loop())
        try:
            return future.result(timeout)
        except concurrent.futures.TimeoutError:
            future.cancel()
            raise DeviceNotFound(f"ble {self.address or self.settings['name']}: no answer "
                                 f"within {timeout:g} s") from None

    # ---- connection ------------------------------------------------------------------
    def open(self) -> None:
        s = self.settings
        self._run(self._connect(), s["scan_timeout"] + s["connect_timeout"] + 2.0)
        self._lost = None

    async def _connect(self) -> None:
        from bleak import BleakClient
        from bleak.exc import BleakBluetoothNotAvailableError, BleakCharacteristicNotFoundError

        s = self.settings
        client_backend, scanner_backend = self._backends
        target: Any = self._address or s["address"].strip()
        if not target:
            found = await find_ble(s["scan_timeout"], s["name"], s["service_uuid"],
                                   scanner_backend)
            if not found:
                what = " ".join(f for f in (
                    f"named {s['name']}*" if s["name"] else "",
                    f"advertising {s['service_uuid']}" if s["service_uuid"] else "") if f)
                raise DeviceNotFound(f"ble: no device {what or 'at all'} found in "
                                     f"{s['scan_timeout']:g} s")
            target = found[0][0]
        label = getattr(target, "address", target)
        kwargs = {"backend": client_backend} if client_backend is not None else {}
        try:
            client = BleakClient(target, disconnected_callback=self._on_disconnect,
                                 timeout=s["connect_timeout"], **kwargs)
            await asyncio.wait_for(client.connect(), s["connect_timeout"])
        except (BleakBluetoothNotAvailableError, FileNotFoundError, ConnectionRefusedError,
                PermissionError) as exc:  # no adapter, or no Bluetooth service (D-Bus)
            raise bluetooth_unavailable(exc) from None
        except asyncio.TimeoutError:
            raise DeviceNotFound(f"ble {label}: no connection within "
                                 f"{s['connect_timeout']:g} s") from None
        except Exception as exc:
            raise DeviceNotFound(f"ble {label}: cannot connect ({_one_line(exc)})") from None
        try:
            await client.start_notify(s["char_uuid"], self._on_notify)
        except BleakCharacteristicNotFoundError:
            await _quietly(client.disconnect())
            raise DeviceNotFound(f"ble {label}: no characteristic {s['char_uuid']} (not a "
                                 "tactile sensor, or set char_uuid)") from None
        except Exception as exc:
            await _quietly(client.disconnect())
            raise DeviceNotFound(f"ble {label}: cannot subscribe ({_one_line(exc)})") from None
        self._client, self._address = client, client.address

    def _on_notify(self, _char: Any, data: bytearray) -> None:
        self._queue.put((time.time(), bytes(data)))

    def _on_disconnect(self, client: Any) -> None:
        if client is self._client:
            self._queue.put(_LOST)

    def _drop_client(self) -> None:
        client, self._client = self._client, None
        if client is not None and self._loop is not None:
            try:
                self._run(_quietly(client.disconnect()), 3.0)
            except DeviceError:
                pass

    def reopen(self) -> None:
        """One reconnection attempt to the same peripheral (the engine drives backoff)."""
        self._drop_client()
        self._queue = queue.Queue()
        self.reassembler.new_connection()
        self.open()

    def close(self) -> None:
        self._drop_client()
        loop, thread = self._loop, self._thread
        self._loop = self._thread = None
        if loop is not None:
            loop.call_soon_threadsafe(loop.stop)
            if thread is not None:
                thread.join(2.0)
            if not loop.is_running():
                loop.close()

    # ---- reading ---------------------------------------------------------------------
    def read(self, max_frames: int) -> FrameBatch:
        if self._lost is not None:
            raise DeviceLost(self._lost)
        if self._client is None:
            raise DeviceLost("ble: not connected")
        raws: list[np.ndarray] = []
        seqs: list[int] = []
        times: list[float] = []
        deadline = time.monotonic() + READ_WAIT_S
        while len(raws) < max_frames:
            try:
                if raws:
                    item = self._queue.get_nowait()
                else:
                    item = self._queue.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            if item is _LOST:
                self._lost = f"ble {self.address}: disconnected"
                break
            stamp, packet = item
            done = self.reassembler.feed(packet)
            if done is not None:
                seqs.append(done[0])
                raws.append(done[1])
                times.append(stamp)
        bad = self.reassembler.bad - self._reported
        self._reported = Counter(self.reassembler.bad)
        if not raws and self._lost is not None and not bad:
            raise DeviceLost(self._lost)
        n = self._layout.n_channels
        raw = np.stack(raws) if raws else np.empty((0, n), dtype=np.uint16)
        return FrameBatch(raw=raw.astype(self._layout.raw_dtype, copy=False),
                          seq=np.asarray(seqs, dtype=np.int64),
                          host_time=np.asarray(times, dtype=np.float64), malformed=dict(bad))

    def info(self) -> dict[str, Any]:
        out = super().info()
        out["address"] = self.address
        return out


async def _quietly(coro: Any) -> None:
    try:
        await coro
    except Exception:
        pass


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
