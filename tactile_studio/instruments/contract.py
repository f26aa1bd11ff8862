"""The instrument-plugin contracts: a positioning stage and a force reference.

They sit beside device plugins and follow the same pattern (a class registered under an
entry-point group, a settings schema of :class:`~tactile_studio.devices.contract.Setting`,
one-line ``UserError``\\ s). The characterisation procedure drives them::

    stage = Stage(**settings); stage.open(); stage.couple(device); stage.home()
    stage.move_to(x=.., y=.., z=.., speed=2.0, acceleration=50.0); stage.wait_until_still()
    force = Force(**settings); force.open(); force.couple(device, stage); force.tare()
    samples = force.read()            # every sample since the last read
    ...; stage.retract(); stage.close(); force.close()

Coordinates are millimetres in the sensor's frame (x, y from the centre of taxel A1 as
:meth:`Layout.taxel_centre_mm`; z up, 0 at the skin surface, negative = indenting).
Forces are newtons, +z pressing into the skin, x/y the traction the indenter applies.
Times come from the stage's :class:`LabClock`: the simulated bench runs on the
simulated sensor's clock, real instruments on the host clock (``time.time()``).
"""

from __future__ import annotations

import abc
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from tactile_studio.errors import Cancelled, UserError
from tactile_studio.plugin_settings import Setting, validate_settings


class InstrumentError(UserError):
    """An instrument refused, failed or went away (one line naming it)."""


class SoftLimitError(InstrumentError):
    """A move would leave the stage's soft limits (e.g. below the indenter floor)."""


class LabClock:
    """The clock every instrument record of a run is stamped with (host wall clock)."""

    name: str = "host_time"

    def now(self) -> float:
        return time.time()

    def sleep(self, seconds: float, cancel: Any = None) -> None:
        """Wait ``seconds`` of lab time; raises Cancelled if ``cancel`` is set meanwhile."""
        if cancel is not None:
            if cancel.wait(max(seconds, 0.0)):
                raise Cancelled("cancelled")
        else:
            time.sleep(max(seconds, 0.0))


@dataclass
class ForceSamples:
    """Timestamped forces: ``t`` (n,) lab-clock seconds, ``f`` (n, 3) fx, fy, fz in N."""

    t: np.ndarray
    f: np.ndarray
    malformed: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @classmethod
    def empty(cls) -> ForceSamples:
        return cls(np.empty(0), np.empty((0, 3)))


class _Instrument(abc.ABC):
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    settings_schema: ClassVar[tuple[Setting, ...]] = ()
    kind: ClassVar[str] = "instrument"

    def __init__(self, **settings: Any) -> None:
        self.settings = self.validate_settings(settings)

    @classmethod
    def validate_settings(cls, settings: dict[str, Any]) -> dict[str, Any]:
        """Defaults filled in, every value parsed and range-checked, unknown keys refused."""
        return validate_settings(cls.settings_schema, settings, cls.name, cls.kind)

    @abc.abstractmethod
    def open(self) -> None:
        """Connect; raise InstrumentError (one line) if impossible."""

    @abc.abstractmethod
    def close(self) -> None:
        """Disconnect; safe to call twice or after a failed open."""

    def couple(self, device: Any, stage: Any = None) -> None:
        """Called once with the sensor device (and, for a force reference, the stage)
        before use. Simulated instruments bind to the simulated sensor; real ones ignore it."""

    def info(self) -> dict[str, Any]:
        return {"plugin": self.name, "settings": dict(self.settings)}


class StagePlugin(_Instrument):
    """A positioning stage carrying the indenter (flexure stage, 3D printer, CNC)."""

    kind: ClassVar[str] = "stage"

    @abc.abstractmethod
    def home(self) -> None:
        """Find the reference position; InstrumentError if the stage does not home."""

    @abc.abstractmethod
    def move_to(self, x: float | None = None, y: float | None = None, z: float | None = None,
                speed: float = 2.0, acceleration: float = 50.0) -> None:
        """Start a move to the absolute position (mm, None = keep the axis) at ``speed``
        mm/s and ``acceleration`` mm/s². SoftLimitError before moving if out of limits."""

    def move_by(self, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0, speed: float = 2.0,
                acceleration: float = 50.0) -> None:
        """A relative move (the same limits apply)."""
        x, y, z = self.position()
        self.move_to(x + dx, y + dy, z + dz, speed, acceleration)

    @abc.abstractmethod
    def wait_until_still(self, timeout_s: float = 60.0) -> None:
        """Block until every commanded move has finished (InstrumentError on timeout)."""

    @abc.abstractmethod
    def position(self) -> tuple[float, float, float]:
        """Current (x, y, z) in mm (the commanded target once still)."""

    def retract(self) -> None:
        """Lift the indenter clear of the skin at once (abort path); must not raise for a
        stage that is still connected."""
        x, y, _ = self.position()
        self.move_to(x, y, float(self.settings.get("safe_z", 5.0)), speed=10.0)
        self.wait_until_still()

    def clock(self) -> LabClock:
        """The clock instrument records are stamped with (default: host time)."""
        return LabClock()


class ForcePlugin(_Instrument):
    """A force reference (multi-axis load cell, amplifier board, HX711 bridge)."""

    kind: ClassVar[str] = "force"

    @abc.abstractmethod
    def read(self) -> ForceSamples:
        """Every sample received since the last call (may be empty; never blocks long).
        InstrumentError when the load cell is silent or sends only garbage."""

    @abc.abstractmethod
    def tare(self) -> None:
        """Zero the current reading (the indenter's weight, the bridge's offset)."""
