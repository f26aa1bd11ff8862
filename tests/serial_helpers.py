"""Shared by the serial tests (waiting itself is ``waiting.wait_until``)."""

from __future__ import annotations

from collections.abc import Callable


def received_all(engine, emulator) -> Callable[[], bool]:
    """True once the engine has seen every line the emulator finished writing."""
    def cond() -> bool:
        rep, got = emulator.report(), engine.counters()
        return got["frames"] == rep["good"] and got["malformed"] == rep["malformed"]
    return cond
