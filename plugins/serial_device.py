"""The ``serial`` device: the sensor's USB receiver, one ASCII line of counts per frame.

Bytes are decoded by :class:`~tactile_studio.devices.line_decoder.LineDecoder`: good
lines become frames, every other line is dropped and counted by kind in the batch's
``malformed``. Frames carry host receive times (the receiver sends no clock).

Losing the port (a read error, or the port path vanishing while silent) is noticed
within ~0.15 s: ``read`` first returns what it already decoded, then raises
``DeviceLost``; the engine calls ``reopen()`` with backoff until the same port is back.
If nothing decodes at all after opening (many lines or bytes and not one good frame),
``read`` raises ``BadData``: almost always a wrong baud rate.
"""

from __future__ import annotations

import errno
import os
import time
from collections import Counter
from collections.abc import Mapping
from typing import Any

import numpy as np

from tactile_studio.devices.contract import DevicePlugin, FrameBatch, Setting, layout_setting
from tactile_studio.devices.discovery import (
    describe_serial_ports,
    list_serial_ports,
    pick_serial_port,
)
from tactile_studio.devices.line_decoder import LineDecoder
from tactile_studio.errors import BadData, DeviceLost, DeviceNotFound, SettingsError
from tactile_studio.sensor.layout import Layout

READ_TIMEOUT_S = 0.05     # one pyserial wait; read() returns within ~2 of these
BAD_START_LINES = 100     # this many bad lines after opening and no good one: BadData
BAD_START_BYTES = 256 * 1024


def _describe_ports() -> str:
    return describe_serial_ports(list_serial_ports())


