"""Stream health during a recording: a device that goes silent is said at once.

LabRecorder's users asked for it: a stream that stops sending while a recording runs
should be noticed then, not when the file is opened. :class:`StreamHealth` is checked
from the owner's poll (``LiveAcquisition.poll``): when no frame has arrived for
``threshold_s`` (once frames have flowed) it writes an engine event ``stream_silent``
(device, seconds, state;
so the file has it at the row where frames stopped) and returns a warning; when frames
come back, an event ``stream_resumed`` (silent_s, at the first frame back) and a line
saying so. The CLI prints
these lines, the main window shows them in its status bar.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from tactile_studio.devices.engine_events import StreamResumed, StreamSilent
from tactile_studio.devices.frame_stream import LiveStream

DEFAULT_SILENCE_S = 2.0


class StreamHealth:
    """Watches ``engine``'s frame count (see the module docstring)."""

    def __init__(self, engine: LiveStream, name: str | None = None,
                 threshold_s: float = DEFAULT_SILENCE_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.engine = engine
        self.name = name or getattr(engine, "device_name", None) or "device"
        self.threshold_s = float(threshold_s)
        self.clock = clock
        self._frames = engine.frames
        self._since = clock()
        self.silent = False
        self._armed = self._frames > 0  # a device still starting is record's own error

    def check(self) -> list[str]:
        """New warnings (and the all-clear after one) since the last check."""
        now, frames = self.clock(), self.engine.frames
        if frames != self._frames:
            first_new, self._frames, self._armed = self._frames, frames, True
            out = []
            if self.silent:
                gap = now - self._since
                # at the first frame that came back, not at the newest: a batch (an LSL
                # chunk, a backlog) may have brought many since
                self.engine.add_event(StreamResumed(self.name, round(gap, 3)),
                                      frame=first_new)
                out.append(f"{self.name} is sending frames again after {gap:.1f} s of silence")
                self.silent = False
            self._since = now
            return out
        if self._armed and not self.silent and now - self._since >= self.threshold_s:
            self.silent = True
            state = str(getattr(self.engine, "state", ""))
            self.engine.add_event(StreamSilent(self.name, self.threshold_s, state))
            return [f"{self.name} sent no frames for {self.threshold_s:g} s ({state}); "
                    "the recording goes on"]
        return []
