"""A wire-level emulator of the sensor's USB receiver on a pseudo-terminal.

It writes frames in the real format (:func:`~tactile_studio.devices.line_decoder.encode_frame`)
into the master side of a pty; the serial plugin opens the slave side like any port.
A fraction of lines is replaced by malformed ones, each of a known kind, and every line
is counted only once it is completely written, so :meth:`SerialEmulator.report` is the
exact truth a receiver's counts can be compared with.

Unplugging is :meth:`SerialEmulator.unplug` (the master closes: the reader gets an I/O
error at once, as when a USB receiver is pulled); :meth:`SerialEmulator.open` plugs a new
pty in. The pty and its stable ``link`` are a :class:`~tactile_studio.devices.pty_port.PtyPort`,
as the instrument emulators' are.

Usable in-process (tests) and from ``tactile-studio emulate-serial``.
"""

from __future__ import annotations

import fcntl
import os
import select
import sys
import termios
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.devices.line_decoder import KINDS, encode_frame
from tactile_studio.devices.pty_port import PtyPort
from tactile_studio.errors import UserError

FrameSource = Callable[[int], np.ndarray]
"""``source(n)`` returns the next ``n`` frames, (n, channels) integer counts."""

DRAIN_SETTLE_S = 0.3  # how long the reader's queue must stay empty before unplug closes

_NON_NUMERIC = (b"ERR", b"nan", b"1a", b"", b" 12", b"0x1F", b"-", b"+7")


def array_source(raw: np.ndarray) -> FrameSource:
    """Frames of a recording, looping at the end (the emulator runs until stopped)."""
    raw = np.asarray(raw)
    if raw.ndim != 2 or raw.shape[0] == 0:
        raise UserError("emulator source has no frames")
    pos = 0

    def source(n: int) -> np.ndarray:
        nonlocal pos
        idx = (pos + np.arange(n)) % raw.shape[0]
        pos = (pos + n) % raw.shape[0]
        return np.rint(raw[idx]).astype(np.int64)

    return source


def corrupt_line(kind: str, frames: np.ndarray, rng: np.random.Generator,
                 trailing_comma: bool = True, max_value: int = 65535) -> bytes:
    """A malformed line of ``kind`` built from ``frames`` (two rows; ``long`` uses both).

    Every result is classified as ``kind`` by the decoder (a test checks many seeds).
    """
    fields = [b"%d" % v for v in frames[0].tolist()]
    tail = b"," if trailing_comma else b""
    if kind == "empty":
        return b"\r\n"
    if kind == "short":
        keep = int(rng.integers(1, len(fields)))
        cut = fields[:keep]
        cut[-1] = cut[-1][:int(rng.integers(1, len(cut[-1]) + 1))]  # maybe mid-number
        return b",".join(cut) + b"\r\n"
    if kind == "long":  # the newline between two frames was lost
        return b",".join(fields) + tail + encode_frame(frames[1], trailing_comma)
    if kind == "non_numeric":
        fields[int(rng.integers(len(fields)))] = _NON_NUMERIC[int(rng.integers(len(_NON_NUMERIC)))]
    elif kind == "undecodable":
        noise = bytes(rng.integers(0x80, 0x100, int(rng.integers(1, 5))).astype(np.uint8))
        i = int(rng.integers(len(fields)))
        fields[i] = fields[i][:1] + noise + fields[i][1:]
    elif kind == "merged_numbers":  # a lost comma
        i = int(rng.integers(len(fields) - 1))
        merged = fields[i] + fields[i + 1]
        if int(merged) <= max_value:
            merged = b"1" + merged.zfill(5)
        fields[i:i + 2] = [merged]
    elif kind == "out_of_range":
        bad = rng.integers(max_value + 1, max(max_value * 2, 99999) + 1)
        fields[int(rng.integers(len(fields)))] = b"%d" % (bad if rng.random() < 0.8 else -bad)
    else:
        raise ValueError(f"unknown malformed kind {kind!r}")
    return b",".join(fields) + tail + b"\r\n"


