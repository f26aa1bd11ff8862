"""ONNX export and int8 quantisation of the models (tiny presets).

Budget: ~20 s on one thread of 2 shared cores.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from tactile_studio.errors import UserError
from tactile_studio.learn.export import (
    export_onnx,
    load_onnx_predictor,
    model_size_bytes,
    quantize_int8,
)
from tactile_studio.learn.models import MODELS


@pytest.fixture(autouse=True)
def _threads():
    torch.set_num_threads(1)  # the 2 cores are shared by the whole team


def _separable(spec, n_classes: int, per_class: int, grid, channels: int, seed: int):
    """Each class a fixed random pattern (a static part plus a changing part) under unit
    noise: z-scored-like data standing in for gestures that differ in where and how."""
    rng = np.random.default_rng(1234)  # templates shared by train and test draws
    t = spec.view("tiny").frames
    spatial = rng.normal(size=(n_classes, channels, 1, *grid))
    moving = rng.normal(size=(n_classes, channels, t, *grid))
    templates = (spatial + moving).astype(np.float32)
    noise = np.random.default_rng(seed)
    y = np.repeat(np.arange(n_classes), per_class)
    x = templates[y] * 0.8 + noise.normal(size=(len(y), channels, t, *grid)).astype(np.float32)
    return torch.from_numpy(x), torch.from_numpy(y)


@pytest.mark.parametrize("name", list(MODELS))
def test_onnx_predictions_match_torch(name, tmp_path):
    spec = MODELS[name]
    torch.manual_seed(0)
    for grid, channels in [((6, 6), 3), ((8, 8), 1)]:
        model = spec.build(7, channels, grid, "tiny").eval()
        # give BN non-trivial statistics so a wrong export of it would show
        model.train()
        with torch.no_grad():
            model(torch.randn(8, *model.input_shape) * 2 + 0.5)
        model.eval()
        path = export_onnx(model, torch.zeros(1, *model.input_shape), tmp_path / f"{name}.onnx",
                           metadata={"labels": "a,b,c,d,e,f,g"})
        predict = load_onnx_predictor(path)
        x = torch.randn(5, *model.input_shape)  # a batch size other than the example's
        with torch.inference_mode():
            expected = model(x).numpy()
        got = predict(x.numpy())
        assert got.shape == (5, 7)
        np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-4)
        single = predict(x[0].numpy())  # one sample without a batch axis
        np.testing.assert_allclose(single[0], expected[0], rtol=1e-4, atol=1e-4)
        assert predict.metadata["labels"] == "a,b,c,d,e,f,g"
        assert not model.training


def test_loading_a_missing_or_broken_onnx_file_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="no such ONNX model"):
        load_onnx_predictor(tmp_path / "missing.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model at all")
    with pytest.raises(UserError, match="bad.onnx: not a loadable ONNX model"):
        load_onnx_predictor(bad)


def _train(model, x, y, lr: float, steps: int) -> None:
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    model.train()
    for _ in range(steps):
        for i in range(0, len(x), 16):
            opt.zero_grad()
            F.cross_entropy(model(x[i:i + 16]), y[i:i + 16]).backward()
            opt.step()
    model.eval()


@pytest.mark.parametrize("name, grid, channels", [("cnn1d", (6, 6), 1),
                                                  ("cnn_transformer", (6, 6), 3)])
def test_int8_model_agrees_with_float_and_is_smaller(name, grid, channels):
    spec = MODELS[name]
    torch.manual_seed(0)
    x_train, y_train = _separable(spec, 4, 16, grid, channels, seed=1)
    x_test, y_test = _separable(spec, 4, 16, grid, channels, seed=2)
    model = spec.build(4, channels, grid, "tiny")
    _train(model, x_train, y_train, spec.train_defaults("tiny").lr, steps=10)
    q = quantize_int8(model, calibration=x_train)
    with torch.inference_mode():
        fp = model(x_test)
        i8 = q(x_test)
    float_acc = (fp.argmax(1) == y_test).float().mean().item()
    int8_acc = (i8.argmax(1) == y_test).float().mean().item()
    agreement = (fp.argmax(1) == i8.argmax(1)).float().mean().item()
    assert float_acc >= 0.7, float_acc  # the float model learnt something to compare with
    assert agreement >= 0.9, agreement
    assert int8_acc >= float_acc - 0.1
    assert model_size_bytes(q) < model_size_bytes(model)
    # the convolutions really are int8 now, and the float original is untouched
    kinds = {type(m).__module__ for m in q.modules()}
    assert any("quantized" in k for k in kinds)
    assert not any("quantized" in type(m).__module__ for m in model.modules())
