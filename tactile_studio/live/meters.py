"""Display meters: frames painted per second and device-to-paint latency."""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np


class RateMeter:
    """Events per second over a sliding window (display fps)."""

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self._times: deque[float] = deque()

    def tick(self, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        self._times.append(now)
        while self._times and self._times[0] < now - self.window_s:
            self._times.popleft()

    def rate(self, now: float | None = None) -> float:
        now = time.monotonic() if now is None else now
        while self._times and self._times[0] < now - self.window_s:
            self._times.popleft()
        if len(self._times) < 2:
            return 0.0
        return (len(self._times) - 1) / max(now - self._times[0], 1e-9)


class LatencyMeter:
    """Device-to-paint latency: time.time() at paint minus the frame's host time."""

    def __init__(self, keep: int = 600) -> None:
        self._values: deque[float] = deque(maxlen=keep)

    def record(self, host_time: float, now: float | None = None) -> float:
        latency = (time.time() if now is None else now) - host_time
        self._values.append(latency)
        return latency

    def clear(self) -> None:
        self._values.clear()

    @property
    def values(self) -> np.ndarray:
        return np.array(self._values)

    def last(self) -> float | None:
        return self._values[-1] if self._values else None

    def percentile(self, q: float, last: int | None = None) -> float | None:
        """The q-th percentile (seconds) of all kept values or of the ``last`` ones."""
        values = self.values if last is None else self.values[-last:]
        return float(np.percentile(values, q)) if values.size else None


class PaintPacer:
    """When to paint a new frame: at once, unless that would exceed the display rate.

    The display polls for new frames every few milliseconds (cheap) instead of on a
    display-rate timer, so a frame from a slow device (43 Hz) is painted within a poll
    interval of its arrival rather than up to a whole display period later, while a fast
    device (1 kHz) is painted once per display period with its newest frame. Paint times
    keep a fixed cadence (a late paint does not push every later one back), so a fast
    device gets the full display rate despite timer jitter.
    """

    def __init__(self, display_hz: float = 60.0) -> None:
        self.period = 1.0 / display_hz
        self._next = -math.inf

    def delay(self, now: float | None = None) -> float:
        """Seconds to wait before the next paint (0: paint now)."""
        now = time.monotonic() if now is None else now
        return max(0.0, self._next - now)

    def painted(self, now: float | None = None) -> None:
        """A frame was drawn at ``now``: the next may follow one display period on."""
        now = time.monotonic() if now is None else now
        if now - self._next < self.period:   # on the cadence: keep it
            self._next += self.period
        else:                                # idle for a while: start a new cadence
            self._next = now + self.period

    def reset(self) -> None:
        self._next = -math.inf
