"""The events of an acquisition engine's journal, declared once: one frozen dataclass per
kind, with typed fields, for everything that is written into it (the engine's own connect,
loss, gaps, tare...; a stream gone silent; markers from a script, another program or live
inference; the LSL clock). An emitter builds one of these and hands it to
:meth:`AcquisitionEngine.add_event`, which accepts nothing else.

The journal itself keeps the file form, because that is what a session file stores and
what its readers (the recorder, the marker stream, ``check``) have always read:
``{"time", "frame", "kind", **detail}``, made in one place (:meth:`EngineEvent.record`),
with the fields in the order they are declared here, so saved files do not change.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar


@dataclass(frozen=True)
class EngineEvent:
    """One journal entry's kind and detail (the engine stamps its time and frame)."""

    kind: ClassVar[str] = ""

    def detail(self) -> dict[str, Any]:
        """The fields as the file stores them, in their declared order."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def record(self, time: float, frame: int) -> dict[str, Any]:
        """The journal's (and the file's) form of this event at ``time`` and ``frame``."""
        return {"time": time, "frame": frame, "kind": self.kind, **self.detail()}


# ---- the engine's own -------------------------------------------------------------------
@dataclass(frozen=True)
class Connected(EngineEvent):
    """The device opened and streams."""

    kind: ClassVar[str] = "connect"
    device: str


@dataclass(frozen=True)
class Disconnected(EngineEvent):
    """The stream ended (stopped, or the device closed)."""

    kind: ClassVar[str] = "disconnect"
    device: str


@dataclass(frozen=True)
class ConnectionLost(EngineEvent):
    """The device went away; the engine tries to reconnect (a ``disconnect`` with why)."""

    kind: ClassVar[str] = "disconnect"
    reason: str


@dataclass(frozen=True)
class SequenceGap(EngineEvent):
    """The device's sequence numbers jumped: ``missing`` frames after ``after_seq``."""

    kind: ClassVar[str] = "gap"
    missing: int
    after_seq: int


@dataclass(frozen=True)
class ReconnectGap(EngineEvent):
    """The stream was interrupted for ``seconds`` while the device was reconnected."""

    kind: ClassVar[str] = "gap"
    seconds: float
    cause: str = "reconnect"


@dataclass(frozen=True)
class Reconnected(EngineEvent):
    """The device is back after ``gap_s`` seconds and ``attempts`` tries."""

    kind: ClassVar[str] = "reconnect"
    gap_s: float
    attempts: int


@dataclass(frozen=True)
class Tared(EngineEvent):
    """A new baseline from ``frames`` frames from ``first_frame`` on."""

    kind: ClassVar[str] = "tare"
    first_frame: int
    frames: int
    baseline: list[float]


@dataclass(frozen=True)
class Finished(EngineEvent):
    """A device with an end (a file replayed) reached it."""

    kind: ClassVar[str] = "finished"


@dataclass(frozen=True)
class DeviceFailed(EngineEvent):
    """The device failed ``during`` open or read; ``message`` says how."""

    kind: ClassVar[str] = "error"
    during: str
    message: str


# ---- written by others into the engine's journal ------------------------------------------
@dataclass(frozen=True)
class StreamSilent(EngineEvent):
    """A recording's device sent nothing for ``seconds`` (acquisition/stream_health.py)."""

    kind: ClassVar[str] = "stream_silent"
    device: str | None
    seconds: float
    state: str


@dataclass(frozen=True)
class StreamResumed(EngineEvent):
    """Frames came again after ``silent_s`` seconds of silence."""

    kind: ClassVar[str] = "stream_resumed"
    device: str | None
    silent_s: float


@dataclass(frozen=True)
class Marker(EngineEvent):
    """A marker with a ``text`` from ``source`` (``remote``: an experiment script)."""

    kind: ClassVar[str] = "marker"
    text: str
    source: str


@dataclass(frozen=True)
class LslMarker(EngineEvent):
    """A marker another program sent on LSL stream ``stream`` (streams/marker_inlet.py):
    its ``text`` (and ``channels``, each as sent, for a stream of several), its LSL time
    and the clock corrections it was placed with."""

    kind: ClassVar[str] = "marker"
    text: str
    stream: str
    lsl_time: float
    time_correction: float
    offset_s: float
    channels: tuple[str, ...] | None = None
    source: str = "lsl"

    def detail(self) -> dict[str, Any]:
        head: dict[str, Any] = {"text": self.text}
        if self.channels is not None:
            head["channels"] = list(self.channels)
        return {**head, "stream": self.stream, "lsl_time": self.lsl_time,
                "time_correction": self.time_correction, "offset_s": self.offset_s,
                "source": self.source}


@dataclass(frozen=True)
class MarkerStreamOpened(EngineEvent):
    """An LSL marker stream is recorded from now on."""

    kind: ClassVar[str] = "marker_stream"
    stream: str
    source_id: str
    hostname: str
    time_correction: float
    offset_s: float


@dataclass(frozen=True)
class MarkerStreamLost(EngineEvent):
    """An LSL marker stream's sender stopped; later markers from it are not recorded."""

    kind: ClassVar[str] = "marker_stream_lost"
    stream: str


@dataclass(frozen=True)
class LslClock(EngineEvent):
    """The host->LSL clock offset in force for the published frames (streams/lsl_outlet.py)."""

    kind: ClassVar[str] = "lsl_clock"
    streaming: bool
    offset_s: float
    uncertainty_s: float
    measured_host_time: float
    measured_lsl_time: float
    content: str
    frame_stream: str
    frame_source_id: str
    marker_stream: str


@dataclass(frozen=True)
class LslClockStopped(EngineEvent):
    """Frames are no longer published on LSL stream ``frame_stream``."""

    kind: ClassVar[str] = "lsl_clock"
    frame_stream: str

    def detail(self) -> dict[str, Any]:
        return {"streaming": False, "frame_stream": self.frame_stream}


@dataclass(frozen=True)
class Prediction(EngineEvent):
    """Live inference's top gesture changed while recording (learn/deploy)."""

    kind: ClassVar[str] = "prediction"
    gesture: str
    probability: float
    run: str


KINDS: tuple[type[EngineEvent], ...] = (
    Connected, Disconnected, ConnectionLost, SequenceGap, ReconnectGap, Reconnected, Tared,
    Finished, DeviceFailed, StreamSilent, StreamResumed, Marker, LslMarker,
    MarkerStreamOpened, MarkerStreamLost, LslClock, LslClockStopped, Prediction)
