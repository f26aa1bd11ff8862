"""Ensemble members inside one model (option ``members`` of the full recipe): K
independently initialised networks and statistics layers over one shared window
statistics, logits averaged, each member trained on its own loss."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from tactile_studio.learn.models import MODELS

RECIPE_MODELS = ["cnn1d", "cnn3d", "sefusion", "mts3d", "cnn_transformer"]


def _build(name: str, members: int, **sets):
    torch.manual_seed(0)
    return MODELS[name].build(9, 3, (6, 6), "full", members=members, **sets)


def _x(name: str, batch: int = 3) -> torch.Tensor:
    torch.manual_seed(1)
    return torch.randn(batch, 3, MODELS[name].view("full").frames, 6, 6)


@pytest.mark.parametrize("name", RECIPE_MODELS)
def test_members_are_distinct_networks_whose_mean_is_the_output(name):
    model = _build(name, 3, mirror=False).eval()
    assert model.members == 3
    first = dict(model.named_parameters())
    for other in model.others:  # same shapes, different initial weights
        weights = [(n, p) for n, p in other.named_parameters() if p.dim() > 1]
        assert weights
        assert all(not torch.equal(p, first[n]) for n, p in weights)
    heads = [model.stats.mlp, *model.stats.more]
    assert len(heads) == 3
    assert not torch.equal(heads[0][-1].weight, heads[1][-1].weight)
    x = _x(name)
    with torch.inference_mode():
        each = model.member_logits(x)
        out = model(x)
    assert each.shape == (3, 3, 9)
    assert not torch.allclose(each[0], each[1], atol=1e-3)
    assert torch.allclose(out, each.mean(0), atol=1e-5)


@pytest.mark.parametrize("name", ["cnn1d", "sefusion"])
def test_one_member_keeps_the_single_network_and_its_weight_names(name):
    single = _build(name, 1)
    assert single.members == 1
    assert not any(k.startswith("others.") or ".more." in k for k in single.state_dict())
    three = _build(name, 3)
    extra = set(three.state_dict()) - set(single.state_dict())
    assert extra and all(k.startswith("others.") or k.startswith("stats.more.") for k in extra)


def test_training_step_is_the_mean_of_the_members_own_losses_and_reaches_all_of_them():
    model = _build("cnn1d", 3, mirror=False, branch_dropout=0.0, dropout=0.0)
    model.train()
    for m in model.modules():  # no dropout: the same pass twice gives the same logits
        if isinstance(m, torch.nn.Dropout):
            m.p = 0.0
    x, y = _x("cnn1d", 8), torch.arange(8) % 9
    loss_fn = torch.nn.CrossEntropyLoss()
    loss, logits = model.training_step(x, y, loss_fn)
    with torch.no_grad():
        each = model.member_logits(x)
    expected = sum(float(loss_fn(e, y)) for e in each) / 3
    assert float(loss.detach()) == pytest.approx(expected, rel=1e-4)
    assert torch.allclose(logits, each.mean(0), atol=1e-4)
    # the mean of the losses is not the loss of the mean (the members train separately)
    assert float(loss.detach()) != pytest.approx(float(loss_fn(each.mean(0), y)), rel=1e-4)
    loss.backward()
    for other in model.others:
        assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in other.parameters()
                   if p.requires_grad and p.dim() > 1)


@pytest.mark.parametrize("name", ["cnn1d", "cnn3d"])
def test_members_export_to_onnx_with_the_same_logits(name):
    from tactile_studio.learn.deploy.export import cpu_session, onnx_bytes

    model = _build(name, 3).eval()
    x = _x(name)
    out = cpu_session(onnx_bytes(model, x[:1])).run(None, {"input": x.numpy()})[0]
    with torch.inference_mode():
        expected = model(x).numpy()
    assert np.abs(out - expected).max() < 1e-4


def test_members_must_be_a_positive_count():
    from tactile_studio.errors import UserError

    with pytest.raises(UserError, match="members"):
        MODELS["cnn1d"].build(9, 3, (6, 6), "full", members=0)
