"""Registry of the reference papers' torch models.

Every model takes float32 ``(B, C, T, R, X)`` (channels, frames, grid rows, grid cols),
already z-scored, and returns logits ``(B, n_classes)``. A ``ModelSpec`` tells the
pipeline how to build the model, which view of a trial to feed it and how to train it,
for the ``full`` (paper) and ``tiny`` (CPU test) presets. Model modules are imported
lazily so the registry itself is cheap to import.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

import torch

from tactile_studio.errors import UserError

PRESETS = ("full", "tiny")


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
class ModelSpec:
    name: str
    description: str
    # build(n_classes, in_channels, grid, preset="full", **overrides) -> nn.Module.
    # Overrides are the module's OPTIONS keys (see model_options), plus view_frames /
    # view_stride when the pipeline overrides the view: the model is sized for that T.
    build: Callable[..., torch.nn.Module]
    view: Callable[[str], ViewSpec]
    train_defaults: Callable[[str], TrainDefaults]
    # export-model --format int8 supports it (export.quantize_onnx_int8, in the onnxruntime
    # format export.int8_format names); every model does today (files 4x smaller for the
    # big models, less for tiny ones whose graph and float constants dominate)
    quantizable: bool


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


def _module(name: str):
    return importlib.import_module(f"{__name__}.{name}")


def _spec(name: str, description: str, quantizable: bool) -> ModelSpec:
    def build(
        n_classes: int,
        in_channels: int,
        grid: tuple[int, int],
        preset: str = "full",
        **overrides: object,
    ) -> torch.nn.Module:
        module = _module(name)
        check_preset(preset)
        frames = _view_frames(name, overrides.pop("view_frames", None))
        overrides.pop("view_stride", None)  # the pipeline's business; no effect on the model
        return module.build(n_classes, in_channels, grid, preset, frames=frames, **overrides)

    def view(preset: str = "full") -> ViewSpec:
        return _module(name).VIEWS[check_preset(preset)]

    def train_defaults(preset: str = "full") -> TrainDefaults:
        return _module(name).TRAIN[check_preset(preset)]

    build.__doc__ = f"Build the {name} model (see tactile_studio.learn.models.{name})."
    return ModelSpec(name, description, build, view, train_defaults, quantizable)


MODELS: dict[str, ModelSpec] = {
    spec.name: spec
    for spec in (
        _spec("cnn3d", "3D CNN over (time, rows, cols) from the shear+normal paper", True),
        _spec(
            "cnn_transformer",
            "per-frame 2D CNN + Transformer encoder over sliding windows (HAART/CoST paper)",
            True,
        ),
        _spec("cnn1d", "tiny 1-D CNN over moving-average slices, taxels as channels", True),
        _spec(
            "mts3d",
            "gradient-adaptive sampling + multi-temporal-scale ResNet3D-18-style CNN",
            True,
        ),
        _spec(
            "sefusion",
            "depthwise-separable 1-D branches per modality + SE + Transformer (fusion=mid|early|late)",
            True,
        ),
    )
}


def get_model_spec(name: str) -> ModelSpec:
    """The registered model called ``name``; a one-line UserError if there is none."""
    try:
        return MODELS[name]
    except KeyError:
        raise UserError(f"unknown model '{name}' (available: {', '.join(MODELS)})") from None


def option_help(name: str) -> dict[str, str]:
    """One line of help per architecture option of model ``name`` (its ``OPTION_HELP``)."""
    return dict(_module(name).OPTION_HELP)


def model_options(name: str, preset: str = "full") -> dict[str, object]:
    """The architecture options ``build`` accepts as overrides, with their preset values
    (for run configs and ``--set`` help). Training options are in ``TrainDefaults``."""
    get_model_spec(name)
    return dict(_module(name).OPTIONS[check_preset(preset)])
