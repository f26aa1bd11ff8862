"""The HDF5 file as a sink: the one way anything opens and closes a recording's file.

The acquisition session (and through it every collection, protocol/collect.py) and the
characterisation lab record through :func:`open_file_sink` and
:func:`close_file_sink`, so every recording is told about its sensor the same way
(:func:`~tactile_studio.storage.recording.sensor_book.sensor_metadata`, before the first row) and
books its hours of use exactly once however it ends: its owner's stop, or the exit hook
closing a file left open (the recorder's on-stop callback;
:func:`~tactile_studio.storage.recording.sensor_book.book_usage` guards "once").
"""

from __future__ import annotations

import os
from typing import Any

from tactile_studio.devices.frame_stream import RecordableStream
from tactile_studio.errors import SessionFileError
from tactile_studio.storage.recording.recorder import Recorder
from tactile_studio.storage.recording.sensor_book import book_usage, sensor_metadata


def open_file_sink(engine: RecordableStream, path: str | os.PathLike[str],
                   metadata: dict[str, Any] | None = None, *, row_offset: int = 0,
                   base_counters: dict[str, Any] | None = None,
                   start: bool = True, overwrite: bool = False,
                   staged: bool = False) -> Recorder:
    """A recorder of ``engine`` into a new file at ``path`` (SessionFileError), told its
    sensor from the logbook and booking its hours when it stops. ``start=False`` leaves
    its thread to the caller (a resume copies the earlier file in first). The file is
    claimed for this recorder alone (``FileBusy`` when another writer has it; an
    existing file is replaced only with ``overwrite``; ``staged``: see SessionWriter)."""
    _not_its_own_source(engine, path)
    rec = Recorder(engine, path, sensor_metadata(engine, metadata), row_offset=row_offset,
                   base_counters=base_counters, overwrite=overwrite, staged=staged)
    rec.on_stop(book_usage)
    return rec.start() if start else rec


def _not_its_own_source(engine: RecordableStream, path: str | os.PathLike[str]) -> None:
    """A replay recording over the very file it plays (``record --device replay --set
    path=s.h5 --out s.h5 --force``) would replace the recording with a copy of however
    much of it was played: refused in one line, the file untouched."""
    source = (engine.device_info().get("settings") or {}).get("path")
    try:
        same = bool(source) and os.path.samefile(str(source), path)
    except OSError:  # either is missing: not the same file
        same = False
    if same:
        raise SessionFileError(f"{path}: is the file being replayed; record to another name")


def close_file_sink(rec: Recorder, discard: bool = False) -> None:
    """Finish the file (once: later calls do nothing); its hours of use are booked by the
    on-stop callback :func:`open_file_sink` registered, after every frame the close pulled.
    Only :func:`open_file_sink` makes a recording's recorder, so none lacks it.
    ``discard``: remove the file instead, while it is still claimed."""
    rec.stop(discard=discard)
