"""The recorder: a consumer thread that pulls everything from the engine into a file."""

from __future__ import annotations

import atexit
import logging
import os
import threading
import time
import weakref
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from tactile_studio.devices.frame_stream import RecordableStream, hold_frames
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_format import OVERRUN
from tactile_studio.storage.format.session_writer import SessionWriter, WriteFailed
from tactile_studio.storage.format.trials import TrialRecord

# Events that state something in force until the next one (the host->LSL clock offset of a
# running LSL outlet): a recording started later begins with the latest one, at its first
# row (row 0, or a resumed file's first new row).
CARRIED_EVENTS = ("lsl_clock",)

# Recorders whose file is open: closed cleanly if the interpreter exits while they run
# (their daemon thread would otherwise die mid-write during interpreter teardown).
_OPEN: weakref.WeakSet[Recorder] = weakref.WeakSet()


class Recorder:
    """Writes every frame and event the engine produces from now on to ``path``.

    Frames are pulled in chunks by cursor, so the recorder never slows a real-time
    device; if it ever falls a whole ring behind one, the lost frames are recorded as an
    ``overrun`` event and counted, never hidden. A device that can wait (a replay or the
    simulator at speed 0) waits for it instead (``AcquisitionEngine.hold``).

    The recorder owns the file's rows: :meth:`row_of` is the one place an engine frame
    becomes a file row, and everything else that goes into the file (trials, notes,
    runner events) goes through its methods. A resumed file already holds ``row_offset``
    rows (and ``base_counters``) from an earlier run: new frames go after them and the
    counters add up. Without :meth:`start` nothing runs in the background and
    :meth:`catch_up` pulls synchronously (tests, headless tools).
    """

    def __init__(self, engine: RecordableStream, path: str | os.PathLike,
                 metadata: dict[str, Any] | None = None, poll_s: float = 0.05,
                 flush_interval: float = 0.5, *, row_offset: int = 0,
                 base_counters: dict[str, Any] | None = None, overwrite: bool = False,
                 staged: bool = False) -> None:
        self.engine = engine
        self.row_offset = int(row_offset)
        self.base_counters = dict(base_counters or {})
        self.device_time_offset = 0.0  # added to the device's clock (a resume continues it)
        self._lock = threading.RLock()
        # the sensor comes in from outside (storage/recording/sensor_book.py looks it up in the
        # logbook): the writer never opens the logbook; else the device's own ID
        metadata = dict(metadata or {})
        metadata["sensor_id"] = metadata.get("sensor_id") or engine.sensor_id()
        self.sensor_id: str | None = metadata["sensor_id"]
        self.recorded = 0  # frames this recorder took from the engine (for hours of use)
        self.usage_booked = False  # set by storage/sensor_book.book_usage (once)
        self.background_compress = False  # stop() compresses on a worker thread
        # the file is claimed here: a second writer of it is refused before anything is
        # recorded (SessionWriter; ``overwrite``, ``staged`` as there)
        self.writer = SessionWriter(path, engine.layout, engine.device_info(), metadata,
                                    flush_interval=flush_interval, overwrite=overwrite,
                                    staged=staged)
        self.poll_s = poll_s
        self.dropped = 0
        # (first lost engine frame, first kept one after it, frames dropped before it)
        self._losses: list[tuple[int, int, int]] = []
        self._cursor = engine.frames
        self._event_cursor = engine.event_count
        self.start_counters = engine.counters()
        self._stop = threading.Event()
        # the first write error (one line: file and cause); the recorder then stops
        # writing, releases its hold and waits for stop() (see _drain)
        self.write_error: str | None = None
        self.started_at = time.time()  # wall clock, for "lost N s into the recording"
        self._counters_written: dict[str, Any] | None = None
        self.stopped_at: float | None = None
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)
        self._release: Callable[[], None] = lambda: None
        if engine.baseline is not None:  # in force from this recording's first row
            self.writer.add_baseline(engine.baseline, self.row_offset)
        self._carry_over()
        self._notes = [line for line in str(self.writer.metadata.get("notes", "")).split("\n")
                       if line]
        # (engine frame, kind, time, detail) of events at frames not pulled yet
        self._pending: list[tuple[int, str, float, dict[str, Any]]] = []
        self._end: int | None = None  # engine frame the file ends before (end_at)
        # a resume's (file's last device time, frame period, resume event detail),
        # written with the first frame (begin_segment)
        self._segment: tuple[float | None, float, dict[str, Any]] | None = None
        # called once, after the file is closed, however it stops (its owner, the exit
        # hook): the file sink books the hours of use there (acquisition/file_sink.py)
        self._on_stop: list[Callable[[Recorder], None]] = []
        self._closed = False
        _OPEN.add(self)

    @property
    def path(self) -> os.PathLike:
        return self.writer.path

    @property
    def start_frame(self) -> int:
        """Engine frame index that became file row ``row_offset`` (before any overrun)."""
        return int(self.start_counters["frames"])

    # ---- file rows ---------------------------------------------------------------------
    def row_of(self, engine_frame: int) -> int:
        """The file row engine frame ``engine_frame`` is (or will be) written to."""
        frame, before = int(engine_frame), self.dropped
        for first_lost, first_kept, dropped_before in reversed(self._losses):
            if frame >= first_kept:
                break
            before = dropped_before
            if frame >= first_lost:  # lost itself: the row of the next frame kept
                frame = first_lost
                break
        return max(0, frame - self.start_frame + self.row_offset - before)

    @property
    def rows_written(self) -> int:
        """Rows in the file now (earlier runs' rows included)."""
        return self.writer.n_frames

    def catch_up(self) -> None:
        """Write everything the engine holds now, at once (on the caller's thread)."""
        self._drain()

    def copy_earlier(self, old: SessionFile, chunk: int = 8192) -> list[dict[str, Any]]:
        """Copy everything an earlier file holds (frames, baselines, events, trials,
        counters) into this one, before any new row: a resume. ``row_offset`` must be
        its row count. Returns the copied trials."""
        n = old.n_frames
        if n != self.row_offset or self.recorded:
            raise ValueError(f"copy_earlier: {n} rows into a recorder with row_offset "
                             f"{self.row_offset} and {self.recorded} rows recorded")
        w = self.writer
        with self._lock:
            for a in range(0, n, chunk):
                b = min(n, a + chunk)
                w.append_frames(old.raw(a, b), old.column("device_time", a, b),
                                old.column("host_time", a, b), old.column("seq", a, b),
                                old.column("index", a, b))
            for base in old.journal.baselines:
                w.add_baseline(base["values"], base["frame"])
            for event in old.events:
                e = dict(event)
                kind, frame, t = e.pop("kind"), e.pop("frame", None), e.pop("time", None)
                w.add_event(kind, frame=frame, time_s=t, **e)
            trials = [dict(t) for t in old.journal.trials]  # copied as stored
            for t in trials:
                w.add_trial(t)
            if old.journal.counters:
                w.set_counters(old.journal.counters)
        return trials

    def begin_segment(self, after: float | None, period: float, **detail: Any) -> None:
        """A resume: this run is a new segment of the file from row ``row_offset``, and
        its ``resume`` event (``detail``, ``segment``, ``device_time_offset``) is written
        with the first frame, once the device's clock is known. A clock that started
        again (the simulator's, a replay's: at or before ``after``, the file's last
        device time) is shifted to go on one ``period`` after it, so the file keeps one
        clock; one that runs on by itself (host-stamped serial or BLE frames, LSL's
        timestamps) is kept, with the real time between the runs. Before any frame."""
        if self.recorded:
            raise ValueError("begin_segment: frames were already recorded")
        with self._lock:
            self._segment = (after, float(period), {"time_s": time.time(), **detail})

    def _start_segment(self, first_device_time: float | None) -> None:
        """Write the pending ``resume`` event, its offset chosen by this run's first
        device time (None: no frame came, nothing to shift)."""
        if self._segment is None:
            return
        after, period, detail = self._segment
        self._segment = None
        if after is not None and first_device_time is not None \
                and first_device_time <= after:
            self.device_time_offset = after + period - first_device_time
        self.writer.add_event("resume", frame=self.row_offset, segment=True,
                              device_time_offset=self.device_time_offset, **detail)

    def publish(self) -> None:
        """A staged file (a resume's copy) takes its name now and records on there."""
        with self._lock:
            self.writer.publish()

    # ---- what else goes into the file ----------------------------------------------------
    def add_event(self, kind: str, **detail: Any) -> None:
        """An event at the next row (runner and lab events; engine events come by
        themselves). ``time_s`` stamps it (default: now)."""
        with self._unless_failed():
            self.writer.add_event(kind, **detail)

    def event(self, kind: str, **detail: Any) -> None:
        """The sink verb (acquisition/sinks.py): an event a session gives its sinks is
        written at the next row, as :meth:`add_event`."""
        self.add_event(kind, **detail)

    def on_stop(self, fn: Callable[[Recorder], None]) -> None:
        """Call ``fn(self)`` once the file is closed, whoever stops it (the exit hook
        too); at once if it is stopped already."""
        with self._lock:
            if not self._closed:
                self._on_stop.append(fn)
                return
        fn(self)

    def end_at(self, engine_frame: int) -> None:
        """The file ends before engine frame ``engine_frame`` (a collection's end): later
        frames are not written, and a device that waits for this recorder is let go
        once it is reached. A simulator at speed 0 streams ahead of a finished runner,
        so without this a collection's length depended on the simulator's speed."""
        with self._lock:
            self._end = int(engine_frame)

    def add_event_at(self, engine_frame: int, kind: str, **detail: Any) -> None:
        """An event at engine frame ``engine_frame`` (the collection runner's: where it
        happened in the stream, not where writing has got to). Written with its file row
        once this recorder has pulled that frame, when frames lost before it are known."""
        with self._lock, self._unless_failed():
            if engine_frame < self._cursor or self.stopped:
                self.writer.add_event(kind, frame=self.row_of(engine_frame), **detail)
            else:
                self._pending.append((int(engine_frame), kind, time.time(), detail))

    def add_baseline(self, values: np.ndarray, row: int | None = None) -> None:
        """A baseline taken outside the engine, in force from ``row`` (default: the
        next row)."""
        with self._unless_failed():
            self.writer.add_baseline(values, row)

    def add_trial(self, trial: TrialRecord) -> TrialRecord:
        """Write a finished trial (rows ``start_sample..end_sample``) and flush.

        Catches up first, so the trial's rows are in the file before its record; rows
        that are not there (the ring overran the recorder) flag it ``dropped_frames``.
        Returns the record as written.
        """
        self.catch_up()
        if self.rows_written < trial.end_sample and "dropped_frames" not in trial.flags:
            trial = trial.with_changes(flags=(*trial.flags, "dropped_frames"))
        if self.device_time_offset:  # measured on the engine's clock: the file's is shifted
            trial = trial.with_changes(start_time=trial.start_time + self.device_time_offset,
                                       end_time=trial.end_time + self.device_time_offset)
        with self._unless_failed():
            self.writer.add_trial(trial.to_dict())
            self.writer.flush()
        return trial

    def update_trial(self, index: int, **changes: Any) -> None:
        """Change a written trial (its status, reason...) and flush."""
        with self._unless_failed():
            self.writer.update_trial(index, **changes)
            self.writer.flush()

    def add_note(self, text: str, **detail: Any) -> list[str]:
        """A ``note`` event plus the note appended to the metadata's ``notes`` (one per
        line); flushed. Returns all notes."""
        self._notes.append(text)
        with self._unless_failed():
            self.writer.add_event("note", text=text, **detail)
            self.writer.update_metadata(notes="\n".join(self._notes))
            self.writer.flush()
        return list(self._notes)

    def flush(self) -> None:
        with self._unless_failed():
            self.writer.flush()

    @contextmanager
    def _unless_failed(self) -> Iterator[None]:
        """Writes from the runner and the lab: after a write error they do nothing (the
        error is in ``write_error``, which the owner's poll reports); never raised into
        a runner mid-trial."""
        try:
            yield
        except WriteFailed as exc:
            if self.write_error is None:
                self.write_error = str(exc)

    def start(self) -> Recorder:
        """Pull in the background. A device that can wait for its reader (a replay or
        the simulator at speed 0) is held to this recorder's pace, so nothing is lost."""
        self._release = hold_frames(self.engine, lambda: self._cursor)
        self._thread.start()
        return self

    def stop(self, background_compress: bool | None = None, discard: bool = False) -> None:
        """Write what is left, then close the file cleanly (once; later calls do nothing).
        With ``background_compress`` (default: the attribute, which a GUI's session sets)
        the file is compressed on a worker thread (a GUI caller does not freeze; the
        complete uncompressed file is there meanwhile). ``discard``: the file is removed
        instead, under its claim (a recording that could not begin: no frame came)."""
        if background_compress is None:
            background_compress = self.background_compress
        if self.stopped:
            return
        self._stop.set()
        self.stopped_at = time.time()
        if self._thread.ident is not None:  # never started: catch_up() did the pulling
            self._thread.join()
        self._drain()
        with self._lock:
            if self.write_error is None:
                try:
                    self._start_segment(None)  # a resume that recorded no frame
                    self._write_pending(final=True)
                    if self._end is not None:  # pulled past the end before it was known
                        self.writer.truncate(self.row_of(self._end))
                except WriteFailed as exc:
                    self.write_error = str(exc)
        self._release()
        if discard:
            self.writer.discard()
        else:
            self.writer.close(background=background_compress)  # after a write error: none
        if self.write_error is None and self.writer.failed:  # the closing touches failed
            self.write_error = self.writer.failed
        _OPEN.discard(self)
        with self._lock:
            self._closed = True
            callbacks, self._on_stop = self._on_stop, []
        for fn in callbacks:
            fn(self)

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    @property
    def running(self) -> bool:
        """Its background thread is pulling frames (started, not stopped, no write
        error)."""
        return self._thread.is_alive() and self.write_error is None

    @property
    def state(self) -> str:
        """``write_error`` (the file could not be written; see ``write_error``),
        ``stopped``, ``running`` or ``idle`` (not started: the owner pulls)."""
        if self.write_error:
            return "write_error"
        if self.stopped:
            return "stopped"
        return "running" if self._thread.is_alive() else "idle"

    def _run(self) -> None:
        try:
            while not self._stop.wait(self.poll_s) and self.write_error is None:
                self._drain()
            self._release()  # a write error ends the pulling: never hold a device then
        except BaseException:
            self._release()  # a dead recorder must not stall a device that waits for it
            raise

    def _carry_over(self) -> None:
        latest: dict[str, dict[str, Any]] = {}
        for event in self.engine.events_since(0)[:self._event_cursor]:
            if event["kind"] in CARRIED_EVENTS:
                latest[event["kind"]] = event
        for kind, event in latest.items():
            if event.get("streaming", True):
                detail = {k: v for k, v in event.items() if k not in ("kind", "frame", "time")}
                # at this recording's first row (a resumed file's earlier rows were not
                # on that stream)
                self.writer.add_event(kind, frame=self.row_offset, time_s=event["time"],
                                      carried=True, **detail)

    def _drain(self) -> None:
        """Pull and write; the first write error is kept in ``write_error`` (not raised:
        the owner's poll sees it and stops the recording) and nothing is written after."""
        with self._lock:
            if self.write_error is not None:
                return
            try:
                self._drain_locked()
            except WriteFailed as exc:
                self.write_error = str(exc)

    def _drain_locked(self) -> None:
        self._pull_frames()
        for event in self.engine.events_since(self._event_cursor):
            self._event_cursor += 1
            event = dict(event)
            kind = event.pop("kind")
            frame = self.row_of(int(event.pop("frame")))
            if self._end is not None:  # after the file's end (before _end): its last row
                frame = min(frame, self.row_of(max(0, self._end - 1)))
            t = event.pop("time")
            if kind == "tare" and "baseline" in event:
                self.writer.add_baseline(event["baseline"], frame)
                event = {k: v for k, v in event.items() if k != "baseline"}
            if kind == "tare" and isinstance(event.get("first_frame"), int):
                # the rows it averaged, as its frame is a row (a resumed run's engine
                # counts from 0 again, where the file holds the earlier runs' rows)
                event["first_frame"] = self.row_of(event["first_frame"])
            self.writer.add_event(kind, frame=frame, time_s=t, **event)
        self._write_pending(final=False)
        counters = self._counters_since_start()
        if counters != self._counters_written:  # a journal line per change, not per poll
            self.writer.set_counters(counters)
            self._counters_written = counters
        self.writer.flush()

    def _pull_frames(self) -> None:
        """The engine's new frames into the file, up to its end (``end_at``). Once the
        file is complete nothing more is read: the ring lapping frames after the end is
        no loss of this file. Read on, the lap was counted as an overrun at every poll
        (the cursor stays at the end), and the doubled count moved the end's row back
        to row 0: an aborted collection's file was cut to no frames under load."""
        end = self._end
        if end is None or self._cursor < end:
            self._write_frames(end)
        if end is not None and self._cursor >= end:
            self._release()  # the file is complete: a waiting device may run on
            self._release = lambda: None

    def _write_frames(self, end: int | None) -> None:
        """Write what the ring holds from the cursor (up to ``end``); a loss is counted
        for the file's frames only."""
        chunk = self.engine.read_since(self._cursor,
                                       None if end is None else end - self._cursor)
        if chunk.lost:
            first_kept = chunk.start if end is None else min(chunk.start, end)
            self._losses.append((self._cursor, chunk.start, self.dropped))
            self.dropped += first_kept - self._cursor  # the file's frames only
            self.writer.add_event(OVERRUN, lost=first_kept - self._cursor)
            self._cursor = first_kept
        if len(chunk):
            if self._segment is not None:
                self._start_segment(float(chunk.device_time[0]))
            device_time = chunk.device_time
            if self.device_time_offset:
                device_time = device_time + self.device_time_offset
            self.writer.append_frames(chunk.raw, device_time, chunk.host_time,
                                      chunk.seq, index=np.arange(chunk.start, chunk.stop))
            self._cursor = chunk.stop
            self.recorded += len(chunk)

    def _write_pending(self, final: bool) -> None:
        """Events at frames pulled by now (``final``: all, the stream has ended)."""
        keep = []
        for frame, kind, t, detail in self._pending:
            if final or frame < self._cursor:
                if self._end is not None:  # the last row is the frame before _end
                    frame = min(frame, max(0, self._end - 1))
                self.writer.add_event(kind, frame=self.row_of(frame), time_s=t, **detail)
            else:
                keep.append((frame, kind, t, detail))
        self._pending = keep

    def _counters_since_start(self) -> dict[str, Any]:
        """The file's counters: this run's engine counters plus ``base_counters``."""
        now, start, base = self.engine.counters(), self.start_counters, self.base_counters
        by_kind = Counter(now["malformed_by_kind"])
        by_kind.subtract(start["malformed_by_kind"])
        merged = dict(base.get("malformed_by_kind", {}))
        for k, v in by_kind.items():
            if v > 0:
                merged[k] = merged.get(k, 0) + v
        run = {
            "gaps": now["gaps"] - start["gaps"],
            "missing_frames": now["missing_frames"] - start["missing_frames"],
            "reconnects": now["reconnects"] - start["reconnects"],
            "dropped": self.dropped,
        }
        return {"malformed_by_kind": merged,
                **{k: v + int(base.get(k, 0)) for k, v in run.items()}}


def running_recorders() -> list[Recorder]:
    """Recorders whose thread runs now (tests check none is left behind)."""
    return [r for r in list(_OPEN) if r.running]


@atexit.register
def _stop_open_recorders() -> None:
    """Exiting with a recording running: write what is left and close the file, so
    nothing recorded is lost and no recorder thread outlives the interpreter. Its
    on-stop callbacks run as for any stop (a file sink books its hours of use)."""
    for recorder in list(_OPEN):
        try:
            recorder.stop()
        except Exception:  # noqa: BLE001 - exiting anyway; the next file must still close
            logging.getLogger(__name__).exception("%s: not closed at exit", recorder.path)

