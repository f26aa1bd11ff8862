"""The ``replay`` device: plays a recorded session or an old ShearSense CSV back as a live stream.

Frames come out at their original timing (``speed=1``), faster (``speed=10``), or as
fast as the consumer takes them (``speed=0``), optionally looping. Device time keeps
growing across loops so downstream rate and gap logic sees one continuous stream.

Malformed rows of a ShearSense CSV (skipped by the reader, counted by kind exactly as
``import`` counts them) are reported through ``FrameBatch.malformed`` with the first
batch of every pass, so the device panel and ``record`` show them like a serial
device's bad lines.

A break in the file's time (a reconnect's outage, a pause in an old CSV) is replayed as
it was, and the frames are numbered across it as the device would have numbered them:
the engine records the frames it cost as a sequence gap, so a copy reads the file's own
rate (its nominal rate too), not a rate over the outage.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from tactile_studio.devices.contract import DevicePlugin, FrameBatch, Setting
from tactile_studio.errors import DeviceNotFound, UserError
from tactile_studio.sensor.layout import SHEARSENSE_6X6, Layout
from tactile_studio.storage.format.segments import pauses, segmented_rate_hz


def _load(path: Path) -> tuple[Layout, np.ndarray, np.ndarray, dict[str, int], list[int]]:
    """(layout, raw, times, malformed rows by kind, rows after a break in time) from a
    session (.h5: its reconnect outages and other timed gaps) or a ShearSense CSV (the
    pauses its import would find)."""
    if not path.exists():
        raise DeviceNotFound(f"replay: {path}: no such file")
    from tactile_studio.storage.format.file_guards import not_regular

    if not_regular(path):  # a FIFO or device would block or never end
        raise UserError(f"replay: {path}: {not_regular(path)}")
    if path.suffix.lower() == ".csv":
        from tactile_studio.storage.exchange.shearsense import read_shearsense_csv

        data = read_shearsense_csv(path)
        times = np.asarray(data.times, dtype=np.float64)
        return SHEARSENSE_6X6, data.raw, times, dict(data.malformed_by_kind), pauses(times)
    from tactile_studio.storage.format.session_file import SessionFile

    with SessionFile(path) as s:
        times = s.column("device_time")
        if len(times) >= 2 and not np.all(np.diff(times) >= 0):
            times = s.column("host_time")
        breaks = sorted({int(e["frame"]) for e in s.events
                         if isinstance(e.get("frame"), int) and 0 < e["frame"] < len(times)
                         and (e.get("kind") == "reconnect"
                              or (e.get("kind") == "gap" and "seconds" in e))})
        return s.layout, s.raw(), times, {}, breaks


def _numbered(rel_t: np.ndarray, breaks: list[int], rate: float) -> np.ndarray:
    """Sequence numbers as the device would have sent them: one per frame, skipping at
    each break the frames its time would have held (a reconnect's outage), so the engine
    records them as a gap and a measured rate leaves that time out."""
    skip = np.zeros(len(rel_t), dtype=np.int64)
    for b in breaks:
        skip[b] = max(0, int(round(float(rel_t[b] - rel_t[b - 1]) * rate)) - 1)
    return np.arange(len(rel_t), dtype=np.int64) + np.cumsum(skip)


class ReplayDevice(DevicePlugin):
    name = "replay"
    description = "Replays a session file (.h5) or a ShearSense CSV at original timing or faster"
    settings_schema = (
        Setting("path", "path", "", "session .h5 or ShearSense .csv to replay"),
        Setting("speed", "float", 1.0, "1 = original timing, N = N times faster, 0 = as fast "
                "as possible", minimum=0.0, maximum=1000.0),
        Setting("loop", "bool", False, "start again at the end"),
    )

    def __init__(self, **settings: object) -> None:
        super().__init__(**settings)
        if not self.settings["path"]:
            raise UserError("device replay: setting path is required (--set path=FILE)")
        self._path = Path(self.settings["path"]).expanduser()
        self._layout, self._raw, times, self._malformed, breaks = _load(self._path)
        if len(self._raw) == 0:
            raise UserError(f"replay: {self._path}: has no frames")
        self._rel_t = times - times[0]
        span = float(self._rel_t[-1]) if len(times) > 1 else 0.0
        self._period = span * len(times) / (len(times) - 1) if len(times) > 1 else 1.0
        # the file's rate without its outages (as info measures it), not over them
        self._rate = segmented_rate_hz(self._rel_t, breaks) or 43.0
        self._seq = _numbered(self._rel_t, breaks, self._rate)
        self._pos = 0
        self._loops = 0
        self._t0 = 0.0
        self._done = False

    @property
    def layout(self) -> Layout:
        return self._layout

    @property
    def nominal_rate_hz(self) -> float:
        return self._rate

    def open(self) -> None:
        self._pos, self._loops, self._done = 0, 0, False
        self._t0 = time.monotonic()

    def close(self) -> None:
        pass

    @property
    def finished(self) -> bool:
        return self._done

    @property
    def waits_for_reader(self) -> bool:
        return self.settings["speed"] <= 0

    def _due(self) -> int:
        """How many frames of the current pass are due by now."""
        speed = self.settings["speed"]
        if speed <= 0:
            return len(self._raw)
        elapsed = (time.monotonic() - self._t0) * speed - self._loops * self._period
        return int(np.searchsorted(self._rel_t, elapsed, side="right"))

    def read(self, max_frames: int) -> FrameBatch:
        deadline = time.monotonic() + 0.1
        while True:
            due = min(self._due(), self._pos + max_frames)
            if due > self._pos or time.monotonic() >= deadline:
                break
            time.sleep(0.002)
        start, stop = self._pos, max(self._pos, due)
        n_total = len(self._raw)
        seq = self._loops * (int(self._seq[-1]) + 1) + self._seq[start:stop]
        first_of_pass = start == 0 and stop > 0
        batch = FrameBatch(raw=self._raw[start:stop],
                           device_time=self._rel_t[start:stop] + self._loops * self._period,
                           seq=seq, malformed=dict(self._malformed) if first_of_pass else {})
        self._pos = stop
        if self._pos >= n_total:
            if self.settings["loop"]:
                self._pos = 0
                self._loops += 1
            else:
                self._done = True
        return batch
