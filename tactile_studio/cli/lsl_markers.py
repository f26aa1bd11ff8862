"""``--markers NAME`` for ``record`` and ``collect``: LSL marker streams of other programs
recorded as events at their frames (streams/marker_inlet.py)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from tactile_studio.cli.recording_warnings import warn
from tactile_studio.devices.frame_stream import LiveStream

MARKERS_HELP = ("record the markers of this LSL marker stream (by name; repeatable), each "
                "as an event at the frame its timestamp falls on, e.g. PsychoPy's")


def add_markers_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--markers", action="append", metavar="NAME", default=None,
                        help=MARKERS_HELP)


def start_markers(engine: LiveStream, names: list[str] | None) -> Any:
    """Inlets on ``names`` feeding ``engine`` (hand them to ``session.add_outlet``, which
    stops them before the file closes); a stream not found is a one-line error."""
    from tactile_studio.streams.marker_inlet import MarkerInlets

    inlets = MarkerInlets(engine, names or [], on_problem=warn)
    print(f"LSL: recording markers from {', '.join(names or [])}", file=sys.stderr)
    return inlets
