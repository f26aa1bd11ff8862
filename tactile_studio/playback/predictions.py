"""A run's prediction over a session's time: a sliding window of the session's frames goes
through the fold model that did not see the session's participant (see window_model.py).
"""

from __future__ import annotations

import os

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.window_model import WindowModel
from tactile_studio.playback import SessionPlayback


def predictions_over_time(run: str | os.PathLike, pb: SessionPlayback, hop: int = 4,
                          window: int | None = None
                          ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(last frame of each window, probabilities (n, classes), labels)."""
    participant = str(pb.metadata.get("participant") or pb.path.stem)
    model = WindowModel(run, participant)
    lengths = [t.end - t.start for t in pb.trials if t.end > t.start]
    w = int(window or (int(np.median(lengths)) if lengths else model.window))
    w = max(2, min(w, pb.n_frames))
    ends = np.arange(w, pb.n_frames + 1, max(1, hop))
    if not len(ends):
        raise UserError(f"{pb.path}: shorter than one prediction window ({w} frames)")
    frames = model.decode(pb.layout, pb.raw, pb.session.baseline(0))
    rate = (pb.n_frames - 1) / pb.duration if pb.duration > 0 else 43.0
    probs = model.predict_windows(pb.layout, [frames[:, e - w:e] for e in ends], rate)
    return ends - 1, probs, model.labels
