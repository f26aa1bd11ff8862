"""The LSL outlets with real liblsl: frames from the simulated device through the engine
and markers arrive exactly (values, timestamps, order) at an inlet; the clock offset is
kept in the session file; bad input is a one-line error."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from lsl_fixtures import WAIT_S, Collector, desc_channels, unique

from tactile_studio.cli import main
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.devices.registry import create_device
from tactile_studio.sensor.decode import decode
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.streams import LslUnavailable, load_pylsl, measure_offset
from tactile_studio.streams.lsl_meta import stable_source_id
from tactile_studio.streams.lsl_outlet import LslStreamer


def _engine(**settings: object) -> AcquisitionEngine:
    return AcquisitionEngine(create_device("simulated", {"rate": 400, "speed": 1, **settings}))


def _stream(engine: AcquisitionEngine, frames: int, **kw: object):
    """Run ``engine`` for ``frames`` frames with a streamer and an inlet on both streams."""
    name = unique("ts")
    streamer = LslStreamer(engine, name=name, **kw).start()
    frames_in = Collector(f"name='{name}'")
    markers_in = Collector(f"name='{name}-markers'")
    frames_in.wait_connected()
    markers_in.wait_connected()
    engine.start()
    assert engine.wait_frames(frames, timeout=20)
    engine.stop()
    frames_in.wait_count(engine.frames)  # the streamer's thread pushes the rest
    streamer.stop()
    frames_in.stop()
    markers_in.stop()
    return streamer, frames_in, markers_in


def test_raw_frames_arrive_exactly_with_host_times_on_lsl_clock() -> None:
    engine = _engine(seed=5)
    streamer, got, markers = _stream(engine, 600)
    ring = engine.read_since(0)
    assert ring.start == 0 and len(ring) == engine.frames == streamer.frames_sent
    data = got.array(np.int64)
    assert data.shape == (engine.frames, 180)
    np.testing.assert_array_equal(data, ring.raw.astype(np.int64))
    # each frame stamped with its host arrival time mapped by the measured offset
    np.testing.assert_array_equal(np.asarray(got.stamps), ring.host_time + streamer.offset.offset_s)
    # the description lets a recipient rebuild the grid
    info = got.info
    assert info.channel_count() == 180 and info.nominal_srate() == 400.0
    ts = info.desc().child("tactile_studio")
    assert ts.child_value("content") == "raw"
    assert ts.child("layout").child_value("name") == "shearsense-6x6"
    chans = desc_channels(info)
    assert [c["label"] for c in chans[:6]] == ["A1:y_neg", "A1:x_neg", "A1:centre", "A1:x_pos",
                                               "A1:y_pos", "B1:y_neg"]
    for ch, c in enumerate(chans):  # taxel t at row t % 6, column t // 6 (the wiring)
        assert (int(c["row"]), int(c["col"])) == SHEARSENSE_6X6.taxel_rc(ch // 5)
    kinds = [json.loads(m[0])["kind"] for m in markers.samples]
    assert kinds == ["connect", "tare", "disconnect"]


def test_decoded_frames_are_normal_then_shear_per_taxel() -> None:
    engine = _engine(seed=2, gesture="poke")
    streamer, got, _ = _stream(engine, 300, decoded=True)
    ring = engine.read_since(0)
    st = decode(SHEARSENSE_6X6, ring.raw, engine.baseline)
    data = got.array(np.float32)
    assert data.shape == (engine.frames, 108) and streamer.content == "decoded"
    n = len(ring)
    np.testing.assert_allclose(data[:, :36], st.normal.reshape(n, 36), rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(data[:, 36:72], st.shear_x.reshape(n, 36), rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(data[:, 72:], st.shear_y.reshape(n, 36), rtol=1e-6, atol=1e-5)
    chans = desc_channels(got.info)
    assert chans[0]["label"] == "A1:normal" and chans[1]["label"] == "A2:normal"
    assert chans[36]["label"] == "A1:shear_x" and chans[107]["label"] == "F6:shear_y"
    assert chans[0]["unit"] == "kPa"
    assert json.loads(got.info.desc().child("tactile_studio").child_value("calibration"))[
        "shear_slope"] == pytest.approx(0.11)


def test_app_and_prediction_markers_keep_their_order_and_times() -> None:
    engine = _engine(seed=1)
    name = unique("mk")
    streamer = LslStreamer(engine, name=name).start()
    got = Collector(f"name='{name}-markers'")
    got.wait_connected()
    engine.start()
    assert engine.wait_frames(150, timeout=20)
    deadline = time.monotonic() + WAIT_S
    while streamer.markers_sent < 2 and time.monotonic() < deadline:  # connect and tare out
        time.sleep(0.01)
    streamer.push_marker("note", text="participant sneezed")
    streamer.push_prediction("Poke", probability=0.875, scores={"Poke": 0.875, "Tickle": 0.125},
                             frame=50, model="cnn3d")
    while streamer.markers_sent < 4 and time.monotonic() < deadline:  # both out
        time.sleep(0.01)
    engine.stop()
    streamer.stop()
    got.wait_count(5)
    got.stop()
    markers = [json.loads(m[0]) for m in got.samples]
    # in the order they happened; the timestamp is the time they refer to
    assert [m["kind"] for m in markers] == ["connect", "tare", "note", "prediction",
                                            "disconnect"]
    pred = markers[3]
    assert pred == {"kind": "prediction", "source": "inference", "label": "Poke",
                    "probability": 0.875, "scores": {"Poke": 0.875, "Tickle": 0.125},
                    "frame": 50, "model": "cnn3d"}
    frame_time = engine.read_since(50, 1).host_time[0]
    assert got.stamps[3] == frame_time + streamer.offset.offset_s
    assert got.stamps[3] < got.stamps[2]  # frame 50 arrived before the note was made
    assert markers[2] == {"kind": "note", "source": "app", "text": "participant sneezed"}


def test_record_with_lsl_keeps_the_clock_offset_for_exact_alignment(tmp_path: Path,
                                                                     capsys) -> None:
    settings = {"rate": "300", "seed": "11"}
    sid = stable_source_id("simulated", "raw", create_device("simulated", settings).settings,
                           None)
    got = Collector(f"source_id='{sid}'")
    out = tmp_path / "s.h5"
    code = main(["record", "--seconds", "1.5", "--set", "rate=300", "--set", "seed=11",
                 "--out", str(out), "--lsl", "--lsl-wait", "10"])
    got.wait_count(1)
    got.stop()
    assert code == 0, capsys.readouterr().err
    with SessionFile(out) as s:
        clock = [e for e in s.events if e["kind"] == "lsl_clock"]
        host = s.column("host_time", 0, s.n_frames)
        raw = s.raw(0, s.n_frames)
    assert clock[0]["streaming"] is True and clock[-1]["streaming"] is False
    offset = clock[0]["offset_s"]
    assert abs(clock[0]["uncertainty_s"]) < 0.01
    # what the inlet got is a run of the file's frames, at host_time + offset exactly
    stamps, data = np.asarray(got.stamps), got.array(np.int64)
    assert len(stamps) > 100
    first = [r for r in np.nonzero(host + offset == stamps[0])[0]
             if (raw[r].astype(np.int64) == data[0]).all()]
    assert first == [0]  # the inlet was connected before the device started
    rows = np.arange(len(stamps))
    assert rows[-1] < len(host)
    np.testing.assert_array_equal(host[rows] + offset, stamps)
    np.testing.assert_array_equal(raw[rows].astype(np.int64), data)


def test_a_recording_started_later_carries_the_offset_in_force(tmp_path: Path) -> None:
    from tactile_studio.storage.recording.recorder import Recorder

    engine = _engine(seed=4)
    streamer = LslStreamer(engine, name=unique("late")).start()
    engine.start()
    assert engine.wait_frames(50, timeout=20)
    rec = Recorder(engine, tmp_path / "late.h5").start()
    assert engine.wait_frames(engine.frames + 50, timeout=20)
    engine.stop()
    streamer.stop()
    rec.stop()
    with SessionFile(tmp_path / "late.h5") as s:
        clock = [e for e in s.events if e["kind"] == "lsl_clock"]
    assert clock[0]["frame"] == 0 and clock[0]["carried"] is True
    assert clock[0]["offset_s"] == streamer.offset.offset_s
    assert clock[-1]["streaming"] is False


def test_a_resumed_recording_carries_the_offset_at_its_first_row(tmp_path: Path) -> None:
    """A resume on a device already streaming to LSL (the console on the live engine):
    the offset in force is the new run's, from the first new row. At row 0 it was said
    to hold for the earlier run's frames too, which were never on that stream."""
    from tactile_studio.storage.format.session_writer import SessionWriter
    from tactile_studio.storage.recording.recorder import Recorder

    old = tmp_path / "old.h5"
    with SessionWriter(old, SHEARSENSE_6X6, {"plugin": "simulated", "nominal_rate_hz": 400.0},
                       {"participant": "P01"}) as w:
        t = np.arange(40) / 400.0
        w.append_frames(np.full((40, 180), 30000, dtype=np.uint16), t, 1.7e9 + t)
    engine = _engine(seed=5)
    streamer = LslStreamer(engine, name=unique("resumed")).start()
    engine.start()
    assert engine.wait_frames(50, timeout=20)
    with SessionFile(old) as earlier:
        rec = Recorder(engine, tmp_path / "resumed.h5", row_offset=40)
        rec.copy_earlier(earlier)
    rec.start()
    assert engine.wait_frames(engine.frames + 50, timeout=20)
    engine.stop()
    streamer.stop()
    rec.stop()
    with SessionFile(tmp_path / "resumed.h5") as s:
        clock = [e for e in s.events if e["kind"] == "lsl_clock"]
    assert clock[0]["frame"] == 40 and clock[0]["carried"] is True


