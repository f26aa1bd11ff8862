"""Streaming inference: class probabilities for the newest window as frames arrive.

Models declaring ``Streaming(cached=True)`` on their ModelSpec (they have ``frame_features``,
a per-frame embedding, and ``classify_embeddings``, window of embeddings -> logits), i.e.
the CNN-Transformer, get the cached path: each
new frame goes through the per-frame CNN exactly once, its embedding is kept in a ring
of the window's length, and a prediction runs only the Transformer over the ring (and,
for a model that ``needs_window``, its statistics head over a second ring of the window's
frames: the same computation as the model's forward pass on the window). Any
other model gets the generic path: the last ``window`` frames are kept, turned into the
model's view (resample / slices / gradient sampling of that window) and fully recomputed.
The rf / k-NN baselines (a :class:`~tactile_studio.learn.learners.baselines.BaselineModel`, an ONNX
graph run by onnxruntime) get the feature path: the last ``window`` frames are one trial,
turned into its handcrafted feature vector and classified.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from tactile_studio.errors import UserError
from tactile_studio.learn.choices import CHANNEL_SETS
from tactile_studio.learn.data import views
from tactile_studio.learn.learners.baselines import BaselineModel
from tactile_studio.learn.models import Streaming, ViewSpec, spec_of
from tactile_studio.learn.models.spec import classify_window, needs_window
from tactile_studio.sensor.decode import decode
from tactile_studio.sensor.layout import Layout

_CHANNEL_SLICES = {"normal": slice(0, 1), "shear": slice(1, 3), "both": slice(0, 3)}


def frames_from_raw(
    layout: Layout, raw: np.ndarray, baseline: np.ndarray, *, virtual: bool = False,
    channels: str = "both",
) -> np.ndarray:
    """Raw counts (N, n_channels) -> decoded frames (N, C, R, X) in the dataset's channel
    order (normal / shear-x / shear-y; pressure-only layouts give the one channel)."""
    frames = decode(layout, raw, baseline, virtual)
    if not layout.has_shear:
        return frames.normal[:, None]
    if channels not in _CHANNEL_SLICES:
        raise UserError(f"unknown channel set {channels!r} "
                        f"(available: {', '.join(CHANNEL_SETS)})")
    return np.ascontiguousarray(frames.stack()[_CHANNEL_SLICES[channels]].transpose(1, 0, 2, 3))


class _Embeddings(nn.Module):
    """The classification half of a cached model, as a module (for ONNX export)."""

    def __init__(self, model: nn.Module) -> None:
        super().__init__()
        self.model = model
        self.train(model.training)  # the export restores this mode: keep the model's

    def forward(self, emb: torch.Tensor, window: torch.Tensor | None = None) -> torch.Tensor:
        return classify_window(self.model, emb, window)


class _FrameCNN(nn.Module):
    def __init__(self, model: nn.Module) -> None:
        super().__init__()
        self.model = model
        self.train(model.training)  # the export restores this mode: keep the model's

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        return self.model.frame_features(frames)


@dataclass(frozen=True)
class InputNorm:
    """How a run z-scored its inputs: per-channel ``mean`` and ``std`` (a fold
    record's ``norm``), applied to every frame before the model sees it."""

    mean: np.ndarray
    std: np.ndarray


class StreamingPredictor:
    """Push frames one at a time; get softmax probabilities for the newest full window.

    ``view`` is the model's ViewSpec. For "windows" models the window is ``view.frames``
    frames; for the others ``window`` (default ``view.frames``) raw frames are buffered and
    converted to the view on each prediction. ``norm`` (per channel, from the training
    set) z-scores incoming frames; omit it if frames are already z-scored.
    ``hop`` predicts every ``hop`` frames (1 = on every frame once the window is full).
    ``backend="onnx"`` runs the same computation with onnxruntime (exported from the
    model at the first frame; several times faster than torch for one frame on a CPU);
    ``threads`` sets its intra-op threads: 1 by default, because one sample's small ops
    gain little from more and, on a busy 2-core machine, two threads stall each other
    (measured: p95 latency 5-100x worse); 0 = onnxruntime's default.
    ``streaming`` is the model's declared streaming facts (default: those of the ModelSpec
    that built ``model``; none for a module built otherwise, which gets the generic path).
    For an rf / k-NN ``model`` (loaded from a run folder's ``model.onnx``), ``view`` may be
    None, ``window`` (the trial length in frames) is required, frames are decoded but not
    z-scored, ``rate`` (Hz) feeds the spectral features, and prediction is onnxruntime.
    """

    def __init__(
        self,
        model: nn.Module,
        view: ViewSpec,
        *,
        window: int | None = None,
        norm: InputNorm | None = None,
        hop: int = 1,
        backend: str = "torch",
        threads: int = 1,
        rate: float = 43.0,
        streaming: Streaming | None = None,
    ) -> None:
        if backend not in ("torch", "onnx"):
            raise UserError(f"unknown streaming backend {backend!r} (available: torch, onnx)")
        self.features = isinstance(model, BaselineModel)
        spec = None if self.features else spec_of(model)
        if streaming is None:
            streaming = spec.streaming if spec is not None else Streaming()
        if backend == "onnx" and spec is not None and "onnx" not in spec.export:
            raise UserError(f"model '{spec.name}' does not export to ONNX "
                            f"(it declares {', '.join(spec.export)}): use backend torch")
        self.model = model if self.features else model.eval()
        self.view, self.rate = view, float(rate)
        if self.features:
            if window is None:
                raise UserError("an rf / knn model needs the streaming window (trial frames)")
            self.window = int(window)
        else:
            self.window = int(view.frames if window is None or view.kind == "windows"
                              else window)
        if self.window < 1 or hop < 1:
            raise UserError("streaming window and hop must be at least 1 frame")
        self.hop, self.backend, self.threads = hop, backend, threads
        self.mean = None if norm is None else np.asarray(norm.mean, np.float32).reshape(-1, 1, 1)
        self.std = None if norm is None else np.asarray(norm.std, np.float32).reshape(-1, 1, 1)
        self.cached = not self.features and view.kind == "windows" and streaming.cached
        # the statistics head of a cached model reads the window's frames: keep them too
        self.keeps_frames = self.cached and needs_window(model)
        self._sessions: tuple | None = None
        self._ring: np.ndarray | None = None
        self._frames: np.ndarray | None = None
        self.frames_seen = 0

    def reset(self) -> None:
        """Forget buffered frames (e.g. after a gap in the stream)."""
        self._ring = None
        self._frames = None
        self.frames_seen = 0

    @property
    def ready(self) -> bool:
        return self.frames_seen >= self.window

    def _normalise(self, frame: np.ndarray) -> np.ndarray:
        frame = np.asarray(frame, dtype=np.float32)
        if frame.ndim != 3:
            raise ValueError(f"a frame is (C, R, X), got shape {frame.shape}")
        if self.mean is not None:
            frame = frame - self.mean
        if self.std is not None:
            frame = frame / self.std
        return np.ascontiguousarray(frame)

    def _onnx(self, frame: np.ndarray) -> tuple:
        """(frame-or-window session, classifier session or None), exported on first use."""
        if self._sessions is None:
            from tactile_studio.learn.learners.onnx_io import cpu_session, onnx_bytes

            one = torch.from_numpy(frame)[None]
            if self.cached:
                with torch.inference_mode():
                    dim = self.model.frame_features(one).shape[1]
                cnn = onnx_bytes(_FrameCNN(self.model), one, "frame", "embedding")
                emb = torch.zeros(1, self.window, dim)
                if self.keeps_frames:
                    window = torch.zeros(1, frame.shape[0], self.window, *frame.shape[1:])
                    head = onnx_bytes(_Embeddings(self.model), (emb, window),
                                      ("input", "window"))
                else:
                    head = onnx_bytes(_Embeddings(self.model), emb)
                self._sessions = (cpu_session(cnn, self.threads),
                                  cpu_session(head, self.threads))
            else:
                shape = (1, frame.shape[0], self.view.frames, *frame.shape[1:])
                whole = onnx_bytes(self.model, torch.zeros(shape))
                self._sessions = (cpu_session(whole, self.threads), None)
        return self._sessions

    def _embed(self, frame: np.ndarray) -> np.ndarray:
        if self.backend == "onnx":
            return self._onnx(frame)[0].run(None, {"frame": frame[None]})[0][0]
        with torch.inference_mode():
            return self.model.frame_features(torch.from_numpy(frame)[None])[0].numpy()

    def push(self, frame: np.ndarray) -> np.ndarray | None:
        """Add one frame (C, R, X); probabilities (n_classes,) when a prediction is due."""
        frame = self._normalise(frame)
        item = self._embed(frame) if self.cached else frame
        if self._ring is None:
            self._ring = np.zeros((self.window, *item.shape), dtype=np.float32)
        self._ring[self.frames_seen % self.window] = item
        if self.keeps_frames:
            if self._frames is None:
                self._frames = np.zeros((self.window, *frame.shape), dtype=np.float32)
            self._frames[self.frames_seen % self.window] = frame
        self.frames_seen += 1
        if not self.ready or (self.frames_seen - self.window) % self.hop:
            return None
        return self.predict()

    def push_many(self, frames: np.ndarray) -> list[np.ndarray]:
        """Push (N, C, R, X) frames in order; the probabilities of every prediction made."""
        out = []
        for frame in frames:
            probs = self.push(frame)
            if probs is not None:
                out.append(probs)
        return out

    def _ordered(self, ring: np.ndarray | None = None) -> np.ndarray:
        """The ring's (or ``ring``'s) contents oldest first."""
        ring = self._ring if ring is None else ring
        start = self.frames_seen % self.window
        if start == 0:
            return ring
        return np.concatenate([ring[start:], ring[:start]])

    def current_window(self) -> np.ndarray:
        """The model input (1, C, T, R, X) the next generic prediction would use."""
        if self.cached or self.features:
            raise ValueError("only the generic path feeds a window to the model")
        trial = self._ordered().transpose(1, 0, 2, 3)  # (C, N, R, X)
        kind = "resample" if self.view.kind == "windows" else self.view.kind
        return np.ascontiguousarray(views.trial_view(trial, kind, self.view.frames)[:1],
                                    dtype=np.float32)

    def predict(self) -> np.ndarray:
        """Probabilities (n_classes,) for the newest full window."""
        if not self.ready:
            raise ValueError(f"need {self.window} frames, have {self.frames_seen}")
        if self.features:
            trial = np.ascontiguousarray(self._ordered().transpose(1, 0, 2, 3))
            return self.model.predict_trial(trial, self.rate)
        x = self._ordered()[None] if self.cached else self.current_window()
        window = None
        if self.keeps_frames:  # (1, C, T, R, X), the frames the embeddings came from
            window = np.ascontiguousarray(self._ordered(self._frames).transpose(1, 0, 2, 3)[None])
        if self.backend == "onnx":
            # cached: exported at the first frame (by _embed); else the ring holds frames
            first, head = self._sessions if self.cached else self._onnx(self._ring[0])
            session = head if self.cached else first
            feed = {session.get_inputs()[0].name: x}
            if window is not None:
                feed["window"] = window
            logits = session.run(None, feed)[0][0]
            e = np.exp(logits - logits.max())
            return e / e.sum()
        with torch.inference_mode():
            t = torch.from_numpy(x)
            logits = self.model(t) if not self.cached else classify_window(
                self.model, t, None if window is None else torch.from_numpy(window))
            return torch.softmax(logits[0], dim=0).numpy()
