"""Regenerate confusion-matrix.png and training-curves-*-folds.png from synthetic metrics.

The counts and histories are drawn from a seeded generator shaped like a real COST-style
run (14 gestures, uneven rows, one gesture with a single test trial, one with none), so
the figures show the cases that used to mislead: a row of one trial, an empty row, and
20 leave-one-participant-out folds that stop at different epochs.

    .venv/bin/python tools/screenshots/make_learning_figures.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = (Path(__file__).resolve().parents[2] / "docs" / "screenshots")
GESTURES = ["grab", "hit", "massage", "pat", "pinch", "poke", "press", "rub", "scratch",
            "slap", "stroke", "squeeze", "tap", "tickle"]


def synthetic_counts(n_classes: int, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    cm = np.zeros((n_classes, n_classes), dtype=np.int64)
    for i in range(n_classes):
        n = int(rng.integers(8, 40))
        p = np.full(n_classes, 0.25 / (n_classes - 1))
        p[i] = 0.75
        cm[i] = rng.multinomial(n, p / p.sum())
    cm[3] = 0
    cm[3, 3] = 1  # a gesture with one test trial: 100 % of 1
    cm[9] = 0  # a gesture with no test trial
    return cm


def synthetic_records(n_folds: int, seed: int = 4) -> list[dict]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n_folds):
        epochs = int(rng.integers(18, 31))
        rate, ceiling = rng.uniform(0.1, 0.25), rng.uniform(0.55, 0.9)
        hist = []
        for e in range(1, epochs + 1):
            tr = 0.95 * (1 - np.exp(-rate * 1.4 * e)) + rng.normal(0, 0.01)
            va = ceiling * (1 - np.exp(-rate * e)) + rng.normal(0, 0.03)
            hist.append({"epoch": e, "train_acc": float(np.clip(tr, 0, 1)),
                         "val_acc": float(np.clip(va, 0, 1)),
                         "train_loss": float(2.6 * np.exp(-rate * 1.4 * e) + 0.05),
                         "val_loss": float(2.6 * np.exp(-rate * e) + 0.6 - 0.5 * ceiling
                                           + rng.normal(0, 0.05))})
        best = int(np.argmax([h["val_acc"] for h in hist])) + 1
        out.append({"round": 0, "name": f"P{k + 1:02d}", "history": hist, "best_epoch": best})
    return out


def main() -> int:
    from tactile_studio.learn.evaluation import plots

    cm = synthetic_counts(len(GESTURES))
    plots.confusion_png(HERE / "confusion-matrix.png", GESTURES, cm.tolist(),
                        "cnn_transformer, lopo (synthetic counts)", "trials")
    for n in (6, 20):
        plots.curves_png(HERE / f"training-curves-{n}-folds.png", synthetic_records(n),
                         f"cnn_transformer, lopo, {n} folds (synthetic histories)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