class SerialDevice(DevicePlugin):
    name = "serial"
    description = "Sensor receiver on a serial port (ASCII lines of counts, 500000 baud)"
    supports_reconnect = True
    settings_schema = (
        Setting("port", "str", "", "serial port, e.g. /dev/ttyUSB0 or COM3; empty: the only "
                "USB serial device there is (`tactile-studio ports` lists them)"),
        Setting("baud", "int", 500000, "baud rate", minimum=50, maximum=12_000_000),
        Setting("layout", "str", "shearsense-6x6", "sensor layout (channel count and order)"),
        Setting("channels", "int", 0, "values per line; 0: the layout's channel count",
                minimum=0, maximum=65536),
        Setting("rate", "float", 44.0, "nominal frame rate in Hz (the real one is measured)",
                minimum=0.1, maximum=100000.0),
    )

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        where = f"serial (port {self.settings['port']})" if self.settings["port"] else "serial"
        self._layout = layout_setting(where, self.settings["layout"])
        channels = self.settings["channels"] or self._layout.n_channels
        if channels != self._layout.n_channels:
            raise SettingsError(f"device {where}: channels={channels} but layout "
                                f"{self._layout.name} has {self._layout.n_channels} channels")
        max_value = int(self._layout.raw_max)
        self.decoder = LineDecoder(channels, max_value, self._layout.raw_dtype)
        self._ser: Any = None
        self._port = ""
        self._lost: str | None = None
        self._carry: Counter[str] = Counter()  # malformed counted after the last batch
        self._backlog: list[tuple[np.ndarray, np.ndarray]] = []
        self._good_since_open = 0
        self._bad_since_open = 0
        self._bytes_since_open = 0

    supports_discover = True
    discover_setting = "port"
    discover_instant = True

    @classmethod
    def discover(cls, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """(port, label) choices for the ``port`` setting: every port the OS lists."""
        return [(dev, " ".join(x for x in (dev, desc, f"[{vp}]" if vp else "") if x))
                for dev, desc, vp in list_serial_ports()]

    @property
    def layout(self) -> Layout:
        return self._layout

    @property
    def nominal_rate_hz(self) -> float:
        return float(self.settings["rate"])

    @property
    def port(self) -> str:
        """The port actually opened (the setting, or the one found when it was empty)."""
        return self._port or self.settings["port"]

    # ---- connection ------------------------------------------------------------------
    def _resolve_port(self) -> str:
        port = self.settings["port"].strip()
        if port:
            return port
        return pick_serial_port(list_serial_ports())

    def open(self) -> None:
        import serial

        port = self._port or self._resolve_port()
        baud = self.settings["baud"]
        if port.startswith("/") and not os.path.exists(port):
            raise DeviceNotFound(f"serial port {port}: not found ({_describe_ports()})")
        try:
            self._ser = serial.Serial(port, baud, timeout=READ_TIMEOUT_S, exclusive=True)
        except ValueError as exc:
            raise SettingsError(f"serial port {port}: baud rate {baud} refused ({exc})") from None
        except (serial.SerialException, OSError) as exc:
            raise DeviceNotFound(self._open_error(port, exc)) from None
        self._port = port
        self._lost = None
        self._good_since_open = self._bad_since_open = self._bytes_since_open = 0

    @staticmethod
    def _open_error(port: str, exc: BaseException) -> str:
        code = getattr(exc, "errno", None)
        if code == errno.ENOENT:
            return f"serial port {port}: not found ({_describe_ports()})"
        if code in (errno.EACCES, errno.EPERM):
            return f"serial port {port}: permission denied (on Linux join the 'dialout' group)"
        if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "lock" in str(exc).lower():
            return f"serial port {port}: busy, another program has it open"
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return f"serial port {port}: cannot open ({text})"

    def close(self) -> None:
        ser, self._ser = self._ser, None
        if ser is not None:
            try:
                ser.close()
            except Exception:
                pass
        self.decoder.reset()
        self._backlog.clear()

    def reopen(self) -> None:
        """Reopen the same port; the partial line of the lost connection is already
        counted, so the new stream starts clean."""
        self.close()
        self.open()

    # ---- reading ---------------------------------------------------------------------
    def read(self, max_frames: int) -> FrameBatch:
        if self._ser is None and self._lost is None:
            raise DeviceLost(f"serial port {self.port}: not open")
        parts, times = self._take_backlog(max_frames)
        bad = self._carry
        self._carry = Counter()
        deadline = time.monotonic() + 2 * READ_TIMEOUT_S
        while not parts and self._lost is None:
            data = self._read_bytes()
            if data:
                now = time.time()
                dec = self.decoder.feed(data)
                self._account(len(data), len(dec), dec.malformed)
                bad.update(dec.malformed)
                if len(dec):
                    parts.append(dec.frames)
                    times.append(np.full(len(dec), now))
            if time.monotonic() >= deadline:
                break
        if self._lost is not None and not parts and not bad:
            raise DeviceLost(self._lost)
        return self._batch(parts, times, bad, max_frames)

    def _read_bytes(self) -> bytes:
        """Whatever is available (waiting up to READ_TIMEOUT_S); notes a lost port."""
        import serial

        ser = self._ser
        try:
            data = ser.read(ser.in_waiting or 1)
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            self._mark_lost(f"read failed: {exc}")
            return b""
        if not data and self._port.startswith("/") and not os.path.exists(self._port):
            self._mark_lost("the port vanished")
        return data

    def _mark_lost(self, why: str) -> None:
        """Count the cut last line, close, and let the next read raise DeviceLost."""
        dec = self.decoder.flush()
        self._carry.update(dec.malformed)
        if len(dec):
            self._backlog.append((dec.frames, np.full(len(dec), time.time())))
        if self._ser is not None:
            try:
                self._ser.close()
            except Exception:
                pass
            self._ser = None
        self._lost = f"serial port {self.port} lost: {why}"

    def _account(self, nbytes: int, good: int, bad: Counter) -> None:
        """Raise BadData when nothing at all decodes after opening (wrong baud rate)."""
        if self._good_since_open:
            return
        self._good_since_open += good
        self._bad_since_open += sum(bad.values())
        self._bytes_since_open += nbytes
        if not self._good_since_open and (self._bad_since_open >= BAD_START_LINES
                                          or self._bytes_since_open >= BAD_START_BYTES):
            raise BadData(
                f"serial port {self.port}: {self._bad_since_open} lines "
                f"({self._bytes_since_open} bytes) and not one valid frame at "
                f"{self.settings['baud']} baud: wrong baud rate, or not a tactile receiver?")

    def _take_backlog(self, max_frames: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
        if not self._backlog:
            return [], []
        raw = np.concatenate([r for r, _ in self._backlog])
        host = np.concatenate([t for _, t in self._backlog])
        self._backlog = [(raw[max_frames:], host[max_frames:])] if len(raw) > max_frames else []
        return [raw[:max_frames]], [host[:max_frames]]

    def _batch(self, parts: list[np.ndarray], times: list[np.ndarray], bad: Counter,
               max_frames: int) -> FrameBatch:
        if parts:
            raw, host = np.concatenate(parts), np.concatenate(times)
        else:
            raw = np.empty((0, self.decoder.n_channels), dtype=self._layout.raw_dtype)
            host = np.empty(0)
        if len(raw) > max_frames:
            self._backlog.insert(0, (raw[max_frames:], host[max_frames:]))
            raw, host = raw[:max_frames], host[:max_frames]
        return FrameBatch(raw=raw, host_time=host, malformed=dict(bad))

    def info(self) -> dict[str, Any]:
        out = super().info()
        out["port"] = self.port
        return out
