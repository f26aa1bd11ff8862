"""ONNX export and int8 ONNX quantisation of the models (tiny presets).

Budget: ~30 s on one thread of 2 shared cores.
"""

from __future__ import annotations

import logging

import numpy as np
import onnx
import pytest
import torch
import torch.nn.functional as F

from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.export import (
    export_onnx,
    int8_format,
    load_onnx_predictor,
    quantize_onnx_int8,
)
from tactile_studio.learn.models import MODELS


@pytest.fixture(autouse=True)
def _threads():
    torch.set_num_threads(1)  # the 2 cores are shared by the whole team


def _separable(spec, n_classes: int, per_class: int, grid, channels: int, seed: int):
    """Each class a fixed random pattern (a static part plus a changing part) under unit
    noise: z-scored-like data standing in for gestures that differ in where and how. The
    signal is weak enough that decisions are close (float accuracy 75-100%), so an int8
    model that drifts flips predictions (mts3d in the QOperator format: 55% agreement)."""
    rng = np.random.default_rng(1234)  # templates shared by train and test draws
    t = spec.view("tiny").frames
    spatial = rng.normal(size=(n_classes, channels, 1, *grid))
    moving = rng.normal(size=(n_classes, channels, t, *grid))
    templates = (spatial + moving).astype(np.float32)
    noise = np.random.default_rng(seed)
    y = np.repeat(np.arange(n_classes), per_class)
    x = templates[y] * 0.3 + noise.normal(size=(len(y), channels, t, *grid)).astype(np.float32)
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
    gen = torch.Generator().manual_seed(0)
    for _ in range(steps):
        order = torch.randperm(len(x), generator=gen)  # mixed classes in every batch
        for i in range(0, len(x), 16):
            batch = order[i:i + 16]
            opt.zero_grad()
            F.cross_entropy(model(x[batch]), y[batch]).backward()
            opt.step()
    model.eval()


@pytest.mark.parametrize("name", list(MODELS))
def test_int8_onnx_file_loads_back_agrees_with_float_and_is_smaller(name, tmp_path, caplog):
    spec = MODELS[name]
    assert spec.quantizable
    grid, channels = (6, 6), (1 if name == "cnn1d" else 3)
    torch.manual_seed(0)
    x_train, y_train = _separable(spec, 4, 16, grid, channels, seed=1)
    x_test, y_test = _separable(spec, 4, 16, grid, channels, seed=2)
    model = spec.build(4, channels, grid, "tiny")
    _train(model, x_train, y_train, spec.train_defaults("tiny").lr, steps=10)
    float_path = export_onnx(model, x_train[:1], tmp_path / "float.onnx",
                             metadata={"labels": "a,b,c,d"})
    with caplog.at_level(logging.DEBUG):
        path = quantize_onnx_int8(float_path, tmp_path / "m.int8.onnx", x_train.numpy(),
                                  quant_format=int8_format(name))
    assert not caplog.records  # onnxruntime's advice would land on the CLI's stderr
    assert path.is_file() and path.stat().st_size < float_path.stat().st_size
    predict = load_onnx_predictor(path)
    assert predict.metadata["labels"] == "a,b,c,d"
    assert "int8" in predict.metadata["quantization"]
    with torch.inference_mode():
        fp = model(x_test).numpy().argmax(1)
    i8 = predict(x_test.numpy()).argmax(1)
    float_acc = (fp == y_test.numpy()).mean()
    assert float_acc >= 0.7, float_acc  # the float model learnt something to compare with
    assert (fp == i8).mean() >= 0.9
    assert (i8 == y_test.numpy()).mean() >= float_acc - 0.1
    # every weight matrix / kernel is stored as 8-bit integers in the file
    proto = onnx.load(str(path))
    int8_values = sum(int(np.prod(t.dims)) for t in proto.graph.initializer
                      if t.data_type in (onnx.TensorProto.INT8, onnx.TensorProto.UINT8))
    assert int8_values >= sum(p.numel() for p in model.parameters() if p.dim() >= 2)
    assert {n.op_type for n in proto.graph.node} & {"QLinearConv", "QuantizeLinear"}


def test_int8_needs_calibration_samples_and_a_known_format(tmp_path):
    model = MODELS["cnn1d"].build(3, 1, (6, 6), "tiny").eval()
    float_path = export_onnx(model, torch.zeros(1, *model.input_shape), tmp_path / "f.onnx")
    with pytest.raises(UserError, match="no calibration samples"):
        quantize_onnx_int8(float_path, tmp_path / "q.onnx", np.zeros((0, *model.input_shape)))
    with pytest.raises(ValueError, match="unknown int8 format"):
        quantize_onnx_int8(float_path, tmp_path / "q.onnx", np.zeros((4, *model.input_shape)),
                           quant_format="fp4")
    assert not (tmp_path / "q.onnx").exists()
