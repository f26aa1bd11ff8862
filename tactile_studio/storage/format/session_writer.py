"""Writing session files: HDF5 in SWMR mode so a killed recording still opens.

All datasets are created up front and the file is switched to SWMR (single writer,
multiple readers): HDF5 then orders its writes so the file is valid at every flush,
and a SIGKILL loses at most what came after the last flush. Everything that is not a
frame (metadata updates, events, baselines, trials, counters) goes into ``/journal``,
an append-only byte stream of JSON lines, because SWMR forbids creating objects or
attributes after the switch. ``close()`` additionally writes readable copies
(``metadata_json``, ``events_json``, ``trials_json`` attributes) for other tools, then
rewrites the file once with compressed datasets (storage/format/session_compress.py explains why
not while recording). See docs/session-format.md.
"""

from __future__ import annotations

import datetime as _dt
import errno
import json
import os
import re
import threading
import time
import uuid
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tactile_studio import __version__
from tactile_studio.errors import SessionFileError
from tactile_studio.file_claims import NameTaken, claim
from tactile_studio.output_faults import fault_line
from tactile_studio.sensor.layout import Layout
from tactile_studio.storage.format.aux_signals import AuxSignal, write_aux
from tactile_studio.storage.format.session_compress import (
    LIVE_CHUNK_BYTES,
    chunk_rows,
    compress_in_background,
    compress_session_file,
    wait_for_compression,
)
from tactile_studio.storage.format.session_format import FORMAT, SCHEMA_VERSION, read_journal


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def own_record(fields: dict[str, Any], detail: Mapping[str, Any]) -> dict[str, Any]:
    """A journal record: its own ``fields`` (type, kind, frame, time, index), then
    ``detail``. A detail key naming one of them would rewrite what the record is (an
    event's ``type: trial`` becomes a trial; ``type: metadata`` replaces the metadata):
    a caller's bug, since foreign content (an imported marker, another program's) is
    kept as values under names the caller chose, so it raises instead."""
    clash = sorted(fields.keys() & detail.keys())
    if clash:
        raise ValueError(f"{fields['type']} record: detail would overwrite its own "
                         f"field(s) {', '.join(clash)}")
    return {**fields, **detail}


class WriteFailed(SessionFileError):
    """Writing the session file failed (disk full, file-size limit, an I/O error). The
    file keeps what was written before; the writer writes nothing more to it. ``errno``
    is the cause's (None when unknown), so callers can tell a full disk from the rest
    (``output_faults.out_of_room``)."""

    def __init__(self, message: str, errno: int | None = None) -> None:
        super().__init__(message)
        self.errno = errno


_CAUSES = {errno.ENOSPC: "no space left on device (disk full)",
           errno.EFBIG: "file too large (the file-size limit was reached)",
           errno.EDQUOT: "disk quota exceeded"}


def write_errno(exc: BaseException) -> int | None:
    """The errno of a failed write: h5py reports one as an OSError or as a RuntimeError
    whose text carries it."""
    code = getattr(exc, "errno", None)
    if not code:
        m = re.search(r"errno = (\d+)", str(exc))
        code = int(m.group(1)) if m else None
    return code or None


def describe_write_error(path: Path, exc: BaseException) -> str:
    """One line naming the file and the cause (see :func:`write_errno`)."""
    code = write_errno(exc)
    if code:
        cause = _CAUSES.get(code) or os.strerror(code).lower()
    else:
        cause = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return f"{path}: write failed: {cause}"


