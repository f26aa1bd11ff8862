"""The bench: rest, place a weight, wait for it to settle, record, lift, over a live engine.

Both the wellness check and the calibration are sequences of these steps, driven from
the CLI or a wizard alike. Steps count *frames*, not wall-clock time, so a simulated
device at ``speed=0`` runs a whole check in a second; every wait is still bounded by a
wall-clock stall limit. A :class:`Placer` puts the weights on (the simulated device can
do it itself for ``--auto``); without one, a person does and the bench detects it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.devices.frame_stream import ERROR, FINISHED, STOPPED, LiveStream
from tactile_studio.errors import Cancelled, DeviceError, UserError
from tactile_studio.health.events import HealthEvent, Misplaced, Phase, Warned
from tactile_studio.jobs import CancelToken
from tactile_studio.sensor.wellness import contact_taxel, is_settled, normal_map, taxel_label

EventFn = Callable[[HealthEvent], None]  # health/events.py: what a follower is told


class WeightNotDetected(UserError):
    """No weight (or the weight in the wrong place) when one was expected."""


class DeviceStopped(DeviceError):
    """The device disconnected or stopped delivering frames during a check."""


@dataclass(frozen=True)
class Timing:
    """Phase lengths in seconds of *device* time (frames / rate)."""

    rest_s: float = 3.0
    place_timeout_s: float = 30.0
    settle_min_s: float = 2.0
    settle_max_s: float = 12.0
    settle_tolerance_per_s: float = 0.005
    record_s: float = 1.5
    lift_timeout_s: float = 30.0
    stall_s: float = 10.0  # wall-clock limit without any frame


class Placer:
    """Puts weights on and takes them off; the base class is a person (does nothing)."""

    confirmed = False  # True: trust that the weight is on even if the sensor cannot see it

    def prepare(self) -> int | None:
        """Get the device ready; returns the first frame seq worth using (or None)."""
        return None

    def place(self, mass_g: float, taxel: str | None, contact_mm: float) -> int | None:
        """Put ``mass_g`` on ``taxel`` (None: a plate over the array); returns its seq."""
        return None

    def lift(self) -> int | None:
        return None


# How far a speed-0 simulator may run ahead of the check. Its weights go on and off this
# far after the last frame the check read (plus the handling time), so every step happens
# at the same device frame however the threads were scheduled: before, they went on at the
# simulator's next frame, anywhere up to 95 s ahead, and a loaded machine shortened the
# rest between weights until a viscoelastic residue spoiled a calibration fit.
LEAD_FRAMES = 256


class SimulatedPlacer(Placer):
    """The simulated device places the weight itself (``--auto``)."""

    confirmed = True
    HANDLING_S = 2.0  # between lifting one weight and placing the next, as a person would
    # creep 0.2 with a 3 s relaxation: 5 s still left 4% of a gesture's load, enough to
    # lift the baseline over the lightest calibration weight's response (seen under load,
    # where the check began in the demo cycle varies); 20 s leaves 2.5e-4 of it
    RESIDUE_FADE_S = 20.0

    def __init__(self, device: Any) -> None:
        if not hasattr(device, "place_weight"):
            raise UserError(f"device {device.name} cannot place weights itself: --auto "
                            "needs the simulated device")
        self.device = device
        self._trial = None
        self._bench: Bench | None = None

    def prepare(self) -> int:
        busy = self.device.settings.get("gesture") != "idle"
        self.device.set_gesture("idle")
        # idle holds from the frame the simulator was at during set_gesture, so read it
        # after: read before, a loaded machine let a whole batch of demo-cycle frames in
        # between (seen as a "noisy" channel on a healthy sensor)
        start = int(self.device.next_frame)
        # a gesture in progress leaves a viscoelastic residue: let it fade first
        return start + (int(self.RESIDUE_FADE_S * self.device.nominal_rate_hz) if busy else 0)

    def place(self, mass_g: float, taxel: str | None, contact_mm: float) -> int:
        at = self._frame_after(self.HANDLING_S)
        if taxel is None:
            self._trial = self.device.place_plate(mass_g, at_frame=at)
        else:
            self._trial = self.device.place_weight(mass_g, taxel, contact_mm, at_frame=at)
        return int(self._trial.start)

    def lift(self) -> int | None:
        if self._trial is None:
            return None
        trial, self._trial = self._trial, None
        return int(self.device.lift(trial, at_frame=self._frame_after(0.0)))

    def _frame_after(self, seconds: float) -> int | None:
        """The device frame for the next step: ``seconds`` after the lead beyond what the
        check has read when the simulator is paced by it (speed 0), else None (the next
        frame; the device also takes the next frame if this one is already made)."""
        bench = self._bench
        paced = float(self.device.settings.get("speed", 1.0)) <= 0
        if bench is None or bench.next_seq is None or not paced:
            return None
        return bench.next_seq + LEAD_FRAMES + int(round(seconds * self.device.nominal_rate_hz))

    def attach(self, bench: Bench) -> None:
        """At speed 0 the simulator runs at most ``LEAD_FRAMES`` ahead of the check, so a
        loaded machine slows the check down instead of making it lose frames."""
        self._bench = bench
        bench.engine.hold(lambda: bench.cursor, lead=LEAD_FRAMES)


class Bench:
    """Frames from an engine, read in order, and the load steps over them."""

    def __init__(self, engine: LiveStream, placer: Placer | None = None,
                 timing: Timing = Timing(), cancel: CancelToken | None = None,
                 on_event: EventFn | None = None) -> None:
        self.engine, self.layout = engine, engine.layout
        self.placer = placer or Placer()
        self.timing = timing
        self.cancel = cancel or CancelToken()
        self.on_event: EventFn = on_event or (lambda event: None)
        self.rate = engine.nominal_rate_hz
        self.baseline: np.ndarray | None = None
        self._cursor = engine.frames
        self._next_seq: int | None = None
        self._skip_before = -1
        self._confirm = threading.Event()
        attach = getattr(self.placer, "attach", None)
        if attach is not None:
            attach(self)

    @property
    def cursor(self) -> int:
        """The next engine frame the check will read."""
        return self._cursor

    @property
    def next_seq(self) -> int | None:
        """The device seq after the last frame the check read (None before any)."""
        return self._next_seq

    def frames(self, seconds: float) -> int:
        return max(1, int(round(seconds * self.rate)))

    def emit(self, event: HealthEvent) -> None:
        self.on_event(event)

    def confirm_placed(self) -> None:
        """The person says the weight is on although the sensor does not see it."""
        self._confirm.set()

    # ---- reading ---------------------------------------------------------------------
    def read(self, max_frames: int = 16) -> tuple[np.ndarray, np.ndarray]:
        """The next frames (raw, seq); raises DeviceStopped, Cancelled. Small chunks by
        default, so phase changes are seen within a fraction of a second of device time."""
        waited = time.monotonic()
        while True:
            self.cancel.check()
            chunk = self.engine.read_since(self._cursor, max_frames)
            if chunk.lost:
                raise DeviceStopped(f"the check fell {chunk.lost} frames behind device "
                                    f"{self.engine.device_name} and lost them (use a finite "
                                    "speed); nothing was stored")
            if len(chunk):
                self._cursor = chunk.stop
                self._next_seq = int(chunk.seq[-1]) + 1
                keep = chunk.seq >= self._skip_before
                if keep.any():
                    return chunk.raw[keep], chunk.seq[keep]
                waited = time.monotonic()
                continue
            state = self.engine.state
            if state in (ERROR, FINISHED, STOPPED):
                why = self.engine.error or state
                raise DeviceStopped(f"device {self.engine.device_name} stopped during the "
                                    f"check ({why}); nothing was stored")
            if time.monotonic() - waited > self.timing.stall_s:
                lost = self.engine.lost_reason()
                if lost is not None:
                    raise DeviceStopped(f"device {self.engine.device_name}: {lost}; not back "
                                        f"within {self.timing.stall_s:g} s, nothing was stored")
                raise DeviceStopped(f"device {self.engine.device_name} sent no frames for "
                                    f"{self.timing.stall_s:g} s; nothing was stored")
            if self.cancel.wait(0.01):
                raise Cancelled("cancelled")

    def take(self, n: int) -> np.ndarray:
        parts, got = [], 0
        while got < n:
            raw, _ = self.read(n - got)
            parts.append(raw)
            got += len(parts[-1])
        return np.concatenate(parts).astype(np.float64)

    # ---- steps -----------------------------------------------------------------------
    def rest(self) -> np.ndarray:
        """Unloaded frames; their mean becomes the baseline for the loaded steps."""
        start = self.placer.prepare()
        if start is not None:
            self._skip_before = start
        self.emit(Phase("rest", f"Hands off: reading noise and baseline for "
                                f"{self.timing.rest_s:g} s"))
        raw = self.take(self.frames(self.timing.rest_s))
        self.baseline = raw.mean(axis=0)
        return raw

    def load(self, mass_g: float, taxel: int | None, expected_kpa: float,
             contact_mm: float = 14.0, recover: float = 0.3) -> np.ndarray:
        """Place, settle, record and lift; returns the recorded settled frames."""
        if self.baseline is None:
            raise RuntimeError("rest() must come first")
        lay, t = self.layout, self.timing
        where = taxel_label(lay, taxel) if taxel is not None else "the whole array (plate)"
        self._confirm.clear()
        seq0 = self.placer.place(mass_g, taxel_label(lay, taxel) if taxel is not None else None,
                                 contact_mm)
        self.emit(Phase("place", f"Place {mass_g:g} g on {where}", where))
        level = self._wait_placed(taxel, expected_kpa, seq0)
        self.emit(Phase("settle", "Hold still: settling", where))
        series = list(level)
        settled_after = None
        while settled_after is None:
            raw, _ = self.read()
            series.extend(self._level(raw, taxel))
            n = len(series)
            if n >= self.frames(t.settle_min_s) and is_settled(
                    np.array(series), self.rate, 1.0, t.settle_tolerance_per_s):
                settled_after = n
            elif n >= self.frames(t.settle_max_s):
                settled_after = n
                self.emit(Warned(f"{where}: did not settle within {t.settle_max_s:g} s"))
        self.emit(Phase("record", "Recording", where))
        recorded = self.take(self.frames(t.record_s))
        held = float(np.mean(self._level(recorded, taxel)))
        settled = float(np.mean(series[-self.frames(0.5):]))
        if settled > 0.3 and held < 0.7 * settled:
            raise WeightNotDetected(f"the weight moved or was lifted off {where} while "
                                    "recording; nothing was stored")
        self._lift(taxel, held, where, recover)
        return recorded

    # ---- internals -------------------------------------------------------------------
    def _level(self, raw: np.ndarray, taxel: int | None) -> np.ndarray:
        """Per frame: the target taxel's normal stress, or the array's mean for a plate."""
        grid = normal_map(self.layout, raw, self.baseline)
        if taxel is None:
            return grid.reshape(len(grid), -1).mean(axis=1)
        r, c = self.layout.taxel_rc(taxel)
        return grid[:, r, c]

    def _wait_placed(self, taxel: int | None, expected_kpa: float,
                     seq0: int | None) -> list[float]:
        lay, limit = self.layout, self.frames(self.timing.place_timeout_s)
        threshold = max(0.3 * expected_kpa, 0.2)
        seen, run, told, last = 0, 0, None, np.zeros((0, lay.rows, lay.cols))
        quiet = np.zeros((0, lay.n_channels))  # unloaded frames just before the placement
        keep_quiet = self.frames(1.0)
        while True:
            raw, seq = self.read()
            if seq0 is not None:
                counted = int((seq >= seq0).sum())
            else:
                counted = len(raw)
            grid = normal_map(lay, raw, self.baseline)
            last = np.concatenate([last, grid])[-5:]
            smooth = last.mean(axis=0)
            if taxel is None:
                on = float(np.median(smooth)) > threshold
                at = None
            else:
                at = contact_taxel(lay, smooth, threshold)
                on = at == taxel
            before = seq < seq0 if seq0 is not None else np.full(len(raw), at is None and not on)
            quiet = np.concatenate([quiet, raw[before]])[-keep_quiet:]
            run = run + len(raw) if on else 0
            if run >= 3:
                self._rebaseline(quiet, manual=seq0 is None)
                return list(self._level(raw, taxel)[-3:])
            if at is not None and at != taxel and at != told:
                told = at
                self.emit(Misplaced(taxel_label(lay, at),
                                    f"The weight is on {taxel_label(lay, at)}, not on "
                                    f"{taxel_label(lay, taxel)}: move it"))
            seen += counted
            if self._confirm.is_set() and at is None:
                return [0.0]
            if seen >= limit:
                if at is not None and at != taxel:
                    raise WeightNotDetected(
                        f"the weight is on {taxel_label(lay, at)}, not on "
                        f"{taxel_label(lay, taxel)}; nothing was stored")
                if self.placer.confirmed:
                    return [0.0]  # the weight is on but the sensor cannot feel it: dead
                where = taxel_label(lay, taxel) if taxel is not None else "the array"
                raise WeightNotDetected(f"no weight detected on {where} within "
                                        f"{self.timing.place_timeout_s:g} s; nothing was stored")

    def _recovered(self, recent: np.ndarray, held: float, recover: float) -> bool:
        """Off, and (for ``recover`` < 0.1) the viscoelastic residue has stopped moving:
        it then changes by less than ``recover`` of the held load per second. (Measured
        by slope, not level: slow baseline drift must not keep a check waiting.)"""
        if float(recent.mean()) >= 0.3 * held:
            return False
        if recover >= 0.1:
            return True
        t = np.arange(len(recent)) / self.rate
        slope, icpt = np.polyfit(t, recent, 1)
        # a slope is only measurable down to a few standard errors of the noise
        se = float(np.std(recent - (slope * t + icpt)) / np.sqrt(((t - t.mean()) ** 2).sum()))
        return abs(float(slope)) < max(recover * held, 4.0 * se)

    def _rebaseline(self, quiet: np.ndarray, manual: bool) -> None:
        """Re-zero on the unloaded frames right before this placement, so slow baseline
        drift over a long session does not bias small loads (a person's hand may already
        be near: drop the last 0.3 s then)."""
        if manual:
            quiet = quiet[: max(0, len(quiet) - self.frames(0.3))]
        if len(quiet) >= self.frames(0.3):
            self.baseline = quiet[-self.frames(0.5):].astype(np.float64).mean(axis=0)

    def _lift(self, taxel: int | None, held: float, where: str, recover: float) -> None:
        """Wait until the load is off and the response has recovered to ``recover`` x."""
        seq0 = self.placer.lift()
        self.emit(Phase("lift", f"Lift the weight off {where}", where))
        limit, seen = self.frames(self.timing.lift_timeout_s), 0
        window = self.frames(1.0 if recover >= 0.1 else 3.0)
        recent = np.zeros(0)
        while True:
            raw, seq = self.read()
            level = self._level(raw, taxel)
            if seq0 is not None:
                level = level[seq >= seq0]
            seen += len(level)
            recent = np.concatenate([recent, level])[-window:]
            if seen >= window and (held <= 0.3 or self._recovered(recent, held, recover)):
                return
            if seen >= limit:
                raise WeightNotDetected(f"the weight was not lifted off {where} within "
                                        f"{self.timing.lift_timeout_s:g} s; nothing was stored")
