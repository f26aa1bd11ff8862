"""The texture paper's multimodal fusion network.

Each modality is a multichannel time series: normal = channel 0's taxels (R*X signals),
shear = the shear channels' taxels (2*R*X). One depthwise-separable 1-D CNN branch per
modality; the branches' feature maps are concatenated along channels, re-weighted by a
Squeeze-and-Excitation block, projected to d_model, given sinusoidal positions, encoded
by a Transformer encoder, averaged over time and classified by an MLP head.

``fusion``: ``mid`` (the paper's: per-modality branches, fused feature maps), ``early``
(all signals concatenated into one branch) or ``late`` (one complete network per modality,
logits averaged). With a single-modality channel set (1 channel = normal/pressure, 2 =
shear) there is one branch and all three variants coincide in structure.

The ``full`` preset is not the paper's network but the generalisation recipe of
docs/learning/models.md (small network + linear window-statistics head, mirror training and
averaging, branch dropout, cosine budget); the paper's network is ``PAPER``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from tactile_studio.learn.models import ModelSpec, TrainDefaults, ViewSpec
from tactile_studio.learn.models._common import (
    RECIPE_HELP,
    NetworkInput,
    PositionalEncoding,
    Recipe,
    RecipeModel,
    build_members,
    check_io,
    hyperparameters,
    resolve_options,
    transformer_encoder,
)

# one line of help per option (the research workspace shows it beside the value)
OPTION_HELP = {
    "fusion": "mid (SE + Transformer over branches), early or late fusion",
    "filters": "channels of each depthwise-separable 1-D branch",
    "kernel": "kernel length of the branch convolutions",
    "blocks": "separable conv blocks per branch",
    "se_reduction": "Squeeze-and-Excitation reduction ratio",
    "d_model": "Transformer width",
    "heads": "attention heads",
    "layers": "Transformer encoder layers",
    "ff": "feed-forward width inside the encoder",
    "hidden": "units of the MLP head",
    "dropout": "dropout in the encoder and head",
    **RECIPE_HELP,
}

OPTIONS: dict[str, dict[str, object]] = {
    "full": {"fusion": "mid", "filters": 32, "kernel": 7, "blocks": 2, "se_reduction": 4,
             "d_model": 32, "heads": 4, "layers": 1, "ff": 64, "hidden": 32, "dropout": 0.3,
             "stats": True, "stats_hidden": 0, "mirror": True, "branch_dropout": 0.75,
             "gesture": False,
             "members": 1},  # 3 measured: no gain for 3.7x the cost (docs/learning/figures.md)
    "tiny": {"fusion": "mid", "filters": 16, "kernel": 5, "blocks": 2, "se_reduction": 4,
             "d_model": 16, "heads": 2, "layers": 1, "ff": 32, "hidden": 16, "dropout": 0.1,
             "stats": False, "stats_hidden": 16, "mirror": False, "branch_dropout": 0.0,
             "gesture": False, "members": 1},
}
# the texture paper's size (trained with adamw, lr 1e-3, weight decay 1e-2, up to 150
# epochs, patience 20)
PAPER = {"filters": 64, "d_model": 64, "heads": 4, "layers": 2, "ff": 256, "hidden": 64,
         "dropout": 0.1, "stats": False, "mirror": False, "gesture": False, "members": 1}
CHOICES = {"fusion": ("mid", "early", "late")}
VIEWS = {"full": ViewSpec("resample", 43), "tiny": ViewSpec("resample", 24)}
TRAIN = {
    "full": TrainDefaults("adamw", 3e-3, 32, 25, 25, weight_decay=1e-2),
    "tiny": TrainDefaults("adam", 3e-3, 16, 40, 8),
}
# training recipe of the preset (see train.fit): a fixed, cosine-decayed budget
RECIPE = {"full": {"label_smoothing": 0.1, "schedule": "cosine", "warmup": 2, "clip": 5.0},
          "tiny": {}}


class SeparableBlock(nn.Module):
    """Depthwise conv over time per signal, then a pointwise conv mixing signals."""

    def __init__(self, cin: int, cout: int, kernel: int, pool: bool) -> None:
        super().__init__()
        self.depthwise = nn.Conv1d(cin, cin, kernel, padding=kernel // 2, groups=cin)
        self.pointwise = nn.Conv1d(cin, cout, 1)
        self.bn = nn.BatchNorm1d(cout)
        self.act = nn.ReLU(inplace=True)
        self.pool = nn.MaxPool1d(2, ceil_mode=True) if pool else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.pool(self.act(self.bn(self.pointwise(self.depthwise(x)))))


class SqueezeExcite(nn.Module):
    def __init__(self, channels: int, reduction: int) -> None:
        super().__init__()
        hidden = max(1, channels // reduction)
        self.gate = nn.Sequential(
            nn.Linear(channels, hidden), nn.ReLU(inplace=True), nn.Linear(hidden, channels),
            nn.Sigmoid(),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # (B, C, T)
        return x * self.gate(x.mean(dim=2)).unsqueeze(2)


@dataclass(frozen=True)
class SEFusionHyperparameters:
    """The options of :data:`OPTIONS` (``members`` aside) as the network takes them;
    a :class:`Tower` reads the architecture's."""

    fusion: str
    filters: int
    kernel: int
    blocks: int
    se_reduction: int
    d_model: int
    heads: int
    layers: int
    ff: int
    hidden: int
    dropout: float
    recipe: Recipe = Recipe()


