"""Live inference's core on a real engine streaming the simulated sensor: a windowed torch
model (tiny CNN-Transformer) goes through the streaming predictor and agrees with the
run's own window path on the same frames; the rf/knn path is exercised in
tests/test_ui_live_inference.py."""

from __future__ import annotations

import time

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.devices import create_device
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.learn.deploy.live_inference import LiveInference, RunningCalibration
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment

GESTURES = ("Poke", "Heavy Pat", "Twist")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("stream")
    make_dataset_folder(root / "data", participants=2, blocks=2, gestures=GESTURES)
    cfg = ExperimentConfig(data=[str(root / "data")], model="cnn_transformer",
                           evaluation="all-inclusive", preset="tiny", epochs=2, threads=1,
                           device="cpu", channels="both", cache_dir=str(root / "cache"))
    run_experiment(cfg, root / "run")
    return root / "run"


def test_windowed_torch_model_streams_and_matches_the_window_path(run):
    model = WindowModel(run)
    assert model.streams and model.learner.view.kind == "windows"
    engine = AcquisitionEngine(create_device("simulated", {"rate": "400", "gesture": "Twist"}))
    engine.start()
    try:
        inf = LiveInference(engine, model)
        assert inf.streamer is not None and inf.streamer.cached  # per-frame embeddings
        deadline = time.monotonic() + 30
        pred = None
        while pred is None and time.monotonic() < deadline:
            pred = inf.step()
            time.sleep(0.05)
        assert pred is not None, "no prediction within 30 s"
        assert pred.probs.shape == (3,) and abs(pred.probs.sum() - 1) < 1e-5
        assert pred.top3[0][0] in GESTURES and pred.latency_ms > 0
        # the same newest window through the run's own (non-streaming) path
        w = model.learner.view.frames
        chunk = engine.read_since(pred.frame + 1 - w, w)
        assert chunk.stop == pred.frame + 1
        frames = model.decode(engine.layout, chunk.raw, engine.baseline)
        ref = model.predict_windows(engine.layout, [frames], 400.0)[0]
        np.testing.assert_allclose(pred.probs, ref, atol=1e-4)
    finally:
        engine.stop()


def test_a_streaming_model_adapting_as_they_touch_predicts_window_by_window(run, tmp_path):
    cfg = ExperimentConfig(data=[str(run.parent / "data")], model="cnn_transformer",
                           evaluation="lopo", preset="tiny", epochs=1, threads=1, device="cpu",
                           channels="both", cache_dir=str(run.parent / "cache"), adapt="person")
    run_experiment(cfg, tmp_path / "adapted")
    model = WindowModel(tmp_path / "adapted")
    assert model.streams and model.adapts_as_they_touch
    engine = AcquisitionEngine(create_device("simulated", {"rate": "400", "gesture": "Twist"}))
    engine.start()
    try:
        adapting = RunningCalibration(model, touches=3, minimum=2, alike=1.0)  # one gesture
        inf = LiveInference(engine, model, adapting=adapting)
        assert inf.streamer is None  # each re-estimate would stale the cached embeddings
        deadline = time.monotonic() + 30
        while adapting.count < 3 and time.monotonic() < deadline:
            pred = inf.step()
            time.sleep(0.02)
        assert adapting.count == 3 and pred is not None and inf.error is None
        assert model.fitted is not model.trained  # its batch norm met the touches
        assert pred.top3[0][0] in GESTURES
    finally:
        engine.stop()
