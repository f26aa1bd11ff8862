"""Shared pieces of the model modules: option validation and small building blocks."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from typing import Protocol, TypeVar

import torch
from torch import nn

from tactile_studio.errors import UserError
from tactile_studio.learn.models.attention import transformer_encoder  # noqa: F401 (models use it)
from tactile_studio.learn.models.gesture_features import GestureFeatures, fourier_basis


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
            number = float(value)  # type: ignore[arg-type]
            if not math.isfinite(number):  # nan slips past every range check below
                raise UserError(f"model '{model}': option {key}={value!r} is not a finite "
                                "number")
            return number
        if isinstance(default, tuple):
            items = value.replace("x", ",").split(",") if isinstance(value, str) else value
            out = tuple(int(v) for v in items)  # type: ignore[union-attr]
            if not out:
                raise ValueError(value)
            return out
        return str(value)
    except (TypeError, ValueError, OverflowError):
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
            elif new < 0 or (new == 0 and not key.endswith("_hidden")):
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
        div = torch.exp(torch.arange(0, d_model, 2, dtype=torch.float32)
                        * (-math.log(10000.0) / d_model))
        pe = torch.zeros(max_len, d_model)
        pe[:, 0::2] = torch.sin(position * div)
        pe[:, 1::2] = torch.cos(position * div[: d_model // 2])
        self.register_buffer("pe", pe, persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.pe[: x.shape[1]].unsqueeze(0)


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


class WindowStatistics(nn.Module):
    """The random forest's kind of features, computed inside the network.

    Per frame, every channel is summarised over the grid (mean, max, min, spread); the
    first channel's load (above the frame's minimum) gives the contact's centroid (row,
    column), radius of gyration, area (share of cells above a quarter of the peak) and the
    centroid's speed; when shear channels are present (the last two), the mean and max
    shear magnitude and the mean divergence and curl of the shear field; each of
    these signals is then described over time by mean, std, min, max, the 10/25/50/75/90th
    percentiles, skewness, kurtosis, energy, trend (last third minus first third) and the share
    of its spectral energy in ``bands``
    frequency bands (a fixed DFT basis: exports to ONNX). The features are compressed
    (sign-log) and batch-normalised. Statistics of a whole window are invariant to where
    on the grid and when in the window a touch happens, which is what carries over from
    one person to the next; a late-fusion head over them (:class:`StatisticsHead`) lets a
    small data set lean on them while the convolutional part learns what they miss.
    """

    QUANTILES = (0.1, 0.25, 0.5, 0.75, 0.9)

    def __init__(self, in_channels: int, frames: int, bands: int = 4) -> None:
        super().__init__()
        self.shear = in_channels >= 2
        self.n_signals = 4 * in_channels + 5 + (4 if self.shear else 0)
        cos, sin = fourier_basis(frames)
        self.register_buffer("cos", cos, persistent=False)
        self.register_buffer("sin", sin, persistent=False)
        n_freqs = cos.shape[1]
        band = torch.zeros(n_freqs, bands)
        for i in range(n_freqs):
            band[i, min(bands - 1, i * bands // max(1, n_freqs))] = 1.0
        self.register_buffer("band", band, persistent=False)
        self.register_buffer("q_index", torch.tensor(
            [round(q * (frames - 1)) for q in self.QUANTILES], dtype=torch.long),
            persistent=False)
        self.out_features = self.n_signals * (8 + len(self.QUANTILES) + bands)
        self.norm = nn.BatchNorm1d(self.out_features)

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # (B, C, T, R, X)
        return self.norm(self.raw(x))

    def raw(self, x: torch.Tensor) -> torch.Tensor:
        """(B, out_features) statistics before the batch norm: they hold no learned
        weight, so training computes them once per window (``RecipeModel.feature_cache``)."""
        b, c, t = x.shape[:3]
        flat = x.reshape(b, c, t, -1)
        signals = [flat.mean(-1), flat.amax(-1), flat.amin(-1), flat.std(-1)]
        signals.append(self._contact(x[:, 0]))
        if self.shear:
            mag = torch.sqrt(flat[:, -2] ** 2 + flat[:, -1] ** 2 + 1e-6)
            sx, sy = x[:, -2], x[:, -1]  # (B, T, R, X): x along columns, y along rows
            div = (sx[..., :, 1:] - sx[..., :, :-1]).mean((-2, -1)) + \
                (sy[..., 1:, :] - sy[..., :-1, :]).mean((-2, -1))
            curl = (sy[..., :, 1:] - sy[..., :, :-1]).mean((-2, -1)) - \
                (sx[..., 1:, :] - sx[..., :-1, :]).mean((-2, -1))
            signals.append(torch.stack([mag.mean(-1), mag.amax(-1), div, curl], dim=1))
        s = torch.cat(signals, dim=1)  # (B, S, T)
        mean = s.mean(-1, keepdim=True)
        centred = s - mean
        std = torch.sqrt((centred ** 2).mean(-1, keepdim=True) + 1e-6)
        z = centred / std
        ordered = torch.sort(s, dim=-1).values
        third = max(1, t // 3)
        trend = s[..., t - third:].mean(-1, keepdim=True) - s[..., :third].mean(-1, keepdim=True)
        power = (centred @ self.cos) ** 2 + (centred @ self.sin) ** 2
        share = (power @ self.band) / (power.sum(-1, keepdim=True) + 1e-6)
        feats = torch.cat([
            mean, std, ordered[..., :1], ordered[..., -1:], ordered[..., self.q_index],
            (z ** 3).mean(-1, keepdim=True), (z ** 4).mean(-1, keepdim=True) - 3,
            (s ** 2).mean(-1, keepdim=True), trend, share], dim=-1).reshape(b, -1)
        return torch.sign(feats) * torch.log1p(feats.abs())

    @staticmethod
    def _contact(load: torch.Tensor) -> torch.Tensor:
        """(B, T, R, X) first channel -> (B, 5, T): centroid row/col, radius, area, speed."""
        b, t, r, c = load.shape
        w = torch.relu(load - load.amin(dim=(-2, -1), keepdim=True))
        total = w.sum((-2, -1)) + 1e-6
        rows = torch.arange(r, dtype=load.dtype, device=load.device).view(1, 1, r, 1)
        cols = torch.arange(c, dtype=load.dtype, device=load.device).view(1, 1, 1, c)
        cr = (w * rows).sum((-2, -1)) / total
        cc = (w * cols).sum((-2, -1)) / total
        radius = torch.sqrt((w * ((rows - cr[..., None, None]) ** 2
                                  + (cols - cc[..., None, None]) ** 2)).sum((-2, -1)) / total
                            + 1e-6)
        peak = w.amax(dim=(-2, -1), keepdim=True)
        area = (w > 0.25 * peak).to(load.dtype).mean((-2, -1))
        if t > 1:
            step = torch.sqrt((cr[:, 1:] - cr[:, :-1]) ** 2 + (cc[:, 1:] - cc[:, :-1]) ** 2
                              + 1e-6)
            speed = torch.cat([step[:, :1], step], dim=1)
        else:
            speed = torch.zeros_like(cr)
        return torch.stack([cr, cc, radius, area, speed], dim=1)


class StatisticsHead(nn.Module):
    """Window statistics -> hidden layer (none when ``hidden`` is 0) -> class logits,
    added to a network's logits. With ensemble members (:meth:`add_members`) the
    statistics are computed once and every member has its own layer(s) over them."""

    def __init__(self, in_channels: int, frames: int, n_classes: int, hidden: int,
                 dropout: float, gesture: bool = False, window_s: float = 2.0) -> None:
        super().__init__()
        self.stats = WindowStatistics(in_channels, frames)
        self.gesture = GestureFeatures(in_channels, frames, window_s) if gesture else None
        self.in_features = self.stats.out_features + (
            self.gesture.out_features if self.gesture is not None else 0)
        self._shape = (n_classes, hidden, dropout)
        self.mlp = self._layers()
        self.more = nn.ModuleList()

    def _layers(self) -> nn.Sequential:
        n_classes, hidden, dropout = self._shape
        if hidden == 0:  # a linear (multinomial logistic) head: the most robust on few people
            return nn.Sequential(nn.Dropout(dropout),
                                 nn.Linear(self.in_features, n_classes))
        return nn.Sequential(
            nn.Dropout(dropout / 2), nn.Linear(self.in_features, hidden),
            nn.ReLU(inplace=True), nn.Dropout(dropout), nn.Linear(hidden, n_classes))

    def add_members(self, count: int) -> None:
        """``count`` more independently initialised layer stacks over the same statistics."""
        self.more.extend(self._layers() for _ in range(count))

    def member_logits(self, x: torch.Tensor,
                      raw: torch.Tensor | None = None) -> list[torch.Tensor]:
        """Logits of every member's layers over the (shared) statistics of ``x`` (or of
        its :meth:`raw_features` ``raw``, computed beforehand)."""
        feats = self.features(x, raw)
        return [self.mlp(feats)] + [layers(feats) for layers in self.more]

    def raw_features(self, x: torch.Tensor) -> torch.Tensor:
        """(B, in_features) statistics (and gesture metrics) of ``x`` before their batch
        norms: a function of the window alone, so a training set's can be computed once."""
        if self.gesture is None:
            return self.stats.raw(x)
        return torch.cat([self.stats.raw(x), self.gesture.raw(x)], dim=1)

    def features(self, x: torch.Tensor, raw: torch.Tensor | None = None) -> torch.Tensor:
        """The window statistics of ``x``, and its gesture metrics when the head has them
        (from ``raw`` = :meth:`raw_features` of ``x`` when given)."""
        if raw is None:
            if self.gesture is None:
                return self.stats(x)
            return torch.cat([self.stats(x), self.gesture(x)], dim=1)
        if self.gesture is None:
            return self.stats.norm(raw)
        cut = self.stats.out_features
        return torch.cat([self.stats.norm(raw[:, :cut].contiguous()),
                          self.gesture.norm(raw[:, cut:].contiguous())], dim=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.mlp(self.features(x))


def mirror_images(x: torch.Tensor, rows: int = 3, cols: int = 4) -> list[torch.Tensor]:
    """``x`` and its three mirror images (left-right, top-bottom, both), the grid's rows
    and columns being dimensions ``rows`` and ``cols`` (3, 4 for windows (B, C, T, R, X);
    2, 3 for frames (N, C, R, X)), shear components turned with the grid as in
    ``learn/data/augment.py`` (channels: 1 = normal/pressure, 2 = shear x/y, 3 = normal +
    shear x/y). Flips become reversed slices in an ONNX export."""
    c = int(x.shape[1])  # a Python int also while tracing for ONNX (the channels are fixed)
    sx, sy = {3: (1, 2), 2: (0, 1)}.get(c, (None, None))
    images = [x]
    for dims in ((cols,), (rows,), (rows, cols)):
        signs = [1.0] * c  # a Python list: a constant in an exported graph
        if sx is not None and cols in dims:
            signs[sx] = -1.0
        if sy is not None and rows in dims:
            signs[sy] = -1.0
        sign = torch.tensor(signs, dtype=x.dtype, device=x.device).view(
            1, c, *([1] * (x.dim() - 2)))
        images.append(torch.flip(x, dims) * sign)
    return images


def mirror_average(forward, x: torch.Tensor) -> torch.Tensor:
    """Mean logits of ``forward`` over the window ``x`` and its three mirror images
    (:func:`mirror_images`).

    Test-time augmentation for models trained with flips: a person touching the mirror
    image of the trained touch gets the same answer. Exports to ONNX with the model, so
    exported and torch predictions agree.
    """
    images = mirror_images(x)
    total = forward(images[0])
    for image in images[1:]:
        total = total + forward(image)
    return total / 4


def random_mirror(x: torch.Tensor) -> torch.Tensor:
    """Each sample of a training batch mirrored left-right and/or top-bottom with
    probability 1/2 each (shear turned with the grid, see :func:`mirror_average`):
    geometry-respecting augmentation inside the model, free of extra copies."""
    return random_mirror_index(x)[0]


def random_mirror_index(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`random_mirror` and, per sample, which of :func:`mirror_images` it became
    (0 as is, 1 left-right, 2 top-bottom, 3 both): precomputed statistics of the
    mirror images (``RecipeModel.feature_cache``) are picked by it."""
    b, c = x.shape[:2]
    sx, sy = {3: (1, 2), 2: (0, 1)}.get(c, (None, None))
    index = torch.zeros(b, dtype=torch.long, device=x.device)
    x = x.clone()  # the caller's batch stays as it was
    for dim, shear, weight in ((4, sx, 1), (3, sy, 2)):
        pick = torch.rand(b, device=x.device) < 0.5
        index = index + pick.long() * weight
        # only the picked samples are flipped and written back (a torch.where over the
        # whole batch and its flipped copy took ~5x longer on CPU; the same values)
        flipped = torch.flip(x[pick], (dim,))
        if shear is not None:
            sign = torch.ones(c, dtype=x.dtype, device=x.device)
            sign[shear] = -1.0
            flipped = flipped * sign.view(1, c, 1, 1, 1)
        x[pick] = flipped
    return x, index


@dataclass(frozen=True)
class NetworkInput:
    """What the data gives a network: classes, input channels, frames of the view and
    grid (rows, cols). The dataset decides these, not the user's options."""

    n_classes: int
    in_channels: int
    frames: int
    grid: tuple[int, int]


@dataclass(frozen=True)
class Recipe:
    """The generalisation recipe's options (:data:`RECIPE_HELP`) every network takes
    beside its architecture: one object so a network's hyperparameters carry it whole."""

    stats: bool = False
    stats_hidden: int = 16
    mirror: bool = False
    branch_dropout: float = 0.0
    gesture: bool = False

    def alone(self) -> Recipe:
        """The recipe of an extra ensemble member: the first model's forward adds the
        statistics head and mirrors for all of them."""
        return replace(self, stats=False, mirror=False, branch_dropout=0.0)


RECIPE_KEYS = tuple(f.name for f in fields(Recipe))


# options every model's full recipe adds (tiny presets keep them off)
RECIPE_HELP = {
    "stats": "add a late-fusion head over window statistics (what the random forest uses)",
    "stats_hidden": "units of the window-statistics head",
    "mirror": "train on random mirror images of the grid, predict as the mean over them",
    "branch_dropout": "chance a training sample's network logits are dropped (statistics alone)",
    "members": "independently initialised copies of the network (and head), logits averaged",
    "gesture": "add the gesture metrics (movement type, spread change, contact area, ...) "
               "in physical units to the statistics head",
}


class RecipeModel(nn.Module):
    """Base of the models with the generalisation recipe: subclasses implement
    ``network_logits``; ``forward`` adds the window-statistics head's logits (``stats``)
    and mirrors the grid (random mirror images in training, their mean in evaluation).

    Ensemble members (:func:`build_members`): ``others`` holds more independently
    initialised copies of the network, each with its own statistics layer over the one
    shared :class:`WindowStatistics`; the output is the mean of the members' logits, and
    :meth:`training_step` trains each member on its own loss (as separately trained
    models would be, so they stay diverse) in one pass over the batch.
    """

    mirror: bool = False
    branch_dropout: float = 0.0

    def attach_recipe(self, data: NetworkInput, recipe: Recipe, dropout: float,
                      window_s: float = 2.0) -> None:
        """``window_s``: the seconds a window spans (the gesture metrics' time unit)."""
        self.mirror = bool(recipe.mirror)
        self.branch_dropout = float(recipe.branch_dropout) if recipe.stats else 0.0
        self.stats = (StatisticsHead(data.in_channels, data.frames, data.n_classes,
                                     recipe.stats_hidden, dropout, recipe.gesture, window_s)
                      if recipe.stats else None)
        self.others = nn.ModuleList()

    def set_input_norm(self, mean, std, cell_pitch: float = 1.0) -> None:
        """How the inputs were z-scored (per channel) and the taxel pitches per grid cell:
        the gesture metrics undo the one and count in the other. Saved with the weights;
        the learner calls this after building, before training."""
        if self.stats is not None and self.stats.gesture is not None:
            self.stats.gesture.set_input_norm(mean, std, cell_pitch)

    @property
    def members(self) -> int:
        return 1 + len(self.others)

    def network_logits(self, x: torch.Tensor) -> torch.Tensor:  # pragma: no cover
        raise NotImplementedError

    def member_logits(self, x: torch.Tensor, raw: torch.Tensor | None = None) -> torch.Tensor:
        """(members, B, n_classes): each member's network logits plus its statistics layer
        (over ``raw``, the statistics head's :meth:`StatisticsHead.raw_features` of ``x``,
        when the caller computed them beforehand)."""
        outs = []
        for net in (self, *self.others):
            out = net.network_logits(x)
            if self.stats is not None and self.training and self.branch_dropout > 0:
                keep = torch.rand(out.shape[0], 1, device=out.device) >= self.branch_dropout
                out = out * keep.to(out.dtype) / (1.0 - self.branch_dropout)
            outs.append(out)
        if self.stats is not None:
            outs = [out + head for out, head in zip(outs, self.stats.member_logits(x, raw))]
        return torch.stack(outs)

    def _fused(self, x: torch.Tensor, raw: torch.Tensor | None = None) -> torch.Tensor:
        logits = self.member_logits(x, raw)
        return logits[0] if len(logits) == 1 else logits.mean(0)

    def feature_cache(self, x: torch.Tensor) -> torch.Tensor | None:
        """(B, images, F): the statistics head's raw features of every window of ``x``
        and (when mirroring) of its three mirror images, in :func:`mirror_images` order;
        None without a statistics head. They depend on the window only, not on learned
        weights, so train.fit computes a training and validation set's once and passes
        them to :meth:`training_step` and :meth:`forward` (``raw``) every epoch: the
        same figures as computing them per batch, without 40 epochs of repeating it."""
        if self.stats is None:
            return None
        images = mirror_images(x) if self.mirror else [x]
        with torch.no_grad():
            return torch.stack([self.stats.raw_features(image) for image in images], dim=1)

    def forward(self, x: torch.Tensor, raw: torch.Tensor | None = None) -> torch.Tensor:
        """Logits of windows ``x``; ``raw``: their :meth:`feature_cache` (optional)."""
        if self.mirror and self.training:
            x, index = random_mirror_index(x)
            if raw is not None:
                raw = raw[torch.arange(len(index), device=raw.device), index]
        elif self.mirror:
            if raw is None:
                return mirror_average(self._fused, x)
            images = mirror_images(x)
            total = self._fused(images[0], raw[:, 0])
            for k in range(1, 4):
                total = total + self._fused(images[k], raw[:, k])
            return total / 4
        elif raw is not None:
            raw = raw[:, 0]
        return self._fused(x, raw)

    def training_step(self, x: torch.Tensor, y: torch.Tensor, loss_fn,
                      raw: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(loss, mean logits) of a training batch: the mean of the members' own losses
        (train.fit calls this when a model has it); ``raw``: the batch's
        :meth:`feature_cache` (optional)."""
        if self.mirror:
            x, index = random_mirror_index(x)
            if raw is not None:
                raw = raw[torch.arange(len(index), device=raw.device), index]
        elif raw is not None:
            raw = raw[:, 0]
        logits = self.member_logits(x, raw)
        loss = sum(loss_fn(member, y) for member in logits) / len(logits)
        return loss, logits.mean(0)


class Hyperparameters(Protocol):
    """A network's hyperparameters object: its architecture options and its recipe."""

    @property
    def recipe(self) -> Recipe: ...


H = TypeVar("H", bound=Hyperparameters)


def hyperparameters(cls: Callable[..., H], options: Mapping[str, object]) -> tuple[int, H]:
    """(members, ``cls``) from a preset's resolved options (``resolve_options``): the
    recipe's keys go into its :class:`Recipe`, the rest are ``cls``'s own fields. The
    options are what run folders and exported models store, so they stay the one
    on-disk form; the object is only how a network is built from them."""
    opts = dict(options)
    members = int(opts.pop("members", 1))  # type: ignore[call-overload]
    recipe = Recipe(**{k: opts.pop(k) for k in RECIPE_KEYS if k in opts})  # type: ignore[arg-type]
    return members, cls(**opts, recipe=recipe)


def build_members(cls: type[RecipeModel], members: int, data: NetworkInput,
                  hp: Hyperparameters) -> RecipeModel:
    """``cls(data, hp)`` with ``members - 1`` more copies of its network, built one after
    the other (so initialised differently) without a statistics head or mirroring of
    their own: the first model's forward fuses and mirrors them all."""
    model = cls(data, hp)  # type: ignore[call-arg]
    plain = replace(hp, recipe=hp.recipe.alone())  # type: ignore[type-var]
    model.others.extend(cls(data, plain) for _ in range(members - 1))  # type: ignore[call-arg]
    if model.stats is not None:
        model.stats.add_members(members - 1)
    return model
