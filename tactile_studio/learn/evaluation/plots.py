"""Run-folder figures with matplotlib's Agg backend (no display, no Qt).

Every figure is built by a ``*_figure`` function (so tests can read its text labels) and
saved by the matching ``*_png`` function. A percentage is never shown without the count it
was computed from: a row of one trial reading "100" would overstate what was measured.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.learn.learners.fold_predictions import FoldRecord

SUMMARY_FOLDS = 9  # from this many folds the curves become a median band + thin lines


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=110, layout="constrained")


def confusion_figure(labels: list[str], counts: list[list[int]], title: str = "",
                     unit: str = "samples"):
    """Confusion matrix of ``counts`` (true classes down the side), cells "pct% / count".

    Each row label carries the row total ("tap  n=12"), each non-empty cell its row
    percentage and its count, so a 100 % from one trial reads "100% / 1" beside "n=1".
    Sized from the number and length of the class names so 9-14 names stay readable.
    """
    c = np.asarray(counts, dtype=np.int64).reshape(len(labels), len(labels))
    totals = c.sum(axis=1)
    pct = np.where(totals[:, None] > 0, 100.0 * c / np.maximum(totals[:, None], 1), 0.0)
    n = len(labels)
    longest = max((len(s) for s in labels), default=4) + 6  # + "  n=123"
    side = max(5.0, 0.62 * n + 0.09 * longest + 2.2)
    fig = _figure(side + 1.2, side)
    ax = fig.add_subplot(111)
    shown = np.where(totals[:, None] > 0, pct, np.nan)  # an empty row stays blank, not 0 %
    im = ax.imshow(shown, cmap="Blues", vmin=0, vmax=100)
    ax.set_xticks(range(n))
    ax.set_yticks(range(n))
    ax.set_xticklabels(labels, rotation=40, ha="right", rotation_mode="anchor", fontsize=9)
    ax.set_yticklabels([f"{name}  n={int(t)}" for name, t in zip(labels, totals)], fontsize=9)
    ax.set_xlabel("predicted gesture")
    ax.set_ylabel("true gesture")
    fs = 8 if n <= 10 else 7
    for i in range(n):
        for j in range(n):
            if c[i, j] > 0:
                ax.text(j, i, f"{pct[i, j]:.0f}%\n{c[i, j]}/{totals[i]}", ha="center",
                        va="center", fontsize=fs, linespacing=1.1,
                        color="white" if pct[i, j] > 55 else "black")
        if totals[i] == 0:
            ax.text((n - 1) / 2, i, f"no test {unit}", ha="center", va="center", fontsize=fs,
                    color="0.4", style="italic")
    cbar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03)
    cbar.set_label(f"% of the true gesture's {unit}")
    head = (f"n = {int(c.sum())} test {unit} (row label: the gesture's n); "
            "cell: % of row, count/row total")
    ax.set_title(f"{title}\n{head}" if title else head, fontsize=10)
    return fig


def confusion_png(path: Path, labels: list[str], counts: list[list[int]], title: str = "",
                  unit: str = "samples") -> None:
    """Save :func:`confusion_figure` as a PNG."""
    confusion_figure(labels, counts, title, unit).savefig(path, bbox_inches="tight",
                                                          pad_inches=0.15)


def _padded(histories: list[list[dict[str, Any]]], key: str) -> np.ndarray:
    """(folds, max epochs) array of ``key`` per epoch, NaN past a fold's last epoch."""
    width = max(len(h) for h in histories)
    out = np.full((len(histories), width), np.nan)
    for k, h in enumerate(histories):
        for e in h:
            v = e.get(key)
            out[k, e["epoch"] - 1] = np.nan if v is None else v
    return out


def _band(ax, values: np.ndarray, color: str, label: str, style: str) -> None:
    """Median line and min-max band over folds, drawn for the epochs at least half the
    folds reached (a median of the one or two folds that trained longest would swing)."""
    ep = np.arange(1, values.shape[1] + 1)
    ok = (~np.isnan(values)).sum(axis=0) * 2 >= values.shape[0]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med, lo, hi = (np.nanmedian(values, axis=0), np.nanmin(values, axis=0),
                       np.nanmax(values, axis=0))
    ax.fill_between(ep[ok], lo[ok], hi[ok], color=color, alpha=0.18, lw=0,
                    label=f"{label} range")
    ax.plot(ep[ok], med[ok], style, color=color, lw=2.2, label=f"{label} median")


def curves_figure(records: list[FoldRecord], title: str = ""):
    """Loss and accuracy per epoch for every fold (train dashed, validation solid).

    Up to ``SUMMARY_FOLDS - 1`` folds get one colour each with the legend outside the axes;
    more folds are drawn as thin grey lines under a median line and a min-max band, so 10-20
    folds stay readable.
    """
    import matplotlib

    shown = [r for r in records if r.get("history")]
    summary = len(shown) >= SUMMARY_FOLDS
    fig = _figure(12.5, 4.6)
    ax_loss, ax_acc = fig.add_subplot(121), fig.add_subplot(122)
    cmap = matplotlib.colormaps["tab10"]
    for k, rec in enumerate(shown):
        h = rec["history"]
        ep = [e["epoch"] for e in h]
        color = "0.55" if summary else cmap(k % 10)
        lw, alpha = (0.6, 0.5) if summary else (1.4, 1.0)
        label = None if summary else f"r{rec['round']} {rec['name']}"
        for ax, key in ((ax_loss, "loss"), (ax_acc, "acc")):
            if not summary:
                ax.plot(ep, [e[f"train_{key}"] for e in h], "--", color=color, lw=1, alpha=0.7)
            val = [np.nan if e[f"val_{key}"] is None else e[f"val_{key}"] for e in h]
            ax.plot(ep, val, "-", color=color, lw=lw, alpha=alpha, label=label)
            best = rec.get("best_epoch")
            if best and best <= len(val) and not summary:
                ax.plot([best], [val[best - 1]], "o", color=color, ms=4)
    if summary:
        hs = [r["history"] for r in shown]
        for ax, key in ((ax_loss, "loss"), (ax_acc, "acc")):
            _band(ax, _padded(hs, f"train_{key}"), "tab:orange", "train", "--")
            _band(ax, _padded(hs, f"val_{key}"), "tab:blue", "validation", "-")
            ax.plot([], [], "-", color="0.55", lw=0.6,
                    label=f"one fold's validation (x{len(shown)})")
        what = (f"{len(shown)} folds: median and min-max band while at least half still "
                "train; thin lines: each fold")
    else:
        what = "dashed: train, solid: validation, dot: best epoch"
    ax_loss.set_xlabel("epoch")
    ax_loss.set_ylabel("cross-entropy loss")
    ax_loss.set_title("loss", fontsize=9)
    ax_acc.set_xlabel("epoch")
    ax_acc.set_ylabel("accuracy")
    ax_acc.set_ylim(0, 1.02)
    ax_acc.set_title("accuracy", fontsize=9)
    for ax in (ax_loss, ax_acc):
        ax.grid(alpha=0.3)
    if shown:
        ax_acc.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                      borderaxespad=0, title=None if summary else "fold")
    fig.suptitle(f"{title}\n{what}" if title else what, fontsize=10)
    return fig


def curves_png(path: Path, records: list[FoldRecord], title: str = "") -> None:
    """Save :func:`curves_figure` as a PNG."""
    curves_figure(records, title).savefig(path, bbox_inches="tight", pad_inches=0.15)
