"""Where an acquisition's stream goes: the sinks an :class:`AcquisitionSession` holds.

A sink pulls the engine's frames and events by itself (from a cursor, as the recorder
does) between ``start()`` and ``stop()``; the session only keeps them in the stop
order and stops them: the outlets a caller added (their end reaches the file), then the
file, then the device's shared LSL publishing (which outlives a recording).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

#: stop ranks: lower stops first (the stop order: engine, outlets, file, publishing)
OUTLET, FILE, PUBLISHING = 0, 1, 2


@runtime_checkable
class Sink(Protocol):
    """Anything fed from the engine while a session runs (the HDF5 recorder, an LSL
    streamer, marker inlets): it starts pulling, and stops once, writing its end."""

    def start(self) -> Any: ...

    def stop(self) -> None: ...


class LslPublishing:
    """The device's LSL outlets as a sink: the one streamer per engine, shared with
    every other user of that engine (streams/lsl_outlet.py counts them)."""

    def __init__(self, engine: Any) -> None:
        self.engine = engine
        self.streamer: Any = None

    def start(self) -> LslPublishing:
        from tactile_studio.streams.lsl_outlet import acquire_streamer

        if self.streamer is None:
            self.streamer = acquire_streamer(self.engine)
        return self

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

    def stop(self, rank: int) -> None:
        """Stop (in order) and forget the sinks of ``rank``."""
        for sink in self.of_rank(rank):
            self.remove(sink)
            sink.stop()
