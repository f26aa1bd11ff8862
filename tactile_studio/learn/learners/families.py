"""One interface over torch models (the registry) and the rf / knn baselines.

A learner turns a dataset into samples (a torch model's view of every trial, or one
feature vector per trial for the baselines), computes normalisation statistics from the
training samples it is given, fits, predicts class probabilities, and saves / loads its
fitted model (torch weights as safetensors, rf / knn as ONNX). Both satisfy the
``Learner`` protocol of learn/learners/contract.py, and the experiment code only talks to it.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.learn.data import views
from tactile_studio.learn.learners import baselines, fused
from tactile_studio.learn.learners.contract import DataInfo, Fitted, Learner, ModelFacts
from tactile_studio.learn.learners.generalise import person_standardised
from tactile_studio.learn.learners.train import TRAIN_KEYS, TrainSettings, train_settings

if TYPE_CHECKING:
    from tactile_studio.learn.models import ModelSpec

__all__ = ["BaselineLearner", "DataInfo", "Fitted", "Learner", "ModelFacts", "TorchFitted",
           "TorchLearner", "available_models", "make_learner"]


def available_models() -> dict[str, str]:
    """Every model name the pipeline accepts, with a one-line description (a registered
    model whose module fails to load says so instead)."""
    from tactile_studio.learn.models import get_model_spec, model_names

    out: dict[str, str] = {}
    for name in model_names():
        try:
            out[name] = get_model_spec(name).description
        except UserError as exc:
            out[name] = str(exc)
    out.update(baselines.DESCRIPTIONS)
    return out


def make_learner(name: str, preset: str = "full", overrides: dict[str, Any] | None = None,
                 epochs: int | None = None, device: str = "auto",
                 spec: ModelSpec | None = None) -> Learner:
    """The learner for model ``name`` (``spec`` bypasses the registry, e.g. for tests)."""
    from tactile_studio.learn.models import get_model_spec, model_names

    overrides = dict(overrides or {})
    if spec is None and name in baselines.BASELINES:
        if fused.OPTION in overrides:
            raise UserError(f"option '{fused.OPTION}' fuses a learned model with rf; "
                            f"model '{name}' is not a learned model")
        return BaselineLearner(name, preset, overrides)
    if spec is None:
        if name not in model_names():
            raise UserError(f"unknown model '{name}' (available: "
                            f"{', '.join(available_models())})")
        spec = get_model_spec(name)
    weight = fused.rf_weight(overrides)
    forest_adapts = fused.forest_adapts(overrides)
    overrides.pop(fused.OPTION, None)
    overrides.pop(fused.ADAPT_OPTION, None)
    network = TorchLearner(spec, preset, overrides, epochs, device)
    if weight > 0:
        # the fused forest keeps the 115 basic features: fusion was measured with them, and
        # the forest files of earlier fused runs read them
        return fused.FusedLearner(network, BaselineLearner("rf", preset, {"features": "basic"}),
                                  weight, forest_adapts)
    return network


class TorchLearner:
    """A registered torch model (learn/models): trained by epochs, saved as safetensors."""

    kind = "torch"

    def __init__(self, spec: ModelSpec, preset: str, overrides: dict[str, Any],
                 epochs: int | None, device: str) -> None:
        from tactile_studio.learn.learners.train import pick_device

        self.spec, self.name, self.preset = spec, spec.name, preset
        train_over = {k: v for k, v in overrides.items() if k in TRAIN_KEYS}
        self.model_overrides = {k: v for k, v in overrides.items() if k not in TRAIN_KEYS}
        self.settings: TrainSettings = train_settings(spec.train_defaults(preset), train_over,
                                                      epochs)
        self.view = _override_view(spec.view(preset), overrides)
        self.device = pick_device(device)
        self.max_epochs = self.settings.max_epochs
        sliding = spec.streaming.sliding
        self.facts = ModelFacts(
            view=self.view.kind, export=tuple(spec.export), quantizable=spec.quantizable,
            sliding=sliding, cached=spec.streaming.cached,
            window=self.view.frames if sliding else None, gpus=spec.gpus,
            option_help={**spec.option_help, fused.OPTION: fused.OPTION_HELP,
                         fused.ADAPT_OPTION: fused.ADAPT_OPTION_HELP})

    @property
    def windowed(self) -> bool:
        return self.facts.windowed

    def describe(self) -> dict[str, Any]:
        return {"kind": "torch", "description": self.spec.description,
                "view": {"kind": self.view.kind, "frames": self.view.frames,
                         "stride": self.view.stride},
                "train": asdict(self.settings), "model_options": self.model_overrides,
                "device": str(self.device)}

    def build(self, info: DataInfo):
        return self.spec.build(info.n_classes, info.in_channels, tuple(info.grid), self.preset,
                               **self.model_overrides)

    def check(self, info: DataInfo) -> None:
        """Build once so bad model options fail before any training."""
        from tactile_studio.learn.models._common import UnknownOptionError

        try:
            self.build(info)
        except UnknownOptionError as exc:
            raise UserError(
                f"unknown option '{exc.key}' for model '{exc.model}' (model options: "
                f"{', '.join(exc.allowed)}; training options: {', '.join(TRAIN_KEYS)})"
            ) from None

    def samples(self, ds) -> tuple[np.ndarray, np.ndarray]:
        return views.make_samples(ds.trials, self.view.kind, self.view.frames, self.view.stride)

    def norm_stats(self, x_train: np.ndarray) -> dict[str, list[float]]:
        mean, std = views.channel_stats(x_train)
        return {"mean": mean.tolist(), "std": std.tolist()}

    def adapt_inputs(self, x: np.ndarray, people: np.ndarray,
                     reference: np.ndarray | None = None) -> np.ndarray:
        """``adapt="person"``: a network adapts when it predicts (``TorchFitted.adapted``),
        its inputs stay as they are."""
        return x

    def apply_norm(self, x: np.ndarray, stats: dict[str, list[float]]) -> np.ndarray:
        return views.normalise(x, np.asarray(stats["mean"], np.float32),
                               np.asarray(stats["std"], np.float32))

    def fit(self, info: DataInfo, train: tuple[np.ndarray, np.ndarray],
            val: tuple[np.ndarray, np.ndarray], seed: int, cancel: CancelToken | None,
            on_epoch: Callable[[dict[str, Any]], None] | None,
            norm: dict[str, Any] | None = None):
        import torch

        from tactile_studio.learn.learners.train import fit

        torch.manual_seed(seed)
        model = self.build(info)
        if norm and hasattr(model, "set_input_norm"):  # the recipe's gesture metrics
            model.set_input_norm(norm["mean"], norm["std"], info.cell_pitch)
        _, history, best = fit(model, train, val, self.settings, seed, self.device, cancel,
                               on_epoch)
        return TorchFitted(model, self.device), history, best

    def load(self, path, info: DataInfo) -> TorchFitted:
        from tactile_studio.learn.learners.train import load_weights

        model = load_weights(self.build(info), path)
        return TorchFitted(model.to(self.device), self.device)


def _override_view(view: Any, overrides: dict[str, Any]) -> Any:
    """The model's view with ``view_frames`` / ``view_stride`` overrides (the registry's
    build also receives them, and sizes the model to the new length)."""
    changes = {}
    for key, attr in (("view_frames", "frames"), ("view_stride", "stride")):
        if key in overrides:
            try:
                value = int(float(overrides[key]))
            except (TypeError, ValueError, OverflowError):  # nan, inf
                value = 0
            if value < 1:
                raise UserError(f"{key}={overrides[key]!r} must be a positive whole number")
            changes[attr] = value
    return replace(view, **changes) if changes else view


class TorchFitted:
    file_name = "model.safetensors"  # runfolder.WEIGHTS

    def __init__(self, model, device) -> None:
        self.model, self.device = model, device

    def adapted(self, x: np.ndarray) -> TorchFitted:
        """This model with its batch-norm statistics re-estimated on one person's
        normalised samples ``x`` (``adapt="person"``, learn/learners/generalise.py)."""
        from tactile_studio.learn.learners.train import adapt_batchnorm

        return TorchFitted(adapt_batchnorm(self.model, x, self.device), self.device)

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        from tactile_studio.learn.learners.train import predict_proba

        return predict_proba(self.model, x, self.device)

    def save(self, path) -> None:
        from tactile_studio.learn.learners.train import save_weights

        save_weights(self.model.state_dict(), path)


class BaselineLearner:
    """rf / et / knn on handcrafted trial features (learn/learners/baselines.py), saved as ONNX."""

    kind = "baseline"
    max_epochs = 1  # not trained by epochs

    def __init__(self, name: str, preset: str, overrides: dict[str, Any]) -> None:
        unused = [k for k in overrides if k in TRAIN_KEYS]
        if unused:
            raise UserError(f"model '{name}' is not trained by epochs: option "
                            f"'{unused[0]}' does not apply")
        self.name, self.preset = name, preset
        self.options = baselines.baseline_options(name, preset, overrides)
        self.facts = ModelFacts(view="features", export=("onnx",),
                                option_help=dict(baselines.OPTION_HELP[name]))

    @property
    def windowed(self) -> bool:
        return self.facts.windowed

    def describe(self) -> dict[str, Any]:
        return {"kind": "baseline", "description": baselines.DESCRIPTIONS[self.name],
                "view": {"kind": "features"}, "model_options": self.options}

    def check(self, info: DataInfo) -> None:
        pass

    def samples(self, ds) -> tuple[np.ndarray, np.ndarray]:
        from tactile_studio.learn.data.features import feature_matrix

        pitch = 0.5 if ds.grid == "virtual" else 1.0
        x, _ = feature_matrix(ds.trials, ds.channel_names, ds.rates, pitch,
                              self.options.get("features") == "touch")
        return x, np.arange(len(ds.trials))

    def adapt_inputs(self, x: np.ndarray, people: np.ndarray,
                     reference: np.ndarray | None = None) -> np.ndarray:
        """``adapt="person"``: every person's features standardised by their own (by the
        ``reference`` samples' when given)."""
        return person_standardised(x, people, reference)

    def norm_stats(self, x_train: np.ndarray) -> dict[str, list[float]]:
        return {}  # k-NN standardises with its own training statistics; rf needs none

    def apply_norm(self, x: np.ndarray, stats: dict[str, list[float]]) -> np.ndarray:
        return x

    def fit(self, info: DataInfo, train, val, seed, cancel, on_epoch, norm=None):
        """Fits on ``train`` and ``val`` together: nothing stops a forest early, so the
        validation share trains too (before issue 45 rf/knn left the fold's 15% unused;
        a fused model's forest does the same)."""
        if cancel is not None:
            cancel.check()
        model = baselines.BaselineModel(self.name, self.options, info.n_classes)
        meta = {"channel_names": json.dumps(list(info.channel_names)),
                "cell_pitch": str(info.cell_pitch)}
        x, y = np.concatenate([train[0], val[0]]), np.concatenate([train[1], val[1]])
        return model.fit(x, y, seed, meta), [], 0

    def load(self, path, info: DataInfo) -> baselines.BaselineModel:
        if str(path).endswith(".safetensors"):
            raise UserError(f"{path}: an rf/knn model saved before they became ONNX files; "
                            "train the run again")
        return baselines.BaselineModel.load(path, self.name, self.options, info.n_classes,
                                            list(info.channel_names))
