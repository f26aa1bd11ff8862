"""Clocks the collection runner can be given: it times free play, the beep and breaks
with one (trials are counted in frames, never on a clock)."""

from __future__ import annotations

from collections.abc import Callable

from tactile_studio.devices.frame_stream import FrameStream

Clock = Callable[[], float]


class StreamClock:
    """Seconds of device time at the newest frame: breaks and free play then run at the
    stream's speed (a simulator ten times faster than real time makes them ten times
    shorter in wall time)."""

    def __init__(self, engine: FrameStream) -> None:
        self.engine = engine
        self._last = 0.0

    def __call__(self) -> float:
        chunk = self.engine.latest()
        if chunk is not None:
            self._last = max(self._last, float(chunk.device_time[0]))
        return self._last

