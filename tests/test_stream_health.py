"""Stream health while recording: a serial device (real pty, the emulator driven line by
line) that goes quiet is warned about once, as an event in the file and a ``health``
event for the CLI and the window, and again when it comes back. The clock is injected,
so nothing waits for the threshold."""

from __future__ import annotations

import numpy as np
from serial_helpers import received_all
from waiting import wait_until

from tactile_studio.acquisition.session import AcquisitionSession
from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
from tactile_studio.storage import Session


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_a_device_gone_silent_while_recording_is_said_once_and_recorded(tmp_path):
    raw = np.random.default_rng(1).integers(30000, 31000, (200, 180)).astype(np.uint16)
    emu = SerialEmulator(array_source(raw), rate_hz=500, link=tmp_path / "port",
                         reader_grace=0.05)
    emu.open()
    clock = Clock()
    session = AcquisitionSession(clock=clock)
    session.silence_warning_s = 1.5
    heard: list[str] = []
    session.add_listener(lambda e: heard.append(e["message"]) if e["kind"] == "health" else None)
    try:
        session.open("serial", {"port": emu.port})
        session.start_recording(tmp_path / "s.h5")
        session.start()
        emu.send_lines(30)
        assert wait_until(received_all(session.engine, emu))
        session.poll()
        clock.t += 1.0
        session.poll()
        assert heard == []                      # quiet, but not for long enough
        clock.t += 1.0
        session.poll()
        session.poll()
        assert len(heard) == 1 and "serial sent no frames for 1.5 s" in heard[0]
        emu.send_lines(20)
        assert wait_until(received_all(session.engine, emu))
        clock.t += 0.5
        session.poll()
        assert len(heard) == 2 and "sending frames again after 2.5 s" in heard[1]
        session.stop_recording()
    finally:
        session.close()
        emu.close()
    with Session(tmp_path / "s.h5") as s:
        silent = [e for e in s.events if e["kind"] == "stream_silent"]
        back = [e for e in s.events if e["kind"] == "stream_resumed"]
        assert len(silent) == 1 and silent[0]["frame"] == 30 and silent[0]["device"] == "serial"
        assert len(back) == 1 and back[0]["silent_s"] == 2.5 and s.n_frames == 50
