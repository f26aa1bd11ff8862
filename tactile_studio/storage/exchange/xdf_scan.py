"""An XDF file's chunks checked before pyxdf reads it: what ``import xdf`` hands pyxdf.

A foreign file may be cut short, damaged or made to lie, and pyxdf believes it: a header
claiming 10^9 channels made it allocate 7.9 GB for a 1.3 KB file; a file cut inside a
chunk lost that chunk silently (or, cut in a chunk's header, was refused whole); a
ClockOffset chunk of the wrong length, a footer naming no declared stream, a Samples
chunk whose samples overrun it made it read the rest of the file out of step. So the
chunks are walked here first (the file is memory-mapped, nothing is allocated by what
it claims), and pyxdf reads only the chunks that hold what they say
(:func:`checked_file`, a file object over them). Checked:

* the magic, each chunk's length (1, 4 or 8 length bytes) against the bytes left; a chunk
  that runs past the end is where the file was cut: a cut Samples chunk keeps its whole
  samples (a shorter chunk is handed on in its place);
* each stream header: readable XML with a name, a known ``channel_format``,
  ``channel_count`` 1..:data:`MAX_CHANNELS`, a finite ``nominal_srate`` 0..
  :data:`MAX_RATE_HZ`, declared once; a stream whose header is refused is left out with
  every chunk of it, and said;
* each Samples chunk: a declared stream, its sample count against its bytes, and every
  sample's optional timestamp flag walked so pyxdf reads exactly the chunk; string
  streams at most :data:`MAX_STRINGS` samples (pyxdf keeps each as a Python list);
* ClockOffset chunks exactly two finite numbers; footers readable, of a declared stream.

What is left out is counted: ``cut`` (where and why the file ends early) and ``damage``
(one line per kind of damage) make an import that says it is incomplete. A stream with
samples but no footer is a recording that did not end (LabRecorder writes every footer
when it stops): the file counts as cut short.
"""

from __future__ import annotations

import io
import math
import mmap
import struct
import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.storage.exchange.xdf_writer import (
    BOUNDARY,
    BOUNDARY_UUID,
    CLOCK_OFFSET,
    FILE_HEADER,
    MAGIC,
    SAMPLES,
    STREAM_FOOTER,
    STREAM_HEADER,
    varlen,
)
from tactile_studio.terminal import shown

MAX_CHANNELS = 65536          # more than any tactile array, EEG cap or marker stream
MAX_RATE_HZ = 100_000.0       # a nominal rate above this is not a recording's
MAX_XML_BYTES = 16 * 2**20    # a header or footer (ours: ~40 KB for 180 channels)
MAX_STRINGS = 2_000_000       # string samples per stream (pyxdf: a list per sample)
ITEMSIZE = {"int8": 1, "int16": 2, "int32": 4, "int64": 8, "float32": 4, "double64": 8}
BOUNDARY_CHUNK = varlen(2 + len(BOUNDARY_UUID)) + struct.pack("<H", BOUNDARY) + BOUNDARY_UUID
_TAGS = {FILE_HEADER, STREAM_HEADER, SAMPLES, CLOCK_OFFSET, BOUNDARY, STREAM_FOOTER}


@dataclass
class StreamDecl:
    """A stream as its header declares it, and what the file holds of it."""

    id: int
    name: str
    fmt: str
    channels: int
    rate: float
    samples: int = 0
    footer_count: int | None = None
    has_footer: bool = False
    info: dict[str, Any] = field(default_factory=dict)  # the header as pyxdf gives it

    @property
    def sample_bytes(self) -> int:
        """The fewest bytes a sample takes: its timestamp flag and its values."""
        return 1 + (2 * self.channels if self.fmt == "string"
                    else self.channels * ITEMSIZE[self.fmt])


