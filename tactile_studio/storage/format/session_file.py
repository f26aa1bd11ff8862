"""Reading session files, including ones whose writer was killed mid-recording."""

from __future__ import annotations

import hashlib
import os
import uuid
from collections import Counter
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tactile_studio.errors import SessionFileError
from tactile_studio.sensor.decode import compute_baseline
from tactile_studio.sensor.layout import Layout, get_layout
from tactile_studio.storage.format.aux_signals import AuxSignal, read_aux
from tactile_studio.storage.format.file_guards import check_frames, check_regular_file, check_stored
from tactile_studio.storage.format.segments import segment_starts, segmented_rate_hz
from tactile_studio.storage.format.session_compress import read_rows
from tactile_studio.storage.format.session_format import (  # noqa: F401
    FORMAT,
    OVERRUN,
    Journal,
    read_journal,
)
from tactile_studio.storage.format.session_recover import (
    cut_short_rows,
    open_cut_short,
    written_rows,
)
from tactile_studio.storage.format.trial_checks import check_counts
from tactile_studio.storage.format.trials import TrialRecord, collection_progress, label_order

# Namespace of the derived session ids (uuid5): imports and files from before ids existed.
SESSION_ID_NAMESPACE = uuid.UUID("6f1d7c52-3a7e-4b8e-9f59-2c1b1e0a7d11")
FINGERPRINT_FRAMES = 64


def user_block(block: Any) -> int:
    """The block number users see: blocks count from 1, practice is block 0.

    The journal keeps the runner's own numbering (0-based, practice -1); every
    user-facing output (console, ``info``, ``info --json``, NPZ and CSV exports)
    goes through this function.
    """
    try:
        b = int(block)
    except (TypeError, ValueError):
        return 0
    return b + 1 if b >= 0 else 0


def _user_blocks(record: dict[str, Any]) -> dict[str, Any]:
    out = dict(record)
    for key in ("block", "after_block"):
        if key in out and out[key] is not None:
            out[key] = user_block(out[key])
    return out


def measured_rate_hz(times: np.ndarray) -> float:
    """Frames per second over a recording of one segment: (frames - 1) / time spanned; 0
    when it cannot be measured (the importers' and the XDF export's device metadata)."""
    return segmented_rate_hz(times, [])


def derived_session_id(text: str) -> str:
    """A stable session id (uuid5) for ``text``: the same input gives the same id."""
    return str(uuid.uuid5(SESSION_ID_NAMESPACE, text))


_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def _check_not_truncated(path: Path) -> str:
    """Compare the superblock's end-of-file address with the real size: "" or why the
    file is short ("truncated (...)").

    A truncated file must be caught before h5py opens it: an SWMR reader retries
    reading damaged metadata for a long time instead of failing. A recording cut short
    by a full disk is short too; storage/format/session_recover.py opens it with bounded retries.
    """
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(96)
    if head[:8] != _SIGNATURE:
        raise SessionFileError(f"{path}: not an HDF5 file (corrupt or not a session)")
    version = head[8]
    if version >= 2:
        off = head[9]
        eof_at = 12 + 2 * off
    else:
        off = head[13]
        eof_at = 24 + (4 if version == 1 else 0) + 2 * off
    if off not in (4, 8) or len(head) < eof_at + off:
        raise SessionFileError(f"{path}: damaged HDF5 superblock")
    eof = int.from_bytes(head[eof_at:eof_at + off], "little")
    if size < eof:
        return f"{path}: truncated ({size} of {eof} bytes present)"
    return ""


def _open_h5(path: Path) -> h5py.File:
    if not path.exists():
        raise SessionFileError(f"{path}: no such file")
    if path.is_dir():
        raise SessionFileError(f"{path}: is a folder, not a session file")
    check_regular_file(path)  # a FIFO or device would block or never end
    short = _check_not_truncated(path)
    if short:  # a recording cut short by a failed write opens; a damaged file does not
        f = open_cut_short(path)
        if f is None:
            raise SessionFileError(short)
        return f
    try:
        return h5py.File(path, "r", locking=False)
    except OSError as exc:
        first = str(exc)
    try:  # a writer killed mid-recording leaves the SWMR "open for write" flag set
        return h5py.File(path, "r", swmr=True, locking=False)
    except OSError:
        pass
    if "signature" in first or "file signature" in first:
        raise SessionFileError(f"{path}: not an HDF5 file (corrupt or not a session)") from None
    raise SessionFileError(f"{path}: cannot be read, truncated or corrupt HDF5") from None


