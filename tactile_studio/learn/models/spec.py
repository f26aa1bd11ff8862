"""What a torch model declares about itself: the ``ModelSpec`` a model module exports.

A model is one module that builds an ``nn.Module`` taking float32 ``(B, C, T, R, X)``
(channels, frames, grid rows, grid cols), already z-scored, and returning logits
``(B, n_classes)``, plus this declaration: the view of a trial it is fed, its training
defaults and architecture options per preset (``full`` = the paper, ``tiny`` = CPU tests),
and the facts the rest of the pipeline reads instead of probing the network: how it
exports, whether int8 quantisation works, how live inference may stream it, and how many
GPUs a training task wants. See docs/models.md.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import torch

from tactile_studio.errors import UserError
from tactile_studio.learn.presets import PRESETS

VIEW_KINDS = ("resample", "windows", "slices", "gradient")
EXPORT_FORMATS = ("onnx", "torchscript")
INT8_FORMATS = ("qoperator", "qdq")


@dataclass(frozen=True)
class ViewSpec:
    """What the pipeline must feed this model.

    kind: "resample" (whole trial resampled to ``frames``), "windows" (sliding windows
    ``frames`` long every ``stride``), "slices" (moving-average slicing with 50% overlap
    down to ``frames`` slices), "gradient" (gradient-adaptive sampling of ``frames``).
    """

    kind: str
    frames: int
    stride: int = 0


@dataclass(frozen=True)
class TrainDefaults:
    optimizer: str  # "adam" | "sgd" | "adamw"
    lr: float
    batch_size: int
    max_epochs: int
    patience: int
    weight_decay: float = 0.0
    momentum: float = 0.0


@dataclass(frozen=True)
class Streaming:
    """How live inference may run the model on the live frame stream.

    ``sliding``: every new frame is pushed through learn/deploy/streaming.py's StreamingPredictor
    and the model predicts on the newest ``view.frames`` frames (the model must take the
    "windows" view); otherwise live inference classifies the newest trial-long window.
    ``cached``: the model has ``frame_features(frames (N, C, R, X)) -> (N, d)`` and
    ``classify_embeddings(emb (B, T, d)) -> logits``, so each frame's embedding is
    computed once and only the classifier runs per prediction (requires ``sliding``). A
    model whose ``needs_window`` is true takes ``classify_embeddings(emb, window (B, C, T,
    R, X))``: the predictor keeps the window's frames beside their embeddings (e.g. for a
    window-statistics head).
    """

    sliding: bool = False
    cached: bool = False


def needs_window(model: torch.nn.Module) -> bool:
    """A cached model whose ``classify_embeddings`` also takes the window's frames."""
    return bool(getattr(model, "needs_window", False))


def classify_window(model: torch.nn.Module, emb: torch.Tensor,
                    window: torch.Tensor | None = None) -> torch.Tensor:
    """A cached model's logits for a window of frame embeddings, plus the window's frames
    for a model that :func:`needs_window` (the one place the two signatures meet)."""
    if window is None:
        return model.classify_embeddings(emb)
    return model.classify_embeddings(emb, window)


def check_preset(preset: str) -> str:
    if preset not in PRESETS:
        raise UserError(f"unknown preset '{preset}' (available: {', '.join(PRESETS)})")
    return preset


def _view_frames(name: str, value: object) -> int | None:
    """``view_frames`` (the pipeline's view-length override): the model sizes itself to it."""
    if value is None:
        return None
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    try:
        frames = int(str(value).strip())
    except ValueError:
        frames = 0
    if frames < 1:
        raise UserError(f"model '{name}': view_frames={value!r} must be a positive integer")
    return frames


@dataclass(frozen=True)
class ModelSpec:
    """A torch model's declaration, registered under ``name``.

    ``builder(n_classes, in_channels, grid, preset, frames=None, **options)`` returns the
    ``nn.Module``; ``frames`` is the view length when the pipeline overrides it (the model
    sizes itself to it), ``options`` are keys of ``options[preset]`` given with ``--set``.
    """

    name: str
    description: str
    builder: Callable[..., torch.nn.Module]
    views: Mapping[str, ViewSpec]
    train: Mapping[str, TrainDefaults]
    options: Mapping[str, Mapping[str, object]]
    option_help: Mapping[str, str] = field(default_factory=dict)
    # the file formats export-model / the streaming ONNX backend may turn it into
    export: tuple[str, ...] = ("onnx",)
    # export-model --format int8 supports it (export.quantize_onnx_int8), in this
    # onnxruntime quantisation format ("qoperator", or "qdq" where QOperator's fused
    # kernels are missing, e.g. for 3-D convolutions with residual adds)
    quantizable: bool = True
    int8_format: str = "qoperator"
    streaming: Streaming = Streaming()
    gpus: float = 0.0  # GPUs a training task asks a sweep scheduler for (0 = CPU is fine)

    def build(self, n_classes: int, in_channels: int, grid: tuple[int, int],
              preset: str = "full", **overrides: object) -> torch.nn.Module:
        """The model for this data. Overrides are ``options`` keys, plus ``view_frames`` /
        ``view_stride`` when the pipeline overrides the view (sized for that length)."""
        check_preset(preset)
        frames = _view_frames(self.name, overrides.pop("view_frames", None))
        overrides.pop("view_stride", None)  # the pipeline's business; no effect on the model
        model = self.builder(n_classes, in_channels, tuple(grid), preset, frames=frames,
                             **overrides)
        _built[model] = self
        return model

    def view(self, preset: str = "full") -> ViewSpec:
        return self.views[check_preset(preset)]

    def train_defaults(self, preset: str = "full") -> TrainDefaults:
        return self.train[check_preset(preset)]

    @property
    def windowed(self) -> bool:
        """Fed sliding windows of a trial (each window is a sample; trials aggregate)."""
        return self.views["full"].kind == "windows"


# which declaration built which live module (the streaming predictor reads its facts)
_built: weakref.WeakKeyDictionary[torch.nn.Module, ModelSpec] = weakref.WeakKeyDictionary()


def spec_of(model: torch.nn.Module) -> ModelSpec | None:
    """The declaration whose ``build`` made ``model`` (None for a module built otherwise)."""
    return _built.get(model)
