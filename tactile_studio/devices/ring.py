"""A preallocated ring buffer of frames that many consumers pull from by cursor.

Frame ``i`` (counting from 0 since the engine started) lives in slot ``i % capacity``.
A consumer keeps the index of the next frame it wants; if it falls more than
``capacity`` behind, the frames it missed are reported as lost rather than silently
skipped.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np


@dataclass
class FrameChunk:
    """Consecutive frames ``start .. start+len-1`` copied out of the ring."""

    start: int
    raw: np.ndarray
    device_time: np.ndarray
    host_time: np.ndarray
    seq: np.ndarray
    lost: int = 0

    def __len__(self) -> int:
        return int(self.raw.shape[0])

    @property
    def stop(self) -> int:
        return self.start + len(self)


class RingBuffer:
    def __init__(self, capacity: int, n_channels: int, dtype: str | np.dtype = "float32") -> None:
        self.capacity = int(capacity)
        self.n_channels = int(n_channels)
        self.raw = np.zeros((self.capacity, self.n_channels), dtype=dtype)
        self.device_time = np.zeros(self.capacity, dtype=np.float64)
        self.host_time = np.zeros(self.capacity, dtype=np.float64)
        self.seq = np.full(self.capacity, -1, dtype=np.int64)
        self._written = 0
        self._lock = threading.Lock()

    @property
    def written(self) -> int:
        """Total frames ever written: the index the next frame will get."""
        return self._written

    def write(self, raw: np.ndarray, device_time: np.ndarray, host_time: np.ndarray,
              seq: np.ndarray) -> int:
        """Append frames; returns the index of the first one."""
        n = int(raw.shape[0])
        if n > self.capacity:  # keep only what fits; the rest would be overwritten anyway
            raw, device_time = raw[-self.capacity:], device_time[-self.capacity:]
            host_time, seq = host_time[-self.capacity:], seq[-self.capacity:]
        with self._lock:
            first = self._written + (n - raw.shape[0])
            slots = (first + np.arange(raw.shape[0])) % self.capacity
            self.raw[slots] = raw
            self.device_time[slots] = device_time
            self.host_time[slots] = host_time
            self.seq[slots] = seq
            self._written = first + raw.shape[0]
            return first

    def read_since(self, cursor: int, max_frames: int | None = None) -> FrameChunk:
        """Frames from index ``cursor`` up to the newest (at most ``max_frames``)."""
        with self._lock:
            end = self._written
            oldest = max(0, end - self.capacity)
            lost = max(0, oldest - cursor)
            start = max(cursor, oldest)
            if max_frames is not None:
                end = min(end, start + max_frames)
            slots = np.arange(start, end) % self.capacity
            return FrameChunk(start, self.raw[slots], self.device_time[slots],
                              self.host_time[slots], self.seq[slots], lost)

    def last(self, n: int) -> FrameChunk:
        """The newest ``n`` frames (fewer if fewer were written)."""
        with self._lock:
            end = self._written
        return self.read_since(max(0, end - min(n, self.capacity)), n)

    def host_times(self) -> tuple[int, np.ndarray]:
        """(index of the oldest frame kept, the host times of every frame kept), read in
        one go: a reader that took the frame count first and then the newest N frames
        got a window that had moved on if frames arrived in between."""
        with self._lock:
            end = self._written
            start = max(0, end - self.capacity)
            return start, self.host_time[np.arange(start, end) % self.capacity]

    def latest(self) -> FrameChunk | None:
        """The newest frame, or None before the first."""
        if self._written == 0:
            return None
        return self.last(1)


def nearest_frame(times: np.ndarray, t: float) -> int:
    """The index of the time in ``times`` (non-decreasing) nearest to ``t``, the earlier
    of two as near; 0 before the first, the last after the last: the frame a marker
    stamped ``t`` belongs to (streams/marker_inlet.py; ``check`` verifies it)."""
    i = int(np.searchsorted(times, t))
    if i > 0 and (i == len(times) or t - times[i - 1] <= times[i] - t):
        i -= 1
    return max(0, min(i, len(times) - 1))
