"""The serial emulator: stable link, exact counts, sources, and the emulate-serial command."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections import Counter

import numpy as np
import pytest
import serial
from waiting import wait_until

from tactile_studio.devices import AcquisitionEngine, create_device
from tactile_studio.devices.line_decoder import KINDS, LineDecoder
from tactile_studio.devices.serial_emulator import Corruption, SerialEmulator, array_source
from tactile_studio.errors import UserError
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage import Recorder, SessionFile, SessionWriter
from tactile_studio.storage.recording.frame_sources import load_source


def ramp_source():
    return array_source(np.arange(50 * 180).reshape(50, 180) % 65536)


def read_all(port: serial.Serial, decoder: LineDecoder, expected_lines: int) -> None:
    def got_all() -> bool:
        decoder.feed(port.read(port.in_waiting or 1))
        return decoder.good + sum(decoder.malformed.values()) >= expected_lines
    assert wait_until(got_all, step=0)


def test_link_follows_each_pty_and_is_gone_while_unplugged(tmp_path):
    link = tmp_path / "port"
    emu = SerialEmulator(ramp_source(), link=link)
    first = emu.open()
    assert os.readlink(link) == first and emu.port == str(link)
    emu.unplug()
    # the kernel gives the freed pty number to the next pty opened anywhere (here at once):
    # a link left behind would lead a reconnecting reader to that stranger's port
    master, slave = os.openpty()
    try:
        assert not link.is_symlink() and not link.exists()
    finally:
        os.close(master)
        os.close(slave)
    second = emu.open()
    assert os.readlink(link) == second and link.exists()
    emu.close()
    assert not link.is_symlink()


def test_nothing_is_written_without_a_reader(tmp_path):
    emu = SerialEmulator(ramp_source(), link=tmp_path / "port", reader_grace=0.05)
    emu.open()
    try:
        assert not emu.has_reader()
        with pytest.raises(TimeoutError):
            emu.send_lines(1, timeout=0.3)
        assert emu.report()["lines"] == 0
        with serial.Serial(emu.port, 500000, timeout=0.05) as port:
            assert wait_until(emu.has_reader)
            emu.send_lines(5)
            dec = LineDecoder()
            read_all(port, dec, 5)
            np.testing.assert_array_equal(dec.feed(b"").frames.shape, (0, 180))
            assert dec.good == 5
    finally:
        emu.close()


def test_report_is_exact_for_a_plain_reader(tmp_path):
    emu = SerialEmulator(ramp_source(), corruption=Corruption(0.5, seed=3), link=tmp_path / "port",
                         trailing_comma=False, keep_sent=True, reader_grace=0.05)
    emu.open()
    try:
        with serial.Serial(emu.port, 500000, timeout=0.05) as port:
            assert wait_until(emu.has_reader)
            writer = threading.Thread(target=emu.send_lines, args=(300,))
            writer.start()  # the pty holds only a few lines: write while reading
            dec = LineDecoder()
            read_all(port, dec, 300)
            writer.join()
            rep = emu.report()
            assert rep["lines"] == 300 and rep["interrupted"] == 0
            assert dec.good == rep["good"] and dec.good == len(emu.sent_frames())
            assert dict(dec.malformed) == rep["malformed_by_kind"]
            assert set(rep["malformed_by_kind"]) == set(KINDS)
            # roughly the asked fraction, spread over the kinds (300 lines: loose bounds)
            assert 90 < rep["malformed"] < 210
    finally:
        emu.close()


def test_bad_options_are_user_errors():
    with pytest.raises(UserError):
        SerialEmulator(ramp_source(), corruption=Corruption(1.5))
    with pytest.raises(UserError):
        SerialEmulator(ramp_source(), rate_hz=0)
    with pytest.raises(UserError):
        SerialEmulator(ramp_source(), corruption=Corruption(kinds=["bogus"]))
    with pytest.raises(UserError):
        load_source("/no/such/file.h5")


def test_sources_from_a_session_and_a_shearsense_csv(tmp_path):
    raw = (np.arange(12 * 180).reshape(12, 180) + 20000).astype(np.uint16)
    h5 = tmp_path / "s.h5"
    with SessionWriter(h5, SHEARSENSE_6X6, {"plugin": "test"}) as w:
        w.append_frames(raw, np.arange(12) / 50.0, np.arange(12) / 50.0)
    src, rate = load_source(str(h5))
    assert rate == pytest.approx(50.0)
    np.testing.assert_array_equal(src(12), raw)
    np.testing.assert_array_equal(src(3), raw[:3])  # loops

    csv = tmp_path / "P1_FLAT.csv"
    header = ['"time (s)"'] + [f'"Channel{i}"' for i in range(180)] + ['"touched"', '"label"']
    rows = [",".join(f'"{v}"' for v in [0] + [30000] * 180 + [0, 0])]
    for i in range(5):
        rows.append(",".join(f'"{v}"' for v in [1700000000 + i / 40] + list(raw[i]) + [0, 0]))
    csv.write_text("\n".join([",".join(header)] + rows) + "\n")
    src, rate = load_source(str(csv))
    assert rate == pytest.approx(40.0, rel=1e-3)
    np.testing.assert_array_equal(src(5), raw[:5])


def test_simulated_source_streams_sensor_counts():
    src, rate = load_source("simulated", seed=1)
    frames = src(20)
    assert rate == 44.0 and frames.shape == (20, 180)
    assert 0 <= frames.min() and frames.max() <= 65535


def run_emulator(link, seed: int) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "tactile_studio", "emulate-serial", "--rate", "300",
           "--corrupt", "0.2", "--seed", str(seed), "--link", str(link), "--json"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert "serial emulator on /dev/" in proc.stdout.readline()
    assert proc.stdout.readline().strip() == f"port: {link}"
    return proc


def ctrl_c(proc: subprocess.Popen) -> dict:
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    return json.loads(out.strip().splitlines()[-1])


def test_emulate_serial_restarted_on_the_same_link_is_one_exact_recording(tmp_path):
    """Two emulator processes one after the other (unplug, replug) on one --link, each
    stopped with Ctrl-C; the serial plugin records across the gap; the file matches
    both reports exactly."""
    link = tmp_path / "port"
    procs = [run_emulator(link, seed=5)]
    engine = AcquisitionEngine(create_device("serial", {"port": str(link)}))
    recorder = Recorder(engine, tmp_path / "s.h5")
    try:
        engine.start()
        recorder.start()
        assert wait_until(lambda: engine.frames >= 100)
        reports = [ctrl_c(procs[0])]
        assert wait_until(lambda: engine.state == "reconnecting")
        assert not link.is_symlink()  # the command cleans its link up
        procs.append(run_emulator(link, seed=6))
        assert wait_until(lambda: engine.frames >= reports[0]["good"] + 100)
        reports.append(ctrl_c(procs[1]))
        assert wait_until(lambda: engine.state == "reconnecting")
        engine.stop()
        recorder.stop()
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
    with SessionFile(tmp_path / "s.h5") as s:
        summary = s.summary()
    assert all(r["interrupted"] == 0 for r in reports)
    assert summary["frames"] == sum(r["good"] for r in reports)
    sent_bad = sum((Counter(r["malformed_by_kind"]) for r in reports), Counter())
    assert Counter(summary["malformed_by_kind"]) == sent_bad
    assert summary["reconnects"] == 1
