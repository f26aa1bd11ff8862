"""Streaming predictor: same answers as a full forward pass, per-frame CNN once per frame.

Budget: ~5 s on one thread of 2 shared cores (tiny presets, random weights in eval mode).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from tactile_studio.errors import UserError
from tactile_studio.learn.data import views
from tactile_studio.learn.deploy.streaming import (
    InputNorm,
    StreamingPredictor,
    frames_from_raw,
)
from tactile_studio.learn.models import MODELS
from tactile_studio.sensor.layout import SHEARSENSE_6X6, get_layout


@pytest.fixture(autouse=True)
def _threads():
    torch.set_num_threads(1)  # the 2 cores are shared by the whole team


def _model(name: str, channels: int = 3, grid=(6, 6)):
    torch.manual_seed(0)
    model = MODELS[name].build(5, channels, grid, "tiny")
    model.train()
    with torch.no_grad():  # non-trivial BN statistics
        model(torch.randn(8, *model.input_shape) + 0.3)
    return model.eval()


def _softmax_full(model, window: np.ndarray) -> np.ndarray:
    with torch.inference_mode():
        return torch.softmax(model(torch.from_numpy(window)), dim=1)[0].numpy()


def test_cnn_transformer_stream_equals_full_forward_and_runs_the_cnn_once_per_frame():
    model = _model("cnn_transformer")
    view = MODELS["cnn_transformer"].view("tiny")
    calls = []
    hook = model.frame_cnn.register_forward_hook(
        lambda mod, inp, out: calls.append(inp[0].shape[0]))
    rng = np.random.default_rng(3)
    stream = rng.normal(size=(40, 3, 6, 6)).astype(np.float32)
    mean, std = np.array([0.5, -0.2, 0.1]), np.array([2.0, 1.0, 0.5])
    predictor = StreamingPredictor(model, view, norm=InputNorm(mean, std))
    assert predictor.cached
    outputs = []
    for i, frame in enumerate(stream):
        probs = predictor.push(frame)
        assert (probs is None) == (i + 1 < view.frames)
        if probs is not None:
            outputs.append((i, probs))
    hook.remove()
    assert sum(calls) == len(stream)  # every frame through the CNN exactly once
    assert len(outputs) == len(stream) - view.frames + 1
    z = (stream - mean.reshape(1, 3, 1, 1)) / std.reshape(1, 3, 1, 1)
    for i, probs in outputs:
        window = z[i + 1 - view.frames:i + 1].transpose(1, 0, 2, 3)[None].astype(np.float32)
        np.testing.assert_allclose(probs, _softmax_full(model, window), rtol=1e-4, atol=1e-5)
        assert probs.sum() == pytest.approx(1.0, abs=1e-5)


def test_hop_and_reset():
    model = _model("cnn_transformer", channels=1, grid=(8, 8))
    view = MODELS["cnn_transformer"].view("tiny")
    predictor = StreamingPredictor(model, view, hop=3)
    frames = np.random.default_rng(0).normal(size=(20, 1, 8, 8)).astype(np.float32)
    out = predictor.push_many(frames)
    assert len(out) == len(range(view.frames - 1, 20, 3))
    predictor.reset()
    assert not predictor.ready and predictor.push(frames[0]) is None
    with pytest.raises(ValueError):
        predictor.predict()


@pytest.mark.parametrize("name", ["cnn1d", "cnn3d", "mts3d"])
def test_generic_models_recompute_the_view_of_the_newest_window(name):
    model = _model(name)
    view = MODELS[name].view("tiny")
    predictor = StreamingPredictor(model, view, window=30)
    assert not predictor.cached
    stream = np.random.default_rng(1).normal(size=(35, 3, 6, 6)).astype(np.float32)
    outputs = predictor.push_many(stream)
    assert len(outputs) == 6
    trial = stream[-30:].transpose(1, 0, 2, 3)
    expected = _softmax_full(model, views.trial_view(trial, view.kind, view.frames))
    np.testing.assert_allclose(outputs[-1], expected, rtol=1e-4, atol=1e-5)


def test_frames_from_raw_decodes_in_dataset_channel_order():
    layout = SHEARSENSE_6X6
    rng = np.random.default_rng(0)
    baseline = rng.uniform(20000, 30000, layout.n_channels)
    raw = baseline * rng.uniform(0.9, 1.0, size=(4, layout.n_channels))
    both = frames_from_raw(layout, raw, baseline)
    assert both.shape == (4, 3, 6, 6)
    np.testing.assert_allclose(frames_from_raw(layout, raw, baseline, channels="shear"),
                               both[:, 1:])
    assert frames_from_raw(layout, raw, baseline, virtual=True).shape == (4, 3, 11, 11)
    with pytest.raises(UserError):
        frames_from_raw(layout, raw, baseline, channels="everything")
    grid = get_layout("cost-8x8")
    pressure = frames_from_raw(grid, rng.uniform(0, 100, (2, 64)), np.zeros(64))
    assert pressure.shape == (2, 1, 8, 8)


@pytest.mark.parametrize("name", ["cnn_transformer", "cnn1d"])
def test_onnx_backend_gives_the_same_probabilities(name):
    model = _model(name)
    view = MODELS[name].view("tiny")
    stream = np.random.default_rng(5).normal(size=(view.frames + 4, 3, 6, 6)).astype(np.float32)
    reference = StreamingPredictor(model, view, window=view.frames).push_many(stream)
    fast = StreamingPredictor(model, view, window=view.frames, backend="onnx", threads=1)
    got = fast.push_many(stream)
    assert len(got) == len(reference) == 5
    np.testing.assert_allclose(np.array(got), np.array(reference), rtol=1e-4, atol=1e-5)
    with pytest.raises(UserError, match="backend"):
        StreamingPredictor(model, view, backend="gpu")


@pytest.mark.parametrize("backend", ["torch", "onnx"])
def test_full_cnn_transformer_streams_its_statistics_head_mirrors_and_members_exactly(backend):
    torch.manual_seed(0)
    spec = MODELS["cnn_transformer"]
    model = spec.build(5, 3, (6, 6), "full", members=2)
    assert model.needs_window and model.mirror and model.members == 2
    model.train()
    with torch.no_grad():  # non-trivial BN statistics, the window statistics' too
        model(torch.randn(8, *model.input_shape) + 0.3)
    model.eval()
    view = spec.view("full")
    stream = np.random.default_rng(4).normal(size=(view.frames + 3, 3, 6, 6)).astype(np.float32)
    predictor = StreamingPredictor(model, view, backend=backend)
    assert predictor.cached and predictor.keeps_frames
    outputs = predictor.push_many(stream)
    assert len(outputs) == 4
    for i, probs in enumerate(outputs):
        window = stream[i:i + view.frames].transpose(1, 0, 2, 3)[None]
        np.testing.assert_allclose(probs, _softmax_full(model, np.ascontiguousarray(window)),
                                   rtol=1e-3, atol=1e-5)
    with pytest.raises(ValueError, match="window"):  # the head cannot be skipped silently
        model.classify_embeddings(torch.zeros(1, view.frames, 4 * 2 * model.d_model))
