"""The HAART/CoST paper's CNN-Transformer over sliding windows.

Per frame: four Conv2D 3x3 (BN, ReLU) with max-pooling after the 2nd and 4th, 512
channels at 2x2, flatten, dense 256, dropout 0.5, dense 32 (the frame embedding). The
window's embeddings get sinusoidal positions and go through a Transformer encoder
(2 layers, 4 heads, d=32, ff=128, dropout 0.5); mean over time; linear to the classes.
Windows are 27 frames, stride 9 in the paper (`--set view_frames=27 view_stride=9`). The
full preset's window is the whole 2 s trial (86 frames at the sensor's ~43 Hz, not
overlapping): the Transformer attends over the touch from start to end and the statistics
head describes the whole trial, as the other models' heads do. Measured (docs/learning/figures.md)
against 27-frame windows: LOPO trial accuracy 0.614 -> 0.653, adapted 0.633 -> 0.672.

The paper's grid is 8x8 (-> 4x4 -> 2x2). Other grids keep the 2x2 output: the second
pooling's kernel/stride are chosen from the grid at build time (6x6: 3x3 -> 2x2 with
kernel 2 stride 1; 11x11: 6x6 -> 2x2 with kernel 3 stride 3), which exports to ONNX
unlike adaptive pooling with non-dividing sizes.

The ``full`` preset adds the generalisation recipe of docs/learning/models.md like the other
models (linear window-statistics head over the window, mirror training and averaging,
branch dropout, cosine budget, ``members``); the paper's network is ``PAPER``.

``frame_features`` and ``classify_embeddings`` are public so the streaming predictor can
cache per-frame embeddings and run only the transformer per prediction. They compute
exactly the forward pass: a frame's cached embedding is the concatenation of every
member's embedding of the frame and (with ``mirror``) of its mirror images, and
``classify_embeddings`` also takes the window's raw frames (which the predictor keeps
beside the embeddings, ``needs_window``) for the statistics head.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from tactile_studio.errors import UserError
from tactile_studio.learn.models import ModelSpec, Streaming, TrainDefaults, ViewSpec
from tactile_studio.learn.models._common import (
    RECIPE_HELP,
    NetworkInput,
    PositionalEncoding,
    Recipe,
    RecipeModel,
    build_members,
    check_io,
    hyperparameters,
    mirror_images,
    resolve_options,
    transformer_encoder,
)
from tactile_studio.learn.models.attention import Dropout

# one line of help per option (the research workspace shows it beside the value)
OPTION_HELP = {
    "filters": "channels of the four per-frame Conv2D layers",
    "dense": "units of the per-frame dense layer (paper: 256)",
    "d_model": "Transformer width (paper: 32)",
    "heads": "attention heads (paper: 4)",
    "layers": "Transformer encoder layers (paper: 2)",
    "ff": "feed-forward width inside the encoder (paper: 128)",
    "dropout": "dropout in the encoder and head (paper: 0.5)",
    **RECIPE_HELP,
}

OPTIONS: dict[str, dict[str, object]] = {
    "full": {
        "filters": (8, 8, 16, 16),
        "dense": 32,
        "d_model": 32,
        "heads": 4,
        "layers": 1,
        "ff": 64,
        "dropout": 0.3,
        "stats": True,
        "stats_hidden": 0,
        "mirror": True,
        "branch_dropout": 0.75,
        "gesture": False,
        "members": 1,
    },
    "tiny": {
        "filters": (8, 8, 16, 16),
        "dense": 32,
        "d_model": 16,
        "heads": 2,
        "layers": 1,
        "ff": 32,
        "dropout": 0.1,
        "stats": False,
        "stats_hidden": 16,
        "mirror": False,
        "branch_dropout": 0.0,
        "gesture": False,
        "members": 1,
    },
}
# the paper's network (trained with sgd, lr 1e-3, momentum 0.9, batch 128, up to 100
# epochs, patience 10)
PAPER = {"filters": (64, 128, 256, 512), "dense": 256, "d_model": 32, "heads": 4,
         "layers": 2, "ff": 128, "dropout": 0.5, "stats": False, "mirror": False,
         "gesture": False, "members": 1}
# full: one window per 2 s trial (the paper's 27-frame windows scored 4 points less)
VIEWS = {"full": ViewSpec("windows", 86, 86), "tiny": ViewSpec("windows", 9, 3)}
TRAIN = {
    # 14 epochs, not 20: over 3 rounds +0.6 points pooled (Wilcoxon p 0.36, McNemar 0.56)
    # for ~30% less CPU (docs/learning/training-time.md)
    "full": TrainDefaults("adamw", 3e-3, 64, 14, 14, weight_decay=1e-2),
    "tiny": TrainDefaults("adam", 3e-3, 32, 40, 8),
}
# training recipe of the preset (see train.fit): a fixed, cosine-decayed budget
RECIPE = {"full": {"label_smoothing": 0.1, "schedule": "cosine", "warmup": 2, "clip": 5.0},
          "tiny": {}}


def _pool_to_two(size: int) -> tuple[int, int]:
    """(kernel, stride) of a max-pool that maps ``size`` to 2 (or 1 -> 1)."""
    if size < 2:
        return 1, 1
    kernel = (size + 1) // 2
    return kernel, size - kernel


def _conv(cin: int, cout: int) -> list[nn.Module]:
    return [nn.Conv2d(cin, cout, 3, padding=1), nn.BatchNorm2d(cout), nn.ReLU(inplace=True)]


class FrameCNN(nn.Module):
    """Embeds one frame (N, C, R, X) -> (N, d_model)."""

    def __init__(self, in_channels: int, grid: tuple[int, int], filters, dense, d_model, dropout):
        super().__init__()
        if len(filters) != 4:
            raise ValueError("filters needs 4 values")
        f1, f2, f3, f4 = filters
        r, c = (-(-g // 2) for g in grid)  # after the first pool (ceil mode)
        (kr, sr), (kc, sc) = _pool_to_two(r), _pool_to_two(c)
        self.convs = nn.Sequential(
            *_conv(in_channels, f1),
            *_conv(f1, f2),
            nn.MaxPool2d(2, ceil_mode=True),
            *_conv(f2, f3),
            *_conv(f3, f4),
            nn.MaxPool2d((kr, kc), stride=(sr, sc)),
        )
        out_r, out_c = (1 if r < 2 else 2), (1 if c < 2 else 2)
        self.embed = nn.Sequential(
            nn.Flatten(),
            nn.Linear(f4 * out_r * out_c, dense),
            nn.ReLU(inplace=True),
            Dropout(dropout),  # a cheaper mask, the same nn.Dropout otherwise
            nn.Linear(dense, d_model),
        )

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        return self.embed(self.convs(frames))


@dataclass(frozen=True)
class CNNTransformerHyperparameters:
    """The options of :data:`OPTIONS` (``members`` aside) as the network takes them."""

    filters: tuple[int, ...]
    dense: int
    d_model: int
    heads: int
    layers: int
    ff: int
    dropout: float
    recipe: Recipe = Recipe()


class CNNTransformer(RecipeModel):
    # train.fit trains it with channels-last conv weights: the per-frame CNN's steps take
    # ~10% less CPU that way (no dropout acts on its feature maps, so nothing else changes)
    train_memory_format = torch.channels_last

    def __init__(self, data: NetworkInput, hp: CNNTransformerHyperparameters) -> None:
        super().__init__()
        self.attach_recipe(data, hp.recipe, hp.dropout,
                           window_s=data.frames / 43.0)  # windows of the sensor's ~43 Hz frames
        self.d_model = hp.d_model
        self.frame_cnn = FrameCNN(data.in_channels, data.grid, hp.filters, hp.dense,
                                  hp.d_model, hp.dropout)
        self.positions = PositionalEncoding(hp.d_model)
        self.encoder = transformer_encoder(hp.d_model, hp.heads, hp.layers, hp.ff, hp.dropout)
        self.classifier = nn.Linear(hp.d_model, data.n_classes)

    @property
    def needs_window(self) -> bool:
        """True when ``classify_embeddings`` needs the window's frames (statistics head)."""
        return self.stats is not None

    def _transform(self, emb: torch.Tensor) -> torch.Tensor:
        h = self.encoder(self.positions(emb))
        return self.classifier(h.mean(dim=1))

    def network_logits(self, x: torch.Tensor) -> torch.Tensor:
        """One member's plain network over windows (B, C, T, R, X)."""
        b, c, t, r, s = x.shape
        frames = x.permute(0, 2, 1, 3, 4).reshape(b * t, c, r, s)
        return self._transform(self.frame_cnn(frames).reshape(b, t, -1))

    def frame_features(self, frames: torch.Tensor) -> torch.Tensor:
        """(N, C, R, X) -> (N, images * members * d_model): the per-frame part, cacheable
        between windows (every member's embedding of the frame and its mirror images)."""
        images = mirror_images(frames, 2, 3) if self.mirror else [frames]
        return torch.cat([net.frame_cnn(image) for image in images
                          for net in (self, *self.others)], dim=-1)

    def classify_embeddings(self, emb: torch.Tensor,
                            window: torch.Tensor | None = None) -> torch.Tensor:
        """(B, T, features) frame embeddings of a window -> logits (B, n_classes); the
        statistics head needs ``window`` (B, C, T, R, X), the same frames z-scored."""
        if self.stats is not None and window is None:
            raise ValueError("this model's statistics head needs the window's frames")
        nets = (self, *self.others)
        windows = (mirror_images(window) if self.mirror else [window]) \
            if window is not None else [None] * (4 if self.mirror else 1)
        total = None
        for m, image in enumerate(windows):
            outs = []
            for k, net in enumerate(nets):
                start = (m * len(nets) + k) * self.d_model
                outs.append(net._transform(emb[..., start:start + self.d_model]))
            if self.stats is not None:
                outs = [o + h for o, h in zip(outs, self.stats.member_logits(image))]
            fused = outs[0] if len(outs) == 1 else torch.stack(outs).mean(0)
            total = fused if total is None else total + fused
        return total / len(windows)