@dataclass
class XdfScan:
    """What the walk found: the pieces pyxdf reads (file byte ranges, or bytes made
    here), the streams declared, and what was left out."""

    path: Path
    size: int
    pieces: list[tuple[int, int] | bytes] = field(default_factory=list)
    streams: dict[int, StreamDecl] = field(default_factory=dict)
    refused: dict[int, str] = field(default_factory=dict)  # stream id -> its line
    refused_names: dict[int, str] = field(default_factory=dict)  # ... -> its name, if any
    cut: str = ""
    damage: Counter[str] = field(default_factory=Counter)

    def problems(self) -> list[str]:
        """One line per thing left out or cut (empty: the file is whole)."""
        lines = [f"{self.path}: {why}" for why in self.refused.values()]
        lines += [f"{self.path}: {why}" + (f" ({n} times)" if n > 1 else "")
                  for why, n in self.damage.items()]
        if self.cut:
            lines.append(f"{self.path}: cut short: {self.cut}")
        return lines

    def refused_name(self, name: str) -> str:
        """The line of a stream left out by its header, by name ("" if none)."""
        return next((why for sid, why in self.refused.items()
                     if self.refused_names.get(sid) == name), "")


class _Bad(Exception):
    """A chunk or stream header that is not what it claims (the message says why)."""


def _varlen(buf: mmap.mmap | bytes, pos: int, end: int) -> tuple[int, int]:
    """(value, position after it) of the varlen int at ``pos``; _Bad past ``end``."""
    if pos >= end:
        raise _Bad("is cut off")
    nb = buf[pos]
    if nb not in (1, 4, 8):
        raise _Bad(f"takes {nb} bytes (not 1, 4 or 8)")
    if pos + 1 + nb > end:
        raise _Bad("is cut off")
    value = int.from_bytes(buf[pos + 1:pos + 1 + nb], "little")
    return value, pos + 1 + nb


def _xml(data: bytes) -> ET.Element:
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        raise _Bad(f"not readable XML ({exc})") from None


def _field(info: ET.Element, tag: str) -> str:
    """The text of ``tag`` as pyxdf will take it (not stripped: pyxdf looks a format up
    as written, so " int32 " must not pass here)."""
    el = info.find(tag)
    if el is None or el.text is None or not el.text.strip():
        raise _Bad(f"no {tag}")
    return el.text


def stream_decl(sid: int, data: bytes) -> StreamDecl:
    """A StreamHeader's content checked (module doc); _Bad says why not."""
    info = _xml(data)
    if info.tag != "info" or not len(info):
        raise _Bad("not a stream header (<info> with fields)")
    name = _field(info, "name").strip()
    fmt = _field(info, "channel_format")
    if fmt != "string" and fmt not in ITEMSIZE:
        raise _Bad(f"channel_format {shown(fmt, 20)!r} is not one of XDF's")
    try:
        channels = int(_field(info, "channel_count"))
        rate = float(_field(info, "nominal_srate"))
    except ValueError:
        raise _Bad("channel_count or nominal_srate is not a number") from None
    if not 1 <= channels <= MAX_CHANNELS:
        raise _Bad(f"channel_count {channels:,} is not 1..{MAX_CHANNELS:,}")
    if not (math.isfinite(rate) and 0.0 <= rate <= MAX_RATE_HZ):
        raise _Bad(f"nominal_srate {rate:g} Hz is not a plausible rate "
                   f"(0 = irregular, at most {MAX_RATE_HZ:,.0f} Hz)")
    return StreamDecl(sid, name, fmt, channels, rate, info=xml_dict(info)["info"])


def xml_dict(el: ET.Element) -> dict[str, Any]:
    """An element as pyxdf gives one: ``{tag: {child: [...], ...}}`` or ``{tag: text}``,
    so a header can be read before pyxdf reads the file."""
    children: dict[str, list[Any]] = {}
    for child in el:
        for key, value in xml_dict(child).items():
            children.setdefault(key, []).append(value)
    return {el.tag: children or el.text}


