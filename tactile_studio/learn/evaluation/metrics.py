"""Classification metrics the papers report, computed from label arrays with numpy.

Conventions (the same as scikit-learn's defaults): macro precision, recall and F1 average
over the classes that occur in the true or the predicted labels, with 0 for a class that
is never predicted (precision) or never true (recall); balanced accuracy is the mean
recall over the classes that occur in the true labels; macro F1 is the mean of the
per-class F1 scores. The confusion matrix has true classes in rows; the row-normalised
matrix divides each row by its count (an empty row stays zero). Per-class accuracy is
the class's recall (None for a class with no test samples).
"""

from __future__ import annotations

from typing import Any

import numpy as np

SCALAR_KEYS = ("accuracy", "precision_macro", "recall_macro", "f1_macro",
               "balanced_accuracy", "kappa")


def confusion_counts(y_true: np.ndarray, y_pred: np.ndarray, n_classes: int) -> np.ndarray:
    cm = np.zeros((n_classes, n_classes), dtype=np.int64)
    np.add.at(cm, (np.asarray(y_true, dtype=np.int64), np.asarray(y_pred, dtype=np.int64)), 1)
    return cm


def metrics_from_counts(cm: np.ndarray, label_names: list[str]) -> dict[str, Any]:
    """Every metric from a confusion matrix of counts (rows true, columns predicted)."""
    cm = np.asarray(cm, dtype=np.float64)
    n = cm.sum()
    true_n, pred_n, tp = cm.sum(axis=1), cm.sum(axis=0), np.diag(cm)
    present = (true_n > 0) | (pred_n > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        precision = np.where(pred_n > 0, tp / pred_n, 0.0)
        recall = np.where(true_n > 0, tp / true_n, 0.0)
        f1 = np.where(precision + recall > 0, 2 * precision * recall / (precision + recall), 0.0)
    acc = float(tp.sum() / n) if n else 0.0
    pe = float((true_n * pred_n).sum() / (n * n)) if n else 0.0
    kappa = (acc - pe) / (1 - pe) if pe < 1 else (1.0 if acc == 1 else 0.0)
    rows = np.where(true_n[:, None] > 0, cm / np.maximum(true_n[:, None], 1), 0.0)
    return {
        "accuracy": acc,
        "precision_macro": float(precision[present].mean()) if present.any() else 0.0,
        "recall_macro": float(recall[present].mean()) if present.any() else 0.0,
        "f1_macro": float(f1[present].mean()) if present.any() else 0.0,
        "balanced_accuracy": float(recall[true_n > 0].mean()) if (true_n > 0).any() else 0.0,
        "kappa": float(kappa),
        "n": int(n),
        "labels": list(label_names),
        "confusion_matrix": rows.round(6).tolist(),
        "confusion_counts": cm.astype(np.int64).tolist(),
        "per_class_accuracy": {name: (float(recall[i]) if true_n[i] > 0 else None)
                               for i, name in enumerate(label_names)},
    }


def classification_metrics(y_true: np.ndarray, y_pred: np.ndarray,
                           label_names: list[str]) -> dict[str, Any]:
    """accuracy, precision_macro, recall_macro, f1_macro, balanced_accuracy, kappa,
    labels, confusion_matrix (row-normalised), confusion_counts, per_class_accuracy, n."""
    return metrics_from_counts(confusion_counts(y_true, y_pred, len(label_names)), label_names)


def median_of(dicts: list[dict[str, Any]], keys: tuple[str, ...] = SCALAR_KEYS) -> dict[str, float]:
    """Median of each scalar key over rounds (keys missing anywhere are skipped)."""
    out = {}
    for key in keys + ("trial_accuracy",):
        values = [d[key] for d in dicts if d.get(key) is not None]
        if values and len(values) == len(dicts):
            out[key] = float(np.median(values))
    return out
