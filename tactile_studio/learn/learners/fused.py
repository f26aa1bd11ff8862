"""A learned model fused with a random forest (model option ``rf_weight``).

On unseen people a network and the random forest on handcrafted trial features make
different mistakes: averaging their probabilities beat either alone on the simulator
(docs/learning/learners.md, "Fused with the random forest"). ``--set rf_weight=W`` (0 < W < 1)
trains both on the same fold, the forest on the samples' trial features exactly as
``rf`` alone (same seed, same options at the same preset), and predicts
``(1 - W) * p_network + W * p_forest``. (A network that cuts a trial into several windows,
cnn_transformer, gives the forest one row per window, each with its trial's features.)

Both parts see the same samples: each sample is the network's view, flattened, with the
feature vector of its trial (or window) appended, so every path that handles a learner's
samples (folds, augmentation, evaluation, live inference by windows) works unchanged.
The fold folder holds ``model.safetensors`` (the network) and ``rf.onnx`` (the forest).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.learn.learners.contract import DataInfo, ModelFacts

RF_FILE = "rf.onnx"
HEAD = 2  # packed samples start with (view values, channels)
OPTION = "rf_weight"
OPTION_HELP = ("weight of a random forest's probabilities averaged with the network's "
               "(0 = the network alone; 0.5 = equal)")
# whether an adapted fused run also standardises its forest's features per person
ADAPT_OPTION = "rf_adapt"
ADAPT_OPTION_HELP = ("with rf_weight and --adapt: 1 also standardises the forest's features "
                     "by each person's own statistics, 0 keeps them as trained (the network "
                     "adapts either way); --adapt auto chooses 0, as for rf alone")


def rf_weight(overrides: dict[str, Any]) -> float:
    """The fusion weight in ``overrides`` (0 when absent); a one-line error if invalid."""
    raw = overrides.get(OPTION, 0)
    try:
        value = float(raw)
    except (TypeError, ValueError):
        value = -1.0
    if not 0.0 <= value < 1.0:
        raise UserError(f"{OPTION}={raw!r} must be a number from 0 (the network alone) "
                        "up to, not including, 1")
    return value


def forest_adapts(overrides: dict[str, Any]) -> bool:
    """``rf_adapt`` in ``overrides``: 1 (the default, what every fused run before the
    option did) or 0; a one-line error otherwise."""
    raw = overrides.get(ADAPT_OPTION, 1)
    if str(raw).strip().lower() in ("1", "true"):
        return True
    if str(raw).strip().lower() in ("0", "false"):
        return False
    raise UserError(f"{ADAPT_OPTION}={raw!r} must be 1 (standardise the forest's features "
                    "per person) or 0 (keep them as trained)")


def display_name(model: str, overrides: dict[str, Any] | None) -> str:
    """``cnn1d + rf 0.5`` for a fused model, else the model's name (titles, tables)."""
    weight = rf_weight(overrides or {})
    return f"{model} + rf {weight:g}" if weight > 0 else model


