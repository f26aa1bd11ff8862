"""The characterisation analysis (the shear paper's): fits on sensor vs load-cell data.

Pure numpy, no Qt, no I/O: the procedure (tactile_studio/characterise/) collects the
points and traces, these functions turn them into the numbers of characterisation.json.
Sensor signals are relative changes (see :func:`taxel_signals`); stresses are the load
cell's force over the indenter face, in kPa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.sensor.decode import decode, relative_change
from tactile_studio.sensor.layout import CENTRE, Layout
from tactile_studio.sensor.taxels import distinct_taxels
from tactile_studio.sensor.taxels import parse_taxels as _parse_taxels


def taxel_signals(layout: Layout, raw: np.ndarray,
                  baseline: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-taxel (normal, shear_x, shear_y), each (n_frames, n_taxels), as relative changes.

    Normal: the centre channel's (C0 - C)/C0, the paper's sensitivity scale (/kPa).
    Shear: the paper's dimensionless differential (decode's shear before its kPa
    calibration), positive the way the skin is dragged.
    """
    rel = relative_change(layout, raw, baseline)
    normal = rel[:, [layout.channel(t, CENTRE) for t in range(layout.n_taxels)]]
    dec = decode(layout, raw, baseline)
    rc = np.array([layout.taxel_rc(t) for t in range(layout.n_taxels)])
    slope = layout.calibration.shear_slope if layout.calibration else 1.0
    sx = dec.shear_x[:, rc[:, 0], rc[:, 1]].astype(np.float64) * slope
    sy = dec.shear_y[:, rc[:, 0], rc[:, 1]].astype(np.float64) * slope
    return normal, sx, sy


def neighbours(layout: Layout, taxel: int) -> dict[str, int]:
    """The up-to-8 neighbours of ``taxel`` by name (fewer at the edge)."""
    r, c = layout.taxel_rc(taxel)
    out = {}
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            rr, cc = r + dr, c + dc
            if (dr or dc) and 0 <= rr < layout.rows and 0 <= cc < layout.cols:
                out[layout.taxel_name(rr, cc)] = layout.taxel_at(rr, cc)
    return out


def parse_taxels(layout: Layout, spec: str) -> list[int]:
    """``"B2,B5"``, ``"7,10"`` or ``"all"`` -> taxel numbers (the one parser,
    :mod:`tactile_studio.sensor.taxels`); ValueError names a bad taxel."""
    try:
        return distinct_taxels(layout, _parse_taxels(layout, spec))
    except UserError as exc:
        raise ValueError(str(exc)) from None


@dataclass
class LinearFit:
    slope: float
    intercept: float
    r2: float


