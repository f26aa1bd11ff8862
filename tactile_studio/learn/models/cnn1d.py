"""The touch-modalities paper's tiny 1-D CNN (made for an int8 microcontroller).

Taxels (and channels) are the 1-D CNN's input channels, time is its axis: the trial is
moving-average sliced (50% overlap) down to Ns=100 slices. A 1x1 convolution first
mixes the C*R*X taxel signals into ``filters`` maps (the paper's sensor had far fewer
taxels; without it a 36-channel first layer alone would hold 2.9 k weights), then 3 conv
layers of 8 filters, kernel 10, each with BN, ReLU and max-pool halving the length
(100 -> 91 -> 45 -> 36 -> 18 -> 9 -> 4), then a convolutional head: a conv to the classes
whose kernel spans the remaining length (4), averaged over any positions left.

Parameters, 6x6 normal (36 input channels), 9 classes:
1x1 projection 36*8+8 = 296; 3 convs 3*(8*8*10+8) = 1944; 3 BN 3*16 = 48; head
8*9*4+9 = 297; total 2,585 (~2.6 k).

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
    "filters": "filters per 1-D conv layer (paper: 8)",
    "kernel": "kernel length in time slices (paper: 10)",
    "layers": "conv layers, each followed by max-pool halving (paper: 3)",
    "dropout": "dropout before the convolutional head",
    **RECIPE_HELP,
}

OPTIONS: dict[str, dict[str, object]] = {
    # members 1: three members gained 0.7 points over 3 LOPO rounds (Wilcoxon p 0.17, McNemar
    # 0.48; issue 37, docs/learning/training-time.md) for three times the training time
    "full": {"filters": 32, "kernel": 7, "layers": 3, "dropout": 0.3, "stats": True,
             "stats_hidden": 0, "mirror": True, "branch_dropout": 0.75, "gesture": False,
             "members": 1},
    "tiny": {"filters": 8, "kernel": 5, "layers": 3, "dropout": 0.0, "stats": False,
             "stats_hidden": 16, "mirror": False, "branch_dropout": 0.0, "gesture": False,
             "members": 1},
}
# the paper's network (2.6 k parameters), e.g. --set filters=8 kernel=10 dropout=0
# stats=false mirror=false
PAPER = {"filters": 8, "kernel": 10, "layers": 3, "dropout": 0.0, "stats": False, "mirror": False,
         "gesture": False, "members": 1}
VIEWS = {"full": ViewSpec("slices", 100), "tiny": ViewSpec("slices", 50)}
TRAIN = {
    "full": TrainDefaults("adamw", 3e-3, 32, 40, 40, weight_decay=1e-2),
    "tiny": TrainDefaults("adam", 1e-2, 16, 60, 10),
}
# training recipe of the preset (see train.fit): a fixed, cosine-decayed budget
RECIPE = {"full": {"label_smoothing": 0.1, "schedule": "cosine", "warmup": 2, "clip": 5.0},
          "tiny": {}}


@dataclass(frozen=True)
class CNN1DHyperparameters:
    """The options of :data:`OPTIONS` (``members`` aside) as the network takes them."""

    filters: int
    kernel: int
    layers: int
    dropout: float
    recipe: Recipe = Recipe()


class CNN1D(RecipeModel):
    def __init__(self, data: NetworkInput, hp: CNN1DHyperparameters) -> None:
        super().__init__()
        self.attach_recipe(data, hp.recipe, hp.dropout)
        filters, kernel, layers, dropout = hp.filters, hp.kernel, hp.layers, hp.dropout
        frames, n_classes = data.frames, data.n_classes
        in_features = data.in_channels * data.grid[0] * data.grid[1]  # taxels as channels
        body: list[nn.Module] = [nn.Conv1d(in_features, filters, 1)]
        length = frames
        for _ in range(layers):
            body += [nn.Conv1d(filters, filters, kernel), nn.BatchNorm1d(filters),
                     nn.ReLU(), nn.MaxPool1d(2)]
            length = (length - kernel + 1) // 2
            if length < 1:
                raise UserError(
                    f"model 'cnn1d': {frames} slices are too short for {layers} layers of "
                    f"kernel {kernel}"
                )
        if dropout > 0:
            body.append(nn.Dropout(dropout))
        body.append(nn.Conv1d(filters, n_classes, length))
        self.net = nn.Sequential(*body)

    def network_logits(self, x: torch.Tensor) -> torch.Tensor:
        b, c, t, r, s = x.shape
        series = x.permute(0, 1, 3, 4, 2).reshape(b, c * r * s, t)
        return self.net(series).mean(dim=2)


def build(
    n_classes: int, in_channels: int, grid: tuple[int, int], preset: str = "full",
    frames: int | None = None, **overrides: object
) -> CNN1D:
    check_io("cnn1d", n_classes, in_channels, grid)
    frames = frames or VIEWS[preset].frames
    opts = resolve_options("cnn1d", preset, OPTIONS, overrides)
    members, hp = hyperparameters(CNN1DHyperparameters, opts)
    data = NetworkInput(n_classes, in_channels, frames, (grid[0], grid[1]))
    model = build_members(CNN1D, members, data, hp)
    model.train_recipe = RECIPE[preset]
    model.input_shape = (in_channels, frames, *grid)
    return model


# the declaration the registry finds
# (pyproject.toml: [project.entry-points."tactile_studio.models"])
MODEL = ModelSpec(
    name="cnn1d",
    description="tiny 1-D CNN over moving-average slices, taxels as channels",
    builder=build,
    views=VIEWS,
    train=TRAIN,
    options=OPTIONS,
    option_help=OPTION_HELP,
    export=("onnx",),
    quantizable=True,
)