class FusedLearner:
    """A torch learner and an rf baseline learner trained side by side on one fold."""

    kind = "fused"

    def __init__(self, network, forest, weight: float,  # noqa: ANN001 - learners
                 forest_adapts: bool = True) -> None:
        self.network, self.forest, self.weight = network, forest, weight
        self.forest_adapts = forest_adapts  # rf_adapt: see standardises_person_features
        self.name, self.preset = network.name, network.preset
        self.max_epochs = network.max_epochs
        self.view = network.view
        net = network.facts
        # predictions come from whole windows (the forest needs a window's features)
        self.facts = ModelFacts(view=net.view, export=("onnx",) if "onnx" in net.export
                                else (), quantizable=False, sliding=False, cached=False,
                                window=None, gpus=net.gpus,
                                option_help=dict(net.option_help))  # rf_weight's included

    @property
    def windowed(self) -> bool:
        return self.network.windowed

    def describe(self) -> dict[str, Any]:
        out = self.network.describe()
        out.update(kind="fused", rf_weight=self.weight, rf=self.forest.describe(),
                   rf_adapt=int(self.forest_adapts))
        return out

    def check(self, info: DataInfo) -> None:
        self.network.check(info)

    # ---- samples: [view size, channels, the view flattened, the trial's features] ------
    def samples(self, ds) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001 - TrialDataset
        view, owner = self.network.samples(ds)
        features, _ = self.forest.samples(ds)
        flat = view.reshape(len(view), -1)
        # the header makes a sample self-describing; float32 is exact below 2**24
        head = np.tile(np.float32([flat.shape[1], view.shape[1]]), (len(view), 1))
        packed = np.concatenate([head, flat, np.asarray(features, np.float32)[owner]], axis=1)
        return packed, owner

    def split(self, x: np.ndarray, info: DataInfo) -> tuple[np.ndarray, np.ndarray]:
        """Packed samples -> (network views (N, C, T, R, X), trial features (N, F))."""
        n, _ = _header(x)
        shape = (info.in_channels, self.view.frames, *info.grid)
        return x[:, HEAD:HEAD + n].reshape(len(x), *shape), x[:, HEAD + n:]

    def _views(self, x: np.ndarray) -> np.ndarray:
        """The view part as (N, C, values per channel): enough for per-channel z-scores."""
        n, channels = _header(x)
        return x[:, HEAD:HEAD + n].reshape(len(x), channels, -1)

    def adapt_inputs(self, x: np.ndarray, people: np.ndarray,
                     reference: np.ndarray | None = None) -> np.ndarray:
        """``adapt="person"``: the forest's features standardised per person (the
        network adapts when it predicts, ``FusedFitted.adapted``); ``reference`` holds
        forest features (``person_columns``), not packed samples. With ``rf_adapt=0`` the
        forest's features stay as trained."""
        if not self.forest_adapts:
            return x
        n, _ = _header(x)
        return np.concatenate([x[:, :HEAD + n], self.forest.adapt_inputs(
            x[:, HEAD + n:], people, reference)], axis=1)

    def norm_stats(self, x_train: np.ndarray) -> dict[str, list[float]]:
        return self.network.norm_stats(self._views(x_train))

    def apply_norm(self, x: np.ndarray, stats: dict[str, list[float]]) -> np.ndarray:
        """z-scores the view part only: the forest splits on raw feature values."""
        if not len(x):
            return x
        n, _ = _header(x)
        normed = self.network.apply_norm(self._views(x), stats).reshape(len(x), n)
        return np.concatenate([x[:, :HEAD], normed, x[:, HEAD + n:]], axis=1)

    # ---- fit / load ------------------------------------------------------------------
    def fit(self, info: DataInfo, train: tuple[np.ndarray, np.ndarray],
            val: tuple[np.ndarray, np.ndarray], seed: int, cancel: CancelToken | None,
            on_epoch: Callable[[dict[str, Any]], None] | None,
            norm: dict[str, Any] | None = None):
        (xv, fv), (xval, fval) = self.split(train[0], info), self.split(val[0], info)
        net, history, best = self.network.fit(info, (xv, train[1]), (xval, val[1]), seed,
                                              cancel, on_epoch, norm=norm)
        forest, _, _ = self.forest.fit(info, (fv, train[1]), (fval, val[1]), seed, cancel,
                                       None)
        return FusedFitted(net, forest, self.weight, self, info), history, best

    def load(self, path, info: DataInfo) -> FusedFitted:  # noqa: ANN001 - path-like
        net = self.network.load(path, info)
        forest = self.forest.load(Path(path).parent / RF_FILE, info)
        return FusedFitted(net, forest, self.weight, self, info)


class FusedFitted:
    """``(1 - w) * network + w * forest`` probabilities; saved as two files."""

    file_name = "model.safetensors"  # runfolder.WEIGHTS: the fold's model file

    def __init__(self, network, forest, weight: float, learner: FusedLearner,  # noqa: ANN001
                 info: DataInfo) -> None:
        self.network, self.forest, self.weight = network, forest, weight
        self.learner, self.info = learner, info

    @property
    def model(self):  # noqa: ANN201 - the torch module, for export
        return self.network.model

    def predict_parts(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(network, forest) probabilities of packed, normalised samples."""
        views, features = self.learner.split(x, self.info)
        return self.network.predict_proba(views), self.forest.predict_proba(features)

    def adapted(self, x: np.ndarray) -> FusedFitted:
        """The network adapted to one person's packed samples ``x`` (the forest's
        features were standardised per person already)."""
        views, _ = self.learner.split(x, self.info)
        return FusedFitted(self.network.adapted(views), self.forest, self.weight,
                           self.learner, self.info)

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        net, forest = self.predict_parts(x)
        return fuse(net, forest, self.weight)

    def save(self, path) -> None:  # noqa: ANN001 - path-like
        self.network.save(path)
        self.forest.save(Path(path).parent / RF_FILE)


def _header(x: np.ndarray) -> tuple[int, int]:
    """(view values per sample, channels) from a packed sample's first columns."""
    return (int(x[0, 0]), int(x[0, 1])) if len(x) else (0, 1)


def standardises_person_features(learner) -> bool:  # noqa: ANN001 - a learner
    """True for a learner whose features an adapted run standardises by each person's
    own statistics: rf and knn, and a fused model's forest unless ``rf_adapt=0``
    (on real people standardising a forest's features cost rf 1.7 points, issue 37). A
    network adapts its batch norm instead."""
    if learner.kind == "fused":
        return bool(learner.forest_adapts)
    return learner.kind != "torch"


def person_columns(learner, x: np.ndarray) -> np.ndarray:  # noqa: ANN001 - a learner
    """The columns ``--adapt person`` standardises by a person's statistics: a fused
    sample's forest features, an rf/knn sample whole (their moments and calibration
    references are kept in this space)."""
    return x[:, HEAD + _header(x)[0]:] if learner.kind == "fused" else x


def fuse(network: np.ndarray, forest: np.ndarray, weight: float) -> np.ndarray:
    """The fused probabilities (one formula for training, evaluation and export)."""
    return (1.0 - weight) * np.asarray(network) + weight * np.asarray(forest)


__all__ = ["ADAPT_OPTION", "OPTION", "RF_FILE", "FusedFitted", "FusedLearner", "display_name",
           "forest_adapts", "fuse", "person_columns", "rf_weight",
           "standardises_person_features"]