class SessionWriter:
    """Appends frames and journal records to a new session file; thread-safe.

    The first write that fails (:class:`WriteFailed`) ends the writer: ``failed`` holds
    the one-line cause, every later write raises at once without touching the file, and
    :meth:`close` releases it without a final flush (see :meth:`_fail`)."""

    def __init__(self, path: str | os.PathLike, layout: Layout, device_info: dict[str, Any],
                 metadata: dict[str, Any] | None = None, flush_interval: float = 0.5,
                 aux: list[AuxSignal] | None = None, *, overwrite: bool = False,
                 staged: bool = False) -> None:
        """``aux``: auxiliary signals (storage/format/aux_signals.py), written before SWMR.

        One writer per file (tactile_studio/file_claims.py): ``path`` is claimed for as
        long as this writer lives (its background compression too); a second writer is
        refused (``FileBusy``) before anything is written. An existing file is replaced
        only with ``overwrite`` (``NameTaken`` otherwise). ``staged`` writes to a
        temporary name that appears at ``path`` whole, at :meth:`publish` or at a clean
        :meth:`close` (an import); :meth:`discard` leaves nothing."""
        self.path = Path(path)  # the session's name; ``file`` is where its bytes are now
        self.layout = layout
        self.flush_interval = flush_interval
        self.overwrite = overwrite
        self._lock = threading.RLock()
        if self.path.parent and not self.path.parent.exists():
            raise SessionFileError(f"{self.path}: folder {self.path.parent} does not exist")
        self._open(staged)
        self._create_datasets(aux or [])
        self._n = 0
        self._last_flush = time.monotonic()
        self._closed = False
        self.failed: str | None = None
        self.failed_errno: int | None = None
        self.metadata: dict[str, Any] = {
            "session_id": str(uuid.uuid4()),  # callers (resume, imports) may pass their own
            "schema_version": SCHEMA_VERSION,
            "app_version": __version__,
            "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "layout": layout.to_dict(),
            "device": device_info,
            "notes": "",
        }
        self.metadata.update(metadata or {})
        self._record({"type": "metadata", "update": self.metadata})
        self.flush()

    def _open(self, staged: bool) -> None:
        """Claim the name and create the HDF5 file (at a temporary name when ``staged``);
        a refusal is one line (SessionFileError, NameTaken) and the claim let go."""
        overwrite = self.overwrite
        wait_for_compression(self.path)  # this process's earlier recording lets go first
        try:
            self._claim = claim(self.path, "session file")
        except OSError as exc:
            raise SessionFileError(fault_line(exc) or f"{self.path}: cannot create session "
                                   f"file ({exc})") from None
        self.file = self._claim.temp("part") if staged else self.path
        self.published = not staged
        try:
            if not overwrite and os.path.lexists(self.path):
                raise NameTaken(f"{self.path}: already exists; not overwritten")
            # a chunk cache of two live chunks: the chunk being filled stays in memory.
            # h5py's default (1 MiB per dataset) made a 1 kHz recording's memory grow by
            # ~40 KB/s for as long as it ran (benchmarks/bench_soak.py). "x": created
            # here, never an existing file (a temporary is new by its name)
            self._f = h5py.File(self.file, "w" if overwrite and not staged else "x",
                                libver="latest", locking=False,
                                rdcc_nbytes=2 * LIVE_CHUNK_BYTES)
        except OSError as exc:
            self._claim.release()
            if not overwrite and not staged and os.path.lexists(self.file):
                # made meanwhile by a program that does not claim: "x" refused it
                raise NameTaken(f"{self.path}: already exists; not overwritten") from None
            line = fault_line(exc)  # read-only, full, no permission: the plain cause
            raise SessionFileError(line or f"{self.path}: cannot create session file ({exc})"
                                   ) from None
        except BaseException:
            self._claim.release()
            raise

    def _create_datasets(self, aux: list[AuxSignal]) -> None:
        """The file's attributes, the frame, column and journal datasets and the
        auxiliary signals; then SWMR, so a reader can follow the recording."""
        f, layout = self._f, self.layout
        c = layout.n_channels
        f.attrs["format"] = FORMAT
        f.attrs["schema_version"] = SCHEMA_VERSION
        f.attrs["app_version"] = __version__
        f.attrs["layout"] = layout.name
        g = f.create_group("frames")
        # uncompressed while recording (see session_compress); close() compresses
        rows = chunk_rows(c * np.dtype(layout.raw_dtype).itemsize, LIVE_CHUNK_BYTES)
        self._raw = g.create_dataset("raw", (0, c), maxshape=(None, c), dtype=layout.raw_dtype,
                                     chunks=(rows, c))
        self._cols = {
            name: g.create_dataset(name, (0,), maxshape=(None,), dtype=dt, chunks=(rows,))
            for name, dt in (("device_time", "f8"), ("host_time", "f8"), ("seq", "i8"),
                             ("index", "i8"))
        }
        self._journal = f.create_dataset("journal", (0,), maxshape=(None,), dtype="u1",
                                         chunks=(16384,))
        write_aux(f, aux)
        f.swmr_mode = True

    def publish(self) -> None:
        """A staged file appears at its name now, open and recording on (a resume: the
        copy of the earlier file replaces it). Atomic; with ``overwrite`` it replaces
        what is there, else :class:`NameTaken` if the name was taken meanwhile."""
        with self._lock:
            if self.published:
                return
            self.flush()
            self._claim.publish(self.file, self.overwrite)
            self.file, self.published = self.path, True

    # ---- frames ----------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return self._n

    def append_frames(self, raw: np.ndarray, device_time: np.ndarray, host_time: np.ndarray,
                      seq: np.ndarray | None = None, index: np.ndarray | None = None) -> int:
        """Append frames; returns the file row of the first. Flushes on the interval."""
        n = int(raw.shape[0])
        if n == 0:
            return self._n
        with self._lock, self._writing():
            first = self._n
            self._raw.resize(first + n, axis=0)
            self._raw[first:] = raw
            cols = {"device_time": device_time, "host_time": host_time,
                    "seq": seq if seq is not None else np.full(n, -1),
                    "index": index if index is not None else np.arange(first, first + n)}
            for name, values in cols.items():
                ds = self._cols[name]
                ds.resize(first + n, axis=0)
                ds[first:] = values
            self._n = first + n
            self._maybe_flush()
            return first

    def truncate(self, n: int) -> None:
        """Keep only the first ``n`` rows (a collection that ends before the frames the
        recorder had already pulled: its file ends with it)."""
        with self._lock, self._writing():
            n = max(0, min(int(n), self._n))
            if n == self._n:
                return
            self._raw.resize(n, axis=0)
            for ds in self._cols.values():
                ds.resize(n, axis=0)
            self._n = n
            # events written at rows now cut (the stream ran ahead): the reader puts
            # them at the last row, as the recorder puts events that come after the end
            self._record({"type": "truncate", "rows": n})
            self.flush()

    # ---- write errors ----------------------------------------------------------------
    @contextmanager
    def _writing(self) -> Iterator[None]:
        """Around every write: after the first failure nothing reaches the file."""
        if self.failed:
            raise WriteFailed(self.failed, self.failed_errno)
        try:
            yield
        except (OSError, RuntimeError) as exc:
            if self._closed:
                raise
            self._fail(exc)
            raise WriteFailed(self.failed, self.failed_errno) from None

    def _fail(self, exc: BaseException) -> None:
        """Remember the cause, and point HDF5's file descriptor at /dev/null: HDF5 keeps
        the unwritten metadata and retries it at every flush and at close, and a file it
        can never write makes it crash the process at exit. What reached the disk before
        stays as it is; the reader recovers it (storage/format/session_recover.py)."""
        self.failed = describe_write_error(self.path, exc)
        self.failed_errno = write_errno(exc)
        try:
            fd = self._f.id.get_vfd_handle()
            null = os.open(os.devnull, os.O_RDWR)
            try:
                os.dup2(null, int(fd))
            finally:
                os.close(null)
        except (OSError, RuntimeError, ValueError, TypeError):
            pass

    # ---- journal ---------------------------------------------------------------------
    def _record(self, record: dict[str, Any]) -> None:
        data = (json.dumps(record, default=_jsonable, separators=(",", ":")) + "\n").encode()
        with self._lock, self._writing():
            m = self._journal.shape[0]
            self._journal.resize(m + len(data), axis=0)
            self._journal[m:] = np.frombuffer(data, dtype=np.uint8)

    def update_metadata(self, **update: Any) -> None:
        self.metadata.update(update)
        self._record({"type": "metadata", "update": update})

    def add_event(self, kind: str, frame: int | None = None, time_s: float | None = None,
                  **detail: Any) -> None:
        """An event at file row ``frame`` (default: the next frame to be written)."""
        self._record(own_record({"type": "event", "kind": kind,
                                 "frame": self._n if frame is None else int(frame),
                                 "time": time.time() if time_s is None else time_s}, detail))

    def add_baseline(self, values: np.ndarray, frame: int | None = None) -> None:
        self._record({"type": "baseline", "frame": self._n if frame is None else int(frame),
                      "values": [float(v) for v in values]})

    def add_trial(self, trial: dict[str, Any]) -> None:
        """A trial record; must carry an ``index``. Later updates merge by index."""
        self._record(own_record({"type": "trial"}, trial))

    def update_trial(self, index: int, **changes: Any) -> None:
        self._record(own_record({"type": "trial_update", "index": int(index)}, changes))

    def set_counters(self, counters: dict[str, Any]) -> None:
        """Device counters (malformed by kind, gaps, ...) for this session; last one wins."""
        self._record({"type": "counters", **counters})

    # ---- flushing --------------------------------------------------------------------
    def _maybe_flush(self) -> None:
        if time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        with self._lock:
            if not self._closed:
                with self._writing():
                    self._f.flush()
                self._last_flush = time.monotonic()

    def close(self, compress: bool = True, background: bool = False) -> None:
        """Flush, close, write human-readable copies of the journal as attributes, and
        (unless ``compress`` is False) rewrite the file compressed, on a worker thread
        with ``background`` (see :func:`compress_in_background`). A staged file is
        published then (its failure raises); the claim is released last."""
        with self._lock:
            if self._closed:
                return
            if not self.failed:
                try:
                    self._record({"type": "closed", "time": time.time()})
                    self.flush()
                except WriteFailed:
                    pass
            self._closed = True
            if self.failed:  # nothing more reaches the disk; the file stays as it was cut
                try:
                    self._f.close()
                except (OSError, RuntimeError):
                    pass
                self._let_go(keep=self.published)
                return
            self._f.close()
        try:
            with h5py.File(self.file, "r+", locking=False) as f:
                j = read_journal(f)
                f.attrs["metadata_json"] = json.dumps(j.metadata, default=_jsonable)
                f.attrs["events_json"] = json.dumps(j.events, default=_jsonable)
                f.attrs["trials_json"] = json.dumps(j.trials, default=_jsonable)
        except (OSError, RuntimeError) as exc:  # closed cleanly; only the copies are missing
            self.failed = describe_write_error(self.path, exc)
            self.failed_errno = write_errno(exc)
            self._let_go(keep=self.published)
            return
        if compress and background and self.published:
            # the claim is held until the compressed file is in place
            compress_in_background(self.file, self._claim.temp("compressing"),
                                   then=self._claim.release)
            return
        try:
            if compress:
                try:
                    compress_session_file(self.file, self._claim.temp("compressing"))
                except (OSError, RuntimeError):  # e.g. no room for the copy: kept as it is
                    pass
            if not self.published:
                self._claim.publish(self.file, self.overwrite)
                self.file, self.published = self.path, True
        except BaseException:
            self._let_go(keep=self.published)  # a recording stays; a staged copy goes
            raise
        self._claim.release()

    def discard(self) -> None:
        """Close and remove the file (a cancelled or failed import, a recording that got
        no frame): nothing is left at the name, and a staged writer never touched it."""
        with self._lock:
            if not self._claim.held:  # closed and let go: the name is another's now
                return
            self._closed = True
            try:
                self._f.close()
            except (OSError, RuntimeError, ValueError):
                pass
            self._let_go(keep=False)

    def _let_go(self, keep: bool) -> None:
        """Remove the file unless ``keep``, then release the claim."""
        if not keep:
            try:
                os.unlink(self.file)
            except OSError:
                pass
        self._claim.release()

    def __enter__(self) -> SessionWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
