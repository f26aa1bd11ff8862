"""Stream health while recording: a serial device (real pty, the emulator driven line by
line) that goes quiet is warned about once, as an event in the file and a ``health``
event for the CLI and the window, and again when it comes back. The clock is injected,
so nothing waits for the threshold."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from serial_helpers import received_all
from waiting import wait_until

from tactile_studio.acquisition.events import Health
from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
from tactile_studio.storage import SessionFile


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
    session = LiveAcquisition(clock=clock)
    session.silence_warning_s = 1.5
    heard: list[str] = []
    session.add_listener(lambda e: heard.append(e.message) if isinstance(e, Health) else None)
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
    with SessionFile(tmp_path / "s.h5") as s:
        silent = [e for e in s.events if e["kind"] == "stream_silent"]
        back = [e for e in s.events if e["kind"] == "stream_resumed"]
        assert len(silent) == 1 and silent[0]["frame"] == 30 and silent[0]["device"] == "serial"
        assert len(back) == 1 and back[0]["silent_s"] == 2.5 and s.n_frames == 50
        # at the row frames came back (the 20 that came in one batch follow it), not
        # where the poll that noticed them had got to
        assert back[0]["frame"] == 30


def test_record_takes_the_silence_threshold_from_its_option(tmp_path, capsys):
    """``record --silence-warning 0.3``: a serial device that sends 30 frames and then
    nothing for the rest of a 3 s recording is said once, and the file's event carries
    the threshold given (not the default 2 s)."""
    import threading

    from tactile_studio.cli import main

    raw = np.random.default_rng(2).integers(30000, 31000, (60, 180)).astype(np.uint16)
    emu = SerialEmulator(array_source(raw), rate_hz=500, link=tmp_path / "port",
                         reader_grace=0.05)
    emu.open()
    feeder = threading.Thread(target=emu.send_lines, args=(30, 60.0), daemon=True)
    feeder.start()  # waits for record to open the port, sends 30 lines, then stays quiet
    try:
        assert main(["record", "--device", "serial", "--set", f"port={emu.port}",
                     "--seconds", "3", "--silence-warning", "0.3",
                     "--out", str(tmp_path / "s.h5")]) == 0
    finally:
        feeder.join(10)
        emu.close()
    err = capsys.readouterr().err
    assert err.count("sent no frames for 0.3 s") == 1, err
    with SessionFile(tmp_path / "s.h5") as s:
        silent = [e for e in s.events if e["kind"] == "stream_silent"]
        assert len(silent) == 1 and silent[0]["seconds"] == 0.3 and silent[0]["frame"] == 30


def test_the_consoles_and_the_main_window_take_the_option_too(qtbot, tmp_path):
    """``collect`` (its console) and ``gui`` hand ``--silence-warning`` to their
    acquisition session; without it the default stays."""
    from tactile_studio.acquisition.stream_health import DEFAULT_SILENCE_S
    from tactile_studio.cli import build_parser
    from tactile_studio.cli.collect import console_options
    from tactile_studio.ui.collect.app import build_console

    base = ["collect", "--protocol", "shear9", "--participant", "P01", "--out", str(tmp_path)]
    for extra, expected in (([], DEFAULT_SILENCE_S), (["--silence-warning", "7.5"], 7.5)):
        console = build_console(console_options(build_parser().parse_args(base + extra)))
        qtbot.addWidget(console)
        assert console.acquisition.silence_warning_s == expected
    args = build_parser().parse_args(["gui", "--silence-warning", "4"])
    assert args.silence_warning == 4.0  # run_gui sets it on the main window's session


def test_headless_collect_says_a_silent_stream_and_records_it(tmp_path, capsys):
    """``collect --virtual-participant`` watches the stream as ``record`` does. The
    simulator at 10 Hz in real time sends a frame every 100 ms: a 30 ms threshold makes
    each gap a silence (a loop slowed by load still looks inside most of them), so the
    warning and its event must come (before, collect never looked)."""
    from tactile_studio.cli import main

    (tmp_path / "p.toml").write_text(
        'name = "quiet"\ntrial_s = 1.0\nblocks = 1\nfree_play_s = 0.0\n'
        '[[gestures]]\nname = "Poke"\nkey = "p"\ndefinition = "x"\n')
    code = main(["collect", "--protocol", str(tmp_path / "p.toml"), "--participant", "P01",
                 "--virtual-participant", "--speed", "1", "--set", "rate=10",
                 "--silence-warning", "0.03",
                 "--out", str(tmp_path)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "sent no frames for 0.03 s" in captured.err
    with SessionFile(captured.out.strip().splitlines()[-1]) as s:
        silent = [e for e in s.events if e["kind"] == "stream_silent"]
        assert silent and silent[0]["seconds"] == 0.03
        assert [t.status for t in s.trials] == ["ok"]


def test_the_collection_console_says_a_silent_stream(qtbot, tmp_path, monkeypatch):
    """The console watches its recording's stream too: with a 30 ms threshold each gap
    between the frames of a 10 Hz simulator in real time (100 ms) is a silence, so its
    banner must come up with the warning (before, the console took the option and never
    looked)."""
    from console_helpers import open_console_session

    from tactile_studio.acquisition.live_acquisition import LiveAcquisition
    from tactile_studio.ui.collect.console import CollectConsole
    from tactile_studio.ui.settings import SETTINGS_ENV

    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    acq = LiveAcquisition()
    acq.silence_warning_s = 0.03
    console = CollectConsole(acquisition=acq)
    qtbot.addWidget(console)
    console.show()
    path = open_console_session(qtbot, console, tmp_path / "data", "P09",
                                {"rate": "10", "gesture": "idle"})
    try:
        qtbot.waitUntil(lambda: console.health_banner.isVisible(), timeout=15_000)
        assert "sent no frames for 0.03 s" in console.health_banner.text() \
            or "sending frames again" in console.health_banner.text()
        shots = os.environ.get("TACTILE_STUDIO_SCREENSHOTS")
        if shots:
            console.grab().save(str(Path(shots) / "collect_console_stream_health.png"))
    finally:
        console.close_session()
    with SessionFile(path) as f:
        assert [e for e in f.events if e["kind"] == "stream_silent"]


def test_record_names_a_serial_sensor_for_the_logbook(tmp_path, capsys, monkeypatch):
    """``record --sensor ID``: a serial receiver reports no sensor of its own, so nothing
    was ever booked for it and the sensor could not be registered from the command line
    (the logbook's 'a recording adds one' held only for the simulator). With the ID the
    logbook registers it, books the recording's hours, and the file names it; an ID that
    contradicts the device's own is refused in one line before anything is recorded."""
    import threading

    from tactile_studio.cli import main
    from tactile_studio.storage.books.logbook import Logbook

    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "appdata"))
    raw = np.random.default_rng(3).integers(30000, 31000, (60, 180)).astype(np.uint16)
    emu = SerialEmulator(array_source(raw), rate_hz=500, link=tmp_path / "port",
                         reader_grace=0.05)
    emu.open()
    feeder = threading.Thread(target=emu.send_lines, args=(40, 60.0), daemon=True)
    feeder.start()
    try:
        assert main(["record", "--device", "serial", "--set", f"port={emu.port}",
                     "--seconds", "1", "--sensor", "S-042",
                     "--out", str(tmp_path / "s.h5")]) == 0
    finally:
        feeder.join(10)
        emu.close()
    with SessionFile(tmp_path / "s.h5") as s:
        assert s.metadata["sensor_id"] == "S-042" and s.n_frames == 40
    with Logbook() as book:
        assert "S-042" in book.sensor_ids()
        assert book.history("S-042")["hours"] == round(40 / 44.0 / 3600, 4) > 0  # 44 Hz
    capsys.readouterr()
    code = main(["record", "--seconds", "1", "--sensor", "S-042",
                 "--out", str(tmp_path / "sim.h5")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and "the device reports sensor sim-0" in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "sim.h5").exists()
