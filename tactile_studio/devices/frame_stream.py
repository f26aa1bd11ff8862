"""What consumers of the device stream need from it: the :class:`FrameStream` seam.

The collection runner, the trial measure and the recorder depend on this small
``typing.Protocol``, not on :class:`~tactile_studio.devices.engine.AcquisitionEngine`:
the engine satisfies it, and so does any plain object with these members (a test's
stream over numpy arrays drives the runner without threads). Frames are numbered from 0
in arrival order; events are an append-only list read by cursor.

:class:`LiveStream` is what a holder of a device stream (a command, a wizard, a window,
the live view) may do with it beyond reading: start, stop, tare, mark, ask its state.
Only ``tactile_studio.acquisition.open_stream`` makes one (the engine), so everything
above acquisition types against these protocols (an import contract, pyproject.toml).
"""

from __future__ import annotations

from collections.abc import Callable
from enum import StrEnum
from typing import Any, Protocol, runtime_checkable

import numpy as np

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.devices.engine_events import EngineEvent
from tactile_studio.devices.ring import FrameChunk
from tactile_studio.sensor.layout import Layout


class EngineState(StrEnum):
    """Where the engine is (strings, so they print and compare as their values)."""

    IDLE = "idle"
    CONNECTING = "connecting"
    RUNNING = "running"
    RECONNECTING = "reconnecting"
    FINISHED = "finished"
    STOPPED = "stopped"
    ERROR = "error"

    @property
    def is_live(self) -> bool:
        """Streaming or trying to (frames may still arrive)."""
        return self in (EngineState.CONNECTING, EngineState.RUNNING, EngineState.RECONNECTING)

    @property
    def is_over(self) -> bool:
        """Ended for good: finished, stopped or failed."""
        return self in (EngineState.FINISHED, EngineState.STOPPED, EngineState.ERROR)


IDLE, CONNECTING, RUNNING, RECONNECTING, FINISHED, STOPPED, ERROR = (
    EngineState.IDLE, EngineState.CONNECTING, EngineState.RUNNING, EngineState.RECONNECTING,
    EngineState.FINISHED, EngineState.STOPPED, EngineState.ERROR)


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
    """A stream the :class:`~tactile_studio.storage.recording.recorder.Recorder` can write to a
    file: it also names its device and keeps the counters a session file stores."""

    def counters(self) -> dict[str, Any]:
        """frames, malformed, malformed_by_kind, gaps, missing_frames, reconnects."""

    def device_info(self) -> dict[str, Any]:
        """The device's description (plugin, settings...), stored in the file."""

    def sensor_id(self) -> str | None:
        """The connected sensor's own ID, if it has one."""


@runtime_checkable
class LiveStream(RecordableStream, Protocol):
    """A device's running stream as its holder drives it (what
    :func:`~tactile_studio.acquisition.open_stream.open_stream` returns): the reader's
    members plus the lifecycle, tare, markers and the figures a status line shows."""

    device: DevicePlugin  # a simulator's own hooks (set_gesture, perform) are reached here
    state: EngineState
    error: str | None  # why it failed (state ``error``)
    reconnect_attempts: int

    @property
    def device_name(self) -> str:
        """The device plugin's name (for messages)."""

    @property
    def capacity(self) -> int:
        """Frames held: how far back :meth:`read_since` reaches."""

    def start(self) -> None:
        """Open the device and stream (in a thread of its own)."""

    def stop(self, timeout: float = 5.0) -> None:
        """Stop streaming and close the device; idempotent."""

    def tare(self, n: int | None = None) -> None:
        """Take a new baseline from the next ``n`` frames."""

    def add_event(self, event: EngineEvent, *, frame: int | None = None,
                  at: float | None = None) -> dict[str, Any]:
        """Append ``event`` (a declared kind of devices/engine_events.py) to the journal at
        ``frame`` (default: the next) and host time ``at``; returns its journal entry."""

    def wait_frames(self, n: int, timeout: float = 10.0) -> bool:
        """Block until ``n`` frames arrived (or the stream ended); True if they did."""

    def hold(self, cursor: Callable[[], int], lead: int | None = None) -> Callable[[], None]:
        """Keep frames from ``cursor()`` on until released (returns the release)."""

    def measured_rate_hz(self, window_s: float = 2.0) -> float:
        """Frames per second of host receive time, lately."""

    def device_rate_hz(self) -> float:
        """Frames per second of device time, lately."""

    def lost_reason(self) -> str | None:
        """While reconnecting: why the device was lost."""


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
