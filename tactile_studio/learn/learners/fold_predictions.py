"""A fold's predictions as code reads them: :class:`FoldPredictions`; the finished fold
that carries them: :class:`FoldRecord`.

In a fold record (in memory and in ``RUN/folds/*/fold.json``) the test and held-out
predictions stay the flat form every run folder has: ``{"owner": [...], "y_true": [...],
"probs": [[...]...]}`` (one row per sample: a window, or a whole trial). Code converts at
the edge with :meth:`FoldPredictions.from_dict` / :meth:`FoldPredictions.to_dict` instead
of indexing by string, so the keys are spelled here once and old runs load unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal, Required, TypedDict

import numpy as np


@dataclass(frozen=True, eq=False)
class FoldPredictions:
    """One row per test sample of a fold."""

    owner: np.ndarray   # (n,) int64: the dataset trial each sample comes from
    y_true: np.ndarray  # (n,) int64: its true class (index into the run's labels)
    probs: np.ndarray   # (n, classes): the model's probabilities, rounded as stored

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> FoldPredictions:
        """From the fold record's form (run_shapes.fold_problem checked its shape)."""
        y = np.asarray(d["y_true"], dtype=np.int64)
        probs = np.asarray(d["probs"], dtype=np.float64)
        if probs.ndim != 2:
            probs = probs.reshape(len(y), -1) if len(y) else np.zeros((0, 0))
        return cls(np.asarray(d["owner"], dtype=np.int64), y, probs)

    @classmethod
    def of_samples(cls, owner: np.ndarray, labels: np.ndarray,
                   probs: np.ndarray) -> FoldPredictions:
        """The predictions of samples ``owner`` (dataset trial indices) whose classes are
        ``labels[owner]``; probabilities rounded to 5 places, as fold.json keeps them."""
        owner = np.asarray(owner, dtype=np.int64)
        return cls(owner, np.asarray(labels, dtype=np.int64)[owner], np.round(probs, 5))

    def to_dict(self) -> dict[str, list[Any]]:
        """The fold record's form (plain lists, JSON as every run folder holds it)."""
        return {"owner": self.owner.tolist(), "y_true": self.y_true.tolist(),
                "probs": self.probs.tolist()}

    def __len__(self) -> int:
        return len(self.y_true)

    @property
    def y_pred(self) -> np.ndarray:
        """Each sample's most likely class."""
        if not len(self):
            return np.zeros(0, dtype=np.int64)
        return np.asarray(self.probs.argmax(axis=1), dtype=np.int64)

    def class_probs(self, n_classes: int) -> np.ndarray:
        """``probs`` as (n, n_classes) float64 (an empty fold included)."""
        return np.asarray(self.probs, dtype=np.float64).reshape(len(self), n_classes)


# the fold record's two sets of predictions: the test people's and the held-out people's
PredictionsKey = Literal["predictions", "heldout_predictions"]


class FoldRecord(TypedDict, total=False):
    """A finished fold as ``RUN/folds/*/fold.json`` holds it, and as the code passes it from
    training to the summary, the sweep, export and re-scoring: every key spelled here once
    and checked by mypy (run_shapes.fold_problem checks a stranger's file to these types).
    The predictions stay in their flat file form; read them with FoldPredictions."""

    round: Required[int]
    fold: Required[int]
    name: Required[str]                 # the fold's name (a LOPO fold: its participant)
    test: Required[list[str]]           # trial uids tested
    seed: int
    test_participants: list[str]
    train: list[str]
    val: list[str]
    heldout: list[str]
    shots: int                          # a few-shot fold's K
    norm: dict[str, Any]                # the input normalisation the model was trained with
    history: list[dict[str, Any]]       # one entry per epoch (networks)
    best_epoch: int | None
    predictions: dict[str, list[Any]]   # FoldPredictions.to_dict()
    heldout_predictions: dict[str, list[Any]]
    seconds: float
    fine_tuned_windows: int             # --shots-by fine-tune
    as_trained: list[list[float]]       # an adapted forest: the training people pooled
    model_sha256: dict[str, str]        # the fold's model files as saved
    version: str
    _dir: str                           # where it was read from (not in the file)
    _model: dict[str, bytes]            # a sweep task's model files, on their way to disk
