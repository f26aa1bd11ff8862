"""The simulated sensor as a device plugin: real-time (or faster) ShearSense frames.

The physics lives in :mod:`tactile_studio.simulate`; this plugin only paces it against
the wall clock and makes its controls safe to call from another thread (a virtual
participant, the GUI) while the acquisition engine reads. ``device_time`` is simulated
time (frame index / rate) and ``seq`` the frame index, so faster-than-real-time runs
look exactly like real ones to everything downstream.
"""

from __future__ import annotations

import threading
import time
from typing import Any, ClassVar

import numpy as np

from tactile_studio.devices.contract import DevicePlugin, FrameBatch, Setting
from tactile_studio.errors import SettingsError, UserError
from tactile_studio.sensor.calibration import sensitivity_spread
from tactile_studio.sensor.layout import SHEARSENSE_6X6, Layout
from tactile_studio.sensor.taxels import parse_taxel
from tactile_studio.simulate import FAULTS, GESTURE_NAMES, SensorSimulator, SimConfig, weights
from tactile_studio.simulate.gestures import canonical_gesture
from tactile_studio.simulate.population import DEFAULT_DIFFICULTY, DIFFICULTIES, SURFACES
from tactile_studio.simulate.schedule import AUTO, Trial

_WAIT_S = 0.1  # longest read() blocks without a frame due
_MIN_PERIOD_S = 0.005  # real-time frames come in batches of at least this much time


