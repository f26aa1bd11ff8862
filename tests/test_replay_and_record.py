"""The replay plugin and the `record` command, end to end through real files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from plugin_fixtures import CountingDevice
from waiting import wait_until

from tactile_studio.cli import main
from tactile_studio.devices.engine import FINISHED, AcquisitionEngine
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import DeviceNotFound, UserError
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage import Recorder, SessionFile, SessionWriter
from tactile_studio.storage.exchange.shearsense import write_shearsense_csv


def record_simulated(path, seconds="1", *extra):
    # 20x real time: ~860 frames a second, a small file whatever the machine's speed (at
    # speed 0 the simulator made up to the ring's 65,536 frames in a second)
    assert main(["record", "--device", "simulated", "--set", "speed=20", "--set", "seed=3",
                 *extra, "--seconds", seconds, "--out", str(path)]) == 0


def wait_finished(engine, timeout=30.0):
    wait_until(lambda: engine.state == FINISHED, timeout, what="the replay to finish")


def test_record_command_writes_a_session_that_info_describes(tmp_path, capsys):
    out = tmp_path / "sim.h5"
    record_simulated(out, "1", "--notes", "bench A")
    capsys.readouterr()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["frames"] > 43 and info["rate_hz"] == pytest.approx(43.0, rel=1e-6)
    assert info["metadata"]["device"]["plugin"] == "simulated"
    assert info["metadata"]["device"]["settings"]["seed"] == 3
    assert info["metadata"]["notes"] == "bench A" and info["closed_cleanly"]
    assert [e["kind"] for e in info["events"]][:2] == ["connect", "tare"]
    assert info["malformed"] == 0 and info["gaps"] == 0


def test_record_refuses_to_overwrite_and_reports_bad_settings(tmp_path, capsys):
    out = tmp_path / "sim.h5"
    out.write_bytes(b"precious")
    assert main(["record", "--seconds", "1", "--out", str(out)]) == 1
    assert "already exists" in capsys.readouterr().err and out.read_bytes() == b"precious"
    assert main(["record", "--set", "rate=fast", "--seconds", "1",
                 "--out", str(tmp_path / "x.h5")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == ("tactile-studio: error: device simulated: setting rate: "
                   "'fast' is not a valid float")
    assert main(["record", "--device", "warp-drive", "--seconds", "1",
                 "--out", str(tmp_path / "y.h5")]) == 1
    assert "unknown device 'warp-drive'" in capsys.readouterr().err
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "y.h5").exists()


def test_replay_of_a_session_reproduces_frames_and_timing(tmp_path):
    src = tmp_path / "src.h5"
    record_simulated(src)
    with SessionFile(src) as s:
        raw, dev_t = s.raw(), s.column("device_time")
    engine = AcquisitionEngine(create_device("replay", {"path": str(src), "speed": "0"}))
    copy = tmp_path / "copy.h5"
    rec = Recorder(engine, copy).start()
    engine.start()
    wait_finished(engine)
    engine.stop()
    rec.stop()
    with SessionFile(copy) as c:
        assert np.array_equal(c.raw(), raw)
        assert np.allclose(c.column("device_time"), dev_t - dev_t[0])
        assert np.array_equal(c.column("seq"), np.arange(len(raw)))
        assert c.layout.name == "shearsense-6x6"


@pytest.mark.parametrize("device", ["replay", "simulated"])
def test_as_fast_as_possible_waits_for_the_recorder_instead_of_lapping_the_ring(tmp_path,
                                                                               device):
    # a 128-frame ring and a recorder that reads every 50 ms: at speed 0 a replay or the
    # simulator makes thousands of frames in that time, so without the hold the ring laps
    src = tmp_path / "src.h5"
    record_simulated(src)
    with SessionFile(src) as s:
        raw = s.raw()
    settings = {"path": str(src)} if device == "replay" else {"seed": "3"}
    engine = AcquisitionEngine(create_device(device, {**settings, "speed": "0"}),
                               capacity=128, baseline_frames=10)
    copy = tmp_path / "copy.h5"
    rec = Recorder(engine, copy).start()
    engine.start()
    if device == "replay":
        wait_finished(engine)
    else:
        wait_until(lambda: rec.recorded >= 3000, 30.0, what="3000 simulated frames recorded")
    engine.stop()
    rec.stop()
    with SessionFile(copy) as c:
        assert "overrun" not in [e["kind"] for e in c.events] and c.journal.counters["dropped"] == 0
        seq = c.column("seq")
        assert np.array_equal(seq, np.arange(len(seq)))
        if device == "replay":
            assert np.array_equal(c.raw(), raw)
        assert len(seq) >= 3000 if device == "simulated" else len(seq) == len(raw)


def test_a_file_ended_at_a_frame_keeps_its_frames_however_far_the_stream_runs_on(tmp_path):
    """A collection ends its file at a frame (``end_at``) and lets the stream go; at
    speed 0 the simulator then laps a 128-frame ring many times before the file closes.
    The lap is after the file's end: no overrun of the file. Counted at every pull, it
    was a loss twice over and cut the file to 0 rows (an aborted collection, under load)."""
    engine = AcquisitionEngine(create_device("simulated", {"seed": "3", "speed": "0"}),
                               capacity=128, baseline_frames=10)
    rec = Recorder(engine, tmp_path / "ended.h5").start()
    rec.end_at(100)
    engine.start()
    try:
        wait_until(lambda: engine.frames > 100 + 10 * 128, 30.0, what="the stream to run on")
        for _ in range(3):  # the polls of a loaded machine (the background one's too)
            rec.catch_up()
    finally:
        engine.stop()
        rec.stop()
    with SessionFile(tmp_path / "ended.h5") as c:
        assert c.n_frames == 100 and np.array_equal(c.column("seq"), np.arange(100))
        assert "overrun" not in [e["kind"] for e in c.events]
        assert c.journal.counters["dropped"] == 0


def test_a_real_time_device_is_not_held_back_by_a_slow_reader():
    # the counting device streams at its own pace: a hold cannot slow it, so a reader
    # that never reads loses frames (which it counts) while the device runs on
    dev = CountingDevice(frames=2000)
    engine = AcquisitionEngine(dev, capacity=128, baseline_frames=10)
    release = engine.hold(lambda: 0)
    engine.start()
    wait_finished(engine)
    assert engine.frames == 2000 and engine.read_since(0).lost == 2000 - 128
    release()


def test_replay_loops_with_continuous_time_and_sequence(tmp_path):
    src = tmp_path / "src.h5"
    record_simulated(src, "0.5")
    with SessionFile(src) as s:
        n = s.n_frames
    # Driven directly: at speed 0 an engine would lap its ring before the test could read.
    dev = create_device("replay", {"path": str(src), "speed": "0", "loop": "true"})
    dev.open()
    batches = []
    while sum(len(b) for b in batches) < 3 * n:
        batches.append(dev.read(256))
    dev.close()
    seq = np.concatenate([b.seq for b in batches])[:3 * n]
    raw = np.concatenate([b.raw for b in batches])[:3 * n]
    t = np.concatenate([b.device_time for b in batches])[:3 * n]
    assert np.array_equal(seq, np.arange(3 * n)) and not dev.finished
    assert np.array_equal(raw[n:2 * n], raw[:n]) and np.array_equal(raw[2 * n:], raw[:n])
    assert np.all(np.diff(t) > 0)


def test_replay_of_a_shearsense_csv(tmp_path):
    rng = np.random.default_rng(0)
    raw = rng.integers(20000, 40000, size=(50, 180)).astype(np.uint16)
    times = 1.7e9 + np.arange(50) / 44.0
    csv = tmp_path / "P01_test_FLAT.csv"
    write_shearsense_csv(csv, raw, times, np.zeros(50, int), raw[0].astype(float))
    engine = AcquisitionEngine(create_device("replay", {"path": str(csv), "speed": "0"}))
    engine.start()
    wait_finished(engine)
    chunk = engine.read_since(0)
    assert np.array_equal(chunk.raw, raw)
    assert np.allclose(chunk.device_time, times - times[0])


def test_replay_errors_are_one_line(tmp_path):
    with pytest.raises(DeviceNotFound, match="nothing.h5: no such file"):
        create_device("replay", {"path": str(tmp_path / "nothing.h5")})
    with pytest.raises(UserError, match="path is required"):
        create_device("replay", {})


def test_a_replayed_outage_is_a_gap_and_no_frame_time(tmp_path, capsys):
    """A file whose serial device was gone 3 s (a reconnect), recorded from the replay:
    the outage came back as a 3 s jump in time that nothing named, so the copy read
    24 Hz instead of 43 Hz (the replay's nominal rate too). The replay now numbers its
    frames across the outage as the device would have, so the engine records the frames
    the outage cost as a sequence gap, left out of the rate."""
    rate = 43.0
    t = 1.7e9 + np.arange(400) / rate
    t[200:] += 3.0
    src = tmp_path / "outage.h5"
    with SessionWriter(src, SHEARSENSE_6X6, {"plugin": "serial", "nominal_rate_hz": rate},
                       {}) as w:
        w.append_frames(np.full((200, 180), 30000, dtype=np.uint16), t[:200], t[:200])
        w.add_event("gap", 200, t[200], seconds=3.0, cause="reconnect")
        w.add_event("reconnect", 200, t[200], gap_s=3.0, attempts=2)
        w.append_frames(np.full((200, 180), 30000, dtype=np.uint16), t[200:], t[200:])
    assert create_device("replay", {"path": str(src)}).nominal_rate_hz == pytest.approx(rate)
    csv = write_shearsense_csv(tmp_path / "P01_outage.csv", np.full((400, 180), 30000),
                               t, np.zeros(400, dtype=np.int64), np.full(180, 30000.0))
    assert create_device("replay", {"path": str(csv)}).nominal_rate_hz == pytest.approx(rate)
    copy = tmp_path / "copy.h5"
    assert main(["record", "--device", "replay", "--set", f"path={src}", "--set", "speed=0",
                 "--seconds", "30", "--out", str(copy)]) == 0
    capsys.readouterr()
    assert main(["info", "--json", str(copy)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["frames"] == 400 and info["rate_hz"] == pytest.approx(rate, rel=1e-3)
    gaps = [(e["frame"], e["missing"]) for e in info["events"] if e["kind"] == "gap"]
    assert gaps == [(200, 129)]  # 3.023 s at 43 Hz: 130 frame steps, 129 frames


@pytest.mark.parametrize("device", ["simulated", "replay"])
def test_record_seconds_are_the_devices_own_time_at_speed_0(tmp_path, capsys, device):
    """A device that makes frames on demand runs at any speed: `--seconds 2` is two
    seconds of its frames, not of the wall clock (which recorded a simulation at speed 0
    for as many frames as the machine could make, polled every 0.1 s)."""
    src = tmp_path / "src.h5"
    record_simulated(src, "3")
    settings = {"path": str(src)} if device == "replay" else {"seed": "3"}
    rate = create_device(device, settings).nominal_rate_hz
    for seconds, frames in (("2", round(2 * rate)), ("0.001", 1)):  # at least one frame
        out = tmp_path / f"{seconds}.h5"
        assert main(["record", "--device", device,
                     *[f"--set={k}={v}" for k, v in settings.items()], "--set", "speed=0",
                     "--seconds", seconds, "--out", str(out)]) == 0
        capsys.readouterr()
        assert main(["info", "--json", str(out)]) == 0
        info = json.loads(capsys.readouterr().out)
        assert info["frames"] == frames, (seconds, info["frames"])