def _numeric_ends(buf: mmap.mmap, pos: int, end: int, n: int, values: int) -> int:
    """Where ``n`` numeric samples of ``values`` bytes each, starting at ``pos``, end
    (each a flag byte, 8 timestamp bytes when the flag is not 0, then the values); -1
    when they do not fit before ``end``. Every sample stamped (LabRecorder, ours) or
    none is checked at once; a mix sample by sample."""
    for stamp in (9, 1):
        stride = stamp + values
        if pos + n * stride <= end and n:
            flags = np.frombuffer(buf, np.uint8, (n - 1) * stride + 1, pos)[::stride]
            uniform = bool(flags.all()) if stamp == 9 else not flags.any()
            del flags  # a view of the map: it must go before the map closes
            if uniform:
                return pos + n * stride
    for _ in range(n):
        if pos >= end:
            return -1
        pos += (9 if buf[pos] else 1) + values
    return pos if pos <= end else -1


def _string_ends(buf: mmap.mmap, pos: int, end: int, n: int, channels: int) -> int:
    """As :func:`_numeric_ends` for string samples (each value a varlen length and its
    bytes)."""
    for _ in range(n):
        if pos >= end:
            return -1
        pos += 9 if buf[pos] else 1
        for _c in range(channels):
            try:
                length, pos = _varlen(buf, pos, end)
            except _Bad:
                return -1
            pos += length
    return pos if pos <= end else -1


def samples_end(buf: mmap.mmap, s: StreamDecl, pos: int, end: int, n: int) -> int:
    """Where ``n`` samples of ``s`` from ``pos`` end, or -1 past ``end``."""
    if s.fmt == "string":
        return _string_ends(buf, pos, end, n, s.channels)
    return _numeric_ends(buf, pos, end, n, s.channels * ITEMSIZE[s.fmt])