def build(
    n_classes: int, in_channels: int, grid: tuple[int, int], preset: str = "full",
    frames: int | None = None, **overrides: object
) -> CNNTransformer:
    check_io("cnn_transformer", n_classes, in_channels, grid)
    frames = frames or VIEWS[preset].frames
    opts = resolve_options("cnn_transformer", preset, OPTIONS, overrides)
    if len(opts["filters"]) != 4:  # type: ignore[arg-type]
        raise UserError("model 'cnn_transformer': filters needs 4 values, "
                        "e.g. filters=64,128,256,512")
    members, hp = hyperparameters(CNNTransformerHyperparameters, opts)
    data = NetworkInput(n_classes, in_channels, frames, (grid[0], grid[1]))
    model = build_members(CNNTransformer, members, data, hp)
    model.train_recipe = RECIPE[preset]
    model.input_shape = (in_channels, frames, *grid)
    return model


# the declaration the registry finds
# (pyproject.toml: [project.entry-points."tactile_studio.models"])
MODEL = ModelSpec(
    name="cnn_transformer",
    description="per-frame 2D CNN + Transformer encoder over sliding windows (HAART/CoST paper)",
    builder=build,
    views=VIEWS,
    train=TRAIN,
    options=OPTIONS,
    option_help=OPTION_HELP,
    export=("onnx",),
    quantizable=True,
    # per-frame embeddings (frame_features) are cached between windows when streaming live
    streaming=Streaming(sliding=True, cached=True),
)
