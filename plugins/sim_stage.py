"""The ``simulated`` stage: an indenter on a 3-axis stage over the simulated sensor.

Moves are scheduled on the simulated sensor's clock and drive its skin through
:class:`tactile_studio.simulate.indenter.Bench`; with the sensor at ``speed=0`` the
bench runs in lockstep, so a characterisation runs far faster than real time.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from tactile_studio.devices.contract import Setting
from tactile_studio.instruments.contract import InstrumentError, LabClock, StagePlugin
from tactile_studio.instruments.limits import LIMIT_SETTINGS, check_limits
from tactile_studio.simulate.indenter import Bench, SkinModel, bench_for


class SimClock(LabClock):
    """Lab time = the simulated sensor's time (its device_time column)."""

    name = "device_time"

    def __init__(self, bench: Bench) -> None:
        self.bench = bench

    def now(self) -> float:
        return self.bench.now()

    def sleep(self, seconds: float, cancel: Any = None) -> None:
        self.bench.advance_to(self.bench.now() + max(seconds, 0.0), cancel)


class SimulatedStage(StagePlugin):
    """A simulated 3-axis stage with a 14x14 mm flat indenter over the simulated skin."""

    name: ClassVar[str] = "simulated"
    description: ClassVar[str] = ("Simulated stage + flat indenter pressing and dragging the "
                                  "simulated sensor's skin (the characterisation ground truth)")
    settings_schema: ClassVar[tuple[Setting, ...]] = LIMIT_SETTINGS + (
        Setting("indenter_mm", "float", 14.0, "square indenter side, mm", minimum=1.0),
        Setting("normal_stiffness", "float", 80.0, "skin: kPa of normal stress per mm depth",
                minimum=1.0),
        Setting("shear_stiffness", "float", 1.0, "skin: kPa of shear per mm of drag",
                minimum=0.01),
        Setting("slip_offset", "float", 0.1, "fraction of the peak drag kept after return",
                minimum=0.0, maximum=0.9),
        Setting("fail_home", "bool", False, "simulate a stage that does not home"),
    )

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        self.bench: Bench | None = None
        self._homed = False

    @property
    def skin(self) -> SkinModel:
        s = self.settings
        return SkinModel(indenter_mm=s["indenter_mm"], normal_stiffness=s["normal_stiffness"],
                         shear_stiffness=s["shear_stiffness"], slip_offset=s["slip_offset"])

    def open(self) -> None:
        pass

    def close(self) -> None:
        if self.bench is not None:
            self.bench.lockstep(False)

    def couple(self, device: Any, stage: Any = None) -> None:
        sim = getattr(device, "simulator", None)
        if sim is None:
            raise InstrumentError(f"stage {self.name}: needs the simulated sensor "
                                  f"(--device simulated), not {getattr(device, 'name', device)!r}")
        self.bench = bench_for(sim, self.skin)
        # the indenter is the only thing on the bench's skin: the simulated sensor's own
        # virtual hand (its demo gestures) would press wherever it liked mid-measurement
        if getattr(device, "settings", {}).get("gesture") != "idle":
            device.set_gesture("idle")
        speed = float(getattr(device, "settings", {}).get("speed", 1.0))
        self.bench.lockstep(speed <= 0)

    def _bench(self) -> Bench:
        if self.bench is None:
            raise InstrumentError(f"stage {self.name}: not coupled to a simulated sensor")
        return self.bench

    def home(self) -> None:
        bench = self._bench()
        if self.settings["fail_home"]:
            raise InstrumentError(f"stage {self.name}: did not home (endstop never triggered)")
        bench.traj.add_move(bench.now(), (0.0, 0.0, self.settings["safe_z"]), 20.0, 200.0)
        self._homed = True
        self.wait_until_still()

    def move_to(self, x: float | None = None, y: float | None = None, z: float | None = None,
                speed: float = 2.0, acceleration: float = 50.0) -> None:
        bench = self._bench()
        if not self._homed:
            raise InstrumentError(f"stage {self.name}: move before home")
        if speed <= 0:
            raise InstrumentError(f"stage {self.name}: speed must be positive, got {speed}")
        cx, cy, cz = bench.traj.target
        tx, ty, tz = (cx if x is None else x), (cy if y is None else y), (cz if z is None else z)
        check_limits(self.name, self.settings, tx, ty, tz)
        bench.traj.add_move(bench.now(), (tx, ty, tz), speed, acceleration)

    def wait_until_still(self, timeout_s: float = 60.0) -> None:
        bench = self._bench()
        bench.advance_to(bench.traj.end_time, timeout_s=timeout_s)

    def position(self) -> tuple[float, float, float]:
        bench = self._bench()
        p = bench.traj.at(np.array([bench.now()]))[0]
        return float(p[0]), float(p[1]), float(p[2])

    def clock(self) -> LabClock:
        return SimClock(self._bench())
