"""A run's prediction over a session's time: a sliding window of the session's frames goes
through the fold model that did not see the session's participant, as the model would
see a trial. Works for every model (torch and the rf / knn baselines): each window is
treated as one trial and passed through the learner's own view, normalisation and
``predict_proba``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.learn.dataset import TrialDataset
from tactile_studio.learn.experiment import ExperimentConfig
from tactile_studio.learn.learners import DataInfo, make_learner
from tactile_studio.learn.runfolder import WEIGHTS, read_run
from tactile_studio.playback import SessionPlayback


def predictions_over_time(run: str | os.PathLike, pb: SessionPlayback, hop: int = 4,
                          window: int | None = None, cancel: CancelToken | None = None
                          ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(end frame of each window, probabilities (n, classes), labels)."""
    cfg, records = read_run(run)
    config = ExperimentConfig.from_dict(cfg["config"])
    resolved = cfg["resolved"]
    info = DataInfo.from_dict(resolved["data_info"])
    labels = list(resolved["dataset"]["labels"])
    participant = str(pb.metadata.get("participant") or pb.path.stem)
    rec = next((r for r in records if participant in (r.get("test_participants") or [])),
               records[0])
    learner = make_learner(config.model, config.preset, config.overrides, config.epochs, "cpu")
    fitted = learner.load(Path(rec["_dir"]) / WEIGHTS, info)
    virtual = config.grid == "virtual"
    lengths = [t.end - t.start for t in pb.trials if t.end > t.start]
    w = int(window or (int(np.median(lengths)) if lengths else 64))
    w = max(2, min(w, pb.n_frames))
    ends = np.arange(w, pb.n_frames + 1, max(1, hop))
    if not len(ends):
        raise UserError(f"{pb.path}: shorter than one prediction window ({w} frames)")
    frames = decode(pb, virtual)
    if frames.shape[0] != 3 and info.in_channels != frames.shape[0]:
        raise UserError(f"{pb.path}: {frames.shape[0]} channel(s), the run needs "
                        f"{info.in_channels}")
    trials = [frames[:, e - w:e] for e in ends]
    rate = (pb.n_frames - 1) / pb.duration if pb.duration > 0 else 43.0
    ds = TrialDataset(trials=trials, labels=np.zeros(len(trials), dtype=np.int64),
                      participants=np.array([participant] * len(trials)),
                      uids=[f"w{e}" for e in ends], rates=np.full(len(trials), rate),
                      label_names=labels, layout=pb.layout.name, grid=config.grid,
                      has_shear=pb.layout.has_shear, channels="both" if pb.layout.has_shear
                      else "normal")
    ds = ds.select(config.channels) if pb.layout.has_shear else ds
    if ds.grid_shape != tuple(info.grid) or ds.n_channels != info.in_channels:
        raise UserError(f"{pb.path}: {ds.grid_shape[0]}x{ds.grid_shape[1]} grid with "
                        f"{ds.n_channels} channel(s) does not fit the run's models")
    x, owner = learner.samples(ds)
    probs = np.zeros((len(ends), len(labels)))
    step = 256
    for i in range(0, len(x), step):
        if cancel is not None:
            cancel.check()
        p = fitted.predict_proba(learner.apply_norm(x[i:i + step], rec["norm"]))
        np.add.at(probs, owner[i:i + step], p)
    probs /= np.maximum(np.bincount(owner, minlength=len(ends))[:, None], 1)
    return ends - 1, probs, labels


def decode(pb: SessionPlayback, virtual: bool) -> np.ndarray:
    """The whole session decoded as (C, N, R, X) against its first baseline."""
    from tactile_studio.sensor.decode import decode as decode_raw

    frames = decode_raw(pb.layout, pb.raw, pb.session.baseline(0), virtual)
    stack = frames.stack() if pb.layout.has_shear else frames.normal[None]
    return np.ascontiguousarray(stack, dtype=np.float32)
