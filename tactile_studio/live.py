"""What a live view shows, computed without Qt.

The GUI's timer asks a :class:`LiveView` for the newest decoded frame, a readout of one
cell and the strip-chart history; the widgets only draw the answers. Keeping this here
(not in the widgets) lets the CLI, benchmarks and tests use the same numbers, and keeps
every piece of stress maths in the core. :class:`LiveController` owns the device, the
engine and the recorder for one live screen. :class:`RateMeter` and
:class:`LatencyMeter` measure display fps and device-to-paint latency.
:func:`run_discovery` is the device panel's "Scan" (serial ports, BLE peripherals).
"""

from __future__ import annotations

import inspect
import logging
import math
import os
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.devices.engine import ERROR, AcquisitionEngine
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import UserError
from tactile_studio.sensor.decode import compute_baseline, contact_map, decode
from tactile_studio.sensor.layout import Layout
from tactile_studio.storage.recorder import Recorder

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


def parse_taxel_name(layout: Layout, name: str) -> tuple[int, int]:
    """"C4" -> (row 2, column 3): the inverse of ``Layout.taxel_name`` (UserError if bad)."""
    text = name.strip().upper()
    letters = text.rstrip("0123456789")
    digits = text[len(letters):]
    for row in range(layout.rows):
        for col in range(layout.cols):
            if layout.taxel_name(row, col) == f"{letters}{digits}":
                return row, col
    last = layout.taxel_name(layout.rows - 1, layout.cols - 1)
    raise UserError(f"no taxel {name!r} on {layout.name} (A1 .. {last})")


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

    def append(self, t: np.ndarray, v: np.ndarray) -> None:
        if len(t) == 0:
            return
        last = self.t[self.n - 1] if self.n else -math.inf
        if t[0] < last - 1e-9:          # the device clock went back (restart): start over
            self.n, last = 0, -math.inf
        # keep the first frame of every time bin of width min_dt
        bins = np.floor(t / self.min_dt)
        prev = np.empty_like(bins)
        prev[0] = math.floor(last / self.min_dt) if self.n else -math.inf
        prev[1:] = bins[:-1]
        keep = bins != prev
        t, v = t[keep], v[keep]
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

    def __init__(self, engine: AcquisitionEngine | None = None, virtual: bool = False,
                 history_s: float = 10.0, max_points: int = 2000) -> None:
        self.virtual = virtual
        self.history_s = history_s
        self.max_points = max_points
        self.engine: AcquisitionEngine | None = None
        self._cache_key: tuple | None = None
        self._cache: LiveFrame | None = None
        self.attach(engine)

    def attach(self, engine: AcquisitionEngine | None) -> None:
        """Show another engine (or none); forgets everything decoded so far."""
        self.engine = engine
        self._cache_key, self._cache = None, None
        self._cache_base: np.ndarray | None = None
        self._trail: _Trail | None = None
        self._trail_cursor = 0
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
        lay = eng.layout
        st = decode(lay, chunk.raw, base, virtual=self.virtual)
        frame = LiveFrame(
            index=chunk.start, host_time=float(chunk.host_time[-1]), normal=st.normal[0],
            shear_x=None if st.shear_x is None else st.shear_x[0],
            shear_y=None if st.shear_y is None else st.shear_y[0],
            units=st.units, virtual=self.virtual,
            contact=contact_map(lay, chunk.raw, base)[0],
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
        rebuild = (self._trail is None or self._trail_baseline is not base
                   or eng.frames - self._trail_cursor > eng.ring.capacity)
        if rebuild:
            if self._trail is None:
                self._trail = _Trail((3, lay.rows, lay.cols), self.history_s, self.max_points)
            self._trail.clear()
            rate = eng.device_rate_hz() or float(eng.device.nominal_rate_hz)
            n = min(eng.ring.capacity, int(rate * self.history_s * 1.2) + 64)
            self._trail_cursor = max(0, eng.frames - n)
            self._trail_baseline = base
        chunk = eng.read_since(self._trail_cursor)
        if len(chunk):
            st = decode(lay, chunk.raw, base)
            self._trail.append(chunk.device_time, st.stack().transpose(1, 0, 2, 3))
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
        trail = self._refresh_trail()
        if trail is None or not taxels:
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


class RateMeter:
    """Events per second over a sliding window (display fps)."""

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self._times: deque[float] = deque()

    def tick(self, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        self._times.append(now)
        while self._times and self._times[0] < now - self.window_s:
            self._times.popleft()

    def rate(self, now: float | None = None) -> float:
        now = time.monotonic() if now is None else now
        while self._times and self._times[0] < now - self.window_s:
            self._times.popleft()
        if len(self._times) < 2:
            return 0.0
        return (len(self._times) - 1) / max(now - self._times[0], 1e-9)


class LatencyMeter:
    """Device-to-paint latency: time.time() at paint minus the frame's host time."""

    def __init__(self, keep: int = 600) -> None:
        self._values: deque[float] = deque(maxlen=keep)

    def record(self, host_time: float, now: float | None = None) -> float:
        latency = (time.time() if now is None else now) - host_time
        self._values.append(latency)
        return latency

    def clear(self) -> None:
        self._values.clear()

    @property
    def values(self) -> np.ndarray:
        return np.array(self._values)

    def last(self) -> float | None:
        return self._values[-1] if self._values else None

    def percentile(self, q: float, last: int | None = None) -> float | None:
        """The q-th percentile (seconds) of all kept values or of the ``last`` ones."""
        values = self.values if last is None else self.values[-last:]
        return float(np.percentile(values, q)) if values.size else None


@dataclass
class LiveStatus:
    """Everything the device panel and status bar show about the connection."""

    device: str | None
    state: str
    error: str | None
    frames: int = 0
    measured_rate_hz: float = 0.0
    device_rate_hz: float = 0.0
    malformed: int = 0
    malformed_by_kind: dict[str, int] = field(default_factory=dict)
    dropped: int = 0
    gaps: int = 0
    reconnects: int = 0
    reconnect_attempts: int = 0
    recording: str | None = None
    recorded_frames: int = 0

    def state_text(self) -> str:
        """One line such as 'serial: reconnecting (attempt 3)' or 'No device connected'."""
        if self.device is None:
            return "No device connected"
        state = self.state
        if state == "reconnecting":
            state += f" (attempt {self.reconnect_attempts})"
        return f"{self.device}: {state}"

    def malformed_text(self) -> str:
        """Dropped input by kind, most frequent first: "3 short, 1 non_numeric" (or "none")."""
        return format_malformed(self.malformed_by_kind)

    def detail_lines(self) -> list[str]:
        """The device panel's lines under the state (empty without a device)."""
        if self.device is None:
            return []
        return [f"{self.measured_rate_hz:.1f} Hz measured · {self.frames} frames",
                f"malformed: {self.malformed_text()}",
                f"dropped {self.dropped} · gaps {self.gaps} · reconnects {self.reconnects}"
                f" (attempts {self.reconnect_attempts})"]


def format_malformed(by_kind: dict[str, int]) -> str:
    """Counts by kind as '3 short, 1 non_numeric': most frequent first, ties by name;
    'none' when nothing was dropped."""
    counts = sorted(((int(n), str(k)) for k, n in by_kind.items() if n),
                    key=lambda nk: (-nk[0], nk[1]))
    return ", ".join(f"{n} {k}" for n, k in counts) or "none"


# ---- discovery: the device panel's "Scan" -------------------------------------------
def discover_setting(cls: type[DevicePlugin] | None) -> str | None:
    """The setting a plugin can fill from a scan (duck-typed ``discover`` +
    ``discover_setting`` hooks, see docs/devices.md), or None."""
    name = getattr(cls, "discover_setting", None)
    if cls is None or not name or not callable(getattr(cls, "discover", None)):
        return None
    return name if any(s.name == name for s in cls.settings_schema) else None


def discover_is_instant(cls: type[DevicePlugin]) -> bool:
    """True when ``discover`` waits for nothing (its ``timeout`` defaults to 0, as for
    serial ports), so a panel may run it as soon as the plugin is chosen; a radio scan
    (BLE) runs only when asked."""
    timeout = inspect.signature(cls.discover).parameters.get("timeout")
    return timeout is None or timeout.default in (0, 0.0)


def discover_kwargs(cls: type[DevicePlugin], texts: dict[str, str]) -> dict[str, Any]:
    """Arguments for ``cls.discover`` from the settings form: parameters named like a
    setting take its value (``timeout`` takes ``scan_timeout``); a value that does not
    parse is left out, so the hook's default applies (the form shows the error)."""
    schema = {s.name: s for s in cls.settings_schema}
    out: dict[str, Any] = {}
    for param in inspect.signature(cls.discover).parameters:
        key = "scan_timeout" if param == "timeout" and "scan_timeout" in schema else param
        setting = schema.get(key)
        if setting is None or key == discover_setting(cls):
            continue
        text = texts.get(key, "")
        try:
            out[param] = setting.default if text == "" else setting.parse(text, cls.name)
        except UserError:
            continue
    return out


def run_discovery(cls: type[DevicePlugin],
                  texts: dict[str, str]) -> tuple[list[tuple[str, str]], str | None]:
    """Scan with the form's settings: ((value, label) choices, None) or ([], one-line
    error). Blocks (a BLE scan listens for seconds): call it from a worker thread."""
    try:
        found = cls.discover(**discover_kwargs(cls, texts))
    except UserError as exc:
        return [], " ".join(str(exc).split())
    except Exception as exc:  # a plugin bug: full traceback in the log, one line shown
        logging.getLogger(__name__).error("device discovery failed", exc_info=exc)
        return [], f"{cls.name}: scan failed ({type(exc).__name__}: {exc})"
    return [(str(value), str(label)) for value, label in found], None


class LiveController:
    """Connect/disconnect a device, tare, and record: the live screen's verbs, Qt-free."""

    def __init__(self) -> None:
        self.engine: AcquisitionEngine | None = None
        self.recorder: Recorder | None = None
        self.device_name: str | None = None
        self.settings: dict[str, Any] = {}

    def connect(self, name: str, settings: dict[str, Any] | None = None) -> AcquisitionEngine:
        """Start streaming from a plugin. Bad settings raise SettingsError at once;
        failing to open shows later as ``engine.state == "error"``."""
        device = create_device(name, settings or {})
        self.disconnect()
        self.device_name, self.settings = name, dict(device.settings)
        self.engine = AcquisitionEngine(device)
        self.engine.start()
        return self.engine

    def disconnect(self) -> None:
        self.stop_recording()
        if self.engine is not None:
            self.engine.stop()

    def tare(self) -> None:
        if self.engine is not None:
            self.engine.tare()

    def start_recording(self, path: str | os.PathLike,
                        metadata: dict[str, Any] | None = None) -> Recorder:
        """Record everything from now on into a new session file (SessionFileError)."""
        if self.engine is None or not self.engine.running:
            raise UserError("connect a device before recording")
        self.stop_recording()
        self.recorder = Recorder(self.engine, path, metadata).start()
        return self.recorder

    def stop_recording(self) -> str | None:
        """Finish the file; returns its path (None if nothing was recording)."""
        rec, self.recorder = self.recorder, None
        if rec is None:
            return None
        rec.stop()
        return str(rec.path)

    def status(self) -> LiveStatus:
        eng = self.engine
        if eng is None:
            return LiveStatus(None, "disconnected", None)
        c = eng.counters()
        rec = self.recorder
        return LiveStatus(
            device=self.device_name, state=eng.state,
            error=eng.error if eng.state == ERROR else None,
            frames=c["frames"], measured_rate_hz=eng.measured_rate_hz(),
            device_rate_hz=eng.device_rate_hz(), malformed=c["malformed"],
            malformed_by_kind=c["malformed_by_kind"],
            dropped=c["missing_frames"] + (rec.dropped if rec else 0), gaps=c["gaps"],
            reconnects=c["reconnects"], reconnect_attempts=eng.reconnect_attempts,
            recording=str(rec.path) if rec else None,
            recorded_frames=rec.writer.n_frames if rec else 0)
