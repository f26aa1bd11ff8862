"""Recording segments: a resume continues a session file in a new run of the device.

Each resume starts a segment at its row (the journal's ``resume`` event with
``from_file``/``segment``; not the collection runner's ``resume`` after a pause). The
device clock is continued across it (``device_time_offset``), but the time between the
runs is no frame time: a rate is measured per segment, so a resume never distorts it.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def is_segment_start(event: dict[str, Any]) -> bool:
    """A resume of the file (not the runner's resume after a pause)."""
    return event.get("kind") == "resume" and ("from_file" in event or "segment" in event)


def segment_starts(events: list[dict[str, Any]], n_frames: int) -> list[dict[str, Any]]:
    """The resume events that start a new segment inside the frames, in row order."""
    starts = [e for e in events if is_segment_start(e)
              and isinstance(e.get("frame"), int) and 0 < e["frame"] < n_frames]
    return sorted(starts, key=lambda e: e["frame"])


def segmented_rate_hz(times: np.ndarray, starts: list[int]) -> float:
    """Frames per second over the segments: the sum of (frames - 1) over the sum of time
    spanned, each segment on its own; 0 when it cannot be measured."""
    bounds = [0, *sorted(set(int(s) for s in starts if 0 < s < len(times))), len(times)]
    steps = span = 0.0
    for a, b in zip(bounds, bounds[1:]):
        if b - a >= 2:
            steps += b - a - 1
            span += float(times[b - 1] - times[a])
    return steps / span if span > 0 and np.isfinite(span) else 0.0


# a pause in a file's frame times: a step longer than this, and than this many typical
# frame intervals (the rule the XDF import gives pyxdf for its jitter segments)
PAUSE_S, PAUSE_FRAMES = 0.2, 5


def pauses(times: np.ndarray) -> list[int]:
    """The rows that follow a pause in ``times`` (a step over max(PAUSE_S, PAUSE_FRAMES
    median steps)): frames that never came, which are no frame time (an old CSV's import,
    its replay)."""
    if len(times) < 3:
        return []
    steps = np.diff(np.asarray(times, dtype=np.float64))
    limit = max(PAUSE_S, PAUSE_FRAMES * float(np.median(steps)))
    return [int(i) + 1 for i in np.flatnonzero(steps > limit)]
