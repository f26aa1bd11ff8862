"""Inputs from strangers (a foreign XDF file, another program's LSL markers): what they
say is data, stored as the content of our records and shown escaped, never taken as a
key of our own records or written raw to a terminal.

Shared below every layer: the XDF importer (storage) and the LSL marker inlets (streams)
both store a marker sample with :func:`marker_content`, and every line that names a
foreign thing goes through :func:`shown`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

SHOWN_CHARS = 80  # a foreign name or text quoted in a message, at most


def shown(text: object, limit: int = SHOWN_CHARS) -> str:
    """``text`` safe to print: every control or non-printable character (an escape
    sequence, a CR that would overwrite the line, a NUL) as a visible ``\\xNN`` /
    ``\\uNNNN``, and at most ``limit`` characters (then ``…``)."""
    s = str(text)
    out = "".join(c if c.isprintable() else ascii(c)[1:-1] for c in s[:limit])
    return out + ("…" if len(s) > limit else "")


def marker_content(values: Sequence[Any]) -> dict[str, Any]:
    """A marker sample's channels as an event's content: ``text`` (the one channel, or
    the channels joined by `` | `` for a reader that shows one text) and, for a stream
    of several channels, ``channels`` (each as sent)."""
    texts = [str(v) for v in values]
    if len(texts) == 1:
        return {"text": texts[0]}
    return {"text": " | ".join(texts), "channels": texts}