def test_clock_offset_is_the_tightest_bracket() -> None:
    host = iter([10.0, 10.4, 20.0, 20.1, 30.0, 30.3])
    lsl = iter([105.0, 115.0, 125.0])
    off = measure_offset(lambda: next(lsl), tries=3, host_clock=lambda: next(host))
    assert off.offset_s == pytest.approx(115.0 - 20.05)
    assert off.uncertainty_s == pytest.approx(0.05)
    assert off.to_lsl(20.05) == pytest.approx(115.0)


def test_without_liblsl_every_entry_is_a_one_line_error(monkeypatch, capsys,
                                                        tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "pylsl", None)  # `import pylsl` now fails
    with pytest.raises(LslUnavailable, match="pip install pylsl"):
        load_pylsl()
    for argv in (["stream", "--seconds", "1"],
                 ["record", "--seconds", "1", "--out", str(tmp_path / "x.h5"), "--lsl"],
                 ["record", "--device", "lsl", "--seconds", "1", "--out", str(tmp_path / "y.h5")]):
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert err.startswith("tactile-studio: error: Lab Streaming Layer is not available")
        assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "y.h5").exists()


def test_stream_command_bad_arguments(capsys) -> None:
    assert main(["stream", "--seconds", "0"]) == 1
    assert "--seconds must be positive" in capsys.readouterr().err
    assert main(["stream", "--device", "nope", "--seconds", "1"]) == 1
    assert "unknown device 'nope'" in capsys.readouterr().err


