"""The gesture metrics inside the networks (learn/models/gesture_features.py) equal the
numpy definition the random forest uses, on z-scored simulated windows, and the fold's
normalisation they undo travels with the weights."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from learn_fixtures import make_dataset_folder

from tactile_studio.learn.data import views
from tactile_studio.learn.data.dataset import build_dataset
from tactile_studio.learn.data.features import trial_features
from tactile_studio.learn.learners.contract import DataInfo
from tactile_studio.learn.learners.families import make_learner
from tactile_studio.learn.learners.train import load_weights, save_weights
from tactile_studio.learn.models.gesture_features import GestureFeatures, metric_names
from tactile_studio.sensor.gesture_metrics import MOVEMENT_TYPES

FRAMES = 86  # a 2 s window at 43 Hz


@pytest.fixture(scope="module")
def windows(tmp_path_factory):
    """Simulated 2 s trials at the real-people difficulty, physical and z-scored."""
    tmp = tmp_path_factory.mktemp("gesture")
    make_dataset_folder(tmp / "data", participants=2, blocks=2, difficulty="real")
    ds = build_dataset([str(tmp / "data")], cache_dir=str(tmp / "cache"))
    x = views.make_samples(ds.trials, "resample", FRAMES, 0)[0]
    mean, std = views.channel_stats(x)
    return ds.channel_names, x, views.normalise(x, mean, std), mean, std


def _reference(x: np.ndarray, names: list[str], pitch: float) -> np.ndarray:
    """The random forest's gesture columns (``trial_features``) of every window."""
    rows = []
    for trial in x:
        row, columns = trial_features(trial, names, FRAMES / 2.0, pitch)
        keep = [i for i, c in enumerate(columns) if c.startswith(("gesture_", "movement_"))]
        assert [columns[i].removeprefix("gesture_") for i in keep] == \
            metric_names(len(names))
        rows.append(row[keep])
    return np.array(rows)


@pytest.mark.parametrize("channels", [[0, 1, 2], [0], [1, 2]])
@pytest.mark.parametrize("pitch", [1.0, 0.5])
def test_torch_metrics_equal_the_numpy_definition(windows, channels, pitch):
    names, x, xz, mean, std = windows
    picked = [names[i] for i in channels]
    features = GestureFeatures(len(channels), FRAMES, window_s=2.0)
    features.set_input_norm(mean[channels], std[channels], pitch)
    got = features.metrics(torch.from_numpy(np.ascontiguousarray(xz[:, channels]))).numpy()
    want = _reference(x[:, channels], picked, pitch)
    assert got.shape == want.shape == (len(x), len(metric_names(len(channels))))
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-4)
    movements = want[:, -len(MOVEMENT_TYPES):].argmax(1)
    assert len(set(movements.tolist())) >= 2  # the windows exercise more than one type


def test_without_the_fold_normalisation_the_metrics_are_wrong(windows):
    """What the buffers are for: z-scored windows read as physical give other metrics."""
    names, x, xz, mean, std = windows
    features = GestureFeatures(3, FRAMES)
    got = features.metrics(torch.from_numpy(xz)).numpy()
    assert not np.allclose(got, _reference(x, list(names), 1.0), rtol=1e-2, atol=1e-2)


def test_the_learner_gives_the_model_its_fold_normalisation_and_it_is_saved(windows,
                                                                             tmp_path):
    names, x, xz, mean, std = windows
    learner = make_learner("sefusion", "full", {"members": 1, "gesture": True}, epochs=1)
    info = DataInfo(9, 3, (6, 6), tuple(names), 0.5)
    xs = views.make_samples([t for t in x], "resample", 43, 0)[0]
    stats = learner.norm_stats(xs)
    y = np.arange(len(xs)) % 9
    xn = learner.apply_norm(xs, stats)
    fitted, _, _ = learner.fit(info, (xn, y), (xn, y), 0, None, None, norm=stats)
    gesture = fitted.model.stats.gesture
    np.testing.assert_allclose(gesture.input_mean.numpy(), stats["mean"], rtol=1e-6)
    np.testing.assert_allclose(gesture.input_std.numpy(), stats["std"], rtol=1e-6)
    assert float(gesture.cell_pitch) == 0.5
    fitted.save(tmp_path / "model.safetensors")
    again = learner.load(tmp_path / "model.safetensors", info)
    np.testing.assert_allclose(again.model.stats.gesture.input_mean.numpy(), stats["mean"],
                               rtol=1e-6)
    np.testing.assert_allclose(again.predict_proba(xn), fitted.predict_proba(xn), atol=1e-6)


def test_weights_round_trip_keeps_the_buffers(tmp_path):
    from tactile_studio.learn.models import get_model_spec

    model = get_model_spec("cnn3d").build(9, 3, (6, 6), "full", gesture=True)
    model.set_input_norm([0.5, 0.1, -0.1], [2.0, 0.3, 0.4], 0.5)
    save_weights(model.state_dict(), tmp_path / "w.safetensors")
    fresh = load_weights(get_model_spec("cnn3d").build(9, 3, (6, 6), "full", gesture=True),
                         tmp_path / "w.safetensors")
    assert fresh.stats.gesture.input_std.tolist() == pytest.approx([2.0, 0.3, 0.4])
    assert float(fresh.stats.gesture.cell_pitch) == 0.5
