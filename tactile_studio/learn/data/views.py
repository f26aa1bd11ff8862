"""Views: fixed-size model inputs from trials of any length (10 to thousands of frames).

Every function takes one trial ``x`` of shape ``(C, N, R, X)`` and works for any
``N >= 1``:

* :func:`resample` — the whole trial linearly resampled to ``T`` frames (the shear
  paper's 86 frames of 2 s).
* :func:`sliding_windows` — windows ``length`` frames long every ``stride`` frames, plus
  one window aligned to the end when the stride leaves the tail uncovered. A trial
  shorter than one window gives exactly one window: the trial followed by zero frames
  (zero = no load, since decoded stress is baseline-relative) — padding rather than
  stretching keeps the time scale the model was trained on.
* :func:`moving_average_slices` — ``n`` slices, each the mean over a span of
  ``2N/(n+1)`` frames, consecutive spans overlapping by 50% (the touch-modalities
  paper). With fewer than ``n + 1`` frames a span rounds to one or two frames, which
  amounts to resampling.
* :func:`gradient_sample` — gradient-adaptive sampling: ``n`` frames chosen so that each
  covers an equal share of the cumulative absolute frame difference (frames are dense
  where the touch changes fast, sparse where it is still); a perfectly still trial falls
  back to uniform sampling. Frames may repeat when ``N < n``.

:func:`make_samples` applies a model's ``ViewSpec`` to many trials and remembers which
trial every sample came from, so splits stay at trial level.
"""

from __future__ import annotations

import numpy as np

VIEW_KINDS = ("resample", "windows", "slices", "gradient")


def resample(x: np.ndarray, frames: int) -> np.ndarray:
    """(C, N, R, X) -> (C, frames, R, X) by linear interpolation in time."""
    n = x.shape[1]
    if n == 1:
        return np.repeat(x, frames, axis=1)
    pos = np.linspace(0.0, n - 1, frames)
    i0 = np.floor(pos).astype(np.int64)
    i1 = np.minimum(i0 + 1, n - 1)
    w = (pos - i0).astype(x.dtype)[None, :, None, None]
    return x[:, i0] * (1 - w) + x[:, i1] * w


def window_starts(n: int, length: int, stride: int) -> np.ndarray:
    """Start frames of the windows of a trial ``n`` frames long (see module doc)."""
    if n <= length:
        return np.zeros(1, dtype=np.int64)
    starts = np.arange(0, n - length + 1, max(1, stride))
    if starts[-1] + length < n:
        starts = np.append(starts, n - length)
    return starts.astype(np.int64)


def sliding_windows(x: np.ndarray, length: int, stride: int) -> np.ndarray:
    """(C, N, R, X) -> (K, C, length, R, X)."""
    c, n, r, cols = x.shape
    if n < length:
        pad = np.zeros((c, length - n, r, cols), dtype=x.dtype)
        return np.concatenate([x, pad], axis=1)[None]
    return np.stack([x[:, s:s + length] for s in window_starts(n, length, stride)])


def moving_average_slices(x: np.ndarray, n_slices: int) -> np.ndarray:
    """(C, N, R, X) -> (C, n_slices, R, X): means over spans overlapping by 50%."""
    n = x.shape[1]
    half = n / (n_slices + 1)
    starts = np.floor(np.arange(n_slices) * half).astype(np.int64)
    stops = np.ceil((np.arange(n_slices) + 2) * half).astype(np.int64)
    starts = np.clip(starts, 0, n - 1)
    stops = np.clip(np.maximum(stops, starts + 1), 1, n)
    cs = np.concatenate([np.zeros_like(x[:, :1], dtype=np.float64),
                         np.cumsum(x, axis=1, dtype=np.float64)], axis=1)
    sums = cs[:, stops] - cs[:, starts]
    return (sums / (stops - starts)[None, :, None, None]).astype(x.dtype)


def gradient_indices(x: np.ndarray, n: int) -> np.ndarray:
    """The ``n`` frame indices of gradient-adaptive sampling (sorted, may repeat)."""
    length = x.shape[1]
    if length == 1:
        return np.zeros(n, dtype=np.int64)
    diff = np.abs(np.diff(x, axis=1)).sum(axis=(0, 2, 3), dtype=np.float64)
    cum = np.concatenate([[0.0], np.cumsum(diff)])
    total = cum[-1]
    if not np.isfinite(total) or total <= 1e-12:
        return np.round(np.linspace(0, length - 1, n)).astype(np.int64)
    targets = (np.arange(n) + 0.5) / n * total
    return np.clip(np.searchsorted(cum, targets, side="left"), 0, length - 1).astype(np.int64)


def gradient_sample(x: np.ndarray, n: int) -> np.ndarray:
    """(C, N, R, X) -> (C, n, R, X) frames picked by :func:`gradient_indices`."""
    return x[:, gradient_indices(x, n)]


def trial_view(x: np.ndarray, kind: str, frames: int, stride: int = 0) -> np.ndarray:
    """One trial -> (K, C, T, R, X) samples (K = 1 except for windows)."""
    if kind == "resample":
        return resample(x, frames)[None]
    if kind == "windows":
        return sliding_windows(x, frames, stride or max(1, frames // 3))
    if kind == "slices":
        return moving_average_slices(x, frames)[None]
    if kind == "gradient":
        return gradient_sample(x, frames)[None]
    raise ValueError(f"unknown view kind {kind!r} (known: {', '.join(VIEW_KINDS)})")


def make_samples(trials: list[np.ndarray], kind: str, frames: int,
                 stride: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Samples of many trials: ``X`` (S, C, T, R, X) float32 and ``owner`` (S,), the
    position in ``trials`` each sample came from."""
    parts = [trial_view(t, kind, frames, stride) for t in trials]
    owner = np.concatenate([np.full(len(p), i, dtype=np.int64) for i, p in enumerate(parts)])
    return np.concatenate(parts).astype(np.float32, copy=False), owner


def channel_stats(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel mean and std of samples ``(S, C, ...)`` (std floored to avoid /0)."""
    axes = (0,) + tuple(range(2, x.ndim))
    mean = x.mean(axis=axes, dtype=np.float64)
    std = x.std(axis=axes, dtype=np.float64)
    return mean.astype(np.float32), np.where(std < 1e-8, 1.0, std).astype(np.float32)


def normalise(x: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """z-score samples ``(S, C, ...)`` with per-channel statistics."""
    shape = (1, -1) + (1,) * (x.ndim - 2)
    return ((x - mean.reshape(shape)) / std.reshape(shape)).astype(np.float32)
