"""Calibrating a finished run to one person (learn/deploy/window_model.py ``calibrate``,
playback/predictions.py): the session player and live inference meet a person as
``--adapt person`` met each test person in evaluation. The calibrated model must predict
that person's trials exactly as the run's stored (adapted) predictions do. Real folds,
real tiny training, real session files."""

from __future__ import annotations

import json
import shutil
import time
from dataclasses import replace

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder
from shared_runs import GESTURES

from tactile_studio.devices import create_device
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.live_inference import LiveInference, RunningCalibration
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.experiments.experiment import (
    ExperimentConfig,
    prepare_inputs,
    run_experiment,
)
from tactile_studio.learn.learners.fused import person_columns
from tactile_studio.learn.results.rescore import load_run_data
from tactile_studio.playback import SessionPlayback
from tactile_studio.playback.predictions import calibrate_to_session, predictions_over_time
from tactile_studio.sensor.layout import get_layout


@pytest.fixture(scope="module")
def root(tmp_path_factory, shared_runs):
    """cnn1d, rf (both --adapt person and rf as trained) and cnn1d fused with rf 0.5 on
    3 people x ``GESTURES`` (tests/shared_runs.py), a copy of ours."""
    root = tmp_path_factory.mktemp("calibration")
    shared_runs.copy_to(root, {"cnn1d_person": "net_adapted", "rf_person": "rf_adapted",
                               "rf_none": "rf", "fused_person": "fused_adapted"})
    return root


def _person(run, person: str):
    """(the person's trials, their rate, layout, stored probabilities per trial)."""
    _, _, records, ds, _, _ = load_run_data(run, device="cpu")
    rec = next(r for r in records if r["test_participants"] == [person])
    owner = np.array(rec["predictions"]["owner"])
    probs = np.array(rec["predictions"]["probs"])
    trials = np.unique(owner)
    stored = np.stack([probs[owner == t].mean(axis=0) for t in trials])
    return ([ds.trials[t] for t in trials], float(ds.rates[trials[0]]),
            get_layout(ds.layout), stored)


@pytest.mark.parametrize("run", ["cnn1d_person", "rf_person", "fused_person"])
def test_a_run_calibrated_to_a_person_predicts_as_its_evaluation_did(root, run):
    windows, rate, layout, stored = _person(root / run, "P02")
    model = WindowModel(root / run, "P02")
    assert not model.needs_calibration  # forests: the training people's pooled statistics
    as_trained = model.predict_windows(layout, windows, rate)
    assert not np.allclose(as_trained, stored, atol=1e-3)
    assert model.calibrate(layout, windows, rate, "P02's trials") >= len(windows)
    assert not model.needs_calibration
    np.testing.assert_allclose(model.predict_windows(layout, windows, rate), stored, atol=1e-4)
    assert model.describe()["calibrated_on"] == "P02's trials"
    if run.startswith("cnn1d"):  # features only (live): the network keeps its statistics
        model.calibrate(layout, windows, rate, batch_norm=False)
        np.testing.assert_allclose(model.predict_windows(layout, windows, rate), as_trained)


@pytest.mark.parametrize("run", ["rf_person", "fused_person"])
def test_an_adapted_forest_reads_a_window_as_trained_with_its_training_people_pooled(root,
                                                                                     run):
    config, _, records, ds, learner, _ = load_run_data(root / run, device="cpu")
    rec = next(r for r in records if r["test_participants"] == ["P02"])
    _, packed, owner, *_ = prepare_inputs(learner, ds, replace(config, adapt="none"))
    raw = person_columns(learner, packed)  # a fused sample's forest features
    index = {u: i for i, u in enumerate(ds.uids)}
    people = np.unique(ds.participants[[index[u] for u in rec["train"]]])
    assert list(people) == ["P01", "P03"]
    rows = np.isin(ds.participants[owner], people)  # every trial of the training people
    model = WindowModel(root / run, "P02")
    assert model.has_view_as_trained and RunningCalibration(model).guarded
    assert model.pooled.shape == (2, raw.shape[1])  # two rows: the pooled mean -+ spread
    np.testing.assert_allclose(model.pooled.mean(axis=0), raw[rows].mean(axis=0), rtol=1e-4,
                               atol=1e-4)
    np.testing.assert_allclose(model.pooled.std(axis=0), raw[rows].std(axis=0), rtol=1e-3,
                               atol=1e-4)
    windows, rate, layout, stored = _person(root / run, "P02")
    model.calibrate(layout, windows, rate)  # as trained stays the pooled view
    np.testing.assert_allclose(model.predict_windows(layout, windows, rate), stored, atol=1e-4)
    fresh = WindowModel(root / run, "P02")
    np.testing.assert_allclose(model.predict_windows(layout, windows, rate, as_trained=True),
                               fresh.predict_windows(layout, windows, rate))