class SessionFile:
    """A session file opened for reading. Use as a context manager or call ``close``."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self._f = _open_h5(self.path)
        # ends before its recorded end: a recording cut short by a failed write
        self.cut_short = bool(_check_not_truncated(self.path))
        try:
            self._check_and_load()
        except SessionFileError:
            self._f.close()
            raise
        except (OSError, KeyError, ValueError, RuntimeError) as exc:
            self._f.close()
            raise SessionFileError(f"{self.path}: damaged session file ({exc})") from None

    def _check_and_load(self) -> None:
        f = self._f
        if f.attrs.get("format") != FORMAT:
            raise SessionFileError(f"{self.path}: HDF5 file but not a Tactile Studio session")
        if "frames/raw" not in f:
            raise SessionFileError(f"{self.path}: session has no frames dataset")
        if self.cut_short:  # rows grown but never stored: counted out, not refused
            stored = cut_short_rows(f, self.path)
        else:
            check_stored(f, self.path)  # claims backed by stored data, before any read
        self.journal = read_journal(f)
        self._trials: list[TrialRecord] | None = None
        self.schema_version = int(f.attrs.get("schema_version", 0))
        cols = [f["frames/raw"].shape[0]] + [
            f[f"frames/{n}"].shape[0] for n in ("device_time", "host_time", "seq", "index")]
        # After a crash the columns may be one flush apart: trust the shortest.
        self.n_frames = int(min(cols))
        if self.cut_short:
            self.n_frames = min(self.n_frames, stored)
        if not self.journal.closed and self.n_frames:  # rows allocated, never written
            self.n_frames = written_rows(f["frames/host_time"], f["frames/raw"], self.n_frames)
        layout_name = self.journal.metadata.get("layout", {}).get("name") or f.attrs.get("layout")
        if not layout_name:
            raise SessionFileError(f"{self.path}: session metadata names no layout")
        self.layout: Layout = get_layout(str(layout_name))
        check_frames(f, self.path, self.layout)

    # ---- context manager -------------------------------------------------------------
    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> SessionFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- data ------------------------------------------------------------------------
    @property
    def metadata(self) -> dict[str, Any]:
        return self.journal.metadata

    @property
    def events(self) -> list[dict[str, Any]]:
        return self.journal.events

    @property
    def trials(self) -> list[TrialRecord]:
        """The trials as typed records (``journal.trials`` keeps the file's own dicts, for
        what checks or copies the file form)."""
        if self._trials is None:
            read = []
            for t in self.journal.trials:
                try:
                    read.append(TrialRecord.from_dict(t))
                except (TypeError, ValueError) as exc:  # `check` names each problem
                    raise SessionFileError(f"{self.path}: trial {t.get('index', '?')}: {exc}"
                                           " (tactile-studio check names what is wrong)"
                                           ) from None
            self._trials = read
        return self._trials

    @property
    def session_id(self) -> str:
        """The id in the metadata; for files written before ids existed, one derived
        from what a resume copies unchanged (creation time, participant, the first
        frames), so a file, its copies and its resume backups share it."""
        sid = self.metadata.get("session_id")
        if sid:
            return str(sid)
        n = min(self.n_frames, FINGERPRINT_FRAMES)
        h = hashlib.sha256()
        for key in ("created", "participant", "source"):
            h.update(f"{key}={self.metadata.get(key, '')};".encode())
        h.update(np.ascontiguousarray(self.raw(0, n)).tobytes())
        h.update(np.ascontiguousarray(self.column("device_time", 0, n)).tobytes())
        return derived_session_id(f"fingerprint:{h.hexdigest()}")

    @property
    def recording(self) -> str:
        """What the recording is by content: a digest of the layout, the frame count and
        the raw counts of the first and last frames. A session re-imported from its own
        export (a new ``session_id``: the importer's, from the exported file) has the
        same frames, so the same digest; two recordings never do (sensor noise)."""
        n = self.n_frames
        h = hashlib.sha256(f"{self.layout.name};{n};".encode())
        h.update(np.ascontiguousarray(self.raw(0, min(n, FINGERPRINT_FRAMES))).tobytes())
        h.update(np.ascontiguousarray(self.raw(max(0, n - FINGERPRINT_FRAMES), n)).tobytes())
        return h.hexdigest()[:32]

    def aux_signals(self) -> list[AuxSignal]:
        """Other instruments' signals kept beside the touch (storage/format/aux_signals.py)."""
        return read_aux(self._f)

    @property
    def closed_cleanly(self) -> bool:
        return self.journal.closed

    def raw(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        stop = self.n_frames if stop is None else min(stop, self.n_frames)
        return self._read("frames/raw", start, stop)

    def column(self, name: str, start: int = 0, stop: int | None = None) -> np.ndarray:
        """One of device_time, host_time, seq, index."""
        stop = self.n_frames if stop is None else min(stop, self.n_frames)
        return self._read(f"frames/{name}", start, stop)

    def _read(self, name: str, start: int, stop: int) -> np.ndarray:
        """Rows of a dataset; more than memory holds is one line, not a MemoryError."""
        ds = self._f[name]
        try:
            return read_rows(ds, start, stop)
        except MemoryError:
            n = max(0, stop - max(0, start))
            size = n * ds.dtype.itemsize * int(np.prod(ds.shape[1:]))
            raise SessionFileError(f"{self.path}: {name} rows {start}-{stop} "
                                   f"({size / 2**30:.1f} GiB) do not fit in memory") from None
        except OSError as exc:  # HDF5 cannot read or inflate a chunk: damaged on disk
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise SessionFileError(f"{self.path}: {name} rows {start}-{stop} cannot be read, "
                                   f"the file is damaged ({first[:100]})") from None

    def baseline(self, row: int = 0) -> np.ndarray:
        """The baseline in force at ``row``: the one recorded at the latest row at or
        before it (the later one of two at a row), else the one at the earliest row, else
        the mean of the first 100 frames. By rows, not by when it was written: a resume
        writes the new run's baseline before it copies the earlier run's."""
        numbered = list(enumerate(self.journal.baselines))  # (write order, record)
        before = [(b["frame"], i, b) for i, b in numbered if b["frame"] <= row]
        chosen = (max(before, key=lambda x: x[:2])[2] if before else
                  min(((b["frame"], i, b) for i, b in numbered), key=lambda x: x[:2],
                      default=(0, 0, None))[2])
        if chosen is not None:
            return np.asarray(chosen["values"], dtype=np.float64)
        if self.n_frames == 0:
            raise SessionFileError(f"{self.path}: session has no frames to take a baseline from")
        return compute_baseline(self.raw(0, 100))

    # ---- summary ---------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        """What ``tactile-studio info --json`` prints."""
        n = self.n_frames
        duration = rate = 0.0
        # a resume starts a new segment: measured within segments, the time between two
        # runs of the device is no frame time (docs/session-format.md, "Segments")
        resumes = [e["frame"] for e in segment_starts(self.events, n)]
        # so is the time a device was gone before it reconnected (the frames after the
        # outage start at the reconnect's frame): 32 Hz for a 43 Hz sensor otherwise;
        # and every other gap, at the frame after it: frames a device skipped (sequence
        # numbers), a pause an import found in the timestamps (cause xdf, import)
        outages = [e["frame"] for e in self.events if isinstance(e.get("frame"), int)
                   and e.get("kind") in ("reconnect", "gap")]
        if n >= 2:
            rate = segmented_rate_hz(self.column("device_time", 0, n), resumes + outages)
            if rate <= 0:
                rate = segmented_rate_hz(self.column("host_time", 0, n), resumes + outages)
            if rate > 0:
                duration = n / rate
        counters = self.journal.counters
        by_kind = dict(counters.get("malformed_by_kind", {}))
        by_kind_total = Counter(by_kind)
        out: dict[str, Any] = {
            "path": str(self.path),
            "session_id": self.session_id,
            "frames": n,
            "duration_s": round(duration, 4),
            "rate_hz": round(rate, 3),
            "malformed": int(sum(by_kind_total.values())),
            "malformed_by_kind": by_kind,
            # a resume is a gap in the recording too (the device stopped between runs)
            "gaps": sum(1 for e in self.events if e.get("kind") == "gap") + len(resumes),
            "segments": len(resumes) + 1,
            "reconnects": sum(1 for e in self.events if e.get("kind") == "reconnect"),
            "frames_lost": self.frames_lost(),
            "closed_cleanly": self.closed_cleanly,
            # or imported from a file cut short or damaged (exchange/importers/xdf.py)
            "cut_short": self.cut_short or bool(self.metadata.get("source_incomplete")),
            "layout": self.layout.name,
            "events": [_user_blocks(e) for e in self.events],
            "metadata": self.metadata,
            # always present, a list (empty for a session without trials)
            "participant": self.metadata.get("participant"),
            "gestures": self.gesture_order(),
            "unmapped_keys": list(self.metadata.get("unmapped_keys") or []),
            "trials": [_user_blocks(t) for t in self.journal.trials],
            # the trials' flags, model checks and decisions (storage/format/trial_checks.py)
            "checks": check_counts(self.trials),
            # a collection's progress against its stored block orders (None otherwise)
            "collection": self.collection_progress(),
            "aux": [{"name": a.name, "type": a.type, "unit": a.unit, "rate_hz": a.rate_hz,
                     "channels": a.labels, "samples": len(a.time)}
                    for a in self.aux_signals()],
        }
        return out

    def collection_progress(self) -> dict[str, Any] | None:
        """Trials and blocks done of a collection session (None for other files)."""
        order = self.metadata.get("block_order")
        if self.metadata.get("source") != "collect" or not isinstance(order, list):
            return None
        blocks = [[str(g) for g in o] for o in order if isinstance(o, list)]
        return collection_progress(blocks, self.trials).to_dict()

    def frames_lost(self) -> dict[str, int]:
        """Frames that never reached the file: ``overrun`` (the recorder fell a whole
        ring behind) and ``missing`` (device sequence numbers skipped); from the
        counters, else from the ``overrun`` and ``gap`` events."""
        counters = self.journal.counters or {}
        overrun = counters.get("dropped")
        if overrun is None:
            overrun = sum(int(e.get("lost") or 0) for e in self.events
                          if e.get("kind") == OVERRUN)
        missing = counters.get("missing_frames")
        if missing is None:
            missing = sum(int(e.get("missing") or 0) for e in self.events
                          if e.get("kind") == "gap")
        return {"overrun": int(overrun), "missing": int(missing)}

    def gesture_order(self) -> list[str]:
        """The session's label order: the protocol's (metadata ``gestures``), then any
        other gesture its trials name, sorted."""
        return label_order([self.metadata], (t.gesture for t in self.trials))
