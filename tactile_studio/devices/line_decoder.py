"""Decoding the receiver's ASCII lines: one frame per line, bad lines dropped and counted.

The wire format (DESIGN.md): ``v0,v1,...,v179`` with an optional trailing comma, then
CR LF (a bare LF is accepted too). Every complete line is either one good frame or one
malformed line of exactly one kind (:data:`KINDS`):

``empty``           nothing (or only blanks) before the newline
``undecodable``     a byte that is not printable ASCII (noise, wrong baud rate)
``non_numeric``     a field that is not an integer (letters, ``1,,2``, spaces)
``long``            more fields than channels (a lost newline joined two frames), or a
                    line longer than ``max_line_bytes``
``merged_numbers``  fewer fields than channels and a value above the maximum: a lost
                    comma ran two numbers together
``short``           fewer fields than channels otherwise (a cut line)
``out_of_range``    the right number of fields but a value below 0 or above the maximum

The checks run in that order (the length limit first), so the kind of a line is unique. A line
only affects its
own classification: decoding resynchronises on the next newline, and a partial line at
the end of a read is kept for the next one.

Speed: a read whose lines are all good is checked with C-speed ``bytes`` methods and
parsed by one numpy call; otherwise each line takes that path on its own and only the
lines that fail it go through :func:`classify_line`, the reference classifier, so the
paths cannot disagree about what a good line is.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

KINDS = ("empty", "short", "long", "non_numeric", "undecodable", "merged_numbers",
         "out_of_range")
DEFAULT_MAX_LINE = 65536
_INT = re.compile(rb"-?[0-9]+\Z")
_PRINTABLE = bytes(range(0x20, 0x7F))
_GROUP = 8  # lines per retry of the fast path when a read holds a bad line


def classify_line(line: bytes, n_channels: int = 180, max_value: int = 65535,
                  max_line_bytes: int = DEFAULT_MAX_LINE) -> tuple[str | None, list[int] | None]:
    """Reference classification of one line (without its LF).

    Returns ``(None, values)`` for a good line, ``(kind, None)`` for a bad one.
    """
    if len(line) > max_line_bytes:
        return "long", None
    if line.endswith(b"\r"):
        line = line[:-1]
    if not line.strip(b" \t\r"):
        return "empty", None
    if line.translate(None, _PRINTABLE):
        return "undecodable", None
    fields = line.split(b",")
    if fields[-1] == b"":
        fields.pop()  # the trailing comma the old receiver firmware prints
    if not all(_INT.match(f) for f in fields):
        return "non_numeric", None
    if len(fields) > n_channels:
        return "long", None
    values = [int(f) for f in fields]
    bad = any(v < 0 or v > max_value for v in values)
    if len(fields) < n_channels:
        return ("merged_numbers" if any(v > max_value for v in values) else "short"), None
    if bad:
        return "out_of_range", None
    return None, values


@dataclass
class Decoded:
    """What one :meth:`LineDecoder.feed` produced: good frames and bad lines by kind."""

    frames: np.ndarray
    malformed: Counter = field(default_factory=Counter)

    def __len__(self) -> int:
        return int(self.frames.shape[0])


class LineDecoder:
    """Stateful, streaming decoder: feed bytes as they arrive, get frames and bad counts.

    Totals since construction are kept in ``good`` and ``malformed`` so a caller (or a
    test) can compare them with what a sender reports.
    """

    def __init__(self, n_channels: int = 180, max_value: int = 65535,
                 dtype: str | np.dtype = np.uint16,
                 max_line_bytes: int = DEFAULT_MAX_LINE) -> None:
        self.n_channels = int(n_channels)
        self.max_value = int(max_value)
        self.dtype = np.dtype(dtype)
        self.max_line_bytes = int(max_line_bytes)
        self.good = 0
        self.malformed: Counter[str] = Counter()
        self._pending = b""
        self._discarding = False  # inside a runaway line longer than max_line_bytes

    @property
    def pending_bytes(self) -> int:
        return len(self._pending)

    def reset(self) -> None:
        """Forget any partial line (e.g. after reopening the port); totals are kept."""
        self._pending = b""
        self._discarding = False

    def flush(self) -> Decoded:
        """Treat the partial line as complete (end of stream, port lost) and decode it."""
        data, self._pending = self._pending, b""
        if not data and not self._discarding:
            return self._result([], Counter())
        return self.feed(data + b"\n")

    def feed(self, data: bytes) -> Decoded:
        """Decode every complete line in ``pending + data``; keep the rest for later."""
        bad: Counter[str] = Counter()
        nl = data.rfind(b"\n")
        if nl < 0:
            self._pending += data
            if len(self._pending) > self.max_line_bytes:  # runaway line: drop, count at LF
                self._pending = b""
                self._discarding = True
            return self._result([], bad)
        block = self._pending + data[:nl + 1]
        self._pending = data[nl + 1:]
        if self._discarding:  # the runaway line ends at the first LF
            bad["long"] += 1
            self._discarding = False
            block = block[block.find(b"\n") + 1:]
        if not block:
            return self._result([], bad)
        whole = self._fast(block)
        if whole is not None:
            return self._result([whole], bad)
        parts: list[np.ndarray] = []
        c, top, limit = self.n_channels, self.max_value, self.max_line_bytes
        lines = block.split(b"\n")[:-1]
        for g in range(0, len(lines), _GROUP):  # clean groups still take the fast path
            group = lines[g:g + _GROUP]
            vals = self._fast(b"\n".join(group) + b"\n") if len(group) > 1 else None
            if vals is not None:
                parts.append(vals)
                continue
            for line in group:
                vals = self._fast(line + b"\n")
                if vals is None:
                    kind, ref = classify_line(line, c, top, limit)
                    if kind is not None:
                        bad[kind] += 1
                        continue
                    vals = np.asarray(ref, dtype=np.int64)[None, :]
                parts.append(vals)
        return self._result(parts, bad)

    # ---- internals -------------------------------------------------------------------
    def _result(self, parts: list[np.ndarray], bad: Counter) -> Decoded:
        if len(parts) == 1:
            frames = parts[0].astype(self.dtype)
        elif parts:
            frames = np.concatenate(parts).astype(self.dtype)
        else:
            frames = np.empty((0, self.n_channels), dtype=self.dtype)
        self.good += len(frames)
        if bad:
            self.malformed.update(bad)
        return Decoded(frames, bad)

    def _fast(self, block: bytes) -> np.ndarray | None:
        """All lines of ``block`` (which ends with LF) as frames if every one is good,
        else None. C-speed string checks, then one numpy parse of the whole block."""
        if block.translate(None, b"0123456789,\r\n"):
            return None  # something else than digits, commas and line ends
        text = block.replace(b"\r\n", b"\n")
        if b"\r" in text:
            return None
        text = text.replace(b",\n", b"\n")  # the optional trailing comma
        lines = text.split(b"\n")
        lines.pop()
        c = self.n_channels
        if not all(line.count(b",") == c - 1 for line in lines):
            return None
        joined = b",".join(lines)
        if b",," in joined or joined.startswith(b",") or joined.endswith(b","):
            return None  # an empty field somewhere
        try:  # int64 parsing saturates on overflow, so a huge field cannot wrap around
            vals = np.fromstring(joined, dtype=np.int64, sep=",")
        except ValueError:
            return None
        if vals.size != len(lines) * c or vals.max() > self.max_value:
            return None
        return vals.reshape(len(lines), c)


def encode_frame(values: np.ndarray, trailing_comma: bool = True) -> bytes:
    """One frame as the receiver prints it (used by the emulator, tests and benchmarks)."""
    text = ",".join(map(str, np.asarray(values).astype(np.int64).tolist()))
    return (text + ("," if trailing_comma else "") + "\r\n").encode("ascii")
