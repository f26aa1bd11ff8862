"""What the live view shows, computed without Qt.

The GUI's timer asks a :class:`LiveView` for the newest decoded frame, a readout of one
cell and the strip-chart history; the widgets only draw the answers. Keeping this here
(not in the widgets) lets the CLI, benchmarks and tests use the same numbers, and keeps
every piece of stress maths in the core.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.sensor.decode import FrameDecoder, compute_baseline
from tactile_studio.sensor.layout import Layout
from tactile_studio.sensor.taxels import parse_taxel

QUANTITIES = ("normal", "shear_x", "shear_y", "shear")
QUANTITY_LABELS = {"normal": "normal", "shear_x": "shear x", "shear_y": "shear y",
                   "shear": "|shear|"}


@dataclass
class LiveFrame:
    """The newest frame decoded on the physical or virtual grid."""

    index: int                    # engine frame number
    host_time: float              # time.time() when the frame reached the host
    normal: np.ndarray            # (R, C) float32, row 0 at the top
    shear_x: np.ndarray | None    # (R, C) or None for pressure-only grids
    shear_y: np.ndarray | None
    units: str
    virtual: bool
    contact: np.ndarray           # (rows, cols) bool on the physical grid
    provisional_baseline: bool    # True until the engine's first tare has finished


@dataclass
class CellReadout:
    """Values at one cell of the displayed grid, for a hover tooltip or status line."""

    row: int
    col: int
    name: str                      # "C4", or "C4-C5" / "C4-D5" for a virtual cell
    virtual_between: tuple[str, ...]  # taxels a virtual cell lies between; () for a taxel
    normal: float
    shear_x: float | None
    shear_y: float | None
    units: str
    raw: dict[str, tuple[int, ...]] = field(default_factory=dict)  # taxel -> its channels

    def text(self) -> str:
        """One line: name, normal, shear and raw counts."""
        where = self.name
        if self.virtual_between:
            where = f"{self.name} (virtual, between {', '.join(self.virtual_between)})"
        out = f"{where}   normal {self.normal:6.2f} {self.units}"
        if self.shear_x is not None and self.shear_y is not None:
            out += f"   shear x {self.shear_x:+5.2f}  y {self.shear_y:+5.2f} {self.units}"
        if len(self.raw) == 1:
            out += "   raw " + " ".join(str(v) for v in next(iter(self.raw.values())))
        return out


@dataclass
class History:
    """Strip-chart data: ``values[:, k]`` is the quantity of ``names[k]`` at time ``t``."""

    t: np.ndarray          # (N,) seconds relative to the newest frame (<= 0)
    values: np.ndarray     # (N, K) float32
    names: list[str]
    quantity: str
    units: str
    t_end: float = 0.0     # device time of t == 0 (to line up with events)


def decimate_minmax(t: np.ndarray, values: np.ndarray, t0: float, t1: float,
                    columns: int) -> tuple[np.ndarray, np.ndarray]:
    """Thin (t, values[:, k]) to two points per pixel column of ``t0..t1``: each column's
    minimum then maximum (at its first and last time), so no peak vanishes however many
    samples share a column. Unchanged when there are no more than two samples a column."""
    n = len(t)
    if n <= 2 * columns or columns < 1 or t1 <= t0:
        return t, values
    col = np.floor((t - t0) * (columns / (t1 - t0))).astype(np.int64)
    np.clip(col, 0, columns - 1, out=col)
    starts = np.flatnonzero(np.concatenate(([True], col[1:] != col[:-1])))
    ends = np.append(starts[1:], n) - 1
    out_t = np.empty(2 * len(starts))
    out_t[0::2], out_t[1::2] = t[starts], t[ends]
    out_v = np.empty((2 * len(starts), *values.shape[1:]), dtype=values.dtype)
    out_v[0::2] = np.minimum.reduceat(values, starts, axis=0)
    out_v[1::2] = np.maximum.reduceat(values, starts, axis=0)
    return out_t, out_v


def parse_taxel_name(layout: Layout, name: str) -> tuple[int, int]:
    """"C4" (or its index) -> (row 2, column 3), through the one taxel parser
    (:func:`tactile_studio.sensor.taxels.parse_taxel`; UserError if bad)."""
    return layout.taxel_rc(parse_taxel(layout, name))


class _Trail:
    """Decoded physical frames over the last ``window_s`` seconds, thinned in time.

    Frames are decoded once as they arrive; at most ``max_points`` per window are kept,
    so a 1 kHz device costs no more to chart than a 43 Hz one.
    """

    def __init__(self, shape: tuple[int, ...], window_s: float, max_points: int) -> None:
        self.shape, self.window_s = shape, window_s
        self.min_dt = window_s / max_points
        self.cap = 2 * max_points + 64
        self.t = np.empty(self.cap)
        self.v = np.empty((self.cap, *shape), dtype=np.float32)
        self.n = 0

    def clear(self) -> None:
        self.n = 0

    def keep_mask(self, t: np.ndarray) -> np.ndarray:
        """Which of the frames at times ``t`` the trail keeps: the first of every time bin
        of width ``min_dt`` (so callers decode only those; at 1 kHz one frame in ten)."""
        if len(t) == 0:
            return np.zeros(0, dtype=bool)
        last = self.t[self.n - 1] if self.n else -math.inf
        if t[0] < last - 1e-9:          # the device clock went back (restart): start over
            self.n, last = 0, -math.inf
        bins = np.floor(t / self.min_dt)
        prev = np.empty_like(bins)
        prev[0] = math.floor(last / self.min_dt) if self.n else -math.inf
        prev[1:] = bins[:-1]
        return bins != prev

    def append(self, t: np.ndarray, v: np.ndarray) -> None:
        keep = self.keep_mask(t)
        self.append_kept(t[keep], v[keep])

    def append_kept(self, t: np.ndarray, v: np.ndarray) -> None:
        """Frames already chosen by :meth:`keep_mask`."""
        if len(t) == 0:
            return
        if self.n + len(t) > self.cap:
            self._compact(float(t[-1]) if len(t) else float(self.t[self.n - 1]))
        overflow = self.n + len(t) - self.cap
        if overflow > 0:  # still too many (should not happen with binning): drop the oldest
            if overflow >= self.n:
                self.n, t, v = 0, t[-self.cap:], v[-self.cap:]
            else:
                self.t[:self.n - overflow] = self.t[overflow:self.n]
                self.v[:self.n - overflow] = self.v[overflow:self.n]
                self.n -= overflow
        m = len(t)
        self.t[self.n:self.n + m] = t
        self.v[self.n:self.n + m] = v
        self.n += m

    def _compact(self, newest: float) -> None:
        first = int(np.searchsorted(self.t[:self.n], newest - self.window_s))
        k = self.n - first
        self.t[:k] = self.t[first:self.n]
        self.v[:k] = self.v[first:self.n]
        self.n = k

    def window(self, seconds: float) -> tuple[np.ndarray, np.ndarray, float]:
        """(t relative to the newest point, values, device time of the newest point)."""
        if self.n == 0:
            return self.t[:0], self.v[:0], 0.0
        newest = float(self.t[self.n - 1])
        first = int(np.searchsorted(self.t[:self.n], newest - seconds))
        return self.t[first:self.n] - newest, self.v[first:self.n], newest


class LiveView:
    """Pulls the newest data from an engine and decodes it for display.

    Decoding happens only when a caller asks and only for frames it has not decoded
    yet, so a display timer at 60 Hz costs the same whether the device sends 43 or
    1000 frames a second.
    """

    def __init__(self, engine: LiveStream | None = None, virtual: bool = False,
                 history_s: float = 10.0, max_points: int = 1000) -> None:
        self.virtual = virtual
        self.history_s = history_s
        self.max_points = max_points
        self.engine: LiveStream | None = None
        self._cache_key: tuple | None = None
        self._cache: LiveFrame | None = None
        self.attach(engine)

    def attach(self, engine: LiveStream | None) -> None:
        """Show another engine (or none); forgets everything decoded so far."""
        self.engine = engine
        self._cache_key, self._cache = None, None
        self._cache_base: np.ndarray | None = None
        self._decoder: FrameDecoder | None = None  # set-up for single frames, per baseline
        self._trail_decoder: FrameDecoder | None = None  # physical grid, for the strip chart
        self._trail: _Trail | None = None
        self._trail_cursor = 0
        self._trail_window = 0  # frames in one history window (set when the trail starts)
        self._trail_baseline: np.ndarray | None = None
        self._provisional: np.ndarray | None = None

    @property
    def layout(self) -> Layout | None:
        return self.engine.layout if self.engine is not None else None

    # ---- baseline ----------------------------------------------------------------
    def baseline(self) -> np.ndarray | None:
        """The engine's baseline, or the mean of the earliest frames until it has one."""
        eng = self.engine
        if eng is None:
            return None
        if eng.baseline is not None:
            return eng.baseline
        if self._provisional is None and eng.frames:
            early = eng.read_since(0, eng.baseline_frames)
            if len(early):
                self._provisional = compute_baseline(early.raw)
        return self._provisional

    # ---- newest frame ------------------------------------------------------------
    def latest(self) -> LiveFrame | None:
        """The newest frame decoded on the current grid (cached until a new one comes)."""
        eng = self.engine
        if eng is None or eng.frames == 0:
            return None
        index = eng.frames - 1
        base = self.baseline()
        key = (index, self.virtual)
        if key == self._cache_key and self._cache_base is base and self._cache is not None:
            return self._cache
        chunk = eng.latest()
        if chunk is None or base is None:
            return None
        dec = self._decoder
        if (dec is None or dec.baseline is not base or dec.virtual != self.virtual
                or dec.layout is not eng.layout):
            dec = self._decoder = FrameDecoder(eng.layout, base, virtual=self.virtual)
        raw = chunk.raw[-1]
        st = dec.decode(raw)
        frame = LiveFrame(
            index=chunk.start, host_time=float(chunk.host_time[-1]), normal=st.normal[0],
            shear_x=None if st.shear_x is None else st.shear_x[0],
            shear_y=None if st.shear_y is None else st.shear_y[0],
            units=st.units, virtual=self.virtual, contact=dec.contact(raw),
            provisional_baseline=eng.baseline is None)
        self._cache_key, self._cache, self._cache_base = (chunk.start, self.virtual), frame, base
        return frame

    def grid_shape(self) -> tuple[int, int] | None:
        lay = self.layout
        if lay is None:
            return None
        return lay.virtual_shape if self.virtual else (lay.rows, lay.cols)

    # ---- readout -----------------------------------------------------------------
    def cell_taxels(self, row: int, col: int) -> list[tuple[int, int]]:
        """Physical (row, col) taxels under a cell of the displayed grid."""
        if not self.virtual:
            return [(row, col)]
        rows = [row // 2] if row % 2 == 0 else [row // 2, row // 2 + 1]
        cols = [col // 2] if col % 2 == 0 else [col // 2, col // 2 + 1]
        return [(r, c) for r in rows for c in cols]

    def nearest_taxel(self, row: int, col: int) -> tuple[int, int]:
        """The physical taxel a click on the displayed grid means (upper-left if between)."""
        return self.cell_taxels(row, col)[0]

    def readout(self, row: int, col: int) -> CellReadout | None:
        """Name, stresses and raw channels at a cell of the displayed grid."""
        frame, lay = self.latest(), self.layout
        if frame is None or lay is None:
            return None
        r_max, c_max = frame.normal.shape
        if not (0 <= row < r_max and 0 <= col < c_max):
            return None
        taxels = self.cell_taxels(row, col)
        names = [lay.taxel_name(r, c) for r, c in taxels]
        chunk = self.engine.latest() if self.engine is not None else None
        raw: dict[str, tuple[int, ...]] = {}
        if chunk is not None:
            k = lay.channels_per_taxel
            for (r, c), name in zip(taxels, names):
                t = lay.taxel_at(r, c)
                raw[name] = tuple(int(v) for v in chunk.raw[-1, t * k:(t + 1) * k])
        sx = None if frame.shear_x is None else float(frame.shear_x[row, col])
        sy = None if frame.shear_y is None else float(frame.shear_y[row, col])
        name = names[0] if len(names) == 1 else f"{names[0]}-{names[-1]}"
        return CellReadout(row, col, name, tuple(names) if len(names) > 1 else (),
                           float(frame.normal[row, col]), sx, sy, frame.units, raw)

    # ---- strip chart -------------------------------------------------------------
    def _refresh_trail(self) -> _Trail | None:
        eng = self.engine
        if eng is None:
            return None
        base = self.baseline()
        if base is None:
            return None
        lay = eng.layout
        # more than a window behind (e.g. no taxel was charted for a while): start over
        rebuild = (self._trail is None or self._trail_baseline is not base
                   or eng.frames - self._trail_cursor > self._trail_window)
        if rebuild:
            if self._trail is None:
                self._trail = _Trail((3, lay.rows, lay.cols), self.history_s, self.max_points)
            self._trail.clear()
            rate = eng.device_rate_hz() or eng.nominal_rate_hz
            n = min(eng.capacity, int(rate * self.history_s * 1.2) + 64)  # one window
            self._trail_window = n
            self._trail_cursor = max(0, eng.frames - n)
            self._trail_baseline = base
        chunk = eng.read_since(self._trail_cursor)
        if len(chunk):
            dec = self._trail_decoder
            if dec is None or dec.baseline is not base or dec.layout is not lay:
                dec = self._trail_decoder = FrameDecoder(lay, base)
            keep = self._trail.keep_mask(chunk.device_time)  # decode only what is kept
            if keep.any():
                st = dec.decode(chunk.raw[keep])
                self._trail.append_kept(chunk.device_time[keep],
                                        st.stack().transpose(1, 0, 2, 3))
            self._trail_cursor = chunk.stop
        return self._trail

    def history(self, taxels: list[tuple[int, int]], quantity: str = "normal",
                seconds: float | None = None) -> History:
        """The last ``seconds`` (default 10 s) of ``quantity`` at physical taxels."""
        if quantity not in QUANTITIES:
            raise ValueError(f"quantity must be one of {QUANTITIES}, got {quantity!r}")
        lay = self.layout
        names = [lay.taxel_name(r, c) for r, c in taxels] if lay else []
        units = lay.units if lay else ""
        trail = self._refresh_trail() if taxels else None  # no taxels: decode nothing
        if trail is None:
            return History(np.empty(0), np.empty((0, len(taxels)), np.float32), names,
                           quantity, units)
        t, v, t_end = trail.window(seconds or self.history_s)
        rows = np.array([r for r, _ in taxels])
        cols = np.array([c for _, c in taxels])
        if quantity == "normal":
            vals = v[:, 0, rows, cols]
        elif quantity == "shear_x":
            vals = v[:, 1, rows, cols]
        elif quantity == "shear_y":
            vals = v[:, 2, rows, cols]
        else:
            vals = np.hypot(v[:, 1, rows, cols], v[:, 2, rows, cols])
        return History(t.copy(), np.ascontiguousarray(vals), names, quantity, units, t_end)
