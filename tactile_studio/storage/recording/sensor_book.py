"""What a recording books in the sensor logbook, kept outside the file writer.

The recorder writes a file and nothing else; every recording (the acquisition session,
a collection without one, the characterisation lab) is opened through
acquisition/file_sink.py, which looks the sensor up before it starts (:func:`sensor_metadata`)
and books its hours of use when it stops, however it stops (:func:`book_usage`). A damaged or
unwritable logbook never stops a recording: it is
said once and the file is recorded anyway.
"""

from __future__ import annotations

from typing import Any

from tactile_studio.devices.frame_stream import RecordableStream
from tactile_studio.errors import UserError
from tactile_studio.paths import text_path
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.storage.books.logbook_file import say_once
from tactile_studio.storage.recording.recorder import Recorder


def sensor_metadata(engine: RecordableStream,
                    metadata: dict[str, Any] | None) -> dict[str, Any]:
    """Session metadata with the sensor ID (given, else the device's own) and the ID of
    the sensor's active calibration in the logbook (so any later decode knows it)."""
    meta = dict(metadata or {})
    sensor = meta.get("sensor_id") or engine.sensor_id()
    meta["sensor_id"] = sensor
    if sensor and "calibration_id" not in meta:
        try:
            with Logbook() as book:
                book.ensure_sensor(sensor, engine.layout.name)
                meta["calibration_id"] = book.active_calibration(sensor)
        except UserError as exc:  # damaged or unwritable: never written into; said once
            say_once(f"sensor logbook not used for this recording: {exc}")
    return meta


def book_usage(recorder: Recorder) -> None:
    """Add a stopped recording's duration to its sensor's hours of use (once)."""
    if recorder.usage_booked:
        return
    recorder.usage_booked = True
    rate = float(recorder.engine.nominal_rate_hz or 0.0)
    if not recorder.sensor_id or rate <= 0 or recorder.recorded == 0:
        return
    try:
        with Logbook() as book:
            book.add_usage(recorder.sensor_id, recorder.recorded / rate,
                           text_path(recorder.path))
    except UserError as exc:  # the recording itself is safe on disk; say so (once), go on
        say_once(f"sensor logbook not used for this recording: {exc}")

