"""Networks built from hyperparameter objects are the networks main built from keyword
lists: saved run folders and exported models store the options, not the constructor's
signature, and rebuild the network from them, so the same options must give the same
modules (state-dict keys and shapes: the saved weights load) and, from the same seed,
the same logits.

``data/networks_before_h44.json`` was written by main at df0abc3 (before the change):
per model, the tiny preset with the whole recipe on (statistics head with gesture
metrics, mirroring, branch dropout, two members), ``torch.manual_seed(0)`` before
building, logits of ``torch.randn(2, 3, frames, 4, 4)`` drawn from seed 1."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from tactile_studio.learn.models._common import Recipe
from tactile_studio.learn.models.registry import get_model_spec

BEFORE = json.loads((Path(__file__).parent / "data" / "networks_before_h44.json")
                    .read_text(encoding="utf-8"))


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_same_options_build_the_network_main_built(name: str) -> None:
    saved = BEFORE[name]
    spec = get_model_spec(name)
    torch.manual_seed(0)
    model = spec.build(3, 3, (4, 4), "tiny", **saved["options"]).eval()
    assert {k: list(v.shape) for k, v in model.state_dict().items()} == saved["shapes"]
    x = torch.randn(2, 3, spec.view("tiny").frames, 4, 4,
                    generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        logits = model(x)
    assert torch.allclose(logits, torch.tensor(saved["logits"]), atol=1e-4)


def test_extra_members_carry_no_recipe_of_their_own() -> None:
    spec = get_model_spec("cnn1d")
    model = spec.build(3, 3, (4, 4), "tiny", stats=True, mirror=True, members=3)
    assert model.stats is not None and model.mirror and len(model.others) == 2
    assert all(other.stats is None and not other.mirror for other in model.others)
    assert Recipe(stats=True, mirror=True, branch_dropout=0.5).alone() == Recipe()
