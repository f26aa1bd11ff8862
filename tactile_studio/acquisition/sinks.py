"""Where an acquisition's stream goes: the sinks an :class:`LiveAcquisition` holds.

A sink is small (:class:`Sink`): ``start()`` sets it up, ``event(kind, **detail)``
takes an application event, ``stop()`` closes it, once, writing its end. The HDF5
recorder (storage/recording/recorder.py, opened by acquisition/file_sink.py), the device's LSL
publishing and the marker inlets of a recording are sinks.

Frames are not handed to sinks: each pulls them (and the engine's own events) from the
engine by cursor, at its own pace. The engine's ring already is the fan-out: pushing
frames would copy every chunk once per sink on the acquisition thread, and a slow sink
(a file on a busy disk) would hold the device back instead of reading behind it.

Events the session itself is given (:meth:`LiveAcquisition.add_event`) are stamped
once and handed to every sink (:meth:`SinkList.event`): the file writes them, LSL
publishing sends them as markers, the marker inlets ignore them. The session keeps the
sinks in stop order and stops them: the outlets a caller added (their end reaches the
file), then the file, then the device's shared LSL publishing (which outlives a
recording).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from tactile_studio.devices.frame_stream import LiveStream

#: stop ranks: lower stops first (the stop order: engine, outlets, file, publishing)
OUTLET, FILE, PUBLISHING = 0, 1, 2


@runtime_checkable
class Sink(Protocol):
    """Anything fed from the engine while a session runs: set up, given events, closed
    (frames: pulled by the sink itself from the engine, see the module doc)."""

    def start(self) -> Any:
        """Set up and start pulling; returns the sink."""

    def event(self, kind: str, **detail: Any) -> None:
        """An application event stamped by the session (``time_s``); may be ignored."""

    def stop(self) -> None:
        """Close, once: pull what is left and write the end."""


class LslPublishing:
    """The device's LSL outlets as a sink: the one streamer per engine, shared with
    every other user of that engine (streams/lsl_outlet.py counts them)."""

    def __init__(self, engine: LiveStream) -> None:
        self.engine = engine
        self.streamer: Any = None

    def start(self) -> LslPublishing:
        from tactile_studio.streams.lsl_outlet import acquire_streamer

        if self.streamer is None:
            self.streamer = acquire_streamer(self.engine)
        return self

    def event(self, kind: str, **detail: Any) -> None:
        """Published as an application marker (source ``app``) while streaming."""
        detail.pop("time_s", None)  # the marker is stamped on arrival, as push_marker does
        if self.streamer is not None:
            self.streamer.push_marker(kind, **detail)

    def stop(self) -> None:
        streamer, self.streamer = self.streamer, None
        if streamer is not None:
            from tactile_studio.streams.lsl_outlet import release_streamer

            release_streamer(streamer)


class SinkList:
    """The session's sinks in stop order (stable within a rank)."""

    def __init__(self) -> None:
        self._sinks: list[tuple[int, Any]] = []

    def add(self, sink: Any, rank: int) -> Any:
        self._sinks.append((rank, sink))
        self._sinks.sort(key=lambda rs: rs[0])
        return sink

    def of_rank(self, rank: int) -> list[Any]:
        return [s for r, s in self._sinks if r == rank]

    def remove(self, sink: Any) -> None:
        self._sinks = [(r, s) for r, s in self._sinks if s is not sink]

    def event(self, kind: str, **detail: Any) -> None:
        """Give an event to every sink that takes events, in stop order (an outlet a
        caller added may have no ``event``: it gets none)."""
        for _, sink in list(self._sinks):
            take = getattr(sink, "event", None)
            if callable(take):
                take(kind, **dict(detail))

    def stop(self, rank: int) -> None:
        """Stop (in order) and forget the sinks of ``rank``."""
        for sink in self.of_rank(rank):
            self.remove(sink)
            sink.stop()
