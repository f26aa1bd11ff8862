"""The shear+normal paper's 3D CNN.

A first Conv3D with a long temporal kernel (43 frames x 1 x 1, stride 4 in time) learns
per-taxel temporal filters; two 3x3x3 convolutions (256, 512 filters) mix space and
time; batch norm after each; global average pooling; dense 512; dropout; dense to the
classes. ~4.7 M parameters at the paper's size (3 channels, 9 classes: 4,710,153).
Input (B, C, 86, R, X): the whole 2 s trial resampled to 86 frames.

The ``full`` preset is not the paper's network but the generalisation recipe of
docs/learning/models.md (small network + linear window-statistics head, mirror training and
averaging, branch dropout, cosine budget); the paper's network is ``PAPER``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from tactile_studio.errors import UserError
from tactile_studio.learn.models import ModelSpec, TrainDefaults, ViewSpec
from tactile_studio.learn.models._common import (
    RECIPE_HELP,
    NetworkInput,
    Recipe,
    RecipeModel,
    build_members,
    check_io,
    hyperparameters,
    resolve_options,
)

# one line of help per option (the research workspace shows it beside the value)
OPTION_HELP = {
    "filters": "filters of the three Conv3D stages (paper: 128, 256, 512)",
    "temporal_kernel": "frames the first Conv3D spans (paper: 43 = 1 s)",
    "temporal_stride": "stride in time of the first Conv3D (paper: 4)",
    "dense": "units of the dense layer before the classes (paper: 512)",
    "dropout": "dropout before the class layer",
    **RECIPE_HELP,
}

OPTIONS: dict[str, dict[str, object]] = {
    "full": {
        "filters": (8, 16, 32),
        "temporal_kernel": 11,
        "temporal_stride": 4,
        "dense": 64,
        "dropout": 0.3,
        "stats": True,
        "stats_hidden": 0,
        "mirror": True,
        "branch_dropout": 0.75,
        "gesture": False,
        "members": 1,  # 3 measured: no gain for 2.4x the cost (docs/learning/figures.md)
    },
    "tiny": {
        "filters": (8, 16, 32),
        "temporal_kernel": 8,
        "temporal_stride": 2,
        "dense": 32,
        "dropout": 0.2,
        "stats": False,
        "stats_hidden": 16,
        "mirror": False,
        "branch_dropout": 0.0,
        "gesture": False,
        "members": 1,
    },
}
# The paper's network (4.7 M parameters; trained with adam, lr 1e-5, batch 32, up to 200
# epochs, patience 15): too slow for 2 CPU cores and no better on unseen people here.
PAPER = {"filters": (128, 256, 512), "temporal_kernel": 43, "temporal_stride": 4,
         "dense": 512, "dropout": 0.5, "stats": False, "mirror": False, "gesture": False,
         "members": 1}
VIEWS = {"full": ViewSpec("resample", 86), "tiny": ViewSpec("resample", 16)}
TRAIN = {
    "full": TrainDefaults("adamw", 3e-3, 32, 25, 25, weight_decay=1e-2),
    "tiny": TrainDefaults("adam", 3e-3, 16, 40, 8),
}
# training recipe of the preset (see train.fit): a fixed, cosine-decayed budget
RECIPE = {"full": {"label_smoothing": 0.1, "schedule": "cosine", "warmup": 2, "clip": 5.0},
          "tiny": {}}


def _block(cin: int, cout: int, kernel, stride=1, padding=0) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv3d(cin, cout, kernel, stride=stride, padding=padding),
        nn.BatchNorm3d(cout),
        nn.ReLU(inplace=True),
    )


@dataclass(frozen=True)
class CNN3DHyperparameters:
    """The options of :data:`OPTIONS` (``members`` aside) as the network takes them."""

    filters: tuple[int, ...]
    temporal_kernel: int
    temporal_stride: int
    dense: int
    dropout: float
    recipe: Recipe = Recipe()


class CNN3D(RecipeModel):
    def __init__(self, data: NetworkInput, hp: CNN3DHyperparameters) -> None:
        super().__init__()
        self.attach_recipe(data, hp.recipe, hp.dropout)
        self.temporal_kernel = hp.temporal_kernel
        filters, dense, dropout, n_classes = hp.filters, hp.dense, hp.dropout, data.n_classes
        layers = [_block(data.in_channels, filters[0], (hp.temporal_kernel, 1, 1),
                         (hp.temporal_stride, 1, 1))]
        for cin, cout in zip(filters[:-1], filters[1:]):
            layers.append(_block(cin, cout, 3, padding=1))
        self.features = nn.Sequential(*layers)
        self.head = nn.Sequential(
            nn.Linear(filters[-1], dense),
            nn.ReLU(inplace=True),
            nn.Dropout(dropout),
            nn.Linear(dense, n_classes),
        )

    def network_logits(self, x: torch.Tensor) -> torch.Tensor:
        h = self.features(x)
        return self.head(h.mean(dim=(2, 3, 4)))


def build(
    n_classes: int, in_channels: int, grid: tuple[int, int], preset: str = "full",
    frames: int | None = None, **overrides: object
) -> CNN3D:
    check_io("cnn3d", n_classes, in_channels, grid)
    frames = frames or VIEWS[preset].frames
    opts = resolve_options("cnn3d", preset, OPTIONS, overrides)
    if opts["temporal_kernel"] > frames:
        raise UserError(
            f"model 'cnn3d': temporal_kernel={opts['temporal_kernel']} is longer than the "
            f"{frames}-frame view"
        )
    members, hp = hyperparameters(CNN3DHyperparameters, opts)
    data = NetworkInput(n_classes, in_channels, frames, (grid[0], grid[1]))
    model = build_members(CNN3D, members, data, hp)
    model.train_recipe = RECIPE[preset]
    model.input_shape = (in_channels, frames, *grid)
    return model


# the declaration the registry finds
# (pyproject.toml: [project.entry-points."tactile_studio.models"])
MODEL = ModelSpec(
    name="cnn3d",
    description="3D CNN over (time, rows, cols) from the shear+normal paper",
    builder=build,
    views=VIEWS,
    train=TRAIN,
    options=OPTIONS,
    option_help=OPTION_HELP,
    export=("onnx",),
    quantizable=True,
)
