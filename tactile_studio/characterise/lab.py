"""The lab during a run: sensor stream, load-cell stream and journal on one clock.

:class:`Lab` owns the device's stream (``open_stream``) and the recorder (one session
file), pulls the sensor frames and the load-cell samples it needs for each measurement,
and journals every stage move, load-cell batch and measured point into the session (see
docs/session-format.md, "Characterisation records").
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.acquisition.file_sink import close_file_sink, open_file_sink
from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.errors import IncompleteError
from tactile_studio.instruments.contract import ForcePlugin, InstrumentError, StagePlugin
from tactile_studio.jobs import CancelToken
from tactile_studio.sensor.characterise import neighbours, still_moving, taxel_signals
from tactile_studio.sensor.decode import relative_change
from tactile_studio.sensor.layout import CENTRE

_KEEP_S = 120.0  # how much recent sensor/force history a measurement can look back on
_STEADY_WINDOW_S = 3.0  # the stretch whose slope says whether the skin still moves


@dataclass
class Reading:
    """Means over a window: per-taxel sensor signals and the load cell (N and kPa)."""

    t0: float
    t1: float
    normal: np.ndarray   # (n_taxels,) relative change
    shear_x: np.ndarray
    shear_y: np.ndarray
    force_n: np.ndarray  # (3,) fx, fy, fz
    stress_kpa: np.ndarray  # (3,) force over the indenter face


@dataclass
class Settled:
    """One wait for a settled skin before a tare: how long, and whether it got there."""

    taxel: str
    waited_s: float
    steady: bool


class Lab:
    """Sensor + stage + load cell, recording to ``session_path`` on the stage's clock."""

    def __init__(self, device: DevicePlugin, stage: StagePlugin, force: ForcePlugin,
                 session_path: Path, indenter_area_mm2: float, cancel: CancelToken,
                 metadata: dict[str, Any]) -> None:
        self.device, self.stage, self.force, self.cancel = device, stage, force, cancel
        self.layout = device.layout
        self.area_mm2 = indenter_area_mm2
        self.clock = stage.clock()
        self.engine = open_stream(device)
        self.engine.start()
        self.recorder = open_file_sink(self.engine, session_path, {
            **metadata, "characterisation_clock": self.clock.name})
        self._cursor = self.engine.frames
        self._t = np.empty(0)
        self._raw = np.empty((0, self.layout.n_channels), dtype=self.layout.raw_dtype)
        self._ft = np.empty(0)
        self._ff = np.empty((0, 3))
        self.baseline: np.ndarray | None = None
        self.on_point: Any = None  # callable(taxel name, point dict) for a live plot
        self.on_settled: Any = None  # callable(Settled) after every settling wait
        self.settles: list[Settled] = []  # this taxel's waits (the run resets it)

    # ---- journal ---------------------------------------------------------------------
    def event(self, kind: str, **detail: Any) -> None:
        """A journal event stamped with lab time (``lab_t``) and host time."""
        self.recorder.event(kind, lab_t=round(self.clock.now(), 6), **detail)

    def close(self) -> None:
        close_file_sink(self.recorder)
        self.engine.stop()

    # ---- streams ---------------------------------------------------------------------
    def _pull_frames(self) -> None:
        chunk = self.engine.read_since(self._cursor)
        if not len(chunk):
            return
        self._cursor = chunk.stop
        t = chunk.device_time if self.clock.name == "device_time" else chunk.host_time
        self._t = np.concatenate([self._t, t])
        self._raw = np.concatenate([self._raw, chunk.raw])
        keep = self._t >= self._t[-1] - _KEEP_S
        self._t, self._raw = self._t[keep], self._raw[keep]

    def _pull_forces(self) -> None:
        s = self.force.read()
        if len(s):
            self.event("force", t=np.round(s.t, 6), f=np.round(s.f, 5))
            self._ft = np.concatenate([self._ft, s.t])
            self._ff = np.concatenate([self._ff, s.f])
            keep = self._ft >= self._ft[-1] - _KEEP_S
            self._ft, self._ff = self._ft[keep], self._ff[keep]

    def frames_between(self, t0: float, t1: float,
                       timeout_s: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
        """Sensor frames with lab time in [t0, t1), waiting (bounded) for them to arrive."""
        deadline = time.monotonic() + timeout_s
        period = 1.0 / max(self.device.nominal_rate_hz, 1.0)
        while True:
            if self.recorder.write_error:  # disk full: stop, never measure into a dead file
                raise IncompleteError(f"{self.recorder.write_error}; characterisation "
                                      "stopped (what was measured is kept)")
            self._pull_frames()
            if len(self._t) and self._t[-1] >= t1 - 1.5 * period:
                break
            if not self.engine.running and self.engine.state != "idle":
                raise InstrumentError(f"sensor {self.device.name}: stopped streaming "
                                      f"({self.engine.error or self.engine.state})")
            if time.monotonic() > deadline:
                raise InstrumentError(f"sensor {self.device.name}: no frames for {timeout_s:.0f} s")
            self.cancel.check()
            time.sleep(0.002)
        sel = (self._t >= t0) & (self._t < t1)
        return self._t[sel], self._raw[sel]

    def tare(self, seconds: float = 1.0) -> None:
        """Sensor baseline = mean of the last ``seconds``; zero the load cell too."""
        now = self.clock.now()
        _, raw = self.frames_between(now - seconds, now)
        if not len(raw):
            raise InstrumentError(f"sensor {self.device.name}: no frames to tare on")
        self.baseline = raw.astype(np.float64).mean(axis=0)
        self.recorder.add_baseline(self.baseline)
        self._pull_forces()
        self.force.tare()
        self._ft, self._ff = np.empty(0), np.empty((0, 3))
        self.event("char_tare")

    def wait_steady(self, taxel: int, min_s: float, max_s: float, per_s: float) -> Settled:
        """Wait ``min_s`` of lab time, then on until the skin under and around ``taxel``
        has stopped moving (a previous press's viscoelastic residue, a previous taxel's
        cycles): the centre channels of it and its neighbours change by less than
        ``per_s`` (relative change per second) over the last few seconds. At most
        ``max_s``; then it is measured anyway and the wait says it was not steady. Every
        wait is journaled (``char_settled``) so a figure's history is on record."""
        start = self.clock.now()
        self.clock.sleep(min_s, self.cancel)
        lay = self.layout
        centres = [lay.channel(t, CENTRE) for t in (taxel, *neighbours(lay, taxel).values())]
        window = min(_STEADY_WINDOW_S, max(min_s, 0.5))
        while True:
            now = self.clock.now()
            t, raw = self.frames_between(now - window, now)
            rel = relative_change(lay, raw, raw.astype(np.float64).mean(axis=0))[:, centres]
            steady = not still_moving(t, rel, per_s).any()
            if steady or now - start >= max_s:
                break
            self.clock.sleep(0.5, self.cancel)
        done = Settled(lay.taxel_name(*lay.taxel_rc(taxel)), round(now - start, 2), steady)
        self.event("char_settled", taxel=done.taxel, waited_s=done.waited_s, steady=steady)
        self.settles.append(done)
        if self.on_settled is not None:
            self.on_settled(done)
        return done

    def signals(self, t0: float, t1: float) -> tuple[np.ndarray, ...]:
        """(t, normal, shear_x, shear_y) per frame in [t0, t1), against the current tare."""
        t, raw = self.frames_between(t0, t1)
        normal, sx, sy = taxel_signals(self.layout, raw, self.baseline)
        return t, normal, sx, sy

    def hold(self, seconds: float, window_s: float) -> Reading:
        """Wait ``seconds`` of lab time, then average the last ``window_s`` of it."""
        self.clock.sleep(seconds, self.cancel)
        t1 = self.clock.now()
        return self.read_window(t1 - min(window_s, seconds) if seconds > 0 else t1 - window_s, t1)

    def read_window(self, t0: float, t1: float) -> Reading:
        _, normal, sx, sy = self.signals(t0, t1)
        self._pull_forces()
        sel = (self._ft >= t0 - 1e-9) & (self._ft < t1 + 1e-9)
        if not np.any(sel):  # a slow load cell: its newest samples up to 0.5 s before
            sel = (self._ft >= t0 - 0.5) & (self._ft < t1 + 1e-9)
        deadline = time.monotonic() + 2.0
        while not np.any(sel) and time.monotonic() < deadline:
            time.sleep(0.05)  # give the plugin the chance to say why (unplugged, garbage)
            self._pull_forces()
            sel = (self._ft >= t0 - 0.5) & (self._ft < t1 + 1e-9)
        if not np.any(sel):
            raise InstrumentError(f"force {self.force.name}: no load-cell samples between "
                                  f"{t0:.2f} and {t1:.2f} s (is it connected and streaming?)")
        f = self._ff[sel].mean(axis=0)
        return Reading(t0, t1, normal.mean(axis=0), sx.mean(axis=0), sy.mean(axis=0), f,
                       f / self.area_mm2 * 1e3)

    def move(self, x: float | None = None, y: float | None = None, z: float | None = None,
             speed: float = 2.0, acceleration: float = 50.0) -> None:
        """Move and wait until still, journaling the target."""
        self.cancel.check()
        self.stage.move_to(x, y, z, speed, acceleration)
        self.stage.wait_until_still()
        pos = self.stage.position()
        self.event("stage", x=round(pos[0], 4), y=round(pos[1], 4), z=round(pos[2], 4),
                   speed=speed)

    def retract(self) -> None:
        """Lift the indenter clear (abort, pause) and journal where it ended."""
        self.stage.retract()
        x, y, z = self.stage.position()
        self.event("stage", x=round(x, 4), y=round(y, 4), z=round(z, 4), retract=True)
