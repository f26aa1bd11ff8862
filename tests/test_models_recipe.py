"""The full presets' generalisation recipe: mirror averaging, window statistics, schedule."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from tactile_studio.learn.learners.train import _lr_factor
from tactile_studio.learn.models import MODELS, cnn1d, cnn3d, cnn_transformer, mts3d, sefusion
from tactile_studio.learn.models._common import WindowStatistics, mirror_average, random_mirror

PAPERS = {"cnn1d": cnn1d, "cnn3d": cnn3d, "cnn_transformer": cnn_transformer,
          "mts3d": mts3d, "sefusion": sefusion}


def _mirror_lr(x: torch.Tensor) -> torch.Tensor:
    """Left-right mirror of (B, 3, T, R, X) normal + shear: columns reversed, shear x negated."""
    y = torch.flip(x, (4,)).clone()
    y[:, 1] = -y[:, 1]
    return y


@pytest.mark.parametrize("name", ["cnn1d", "cnn3d", "sefusion"])
def test_mirror_averaged_prediction_is_the_same_for_a_mirrored_touch(name):
    spec = MODELS[name]
    torch.manual_seed(0)
    model = spec.build(5, 3, (6, 6), "full").eval()
    x = torch.randn(2, 3, spec.view("full").frames, 6, 6)
    with torch.inference_mode():
        a, b = model(x), model(_mirror_lr(x))
        plain = model.network_logits(x)
    assert torch.allclose(a, b, atol=1e-4)
    assert not torch.allclose(plain, model.network_logits(_mirror_lr(x)), atol=1e-4)


def test_mirror_average_of_a_plain_function_and_random_mirror_keep_the_shape():
    x = torch.randn(4, 3, 5, 6, 6)
    assert torch.allclose(mirror_average(lambda v: v.sum(dim=(2, 3, 4)), x)[:, 0],
                          x[:, 0].sum(dim=(1, 2, 3)), atol=1e-4)
    torch.manual_seed(1)
    y = random_mirror(x)
    assert y.shape == x.shape
    # every sample is x itself or one of its mirror images: the normal load is preserved
    assert torch.allclose(y[:, 0].sum(dim=(1, 2, 3)), x[:, 0].sum(dim=(1, 2, 3)), atol=1e-4)


def test_window_statistics_ignore_where_on_the_grid_a_touch_happens_in_its_summaries():
    stats = WindowStatistics(1, 20).eval()
    x = torch.zeros(1, 1, 20, 6, 6)
    x[0, 0, :, 1, 1] = torch.linspace(0, 3, 20)
    moved = torch.roll(x, shifts=(3, 2), dims=(3, 4))
    a, b = stats(x), stats(moved)
    per_signal = a.shape[1] // stats.n_signals
    # the grid summaries (mean, max, min, spread: first 4 signals) do not change
    assert torch.allclose(a[:, :4 * per_signal], b[:, :4 * per_signal], atol=1e-5)
    assert not torch.allclose(a, b)  # the centroid signals do


def test_cosine_schedule_warms_up_then_decays_to_almost_zero():
    recipe = {"schedule": "cosine", "warmup": 2}
    factors = [_lr_factor(recipe, e, 30) for e in range(1, 31)]
    assert factors[0] < factors[1] < factors[2] == pytest.approx(1.0)
    assert all(a >= b for a, b in zip(factors[2:], factors[3:]))
    assert factors[-1] < 0.01
    assert _lr_factor({}, 17, 30) == 1.0


@pytest.mark.parametrize("name", list(PAPERS))
def test_every_model_keeps_the_papers_network_as_overrides_beside_the_full_recipe(name):
    from tactile_studio.learn.models._common import count_parameters

    spec = MODELS[name]
    paper = spec.build(9, 3, (6, 6), "full", **PAPERS[name].PAPER)
    full = spec.build(9, 3, (6, 6), "full")
    assert count_parameters(full) != count_parameters(paper)
    assert full.train_recipe["schedule"] == "cosine"
    assert spec.build(9, 3, (6, 6), "tiny").train_recipe == {}
    frames = spec.view("full").frames
    with torch.inference_mode():
        assert np.isfinite(full.eval()(torch.randn(1, 3, frames, 6, 6)).numpy()).all()


def test_full_recipe_exports_to_onnx_with_its_mirror_averaging_and_statistics():
    from tactile_studio.learn.deploy.export import cpu_session, onnx_bytes

    torch.manual_seed(0)
    spec = MODELS["cnn1d"]
    model = spec.build(9, 3, (6, 6), "full").eval()
    x = torch.randn(3, 3, spec.view("full").frames, 6, 6)
    out = cpu_session(onnx_bytes(model, x[:1])).run(None, {"input": x.numpy()})[0]
    with torch.inference_mode():
        expected = model(x).numpy()
    assert np.abs(out - expected).max() < 1e-4
