"""Nothing a file, a device or a peer says reaches the terminal raw.

Names and texts from outside (a session's participant, notes and event kinds, a foreign
dataset's subjects, a stranger's run folder, a BLE device's advertised name) end up in
what commands print. Written raw, an escape sequence in them retitles the window, clears
the screen or recolours what follows, a carriage return overwrites the start of a line
and a bidirectional override reorders it. So the command line writes through
:class:`TerminalText` (``cli.main`` installs it on stdout and stderr): every character
that is not printable except newline and tab is shown as its escape (``\\u001b``), in
the form JSON also reads, so ``--json`` stays valid. The few writers that draw on the
terminal themselves (rich tables, progress bars, a status line) write to the stream
underneath (:func:`raw_stream`) and make their own text printable first.
"""

from __future__ import annotations

import io
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, TextIO


def printable(text: str, keep: str = "\n\t") -> str:
    """``text`` with every non-printable character but those in ``keep`` escaped.

    The one way a stranger's text is shown: on the terminal (newline and tab kept), and in
    a one-line message or a remote client's reply (``keep=""``: a CR or a newline there
    would hide or forge a line)."""
    if text.translate(str.maketrans("", "", keep)).isprintable():
        return text
    return "".join(c if c.isprintable() or c in keep else _escape(c) for c in text)


SHOWN_CHARS = 80  # a stranger's name or text quoted in a message, at most


def shown(text: object, limit: int = SHOWN_CHARS) -> str:
    """A stranger's name or text (a foreign file's stream, a client's field, a session's
    participant) as quoted in a one-line message: every non-printable character as its
    Python escape (``\\r``, ``\\x1b``, ``\\u202e``), so it can neither drive the
    terminal nor hide or forge text, and at most ``limit`` characters (then ``…``)."""
    s = str(text)
    out = "".join(c if c.isprintable() else ascii(c)[1:-1] for c in s[:limit])
    return out + ("…" if len(s) > limit else "")


def _escape(c: str) -> str:
    n = ord(c)
    return f"\\u{n:04x}" if n <= 0xFFFF else f"\\U{n:08x}"


class TerminalText(io.TextIOBase):
    """A text stream that writes :func:`printable` text to ``raw`` (and is it otherwise:
    ``isatty``, ``fileno``, ``encoding``... are the raw stream's)."""

    def __init__(self, raw: TextIO) -> None:
        super().__init__()
        self.raw = raw

    def write(self, text: str) -> int:
        self.raw.write(printable(text))
        return len(text)

    def flush(self) -> None:
        self.raw.flush()

    def isatty(self) -> bool:
        return self.raw.isatty()

    def fileno(self) -> int:
        return self.raw.fileno()

    def writable(self) -> bool:
        return True

    def close(self) -> None:
        """The raw stream is not ours to close (nor to flush when this one is dropped)."""

    @property
    def encoding(self) -> str:  # type: ignore[override]
        return getattr(self.raw, "encoding", "utf-8")

    def __getattr__(self, name: str) -> Any:
        return getattr(self.raw, name)


def raw_stream(stream: TextIO) -> TextIO:
    """The stream under a :class:`TerminalText` (any other stream as it is): for a writer
    that draws on the terminal with its own escape sequences."""
    while isinstance(stream, TerminalText):
        stream = stream.raw
    return stream


@contextmanager
def printable_output() -> Iterator[None]:
    """stdout and stderr write printable text only, until the block ends."""
    saved = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _wrapped(sys.stdout), _wrapped(sys.stderr)
    try:
        yield
    finally:
        sys.stdout, sys.stderr = saved


def _wrapped(stream: TextIO | None) -> TextIO | None:
    if stream is None or isinstance(stream, TerminalText):  # no console; already wrapped
        return stream
    return TerminalText(stream)
