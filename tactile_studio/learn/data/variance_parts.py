"""How much of a touch statistic's spread is the person, the gesture, the person's way of
doing that gesture, and repetition (issue 45 item 5): the table the simulator is
calibrated against, for real recordings and simulated ones alike.

A person who presses everything harder is a *person* part; a Poke firmer than a Stroke
for everyone is a *gesture* part; one person's Poke firm and their Stroke light while
another's is the reverse is *person x gesture*; what changes between repetitions of one
person's gesture is *within*. Only the person x gesture part makes per-person
standardisation lose on people, so a simulator without it rewards the wrong models.

Method: unbalanced two-way random effects with interaction ("unweighted means"): the
within-cell variance pooled over person x gesture cells; a two-way ANOVA without
replication on the table of cell means with n~ = the cells' harmonic mean size:
E[MS_PG] = v_pg + s2/n~, E[MS_P] = E[MS_PG] + G v_p, E[MS_G] = E[MS_PG] + P v_g;
negative estimates are 0. Gestures not every person performed are left out. Positive
skewed statistics are taken as log(x + c), so their parts are relative spreads (comparable
between soft and hard pressers).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from tactile_studio.learn.data.touch_stats import trial_stats
from tactile_studio.sensor.gesture_metrics import dominant_frequency

STATS = ("peak_normal_p90", "taxels_above", "peak_shear_p90", "shear_normal",
         "contact_s", "dominant_hz")
LOG_OFFSET = {"peak_normal_p90": 0.1, "taxels_above": 0.5, "peak_shear_p90": 0.02,
              "shear_normal": 0.01}
PARTS = ("person", "gesture", "person_x_gesture", "within")
MIN_CONTACT = 0.1  # trials touched in under 10% of their frames say nothing of a touch


def stats_of(x: np.ndarray, channel_names: list[str], rate: float) -> dict[str, float]:
    """touch_stats.trial_stats of one trial plus contact time (s) and the dominant
    frequency of its total load (Hz)."""
    s = trial_stats(x, channel_names)
    load = np.clip(x[0], 0, None).sum(axis=(1, 2))
    return {**s, "contact_s": s["contact"] * x.shape[1] / rate,
            "dominant_hz": float(dominant_frequency(load, rate))}


def variance_parts(values: np.ndarray, person: np.ndarray, gesture: np.ndarray
                   ) -> dict[str, float]:
    """Variance of ``values`` split into :data:`PARTS` (absolute), plus ``P``, ``G``."""
    v, person, gesture = np.asarray(values, float), np.asarray(person), np.asarray(gesture)
    ps, gs = np.unique(person), np.unique(gesture)
    means = np.full((len(ps), len(gs)), np.nan)
    n = np.zeros_like(means)
    ss_e = df_e = 0.0
    for i, p in enumerate(ps):
        for j, g in enumerate(gs):
            c = v[(person == p) & (gesture == g)]
            if len(c):
                means[i, j], n[i, j] = c.mean(), len(c)
                ss_e += float(((c - c.mean()) ** 2).sum())
                df_e += len(c) - 1
    everyone = ~np.isnan(means).any(axis=0)
    means, n = means[:, everyone], n[:, everyone]
    p_, g_ = means.shape
    if p_ < 2 or g_ < 2:
        raise ValueError("variance parts need at least 2 people and 2 gestures in common")
    s2e = ss_e / max(df_e, 1.0)
    n_h = 1.0 / float(np.mean(1.0 / n))
    grand, rows, cols = means.mean(), means.mean(1), means.mean(0)
    ms_p = g_ * float(((rows - grand) ** 2).sum()) / (p_ - 1)
    ms_g = p_ * float(((cols - grand) ** 2).sum()) / (g_ - 1)
    resid = means - rows[:, None] - cols[None, :] + grand
    ms_pg = float((resid ** 2).sum()) / ((p_ - 1) * (g_ - 1))
    return {"person": max((ms_p - ms_pg) / g_, 0.0), "gesture": max((ms_g - ms_pg) / p_, 0.0),
            "person_x_gesture": max(ms_pg - s2e / n_h, 0.0), "within": s2e,
            "P": p_, "G": g_}


def parts_table(rows: Sequence[dict[str, float]], person: Iterable, gesture: Iterable
                ) -> dict[str, dict[str, float]]:
    """:func:`variance_parts` of every statistic in :data:`STATS` over trial ``rows``
    (from :func:`stats_of`), trials touched under :data:`MIN_CONTACT` left out; logs
    where :data:`LOG_OFFSET` says. Also ``_kept``: trials used / given."""
    person, gesture = np.asarray(list(person)), np.asarray(list(gesture))
    keep = np.array([r["contact"] >= MIN_CONTACT for r in rows], bool)
    out: dict[str, dict[str, float]] = {"_kept": {"kept": int(keep.sum()), "of": len(rows)}}
    for k in STATS:
        v = np.array([r[k] for r, ok in zip(rows, keep) if ok], float)
        if k in LOG_OFFSET:
            v = np.log(v + LOG_OFFSET[k])
        out[k] = variance_parts(v, person[keep], gesture[keep])
    return out


def shares(parts: dict[str, float]) -> dict[str, float]:
    """The parts as shares of their sum."""
    total = sum(parts[p] for p in PARTS) or 1.0
    return {p: parts[p] / total for p in PARTS}


def mean_parts(tables: Sequence[dict[str, dict[str, Any]]]) -> dict[str, dict[str, float]]:
    """Several populations' tables averaged part by part (variances, then SDs from them)."""
    return {k: {p: float(np.mean([t[k][p] for t in tables])) for p in PARTS} for k in STATS}
