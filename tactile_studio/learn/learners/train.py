"""The training loop shared by every torch model (generic over the registry's ModelSpec).

Optimiser and schedule come from the model's ``TrainDefaults`` for the preset, with
``--set`` overrides (``lr``, ``batch_size``, ``epochs``/``max_epochs``, ``patience``,
``weight_decay``, ``momentum``, ``optimizer``). Early stopping watches the validation
loss (the validation set comes from training participants only); the weights of the
best epoch are kept and returned. Seeds are fixed per fold; the device is CUDA when
available unless asked otherwise.

A model may carry a ``train_recipe`` attribute (set by its module's ``build`` from the
preset's ``RECIPE``): ``label_smoothing`` (cross-entropy target smoothing), ``schedule``
(``"cosine"``: the learning rate decays to 0 over ``max_epochs`` after ``warmup`` linear
warm-up epochs; otherwise constant) and ``clip`` (gradient norm limit). These make small,
person-to-person data sets train to a fixed budget instead of chasing a noisy
validation loss; models without it train as before. A model with a ``training_step(x,
y, loss_fn) -> (loss, logits)`` method computes its own training loss (an ensemble of
members: the mean of each member's loss, see ``models/_common.py``).
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import torch
from torch import nn

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.learn.models import TrainDefaults

TRAIN_KEYS = ("optimizer", "lr", "batch_size", "max_epochs", "epochs", "patience",
              "weight_decay", "momentum")
OPTIMIZERS = ("adam", "adamw", "sgd")


# The settings a fold trains with have exactly the fields of a model's defaults.
TrainSettings = TrainDefaults


def train_settings(defaults: Any, overrides: dict[str, Any],
                   epochs: int | None = None) -> TrainSettings:
    """``TrainDefaults`` + training overrides (typed like the defaults) + ``--epochs``."""
    s = TrainSettings(**{k: getattr(defaults, k) for k in TrainSettings.__dataclass_fields__})
    changes: dict[str, Any] = {}
    for key, value in overrides.items():
        field = "max_epochs" if key == "epochs" else key
        default = getattr(s, field)
        try:
            changes[field] = type(default)(float(value) if type(default) is int else value)
        except (TypeError, ValueError, OverflowError):  # int(inf) overflows
            raise UserError(f"training option {key}={value!r} is not a valid "
                            f"{type(default).__name__}") from None
        if isinstance(changes[field], float) and not math.isfinite(changes[field]):
            raise UserError(f"training option {key}={value!r} is not a finite number")
        if isinstance(default, int) and changes[field] != float(value):
            raise UserError(f"training option {key}={value!r} must be a whole number")
    if epochs is not None:
        changes["max_epochs"] = int(epochs)
    s = replace(s, **changes)
    if s.optimizer not in OPTIMIZERS:
        raise UserError(f"unknown optimizer {s.optimizer!r} (available: {', '.join(OPTIMIZERS)})")
    if s.lr <= 0 or s.batch_size < 1 or s.max_epochs < 1 or s.patience < 1:
        raise UserError("lr, batch_size, epochs and patience must be positive")
    return s


def pick_device(preference: str = "auto") -> torch.device:
    if preference == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if preference.startswith("cuda") and not torch.cuda.is_available():
        raise UserError(f"device {preference!r} asked for but CUDA is not available")
    try:
        return torch.device(preference)
    except RuntimeError:
        raise UserError(f"unknown device {preference!r} (use auto, cpu or cuda)") from None


def make_optimizer(model: nn.Module, s: TrainSettings) -> torch.optim.Optimizer:
    """The settings' optimiser over ``model``'s parameters. On the CPU Adam and AdamW use
    torch's fused kernel: the same update (to float rounding) in one call instead of a
    Python loop of ~10 tensor operations per parameter tensor (0.3 instead of 1.2 ms per
    step for cnn1d's three members, ~4% of its full-preset fold)."""
    params = list(model.parameters())
    if s.optimizer == "sgd":
        return torch.optim.SGD(params, lr=s.lr, momentum=s.momentum, weight_decay=s.weight_decay)
    fused = bool(params) and all(p.device.type == "cpu" and p.dtype == torch.float32
                                 for p in params)
    if s.optimizer == "adamw":
        return torch.optim.AdamW(params, lr=s.lr, weight_decay=s.weight_decay, fused=fused)
    return torch.optim.Adam(params, lr=s.lr, weight_decay=s.weight_decay, fused=fused)


def _batches(n: int, size: int, rng: np.random.Generator | None) -> list[np.ndarray]:
    order = rng.permutation(n) if rng is not None else np.arange(n)
    out = [order[i:i + size] for i in range(0, n, size)]
    if len(out) > 1 and len(out[-1]) == 1:  # batch norm cannot train on one sample
        last = out.pop()  # (popped first: ``out[-2] = f(out.pop())`` hits the wrong batch)
        out[-1] = np.concatenate([out[-1], last])
    return out


def _evaluate(model: nn.Module, x: np.ndarray, y: np.ndarray, device: torch.device,
              batch_size: int, raw: torch.Tensor | None = None) -> tuple[float, float]:
    if len(y) == 0:
        return float("nan"), float("nan")
    probs = predict_proba(model, x, device, batch_size, raw=raw)
    p = np.clip(probs[np.arange(len(y)), y], 1e-12, None)
    return float(-np.log(p).mean()), float((probs.argmax(axis=1) == y).mean())


def predict_proba(model: nn.Module, x: np.ndarray, device: torch.device | str = "cpu",
                  batch_size: int = 256, raw: torch.Tensor | None = None) -> np.ndarray:
    """Class probabilities for samples ``x`` (S, C, T, R, X), in eval mode; ``raw``: the
    samples' precomputed window statistics (:func:`feature_cache`), when there are."""
    model.eval()
    out = []
    with torch.no_grad():
        for i in range(0, len(x), batch_size):
            xb = torch.from_numpy(np.ascontiguousarray(x[i:i + batch_size])).to(device)
            logits = model(xb) if raw is None else model(xb, raw=raw[i:i + batch_size])
            out.append(torch.softmax(logits.float(), dim=1).cpu().numpy())
    if not out:
        return np.zeros((0, 0), dtype=np.float32)
    return np.concatenate(out)


def feature_cache(model: nn.Module, x: np.ndarray, device: torch.device | str = "cpu",
                  chunk: int = 512) -> torch.Tensor | None:
    """The model's weight-free window statistics of every sample of ``x`` (and of its
    mirror images), computed once before training (``RecipeModel.feature_cache``); None
    for a model without them. Profiled on cnn1d's full preset they were a third of a
    fold's time when computed per batch every epoch and per validation pass."""
    cache = getattr(model, "feature_cache", None)
    if cache is None or len(x) == 0:
        return None
    parts = []
    for i in range(0, len(x), chunk):
        part = cache(torch.from_numpy(np.ascontiguousarray(x[i:i + chunk])).to(device))
        if part is None:
            return None
        parts.append(part)
    return torch.cat(parts)


def adapt_batchnorm(model: nn.Module, x: np.ndarray, device: torch.device | str = "cpu",
                    chunk: int = 2048) -> nn.Module:
    """A copy of ``model`` whose batch-norm statistics are those of ``x`` (AdaBN).

    ``x`` is one person's unlabelled, normalised samples: every batch-norm layer then
    centres and scales by what that person's touches look like at that layer, not by
    the training people's. The forward runs in eval mode (mirror averaging, no dropout)
    with only the batch-norm layers collecting statistics; up to ``chunk`` samples go
    in one pass, so the statistics are exact for a person's session. With fewer than
    2 samples there is nothing to estimate and the copy is left as trained.
    """
    adapted = copy.deepcopy(model).to(device).eval()
    if len(x) < 2:
        return adapted
    layers = [m for m in adapted.modules() if isinstance(m, nn.modules.batchnorm._BatchNorm)]
    if not layers:  # a model without batch norm has nothing to adapt
        return adapted
    for layer in layers:
        layer.reset_running_stats()
        layer.momentum = None  # cumulative: the chunks' statistics averaged
        layer.train()
    n_chunks = -(-len(x) // chunk)
    with torch.no_grad():
        for part in np.array_split(np.arange(len(x)), n_chunks):
            adapted(torch.from_numpy(np.ascontiguousarray(x[part])).to(device))
    return adapted.eval()


def _lr_factor(recipe: dict[str, Any], epoch: int, total: int) -> float:
    """Multiplier of the base learning rate in (1-based) ``epoch`` of ``total``."""
    warmup = int(recipe.get("warmup", 0))
    if epoch <= warmup:
        return epoch / (warmup + 1)
    if recipe.get("schedule") != "cosine":
        return 1.0
    done = (epoch - 1 - warmup) / max(1, total - warmup)
    return 0.5 * (1.0 + float(np.cos(np.pi * done)))


def fit(model: nn.Module, train: tuple[np.ndarray, np.ndarray],
        val: tuple[np.ndarray, np.ndarray], s: TrainSettings, seed: int,
        device: torch.device, cancel: CancelToken | None = None,
        on_epoch: Callable[[dict[str, Any]], None] | None = None,
        ) -> tuple[dict[str, torch.Tensor], list[dict[str, Any]], int]:
    """Train with early stopping; returns (best state dict, history, best epoch)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng([seed, 0x7EA])
    model.to(device)
    opt = make_optimizer(model, s)
    recipe = dict(getattr(model, "train_recipe", None) or {})
    loss_fn = nn.CrossEntropyLoss(label_smoothing=float(recipe.get("label_smoothing", 0.0)))
    clip = float(recipe.get("clip", 0.0))
    step = getattr(model, "training_step", None)  # ensembles: each member's own loss
    xt, yt = train
    xv, yv = val
    raw_t = feature_cache(model, xt, device)
    # a model may train faster with its weights in another memory layout (channels-last:
    # mts3d's 3-D convolutions ~30% less CPU per step, cnn_transformer's frame CNN ~10%;
    # cnn3d's no faster, and mts3d evaluates slower that way, so evaluation keeps the usual)
    layout = getattr(model, "train_memory_format", None) if device.type == "cpu" else None
    raw_v = feature_cache(model, xv, device)
    history: list[dict[str, Any]] = []
    best_loss, best_epoch, best_state, stale = float("inf"), 0, None, 0
    for epoch in range(1, s.max_epochs + 1):
        t0 = time.perf_counter()
        model.train()
        if layout is not None:  # see below; back to the usual layout before evaluating
            model.to(memory_format=layout)
        for group in opt.param_groups:
            group["lr"] = s.lr * _lr_factor(recipe, epoch, s.max_epochs)
        total, correct, count = 0.0, 0, 0
        for idx in _batches(len(yt), s.batch_size, rng):
            if cancel is not None:
                cancel.check()
            xb = torch.from_numpy(xt[idx]).to(device)
            yb = torch.from_numpy(yt[idx]).to(device)
            opt.zero_grad(set_to_none=True)
            if step is not None and raw_t is not None:
                loss, logits = step(xb, yb, loss_fn, raw=raw_t[torch.from_numpy(idx)])
            elif step is not None:
                loss, logits = step(xb, yb, loss_fn)
            else:
                logits = model(xb)
                loss = loss_fn(logits, yb)
            loss.backward()
            if clip > 0:
                nn.utils.clip_grad_norm_(model.parameters(), clip)
            opt.step()
            total += float(loss.detach()) * len(idx)
            correct += int((logits.argmax(1) == yb).sum())
            count += len(idx)
        if layout is not None:
            model.to(memory_format=torch.contiguous_format)
        val_loss, val_acc = _evaluate(model, xv, yv, device, max(s.batch_size, 64), raw_v)
        watch = val_loss if np.isfinite(val_loss) else total / count
        rec = {"epoch": epoch, "train_loss": total / count, "train_acc": correct / count,
               "val_loss": val_loss, "val_acc": val_acc,
               "seconds": time.perf_counter() - t0}
        history.append(rec)
        if watch < best_loss - 1e-6:
            best_loss, best_epoch, stale = watch, epoch, 0
            best_state = copy.deepcopy({k: v.detach().cpu() for k, v in model.state_dict().items()})
        else:
            stale += 1
        rec["best_epoch"] = best_epoch
        if on_epoch is not None:
            on_epoch(rec)
        if stale >= s.patience:
            break
    if best_state is None:  # the loss never became finite: keep the last weights
        best_state = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
        best_epoch = len(history)
    model.load_state_dict(best_state)
    return best_state, history, best_epoch


def save_weights(state: dict[str, torch.Tensor], path) -> None:
    """safetensors file of a state dict (contiguous, unshared copies)."""
    from safetensors.torch import save_file

    save_file({k: v.detach().cpu().contiguous().clone() for k, v in state.items()}, str(path))


def load_weights(model: nn.Module, path) -> nn.Module:
    """Load safetensors weights into ``model`` (no pickle involved)."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    try:
        model.load_state_dict(load_file(str(path)))
    except (OSError, RuntimeError, SafetensorError) as exc:  # missing, damaged, or not this model's
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise UserError(f"{path}: cannot load model weights ({first[:160]})") from None
    return model
