"""Problems during a recording, said on a line of their own as they happen: a device gone
silent (acquisition/stream_health.py), a marker stream that disappeared."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from tactile_studio.acquisition.events import Health
from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.acquisition.stream_health import DEFAULT_SILENCE_S
from tactile_studio.cli.argtypes import positive_float


def warn(message: str) -> None:
    """``warning: <message>`` on stderr, after a line break (a progress bar may be drawn)."""
    print(f"\nwarning: {message}", file=sys.stderr, flush=True)


def add_silence_option(parser: argparse.ArgumentParser) -> None:
    """``--silence-warning S`` (record, collect, listen, gui): how long a device may send
    nothing while recording before it is said and stored (``stream_silent``)."""
    parser.add_argument("--silence-warning", type=positive_float, metavar="S", default=None,
                        help="say (and store as an event) a device that sends no frames for "
                             f"S seconds while recording (default {DEFAULT_SILENCE_S:g}); "
                             "longer for a device that pauses by design")


def apply_silence_option(session: Any, args: argparse.Namespace) -> None:
    """The acquisition session's threshold from ``--silence-warning`` when given."""
    if getattr(args, "silence_warning", None) is not None:
        session.silence_warning_s = args.silence_warning


def watch_health(session: LiveAcquisition) -> None:
    """Print the acquisition session's :class:`Health` events (its poll finds them)."""
    session.add_listener(lambda e: warn(e.message) if isinstance(e, Health) else None)
