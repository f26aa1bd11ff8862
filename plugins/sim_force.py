"""The ``simulated`` load cell: the true force of the simulated indenter, plus noise.

It reports at the simulated sensor's frame instants on the sensor's clock, so the
characterisation compares sensor and force sample for sample.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from tactile_studio.devices.contract import Setting
from tactile_studio.instruments.contract import ForcePlugin, ForceSamples, InstrumentError
from tactile_studio.simulate.indenter import Bench, bench_for


class SimulatedForce(ForcePlugin):
    """A 3-axis load cell under the simulated indenter (the reference the paper used)."""

    name: ClassVar[str] = "simulated"
    description: ClassVar[str] = "Simulated 3-axis load cell reading the simulated indenter"
    settings_schema: ClassVar[tuple[Setting, ...]] = (
        Setting("noise_n", "float", 0.002, "Gaussian noise, N (std)", minimum=0.0),
        Setting("seed", "int", 0, "noise seed", minimum=0),
        Setting("silent", "bool", False, "simulate a load cell that sends nothing"),
    )

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        self.bench: Bench | None = None
        self._offset = np.zeros(3)
        self._rng = np.random.default_rng(self.settings["seed"])

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def couple(self, device: Any, stage: Any = None) -> None:
        sim = getattr(device, "simulator", None)
        if sim is None:
            raise InstrumentError(f"force {self.name}: needs the simulated sensor "
                                  f"(--device simulated), not {getattr(device, 'name', device)!r}")
        self.bench = getattr(stage, "bench", None) or bench_for(sim)

    def read(self) -> ForceSamples:
        if self.bench is None:
            raise InstrumentError(f"force {self.name}: not coupled to a simulated sensor")
        t, f = self.bench.forces_since()
        if self.settings["silent"]:
            return ForceSamples.empty()
        f = f + self._rng.normal(0.0, self.settings["noise_n"], f.shape) - self._offset
        return ForceSamples(t, f)

    def tare(self) -> None:
        samples = self.read()
        if len(samples):
            self._offset = self._offset + samples.f[-min(len(samples), 20):].mean(axis=0)