@dataclass(frozen=True)
class Corruption:
    """The malformed lines an emulator injects: ``fraction`` of the lines, spread evenly
    (at random, from ``seed``) over ``kinds`` (line_decoder.KINDS)."""

    fraction: float = 0.0
    kinds: Iterable[str] = KINDS
    seed: int = 0


class SerialEmulator:
    """Streams frames into a pty, with malformed lines injected as ``corruption`` says.

    ``keep_sent`` keeps a copy of every good frame written, for tests.
    Nothing is written while no program has the port open (a reader flushes what was
    queued before it opened, which would make the counts lie), so the emulator pauses
    instead; ``reader_grace`` is how long a new reader gets to set the port up.
    """

    def __init__(self, source: FrameSource, rate_hz: float = 44.0,
                 corruption: Corruption = Corruption(),
                 link: str | os.PathLike | None = None, trailing_comma: bool = True,
                 keep_sent: bool = False, max_value: int = 65535,
                 reader_grace: float = 0.2) -> None:
        corrupt, kinds, seed = corruption.fraction, corruption.kinds, corruption.seed
        if not 0.0 <= corrupt <= 1.0:
            raise UserError(f"--corrupt must be a fraction from 0 to 1, got {corrupt}")
        if rate_hz <= 0:
            raise UserError(f"--rate must be positive, got {rate_hz}")
        self.kinds = tuple(kinds)
        unknown = set(self.kinds) - set(KINDS)
        if unknown or not self.kinds:
            raise UserError(f"unknown malformed kinds {sorted(unknown)} "
                            f"(known: {', '.join(KINDS)})")
        self.source, self.rate_hz, self.corrupt = source, float(rate_hz), float(corrupt)
        self.pty = PtyPort(link)
        self.trailing_comma, self.keep_sent, self.max_value = trailing_comma, keep_sent, max_value
        self.good = 0
        self.malformed: Counter[str] = Counter()
        self.interrupted = 0  # lines cut by unplug/stop before their end was written
        self.opens = 0
        self._rng = np.random.default_rng(seed)
        self._sent: list[np.ndarray] = []
        self.reader_grace = reader_grace
        self._poll: Any = None
        self._reader_since: float | None = None
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- plugging --------------------------------------------------------------------
    def open(self) -> str:
        """Plug in a new pty and point ``link`` at it; returns the slave path."""
        with self._lock:
            path = self.pty.open()
            self._poll = select.poll()
            self._poll.register(self.pty.fd, select.POLLHUP)
            self._reader_since = None
            self.opens += 1
            return path

    def has_reader(self) -> bool:
        """True when some program has the port open (and has had it for ``reader_grace``
        seconds, time for it to configure the port and flush its input)."""
        poll = self._poll
        if not self.pty.is_open or poll is None:
            return False
        if any(ev & select.POLLHUP for _, ev in poll.poll(0)):
            self._reader_since = None
            return False
        now = time.monotonic()
        if self._reader_since is None:
            self._reader_since = now
        return now - self._reader_since >= self.reader_grace

    @property
    def path(self) -> str | None:
        """The current pty's slave path (None before the first open)."""
        return self.pty.path

    @property
    def port(self) -> str:
        """The path a receiver should open: the link if there is one."""
        return self.pty.port

    @property
    def is_open(self) -> bool:
        return self.pty.is_open

    def unread_bytes(self) -> int:
        """Bytes written that no reader has taken from the pty yet."""
        if not self.pty.is_open or self.path is None:
            return 0
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError:
            return 0
        try:
            buf = fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0")
        except OSError:
            return 0
        finally:
            os.close(fd)
        return int.from_bytes(buf, sys.byteorder)

    def unplug(self, drain: float = 0.0) -> None:
        """Close the pty (the reader sees an I/O error) and remove the link, as a pulled
        USB cable removes its port. A link left behind pointed at a pty number the kernel
        hands to the next pty opened anywhere: a reconnecting reader then opened someone
        else's port (seen as two tests, in parallel, each reading the other's).

        Closing a pty discards what the reader has not read yet, as pulling a cable
        does; ``drain`` waits up to that many seconds for the reader to take it first,
        so the report stays exact.
        """
        with self._lock:
            deadline, empty_since = time.monotonic() + drain, None
            while time.monotonic() < deadline:
                # a write reaches the reader's queue from a kernel work queue, later under
                # load: the queue must stay empty a moment, not be seen empty once
                if self.unread_bytes():
                    empty_since = None
                elif empty_since is None:
                    empty_since = time.monotonic()
                elif time.monotonic() - empty_since >= DRAIN_SETTLE_S:
                    break
                time.sleep(0.005)
            self.pty.close()
            self._poll = None

    def close(self, drain: float = 0.0) -> None:
        """Stop streaming and unplug (after ``drain``)."""
        self.stop()
        self.unplug(drain)

    # ---- lines -----------------------------------------------------------------------
    def next_line(self) -> tuple[bytes, str | None, np.ndarray | None]:
        """The next line to send: (bytes, malformed kind or None, the good frame or None)."""
        if self.corrupt and self._rng.random() < self.corrupt:
            kind = self.kinds[int(self._rng.integers(len(self.kinds)))]
            frames = self.source(2 if kind == "long" else 1)
            if kind != "long":
                frames = np.concatenate((frames, frames))
            line = corrupt_line(kind, frames, self._rng, self.trailing_comma, self.max_value)
            return line, kind, None
        frame = self.source(1)[0]
        return encode_frame(frame, self.trailing_comma), None, frame

    def send_lines(self, n: int, timeout: float = 10.0) -> None:
        """Write ``n`` lines now (blocking while the reader catches up)."""
        for _ in range(n):
            if not self._send_one(time.monotonic() + timeout):
                raise TimeoutError("serial emulator: the reader did not take the data")

    def _send_one(self, deadline: float) -> bool:
        while not self.has_reader():
            if time.monotonic() >= deadline or not self.pty.is_open:
                return False
            time.sleep(0.01)
        with self._lock:
            line, kind, frame = self.next_line()
            done = self._write_all(line, deadline)
            if done:
                if kind is None:
                    self.good += 1
                    if self.keep_sent:
                        self._sent.append(np.asarray(frame).copy())
                else:
                    self.malformed[kind] += 1
            elif done is False:
                self.interrupted += 1
            return bool(done)

    def _write_all(self, data: bytes, deadline: float) -> bool | None:
        """True when all written; False if cut part-way; None if nothing went out."""
        view, sent = memoryview(data), 0
        while sent < len(data):
            master = self.pty.fd
            if master is None:
                return None if sent == 0 else False
            left = deadline - time.monotonic()
            if left <= 0:
                return None if sent == 0 else False
            try:
                _, ready, _ = select.select([], [master], [], min(left, 0.05))
                if ready:
                    sent += os.write(master, view[sent:])
            except BlockingIOError:
                continue
            except OSError:
                return None if sent == 0 else False
        return True

    # ---- streaming -------------------------------------------------------------------
    def start(self) -> None:
        """Stream at ``rate_hz`` in a background thread until :meth:`stop`."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="serial-emulator", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        next_t = time.monotonic()
        while not self._stop.is_set():
            if self._stop.wait(max(0.0, next_t - time.monotonic())):
                break
            if not self.has_reader():  # unplugged or nobody listening: pause
                next_t = time.monotonic() + 0.01
                continue
            # finish a started line even while stopping (up to 2 s), never cut it
            self._send_one(time.monotonic() + 2.0)
            next_t += period
            if time.monotonic() - next_t > 1.0:  # the reader stalled: no catch-up burst
                next_t = time.monotonic()

    # ---- results ---------------------------------------------------------------------
    def report(self) -> dict[str, Any]:
        """Exact counts of lines completely written since construction."""
        with self._lock:
            bad = {k: self.malformed[k] for k in KINDS if self.malformed[k]}
            return {"lines": self.good + sum(bad.values()), "good": self.good,
                    "malformed": sum(bad.values()), "malformed_by_kind": bad,
                    "interrupted": self.interrupted, "opens": self.opens}

    def sent_frames(self) -> np.ndarray:
        """Every good frame written (needs ``keep_sent``), in order."""
        with self._lock:
            if not self._sent:
                return np.empty((0, 0), dtype=np.int64)
            return np.stack(self._sent)
