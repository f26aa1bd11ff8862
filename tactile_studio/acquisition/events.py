"""The events an :class:`~tactile_studio.acquisition.live_acquisition.LiveAcquisition` tells its
listeners (the live screen's device panel and status bar, the collection console,
``record`` and ``listen``): one frozen dataclass per kind, declared here once, so a
listener switches on the type (``isinstance``, ``match``) and a misspelt field is an error
where the event is made, not a silent ``KeyError`` in a window.

None of them is written to a file (the file's events are the engine's); they live only
between the session and its listeners, on the caller's thread.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from tactile_studio.acquisition.outcome import RecordingOutcome
from tactile_studio.devices.frame_stream import EngineState


@dataclass(frozen=True)
class Connected:
    """The session started its own engine on ``device``."""

    device: str | None


@dataclass(frozen=True)
class Disconnected:
    """The session stopped its own engine (a shared engine never says so)."""

    device: str | None


@dataclass(frozen=True)
class StateChanged:
    """:meth:`LiveAcquisition.poll` saw the engine reach ``state``."""

    state: EngineState


@dataclass(frozen=True)
class RecordingStarted:
    """A recording into ``path`` began."""

    path: str


@dataclass(frozen=True)
class RecordingStopped:
    """The recording into ``path`` ended. ``reason``: ``requested``, ``limit``, ``device``
    or ``write_error``; ``message``: the outcome's one line when the recording is
    incomplete, else ""."""

    path: str
    reason: str
    message: str
    outcome: RecordingOutcome


@dataclass(frozen=True)
class Health:
    """The recording's device went silent (``silent``) or came back, or a marker stream
    was lost (acquisition/stream_health.py, marker_recording.py), told in one line."""

    message: str
    silent: bool


AcquisitionEvent = (Connected | Disconnected | StateChanged | RecordingStarted
                    | RecordingStopped | Health)
#: every declared kind, for a test that checks nothing else is ever sent
KINDS: tuple[type, ...] = (Connected, Disconnected, StateChanged, RecordingStarted,
                           RecordingStopped, Health)
Listener = Callable[[AcquisitionEvent], None]
