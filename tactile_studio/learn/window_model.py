"""A finished run's fold model applied to windows of raw frames — shared by the session
player (prediction over a recording) and live inference (prediction on the live stream).

Each window is treated as one trial and goes through the learner's own view,
normalisation and ``predict_proba``, so every model (torch or the rf / knn baselines)
works the same way.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.dataset import TrialDataset
from tactile_studio.learn.experiment import ExperimentConfig
from tactile_studio.learn.learners import DataInfo, make_learner
from tactile_studio.learn.runfolder import model_file, read_run
from tactile_studio.sensor.decode import decode
from tactile_studio.sensor.layout import Layout


class WindowModel:
    def __init__(self, run: str | os.PathLike, participant: str | None = None) -> None:
        """Loads the fold model that did not see ``participant`` (else the first fold)."""
        self.run = Path(run)
        cfg, records = read_run(run)
        try:
            self.config = ExperimentConfig.from_dict(cfg["config"])
            resolved = cfg["resolved"]
            self.info = DataInfo.from_dict(resolved["data_info"])
            self.labels: list[str] = list(resolved["dataset"]["labels"])
            summary = resolved["dataset"]
        except (KeyError, TypeError):
            raise UserError(f"{run}: not a run folder of this version (config.json lacks "
                            "the resolved data description)") from None
        self.record = next((r for r in records
                            if participant and participant in (r.get("test_participants") or [])),
                           records[0])
        self.learner = make_learner(self.config.model, self.config.preset,
                                    self.config.overrides, self.config.epochs, "cpu")
        if self.config.adapt != "none" and self.learner.kind != "torch":
            raise UserError(f"{run}: trained with --adapt {self.config.adapt}, so "
                            f"{self.config.model} reads "
                            "features standardised by each person's own statistics, which a "
                            "live stream does not have; for live use train without --adapt")
        self.fitted = self.learner.load(model_file(self.record["_dir"]), self.info)
        lo, hi = int(summary.get("frames_min", 64)), int(summary.get("frames_max", 64))
        self.window = max(2, (lo + hi) // 2)  # a typical trial's length in frames

    @property
    def name(self) -> str:
        return self.run.name

    @property
    def streams(self) -> bool:
        """True for models declaring sliding-window streaming: live inference then pushes
        frames through learn/streaming.py (cached per-frame embeddings where declared)."""
        return self.learner.facts.sliding

    def streaming_predictor(self):
        from tactile_studio.learn.models import Streaming
        from tactile_studio.learn.streaming import StreamingPredictor

        facts, norm = self.learner.facts, self.record["norm"]
        # hop far beyond any stream: frames are only pushed, predict() is called per step
        return StreamingPredictor(self.fitted.model, self.learner.view, mean=norm["mean"],
                                  std=norm["std"], hop=1 << 30,
                                  streaming=Streaming(facts.sliding, facts.cached))

    def channels_of(self, frames: np.ndarray, layout: Layout) -> np.ndarray:
        """Decoded (C, N, R, X) with every channel -> the run's channel set, (N, C', R, X)."""
        if layout.has_shear and self.config.channels in ("normal", "shear"):
            frames = frames[slice(0, 1) if self.config.channels == "normal" else slice(1, 3)]
        return np.ascontiguousarray(frames.transpose(1, 0, 2, 3))

    def decode(self, layout: Layout, raw: np.ndarray, baseline: np.ndarray) -> np.ndarray:
        """Raw counts (N, channels) -> (C, N, R, X) with every decoded channel."""
        frames = decode(layout, raw, baseline, self.config.grid == "virtual")
        stack = frames.stack() if layout.has_shear else frames.normal[None]
        return np.ascontiguousarray(stack, dtype=np.float32)

    def predict_windows(self, layout: Layout, windows: list[np.ndarray], rate: float
                        ) -> np.ndarray:
        """Probabilities (n_windows, n_classes) for decoded windows (C, N, R, X)."""
        ds = TrialDataset(trials=windows, labels=np.zeros(len(windows), dtype=np.int64),
                          participants=np.array(["live"] * len(windows)),
                          uids=[f"w{i}" for i in range(len(windows))],
                          rates=np.full(len(windows), float(rate)), label_names=self.labels,
                          layout=layout.name, grid=self.config.grid,
                          has_shear=layout.has_shear,
                          channels="both" if layout.has_shear else "normal")
        if layout.has_shear:
            ds = ds.select(self.config.channels)
        if ds.grid_shape != tuple(self.info.grid) or ds.n_channels != self.info.in_channels:
            raise UserError(f"{layout.name}: a {ds.grid_shape[0]}x{ds.grid_shape[1]} grid with "
                            f"{ds.n_channels} channel(s) does not fit the run's models "
                            f"({self.info.grid[0]}x{self.info.grid[1]}, "
                            f"{self.info.in_channels})")
        x, owner = self.learner.samples(ds)
        probs = np.zeros((len(windows), len(self.labels)))
        for i in range(0, len(x), 256):
            p = self.fitted.predict_proba(self.learner.apply_norm(x[i:i + 256],
                                                                  self.record["norm"]))
            np.add.at(probs, owner[i:i + 256], p)
        return probs / np.maximum(np.bincount(owner, minlength=len(windows))[:, None], 1)

    def describe(self) -> dict[str, Any]:
        return {"run": str(self.run), "model": self.config.model,
                "channels": self.config.channels, "fold": self.record["name"],
                "window": self.window, "labels": self.labels}
