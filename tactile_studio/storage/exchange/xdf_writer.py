"""A small XDF 1.0 writer: the file format LabRecorder writes and pyxdf reads.

No writer library of note exists, so this is the whole format we use, chunk by chunk.
A file is the magic ``XDF:`` followed by chunks::

    chunk   = [NumLengthBytes: 1|4|8 as one byte][Length: that many bytes, little-endian]
              [Tag: uint16 LE][Content]          (Length counts Tag + Content)
    tag 1   FileHeader    XML <info><version>1.0</version><datetime/></info>
    tag 2   StreamHeader  [StreamId: uint32 LE] XML <info> name, type, channel_count,
                          nominal_srate, channel_format, source_id, version, created_at,
                          uid, session_id, hostname, desc </info>
    tag 3   Samples       [StreamId][NumSamples: varlen int] then per sample
                          [8][timestamp: float64 LE] (we always stamp every sample) and
                          the values: numeric channels little-endian in the declared
                          format; string channels each [varlen length][UTF-8 bytes]
    tag 4   ClockOffset   [StreamId][CollectionTime: float64][OffsetValue: float64]
    tag 5   Boundary      16 fixed bytes (a UUID readers scan for after damage)
    tag 6   StreamFooter  [StreamId] XML <info> first_timestamp, last_timestamp,
                          sample_count, clock_offsets/offset*/{time, value} </info>

``varlen int`` is the same 1|4|8 length-of-length encoding as a chunk's length.
An offset value is what a reader adds to that stream's timestamps to put them on the
recording's clock (LSL's ``time_correction``); see docs/import-export.md.
"""

from __future__ import annotations

import datetime as _dt
import socket
import struct
import uuid
import xml.etree.ElementTree as ET
from typing import Any, BinaryIO

import numpy as np

MAGIC = b"XDF:"
FILE_HEADER, STREAM_HEADER, SAMPLES, CLOCK_OFFSET, BOUNDARY, STREAM_FOOTER = 1, 2, 3, 4, 5, 6
BOUNDARY_UUID = bytes([0x43, 0xA5, 0x46, 0xDC, 0xCB, 0xF5, 0x41, 0x0F,
                       0xB3, 0x0E, 0xD5, 0x46, 0x73, 0x83, 0xCB, 0xE4])
FORMATS = {"int8": "<i1", "int16": "<i2", "int32": "<i4", "int64": "<i8",
           "float32": "<f4", "double64": "<f8"}


def varlen(n: int) -> bytes:
    """XDF's variable-length integer: the byte count (1, 4 or 8), then the value."""
    if n < 256:
        return b"\x01" + struct.pack("<B", n)
    if n < 1 << 32:
        return b"\x04" + struct.pack("<I", n)
    return b"\x08" + struct.pack("<Q", n)


def xml_text(root: ET.Element) -> bytes:
    return b'<?xml version="1.0"?>' + ET.tostring(root, encoding="utf-8")


def add_children(parent: ET.Element, values: dict[str, Any]) -> ET.Element:
    """Nested dicts become nested elements, lists repeated elements, the rest text."""
    for key, value in values.items():
        if value is None:
            continue
        if isinstance(value, dict):
            add_children(ET.SubElement(parent, key), value)
        elif isinstance(value, list):
            for item in value:
                add_children(parent, {key: item})
        else:
            ET.SubElement(parent, key).text = str(value)
    return parent


class XdfWriter:
    """Writes chunks to an open binary file; one instance per file."""

    def __init__(self, fh: BinaryIO) -> None:
        self.fh = fh
        self.session_id = str(uuid.uuid4())
        fh.write(MAGIC)

    def _chunk(self, tag: int, content: bytes, stream_id: int | None = None) -> None:
        head = b"" if stream_id is None else struct.pack("<I", stream_id)
        self.fh.write(varlen(2 + len(head) + len(content)) + struct.pack("<H", tag))
        self.fh.write(head)
        self.fh.write(content)

    def file_header(self) -> None:
        now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        self._chunk(FILE_HEADER, xml_text(add_children(
            ET.Element("info"), {"version": "1.0", "datetime": now})))

    def stream_header(self, stream_id: int, name: str, type_: str, channel_count: int,
                      nominal_srate: float, channel_format: str, source_id: str,
                      created_at: float, desc: dict[str, Any] | None = None) -> None:
        info = add_children(ET.Element("info"), {
            "name": name, "type": type_, "channel_count": channel_count,
            "nominal_srate": repr(float(nominal_srate)), "channel_format": channel_format,
            "source_id": source_id, "version": "1.1000000000000001",
            "created_at": repr(float(created_at)), "uid": str(uuid.uuid4()),
            "session_id": self.session_id, "hostname": socket.gethostname()})
        add_children(ET.SubElement(info, "desc"), desc or {})
        self._chunk(STREAM_HEADER, xml_text(info), stream_id)

    def samples(self, stream_id: int, channel_format: str, stamps: np.ndarray,
                values: Any) -> None:
        """One Samples chunk: ``values`` (n, channels) numeric, or n lists of strings."""
        stamps = np.asarray(stamps, dtype="<f8")
        n = len(stamps)
        if channel_format == "string":
            parts = [varlen(n)]
            for t, sample in zip(stamps.tolist(), values):
                parts.append(b"\x08" + struct.pack("<d", t))
                for text in sample:
                    data = str(text).encode("utf-8")
                    parts.append(varlen(len(data)) + data)
            self._chunk(SAMPLES, b"".join(parts), stream_id)
            return
        values = np.asarray(values)
        rec = np.empty(n, dtype=[("n", "u1"), ("t", "<f8"),
                                 ("v", FORMATS[channel_format], (values.shape[1],))])
        rec["n"], rec["t"], rec["v"] = 8, stamps, values
        self._chunk(SAMPLES, varlen(n) + rec.tobytes(), stream_id)

    def clock_offset(self, stream_id: int, collection_time: float, offset: float) -> None:
        self._chunk(CLOCK_OFFSET, struct.pack("<dd", collection_time, offset), stream_id)

    def boundary(self) -> None:
        self._chunk(BOUNDARY, BOUNDARY_UUID)

    def stream_footer(self, stream_id: int, first: float, last: float, count: int,
                      offsets: list[tuple[float, float]]) -> None:
        info = add_children(ET.Element("info"), {
            "first_timestamp": repr(float(first)), "last_timestamp": repr(float(last)),
            "sample_count": int(count),
            "clock_offsets": {"offset": [{"time": repr(float(t)), "value": repr(float(v))}
                                         for t, v in offsets]}})
        self._chunk(STREAM_FOOTER, xml_text(info), stream_id)
