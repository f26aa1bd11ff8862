"""Compressing a finished session file: HDF5's own filters, chunks sized to the data.

Why at close and not while recording: under SWMR, HDF5 never reuses freed file space,
and a compressed chunk that is flushed half full is rewritten (and reallocated) at every
flush as it fills. A 20,000-frame recording flushed every 0.5 s grew to 49 MB that way
instead of 2.7 MB (measured; see benchmarks/bench_session_size.py). So frames are
recorded uncompressed in SWMR mode (a killed recording stays readable, just bigger), and
a clean ``SessionWriter.close()`` rewrites the file once, compressed, then swaps it in
atomically. Readers do not care: h5py decompresses transparently and files written
before compression existed open unchanged.

Filters: byte shuffle + gzip level 1. Shuffle groups the high bytes of 16-bit counts and
of float timestamps, which is what makes them compressible; gzip (unlike lzf) is readable
by every HDF5 tool (MATLAB, HDFView, h5py, R) and shrank raw counts 2.7x against lzf's 2.0x;
levels above 1 gained under 1% for twice the time.
"""

from __future__ import annotations

import logging
import os
import threading
import zlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import h5py
import numpy as np

from tactile_studio.file_claims import temp_beside

FILTERS = {"compression": "gzip", "compression_opts": 1, "shuffle": True}
LIVE_CHUNK_BYTES = 64 * 1024  # uncompressed chunks while recording: ~1.5 min at 43 Hz
CHUNK_BYTES = 256 * 1024      # compressed chunks: large enough to compress well
COLUMNS = ("device_time", "host_time", "seq", "index")


