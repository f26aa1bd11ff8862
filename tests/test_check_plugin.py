"""``check_plugin`` over every built-in plugin on real paths (a replayed file, the serial
emulator on a pty, the BLE plugin on the fake radio), and over broken plugins whose
every problem must be listed."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from ble_fakes import BACKENDS, RADIO, FakePeripheral

from tactile_studio.devices import (
    DevicePlugin,
    FrameBatch,
    PluginCheckError,
    Setting,
    available_plugins,
    check_plugin,
    plugin_class,
)
from tactile_studio.devices.serial_emulator import Corruption, SerialEmulator, array_source
from tactile_studio.plugins import ble_device
from tactile_studio.sensor.layout import grid_layout
from tactile_studio.storage.exchange.shearsense import write_shearsense_csv

BUILT_IN = {"simulated", "replay", "serial", "ble", "lsl"}


def test_every_built_in_plugin_is_checked_here():
    built_in = {n for n, cls in available_plugins().items()
                if getattr(cls, "__module__", "").startswith("tactile_studio.plugins.")}
    assert built_in == BUILT_IN


def test_simulated():
    seen = check_plugin(plugin_class("simulated"), {"speed": 20}, frames=10)
    assert seen["frames"] >= 10


def test_lsl_on_a_stream_published_here():
    from lsl_fixtures import unique
    from test_lsl_device import Publisher

    pub = Publisher(unique("check"), channels=64).start()
    try:
        seen = check_plugin(plugin_class("lsl"), {"name": pub.name}, frames=20, timeout_s=10)
    finally:
        pub.stop()
    assert seen["frames"] >= 20


def test_replay_of_a_small_csv(tmp_path):
    raw = np.random.default_rng(0).integers(20000, 40000, size=(20, 180)).astype(np.uint16)
    csv = tmp_path / "P01_test_FLAT.csv"
    write_shearsense_csv(csv, raw, 1.7e9 + np.arange(20) / 44.0, np.zeros(20, int),
                         raw[0].astype(float))
    seen = check_plugin(plugin_class("replay"), {"path": str(csv), "speed": 0}, frames=20)
    assert seen["frames"] == 20


def test_serial_against_the_pty_emulator(tmp_path):
    raw = np.random.default_rng(1).integers(0, 65535, size=(400, 180)).astype(np.uint16)
    emu = SerialEmulator(array_source(raw), rate_hz=300, corruption=Corruption(0.1, seed=2),
                         link=tmp_path / "port", reader_grace=0.05)
    emu.open()
    emu.start()
    try:
        seen = check_plugin(plugin_class("serial"), {"port": emu.port}, frames=50,
                            timeout_s=10)
    finally:
        emu.stop()
        emu.close()
    assert seen["frames"] >= 50


def test_ble_on_the_fake_radio(monkeypatch):
    monkeypatch.setattr(ble_device, "TEST_BACKENDS", BACKENDS)
    RADIO.clear()
    per = FakePeripheral().install()
    stop = threading.Event()

    def transmit() -> None:  # a sensor streaming once the plugin subscribed
        if not per.subscribed.wait(10):
            return
        seq = 0
        rows = np.random.default_rng(2).integers(0, 65536, (1, 180)).astype(np.uint16)
        while not stop.wait(0.01) and per.subscribed.is_set():
            try:
                per.send_frame(seq, rows[0])
            except RuntimeError:  # unsubscribed between the check and the send
                return
            seq += 1

    sender = threading.Thread(target=transmit, daemon=True)
    sender.start()
    try:
        seen = check_plugin(plugin_class("ble"), {"address": per.address,
                                                  "scan_timeout": 0.2}, frames=5, timeout_s=10)
    finally:
        stop.set()
        sender.join(5)
        RADIO.clear()
    assert seen["frames"] >= 5


# ---- broken plugins: every problem is named -----------------------------------------
LAYOUT = grid_layout(2, 2, "grid-2x2")


class GoodDevice(DevicePlugin):
    """A minimal correct plugin the broken ones below change one thing at a time."""

    name = "good"
    description = "test device"
    settings_schema = (Setting("rate", "float", 100.0, "frames per second", minimum=1.0),)

    def __init__(self, **settings):
        super().__init__(**settings)
        self.n = 0
        self.opened = False

    @property
    def layout(self):
        return LAYOUT

    @property
    def nominal_rate_hz(self):
        return self.settings["rate"]

    def open(self):
        self.opened = True

    def close(self):
        self.opened = False

    def read(self, max_frames):
        k = min(max_frames, 2)
        seq = np.arange(self.n, self.n + k)
        self.n += k
        return FrameBatch(raw=np.full((k, 4), 1.0, dtype=np.float32),
                          device_time=seq / self.settings["rate"], seq=seq)


def test_a_correct_minimal_plugin_passes():
    assert check_plugin(GoodDevice, frames=6)["frames"] == 6


def test_every_problem_of_a_broken_plugin_is_listed():
    class Broken(GoodDevice):
        name = "Broken Device"
        description = ""
        settings_schema = (
            Setting("rate", "float", "fast", "frames per second"),
            Setting("mode", "choice", "c", "", choices=("a", "b")),
        )

        def __init__(self, **settings):
            DevicePlugin.__init__(self, **{"rate": 50.0, "mode": "a", **settings})
            self.n = 0
            self.closed = 0

        def close(self):
            self.closed += 1
            if self.closed > 2:  # once before open, once after: the second after fails
                raise RuntimeError("already closed")

        def read(self, max_frames):
            batch = super().read(max_frames)
            return FrameBatch(raw=batch.raw.astype(np.float64)[:, :3],
                              device_time=batch.device_time[::-1].copy(), seq=batch.seq)

        @classmethod
        def discover(cls, timeout=0.0):
            return []

    with pytest.raises(PluginCheckError) as err:
        check_plugin(Broken, frames=4)
    text = str(err.value)
    problems = err.value.problems
    expected = ["name 'Broken Device'", "description:", "setting 'rate': the default 'fast'",
                "setting 'mode': the default 'c'", "setting 'mode': give a help text",
                "raw has 3 channels", "raw dtype float64", "device_time goes back in time",
                "a second close() raised RuntimeError",
                "discover is defined but supports_discover is False"]
    for fragment in expected:
        assert any(fragment in p for p in problems), (fragment, text)
    assert text.startswith("device plugin Broken Device: ")
    assert isinstance(err.value, AssertionError)


def test_declared_hooks_need_their_signature_and_attributes():
    class WrongDiscover(GoodDevice):
        supports_discover = True

        @classmethod
        def discover(cls, timeout=5.0, name=""):
            return []

    class NotClassmethod(GoodDevice):
        supports_discover = True
        discover_setting = "rate"
        discover_instant = True

        def discover(self, settings):
            return []

    class FlagOnly(GoodDevice):
        supports_discover = True

    with pytest.raises(PluginCheckError) as err:
        check_plugin(WrongDiscover)
    assert any("discover(cls, timeout, name): the declared signature is discover(cls, settings)"
               in p for p in err.value.problems), err.value
    assert any("set the class attribute discover_setting" in p for p in err.value.problems)
    with pytest.raises(PluginCheckError, match="discover must be a @classmethod"):
        check_plugin(NotClassmethod)
    with pytest.raises(PluginCheckError, match="supports_discover is True but discover is not"):
        check_plugin(FlagOnly)


def test_an_instant_discover_is_called_and_its_result_checked():
    class Ports(GoodDevice):
        settings_schema = GoodDevice.settings_schema + (Setting("port", "str", "", "port"),)
        supports_discover = True
        discover_setting = "port"
        discover_instant = True
        calls: list = []

        @classmethod
        def discover(cls, settings):
            cls.calls.append(dict(settings))
            return [("/dev/x", "x"), ("/dev/y", 2)]

    with pytest.raises(PluginCheckError, match=r"list of \(value, label\) str pairs"):
        check_plugin(Ports)
    assert Ports.calls == [{"rate": 100.0, "port": ""}]  # the validated default settings


def test_a_plugin_that_sends_nothing_is_reported_within_the_timeout():
    class Silent(GoodDevice):
        def read(self, max_frames):
            return FrameBatch(raw=np.empty((0, 4), dtype=np.float32))

    with pytest.raises(PluginCheckError, match="delivered 0 of 3 frames in 0.3 s"):
        check_plugin(Silent, timeout_s=0.3)
