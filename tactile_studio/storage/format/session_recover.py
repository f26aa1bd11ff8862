"""Reading a session file whose writer was cut short by a failed write.

A recording that hits a full disk or the file-size limit (``ulimit -f``) stops at the
first failed write (storage/format/session_writer.py). The file on disk then ends where the
writes stopped, while its superblock already names the larger end-of-file HDF5 was
about to write: by size it looks truncated. Unlike a file cut by copying, its
beginning (superblock, object headers, the frames flushed so far) is intact, so it is
opened read-only in SWMR mode with HDF5's metadata read attempts limited to one: a
file that really is damaged then fails at once instead of being retried for minutes
(the reason truncated files were refused outright before).

The datasets may claim rows that were allocated but never written: HDF5 reads those as
zeros. :func:`written_rows` counts the frames really there (docs/session-format.md,
"A recording cut short").
"""

from __future__ import annotations

import ctypes
import glob
import os
from functools import cache
from pathlib import Path

import h5py
import numpy as np
from h5py import h5f, h5p

from tactile_studio.errors import SessionFileError
from tactile_studio.storage.format.file_guards import COLUMNS, _stored_rows

JOURNAL_SLACK = 1 << 20  # bytes a cut-short journal may claim beyond its stored chunks
TAIL_BLOCK = 4096  # rows read at a time from the end when looking for written rows


@cache
def _hdf5_library() -> ctypes.CDLL | None:
    """The HDF5 library h5py runs on (its wheel's bundled copy, else the system's)."""
    here = os.path.dirname(h5py.__file__)
    for pattern in (os.path.join(here, os.pardir, "h5py.libs", "libhdf5-*.so*"),
                    os.path.join(here, ".dylibs", "libhdf5*.dylib")):
        for name in sorted(glob.glob(pattern)):
            if "_hl" not in os.path.basename(name):
                try:
                    return ctypes.CDLL(name)
                except OSError:
                    pass
    try:
        return ctypes.CDLL("libhdf5.so")
    except OSError:
        return None


def open_cut_short(path: Path) -> h5py.File | None:
    """Open a file whose size is below its recorded end, if its metadata is readable;
    None when it cannot be done quickly and safely (then it is refused as truncated)."""
    lib = _hdf5_library()
    if lib is None or not hasattr(lib, "H5Pset_metadata_read_attempts"):
        return None
    fapl = h5p.create(h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5f.LIBVER_LATEST, h5f.LIBVER_LATEST)
    fapl.set_file_locking(False, True)
    if lib.H5Pset_metadata_read_attempts(ctypes.c_int64(fapl.id), ctypes.c_uint(1)) < 0:
        return None
    try:
        fid = h5f.open(os.fsencode(path), h5f.ACC_RDONLY | h5f.ACC_SWMR_READ, fapl=fapl)
    except (OSError, RuntimeError, ValueError):
        return None
    f = h5py.File(fid)
    try:  # the objects a session needs must be readable, else it is really damaged
        for name in ("frames/raw", "frames/host_time", "journal"):
            f[name].shape  # noqa: B018 - opening them is the test
    except (OSError, KeyError, RuntimeError, ValueError):
        f.close()
        return None
    return f


def cut_short_rows(f: h5py.File, path: Path) -> int:
    """The frame rows whose data is stored, in a file cut short: its datasets were grown
    before the writes that failed, so they may claim more rows than they store (the
    check of every other file, ``check_stored``, refuses such claims). Datasets kept in
    other files and a journal claiming more than it stores are refused as there."""
    datasets: list[tuple[str, h5py.Dataset]] = []
    f.visititems(lambda name, obj: datasets.append((name, obj))
                 if isinstance(obj, h5py.Dataset) else None)
    for name, ds in datasets:
        if ds.is_virtual or ds.external:
            raise SessionFileError(f"{path}: dataset {name} is kept in other files "
                                   "(external or virtual storage); not read")
    # the write that failed may have been the journal's own growth: a claim a little past
    # what is stored reads as zeros there, which the journal's reader skips as a cut line
    if "journal" in f and f["journal"].shape[0] > _stored_rows(f["journal"]) + JOURNAL_SLACK:
        raise SessionFileError(f"{path}: its journal claims more bytes than the file holds")
    frames = [f[f"frames/{name}"] for name in ("raw", *COLUMNS) if f"frames/{name}" in f]
    return min((min(ds.shape[0], _stored_rows(ds)) for ds in frames if ds.shape), default=0)


def written_rows(host_time: h5py.Dataset, raw: h5py.Dataset, n: int) -> int:
    """Rows ``0..k`` that were really written, of the ``n`` the datasets claim.

    A received frame always has a host time (Unix seconds) and, from a real device, some
    non-zero count; rows allocated but never written read as zeros in both. So trailing
    rows whose host time is 0 or whose raw counts are all 0 are not frames. Only the
    tail is read (blocks of :data:`TAIL_BLOCK` rows from the end).
    """
    stop = n
    while stop > 0:
        start = max(0, stop - TAIL_BLOCK)
        h = np.asarray(host_time[start:stop])
        r = np.asarray(raw[start:stop])
        written = (h != 0) & np.any(r.reshape(len(r), -1) != 0, axis=1)
        hits = np.flatnonzero(written)
        if len(hits):
            return start + int(hits[-1]) + 1
        stop = start
    return 0
