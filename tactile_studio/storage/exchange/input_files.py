"""What every importer does with an input file from elsewhere: checks before reading it
(one-line errors), its content read as labs archive it (``.csv.xz``, ``.csv.gz``,
``.csv.bz2`` stream-decompressed: :class:`InputFile`), its lines read in bounded blocks,
and its values kept only when the session can store them as they are."""

from __future__ import annotations

import bz2
import gzip
import hashlib
import lzma
import os
import threading
import zlib
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO, Protocol

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.storage.format.file_guards import not_regular

MAX_LINE_BYTES = 1 << 20  # a text row of ours is < 10 KB; a longer "line" is no row


def check_input_file(path: Path, what: str, error: type[UserError] = UserError) -> int:
    """Raise ``error`` naming ``path`` unless it is a non-empty regular file (a FIFO
    would block the first read, a device never end: storage/format/file_guards.py); return
    its size. ``what``: "an XDF file", "a ShearSense CSV"..."""
    why = not_regular(path, what)
    if why:
        raise error(f"{path}: {why}")
    size = path.stat().st_size
    if size == 0:
        raise error(f"{path}: empty file, not {what}")
    return size


# suffix -> (the format's name in messages, how its stream is opened over the file)
COMPRESSIONS = {
    ".xz": ("xz", lambda fh: lzma.LZMAFile(fh)),
    ".gz": ("gzip", lambda fh: gzip.GzipFile(fileobj=fh)),
    ".bz2": ("bzip2", lambda fh: bz2.BZ2File(fh)),
}
# what a damaged or cut-short archive raises while it is read (gzip's BadGzipFile and
# bz2's "Invalid data stream" are OSErrors)
_DAMAGED = (lzma.LZMAError, zlib.error, EOFError, OSError)


def compression(path: str | Path) -> str:
    """The archive format of ``path`` by its suffix ("xz", "gzip", "bzip2"), or ""."""
    found = COMPRESSIONS.get(Path(path).suffix.lower())
    return found[0] if found else ""


def plain_name(path: str | os.PathLike[str]) -> str:
    """The file's name without an archive suffix: ``P08_FLAT.csv.xz`` -> ``P08_FLAT.csv``."""
    name = Path(path).name
    return name[:-len(Path(name).suffix)] if compression(name) else name


def plain_stem(path: str | os.PathLike[str]) -> str:
    """The stem of :func:`plain_name`: ``P08_FLAT.csv.xz`` -> ``P08_FLAT`` (what an
    import names its output after, as for the uncompressed file)."""
    return Path(plain_name(path)).stem


class _Readable(Protocol):
    def read(self, n: int = -1) -> bytes: ...


