"""Run-folder figures: every percentage carries its count and row total; many folds stay
readable (summary band, legend outside the axes)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from tactile_studio.learn.evaluation import plots

LABELS = ["grab", "hit", "massage", "pat", "pinch", "poke", "press", "rub", "scratch",
          "slap", "stroke", "squeeze", "tap", "tickle"]


def _counts(n: int) -> np.ndarray:
    rng = np.random.default_rng(1)
    cm = rng.integers(0, 4, size=(n, n)) + np.diag(rng.integers(5, 20, size=n))
    cm[1] = 0
    cm[1, 1] = 1  # a row of one trial
    cm[2] = 0  # a row with no trial
    return cm


def _texts(ax) -> list[str]:
    return [t.get_text() for t in ax.texts]


@pytest.mark.parametrize("n", [9, 14])
def test_confusion_cells_show_percent_count_and_row_total(n):
    cm = _counts(n)
    fig = plots.confusion_figure(LABELS[:n], cm.tolist(), "run", "trials")
    ax = fig.axes[0]
    texts = _texts(ax)
    rows = ax.get_yticklabels()
    for i in range(n):
        total = int(cm[i].sum())
        assert rows[i].get_text() == f"{LABELS[i]}  n={total}"
        for j in range(n):
            if cm[i, j]:
                pct = 100 * cm[i, j] / total
                assert f"{pct:.0f}%\n{cm[i, j]}/{total}" in texts
    assert "100%\n1/1" in texts  # the one-trial row says it is one trial
    assert "no test trials" in texts  # the empty row says so instead of showing 0 %
    assert sum("%" in t for t in texts) == int((cm > 0).sum())  # no cell without a count
    assert f"n = {int(cm.sum())} test trials" in ax.get_title()


def _records(n_folds: int) -> list[dict]:
    rng = np.random.default_rng(n_folds)
    out = []
    for k in range(n_folds):
        epochs = int(rng.integers(5, 12))
        hist = [{"epoch": e, "train_loss": 2.0 / e, "val_loss": 2.2 / e,
                 "train_acc": 1 - 1 / (e + 1), "val_acc": float(rng.uniform(0.3, 0.8))}
                for e in range(1, epochs + 1)]
        out.append({"round": 0, "name": f"P{k + 1:02d}", "history": hist, "best_epoch": 2})
    return out


def _legend_outside(fig, ax) -> bool:
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.canvas.draw()
    return ax.get_legend().get_window_extent(renderer).x0 >= ax.get_window_extent(renderer).x1


def test_few_folds_one_line_each_with_legend_outside():
    fig = plots.curves_figure(_records(4), "run")
    ax_acc = fig.axes[1]
    names = [t.get_text() for t in ax_acc.get_legend().get_texts()]
    assert names == [f"r0 P{k:02d}" for k in range(1, 5)]
    assert _legend_outside(fig, ax_acc)


@pytest.mark.parametrize("n_folds", [10, 20])
def test_many_folds_become_a_median_band(n_folds):
    recs = _records(n_folds)
    fig = plots.curves_figure(recs, "run")
    ax_acc = fig.axes[1]
    names = [t.get_text() for t in ax_acc.get_legend().get_texts()]
    assert "validation median" in names and "validation range" in names
    assert f"one fold's validation (x{n_folds})" in names
    assert len(names) <= 6  # a short legend, not one entry per fold
    assert _legend_outside(fig, ax_acc)
    # the median line is the median of the folds' validation accuracy at each epoch
    median = next(line for line in ax_acc.get_lines() if line.get_label() == "validation median")
    ep1 = np.median([r["history"][0]["val_acc"] for r in recs])
    assert median.get_ydata()[0] == pytest.approx(ep1)
    # drawn only while at least half the folds still train
    reached = [len(r["history"]) for r in recs]
    assert len(median.get_xdata()) == sum(1 for e in range(1, max(reached) + 1)
                                           if 2 * sum(n >= e for n in reached) >= n_folds)
