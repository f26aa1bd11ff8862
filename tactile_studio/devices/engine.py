"""The acquisition engine: one thread drives a device plugin into a ring buffer.

Consumers never get pushed to; they pull (newest frame for the live view, everything
since a cursor for the recorder). The engine keeps the counters every report needs:
frames, malformed input by kind, device sequence gaps, reconnects, and an append-only
event list, the journal (connect, disconnect, reconnect, gap, tare, marker, error...: the
kinds are declared once in :mod:`tactile_studio.devices.engine_events`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

import numpy as np

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.devices.engine_events import (
    KINDS,
    Connected,
    ConnectionLost,
    DeviceFailed,
    Disconnected,
    EngineEvent,
    Finished,
    Reconnected,
    ReconnectGap,
    SequenceGap,
    Tared,
)
from tactile_studio.devices.frame_stream import (  # noqa: F401 (the states, named here too)
    CONNECTING,
    ERROR,
    FINISHED,
    IDLE,
    RECONNECTING,
    RUNNING,
    STOPPED,
    EngineState,
)
from tactile_studio.devices.ring import FrameChunk, RingBuffer
from tactile_studio.errors import DeviceError, DeviceLost
from tactile_studio.sensor.decode import compute_baseline

RECONNECT_BACKOFF_S = (0.1, 0.2, 0.5, 1.0, 2.0)


class AcquisitionEngine:
    """Runs ``device`` in a background thread; safe to query from any thread."""

    def __init__(self, device: DevicePlugin, capacity: int = 1 << 16,
                 baseline_frames: int = 100, read_chunk: int = 256) -> None:
        self.device = device
        self.layout = device.layout
        self.ring = RingBuffer(capacity, self.layout.n_channels, self.layout.raw_dtype)
        self.baseline_frames = baseline_frames
        self.read_chunk = read_chunk
        self.state = IDLE
        self.error: str | None = None
        self.malformed: Counter[str] = Counter()
        self.gaps = 0
        self.missing_frames = 0
        self.reconnects = 0
        self.reconnect_attempts = 0
        self.baseline: np.ndarray | None = None
        self._events: list[dict[str, Any]] = []  # the journal, in the file's form
        self._lost_reason: str | None = None  # why the device was last lost
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._tare_from: int | None = 0  # auto-tare on the first frames
        self._tare_n = baseline_frames
        self._last_seq: int | None = None
        self._holds: dict[object, tuple[Callable[[], int], int]] = {}

    # ---- lifecycle -------------------------------------------------------------------
    def start(self) -> None:
        """Open the device in the engine thread and start streaming."""
        if self._thread is not None:
            raise RuntimeError("engine already started")
        self.state = CONNECTING
        self._thread = threading.Thread(target=self._run, name="acquisition", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop streaming and close the device; idempotent."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
        if self.state not in (ERROR, FINISHED):
            self.state = STOPPED

    @property
    def running(self) -> bool:
        return EngineState(self.state).is_live

    # ---- the device, by public methods (consumers never reach into .device) ----------
    @property
    def nominal_rate_hz(self) -> float:
        """The device's nominal frame rate (0.0 if it has none)."""
        return float(self.device.nominal_rate_hz or 0.0)

    @property
    def device_name(self) -> str:
        """The device plugin's name (for messages)."""
        return str(self.device.name)

    def device_info(self) -> dict[str, Any]:
        """The device's description (plugin, settings, port...) for files and reports."""
        return self.device.info()

    def sensor_id(self) -> str | None:
        """The connected sensor's own ID (None if the device has no identity hook)."""
        return getattr(self.device, "sensor_id", lambda: None)()

    @property
    def capacity(self) -> int:
        """Frames the ring holds: how far back :meth:`read_since` can reach."""
        return self.ring.capacity

    def wait_frames(self, n: int, timeout: float = 10.0) -> bool:
        """Block until ``n`` frames have arrived (or the engine ended); True if they did."""
        deadline = time.monotonic() + timeout
        while self.ring.written < n and time.monotonic() < deadline:
            if not self.running and self.state != IDLE:
                break
            time.sleep(0.005)
        return self.ring.written >= n

    # ---- readers that may not lose frames -----------------------------------------------
    def hold(self, cursor: Callable[[], int], lead: int | None = None) -> Callable[[], None]:
        """Keep frames for a reader that may not lose any (a recorder, a health check):
        ``cursor()`` is the next frame it will read. A device that can wait for its
        reader (a file replayed or the simulator at speed 0) is read at most ``lead``
        frames (default: the ring) ahead of the slowest held cursor, so "as fast as
        possible" means as fast as the reader, not a lapped ring. A real-time device
        cannot wait: its frames still overrun a slow reader, which counts them.
        Returns the function that releases the hold."""
        key = object()
        with self._lock:
            self._holds[key] = (cursor, min(self.ring.capacity, lead or self.ring.capacity))

        def release() -> None:
            with self._lock:
                self._holds.pop(key, None)
        return release

    def _room(self) -> int:
        """Frames the device may deliver now without lapping a held reader."""
        if not self.device.waits_for_reader:
            return self.read_chunk
        with self._lock:  # one look: a hold released between two would leave none here
            holds = list(self._holds.values())
        if not holds:
            return self.read_chunk
        written = self.ring.written
        return max(0, min(lead - (written - cursor()) for cursor, lead in holds))

    # ---- events and tare -------------------------------------------------------------
    def add_event(self, event: EngineEvent, *, frame: int | None = None,
                  at: float | None = None) -> dict[str, Any]:
        """Append ``event`` (one of devices/engine_events.py's kinds) to the journal at
        ``frame`` (default: the next frame) and host time ``at`` (default: now); returns
        its journal entry, the form a session file stores."""
        if type(event) not in KINDS:
            raise TypeError(f"not a declared engine event: {event!r}")
        entry = event.record(time.time() if at is None else at,
                             self.ring.written if frame is None else frame)
        with self._lock:
            self._events.append(entry)
        return entry

    def events_since(self, cursor: int) -> list[dict[str, Any]]:
        with self._lock:
            return list(self._events[cursor:])

    @property
    def event_count(self) -> int:
        return len(self._events)

    def lost_reason(self) -> str | None:
        """While reconnecting: why the device was lost ('serial port X lost: ...'), so a
        job that waited in vain for frames can name the device and the cause."""
        if self.state != RECONNECTING:
            return None
        with self._lock:
            lost = self._lost_reason
        return lost or "disconnected"

    def tare(self, n: int | None = None) -> None:
        """Take a new baseline from the next ``n`` frames (default: baseline_frames)."""
        with self._lock:
            self._tare_from = self.ring.written
            self._tare_n = n or self.baseline_frames

    def _maybe_finish_tare(self) -> None:
        start = self._tare_from
        if start is None or self.ring.written - start < self._tare_n:
            return
        chunk = self.ring.read_since(start, self._tare_n)
        if len(chunk) == 0:
            return
        self.baseline = compute_baseline(chunk.raw, self._tare_n)
        with self._lock:
            self._tare_from = None
        self.add_event(Tared(chunk.start, len(chunk), [float(v) for v in self.baseline]))

    # ---- pull API --------------------------------------------------------------------
    def latest(self) -> FrameChunk | None:
        return self.ring.latest()

    def read_since(self, cursor: int, max_frames: int | None = None) -> FrameChunk:
        return self.ring.read_since(cursor, max_frames)

    @property
    def frames(self) -> int:
        return self.ring.written

    def measured_rate_hz(self, window_s: float = 2.0) -> float:
        """Frames per second of host receive time over the last ``window_s`` seconds."""
        chunk = self.ring.last(min(self.ring.capacity, 4096))
        if len(chunk) < 2:
            return 0.0
        t = chunk.host_time
        recent = t[t >= t[-1] - window_s]
        if len(recent) < 2 or recent[-1] <= recent[0]:
            return 0.0
        return float((len(recent) - 1) / (recent[-1] - recent[0]))

    def device_rate_hz(self) -> float:
        """Frames per second of device time over the newest frames (sim: simulated time)."""
        chunk = self.ring.last(min(self.ring.capacity, 256))
        if len(chunk) < 2 or chunk.device_time[-1] <= chunk.device_time[0]:
            return 0.0
        return float((len(chunk) - 1) / (chunk.device_time[-1] - chunk.device_time[0]))

    def counters(self) -> dict[str, Any]:
        return {
            "frames": self.ring.written,
            "malformed": int(sum(self.malformed.values())),
            "malformed_by_kind": dict(self.malformed),
            "gaps": self.gaps,
            "missing_frames": self.missing_frames,
            "reconnects": self.reconnects,
        }

    # ---- the thread ------------------------------------------------------------------
    def _run(self) -> None:
        dev = self.device
        try:
            dev.open()
        except Exception as exc:  # reported, never raised into the app
            self._fail(exc, "open")
            return
        self.state = RUNNING
        self.add_event(Connected(dev.name))
        try:
            while not self._stop.is_set():
                room = min(self.read_chunk, self._room())
                if room <= 0:  # a held reader is a ring (or its lead) behind: let it read
                    self._stop.wait(0.002)
                    continue
                try:
                    batch = dev.read(room)
                except DeviceLost as exc:
                    if not dev.supports_reconnect or not self._reconnect(exc):
                        if not self._stop.is_set():
                            self._fail(exc, "read")
                        return
                    continue
                self._ingest(batch)
                if dev.finished:
                    self._maybe_finish_tare()
                    self.state = FINISHED
                    self.add_event(Finished())
                    return
        except Exception as exc:
            self._fail(exc, "read")
        finally:
            try:
                dev.close()
            except Exception:
                pass
            if self.state not in (ERROR, FINISHED):
                self.add_event(Disconnected(dev.name))

    def _ingest(self, batch: Any) -> None:
        if batch.malformed:
            with self._lock:
                self.malformed.update({k: v for k, v in batch.malformed.items() if v})
        n = len(batch)
        if n == 0:
            return
        now = time.time()
        host = batch.host_time if batch.host_time is not None else np.full(n, now)
        dev_t = batch.device_time if batch.device_time is not None else host
        seq = np.asarray(batch.seq, dtype=np.int64) if batch.seq is not None else np.full(n, -1)
        if batch.seq is not None:
            self._check_seq(seq)
        self.ring.write(batch.raw, dev_t, host, seq)
        self._maybe_finish_tare()

    def _check_seq(self, seq: np.ndarray) -> None:
        prev = self._last_seq
        full = np.concatenate([[prev], seq]) if prev is not None else seq
        jumps = np.diff(full)
        first = 0 if prev is not None else 1  # batch index of full[1]
        for pos in np.nonzero(jumps > 1)[0]:
            missing = int(jumps[pos] - 1)
            self.gaps += 1
            self.missing_frames += missing
            # at the frame after the jump (not the batch's first): the time between the
            # two is the missing frames', which a measured rate leaves out
            self.add_event(SequenceGap(missing, int(full[pos])),
                           frame=self.ring.written + int(pos) + first)
        self._last_seq = int(seq[-1])

    def _reconnect(self, exc: Exception) -> bool:
        lost_at = time.time()
        self.state = RECONNECTING
        self._lost_reason = str(exc)
        self.add_event(ConnectionLost(str(exc)))
        attempt = 0
        while not self._stop.is_set():
            delay = RECONNECT_BACKOFF_S[min(attempt, len(RECONNECT_BACKOFF_S) - 1)]
            if self._stop.wait(delay):
                return False
            attempt += 1
            self.reconnect_attempts += 1
            try:
                self.device.reopen()
            except DeviceError:
                continue
            self.reconnects += 1
            self.state = RUNNING
            gap_s = round(time.time() - lost_at, 3)
            self.gaps += 1
            self.add_event(ReconnectGap(gap_s))
            self.add_event(Reconnected(gap_s, attempt))
            return True
        return False

    def _fail(self, exc: Exception, during: str) -> None:
        if not isinstance(exc, DeviceError):  # a plugin bug: keep its traceback
            logging.getLogger(__name__).error("device plugin failed", exc_info=exc)
        self.error = str(exc) if isinstance(exc, DeviceError) else f"{type(exc).__name__}: {exc}"
        self.state = ERROR
        self.add_event(DeviceFailed(during, self.error))
