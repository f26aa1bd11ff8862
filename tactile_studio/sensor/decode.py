"""Raw counts to normal and shear stress, vectorised over batches of frames.

Every function takes ``raw`` of shape (N, n_channels) (or a single frame of shape
(n_channels,)) and a per-channel ``baseline`` of shape (n_channels,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.sensor.layout import CENTRE, X_NEG, X_POS, Y_NEG, Y_POS, Layout


@dataclass
class StressFrames:
    """Decoded frames on a grid: ``normal`` (N, R, C), shear (N, R, C) or None.

    Units are the layout's (kPa for a calibrated shear sensor, raw units for pressure
    grids). Pressing reads positive; shear points the way the skin is dragged.
    """

    normal: np.ndarray
    shear_x: np.ndarray | None
    shear_y: np.ndarray | None
    units: str

    def stack(self) -> np.ndarray:
        """(3, N, R, C) normal, shear-x, shear-y (zeros when there is no shear)."""
        sx = self.shear_x if self.shear_x is not None else np.zeros_like(self.normal)
        sy = self.shear_y if self.shear_y is not None else np.zeros_like(self.normal)
        return np.stack([self.normal, sx, sy])


def _as_batch(raw: np.ndarray, layout: Layout) -> np.ndarray:
    raw = np.asarray(raw, dtype=np.float64)
    if raw.ndim == 1:
        raw = raw[None, :]
    if raw.shape[-1] != layout.n_channels:
        raise UserError(
            f"layout {layout.name} has {layout.n_channels} channels, data has {raw.shape[-1]}"
        )
    return raw


def compute_baseline(raw: np.ndarray, n: int = 100) -> np.ndarray:
    """Per-channel mean of the first ``n`` frames (the old software's tare)."""
    raw = np.asarray(raw, dtype=np.float64)
    if raw.ndim != 2 or raw.shape[0] == 0:
        raise UserError("cannot compute a baseline from no frames")
    return raw[: max(1, n)].mean(axis=0)


def _safe_baseline(baseline: np.ndarray) -> np.ndarray:
    base = np.asarray(baseline, dtype=np.float64)
    return np.where(np.abs(base) < 1e-9, 1.0, base)


def relative_change(layout: Layout, raw: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """Per-channel load signal, positive when pressed: (C - C')/C, or C' - C for grids."""
    raw = _as_batch(raw, layout)
    if layout.falls_under_load:
        base = _safe_baseline(baseline)
        return (base - raw) / base
    return raw - np.asarray(baseline, dtype=np.float64)


def _normal_units(layout: Layout, rel: np.ndarray) -> np.ndarray:
    return layout.calibration.normal_kpa(rel) if layout.calibration else rel


def _shear(layout: Layout, raw: np.ndarray, base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's differential shear per taxel, made dimensionless and calibrated.

    ``Dx = (C_a*C_b' - C_b*C_a') / C3'`` with a, b the -x and +x channels; we divide
    additionally by the centre baseline C3 so the value is a relative change (this
    is the scale on which the paper's 0.11 /kPa slope is quoted).
    """
    def grid(role: int, arr: np.ndarray) -> np.ndarray:
        return arr[..., layout.role_channels(role)]

    c3b, c3 = grid(CENTRE, base), grid(CENTRE, raw)
    c3 = np.where(np.abs(c3) < 1e-9, 1e-9, c3)
    out = []
    for neg, pos, sign in ((X_NEG, X_POS, layout.shear_sign_x),
                           (Y_NEG, Y_POS, layout.shear_sign_y)):
        d = (grid(neg, base) * grid(pos, raw) - grid(pos, base) * grid(neg, raw)) / (c3 * c3b)
        d = sign * d
        out.append(layout.calibration.shear_kpa(d) if layout.calibration else d)
    return out[0], out[1]


def decode(layout: Layout, raw: np.ndarray, baseline: np.ndarray,
           virtual: bool = False) -> StressFrames:
    """Decode raw frames to stresses on the physical (R x C) or virtual grid."""
    raw = _as_batch(raw, layout)
    base = _safe_baseline(baseline) if layout.falls_under_load else np.asarray(baseline, float)
    rel = relative_change(layout, raw, base)
    if not layout.has_shear:
        normal = rel[:, layout.role_channels(CENTRE)]
        if virtual:
            normal = _midpoints(normal)
        return StressFrames(normal.astype(np.float32), None, None, layout.units)
    sx, sy = _shear(layout, raw, base)
    if virtual:
        normal_rel = virtual_normal_rel(layout, rel)
        sx, sy = _midpoints(sx), _midpoints(sy)
    else:
        normal_rel = rel[:, layout.role_channels(CENTRE)]
    normal = _normal_units(layout, normal_rel)
    return StressFrames(normal.astype(np.float32), sx.astype(np.float32),
                        sy.astype(np.float32), layout.units)


def _midpoints(grid: np.ndarray) -> np.ndarray:
    """Lift (N, R, C) to (N, 2R-1, 2C-1): originals on even cells, neighbour means between."""
    n, r, c = grid.shape
    out = np.empty((n, 2 * r - 1, 2 * c - 1), dtype=np.float64)
    out[:, ::2, ::2] = grid
    out[:, 1::2, ::2] = 0.5 * (grid[:, :-1, :] + grid[:, 1:, :])
    out[:, ::2, 1::2] = 0.5 * (grid[:, :, :-1] + grid[:, :, 1:])
    out[:, 1::2, 1::2] = 0.25 * (grid[:, :-1, :-1] + grid[:, 1:, :-1]
                                 + grid[:, :-1, 1:] + grid[:, 1:, 1:])
    return out


def virtual_normal_rel(layout: Layout, rel: np.ndarray) -> np.ndarray:
    """Normal load on the virtual (2R-1) x (2C-1) grid from the channels facing each spot.

    Method (the shear paper's virtual taxels): a physical taxel's cell uses its centre
    channel. A spot between two taxels in a row uses the two outer channels that face
    it (the left taxel's +x and the right taxel's -x), and likewise between rows (+y of
    the upper taxel, -y of the lower). A spot between four taxels uses the eight outer
    channels of those taxels that face it (each taxel's channels towards the spot along x
    and along y). Each value is the mean relative change of those channels, so a uniform
    load gives a uniform map and a load between taxels peaks between them. Shear on
    virtual cells is the mean of the neighbouring taxels' shear, because the
    differential signal needs both channels of a pair.
    """
    g = {role: rel[:, layout.role_channels(role)] for role in (CENTRE, X_NEG, X_POS, Y_NEG, Y_POS)}
    return _virtual_from_roles(g)


def _virtual_from_roles(g: dict[int, np.ndarray]) -> np.ndarray:
    """The virtual grid from per-role (N, R, C) relative changes (see virtual_normal_rel)."""
    n, r, c = g[CENTRE].shape
    out = np.empty((n, 2 * r - 1, 2 * c - 1), dtype=np.float64)
    out[:, ::2, ::2] = g[CENTRE]
    out[:, ::2, 1::2] = 0.5 * (g[X_POS][:, :, :-1] + g[X_NEG][:, :, 1:])
    out[:, 1::2, ::2] = 0.5 * (g[Y_POS][:, :-1, :] + g[Y_NEG][:, 1:, :])
    out[:, 1::2, 1::2] = (
        g[X_POS][:, :-1, :-1] + g[Y_POS][:, :-1, :-1]      # upper-left taxel
        + g[X_NEG][:, :-1, 1:] + g[Y_POS][:, :-1, 1:]      # upper-right taxel
        + g[X_POS][:, 1:, :-1] + g[Y_NEG][:, 1:, :-1]      # lower-left taxel
        + g[X_NEG][:, 1:, 1:] + g[Y_NEG][:, 1:, 1:]        # lower-right taxel
    ) / 8.0
    return out


def touched(layout: Layout, raw: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """(N, n_channels) bool: a channel is touched below 0.97 x baseline (old software's rule).

    For pressure grids that rise under load, a channel is touched when it rises by more
    than 3% of the full scale.
    """
    raw = _as_batch(raw, layout)
    base = np.asarray(baseline, dtype=np.float64)
    if layout.falls_under_load:
        return raw < layout.touch_ratio * base
    return (raw - base) > (1.0 - layout.touch_ratio) * layout.raw_max


def contact_map(layout: Layout, raw: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """(N, R, C) bool: a taxel is in contact when any of its channels is touched."""
    t = touched(layout, raw, baseline)
    k = layout.channels_per_taxel
    per_taxel = t.reshape(t.shape[0], layout.n_taxels, k).any(axis=2)
    return per_taxel[:, layout.grid_index()]


def contact_taxels(layout: Layout, raw: np.ndarray, baseline: np.ndarray,
                   contact_rel: float = 0.015) -> np.ndarray:
    """(T, R, C) bool. Capacitance arrays: any channel of the taxel ``contact_rel`` below
    its baseline (finer than the old 0.97 rule, which misses light pokes); pressure
    grids: the old rule (:func:`contact_map`)."""
    if not layout.falls_under_load:
        return contact_map(layout, raw, baseline)
    rel = relative_change(layout, raw, baseline) > contact_rel
    k = layout.channels_per_taxel
    per_taxel = rel.reshape(rel.shape[0], layout.n_taxels, k).any(axis=2)
    return per_taxel[:, layout.grid_index()]


class FrameDecoder:
    """Decodes one frame at a time for a fixed layout, baseline and grid, fast.

    The live view decodes a single frame per painted frame; :func:`decode` spends most of
    that time on set-up (channel look-ups, baseline terms) that never changes between
    frames. This does the set-up once and then the same arithmetic, in the same order, so
    the results are identical to ``decode(layout, raw[None], baseline, virtual)``.
    """

    def __init__(self, layout: Layout, baseline: np.ndarray, virtual: bool = False) -> None:
        self.layout, self.virtual = layout, virtual
        self.baseline = baseline
        lay = layout
        base = _safe_baseline(baseline) if lay.falls_under_load else np.asarray(baseline, float)
        if lay.falls_under_load:
            base = _safe_baseline(base)  # relative_change applies it again: keep that
        self._base = base
        roles = (CENTRE, X_NEG, X_POS, Y_NEG, Y_POS) if lay.has_shear else (CENTRE,)
        self._idx = {role: np.ascontiguousarray(lay.role_channels(role)) for role in roles}
        self._bgrid = {role: base[idx] for role, idx in self._idx.items()}
        self._cal = lay.calibration
        if lay.has_shear:
            self._c3b = self._bgrid[CENTRE]
            self._signs = (lay.shear_sign_x, lay.shear_sign_y)
        k = lay.channels_per_taxel
        self._touch_limit = (lay.touch_ratio * np.asarray(baseline, dtype=np.float64)
                             if lay.falls_under_load else None)
        self._touch_k = k
        self._grid = lay.grid_index()

    def _rel(self, role: int, raw_grid: np.ndarray) -> np.ndarray:
        b = self._bgrid[role]
        return (b - raw_grid) / b if self.layout.falls_under_load else raw_grid - b

    def decode(self, raw: np.ndarray) -> StressFrames:
        """One frame (n_channels,) to (1, R, C) stresses, or a few (N, n_channels) to N."""
        lay = self.layout
        raw = np.asarray(raw, dtype=np.float64)
        if raw.ndim == 1:
            raw = raw[None]
        if raw.shape[-1] != lay.n_channels:
            raise UserError(
                f"layout {lay.name} has {lay.n_channels} channels, data has {raw.shape[-1]}")
        g = {role: raw[:, idx] for role, idx in self._idx.items()}
        if not lay.has_shear:
            normal = self._rel(CENTRE, g[CENTRE])
            if self.virtual:
                normal = _midpoints(normal)
            return StressFrames(normal.astype(np.float32), None, None, lay.units)
        c3 = g[CENTRE]
        c3 = np.where(np.abs(c3) < 1e-9, 1e-9, c3)
        denom = c3 * self._c3b
        shear = []
        for (neg, pos), sign in zip(((X_NEG, X_POS), (Y_NEG, Y_POS)), self._signs):
            d = (self._bgrid[neg] * g[pos] - self._bgrid[pos] * g[neg]) / denom
            d = sign * d
            shear.append(self._cal.shear_kpa(d) if self._cal else d)
        sx, sy = shear
        if self.virtual:
            normal_rel = _virtual_from_roles({role: self._rel(role, g[role]) for role in g})
            both = _midpoints(np.concatenate((sx, sy)))  # both in one pass
            sx, sy = both[:len(raw)], both[len(raw):]
        else:
            normal_rel = self._rel(CENTRE, g[CENTRE])
        normal = _normal_units(lay, normal_rel)
        return StressFrames(normal.astype(np.float32), sx.astype(np.float32),
                            sy.astype(np.float32), lay.units)

    def contact(self, raw: np.ndarray) -> np.ndarray:
        """(R, C) bool contact map of one frame, as :func:`contact_map` gives."""
        raw = np.asarray(raw, dtype=np.float64).reshape(-1)
        lay = self.layout
        if self._touch_limit is not None:
            t = raw < self._touch_limit
        else:
            t = (raw - np.asarray(self.baseline, dtype=np.float64)) > (
                (1.0 - lay.touch_ratio) * lay.raw_max)
        return t.reshape(lay.n_taxels, self._touch_k).any(axis=1)[self._grid]
