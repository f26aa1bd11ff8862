"""The recorder: a consumer thread that pulls everything from the engine into a file."""

from __future__ import annotations

import logging
import os
import threading
from collections import Counter
from typing import Any

import numpy as np

from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.errors import UserError
from tactile_studio.storage.logbook import Logbook
from tactile_studio.storage.session_writer import SessionWriter

# Events that state something in force until the next one (the host->LSL clock offset of a
# running LSL outlet): a recording started later begins with the latest one, at row 0.
CARRIED_EVENTS = ("lsl_clock",)


class Recorder:
    """Writes every frame and event the engine produces from now on to ``path``.

    Frames are pulled in chunks by cursor, so the recorder never slows the device
    thread; if it ever falls a whole ring behind, the lost frames are recorded as an
    ``overrun`` event and counted, never hidden.
    """

    def __init__(self, engine: AcquisitionEngine, path: str | os.PathLike,
                 metadata: dict[str, Any] | None = None, poll_s: float = 0.05,
                 flush_interval: float = 0.5) -> None:
        self.engine = engine
        metadata = sensor_metadata(engine, metadata)
        self.sensor_id: str | None = metadata.get("sensor_id")
        self.recorded = 0  # frames this recorder took from the engine (for hours of use)
        self.writer = SessionWriter(path, engine.layout, engine.device.info(), metadata,
                                    flush_interval=flush_interval)
        self.poll_s = poll_s
        self.dropped = 0
        self._cursor = engine.frames
        self._event_cursor = engine.event_count
        self.start_counters = engine.counters()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)
        if engine.baseline is not None:
            self.writer.add_baseline(engine.baseline, 0)
        self._carry_over()

    @property
    def path(self) -> os.PathLike:
        return self.writer.path

    @property
    def start_frame(self) -> int:
        """Engine frame index that became file row 0 (before any overrun)."""
        return int(self.start_counters["frames"])

    def start(self) -> Recorder:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Write what is left, then close the file cleanly."""
        self._stop.set()
        self._thread.join()
        self._drain()
        self.writer.close()
        self._log_usage()

    def _log_usage(self) -> None:
        """Add this recording's duration to the sensor's hours of use in the logbook."""
        rate = float(self.engine.device.nominal_rate_hz or 0.0)
        if not self.sensor_id or rate <= 0 or self.recorded == 0:
            return
        try:
            with Logbook() as book:
                book.add_usage(self.sensor_id, self.recorded / rate, str(self.path))
        except UserError as exc:  # the recording itself is safe on disk; say so and go on
            logging.getLogger(__name__).warning("hours of use not logged: %s", exc)

    def _run(self) -> None:
        while not self._stop.wait(self.poll_s):
            self._drain()

    def _carry_over(self) -> None:
        latest: dict[str, dict[str, Any]] = {}
        for event in self.engine.events_since(0)[:self._event_cursor]:
            if event["kind"] in CARRIED_EVENTS:
                latest[event["kind"]] = event
        for kind, event in latest.items():
            if event.get("streaming", True):
                detail = {k: v for k, v in event.items() if k not in ("kind", "frame", "time")}
                self.writer.add_event(kind, frame=0, time_s=event["time"], carried=True, **detail)

    def _engine_to_row(self, frame: int) -> int:
        return max(0, frame - self.start_frame - self.dropped)

    def _drain(self) -> None:
        chunk = self.engine.read_since(self._cursor)
        if chunk.lost:
            self.dropped += chunk.lost
            self.writer.add_event("overrun", lost=chunk.lost)
        if len(chunk):
            self.writer.append_frames(chunk.raw, chunk.device_time, chunk.host_time,
                                      chunk.seq, index=np.arange(chunk.start, chunk.stop))
            self._cursor = chunk.stop
            self.recorded += len(chunk)
        for event in self.engine.events_since(self._event_cursor):
            self._event_cursor += 1
            event = dict(event)
            kind = event.pop("kind")
            frame = self._engine_to_row(int(event.pop("frame")))
            t = event.pop("time")
            if kind == "tare" and "baseline" in event:
                self.writer.add_baseline(event["baseline"], frame)
                event = {k: v for k, v in event.items() if k != "baseline"}
            self.writer.add_event(kind, frame=frame, time_s=t, **event)
        self.writer.set_counters(self._counters_since_start())
        self.writer.flush()

    def _counters_since_start(self) -> dict[str, Any]:
        now, start = self.engine.counters(), self.start_counters
        by_kind = Counter(now["malformed_by_kind"])
        by_kind.subtract(start["malformed_by_kind"])
        return {
            "malformed_by_kind": {k: v for k, v in by_kind.items() if v > 0},
            "gaps": now["gaps"] - start["gaps"],
            "missing_frames": now["missing_frames"] - start["missing_frames"],
            "reconnects": now["reconnects"] - start["reconnects"],
            "dropped": self.dropped,
        }


def sensor_metadata(engine: AcquisitionEngine,
                    metadata: dict[str, Any] | None) -> dict[str, Any]:
    """Session metadata with the sensor ID (given, else the device's own) and the ID of
    the sensor's active calibration in the logbook (so any later decode knows it)."""
    meta = dict(metadata or {})
    sensor = meta.get("sensor_id") or getattr(engine.device, "sensor_id", lambda: None)()
    meta["sensor_id"] = sensor
    if sensor and "calibration_id" not in meta:
        try:
            with Logbook() as book:
                book.ensure_sensor(sensor, engine.layout.name)
                meta["calibration_id"] = book.active_calibration(sensor)
        except UserError as exc:
            logging.getLogger(__name__).warning("sensor logbook unavailable: %s", exc)
    return meta
