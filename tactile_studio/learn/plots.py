"""Run-folder figures with matplotlib's Agg backend (no display, no Qt)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=110)


def confusion_png(path: Path, labels: list[str], matrix: list[list[float]],
                  counts: list[list[int]] | None = None, title: str = "") -> None:
    """Row-normalised confusion matrix as percentages, true classes down the side.

    Sized from the number and length of the class names so 9-14 names stay readable.
    """
    m = np.asarray(matrix, dtype=float) * 100
    n = len(labels)
    longest = max((len(s) for s in labels), default=4)
    side = max(5.0, 0.55 * n + 0.09 * longest + 2.0)
    fig = _figure(side + 1.2, side)
    ax = fig.add_subplot(111)
    im = ax.imshow(m, cmap="Blues", vmin=0, vmax=100)
    ax.set_xticks(range(n))
    ax.set_yticks(range(n))
    ax.set_xticklabels(labels, rotation=40, ha="right", rotation_mode="anchor", fontsize=9)
    ax.set_yticklabels(labels, fontsize=9)
    ax.set_xlabel("predicted gesture")
    ax.set_ylabel("true gesture")
    fs = 9 if n <= 10 else 8
    for i in range(n):
        for j in range(n):
            if m[i, j] >= 0.5:
                ax.text(j, i, f"{m[i, j]:.0f}", ha="center", va="center", fontsize=fs,
                        color="white" if m[i, j] > 55 else "black")
    cbar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03)
    cbar.set_label("% of the true gesture's samples")
    if counts is not None:
        total = int(np.asarray(counts).sum())
        title = f"{title}\n(n = {total} test samples; row-normalised %)" if title else \
            f"n = {total} test samples; row-normalised %"
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)


def curves_png(path: Path, records: list[dict[str, Any]], title: str = "") -> None:
    """Loss and accuracy per epoch for every fold (train dashed, validation solid)."""
    fig = _figure(11, 4.4)
    ax_loss, ax_acc = fig.add_subplot(121), fig.add_subplot(122)
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    shown = [r for r in records if r.get("history")]
    for k, rec in enumerate(shown):
        h = rec["history"]
        ep = [e["epoch"] for e in h]
        color = cmap(k % 10)
        label = f"r{rec['round']} {rec['name']}"
        for ax, key in ((ax_loss, "loss"), (ax_acc, "acc")):
            ax.plot(ep, [e[f"train_{key}"] for e in h], "--", color=color, lw=1, alpha=0.7)
            val = [np.nan if e[f"val_{key}"] is None else e[f"val_{key}"] for e in h]
            ax.plot(ep, val, "-", color=color, lw=1.4, label=label)
            best = rec.get("best_epoch")
            if best and best <= len(val):
                ax.plot([best], [val[best - 1]], "o", color=color, ms=4)
    ax_loss.set_xlabel("epoch")
    ax_loss.set_ylabel("cross-entropy loss")
    ax_loss.set_title("loss (dashed: train, solid: validation, dot: best epoch)", fontsize=9)
    ax_acc.set_xlabel("epoch")
    ax_acc.set_ylabel("accuracy")
    ax_acc.set_ylim(0, 1.02)
    ax_acc.set_title("accuracy", fontsize=9)
    if len(shown) <= 12:
        ax_acc.legend(fontsize=7, loc="lower right", ncol=2 if len(shown) > 6 else 1)
    for ax in (ax_loss, ax_acc):
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
