"""The ``gcode`` stage: a 3D printer or CNC over serial speaking Marlin-style G-code.

The indenter is mounted on the print head. Sensor coordinates (mm from taxel A1's
centre, z = 0 at the skin surface) map to machine coordinates by the ``x/y/z_offset``
settings (the machine position of that point). Soft limits are checked in sensor
coordinates before any command is sent, so the indenter can never be driven below
``floor_z``. Every command waits for Marlin's "ok"; "echo:busy" lines extend the wait;
an "Error:" line fails the command with that text.
"""

from __future__ import annotations

import re
import time
from typing import Any, ClassVar

from tactile_studio.devices.contract import Setting
from tactile_studio.instruments.contract import InstrumentError, StagePlugin
from tactile_studio.instruments.limits import LIMIT_SETTINGS, check_limits

_POS = re.compile(r"X:\s*(-?[\d.]+)\s+Y:\s*(-?[\d.]+)\s+Z:\s*(-?[\d.]+)")


class GcodeStage(StagePlugin):
    """A Marlin-style printer/CNC carrying the indenter."""

    name: ClassVar[str] = "gcode"
    description: ClassVar[str] = ("3D printer or CNC over serial (Marlin G-code: G28, G90, G1, "
                                  "M400, M114, M410) carrying the indenter, with soft limits")
    settings_schema: ClassVar[tuple[Setting, ...]] = (
        Setting("port", "str", "", "serial port of the printer, e.g. /dev/ttyUSB0"),
        Setting("baud", "int", 115200, "baud rate", minimum=1200),
        Setting("x_offset", "float", 100.0, "machine X of taxel A1's centre, mm"),
        Setting("y_offset", "float", 100.0, "machine Y of taxel A1's centre, mm"),
        Setting("z_offset", "float", 20.0, "machine Z where the indenter touches the skin, mm"),
        Setting("indenter_mm", "float", 14.0, "square indenter side, mm", minimum=1.0),
        Setting("command_timeout_s", "float", 10.0, "longest wait for an 'ok'", minimum=0.1),
        Setting("home_timeout_s", "float", 120.0, "longest wait for homing", minimum=1.0),
        Setting("travel_speed", "float", 30.0, "speed of moves clear of the skin, mm/s",
                minimum=0.1),
    ) + LIMIT_SETTINGS

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        self._ser = None
        self._accel: float | None = None
        self._target: tuple[float, float, float] | None = None

    # ---- connection --------------------------------------------------------------------
    def open(self) -> None:
        import serial

        port = self.settings["port"]
        if not port:
            raise InstrumentError("stage gcode: no port given (--stage-set port=/dev/ttyUSB0)")
        try:
            self._ser = serial.Serial(port, self.settings["baud"], timeout=0.05)
        except (serial.SerialException, OSError) as exc:
            raise InstrumentError(f"stage gcode: cannot open {port} ({exc})") from None
        self._ser.reset_input_buffer()

    def close(self) -> None:
        if self._ser is not None:
            try:
                self._ser.close()
            finally:
                self._ser = None

    def command(self, line: str, timeout_s: float | None = None) -> list[str]:
        """Send one G-code line and wait for its "ok"; returns the lines before it."""
        import serial

        port = self.settings["port"]
        if self._ser is None:
            raise InstrumentError(f"stage gcode: {port} is not open")
        timeout_s = self.settings["command_timeout_s"] if timeout_s is None else timeout_s
        out: list[str] = []
        error = None
        try:
            self._ser.write((line + "\n").encode("ascii"))
            deadline = time.monotonic() + timeout_s
            while time.monotonic() < deadline:
                raw = self._ser.readline()
                if not raw:
                    continue
                text = raw.decode("ascii", "replace").strip()
                if text == "ok" or text.startswith("ok "):
                    if error:
                        raise InstrumentError(f"stage gcode: {port} replied '{error}' to {line}")
                    return out
                if text.startswith("Error:") or text.startswith("!!"):
                    error = text
                elif text.startswith("echo:busy"):
                    deadline = time.monotonic() + timeout_s
                else:
                    out.append(text)
        except (serial.SerialException, OSError) as exc:
            self.close()
            raise InstrumentError(f"stage gcode: {port} disconnected during {line} "
                                  f"({exc})") from None
        raise InstrumentError(f"stage gcode: no 'ok' from {port} for {line} within {timeout_s:g} s")

    # ---- contract ----------------------------------------------------------------------
    def _machine(self, x: float, y: float, z: float) -> str:
        s = self.settings
        return f"X{x + s['x_offset']:.3f} Y{y + s['y_offset']:.3f} Z{z + s['z_offset']:.3f}"

    def home(self) -> None:
        self.command("G28", self.settings["home_timeout_s"])
        self.command("G90")
        self._target = self.position()
        # over taxel A1 at the safe height (the endstops may be outside the soft limits)
        safe = self.settings["safe_z"]
        self.command(f"G1 {self._machine(0.0, 0.0, max(safe, self._target[2]))} "
                     f"F{self.settings['travel_speed'] * 60:.1f}")
        self.command(f"G1 {self._machine(0.0, 0.0, safe)} "
                     f"F{self.settings['travel_speed'] * 60:.1f}")
        self._target = (0.0, 0.0, safe)
        self.wait_until_still(self.settings["home_timeout_s"])

    def move_to(self, x: float | None = None, y: float | None = None, z: float | None = None,
                speed: float = 2.0, acceleration: float = 50.0) -> None:
        if self._target is None:
            raise InstrumentError("stage gcode: move before home")
        if speed <= 0:
            raise InstrumentError(f"stage gcode: speed must be positive, got {speed}")
        cx, cy, cz = self._target
        tx, ty, tz = (cx if x is None else x), (cy if y is None else y), (cz if z is None else z)
        check_limits(self.name, self.settings, tx, ty, tz)
        if acceleration != self._accel:
            self.command(f"M204 P{acceleration:.1f} T{acceleration:.1f}")
            self._accel = acceleration
        self.command(f"G1 {self._machine(tx, ty, tz)} F{speed * 60:.1f}")
        self._target = (tx, ty, tz)

    def wait_until_still(self, timeout_s: float = 60.0) -> None:
        self.command("M400", timeout_s)

    def position(self) -> tuple[float, float, float]:
        for text in self.command("M114"):
            m = _POS.search(text)
            if m:
                s = self.settings
                return (float(m[1]) - s["x_offset"], float(m[2]) - s["y_offset"],
                        float(m[3]) - s["z_offset"])
        raise InstrumentError("stage gcode: no position in the M114 reply from "
                              f"{self.settings['port']}")

    def retract(self) -> None:
        """Quick-stop whatever move is under way (M410), then lift straight up."""
        self.command("M410")
        self._target = x, y, _ = self.position()  # where the quick stop left the head
        self.move_to(x, y, self.settings["safe_z"], speed=self.settings["travel_speed"])
        self.wait_until_still()
