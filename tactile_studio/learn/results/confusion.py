"""The confusion matrix a researcher explores: counts or shares, ordered by confusion,
per-class precision / recall / F1, filtered by participant or condition, and the trials
behind each cell. Views (GUI, CSV) only present what this model computes.

A few-shot run (``train --shots``) tests each trial once per K: the model shows one K at
a time (``shots``, the smallest by default), never the K mixed.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass, field

import numpy as np

from tactile_studio.learn.results.trialpreds import TrialPrediction

MODES = ("counts", "row", "column")  # row % = share of the true gesture, column % = of predicted


@dataclass
class ConfusionModel:
    labels: list[str]
    trials: list[TrialPrediction]
    participant: str | None = None
    condition: str | None = None
    order: list[int] = field(default_factory=list)  # display order of label indices
    shots: int | None = None  # a few-shot run's K shown (None: the smallest it has)

    def __post_init__(self) -> None:
        if not self.order:
            self.order = list(range(len(self.labels)))
        if self.shots is None and self.shot_counts:
            self.shots = self.shot_counts[0]

    # --- selection -------------------------------------------------------------------------
    @property
    def shot_counts(self) -> list[int]:
        """The K of a few-shot run's folds, sorted ([] for other runs)."""
        return sorted({t.shots for t in self.trials if t.shots is not None})

    def set_shots(self, k: int) -> None:
        if k not in self.shot_counts:
            raise ValueError(f"K={k} not in the run's {self.shot_counts}")
        self.shots = k

    @property
    def participants(self) -> list[str]:
        return sorted({t.participant for t in self.trials})

    @property
    def conditions(self) -> list[str]:
        return sorted({t.condition for t in self.trials if t.condition})

    def selected(self) -> list[TrialPrediction]:
        return [t for t in self.trials
                if (self.shots is None or t.shots == self.shots)
                and (self.participant is None or t.participant == self.participant)
                and (self.condition is None or t.condition == self.condition)]

    def set_filter(self, participant: str | None = None, condition: str | None = None) -> None:
        self.participant, self.condition = participant or None, condition or None

    # --- numbers ---------------------------------------------------------------------------
    def counts(self) -> np.ndarray:
        """Counts in label order (rows true, columns predicted)."""
        n = len(self.labels)
        cm = np.zeros((n, n), dtype=np.int64)
        for t in self.selected():
            cm[t.true, t.pred] += 1
        return cm

    def matrix(self, mode: str = "counts") -> np.ndarray:
        """The displayed matrix in display order: counts, row shares or column shares (0..1)."""
        if mode not in MODES:
            raise ValueError(f"mode {mode!r} not in {MODES}")
        cm = self.counts()[np.ix_(self.order, self.order)].astype(np.float64)
        if mode == "row":
            cm = cm / np.maximum(cm.sum(axis=1, keepdims=True), 1)
        elif mode == "column":
            cm = cm / np.maximum(cm.sum(axis=0, keepdims=True), 1)
        return cm

    def ordered_labels(self) -> list[str]:
        return [self.labels[i] for i in self.order]

    def per_class(self) -> dict[str, np.ndarray]:
        """precision, recall, f1 and support per class, in display order."""
        cm = self.counts().astype(np.float64)
        tp, pred_n, true_n = np.diag(cm), cm.sum(axis=0), cm.sum(axis=1)
        precision = np.divide(tp, pred_n, out=np.zeros_like(tp), where=pred_n > 0)
        recall = np.divide(tp, true_n, out=np.zeros_like(tp), where=true_n > 0)
        denom = precision + recall
        f1 = np.divide(2 * precision * recall, denom, out=np.zeros_like(tp), where=denom > 0)
        o = self.order
        return {"precision": precision[o], "recall": recall[o], "f1": f1[o],
                "support": true_n[o].astype(np.int64)}

    def accuracy(self) -> float:
        cm = self.counts()
        return float(np.trace(cm) / cm.sum()) if cm.sum() else 0.0

    def cell_info(self, row: int, col: int) -> tuple[int, float, float]:
        """(count, share of the true gesture, share of the predicted) of a display cell."""
        counts = self.matrix("counts")
        return (int(counts[row, col]), float(self.matrix("row")[row, col]),
                float(self.matrix("column")[row, col]))

    def cell_trials(self, row: int, col: int) -> list[TrialPrediction]:
        """The trials behind a display cell, least confident first."""
        true, pred = self.order[row], self.order[col]
        found = [t for t in self.selected() if t.true == true and t.pred == pred]
        return sorted(found, key=lambda t: (t.confidence, t.participant, t.trial))

    # --- ordering --------------------------------------------------------------------------
    def order_by_confusion(self) -> list[int]:
        """Put gestures that are confused with each other next to each other.

        Greedy agglomerative chaining on the symmetric confusion (row shares of both
        directions): the most-confused pair starts a chain, and chains join end to end at
        their most-confused ends, so clusters of confused gestures form blocks along the
        diagonal.
        """
        n = len(self.labels)
        rows = self.counts().astype(np.float64)
        rows = rows / np.maximum(rows.sum(axis=1, keepdims=True), 1)
        sim = rows + rows.T
        np.fill_diagonal(sim, -1.0)
        chains: list[list[int]] = [[i] for i in range(n)]
        while len(chains) > 1:
            best = (-2.0, 0, 0, False, False)
            for a in range(len(chains)):
                for b in range(a + 1, len(chains)):
                    for ra in (False, True):
                        for rb in (False, True):
                            ea = chains[a][0] if ra else chains[a][-1]
                            eb = chains[b][-1] if rb else chains[b][0]
                            if sim[ea, eb] > best[0]:
                                best = (sim[ea, eb], a, b, ra, rb)
            _, a, b, ra, rb = best
            left = chains[a][::-1] if ra else chains[a]
            right = chains[b][::-1] if rb else chains[b]
            chains[a] = left + right
            del chains[b]
        self.order = chains[0] if chains else []
        return self.order

    def reset_order(self) -> None:
        self.order = list(range(len(self.labels)))

    # --- export ----------------------------------------------------------------------------
    def write_csv(self, path: str | os.PathLike, mode: str = "counts") -> None:
        """The displayed matrix with precision/recall/F1 columns."""
        m, pc = self.matrix(mode), self.per_class()
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["true \\ predicted", *self.ordered_labels(), "precision", "recall", "f1",
                        "support"])
            for i, name in enumerate(self.ordered_labels()):
                cells = [str(int(v)) if mode == "counts" else f"{v:.4f}" for v in m[i]]
                w.writerow([name, *cells, f"{pc['precision'][i]:.4f}", f"{pc['recall'][i]:.4f}",
                            f"{pc['f1'][i]:.4f}", int(pc["support"][i])])