class InputFile:
    """An importer's input, opened to read its content: a plain file as it is, an archive
    (by suffix: :data:`COMPRESSIONS`) decompressed as it is read, never whole in memory
    nor on disk. ``done`` is how far into the file on disk the reading is (progress
    against ``size``); with ``digest``, :meth:`sha256` is the SHA-256 of the content, so
    a recording imported from its ``.csv`` and from its ``.csv.xz`` gets one session id.
    A damaged or cut-short archive raises ``error`` in one line naming the file, while it
    is read: the importers write a session only after reading all of its input."""

    def __init__(self, path: Path, what: str, error: type[UserError] = UserError,
                 digest: bool = False) -> None:
        self.path, self.what, self.error = Path(path), what, error
        self.size = check_input_file(self.path, what, error)
        self.kind = compression(self.path)
        try:
            self._raw = open(self.path, "rb")
        except OSError as exc:
            raise error(f"{self.path}: cannot be read ({exc.strerror})") from None
        self._stream: _Readable = (COMPRESSIONS[self.path.suffix.lower()][1](self._raw)
                                   if self.kind else self._raw)
        self._hash = hashlib.sha256() if digest and self.kind else None
        # a plain file is hashed by a thread beside the parse (hashlib releases the GIL;
        # hashing a real 150 MB file alone takes ~0.2 s); an archive's content as read
        self._thread = _FileHash(self.path, error) if digest and not self.kind else None

    def read(self, n: int = -1) -> bytes:
        try:
            data = self._stream.read(n)
        except _DAMAGED as exc:
            if not self.kind:
                raise self.error(f"{self.path}: cannot be read "
                                 f"({getattr(exc, 'strerror', None) or exc})") from None
            raise self.error(f"{self.path}: damaged {self.kind} archive, not {self.what} "
                             f"({exc})") from None
        if self._hash is not None:
            self._hash.update(data)
        return data

    @property
    def done(self) -> int:
        """Bytes of the file on disk read so far."""
        return self._raw.tell() if not self._raw.closed else self.size

    def sha256(self) -> str:
        """The content's SHA-256, hex (after the whole content was read)."""
        if self._thread is not None:
            return self._thread.result()
        return self._hash.hexdigest() if self._hash is not None else ""

    def close(self) -> None:
        if self._stream is not self._raw:
            self._stream.close()  # type: ignore[attr-defined]
        self._raw.close()

    def __enter__(self) -> InputFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _FileHash:
    """SHA-256 of a file's bytes computed by a thread beside the parse."""

    def __init__(self, path: Path, error: type[UserError]) -> None:
        self._path, self._error_type = path, error
        self._digest = hashlib.sha256()
        self._error: OSError | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            with open(self._path, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    self._digest.update(block)
        except OSError as exc:
            self._error = exc

    def result(self) -> str:
        self._thread.join()
        if self._error is not None:
            raise self._error_type(f"{self._path}: cannot be read ({self._error.strerror})")
        return self._digest.hexdigest()


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes, hex (read in 1 MB blocks): an import's source identity,
    a run folder's model fingerprint."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def unrepresentable_rows(values: np.ndarray, dtype: str | np.dtype
                         ) -> tuple[np.ndarray, Counter[str]]:
    """Which rows of ``values`` hold a value the layout's raw ``dtype`` cannot store as
    it is, and how many rows of each kind: ``not_finite`` (NaN, infinity),
    ``out_of_range`` (beyond the type: 1e9 in 16-bit counts), ``not_whole`` (12.75 as a
    count). A cast would turn them into other numbers (NaN -> 0, 1e9 -> 65535, 12.75 ->
    12) that look like measurements, so importers leave such rows out and count them.
    Float layouts keep any finite value within float32's range (to its precision)."""
    dt = np.dtype(dtype)
    v = np.asarray(values)
    kinds: Counter[str] = Counter()
    if v.dtype.kind in "iub" and dt.kind in "iu":
        lim = np.iinfo(dt)
        bad = ((v < lim.min) | (v > lim.max)).any(axis=1) if v.size else np.zeros(len(v), bool)
        kinds["out_of_range"] = int(bad.sum())
        return bad, +kinds
    if v.dtype.kind not in "iubf":  # text, objects: nothing of it is a number we can keep
        return np.ones(len(v), bool), Counter({"not_a_number": len(v)})
    v = v.astype(np.float64, copy=False)
    finite = np.isfinite(v)
    lim = np.iinfo(dt) if dt.kind in "iu" else np.finfo(dt)
    inside = np.abs(np.where(finite, v, 0.0)) <= lim.max if dt.kind == "f" else \
        (np.where(finite, v, 0.0) >= lim.min) & (np.where(finite, v, 0.0) <= lim.max)
    rows_nan = ~finite.all(axis=1)
    rows_range = ~rows_nan & ~inside.all(axis=1)
    rows_frac = np.zeros(len(v), bool)
    if dt.kind in "iu":
        rows_frac = ~rows_nan & ~rows_range & (np.where(finite, v, 0.0) % 1 != 0).any(axis=1)
    kinds.update(not_finite=int(rows_nan.sum()), out_of_range=int(rows_range.sum()),
                 not_whole=int(rows_frac.sum()))
    return rows_nan | rows_range | rows_frac, +kinds


class LineBlocks:
    """A text file's lines in blocks of whole lines, memory bounded whatever it holds.

    A file with no line end (a binary file picked by mistake, one huge field) grew one
    pending "line" to the file's size, copied again with every block read; now a line
    longer than ``max_line`` is dropped as it is read (counted in :attr:`overlong`,
    the readers' ``long_row``). A file whose lines end in CR alone (Excel's "CSV
    (Macintosh)") was one line of the whole file; its CRs are read as line ends."""

    def __init__(self, fh: BinaryIO | InputFile, block_bytes: int = 1 << 20,
                 max_line: int = MAX_LINE_BYTES) -> None:
        self.fh, self.block_bytes, self.max_line = fh, block_bytes, max_line
        self.overlong = 0
        self._rest = b""
        self._skipping = False  # inside a line already dropped, until its end
        head = fh.read(min(block_bytes, 64 << 10))
        self.cr_only = b"\r" in head and b"\n" not in head
        self._pending = [head]
        self.done = len(head)  # bytes read so far (progress)

    def first_line(self) -> bytes:
        """The first line (its end included), at most ``max_line`` bytes: a header."""
        while b"\n" not in self._rest and len(self._rest) <= self.max_line:
            data = self._next()
            if not data:
                break
            self._rest += data
        cut = self._rest.find(b"\n") + 1 or len(self._rest)
        cut = min(cut, self.max_line)
        line, self._rest = self._rest[:cut], self._rest[cut:]
        if not line.endswith(b"\n") and self._rest:
            self._skipping = True
        return line

    def _next(self) -> bytes:
        if self._pending:
            data = self._pending.pop()
        else:
            data = self.fh.read(self.block_bytes)
            self.done += len(data)
        return data.replace(b"\r", b"\n") if self.cr_only else data

    def blocks(self) -> Iterator[bytes]:
        """The rest, as blocks ending at a line end (the last may not: the file's last
        line without one)."""
        while True:
            chunk = self._next()
            data = self._rest + chunk
            if not chunk:
                if self._skipping:
                    data = b""
                if data.strip():
                    yield data
                return
            if self._skipping:
                end = data.find(b"\n")
                if end < 0:
                    self._rest = b""
                    continue
                self._skipping = False
                data = data[end + 1:]
            cut = data.rfind(b"\n") + 1
            self._rest = data[cut:]
            if len(self._rest) > self.max_line:
                self.overlong += 1
                self._rest = b""
                self._skipping = True
            if cut:
                yield data[:cut]
