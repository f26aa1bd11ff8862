"""A serial load cell (amplifier board / HX711 bridge) on a pty: ASCII lines of force
values at a fixed rate, for testing the ``serial`` force plugin without hardware.

``source(t)`` gives (fx, fy, fz) in raw units at host time ``t``; ``axes`` "z" sends one
value per line, "xyz" three. :meth:`set_mode`: "ok", "garbage" (lines that are not
numbers) or "silent" (nothing); :meth:`unplug` is a pulled cable.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from tactile_studio.devices.pty_port import PtyPort
from tactile_studio.instruments.pty_emulator import PtyEmulator

MODES = ("ok", "garbage", "silent")


class LoadCellEmulator(PtyEmulator):
    thread_name = "loadcell-emulator"

    def __init__(self, source: Callable[[float], tuple[float, float, float]] | None = None,
                 rate_hz: float = 100.0, axes: str = "xyz", link: str | None = None,
                 offset: tuple[float, float, float] = (0.0, 0.0, 0.0), noise: float = 0.0,
                 seed: int = 0) -> None:
        self.pty = PtyPort(link)
        self.source = source or (lambda t: (0.0, 0.0, 0.0))
        self.rate_hz, self.axes = float(rate_hz), axes
        self.offset, self.noise = np.asarray(offset, float), float(noise)
        self.mode = "ok"
        self.sent = 0
        self._rng = np.random.default_rng(seed)
        self._init_thread()

    def set_mode(self, mode: str) -> None:
        if mode not in MODES:
            raise ValueError(f"unknown mode {mode!r} (known: {', '.join(MODES)})")
        self.mode = mode

    def line(self, t: float) -> bytes:
        f = np.asarray(self.source(t), float) + self.offset
        if self.noise:
            f = f + self._rng.normal(0.0, self.noise, 3)
        vals = f[2:] if self.axes == "z" else f
        return (",".join(f"{v:.5f}" for v in vals) + "\r\n").encode()

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        next_t = time.monotonic()
        while not self._stop.is_set():
            next_t += period
            time.sleep(max(0.0, next_t - time.monotonic()))
            if not self.pty.is_open or self.mode == "silent":
                continue
            data = self.line(time.time()) if self.mode == "ok" else b"ovf,#?,--\r\n"
            if self.pty.write(data):
                self.sent += 1
