"""Inputs from strangers (a foreign XDF file, another program's LSL markers): what they
say is data, stored as the content of our records and shown escaped, never taken as a
key of our own records or written raw to a terminal.

Shared below every layer: the XDF importer (storage) and the LSL marker inlets (streams)
both store a marker sample with :func:`marker_content`; every line that names a
foreign thing quotes it with ``terminal.shown``.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

FILE_PART_CHARS = 60  # of a foreign name in a file name



def marker_content(values: Sequence[Any]) -> dict[str, Any]:
    """A marker sample's channels as an event's content: ``text`` (the one channel, or
    the channels joined by `` | `` for a reader that shows one text) and, for a stream
    of several channels, ``channels`` (each as sent)."""
    texts = [str(v) for v in values]
    if len(texts) == 1:
        return {"text": texts[0]}
    return {"text": " | ".join(texts), "channels": texts}


def file_part(text: object, limit: int = FILE_PART_CHARS) -> str:
    """A foreign name (a dataset's subject, an XDF stream's name) as one part of a file
    name: letters, digits, ``.``, ``_`` and ``-`` only, at most ``limit`` characters, no
    leading or trailing dot or dash ("a/b" -> "a-b", "../x" -> "x", "" -> "unnamed").
    A separator, ``..``, a NUL or an escape sequence would otherwise make the name
    another folder, a traceback or a command to the terminal that prints it."""
    part = re.sub(r"[^A-Za-z0-9._-]+|\.\.+", "-", str(text))
    part = re.sub(r"-{2,}", "-", part)[:limit].strip(".-")
    return part or "unnamed"
