"""Few-shot personalisation of a finished run's fold model with a new person's labelled
touches: live inference's form of ``train --shots K`` (splits.with_shots).

Offline, K labelled performances per gesture of the held-out person join the fold's
training. Live, the experimenter prompts the person for each gesture K times and each
prompt gives one labelled window of the model's window length; :func:`personalise` then

* rf / knn: refits the fold's model on its training windows (the run's data, read
  again through the dataset cache, exactly the fold's ``train`` trials) plus the
  person's windows: the offline mechanism, the same learner and options;
* a network: fine-tunes its output layers on the person's windows (the rest
  frozen, batch norm as trained), without the training data. A refit of a whole
  network on its training data plus a few windows takes minutes, which a participant
  waiting at the sensor does not have. Measured on a new virtual person (full cnn1d
  trained on 4 people, 27 test performances, 0.41 as trained): output layers K=1 0.52,
  K=2 0.70; every layer 0.48 / 0.67 and 1.5-3x slower; so the output layers.

The result is used by ``WindowModel.personalise`` until ``forget_personalisation``.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.sensor.decode import contact_taxels
from tactile_studio.sensor.layout import Layout

FINE_TUNE_STEPS = 150
FINE_TUNE_LR = 3e-3


@dataclass
class Personalised:
    fitted: Any                    # the refitted / fine-tuned model (predict_proba)
    norm: dict[str, Any]           # its input normalisation
    reference: np.ndarray | None   # the person's feature statistics (rf/knn --adapt runs)
    how: str                       # "refit" (rf/knn) or "fine-tuned" (a network's head)
    windows: int                   # labelled windows it rests on
    per_gesture: int               # the fewest labelled windows of a gesture (K)


def personalise(model: WindowModel, layout: Layout, windows: Sequence[np.ndarray],
                gestures: Sequence[str], rate: float, seed: int = 0,
                dataset: Any = None) -> Personalised:
    """``model``'s fold model personalised with decoded windows (C, N, R, X) of one
    person, labelled ``gestures`` (names of the run's gestures). ``dataset``: the run's
    TrialDataset when the caller has it (else read from the run's data paths)."""
    if len(windows) != len(gestures) or not len(windows):
        raise UserError("personalisation needs labelled windows: none were recorded")
    unknown = sorted(set(gestures) - set(model.labels))
    if unknown:
        raise UserError(f"{model.run}: the run has no gesture {', '.join(unknown)}")
    y_win = np.array([model.labels.index(g) for g in gestures], dtype=np.int64)
    per_gesture = int(min(np.bincount(y_win, minlength=len(model.labels))[np.unique(y_win)]))
    x_p, owner = model._samples(layout, list(windows), rate)
    y_p = y_win[owner]
    learner = model.learner
    reference = None
    if model.reads_person_features:  # the person's features standardised by their own
        from tactile_studio.learn.learners.fused import person_columns

        reference = person_columns(learner, x_p)
        x_p = learner.adapt_inputs(x_p, np.zeros(len(x_p)), reference)
    if learner.kind == "baseline":
        x_tr, y_tr = fold_training_samples(model, dataset)
        x_all, y_all = np.concatenate([x_tr, x_p]), np.concatenate([y_tr, y_p])
        stats = learner.norm_stats(x_all)
        fitted, _, _ = learner.fit(model.info, (learner.apply_norm(x_all, stats), y_all),
                                   (x_all[:0], y_all[:0]), seed, None, None, norm=stats)
        return Personalised(fitted, stats, reference, "refit", len(windows), per_gesture)
    if learner.kind != "torch":
        raise UserError(f"{model.run}: {model.config.model} (a fused model) cannot be "
                        "personalised yet; use its rf or network run")
    fitted = fine_tune_head(model.trained, learner.apply_norm(x_p, model.run_norm), y_p,
                            len(model.labels), seed)
    return Personalised(fitted, model.run_norm, None, "fine-tuned", len(windows),
                        per_gesture)


def fold_training_samples(model: WindowModel, dataset: Any = None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """The samples (and labels) the fold model was trained on: the run's data, made into
    model inputs as the run made them, of the fold's ``train`` trials."""
    from tactile_studio.learn.data.dataset import build_dataset
    from tactile_studio.learn.experiments.experiment import prepare_inputs

    cfg = model.config
    if dataset is None:
        try:
            dataset = build_dataset(cfg.data, cfg.grid, cfg.channels, cfg.cache_dir,
                                    cfg.use_cache)
        except UserError as exc:
            raise UserError(f"{model.run}: its training data cannot be read to refit "
                            f"with the person's touches ({exc})") from None
    elif cfg.channels not in (None, dataset.channels):
        dataset = dataset.select(cfg.channels)
    ds, x, owner, *_ = prepare_inputs(model.learner, dataset, cfg)
    wanted = set(model.record.get("train") or [])
    idx = np.array([i for i, u in enumerate(ds.uids) if u in wanted], dtype=np.int64)
    if len(idx) < len(wanted):
        raise UserError(f"{model.run}: its data changed since training ({len(wanted) - len(idx)}"
                        f" of the fold's {len(wanted)} training trials are gone from "
                        f"{', '.join(map(str, cfg.data))})")
    mask = np.isin(owner, idx)
    return x[mask], ds.labels[owner[mask]]


def fine_tune_head(fitted: Any, x: np.ndarray, y: np.ndarray, n_classes: int,
                   seed: int = 0, steps: int = FINE_TUNE_STEPS, lr: float = FINE_TUNE_LR
                   ) -> Any:
    """A copy of a network whose output layers (every linear or convolution layer with
    ``n_classes`` outputs: the network's own, its statistics head's, each ensemble
    member's) are trained further on normalised samples ``x`` labelled ``y``; everything
    else frozen, in eval mode (batch norm and dropout as trained)."""
    import torch

    from tactile_studio.learn.learners.families import TorchFitted

    torch.manual_seed(seed)
    net = copy.deepcopy(fitted.model).cpu()
    net.eval()
    kinds = (torch.nn.Linear, torch.nn.Conv1d, torch.nn.Conv2d, torch.nn.Conv3d)
    heads = [m for m in net.modules() if isinstance(m, kinds) and n_classes ==
             getattr(m, "out_features", getattr(m, "out_channels", None))]
    if not heads:
        raise UserError(f"the network has no output layer of {n_classes} classes to "
                        "fine-tune")
    for p in net.parameters():
        p.requires_grad_(False)
    params = [p for m in heads for p in m.parameters()]
    for p in params:
        p.requires_grad_(True)
    opt = torch.optim.Adam(params, lr=lr)
    xt = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))
    yt = torch.from_numpy(np.asarray(y, dtype=np.int64))
    for _ in range(steps):
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(net(xt).float(), yt)
        loss.backward()
        opt.step()
    for p in net.parameters():
        p.requires_grad_(False)
    return TorchFitted(net, "cpu")


class TouchPrompts:
    """The prompts of a live personalisation: "Perform <gesture> now" for every gesture
    of the run, K rounds, each answered by one labelled window of the model's window
    length taken from the live stream once the touch is there.

    :meth:`poll` watches the engine from the prompt on: the first frame in contact
    (``contact_taxels``) is the touch's onset; the window starts a quarter window before
    it (the approach, as a trial's window holds it) and is taken once complete, if the
    sensor was touched in ``contact_share`` of it. Skip leaves a prompt unanswered; Redo
    takes the last answered prompt again. Qt-free: the live panel's dialog drives it."""

    def __init__(self, model: WindowModel, k: int, contact_share: float = 0.05) -> None:
        if k < 1:
            raise UserError("personalisation needs at least one touch per gesture")
        self.model, self.k, self.contact_share = model, int(k), contact_share
        self.prompts = [g for _ in range(self.k) for g in model.labels]
        self.answers: dict[int, tuple[np.ndarray, float]] = {}  # prompt -> (window, rate)
        self.pos = 0
        self._cursor: int | None = None  # first frame not yet looked at
        self._onset: int | None = None
        self._order: list[int] = []  # answered prompts, oldest first

    @property
    def done(self) -> bool:
        return self.pos >= len(self.prompts)

    @property
    def gesture(self) -> str | None:
        """The gesture the person is asked for now (None when every prompt is past)."""
        return None if self.done else self.prompts[self.pos]

    @property
    def round(self) -> int:
        """1-based: which of the K performances of the gesture is asked for."""
        return min(self.pos, len(self.prompts) - 1) // len(self.model.labels) + 1

    @property
    def touching(self) -> bool:
        """A touch has begun since the prompt (its window is not complete yet)."""
        return self._onset is not None

    def begin(self, engine) -> None:
        """The current prompt is shown now: only frames from now on answer it."""
        self._cursor, self._onset = engine.frames, None

    def skip(self, engine) -> None:
        self.pos += 1
        self.begin(engine)

    def redo(self, engine) -> None:
        """Ask again for the last answered prompt (its window is dropped)."""
        if self._order:
            self.pos = self._order.pop()
            self.answers.pop(self.pos, None)
        self.begin(engine)

    def poll(self, engine) -> bool:
        """Looks at the frames since the last call; True when the current prompt was
        answered (then the next prompt begins)."""
        base = engine.baseline
        if self.done or base is None:
            return False
        if self._cursor is None:
            self.begin(engine)
        rate = engine.device_rate_hz() or engine.nominal_rate_hz
        w = self.model.window_for(rate)
        if self._onset is None:
            chunk = engine.read_since(self._cursor)
            if not len(chunk):
                return False
            touching = contact_taxels(engine.layout, chunk.raw, base).any(axis=(1, 2))
            self._cursor = chunk.stop
            if not touching.any():
                return False
            self._onset = max(chunk.start + int(np.argmax(touching)) - w // 4, chunk.start)
        if engine.frames < self._onset + w:
            return False
        chunk = engine.read_since(self._onset, w)
        if len(chunk) < w:  # overwritten in the ring meanwhile: wait for another touch
            self._cursor, self._onset = engine.frames, None
            return False
        touching = contact_taxels(engine.layout, chunk.raw, base).any(axis=(1, 2))
        if touching.mean() < self.contact_share:  # a brush, not the gesture
            self._cursor, self._onset = chunk.stop, None
            return False
        span = float(chunk.device_time[-1] - chunk.device_time[0])
        self.answers[self.pos] = (self.model.decode(engine.layout, chunk.raw, base),
                                  (w - 1) / span if span > 0 else rate)
        self._order.append(self.pos)
        self.pos += 1
        self.begin(engine)
        return True

    def labelled(self) -> tuple[list[np.ndarray], list[str], float]:
        """(windows, their gestures, rate) of the answered prompts."""
        keys = sorted(self.answers)
        rates = [self.answers[i][1] for i in keys]
        return ([self.answers[i][0] for i in keys], [self.prompts[i] for i in keys],
                float(np.median(rates)) if rates else 0.0)

    def personalise(self, layout: Layout, seed: int = 0) -> Personalised:
        windows, gestures, rate = self.labelled()
        return personalise(self.model, layout, windows, gestures, rate, seed)
