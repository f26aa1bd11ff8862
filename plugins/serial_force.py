"""The ``serial`` load cell: ASCII lines of force values (an amplifier board, an HX711
bridge) read by a thread, timestamped on arrival with the host clock.

Each line holds one value (``axes=z``) or three (``axes=xyz``), comma/space separated, in
raw units; newtons = raw x ``factor`` - tare. Lines that do not parse are counted; a load
cell that sends only those, or nothing, or goes away, is a one-line InstrumentError.
"""

from __future__ import annotations

import re
import threading
import time
from typing import Any, ClassVar

import numpy as np

from tactile_studio.devices.contract import Setting
from tactile_studio.instruments.contract import ForcePlugin, ForceSamples, InstrumentError

_SPLIT = re.compile(r"[,;\s]+")


class SerialForce(ForcePlugin):
    """A load cell streaming ASCII force lines over a serial port."""

    name: ClassVar[str] = "serial"
    description: ClassVar[str] = ("Load cell over serial: ASCII lines of 1 (z) or 3 (x,y,z) "
                                  "force values, with tare and a calibration factor")
    settings_schema: ClassVar[tuple[Setting, ...]] = (
        Setting("port", "str", "", "serial port, e.g. /dev/ttyACM0"),
        Setting("baud", "int", 115200, "baud rate", minimum=1200),
        Setting("axes", "choice", "xyz", "values per line", choices=("z", "xyz")),
        Setting("factor", "float", 1.0, "newtons per raw unit (calibration factor)"),
        Setting("silence_s", "float", 2.0, "no good line for this long is an error", minimum=0.1),
    )

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        self._ser = None
        self._lock = threading.Lock()
        self._t: list[float] = []
        self._f: list[np.ndarray] = []
        self._bad = 0
        self._bad_example = ""
        self._lost: str | None = None
        self._last_good = 0.0
        self._last_bad = 0.0
        self._offset = np.zeros(3)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def open(self) -> None:
        import serial

        port = self.settings["port"]
        if not port:
            raise InstrumentError("force serial: no port given (--force-set port=/dev/ttyACM0)")
        try:
            self._ser = serial.Serial(port, self.settings["baud"], timeout=0.05)
        except (serial.SerialException, OSError) as exc:
            raise InstrumentError(f"force serial: cannot open {port} ({exc})") from None
        self._ser.reset_input_buffer()
        self._last_good = time.monotonic()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="serial-force", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(1.0)
            self._thread = None
        if self._ser is not None:
            try:
                self._ser.close()
            finally:
                self._ser = None

    def _run(self) -> None:
        import serial

        n = 1 if self.settings["axes"] == "z" else 3
        while not self._stop.is_set():
            try:
                raw = self._ser.readline()
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                self._lost = str(exc) or type(exc).__name__
                return
            if not raw:
                continue
            now = time.time()
            text = raw.decode("ascii", "replace").strip()
            try:
                vals = [float(v) for v in _SPLIT.split(text) if v]
                if len(vals) != n or not all(np.isfinite(vals)):
                    raise ValueError(text)
            except ValueError:
                with self._lock:
                    self._bad += 1
                    self._bad_example = text[:30]
                    self._last_bad = time.monotonic()
                continue
            f = np.zeros(3)
            f[3 - n:] = np.asarray(vals) * self.settings["factor"]
            with self._lock:
                self._t.append(now)
                self._f.append(f)
                self._last_good = time.monotonic()

    def _take(self) -> tuple[np.ndarray, np.ndarray]:
        port = self.settings["port"]
        with self._lock:
            t, f = np.asarray(self._t), np.asarray(self._f).reshape(-1, 3)
            self._t, self._f = [], []
            silent = time.monotonic() - self._last_good
            garbage = time.monotonic() - self._last_bad < self.settings["silence_s"]
            bad, example = self._bad, self._bad_example
        if self._lost is not None and not len(t):
            raise InstrumentError(f"force serial: {port} disconnected ({self._lost})")
        if not len(t) and silent > self.settings["silence_s"]:
            if garbage:
                raise InstrumentError(f"force serial: only garbage from {port} for "
                                      f"{silent:.1f} s ({bad} bad lines, last {example!r})")
            raise InstrumentError(f"force serial: no data from {port} for {silent:.1f} s")
        return t, f

    def read(self) -> ForceSamples:
        t, f = self._take()
        with self._lock:
            bad, self._bad = self._bad, 0
        return ForceSamples(t, f - self._offset, {"unparsable": bad} if bad else {})

    def tare(self) -> None:
        """Zero on the mean of the next 10 samples (bounded by ``silence_s``)."""
        got: list[np.ndarray] = []
        deadline = time.monotonic() + self.settings["silence_s"]
        while sum(len(g) for g in got) < 10 and time.monotonic() < deadline:
            time.sleep(0.02)
            got.append(self._take()[1])
        samples = np.concatenate(got) if got else np.empty((0, 3))
        if not len(samples):
            self._take()  # raises the right error (silent, garbage, disconnected)
            raise InstrumentError("force serial: no samples to tare on from "
                                  f"{self.settings['port']}")
        self._offset = samples[-10:].mean(axis=0)
