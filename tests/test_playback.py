"""The session player's core on real session files: time ↔ frame, trials, the play
clock, and a run's prediction over a session's time (knn and a tiny torch model)."""

from __future__ import annotations

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder, trial_record, write_participant

from tactile_studio.errors import UserError
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.playback import PlayClock, SessionPlayback, session_history
from tactile_studio.playback.predictions import predictions_over_time

GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("pb")
    make_dataset_folder(root / "data", participants=3, blocks=3, gestures=GESTURES)
    return root


def test_time_frames_trials_and_clock(tmp_path):
    extra = [trial_record(99, "Poke", 10, 30, status="discarded")]
    path = write_participant(tmp_path / "P01.h5", "P01", 5, gestures=GESTURES, blocks=1,
                             extra_trials=extra)
    pb = SessionPlayback(path)
    try:
        assert pb.n_frames == len(pb.times) and pb.times[0] == 0
        assert pb.duration == pytest.approx((pb.n_frames - 1) / 43.0, rel=1e-3)
        for f in (0, 17, pb.n_frames - 1):
            assert pb.frame_at(pb.time_of(f)) == f
        assert pb.frame_at(-5) == 0 and pb.frame_at(1e9) == pb.n_frames - 1
        assert [t.start for t in pb.trials] == sorted(t.start for t in pb.trials)
        assert any(t.status == "discarded" for t in pb.trials)
        ok = [t for t in pb.trials if t.status == "ok"]
        assert sorted(t.gesture for t in ok) == sorted(GESTURES)
        mid = (ok[0].start + ok[0].end) // 2
        assert pb.trial_at(mid) == ok[0]
        normal, sx, sy, units = pb.frame(mid)
        assert normal.shape == (6, 6) and sx.shape == (6, 6) and units
        assert normal.max() > pb.frame(0)[0].max()  # pressed mid-trial, idle at the start
        h = session_history(pb, mid, [(2, 3), (0, 0)], "normal", seconds=2.0)
        assert h.names == [pb.layout.taxel_name(2, 3), pb.layout.taxel_name(0, 0)]
        assert h.t[-1] == 0 and h.t[0] >= -2.0 - 1 / 43 and h.values.shape == (len(h.t), 2)
        assert h.values[-1, 0] == pytest.approx(normal[2, 3], rel=1e-4, abs=1e-4)
        assert session_history(pb, mid, [(2, 3)], "shear").values.min() >= 0
        with pytest.raises(UserError, match="no trial 12346"):  # said from 1
            pb.trial(12345)
        clock = PlayClock(pb)
        clock.playing, clock.speed = True, 2.0
        assert clock.advance(0.5) == pb.frame_at(1.0)
        clock.loop_trial(ok[0])
        assert clock.frame == ok[0].start
        seen = {clock.advance(0.1) for _ in range(200)}
        assert min(seen) >= ok[0].start and max(seen) < ok[0].end and clock.playing
        clock.loop_trial(None)
        clock.seek(pb.n_frames - 3)
        clock.advance(10.0)
        assert clock.frame == pb.n_frames - 1 and not clock.playing
        assert clock.step(-4) == pb.n_frames - 5
    finally:
        pb.close()


@pytest.mark.parametrize("model", ["knn", "cnn1d"])
def test_predictions_over_time_follow_the_gestures(data, tmp_path, model):
    cfg = ExperimentConfig(data=[str(data / "data")], model=model, evaluation="lopo",
                           preset="tiny", epochs=8 if model == "cnn1d" else None,
                           cache_dir=str(data / "cache"), threads=1, device="cpu")
    run_experiment(cfg, tmp_path / "run")
    pb = SessionPlayback(data / "data" / "P02.h5")
    try:
        frames, probs, labels = predictions_over_time(tmp_path / "run", pb, hop=4)
        assert labels == list(GESTURES) or sorted(labels) == sorted(GESTURES)
        assert probs.shape == (len(frames), 3)
        np.testing.assert_allclose(probs.sum(axis=1), 1.0, atol=1e-5)
        assert np.all(np.diff(frames) == 4)
        # a window that ends at a trial's end covers that trial: mostly right
        hits = []
        for t in pb.trials:
            k = int(np.searchsorted(frames, t.end - 1))
            if k < len(frames) and abs(frames[k] - (t.end - 1)) < 4:
                hits.append(labels[int(probs[k].argmax())] == t.gesture)
        assert len(hits) >= 6 and np.mean(hits) >= 0.6
    finally:
        pb.close()


def test_bad_session_files(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not hdf5")
    with pytest.raises(UserError, match="bad.h5"):
        SessionPlayback(bad)


def test_events_are_placed_on_their_frames(tmp_path):
    from tactile_studio.simulate import SensorSimulator, SimConfig
    from tactile_studio.storage.format.session_writer import SessionWriter

    sim = SensorSimulator(SimConfig(rate=43.0, seed=1, gesture="idle"))
    raw = sim.step(200)
    t = np.arange(200) / 43.0
    path = tmp_path / "ev.h5"
    with SessionWriter(path, sim.layout, {"name": "simulated"}, {"participant": "P1"}) as w:
        w.append_frames(raw, t, 1.7e9 + t)
        w.add_baseline(raw[:40].mean(axis=0), frame=0)
        w.add_event("gap", frame=120, missing=3)
        w.add_event("note", frame=150, text="participant sneezed")
    pb = SessionPlayback(path)
    try:
        marks = {(e.frame, e.kind) for e in pb.events}
        assert {(120, "gap"), (150, "note")} <= marks
        assert next(e for e in pb.events if e.kind == "note").text == "participant sneezed"
    finally:
        pb.close()
