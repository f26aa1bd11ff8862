"""What consumers of the device stream need from it: the :class:`FrameStream` seam.

The collection runner, the trial measure and the recorder depend on this small
``typing.Protocol``, not on :class:`~tactile_studio.devices.engine.AcquisitionEngine`:
the engine satisfies it, and so does any plain object with these members (a test's
stream over numpy arrays drives the runner without threads). Frames are numbered from 0
in arrival order; events are an append-only list read by cursor.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from tactile_studio.devices.ring import FrameChunk
from tactile_studio.sensor.layout import Layout


@runtime_checkable
class FrameStream(Protocol):
    """A pull-based stream of frames and events (what the runner reads)."""

    layout: Layout
    baseline: np.ndarray | None  # the current tare (None until the first one)
    baseline_frames: int  # frames a tare averages (the first one starts at frame 0)

    @property
    def frames(self) -> int:
        """Frames that have arrived so far (the next frame's index)."""

    @property
    def event_count(self) -> int:
        """Events so far (the next event's cursor)."""

    @property
    def running(self) -> bool:
        """Streaming or trying to (frames may still arrive)."""

    @property
    def nominal_rate_hz(self) -> float:
        """The device's nominal frame rate (trial lengths are counted with it)."""

    def read_since(self, cursor: int, max_frames: int | None = None) -> FrameChunk:
        """Frames from ``cursor`` on (``lost`` counts those no longer held)."""

    def latest(self) -> FrameChunk | None:
        """The newest frame, or None before the first."""

    def events_since(self, cursor: int) -> list[dict[str, Any]]:
        """Events from ``cursor`` on: dicts with ``kind``, ``frame``, ``time`` and detail."""


@runtime_checkable
class RecordableStream(FrameStream, Protocol):
    """A stream the :class:`~tactile_studio.storage.recorder.Recorder` can write to a
    file: it also names its device and keeps the counters a session file stores."""

    def counters(self) -> dict[str, Any]:
        """frames, malformed, malformed_by_kind, gaps, missing_frames, reconnects."""

    def device_info(self) -> dict[str, Any]:
        """The device's description (plugin, settings...), stored in the file."""

    def sensor_id(self) -> str | None:
        """The connected sensor's own ID, if it has one."""


def hold_frames(stream: FrameStream, cursor: Callable[[], int],
                lead: int | None = None) -> Callable[[], None]:
    """Keep ``stream``'s frames from ``cursor()`` on until released, where the stream
    can (``AcquisitionEngine.hold``: a device that waits for its readers is held to
    their pace); a plain stream has nothing to hold. Returns the release function."""
    hold = getattr(stream, "hold", None)
    if hold is None:
        return lambda: None
    release: Callable[[], None] = hold(cursor, lead)
    return release
