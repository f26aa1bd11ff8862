"""Augmentation that respects the sensor's geometry, on decoded trials ``(C, N, R, X)``.

Axes (see ``sensor/layout.py``): ``x`` grows with the column index, ``y`` with the row
index, and decoded ``shear_x`` / ``shear_y`` point the way the skin is dragged along
them (``decode`` applies the layout's shear signs). So a mirror image of a touch is the
grid mirrored *and* the shear component across the mirror negated; swapping rows and
columns (a transpose, the diagonal mirror) swaps ``shear_x`` and ``shear_y``; a 90°
rotation is a transpose then a mirror. Together they give the 8 symmetries of a square
grid (transposes only on square grids). Also:

* translations by whole cells (what slides off the grid is lost; new cells read 0 kPa,
  i.e. no load, since decoded stress is baseline-relative);
* time warping — the trial resampled to 0.8-1.25x its length (slower or faster tempo at
  the same frame rate);
* amplitude scaling — every channel x a log-normal factor (harder or softer touch), and
  the shear channels x a second one (people differ in how much they drag).

Used for training data only (:func:`augment_trials`), with a generator seeded per fold.
"""

from __future__ import annotations

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.data.views import resample

KINDS = ("flip", "rotate", "shift", "warp", "scale")


def parse_kinds(spec: str | None) -> tuple[str, ...]:
    """``"flip,shift"`` / ``"all"`` / ``""`` -> the augmentation kinds (UserError if unknown)."""
    if not spec or spec == "none":
        return ()
    kinds = KINDS if spec == "all" else tuple(k.strip() for k in spec.split(",") if k.strip())
    bad = [k for k in kinds if k not in KINDS]
    if bad:
        raise UserError(f"unknown augmentation {bad[0]!r} (available: {', '.join(KINDS)}, all)")
    return kinds


def _index(channel_names: list[str], name: str) -> int | None:
    return channel_names.index(name) if name in channel_names else None


def mirror(x: np.ndarray, channel_names: list[str], axis: str) -> np.ndarray:
    """Mirror left-right (``axis="x"``: columns reversed, shear_x negated) or top-bottom
    (``"y"``: rows reversed, shear_y negated)."""
    out = x[..., ::-1] if axis == "x" else x[..., ::-1, :]
    out = np.array(out)
    k = _index(channel_names, f"shear_{axis}")
    if k is not None:
        out[k] = -out[k]
    return out


def transpose(x: np.ndarray, channel_names: list[str]) -> np.ndarray:
    """Mirror across the main diagonal: rows <-> columns and shear_x <-> shear_y."""
    out = np.array(x.swapaxes(-1, -2))
    kx, ky = _index(channel_names, "shear_x"), _index(channel_names, "shear_y")
    if kx is not None and ky is not None:
        out[[kx, ky]] = out[[ky, kx]]
    return out


def rotate90(x: np.ndarray, channel_names: list[str], turns: int = 1) -> np.ndarray:
    """Rotate by ``turns`` quarter turns (x towards y), shear vectors turning with it."""
    for _ in range(turns % 4):
        x = mirror(transpose(x, channel_names), channel_names, "x")
    return x


def shift(x: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Translate by whole cells, filling with zero load."""
    out = np.zeros_like(x)
    r, c = x.shape[-2:]
    src_r = slice(max(0, -rows), r - max(0, rows))
    dst_r = slice(max(0, rows), r - max(0, -rows))
    src_c = slice(max(0, -cols), c - max(0, cols))
    dst_c = slice(max(0, cols), c - max(0, -cols))
    out[..., dst_r, dst_c] = x[..., src_r, src_c]
    return out


def augment_one(x: np.ndarray, channel_names: list[str], kinds: tuple[str, ...],
                rng: np.random.Generator) -> np.ndarray:
    """One random augmented copy of trial ``x`` (C, N, R, X)."""
    square = x.shape[-1] == x.shape[-2]
    if "flip" in kinds:
        if rng.random() < 0.5:
            x = mirror(x, channel_names, "x")
        if rng.random() < 0.5:
            x = mirror(x, channel_names, "y")
    if "rotate" in kinds and square:
        x = rotate90(x, channel_names, int(rng.integers(4)))
    if "shift" in kinds:
        x = shift(x, int(rng.integers(-1, 2)), int(rng.integers(-1, 2)))
    if "warp" in kinds and x.shape[1] > 2:
        x = resample(x, max(2, int(round(x.shape[1] * np.exp(rng.uniform(-0.22, 0.22))))))
    if "scale" in kinds:
        x = x * np.float32(np.exp(rng.normal(0, 0.25)))
        ks = [k for k in (_index(channel_names, "shear_x"), _index(channel_names, "shear_y"))
              if k is not None]
        if ks:
            x = np.array(x)
            x[ks] *= np.float32(np.exp(rng.normal(0, 0.2)))
    return np.ascontiguousarray(x, dtype=np.float32)


def augment_trials(trials: list[np.ndarray], channel_names: list[str], kinds: tuple[str, ...],
                   copies: int, rng: np.random.Generator) -> tuple[list[np.ndarray], np.ndarray]:
    """``copies`` augmented copies of every trial: (new trials, index of the source)."""
    out, src = [], []
    for _ in range(copies):
        for i, t in enumerate(trials):
            out.append(augment_one(t, channel_names, kinds, rng))
            src.append(i)
    return out, np.asarray(src, dtype=np.int64)
