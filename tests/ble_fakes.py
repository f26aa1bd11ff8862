"""An in-process fake BLE radio: bleak backends that talk to scripted peripherals.

Only the radio edge is fake. The plugin uses the real ``BleakClient`` and
``BleakScanner``; these classes sit under them through bleak's ``backend=`` seam, the
way a platform backend (BlueZ, CoreBluetooth, WinRT) would.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
from bleak.backends.characteristic import BleakGATTCharacteristic
from bleak.backends.client import BaseBleakClient
from bleak.backends.device import BLEDevice
from bleak.backends.scanner import AdvertisementData, BaseBleakScanner
from bleak.backends.service import BleakGATTService, BleakGATTServiceCollection
from bleak.exc import (
    BleakBluetoothNotAvailableError,
    BleakBluetoothNotAvailableReason,
    BleakDeviceNotFoundError,
    BleakError,
)

from tactile_studio.devices.ble_payload import encode_packets
from tactile_studio.plugins.ble_device import FRAME_CHAR_UUID, SERVICE_UUID

RADIO: dict[str, FakePeripheral] = {}
"""Peripherals in range, by address. Tests add and remove them."""


class FakePeripheral:
    """A sensor in range: advertises, accepts one connection, sends notifications."""

    def __init__(self, address: str = "AA:BB:CC:00:00:01", name: str = "ShearSense-01",
                 rssi: int = -50, services: tuple[str, ...] = (SERVICE_UUID,),
                 char_uuid: str = FRAME_CHAR_UUID, mtu: int = 23) -> None:
        self.address, self.name, self.rssi = address, name, rssi
        self.services, self.char_uuid, self.mtu = services, char_uuid, mtu
        self.available = True  # False: connect attempts fail (out of range)
        self.connects = 0
        self.subscribed = threading.Event()
        self._client: FakeClient | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._callback: Callable[[bytearray], None] | None = None

    def install(self) -> FakePeripheral:
        RADIO[self.address] = self
        return self

    # called by FakeClient in the plugin's event loop
    def attach(self, client: FakeClient, loop: asyncio.AbstractEventLoop) -> None:
        self._client, self._loop = client, loop
        self.connects += 1

    def subscribe(self, callback: Callable[[bytearray], None]) -> None:
        self._callback = callback
        self.subscribed.set()

    def detach(self) -> None:
        self._client, self._callback = None, None
        self.subscribed.clear()

    # called by tests, from the test thread
    def notify(self, packet: bytes) -> None:
        """One notification, delivered in the plugin's event loop as a radio would."""
        loop, callback = self._loop, self._callback
        if loop is None or callback is None:
            raise RuntimeError("no subscriber")
        loop.call_soon_threadsafe(callback, bytearray(packet))

    def send_frame(self, seq: int, values: np.ndarray, drop: tuple[int, ...] = ()) -> int:
        """All fragments of one frame at this MTU, minus the indices in ``drop``."""
        packets = encode_packets(seq, values, self.mtu)
        for i, packet in enumerate(packets):
            if i not in drop:
                self.notify(packet)
        return len(packets)

    def drop_link(self) -> None:
        """The peripheral goes away: the client sees an unsolicited disconnect."""
        client, loop = self._client, self._loop
        if client is None or loop is None:
            return

        def gone() -> None:
            client._connected = False
            self.detach()
            if client._disconnected_callback is not None:
                client._disconnected_callback()

        loop.call_soon_threadsafe(gone)


class FakeClient(BaseBleakClient):
    """bleak client backend that reaches :data:`RADIO` instead of an adapter."""

    def __init__(self, address_or_ble_device: BLEDevice | str, **kwargs: Any) -> None:
        super().__init__(address_or_ble_device, disconnected_callback=kwargs.get(
            "disconnected_callback"), timeout=kwargs.get("timeout", 10.0))
        self._connected = False
        self._peripheral: FakePeripheral | None = None

    @property
    def name(self) -> str:
        return self._peripheral.name if self._peripheral else ""

    @property
    def mtu_size(self) -> int:
        return self._peripheral.mtu if self._peripheral else 23

    @property
    def is_connected(self) -> bool:
        return self._connected

    async def connect(self, pair: bool, **kwargs: Any) -> None:
        await asyncio.sleep(0)
        per = RADIO.get(self.address)
        if per is None or not per.available:
            raise BleakDeviceNotFoundError(self.address, f"Device {self.address} not found")
        services = BleakGATTServiceCollection()
        for n, uuid in enumerate(per.services):
            service = BleakGATTService(None, 10 * n + 1, uuid)
            services.add_service(service)
            if n == 0:
                services.add_characteristic(BleakGATTCharacteristic(
                    None, 10 * n + 2, per.char_uuid, ["notify"], lambda: per.mtu - 3, service))
        self.services = services
        self._peripheral = per
        self._connected = True
        per.attach(self, asyncio.get_running_loop())

    async def disconnect(self) -> None:
        if self._connected and self._peripheral is not None:
            self._peripheral.detach()
        self._connected = False

    async def pair(self, *args: Any, **kwargs: Any) -> None:
        pass

    async def unpair(self) -> None:
        pass

    async def read_gatt_char(self, characteristic: Any, **kwargs: Any) -> bytearray:
        raise BleakError("not readable")

    async def read_gatt_descriptor(self, descriptor: Any, **kwargs: Any) -> bytearray:
        raise BleakError("not readable")

    async def write_gatt_char(self, characteristic: Any, data: Any, response: bool) -> None:
        raise BleakError("not writable")

    async def write_gatt_descriptor(self, descriptor: Any, data: Any) -> None:
        raise BleakError("not writable")

    async def start_notify(self, characteristic: BleakGATTCharacteristic,
                           callback: Callable[[bytearray], None], **kwargs: Any) -> None:
        if not self._connected or self._peripheral is None:
            raise BleakError("Not connected")
        self._peripheral.subscribe(callback)

    async def stop_notify(self, characteristic: BleakGATTCharacteristic) -> None:
        if self._peripheral is not None:
            self._peripheral.detach()


class FakeScanner(BaseBleakScanner):
    """bleak scanner backend: every available peripheral in :data:`RADIO` advertises."""

    def __init__(self, detection_callback: Any, service_uuids: Any, scanning_mode: str = "active",
                 **kwargs: Any) -> None:
        super().__init__(detection_callback, service_uuids)

    async def start(self) -> None:
        self.seen_devices = {}
        for per in list(RADIO.values()):
            if not per.available:
                continue
            adv = AdvertisementData(local_name=per.name, manufacturer_data={}, service_data={},
                                    service_uuids=list(per.services), tx_power=None,
                                    rssi=per.rssi, platform_data=())
            if not self.is_allowed_uuid(adv.service_uuids):
                continue
            device = self.create_or_update_device(per.address, per.address, per.name, None, adv)
            self.call_detection_callbacks(device, adv)

    async def stop(self) -> None:
        pass


class NoAdapterScanner(FakeScanner):
    """A machine without a Bluetooth adapter, as bleak reports it."""

    async def start(self) -> None:
        raise BleakBluetoothNotAvailableError("no Bluetooth adapters found",
                                              BleakBluetoothNotAvailableReason.NO_BLUETOOTH)


class NoAdapterClient(FakeClient):
    async def connect(self, pair: bool, **kwargs: Any) -> None:
        raise BleakBluetoothNotAvailableError("no Bluetooth adapters found",
                                              BleakBluetoothNotAvailableReason.NO_BLUETOOTH)


BACKENDS = (FakeClient, FakeScanner)