class SimulatedSensor(DevicePlugin):
    """A virtual 6x6 shear+normal sensor with gestures, noise, drift and faults."""

    name: ClassVar[str] = "simulated"
    description: ClassVar[str] = (
        "Simulated ShearSense 6x6 sensor: the nine protocol gestures, viscoelasticity, "
        "noise, drift, crosstalk and optional faults")
    # labels and units are what a form shows a person; the names are --set's and the files'
    settings_schema: ClassVar[tuple[Setting, ...]] = (
        Setting("rate", "float", 43.0, "frames per second", minimum=1.0, maximum=5000.0,
                label="Frame rate", unit="Hz"),
        Setting("speed", "float", 1.0, "1 = real time, 10 = ten times faster, "
                "0 = as fast as possible", minimum=0.0, maximum=10000.0,
                label="Speed", unit="\u00d7 real time"),
        Setting("seed", "int", 0, "random seed: sensor identity (sim-N in the logbook), "
                "noise, trials", minimum=0, label="Sensor seed", unit="sim-N"),
        Setting("gesture", "str", AUTO, "auto (demo cycle), idle, or a gesture name: "
                + ", ".join(GESTURE_NAMES), label="Touches by itself",
                unit="auto, idle, a gesture"),
        Setting("intensity", "float", 1.0, "scales gesture load", minimum=0.0, maximum=5.0,
                label="Touch strength", unit="\u00d7 typical", advanced=True),
        Setting("gesture_speed", "float", 1.0, "scales gesture tempo", minimum=0.1, maximum=5.0,
                label="Touch tempo", unit="\u00d7 typical", advanced=True),
        Setting("style_seed", "int", 0, "virtual participant's personal style", minimum=0,
                label="Person's style", unit="seed", advanced=True),
        Setting("noise", "float", 20.0, "Gaussian noise, counts std", minimum=0.0, maximum=5000.0,
                label="Noise", unit="counts rms", advanced=True),
        Setting("drift", "float", 0.002, "slow baseline wander, relative amplitude",
                minimum=0.0, maximum=0.1, label="Baseline drift",
                unit="fraction of baseline", advanced=True),
        Setting("crosstalk", "float", 0.07, "shear x<->y crosstalk fraction",
                minimum=0.0, maximum=0.2, label="Shear crosstalk x\u2194y",
                unit="fraction", advanced=True),
        Setting("difficulty", "choice", DEFAULT_DIFFICULTY, "how varied virtual people are: "
                "easy (original), real (calibrated to recordings), people "
                "(real, its differences split as on real people), hard", choices=DIFFICULTIES,
                label="How people vary", advanced=True),
        Setting("surface", "choice", "flat", "flat, or a soft pillow under the sensor",
                choices=SURFACES, label="Surface under the sensor", advanced=True),
        Setting("fault", "choice", "none", "simulated defect", choices=FAULTS,
                label="Simulated fault", advanced=True),
        Setting("fault_taxel", "taxel", "C3", "taxel the fault affects: a name (A1..F6) "
                "or an index (0..35)", minimum=0, maximum=35, label="Faulty taxel",
                unit="A1..F6", advanced=True),
        Setting("sensitivity_spread", "float", 0.0, "per-taxel sensitivity spread "
                "(relative std; calibration recovers it)", minimum=0.0, maximum=0.5,
                label="Taxel sensitivity spread", unit="relative std",
                advanced=True),
        # a virtual participant's mistakes (protocol/virtual.py), for testing the checks
        Setting("mistakes", "float", 0.0, "share of a virtual participant's trials where "
                "it performs another gesture than the prompted one", minimum=0.0,
                maximum=1.0, label="Wrong gestures", unit="share of trials", advanced=True),
        Setting("light", "float", 0.0, "share of a virtual participant's trials performed "
                "far too lightly", minimum=0.0, maximum=1.0, label="Too light",
                unit="share of trials", advanced=True),
        Setting("off_centre", "float", 0.0, "share of a virtual participant's trials "
                "performed off the sensor's centre", minimum=0.0, maximum=1.0,
                label="Off centre", unit="share of trials", advanced=True),
    )

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        s = self.settings
        try:
            mode = AUTO if s["gesture"].strip().lower() == AUTO else canonical_gesture(s["gesture"])
        except ValueError as exc:
            raise SettingsError(f"device {self.name}: setting gesture: {exc}") from None
        s["gesture"] = mode
        self._sim = SensorSimulator(SimConfig(
            rate=s["rate"], seed=s["seed"], gesture=mode, intensity=s["intensity"],
            speed=s["gesture_speed"], style_seed=s["style_seed"], noise=s["noise"],
            drift=s["drift"], crosstalk=s["crosstalk"], fault=s["fault"],
            fault_taxel=self._taxel(s["fault_taxel"]), sensitivity_spread=s["sensitivity_spread"],
            difficulty=s["difficulty"], surface=s["surface"]))
        self._lock = threading.RLock()
        self._open = False
        self._t0 = 0.0        # wall clock at open
        self._f0 = 0          # frame index at open

    def _taxel(self, spec: str | int) -> int:
        """The fault_taxel setting ("C3" or 14) as an index of this sensor's array."""
        try:
            return parse_taxel(SHEARSENSE_6X6, spec)
        except UserError as exc:
            raise SettingsError(f"device {self.name}: setting fault_taxel: {exc}") from None

    # ---- contract --------------------------------------------------------------------
    @property
    def layout(self) -> Layout:
        return SHEARSENSE_6X6

    @property
    def nominal_rate_hz(self) -> float:
        return float(self.settings["rate"])

    def open(self) -> None:
        with self._lock:
            self._open = True
            self._t0 = time.monotonic()
            self._f0 = self._sim.frame

    def close(self) -> None:
        with self._lock:
            self._open = False

    def read(self, max_frames: int) -> FrameBatch:
        """Frames due by now (real-time pacing), or up to ``max_frames`` at speed 0."""
        max_frames = max(1, int(max_frames))
        speed = float(self.settings["speed"])
        n = max_frames
        external = self._sim.external  # a lockstep bench (simulate/indenter.py) paces speed 0
        if speed <= 0 and external is not None:
            n = external.allowed(self._sim.frame, max_frames, _WAIT_S)
        elif speed > 0:
            # a batch of at least _MIN_PERIOD_S of frames: the physics cost a fixed
            # ~0.2 ms per call, half a core at 1 kHz frame by frame (as a USB device
            # delivers a fast stream in packets, too)
            frames_per_s = self.nominal_rate_hz * speed
            want = max(1, min(max_frames, int(frames_per_s * _MIN_PERIOD_S)))
            deadline = time.monotonic() + _WAIT_S
            while True:
                due = self._due() - self._sim.frame
                now = time.monotonic()
                if due >= want or (due > 0 and now >= deadline):
                    n = min(max_frames, due)
                    break
                if now >= deadline:
                    return self._batch(0)
                next_at = self._t0 + (self._sim.frame + want - 1 - self._f0) / frames_per_s
                time.sleep(min(max(next_at - now, 0.0005), deadline - now))
        return self._batch(n)

    @property
    def waits_for_reader(self) -> bool:
        """At speed 0 frames are made on demand: a wellness check on a loaded machine
        lapped the ring before the engine held the simulator to its reader."""
        return float(self.settings["speed"]) <= 0

    def sensor_id(self) -> str:
        """The simulated sensor's identity comes from its seed (baselines, gains, faults)."""
        return f"sim-{self.settings['seed']}"

    def info(self) -> dict[str, Any]:
        out = super().info()
        out["simulated"] = True
        # the spread a calibration measures: the setting ``sensitivity_spread`` only adds
        # to what the simulated sensor's own per-channel gains give (about 4-5% by default)
        truth = [v for v in self.true_sensitivity() if v > 0]
        out["true_sensitivity"] = sensitivity_spread(truth)
        return out

    # ---- virtual-participant controls (thread-safe) ----------------------------------
    def perform(self, gesture: str, duration_s: float = 2.0, intensity: float | None = None,
                speed: float | None = None, at_frame: int | None = None,
                shift_mm: tuple[float, float] = (0.0, 0.0)) -> Trial:
        """Start ``gesture`` at the next frame (or at simulated frame ``at_frame``),
        ``shift_mm`` away from where the person usually touches.

        Returns the scheduled :class:`Trial` (its ``start`` is the first frame).
        Raises ValueError for an unknown gesture or a frame already generated.
        """
        with self._lock:
            return self._sim.perform(gesture, duration_s, intensity, speed, at_frame, shift_mm)

    def press(self, x_mm: float, y_mm: float, load_kpa: float, radius_mm: float = 5.0,
              shear_x: float = 0.0, shear_y: float = 0.0, duration_s: float = 2.0,
              at_frame: int | None = None) -> Trial:
        """A static press (indenter / known weight) at (x, y) mm; ground truth 'press'."""
        with self._lock:
            return self._sim.press(x_mm, y_mm, load_kpa, radius_mm, shear_x, shear_y,
                                   duration_s, at_frame=at_frame)

    def set_gesture(self, name: str, at_frame: int | None = None,
                    intensity: float | None = None, speed: float | None = None) -> None:
        """Continuous mode from the next frame (or ``at_frame``): 'auto', 'idle', or a
        gesture repeated in back-to-back 2 s trials. ``intensity``/``speed`` also become
        the defaults of later :meth:`perform` calls."""
        with self._lock:
            self._sim.set_gesture(name, at_frame, intensity, speed)
            # the settings (stored in every file recorded from here on) say what it does now
            self.settings["gesture"] = (AUTO if name.strip().lower() == AUTO
                                        else canonical_gesture(name))

    def set_style(self, seed: int, at_frame: int | None = None) -> None:
        """Become another virtual participant from the next frame (or ``at_frame``)."""
        with self._lock:
            self._sim.set_style(seed, at_frame)

    @property
    def current_gesture(self) -> str:
        """Ground truth: the gesture being performed at the newest frame delivered."""
        with self._lock:
            return self._sim.current_gesture

    def gesture_at(self, frame: int) -> str:
        """Ground truth at frame (= seq) ``frame``."""
        with self._lock:
            return self._sim.gesture_at(frame)

    def place_weight(self, mass_g: float, taxel: str, contact_mm: float = 14.0,
                     duration_s: float = 60.0, at_frame: int | None = None) -> Trial:
        """Put a known weight on ``taxel`` from ``at_frame`` (default: the next frame;
        headless wellness checks)."""
        with self._lock:
            return weights.place_weight(self._sim, mass_g, taxel, contact_mm, duration_s,
                                        at_frame=self._future(at_frame))

    def place_plate(self, mass_g: float, plate_mm: float | None = None,
                    duration_s: float = 60.0, at_frame: int | None = None) -> Trial:
        """Put a uniform plate of ``mass_g`` over the whole array from ``at_frame``."""
        with self._lock:
            return weights.place_plate(self._sim, mass_g, plate_mm, duration_s,
                                       at_frame=self._future(at_frame))

    def lift(self, trial: Trial, at_frame: int | None = None) -> int:
        """Take the weight of ``trial`` off from ``at_frame`` (default: the next frame);
        returns that frame."""
        with self._lock:
            frame = self._future(at_frame)
            weights.lift(self._sim, trial, at_frame=frame)
            return frame

    def _future(self, at_frame: int | None) -> int:
        """``at_frame``, or the next frame if that is already made (call with the lock)."""
        return self._sim.frame if at_frame is None else max(int(at_frame), self._sim.frame)

    def true_sensitivity(self) -> np.ndarray:
        """Ground truth per taxel (1 = nominal), for tests of the calibration."""
        with self._lock:
            return weights.true_sensitivity(self._sim)

    @property
    def next_frame(self) -> int:
        """The seq the next delivered frame will have (for scheduling with ``at_frame``)."""
        with self._lock:
            return self._sim.frame

    @property
    def performing_until(self) -> int:
        """The frame after the last scheduled performance ends (0: none scheduled): a
        script that lets go of one gesture before the next waits for ``next_frame`` to
        reach it."""
        with self._lock:
            return max((t.stop for t in self._sim.schedule.trials), default=0)

    @property
    def simulator(self) -> SensorSimulator:
        """The underlying generator (hold no reference across threads without the lock)."""
        return self._sim

    # ---- internals -------------------------------------------------------------------
    def _due(self) -> int:
        """Index one past the newest frame due by now (the first one is due at open)."""
        elapsed = time.monotonic() - self._t0
        return self._f0 + int(elapsed * self.nominal_rate_hz * float(self.settings["speed"])) + 1

    def _batch(self, n: int) -> FrameBatch:
        with self._lock:
            f0 = self._sim.frame
            raw = self._sim.step(n)
        seq = np.arange(f0, f0 + len(raw), dtype=np.int64)
        return FrameBatch(raw=raw, device_time=seq / self.nominal_rate_hz, seq=seq)
