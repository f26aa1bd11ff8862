"""The BLE frame payload: how one frame of raw counts travels in GATT notifications.

A frame is split into fragments, one per notification (the usable size of a
notification is the ATT MTU minus 3). Every notification starts with a 4-byte
fragment header; all integers are little-endian::

    offset  size  field
    0       2     seq      frame sequence number, +1 per frame, wraps 65535 -> 0
    2       1     index    fragment index in the frame, 0 .. count-1
    3       1     count    number of fragments of this frame (1 .. 255)
    4       ...   chunk    the next bytes of the frame body

The chunks of one frame, concatenated in index order, form the frame body::

    0       1     version  1
    1       1     flags    0 (reserved)
    2       2     n        number of counts (180 for the ShearSense array)
    4       2n    counts   n x uint16, in the channel order of the serial format
    4+2n    2     crc      CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of bytes 0 .. 3+2n

180 counts make a 366-byte body: 1 notification at MTU >= 373, 2 at MTU 247, 23 at the
default MTU of 23. Fragments of one frame are sent back to back, in order.

The :class:`Reassembler` checks everything and counts what it drops, by kind
(:data:`KINDS`); it reports sequence gaps (frames never seen) separately, as an
unwrapped 64-bit sequence the acquisition engine turns into gap events.
"""

from __future__ import annotations

import binascii
import struct
from collections import Counter

import numpy as np

VERSION = 1
FRAG_HEADER = struct.Struct("<HBB")
BODY_HEADER = struct.Struct("<BBH")
KINDS = ("bad_fragment", "incomplete", "bad_version", "bad_length", "bad_crc", "duplicate",
         "out_of_order")
"""``bad_fragment``: a notification too short or with an impossible index/count;
``incomplete``: a frame with a fragment missing (or garbled header); ``bad_version``;
``bad_length``: n or the body size is not what the layout expects; ``bad_crc``: payload
corrupted; ``duplicate`` / ``out_of_order``: a sequence number already seen or older."""


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (binascii's C implementation, with init 0xFFFF)."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode_body(values: np.ndarray) -> bytes:
    """The frame body for ``values`` (uint16 counts)."""
    counts = np.asarray(values, dtype="<u2").tobytes()
    body = BODY_HEADER.pack(VERSION, 0, len(counts) // 2) + counts
    return body + struct.pack("<H", crc16(body))


def encode_packets(seq: int, values: np.ndarray, mtu: int = 247) -> list[bytes]:
    """The notifications that carry one frame at ATT MTU ``mtu`` (what firmware sends)."""
    chunk = mtu - 3 - FRAG_HEADER.size
    if chunk < 1:
        raise ValueError(f"MTU {mtu} is too small for the fragment header")
    body = encode_body(values)
    pieces = [body[i:i + chunk] for i in range(0, len(body), chunk)]
    if len(pieces) > 255:
        raise ValueError(f"MTU {mtu} needs {len(pieces)} fragments (at most 255)")
    return [FRAG_HEADER.pack(seq & 0xFFFF, i, len(pieces)) + p for i, p in enumerate(pieces)]


class Reassembler:
    """Turns notifications back into frames; counts drops by kind and sequence gaps.

    Not thread-safe: feed it from one thread.
    """

    def __init__(self, n_channels: int = 180) -> None:
        self.n_channels = int(n_channels)
        self.body_size = BODY_HEADER.size + 2 * self.n_channels + 2
        self.bad: Counter[str] = Counter()
        self.frames = 0
        self.gaps = 0
        self.missing = 0
        self._parts: list[bytes] = []
        self._cur: tuple[int, int] | None = None  # (seq, count) of the frame in progress
        self._dropped: int | None = None  # seq of a frame already counted as incomplete
        self._last: int | None = None  # last delivered seq (16-bit) ...
        self._unwrapped = -1  # ... and its unwrapped value
        self._rebase = False

    def new_connection(self) -> None:
        """After a reconnect: drop the partial frame silently (the link broke, the engine
        records the gap) and continue the numbering from the next frame that arrives."""
        self._parts, self._cur, self._dropped = [], None, None
        self._rebase = self._last is not None

    def feed(self, packet: bytes) -> tuple[int, np.ndarray] | None:
        """One notification in; ``(unwrapped seq, counts)`` when it completes a frame."""
        if len(packet) < FRAG_HEADER.size:
            self.bad["bad_fragment"] += 1
            return None
        seq, index, count = FRAG_HEADER.unpack_from(packet)
        if count == 0 or index >= count:
            self.bad["bad_fragment"] += 1
            return None
        cur = self._cur
        if cur is not None and cur[0] != seq:  # the previous frame never finished
            self._drop(cur[0])
            cur = None
        if index == 0:
            self._cur, self._parts = (seq, count), [packet[FRAG_HEADER.size:]]
        elif cur is None:  # a frame whose start we missed: count it once
            if seq != self._dropped:
                self._drop(seq)
            return None
        elif index != len(self._parts) or count != cur[1]:
            self._drop(seq)
            return None
        else:
            self._parts.append(packet[FRAG_HEADER.size:])
        if len(self._parts) < count:
            return None
        body = b"".join(self._parts)
        self._cur, self._parts = None, []
        return self._finish(seq, body)

    def _drop(self, seq: int) -> None:
        self.bad["incomplete"] += 1
        self._dropped = seq
        self._cur, self._parts = None, []

    def _finish(self, seq: int, body: bytes) -> tuple[int, np.ndarray] | None:
        if len(body) < BODY_HEADER.size + 2:
            self.bad["bad_length"] += 1
            return None
        version, _flags, n = BODY_HEADER.unpack_from(body)
        if version != VERSION:
            self.bad["bad_version"] += 1
            return None
        if n != self.n_channels or len(body) != self.body_size:
            self.bad["bad_length"] += 1
            return None
        if crc16(body[:-2]) != int.from_bytes(body[-2:], "little"):
            self.bad["bad_crc"] += 1
            return None
        if self._last is None:  # the first frame ever: number from the device's seq
            unwrapped = seq
        else:
            delta = 1 if self._rebase else (seq - self._last) & 0xFFFF
            if delta == 0:
                self.bad["duplicate"] += 1
                return None
            if delta > 0x8000:
                self.bad["out_of_order"] += 1
                return None
            if delta > 1:
                self.gaps += 1
                self.missing += delta - 1
            unwrapped = self._unwrapped + delta
        self._rebase = False
        self._last, self._unwrapped = seq, unwrapped
        self.frames += 1
        values = np.frombuffer(body, dtype="<u2", count=n, offset=BODY_HEADER.size)
        return self._unwrapped, values.astype(np.uint16)
