"""A finished run's fold model applied to windows of raw frames — shared by the session
player (prediction over a recording) and live inference (prediction on the live stream).

Each window is treated as one trial and goes through the learner's own view,
normalisation and ``predict_proba``, so every model (torch or the rf / knn baselines)
works the same way.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.data.dataset import TrialDataset
from tactile_studio.learn.data.windowing import cut, window_spec
from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.runfolder import model_file, read_run
from tactile_studio.learn.learners.baselines import legacy_options
from tactile_studio.learn.learners.families import DataInfo, make_learner
from tactile_studio.learn.learners.fused import (
    display_name,
    person_columns,
    standardises_person_features,
)
from tactile_studio.sensor.decode import decode
from tactile_studio.sensor.layout import Layout

PREDICTION_HOP_S = 0.25  # live inference predicts its newest window this often; the player too


class WindowModel:
    def __init__(self, run: str | os.PathLike, participant: str | None = None,
                 round_: int = 0) -> None:
        """Loads the fold model of round ``round_`` that did not see ``participant``
        (else the first fold)."""
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
        self.record = next((r for r in records if participant and r.get("round", 0) == round_
                            and participant in (r.get("test_participants") or [])),
                           records[0])
        overrides = legacy_options(self.config.model, resolved.get("model"),
                                   self.config.overrides)
        self.learner = make_learner(self.config.model, self.config.preset, overrides,
                                    self.config.epochs, "cpu")
        self.trained = self.learner.load(model_file(self.record["_dir"]), self.info)
        self.fitted = self.trained  # or adapted to one person by calibrate()
        self.run_trained = self.trained  # the run's own fold model (personalise() swaps)
        self.run_norm = self.record["norm"]
        self.norm = self.run_norm  # the input normalisation of ``trained``
        self.personalised: Any = None  # learn/deploy/personalise.py's Personalised, when used
        self.reference: np.ndarray | None = None  # that person's samples (rf/knn features)
        pooled = self.record.get("as_trained")  # a forest --adapt: training people pooled
        self.pooled = None if pooled is None else np.asarray(pooled, dtype=np.float32)
        self.calibrated_on = ""  # what calibrate() was given, for display
        self.spec = window_spec(self.config.window_s, self.config.window_overlap,
                                float(summary.get("trial_s") or 0.0))
        lo, hi = int(summary.get("frames_min", 64)), int(summary.get("frames_max", 64))
        self.window = max(2, (lo + hi) // 2)  # a typical trial's length in frames

    @property
    def name(self) -> str:
        return self.run.name

    def window_for(self, rate: float) -> int:
        """Frames per live window at ``rate``: a typical trial, or the run's training
        window when its trials were long (a 12 s performance is then predicted 2 s at a
        time, as the run trained, not 12 s behind the touch)."""
        if not rate > 0:  # rate not known yet
            return self.window
        w = self.spec.frames(rate)
        return w if self.window > self.spec.long_factor * w else self.window

    def prediction_ends(self, n_frames: int, rate: float, hop: int | None = None
                        ) -> tuple[int, np.ndarray]:
        """(window frames, end frame (exclusive) of each window) of the predictions over
        ``n_frames`` frames at ``rate``: the window live inference predicts with
        (:meth:`window_for`), one every ``PREDICTION_HOP_S`` (or ``hop`` frames), the first
        once a whole window is in: what live inference would have shown over them."""
        w = max(2, min(self.window_for(rate), n_frames))
        step = hop or max(1, int(round(PREDICTION_HOP_S * rate)))
        return w, np.arange(w, n_frames + 1, max(1, step))

    @property
    def reads_person_features(self) -> bool:
        """An rf/knn (or fused forest) run trained with ``--adapt`` reads features
        standardised by the person's own statistics, from a recording of them or their
        touches (until then they read them with the training people's pooled ones)."""
        return self.config.adapt != "none" and standardises_person_features(self.learner)

    @property
    def has_view_as_trained(self) -> bool:
        """True when ``predict_windows(as_trained=True)`` can read a window without the
        person's statistics: networks (batch norm as trained), plain rf/knn, and rf/knn
        (or a fused forest) trained with ``--adapt`` whose folds kept their training
        people's pooled feature statistics (runs from before that have none)."""
        return not self.reads_person_features or self.pooled is not None

    @property
    def needs_calibration(self) -> bool:
        """True until a run that reads person features, and has no view as trained,
        has been calibrated."""
        return self.reference is None and not self.has_view_as_trained

    @property
    def adapts_as_they_touch(self) -> bool:
        """Trained with ``--adapt``, so live inference can adapt it to each window with
        the person's last touches (live_inference.py). A streaming model is then predicted
        window by window: every re-estimate changes its cached per-frame embeddings."""
        return self.config.adapt != "none"

    @property
    def can_calibrate(self) -> bool:
        """A network adapts its batch norm to anyone; rf/knn only when trained on
        features standardised per person (``--adapt``)."""
        return self.learner.kind != "baseline" or self.config.adapt != "none"

    def calibrate(self, layout: Layout, windows: list[np.ndarray],
                  rate: float | Sequence[float], source: str = "",
                  batch_norm: bool = True) -> int:
        """Meets one person as ``--adapt person`` met each test person, from decoded
        windows (C, N, R, X) of a recording of them (labels unused; ``rate``: theirs, or
        one per window when they were recorded at different rates): rf/knn features
        standardised by their statistics, and (``batch_norm``) a network's batch norm
        re-estimated on them. Returns the number of samples it rests on."""
        self._can_calibrate()
        return self.calibrate_samples(self._samples(layout, windows, rate)[0], source,
                                      batch_norm)

    def _can_calibrate(self) -> None:
        if not self.can_calibrate:
            raise UserError(f"{self.run}: {self.config.model} was trained without --adapt; "
                            "its features cannot be re-standardised afterwards (a network's "
                            "batch norm can: train again with --adapt person)")

    def calibrate_samples(self, x: np.ndarray, source: str = "",
                          batch_norm: bool = True) -> int:
        """:meth:`calibrate` from the learner's samples of the person's windows
        (``samples``), for a caller that keeps them as the person's recording grows."""
        self._can_calibrate()
        if len(x) < 2:
            raise UserError(f"{source or 'calibration'}: too short to calibrate "
                            f"({len(x)} window(s) of {self.window} frames)")
        reference = person_columns(self.learner, x) if self.config.adapt != "none" else None
        x = self.learner.adapt_inputs(x, np.zeros(len(x)), reference)
        fitted = self.trained
        if batch_norm and hasattr(fitted, "adapted"):
            fitted = fitted.adapted(self.learner.apply_norm(x, self.norm))
        self.fitted, self.reference, self.calibrated_on = fitted, reference, source
        return len(x)

    def uncalibrate(self) -> None:
        """Back to the model as trained (a running calibration starts from nothing)."""
        self.fitted, self.reference, self.calibrated_on = self.trained, None, ""

    def personalise(self, personal: Any) -> None:
        """Predict with a model personalised with the person's labelled touches
        (learn/deploy/personalise.py) in place of the run's fold model, as trained for it."""
        self.trained = self.fitted = personal.fitted
        self.norm, self.personalised = personal.norm, personal
        self.reference = personal.reference
        self.calibrated_on = "their labelled touches" if personal.reference is not None else ""

    def forget_personalisation(self) -> None:
        """Back to the run's own fold model, as trained."""
        self.trained, self.norm, self.personalised = self.run_trained, self.run_norm, None
        self.uncalibrate()

    @property
    def streams(self) -> bool:
        """True for models declaring sliding-window streaming: live inference then pushes
        frames through learn/deploy/streaming.py (cached per-frame embeddings where declared)."""
        return self.learner.facts.sliding

    def streaming_predictor(self):
        from tactile_studio.learn.deploy.streaming import InputNorm, StreamingPredictor
        from tactile_studio.learn.models import Streaming

        facts, norm = self.learner.facts, self.norm
        # hop far beyond any stream: frames are only pushed, predict() is called per step
        return StreamingPredictor(self.fitted.model, self.learner.view,
                                  norm=InputNorm(norm["mean"], norm["std"]), hop=1 << 30,
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

    def predict_windows(self, layout: Layout, windows: list[np.ndarray], rate: float,
                        as_trained: bool = False) -> np.ndarray:
        """Probabilities (n_windows, n_classes) for decoded windows (C, N, R, X), by the
        model as calibrated (``as_trained``: with the training people's statistics; a forest
        trained with ``--adapt`` reads the features standardised by the training people's
        pooled statistics, the nearest they have to a view without the person's)."""
        if self.needs_calibration or (as_trained and not self.has_view_as_trained):
            raise UserError(f"{self.run}: trained with --adapt {self.config.adapt}, so "
                            f"{self.config.model} reads features standardised by the "
                            "person's own statistics: calibrate it on a recording of them")
        x, owner = self._samples(layout, windows, rate)
        reference = self.pooled if as_trained or self.reference is None else self.reference
        if reference is not None and self.reads_person_features:
            x = self.learner.adapt_inputs(x, np.zeros(len(x)), reference)
        fitted = self.trained if as_trained else self.fitted
        probs = np.zeros((len(windows), len(self.labels)))
        for i in range(0, len(x), 256):
            p = fitted.predict_proba(self.learner.apply_norm(x[i:i + 256],
                                                                  self.norm))
            np.add.at(probs, owner[i:i + 256], p)
        return probs / np.maximum(np.bincount(owner, minlength=len(windows))[:, None], 1)

    def samples(self, layout: Layout, windows: list[np.ndarray],
                rate: float | Sequence[float]) -> np.ndarray:
        """The learner's samples of decoded windows (:meth:`calibrate_samples` reads
        them), each cut as the run cut long trials."""
        return self._samples(layout, windows, rate)[0]

    def _samples(self, layout: Layout, windows: list[np.ndarray],
                 rate: float | Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """The learner's samples of decoded windows, each window one trial cut as the
        run cut long trials at its rate (``rate``: of all, or one per window) (samples,
        owner window per sample)."""
        rates = np.broadcast_to(np.asarray(rate, dtype=np.float64), (len(windows),)).copy()
        ds = TrialDataset(trials=windows, labels=np.zeros(len(windows), dtype=np.int64),
                          participants=np.array(["live"] * len(windows)),
                          uids=[f"w{i}" for i in range(len(windows))],
                          rates=rates, label_names=self.labels,
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
        pieces, piece_owner = cut(ds, self.spec)  # long windows: pieces as trained on
        x, sample_piece = self.learner.samples(pieces)
        return x, piece_owner[sample_piece]

    def describe(self) -> dict[str, Any]:
        return {"run": str(self.run),
                "model": display_name(self.config.model, self.config.overrides),
                "channels": self.config.channels, "fold": self.record["name"],
                "window": self.window, "labels": self.labels, "adapt": self.config.adapt,
                "calibrated_on": self.calibrated_on}
