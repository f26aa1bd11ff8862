"""The runner over the FrameStream seam, without threads: a plain in-test stream over
numpy arrays (frames "arrive" when the test says so), a real Recorder that is never
started (it pulls on the runner's calls), a real session file and a manual clock."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np
from collect_fixtures import ManualClock, mini_protocol

from tactile_studio.devices.frame_stream import FrameStream, RecordableStream
from tactile_studio.devices.ring import FrameChunk
from tactile_studio.protocol.trial_runner import RunnerOptions, TrialRunner
from tactile_studio.sensor import SHEARSENSE_6X6
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.recording.recorder import Recorder

RATE = 100.0


class ArrayStream:
    """A FrameStream over prepared arrays; ``capacity`` frames back can be read, older
    ones are reported ``lost`` (as the engine's ring does)."""

    def __init__(self, n_total: int, capacity: int = 1 << 16, seed: int = 0) -> None:
        self.layout = SHEARSENSE_6X6
        rng = np.random.default_rng(seed)
        c = self.layout.n_channels
        self.raw = (1000 + rng.integers(0, 50, (n_total, c))).astype(self.layout.raw_dtype)
        self.device_time = np.arange(n_total) / RATE
        self.baseline: np.ndarray | None = None
        self.baseline_frames = 100
        self.capacity = capacity
        self.running = True
        self._n = 0
        self._events: list[dict[str, Any]] = []

    def arrive(self, n: int) -> None:
        self._n += n

    @property
    def frames(self) -> int:
        return self._n

    @property
    def event_count(self) -> int:
        return len(self._events)

    @property
    def nominal_rate_hz(self) -> float:
        return RATE

    def read_since(self, cursor: int, max_frames: int | None = None) -> FrameChunk:
        lo = max(cursor, self._n - self.capacity, 0)
        hi = self._n if max_frames is None else min(self._n, lo + max_frames)
        return FrameChunk(lo, self.raw[lo:hi], self.device_time[lo:hi],
                          self.device_time[lo:hi] + 1e9, np.arange(lo, hi),
                          lost=max(0, lo - cursor))

    def latest(self) -> FrameChunk | None:
        return self.read_since(self._n - 1) if self._n else None

    def events_since(self, cursor: int) -> list[dict[str, Any]]:
        return list(self._events[cursor:])

    def counters(self) -> dict[str, Any]:
        return {"frames": self._n, "malformed": 0, "malformed_by_kind": {}, "gaps": 0,
                "missing_frames": 0, "reconnects": 0}

    def device_info(self) -> dict[str, Any]:
        return {"plugin": "arrays", "settings": {}}

    def sensor_id(self) -> str | None:
        return None


def _rig(tmp_path: Path, capacity: int = 1 << 16):
    protocol = mini_protocol(n_gestures=2, blocks=1)
    stream = ArrayStream(4000, capacity=capacity)
    recorder = Recorder(stream, tmp_path / "s.h5", {"source": "collect"})
    clock = ManualClock()
    names = [g.name for g in protocol.gestures]
    runner = TrialRunner(protocol, stream, recorder, "P01", [names],
                         options=RunnerOptions(clock=clock))
    return stream, recorder, runner, clock


def _trial(stream: ArrayStream, runner: TrialRunner, clock: ManualClock) -> dict:
    stream.arrive(30)
    start = stream.frames - 1
    assert runner.key(runner.snapshot().prompted_key), runner.hint
    assert runner.state == "trial_recording"
    stream.arrive(runner.trial_frames - 2)  # the key's frame is the trial's first
    runner.tick()
    assert runner.state == "trial_recording"  # one frame short: the trial runs on
    stream.arrive(1)
    runner.tick()
    assert runner.state == "trial_end"
    clock.advance(runner.protocol.beep_s)
    runner.tick()
    assert runner.trials[-1]["start_sample"] == start  # file rows = stream frames here
    return runner.trials[-1]


def test_the_engine_and_the_array_stream_both_satisfy_the_seam() -> None:
    from tactile_studio.devices.engine import AcquisitionEngine
    from tactile_studio.plugins.simulated import SimulatedSensor

    assert isinstance(ArrayStream(10), RecordableStream)
    assert isinstance(AcquisitionEngine(SimulatedSensor()), RecordableStream)
    assert not isinstance(object(), FrameStream)


def test_runner_runs_a_block_on_a_plain_stream_without_threads(tmp_path: Path) -> None:
    before = set(threading.enumerate())
    stream, recorder, runner, clock = _rig(tmp_path)
    assert runner.start()
    assert runner.state == "setup" and "baseline" in runner.hint  # no tare yet
    stream.arrive(100)
    stream.baseline = stream.raw[:100].mean(axis=0)
    runner.tick()
    runner.tick()
    assert runner.state == "waiting_for_key"
    first = _trial(stream, runner, clock)
    second = _trial(stream, runner, clock)
    assert runner.state == "finished"
    assert set(threading.enumerate()) == before  # nothing ran in the background
    n = runner.trial_frames
    assert [t["end_sample"] - t["start_sample"] for t in (first, second)] == [n, n]
    assert second["start_sample"] >= first["end_sample"]
    assert "dropped_frames" not in first["flags"] + second["flags"]
    assert recorder.rows_written >= second["end_sample"]
    recorder.stop()
    with SessionFile(tmp_path / "s.h5") as s:
        assert [(t["gesture"], t["start_sample"], t["status"]) for t in s.journal.trials] == [
            (t["gesture"], t["start_sample"], "ok") for t in (first, second)]
        rows = slice(second["start_sample"], second["end_sample"])
        frames = slice(second["start_sample"], second["start_sample"] + n)
        np.testing.assert_array_equal(s.raw(rows.start, rows.stop), stream.raw[frames])
        assert [e["kind"] for e in s.events].count("session_end") == 1


def test_frames_the_recorder_lost_shift_the_rows_of_later_trials(tmp_path: Path) -> None:
    stream, recorder, runner, clock = _rig(tmp_path, capacity=256)
    runner.start()
    stream.arrive(100)
    stream.baseline = stream.raw[:100].mean(axis=0)
    runner.tick()
    runner.tick()
    recorder.catch_up()  # rows 0..99 written
    stream.arrive(400)   # more than the stream holds: 144 frames are gone for the recorder
    recorder.catch_up()
    assert recorder.dropped == 144
    assert recorder.row_of(150) == recorder.row_of(244) == 100  # lost: the next kept row
    stream.arrive(30)
    start = stream.frames - 1
    assert runner.key(runner.snapshot().prompted_key), runner.hint
    stream.arrive(runner.trial_frames - 1)
    runner.tick()
    trial = runner.trials[-1]
    assert trial["start_sample"] == recorder.row_of(start) == start - 144
    assert "dropped_frames" not in trial["flags"]  # the trial's own frames all arrived
    recorder.stop()
    with SessionFile(tmp_path / "s.h5") as s:
        assert s.journal.counters["dropped"] == 144
        assert [e["lost"] for e in s.events if e["kind"] == "overrun"] == [144]
        np.testing.assert_array_equal(s.raw(trial["start_sample"], trial["end_sample"]),
                                      stream.raw[start:start + runner.trial_frames])


def test_a_trial_whose_frames_the_recorder_lost_is_flagged(tmp_path: Path) -> None:
    stream, recorder, runner, clock = _rig(tmp_path, capacity=64)
    runner.start()
    stream.arrive(100)
    stream.baseline = stream.raw[:100].mean(axis=0)
    runner.tick()
    runner.tick()
    recorder.catch_up()
    assert runner.key(runner.snapshot().prompted_key), runner.hint
    stream.arrive(runner.trial_frames + 100)  # the ring overran before anyone read them
    runner.tick()
    assert runner.state == "trial_end"
    assert "dropped_frames" in runner.trials[-1]["flags"]
    recorder.stop()
