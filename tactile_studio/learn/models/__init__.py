"""The torch models: their declaration (``ModelSpec``) and the registry that finds them.

Every model takes float32 ``(B, C, T, R, X)`` (channels, frames, grid rows, grid cols),
already z-scored, and returns logits ``(B, n_classes)``. A model is one module exporting
a ``ModelSpec`` (how to build it, which view of a trial to feed it, how to train it for
the ``full`` (paper) and ``tiny`` (CPU test) presets, and its declared facts), found
through the ``tactile_studio.models`` entry-point group or :func:`register_model`
(docs/models.md). Model modules are imported lazily so the registry is cheap to import.
"""

from __future__ import annotations

from tactile_studio.learn.models._common import check_io, resolve_options
from tactile_studio.learn.models.registry import (
    GROUP,
    MODELS,
    get_model_spec,
    model_names,
    model_options,
    option_help,
    register_model,
    unregister_model,
)
from tactile_studio.learn.models.spec import (
    PRESETS,
    ModelSpec,
    Streaming,
    TrainDefaults,
    ViewSpec,
    check_preset,
    spec_of,
)

__all__ = [
    "GROUP", "MODELS", "PRESETS", "ModelSpec", "Streaming", "TrainDefaults", "ViewSpec",
    "check_io", "check_preset", "get_model_spec", "model_names", "model_options", "option_help",
    "register_model", "resolve_options", "spec_of", "unregister_model",
]