def test_the_core_and_the_plugin_import_without_pylsl() -> None:
    import subprocess

    code = ("import sys; sys.modules['pylsl'] = None\n"
            "import tactile_studio.streams.lsl_outlet, tactile_studio.cli.stream\n"
            "from tactile_studio.devices.registry import available_plugins\n"
            "cls = available_plugins()['lsl']\n"
            "assert isinstance(cls, type), cls\n"
            "cls(name='x')  # settings are checked without liblsl\n"
            "print('ok')\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


def test_a_wall_clock_step_is_recorded_and_applies_from_its_frame(tmp_path: Path) -> None:
    from tactile_studio.storage.recording.recorder import Recorder

    step = {"s": 0.0}
    engine = _engine(seed=6)
    rec = Recorder(engine, tmp_path / "step.h5").start()
    streamer = LslStreamer(engine, name=unique("step"), clock_check_s=0.05,
                           host_clock=lambda: time.time() + step["s"]).start()
    got = Collector(f"name='{streamer.name}'")
    got.wait_connected()
    engine.start()
    assert engine.wait_frames(200, timeout=20)
    step["s"] = -2.5  # as if NTP stepped the wall clock back
    assert engine.wait_frames(engine.frames + 200, timeout=20)
    engine.stop()
    got.wait_count(engine.frames)
    streamer.stop()
    got.stop()
    rec.stop()
    with SessionFile(tmp_path / "step.h5") as s:
        clocks = [e for e in s.events if e["kind"] == "lsl_clock" and e["streaming"]]
        host = s.column("host_time", 0, s.n_frames)
    assert len(clocks) == 2
    assert clocks[1]["offset_s"] - clocks[0]["offset_s"] == pytest.approx(2.5, abs=0.01)
    change = clocks[1]["frame"]
    assert 200 <= change < len(host)
    expected = np.where(np.arange(len(host)) < change, host + clocks[0]["offset_s"],
                        host + clocks[1]["offset_s"])
    np.testing.assert_array_equal(np.asarray(got.stamps), expected)
