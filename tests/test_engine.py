"""The acquisition engine and ring buffer, driven by a real (test) plugin in a real thread."""

from __future__ import annotations

import numpy as np
import pytest
from plugin_fixtures import CountingDevice
from waiting import wait_until

from tactile_studio.devices.engine import ERROR, FINISHED, RUNNING, AcquisitionEngine
from tactile_studio.devices.engine_events import KINDS, EngineEvent, LslClockStopped, LslMarker
from tactile_studio.devices.registry import parse_set_options
from tactile_studio.devices.ring import RingBuffer
from tactile_studio.errors import SettingsError


def wait(cond, timeout=10.0):
    wait_until(cond, timeout, step=0.005)


def test_ring_buffer_cursor_reads_and_overrun():
    ring = RingBuffer(8, 2, "float32")
    ring.write(np.arange(10, dtype=np.float32).reshape(5, 2), np.arange(5.0), np.arange(5.0),
               np.arange(5))
    chunk = ring.read_since(0)
    assert (chunk.start, len(chunk), chunk.lost) == (0, 5, 0)
    ring.write(np.zeros((6, 2), np.float32), np.arange(6.0), np.arange(6.0), np.arange(6))
    chunk = ring.read_since(0)
    assert chunk.lost == 3 and chunk.start == 3 and len(chunk) == 8
    assert ring.latest().start == 10
    assert len(ring.last(3)) == 3 and ring.last(3).stop == 11


def test_engine_delivers_every_frame_in_order_then_finishes():
    dev = CountingDevice(frames=500)
    eng = AcquisitionEngine(dev, capacity=1024, baseline_frames=10)
    eng.start()
    wait(lambda: eng.state == FINISHED)
    chunk = eng.read_since(0)
    assert len(chunk) == 500
    assert np.array_equal(chunk.seq, np.arange(500))
    assert np.array_equal(chunk.raw[:, 0], np.arange(500))
    assert eng.gaps == 0
    kinds = [e["kind"] for e in eng.events_since(0)]
    assert kinds[0] == "connect" and "tare" in kinds and kinds[-1] == "finished"
    assert np.allclose(eng.baseline, np.arange(10).mean())


def test_engine_counts_sequence_gaps_and_malformed_input():
    eng = AcquisitionEngine(CountingDevice(frames=300, skip_every=50, malformed_every=100))
    eng.start()
    wait(lambda: eng.state == FINISHED)
    assert eng.gaps == 6 and eng.missing_frames == 6
    assert eng.counters()["malformed_by_kind"] == {"short": 3}
    gaps = [e for e in eng.events_since(0) if e["kind"] == "gap"]
    assert [g["after_seq"] for g in gaps] == [49, 99, 149, 199, 249, 299]


def test_re_tare_uses_the_next_frames_and_is_an_event():
    dev = CountingDevice(frames=0)
    eng = AcquisitionEngine(dev, baseline_frames=20)
    eng.start()
    wait(lambda: eng.baseline is not None)
    first = eng.baseline.copy()
    eng.tare(5)
    wait(lambda: sum(e["kind"] == "tare" for e in eng.events_since(0)) == 2)
    eng.stop()
    tare = [e for e in eng.events_since(0) if e["kind"] == "tare"][-1]
    assert tare["frames"] == 5 and not np.allclose(eng.baseline, first)
    assert np.allclose(eng.baseline,
                       np.mean(np.arange(tare["first_frame"], tare["first_frame"] + 5)))


def test_plugin_crash_is_reported_and_the_engine_stops_cleanly():
    eng = AcquisitionEngine(CountingDevice(frames=0, crash_at=40))
    eng.start()
    wait(lambda: eng.state == ERROR)
    assert "ZeroDivisionError" in eng.error
    assert eng.frames >= 32  # what arrived before the crash is kept
    assert eng.events_since(0)[-1]["kind"] == "error"


def test_open_failure_is_a_one_line_error():
    eng = AcquisitionEngine(CountingDevice(fail_open=True))
    eng.start()
    wait(lambda: eng.state == ERROR)
    assert eng.error == "counting: port /dev/nothing not found"


def test_lost_device_reconnects_with_a_gap_event():
    dev = CountingDevice(frames=0)
    eng = AcquisitionEngine(dev)
    eng.start()
    wait(lambda: eng.frames > 50)
    dev.lose.set()
    wait(lambda: eng.state != RUNNING)
    wait(lambda: dev.open_calls >= 2)  # at least one failed reopen while unplugged
    dev.unplugged.clear()
    wait(lambda: eng.reconnects == 1 and eng.state == RUNNING)
    before = eng.frames
    wait(lambda: eng.frames > before + 50)
    eng.stop()
    kinds = [e["kind"] for e in eng.events_since(0)]
    assert kinds.index("disconnect") < kinds.index("gap") < kinds.index("reconnect")
    gap = next(e for e in eng.events_since(0) if e["kind"] == "gap" and e.get("cause"))
    assert gap["seconds"] > 0


def test_settings_are_validated_with_named_errors():
    with pytest.raises(SettingsError, match="unknown setting 'speed'"):
        CountingDevice(speed=3)
    with pytest.raises(SettingsError, match="setting frames: 'abc' is not a valid int"):
        CountingDevice(frames="abc")
    with pytest.raises(SettingsError, match="below the minimum"):
        CountingDevice(frames=-1)
    assert CountingDevice(fail_open="yes").settings["fail_open"] is True
    assert parse_set_options(["a=1", "b = x=y"]) == {"a": "1", "b": "x=y"}
    with pytest.raises(SettingsError, match="key=value"):
        parse_set_options(["novalue"])


def test_the_journal_holds_only_declared_kinds_in_the_file_form():
    """Sequence gaps, a tare, a crash: every journal entry is a kind declared in
    devices/engine_events.py, in the form a session file stores (time, frame, kind, then
    the detail in its declared order); an undeclared event is refused."""
    eng = AcquisitionEngine(CountingDevice(frames=0, skip_every=50, crash_at=120))
    eng.start()
    wait(lambda: eng.state == ERROR)
    with pytest.raises(TypeError, match="not a declared engine event"):
        eng.add_event(EngineEvent())
    entries = eng.events_since(0)
    assert {e["kind"] for e in entries} <= {k.kind for k in KINDS}
    assert {"connect", "gap", "tare", "error"} <= {e["kind"] for e in entries}
    gap = next(e for e in entries if e["kind"] == "gap")
    assert list(gap) == ["time", "frame", "kind", "missing", "after_seq"]
    assert gap["frame"] == 50 and gap["after_seq"] == 49
    marker = eng.add_event(LslMarker("a | b", "cues", 12.5, 0.25, -3.0, ("a", "b")), frame=7,
                           at=99.0)
    assert marker == {"time": 99.0, "frame": 7, "kind": "marker", "text": "a | b",
                      "channels": ["a", "b"], "stream": "cues", "lsl_time": 12.5,
                      "time_correction": 0.25, "offset_s": -3.0, "source": "lsl"}
    assert list(eng.add_event(LslClockStopped("x"))) == ["time", "frame", "kind", "streaming",
                                                         "frame_stream"]
