"""Colours of the live view: colour maps of the stress image, auto-range steps and the
strip chart's line colours (shared with the heatmap's taxel marks)."""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg

BACKGROUND = "#ffffff"
FOREGROUND = "#303030"
# Colour schemes: "sequential" maps 0..max (stress below baseline shows as 0);
# "diverging" puts white at 0, load in reds and stress below baseline (counts above the
# baseline, e.g. a neighbouring taxel lifted) in blues, down to -NEGATIVE_SHARE x max.
COLOR_SCHEMES = {"sequential": "viridis 0…max", "diverging": "diverging ±"}
NEGATIVE_SHARE = 0.25
_NEG_STOPS = ["#053061", "#2166ac", "#4393c3", "#92c5de", "#d1e5f0"]
_POS_STOPS = ["#fddbc7", "#f4a582", "#d6604d", "#b2182b", "#67001f"]
_ZERO = "#f7f7f7"


def diverging_colormap(lo: float, hi: float) -> pg.ColorMap:
    """Blues below 0, white at 0, reds above, for levels ``lo < 0 < hi`` (zero stays white
    however asymmetric the range)."""
    z = min(max(-lo / (hi - lo), 0.05), 0.95) if hi > lo else 0.5
    neg = np.linspace(0.0, z, len(_NEG_STOPS) + 1)[:-1]
    pos = np.linspace(z, 1.0, len(_POS_STOPS) + 1)[1:]
    stops = np.concatenate([neg, [z], pos])
    return pg.ColorMap(stops, [*_NEG_STOPS, _ZERO, *_POS_STOPS])


def nice_ceil(x: float) -> float:
    """The 1-2-3-5 value at or above ``x`` (auto ranges move in steps, not every frame;
    a 30 kPa press gets a 0-30 scale, not 0-50)."""
    if x <= 0:
        return 0.0
    mag = 10.0 ** math.floor(math.log10(x))
    for m in (1.0, 2.0, 3.0, 5.0, 10.0):
        if m * mag >= x * (1 - 1e-9):
            return m * mag
    return 10.0 * mag


def strip_colors(n: int) -> list[str]:
    """Distinct line colours shared by the strip chart and the heatmap's taxel marks."""
    palette = ["#e6194b", "#f58231", "#f032e6", "#4363d8", "#3cb44b", "#911eb4",
               "#42d4f4", "#9a6324", "#000075", "#808000"]
    return [palette[i % len(palette)] for i in range(n)]


__all__ = ["BACKGROUND", "COLOR_SCHEMES", "FOREGROUND", "NEGATIVE_SHARE",
           "diverging_colormap", "nice_ceil", "strip_colors"]
