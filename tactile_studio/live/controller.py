"""The live screen's verbs (connect, tare, record, stream to LSL) over one device, engine
and recorder."""

from __future__ import annotations

import os
from typing import Any

from tactile_studio.devices.engine import ERROR, AcquisitionEngine
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import UserError
from tactile_studio.live.status import LiveStatus
from tactile_studio.storage.recorder import Recorder


class LiveController:
    """Connect/disconnect a device, tare, and record: the live screen's verbs, Qt-free."""

    def __init__(self) -> None:
        self.engine: AcquisitionEngine | None = None
        self.recorder: Recorder | None = None
        self.device_name: str | None = None
        self.settings: dict[str, Any] = {}
        self.lsl: Any = None              # the LslStreamer while streaming
        self.lsl_wanted = False
        self.lsl_error: str | None = None

    def connect(self, name: str, settings: dict[str, Any] | None = None) -> AcquisitionEngine:
        """Start streaming from a plugin. Bad settings raise SettingsError at once;
        failing to open shows later as ``engine.state == "error"``."""
        device = create_device(name, settings or {})
        self.disconnect()
        self.device_name, self.settings = name, dict(device.settings)
        self.engine = AcquisitionEngine(device)
        self._sync_lsl_quietly()  # before start: the connect event is a marker too
        self.engine.start()
        return self.engine

    def disconnect(self) -> None:
        self.stop_recording()
        if self.engine is not None:
            self.engine.stop()
        self._release_lsl()

    # ---- Lab Streaming Layer ----------------------------------------------------------
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

    def lsl_status(self) -> str:
        """Two short lines for the panel: what is streamed, or why not."""
        if self.lsl is not None:
            return "\n".join(self.lsl.status_lines())
        return self.lsl_error or ""

    def _start_lsl(self) -> None:
        from tactile_studio.streams.lsl_outlet import acquire_streamer

        if self.lsl is None or self.lsl.engine is not self.engine:
            self._release_lsl()
            self.lsl = acquire_streamer(self.engine)

    def _sync_lsl_quietly(self) -> None:
        self._release_lsl()
        if self.lsl_wanted:
            try:
                self._start_lsl()
            except UserError as exc:
                self.lsl_error = str(exc)

    def _release_lsl(self) -> None:
        lsl, self.lsl = self.lsl, None
        if lsl is not None:
            from tactile_studio.streams.lsl_outlet import release_streamer

            release_streamer(lsl)

    def tare(self) -> None:
        if self.engine is not None:
            self.engine.tare()

    def start_recording(self, path: str | os.PathLike,
                        metadata: dict[str, Any] | None = None) -> Recorder:
        """Record everything from now on into a new session file (SessionFileError)."""
        if self.engine is None or not self.engine.running:
            raise UserError("connect a device before recording")
        self.stop_recording()
        self.recorder = Recorder(self.engine, path, metadata).start()
        return self.recorder

    def stop_recording(self) -> str | None:
        """Finish the file; returns its path (None if nothing was recording)."""
        rec, self.recorder = self.recorder, None
        if rec is None:
            return None
        rec.stop()
        return str(rec.path)

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