def linear_fit(x: np.ndarray, y: np.ndarray) -> LinearFit:
    """Least-squares line with its coefficient of determination."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 2 or np.ptp(x) == 0:
        return LinearFit(float("nan"), float("nan"), float("nan"))
    slope, intercept = np.polyfit(x, y, 1)
    resid = y - (slope * x + intercept)
    ss = float(np.sum((y - y.mean()) ** 2))
    return LinearFit(float(slope), float(intercept), 1.0 - float(resid @ resid) / ss if ss else 1.0)


@dataclass
class TwoRangeFit:
    low: float
    high: float
    breakpoint: float
    intercept: float
    r2: float

    def predict(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float)
        return (self.intercept + self.low * np.minimum(p, self.breakpoint)
                + self.high * np.maximum(p - self.breakpoint, 0.0))


def two_range_fit(p: np.ndarray, y: np.ndarray) -> TwoRangeFit:
    """Continuous two-segment line with a fitted breakpoint (the paper's normal response).

    The breakpoint is searched between the 2nd and the 2nd-to-last distinct stress and
    refined on a fine grid; each candidate is an ordinary least-squares fit.
    """
    p, y = np.asarray(p, float), np.asarray(y, float)
    xs = np.unique(p)
    if len(xs) < 4:
        raise ValueError("a two-range fit needs at least 4 distinct stresses")

    def solve(b: float) -> tuple[float, np.ndarray]:
        a = np.stack([np.ones_like(p), np.minimum(p, b), np.maximum(p - b, 0.0)], axis=1)
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        r = y - a @ coef
        return float(r @ r), coef

    grid = np.linspace(xs[1], xs[-2], 200)
    errs = [solve(b)[0] for b in grid]
    i = int(np.argmin(errs))
    fine = np.linspace(grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)], 101)
    b = float(fine[int(np.argmin([solve(v)[0] for v in fine]))])
    sse, coef = solve(b)
    ss = float(np.sum((y - y.mean()) ** 2))
    return TwoRangeFit(float(coef[1]), float(coef[2]), b, float(coef[0]),
                       1.0 - sse / ss if ss else 1.0)


def exp_settle_fit(t: np.ndarray, y: np.ndarray, tau: float | None = None,
                   ) -> tuple[float, float, float]:
    """Fit ``y = a + b*exp(-t/tau)``; returns (tau, a, b). With ``tau`` given only a, b
    are fitted (the asymptote of a shear return). Tau: log grid, then a fine grid."""
    t, y = np.asarray(t, float) - float(np.min(t)), np.asarray(y, float)

    def solve(tt: float) -> tuple[float, np.ndarray]:
        a = np.stack([np.ones_like(t), np.exp(-t / tt)], axis=1)
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        r = y - a @ coef
        return float(r @ r), coef

    if tau is None:
        grid = np.geomspace(0.05, 60.0, 240)
        i = int(np.argmin([solve(v)[0] for v in grid]))
        fine = np.geomspace(grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)], 101)
        tau = float(fine[int(np.argmin([solve(v)[0] for v in fine]))])
    _, coef = solve(tau)
    return float(tau), float(coef[0]), float(coef[1])


def hysteresis(p_load: np.ndarray, y_load: np.ndarray, p_unload: np.ndarray,
               y_unload: np.ndarray) -> float:
    """Area between the unloading and loading curves over the loading curve's area."""
    lo = np.argsort(p_load)
    un = np.argsort(p_unload)
    grid = np.linspace(max(np.min(p_load), np.min(p_unload)),
                       min(np.max(p_load), np.max(p_unload)), 200)
    yl = np.interp(grid, np.asarray(p_load)[lo], np.asarray(y_load)[lo])
    yu = np.interp(grid, np.asarray(p_unload)[un], np.asarray(y_unload)[un])
    area = float(np.trapezoid(yl, grid))
    return float(np.trapezoid(yu - yl, grid)) / area if area > 0 else float("nan")


def still_moving(t: np.ndarray, y: np.ndarray, per_s: float, k: float = 3.0) -> np.ndarray:
    """Which columns of ``y`` (frames x signals, relative changes) still move: a fitted
    slope over ``t`` steeper than ``per_s`` per second, and steeper than ``k`` standard
    errors of that slope (noise alone must not keep a bench waiting: a slope is only
    measurable down to a few standard errors)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    if len(t) < 3 or np.ptp(t) == 0:
        return np.ones(y.shape[1], dtype=bool)
    tc = t - t.mean()
    sxx = float(tc @ tc)
    slope = tc @ (y - y.mean(axis=0)) / sxx
    resid = y - y.mean(axis=0) - np.outer(tc, slope)
    se = np.sqrt((resid ** 2).sum(axis=0) / max(len(t) - 2, 1) / sxx)
    return np.abs(slope) > np.maximum(per_s, k * se)


def drift(peaks: np.ndarray) -> tuple[float, float]:
    """Repeatability: (relative change of the peak from the first to the last tenth of
    the cycles, coefficient of variation of the peaks)."""
    peaks = np.asarray(peaks, float)
    if len(peaks) < 2:
        return float("nan"), float("nan")
    k = max(1, len(peaks) // 10)
    first, last = peaks[:k].mean(), peaks[-k:].mean()
    return float((last - first) / first), float(peaks.std() / peaks.mean())
