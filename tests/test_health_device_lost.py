"""A sensor unplugged during a wellness check: the one line names the port and says it
was lost (the serial receiver reconnects, in vain), not only that 'device serial sent no
frames for 10 s'; nothing is stored. A real pty emulator, the real CLI."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
from tactile_studio.storage.books.logbook import Logbook


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))
    with Logbook() as book:
        book.ensure_sensor("s1", "shearsense-6x6")


def test_a_sensor_unplugged_during_a_check_is_named_with_its_cause(tmp_path, capsys):
    rng = np.random.default_rng(0)
    rest = (30000 + rng.normal(0, 20, (997, 180))).astype(np.uint16)  # at rest, unloaded
    emu = SerialEmulator(array_source(rest), rate_hz=2000, link=tmp_path / "port",
                         reader_grace=0.05)
    emu.open()
    port = tmp_path / "port"

    def feed_then_unplug() -> None:  # the rest's 3 s (at 44 Hz) and some, then the cable
        emu.send_lines(400, timeout=20)
        emu.unplug(drain=2.0)

    feeder = threading.Thread(target=feed_then_unplug, daemon=True)
    feeder.start()
    try:
        code = main(["wellness", "--device", "serial", "--set", f"port={port}",
                     "--set", "rate=44", "--sensor", "s1", "--weight-g", "200"])
    finally:
        feeder.join(30)
        emu.close()
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]
    assert code == 1 and len(lines) == 1, err
    assert f"serial port {port} lost" in lines[0] and "nothing was stored" in lines[0]
    with Logbook() as book:
        assert book.checks("s1") == []