class Tower(nn.Module):
    """Branches (one per input group) -> concat -> SE -> Transformer -> MLP head."""

    def __init__(self, groups: list[int], n_classes: int, hp: SEFusionHyperparameters) -> None:
        super().__init__()
        filters, kernel, blocks, dropout = hp.filters, hp.kernel, hp.blocks, hp.dropout
        d_model, hidden = hp.d_model, hp.hidden
        self.branches = nn.ModuleList()
        for cin in groups:
            mods = []
            for i in range(blocks):
                # pool after every block but the last: halves time for the transformer
                mods.append(SeparableBlock(cin if i == 0 else filters, filters, kernel,
                                           pool=i < blocks - 1))
            self.branches.append(nn.Sequential(*mods))
        width = filters * len(groups)
        self.se = SqueezeExcite(width, hp.se_reduction)
        self.project = nn.Linear(width, d_model)
        self.positions = PositionalEncoding(d_model)
        self.encoder = transformer_encoder(d_model, hp.heads, hp.layers, hp.ff, dropout)
        self.head = nn.Sequential(
            nn.Linear(d_model, hidden), nn.ReLU(inplace=True), nn.Dropout(dropout),
            nn.Linear(hidden, n_classes),
        )

    def forward(self, inputs: list[torch.Tensor]) -> torch.Tensor:
        maps = [branch(x) for branch, x in zip(self.branches, inputs)]
        h = self.se(torch.cat(maps, dim=1) if len(maps) > 1 else maps[0])
        h = self.project(h.transpose(1, 2))
        h = self.encoder(self.positions(h))
        return self.head(h.mean(dim=1))


class SEFusion(RecipeModel):
    def __init__(self, data: NetworkInput, hp: SEFusionHyperparameters) -> None:
        super().__init__()
        self.attach_recipe(data, hp.recipe, float(hp.dropout))
        taxels = data.grid[0] * data.grid[1]
        n_classes, in_channels, fusion = data.n_classes, data.in_channels, hp.fusion
        self.fusion = fusion
        # channel 0 is normal when shear channels follow it; 1 channel = normal/pressure,
        # 2 channels = shear only: a single modality.
        self.split = in_channels == 3
        if self.split and fusion == "mid":
            self.towers = nn.ModuleList([Tower([taxels, 2 * taxels], n_classes, hp)])
        elif self.split and fusion == "late":
            self.towers = nn.ModuleList([Tower([taxels], n_classes, hp),
                                         Tower([2 * taxels], n_classes, hp)])
        else:
            self.towers = nn.ModuleList([Tower([in_channels * taxels], n_classes, hp)])

    def network_logits(self, x: torch.Tensor) -> torch.Tensor:
        b, c, t, r, s = x.shape
        if self.split and self.fusion != "early":
            normal = x[:, :1].permute(0, 1, 3, 4, 2).reshape(b, r * s, t)
            shear = x[:, 1:].permute(0, 1, 3, 4, 2).reshape(b, 2 * r * s, t)
            if self.fusion == "mid":
                return self.towers[0]([normal, shear])
            return (self.towers[0]([normal]) + self.towers[1]([shear])) / 2
        return self.towers[0]([x.permute(0, 1, 3, 4, 2).reshape(b, c * r * s, t)])


def build(
    n_classes: int, in_channels: int, grid: tuple[int, int], preset: str = "full",
    frames: int | None = None, **overrides: object
) -> SEFusion:
    check_io("sefusion", n_classes, in_channels, grid)
    frames = frames or VIEWS[preset].frames
    opts = resolve_options("sefusion", preset, OPTIONS, overrides, CHOICES)
    members, hp = hyperparameters(SEFusionHyperparameters, opts)
    data = NetworkInput(n_classes, in_channels, frames, (grid[0], grid[1]))
    model = build_members(SEFusion, members, data, hp)
    model.train_recipe = RECIPE[preset]
    model.input_shape = (in_channels, frames, *grid)
    return model


# the declaration the registry finds
# (pyproject.toml: [project.entry-points."tactile_studio.models"])
MODEL = ModelSpec(
    name="sefusion",
    description="depthwise-separable 1-D branches per modality + SE + Transformer "
                "(fusion=mid|early|late)",
    builder=build,
    views=VIEWS,
    train=TRAIN,
    options=OPTIONS,
    option_help=OPTION_HELP,
    export=("onnx",),
    quantizable=True,
)
