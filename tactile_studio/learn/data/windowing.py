"""Long trials become windows: the unit a model learns from is at most one protocol trial.

An imported performance (~12 s) or a free-play segment is far longer than the trials the
models are designed for (the shear9 protocol's 2 s). Resampling 12 s into 86 frames would
blur every stroke, so a trial longer than ``long_factor`` x the window is cut into windows
of ``seconds`` (at the trial's own frame rate) overlapping by ``overlap``; shorter trials
stay whole (a 2.2 s trial is one window, not two nearly identical ones). Each window is
then given to the model's view exactly as a whole trial would be.

Every piece remembers the trial it came from, so splits stay at trial level (windows of
one trial never straddle train and test) and the trial's prediction aggregates its
windows (:func:`aggregate`: mean probability, or majority vote).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from tactile_studio.learn.choices import AGGREGATES
from tactile_studio.learn.data.views import window_starts

DEFAULT_WINDOW_S = 2.0


@dataclass(frozen=True)
class WindowSpec:
    seconds: float = DEFAULT_WINDOW_S
    overlap: float = 0.5       # share of a window shared with the next one
    long_factor: float = 1.5   # trials longer than this many windows are cut

    def frames(self, rate: float) -> int:
        return max(2, int(round(self.seconds * float(rate))))

    def stride(self, rate: float) -> int:
        return max(1, int(round(self.frames(rate) * (1.0 - self.overlap))))


def window_spec(seconds: float | None, overlap: float, ds_trial_s: float = 0.0) -> WindowSpec:
    """The spec for a dataset: ``seconds`` if given, else the protocol's trial length the
    sessions recorded, else 2 s."""
    return WindowSpec(seconds or ds_trial_s or DEFAULT_WINDOW_S, overlap)


def cut(ds, spec: WindowSpec):
    """(pieces dataset, piece -> trial index). Pieces share the trials' labels,
    participants and rates; a trial that is not long stays one piece (the same array)."""
    pieces, owner = [], []
    for i, (x, rate) in enumerate(zip(ds.trials, ds.rates)):
        n, w = x.shape[1], spec.frames(rate)
        if n > spec.long_factor * w:
            for s in window_starts(n, w, spec.stride(rate)):
                pieces.append(x[:, s:s + w])
                owner.append(i)
        else:
            pieces.append(x)
            owner.append(i)
    owner_arr = np.asarray(owner, dtype=np.int64)
    if len(pieces) == len(ds.trials):
        return ds, owner_arr
    return replace(ds, trials=pieces, labels=ds.labels[owner_arr],
                   participants=ds.participants[owner_arr],
                   uids=[f"{ds.uids[i]}@{k}" for k, i in enumerate(owner_arr)],
                   rates=ds.rates[owner_arr],
                   conditions=ds.trial_conditions()[owner_arr]), owner_arr


def learner_samples(learner, ds, spec: WindowSpec) -> tuple[np.ndarray, np.ndarray, int]:
    """A learner's samples over the windows of ``ds``: (X, owner trial index, pieces)."""
    pieces, piece_owner = cut(ds, spec)
    x, sample_piece = learner.samples(pieces)
    return x, piece_owner[sample_piece], len(pieces)


def vote(owner: np.ndarray, probs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trial-level predictions by majority vote over each trial's windows.

    Returns (trial ids in sorted order, predicted class per trial); a tie between classes
    goes to the one with the larger summed probability.
    """
    owner = np.asarray(owner)
    trials, inverse = np.unique(owner, return_inverse=True)
    n_classes = probs.shape[1]
    votes = np.zeros((len(trials), n_classes))
    np.add.at(votes, (inverse, probs.argmax(axis=1)), 1.0)
    mass = np.zeros((len(trials), n_classes))
    np.add.at(mass, inverse, probs)
    score = votes + 1e-6 * mass / np.maximum(mass.sum(axis=1, keepdims=True), 1e-12)
    return trials, score.argmax(axis=1)


def aggregate(owner: np.ndarray, probs: np.ndarray,
              how: str = "mean") -> tuple[np.ndarray, np.ndarray]:
    """Trial predictions from sample probabilities: (trial ids sorted, predicted class).

    ``mean`` averages each trial's probabilities (a confident window counts more);
    ``vote`` is the majority of window predictions (ties to the larger summed probability).
    """
    if how == "vote":
        return vote(owner, probs)
    if how != "mean":
        raise ValueError(f"unknown aggregate {how!r} (known: {', '.join(AGGREGATES)})")
    trials, inverse = np.unique(np.asarray(owner), return_inverse=True)
    mass = np.zeros((len(trials), probs.shape[1]))
    np.add.at(mass, inverse, probs)
    return trials, mass.argmax(axis=1)
