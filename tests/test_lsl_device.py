"""The ``lsl`` device plugin with real liblsl: it records a stream the test publishes,
end to end through ``tactile-studio record``, across a vanish and return (a gap event);
layouts come from our outlet's metadata or the channel count; bad input is one line."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pylsl
import pytest
from lsl_fixtures import WAIT_S, unique
from waiting import wait_until

from tactile_studio.cli import main
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import DeviceNotFound, SettingsError
from tactile_studio.sensor.layout import grid_layout
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.streams.clock import measure_offset
from tactile_studio.streams.lsl_meta import frame_stream_info


class Publisher:
    """Pushes frame i = [i, i, ...] at ``rate`` Hz stamped base + i/rate; ``vanish()``
    destroys the outlet for a while and makes a new one with the same source_id."""

    def __init__(self, name: str, channels: int = 64, rate: float = 100.0,
                 fmt: str = "float32", info_factory=None) -> None:  # noqa: ANN001
        self.name, self.channels, self.rate, self.fmt = name, channels, rate, fmt
        self.info_factory = info_factory
        self.source_id = f"{name}-src"
        self.pushed: list[tuple[int, float]] = []
        self.base = pylsl.local_clock()
        self._away = threading.Event()
        self._back = threading.Event()
        self._stop = threading.Event()
        self.outlet = self._outlet()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _outlet(self) -> pylsl.StreamOutlet:
        if self.info_factory is not None:
            return pylsl.StreamOutlet(self.info_factory())
        return pylsl.StreamOutlet(pylsl.StreamInfo(self.name, "Tactile", self.channels,
                                                   self.rate, self.fmt, self.source_id))

    def start(self) -> Publisher:
        self._thread.start()
        return self

    def _run(self) -> None:
        i = 0
        t0 = time.monotonic()
        while not self._stop.is_set() and time.monotonic() - t0 < 3 * WAIT_S:
            if self._away.is_set():
                self.outlet = None  # liblsl closes the outlet: recipients lose it
                self._back.wait(WAIT_S)
                self._away.clear()
                self.outlet = self._outlet()
            due = t0 + i / self.rate
            if time.monotonic() < due:
                time.sleep(min(0.005, due - time.monotonic()))
                continue
            stamp = self.base + i / self.rate
            self.outlet.push_sample(np.full(self.channels, i, dtype=np.float32), stamp)
            self.pushed.append((i, stamp))
            i += 1

    def vanish(self) -> None:
        self._back.clear()
        self._away.set()

    def come_back(self) -> None:
        self._back.set()

    def stop(self) -> None:
        self._stop.set()
        self._back.set()
        self._thread.join(WAIT_S)
        self.outlet = None


def test_record_an_lsl_stream_across_a_vanish_and_return(tmp_path: Path, capsys) -> None:
    name = unique("pub")
    pub = Publisher(name).start()
    out = tmp_path / "lsl.h5"

    def recorded(enough) -> bool:  # noqa: ANN001 - the file as the recorder has it now
        try:
            with SessionFile(out) as s:
                return enough(s)
        except Exception:  # noqa: BLE001 - not created yet, or mid-creation
            return False

    def script() -> None:  # while `record` runs in this thread's sibling (the main one)
        # each step on what the file holds, not on a sleep: a loaded machine that took
        # a second to find the stream had vanished it before the first frame
        wait_until(lambda: recorded(lambda s: s.n_frames > 60), WAIT_S, 0.05,
                   "60 frames before the stream vanishes")
        pub.vanish()
        wait_until(lambda: recorded(lambda s: any(e["kind"] == "disconnect"
                                                  for e in s.events)), WAIT_S, 0.05,
                   "the recording to say the stream is gone")
        pub.come_back()

    helper = threading.Thread(target=script, daemon=True)
    helper.start()
    try:
        code = main(["record", "--device", "lsl", "--set", f"name={name}", "--seconds", "6",
                     "--out", str(out)])
    finally:
        helper.join(WAIT_S)
        pub.stop()
    err = capsys.readouterr().err
    assert code == 0, err
    with SessionFile(out) as s:
        raw = s.raw(0, s.n_frames)
        dev_t = s.column("device_time", 0, s.n_frames)
        events = s.events
        meta = s.metadata
        summary = s.summary()
    assert s.layout.name == "grid-8x8"  # 64 channels, no metadata of ours
    assert meta["device"]["stream"]["name"] == name
    values = raw[:, 0].astype(int)
    assert (raw == raw[:, :1]).all()  # every channel of frame i is i: nothing mixed up
    steps = np.diff(values)
    assert (steps >= 1).all()  # in order, never repeated
    assert (steps > 1).sum() == 1  # frames were lost only while the stream was away
    before, after = np.split(values, [int(np.argmax(steps > 1)) + 1])
    assert len(before) > 50 and len(after) > 50
    pushed = dict(pub.pushed)
    # device time is the LSL timestamp the publisher gave (clock-synchronised, same host)
    np.testing.assert_allclose(dev_t, [pushed[v] for v in values], atol=0.005)
    kinds = [e["kind"] for e in events]
    gap = next(e for e in events if e["kind"] == "gap")
    assert gap["cause"] == "reconnect" and gap["frame"] == len(before)
    assert kinds.index("disconnect") < kinds.index("gap") < kinds.index("reconnect")
    assert summary["reconnects"] == 1 and summary["gaps"] == 1


def _grid_4x8_info(name: str):  # noqa: ANN202
    lay = grid_layout(4, 8)
    info = {"plugin": "test", "settings": {}, "nominal_rate_hz": 50.0, "sensor_id": "S-0042"}
    return lambda: frame_stream_info(pylsl, lay, info, "raw", name, f"{name}-src",
                                     measure_offset(pylsl.local_clock))


def test_layout_and_sensor_id_come_from_our_outlets_metadata() -> None:
    name = unique("meta")
    pub = Publisher(name, channels=32, rate=50.0, info_factory=_grid_4x8_info(name)).start()
    dev = create_device("lsl", {"name": name})
    try:
        assert dev.layout.name == "grid-4x8"  # 32 channels alone would match no layout
        assert dev.nominal_rate_hz == 50.0
        dev.open()
        deadline = time.monotonic() + WAIT_S
        got = 0
        while got < 5 and time.monotonic() < deadline:
            batch = dev.read(64)
            got += len(batch)
        assert got >= 5 and batch.raw.dtype == np.float32
        assert dev.info()["sensor_id"] == "S-0042"
        found = dict(type(dev).discover({"timeout": 1.0}))  # the device panel's Scan
        assert found[name].startswith(f"{name} (Tactile, 32 ch at 50 Hz, ")
    finally:
        dev.close()
        pub.stop()


def test_bad_streams_and_settings_are_one_line_errors(capsys, tmp_path: Path) -> None:
    odd = unique("odd")
    pub = Publisher(odd, channels=7).start()
    irregular = pylsl.StreamOutlet(pylsl.StreamInfo(unique("irr"), "Tactile", 64, 0.0,
                                                    "float32", "irr-src"))
    try:
        with pytest.raises(SettingsError, match=f"stream '{odd}' has 7 channels, which "
                                                "matches no layout"):
            create_device("lsl", {"name": odd}).layout
        with pytest.raises(SettingsError, match="layout grid-8x8 needs 64"):
            create_device("lsl", {"name": odd, "layout": "grid-8x8"}).layout
        assert create_device("lsl", {"name": odd, "layout": "grid-1x7"}).layout.n_channels == 7
        with pytest.raises(SettingsError, match="irregular rate"):
            create_device("lsl", {"source_id": "irr-src"}).layout
        with pytest.raises(DeviceNotFound, match="no stream with name='nothing-here' found"):
            create_device("lsl", {"name": "nothing-here", "timeout": 1}).layout
        with pytest.raises(SettingsError, match="unknown layout"):
            create_device("lsl", {"layout": "hexagon"})
        out = tmp_path / "never.h5"
        assert main(["record", "--device", "lsl", "--set", f"name={odd}", "--seconds", "1",
                     "--out", str(out)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("tactile-studio: error: lsl: stream") and "\n" not in err
        assert not out.exists()
    finally:
        pub.stop()
        irregular = None  # noqa: F841


def test_a_decoded_stream_is_refused_with_a_hint() -> None:
    from tactile_studio.devices.engine import AcquisitionEngine
    from tactile_studio.streams.lsl_outlet import LslStreamer

    engine = AcquisitionEngine(create_device("simulated", {"rate": 50}))
    streamer = LslStreamer(engine, decoded=True, name=unique("dec")).start()
    try:
        with pytest.raises(SettingsError, match="carries decoded stresses"):
            create_device("lsl", {"name": streamer.name}).layout
    finally:
        streamer.stop()