def chunk_rows(row_bytes: int, target: int = CHUNK_BYTES, n_rows: int | None = None) -> int:
    """Rows per chunk so one chunk holds about ``target`` bytes, never more rows than
    the data has (a 1,300-frame file gets one 1,300-row chunk, not 4,096)."""
    rows = max(64, min(65536, target // max(int(row_bytes), 1)))
    if n_rows is not None:
        rows = max(1, min(rows, int(n_rows)))
    return rows


COPY_BYTES = 4_000_000  # copied in slices of whole chunks, ~4 MB each: bounded memory


def _copy_compressed(src: h5py.Dataset, dst_group: h5py.Group, name: str, n: int,
                     rows: int) -> None:
    """The first ``n`` rows of ``src`` into a new compressed dataset, chunks of ``rows``."""
    tail = src.shape[1:]
    ds = dst_group.create_dataset(name, (n, *tail), maxshape=(None, *tail), dtype=src.dtype,
                                  chunks=(rows, *tail), **FILTERS)
    chunk_bytes = rows * src.dtype.itemsize * int(np.prod(tail))
    step = rows * max(1, COPY_BYTES // max(1, chunk_bytes))
    for i in range(0, n, step):
        j = min(n, i + step)
        ds[i:j] = src[i:j]


def compress_session_file(path: str | os.PathLike, tmp: str | os.PathLike | None = None
                          ) -> Path:
    """Rewrite a closed session file with compressed, right-sized chunks, atomically.

    The original stays in place until the compressed copy is complete; if the swap is
    refused (another program holds the file open on Windows) the uncompressed file is kept.
    The copy is written to ``tmp`` (default: a name of this process's own, so two
    compressions never share one; the session writer passes one of its claim's).
    """
    path = Path(path)
    tmp = Path(tmp) if tmp is not None else temp_beside(path, "compressing")
    try:
        with h5py.File(path, "r", locking=False) as src, \
                h5py.File(tmp, "w", libver="latest", locking=False) as dst:
            for key, value in src.attrs.items():
                dst.attrs[key] = value
            raw = src["frames/raw"]
            n = min([raw.shape[0]] + [src[f"frames/{c}"].shape[0] for c in COLUMNS])
            g = dst.create_group("frames")
            row_bytes = raw.dtype.itemsize * int(np.prod(raw.shape[1:]))
            rows = chunk_rows(row_bytes, n_rows=n)
            _copy_compressed(raw, g, "raw", n, rows)
            for c in COLUMNS:
                col = src[f"frames/{c}"]
                _copy_compressed(col, g, c, n, chunk_rows(col.dtype.itemsize, n_rows=n))
            journal = src["journal"]
            m = journal.shape[0]
            _copy_compressed(journal, dst, "journal", m, chunk_rows(1, n_rows=max(m, 1)))
            for name in src:  # anything else a later version adds is copied as it is
                if name not in dst:
                    src.copy(src[name], dst, name)
            for name in src["frames"]:
                if name not in g:
                    src.copy(src["frames"][name], g, name)
        os.replace(tmp, path)
    except PermissionError:
        tmp.unlink(missing_ok=True)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


_pending: dict[Path, threading.Thread] = {}
_pending_lock = threading.Lock()
_log = logging.getLogger(__name__)


def compress_in_background(path: str | os.PathLike, tmp: str | os.PathLike | None = None,
                           then: Callable[[], None] | None = None) -> threading.Thread:
    """Compress a closed session file on a worker thread, so stopping a recording does
    not freeze the window that asked (1-2 s per 100k frames); ``then()`` runs after it,
    however it ended (the session writer releases its claim on the file there).

    Until the swap the uncompressed file is complete and readable, so nothing is at risk;
    the thread is not a daemon, so the interpreter finishes it before exiting. A failure
    keeps the uncompressed file and is logged.
    """
    path = Path(path).resolve()

    def work() -> None:
        try:
            compress_session_file(path, tmp)
        except Exception as exc:  # the uncompressed file stays: say so, lose nothing
            _log.warning("%s: left uncompressed (%s)", path, exc)
        finally:
            try:
                if then is not None:
                    then()
            finally:
                with _pending_lock:
                    if _pending.get(path) is threading.current_thread():
                        del _pending[path]

    wait_for_compression(path)
    thread = threading.Thread(target=work, name=f"compress {path.name}")
    with _pending_lock:
        _pending[path] = thread
    thread.start()
    return thread


def wait_for_compression(path: str | os.PathLike | None = None,
                         timeout: float | None = None) -> bool:
    """Wait for the background compression of ``path`` (of every file if None); True
    when none is left. A new writer waits before creating a file at the same name, so a
    late swap can never replace a newer recording."""
    with _pending_lock:
        threads = list(_pending.values()) if path is None else \
            [t for t in [_pending.get(Path(path).resolve())] if t is not None]
    for t in threads:
        t.join(timeout)
    return not any(t.is_alive() for t in threads)


_READ_WORKERS = max(1, min(8, os.cpu_count() or 1))
try:  # ISA-L inflates the same deflate streams ~1.5-2x faster than zlib
    from isal.isal_zlib import decompress as _inflate
    from isal.isal_zlib import error as _isal_error
    _INFLATE_ERRORS: tuple[type[Exception], ...] = (zlib.error, _isal_error)
except ImportError:  # pragma: no cover - isal is a dependency; zlib reads the same bytes
    _inflate = zlib.decompress
    _INFLATE_ERRORS = (zlib.error,)


def _plain_gzip_shuffle(ds: h5py.Dataset) -> bool:
    """True for datasets written with exactly our filters (gzip + shuffle, nothing else)."""
    return (ds.chunks is not None and ds.compression == "gzip" and bool(ds.shuffle)
            and not ds.fletcher32 and ds.scaleoffset is None and ds.dtype.kind in "uif")


def read_rows(ds: h5py.Dataset, start: int, stop: int) -> np.ndarray:
    """Rows ``start:stop`` of a dataset; gzip+shuffle chunks are inflated in parallel.

    Why: a whole-session load is dominated by inflating and un-shuffling, which h5py does
    chunk after chunk on one core. Reading the stored chunks directly, inflating them with
    ISA-L in threads and un-shuffling 16-bit counts arithmetically (a byte transpose costs
    as much as the inflate) loads a 100k-frame session about 2x faster
    (benchmarks/bench_session_files.py). The files stay plain gzip + shuffle.
    Anything unusual (other filters, a skipped filter) falls back to h5py.
    """
    n = ds.shape[0]
    start, stop = max(0, start), min(stop, n)
    rows = ds.chunks[0] if ds.chunks else 0
    if stop <= start or not _plain_gzip_shuffle(ds) or stop - start < 2 * rows:
        return ds[start:stop]
    tail, dtype = ds.shape[1:], ds.dtype
    row_elems = int(np.prod(tail)) if tail else 1
    out = np.empty((stop - start, *tail), dtype=dtype)
    dsid = ds.id

    def inflate_into(k: int) -> bool:
        """Chunk ``k`` inflated and un-shuffled straight into its rows of ``out``."""
        mask, data = dsid.read_direct_chunk((k * rows,) + (0,) * len(tail))
        if mask:
            return False
        try:
            planes = np.frombuffer(_inflate(data), dtype=np.uint8).reshape(dtype.itemsize, -1)
        except (*_INFLATE_ERRORS, ValueError):  # a damaged chunk: h5py's read says so
            return False
        a, b = max(start, k * rows), min(stop, (k + 1) * rows)
        e0, e1 = (a - k * rows) * row_elems, (b - k * rows) * row_elems
        flat = out[a - start:b - start].reshape(-1)
        if dtype.itemsize == 2 and dtype.byteorder in "<=|":  # 16-bit counts: 10x faster
            words = flat.view(np.uint16)
            np.left_shift(planes[1, e0:e1], 8, out=words, dtype=np.uint16)
            words |= planes[0, e0:e1]
        else:  # undo HDF5's byte shuffle
            flat.view(np.uint8).reshape(-1, dtype.itemsize)[:] = planes[:, e0:e1].T
        return True

    with ThreadPoolExecutor(_READ_WORKERS) as pool:
        done = list(pool.map(inflate_into, range(start // rows, (stop - 1) // rows + 1)))
    return out if all(done) else ds[start:stop]
