"""Paired significance tests for comparing two runs, in numpy only.

* Wilcoxon signed-rank (two-sided, zero differences dropped): the exact null
  distribution when there are at most 50 non-zero differences and no ties, otherwise
  the normal approximation with the tie correction (no continuity correction) — the
  same choices as ``scipy.stats.wilcoxon(zero_method="wilcox")``.
* McNemar's exact test: a two-sided binomial test on the discordant pairs.
"""

from __future__ import annotations

import math

import numpy as np


def _rank(values: np.ndarray) -> np.ndarray:
    """Average ranks (1-based) with ties sharing the mean rank."""
    order = np.argsort(values, kind="mergesort")
    ranks = np.empty(len(values), dtype=np.float64)
    sorted_v = values[order]
    i = 0
    while i < len(values):
        j = i
        while j + 1 < len(values) and sorted_v[j + 1] == sorted_v[i]:
            j += 1
        ranks[order[i:j + 1]] = (i + j) / 2 + 1
        i = j + 1
    return ranks


def _exact_signed_rank_cdf(n: int, t: int) -> float:
    """P(T+ <= t) under H0 for n untied non-zero differences."""
    top = n * (n + 1) // 2
    counts = np.zeros(top + 1, dtype=np.float64)
    counts[0] = 1.0
    for k in range(1, n + 1):
        counts[k:] = counts[k:] + counts[:-k].copy()
    return float(counts[: t + 1].sum() / 2.0 ** n)


def wilcoxon_signed_rank(x: np.ndarray, y: np.ndarray) -> tuple[float, float, int]:
    """(statistic min(R+, R-), two-sided p, number of non-zero differences)."""
    d = np.asarray(x, dtype=np.float64) - np.asarray(y, dtype=np.float64)
    d = d[d != 0]
    n = len(d)
    if n == 0:
        return 0.0, 1.0, 0
    ranks = _rank(np.abs(d))
    r_plus, r_minus = float(ranks[d > 0].sum()), float(ranks[d < 0].sum())
    stat = min(r_plus, r_minus)
    ties = len(np.unique(np.abs(d))) < n
    if n <= 50 and not ties:
        p = 2.0 * _exact_signed_rank_cdf(n, int(round(stat)))
    else:
        mean = n * (n + 1) / 4.0
        _, t = np.unique(np.abs(d), return_counts=True)
        var = n * (n + 1) * (2 * n + 1) / 24.0 - float((t ** 3 - t).sum()) / 48.0
        z = (r_plus - mean) / math.sqrt(var) if var > 0 else 0.0
        p = math.erfc(abs(z) / math.sqrt(2.0))
    return stat, min(1.0, p), n


def mcnemar_exact(b: int, c: int) -> float:
    """Two-sided exact McNemar p from the discordant counts b (only A right), c (only B)."""
    n = b + c
    if n == 0:
        return 1.0
    k = min(b, c)
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2.0 ** n
    return min(1.0, 2.0 * tail)
