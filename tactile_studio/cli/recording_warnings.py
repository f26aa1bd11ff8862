"""Problems during a recording, said on a line of their own as they happen: a device gone
silent (acquisition/stream_health.py), a marker stream that disappeared."""

from __future__ import annotations

import sys
from typing import Any


def warn(message: str) -> None:
    """``warning: <message>`` on stderr, after a line break (a progress bar may be drawn)."""
    print(f"\nwarning: {message}", file=sys.stderr, flush=True)


def watch_health(session: Any) -> None:
    """Print the acquisition session's ``health`` events (its poll finds them)."""
    session.add_listener(lambda e: warn(e["message"]) if e["kind"] == "health" else None)
