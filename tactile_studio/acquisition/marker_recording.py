"""Other programs' LSL markers in a recording made through an AcquisitionSession (the
live window's ``gui --markers NAME``): the inlets (streams/marker_inlet.py) start with
the recording and stop before its file closes; their problems (a stream that
disappeared) are handed to the owner's thread, which says them as ``health`` events."""

from __future__ import annotations

import queue
from collections.abc import Sequence
from typing import Any


class MarkerRecording:
    """Marker inlets for one recording (an outlet-like: ``stop()``)."""

    def __init__(self, engine: Any, names: Sequence[str]) -> None:
        from tactile_studio.streams.marker_inlet import MarkerInlets

        self._problems: queue.SimpleQueue[str] = queue.SimpleQueue()
        self.inlets = MarkerInlets(engine, list(names), on_problem=self._problems.put)

    def stop(self) -> None:
        self.inlets.stop()

    def messages(self) -> list[str]:
        """Problems since the last call (owner's thread)."""
        out = []
        while not self._problems.empty():
            out.append(self._problems.get_nowait())
        return out
