"""The learner contract: what the experiment, export and live code may ask of any model.

A :class:`Learner` (one per model name, preset and options; learn/learners/families.py makes them)
turns a dataset into samples, computes normalisation statistics from training samples,
fits, and loads a saved fit; a :class:`Fitted` model predicts class probabilities and
saves itself. :class:`ModelFacts` is what a learner declares about its model, read
instead of probing the network: the view it takes, export formats, int8, live streaming,
GPU wish and option help. ``tactile_studio.learn.check_model`` checks a model against
this contract (docs/models.md).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from tactile_studio.jobs import CancelToken
from tactile_studio.learn.presets import PRESETS  # noqa: F401 (its home is learn/presets.py)

if TYPE_CHECKING:
    from tactile_studio.learn.data.dataset import TrialDataset


@dataclass(frozen=True)
class DataInfo:
    """What a model needs to know about its input (saved in the run config)."""

    n_classes: int
    in_channels: int
    grid: tuple[int, int]
    channel_names: tuple[str, ...]
    cell_pitch: float  # physical taxel pitches per grid cell (0.5 on the virtual grid)

    @classmethod
    def of(cls, ds: TrialDataset) -> DataInfo:
        return cls(ds.n_classes, ds.n_channels, ds.grid_shape, tuple(ds.channel_names),
                   0.5 if ds.grid == "virtual" else 1.0)

    def to_dict(self) -> dict[str, Any]:
        return {"n_classes": self.n_classes, "in_channels": self.in_channels,
                "grid": list(self.grid), "channel_names": list(self.channel_names),
                "cell_pitch": self.cell_pitch}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> DataInfo:
        return cls(int(d["n_classes"]), int(d["in_channels"]), tuple(d["grid"]),
                   tuple(d["channel_names"]), float(d["cell_pitch"]))


@dataclass(frozen=True)
class ModelFacts:
    """A learner's declared facts, resolved for its preset and options.

    ``view``: the view kind it takes ("resample", "windows", "slices", "gradient" for torch
    models, "features" for the rf / knn baselines). ``export``: file formats its fitted
    model can become ("onnx", "torchscript"). ``quantizable``: export-model --format int8
    works. ``sliding``: live inference streams it frame by frame over a sliding window of
    ``window`` frames (else it classifies the newest trial-long window); ``cached``: the
    per-frame part is computed once per frame. ``gpus``: what a sweep task asks for.
    """

    view: str
    export: tuple[str, ...] = ("onnx",)
    quantizable: bool = False
    sliding: bool = False
    cached: bool = False
    window: int | None = None
    gpus: float = 0.0
    option_help: Mapping[str, str] = field(default_factory=dict)

    @property
    def windowed(self) -> bool:
        """Trials are cut into windows, each a sample; trial predictions aggregate them."""
        return self.view == "windows"


Samples = tuple[np.ndarray, np.ndarray]  # (x, owner): the inputs and each one's trial index
EpochCallback = Callable[[dict[str, Any]], None]


@runtime_checkable
class Fitted(Protocol):
    """A fitted model: class probabilities, and a file it saves itself to."""

    file_name: str  # the file name in a run's fold folder ("model.safetensors", "model.onnx")

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """(N, ...) normalised samples -> (N, n_classes) probabilities."""
        ...

    def save(self, path: str | os.PathLike[str]) -> None: ...

    # optional: ``adapted(x) -> Fitted``, the model adapted to one person's normalised
    # samples (``--adapt person``; torch models re-estimate batch norm). Without it a
    # fitted model predicts every person as it is.


@runtime_checkable
class Learner(Protocol):
    """One model at one preset with its options, ready to fit on a dataset."""

    kind: str  # "torch" | "baseline": the run folder's weights format and export path
    name: str
    preset: str
    facts: ModelFacts
    max_epochs: int  # for progress; 1 for models not trained by epochs

    @property
    def windowed(self) -> bool: ...

    def describe(self) -> dict[str, Any]:
        """JSON-able description saved in the run config (view, options, training)."""
        ...

    def check(self, info: DataInfo) -> None:
        """Raise a one-line UserError now if the options cannot work for this data."""
        ...

    def samples(self, ds: TrialDataset) -> Samples: ...

    def adapt_inputs(self, x: np.ndarray, people: np.ndarray,
                     reference: np.ndarray | None = None) -> np.ndarray:
        """Samples as trained and tested with ``--adapt person`` (``people``: each
        sample's adaptation group, its participant or participant and condition):
        rf/knn standardise each group's features (every sample by the ``reference``
        samples' statistics when given: a person's calibration recording, live); a
        network returns ``x`` (it adapts when predicting)."""
        ...

    def norm_stats(self, x_train: np.ndarray) -> dict[str, list[float]]: ...

    def apply_norm(self, x: np.ndarray, stats: dict[str, list[float]]) -> np.ndarray: ...

    def fit(self, info: DataInfo, train: tuple[np.ndarray, np.ndarray],
            val: tuple[np.ndarray, np.ndarray], seed: int, cancel: CancelToken | None,
            on_epoch: EpochCallback | None, norm: Mapping[str, Any] | None = None,
            ) -> tuple[Fitted, list[dict[str, Any]], int]:
        """(fitted model, per-epoch history, best epoch) from normalised samples; ``norm``
        is what ``norm_stats`` gave for them (a model may need the physical units back)."""
        ...

    def load(self, path: str | os.PathLike[str], info: DataInfo) -> Fitted: ...


# the members above, for naming what a non-conforming learner lacks
LEARNER_MEMBERS = ("kind", "name", "preset", "facts", "max_epochs", "windowed", "describe",
                   "check", "samples", "adapt_inputs", "norm_stats", "apply_norm", "fit",
                   "load")