def test_an_adapted_rf_from_before_the_pooled_view_needs_calibrating(root, tmp_path):
    old = tmp_path / "rf_person"
    shutil.copytree(root / "rf_person", old)
    for fold in old.glob("folds/*/fold.json"):
        record = json.loads(fold.read_text())
        del record["as_trained"]
        fold.write_text(json.dumps(record))
    windows, rate, layout, _ = _person(old, "P02")
    model = WindowModel(old, "P02")
    assert model.needs_calibration and not model.has_view_as_trained
    with pytest.raises(UserError, match="calibrate it on a recording"):
        model.predict_windows(layout, windows, rate)
    assert not RunningCalibration(model).guarded  # nothing to judge the touches by
    model.calibrate(layout, windows, rate)
    assert model.predict_windows(layout, windows, rate).shape == (len(windows), 3)


def test_calibrating_from_a_session_file_and_its_one_line_errors(root):
    session = root / "data" / "P03.h5"
    rf = WindowModel(root / "rf_person", "P03")
    pb = SessionPlayback(session)
    try:
        counted = sum(t.status == "ok" for t in pb.trials)
    finally:
        pb.close()
    assert calibrate_to_session(rf, session) == counted  # one feature row per trial
    with pytest.raises(UserError, match="trained without --adapt"):
        calibrate_to_session(WindowModel(root / "rf_none", "P03"), session)
    windows, rate, layout, _ = _person(root / "cnn1d_person", "P03")
    with pytest.raises(UserError, match="too short to calibrate"):
        WindowModel(root / "cnn1d_person", "P03").calibrate(layout, windows[:1], rate, "x")


def test_the_player_adapts_an_adapted_run_to_the_session_it_plays(root):
    pb = SessionPlayback(root / "data" / "P01.h5")
    try:
        _, probs, _ = predictions_over_time(root / "rf_person", pb, hop=8)
        _, plain, _ = predictions_over_time(root / "rf_none", pb, hop=8)
    finally:
        pb.close()
    # rf_person predicts only once calibrated: the player calibrated it on the session
    assert probs.shape == plain.shape and np.isfinite(probs).all()
    np.testing.assert_allclose(probs.sum(axis=1), 1.0, atol=1e-5)


def test_a_long_window_is_cut_as_the_run_cut_long_trials(root, tmp_path):
    # 6 s performances: the run trained on 2 s windows of them, so a 6 s window predicts
    # as the mean over its 2 s windows (the trial prediction evaluation made)
    make_dataset_folder(tmp_path / "data", participants=3, blocks=1, gestures=GESTURES,
                        repeats=3)
    cfg = ExperimentConfig(data=[str(tmp_path / "data")], model="rf", evaluation="lopo",
                           preset="tiny", threads=1, cache_dir=str(tmp_path / "cache"))
    run_experiment(cfg, tmp_path / "run")
    windows, rate, layout, stored = _person(tmp_path / "run", "P01")
    assert windows[0].shape[1] > 2.5 * 2 * rate  # long: several windows each
    model = WindowModel(tmp_path / "run", "P01")
    np.testing.assert_allclose(model.predict_windows(layout, windows, rate), stored, atol=1e-4)
    # live, such a run predicts 2 s windows (as trained), not whole performances
    assert model.window > 2.5 * model.window_for(rate) and model.window_for(rate) == \
        round(2 * rate)
    short = WindowModel(root / "rf_none", "P01")  # 2 s trials: a window is a trial
    assert short.window_for(rate) == short.window


def _until(step, done, seconds: float = 30.0):
    """Steps live inference until ``done(result)``; the last result."""
    deadline, got = time.monotonic() + seconds, None
    while time.monotonic() < deadline:
        got = step()
        if done(got):
            return got
        time.sleep(0.02)
    return got


