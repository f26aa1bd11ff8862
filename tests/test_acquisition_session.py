"""LiveAcquisition: the one start order, auto-stop (a frame limit, the stream ending),
events, and a shared engine left alone; on the real simulated and replay devices."""

from __future__ import annotations

from pathlib import Path

from waiting import wait_until

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.acquisition.events import (
    KINDS,
    AcquisitionEvent,
    Connected,
    Disconnected,
    RecordingStarted,
    RecordingStopped,
    StateChanged,
)
from tactile_studio.acquisition.sinks import FILE, OUTLET, Sink
from tactile_studio.storage.format.session_file import SessionFile


def _events(session: LiveAcquisition) -> list[AcquisitionEvent]:
    seen: list[AcquisitionEvent] = []
    session.add_listener(seen.append)
    return seen


def test_start_order_puts_the_first_frame_and_the_connect_event_in_the_file(tmp_path) -> None:
    s = LiveAcquisition()
    seen = _events(s)
    engine = s.open("simulated", {"rate": "400", "speed": "4"})
    s.start_recording(tmp_path / "a.h5", {"source": "test"})  # before start: step 2
    s.start()
    try:
        wait_until(lambda: engine.frames > 150, what="150 frames")
        s.stop_recording_after(frames=120)
        wait_until(lambda: (s.poll(), not s.recording)[1], what="the frame limit")
    finally:
        s.close()
    assert [type(e) for e in seen][:3] == [RecordingStarted, Connected, StateChanged]
    stopped = [e for e in seen if isinstance(e, RecordingStopped)]
    assert [e.reason for e in stopped] == ["limit"]
    with SessionFile(tmp_path / "a.h5") as f:
        assert f.n_frames >= 120
        assert int(f.column("index", 0, 1)[0]) == 0  # row 0 is the engine's frame 0
        assert "connect" in [e["kind"] for e in f.events]


def test_every_event_a_session_sends_is_a_declared_type(tmp_path: Path) -> None:
    """Connect, record, stop on a limit, disconnect: each event the listeners hear is one
    of acquisition/events.py's types (a dict or an undeclared kind fails here)."""
    s = LiveAcquisition()
    seen = _events(s)
    engine = s.connect("simulated", {"rate": "400", "speed": "4"})
    try:
        s.start_recording(tmp_path / "k.h5")
        wait_until(lambda: engine.frames > 100, what="100 frames")
        s.stop_recording_after(frames=50)
        wait_until(lambda: (s.poll(), not s.recording)[1], what="the frame limit")
    finally:
        s.close()
    assert seen and all(isinstance(e, KINDS) for e in seen), seen
    assert {type(e) for e in seen} >= {Connected, StateChanged, RecordingStarted,
                                        RecordingStopped, Disconnected}


def test_the_recording_stops_itself_when_the_stream_ends(tmp_path: Path) -> None:
    src = LiveAcquisition()
    src.connect("simulated", {"rate": "400", "speed": "8"})
    src.start_recording(tmp_path / "src.h5")
    wait_until(lambda: src.recorder.rows_written > 200, what="a source recording")
    src.close()
    s = LiveAcquisition()
    seen = _events(s)
    s.open("replay", {"path": str(tmp_path / "src.h5"), "speed": "0"})
    s.start_recording(tmp_path / "copy.h5")  # before start: a fast replay may end at once
    s.start()
    try:
        wait_until(lambda: (s.poll(), not s.recording)[1], what="the replay to end")
    finally:
        s.close()
    assert [e.reason for e in seen if isinstance(e, RecordingStopped)] == ["device"]
    assert s.status().state == "finished" and s.status().recording is None
    with SessionFile(tmp_path / "copy.h5") as f:
        assert f.closed_cleanly and f.n_frames > 0


def test_a_shared_engine_is_not_stopped_by_the_session_sharing_it(tmp_path: Path) -> None:
    owner = LiveAcquisition()
    engine = owner.connect("simulated", {"rate": "400"})
    try:
        guest = LiveAcquisition()
        guest.share(engine, "simulated")
        guest.start()  # nothing to do: it is running already
        rec = guest.start_recording(tmp_path / "g.h5")
        wait_until(lambda: rec.rows_written > 20, what="the guest's rows")
        guest.close()
        assert engine.running and rec.stopped
    finally:
        owner.close()
    assert not engine.running


def test_a_recorder_closed_by_its_collection_is_released_on_poll(tmp_path: Path) -> None:
    s = LiveAcquisition()
    seen = _events(s)
    s.connect("simulated", {"rate": "400"})
    try:
        rec = s.start_recording(tmp_path / "c.h5")
        rec.stop()  # as Collection.close() does
        s.poll()
        assert not s.recording
        assert [e.reason for e in seen if isinstance(e, RecordingStopped)] == ["requested"]
    finally:
        s.close()


class _MarkerSink:
    """A sink beside the file: writes its end as an event into the recording."""

    def __init__(self, session: LiveAcquisition) -> None:
        self.session, self.stopped_with_file_open = session, None

    def start(self) -> "_MarkerSink":
        return self

    def event(self, kind: str, **detail: object) -> None:
        pass

    def stop(self) -> None:
        rec = self.session.recorder
        self.stopped_with_file_open = rec is not None and not rec.stopped
        if rec is not None:
            rec.add_event("sink_end")


def test_the_file_and_the_outlets_are_sinks_stopped_in_order(tmp_path: Path) -> None:
    s = LiveAcquisition()
    engine = s.open("simulated", {"rate": "400", "speed": "4"})
    rec = s.start_recording(tmp_path / "s.h5")
    sink = s.add_outlet(_MarkerSink(s).start())
    assert isinstance(rec, Sink) and isinstance(sink, Sink)
    assert s.sinks.of_rank(OUTLET) == [sink] and s.sinks.of_rank(FILE) == [rec]
    s.start()
    try:
        wait_until(lambda: engine.frames > 50, what="50 frames")
    finally:
        s.close()
    assert sink.stopped_with_file_open  # the outlets stop first: their end is in the file
    assert s.sinks.of_rank(OUTLET) == [] and s.sinks.of_rank(FILE) == []
    with SessionFile(tmp_path / "s.h5") as f:
        assert "sink_end" in [e["kind"] for e in f.events]
