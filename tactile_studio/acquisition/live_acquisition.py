"""One acquisition session: device + engine + its sinks (the file, LSL outlets).

Every place that acquires (the main window, ``record``, ``collect`` and the collection
console) wires the stream through this class, so they all start in the same order and
stop recording for the same reasons. Widgets are handed a session (as pymmcore-plus
hands widgets their core): they call its verbs and listen to its events; they never
build engines or recorders themselves.

The start order (docs/runner-api.md, "Acquisition session"):

1. :meth:`open` (or :meth:`use_device`) makes the device and its engine, not started;
2. :meth:`start_recording` (or ``open_collection(CollectionSettings(...), acquisition)``)
   makes the recorder *before* any frame, so file rows equal engine frames and the
   connect and first tare events are in the file;
3. :meth:`set_lsl` / :meth:`add_outlet`: the outlets see the connect event too;
4. :meth:`start` starts the engine.

:meth:`connect` is 1 + 3 + 4 (the live screen records later, from the running stream).
A session can also :meth:`share` an engine someone else started (the console on the
main window's stream): then it never stops that engine.

Qt-free and thread-free: the owner calls :meth:`poll` a few times a second (a GUI timer,
the CLI's loop); that is where auto-stop happens (a time or frame limit, the device
lost) and where listeners hear about it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

from tactile_studio.acquisition.events import (
    AcquisitionEvent,
    Connected,
    Disconnected,
    Health,
    Listener,
    RecordingStarted,
    RecordingStopped,
    StateChanged,
)
from tactile_studio.acquisition.file_sink import close_file_sink, open_file_sink
from tactile_studio.acquisition.marker_recording import MarkerRecording
from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.acquisition.outcome import RecordingOutcome, outcome_of
from tactile_studio.acquisition.sinks import FILE, OUTLET, PUBLISHING, LslPublishing, SinkList
from tactile_studio.acquisition.status import LiveStatus
from tactile_studio.acquisition.stream_health import DEFAULT_SILENCE_S, StreamHealth
from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.devices.frame_stream import ERROR, EngineState, LiveStream
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import UserError
from tactile_studio.storage.recording.recorder import Recorder


class LiveAcquisition:
    """Device, engine, recorder and outlets of one acquisition (see the module doc).

    Events (``add_listener``), all emitted on the caller's thread, are declared once in
    :mod:`tactile_studio.acquisition.events`: :class:`Connected`, :class:`Disconnected`,
    :class:`StateChanged` (seen by :meth:`poll`), :class:`RecordingStarted`,
    :class:`RecordingStopped` (with its reason and
    :class:`~tactile_studio.acquisition.outcome.RecordingOutcome`) and :class:`Health`
    (the device went silent while recording, or came back).
    """

    #: a recording warns (event ``health``) when the device is silent this long
    silence_warning_s = DEFAULT_SILENCE_S
    #: LSL marker streams (by name) recorded with every recording (``gui --markers``)
    marker_streams: tuple[str, ...] = ()

    def __init__(self, *, capacity: int = 1 << 16,
                 clock: Callable[[], float] = time.monotonic,
                 compress_in_background: bool = False) -> None:
        self.capacity = capacity
        # the main window's session compresses a stopped recording on a worker thread
        # (stopping a recording must not freeze the window)
        self.compress_in_background = compress_in_background
        self.clock = clock
        self.engine: LiveStream | None = None
        self.recorder: Recorder | None = None
        self.device_name: str | None = None
        self.settings: dict[str, Any] = {}
        self.lsl_wanted = False
        self.lsl_error: str | None = None
        self._owns_engine = False
        # the sinks in stop order (acquisition/sinks.py): outlets, the file, LSL publishing
        self.sinks = SinkList()
        self._listeners: list[Listener] = []
        self._seen_state: str | None = None
        self._stop_at: float | None = None
        self._stop_rows: int | None = None
        self._stop_all = False
        self._health: StreamHealth | None = None
        self._markers: MarkerRecording | None = None
        #: how the last recording ended (set when it stops; acquisition/outcome.py)
        self.outcome: RecordingOutcome | None = None

    # ---- events ------------------------------------------------------------------------
    def add_listener(self, fn: Listener) -> Callable[[], None]:
        """Call ``fn(event)`` for every event; returns a function that unsubscribes."""
        self._listeners.append(fn)
        return lambda: fn in self._listeners and self._listeners.remove(fn)

    def _emit(self, event: AcquisitionEvent) -> None:
        for fn in list(self._listeners):
            fn(event)

    # ---- the device and its engine -------------------------------------------------------
    def open(self, name: str, settings: dict[str, Any] | None = None) -> LiveStream:
        """Make device ``name`` and its engine, not started yet (step 1). Bad settings
        raise SettingsError at once; failing to open shows later as the ``error`` state."""
        device = create_device(name, settings or {})
        return self.use_device(device, name)

    def use_device(self, device: DevicePlugin, name: str | None = None) -> LiveStream:
        """Like :meth:`open` for a device made elsewhere (a CLI that checks it first)."""
        self.disconnect()
        self.device_name = name or device.name
        self.settings = dict(device.settings)
        self.engine = open_stream(device, capacity=self.capacity)
        self._owns_engine = True
        self._seen_state = None
        return self.engine

    def share(self, engine: LiveStream, name: str | None = None) -> LiveStream:
        """Acquire from an engine someone else owns (and keeps running after us)."""
        self.disconnect()
        self.engine, self.device_name = engine, name
        self._owns_engine = False
        self._seen_state = None
        return engine

    def start(self) -> LiveStream:
        """Start the engine (step 4): after the recorder and outlets that want its first
        frames and its connect event."""
        if self.engine is None:
            raise RuntimeError("open a device before starting the session")
        if self._owns_engine and self.engine.state == EngineState.IDLE:
            self.engine.start()
            self._emit(Connected(self.device_name))
        return self.engine

    def connect(self, name: str, settings: dict[str, Any] | None = None) -> LiveStream:
        """Open, publish on LSL if wanted, and start: the live screen's Connect."""
        self.open(name, settings)
        self._sync_lsl_quietly()  # before start: the connect event is a marker too
        return self.start()

    @property
    def running(self) -> bool:
        return self.engine is not None and self.engine.running

    def disconnect(self, reason: str = "requested") -> None:
        """The stop order: the engine (if ours), so its last frames and its disconnect
        event reach the file; the outlets, so their end does too; then the recording."""
        engine, owned = self.engine, self._owns_engine
        if engine is not None and owned:
            engine.stop()
        self._close_outlets()
        self.stop_recording(reason)
        self._release_lsl()
        if engine is not None and owned:
            self._emit(Disconnected(self.device_name))

    close = disconnect

    def tare(self) -> None:
        if self.engine is not None:
            self.engine.tare()

    # ---- recording -----------------------------------------------------------------------
    def start_recording(self, path: str | os.PathLike, metadata: dict[str, Any] | None = None,
                        *, row_offset: int = 0, base_counters: dict[str, Any] | None = None,
                        start: bool = True, overwrite: bool = False,
                        staged: bool = False) -> Recorder:
        """Record everything from now on into a new session file (SessionFileError).

        Before :meth:`start` the file begins with the stream's first frame (step 2); on
        a running stream it begins now. ``start=False`` leaves the recorder's thread to
        the caller (a resume copies the earlier file in first). The file is this
        recording's alone (``FileBusy`` while another writer has it); one that exists is
        replaced only with ``overwrite`` (``staged``: see SessionWriter).
        """
        if self.engine is None or (self.engine.state != EngineState.IDLE
                                   and not self.engine.running):
            raise UserError("connect a device before recording")
        self.stop_recording()
        self._stop_at = self._stop_rows = None
        self.recorder = open_file_sink(self.engine, path, metadata, row_offset=row_offset,
                                       base_counters=base_counters, start=False,
                                       overwrite=overwrite, staged=staged)
        self.recorder.background_compress = self.compress_in_background
        self.sinks.add(self.recorder, FILE)
        if start:
            self.recorder.start()
        self._health = StreamHealth(self.engine, self.device_name, self.silence_warning_s,
                                    self.clock)
        self._markers = None
        if self.marker_streams:  # after the recorder, so their start is in the file
            try:
                self._markers = self.add_outlet(MarkerRecording(self.engine,
                                                                self.marker_streams))
            except UserError:  # a named stream is missing: no recording, no empty file
                self.stop_recording("requested", discard=True)
                raise
        self._emit(RecordingStarted(str(path)))
        return self.recorder

    def stop_recording_after(self, seconds: float | None = None, frames: int | None = None,
                             *, disconnect: bool = False) -> None:
        """Auto-stop the recording ``seconds`` from now or once the file holds ``frames``
        rows, whichever comes first (checked by :meth:`poll`). With ``disconnect`` the
        whole session stops then, in the stop order (``record --seconds``)."""
        self._stop_at = None if seconds is None else self.clock() + float(seconds)
        self._stop_rows = None if frames is None else int(frames)
        self._stop_all = disconnect
        rec = self.recorder
        if frames is not None and rec is not None:  # exactly: a fast device overshot a poll
            rec.end_at(rec.start_frame + max(0, int(frames) - rec.row_offset))

    def stop_recording(self, reason: str = "requested", discard: bool = False) -> str | None:
        """Finish the file; returns its path (None if nothing was recording).
        ``discard``: remove it instead, while it is still this recording's (one that
        could not begin: no frame came, a named stream is missing)."""
        rec, self.recorder = self.recorder, None
        self._stop_at = self._stop_rows = None
        self._health = None
        if rec is None:
            return None
        self._close_outlets()  # an outlet's last markers go into the file too
        # idempotent: a collection session may have closed it already; the hours of
        # use are booked with it (acquisition/file_sink.py), never by the file writer
        self.sinks.remove(rec)
        close_file_sink(rec, discard=discard)
        eng = self.engine
        self.outcome = outcome_of(rec, eng.reconnect_attempts if eng is not None else None)
        if rec.write_error:
            reason = "write_error"
        self._emit(RecordingStopped(str(rec.path), reason,
                                    "" if self.outcome.complete else self.outcome.line,
                                    self.outcome))
        return str(rec.path)

    @property
    def recording(self) -> bool:
        return self.recorder is not None

    def add_event(self, kind: str, **detail: Any) -> None:
        """An application event for every sink that takes events (acquisition/sinks.py):
        stamped once here (``time_s``, host time) so the file and the LSL markers carry
        the same instant. Engine events (connect, tare, markers fed into the engine)
        need not come here: every sink pulls those from the engine itself."""
        detail.setdefault("time_s", time.time())
        self.sinks.event(kind, **detail)

    # ---- polling: state changes and auto-stop ------------------------------------------------
    def check_health(self) -> None:
        """``health`` events for a recording's device gone silent (or back) and a marker
        stream gone: part of :meth:`poll`, and alone for an owner that stops the recording
        itself (headless collection aborts its runner first, so the abort is in the file)."""
        health = self._health
        if self.recorder is None:
            return
        for message in health.check() if health is not None else []:
            self._emit(Health(message, health.silent))
        for message in self._markers.messages() if self._markers is not None else []:
            self._emit(Health(message, True))

    def poll(self) -> None:
        """Notice engine state changes and stop a recording that is due: its limit is
        reached, or the stream ended (error, finished, stopped: close the file safely)."""
        eng = self.engine
        if eng is None:
            return
        if eng.state != self._seen_state:
            self._seen_state = eng.state
            self._emit(StateChanged(EngineState(eng.state)))
        rec = self.recorder
        if rec is None:
            return
        self.check_health()
        if rec.write_error:  # the file cannot be written: stop now, never "running"
            if self._stop_all:
                self.disconnect("write_error")
            else:
                self.stop_recording("write_error")
        elif rec.stopped:  # closed by its other user (a collection session's close())
            self.stop_recording()
        elif EngineState(eng.state).is_over:
            self.stop_recording("device")
        elif ((self._stop_at is not None and self.clock() >= self._stop_at)
              or (self._stop_rows is not None and rec.rows_written >= self._stop_rows)):
            if self._stop_all:
                self.disconnect("limit")
            else:
                self.stop_recording("limit")

    # ---- outlets (Lab Streaming Layer) -----------------------------------------------------
    def add_outlet(self, outlet: Any) -> Any:
        """An outlet made by the caller (anything with ``stop()``): stopped before the
        recording closes, so its end is in the file."""
        return self.sinks.add(outlet, OUTLET)

    def close_outlets(self) -> None:
        """Stop the outlets added with :meth:`add_outlet` now (before closing a
        collection session's file, so their end is recorded in it)."""
        self._close_outlets()

    def _close_outlets(self) -> None:
        self.sinks.stop(OUTLET)

    def set_lsl(self, on: bool) -> None:
        """Publish the device on LSL now and after every (re)connect; LslUnavailable
        (one line) if liblsl cannot be loaded."""
        self.lsl_wanted, self.lsl_error = bool(on), None
        if not on:
            self._release_lsl()
            return
        try:
            from tactile_studio.streams import load_pylsl

            load_pylsl()  # say so now, even before a device is connected
        except UserError:
            self.lsl_wanted = False
            raise
        if self.engine is not None and self.engine.state != "stopped":
            try:
                self._start_lsl()
            except UserError:
                self.lsl_wanted = False
                raise

    @property
    def lsl(self) -> Any:
        """The shared LslStreamer while the device is published on LSL, else None."""
        publishing = self.sinks.of_rank(PUBLISHING)
        return publishing[0].streamer if publishing else None

    def lsl_status(self) -> str:
        """Two short lines for the panel: what is streamed, or why not."""
        if self.lsl is not None:
            return "\n".join(self.lsl.status_lines())
        return self.lsl_error or ""

    def _start_lsl(self) -> None:
        engine = self.engine
        assert engine is not None, "publishing on LSL needs a device"  # callers check
        if self.lsl is None or self.lsl.engine is not engine:
            self._release_lsl()
            self.sinks.add(LslPublishing(engine).start(), PUBLISHING)

    def _sync_lsl_quietly(self) -> None:
        self._release_lsl()
        if self.lsl_wanted:
            try:
                self._start_lsl()
            except UserError as exc:
                self.lsl_error = str(exc)

    def _release_lsl(self) -> None:
        self.sinks.stop(PUBLISHING)

    # ---- status ----------------------------------------------------------------------------
    def status(self) -> LiveStatus:
        eng = self.engine
        if eng is None:
            return LiveStatus(None, "disconnected", None)
        c = eng.counters()
        rec = self.recorder
        return LiveStatus(
            device=self.device_name, state=eng.state,
            error=eng.error if eng.state == ERROR else None,
            frames=c["frames"], measured_rate_hz=eng.measured_rate_hz(),
            device_rate_hz=eng.device_rate_hz(), malformed=c["malformed"],
            malformed_by_kind=c["malformed_by_kind"],
            dropped=c["missing_frames"] + (rec.dropped if rec else 0), gaps=c["gaps"],
            reconnects=c["reconnects"], reconnect_attempts=eng.reconnect_attempts,
            recording=str(rec.path) if rec else None,
            recorded_frames=rec.rows_written if rec else 0)
