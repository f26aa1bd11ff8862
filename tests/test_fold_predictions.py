"""FoldPredictions: the fold record's predictions read typed, written in the exact form
every run folder holds (so old runs load and new ones are byte for byte as before)."""

from __future__ import annotations

import json

import numpy as np

from tactile_studio.learn.evaluation.summary import fold_metrics
from tactile_studio.learn.learners.fold_predictions import FoldPredictions


def _as_before(owner: np.ndarray, labels: np.ndarray, probs: np.ndarray) -> dict:
    """What experiment._predictions wrote before the class existed."""
    return {"owner": owner.tolist(), "y_true": labels[owner].tolist(),
            "probs": np.round(probs, 5).tolist()}


def test_new_predictions_are_written_exactly_as_before_and_read_back() -> None:
    rng = np.random.default_rng(4)
    probs = rng.dirichlet(np.ones(3), size=7).astype(np.float32)
    owner, labels = np.array([0, 0, 2, 3, 3, 5, 6]), np.array([2, 0, 1, 1, 0, 2, 0, 1])
    p = FoldPredictions.of_samples(owner, labels, probs)
    before = _as_before(owner, labels, probs)
    assert json.dumps(p.to_dict()) == json.dumps(before)
    back = FoldPredictions.from_dict(json.loads(json.dumps(before)))  # an old fold.json
    assert json.dumps(back.to_dict()) == json.dumps(before)
    assert back.y_true.tolist() == [2, 2, 1, 1, 1, 2, 0] and len(back) == 7
    assert back.y_pred.tolist() == np.asarray(before["probs"]).argmax(axis=1).tolist()


def test_an_empty_fold_reads_and_scores() -> None:
    p = FoldPredictions.from_dict({"owner": [], "y_true": [], "probs": []})
    assert len(p) == 0 and p.y_pred.tolist() == [] and p.class_probs(2).shape == (0, 2)
    assert p.to_dict() == {"owner": [], "y_true": [], "probs": []}
    rec = {"predictions": {"owner": [0, 1], "y_true": [1, 0], "probs": [[0.2, 0.8],
                                                                          [0.4, 0.6]]}}
    assert fold_metrics(rec, ["a", "b"], windowed=False)["accuracy"] == 0.5
