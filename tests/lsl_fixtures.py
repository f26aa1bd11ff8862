"""Helpers for the LSL tests: real liblsl on the loopback (conftest.py points LSLAPICFG at
tests/lsl_api.cfg), unique stream names, and inlets read in a background thread with
every wait bounded."""

from __future__ import annotations

import threading
import time
import uuid
from typing import Any

import numpy as np
import pylsl

WAIT_S = 10.0  # a safety net for a hung stream, never a timing assertion


def unique(prefix: str) -> str:
    return f"{prefix}-{uuid.uuid4().hex[:8]}"


def resolve(predicate: str, timeout: float = WAIT_S) -> Any:
    found = pylsl.resolve_bypred(predicate, 1, timeout)
    assert found, f"no LSL stream matching {predicate} within {timeout} s"
    return found[0]


class Collector:
    """An inlet on the first stream matching ``predicate``, pulled in a thread until
    ``stop()`` (the stream is looked up in the thread, so it may appear later).
    ``wait_s``: how long it may take to appear, for a stream a whole program starts (a
    bound, never a measurement: waiting ends when the stream is there)."""

    def __init__(self, predicate: str, wait_s: float = WAIT_S) -> None:
        self.predicate = predicate
        self.wait_s = wait_s
        self.samples: list[Any] = []
        self.stamps: list[float] = []
        self.info: Any = None
        self.connected = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        deadline = time.monotonic() + self.wait_s
        found: list[Any] = []
        while not found and not self._stop.is_set() and time.monotonic() < deadline:
            found = pylsl.resolve_bypred(self.predicate, 1, 1.0)
        if not found:
            return
        inlet = pylsl.StreamInlet(found[0], max_buflen=60)
        self.info = inlet.info(self.wait_s)
        inlet.open_stream(self.wait_s)
        self.connected.set()
        while not self._stop.is_set():
            self._pull(inlet)
        self._pull(inlet)

    def _pull(self, inlet: Any) -> None:
        data, stamps = inlet.pull_chunk(timeout=0.05, max_samples=4096)
        self.samples.extend(data)
        self.stamps.extend(stamps)

    def wait_connected(self) -> None:
        assert self.connected.wait(self.wait_s), f"no inlet on {self.predicate}"

    def wait_count(self, n: int) -> None:
        deadline = time.monotonic() + WAIT_S
        while len(self.stamps) < n and time.monotonic() < deadline:
            time.sleep(0.02)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(WAIT_S)

    def array(self, dtype: Any = None) -> np.ndarray:
        return np.asarray(self.samples, dtype=dtype)


def desc_channels(info: Any) -> list[dict[str, str]]:
    """The ``desc/channels/channel`` entries of a full stream info."""
    out = []
    ch = info.desc().child("channels").child("channel")
    while not ch.empty():
        out.append({k: ch.child_value(k) for k in ("label", "type", "unit", "taxel", "row",
                                                   "col")})
        ch = ch.next_sibling("channel")
    return out
