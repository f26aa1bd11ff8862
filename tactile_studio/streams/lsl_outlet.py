"""``LslStreamer``: a consumer of the acquisition engine that publishes two LSL streams.

* frames: raw counts (int32, or float32 for float layouts) or decoded normal / shear-x /
  shear-y per taxel (float32), at the device's nominal rate, described in the stream XML
  (:mod:`.lsl_meta`);
* markers: JSON strings at an irregular rate (:mod:`.markers`): engine events, the
  collection runner's events (:meth:`LslStreamer.attach_runner`) and predictions
  (:meth:`LslStreamer.push_prediction`).

Like the recorder it pulls from the engine's ring by cursor in its own thread, so it never
slows the device. Each frame's LSL timestamp is its host arrival time plus the measured
host->LSL clock offset; the offset in force is written into the engine's event list as an
``lsl_clock`` event (and so into a session file being recorded), re-measured every
``clock_check_s`` and written again when it moved.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from tactile_studio.devices.engine_events import LslClock, LslClockStopped
from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.streams.clock import ClockOffset, measure_offset
from tactile_studio.streams.lsl_lib import load_pylsl
from tactile_studio.streams.lsl_meta import (
    DECODED,
    MARKER_TYPE,
    RAW,
    decoded_channels,
    frame_stream_info,
    stable_source_id,
)
from tactile_studio.streams.markers import (
    RecordedEvent,
    engine_marker,
    prediction_marker,
    runner_marker,
    to_json,
)


class EventSource(Protocol):
    """What :meth:`LslStreamer.attach_runner` needs of a collection runner (protocol is a
    layer above streams): listeners for its typed events."""

    def add_listener(self, fn: Callable[[RecordedEvent], None]) -> None: ...


CLOCK_TOLERANCE_S = 0.0005  # a re-measured offset that moved more than this is written
MAX_CHUNK = 8192
STOP_GRACE_S = 0.2


class LslStreamer:
    """Frame + marker outlets over ``engine`` (see the module docstring)."""

    def __init__(self, engine: LiveStream, decoded: bool = False,
                 name: str | None = None, poll_s: float = 0.02,
                 clock_check_s: float = 10.0,
                 host_clock: Callable[[], float] = time.time) -> None:
        self.pylsl = load_pylsl()
        self.host_clock = host_clock  # the engine's host_time clock
        self.engine = engine
        self.content = DECODED if decoded else RAW
        self.poll_s, self.clock_check_s = poll_s, clock_check_s
        info = engine.device_info()
        self.device_info = info
        dev = str(info.get("plugin") or engine.device_name)
        self.name = name or f"TactileStudio-{dev}" + ("-decoded" if decoded else "")
        self.marker_name = f"{self.name}-markers"
        self.source_id = stable_source_id(dev, self.content, info.get("settings", {}),
                                          info.get("sensor_id"))
        self.offset = measure_offset(self.pylsl.local_clock, host_clock=host_clock)
        self._last_check = time.monotonic()
        self.frame_outlet: Any = self.pylsl.StreamOutlet(frame_stream_info(
            self.pylsl, engine.layout, info, self.content, self.name, self.source_id,
            self.offset))
        minfo = self.pylsl.StreamInfo(self.marker_name, MARKER_TYPE, 1, self.pylsl.IRREGULAR_RATE,
                                      self.pylsl.cf_string, f"{self.source_id}:markers")
        ts = minfo.desc().append_child("tactile_studio")
        ts.append_child_value("format", "json")
        ts.append_child_value("frame_stream", self.name)
        ts.append_child_value("frame_source_id", self.source_id)
        self.marker_outlet: Any = self.pylsl.StreamOutlet(minfo)
        self.frames_sent = self.markers_sent = self.lost = 0
        self._cursor = engine.frames
        self._event_cursor = engine.event_count
        self._queue: collections.deque[tuple[float, dict[str, Any]]] = collections.deque()
        self._push_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lsl-outlet", daemon=True)
        self.running = False

    # ---- lifecycle -------------------------------------------------------------------
    def start(self) -> LslStreamer:
        self._clock_event(self._cursor, streaming=True)
        self.running = True
        self._thread.start()
        return self

    def stop(self) -> None:
        """Push what is left, write the end of streaming, close both outlets."""
        if not self.running:
            return
        self.running = False
        self._stop.set()
        self._thread.join(5.0)
        self._drain()
        self.engine.add_event(LslClockStopped(self.name))
        if self.has_consumers():
            time.sleep(STOP_GRACE_S)  # let connected recipients take the last chunk
        self.frame_outlet = self.marker_outlet = None  # liblsl closes them when freed

    # ---- markers from elsewhere ----------------------------------------------------------
    def attach_runner(self, runner: EventSource) -> Callable[[], None]:
        """Forward a TrialRunner's events (trials, beeps, keys, redo...) as markers;
        returns a function that stops forwarding.

        A trial start is stamped with the arrival of its first frame, a trial end with the
        arrival of its last one (``frame`` names that frame)."""
        started: list[int | None] = [None]
        attached = [True]

        def on_event(event: RecordedEvent) -> None:
            if not (self.running and attached[0]):
                return
            marker = runner_marker(event)
            when = None
            if marker["kind"] == "trial_start" and marker.get("frame") is not None:
                started[0] = int(marker["frame"])
                when = self._frame_host_time(started[0])
            elif marker["kind"] == "trial_end" and started[0] is not None:
                last = started[0] + int(getattr(runner, "trial_frames", 1)) - 1
                marker["frame"] = last
                when = self._frame_host_time(last)
            self._queue.append((time.time() if when is None else when, marker))

        runner.add_listener(on_event)
        return lambda: attached.__setitem__(0, False)

    def push_prediction(self, label: str, probability: float | None = None,
                        scores: dict[str, float] | None = None, frame: int | None = None,
                        model: str | None = None) -> None:
        """A live-inference prediction (timestamped at ``frame``'s arrival if given)."""
        when = self._frame_host_time(frame) if frame is not None else None
        self._queue.append((time.time() if when is None else when,
                            prediction_marker(label, probability, scores, frame, model)))

    def push_marker(self, kind: str, **detail: Any) -> None:
        """Any other application marker (source ``app``)."""
        self._queue.append((time.time(), {"kind": kind, "source": "app", **detail}))

    # ---- status ------------------------------------------------------------------------
    def has_consumers(self) -> bool:
        out = self.frame_outlet
        return bool(out is not None and out.have_consumers())

    def wait_for_recipient(self, timeout: float) -> bool:
        """Block until some inlet (e.g. LabRecorder) has opened the frame or the marker
        stream, or ``timeout`` s passed; True if one did."""
        deadline = time.monotonic() + timeout
        while True:
            if self.has_consumers() or (self.marker_outlet is not None
                                        and self.marker_outlet.have_consumers()):
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)

    def status_line(self) -> str:
        return ", ".join(self.status_lines())

    def status_lines(self) -> list[str]:
        """What is published and how it goes, in two short lines (the device panel)."""
        who = "recipient connected" if self.has_consumers() else "no recipient yet"
        lost = f" · lost {self.lost}" if self.lost else ""
        return [f"LSL {self.name} ({self.content})",
                f"{self.frames_sent} frames · {self.markers_sent} markers{lost} · {who}"]

    # ---- the thread --------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.wait(self.poll_s):
            self._drain()

    def _frame_host_time(self, frame: int) -> float | None:
        chunk = self.engine.read_since(frame, 1)
        return float(chunk.host_time[0]) if len(chunk) and chunk.start == frame else None

    def _drain(self) -> None:
        with self._push_lock:
            if self.frame_outlet is None:
                return
            self._push_frames()
            self._push_markers()
            if time.monotonic() - self._last_check >= self.clock_check_s:
                self._recheck_clock()

    def _push_frames(self) -> None:
        eng = self.engine
        while True:
            if self.content == DECODED and eng.baseline is None:
                return  # decoded frames need the first tare; they wait in the ring
            chunk = eng.read_since(self._cursor, MAX_CHUNK)
            if chunk.lost:
                self.lost += chunk.lost
                self._queue.append((time.time(), {"kind": "lsl_overrun", "source": "app",
                                                  "lost": chunk.lost, "frame": chunk.start}))
            if not len(chunk):
                return
            data = (decoded_channels(eng.layout, chunk.raw, eng.baseline)
                    if self.content == DECODED else chunk.raw)
            stamps = self.offset.to_lsl(chunk.host_time).tolist()
            self.frame_outlet.push_chunk(data, stamps)
            self.frames_sent += len(chunk)
            self._cursor = chunk.stop
            if len(chunk) < MAX_CHUNK:
                return

    def _push_markers(self) -> None:
        batch: list[tuple[float, dict[str, Any]]] = []
        for event in self.engine.events_since(self._event_cursor):
            self._event_cursor += 1
            marker = engine_marker(event)
            if marker is not None:
                batch.append((float(event["time"]), marker))
        while self._queue:  # each source in the order its markers happened
            batch.append(self._queue.popleft())
        for host_t, marker in batch:
            self.marker_outlet.push_sample([to_json(marker)], self.offset.to_lsl(host_t))
            self.markers_sent += 1

    def _recheck_clock(self) -> None:
        self._last_check = time.monotonic()
        new = measure_offset(self.pylsl.local_clock, host_clock=self.host_clock)
        if abs(new.offset_s - self.offset.offset_s) > CLOCK_TOLERANCE_S:
            self.offset = new
            self._clock_event(self._cursor, streaming=True)

    def _clock_event(self, from_frame: int, streaming: bool) -> None:
        o: ClockOffset = self.offset
        self.engine.add_event(
            LslClock(streaming=streaming, offset_s=o.offset_s, uncertainty_s=o.uncertainty_s,
                     measured_host_time=o.host_time, measured_lsl_time=o.lsl_time,
                     content=self.content, frame_stream=self.name,
                     frame_source_id=self.source_id, marker_stream=self.marker_name),
            frame=from_frame)


# ---- one streamer per engine, shared by the live window and the collection console ---------
_SHARED: dict[int, list[Any]] = {}
_SHARED_LOCK = threading.Lock()


def acquire_streamer(engine: LiveStream, decoded: bool = False) -> LslStreamer:
    """The running streamer of ``engine`` (started if none); pair with release_streamer."""
    with _SHARED_LOCK:
        entry = _SHARED.get(id(engine))
        if entry is None or entry[0] is not engine or not entry[1].running:
            entry = [engine, LslStreamer(engine, decoded=decoded).start(), 0]
            _SHARED[id(engine)] = entry
        entry[2] += 1
        return entry[1]


def release_streamer(streamer: LslStreamer) -> None:
    """Stop ``streamer`` when its last user lets go of it."""
    with _SHARED_LOCK:
        entry = _SHARED.get(id(streamer.engine))
        if entry is None or entry[1] is not streamer:
            streamer.stop()
            return
        entry[2] -= 1
        if entry[2] > 0:
            return
        del _SHARED[id(streamer.engine)]
    streamer.stop()
