"""Handcrafted trial features for the random-forest and k-NN baselines.

Two families, computed on one decoded trial ``(C, N, R, X)`` in physical units:

1. **Statistical / spectral** (the texture paper): each channel is reduced to per-frame
   summary signals (spatial mean and spatial max of normal; spatial mean of shear-x and
   shear-y and the mean and max of |shear|). Each signal gives mean, std, min, max, the
   10/25/50/75/90th percentiles, skewness, kurtosis, the share of spectral energy in four
   equal bands up to Nyquist, the dominant frequency and the spectral centroid (Hz).

2. **Gesture metrics** (the shear paper), see :func:`gesture_metrics`: mean normal
   stress, mean |shear|, contact area, dominant frequency and the movement type
   (transversal / convergent / divergent / static) with the quantities it is decided
   from.

3. **Touch and shear** (``touch=True``, the forest family's default since issue 45), see
   :mod:`touch_features`: 122 values appended after the 115 above.

Features depend only on the trial itself (no statistics across trials), so computing
them before splitting leaks nothing.
"""

from __future__ import annotations

import numpy as np

from tactile_studio.learn.data.touch_features import NAMES as TOUCH_NAMES
from tactile_studio.learn.data.touch_features import touch_features
from tactile_studio.sensor.gesture_metrics import (  # noqa: F401 - part of this API
    MOVEMENT_TYPES,
    SPECTRAL_NAMES,
    SPREAD_MIN_PITCH,
    SPREAD_THRESHOLD,
    TRAVEL_THRESHOLD,
    dominant_frequency,
    gesture_metrics,
)
from tactile_studio.sensor.gesture_metrics import spectral_summary as _spectral

_STATS = ("mean", "std", "min", "max", "p10", "p25", "p50", "p75", "p90", "skew", "kurtosis")
_SPECTRAL = SPECTRAL_NAMES


def _stats(sigs: np.ndarray) -> np.ndarray:
    """(k, n) signals -> (k, 11) statistics (``_STATS``), all signals at once (live
    inference computes these for every window: one pass instead of one per signal)."""
    mean, std = sigs.mean(axis=1), sigs.std(axis=1)
    ok = std > 1e-12
    z = np.where(ok[:, None], (sigs - mean[:, None]) / np.where(ok, std, 1)[:, None], 0)
    p = np.percentile(sigs, [10, 25, 50, 75, 90], axis=1)
    z3 = z ** 3
    return np.column_stack([mean, std, sigs.min(axis=1), sigs.max(axis=1), *p,
                            z3.mean(axis=1), np.where(ok, (z3 * z).mean(axis=1) - 3.0, 0.0)])


def _signals(x: np.ndarray, channel_names: list[str]) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    ch = {name: x[i] for i, name in enumerate(channel_names)}
    normal = ch.get("normal", ch.get("pressure"))
    if normal is not None:
        out["normal_mean"] = normal.mean(axis=(1, 2))
        out["normal_max"] = normal.max(axis=(1, 2))
    if "shear_x" in ch and "shear_y" in ch:
        mag = np.hypot(ch["shear_x"], ch["shear_y"])
        out["shear_x_mean"] = ch["shear_x"].mean(axis=(1, 2))
        out["shear_y_mean"] = ch["shear_y"].mean(axis=(1, 2))
        out["shear_mag_mean"] = mag.mean(axis=(1, 2))
        out["shear_mag_max"] = mag.max(axis=(1, 2))
    return out


def trial_features(x: np.ndarray, channel_names: list[str], rate: float,
                   cell_pitch: float = 1.0, touch: bool = False
                   ) -> tuple[np.ndarray, list[str]]:
    """The feature vector of one trial and the feature names (``touch``: the touch and
    shear features appended, in the first 115's order so a model of the 115 reads the
    first columns). The rate is read to a micro-hertz: a trial's own rate and its
    session's differ in the 13th digit, and a forest's float32 thresholds can fall
    between the two readings of a rate-scaled feature (the live model then answered a
    window otherwise than the evaluated one)."""
    rate = round(float(rate), 6)
    values: list[float] = []
    names: list[str] = []
    signals = _signals(x, channel_names)
    stats = _stats(np.stack(list(signals.values()))) if signals else []
    for (sig_name, sig), row in zip(signals.items(), stats):
        values += [*map(float, row), *_spectral(sig, rate)]
        names += [f"{sig_name}_{s}" for s in _STATS + _SPECTRAL]
    metrics = gesture_metrics(x, channel_names, rate, cell_pitch)
    movement = metrics.pop("movement")
    for key, value in metrics.items():
        values.append(float(value))
        names.append(f"gesture_{key}")
    for m in MOVEMENT_TYPES:
        values.append(1.0 if movement == m else 0.0)
        names.append(f"movement_{m}")
    out = np.nan_to_num(np.array(values, dtype=np.float64))
    if touch:
        out = np.concatenate([out, touch_features(x, channel_names, rate)])
        names += list(TOUCH_NAMES)
    return out, names


def feature_matrix(trials: list[np.ndarray], channel_names: list[str], rates: np.ndarray,
                   cell_pitch: float = 1.0, touch: bool = False
                   ) -> tuple[np.ndarray, list[str]]:
    """(n_trials, n_features) for a list of trials, plus the feature names."""
    rows, names = [], []
    for x, rate in zip(trials, rates):
        row, names = trial_features(x, channel_names, float(rate), cell_pitch, touch)
        rows.append(row)
    return np.vstack(rows), names
