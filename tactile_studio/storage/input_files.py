"""What every importer does with an input file from elsewhere: checks before reading it
(one-line errors), its lines read in bounded blocks, and its values kept only when the
session can store them as they are."""

from __future__ import annotations

import hashlib
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.storage.file_guards import not_regular

MAX_LINE_BYTES = 1 << 20  # a text row of ours is < 10 KB; a longer "line" is no row


def check_input_file(path: Path, what: str, error: type[UserError] = UserError) -> int:
    """Raise ``error`` naming ``path`` unless it is a non-empty regular file (a FIFO
    would block the first read, a device never end: storage/file_guards.py); return
    its size. ``what``: "an XDF file", "a ShearSense CSV"..."""
    why = not_regular(path, what)
    if why:
        raise error(f"{path}: {why}")
    size = path.stat().st_size
    if size == 0:
        raise error(f"{path}: empty file, not {what}")
    return size


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

    def __init__(self, fh: BinaryIO, block_bytes: int = 1 << 20,
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
