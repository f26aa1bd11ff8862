"""Figures of the individual-differences report (matplotlib, Agg, no window)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.learn.evaluation.plots import _figure


def effects_png(path: Path, effects: list[dict[str, Any]]) -> str:
    """Heatmap of partial eta² (metrics x factors)."""
    metrics = list(dict.fromkeys(r["metric"] for r in effects))
    factors = list(dict.fromkeys(r["factor"] for r in effects))
    m = np.full((len(metrics), len(factors)), np.nan)
    for r in effects:
        m[metrics.index(r["metric"]), factors.index(r["factor"])] = r["partial_eta2"]
    fig = _figure(2.6 + 1.6 * len(factors), 1.4 + 0.5 * len(metrics))
    ax = fig.add_subplot()
    im = ax.imshow(m, vmin=0, vmax=1, cmap="viridis", aspect="auto")
    ax.set_xticks(range(len(factors)), factors)
    ax.set_yticks(range(len(metrics)), metrics)
    for i in range(len(metrics)):
        for j in range(len(factors)):
            if np.isfinite(m[i, j]):
                ax.text(j, i, f"{m[i, j]:.2f}", ha="center", va="center",
                        color="white" if m[i, j] < 0.6 else "black")
    fig.colorbar(im, ax=ax, label="partial η²")
    ax.set_title("How much each factor explains (GLM)")
    # the figure lays itself out (constrained layout, see plots.figure)
    fig.savefig(path, dpi=110)
    return path.name


def balance_png(path: Path, balance: list[dict[str, Any]]) -> str:
    """Per-participant shear/normal balance: median with IQR bars."""
    fig = _figure(max(5.0, 1.5 + 0.6 * len(balance)), 3.8)
    ax = fig.add_subplot()
    x = np.arange(len(balance))
    med = np.array([b["median"] for b in balance])
    err = np.array([[b["median"] - b["q25"] for b in balance],
                    [b["q75"] - b["median"] for b in balance]])
    ax.bar(x, med, yerr=err, color="#4c72b0", capsize=3)
    ax.set_xticks(x, [b["participant"] for b in balance], rotation=45, ha="right")
    ax.set_ylabel("mean |shear| / mean normal")
    ax.set_title("Shear / normal balance per participant (median, IQR)")
    # the figure lays itself out (constrained layout, see plots.figure)
    fig.savefig(path, dpi=110)
    return path.name


def metrics_png(path: Path, rows: list[dict[str, Any]]) -> str:
    """Box plots of four metrics by gesture."""
    shown = ("mean_normal", "mean_abs_shear", "contact_area", "dominant_hz")
    gestures = sorted({r["gesture"] for r in rows})
    fig = _figure(12, 7.5)
    axes = fig.subplots(2, 2)
    for ax, metric in zip(np.ravel(axes), shown):
        data = [[r[metric] for r in rows if r["gesture"] == g and np.isfinite(r[metric])]
                for g in gestures]
        ax.boxplot(data, showfliers=False)
        ax.set_xticks(range(1, len(gestures) + 1), gestures, rotation=30, ha="right",
                      fontsize=8)
        ax.set_title(metric)
    # the figure lays itself out (constrained layout, see plots.figure)
    fig.savefig(path, dpi=100)
    return path.name
