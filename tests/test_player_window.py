"""The session player predicts with the model's own window and step, the ones live
inference uses (WindowModel.prediction_ends), not the session's trial length: a run
trained on 2 s windows of 12 s performances predicts a 12 s performance 2 s at a time."""

from __future__ import annotations

import numpy as np
from learn_fixtures import make_dataset_folder

from tactile_studio.learn.deploy.window_model import PREDICTION_HOP_S, WindowModel
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.playback import SessionPlayback
from tactile_studio.playback.predictions import predictions_over_time

GESTURES = ("Poke", "Heavy Pat", "Twist")


def test_the_player_predicts_12_s_performances_with_the_runs_2_s_windows(tmp_path):
    make_dataset_folder(tmp_path / "data", participants=3, blocks=1, gestures=GESTURES,
                        repeats=6)  # 12 s performances of a 2 s gesture repeated
    cfg = ExperimentConfig(data=[str(tmp_path / "data")], model="rf", evaluation="lopo",
                           preset="tiny", threads=1, cache_dir=str(tmp_path / "cache"))
    run_experiment(cfg, tmp_path / "run")
    pb = SessionPlayback(tmp_path / "data" / "P02.h5")
    try:
        rate = (pb.n_frames - 1) / pb.duration
        lengths = [t.end - t.start for t in pb.trials]
        assert min(lengths) > 11 * rate  # the session's trials are 12 s long
        frames, probs, labels = predictions_over_time(tmp_path / "run", pb)
        w = round(2 * rate)
        # the first prediction comes once 2 s are in, not after a whole 12 s trial
        assert frames[0] == w - 1
        assert frames[0] / rate < 2.1
        # one prediction per live step (a quarter second)
        assert np.all(np.diff(frames) == round(PREDICTION_HOP_S * rate))
        # each is the model's prediction of the 2 s window ending at that frame
        model = WindowModel(tmp_path / "run", "P02")
        decoded = model.decode(pb.layout, pb.raw, pb.session.baseline(0))
        k = len(frames) // 2
        end = int(frames[k]) + 1
        expected = model.predict_windows(pb.layout, [decoded[:, end - w:end]], rate)[0]
        np.testing.assert_allclose(probs[k], expected, atol=1e-6)
        assert model.prediction_ends(pb.n_frames, rate)[0] == model.window_for(rate) == w
    finally:
        pb.close()
