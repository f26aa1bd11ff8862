"""Other programs' LSL markers in a recording made through an LiveAcquisition (the
live window's ``gui --markers NAME``): the inlets (streams/marker_inlet.py) start with
the recording and stop before its file closes; their problems (a stream that
disappeared) are handed to the owner's thread, which says them as ``health`` events."""

from __future__ import annotations

import queue
from collections.abc import Sequence
from typing import Any

from tactile_studio.devices.frame_stream import LiveStream


class MarkerRecording:
    """Marker inlets for one recording, a sink (acquisition/sinks.py): they open (and
    refuse a stream that is not there) when made, feed the engine, stop with the
    recording; the session's own events are not theirs to record (the file has them)."""

    def __init__(self, engine: LiveStream, names: Sequence[str]) -> None:
        from tactile_studio.streams.marker_inlet import MarkerInlets

        self._problems: queue.SimpleQueue[str] = queue.SimpleQueue()
        self.inlets = MarkerInlets(engine, list(names), on_problem=self._problems.put)

    def start(self) -> MarkerRecording:
        """Nothing to set up: the inlets run from when they are made."""
        return self

    def event(self, kind: str, **detail: Any) -> None:
        """Ignored: the inlets record other programs' markers, not the session's."""

    def stop(self) -> None:
        self.inlets.stop()

    def messages(self) -> list[str]:
        """Problems since the last call (owner's thread)."""
        out = []
        while not self._problems.empty():
            out.append(self._problems.get_nowait())
        return out
