"""Shared pieces of the model modules: option validation and small building blocks."""

from __future__ import annotations

import math
from collections.abc import Mapping

import torch
from torch import nn

from tactile_studio.errors import UserError


def _coerce(model: str, key: str, value: object, default: object) -> object:
    """Turn a ``--set key=value`` string (or a Python value) into the default's type."""
    try:
        if isinstance(default, bool):
            if isinstance(value, str):
                low = value.strip().lower()
                if low in ("1", "true", "yes", "on"):
                    return True
                if low in ("0", "false", "no", "off"):
                    return False
                raise ValueError(value)
            return bool(value)
        if isinstance(default, int):
            if isinstance(value, float) and not value.is_integer():
                raise ValueError(value)
            return int(value)  # type: ignore[arg-type]
        if isinstance(default, float):
            return float(value)  # type: ignore[arg-type]
        if isinstance(default, tuple):
            items = value.replace("x", ",").split(",") if isinstance(value, str) else value
            out = tuple(int(v) for v in items)  # type: ignore[union-attr]
            if not out:
                raise ValueError(value)
            return out
        return str(value)
    except (TypeError, ValueError):
        kind = type(default).__name__
        if isinstance(default, tuple):
            kind = "comma-separated integers"
        raise UserError(
            f"model '{model}': option {key}={value!r} is not a valid {kind}"
        ) from None


class UnknownOptionError(UserError):
    """A ``--set`` key the model does not have; the learner adds the training options."""

    def __init__(self, model: str, key: str, allowed: list[str]) -> None:
        self.model, self.key, self.allowed = model, key, list(allowed)
        super().__init__(f"unknown option '{key}' for model '{model}' "
                         f"(allowed: {', '.join(allowed)})")


def resolve_options(
    model: str,
    preset: str,
    presets: Mapping[str, Mapping[str, object]],
    overrides: Mapping[str, object],
    choices: Mapping[str, tuple[str, ...]] | None = None,
) -> dict[str, object]:
    """The preset's options with ``overrides`` applied; unknown or ill-typed keys raise a
    one-line UserError naming the key and the allowed keys."""
    options = dict(presets[preset])
    for key, value in overrides.items():
        if key not in options:
            raise UnknownOptionError(model, key, list(options))
        options[key] = _coerce(model, key, value, options[key])
        if choices and key in choices and options[key] not in choices[key]:
            raise UserError(
                f"model '{model}': {key}={value!r} is not one of {', '.join(choices[key])}"
            )
        new = options[key]
        if isinstance(new, (int, float)) and not isinstance(new, bool):
            if key == "dropout" or key.endswith("_dropout"):
                if not 0.0 <= new < 1.0:
                    raise UserError(f"model '{model}': {key}={value!r} must be in [0, 1)")
            elif new <= 0:
                raise UserError(f"model '{model}': {key}={value!r} must be positive")
        if isinstance(new, tuple) and any(v <= 0 for v in new):
            raise UserError(f"model '{model}': {key}={value!r} must be positive integers")
    return options


def check_io(model: str, n_classes: int, in_channels: int, grid: tuple[int, int]) -> None:
    """Reject shapes no model can use (these come from the dataset, so they are user input)."""
    if n_classes < 2:
        raise UserError(f"model '{model}' needs at least 2 classes, got {n_classes}")
    if not 1 <= in_channels <= 3:
        raise UserError(f"model '{model}' takes 1 to 3 input channels, got {in_channels}")
    if len(grid) != 2 or min(grid) < 1:
        raise UserError(f"model '{model}': bad grid {grid!r}")


class PositionalEncoding(nn.Module):
    """Fixed sinusoidal positions (Vaswani et al.), added to a (B, T, d) sequence."""

    def __init__(self, d_model: int, max_len: int = 1024) -> None:
        super().__init__()
        position = torch.arange(max_len, dtype=torch.float32).unsqueeze(1)
        div = torch.exp(torch.arange(0, d_model, 2, dtype=torch.float32) * (-math.log(10000.0) / d_model))
        pe = torch.zeros(max_len, d_model)
        pe[:, 0::2] = torch.sin(position * div)
        pe[:, 1::2] = torch.cos(position * div[: d_model // 2])
        self.register_buffer("pe", pe, persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.pe[: x.shape[1]].unsqueeze(0)


def transformer_encoder(
    d_model: int, heads: int, layers: int, ff: int, dropout: float
) -> nn.TransformerEncoder:
    if d_model % heads:
        raise UserError(f"d_model={d_model} must be divisible by heads={heads}")
    layer = nn.TransformerEncoderLayer(
        d_model, heads, dim_feedforward=ff, dropout=dropout, batch_first=True
    )
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
