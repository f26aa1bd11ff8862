"""A run's prediction over a session's time: a sliding window of the session's frames goes
through the fold model that did not see the session's participant (see window_model.py).

A run trained with ``--adapt`` met each test person with their own statistics, so the
prediction over a session is adapted to that session (as ``evaluate`` scored it); the same
calibration from a recording of a person serves live inference (``calibrate_to_session``).
"""

from __future__ import annotations

import os

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.playback import SessionPlayback
from tactile_studio.storage.format.trials import TrialStatus


def predictions_over_time(run: str | os.PathLike, pb: SessionPlayback, hop: int | None = None
                          ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(last frame of each window, probabilities (n, classes), labels): the model's own
    window and step, as live inference predicts (``WindowModel.prediction_ends``; ``hop``
    frames between predictions instead of live's step). A run trained on 2 s windows of
    12 s performances predicts 2 s windows, the first 2 s into the session."""
    participant = str(pb.metadata.get("participant") or pb.path.stem)
    model = WindowModel(run, participant)
    w, ends = model.prediction_ends(pb.n_frames, _rate(pb), hop)
    if not len(ends):
        raise UserError(f"{pb.path}: shorter than one prediction window ({w} frames)")
    frames = model.decode(pb.layout, pb.raw, pb.session.baseline(0))
    if model.config.adapt != "none":
        model.calibrate(pb.layout, calibration_windows(pb, frames, w), _rate(pb), str(pb.path))
    probs = model.predict_windows(pb.layout, [frames[:, e - w:e] for e in ends], _rate(pb))
    return ends - 1, probs, model.labels


def calibration_windows(pb: SessionPlayback, frames: np.ndarray, window: int
                        ) -> list[np.ndarray]:
    """What a person's statistics are taken from: the session's counted trials (as
    ``--adapt`` took each test person's trials), or, in a recording without trials,
    half-overlapping windows of ``window`` frames over all of it."""
    trials = [frames[:, t.start:t.end] for t in pb.trials
              if t.status == TrialStatus.OK and t.end - t.start >= 2]
    if trials:
        return trials
    hop = max(1, window // 2)
    return [frames[:, s:s + window] for s in range(0, pb.n_frames - window + 1, hop)]


def calibrate_to_session(model: WindowModel, path: str | os.PathLike,
                         batch_norm: bool = True) -> int:
    """``model`` adapted to the person recorded in session file ``path`` (live use: a
    short calibration recording of the participant first; ``batch_norm``: see
    ``WindowModel.calibrate``). Returns the samples used."""
    pb = SessionPlayback(path)
    try:
        frames = model.decode(pb.layout, pb.raw, pb.session.baseline(0))
        windows = calibration_windows(pb, frames, min(model.window, pb.n_frames))
        return model.calibrate(pb.layout, windows, _rate(pb), str(path), batch_norm)
    finally:
        pb.close()


def _rate(pb: SessionPlayback) -> float:
    return (pb.n_frames - 1) / pb.duration if pb.duration > 0 else 43.0
