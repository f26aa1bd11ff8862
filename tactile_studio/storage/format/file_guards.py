"""Checks a session file must pass before anything in it is read into memory.

A session file may come from anywhere (a shared drive, a collaborator, a broken disk), so
what it claims is checked against what it really holds before a reader allocates: a
dataset resized to claim 10^12 rows costs nothing on disk yet would make ``info``,
``export``, replay and ``train`` ask for terabytes. Checked here:

* the path is a regular file (``os.stat`` + ``S_ISREG``): a FIFO named ``x.h5`` would
  block the first read forever, ``/dev/zero`` would never end;
* every dataset's rows are backed by stored data: a chunked dataset claims no more rows
  than its allocated chunks hold (plus one chunk: a writer killed between growing a
  dataset and writing it), a contiguous one no more bytes than it stores; datasets kept
  in other files (external storage, virtual datasets) are refused, since they can point
  anywhere;
* no chunk is larger than 256 MiB (reading one row inflates its whole chunk);
* the frame datasets have the layout's shape and numeric dtypes (``raw`` (N, channels)
  of integers or floats, the time, seq and index columns 1-D numbers, the journal bytes).

Whatever a file claims, a reader then allocates at most what the file holds, and a claim
that is real but larger than memory ends as one line (``Session.raw`` / ``column``).
"""

from __future__ import annotations

import math
import os
import stat
from pathlib import Path

import h5py

from tactile_studio.errors import SessionFileError
from tactile_studio.sensor.layout import Layout

COLUMNS = ("device_time", "host_time", "seq", "index")
MAX_CHUNK_BYTES = 256 * 2**20  # ours are <= 256 KiB; reading any row inflates a whole chunk

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISDIR, "a folder"))


def not_regular(path: str | os.PathLike, what: str = "a session file") -> str:
    """Why ``path`` (links followed) is not a regular file to read ("" when it is);
    ``what`` it should have been (an importer's "an XDF file")."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "no such file" + (" (a broken link)" if os.path.islink(path) else "")
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if stat.S_ISREG(mode):
        return ""
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    return f"{kind}, not {what}"


def check_regular_file(path: Path) -> None:
    """Refuse, with one line, anything but a regular file, before it is opened."""
    why = not_regular(path)
    if why:
        raise SessionFileError(f"{path}: {why}")


def _stored_rows(ds: h5py.Dataset) -> int:
    """How many leading rows of ``ds`` can hold stored data (an upper bound)."""
    shape = ds.shape
    width = math.prod(shape[1:]) if len(shape) > 1 else 1
    if ds.chunks is None:
        row_bytes = ds.dtype.itemsize * width
        return ds.id.get_storage_size() // row_bytes if row_bytes else shape[0]
    per_row = math.prod(-(-s // c) for s, c in zip(shape[1:], ds.chunks[1:])) or 1
    return (ds.id.get_num_chunks() // per_row + 1) * ds.chunks[0]


def _check_backed(path: Path, name: str, ds: h5py.Dataset) -> None:
    if ds.is_virtual or ds.external:
        raise SessionFileError(f"{path}: dataset {name} is kept in other files "
                               "(external or virtual storage); not read")
    if not ds.shape:
        return
    if ds.chunks is not None and math.prod(ds.chunks) * ds.dtype.itemsize > MAX_CHUNK_BYTES:
        raise SessionFileError(f"{path}: dataset {name} is stored in chunks of "
                               f"{math.prod(ds.chunks) * ds.dtype.itemsize / 2**20:,.0f} MiB "
                               "(damaged, or not written by Tactile Studio)")
    stored = _stored_rows(ds)
    if ds.shape[0] > stored:
        raise SessionFileError(f"{path}: dataset {name} claims {ds.shape[0]:,} rows but the "
                               f"file holds data for at most {stored:,} (damaged, or not "
                               "written by Tactile Studio)")


def _check_dtype(path: Path, name: str, ds: h5py.Dataset, ndim: int, kinds: str) -> None:
    if ds.ndim != ndim or ds.dtype.kind not in kinds or ds.dtype.fields:
        want = "numbers" if "f" in kinds else "integers"
        what = ("a compound type" if ds.dtype.fields else
                "text" if ds.dtype.kind in "SUO" else str(ds.dtype)[:40])
        raise SessionFileError(f"{path}: dataset {name} is {what} of shape {ds.shape}, "
                               f"not {ndim}-D {want} (damaged, or not written by "
                               "Tactile Studio)")


def check_stored(f: h5py.File, path: Path) -> None:
    """Every dataset's claimed size is stored in the file itself; the journal is bytes.
    Before anything (the journal first) is read."""
    datasets: list[tuple[str, h5py.Dataset]] = []
    f.visititems(lambda name, obj: datasets.append((name, obj))
                 if isinstance(obj, h5py.Dataset) else None)
    for name, ds in datasets:
        _check_backed(path, name, ds)
    if "journal" in f:
        _check_dtype(path, "journal", f["journal"], 1, "ui")


def check_frames(f: h5py.File, path: Path, layout: Layout) -> None:
    """The frame datasets have ``layout``'s shape and numeric dtypes."""
    raw = f["frames/raw"]
    _check_dtype(path, "frames/raw", raw, 2, "uif")
    if raw.shape[1] != layout.n_channels:
        raise SessionFileError(f"{path}: frames/raw has {raw.shape[1]:,} channels per frame, "
                               f"layout {layout.name} has {layout.n_channels}")
    for c in COLUMNS:
        if f"frames/{c}" not in f:
            raise SessionFileError(f"{path}: session has no frames/{c} dataset")
        _check_dtype(path, f"frames/{c}", f[f"frames/{c}"], 1, "uif")
