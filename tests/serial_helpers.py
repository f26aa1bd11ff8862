"""Shared by the serial tests: waiting for conditions (never for fixed times)."""

from __future__ import annotations

import time
from collections.abc import Callable


def wait_until(cond: Callable[[], bool], timeout: float = 15.0, step: float = 0.01) -> bool:
    """Poll ``cond`` until true or ``timeout`` (generous: a slow CI is not a failure)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(step)
    return bool(cond())


def received_all(engine, emulator) -> Callable[[], bool]:
    """True once the engine has seen every line the emulator finished writing."""
    def cond() -> bool:
        rep, got = emulator.report(), engine.counters()
        return got["frames"] == rep["good"] and got["malformed"] == rep["malformed"]
    return cond