def whole_samples(buf: mmap.mmap, s: StreamDecl, pos: int, end: int, n: int) -> tuple[int, int]:
    """(how many of ``n`` samples from ``pos`` end before ``end``, where they end): the
    samples a cut chunk still holds."""
    lo, hi = 0, min(n, (end - pos) // s.sample_bytes)
    while lo < hi:  # the samples before a cut end in order: bisect on the count
        mid = (lo + hi + 1) // 2
        if samples_end(buf, s, pos, end, mid) >= 0:
            lo = mid
        else:
            hi = mid - 1
    return lo, samples_end(buf, s, pos, end, lo) if lo else pos


class _Walk:
    """One pass over the chunks (module doc); fills an :class:`XdfScan`."""

    def __init__(self, path: Path, buf: mmap.mmap, size: int) -> None:
        self.buf, self.size = buf, size
        self.scan = XdfScan(path, size, pieces=[MAGIC])

    def run(self) -> XdfScan:
        pos = len(MAGIC)
        while pos < self.size:
            pos = self._chunk(pos)
            if pos < 0:
                break
        for s in self.scan.streams.values():
            if s.footer_count is not None and s.samples < s.footer_count:
                self.scan.damage[f"stream '{shown(s.name)}': its footer counts "
                                  f"{s.footer_count:,} samples, the file holds "
                                  f"{s.samples:,}"] += 1
        unended = [s.name for s in self.scan.streams.values() if not s.has_footer]
        if unended and not self.scan.cut:
            self.scan.cut = (f"no stream footer for {', '.join(map(shown, unended[:3]))}"
                             + (", ..." if len(unended) > 3 else "")
                             + " (the recording did not end: LabRecorder writes the "
                             "footers when it stops)")
        return self.scan

    def _chunk(self, start: int) -> int:
        """Check the chunk at ``start``; the position after it, or -1 to stop."""
        buf, size = self.buf, self.size
        try:
            length, body = _varlen(buf, start, size)
        except _Bad as exc:
            return self._lost(start, f"a chunk whose length {exc}")
        end = body + length
        if length < 2 or body + 2 > size:
            return self._lost(start, "a chunk too short to be one")
        tag = int.from_bytes(buf[body:body + 2], "little")
        if tag not in _TAGS:
            return self._lost(start, f"a chunk of unknown kind {tag}")
        if end > size:
            after = self._boundary_after(start)
            if after < 0:
                self._cut_chunk(start, body, tag, length)
                return -1
            self.scan.damage[f"a chunk at byte {start:,} claims {length:,} bytes, more than "
                              "the file holds (skipped to the next boundary chunk)"] += 1
            return after
        if tag in (FILE_HEADER, BOUNDARY):
            return end  # nothing we read: pyxdf need not see them
        if length < 6:
            self.scan.damage["a chunk without its stream id (left out)"] += 1
            return end
        sid = int.from_bytes(buf[body + 2:body + 6], "little")
        try:
            keep = self._stream_chunk(tag, sid, body + 6, end)
        except _Bad as exc:
            self.scan.damage[str(exc)] += 1
            keep = False
        if keep:
            self.scan.pieces.append((start, end - start))
        return end

    def _boundary_after(self, start: int) -> int:
        """Where the next Boundary chunk after ``start`` begins (-1: none): LabRecorder
        writes one every few seconds for a reader to find its way after damage."""
        return self.buf.find(BOUNDARY_CHUNK, start + 1)

    def _lost(self, start: int, why: str) -> int:
        """The bytes at ``start`` are no chunk: go on at the next boundary chunk (the
        damage counted), else the file ends here (cut)."""
        after = self._boundary_after(start)
        if after > 0:
            self.scan.damage[f"bytes {start:,}..{after:,} are not XDF chunks ({why}; "
                              "skipped to the next boundary chunk)"] += 1
            return after
        self.scan.cut = f"at byte {start:,} of {self.size:,}: {why}"
        return -1

    def _stream_chunk(self, tag: int, sid: int, pos: int, end: int) -> bool:
        scan = self.scan
        if tag == STREAM_HEADER:
            if sid in scan.streams or sid in scan.refused:
                raise _Bad(f"stream {sid} declared twice (the second header is ignored)")
            if end - pos > MAX_XML_BYTES:
                scan.refused[sid] = f"stream {sid}: header of {end - pos:,} bytes, not read"
                return False
            try:
                scan.streams[sid] = stream_decl(sid, bytes(self.buf[pos:end]))
            except _Bad as exc:
                name = _header_name(bytes(self.buf[pos:end]))
                scan.refused_names[sid] = name
                scan.refused[sid] = (f"stream '{shown(name)}' not read: {exc}" if name
                                     else f"stream {sid} not read: {exc}")
                return False
            return True
        if sid in scan.refused:
            return False
        s = scan.streams.get(sid)
        if s is None:
            raise _Bad(f"chunks of an undeclared stream {sid} (left out)")
        if tag == SAMPLES:
            n, first = _varlen(self.buf, pos, end)
            if n * s.sample_bytes > end - first:
                raise _Bad(f"stream '{shown(s.name)}': a Samples chunk claims {n:,} samples "
                           f"in {end - first:,} bytes (left out)")
            if s.fmt == "string" and s.samples + n > MAX_STRINGS:
                raise _Bad(f"stream '{shown(s.name)}': more than {MAX_STRINGS:,} text "
                           "samples (the rest left out)")
            if samples_end(self.buf, s, first, end, n) != end:
                raise _Bad(f"stream '{shown(s.name)}': a Samples chunk whose samples do "
                           "not fill it (left out)")
            s.samples += n
            return True
        if tag == CLOCK_OFFSET:
            values = struct.unpack("<dd", self.buf[pos:end]) if end - pos == 16 else ()
            if not (len(values) == 2 and all(map(math.isfinite, values))):
                raise _Bad(f"stream '{shown(s.name)}': a ClockOffset that is not two "
                           "finite numbers (left out)")
            return True
        # STREAM_FOOTER
        if end - pos > MAX_XML_BYTES:
            raise _Bad(f"stream '{shown(s.name)}': a footer of {end - pos:,} bytes (left out)")
        s.has_footer = True
        try:
            info = _xml(bytes(self.buf[pos:end]))
        except _Bad as exc:
            raise _Bad(f"stream '{shown(s.name)}': a footer that is {exc} (left out)") from None
        count = info.find("sample_count")
        try:
            s.footer_count = int(count.text) if count is not None and count.text else None
        except ValueError:
            s.footer_count = None
        if info.tag != "info" or not len(info) or (count is not None and s.footer_count is None):
            raise _Bad(f"stream '{shown(s.name)}': a footer that is not one (left out)")
        return True

    def _cut_chunk(self, start: int, body: int, tag: int, length: int) -> None:
        """The file ends inside the chunk at ``start``: keep the whole samples of a cut
        Samples chunk (as a shorter chunk made here), say where it was cut."""
        scan, size = self.scan, self.size
        where = f"the file ends at byte {size:,}, inside a chunk of {length:,} bytes " \
                f"at byte {start:,}"
        scan.cut = where
        if tag != SAMPLES or body + 6 > size:
            return
        sid = int.from_bytes(self.buf[body + 2:body + 6], "little")
        s = scan.streams.get(sid)
        if s is None or sid in scan.refused:
            return
        try:
            n, first = _varlen(self.buf, body + 6, size)
        except _Bad:
            return
        if s.fmt == "string" and s.samples + n > MAX_STRINGS:
            return
        kept, stop = whole_samples(self.buf, s, first, size, n)
        if not kept:
            return
        head = struct.pack("<H", SAMPLES) + struct.pack("<I", sid) + varlen(kept)
        scan.pieces += [varlen(len(head) + stop - first) + head, (first, stop - first)]
        s.samples += kept
        scan.cut = f"{where} ({kept:,} of its {n:,} samples of '{shown(s.name)}' kept)"


def _header_name(data: bytes) -> str:
    try:
        el = ET.fromstring(data).find("name")
    except ET.ParseError:
        return ""
    return (el.text or "").strip() if el is not None else ""


def scan_xdf(path: Path) -> XdfScan:
    """Walk ``path``'s chunks (module doc). Raises _Bad-free: a file that is not XDF
    at all is ``ValueError`` (the caller's one line)."""
    with open(path, "rb") as fh:
        size = fh.seek(0, io.SEEK_END)
        if size < len(MAGIC) or fh.seek(0) != 0 or fh.read(len(MAGIC)) != MAGIC:
            raise ValueError("not an XDF file (it does not start with 'XDF:')")
        with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            return _Walk(path, buf, size).run()


class _Pieces(io.RawIOBase):
    """The checked chunks as one read-only file: what pyxdf reads instead of ``path``."""

    def __init__(self, path: Path, pieces: list[tuple[int, int] | bytes]) -> None:
        super().__init__()
        self._fh = open(path, "rb")
        self._pieces = pieces
        self._starts = np.cumsum([0] + [len(p) if isinstance(p, bytes) else p[1]
                                        for p in pieces])
        self._pos = 0

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self._pos

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._pos, io.SEEK_END: int(self._starts[-1])}
        self._pos = max(0, base[whence] + offset)
        return self._pos

    def readinto(self, b: bytearray | memoryview) -> int:  # type: ignore[override]
        view = memoryview(b).cast("B")
        done = 0
        while done < len(view) and self._pos < self._starts[-1]:
            k = int(np.searchsorted(self._starts, self._pos, side="right")) - 1
            piece, off = self._pieces[k], self._pos - int(self._starts[k])
            if isinstance(piece, bytes):
                data = piece[off:off + len(view) - done]
            else:
                self._fh.seek(piece[0] + off)
                data = self._fh.read(min(piece[1] - off, len(view) - done))
            if not data:
                break
            view[done:done + len(data)] = data
            done += len(data)
            self._pos += len(data)
        return done

    def close(self) -> None:
        self._fh.close()
        super().close()


def checked_file(scan: XdfScan) -> io.BufferedReader:
    """A file object over the chunks :func:`scan_xdf` kept, for ``pyxdf.load_xdf``."""
    return io.BufferedReader(_Pieces(scan.path, scan.pieces), buffer_size=1 << 20)
