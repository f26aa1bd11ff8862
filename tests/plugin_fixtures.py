"""A tiny third-party-style device plugin for engine tests, written only against the
public contract (what an outside author would write), with controllable failures."""

from __future__ import annotations

import threading

import numpy as np

from tactile_studio.devices.contract import DevicePlugin, FrameBatch, Setting
from tactile_studio.errors import DeviceLost, DeviceNotFound
from tactile_studio.sensor.layout import Layout, grid_layout

LAYOUT = grid_layout(2, 2, "grid-2x2")


class CountingDevice(DevicePlugin):
    """Emits frames whose every channel equals the sequence number."""

    name = "counting"
    description = "test source"
    supports_reconnect = True
    settings_schema = (
        Setting("frames", "int", 1000, "frames before finishing (0 = endless)", minimum=0),
        Setting("skip_every", "int", 0, "drop one sequence number every N frames", minimum=0),
        Setting("malformed_every", "int", 0, "report one malformed line every N frames"),
        Setting("crash_at", "int", -1, "raise a programming error at this frame"),
        Setting("fail_open", "bool", False, "open() fails"),
    )

    def __init__(self, **settings):
        super().__init__(**settings)
        self.seq = 0
        self.sent = 0
        self.lose = threading.Event()
        self.unplugged = threading.Event()
        self.open_calls = 0

    @property
    def layout(self) -> Layout:
        return LAYOUT

    @property
    def nominal_rate_hz(self) -> float:
        return 1000.0

    def open(self) -> None:
        self.open_calls += 1
        if self.settings["fail_open"] or self.unplugged.is_set():
            raise DeviceNotFound("counting: port /dev/nothing not found")

    def close(self) -> None:
        pass

    @property
    def finished(self) -> bool:
        return 0 < self.settings["frames"] <= self.sent

    def read(self, max_frames: int) -> FrameBatch:
        if self.lose.is_set():
            self.lose.clear()
            self.unplugged.set()
            raise DeviceLost("counting: device unplugged")
        n = min(max_frames, 16)
        if self.settings["frames"]:
            n = min(n, self.settings["frames"] - self.sent)
        seqs = []
        malformed = 0
        for _ in range(n):
            if self.settings["crash_at"] == self.sent:
                raise ZeroDivisionError("bug in plugin")
            if (self.settings["skip_every"] and self.seq
                    and self.seq % self.settings["skip_every"] == 0):
                self.seq += 1
            if (self.settings["malformed_every"]
                    and self.sent % self.settings["malformed_every"] == 0):
                malformed += 1
            seqs.append(self.seq)
            self.seq += 1
            self.sent += 1
        seq = np.array(seqs, dtype=np.int64)
        raw = np.repeat(seq[:, None], LAYOUT.n_channels, axis=1).astype(np.float32)
        return FrameBatch(raw=raw, device_time=seq / 1000.0, seq=seq,
                          malformed={"short": malformed} if malformed else {})