@pytest.mark.parametrize("run", ["rf_person", "cnn1d_person"])
def test_each_live_window_meets_the_statistics_of_the_last_touches_and_itself(root, run):
    pb = SessionPlayback(root / "data" / "P02.h5")
    try:
        layout, base = pb.layout, pb.session.baseline(0)
        trials = [(pb.raw[t.start:t.end], t.end) for t in pb.trials][:5]
    finally:
        pb.close()
    model = WindowModel(root / run, "P02")
    decoded = [model.decode(layout, raw, base) for raw, _ in trials]
    idle_raw = np.repeat(base[None], len(trials[2][0]), axis=0).astype(trials[2][0].dtype)
    idle = model.decode(layout, idle_raw, base)
    running = RunningCalibration(model, touches=4, minimum=3, alike=1.0)  # unguarded
    rate = 43.0

    def meets(windows: list[np.ndarray]) -> None:
        fresh = WindowModel(root / run, "P02")
        fresh.calibrate(layout, windows, rate)
        np.testing.assert_allclose(model.reference, fresh.reference)
        probe = [decoded[0]]
        np.testing.assert_allclose(model.predict_windows(layout, probe, rate),
                                   fresh.predict_windows(layout, probe, rate), atol=1e-6)

    for k in range(2):
        running.prepare(layout, trials[k][0], base, decoded[k], trials[k][1], rate)
    assert running.count == 2 and model.reference is None  # as trained until the third
    running.prepare(layout, trials[2][0], base, decoded[2], trials[2][1], rate)
    meets(decoded[:3])
    # nobody touching: not kept, but that window is predicted with its own statistics
    running.prepare(layout, idle_raw, base, idle, trials[2][1] + len(idle_raw), rate)
    assert running.count == 3
    meets(decoded[:3] + [idle])
    for k in (3, 4):
        running.prepare(layout, trials[k][0], base, decoded[k], trials[k][1], rate)
    assert running.count == 4  # the last four touches
    meets(decoded[1:5])
    # a window overlapping the last touch by more than half: not kept, still among them
    running.prepare(layout, trials[4][0], base, decoded[4], trials[4][1] + 1, rate)
    assert running.count == 4
    meets(decoded[2:5] + [decoded[4]])
    if run.startswith("cnn1d"):  # the network's batch norm moved with them
        assert model.fitted is not model.trained


def test_live_adapts_only_while_no_one_gesture_fills_the_touches(root):
    run = root / "cnn1d_person"
    windows, rate, layout, _ = _person(run, "P02")
    model = WindowModel(run, "P02")
    seen = model.predict_windows(layout, windows, rate, as_trained=True).argmax(axis=1)
    a, b = windows[0], next(w for w, s in zip(windows, seen) if s != seen[0])
    alone = model.predict_windows(layout, [a], rate)
    running = RunningCalibration(model, touches=4, minimum=3, alike=0.75)  # 3 of 4 at most
    end = 0

    def touch(window: np.ndarray) -> bool:
        nonlocal end
        end += 1000
        running.keep(layout, window, end, rate)
        running.adapt_for(layout, window, rate, kept=True)
        return running.adapted

    # one gesture again and again: its statistics would normalise it away
    assert not any(touch(a) for _ in range(4))
    assert running.count == 4 and running.most_alike == 4 and model.fitted is model.trained
    np.testing.assert_allclose(model.predict_windows(layout, [a], rate), alone)
    assert touch(b) and running.most_alike == 3  # another gesture among them: adapted
    fresh = WindowModel(run, "P02")
    fresh.calibrate(layout, [a, a, a, b], rate)
    np.testing.assert_allclose(model.predict_windows(layout, [b], rate),
                               fresh.predict_windows(layout, [b], rate), atol=1e-6)
    assert [touch(a) for _ in range(4)] == [True, True, True, False]  # b has left the four
    assert model.fitted is model.trained and model.calibrated_on == ""
    # an rf trained with --adapt judges them by its training people's pooled statistics
    assert RunningCalibration(WindowModel(root / "rf_person", "P02")).guarded
    assert RunningCalibration(model).alike == pytest.approx(2 / 3)  # 3 gestures: 6 of 9


def test_live_adapts_to_whoever_touches_from_their_last_touches(root):
    model = WindowModel(root / "rf_person")
    engine = AcquisitionEngine(create_device("simulated", {"rate": "400", "gesture": "idle"}))
    engine.start()
    try:
        running = RunningCalibration(model, touches=4, minimum=3, alike=1.0)  # unguarded
        inf = LiveInference(engine, model, adapting=running)
        # nobody touches: nothing is kept, predicted as trained
        _until(inf.step, lambda _: engine.frames > 3 * model.window)
        assert running.count == 0 and model.reference is None and inf.latest is not None
        engine.device.set_gesture("Heavy Pat")
        _until(inf.step, lambda _: running.count >= 3)
        assert running.count >= 3 and model.reference is not None, "no 3 touches in 30 s"
        assert model.calibrated_on == f"their last {running.count} touches"
        first = running.ends[0]  # kept until a fifth touch pushes it out
        _until(inf.step, lambda _: running.ends[0] > first)
        assert running.ends[0] > first, "no fifth touch in 30 s"
        assert running.count == 4 and inf.error is None  # the last four touches only
        assert np.diff(running.ends).min() >= model.window // 2  # overlapping by half at most
    finally:
        engine.stop()
