"""A finished trial's times and quality flags, measured on the stream's ring buffer."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tactile_studio.devices.engine_events import SequenceGap
from tactile_studio.devices.frame_stream import FrameStream
from tactile_studio.protocol.quality import FrameTiming, QualitySettings, trial_flags


@dataclass(frozen=True)
class TrialMeasure:
    start_time: float  # device time of the first frame, s
    end_time: float    # device time just after the last frame, s
    flags: list[str]
    raw: np.ndarray | None = None  # the trial's raw counts (T, channels) as the ring held them


def measure_trial(engine: FrameStream, start: int, n: int, rate: float,
                  settings: QualitySettings, event_cursor: int = 0,
                  recorder_lost: int = 0, force: str | None = None) -> TrialMeasure:
    """Frames ``start .. start+n`` (engine indices) judged for quality.

    Frames the ring no longer holds, and frames the recorder lost (``recorder_lost``),
    count as dropped; engine gap events strictly inside the trial count as gaps.
    """
    end = start + n
    chunk = engine.read_since(start, n)
    lo = max(chunk.start, start)
    keep = slice(lo - chunk.start, max(lo - chunk.start, min(chunk.stop, end) - chunk.start))
    raw, dev_t, seq = chunk.raw[keep], chunk.device_time[keep], chunk.seq[keep]
    lost = n - raw.shape[0] + recorder_lost
    gaps = sum(1 for e in engine.events_since(event_cursor)
               if e.get("kind") == SequenceGap.kind and start < int(e.get("frame", -1)) < end)
    flags: list[str] = []
    if engine.baseline is not None:
        timing = FrameTiming(dev_t, seq, rate, lost, gaps)
        flags = trial_flags(engine.layout, raw, engine.baseline, timing=timing,
                            settings=settings, force=force)
    t0 = float(dev_t[0]) if len(dev_t) else 0.0
    t1 = float(dev_t[-1]) + 1.0 / rate if len(dev_t) else 0.0
    return TrialMeasure(round(t0, 6), round(t1, 6), flags, raw)
