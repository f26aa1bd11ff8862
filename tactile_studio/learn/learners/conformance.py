"""``check_model``: the conformance check a model author runs in their own tests.

It reads the model's declaration (views, training defaults, options and their help,
export formats, int8, streaming, GPUs) for consistency, builds the model for every preset
on 1- and 3-channel data and runs a forward pass, checks the declared facts against the
network (a ``cached`` streaming model's two halves equal its forward pass; a model
declaring ONNX exports and runs in onnxruntime with the same logits), then drives its
learner as the experiment does on a small synthetic dataset (samples, normalisation,
fit, predict_proba, save, load) and raises one :class:`ModelCheckError` listing every
problem found::

    from tactile_studio.learn import check_model

    def test_my_model_meets_the_contract():
        check_model("my_model")
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError

GRID = (6, 6)
N_CLASSES = 3


class ModelCheckError(AssertionError):
    """Every way a model breaks the contract, one per line."""

    def __init__(self, model: str, problems: list[str]) -> None:
        self.model, self.problems = model, list(problems)
        lines = "\n".join(f"  - {p}" for p in problems)
        super().__init__(f"model {model}: {len(problems)} problem(s)\n{lines}")


def check_model(model: Any, *, epochs: int = 2, seed: int = 0) -> dict[str, Any]:
    """Check the model registered as ``model`` (a name, or a ModelSpec not registered yet)
    against the learner contract; raise ModelCheckError listing every problem. ``epochs``
    bounds the tiny training run. Returns what was observed (parameters per preset,
    samples, probabilities) for the caller's own assertions."""
    from tactile_studio.learn.learners import baselines
    from tactile_studio.learn.models import ModelSpec, get_model_spec

    problems: list[str] = []
    observed: dict[str, Any] = {"parameters": {}}
    spec: ModelSpec | None = None
    if isinstance(model, ModelSpec):
        spec, name = model, model.name
    elif isinstance(model, str) and model in baselines.BASELINES:
        name = model
    elif isinstance(model, str):
        name = model
        try:
            spec = get_model_spec(model)
        except UserError as exc:
            raise ModelCheckError(model, [str(exc)]) from None
    else:
        raise ModelCheckError(repr(model), [f"{model!r} is neither a model name nor a ModelSpec"])
    if spec is not None:
        from tactile_studio.learn.learners.conformance_spec import check_build, check_declaration

        check_declaration(spec, problems)
        if not problems:  # building needs a sound declaration
            check_build(spec, problems, observed)
    if not problems:
        _check_learner(name, spec, epochs, seed, problems, observed)
    if problems:
        raise ModelCheckError(name, problems)
    return observed


def synthetic_dataset(channels: int, trials_per_class: int = 6, frames: int = 60,
                      seed: int = 0):
    """A small TrialDataset whose classes differ in mean and in temporal pattern."""
    from tactile_studio.learn.data.dataset import TrialDataset

    rng = np.random.default_rng(seed)
    trials, labels = [], []
    t = np.linspace(0, 1, frames, dtype=np.float32)
    for k in range(N_CLASSES):
        for _ in range(trials_per_class):
            wave = np.sin(2 * np.pi * (k + 1) * t)[None, :, None, None]
            noise = rng.normal(0, 0.3, (channels, frames, *GRID))
            trials.append((0.5 * k + wave + noise).astype(np.float32))
            labels.append(k)
    n = len(trials)
    shear = channels == 3
    return TrialDataset(
        trials=trials, labels=np.array(labels, np.int64),
        participants=np.array([f"p{i % 2}" for i in range(n)]),
        uids=[f"t{i}" for i in range(n)], rates=np.full(n, 43.0),
        label_names=[f"class{k}" for k in range(N_CLASSES)],
        layout="shearsense-6x6" if shear else "grid-6x6", grid="physical", has_shear=shear,
        channels="both" if shear else "normal",
        channel_names=["normal", "shear_x", "shear_y"] if shear else ["pressure"])


def _check_learner(name: str, spec: Any, epochs: int, seed: int, problems: list[str],
                   observed: dict[str, Any]) -> None:
    """Drive the learner as run_experiment does, on 3-channel synthetic trials."""
    from tactile_studio.learn.learners.contract import LEARNER_MEMBERS, DataInfo, Fitted, Learner
    from tactile_studio.learn.learners.families import make_learner

    try:
        learner = make_learner(name, "tiny", {}, epochs, "cpu", spec=spec)
    except UserError as exc:
        problems.append(f"make_learner: {exc}")
        return
    if not isinstance(learner, Learner):
        missing = [m for m in LEARNER_MEMBERS if not hasattr(learner, m)]
        problems.append(f"the learner lacks {', '.join(missing)} of the Learner protocol")
        return
    facts = learner.facts
    if learner.windowed != facts.windowed:
        problems.append("learner.windowed disagrees with facts.windowed")
    if facts.sliding and facts.window is None:
        problems.append("a sliding-window model needs facts.window (frames per window)")
    ds = synthetic_dataset(3, seed=seed)
    info = DataInfo.of(ds)
    try:
        learner.check(info)
        json.dumps(learner.describe())
        x, owner = learner.samples(ds)
        if len(x) != len(owner) or set(owner.tolist()) != set(range(len(ds))):
            problems.append(f"samples: {len(x)} samples, owners {sorted(set(owner.tolist()))} "
                            f"do not cover the {len(ds)} trials")
            return
        y = ds.labels[owner]
        stats = learner.norm_stats(x)
        xn = learner.apply_norm(x, stats)
        epochs_seen: list[dict[str, Any]] = []
        fitted, history, best = learner.fit(info, (xn, y), (xn, y), seed, None,
                                            epochs_seen.append, norm=stats)
    except UserError as exc:
        problems.append(f"training on synthetic 6x6 trials: {exc}")
        return
    if not isinstance(fitted, Fitted):
        problems.append(f"fit returned a {type(fitted).__name__}, which lacks the Fitted "
                        "protocol (file_name, predict_proba, save)")
        return
    probs = np.asarray(fitted.predict_proba(xn))
    if probs.shape != (len(x), N_CLASSES):
        problems.append(f"predict_proba gave shape {probs.shape}, expected {(len(x), N_CLASSES)}")
        return
    if not np.allclose(probs.sum(axis=1), 1.0, atol=1e-4) or (probs < 0).any():
        problems.append("predict_proba rows are not probabilities (>= 0, summing to 1)")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / fitted.file_name
        fitted.save(path)
        again = np.asarray(learner.load(path, info).predict_proba(xn))
    if not np.allclose(again, probs, atol=1e-5):
        problems.append("the loaded model predicts differently from the saved one "
                        f"(max difference {float(np.abs(again - probs).max()):.2g})")
    accuracy = float((probs.argmax(axis=1) == y).mean())
    observed.update(samples=len(x), history=history, best_epoch=best,
                    train_accuracy=accuracy, facts=facts)
    if not math.isfinite(accuracy):
        problems.append("training accuracy is not a number")
